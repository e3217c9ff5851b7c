"""Reference answers and self-checks for the exercises of notebooks/05_hierarchical_vrnn.ipynb.

Students write their own version in the notebook; each ``check_*`` runs it on fixed inputs and
compares it with the library (course_lib.models.hvrnn), raising an AssertionError that says what
is wrong.
"""

from __future__ import annotations

import numpy as np
import torch

from course_lib.models.hvrnn import geodesic, impact_factors, kl_weight
from course_lib.skeleton import Skeleton

__all__ = ["angle_distances", "check_angle_distances", "check_d3", "check_impact_factors", "check_kl_schedule",
           "check_word_count", "d3", "kl_schedule", "path_lengths", "word_count"]


# ----------------------------------------------------------------------------- reference answers


def path_lengths(skeleton: Skeleton) -> np.ndarray:
    """alpha_k = max_j (alpha_j + l_{k-j}) over the children j of k, leaves: their end-site length  -- eq. (23)."""
    alpha = np.zeros(skeleton.num_joints)
    for k in reversed(range(skeleton.num_joints)):
        kids = skeleton.children(k)
        if kids:
            alpha[k] = max(alpha[j] + np.linalg.norm(skeleton.offsets[j]) for j in kids)
        elif k in skeleton.end_sites:
            alpha[k] = np.linalg.norm(skeleton.end_sites[k])
    return alpha


def d3(q: torch.Tensor, q_hat: torch.Tensor) -> torch.Tensor:
    """d3 = min(||q - q~||^2, ||q + q~||^2)  -- eq. (20).  (..., 4) x 2 -> (...)."""
    return torch.minimum((q - q_hat).pow(2).sum(-1), (q + q_hat).pow(2).sum(-1))


def angle_distances(theta: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """d2 and d3 (eq. 18, 20) of two unit quaternions whose rotations differ by the angle theta: |q . q~| =
    cos(theta / 2), so d2 = 1 - cos(theta / 2) and d3 = 2 - 2 cos(theta / 2) = 2 d2 (about theta^2 / 4)."""
    c = torch.cos(theta / 2)
    return 1 - c, 2 - 2 * c


def kl_schedule(step: int, warmup: int, anneal: int) -> float:
    """0 during warm-up, linear 0 -> 1 during annealing, 1 in the cool-down."""
    return float(min(1.0, max(0.0, (step - warmup) / anneal)))


def word_count(frames: int, word_len: int) -> int:
    """Motion Cell steps for a sequence: N = floor(T / l)."""
    return frames // word_len


# ----------------------------------------------------------------------------- checks


def check_impact_factors(fn) -> None:
    """fn(skeleton) -> (J,) un-normalised alpha_k, checked on the canonical and a scaled skeleton."""
    for skel in (Skeleton.canonical(), Skeleton.canonical().scaled(1.2)):
        got = np.asarray(fn(skel), float)
        want = impact_factors(skel, normalize=False)
        assert got.shape == want.shape, f"expected shape {want.shape}, got {got.shape}"
        bad = np.flatnonzero(~np.isclose(got, want, atol=1e-6))
        assert not len(bad), (f"alpha wrong for {[skel.names[j] for j in bad[:3]]}: got {got[bad[:3]]}, want "
                              f"{want[bad[:3]]} -- take the max over children of (child's alpha + child's bone)")


def check_d3(fn) -> None:
    """fn(q, q_hat) -> d3, compared with the library on random unit quaternions, both signs."""
    g = torch.Generator().manual_seed(0)
    q = torch.nn.functional.normalize(torch.randn(64, 4, generator=g), dim=-1)
    p = torch.nn.functional.normalize(torch.randn(64, 4, generator=g), dim=-1)
    for other, what in ((p, "random pairs"), (-q, "q and -q (the same rotation)")):
        got, want = fn(q, other), geodesic(q, other, "d3")
        assert torch.allclose(got, want, atol=1e-6), f"d3 differs on {what}: max error {(got - want).abs().max():.3g}"


def check_angle_distances(fn) -> None:
    """fn(theta) -> (d2, d3) as functions of the true angle, compared with the library's geodesic on rotations
    about a random axis (angles 0..pi)."""
    from course_lib.rotations import axis_angle_to_quat

    theta = torch.linspace(0.0, np.pi, 37, dtype=torch.float64)
    axis = torch.nn.functional.normalize(torch.tensor([0.2, -0.9, 0.4], dtype=torch.float64), dim=0)
    q_hat = axis_angle_to_quat(axis.expand(len(theta), 3), theta)
    q = torch.tensor([1.0, 0, 0, 0], dtype=torch.float64).expand_as(q_hat)
    got = fn(theta)
    assert isinstance(got, tuple) and len(got) == 2, "return a pair (d2, d3), each of theta's shape"
    for name, g in zip(("d2", "d3"), got, strict=True):
        want = geodesic(q, q_hat, name)
        g = torch.as_tensor(g, dtype=torch.float64)
        assert g.shape == want.shape, f"{name}: expected shape {tuple(want.shape)}, got {tuple(g.shape)}"
        if torch.allclose(g, want, atol=1e-6):
            continue
        mid = len(theta) // 2  # 90 degrees
        ratio = float(g[mid] / want[mid]) if abs(float(want[mid])) > 0 else float("nan")
        hint = ("the dot product of two unit quaternions is the cosine of HALF the angle" if abs(ratio - 1) > 0.05
                and not np.isnan(ratio) and float(g[mid]) > 0 else "write it with torch.cos(theta / 2)")
        if abs(ratio - 2) < 0.01 or abs(ratio - 0.5) < 0.01:
            hint = "||q - q~||^2 = 2 - 2 q.q~ for unit quaternions: check the factor 2"
        raise AssertionError(f"{name} at 90 degrees: yours {float(g[mid]):.4f}, the library's {float(want[mid]):.4f} "
                             f"-- {hint}")


def check_kl_schedule(fn) -> None:
    """fn(step, warmup, anneal) -> lambda_KL, compared with the library's kl_weight."""
    for step in (0, 5, 10, 15, 20, 30, 200):
        got, want = fn(step, 10, 20), kl_weight(step, 10, 20)
        assert abs(got - want) < 1e-9, f"step {step} (warm-up 10, annealing 20): got {got}, want {want}"


def check_word_count(fn) -> None:
    for frames, l, n in ((90, 3, 30), (200, 3, 66), (90, 1, 90)):
        assert fn(frames, l) == n, f"{frames} frames, l = {l}: N = {n}, got {fn(frames, l)}"
