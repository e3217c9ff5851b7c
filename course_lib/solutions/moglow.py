"""Reference answers and self-checks for the exercises of notebooks/06_moglow.ipynb.

Students write their own version in the notebook; each ``check_*`` runs it on fixed inputs and
compares it with the library (course_lib.models.moglow), raising an AssertionError that says what
is wrong.
"""

from __future__ import annotations

import math

import numpy as np
import torch

from course_lib.models.moglow import ActNorm, AffineCoupling, MoGlow, MoGlowConfig

__all__ = ["actnorm_init", "check_actnorm_init", "check_coupling_inverse", "check_log_prob", "check_nats_offset",
           "check_stepping_prediction", "coupling_inverse", "log_prob", "nats_offset", "stepping_at_zero_temperature"]


# ----------------------------------------------------------------------------- reference answers


def actnorm_init(x: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """x (N, D) first batch -> (b, s) with exp(s) (x + b) of zero mean and unit std per feature."""
    return -x.mean(0), -torch.log(x.std(0) + 1e-6)


def coupling_inverse(y_b: torch.Tensor, log_sigma: torch.Tensor, t: torch.Tensor) -> torch.Tensor:
    """Invert y_b = sigma (x_b + t)  -- eq. (6): x_b = y_b / sigma - t."""
    return y_b * torch.exp(-log_sigma) - t


def log_prob(model: MoGlow, poses: torch.Tensor, controls: torch.Tensor) -> torch.Tensor:
    """log p = sum_t log N(z_t; 0, I) + log|det dz/dx|  -- eq. (5), from model.encode."""
    z, log_det = model.encode(poses, controls)
    return (-0.5 * z ** 2 - 0.5 * math.log(2 * math.pi)).sum((1, 2)) + log_det


def nats_offset(std: np.ndarray, fixed: np.ndarray) -> float:
    """std (66,) of the positions_control standardisation, fixed (63,) bool -> sum_d log std_d over the modelled
    pose values: x = std * x~ + mean, so -log p(x) = -log p~(x~) + sum_d log std_d (change of variables, eq. 5)."""
    return float(np.log(np.asarray(std, float)[:63][~np.asarray(fixed, bool)]).sum())


# ----------------------------------------------------------------------------- checks


def _data(seed: int = 0, n: int = 64, d: int = 6):
    g = torch.Generator().manual_seed(seed)
    return 3.0 * torch.randn(n, d, generator=g, dtype=torch.float64) + 5.0


def check_actnorm_init(fn) -> None:
    """fn(x (N, D)) -> (b, s): compared with ActNorm's data-dependent initialisation."""
    x = _data()
    norm = ActNorm(6).double()
    norm(x)  # the first batch initialises it
    b, s = fn(x)
    assert tuple(b.shape) == (6,) and tuple(s.shape) == (6,), f"expected b, s of shape (6,), got {b.shape}, {s.shape}"
    assert torch.allclose(b, norm.bias, atol=1e-6), "b should be minus the per-feature mean of x"
    assert torch.allclose(s, norm.log_scale, atol=1e-4), ("s is a log-scale: exp(s) = 1 / std, so s = -log std "
                                                          "(did you return the scale instead of its log?)")


def check_coupling_inverse(fn) -> None:
    """fn(y_b, log_sigma, t) -> x_b: must undo AffineCoupling's forward pass."""
    torch.manual_seed(0)
    coupling = AffineCoupling(6, 2, 8).double()
    with torch.no_grad():
        for p in coupling.parameters():
            p.add_(0.3 * torch.randn_like(p))
    x, h = _data(1, 16), torch.randn(16, 2, dtype=torch.float64)
    y, _ = coupling(x, h)
    log_sigma, t = coupling.scale_and_shift(y[:, :3], h)  # the NN sees y_a = x_a
    x_b = fn(y[:, 3:], log_sigma, t)
    err = (x_b - x[:, 3:]).abs().max().item()
    assert err < 1e-8, f"x_b differs from the input by up to {err:.3g}: invert y_b = sigma * (x_b + t) step by step"


def check_log_prob(fn) -> None:
    """fn(model, poses, controls) -> (N,) log-likelihoods: compared with MoGlow.log_prob."""
    torch.manual_seed(0)
    model = MoGlow(MoGlowConfig(6, 3, 3, steps=2, hidden=8, layers=1, coupling_hidden=8)).double().eval()
    g = torch.Generator().manual_seed(2)
    poses = torch.randn(3, 9, 6, generator=g, dtype=torch.float64)
    controls = torch.randn(3, 9, 3, generator=g, dtype=torch.float64)
    got, want = fn(model, poses, controls), model.log_prob(poses, controls)
    assert tuple(got.shape) == (3,), f"expected one log-likelihood per sequence, shape (3,), got {tuple(got.shape)}"
    diff = (got - want).abs().max().item()
    assert diff < 1e-8, (f"off by up to {diff:.3g} nats: sum the standard-normal log-density of every z value "
                         "(with its -0.5 log 2 pi) over frames and features, then add log_det")


def _metric_nll_gap(std: np.ndarray, fixed: np.ndarray, mean: np.ndarray, seed: int = 3) -> float:
    """-log N(x; mean, diag std^2) - (-log N(x~; 0, I)) on random poses, the modelled values only: the exact gap."""
    keep = ~np.asarray(fixed, bool)
    sd = torch.as_tensor(np.asarray(std, float)[:63][keep])
    mu = torch.as_tensor(np.asarray(mean, float)[:63][keep])
    x_std = torch.randn(5, len(sd), generator=torch.Generator().manual_seed(seed), dtype=torch.float64)
    x = x_std * sd + mu  # metres
    metres = -torch.distributions.Normal(mu, sd).log_prob(x).sum(-1)
    standard = -torch.distributions.Normal(0.0, 1.0).log_prob(x_std).sum(-1)
    gap = metres - standard
    assert float(gap.std()) < 1e-8, "the gap should not depend on the pose"  # a constant: the log-det
    return float(gap.mean())


def check_nats_offset(fn, data=None) -> None:
    """fn(std (66,), fixed (63,)) -> the constant c with NLL per frame in metres = NLL per standardised frame + c.

    Checked on planted statistics (every modelled std e: c = number of modelled values) and, given `data`
    (a MoGlowData), on its own standardisation, against the exact gap between the two Gaussian densities."""
    rng = np.random.default_rng(0)
    fixed = np.zeros(63, bool)
    fixed[[0, 2]] = True
    planted = np.full(66, math.e)
    planted[[0, 2]] = 1e-6  # fixed values: (clamped) zero spread, not modelled
    planted[63:] = 50.0  # the controls: an input, not modelled
    got = float(fn(planted, fixed))
    sign = ": the sign? x = std x~ + mean stretches space by std, which lowers the density"
    assert abs(got + 61.0) > 1e-9, f"got -61 nats for 61 modelled values of std e, want +61{sign}"
    assert abs(got - 61.0) < 1e-9, (f"got {got:.4g} nats for 61 modelled values of std e (want 61): sum log std over "
                                    "the modelled pose values only (not the fixed ones, not the 3 controls)")
    cases = [(np.exp(rng.normal(-2.0, 0.5, 66)), fixed, rng.normal(0, 1, 66))]
    if data is not None:
        cases.append((data.stats[1], data.fixed, data.stats[0]))
    for std, fx, mean in cases:
        got, want = float(fn(std, fx)), _metric_nll_gap(std, fx, mean)
        assert abs(got - want) < 1e-6 * max(1.0, abs(want)), (
            f"got {got:.4f}, want {want:.4f} nats" + (sign if abs(got + want) < 1e-6 * abs(want) else ""))


def stepping_at_zero_temperature(n: int = 8, frames: int = 100, seed: int = 1) -> dict:
    """The pretrained dropout and no-dropout models under zero control at temperature 0 (z_t = 0), from n
    held-out starts of the CI data -> {"dropout": m/s, "no dropout": m/s}: the feet speed in the root frame over
    `STEP_LAG` frames (the measure of lesson 06, section 6)."""
    from course_lib.experiments import moglow as E

    data = E.load_data("ci")
    out = {}
    for label, name in (("dropout", "moglow"), ("no dropout", "moglow_nodrop")):
        poses, ctl = E.generate(E.load_model(name), data, E.constant_control(data, n, E.TAU + frames), seed=seed,
                                temperature=0.0)
        out[label] = E.foot_speed(E.local_positions(data, poses[:, E.TAU:], ctl[:, E.TAU:]), E.STEP_LAG)
    return out


def check_stepping_prediction(fn, threshold: float = 0.1) -> None:
    """fn() -> {"dropout": bool, "no dropout": bool}, a prediction of whether each model's feet speed at T = 0
    (lag STEP_LAG) is under ``threshold`` m/s, compared with a run of both models."""
    guess = fn()
    assert isinstance(guess, dict) and set(guess) == {"dropout", "no dropout"}, \
        'return a dict {"dropout": True or False, "no dropout": True or False}'
    for label, g in guess.items():
        assert isinstance(g, bool), f'make a prediction for "{label}": True (under {threshold} m/s) or False'
    speeds = stepping_at_zero_temperature()
    for label, g in guess.items():
        still = speeds[label] < threshold
        assert g == still, (f'"{label}": you predicted {"under" if g else "over"} {threshold} m/s, the run gives '
                            f"{speeds[label]:.3f} m/s at temperature 0 -- "
                            + ("with no sampling noise, what is left of its feet's motion is real stepping"
                               if not still else "with no sampling noise, nothing is left to move its feet"))
