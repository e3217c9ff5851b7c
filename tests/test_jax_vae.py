"""Parity of the JAX pose VAE (course_lib.models.jax_vae) with the torch one, and the written-out Adam."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest
import torch

from course_lib.models import jax_vae
from course_lib.models.vae import PoseVae, VaeConfig


def _pair(n_labels=0, seed=0):
    torch.manual_seed(seed)
    model = PoseVae(VaeConfig.cpu(x_dim=12, z_dim=3, hidden=16, n_labels=n_labels, obs_std=0.2)).double()
    g = torch.Generator().manual_seed(seed + 1)
    x = torch.randn(9, 12, generator=g, dtype=torch.float64)
    eps = torch.randn(9, 3, generator=g, dtype=torch.float64)
    return model, x, eps


@pytest.mark.parametrize("n_labels", [0, 4])
def test_same_weights_same_eps_same_elbo_and_gradients(n_labels):
    model, x, eps = _pair(n_labels)
    label = torch.arange(9) % 4 if n_labels else None
    out = model.loss((x, label) if n_labels else x, eps=eps)
    out["loss"].backward()
    with jax.enable_x64(True):
        params = jax_vae.torch_to_jax(model, jnp.float64)
        y = jnp.asarray(torch.nn.functional.one_hot(label, 4).double().numpy()) if n_labels else None
        (loss, aux), grads = jax.value_and_grad(jax_vae.negative_elbo, has_aux=True)(
            params, jnp.asarray(x.numpy()), jnp.asarray(eps.numpy()), 0.2, 1.0, y)
        assert abs(float(loss) - out["loss"].item()) < 1e-5
        assert abs(float(aux["kl"]) - out["kl"].item()) < 1e-5
        lins = [m for m in model.encoder if hasattr(m, "weight")] + [m for m in model.decoder if hasattr(m, "weight")]
        assert len(lins) == len(params["encoder"] + params["decoder"]) == 6
        for lin, g in zip(lins, grads["encoder"] + grads["decoder"], strict=True):
            np.testing.assert_allclose(np.asarray(g["W"]).T, lin.weight.grad.numpy(), atol=1e-5, rtol=0)
            np.testing.assert_allclose(np.asarray(g["b"]), lin.bias.grad.numpy(), atol=1e-5, rtol=0)


def test_round_trip_torch_jax_torch():
    model, x, eps = _pair()
    model, x, eps = model.float(), x.float(), eps.float()
    params = jax_vae.torch_to_jax(model)
    other = PoseVae(model.config)
    jax_vae.jax_to_torch(params, other)
    assert torch.equal(other.loss(x, eps=eps)["loss"], model.loss(x, eps=eps)["loss"])
    params["decoder"][0]["W"] = params["decoder"][0]["W"][:2]
    with pytest.raises(ValueError, match="weight shape"):
        jax_vae.jax_to_torch(params, other)


def test_written_out_adam_matches_torch_adam():
    model, x, eps = _pair()
    opt = torch.optim.Adam(model.parameters(), lr=1e-2)
    with jax.enable_x64(True):
        params = jax_vae.torch_to_jax(model, jnp.float64)
        state = jax_vae.adam_init(params)
        grad_fn = jax.grad(lambda p: jax_vae.negative_elbo(p, jnp.asarray(x.numpy()), jnp.asarray(eps.numpy()),
                                                           0.2)[0])
        for _ in range(3):
            opt.zero_grad()
            model.loss(x, eps=eps)["loss"].backward()
            opt.step()
            params, state = jax_vae.adam_update(params, grad_fn(params), state, lr=1e-2)
        np.testing.assert_allclose(np.asarray(params["decoder"][-1]["W"]).T, model.decoder[-1].weight.detach().numpy(),
                                   atol=1e-8)


def test_jitted_training_lowers_the_loss():
    params = jax_vae.init_params(jax.random.PRNGKey(0), x_dim=12, z_dim=2, hidden=32)
    x = jnp.asarray(np.random.default_rng(0).normal(size=(256, 12)) @ np.random.default_rng(1).normal(size=(12, 12)),
                    jnp.float32)
    step, state = jax_vae.make_train_step(obs_std=0.5, lr=3e-3), jax_vae.adam_init(params)
    losses = []
    for key in jax.random.split(jax.random.PRNGKey(1), 150):
        params, state, loss, _ = step(params, state, x, key)
        losses.append(float(loss))
    assert np.mean(losses[-20:]) < 0.7 * losses[0]
