"""course_lib.models.lstm_step: one written-out LSTM step equals torch's nn.LSTM (known answer), and the GMM-RNN
stepped one frame at a time equals its run over the whole sequence."""

import pytest
import torch
from torch import nn

from course_lib.models.gmm_rnn import GmmRnn, GmmRnnConfig
from course_lib.models.lstm_step import lstm_step


@pytest.mark.parametrize("N", [1, 3])
def test_lstm_step_equals_nn_lstm(N):
    torch.manual_seed(0)
    lstm = nn.LSTM(7, 5, num_layers=2, batch_first=True)
    x = torch.randn(N, 4, 7)
    ref, (h_ref, c_ref) = lstm(x)
    state, outs = None, []
    for t in range(4):
        out, state = lstm_step(lstm, x[:, t], state)
        outs.append(out)
    assert torch.allclose(torch.stack(outs, 1), ref, atol=1e-6)
    assert torch.allclose(state[0], h_ref, atol=1e-6) and torch.allclose(state[1], c_ref, atol=1e-6)


def test_lstm_step_gradients_equal_nn_lstm():
    torch.manual_seed(1)
    lstm = nn.LSTM(3, 4, num_layers=2, batch_first=True)
    x = torch.randn(2, 3, requires_grad=True)
    lstm(x[:, None])[0].sum().backward()
    g_ref = (x.grad.clone(), lstm.weight_hh_l1.grad.clone())
    x.grad, lstm.weight_hh_l1.grad = None, None
    lstm_step(lstm, x)[0].sum().backward()
    assert torch.allclose(x.grad, g_ref[0], atol=1e-6) and torch.allclose(lstm.weight_hh_l1.grad, g_ref[1], atol=1e-6)


def test_lstm_step_names_what_it_cannot_do():
    with pytest.raises(ValueError, match="unidirectional"):
        lstm_step(nn.LSTM(3, 4, bidirectional=True), torch.zeros(1, 3))
    with pytest.raises(ValueError, match=r"x must be \(N, 3\)"):
        lstm_step(nn.LSTM(3, 4), torch.zeros(1, 5))


def test_gmm_rnn_one_frame_at_a_time_equals_the_sequence():
    torch.manual_seed(2)
    model = GmmRnn(GmmRnnConfig.cpu(fc_width=16, lstm_width=16, out_width=16)).eval()
    x = torch.randn(2, 5, model.config.dim)
    full, (h, c) = model(x)
    state, mus = None, []
    for t in range(5):
        p, state = model(x[:, t:t + 1], state)
        mus.append(p["mu"])
    assert torch.allclose(torch.cat(mus, 1), full["mu"], atol=1e-5)
    assert torch.allclose(state[0], h, atol=1e-6) and torch.allclose(state[1], c, atol=1e-6)
