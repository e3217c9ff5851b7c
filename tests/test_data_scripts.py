"""data_scripts/: --help, small runs into tmp_path, refusal without --force, same seed -> same bytes."""

import ast
import hashlib
import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from conftest import load_module

from course_lib import datasets as D

SCRIPTS = Path(__file__).resolve().parents[1] / "data_scripts"
NAMES = ("make_locomotion", "make_actions", "make_noisy")


def script(name):
    return load_module(SCRIPTS / f"{name}.py")


def sha(path):
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


@pytest.mark.parametrize("name", NAMES)
def test_help_and_thin_cli(name, capsys):
    with pytest.raises(SystemExit) as e:
        script(name).main(["--help"])
    assert e.value.code == 0
    text = capsys.readouterr().out
    for flag in ("--seed", "--out", "--fps", "--force"):
        assert flag in text
    assert "--clips" in text or "--subjects" in text
    tree = ast.parse((SCRIPTS / f"{name}.py").read_text())
    defined = [n.name for n in tree.body if isinstance(n, (ast.FunctionDef, ast.ClassDef))]
    assert defined == ["main"]  # the logic lives in course_lib


def test_locomotion_cli_is_deterministic_and_refuses_overwrite(tmp_path, capsys):
    env = dict(os.environ, TQDM_DISABLE="1", OMP_NUM_THREADS="1")
    a, b = tmp_path / "a" / "loco.npz", tmp_path / "b" / "loco.npz"
    run = subprocess.run([sys.executable, str(SCRIPTS / "make_locomotion.py"), "--clips", "4", "--subjects", "2",
                          "--seed", "3", "--out", str(a), "--workers", "1"], env=env, capture_output=True, text=True)
    assert run.returncode == 0, run.stderr
    script("make_locomotion").main(["--clips", "4", "--subjects", "2", "--seed", "3", "--out", str(b),
                                    "--workers", "1"])
    assert sha(a) == sha(b)  # same seed -> same bytes (in another process, to another path)
    ms = D.load_motions(a)
    assert len(ms) == 4 and {m.subject for m in ms} == {"s00", "s01"} and all(m.fps == 60 for m in ms)
    assert all(len(m) == 241 for m in ms) and ms[0].meta["speed"].shape == (241,)
    card = json.loads(a.with_name("loco.card.json").read_text())
    assert card["clips"] == 4 and sum(card["counts"]["action"].values()) == 4 and card["seed"] == 3
    assert card["ranges"]["duration_s"]["max"] == 4.0 and len(card["lacks"]) >= 5
    assert "What real motion capture has" in a.with_name("loco.card.md").read_text()
    assert D.read_file_meta(a)["clips"] == 4
    before = sha(a)
    with pytest.raises(SystemExit) as refused:
        script("make_locomotion").main(["--clips", "1", "--out", str(a)])
    assert refused.value.code == 2 and "--force" in capsys.readouterr().err and sha(a) == before
    script("make_locomotion").main(["--clips", "2", "--seed", "4", "--out", str(a), "--force", "--workers", "1"])
    assert len(D.load_motions(a)) == 2 and sha(a) != before
    assert sorted(os.listdir(a.parent)) == ["loco.card.json", "loco.card.md", "loco.npz"]  # no temp files


def test_worker_processes_keep_the_order():
    assert D._map(abs, list(range(-7, 3)), workers=2, desc="", progress=False) == [abs(i) for i in range(-7, 3)]


def test_actions_cli(tmp_path):
    out = tmp_path / "actions.npz"
    script("make_actions").main(["--subjects", "1", "--out", str(out), "--fps", "30", "--workers", "1"])
    ms = D.load_motions(out)
    assert sorted((m.action, m.style) for m in ms) == sorted((a, s) for a in D.ACTIONS for s in D.STYLES)
    assert all(m.fps == 30 and m.subject == "s00" for m in ms)
    first = sha(out)
    script("make_actions").main(["--subjects", "1", "--out", str(out), "--fps", "30", "--workers", "1", "--force"])
    assert sha(out) == first
    with pytest.raises(SystemExit) as e:
        script("make_actions").main(["--subjects", "1", "--out", str(out)])
    assert e.value.code == 2


def test_noisy_cli_keeps_clean_beside(tmp_path):
    clean = tmp_path / "loco.npz"
    script("make_locomotion").main(["--clips", "3", "--subjects", "1", "--out", str(clean), "--workers", "1"])
    script("make_noisy").main(["--input", str(clean), "--clips", "2"])
    out = tmp_path / "loco_noisy.npz"
    first = sha(out)
    noisy, pairs = D.load_noisy_pairs("loco_noisy", data_dir=tmp_path)
    assert len(noisy) == len(pairs) == 2
    ref = D.load_motions(clean)
    for n, c, r in zip(noisy, pairs, ref, strict=False):
        np.testing.assert_array_equal(c.rotations, r.rotations)
        assert n.meta["clean_index"] in (0, 1) and len(n) == len(c) and "dropped" in n.meta["noise"]
        err = np.linalg.norm(n.positions() - c.positions(), axis=-1).mean()
        assert 0.002 < err < 0.2  # jitter and spikes: millimetres to centimetres, not a different motion
    with pytest.raises(SystemExit):
        script("make_noisy").main(["--input", str(clean), "--clips", "2"])
    script("make_noisy").main(["--input", str(clean), "--clips", "2", "--force"])
    assert sha(out) == first
    D.save_motions(ref[:1], clean, overwrite=True)  # the clean file changed: pairs refuse
    with pytest.raises(ValueError, match="changed since"):
        D.load_noisy_pairs("loco_noisy", data_dir=tmp_path)


@pytest.mark.parametrize("args, words", [
    (["--subjects", "0"], "--subjects must be at least 1"),
    (["--subjects", "-2"], "--subjects must be at least 1"),
    (["--duration", "nan"], "must be positive finite numbers"),
    (["--duration", "inf"], "must be positive finite numbers"),
    (["--fps", "nan"], "must be positive finite numbers"),
])
def test_locomotion_cli_refuses_bad_numbers(args, words, tmp_path, capsys):
    with pytest.raises(SystemExit) as e:
        script("make_locomotion").main(["--clips", "1", "--out", str(tmp_path / "l.npz"), *args])
    assert e.value.code == 2 and words in capsys.readouterr().err
    assert not (tmp_path / "l.npz").exists()


def test_noisy_cli_cannot_destroy_the_clean_set(tmp_path, capsys):
    clean = tmp_path / "clean.npz"
    script("make_locomotion").main(["--clips", "2", "--subjects", "1", "--duration", "1", "--out", str(clean),
                                    "--workers", "1"])
    before = sha(clean)
    cases = [(["--out", str(clean), "--force"], "is the input file"),
             (["--out", str(tmp_path / "." / "clean.npz"), "--force"], "is the input file"),
             (["--clips", "-1"], "--clips must be at least 1"), (["--clips", "0"], "--clips must be at least 1"),
             (["--clips", "3"], "holds only 2 clips"), (["--fps", "nan"], "--fps must be a positive finite")]
    (tmp_path / "link.npz").symlink_to(clean)
    cases.append((["--out", str(tmp_path / "link.npz"), "--force"], "is the input file"))
    for args, words in cases:
        with pytest.raises(SystemExit) as e:
            script("make_noisy").main(["--input", str(clean), *args])
        assert e.value.code == 2 and words in capsys.readouterr().err, args
    assert sha(clean) == before and sorted(p.name for p in tmp_path.glob("*.npz")) == ["clean.npz", "link.npz"]
