"""Tests of course_lib.training: the fit loop, seeding, clipping, checkpoints and the manifest."""

import json
import shutil
from dataclasses import dataclass

import numpy as np
import pytest
import torch

from course_lib.checksums import write_sidecar
from course_lib.training import (
    History,
    fit,
    load_checkpoint,
    record_metrics,
    save_checkpoint,
    seed_everything,
    sha256_file,
)


@dataclass
class TinyConfig:
    d_in: int = 3  # input features
    hidden: tuple = (8,)  # hidden widths (a tuple, to test JSON round trip)


class TinyRegressor(torch.nn.Module):
    """y = MLP(x); loss is the mean squared error plus a logged auxiliary term."""

    def __init__(self, config: TinyConfig):
        super().__init__()
        self.config = config
        self.net = torch.nn.Sequential(torch.nn.Linear(config.d_in, config.hidden[0]), torch.nn.Tanh(),
                                       torch.nn.Linear(config.hidden[0], 1))

    def forward(self, x):
        return self.net(x)

    def loss(self, batch):
        x, y = batch
        mse = ((self(x) - y) ** 2).mean()
        return {"loss": mse, "abs": (self(x) - y).abs().mean(), "vec": torch.stack([mse, 2 * mse])}


def _data(n=256, seed=0):
    g = torch.Generator().manual_seed(seed)
    x = torch.randn(n, 3, generator=g)
    y = (x @ torch.tensor([[1.0], [-2.0], [0.5]])) + 0.3
    return x, y


def _loader(seed=0):
    x, y = _data(seed=seed)
    ds = torch.utils.data.TensorDataset(x, y)
    return torch.utils.data.DataLoader(ds, batch_size=32, shuffle=True, generator=torch.Generator().manual_seed(1))


def test_fit_drives_regression_loss_down():
    seed_everything(0)
    model = TinyRegressor(TinyConfig())
    hist = fit(model, _loader(), epochs=40, lr=1e-2, progress=False)
    assert isinstance(hist, History)
    assert hist.num_steps == 40 * 8
    assert len(hist.epoch["loss"]) == 40
    assert hist.final("loss", 8) < hist.step["loss"][0] / 10
    assert hist.step["vec"][0].shape == (2,)
    assert "abs" in hist.scalar_keys() and "vec" not in hist.scalar_keys()


def test_callable_data_and_steps_and_rmsprop():
    x, y = _data()
    g = torch.Generator().manual_seed(3)

    def batch():
        idx = torch.randint(0, len(x), (32,), generator=g)
        return x[idx], y[idx]

    model = TinyRegressor(TinyConfig())
    hist = fit(model, batch, steps=150, steps_per_epoch=50, optimizer="rmsprop", lr=3e-3, progress=False, seed=0)
    assert hist.num_steps == 150 and len(hist.epoch["loss"]) == 3
    assert hist.final("loss", 10) < hist.step["loss"][0] / 10


def test_seed_gives_identical_histories():
    runs = []
    for _ in range(2):
        seed_everything(5)
        model = TinyRegressor(TinyConfig())
        runs.append(fit(model, _loader(), epochs=3, lr=1e-2, progress=False, seed=7).step["loss"])
    assert runs[0] == runs[1]
    seed_everything(6)
    other = fit(TinyRegressor(TinyConfig()), _loader(), epochs=3, lr=1e-2, progress=False, seed=8).step["loss"]
    assert other != runs[0]


def test_grad_clipping_bounds_the_update():
    seed_everything(0)
    model = TinyRegressor(TinyConfig())

    class Huge(torch.nn.Module):
        def __init__(self):
            super().__init__()
            self.inner = model

        def loss(self, batch):
            return {"loss": 1e4 * self.inner.loss(batch)["loss"]}

    before = torch.nn.utils.parameters_to_vector(model.parameters()).detach().clone()
    norms = []

    def check(info):
        grads = [p.grad for p in info.model.parameters() if p.grad is not None]
        norms.append(torch.linalg.vector_norm(torch.stack([torch.linalg.vector_norm(g) for g in grads])).item())

    hist = fit(Huge(), _loader(), steps=1, lr=1.0, grad_clip=0.1, progress=False, callback=check,
               optimizer=lambda p, lr: torch.optim.SGD(p, lr=lr))
    after = torch.nn.utils.parameters_to_vector(model.parameters()).detach()
    assert hist.step["grad_norm"][0] > 100  # the raw gradient is large ...
    assert norms[0] == pytest.approx(0.1, rel=1e-4)  # ... clipped to 0.1
    assert torch.linalg.vector_norm(after - before).item() == pytest.approx(0.1, rel=1e-4)


def test_lr_schedule_and_callback_stop():
    model = TinyRegressor(TinyConfig())
    hist = fit(model, _loader(), epochs=4, lr=1e-2, lr_schedule=lambda e: 0.5**e, progress=False,
               callback=lambda info: info.step >= 20)
    assert hist.num_steps == 20
    assert hist.lr[0] == pytest.approx(1e-2) and hist.lr[8] == pytest.approx(5e-3) and hist.lr[19] == pytest.approx(
        2.5e-3)


def test_fit_errors_are_clear():
    model = TinyRegressor(TinyConfig())
    with pytest.raises(ValueError, match="steps= or epochs="):
        fit(model, _loader(), progress=False)

    class NaNModel(TinyRegressor):
        def loss(self, batch):
            return {"loss": self(batch[0]).mean() * float("nan")}

    with pytest.raises(FloatingPointError, match="step 0"):
        fit(NaNModel(TinyConfig()), _loader(), steps=2, progress=False)

    class NoLoss(TinyRegressor):
        def loss(self, batch):
            return {"mse": self(batch[0]).mean()}

    with pytest.raises(KeyError, match="'loss'"):
        fit(NoLoss(TinyConfig()), _loader(), steps=2, progress=False)


def test_checkpoint_round_trip_identical_outputs(tmp_path):
    seed_everything(0)
    config = TinyConfig(d_in=3, hidden=(16,))
    model = TinyRegressor(config)
    fit(model, _loader(), steps=20, progress=False)
    path = tmp_path / "tiny.pt"
    entry = save_checkpoint(model, config, path, command="python -m tiny", metrics={"mse": np.float32(0.25)})
    manifest = json.loads((tmp_path / "MANIFEST.json").read_text())
    assert manifest["tiny"]["sha256"] == sha256_file(path) == entry["sha256"]
    assert manifest["tiny"]["file"] == "tiny.pt" and manifest["tiny"]["bytes"] == path.stat().st_size
    assert manifest["tiny"]["config"] == {"d_in": 3, "hidden": [16]}
    assert manifest["tiny"]["command"] == "python -m tiny" and "metrics" not in manifest["tiny"]  # provenance only
    results = json.loads((tmp_path / "results" / "tiny.json").read_text())  # the metrics: results/<name>.json
    assert results == {"command": "python -m tiny", "checkpoints": {"tiny": {"mse": 0.25}}}
    loaded = load_checkpoint(path, TinyRegressor, TinyConfig)
    assert loaded.config == config and not loaded.training
    x = torch.randn(5, 3)
    assert torch.equal(loaded(x), model(x))


def test_manifest_records_where_a_checkpoint_was_trained_and_a_re_save_keeps_it(tmp_path):
    """A fresh save records the training environment (torch version, CPU kernels); record_metrics keeps the
    entry's own, and an entry saved before the field existed stays without one (unknown, not this machine)."""
    model = TinyRegressor(TinyConfig())
    path = tmp_path / "e.pt"
    entry = save_checkpoint(model, TinyConfig(), path, command="make e")
    assert entry["trained_on"]["torch"] == torch.__version__
    assert entry["trained_on"]["cpu_capability"] == torch.backends.cpu.get_cpu_capability()
    manifest_path = tmp_path / "MANIFEST.json"
    manifest = json.loads(manifest_path.read_text())
    manifest["e"]["trained_on"] = {"torch": "0.0-elsewhere"}
    manifest_path.write_text(json.dumps(manifest))
    assert record_metrics(path, TinyRegressor, TinyConfig, mse=1.0)["trained_on"] == {"torch": "0.0-elsewhere"}
    del manifest["e"]["trained_on"]
    manifest_path.write_text(json.dumps(manifest))
    assert "trained_on" not in record_metrics(path, TinyRegressor, TinyConfig, mse=2.0)


def test_checkpoint_is_weights_only_loadable(tmp_path):
    model = TinyRegressor(TinyConfig())
    save_checkpoint(model, TinyConfig(), tmp_path / "w.pt", command="make w")
    payload = torch.load(tmp_path / "w.pt", weights_only=True)
    assert set(payload) >= {"state_dict", "config_json", "course_lib_version"}
    assert json.loads(payload["config_json"]) == {"d_in": 3, "hidden": [8]}


def test_refuses_overwrite_and_detects_tampering(tmp_path):
    model = TinyRegressor(TinyConfig())
    path = tmp_path / "a.pt"
    save_checkpoint(model, TinyConfig(), path, command="make a")
    with pytest.raises(FileExistsError, match="overwrite=True"):
        save_checkpoint(model, TinyConfig(), path, command="make a")
    save_checkpoint(model, TinyConfig(), tmp_path / "b.pt", command="make b")
    assert set(json.loads((tmp_path / "MANIFEST.json").read_text())) == {"a", "b"}
    with open(path, "ab") as f:
        f.write(b"junk")
    with pytest.raises(ValueError, match="sha256 mismatch.*make a"):
        load_checkpoint(path, TinyRegressor, TinyConfig)
    save_checkpoint(model, TinyConfig(), path, command="make a", overwrite=True)
    assert isinstance(load_checkpoint(path, TinyRegressor, TinyConfig), TinyRegressor)


def test_history_plot_and_epoch_means():
    h = History()
    h.log_step({"loss": 1.0, "v": np.array([1.0, 2.0])})
    h.log_step({"loss": 3.0, "v": np.array([3.0, 4.0])})
    h.end_epoch()
    assert h.epoch["loss"] == [2.0] and np.allclose(h.epoch["v"][0], [2.0, 3.0])
    import matplotlib

    matplotlib.use("Agg")
    ax = h.plot()
    assert len(ax.lines) == 1
    with pytest.raises(KeyError, match="never logged"):
        h.plot(keys=["nope"])


def _flip_a_byte(path):
    data = bytearray(path.read_bytes())
    data[len(data) // 2] ^= 0xFF
    path.write_bytes(bytes(data))


def test_every_load_verifies_a_sha256(tmp_path):
    """Manifest entry, else the sidecar save_checkpoint wrote; neither -> refuse, saying how to proceed."""
    model, config = TinyRegressor(TinyConfig()), TinyConfig()
    path = tmp_path / "ckpt" / "a.pt"
    save_checkpoint(model, config, path, command="make a")
    assert (tmp_path / "ckpt" / "a.pt.sha256").read_text() == f"{sha256_file(path)}  a.pt\n"
    # a copy elsewhere with its sidecar (no manifest there) loads; corrupted, it is refused
    (tmp_path / "copy").mkdir()
    copy = tmp_path / "copy" / "a.pt"
    shutil.copy(path, copy)
    shutil.copy(path.with_name("a.pt.sha256"), copy.with_name("a.pt.sha256"))
    assert isinstance(load_checkpoint(copy, TinyRegressor, TinyConfig), TinyRegressor)
    _flip_a_byte(copy)
    with pytest.raises(ValueError, match="sha256 mismatch .* sidecar a.pt.sha256"):
        load_checkpoint(copy, TinyRegressor, TinyConfig)
    # a renamed copy: the manifest does not list it and it has no sidecar
    renamed = path.with_name("renamed.pt")
    shutil.copy(path, renamed)
    with pytest.raises(ValueError, match="cannot verify .*renamed.pt: .*MANIFEST.json has no entry 'renamed' and "
                                         "there is no sidecar .*write_sidecar.*verify=False"):
        load_checkpoint(renamed, TinyRegressor, TinyConfig)
    lone = tmp_path / "lone.pt"
    shutil.copy(path, lone)
    with pytest.raises(ValueError, match="MANIFEST.json does not exist and there is no sidecar"):
        load_checkpoint(lone, TinyRegressor, TinyConfig)
    assert isinstance(load_checkpoint(lone, TinyRegressor, TinyConfig, verify=False), TinyRegressor)
    write_sidecar(lone)
    assert isinstance(load_checkpoint(lone, TinyRegressor, TinyConfig), TinyRegressor)
    lone.with_name("lone.pt.sha256").write_text("not a hash\n")
    with pytest.raises(ValueError, match="is not a sha256 sidecar"):
        load_checkpoint(lone, TinyRegressor, TinyConfig)


def test_bad_manifests_are_clear_errors(tmp_path):
    model, config = TinyRegressor(TinyConfig()), TinyConfig()
    path = tmp_path / "a.pt"
    save_checkpoint(model, config, path, command="make a")
    manifest = tmp_path / "MANIFEST.json"
    table = json.loads(manifest.read_text())
    del table["a"]["sha256"]
    manifest.write_text(json.dumps(table))
    with pytest.raises(ValueError, match="entry 'a' has no valid sha256.*rebuild it with: make a"):
        load_checkpoint(path, TinyRegressor, TinyConfig)
    manifest.write_text('{"a": {"sha256": ')
    with pytest.raises(ValueError, match="MANIFEST.json is not valid JSON .*git checkout"):
        load_checkpoint(path, TinyRegressor, TinyConfig)
    manifest.write_text("[1, 2]")
    with pytest.raises(ValueError, match="MANIFEST.json is malformed"):
        load_checkpoint(path, TinyRegressor, TinyConfig)


def test_load_classifier_with_a_path_verifies_it(tmp_path, repo_root):
    from course_lib.evaluation.classifiers import load_classifier

    shipped = repo_root / "checkpoints" / "action_classifier.pt"
    copy = tmp_path / "action_classifier.pt"
    shutil.copy(shipped, copy)
    with pytest.raises(ValueError, match="cannot verify"):
        load_classifier("action", path=copy)
    copy.with_name("action_classifier.pt.sha256").write_text(f"{sha256_file(shipped)}  action_classifier.pt\n")
    load_classifier("action", path=copy)
    _flip_a_byte(copy)
    with pytest.raises(ValueError, match="sha256 mismatch"):
        load_classifier("action", path=copy)


def test_record_metrics_keeps_weights_config_and_command(tmp_path):
    from course_lib.training import record_metrics, recorded_metrics

    torch.manual_seed(0)
    model, config = TinyRegressor(TinyConfig()), TinyConfig()
    path = tmp_path / "tiny.pt"
    before = save_checkpoint(model, config, path, command="python -m tiny", metrics={"mse": 0.25})
    manifest = (tmp_path / "MANIFEST.json").read_bytes()
    after = record_metrics(path, TinyRegressor, TinyConfig, tables={"FID": 12.5})
    assert recorded_metrics(path) == {"mse": 0.25, "tables": {"FID": 12.5}}
    assert after == before and (tmp_path / "MANIFEST.json").read_bytes() == manifest  # the manifest untouched
    assert sha256_file(path) == before["sha256"]  # the file too
    again = load_checkpoint(path, TinyRegressor, TinyConfig)
    for a, b in zip(model.state_dict().values(), again.state_dict().values(), strict=True):
        torch.testing.assert_close(a, b, rtol=0, atol=0)
    with pytest.raises(KeyError, match="no entry"):
        recorded_metrics(tmp_path / "other.pt")


def test_metrics_go_to_the_lesson_results_file_of_the_command(tmp_path, repo_root):
    """A lesson's checkpoints share results/<NAME>.json (python -m course_lib.reproduce NAME), under their
    manifest names; a re-save without metrics drops the stale ones; other checkpoint folders keep their own
    results/ (the repository's results/ is only for its own checkpoints/)."""
    from course_lib.results import read_results, results_file
    from course_lib.training import recorded_metrics

    model, config = TinyRegressor(TinyConfig()), TinyConfig()
    command = "python -m course_lib.reproduce lesson"
    save_checkpoint(model, config, tmp_path / "a.pt", command=command, metrics={"steps": 3})
    save_checkpoint(model, config, tmp_path / "b.pt", command=command, metrics={"curve": [1.0, 0.5]})
    assert results_file("lesson", tmp_path) == tmp_path / "results" / "lesson.json"
    assert read_results("lesson", tmp_path) == {"command": command,
                                                "checkpoints": {"a": {"steps": 3}, "b": {"curve": [1.0, 0.5]}}}
    assert recorded_metrics(tmp_path / "b.pt") == {"curve": [1.0, 0.5]}
    save_checkpoint(model, config, tmp_path / "a.pt", command=command, overwrite=True)
    assert recorded_metrics(tmp_path / "a.pt") == {} and set(read_results("lesson", tmp_path)["checkpoints"]) == {"b"}
    assert results_file("gmm_rnn") == results_file("gmm_rnn", repo_root / "checkpoints") == \
        repo_root / "results" / "gmm_rnn.json"  # the repository's own checkpoints/: its results/

