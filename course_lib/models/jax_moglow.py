"""One MoGlow step of flow (``course_lib.models.moglow.FlowStep``) written functionally in JAX.

Taught in notebooks/06_moglow.ipynb; tests/test_jax_moglow.py checks that values, inverses,
log-determinants and gradients agree with torch's.  Written from the equations, not from the torch
code: the 1x1 map's log-determinant is taken from ``jnp.linalg.slogdet`` of the assembled W (not the
sum of the LU diagonal), its inverse by ``jnp.linalg.solve``, the coupling's scale by an explicit
``1 / (1 + exp(-(raw + shift)))``.

Parameters are a dict of arrays (``torch_to_jax`` reads them from a torch FlowStep):

    actnorm:  bias (D,), log_scale (D,)                 y = exp(s) (x + b)
    linear:   P (D, D), lower (D, D), upper (D, D), sign_s (D,), log_s (D,)
              W = P (tril(lower, -1) + I) (triu(upper, 1) + diag(sign_s exp(log_s)))
    coupling: W1, b1, W2, b2, W3, b3 (W as (d_in, d_out)), and the scale shift (a float argument)
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

__all__ = ["inverse", "forward", "linear_weight", "torch_to_jax"]


def linear_weight(p: dict) -> jnp.ndarray:
    """-> W (D, D) of the LU-parameterised 1x1 map."""
    D = p["log_s"].shape[0]
    L = jnp.tril(p["lower"], -1) + jnp.eye(D, dtype=p["lower"].dtype)
    U = jnp.triu(p["upper"], 1) + jnp.diag(p["sign_s"] * jnp.exp(p["log_s"]))
    return p["P"] @ L @ U


def _coupling_net(p: dict, x_a, h, shift: float):
    """-> sigma, t of the coupling: (raw, t) = MLP([x_a, h]), sigma = 1 / (1 + exp(-(raw + shift)))."""
    u = jnp.concatenate((x_a, h), -1)
    u = jax.nn.relu(u @ p["W1"] + p["b1"])
    u = jax.nn.relu(u @ p["W2"] + p["b2"])
    out = u @ p["W3"] + p["b3"]
    half = out.shape[-1] // 2
    raw, t = out[..., :half], out[..., half:]
    return 1.0 / (1.0 + jnp.exp(-(raw + shift))), t


def forward(p: dict, x, h, shift: float = 2.0):
    """x (..., D), h (..., H) -> y (..., D), log|det dy/dx| (...): actnorm, 1x1 map, affine coupling."""
    y = jnp.exp(p["log_scale"]) * (x + p["bias"])
    W = linear_weight(p)
    y = y @ W.T
    k = x.shape[-1] // 2
    sigma, t = _coupling_net(p, y[..., :k], h, shift)
    y = jnp.concatenate((y[..., :k], sigma * (y[..., k:] + t)), -1)
    log_det = jnp.sum(p["log_scale"]) + jnp.linalg.slogdet(W)[1] + jnp.sum(jnp.log(sigma), -1)
    return y, log_det


def inverse(p: dict, y, h, shift: float = 2.0):
    """y (..., D), h (..., H) -> x (..., D), the inverse of `forward`."""
    k = y.shape[-1] // 2
    sigma, t = _coupling_net(p, y[..., :k], h, shift)
    u = jnp.concatenate((y[..., :k], y[..., k:] / sigma - t), -1)
    u = jnp.linalg.solve(linear_weight(p), u.reshape(-1, u.shape[-1]).T).T.reshape(u.shape)
    return u * jnp.exp(-p["log_scale"]) - p["bias"]


def torch_to_jax(step, dtype=jnp.float64) -> dict:
    """A torch FlowStep -> the parameter dict above (copies)."""
    def a(t):
        return jnp.asarray(np.asarray(t.detach().cpu().double().numpy()), dtype=dtype)

    if step.coupling.recurrent:
        raise ValueError("torch_to_jax: writes the MLP coupling (coupling_net='mlp'); this step's coupling is an LSTM")
    lins = [m for m in step.coupling.net if hasattr(m, "weight")]
    p = {"bias": a(step.actnorm.bias), "log_scale": a(step.actnorm.log_scale), "P": a(step.linear.P),
         "lower": a(step.linear.lower), "upper": a(step.linear.upper), "sign_s": a(step.linear.sign_s),
         "log_s": a(step.linear.log_s)}
    for i, lin in enumerate(lins, 1):
        p[f"W{i}"], p[f"b{i}"] = a(lin.weight).T, a(lin.bias)
    return p
