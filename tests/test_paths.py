"""course_lib.paths: a clone needs no setting; an installed course_lib finds the weights through COURSE_CHECKPOINTS,
and says so when it cannot."""

import os
import subprocess
import sys
from pathlib import Path

import pytest

from course_lib import paths
from course_lib.training import load_checkpoint

REPO = Path(__file__).resolve().parents[1]


def run(code: str, **env) -> str:
    environment = {k: v for k, v in os.environ.items() if k != paths.CHECKPOINTS_ENV} | env
    return subprocess.run([sys.executable, "-c", code], env=environment, capture_output=True, text=True,
                          check=True, cwd="/").stdout.strip()


def test_a_clone_finds_its_own_checkpoints():
    assert paths.REPO_ROOT == REPO and run("from course_lib import paths; print(paths.CHECKPOINTS)") == str(
        REPO / "checkpoints")


def test_the_variable_points_every_lesson_at_another_folder(tmp_path):
    code = ("from course_lib.experiments import moglow, vae_lstm; from course_lib.control import rnn_prior; "
            "from course_lib.evaluation import classifiers; "
            "print({str(m) for m in (moglow.CHECKPOINTS, vae_lstm.CHECKPOINTS, rnn_prior.CHECKPOINTS, "
            "classifiers.CHECKPOINT_DIR)})")
    assert run(code, COURSE_CHECKPOINTS=str(tmp_path)) == str({str(tmp_path)})


def test_a_missing_checkpoints_folder_names_the_variable(tmp_path):
    from course_lib.models.vae import PoseVae, VaeConfig

    with pytest.raises(FileNotFoundError, match="COURSE_CHECKPOINTS"):
        load_checkpoint(tmp_path / "no_such_folder" / "vae.pt", PoseVae, VaeConfig)
    with pytest.raises(FileNotFoundError, match="MANIFEST.json") as err:
        load_checkpoint(tmp_path / "vae.pt", PoseVae, VaeConfig)
    assert "COURSE_CHECKPOINTS" not in str(err.value)
