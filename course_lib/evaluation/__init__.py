"""Evaluation toolkit: motion metrics, attribute classifiers, FID/IS, results tables.

- `metrics`: prediction/pose error (Habibie 2017 sec. 4.3), foot skate, ground
  penetration, jitter, bone-length violation, control following, APD, NPSS;
- `contacts`: the lower toe's height, contact labels against the pose's own contacts;
- `freezing`: joint speed per frame and the freezing threshold from mocap;
- `classifiers`: Ghorbani 2020 Table 1 action/style classifiers (shipped checkpoints);
- `distribution`: FID, Inception Score (Ghorbani eq. 27-29), the classifier two-sample test (C2ST);
- `tables`: our numbers beside the paper's as Markdown / HTML / dict.

Importing this package loads nothing from disk; the classifiers load on first use.  The
classifier and distribution names are imported lazily (PEP 562), so that
``python -m course_lib.evaluation.classifiers`` runs its module only once.
"""

import importlib

from course_lib.evaluation.contacts import contact_agreement, lower_toe
from course_lib.evaluation.freezing import freeze_floor, joint_speed
from course_lib.evaluation.metrics import (
    apd,
    bone_length_violation,
    facing_yaw,
    foot_skate,
    foot_skate_at_floor,
    ground_penetration,
    heading_error,
    jitter,
    npss,
    path_distance,
    pose_error,
    prediction_error,
    root_jerk_split,
    root_relative,
    speed_error,
)
from course_lib.evaluation.tables import ResultsTable, mean_sd, over_seeds, table

_LAZY = {
    "classifiers": ("ClassifierConfig", "MotionClassifier", "accuracy", "load_classifier", "motions_to_batch"),
    "distribution": ("c2st", "classifier_features", "fid", "frechet_distance", "inception_score", "wilson_interval"),
}


def __getattr__(name: str):
    for module, names in _LAZY.items():
        if name in names:
            return getattr(importlib.import_module(f"course_lib.evaluation.{module}"), name)
    raise AttributeError(f"module 'course_lib.evaluation' has no attribute {name!r}")


def __dir__():
    return sorted(set(globals()) | set(__all__))


__all__ = [
    "ClassifierConfig", "MotionClassifier", "ResultsTable", "accuracy", "apd", "bone_length_violation", "c2st",
    "classifier_features", "contact_agreement", "facing_yaw", "fid", "foot_skate", "foot_skate_at_floor",
    "frechet_distance",
    "freeze_floor", "ground_penetration", "heading_error", "inception_score", "jitter", "joint_speed",
    "load_classifier", "lower_toe", "mean_sd", "motions_to_batch", "npss", "over_seeds", "path_distance", "pose_error",
    "prediction_error", "root_jerk_split", "root_relative", "speed_error", "table", "wilson_interval",
]
