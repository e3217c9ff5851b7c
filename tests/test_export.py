"""course_lib.export: lesson 06's MoGlow sampling step in ONNX, checked in onnxruntime (CPU) against torch."""

from __future__ import annotations

import numpy as np
import pytest
import torch

onnx = pytest.importorskip("onnx")
ort = pytest.importorskip("onnxruntime")

from course_lib import export as X  # noqa: E402
from course_lib.experiments import moglow as lesson06  # noqa: E402


@pytest.fixture(scope="module")
def exported(tmp_path_factory):
    model = lesson06.load_model("moglow")  # the pretrained checkpoint, sha256-verified
    return model, X.export_step(model, tmp_path_factory.mktemp("onnx") / "step.onnx")


def _inputs(model, batch, seed=1):
    c = model.config
    g = torch.Generator().manual_seed(seed)
    return (0.5 * torch.randn(batch, c.tau, c.pose_dim, generator=g), 0.5 * torch.randn(batch, c.tau, 3, generator=g),
            0.5 * torch.randn(batch, 30, 3, generator=g), torch.randn(batch, 30, c.pose_dim, generator=g))


def test_opset_and_no_inverse_in_the_graph(exported):
    _, path = exported
    graph = onnx.load(str(path))
    assert max(o.version for o in graph.opset_import if o.domain in ("", "ai.onnx")) >= 17
    ops = {n.op_type for n in graph.graph.node}
    assert "LSTM" in ops and not ops & {"Inverse", "Det"}, ops


def test_weight_inverse_is_a_stored_constant(exported):
    model, path = exported
    graph = onnx.load(str(path))
    consts = [onnx.numpy_helper.to_array(t) for t in graph.graph.initializer]
    consts += [onnx.numpy_helper.to_array(a.t) for n in graph.graph.node if n.op_type == "Constant"
               for a in n.attribute if a.name == "value"]
    w_inv = torch.linalg.inv(model.flow[0].linear.weight().detach().double()).float().numpy()
    D = model.config.pose_dim
    square = [c for c in consts if c.shape == (D, D)]
    assert any(np.abs(c - w_inv).max() < 1e-6 or np.abs(c - w_inv.T).max() < 1e-6 for c in square), \
        "step 1's W^-1 is not among the graph's constants"
    assert not any(np.abs(c - model.flow[0].linear.weight().detach().numpy()).max() < 1e-6 for c in square), \
        "W itself is in the graph: sampling needs only W^-1"


@pytest.mark.parametrize("batch", [1, 4])
def test_dynamic_batch_matches_torch(exported, batch):
    model, path = exported  # traced at batch 2, run at 1 and 4
    x0, c0, controls, z = _inputs(model, batch)
    ref = X.rollout_torch(model, x0, c0, controls, z).numpy()
    got = X.rollout_onnx(path, x0, c0, controls, z)
    assert got.shape == ref.shape == (batch, 30, model.config.pose_dim)
    assert np.abs(got - ref).max() < 1e-4  # standardised units; a wrong W^-1 or a transposed one is O(1)


def test_parity_in_metres(exported):
    model, path = exported
    from course_lib.datasets import FixedDofs, load_stats

    mean, std = load_stats(lesson06.stats_file())
    fixed = FixedDofs.from_stats(mean, std).mask[:63]
    p = X.parity(model, path, std[:63][~fixed], frames=60)
    assert p["single_step_max_abs_m"] <= 1e-5 and p["rollout_max_abs_m"] <= 1e-4, p
    assert p["first_parting_frame"] is None


def test_export_refuses_an_old_opset(exported, tmp_path):
    with pytest.raises(ValueError, match="opset"):
        X.export_step(exported[0], tmp_path / "old.onnx", opset=16)


def test_export_refuses_recurrent_couplings(tmp_path):
    from course_lib.models.moglow import MoGlow, MoGlowConfig

    model = MoGlow(MoGlowConfig(6, 3, 3, steps=2, hidden=8, layers=1, coupling_hidden=8, coupling_net="lstm"))
    with pytest.raises(ValueError, match="MLP couplings"):
        X.export_step(model, tmp_path / "recurrent.onnx")
    assert not (tmp_path / "recurrent.onnx").exists()


def test_control_sequence_reaches_the_commands():
    raw = X.control_sequence(fps=20.0)
    assert raw.shape == (240, 3)
    ends = np.cumsum([round(s * 20) for _, s, *_ in X.SELFTEST_PHASES]) - 1
    for (_, _, *cmd), t in zip(X.SELFTEST_PHASES, ends, strict=True):
        np.testing.assert_allclose(raw[t], cmd, atol=0.01)  # settled by each phase's end (lag 0.25 s)
    turn = raw[ends[1] + 1: ends[2] + 1, 2].sum() / 20.0  # heading change over the turn phase, rad
    assert 0.75 * 2.4 < turn < 2.4
