"""course_lib.benchmark (lesson 07): the protocol's pieces on known answers, a small live run, and the recorded
results (results/benchmark_results*.json) against the issue's must-shows."""

from __future__ import annotations

import numpy as np
import pytest

from course_lib import benchmark as B

ISSUE_ROWS = ("Mocap", "ERD", "LSTM-3LR", "cRBM (CD-15)", "VAE-LSTM", "GMM-RNN", "GMM-RNN + refiner (GAN2 + contacts)",
              "HVRNN (Proposed)", "QuaterNet-style GRU", "MoGlow")
LOWER = ("foot_skate", "penetration", "bone_length", "fid", "path_error", "speed_error", "frozen")  # mocap: minimum


# ----------------------------------------------------------------------------- known answers


def test_at_times_is_exact_on_frames_and_on_a_cubic():
    t20 = np.arange(41) / 20.0
    cubic = (0.3 * t20 ** 3 - t20 ** 2 + 2 * t20)[None, :, None, None] * np.ones((1, 1, 2, 3))
    times = np.arange(0.5, 1.95, 1 / 30)
    want = (0.3 * times ** 3 - times ** 2 + 2 * times)
    assert np.abs(B.at_times(cubic, 20.0, times)[0, :, 0, 0] - want).max() < 1e-9  # not-a-knot: cubics exactly
    x = np.random.default_rng(0).normal(size=(2, 60, 21, 3))
    assert np.abs(B.at_times(x, 60.0, np.arange(30) / 30) - x[:, ::2]).max() < 1e-12  # 60 -> 30 fps drops frames
    with pytest.raises(ValueError, match="outside"):
        B.at_times(x, 60.0, np.array([1.5]))


def test_halves_split_every_clip_once():
    a, b = B.halves(41, seed=3)
    assert len(a) == 20 and len(b) == 21 and not set(a) & set(b) and set(a) | set(b) == set(range(41))
    assert not np.array_equal(B.halves(40, 0)[0], B.halves(40, 1)[0])


def _walk(n=3, T=90, speed=1.2, fps=B.FPS):
    """n straight walks along +Z at `speed` (every joint carried along)."""
    pos = np.zeros((n, T, 21, 3))
    pos[..., 2] = (np.arange(T) / fps * speed)[None, :, None]
    pos[..., 1] = 0.9
    return pos


def test_control_errors_known_answers():
    truth = _walk()
    assert B.control_errors(truth, truth) == {"path_error": 0.0, "speed_error": 0.0}
    side = truth.copy()
    side[..., 0] += 0.3  # 30 cm beside the path, same speed
    err = B.control_errors(side, truth)
    assert err["path_error"] == pytest.approx(0.3) and err["speed_error"] == pytest.approx(0.0, abs=1e-9)
    slow = _walk(speed=0.8)  # on the path, 0.4 m/s slow
    err = B.control_errors(slow, truth)
    assert err["path_error"] == pytest.approx(0.0, abs=1e-9) and err["speed_error"] == pytest.approx(0.4)


@pytest.fixture(scope="module")
def proto():
    return B.load_protocol(B.BenchSpec(clips=20))


def test_protocol_truth_is_the_clips_at_30_fps(proto):
    c0 = proto.c0
    assert c0 == 15 and proto.frames == 105 and proto.truth.shape == (20, 105, 21, 3)
    for i in (0, 7, 19):
        assert np.abs(proto.truth[i] - proto.clips[i].positions()[::2][c0:c0 + 105]).max() < 1e-9
    assert all(m.subject in ("s00", "s05", "s09") for m in proto.clips)  # lesson 02's held-out subjects


def test_stability_known_answers(proto):
    from course_lib.evaluation import freeze_floor

    floor = freeze_floor([m.resample(B.FPS) for m in proto.clips])
    assert B.stability(proto.truth, proto, floor) == {"in_range": 1.0, "frozen": 0.0}
    still = np.repeat(proto.truth[:4, :1], 600, 1)  # one pose held for 20 s
    assert B.stability(still, proto, floor)["frozen"] == 1.0
    high = proto.truth[:4].copy()
    high[..., 1] += 1.0  # the root a metre above any mocap frame
    high[1, 5] = np.nan
    assert B.stability(high, proto, floor)["in_range"] == 0.0


def test_every_row_reading_the_start_continues_the_clip(proto):
    """The first measured frame of a model given the context lies within a few cm of the mocap's (a misaligned
    start or frame rate would put it metres away)."""
    idx = np.arange(6)
    for row in B.build_rows(names=["ERD", "cRBM (CD-15)", "VAE-LSTM", "GMM-RNN", "MoGlow"]):
        s = row.generate(proto, idx, seed=0)
        assert s.positions.shape == (6, proto.frames, 21, 3)
        gap = np.linalg.norm(s.positions[:, 0, 0, [0, 2]] - proto.truth[idx, 0, 0][:, [0, 2]], axis=-1)
        assert gap.max() < 0.05, (row.name, gap)


# ----------------------------------------------------------------------------- a small live run


@pytest.fixture(scope="module")
def small():
    spec = B.BenchSpec(clips=30, seeds=(0, 1), apd_starts=2, apd_samples=3, long_samples=2, online_clips=2)
    return B.run(spec, progress=False, rows=["Mocap", "ERD", "VAE-LSTM", "GMM-RNN", "MoGlow"])


def test_small_run_has_every_row_and_no_silent_gaps(small):
    assert list(small["rows"]) == ["Mocap", "ERD", "VAE-LSTM", "GMM-RNN", "MoGlow"]
    for name, row in small["rows"].items():
        for key in B.MEASURES:
            assert (key in row["mean"]) != (key in row["blanks"]), (name, key)  # a number or a reason, never both
            if key in row["blanks"]:
                assert len(row["blanks"][key]) > 10
    assert set(small["rows"]["MoGlow"]["blanks"]) == {"path_error", "speed_error"}
    assert "nll" in small["rows"]["VAE-LSTM"]["mean"] and "nll" in small["rows"]["MoGlow"]["mean"]


def test_small_run_mocap_at_the_floor(small):
    """Per-sample measures; FID at 15 clips a half is noise (the recorded runs' test below checks it)."""
    rows = small["rows"]
    mocap = rows["Mocap"]["mean"]
    for key in (k for k in LOWER if k != "fid"):
        for name, row in rows.items():
            if key in row["mean"]:
                assert mocap[key] <= row["mean"][key] + 1e-12, (key, name)
    assert mocap["foot_skate"] < 0.02 and mocap["path_error"] == 0 and mocap["in_range"] == 1.0
    assert rows["ERD"]["mean"]["apd"] == 0.0  # a deterministic regressor: every draw the same
    assert rows["MoGlow"]["mean"]["apd"] > 0.01


def test_markdown_and_html_list_every_row_and_number_each_reason(small):
    md, page = B.markdown(small), B.html(small)
    assert all(f"| {name} |" in md and f"<td>{name}</td>" in page for name in small["rows"])
    assert "[1] one recording per start" in md and "— [" in md
    assert page.count("<tr>") == len(small["rows"]) + 1 and "[1] one recording per start" in page
    assert "≤ " in md  # the VAE-LSTM's negative ELBO bounds its NLL from above


# ----------------------------------------------------------------------------- the recorded results


@pytest.mark.parametrize("name", ["benchmark_results.json", "benchmark_results_ci.json"])
def test_recorded_results_show_the_must_shows(name):
    path = B.RESULTS.with_name(name)
    if not path.exists():
        pytest.skip(f"{path} not recorded")
    res = B.load_results(path)
    rows = res["rows"]
    assert set(ISSUE_ROWS) <= set(rows)
    assert len(res["spec"]["seeds"]) >= 2 and res.get("cpu_seconds", res["seconds"]) < (
        900 if name == "benchmark_results.json" else 180)  # on one core: CPU time where recorded
    mocap = rows["Mocap"]["mean"]
    learned = {n: r for n, r in rows.items() if not r.get("flag")}  # a row that replays training clips may beat
    for key in LOWER:  # the held-out floor (its memorisation column says so); every learned model stays above it
        assert all(mocap[key] <= r["mean"][key] + 1e-12 for r in learned.values() if key in r["mean"]), key
    for n, r in rows.items():
        if r.get("flag") and "fid" in r["mean"]:  # a replaying row within the floor's interval, not below it
            assert r["mean"]["fid"] >= rows["Mocap"]["ci"]["fid"][0], n
    # C2ST: the mocap halves are not told apart (0.5 inside the interval); no model's interval lies below it
    assert rows["Mocap"]["mean"]["c2st_low"] <= 0.5 <= rows["Mocap"]["mean"]["c2st_high"]
    assert all(r["mean"]["c2st_high"] >= mocap["c2st"] for r in rows.values() if "c2st" in r["mean"])
    for row in rows.values():
        assert all((k in row["mean"]) != (k in row["blanks"]) for k in res["measures"])  # the run's own measures
        assert all(row["sd"][k] >= 0 for k in B.SEEDED if k in row["sd"])


# ----------------------------------------------------------------------------- skating ratio, memorisation, intervals


def test_skating_ratio_equals_the_lesson_00c_reference():
    from course_lib.solutions.measures import skating_ratio as reference

    x = _walk(n=2, T=40, speed=0.3)
    x[..., 1] = 0.02  # every joint (the toes too) 2 cm above the floor: in contact
    x[1, :, :, 0] += np.arange(40)[:, None] * 0.03  # clip 1 also slides sideways at 0.9 m/s
    assert B.skating_ratio(x) == pytest.approx(0.5) == reference(x, B.FPS, B.SKATING_SPEED)
    x[..., 1] = 0.5  # lifted: no contact pair
    assert B.skating_ratio(x) == 0.0


def test_memorisation_of_a_replayed_training_clip_is_zero_distance(proto):
    memo = B.Memorisation.build(proto)
    assert 0.0 < memo.p5 < np.median(memo.mocap) < 0.5  # held-out mocap: centimetres from the training set
    replay = np.stack([m.resample(B.FPS).positions()[6:111] for m in proto.train[:4]])  # training clips, 0.2 s on
    replay[..., [0, 2]] += 3.0  # elsewhere on the floor: where a window walks does not count
    d = memo.distance(replay)
    assert d.max() < 0.02 * memo.p5  # the replay lies on training windows (0.1 s apart)
    assert memo.measure(replay)["memorised"] == 1.0
    assert 0.02 < memo.measure(proto.truth)["memorised"] < 0.08  # held-out mocap: its 5 %, by definition


def test_bootstrap_interval_known_answers():
    rng = np.random.default_rng(0)
    same = [(np.full(50, 2.0), np.ones(50))] * 3
    assert B.bootstrap_interval(same, rng) == (2.0, 2.0)  # no spread, no width
    noisy = [(rng.normal(1.0, 0.5, 400), np.ones(400)) for _ in range(5)]
    lo, hi = B.bootstrap_interval(noisy, rng)
    assert lo < 1.0 < hi and 0.04 < hi - lo < 0.2  # about 4 standard errors of 0.5 / sqrt(2000), plus seeds
    lo, hi = B.t_interval([1.0, 2.0, 3.0])
    assert lo == pytest.approx(2.0 - 4.303 / np.sqrt(3), abs=1e-3) and hi == pytest.approx(2.0 + 4.303 / np.sqrt(3),
                                                                                              abs=1e-3)


def test_orderings_hold_only_outside_the_noise():
    row = lambda m, lo, hi: {"mean": {"fid": m}, "ci": {"fid": [lo, hi]}}  # noqa: E731
    res = {"rows": {"A": row(1.0, 0.5, 1.5), "B": row(1.4, 1.2, 1.6), "C": row(3.0, 2.0, 4.0)}}
    (o,) = B.orderings(res, ["fid"])
    assert o["chain"] == "A ~ B < C" and o["apart"] == [["A", "C"], ["B", "C"]] and o["pairs"] == 3


def test_protocol_card_names_every_measure_with_its_literature_name():
    card = B.protocol_card()
    assert set(card["measures"]) == set(B.MEASURES)
    assert "skating ratio" in card["measures"]["skating_ratio"]["literature"]
    assert card["seeds"]["full"] == [0, 1, 2, 3, 4] and "| skating ratio |" in B.card_markdown(card)


def test_recorded_ci_results_have_motion_matching_memorisation_and_intervals():
    path = B.RESULTS.with_name("benchmark_results_ci.json")
    if not path.exists():
        pytest.skip(f"{path} not recorded")
    res = B.load_results(path)
    rows = res["rows"]
    assert res["cpu_seconds"] < 180  # --ci within 3 minutes on one core (wall time grows on a shared machine)
    for name in ("Motion matching", "Motion matching, control"):
        assert rows[name]["flag"].startswith("replays") and 0 < rows[name]["search_us_per_frame"] < 1e4
        assert rows[name]["mean"]["memorised"] > 3 * rows["Mocap"]["mean"]["memorised"]  # replay: near training
    assert rows["Motion matching, control"]["mean"]["apd"] == 0.0  # the control row has no sampling noise
    for name, row in rows.items():
        assert "memorised" in row["mean"], name
        for key, (lo, hi) in row["ci"].items():
            assert lo <= row["mean"][key] + 1e-9 and row["mean"][key] <= hi + 1e-9 or key == "fid_excess", (name, key)
    assert {o["measure"] for o in res["orderings"]} >= {"foot_skate", "fid", "c2st", "memorised"}
