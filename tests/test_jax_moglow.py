"""One MoGlow step of flow: torch (models/moglow.py) vs the JAX reference (jax_moglow.py), float64."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest
import torch

from course_lib.models import jax_moglow as jm
from course_lib.models.moglow import FlowStep

ATOL = 1e-5


@pytest.fixture(autouse=True)
def _x64():
    with jax.enable_x64(True):
        yield


def _step(seed=0):
    """A step with every parameter perturbed (the zero-initialised output layer too)."""
    torch.manual_seed(seed)
    step = FlowStep(7, 5, 16).double()
    with torch.no_grad():
        for p in step.parameters():
            p.add_(0.3 * torch.randn_like(p))
    g = np.random.default_rng(seed)
    return step, g.normal(size=(11, 7)), g.normal(size=(11, 5)), g.normal(size=(11, 7))


def test_forward_inverse_log_det_values():
    step, x, h, _ = _step()
    y_t, ld_t = step(torch.from_numpy(x), torch.from_numpy(h))
    p = jm.torch_to_jax(step)
    y_j, ld_j = jm.forward(p, jnp.asarray(x), jnp.asarray(h))
    np.testing.assert_allclose(y_t.detach().numpy(), np.asarray(y_j), atol=ATOL, rtol=0)
    np.testing.assert_allclose(ld_t.detach().numpy(), np.asarray(ld_j), atol=ATOL, rtol=0)
    x_back = jm.inverse(p, y_j, jnp.asarray(h))
    np.testing.assert_allclose(np.asarray(x_back), x, atol=ATOL, rtol=0)
    x_t = step.inverse(torch.from_numpy(np.array(y_j)), torch.from_numpy(h))
    np.testing.assert_allclose(x_t.detach().numpy(), x, atol=ATOL, rtol=0)
    assert np.abs(np.asarray(y_j) - x).max() > 0.1 and np.abs(ld_t.detach().numpy()).min() > 1e-3


def test_gradients_of_inputs_and_parameters():
    step, x, h, w = _step(1)
    xt, ht = torch.tensor(x, requires_grad=True), torch.tensor(h, requires_grad=True)
    y, ld = step(xt, ht)
    loss_t = (y * torch.from_numpy(w)).sum() + ld.sum()
    loss_t.backward()

    def loss_j(p, x, h):
        y, ld = jm.forward(p, x, h)
        return jnp.sum(y * w) + jnp.sum(ld)

    p = jm.torch_to_jax(step)
    value, (gp, gx, gh) = jax.value_and_grad(loss_j, argnums=(0, 1, 2))(p, jnp.asarray(x), jnp.asarray(h))
    assert abs(float(value) - loss_t.item()) < ATOL
    np.testing.assert_allclose(np.asarray(gx), xt.grad.numpy(), atol=ATOL, rtol=0)
    np.testing.assert_allclose(np.asarray(gh), ht.grad.numpy(), atol=ATOL, rtol=0)
    torch_grads = {"bias": step.actnorm.bias, "log_scale": step.actnorm.log_scale, "log_s": step.linear.log_s,
                   "lower": step.linear.lower, "upper": step.linear.upper}
    for name, param in torch_grads.items():
        g_t = param.grad.numpy()
        if name == "lower":
            g_t = np.tril(g_t, -1)  # torch's masked entries get no gradient; JAX's tril drops them too
        if name == "upper":
            g_t = np.triu(g_t, 1)
        np.testing.assert_allclose(np.asarray(gp[name]), g_t, atol=ATOL, rtol=0, err_msg=name)
    lins = [m for m in step.coupling.net if hasattr(m, "weight")]
    for i, lin in enumerate(lins, 1):
        np.testing.assert_allclose(np.asarray(gp[f"W{i}"]).T, lin.weight.grad.numpy(), atol=ATOL, rtol=0)
        np.testing.assert_allclose(np.asarray(gp[f"b{i}"]), lin.bias.grad.numpy(), atol=ATOL, rtol=0)
    assert np.abs(np.asarray(gp["W3"])).max() > 1e-3


def test_torch_to_jax_refuses_a_recurrent_coupling():
    step = FlowStep(6, 2, 8, recurrent=True)
    with pytest.raises(ValueError, match="coupling is an LSTM"):
        jm.torch_to_jax(step)
