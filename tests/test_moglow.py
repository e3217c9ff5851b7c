"""MoGlow (Henter et al. 2019): invertibility, exact log-determinants, the likelihood, dropout, sampling."""

import math

import numpy as np
import pytest
import torch

from course_lib.models.moglow import (
    ActNorm,
    AffineCoupling,
    FlowStep,
    InvertibleLinear,
    MoGlow,
    MoGlowConfig,
)

torch.set_num_threads(1)
TINY = dict(steps=3, hidden=16, layers=1, coupling_hidden=16)


def tiny(seed=0, dtype=torch.float32, **kw) -> MoGlow:
    """A tiny model pulled away from its identity-like initialisation (zeroed output layers)."""
    torch.manual_seed(seed)
    model = MoGlow(MoGlowConfig(6, 3, 3, **{**TINY, **kw}))
    with torch.no_grad():
        for p in model.parameters():
            p.add_(0.2 * torch.randn_like(p))
    return model.to(dtype).eval()


def data(n=4, t=12, d=6, c=3, seed=1, dtype=torch.float32):
    g = torch.Generator().manual_seed(seed)
    return torch.randn(n, t, d, generator=g, dtype=dtype), torch.randn(n, t, c, generator=g, dtype=dtype)


VARIANTS = [dict(), dict(conditioner="markov", coupling_net="mlp"), dict(next_step="gaussian"), dict(layers=2),
            dict(coupling_net="mlp"), dict(coupling_net="lstm")]


@pytest.mark.parametrize("kw", VARIANTS)
def test_encode_shapes_and_decode_is_exact_inverse(kw):
    model = tiny(**kw)
    x, c = data()
    z, log_det = model.encode(x, c)
    assert z.shape == (4, 9, 6) and log_det.shape == (4,)
    back = model.decode(z, x[:, :3], c)
    assert back.shape == x.shape
    assert (back - x).abs().max().item() < 1e-4
    assert (z - x[:, 3:]).abs().max().item() > 0.1  # the flow is not the identity


@pytest.mark.parametrize("kw", VARIANTS)
def test_log_det_equals_brute_force_jacobian(kw):
    """log_det = log|det| of the autograd Jacobian of all latents w.r.t. all modelled poses (float64)."""
    model = tiny(dtype=torch.float64, **kw)
    x, c = data(n=1, t=8, dtype=torch.float64)

    def f(flat):
        poses = torch.cat((x[:, :3], flat.reshape(1, 5, 6)), 1)
        return model.encode(poses, c)[0].reshape(-1)

    J = torch.autograd.functional.jacobian(f, x[:, 3:].reshape(-1))  # (30, 30), block lower-triangular in time
    sign, logabs = torch.linalg.slogdet(J)
    assert sign != 0
    assert abs(logabs.item() - model.encode(x, c)[1].item()) < 1e-4
    assert abs(logabs.item()) > 0.1


def test_log_prob_is_change_of_variables():
    model = tiny(dtype=torch.float64)
    x, c = data(dtype=torch.float64)
    z, log_det = model.encode(x, c)
    expected = torch.distributions.Normal(0.0, 1.0).log_prob(z).sum((1, 2)) + log_det
    torch.testing.assert_close(model.log_prob(x, c), expected)


def test_gaussian_variant_is_a_diagonal_normal_of_the_conditioning():
    model = tiny(dtype=torch.float64, next_step="gaussian")
    x, c = data(dtype=torch.float64)
    h, _ = model.condition(model.condition_inputs(x, c))
    mu, log_sigma = model.flow[0].net(h).chunk(2, -1)
    expected = torch.distributions.Normal(mu, log_sigma.exp()).log_prob(x[:, 3:]).sum((1, 2))
    torch.testing.assert_close(model.log_prob(x, c), expected)


def test_pieces_invert_and_their_log_dets():
    torch.manual_seed(3)
    x, h = torch.randn(50, 7, dtype=torch.float64), torch.randn(50, 4, dtype=torch.float64)
    norm = ActNorm(7).double()
    y, ld = norm(x)  # training mode, first call: data-dependent initialisation
    assert bool(norm.initialized)
    assert y.mean(0).abs().max() < 1e-10 and (y.std(0) - 1).abs().max() < 1e-5
    torch.testing.assert_close(norm.inverse(y), x)
    assert torch.allclose(ld, norm.log_scale.sum().expand(50))
    lin = InvertibleLinear(7).double()
    W = lin.weight()
    torch.testing.assert_close(W @ W.T, torch.eye(7, dtype=torch.float64))  # initialised as a rotation
    with torch.no_grad():
        lin.log_s.add_(0.3)
        lin.upper.add_(0.1)
    y, ld = lin(x)
    torch.testing.assert_close(ld[0], torch.linalg.slogdet(lin.weight())[1])
    torch.testing.assert_close(lin.inverse(y), x)
    coupling = AffineCoupling(7, 4, 8).double()
    y, ld = coupling(x, h)
    assert torch.allclose(y[:, :3], x[:, :3])  # x_a passes through
    torch.testing.assert_close(ld, torch.full((50,), 4 * math.log(1 / (1 + math.exp(-2.0))),
                                              dtype=torch.float64))  # zero-initialised NN: sigma = sigmoid(2)
    torch.testing.assert_close(coupling.inverse(y, h), x)


def test_coupling_scale_is_bounded():
    """sigma = sigmoid(raw + 2) stays in (0, 1) however large the NN's output: no exploding scales."""
    coupling = AffineCoupling(4, 2, 8).double()
    with torch.no_grad():
        coupling.net[-1].bias.fill_(1e3)
    log_sigma, _ = coupling.scale_and_shift(torch.zeros(1, 2, dtype=torch.float64), torch.zeros(1, 2,
                                                                                                 dtype=torch.float64))
    assert torch.isfinite(log_sigma).all() and (log_sigma <= 0).all()


def test_actnorm_initialises_once_from_the_first_batch_only():
    model = MoGlow(MoGlowConfig(6, 3, 3, **TINY))
    x, c = data(n=16, t=20)
    model.train()
    model.loss({"poses": 3 * x + 5, "controls": c})
    z = model.flow[0].actnorm.bias.clone()
    assert all(bool(s.actnorm.initialized) for s in model.flow)
    torch.testing.assert_close(z, -(3 * x[:, 3:] + 5).reshape(-1, 6).mean(0))
    model.loss({"poses": x, "controls": c})
    torch.testing.assert_close(model.flow[0].actnorm.bias, z)
    state = model.state_dict()
    assert "flow.0.actnorm.initialized" in state  # a loaded checkpoint does not re-initialise


def test_history_dropout_rate_and_controls_untouched():
    model = MoGlow(MoGlowConfig(6, 3, 3, **TINY))
    x, c = data(n=64, t=40)
    inp = model.condition_inputs(x + 10.0, c, dropout=0.95, generator=torch.Generator().manual_seed(0))
    hist = inp[..., :18].reshape(64, 37, 3, 6)
    kept = (hist != 0).all(-1).float().mean().item()
    assert abs(kept - 0.05) < 0.01  # whole frames dropped with probability 0.95
    assert ((hist == 0).all(-1) | (hist != 0).all(-1)).all()  # a frame is dropped whole or not at all
    full = model.condition_inputs(x + 10.0, c)
    torch.testing.assert_close(inp[..., 18:], full[..., 18:])  # controls never dropped
    # outside training frame tau sees x_{0:tau-1} times the keep probability (dropout's inference rule) ...
    torch.testing.assert_close(full[0, 0, :18].reshape(3, 6), 0.05 * (x[0, :3] + 10.0))
    torch.testing.assert_close(full[0, 0, 18:].reshape(4, 3), c[0, :4])  # and c_{0:tau}
    # ... which is the mean of the training-time masked input
    torch.testing.assert_close(inp[..., :18].mean((0, 1)), full[..., :18].mean((0, 1)), atol=0.15, rtol=0.1)
    raw = MoGlow(MoGlowConfig(6, 3, 3, **TINY, history_scale=False)).condition_inputs(x + 10.0, c)
    torch.testing.assert_close(raw[0, 0, :18].reshape(3, 6), x[0, :3] + 10.0)  # StyleGestures' rule: unscaled
    nodrop = MoGlow(MoGlowConfig(6, 3, 3, **TINY, dropout=0.0)).condition_inputs(x + 10.0, c)
    torch.testing.assert_close(nodrop[0, 0, :18].reshape(3, 6), x[0, :3] + 10.0)  # no dropout: nothing to scale


def test_stream_scales_the_history_as_condition_inputs():
    """The streaming generator must condition exactly as encode does, or decode(encode(x)) != x."""
    model = tiny(dropout=0.5).eval()  # a history scale far from 1
    x, c = data()
    z, _ = model.encode(x, c)
    torch.testing.assert_close(model.decode(z, x[:, :3], c), x, atol=1e-4, rtol=0)
    model.config.history_scale = False
    assert (model.decode(z, x[:, :3], c) - x).abs().max() > 1e-3  # the other rule is a different model


def test_loss_nats_per_frame_and_dropout_only_in_training():
    model = tiny()
    x, c = data()
    model.eval()
    out = model.loss({"poses": x, "controls": c})
    torch.testing.assert_close(out["loss"], -model.log_prob(x, c).sum() / (4 * 9))
    model.train()
    a = model.loss({"poses": x, "controls": c})["loss"]
    assert abs(a.item() - out["loss"].item()) > 1e-3  # history dropped


@pytest.mark.parametrize("kw", [dict(coupling_net="mlp"), dict(coupling_net="lstm")])
def test_streaming_equals_batched_sampling(kw):
    model = tiny(**kw)
    x, c = data(t=15)
    g = torch.Generator().manual_seed(5)
    batched = model.sample(c, x[:, :3], temperature=0.7, generator=g)
    assert batched.shape == (4, 15, 6)
    torch.testing.assert_close(batched[:, :3], x[:, :3])
    z = 0.7 * torch.randn(4, 12, 6, generator=torch.Generator().manual_seed(5))
    stream = model.stream(x[:, :3], c[:, :3])
    frames = torch.stack([stream.step(c[:, 3 + t], z=z[:, t]) for t in range(12)], 1)
    torch.testing.assert_close(frames, batched[:, 3:])
    zero = model.sample(c, x[:, :3], temperature=0.0)
    torch.testing.assert_close(model.encode(zero, c)[0], torch.zeros(4, 12, 6), atol=1e-4, rtol=0)


@pytest.mark.parametrize("kw", [dict(), dict(conditioner="markov", coupling_net="mlp"), dict(coupling_net="lstm")])
def test_sample_history_fn_changes_only_what_is_fed_back(kw):
    """history_fn = 0: frame t conditions on the given poses, then zeros; computed in parallel by hand."""
    model = tiny(dropout=0.5, **kw)
    x, c = data(t=10)
    out = model.sample(c, x[:, :3], generator=torch.Generator().manual_seed(5), history_fn=torch.zeros_like)
    hist = torch.cat((x[:, :3], torch.zeros(4, 7, 6)), 1)  # what the frames after tau were conditioned on
    h, _ = model.condition(model.condition_inputs(hist, c))
    z = torch.randn(4, 7, 6, generator=torch.Generator().manual_seed(5))
    expected = model.flow_inverse(z, h)
    torch.testing.assert_close(out[:, 3:], expected, atol=1e-5, rtol=0)  # the returned poses are not zeroed
    assert expected.abs().min() > 0
    plain = model.sample(c, x[:, :3], generator=torch.Generator().manual_seed(5))
    assert (plain[:, 4:] - expected[:, 1:]).abs().max() > 1e-2  # the hook did change the history


def test_temperature_scales_the_spread():
    model = tiny()
    x, c = data(n=64, t=8)
    x0 = x[:1, :3].expand(64, 3, 6).contiguous()
    c0 = c[:1].expand(64, 8, 3).contiguous()
    spreads = [model.sample(c0, x0, temperature=t, generator=torch.Generator().manual_seed(0))[:, 3].std(0).mean()
               for t in (0.0, 0.5, 1.0)]
    assert spreads[0] < 1e-6 < spreads[1] < spreads[2]


def test_a_few_steps_of_training_lower_the_nll():
    from course_lib.training import fit

    torch.manual_seed(0)
    model = MoGlow(MoGlowConfig(6, 3, 3, **TINY, dropout=0.0))
    t = torch.linspace(0, 6, 16)
    x = torch.stack([torch.sin(t[:, None] * (1 + torch.arange(6)) + p) for p in torch.rand(32) * 6]) + 0.05 * \
        torch.randn(32, 16, 6)
    c = torch.randn(32, 16, 3)
    batch = {"poses": x, "controls": c}
    hist = fit(model, lambda: batch, steps=60, lr=3e-3, progress=False)
    assert hist.step["loss"][-1] < hist.step["loss"][0] - 1.0


def test_clear_errors():
    model = tiny()
    x, c = data()
    with pytest.raises(ValueError, match="poses must be"):
        model.encode(x[..., :5], c)
    with pytest.raises(ValueError, match="controls must be"):
        model.encode(x, c[..., :2])
    with pytest.raises(ValueError, match="at least 4 frames"):
        model.encode(x[:, :3], c[:, :3])
    with pytest.raises(ValueError, match="must agree"):
        model.decode(torch.zeros(4, 9, 6), x[:, :3], c[:, :10])
    with pytest.raises(ValueError, match="temperature"):
        model.sample(c, x[:, :3], temperature=-1)
    with pytest.raises(ValueError, match="conditioner"):
        MoGlowConfig(6, 3, 3, conditioner="gru")
    with pytest.raises(ValueError, match="dropout"):
        MoGlowConfig(6, 3, 3, dropout=1.0)
    with pytest.raises(ValueError, match="coupling_net must be"):
        MoGlowConfig(6, 3, 3, coupling_net="gru")
    with pytest.raises(ValueError, match="Markov model .* no memory"):
        MoGlowConfig(6, 3, 3, conditioner="markov", coupling_net="lstm")
    with pytest.raises(ValueError, match="control must be"):
        model.stream(x[:, :3], c[:, :3]).step(c[:2, 3])


def test_recurrent_coupling_remembers_poses_the_history_dropout_hides():
    """With every history frame dropped (history_fn = 0 and no history scale), an MLP-coupling model's frame t
    cannot depend on the poses it generated before; the recurrent couplings' memory carries them (the authors'
    design).  Generated frame by frame, the memory gives what the whole sequence gives at once."""
    x, c = data(t=10)
    z = torch.randn(4, 7, 6, generator=torch.Generator().manual_seed(3))
    for kind, depends in (("mlp", False), ("lstm", True)):
        model = tiny(coupling_net=kind, dropout=0.0)
        zeros = torch.zeros(4, 7, 6)
        h, _ = model.condition(model.condition_inputs(torch.cat((x[:, :3], zeros), 1), c))
        a = model.flow_inverse(z, h)
        z2 = z.clone()
        z2[:, 0] += 1.0  # another first frame; the conditioning h is the same (history zeroed)
        b = model.flow_inverse(z2, h)
        assert ((b[:, 1:] - a[:, 1:]).abs().max() > 1e-3) == depends, kind
        memory = model.new_memory()
        frames = torch.cat([model.flow_inverse(z[:, t:t + 1], h[:, t:t + 1], memory=memory) for t in range(7)], 1)
        torch.testing.assert_close(frames, a)


def test_cpu_preset_and_step_api():
    cfg = MoGlowConfig.cpu(61, 3)
    assert (cfg.steps, cfg.hidden, cfg.layers, cfg.tau, cfg.dropout) == (8, 128, 1, 10, 0.95)
    assert cfg.condition_dim == 10 * 61 + 11 * 3
    step = FlowStep(5, 2, 8).double()
    x, h = torch.randn(3, 5, dtype=torch.float64), torch.randn(3, 2, dtype=torch.float64)
    y, ld = step(x, h)
    np.testing.assert_allclose(step.inverse(y, h).detach().numpy(), x.numpy(), atol=1e-12)


def test_lesson_solutions_pass_and_wrong_answers_fail():
    from course_lib.solutions import moglow as S

    S.check_actnorm_init(S.actnorm_init)
    S.check_coupling_inverse(S.coupling_inverse)
    S.check_log_prob(S.log_prob)
    with pytest.raises(AssertionError, match="log-scale"):
        S.check_actnorm_init(lambda x: (-x.mean(0), 1 / x.std(0)))
    with pytest.raises(AssertionError, match="invert"):
        S.check_coupling_inverse(lambda y, ls, t: y * torch.exp(-ls) + t)
    with pytest.raises(AssertionError, match="nats"):
        S.check_log_prob(lambda m, p, c: S.log_prob(m, p, c) - 0.5)


def test_nats_offset_known_answers_and_wrong_answers_fail():
    """Exercise 4: NLL in metres = NLL standardised + sum log std over the modelled pose values."""
    from course_lib.solutions import moglow as S

    fixed = np.zeros(63, bool)
    fixed[[0, 2]] = True
    std = np.full(66, 0.1)
    assert S.nats_offset(std, fixed) == pytest.approx(61 * np.log(0.1))  # 61 values of 10 cm spread: -140.5 nats
    # the exact density gap, by the library's own Gaussian, equals the log-det of the standardisation
    mean = np.linspace(-1, 1, 66)
    jac = torch.autograd.functional.jacobian(lambda v: v * torch.as_tensor(std[:63][~fixed]),
                                             torch.zeros(61, dtype=torch.float64))
    assert S._metric_nll_gap(std, fixed, mean) == pytest.approx(float(torch.linalg.slogdet(jac)[1]))
    S.check_nats_offset(S.nats_offset)
    for wrong, why in ((lambda s, f: -S.nats_offset(s, f), "sign"),  # divided instead of multiplied
                       (lambda s, f: float(np.log(s[:63]).sum()), "modelled"),  # the fixed values too
                       (lambda s, f: float(np.log(s[~np.r_[f, np.zeros(3, bool)]]).sum()), "modelled"),  # + controls
                       (lambda s, f: 0.0, "modelled")):
        with pytest.raises(AssertionError, match=why):
            S.check_nats_offset(wrong)
