"""Reference answers and self-checks for the exercises of notebooks/04_map_control.ipynb.

Students write their own version in the notebook; each ``check_*`` runs it on fixed inputs and compares it with
the library (course_lib.control), raising an AssertionError that says what is wrong.
"""

from __future__ import annotations

import math
import sys
from contextlib import contextmanager
from types import SimpleNamespace

import torch

from course_lib.control.design import DesignConfig, default_prior, prepare_start
from course_lib.control.energy import contact_energy as lib_contact_energy
from course_lib.control.energy import curve_energy as lib_curve_energy
from course_lib.control.energy import stance_plane
from course_lib.control.kinematics import heading_yaw, integrate_root, second_pose, toe_positions
from course_lib.control.lbfgs import LbfgsConfig
from course_lib.control.online import direction_energy as lib_direction_energy
from course_lib.control.pso import PsoConfig
from course_lib.control.rnn_prior import SIGMA_NOISE, expand_state
from course_lib.control.rollout import draw_noise, rollout
from course_lib.control.window import WindowEnergy
from course_lib.motion import CONTACT_HEIGHT

# the modules themselves: course_lib.control's names pso, design, ... are its functions, so read sys.modules
lib_design, lib_energy_module, lib_lbfgs, lib_pso, lib_window = (
    sys.modules[f"course_lib.control.{m}"] for m in ("design", "energy", "lbfgs", "pso", "window"))

__all__ = ["check_contact_energy", "check_direction_energy", "check_sigma_fit2", "check_window", "contact_energy",
           "direction_energy", "sigma_fit2_for", "solve_window", "window_energy", "window_problem"]


# ----------------------------------------------------------------------------- reference answers


def sigma_fit2_for(offset: float, frames: int, nats: float) -> float:
    """Eq. (17) on `frames` frames each `offset` m off the curve costs frames offset^2 / sigma_fit^2 = nats."""
    return frames * offset ** 2 / nats


def contact_energy(toes, bits, prev_toes, plane, sigma_con, sigma_con_y):
    """Eq. (18): toes (N, T, 2, 3), bits (N, T, 2), prev_toes (N, 2, 3) -> (N,)."""
    before = torch.cat((prev_toes[:, None], toes[:, :-1]), 1)
    still = ((toes - before) ** 2).sum(-1) / sigma_con ** 2
    height = (toes[..., 1] - plane) ** 2 / sigma_con_y ** 2
    return (bits * (still + height)).sum((1, 2))


def direction_energy(yaw, direction, sigma):
    """Eq. (23) without the jump at +-pi: yaw (N, T) -> (N,) 2 (1 - cos(yaw_T - direction)) / sigma^2."""
    return 2 * (1 - torch.cos(yaw[:, -1] - direction)) / sigma ** 2


def window_energy(W, eps, gum, d=None) -> dict:
    """Eq. (19) of the frames the RNN's sampler makes from eps (N, T, D), gumbel (N, T, M) and d (N, T, D) or None
    -> {"prior", "noise", "control", "contact", "total"}, each (N,)."""
    raw, nll, toes_rel = W.rollout(eps, gum, d)  # frames, eq. (15)'s -log p, toes relative to the root
    xz, yaw, toes = W.root_and_toes(raw, toes_rel)  # eq. (4) and FK: (N, T, 2), (N, T), (N, T, 2, 3)
    noise = torch.zeros(len(eps), dtype=torch.float64) if d is None else (d ** 2).sum((1, 2)) / (2 * W.sigma_noise ** 2)
    near, _ = W.nearest(xz, W.curve)  # eq. (17)
    control = ((xz - near) ** 2).sum((1, 2)) / W.sigma_fit2
    bits = (raw[..., W.contact_cols] > 0.5).double()
    bits = torch.maximum(bits, (toes[..., 1].detach() < W.contact_height).double())  # low toes count as in contact
    before = torch.cat((W.prev_toes.expand(len(eps), 2, 3)[:, None], toes[:, :-1]), 1)  # eq. (18)
    contact = (bits * (((toes - before) ** 2).sum(-1) / W.sigma_con ** 2
                       + (toes[..., 1] - W.plane) ** 2 / W.sigma_con_y ** 2)).sum((1, 2))
    return {"prior": nll, "noise": noise, "control": control, "contact": contact,
            "total": nll + noise + control + contact}


def solve_window(W, generator, energy=window_energy) -> dict:
    """One window of sec. 5.2: candidates -> PSO -> L-BFGS -> {"frames", "pso", "lbfgs", "terms"}."""
    T, D, P = W.frames, W.dim, W.candidates
    eps0, g0 = W.draw(P, generator)  # (P, T, D), (P, T, M): P samples of the RNN
    x = torch.cat((eps0, g0), -1).reshape(P, -1)  # particles

    def loss(x):
        x = x.reshape(len(x), T, -1)
        return energy(W, x[..., :D], x[..., D:])["total"]

    v = torch.zeros_like(x)
    with torch.no_grad():
        f = loss(x)
    p, fp = x.clone(), f.clone()
    k = int(fp.argmin())
    g, fg = p[k].clone(), float(fp[k])
    pso_hist = [fg]
    for _ in range(W.pso.iterations):
        r1 = torch.rand(x.shape, generator=generator, dtype=x.dtype)
        r2 = torch.rand(x.shape, generator=generator, dtype=x.dtype)
        v = W.pso.inertia * v + W.pso.c1 * r1 * (p - x) + W.pso.c2 * r2 * (g - x)
        x = x + v
        with torch.no_grad():
            f = loss(x)
        better = f < fp
        p[better], fp[better] = x[better], f[better]
        k = int(fp.argmin())
        if float(fp[k]) < fg:
            g, fg = p[k].clone(), float(fp[k])
        pso_hist.append(fg)
    best = g.reshape(1, T, -1)
    gum = best[..., D:]
    eps = best[..., :D].clone().requires_grad_(True)
    d = torch.zeros(1, T, D, dtype=torch.float64, requires_grad=True)
    opt = torch.optim.LBFGS([eps, d], lr=1.0, max_iter=W.lbfgs.iterations, history_size=10,
                            line_search_fn="strong_wolfe", tolerance_grad=1e-7, tolerance_change=1e-9)
    lb_hist = []

    def closure():
        opt.zero_grad()
        e = energy(W, eps, gum, d)["total"].sum()
        e.backward()
        lb_hist.append(float(e.detach()))
        return e

    opt.step(closure)
    eps, d = eps.detach(), d.detach()
    with torch.no_grad():
        if not float(energy(W, eps, gum, d)["total"]) <= pso_hist[-1]:  # keep the better end
            eps, d = best[..., :D], torch.zeros_like(d)
        terms = energy(W, eps, gum, d)
        frames = W.rollout(eps, gum, d)[0]
    return {"frames": frames, "pso": pso_hist, "lbfgs": lb_hist, "terms": {k: float(v) for k, v in terms.items()}}


# ----------------------------------------------------------------------------- the window of exercise 3


def window_problem(seed: int = 0, candidates: int = 8, pso_iterations: int = 3, lbfgs_iterations: int = 5):
    """One window of offline design, ready to solve: a walk's two held-out start frames at the start of a 3-m
    line, facing along it -> a namespace W of what eq. (19) needs (the RNN, its state, the start, the curve, the
    sigmas) and helpers for the parts other lessons built (the RNN's sampler, eq. 4, FK)."""
    prior = default_prior()
    curve = torch.tensor([[0.0, 0.0], [0.0, 3.0]], dtype=torch.float64)
    init0 = (0.0, 0.0, float(heading_yaw(curve[1] - curve[0])))
    raw0, init0, start = prepare_start(None, "walk", seed, init0, prior)
    cfg = DesignConfig(candidates=candidates, pso=PsoConfig(iterations=pso_iterations),
                       lbfgs=LbfgsConfig(iterations=lbfgs_iterations), retry_control=None, retry_rise=None)
    s2 = cfg.sigma_fit2
    lib = WindowEnergy(prior, start.skeleton, raw0, prior.start_state(raw0, start.skeleton), second_pose(raw0, init0),
                       lambda xz, yaw, raw: lib_curve_energy(xz, curve, s2), stance_plane(start),
                       contact_height=cfg.contact_height)
    W = SimpleNamespace(prior=prior, skeleton=start.skeleton, prev=lib.prev, state=lib.state, init=lib.init,
                        prev_toes=lib.prev_toes, plane=lib.plane, curve=curve, sigma_fit2=s2, sigma_noise=SIGMA_NOISE,
                        sigma_con=lib.sigma_con, sigma_con_y=lib.sigma_con_y, contact_height=CONTACT_HEIGHT["ToeBase"],
                        contact_cols=prior.contact_cols, frames=cfg.window, dim=prior.dim,
                        mixtures=prior.model.config.mixtures, candidates=cfg.candidates, bias=cfg.sample_bias,
                        pso=cfg.pso, lbfgs=cfg.lbfgs, seed=seed, config=cfg, library=lib,
                        nearest=lib_energy_module.nearest_on_polyline)

    def draw(n, generator):  # n random sampler inputs: eps (n, T, D), Gumbel (n, T, M)
        return draw_noise(n, W.frames, prior, generator)

    def sampler(eps, gum, d=None):  # the RNN's frames from its random numbers, their -log p (eq. 15), toes
        N = len(eps)
        raw, nll, _, toes = rollout(prior, lib.prev.expand(N, -1, -1), expand_state(lib.state, N), eps, gum,
                                    start.skeleton, d, W.bias, lib.prev_model, with_toes=True)
        return raw, nll, toes

    def root_and_toes(raw, toes_rel):  # eq. (4) from the start's last frame, then the toes in the world
        init = lib.init.expand(len(raw), 3)
        xz, yaw = integrate_root(raw[..., 0:2], raw[..., 2], init)
        return xz, yaw, toe_positions(raw, start.skeleton, init, toes_rel)

    W.draw, W.rollout, W.root_and_toes = draw, sampler, root_and_toes
    return W


# ----------------------------------------------------------------------------- checks


def _close(mine, ref, what: str, tol: float = 1e-8) -> None:
    mine = torch.as_tensor(mine, dtype=torch.float64)
    assert mine.shape == ref.shape, f"{what}: expected shape {tuple(ref.shape)}, got {tuple(mine.shape)}"
    err = float((mine - ref).abs().max()) if ref.numel() else 0.0
    assert err < tol, f"{what}: differs from the library by up to {err:.3g}"


def check_sigma_fit2(fn) -> None:
    """fn(offset m, frames, nats) -> sigma_fit^2 (m^2) at which eq. (17) charges `nats` for `frames` frames
    `offset` off the curve; checked with energy.curve_energy on a straight line."""
    line = torch.tensor([[0.0, 0.0], [0.0, 10.0]], dtype=torch.float64)
    for offset, frames, nats in ((0.05, 34, 10.0), (0.2, 17, 3.0)):
        s2 = float(fn(offset, frames, nats))
        assert math.isfinite(s2) and s2 > 0, f"sigma_fit^2 must be a positive number of m^2, got {s2}"
        root = torch.zeros(1, frames, 2, dtype=torch.float64)
        root[..., 0], root[..., 1] = offset, torch.linspace(0.5, 5.0, frames)
        paid = float(lib_curve_energy(root, line, s2))
        hint = ""
        if abs(paid / nats - offset) < 1e-6 or abs(paid / nats - 1 / offset) < 1e-6:
            hint = ": is the distance squared?"
        elif abs(paid / nats - frames) < 1e-6 or abs(paid / nats - 1 / frames) < 1e-6:
            hint = ": the energy sums over the frames"
        assert abs(paid - nats) < 1e-9 * nats, (f"with your sigma_fit^2 = {s2:.4g} m^2, {frames} frames {offset} m off "
                                                f"the curve pay {paid:.4g} nats, not {nats}{hint}")


def check_contact_energy(fn) -> None:
    """fn(toes, bits, prev_toes, plane, sigma_con, sigma_con_y) -> (N,), against energy.contact_energy."""
    gen = torch.Generator().manual_seed(2)
    toes = 0.05 * torch.randn(3, 8, 2, 3, generator=gen, dtype=torch.float64) + 0.03
    prev = 0.05 * torch.randn(3, 2, 3, generator=gen, dtype=torch.float64)
    bits = (torch.rand(3, 8, 2, generator=gen) > 0.5).double()
    ref = lib_contact_energy(toes, bits, prev, 0.024, 0.03, 0.03)
    mine = torch.as_tensor(fn(toes, bits, prev, 0.024, 0.03, 0.03), dtype=torch.float64)
    if mine.shape == ref.shape:
        no_prev = lib_contact_energy(toes, bits, toes[:, 0], 0.024, 0.03, 0.03)
        assert not torch.allclose(mine, no_prev), \
            "the first frame's step is from prev_toes, the frame before the window"
        if torch.allclose(mine, (bits * (toes[..., 1] - 0.024) ** 2 / 0.03 ** 2).sum((1, 2))):
            raise AssertionError("only the plane term: a foot in contact also pays for moving since the frame before")
    _close(mine, ref, "contact energy", tol=1e-6)


def check_direction_energy(fn) -> None:
    """fn(yaw (N, T), direction, sigma) -> (N,), against online.direction_energy, including headings across +-pi."""
    yaw = torch.tensor([[0.0, 0.3], [0.0, math.pi - 0.05], [0.0, -math.pi + 0.05], [0.0, 7.0]], dtype=torch.float64)
    for direction in (0.0, math.pi, -math.pi + 0.1):
        _close(fn(yaw, direction, 0.1), lib_direction_energy(yaw, direction, 0.1),
               f"direction energy (direction {direction:.2f})", tol=1e-6)


@contextmanager
def _written_out():
    """The library's own window solver, PSO, L-BFGS and energies refuse to run: the exercise writes them."""
    def refuse(name):
        def f(*a, **k):
            raise AssertionError(f"write it out: your window calls the library's {name}")
        return f

    saved = [(lib_design, "_solve_window"), (lib_design, "solve_windows"), (lib_pso, "pso"),
             (lib_lbfgs, "minimise_lbfgs"), (lib_window.WindowEnergy, "sampled"), (lib_window.WindowEnergy, "terms"),
             (lib_energy_module, "curve_energy"), (lib_energy_module, "contact_energy")]
    old = [getattr(o, n) for o, n in saved]
    for o, n in saved:
        setattr(o, n, refuse(n))
    try:
        yield
    finally:
        for (o, n), f in zip(saved, old, strict=True):
            setattr(o, n, f)


def check_window(my_energy, my_solve, seed: int = 0) -> dict:
    """my_energy(W, eps, gum, d=None) -> eq. (19)'s terms; my_solve(W, generator) -> {"frames", "pso", "lbfgs"}:
    against course_lib.control (WindowEnergy.sampled, design's window solver) on one window, the same seed.
    Prints and returns the largest differences."""
    W = window_problem(seed)
    eps, gum = W.draw(W.candidates, torch.Generator().manual_seed(seed + 100))
    d = 0.02 * torch.randn(eps.shape, generator=torch.Generator().manual_seed(seed + 101), dtype=torch.float64)
    with torch.no_grad():
        ref = W.library.sampled(eps, gum, d, W.bias)[1]
        with _written_out():
            mine = my_energy(W, eps, gum, d)
    hints = {"prior": "eq. (15): the sum over frames of -log p that W.rollout returns",
             "noise": "eq. (16): ||d||^2 / (2 sigma_noise^2), summed over frames and features",
             "control": "eq. (17): squared distance to the nearest curve point over sigma_fit^2, summed over frames",
             "contact": "eq. (18): a toe in contact (bit on, or below contact_height) pays for its step and its height",
             "total": "eq. (19): the sum of the four terms"}
    diff = {}
    for k, hint in hints.items():
        assert k in mine, f"your energy returns no '{k}' term"
        m = torch.as_tensor(mine[k], dtype=torch.float64)
        assert m.shape == ref[k].shape, \
            f"{k}: expected shape {tuple(ref[k].shape)} (one per candidate), got {tuple(m.shape)}"
        diff[k] = float((m - ref[k]).abs().max())
        assert diff[k] <= 1e-9 * (1 + float(ref[k].abs().max())), f"the {k} term differs by up to {diff[k]:.3g}: {hint}"
    lib = lib_design._solve_window(W.library, None, W.config, torch.Generator().manual_seed(seed))
    with _written_out():
        out = my_solve(W, torch.Generator().manual_seed(seed))
    n = len(lib[2]["pso"])
    assert len(out["pso"]) == n, (f"{len(out['pso'])} PSO losses, the library has {n}: the start's best, then one per "
                                  f"iteration ({W.pso.iterations} iterations)")
    diff["pso"] = max(abs(a - b) for a, b in zip(out["pso"], lib[2]["pso"], strict=True))
    assert diff["pso"] <= 1e-6 * (1 + abs(lib[2]["pso"][0])), (
        f"your swarm's best losses {[round(v, 2) for v in out['pso']]} differ from the library's "
        f"{[round(v, 2) for v in lib[2]['pso']]}: draw r1 then r2 per iteration, same shapes, same generator")
    assert len(out["lbfgs"]) == len(lib[2]["lbfgs"]), (f"{len(out['lbfgs'])} L-BFGS evaluations, the library makes "
                                                       f"{len(lib[2]['lbfgs'])}: torch.optim.LBFGS settings?")
    diff["lbfgs"] = max(abs(a - b) for a, b in zip(out["lbfgs"], lib[2]["lbfgs"], strict=True))
    frames = torch.as_tensor(out["frames"], dtype=torch.float64)
    assert frames.shape == lib[0].shape, f"frames: expected shape {tuple(lib[0].shape)}, got {tuple(frames.shape)}"
    diff["frames"] = float((frames - lib[0]).abs().max())
    assert diff["lbfgs"] <= 1e-6 * (1 + abs(lib[2]["lbfgs"][0])) and diff["frames"] <= 1e-6, (
        f"after L-BFGS your window differs (energies by {diff['lbfgs']:.3g}, frames by {diff['frames']:.3g}): "
        "L-BFGS moves eps and d with the Gumbel draws held, and keeps PSO's end if it ends higher")
    return diff
