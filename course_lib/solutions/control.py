"""Reference answers and self-checks for the exercises of notebooks/04_map_control.ipynb.

Students write their own version in the notebook; each ``check_*`` runs it on fixed inputs and compares it with
the library (course_lib.control), raising an AssertionError that says what is wrong.
"""

from __future__ import annotations

import math

import torch

from course_lib.control.energy import contact_energy as lib_contact_energy
from course_lib.control.energy import nearest_on_polyline as lib_nearest
from course_lib.control.online import direction_energy as lib_direction_energy
from course_lib.control.pso import PsoConfig
from course_lib.control.pso import pso_step as lib_pso_step

__all__ = ["check_contact_energy", "check_direction_energy", "check_nearest", "check_pso_step", "contact_energy",
           "direction_energy", "nearest", "pso_step"]


# ----------------------------------------------------------------------------- reference answers


def nearest(points: torch.Tensor, curve: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """points (N, 2), curve (K, 2) -> the nearest point of the polyline (N, 2) and the distance (N,)."""
    a, b = curve[:-1], curve[1:]
    t = (((points[:, None] - a) * (b - a)).sum(-1) / ((b - a) ** 2).sum(-1)).clamp(0, 1)  # (N, K-1)
    c = a + t[..., None] * (b - a)  # (N, K-1, 2)
    d = (points[:, None] - c).norm(dim=-1)
    k = d.argmin(-1)
    return c[torch.arange(len(points)), k], d[torch.arange(len(points)), k]


def pso_step(x, v, p, g, r1, r2, w, c1, c2):
    """One swarm update (Kennedy-Eberhart with inertia w) -> (new x, new v)."""
    v = w * v + c1 * r1 * (p - x) + c2 * r2 * (g - x)
    return x + v, v


def contact_energy(toes, bits, prev_toes, plane, sigma_con, sigma_con_y):
    """Eq. (18): toes (N, T, 2, 3), bits (N, T, 2), prev_toes (N, 2, 3) -> (N,)."""
    before = torch.cat((prev_toes[:, None], toes[:, :-1]), 1)
    still = ((toes - before) ** 2).sum(-1) / sigma_con ** 2
    height = (toes[..., 1] - plane) ** 2 / sigma_con_y ** 2
    return (bits * (still + height)).sum((1, 2))


def direction_energy(yaw, direction, sigma):
    """Eq. (23) without the jump at +-pi: yaw (N, T) -> (N,) 2 (1 - cos(yaw_T - direction)) / sigma^2."""
    return 2 * (1 - torch.cos(yaw[:, -1] - direction)) / sigma ** 2


# ----------------------------------------------------------------------------- checks


def _close(mine, ref, what: str, tol: float = 1e-8) -> None:
    mine = torch.as_tensor(mine, dtype=torch.float64)
    assert mine.shape == ref.shape, f"{what}: expected shape {tuple(ref.shape)}, got {tuple(mine.shape)}"
    err = float((mine - ref).abs().max()) if ref.numel() else 0.0
    assert err < tol, f"{what}: differs from the library by up to {err:.3g}"


def check_nearest(fn) -> None:
    """fn(points (N, 2), curve (K, 2)) -> (near (N, 2), dist (N,)), against energy.nearest_on_polyline."""
    g = torch.Generator().manual_seed(0)
    curve = torch.tensor([[0.0, 0.0], [2.0, 0.0], [2.0, 2.0], [0.0, 3.0]], dtype=torch.float64)
    points = 4 * torch.rand(50, 2, generator=g, dtype=torch.float64) - 1
    near, dist = fn(points, curve)
    ref_near, ref_dist = lib_nearest(points, curve)
    _close(dist, ref_dist, "distance")
    _close(near, ref_near, "nearest point")


def check_pso_step(fn) -> None:
    """fn(x, v, p, g, r1, r2, w, c1, c2) -> (x, v), against pso.pso_step."""
    gen = torch.Generator().manual_seed(1)
    x, v, p, r1, r2 = (torch.rand(6, 3, generator=gen, dtype=torch.float64) for _ in range(5))
    g = torch.rand(3, generator=gen, dtype=torch.float64)
    cfg = PsoConfig()
    ref_x, ref_v = lib_pso_step(x, v, p, g, r1, r2, cfg)
    out = fn(x, v, p, g, r1, r2, cfg.inertia, cfg.c1, cfg.c2)
    assert isinstance(out, tuple) and len(out) == 2, "return (new x, new v)"
    _close(out[1], ref_v, "velocity")
    _close(out[0], ref_x, "position")


def check_contact_energy(fn) -> None:
    """fn(toes, bits, prev_toes, plane, sigma_con, sigma_con_y) -> (N,), against energy.contact_energy."""
    gen = torch.Generator().manual_seed(2)
    toes = 0.05 * torch.randn(3, 8, 2, 3, generator=gen, dtype=torch.float64) + 0.03
    prev = 0.05 * torch.randn(3, 2, 3, generator=gen, dtype=torch.float64)
    bits = (torch.rand(3, 8, 2, generator=gen) > 0.5).double()
    ref = lib_contact_energy(toes, bits, prev, 0.024, 0.03, 0.03)
    _close(fn(toes, bits, prev, 0.024, 0.03, 0.03), ref, "contact energy", tol=1e-6)


def check_direction_energy(fn) -> None:
    """fn(yaw (N, T), direction, sigma) -> (N,), against online.direction_energy, including headings across +-pi."""
    yaw = torch.tensor([[0.0, 0.3], [0.0, math.pi - 0.05], [0.0, -math.pi + 0.05], [0.0, 7.0]], dtype=torch.float64)
    for direction in (0.0, math.pi, -math.pi + 0.1):
        _close(fn(yaw, direction, 0.1), lib_direction_energy(yaw, direction, 0.1),
               f"direction energy (direction {direction:.2f})", tol=1e-6)
