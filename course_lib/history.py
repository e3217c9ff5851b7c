"""What a training run logged: every loss term per optimiser step and per epoch, the learning rates, the wall time.

`training.fit` fills one (and returns it); so does every hand-written loop of the course (the refiner's GAN
rounds in models/refiner.py), so that a notebook plots and summarises any run alike.
"""

from __future__ import annotations

from collections.abc import Iterable

import numpy as np

__all__ = ["History"]


class History:
    """Every logged loss term, per optimiser step and per epoch (epoch = mean of its steps).

    ``history.step["loss"]`` is a list with one float per step; vector terms (e.g. ``kl_per_dim``)
    are stored as 1-D numpy arrays.  ``history.epoch[...]`` holds the epoch means, ``history.lr``
    the learning rate of each step and ``history.seconds`` the wall time of the run.
    """

    def __init__(self) -> None:
        self.step: dict[str, list] = {}
        self.epoch: dict[str, list] = {}
        self.lr: list[float] = []
        self.seconds: float = 0.0
        self._epoch_buffer: dict[str, list] = {}

    def log_step(self, logs: dict[str, float | np.ndarray]) -> None:
        for key, value in logs.items():
            self.step.setdefault(key, []).append(value)
            self._epoch_buffer.setdefault(key, []).append(value)

    def end_epoch(self) -> None:
        for key, values in self._epoch_buffer.items():
            mean = np.mean(np.stack([np.asarray(v, dtype=np.float64) for v in values]), axis=0)
            self.epoch.setdefault(key, []).append(float(mean) if mean.ndim == 0 else mean)
        self._epoch_buffer = {}

    @property
    def num_steps(self) -> int:
        return len(self.step.get("loss", []))

    def scalar_keys(self) -> list[str]:
        """The keys whose values are scalars (the ones :meth:`plot` draws)."""
        return [k for k, v in self.step.items() if v and np.ndim(v[0]) == 0]

    def final(self, key: str = "loss", window: int = 1) -> float:
        """Mean of the last ``window`` step values of ``key``."""
        if key not in self.step:
            raise KeyError(f"{key!r} was never logged; logged keys: {sorted(self.step)}")
        return float(np.mean(self.step[key][-window:]))

    def plot(self, ax=None, keys: Iterable[str] | None = None, per: str = "step", logy: bool = False):
        """Plot the scalar loss terms against steps (``per="step"``) or epochs; returns the axes."""
        import matplotlib.pyplot as plt  # imported lazily: no matplotlib cost for headless training

        if per not in ("step", "epoch"):
            raise ValueError(f"per must be 'step' or 'epoch', got {per!r}")
        table = self.step if per == "step" else self.epoch
        keys = list(keys) if keys is not None else self.scalar_keys()
        if ax is None:
            _, ax = plt.subplots(figsize=(6, 3.5))
        for key in keys:
            if key not in table:
                raise KeyError(f"{key!r} was never logged; logged keys: {sorted(table)}")
            ax.plot(np.arange(1, len(table[key]) + 1), table[key], label=key)
        ax.set_xlabel(per)
        ax.set_ylabel("value")
        if logy:
            ax.set_yscale("log")
        ax.legend(fontsize="small")
        ax.grid(alpha=0.3)
        return ax

    def __repr__(self) -> str:
        last = ", ".join(f"{k}={self.final(k):.4g}" for k in self.scalar_keys())
        return f"History(steps={self.num_steps}, epochs={len(self.epoch.get('loss', []))}, {last})"
