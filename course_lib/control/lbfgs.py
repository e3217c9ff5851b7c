"""The gradient stage of Wang, Chai et al.'s MAP problems (sec. 5.2-5.4): L-BFGS (``torch.optim.LBFGS``,
Liu and Nocedal 1989, strong-Wolfe line search), the gradient of eq. (19) by backpropagation through the RNN
and the eq. (4) integration (BPTT).

Taught in notebooks/04_map_control.ipynb.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import torch

__all__ = ["LbfgsConfig", "minimise_lbfgs"]


@dataclass
class LbfgsConfig:
    """L-BFGS settings."""

    iterations: int = 40  # L-BFGS iterations at most (torch's max_iter)
    evaluations: int | None = None  # energy evaluations at most (torch's max_eval; None: torch's 1.25 x iterations)
    history_size: int = 10  # curvature pairs kept
    lr: float = 1.0  # torch's step scale; with the strong-Wolfe line search 1 is the textbook value

    def __post_init__(self):
        if int(self.iterations) != self.iterations or self.iterations < 0:
            raise ValueError(f"LbfgsConfig: iterations must be an int >= 0, got {self.iterations}")
        if self.evaluations is not None and (int(self.evaluations) != self.evaluations or self.evaluations < 1):
            raise ValueError(f"LbfgsConfig: evaluations must be None or an int >= 1, got {self.evaluations}")


def minimise_lbfgs(energy: Callable[..., torch.Tensor], variables: Sequence[torch.Tensor],
                   config: LbfgsConfig | None = None) -> tuple[list, list]:
    """Minimise the scalar energy(*variables) from the given starts -> (the variables at the end, the
    energy at each evaluation).  The inputs are not modified."""
    config = config or LbfgsConfig()
    xs = [v.detach().clone().requires_grad_(True) for v in variables]
    opt = torch.optim.LBFGS(xs, lr=config.lr, max_iter=config.iterations, max_eval=config.evaluations,
                            history_size=config.history_size,
                            line_search_fn="strong_wolfe", tolerance_grad=1e-7, tolerance_change=1e-9)
    history = []

    def closure():
        opt.zero_grad()
        e = energy(*xs)
        e.backward()
        history.append(float(e.detach()))
        return e

    if config.iterations > 0:
        opt.step(closure)
    return [x.detach() for x in xs], history
