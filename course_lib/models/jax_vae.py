"""The pose VAE of ``course_lib/models/vae.py`` written functionally in JAX.

Taught in notebooks/01_vae_basics.ipynb, side by side with the torch version.

Parameters are a pytree (nested dicts/lists of arrays), the loss is a pure function of
``(params, x, eps)``, ``jax.grad`` differentiates it and ``jax.jit`` compiles it.  Adam is
written out in a few lines (``adam_init`` / ``adam_update``) instead of using optax: optax is
not a dependency of the course, and seeing the two moment estimates and the bias correction
as tree_maps over the parameter pytree teaches what ``torch.optim.Adam`` hides.

``torch_to_jax`` / ``jax_to_torch`` convert weights both ways, so the same weights and the same
noise eps give the same ELBO and gradients in both frameworks (tests/test_jax_vae.py).

Differs from the torch version: unconditional or conditional MLP VAE only (no KL schedule,
free bits or skip_noise decoder); the KL weight ``beta`` is an argument.
"""

from __future__ import annotations

import math

import jax
import jax.numpy as jnp
import numpy as np

__all__ = ["adam_init", "adam_update", "decode", "encode", "init_params", "jax_to_torch", "make_train_step",
           "negative_elbo", "torch_to_jax"]

LOG_2PI = math.log(2 * math.pi)


def _dense_init(key, d_in: int, d_out: int) -> dict:
    """torch.nn.Linear's default init: U(-1/sqrt(d_in), 1/sqrt(d_in)); W stored as (d_in, d_out)."""
    k_w, k_b = jax.random.split(key)
    bound = 1.0 / math.sqrt(d_in)
    return {"W": jax.random.uniform(k_w, (d_in, d_out), minval=-bound, maxval=bound),
            "b": jax.random.uniform(k_b, (d_out,), minval=-bound, maxval=bound)}


def init_params(key, x_dim: int = 63, z_dim: int = 2, hidden: int = 128, layers: int = 2, n_labels: int = 0) -> dict:
    """{'encoder': [layer]*(layers+1), 'decoder': [layer]*(layers+1)}, layer = {'W': (in, out), 'b': (out,)}."""
    def mlp(key, d_in, d_out):
        sizes = [d_in] + [hidden] * layers + [d_out]
        keys = jax.random.split(key, len(sizes) - 1)
        return [_dense_init(k, a, b) for k, a, b in zip(keys, sizes[:-1], sizes[1:], strict=True)]

    k_enc, k_dec = jax.random.split(key)
    return {"encoder": mlp(k_enc, x_dim + n_labels, 2 * z_dim), "decoder": mlp(k_dec, z_dim + n_labels, x_dim)}


def _mlp(layers: list, h):
    """SiLU hidden layers, linear output (matches course_lib.models.vae._mlp)."""
    for layer in layers[:-1]:
        h = jax.nn.silu(h @ layer["W"] + layer["b"])
    return h @ layers[-1]["W"] + layers[-1]["b"]


def encode(params: dict, x, y=None):
    """x: (N, x_dim), y: optional (N, n_labels) one-hot -> mu, logvar: (N, z_dim)."""
    h = _mlp(params["encoder"], x if y is None else jnp.concatenate([x, y], -1))
    mu, logvar = jnp.split(h, 2, axis=-1)
    return mu, logvar


def decode(params: dict, z, y=None):
    """z: (N, z_dim) -> mean of p(x|z): (N, x_dim)."""
    return _mlp(params["decoder"], z if y is None else jnp.concatenate([z, y], -1))


def negative_elbo(params: dict, x, eps, obs_std: float = 0.1, beta: float = 1.0, y=None):
    """Mean over the batch of -ELBO = recon NLL + beta * KL.  x: (N, x_dim), eps: (N, z_dim) -> scalar.

    Returns (loss, aux) with aux = {'recon', 'kl'} so ``jax.grad(..., has_aux=True)`` works.
    """
    mu, logvar = encode(params, x, y)
    z = jnp.exp(0.5 * logvar) * eps + mu  # Habibie eq. (3)
    x_hat = decode(params, z, y)
    recon = 0.5 * (((x - x_hat) / obs_std) ** 2 + 2 * math.log(obs_std) + LOG_2PI).sum(-1).mean()
    kl = (0.5 * (mu**2 + jnp.exp(logvar) - logvar - 1.0)).sum(-1).mean()  # closed form, eq. (2)
    return recon + beta * kl, {"recon": recon, "kl": kl}


# ----------------------------------------------------------------------------- Adam, written out


def adam_init(params: dict) -> dict:
    """Adam state: first and second moment pytrees (zeros like params) and the step count."""
    zeros = jax.tree_util.tree_map(jnp.zeros_like, params)
    return {"m": zeros, "v": jax.tree_util.tree_map(jnp.zeros_like, params), "t": jnp.zeros((), jnp.int32)}


def adam_update(params, grads, state, lr=1e-3, b1=0.9, b2=0.999, eps=1e-8):
    """One Adam step (Kingma & Ba 2015, Algorithm 1); returns (params, state)."""
    t = state["t"] + 1
    m = jax.tree_util.tree_map(lambda m, g: b1 * m + (1 - b1) * g, state["m"], grads)  # m_t = b1 m + (1-b1) g
    v = jax.tree_util.tree_map(lambda v, g: b2 * v + (1 - b2) * g**2, state["v"], grads)  # v_t = b2 v + (1-b2) g^2
    c1, c2 = 1 - b1**t, 1 - b2**t  # bias corrections: m_hat = m / c1, v_hat = v / c2
    params = jax.tree_util.tree_map(lambda p, m, v: p - lr * (m / c1) / (jnp.sqrt(v / c2) + eps), params, m, v)
    return params, {"m": m, "v": v, "t": t}


def make_train_step(obs_std: float = 0.1, beta: float = 1.0, lr: float = 1e-3):
    """A jitted ``step(params, state, x, key) -> (params, state, loss, aux)`` drawing eps from ``key``."""
    grad_fn = jax.value_and_grad(negative_elbo, has_aux=True)

    @jax.jit
    def step(params, state, x, key):
        eps = jax.random.normal(key, (x.shape[0], params["encoder"][-1]["b"].shape[0] // 2), x.dtype)
        (loss, aux), grads = grad_fn(params, x, eps, obs_std, beta)
        params, state = adam_update(params, grads, state, lr)
        return params, state, loss, aux

    return step


# ----------------------------------------------------------------------------- torch <-> JAX


def _linears(sequential) -> list:
    return [m for m in sequential if hasattr(m, "weight")]


def torch_to_jax(model, dtype=None) -> dict:
    """A ``PoseVae``'s weights as a JAX params pytree (W transposed to (in, out)).  dtype: e.g. jnp.float64."""
    if getattr(model.config, "skip_noise", 0) > 0:
        raise ValueError("the JAX VAE has no skip_noise decoder")

    def conv(lin):
        # copies: jnp.asarray may alias a numpy buffer, and torch updates its weights in place
        w, b = lin.weight.detach().cpu().numpy().T.copy(), lin.bias.detach().cpu().numpy().copy()
        return {"W": jnp.asarray(w, dtype or w.dtype), "b": jnp.asarray(b, dtype or b.dtype)}

    return {"encoder": [conv(m) for m in _linears(model.encoder)],
            "decoder": [conv(m) for m in _linears(model.decoder)]}


def jax_to_torch(params: dict, model) -> None:
    """Copy a JAX params pytree into a ``PoseVae`` in place (shapes must match)."""
    import torch

    for name in ("encoder", "decoder"):
        lins = _linears(getattr(model, name))
        if len(lins) != len(params[name]):
            raise ValueError(f"{name}: torch has {len(lins)} linear layers, params have {len(params[name])}")
        for lin, layer in zip(lins, params[name], strict=True):
            w = torch.as_tensor(np.asarray(layer["W"]).T.copy(), dtype=lin.weight.dtype)
            if w.shape != lin.weight.shape:
                raise ValueError(f"{name}: weight shape {tuple(w.shape)} != torch {tuple(lin.weight.shape)}")
            with torch.no_grad():
                lin.weight.copy_(w)
                lin.bias.copy_(torch.as_tensor(np.array(layer["b"]), dtype=lin.bias.dtype))
