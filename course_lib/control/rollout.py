"""The GMM-RNN's sampler written as a deterministic function of its random numbers (a change of variables for
the MAP problems of Wang, Chai et al. sec. 5.2-5.3):

    k_i = argmax_m ((1 + b) w_hat_m(h_i) + g_im),   g_im ~ Gumbel(0, 1)        the component (Gumbel-max)
    s_i = mu_k(h_i) + sigma_k(h_i) exp(-b) eps_i,    eps_i ~ N(0, I)            the frame, eq. (6)-(7)
    h_{i+1} = LSTM(h_i, s_i + d_i)                                              the RNN reads s_i + d_i, eq. (5)

With u = (eps, g) drawn at random this *is* sec. 4.1.4's sampling (b: Graves' bias, as lesson 03's generation);
optimising u instead of s moves every later frame with the RNN's own dynamics, so PSO particles stay motions.
The energy is still eq. (19) of the frames s: the prior term is the mixture's -log p(s_i | s_<i, d) (eq. 15).

Taught in notebooks/04_map_control.ipynb.  Uses only the model's public ``forward`` and ``log_prob`` (via RnnPrior).

Differs from the paper: the paper optimises s and d directly; for the sampling stage that gave particles that
were not motions (PSO made no progress on 34 x 68 free frame values), so we optimise the sampler's eps (and d;
s is a smooth one-to-one function of eps for a fixed component sequence).  The contact bits are thresholded at
0.5 (lesson 03's generation); a model with a Bernoulli contact head uses bit = [logit + 1.6 eps > 0].
"""

from __future__ import annotations

import torch

from course_lib.control.rnn_prior import RnnPrior, expand_state
from course_lib.skeleton import Skeleton

__all__ = ["rollout", "draw_noise"]


def draw_noise(n: int, frames: int, prior: RnnPrior, generator: torch.Generator | None = None):
    """-> (eps (n, frames, D) standard normal, g (n, frames, M) standard Gumbel): one random sampler input each."""
    M, D = prior.model.config.mixtures, prior.dim
    eps = torch.randn(n, frames, D, generator=generator, dtype=torch.float64)
    u = torch.rand(n, frames, M, generator=generator, dtype=torch.float64).clamp(1e-12, 1 - 1e-12)
    return eps, -torch.log(-torch.log(u))


def rollout(prior: RnnPrior, prev: torch.Tensor, state, eps: torch.Tensor, gumbel: torch.Tensor,
            skeleton: Skeleton, d: torch.Tensor | None = None, bias: float = 0.0,
            prev_model: torch.Tensor | None = None, with_toes: bool = False):
    """prev (N, P, D) raw known frames, state (before prev's last frame), eps (N, T, D), gumbel (N, T, M),
    d (N, T, D) input noise or None -> (raw frames (N, T, D) float64, prior -log p (N,) of eq. 15, state after
    reading prev's last frame and every frame but the last).  prev_model: ``prior.to_model(prev[:1], skeleton)``
    if the caller already has it (it is the same for every rollout from one prev).  with_toes: also the frames'
    toes relative to the root (N, T, 2, 3) (`RnnPrior.from_model`; None for a plain state-feature model), so
    that the contact energy needs no second FK."""
    model, c = prior.model, prior.model.config
    N, T = eps.shape[:2]
    y_prev = prior.to_model(prev, skeleton) if prev_model is None else prev_model.expand(N, -1, -1)  # (N, P, D)
    state = expand_state(state, N)
    mean, std = (s.float() for s in prior.model_norm)
    cols = list(c.contact_dims)
    rows = torch.arange(N)
    D = eps.shape[-1]
    # the columns each frame takes from elsewhere, as masks (one torch.where per frame, not index assignments):
    # the contact bits (normalised 0/1 values), the columns the model copies from its input, the fixed ones
    is_bit, copied = torch.zeros(D, dtype=torch.bool), torch.zeros(D, dtype=torch.bool)
    is_bit[cols] = True
    copied[list(prior.fixed_dims)] = True
    place = torch.zeros(len(cols), D)  # bits (N, 2) @ place + shift: the bits' normalised values in their columns
    place[range(len(cols)), cols] = 1.0 / std[cols]
    shift = torch.zeros(D)
    shift[cols] = -mean[cols] / std[cols]
    fixed = None  # the columns the data never vary, at their constants (what `RnnPrior.clean` makes of them)
    if prior.features == "state_features" and prior.fixed.any():
        fixed = torch.from_numpy(prior.fixed)
        const = ((torch.from_numpy(prior.mean) - prior.model_norm[0]) / prior.model_norm[1]).float()
    x, ys, steps = y_prev[:, -1], [], []
    noise = eps.float() * torch.exp(torch.tensor(-float(bias)))  # (N, T, D): sigma_k exp(-b) eps is the deviation
    bit_noise = 1.6 * eps[:, :, cols].float()  # (N, T, 2)
    dd = None if d is None else d.float()
    for t in range(T):
        inp = x if dd is None else x + dd[:, t]
        params, state = model(inp[:, None], state)
        p = {k: v[:, 0] for k, v in params.items()}
        k = ((1.0 + bias) * p["logits"].double() + gumbel[:, t]).argmax(-1)  # (N,) Gumbel-max
        y = p["mu"][rows, k] + p["log_sigma"][rows, k].exp() * noise[:, t]  # (N, D)
        if "contact_logits" in p:
            bits = (p["contact_logits"] + bit_noise[:, t] > 0).float()
        else:
            bits = (y[:, cols] * std[cols] + mean[cols] > 0.5).float()
        y = torch.where(is_bit, bits @ place + shift, y)
        if prior.fixed_dims:
            y = torch.where(copied, x, y)
        if fixed is not None:
            y = torch.where(fixed, const, y)
        ys.append(y)
        steps.append(p)
        x = y
    y_all = torch.stack(ys, 1)  # (N, T, D); every frame's -log p(s_i | s_<i, d) at once   -- eq. (15), (8)
    nll = -prior.log_prob(y_all, {k: torch.stack([p[k] for p in steps], 1) for k in steps[0]}).double().sum(1)
    raw, toes = prior.from_model(torch.cat((y_prev, y_all), 1), skeleton, with_toes=True)
    P = prev.shape[1]
    raw, toes = raw[:, P:], None if toes is None else toes[:, P:]
    return (raw, nll, state, toes) if with_toes else (raw, nll, state)
