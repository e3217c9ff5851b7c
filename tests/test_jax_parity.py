"""torch (rotations.py, skeleton.py) vs the independent JAX reference: values and gradients, float64.

Inputs are random raw 4-vectors normalised inside each loss, in both frameworks, so
both sides compute the same function of the raw numbers (the formulas agree only on
unit quaternions) and their gradients must agree too.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest
import torch

from course_lib import jax_reference as jr
from course_lib import rotations as rot
from course_lib.skeleton import Skeleton, forward_kinematics

ATOL = 1e-5


@pytest.fixture(autouse=True)
def _x64():
    """float64 in JAX for these tests only (the global flag would leak into other test files)."""
    with jax.enable_x64(True):
        yield


def _unit_t(q: torch.Tensor) -> torch.Tensor:
    return q / torch.linalg.vector_norm(q, dim=-1, keepdim=True)


def _unit_j(q: jnp.ndarray) -> jnp.ndarray:
    return q / jnp.linalg.norm(q, axis=-1, keepdims=True)


def _compare(torch_loss, jax_loss, *inputs: np.ndarray) -> None:
    """Scalar losses of the same inputs: values and every input's gradient agree within ATOL."""
    ts = [torch.tensor(x, dtype=torch.float64, requires_grad=True) for x in inputs]
    value_t = torch_loss(*ts)
    grads_t = torch.autograd.grad(value_t, ts)
    value_j, grads_j = jax.jit(jax.value_and_grad(jax_loss, argnums=tuple(range(len(inputs)))))(
        *[jnp.asarray(x, dtype=jnp.float64) for x in inputs])
    assert abs(value_t.item() - float(value_j)) < ATOL, (value_t.item(), float(value_j))
    for i, (gt, gj) in enumerate(zip(grads_t, grads_j, strict=True)):
        np.testing.assert_allclose(gt.numpy(), np.asarray(gj), atol=ATOL, err_msg=f"gradient of input {i}")
        assert np.abs(gt.numpy()).max() > 1e-3  # a real, non-trivial gradient


@pytest.fixture
def rng() -> np.random.Generator:
    return np.random.default_rng(7)


def test_quat_mul_parity(rng):
    a, b, w = rng.normal(size=(3, 32, 4))
    _compare(lambda a, b: (rot.quat_mul(a, b) * torch.from_numpy(w)).sum(),
             lambda a, b: (jr.quat_mul(a, b) * w).sum(), a, b)


def test_quat_rotate_parity(rng):
    q, v, w = rng.normal(size=(32, 4)), rng.normal(size=(32, 3)), rng.normal(size=(32, 3))
    _compare(lambda q, v: (rot.quat_rotate(_unit_t(q), v) * torch.from_numpy(w)).sum(),
             lambda q, v: (jr.quat_rotate(_unit_j(q), v) * w).sum(), q, v)


@pytest.mark.parametrize("kind", ["d1", "d2", "d3"])
def test_quat_geodesic_parity(rng, kind):
    q1, q2 = rng.normal(size=(2, 64, 4))
    _compare(lambda a, b: rot.quat_geodesic(_unit_t(a), _unit_t(b), kind).sum(),
             lambda a, b: jr.quat_geodesic(_unit_j(a), _unit_j(b), kind).sum(), q1, q2)


def test_matrix_geodesic_parity(rng):
    """Gradients through quaternion -> matrix on each side (torch's closed form vs JAX's q e_i q*)."""
    def jax_matrix(q):
        return jnp.stack([jr.quat_rotate(_unit_j(q), e) for e in jnp.eye(3, dtype=q.dtype)], -1)  # columns R e_i

    q1, q2 = rng.normal(size=(2, 64, 4))
    _compare(lambda a, b: rot.matrix_geodesic(rot.quat_to_matrix(_unit_t(a)), rot.quat_to_matrix(_unit_t(b))).sum(),
             lambda a, b: jr.matrix_geodesic(jax_matrix(a), jax_matrix(b)).sum(), q1, q2)


def test_forward_kinematics_parity(rng):
    sk = Skeleton.canonical()
    J = sk.num_joints
    q, root = rng.normal(size=(2, 5, J, 4)), rng.normal(size=(2, 5, 3))
    offsets = sk.offsets * rng.uniform(0.8, 1.2, size=(J, 1))
    wp, wr = rng.normal(size=(2, 5, J, 3)), rng.normal(size=(2, 5, J, 4))

    def torch_loss(q, root, off):
        pos, glob = forward_kinematics(_unit_t(q), root, off, sk.parents)
        return (pos * torch.from_numpy(wp)).sum() + (glob * torch.from_numpy(wr)).sum()

    def jax_loss(q, root, off):
        pos, glob = jr.forward_kinematics(_unit_j(q), root, off, sk.parents)
        return (pos * wp).sum() + (glob * wr).sum()

    _compare(torch_loss, jax_loss, q, root, offsets)


def test_forward_kinematics_float32_parity(rng):
    """The float32 path the course trains with, at float32 tolerance."""
    sk = Skeleton.canonical()
    q = rng.normal(size=(64, sk.num_joints, 4)).astype(np.float32)
    q /= np.linalg.norm(q, axis=-1, keepdims=True)
    root = rng.normal(size=(64, 3)).astype(np.float32)
    off = sk.offsets.astype(np.float32)
    pos_t, glob_t = forward_kinematics(torch.from_numpy(q), torch.from_numpy(root), torch.from_numpy(off), sk.parents)
    pos_j, glob_j = jr.forward_kinematics(jnp.asarray(q), jnp.asarray(root), jnp.asarray(off), sk.parents)
    assert pos_t.dtype == torch.float32 and pos_j.dtype == jnp.float32
    np.testing.assert_allclose(pos_t.numpy(), np.asarray(pos_j), atol=ATOL)
    np.testing.assert_allclose(glob_t.numpy(), np.asarray(glob_j), atol=ATOL)
