"""Initial hidden-state estimation (Wang, Chai et al. 2021, sec. 5.4, eq. 26): an RNN started from the zero
state "hops" between its first two frames, because in training it never saw a zero state after the first
frame.  Instead, find the LSTM state h_1 under which the first frame s_1 predicts the second, s_2:

    min_{h_1}  E = -log sum_i w_i P(s_2 | s_1, h_1)                                   -- eq. (26)

by gradient descent (Adam here), the gradient dE/dh_1 by backpropagation; h_1 = (h, C) of both LSTM layers.

Taught in notebooks/04_map_control.ipynb.  ``RnnPrior.start_state`` is the zero-state start it replaces.
"""

from __future__ import annotations

import torch

from course_lib.control.kinematics import world_positions
from course_lib.control.rnn_prior import RnnPrior
from course_lib.skeleton import Skeleton

__all__ = ["estimate_initial_state", "initial_state_nll", "predicted_second", "first_frame_speed"]


def initial_state_nll(prior: RnnPrior, first: torch.Tensor, state, skeleton: Skeleton) -> torch.Tensor:
    """first (N, 2, D) raw frames s_1, s_2; state (h, C) before s_1 or None (zero) -> (N,) E of eq. (26)."""
    return prior.nll(first[:, :1], first[:, 1:2], state, skeleton)


def estimate_initial_state(prior: RnnPrior, first: torch.Tensor, skeleton: Skeleton, steps: int = 100,
                           lr: float = 0.05) -> tuple[tuple, list]:
    """first (N, 2, D) raw frames s_1, s_2 -> (the state h_1 = (h, C), each (layers, N, H), that minimises eq. 26
    from zero; the energy at every step)."""
    if first.ndim != 3 or first.shape[1] < 2:
        raise ValueError(f"estimate_initial_state: first must be (N, >= 2, D) raw frames, got {tuple(first.shape)}")
    lstm = prior.model.lstm
    shape = (lstm.num_layers, len(first), lstm.hidden_size)
    h, c = torch.zeros(shape, requires_grad=True), torch.zeros(shape, requires_grad=True)
    opt = torch.optim.Adam([h, c], lr=lr)
    history = []
    for _ in range(int(steps)):
        opt.zero_grad()
        e = initial_state_nll(prior, first[:, :2], (h, c), skeleton).sum()
        e.backward()
        opt.step()
        history.append(float(e.detach()))
    return (h.detach(), c.detach()), history


@torch.no_grad()
def predicted_second(prior: RnnPrior, raw: torch.Tensor, state, skeleton: Skeleton) -> torch.Tensor:
    """raw (1, 2, D) frames s_1, s_2; state before s_1 (None: zero) -> the RNN's s_2 given s_1: the most likely
    component's mean, raw (1, 1, D)."""
    y = prior.to_model(raw, skeleton)
    params, _ = prior.model(y[:, :1], state)
    k = params["logits"][0, 0].argmax()
    pred = y.clone()
    pred[0, 1] = params["mu"][0, 0, k]
    return prior.from_model(pred, skeleton)[:, 1:]


def first_frame_speed(raw_pair: torch.Tensor, skeleton: Skeleton, fps: float = 30.0) -> float:
    """(1, 2, D) raw frames -> the mean joint speed (m/s) from frame 0 to frame 1: the "hop" of eq. (26)."""
    r = raw_pair.double().clone()
    r[:, 0, :3] = 0.0
    p = world_positions(r, skeleton, torch.zeros(3, dtype=torch.float64))  # frame 0 at the origin, frame 1 a step on
    return float((p[0, 1] - p[0, 0]).norm(dim=-1).mean()) * fps
