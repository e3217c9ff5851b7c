"""An independent JAX reference for the core formulas, used by tests to check torch.

Written out from the definitions, not from rotations.py: the rotation of a vector is
the sandwich q (0, v) q* by two Hamilton products, forward kinematics walks the joints
one by one in a loop, d1 uses arccos itself.  tests/test_jax_parity.py checks that values and
gradients (jax.grad vs torch.autograd) agree.  Conventions as in rotations.py:
quaternions (w, x, y, z), Hamilton product, v' = q v q*.

Differs from rotations.py: no small-angle safeguards (d1's gradient is infinite at
distance 0); compare at generic random inputs only.
"""

from __future__ import annotations

from functools import partial

import jax
import jax.numpy as jnp


def quat_mul(a: jnp.ndarray, b: jnp.ndarray) -> jnp.ndarray:
    """Hamilton product (..., 4), (..., 4) -> (..., 4): (a_w b_w - a.b, a_w b + b_w a + a x b)."""
    aw, av = a[..., :1], a[..., 1:]
    bw, bv = b[..., :1], b[..., 1:]
    w = aw * bw - jnp.sum(av * bv, -1, keepdims=True)
    v = aw * bv + bw * av + jnp.cross(av, bv)
    return jnp.concatenate((w, v), -1)


def quat_conjugate(q: jnp.ndarray) -> jnp.ndarray:
    """(..., 4) -> (..., 4)."""
    return jnp.concatenate((q[..., :1], -q[..., 1:]), -1)


def quat_rotate(q: jnp.ndarray, v: jnp.ndarray) -> jnp.ndarray:
    """q (..., 4) unit, v (..., 3) -> (..., 3): the vector part of q (0, v) q*."""
    lead = jnp.broadcast_shapes(q.shape[:-1], v.shape[:-1])
    v = jnp.broadcast_to(v, lead + (3,))
    q = jnp.broadcast_to(q, lead + (4,))
    v4 = jnp.concatenate((jnp.zeros_like(v[..., :1]), v), -1)
    return quat_mul(quat_mul(q, v4), quat_conjugate(q))[..., 1:]


@partial(jax.jit, static_argnames="parents")
def forward_kinematics(rotations: jnp.ndarray, root_positions: jnp.ndarray, offsets: jnp.ndarray,
                       parents: tuple[int, ...]) -> tuple[jnp.ndarray, jnp.ndarray]:
    """rotations (..., J, 4), root_positions (..., 3), offsets (J, 3), parents (J,) tuple
    -> positions (..., J, 3), global rotations (..., J, 4).

    One joint per step of a `fori_loop` over joint-major arrays (J, ..., 4): XLA compiles
    the step once instead of an unrolled 20-joint graph.
    """
    local = jnp.moveaxis(rotations, -2, 0)  # (J, ..., 4)
    parent = jnp.asarray(parents)
    glob = jnp.zeros_like(local).at[0].set(local[0])
    pos = jnp.zeros(local.shape[:-1] + (3,), local.dtype).at[0].set(root_positions)

    def step(j, carry):
        glob, pos = carry
        p = parent[j]
        # x_j = x_p + R_p o_j ;  R_j = R_p r_j
        pos = pos.at[j].set(pos[p] + quat_rotate(glob[p], offsets[j]))
        glob = glob.at[j].set(quat_mul(glob[p], local[j]))
        return glob, pos

    glob, pos = jax.lax.fori_loop(1, len(parents), step, (glob, pos))
    return jnp.moveaxis(pos, 0, -2), jnp.moveaxis(glob, 0, -2)


def quat_geodesic(q1: jnp.ndarray, q2: jnp.ndarray, kind: str = "d1") -> jnp.ndarray:
    """(..., 4), (..., 4) unit quaternions -> (...); Ghorbani et al. 2020 eq. (17), (18), (20)."""
    dot = jnp.sum(q1 * q2, -1)
    if kind == "d1":
        return 2.0 * jnp.arccos(jnp.clip(jnp.abs(dot), 0.0, 1.0))
    if kind == "d2":
        return 1.0 - jnp.abs(dot)
    if kind == "d3":
        return jnp.minimum(jnp.sum((q1 - q2) ** 2, -1), jnp.sum((q1 + q2) ** 2, -1))
    raise ValueError(f"quat_geodesic: kind must be 'd1', 'd2' or 'd3', got {kind!r}")


def matrix_geodesic(m1: jnp.ndarray, m2: jnp.ndarray) -> jnp.ndarray:
    """(..., 3, 3), (..., 3, 3) -> (...) angle of R1 R2^T = arccos((tr - 1) / 2)   -- Ghorbani eq. (21)."""
    r = m1 @ jnp.swapaxes(m2, -1, -2)
    return jnp.arccos(jnp.clip(0.5 * (jnp.trace(r, axis1=-2, axis2=-1) - 1.0), -1.0, 1.0))
