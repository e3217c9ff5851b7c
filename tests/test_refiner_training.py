"""The adversarial training loop of the refiner (Wang, Chai et al. 2021, sec. 4.2.2) on tiny synthetic data:
real = smooth sinusoidal joint angles, "RNN" = the same plus white jitter; record shapes, the adaptive r, learning."""

import numpy as np
import pytest
import torch

from course_lib.models.refiner import AdversarialSchedule, Discriminator, Refiner, RefinerConfig, train_refiner

T, D, N = 16, 68, 16


def sampler(seed: int, jitter: float):
    """-> callable() -> (N, T, 68) features: walk forward, joint angles 0.3 sin(2 pi t + phase), contacts, + jitter."""
    rng = np.random.default_rng(seed)

    def sample() -> torch.Tensor:
        t = np.arange(T)[None, :, None] / 30.0
        phase = rng.uniform(0, 2 * np.pi, (N, 1, 60))
        x = np.zeros((N, T, D))
        x[..., 1], x[..., 3] = 0.04, 0.95  # dz per frame, root height
        x[..., 6:66] = 0.3 * np.sin(2 * np.pi * t + phase) + jitter * rng.standard_normal((N, T, 60))
        x[..., 66] = np.sin(2 * np.pi * t[..., 0] + phase[..., 0, :1]) > 0
        x[..., 67] = 1 - x[..., 66]
        return torch.tensor(x, dtype=torch.float32)

    return sample


def config(**kw) -> RefinerConfig:
    return RefinerConfig.cpu(**{"fc_width": 32, "lstm_width": 32, "d_fc_width": 16, "d_lstm_width": 16,
                                "warmup": 30, "buffer_size": 32, "d_batch": 16, **kw})


def jitter(x: torch.Tensor) -> float:
    """x: (N, T, 68) -> mean squared second difference of the joint angles."""
    a = x[:, :, 6:66]
    return float((a[:, 2:] - 2 * a[:, 1:-1] + a[:, :-2]).pow(2).mean())


def run(seed: int, iterations: int, **kw):
    torch.manual_seed(seed)
    cfg = config(**kw)
    R, Dn = Refiner(cfg), Discriminator(cfg)
    history = train_refiner(R, Dn, sampler(100 + seed, 0.1), sampler(200 + seed, 0.0), iterations=iterations,
                            seed=seed, progress=False)
    return R, Dn, history


def test_record_lengths_and_adaptive_r_follow_the_schedule_rules():
    R, _, h = run(0, 12, warmup=4)
    assert len(h.warmup.step["loss"]) == 4 and len(h.warmup.step["d_loss"]) == 4
    for key in ("loss", "adversarial", "root", "d_loss", "d_acc_real", "d_acc_fake", "r_updates"):
        assert len(h.step[key]) == 12, key
        assert np.isfinite(h.step[key]).all(), key
    assert all(0 <= a <= 1 for a in h.step["d_acc_real"] + h.step["d_acc_fake"])
    r, d = h.step["r_updates"], h.step["d_loss"]
    assert r[0] == 5
    for i in range(len(r) - 1):  # sec. 4.2.2: double when D's loss < 0.01, halve (>= 1) when > 1
        expect = min(2 * r[i], 640) if d[i] < 0.01 else max(r[i] // 2, 1) if d[i] > 1 else r[i]
        assert r[i + 1] == expect, (i, r[i], d[i], r[i + 1])
    assert all(torch.isfinite(p).all() for p in R.parameters())


def test_no_warmup_and_custom_schedule():
    schedule = AdversarialSchedule(warmup=0, r_per_d=2)
    cfg = config(warmup=0)
    R, Dn = Refiner(cfg), Discriminator(cfg)
    h = train_refiner(R, Dn, sampler(1, 0.1), sampler(2, 0.0), iterations=3, schedule=schedule, progress=False)
    assert h.warmup.num_steps == 0 and h.step["r_updates"][0] == 2 and schedule.history[0] == 2


# seeds 0, 1, 2 checked: jitter ratio 0.931, 0.935, 0.944; D loss 0.029 -> 0.33, 0.036 -> 0.68, 0.029 -> 0.36
@pytest.mark.parametrize("seed", [0])
def test_refiner_learns_to_remove_jitter_and_fools_the_discriminator(seed):
    torch.manual_seed(seed)
    probe = sampler(300, 0.1)()
    R, _, h = run(seed, 40)
    torch.manual_seed(seed)
    R0 = Refiner(config())  # the same initial weights (near identity) as the trained R had
    with torch.no_grad():
        before, after = jitter(R0(probe)), jitter(R(probe))
    assert after < 0.97 * before, (before, after)  # the refined motion is smoother than the RNN's
    d_after_warmup = np.mean(h.warmup.step["d_loss"][-5:])
    assert d_after_warmup < 0.1  # D has learnt real vs. jittery in the warm-up ...
    assert np.mean(h.step["d_loss"]) > 3 * d_after_warmup  # ... and R's updates make its job harder


def test_bad_sampler_output_is_named():
    cfg = config(warmup=1)
    R, Dn = Refiner(cfg), Discriminator(cfg)
    with pytest.raises(ValueError, match="sample_real_batch"):
        train_refiner(R, Dn, sampler(1, 0.1), lambda: torch.zeros(4, T, 10), iterations=1, progress=False)
    with pytest.raises(ValueError, match="iterations"):
        train_refiner(R, Dn, sampler(1, 0.1), sampler(2, 0.0), iterations=-1, progress=False)


def test_refiner_update_budget_stops_the_rounds():
    """max_refiner_updates: training stops after the round in which R's adversarial updates reach the budget."""
    cfg = config(warmup=2)
    R, Dn = Refiner(cfg), Discriminator(cfg)
    h = train_refiner(R, Dn, sampler(1, 0.1), sampler(2, 0.0), iterations=50, progress=False, max_refiner_updates=12,
                      schedule=AdversarialSchedule(warmup=2, r_per_d=5, max_r_updates=5))
    assert h.step["r_updates"] == [5, 5, 5]  # 15 >= 12 after the third round (r stays 5: capped, never halved)
