"""One time step of a stacked ``nn.LSTM``, written out with the module's own weights.

    g_l = W_ih,l x_l + b_ih,l + W_hh,l h_l + b_hh,l,    (i, f, g, o) = g_l split in four (PyTorch's order)
    c_l' = sigmoid(f) c_l + sigmoid(i) tanh(g),       h_l' = sigmoid(o) tanh(c_l'),     x_{l+1} = h_l'

The same function as ``lstm(x[:, None], state)`` (to float rounding, ~1e-7), for autoregressive models that
read one frame at a time.  Measured on the course machine (torch 2.13, one thread, 2 layers of width 256):
torch's fused LSTM took 1.1-3.6 ms per one-frame call at batch 1-4 and 9.6 ms per step forward + backward;
these few matrix products take 0.3-0.5 ms and 2.1-3.3 ms.  With it, lesson 04's online-control step
(`python -m course_lib.timings --only online --repeat 60`) went from a median of 324 ms to 131-144 ms per 10
frames (together with `WindowEnergy`'s cached start frames and one `log_prob` per rollout).
Unidirectional, with biases, no projections and no dropout between layers (what the course's models use);
anything else raises.
"""

from __future__ import annotations

import torch
from torch import nn

__all__ = ["lstm_step"]


def lstm_step(lstm: nn.LSTM, x: torch.Tensor, state=None):
    """x (N, input_size), state (h, C) each (layers, N, hidden) or None (zeros) -> (h of the top layer (N, hidden),
    (h, C) after the step)."""
    if lstm.bidirectional or not lstm.bias or lstm.proj_size or (lstm.dropout and lstm.training):
        raise ValueError("lstm_step: only a unidirectional LSTM with biases, no projection and no active dropout")
    if x.ndim != 2 or x.shape[1] != lstm.input_size:
        raise ValueError(f"lstm_step: x must be (N, {lstm.input_size}), got {tuple(x.shape)}")
    N, H = x.shape[0], lstm.hidden_size
    if state is None:
        zeros = x.new_zeros(lstm.num_layers, N, H)
        state = (zeros, zeros)
    h0, c0 = state
    hs, cs, inp = [], [], x
    for layer in range(lstm.num_layers):
        w_ih, w_hh = getattr(lstm, f"weight_ih_l{layer}"), getattr(lstm, f"weight_hh_l{layer}")
        b = getattr(lstm, f"bias_ih_l{layer}") + getattr(lstm, f"bias_hh_l{layer}")
        gates = torch.addmm(torch.addmm(b, inp, w_ih.t()), h0[layer], w_hh.t())  # (N, 4H)
        i, f, _, o = torch.sigmoid(gates).chunk(4, -1)  # one sigmoid for the three gates (g's is not used)
        c = f * c0[layer] + i * torch.tanh(gates[:, 2 * H:3 * H])
        inp = o * torch.tanh(c)
        hs.append(inp)
        cs.append(c)
    return inp, (torch.stack(hs), torch.stack(cs))
