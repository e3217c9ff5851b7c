"""Particle swarm optimisation (Kennedy and Eberhart 1995), written out and vectorised over particles: the
sampling stage of Wang, Chai et al.'s offline motion design (sec. 5.2).

Taught in notebooks/04_map_control.ipynb.

Each particle i has a position x_i, a velocity v_i and the best position it has visited, p_i; g is the best
position of the swarm.  Every iteration, with r1, r2 ~ U(0, 1) drawn per coordinate:

    v_i <- w v_i + c1 r1 (p_i - x_i) + c2 r2 (g - x_i)          velocity (w = 1 in the 1995 paper)
    v_i <- clamp(v_i, -v_max, v_max)                           the 1995 paper's V_max
    x_i <- x_i + v_i

Differs from the 1995 paper: the inertia weight w (Shi and Eberhart 1998) with the constriction values
w = 0.7298, c1 = c2 = 1.49618 (Clerc and Kennedy 2002) by default, because the original w = 1, c = 2 needs
V_max to stay bounded; V_max is still applied when given.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import torch

__all__ = ["PsoConfig", "PsoResult", "pso", "pso_step"]


@dataclass
class PsoConfig:
    """PSO settings."""

    iterations: int = 50  # swarm updates
    inertia: float = 0.7298  # w (Clerc-Kennedy constriction; 1.0 is the 1995 paper)
    c1: float = 1.49618  # pull towards the particle's own best
    c2: float = 1.49618  # pull towards the swarm's best
    v_max: float | None = None  # per-coordinate velocity clamp (the 1995 paper's V_max); None: none
    tol: float | None = None  # stop once the swarm's best loss is below this
    patience: int | None = None  # stop once the best improved by under rel_tol (relative) in this many iterations
    rel_tol: float = 1e-3

    def __post_init__(self):
        if int(self.iterations) != self.iterations or self.iterations < 0:
            raise ValueError(f"PsoConfig: iterations must be an int >= 0, got {self.iterations}")
        if self.v_max is not None and self.v_max <= 0:
            raise ValueError(f"PsoConfig: v_max must be > 0 or None, got {self.v_max}")


@dataclass
class PsoResult:
    """best (n,) position, best_loss, history: the swarm's best loss after each iteration (first: the start)."""

    best: torch.Tensor
    best_loss: float
    history: list = field(default_factory=list)


@torch.no_grad()
def pso(loss: Callable[[torch.Tensor], torch.Tensor], x0: torch.Tensor, config: PsoConfig | None = None,
        generator: torch.Generator | None = None, v0: torch.Tensor | None = None) -> PsoResult:
    """Minimise loss over R^n: loss maps positions (P, n) to (P,) losses; x0 (P, n) the initial particles
    (e.g. samples of a model); v0 (P, n) initial velocities (default zeros) -> PsoResult.

    The same generator state gives the same result."""
    config = config or PsoConfig()
    if x0.ndim != 2 or len(x0) < 1:
        raise ValueError(f"pso: x0 must be (particles, n) with at least one particle, got {tuple(x0.shape)}")
    x = x0.clone()
    v = torch.zeros_like(x) if v0 is None else v0.clone()
    f = _evaluate(loss, x)  # (P,)
    p, fp = x.clone(), f.clone()  # each particle's best
    k = int(fp.argmin())
    g, fg = p[k].clone(), float(fp[k])
    history = [fg]
    for _ in range(int(config.iterations)):
        if _converged(history, config):
            break
        r1 = torch.rand(x.shape, generator=generator, dtype=x.dtype)
        r2 = torch.rand(x.shape, generator=generator, dtype=x.dtype)
        x, v = pso_step(x, v, p, g, r1, r2, config)
        f = _evaluate(loss, x)
        better = f < fp
        p[better], fp[better] = x[better], f[better]
        k = int(fp.argmin())
        if float(fp[k]) < fg:
            g, fg = p[k].clone(), float(fp[k])
        history.append(fg)
    return PsoResult(g, fg, history)


def pso_step(x: torch.Tensor, v: torch.Tensor, p: torch.Tensor, g: torch.Tensor, r1: torch.Tensor,
             r2: torch.Tensor, config: PsoConfig) -> tuple[torch.Tensor, torch.Tensor]:
    """One swarm update: positions x, velocities v, personal bests p (P, n), swarm best g (n,), uniform draws
    r1, r2 (P, n) -> (new x, new v)."""
    # v <- w v + c1 r1 (p - x) + c2 r2 (g - x)
    v = config.inertia * v + config.c1 * r1 * (p - x) + config.c2 * r2 * (g - x)
    if config.v_max is not None:
        v = v.clamp(-config.v_max, config.v_max)
    return x + v, v


def _converged(history: list, config: PsoConfig) -> bool:
    """The switch to the gradient stage: the loss is small (tol) or has stopped falling (patience)."""
    if config.tol is not None and history[-1] < config.tol:
        return True
    if config.patience is None or len(history) <= config.patience:
        return False
    old, new = history[-1 - config.patience], history[-1]
    return old - new <= config.rel_tol * abs(old)


def _evaluate(loss, x: torch.Tensor) -> torch.Tensor:
    f = loss(x)
    if f.shape != (len(x),):
        raise ValueError(f"pso: loss must map ({len(x)}, n) positions to ({len(x)},) losses, got {tuple(f.shape)}")
    return torch.where(torch.isfinite(f), f, torch.full_like(f, float("inf")))  # a diverged particle never wins
