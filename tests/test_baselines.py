"""ERD, LSTM-3LR and conditional RBM baselines: shapes, control clamping, CD maths, learning."""

import pytest
import torch

from course_lib.models.baselines import CRbm, CRbmConfig, Erd, ErdConfig, Lstm3lr, Lstm3lrConfig, rollout

SMALL = {"erd": lambda: Erd(ErdConfig.cpu(encoder=16, lstm=16, decoder=16)),
         "lstm3lr": lambda: Lstm3lr(Lstm3lrConfig.cpu(lstm=16)),
         "crbm": lambda: CRbm(CRbmConfig.cpu(hidden=16, gibbs_steps=3))}


@pytest.mark.parametrize("name", sorted(SMALL))
def test_predict_shapes_and_control_clamp(name):
    torch.manual_seed(0)
    m = SMALL[name]().eval()
    x = torch.randn(3, 40, 66)
    free = m.predict(x[:, :10], 30)
    assert free.shape == (3, 40, 66)
    torch.testing.assert_close(free[:, :10], x[:, :10])  # initial frames kept
    clamped = m.predict(x[:, :4], 36, control=x[..., 63:])
    torch.testing.assert_close(clamped[:, 4:, 63:], x[:, 4:, 63:])  # Table 2: ground-truth control
    assert (clamped[:, 4:, :63] - x[:, 4:, :63]).abs().max() > 0


def test_paper_sizes():
    erd = Erd(ErdConfig())
    assert erd.lstm.hidden_size == 1000 and erd.lstm.num_layers == 2
    assert Lstm3lr(Lstm3lrConfig()).lstm.num_layers == 3
    assert CRbm(CRbmConfig()).W.shape == (66, 150)


def test_rollout_feeds_back_predictions():
    """A step that adds 1 to every feature: the rollout counts up from the last initial frame."""
    x0 = torch.zeros(2, 3, 5)
    out = rollout(lambda f, s: (f + 1, s), x0, 4, None, 2)
    torch.testing.assert_close(out[:, 3:, 0], torch.arange(1.0, 5.0).expand(2, 4))
    ctrl = torch.full((2, 7, 2), 9.0)
    out = rollout(lambda f, s: (f + 1, s), x0, 4, ctrl, 2)
    torch.testing.assert_close(out[:, 3:, -2:], ctrl[:, 3:])
    torch.testing.assert_close(out[:, 3:, 0], torch.arange(1.0, 5.0).expand(2, 4))
    with pytest.raises(ValueError, match="control"):
        rollout(lambda f, s: (f, s), x0, 4, torch.zeros(2, 6, 2), 2)


def test_crbm_free_energy_and_cd_gradient():
    """F(v) = |v-a|^2/2 - sum softplus(b + W^T v) is -log sum_h exp(-E(v,h)) (brute force over h);
    the gradient of F(v_data) - F(v_k) w.r.t. W is -(<v p(h|v)>_data - <v p(h|v)>_k) (the CD update)."""
    torch.manual_seed(1)
    m = CRbm(CRbmConfig(dim=3, control_dim=1, hidden=3, order=2))
    v, a, b = torch.randn(1, 3), torch.randn(1, 3), torch.randn(1, 3)
    hs = torch.tensor([[i >> k & 1 for k in range(3)] for i in range(8)], dtype=torch.float32)  # all h
    energy = 0.5 * ((v - a) ** 2).sum() - hs @ b[0] - (v @ m.W @ hs.T)[0]  # E(v, h) for every h
    torch.testing.assert_close(m.free_energy(v, a, b)[0], -torch.logsumexp(-energy, 0))
    v_k = torch.randn(1, 3)
    (m.free_energy(v, a, b) - m.free_energy(v_k, a, b)).sum().backward()
    pos = v.T @ torch.sigmoid(b + v @ m.W)
    neg = v_k.T @ torch.sigmoid(b + v_k @ m.W)
    torch.testing.assert_close(m.W.grad, -(pos - neg).detach())


def test_crbm_pairs_past_newest_first():
    m = CRbm(CRbmConfig(dim=2, control_dim=1, hidden=2, order=2))
    x = torch.arange(10.0).reshape(1, 5, 2)  # frame t = (2t, 2t + 1)
    v, past = m._pairs(x)
    torch.testing.assert_close(v[0], x[0, 2])
    torch.testing.assert_close(past[0], torch.cat((x[0, 1], x[0, 0])))


@pytest.mark.parametrize("name", ["erd", "lstm3lr", "crbm"])
def test_learns_a_smooth_signal(name):
    """A few steps on sinusoids lower the next-frame error (ERD/LSTM) or the CD reconstruction (cRBM)."""
    torch.manual_seed(2)
    t = torch.linspace(0, 6.28, 48)
    x = torch.stack([torch.sin(t[:, None] * (1 + torch.arange(66) / 66) + p) for p in torch.rand(8) * 6], 0)
    m = SMALL[name]()
    opt = torch.optim.Adam(m.parameters(), 1e-2)
    key = "recon" if name == "crbm" else "loss"
    first = float(m.loss(x)[key].detach())
    for _ in range(40):
        out = m.loss(x)
        opt.zero_grad()
        out["loss"].backward()
        opt.step()
    assert float(out[key].detach()) < 0.7 * first


def test_bad_inputs():
    with pytest.raises(ValueError, match="66"):
        SMALL["erd"]().loss(torch.randn(2, 10, 60))
    with pytest.raises(ValueError, match="order"):
        SMALL["crbm"]().predict(torch.randn(2, 3, 66), 5)
    with pytest.raises(ValueError, match="NaN"):
        SMALL["lstm3lr"]().predict(torch.full((1, 4, 66), float("nan")), 2)
