"""Reference answers and self-checks for the exercises of notebooks/03_gmm_rnn_refiner.ipynb.

Students write their own version in the notebook; each ``check_*`` runs it on fixed inputs and compares it with
the library (course_lib.models.gmm_rnn, course_lib.models.refiner), raising an AssertionError that says what is
wrong.
"""

from __future__ import annotations

import math

import numpy as np
import torch

from course_lib.models.gmm_rnn import mixture_log_prob
from course_lib.models.refiner import HistoryBuffer, discriminator_loss, root_trajectory

__all__ = ["check_discriminator_loss", "check_fraction_left", "check_mixture_nll", "check_root_path",
           "discriminator_loss_by_hand", "fraction_left", "mixture_nll", "root_path"]


# ----------------------------------------------------------------------------- reference answers


def mixture_nll(x: torch.Tensor, logits: torch.Tensor, mu: torch.Tensor, log_sigma: torch.Tensor) -> torch.Tensor:
    """E = -log sum_i w_i prod_j N(x_j; mu_ij, sigma_ij^2), w = softmax(logits)  -- eq. (8), for one frame."""
    w = torch.exp(logits) / torch.exp(logits).sum()
    sigma = torch.exp(log_sigma)
    n_i = (torch.exp(-((x - mu) ** 2) / (2 * sigma ** 2)) / (math.sqrt(2 * math.pi) * sigma)).prod(-1)
    return -torch.log((w * n_i).sum())


def fraction_left(capacity: int, replaced: int, updates: int) -> float:
    """Expected fraction of a HistoryBuffer's initial entries left after `updates` replacements of `replaced`
    distinct random entries each: every update keeps a given entry with probability 1 - replaced / capacity."""
    return (1.0 - replaced / capacity) ** updates


def root_path(dz: float, dyaw: float, frames: int) -> np.ndarray:
    """Eq. (4) by hand for a root stepping dz forward and turning dyaw every frame from the origin facing +Z ->
    (frames + 1, 2) floor positions (x, z): p_t = p_{t-1} + R_y(yaw_{t-1}) (0, dz), yaw_t = yaw_{t-1} + dyaw."""
    yaw, pos, out = 0.0, np.zeros(2), [np.zeros(2)]
    for _ in range(frames):
        pos = pos + dz * np.array([np.sin(yaw), np.cos(yaw)])
        yaw += dyaw
        out.append(pos)
    return np.array(out)


def discriminator_loss_by_hand(real_logits: torch.Tensor, fake_logits: torch.Tensor) -> torch.Tensor:
    """(-mean log(1 - D(R(x))) - mean log D(x_real)) / 2 with D = sigmoid(logit)  -- eq. (10) halved."""
    d_real, d_fake = torch.sigmoid(real_logits), torch.sigmoid(fake_logits)
    return 0.5 * (-torch.log(1 - d_fake).mean() - torch.log(d_real).mean())


# ----------------------------------------------------------------------------- checks


def _frame(seed: int):
    g = torch.Generator().manual_seed(seed)
    draw = lambda *shape: torch.randn(*shape, generator=g, dtype=torch.float64)  # noqa: E731
    return draw(3), draw(2), draw(2, 3), 0.3 * draw(2, 3)


def check_mixture_nll(fn) -> None:
    """fn(x (D,), logits (M,), mu (M, D), log_sigma (M, D)) -> E, compared with -mixture_log_prob on 3 frames."""
    for seed in range(3):
        x, logits, mu, log_sigma = _frame(seed)
        mine = torch.as_tensor(fn(x, logits, mu, log_sigma), dtype=torch.float64)
        lib = -mixture_log_prob(x, logits, mu, log_sigma)
        assert mine.shape == () or mine.numel() == 1, f"E must be one number, got shape {tuple(mine.shape)}"
        assert torch.allclose(mine.reshape(()), lib, atol=1e-6), \
            f"frame {seed}: E = {float(mine):.6f}, the library gives {float(lib):.6f}: E = -log sum_i w_i N_i(x)"


def check_fraction_left(fn) -> None:
    """fn(capacity, replaced, updates) -> fraction: the formula on three settings, and a HistoryBuffer run."""
    for B, r, u in ((320, 16, 100), (100, 10, 5), (50, 1, 30)):
        mine, want = float(fn(B, r, u)), fraction_left(B, r, u)
        assert abs(mine - want) < 1e-9, f"B={B}, {r} replaced per update, {u} updates: got {mine:.4f}, want {want:.4f}"
    buf = HistoryBuffer(320, torch.Generator().manual_seed(0))
    buf.fill(torch.zeros(320, 1))
    for _ in range(100):
        buf.replace(torch.ones(16, 1))
    measured, want = float((buf.data == 0).float().mean()), fraction_left(320, 16, 100)
    sd = math.sqrt(want * (1 - want) / 320)
    assert abs(measured - want) < 4 * sd, f"the buffer keeps {measured:.3f}, the formula says {want:.3f}"


def check_root_path(fn) -> None:
    """fn(dz, dyaw, frames) -> (frames + 1, 2) positions (x, z), compared with root_trajectory (eq. 4 in torch)."""
    for dz, dyaw, frames in ((0.05, 0.1, 3), (0.03, -0.4, 6), (0.1, 0.0, 2)):
        feat = torch.zeros(frames + 1, 68, dtype=torch.float64)
        feat[1:, 1], feat[1:, 2] = dz, dyaw
        lib = root_trajectory(feat)[0][:, [0, 2]].numpy()
        mine = np.asarray(fn(dz, dyaw, frames), dtype=float)
        assert mine.shape == lib.shape, f"expected ({frames + 1}, 2) positions, got {mine.shape}"
        assert np.allclose(mine, lib, atol=1e-9), \
            f"dz={dz}, dyaw={dyaw}: last position {mine[-1].round(4)}, eq. (4) gives {lib[-1].round(4)}"


def check_discriminator_loss(fn) -> None:
    """fn(real_logits (N,), fake_logits (M,)) -> L_D: chance level ln 2, and the library's on random logits."""
    zero = torch.zeros(4, dtype=torch.float64)
    assert abs(float(fn(zero, zero)) - math.log(2)) < 1e-9, "a D at chance (every logit 0) must score ln 2"
    g = torch.Generator().manual_seed(1)
    real = 2 * torch.randn(8, generator=g, dtype=torch.float64)
    fake = 2 * torch.randn(5, generator=g, dtype=torch.float64)
    mine, lib = float(fn(real, fake)), float(discriminator_loss(real, fake))
    assert abs(mine - lib) < 1e-9, f"got {mine:.6f}, the library's eq. (10) halved gives {lib:.6f}"
