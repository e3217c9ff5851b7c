"""Packaging: pyproject.toml and environment.yml pin the same packages; course_lib imports cleanly;
the Makefile's helpers (tools/build_site.py, tools/reproduce.py) do what `make course`/`make reproduce` need."""

from __future__ import annotations

import importlib.metadata
import json
import os
import re
import subprocess
import sys
import tomllib
from pathlib import Path

import pytest
import yaml

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO / "tools"))

import build_site  # noqa: E402  (tools/ is not a package)
import reproduce  # noqa: E402

PIN = re.compile(r"^([A-Za-z0-9][A-Za-z0-9._-]*)==([A-Za-z0-9.+!-]+)$")


def exact_pins(requirements: list[str]) -> dict[str, str]:
    """['Torch==2.13.0', ...] -> {'torch': '2.13.0'}; ValueError naming any requirement that is not `name==version`."""
    pins = {}
    for req in requirements:
        match = PIN.match(req.replace(" ", ""))
        if match is None:
            raise ValueError(f"{req!r} is not an exact pin name==version")
        pins[re.sub(r"[-_.]+", "-", match.group(1)).lower()] = match.group(2)
    return pins


def pin_differences(a: dict[str, str], b: dict[str, str]) -> list[str]:
    """Human-readable differences between two {name: version} dicts (empty when equal)."""
    out = [f"{name}: {a.get(name)} vs {b.get(name)}" for name in sorted(set(a) | set(b)) if a.get(name) != b.get(name)]
    return out


def pyproject() -> dict:
    return tomllib.loads((REPO / "pyproject.toml").read_text(encoding="utf-8"))


def environment() -> dict:
    return yaml.safe_load((REPO / "environment.yml").read_text(encoding="utf-8"))


def environment_pip(env: dict) -> list[str]:
    """The `pip:` list of environment.yml."""
    pips = [item["pip"] for item in env["dependencies"] if isinstance(item, dict) and "pip" in item]
    assert len(pips) == 1, "environment.yml must have exactly one `pip:` section"
    return pips[0]


def test_exact_pins_parses_and_rejects():
    assert exact_pins(["Scikit_Image==0.26.0", "torch == 2.13.0"]) == {"scikit-image": "0.26.0", "torch": "2.13.0"}
    for bad in ["torch>=2.13", "torch", "torch==2.13.*,<3"]:
        with pytest.raises(ValueError, match="not an exact pin"):
            exact_pins([bad])
    assert pin_differences({"a": "1", "b": "2"}, {"a": "1", "b": "3", "c": "4"}) == ["b: 2 vs 3", "c: None vs 4"]


def test_pyproject_pins_every_dependency_exactly():
    project = pyproject()["project"]
    runtime = exact_pins(project["dependencies"])
    dev = exact_pins(project["optional-dependencies"]["dev"])
    assert runtime["torch"] == "2.13.0", "torch must stay 2.13.0 (the CPU build on local disk)"
    assert not set(runtime) & set(dev), "a package is pinned both in dependencies and in [dev]"


def test_environment_yml_mirrors_pyproject():
    project = pyproject()["project"]
    env = environment()
    wanted = exact_pins(project["dependencies"] + project["optional-dependencies"]["dev"])
    pip_list = environment_pip(env)
    assert "-e ." in pip_list, "environment.yml must install course_lib itself (`-e .`)"
    got = exact_pins([req for req in pip_list if req != "-e ."])
    assert pin_differences(wanted, got) == [], "pyproject.toml (left) and environment.yml (right) disagree"
    assert "python=3.11" in env["dependencies"] and "pip" in env["dependencies"]
    assert project["requires-python"].startswith(">=3.11")  # tomllib; the on-disk torch wheel is cp311


def test_tqdm_finds_ipywidgets_for_notebook_progress_bars():
    # without ipywidgets every notebook printed "TqdmWarning: IProgress not found" and drew text bars
    import tqdm.notebook

    assert tqdm.notebook.IProgress is not None
    assert "ipywidgets" in exact_pins(pyproject()["project"]["dependencies"])


def test_version_matches_pyproject():
    import course_lib

    version = pyproject()["project"]["version"]
    assert course_lib.__version__ == version
    assert importlib.metadata.version("course_lib") == version, "installed metadata is stale: run `make setup`"


# The child imports the third-party libraries first (their caches and messages are not ours),
# snapshots files, environment and global RNG/torch state, prints a marker, then imports every
# course_lib module.  Anything printed after the marker, or any change, is an import-time side effect.
IMPORT_PROBE = r"""
import importlib, json, os, pkgutil, sys
package_name, third_party, watched = sys.argv[2], sys.argv[3].split(","), sys.argv[4:]
for lib in third_party:
    importlib.import_module(lib)
import numpy as np, torch

# files this process opens for writing under the watched folders (an audit hook sees only this process:
# other tests running beside this one may write data/ caches meanwhile, and teammates may edit course_lib)
roots = [os.path.realpath(r) + os.sep for r in watched]
written = {}

def audit(event, args):
    if event == "open" and args and isinstance(args[0], (str, bytes, os.PathLike)):
        path, mode, flags = args[0], args[1] or "", args[2] or 0
        writes = any(ch in str(mode) for ch in "wax+") or flags & (os.O_WRONLY | os.O_RDWR | os.O_CREAT)
        full = os.path.realpath(os.fsdecode(path))
        if writes and any(full.startswith(r) for r in roots) and "__pycache__" not in full:
            written[full] = ""

sys.addaudithook(audit)

def state():
    return {"files": dict(written), "env": dict(os.environ), "np_rng": repr(np.random.get_state()),
            "torch_seed": torch.initial_seed(), "torch_dtype": str(torch.get_default_dtype()),
            "torch_threads": torch.get_num_threads(), "cwd": os.getcwd()}

before = state()
print("---MARKER---", flush=True); print("---MARKER---", file=sys.stderr, flush=True)
package = importlib.import_module(package_name)
names = [m.name for m in pkgutil.walk_packages(package.__path__, package_name + ".") if not m.name.endswith("__main__")]
for name in names:
    importlib.import_module(name)
sys.stdout.flush(); sys.stderr.flush()
after = state()
changed = {key: (sorted(set(after[key].items()) - set(before[key].items())) if isinstance(before[key], dict)
                 else [before[key], after[key]]) for key in before if before[key] != after[key]}
changed = {key: value for key, value in changed.items() if value}
with open(sys.argv[1], "w") as fh:
    json.dump({"modules": [package_name] + names, "changed": changed}, fh, default=str)
"""


THIRD_PARTY = ["numpy", "scipy", "torch", "jax", "jax.numpy", "matplotlib", "matplotlib.pyplot", "pyvista",
               "skimage", "imageio", "PIL", "tqdm"]


def import_probe(package: str, tmp_path: Path, watched: list[Path], pythonpath: Path | None = None,
                 third_party: tuple[str, ...] = ("numpy", "torch")) -> dict:
    """Import `third_party`, then every module of `package`, in a fresh interpreter (cwd = an empty folder):
    {'modules', 'changed', 'stdout', 'stderr'}, the output being only what was printed during the package's imports."""
    cwd, report = tmp_path / "cwd", tmp_path / "report.json"
    cwd.mkdir()
    env = {k: v for k, v in os.environ.items() if not k.startswith(("VTK_", "PYVISTA_", "COURSE_MODE"))}
    env.update(MPLCONFIGDIR=str(tmp_path / "mpl"), MPLBACKEND="Agg")
    if pythonpath is not None:
        env["PYTHONPATH"] = str(pythonpath)
    args = [sys.executable, "-c", IMPORT_PROBE, str(report), package, ",".join(third_party), str(cwd)]
    args += [str(path) for path in watched]
    proc = subprocess.run(args, cwd=cwd, env=env, capture_output=True, text=True, timeout=180)
    assert proc.returncode == 0, f"importing {package} failed:\n{proc.stderr[-3000:]}"
    result = json.loads(report.read_text())
    result["stdout"] = proc.stdout.split("---MARKER---\n", 1)[1]
    result["stderr"] = proc.stderr.split("---MARKER---\n", 1)[1]
    return result


def test_import_probe_catches_side_effects(tmp_path):
    pkg = tmp_path / "src" / "noisy_pkg"
    pkg.mkdir(parents=True)
    (pkg / "__init__.py").write_text("")
    (pkg / "chatty.py").write_text("import os, sys\nprint('hello')\nsys.stderr.write('warn\\n')\n"
                                   "os.environ['PYVISTA_OFF_SCREEN'] = 'true'\nopen('out.txt', 'w').close()\n")
    (pkg / "seeding.py").write_text("import numpy, torch\nnumpy.random.seed(0)\ntorch.manual_seed(0)\n"
                                    "torch.set_default_dtype(torch.float64)\n")
    result = import_probe("noisy_pkg", tmp_path, [], pythonpath=tmp_path / "src")
    assert result["modules"] == ["noisy_pkg", "noisy_pkg.chatty", "noisy_pkg.seeding"]
    assert (result["stdout"], result["stderr"]) == ("hello\n", "warn\n")
    assert set(result["changed"]) == {"files", "env", "np_rng", "torch_seed", "torch_dtype"}
    assert result["changed"]["env"] == [["PYVISTA_OFF_SCREEN", "true"]]


def test_every_module_imports_without_side_effects(tmp_path):
    result = import_probe("course_lib", tmp_path, [REPO / "course_lib", REPO / "data"], third_party=THIRD_PARTY)
    assert result["stdout"] == "", "course_lib printed to stdout at import"
    assert result["stderr"] == "", "course_lib printed to stderr at import"
    assert result["changed"] == {}, f"importing course_lib changed global state: {result['changed']}"
    expected = {f"course_lib.{p.stem}" for p in (REPO / "course_lib").glob("*.py") if p.stem != "__init__"}
    assert expected - {"course_lib.__main__"} <= set(result["modules"])


def write_notebook(path: Path, *cells: str) -> None:
    cells = [{"cell_type": "markdown", "metadata": {}, "source": [c]} for c in cells]
    path.write_text(json.dumps({"cells": cells, "metadata": {}, "nbformat": 4, "nbformat_minor": 5}))


HEAD = ("# Lesson 02 — A recurrent VAE (Habibie et al. 2017)\n\n"
        "**Prerequisites:** lesson 01 (the ELBO) and\nPyTorch's LSTM.  \n**Time:** about 2 hours.\n\n"
        "**Objectives.** After this lesson you can\n\n1. build the modified LSTM\n   (eq. 7-9);\n"
        "2. train it.\n\nThe data are synthetic.")
SUMMARY = ("## 12. Summary\n\n* **Built:** the VAE-LSTM.\n* **What holds** (section 5): long-horizon error\n"
           "  stays low.\n* **What fails:** prior samples are alike.\n* **Steering:** drawn controls drift.")


def test_build_site_reads_each_lesson_for_the_landing_page(tmp_path):
    nb = tmp_path / "02_vae_lstm.ipynb"
    write_notebook(nb, HEAD, "## 1. Text", SUMMARY)
    info = build_site.lesson_info(nb)
    assert info["title"] == "Lesson 02 — A recurrent VAE (Habibie et al. 2017)" and info["name"] == "02_vae_lstm"
    assert info["prerequisites"] == "lesson 01 (the ELBO) and PyTorch's LSTM."  # up to **Time:**, on one line
    assert info["time"] == "about 2 hours."
    assert info["objectives"] == "After this lesson you can\n1. build the modified LSTM\n   (eq. 7-9);\n2. train it."
    assert info["paper"] == ["**What holds** (section 5): long-horizon error stays low.",
                             "**What fails:** prior samples are alike."]  # not "Built" or "Steering"
    bare = tmp_path / "03_x.ipynb"
    write_notebook(bare, "# Lesson 03\n\n**Objectives.** After this you can\n\n1. one thing.")
    info3 = build_site.lesson_info(bare)
    assert (info3["prerequisites"], info3["time"], info3["paper"]) == (None, None, [])
    page = build_site.landing_page([info, info3], "ci")
    assert page.index("Lesson 02 —") < page.index("## Lesson 03")  # the order given (file-name order)
    assert "{doc}`Open the lesson <02_vae_lstm>`" in page and "* **What fails:** prior samples are alike." in page
    assert "**Time:** (not stated in the lesson)" in page and "no paper is reproduced" in page
    assert page.count("```{toctree}") == 1 and "COURSE_MODE=ci" in page
    assert "\n02_vae_lstm\n03_x\nreproduction_notes\nstudies_02_vae_lstm\n" in page and "\ntroubleshooting\n```" in page


def test_reproduce_runs_manifest_commands_in_order(tmp_path, capsys):
    log = tmp_path / "log.txt"
    manifest = tmp_path / "checkpoints" / "MANIFEST.json"
    manifest.parent.mkdir()
    append = "python -c \"import sys; open('log.txt', 'a').write(sys.argv[1] + chr(10))\" "
    entries = {"b_model": {"file": "b.pt", "command": append + "b"}, "a_model": {"command": append + "a"}}
    manifest.write_text(json.dumps(entries))
    assert reproduce.main(["--manifest", str(manifest)]) == 0
    assert log.read_text().splitlines() == ["b", "a"]  # manifest order, run from the manifest's parent folder
    assert "reproduce: [b_model] $ python -c" in capsys.readouterr().out
    assert reproduce.main(["--manifest", str(manifest), "--only", "a_model"]) == 0
    assert log.read_text().splitlines() == ["b", "a", "a"]
    entries["c_model"] = {"command": append + "b"}  # a command that rebuilds two entries runs once
    manifest.write_text(json.dumps(entries))
    capsys.readouterr()
    assert reproduce.main(["--manifest", str(manifest)]) == 0
    assert log.read_text().splitlines() == ["b", "a", "a", "b", "a"]
    assert "reproduce: [b_model, c_model] $ python -c" in capsys.readouterr().out


def test_make_reproduce_reruns_every_lesson_including_those_without_checkpoints(capsys):
    """Every lesson's reproduction command is run by `make reproduce`: the manifest's, and lesson 04's (it trains
    nothing, so only its results file names it)."""
    assert reproduce.main(["--manifest", str(REPO / "checkpoints" / "MANIFEST.json"), "--dry-run"]) == 0
    out = capsys.readouterr().out
    for name in ("vae_lstm", "gmm_rnn", "control", "hvrnn", "moglow"):
        assert out.count(f"$ python -m course_lib.reproduce {name}\n") == 1, name


def test_reproduce_stops_at_failure_and_rejects_bad_manifests(tmp_path):
    manifest = tmp_path / "MANIFEST.json"
    manifest.write_text(json.dumps([{"name": "bad", "command": "exit 3"}, {"name": "never", "command": "touch x"}]))
    assert reproduce.main(["--manifest", str(manifest), "--root", str(tmp_path)]) == 1
    assert not (tmp_path / "x").exists()
    assert reproduce.main(["--manifest", str(manifest), "--root", str(tmp_path), "--keep-going"]) == 1
    assert (tmp_path / "x").exists()
    manifest.write_text(json.dumps({"m": {"file": "m.pt"}}))
    with pytest.raises(ValueError, match="entry 'm' has no 'command'"):
        reproduce.read_manifest(manifest)
    assert reproduce.main(["--manifest", str(tmp_path / "missing.json")]) == 0


def test_makefile_targets_run_the_right_commands():
    def dry(*targets: str) -> str:
        proc = subprocess.run(["make", "-n", "-B", *targets], cwd=REPO, capture_output=True, text=True, timeout=60)
        assert proc.returncode == 0, proc.stderr
        return proc.stdout

    data = dry("data")
    for script in ["make_locomotion.py --out data/locomotion.npz", "make_actions.py --out data/actions.npz",
                   "make_noisy.py"]:
        assert script in data
    assert "pip install --quiet -e \".[dev]\"" in data  # -B: the setup recipe is part of the plan
    course = dry("course", "COURSE_MODE=full")
    assert "COURSE_MODE=full" in course and "--ExecutePreprocessor.timeout=1800 --output-dir build/executed" in course
    assert "tools/build_site.py --notebooks build/executed --site site" in course
    assert "tools/build_site.py --notebooks notebooks --site site" in dry("site")  # committed notebooks, no execution
    # Agg in a notebook kernel replaces the inline backend: the executed lessons would lose their figures
    assert "env -u MPLBACKEND" in course and "MPLBACKEND=Agg" not in course
    test = dry("test")
    assert "ruff check ." in test and "pytest -n 2 -m \"not slow\" tests" in test
    slow = dry("test-slow")
    assert "pytest -n 2 -m slow tests" in slow and "make -C" not in slow  # the slow half: run by .ci/run after test
    assert "make test-slow" in (REPO / ".ci" / "run").read_text()
    for option in ["COURSE_MODE=ci TQDM_DISABLE=1", "VTK_DEFAULT_OPENGL_WINDOW=vtkEGLRenderWindow",
                   "PYVISTA_OFF_SCREEN=true", "--nbval-lax --nbval-current-env --nbval-cell-timeout=300"]:
        assert option in test, option
