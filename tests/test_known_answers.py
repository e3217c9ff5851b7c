"""Known answers of the classifier feature space (FID, C2ST) on real synthetic clips.

A change a person would not see -- every joint turned by a constant 1-3 degrees -- must score far
below changes they would see: the clips played backwards, half of the action classes removed, one
style removed.  FID must grow with the size of a change, and the classifier two-sample test must
give chance on two real sets and rank a noise sweep.  The classifiers before the fixed-degree-of-
freedom handling failed the first test (a 3-degree turn scored 2.9x time reversal; now < 0.01x).
"""

from __future__ import annotations

import numpy as np
import pytest

from course_lib.evaluation import c2st, classifier_features, fid, load_classifier
from course_lib.evaluation.classifiers import ClassifierData
from course_lib.evaluation.perturb import drop_labels, joint_noise, time_reversed, turn_joints
from course_lib.synthetic import make_subjects

DATA = ClassifierData()
TURNS = (1, 2, 3, 5, 10, 20)  # degrees
NOISE = (0, 10, 20, 40)  # degrees of i.i.d. per-frame joint noise


@pytest.fixture(scope="module")
def held_out():
    """Two takes per (action, style) of the 4 held-out subjects: 64 clips at 30 fps."""
    return DATA.motions(DATA.split()[1], 2)


@pytest.fixture(scope="module")
def other_real():
    """Two takes per (action, style) of 6 subjects the classifiers never saw (s06..s11): 96 clips."""
    return DATA.motions(make_subjects(DATA.num_subjects, DATA.seed)[6:12], 2)


@pytest.fixture(scope="module")
def fids(held_out, other_real):
    """{change: FID against other_real} in the action classifier's features -- printed for the report."""
    clf = load_classifier("action")
    ref = classifier_features(other_real, clf)
    sets = {"real": held_out, **{f"turn {d}": turn_joints(held_out, d) for d in TURNS},
            "time reversal": [time_reversed(m) for m in held_out], "half of the actions": drop_labels(held_out)}
    out = {name: fid(ref, classifier_features(ms, clf), clf) for name, ms in sets.items()}
    print("FID (action features):", {k: round(v, 1) for k, v in out.items()})
    return out


def test_small_turns_score_far_below_semantic_changes(fids):
    for d in (1, 2, 3):
        for change in ("time reversal", "half of the actions"):
            assert fids[f"turn {d}"] <= 0.25 * fids[change], (d, change, fids)
    assert fids["turn 3"] < 3 * fids["real"]  # an invisible change stays near the real-vs-real floor


def test_fid_grows_with_the_size_of_a_turn(fids):
    values = [fids["real"]] + [fids[f"turn {d}"] for d in TURNS]
    assert np.all(np.diff(values) > 0), values
    assert values[-1] > 20 * values[0]  # 20 degrees at every joint is plainly visible


def test_style_features_see_a_removed_style_not_a_small_turn(held_out, other_real):
    clf = load_classifier("style")
    ref = classifier_features(other_real, clf)
    real = fid(ref, classifier_features(held_out, clf), clf)
    turned = fid(ref, classifier_features(turn_joints(held_out, 3), clf), clf)
    one_style = fid(ref, classifier_features(drop_labels(held_out, "style"), clf), clf)
    print(f"FID (style features): real {real:.1f}, 3-degree turn {turned:.1f}, one style only {one_style:.1f}")
    assert turned <= 0.25 * one_style


def test_c2st_real_vs_real_is_chance(held_out, other_real):
    pool = held_out + other_real
    order = np.random.default_rng(0).permutation(len(pool))
    a, b = [pool[i] for i in order[::2]], [pool[i] for i in order[1::2]]  # one population, split at random
    r = c2st(a, b, seed=0)
    print("C2ST real vs real (random halves):", r)
    assert r["ci_low"] <= 0.5 <= r["ci_high"]
    assert r["ci_high"] - r["ci_low"] < 0.25 and r["n"] == 2 * min(len(a), len(b))
    other = c2st(other_real, held_out, seed=0)  # other subjects: still indistinguishable
    assert other["ci_low"] <= 0.5 <= other["ci_high"], other


def test_c2st_ranks_a_noise_sweep(held_out, other_real):
    acc = [c2st(other_real, joint_noise(held_out, d, seed=1), seed=0)["accuracy"] for d in NOISE]
    print("C2ST along the noise sweep", dict(zip(NOISE, [round(a, 3) for a in acc], strict=True)))
    assert np.all(np.diff(acc) > 0) and acc[-1] > 0.95


def test_c2st_rejects_bad_input():
    with pytest.raises(ValueError, match="at least 2"):
        c2st(np.zeros((1, 8)), np.zeros((10, 8)))
    assert c2st(np.zeros((3, 8)), np.ones((10, 8)))["accuracy"] == 1.0  # 3 folds of a separable pair
    with pytest.raises(ValueError, match="differ"):
        c2st(np.zeros((10, 8)), np.zeros((10, 9)))
    with pytest.raises(ValueError, match="NaN"):
        c2st(np.zeros((10, 8)), np.full((10, 8), np.nan))


def test_perturbations_change_what_they_say(held_out):
    clip = held_out[:2]
    turned = turn_joints(clip, 3, joints=["LeftFoot", "Head"])
    skel = clip[0].skeleton
    changed = {skel.names[j] for j in range(skel.num_joints)
               if not np.allclose(turned[0].rotations[:, j], clip[0].rotations[:, j])}
    assert changed == {"LeftFoot", "Head"}
    cos = np.abs((turned[0].rotations * clip[0].rotations).sum(-1))[:, skel.index("Head")]
    np.testing.assert_allclose(np.degrees(2 * np.arccos(np.clip(cos, -1, 1))), 3.0, atol=1e-6)  # the angle turned
    assert [m.action for m in drop_labels(held_out)] and {m.action for m in drop_labels(held_out)} == {"jog", "jump"}
    assert np.allclose(time_reversed(clip[0]).root_positions, clip[0].root_positions[::-1])


def test_diversity_of_copies_is_zero_and_counts_recognised_clips(held_out):
    from course_lib.experiments.hvrnn import diversity

    jumps = [m for m in held_out if m.action == "jump"]
    d = diversity([jumps[0]] * 4, load_classifier("action"))
    assert d["apd"] == pytest.approx(0.0, abs=1e-12) and d["recognised"] == 1.0
    walked = diversity([m for m in held_out if m.action == "walk"][:4], load_classifier("action"))
    assert walked["travel"] > 1.0 > d["travel"]  # walks leave their start, a jump lands near it


def test_nearest_distance_known_answers(held_out):
    import dataclasses

    from course_lib.experiments.hvrnn import nearest_distance

    subjects = sorted({m.subject for m in held_out})  # one jump per subject, 2 s of each (their lengths differ)
    jumps = [next(m for m in held_out if m.subject == s and m.action == "jump")[:60] for s in subjects]
    twin = [dataclasses.replace(m, subject="other") for m in jumps]
    assert nearest_distance(jumps, twin) == pytest.approx(0.0, abs=1e-12)  # each clip's twin is in the reference
    own = nearest_distance(jumps, jumps)  # its own subject's clips are skipped: another subject's jump is nearest
    assert 0.005 < own < 0.2
    assert nearest_distance(turn_joints(jumps, 20), twin) > nearest_distance(turn_joints(jumps, 5), twin)
    with pytest.raises(ValueError, match="another subject"):
        nearest_distance(jumps[:1], jumps[:1])
