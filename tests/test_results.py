"""course_lib.results: `rounded` (what every experiment writes to JSON), the lessons' results files, and the
shipped manifest holding provenance only (with the configs the lessons build)."""

import hashlib
import json
from pathlib import Path

import numpy as np

from course_lib.results import rounded


def test_rounded_rounds_floats_at_every_depth_and_keys_become_str():
    d = {1: np.float32(0.5), "a": [1.23456789, (2, np.float64(3.0000004))], "b": {"c": 0.1 + 0.2}}
    out = rounded(d)
    assert out == {"1": 0.5, "a": [1.234568, [2, 3.0]], "b": {"c": 0.3}}
    assert type(out["1"]) is float and type(out["a"][1][1]) is float
    assert json.loads(json.dumps(out)) == out
    assert rounded({"x": 1.23456789}, 3) == {"x": 1.235}
    assert rounded([7, "s", None, True]) == [7, "s", None, True]  # ints, strings, None, bools as given


# ----------------------------------------------------------------------------- the shipped manifest and results
# DESIGN.md "Layout": checkpoints/MANIFEST.json holds provenance only; what training and the lessons' evaluations
# measured is in results/<name>.json, one file per reproduction command.

MODEL_KEYS = {"file", "sha256", "bytes", "config", "model_class", "command", "course_lib_version"}
STATS_KEYS = {"file", "sha256", "bytes", "command", "course_lib_version"}


def _manifest(repo_root) -> dict:
    return json.loads((repo_root / "checkpoints" / "MANIFEST.json").read_text())


def test_manifest_is_small_and_holds_provenance_only(repo_root):
    path = repo_root / "checkpoints" / "MANIFEST.json"
    assert path.stat().st_size < 100_000, f"{path} is {path.stat().st_size} bytes: results belong in results/"
    for name, entry in _manifest(repo_root).items():
        if name.endswith("_stats"):
            assert set(entry) == STATS_KEYS, (name, sorted(entry))
        else:
            assert MODEL_KEYS <= set(entry) <= MODEL_KEYS | {"trained_on"}, (name, sorted(entry))


def test_every_checkpoint_file_has_an_entry_and_every_entry_a_file(repo_root):
    folder = repo_root / "checkpoints"
    files = {e["file"] for e in _manifest(repo_root).values()}
    assert all((folder / f).is_file() for f in files), sorted(f for f in files if not (folder / f).is_file())
    shipped = {p.name for p in folder.iterdir() if p.suffix in (".pt", ".npz")}
    assert shipped == files, {"without an entry": sorted(shipped - files), "without a file": sorted(files - shipped)}


def test_each_lesson_results_file_holds_the_metrics_of_its_checkpoints(repo_root):
    """results/<NAME>.json's checkpoints are the model entries of `python -m course_lib.reproduce NAME`, and each
    lesson's evaluation is where its readers look for it."""
    from course_lib.experiments import control, gmm_rnn, hvrnn, moglow, vae_lstm
    from course_lib.results import read_results, results_name

    manifest = _manifest(repo_root)
    lessons = {}
    for name, entry in manifest.items():
        if "config" in entry:  # a model (the stats files record no metrics)
            lessons.setdefault(results_name(entry["command"], name), set()).add(name)
    assert {"vae_lstm", "gmm_rnn", "hvrnn", "moglow"} <= set(lessons)
    for lesson, names in lessons.items():
        data = read_results(lesson)
        assert set(data["checkpoints"]) == names, lesson
        assert data["command"] == f"python -m course_lib.reproduce {lesson}" or (
            names == {lesson} and data["command"] == manifest[lesson]["command"]), lesson  # a classifier's own file
    assert "table1" in vae_lstm.recorded_results() and "per_seed" in gmm_rnn.recorded_results()
    assert "table2" in hvrnn.recorded_results() and "quality" in moglow.recorded_results()
    assert control.recorded_results()["gmm_rnn_sha256"] == manifest["gmm_rnn"]["sha256"]
    assert read_results("control")["checkpoints"] == {}  # lesson 04 trains nothing


def _config_dict(config) -> dict:
    import dataclasses

    return json.loads(json.dumps(dataclasses.asdict(config)))  # tuples -> lists, as the manifest stores them


def test_the_manifest_records_the_config_each_lesson_builds(repo_root):
    """Each lesson-02/03/05/06 checkpoint's recorded config is the one its experiment module builds today (so
    `python -m course_lib.reproduce NAME` would train the model the manifest describes).  Sizes that come from the
    data are taken from the shipped files: the GMM-RNN's unmodelled columns from the statistics it keeps, MoGlow's
    pose size from moglow_stats.npz.

    The refiners' balance band: their entries used to record RefinerConfig's defaults (d_loss_low/high 0.01 / 1.0)
    while `train_gan` ran the schedule on Lesson03Spec's [0.3, 0.6] band (5-round mean, r <= 40); the recorded
    r of every round of all six runs follows from their recorded D losses under that band and no other
    (test below), so the config now carries the band and the entries record it.

    MoGlow's coupling_net came after its four checkpoints were trained, with MLP couplings, the only kind then;
    their entries record "mlp", and their weights are MLP couplings (checked here)."""
    from course_lib.datasets import FixedDofs, load_stats
    from course_lib.experiments import gmm_rnn, hvrnn, moglow, vae_lstm

    manifest = _manifest(repo_root)
    built = {name: config for name, (_, config, _) in vae_lstm.lesson02_models().items()}
    built.update({name: spec.config for name, spec in hvrnn.model_specs().items()})
    mean, std = load_stats(repo_root / "checkpoints" / "moglow_stats.npz")
    pose_dim = int((~FixedDofs.from_stats(mean, std).mask[:63]).sum())
    built.update({name: moglow.config_for(name, pose_dim) for name in moglow.MODELS})
    spec = gmm_rnn.Lesson03Spec()
    rnn = gmm_rnn.load_models_rnn(repo_root / "checkpoints")
    built["gmm_rnn"] = gmm_rnn.rnn_config(spec, (rnn.feature_mean.double().numpy(), rnn.feature_std.double().numpy()))
    for seed in spec.seeds:
        for kind in ("GAN1", "GAN2"):
            built[gmm_rnn.refiner_file(kind, seed)[:-3]] = gmm_rnn.refiner_config(spec, contacts=kind == "GAN2")
    assert len(built) == 6 + 6 + 4 + 7
    for name, config in built.items():
        assert manifest[name]["config"] == _config_dict(config), name
    for name in moglow.MODELS:  # sha256-verified, weights_only; a strict load of the recorded kind of coupling
        model = moglow.load_model(name, repo_root / "checkpoints")
        recurrent = any(getattr(getattr(step, "coupling", None), "recurrent", False) for step in model.flow)
        assert recurrent == (manifest[name]["config"]["coupling_net"] == "lstm"), name


def test_the_refiners_were_trained_with_the_recorded_balance_band(repo_root):
    """The evidence for the band the refiner entries record: replaying each shipped refiner's recorded D losses
    through `AdversarialSchedule` with the recorded band, the spec's 5-round mean and cap gives its recorded
    r of every round; the paper's 0.01 / 1 (RefinerConfig's default) does not."""
    from course_lib.experiments import gmm_rnn
    from course_lib.models.refiner import AdversarialSchedule
    from course_lib.training import recorded_metrics

    spec, manifest = gmm_rnn.Lesson03Spec(), _manifest(repo_root)

    def replay(d_losses, low, high):
        schedule = AdversarialSchedule(75, 5, low, high, max_r_updates=spec.max_r_updates,
                                       smooth=spec.schedule_smooth)
        schedule.next_round()  # the warm-up
        r = []
        for d in d_losses:
            r.append(schedule.next_round()[0])
            schedule.record(d)
        return r

    for seed in spec.seeds:
        for kind in ("GAN1", "GAN2"):
            file = gmm_rnn.refiner_file(kind, seed)
            config = manifest[file[:-3]]["config"]
            history = recorded_metrics(repo_root / "checkpoints" / file)["history"]
            assert replay(history["d_loss"], config["d_loss_low"], config["d_loss_high"]) == history["r_updates"], file
            assert replay(history["d_loss"], 0.01, 1.0) != history["r_updates"], file


def test_git_commit_marks_changed_inputs_but_not_a_study_result(tmp_path):
    """Known answers in a throw-away repository: a clean tree gives the bare commit; a changed study result JSON
    (another study's output) still does; a changed module or a changed results/ file adds "+changes"."""
    import subprocess

    from course_lib.results import git_commit

    def run(*args):
        subprocess.run(["git", *args], cwd=tmp_path, check=True, capture_output=True)

    for rel in ("studies/06_moglow/a_results.json", "course_lib/m.py", "results/moglow.json"):
        (tmp_path / rel).parent.mkdir(parents=True, exist_ok=True)
        (tmp_path / rel).write_text("0\n")
    run("init", "-q")
    run("add", ".")
    run("-c", "user.name=t", "-c", "user.email=t@t", "commit", "-qm", "x")
    head = subprocess.run(["git", "rev-parse", "HEAD"], cwd=tmp_path, capture_output=True, text=True).stdout.strip()
    assert git_commit(tmp_path) == head
    (tmp_path / "studies/06_moglow/a_results.json").write_text("1\n")
    assert git_commit(tmp_path) == head
    for rel in ("course_lib/m.py", "results/moglow.json"):
        (tmp_path / rel).write_text("1\n")
        assert git_commit(tmp_path) == head + "+changes", rel
        run("checkout", "-q", "--", rel)
    assert git_commit(tmp_path / "course_lib").startswith(head)  # from a folder inside the checkout
    assert git_commit(tmp_path.parent / "nowhere").startswith("unknown")


def test_provenance_records_the_command_the_commit_and_every_verified_file(tmp_path):
    from course_lib.datasets import load_stats
    from course_lib.results import provenance

    load_stats(Path(__file__).resolve().parents[1] / "checkpoints" / "moglow_stats.npz")  # a verified load
    record = provenance(argv=["studies/06_moglow/some_study.py", "--out", "x.json"])
    assert record["command"] == "python studies/06_moglow/some_study.py --out x.json"
    assert len(record["commit"].removesuffix("+changes")) == 40
    shipped = json.loads((Path(__file__).resolve().parents[1] / "checkpoints" / "MANIFEST.json").read_text())
    assert record["checkpoints_sha256"]["moglow_stats.npz"] == shipped["moglow_stats"]["sha256"]
    (tmp_path / "w.pt").write_bytes(b"weights")
    named = provenance([tmp_path / "w.pt"], argv=["s.py"])["checkpoints_sha256"]
    assert named == {"w.pt": hashlib.sha256(b"weights").hexdigest()}


def test_write_study_result_rounds_and_adds_provenance(tmp_path):
    from course_lib.results import write_study_result

    path = write_study_result(tmp_path / "r.json", {"x": 1.23456789, "n": np.float32(2.5)}, digits=3,
                              checkpoints=[])
    text = path.read_text()
    record = json.loads(text)
    assert text.endswith("}\n") and record["x"] == 1.235 and record["n"] == 2.5
    assert set(record) == {"x", "n", "command", "commit", "checkpoints_sha256"} and record["checkpoints_sha256"] == {}
