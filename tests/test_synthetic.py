"""The synthetic generator is physically sane and human-like: planted feet, no ground penetration,
rigid bones, controls that integrate to the path, human ranges, ballistic jumps, determinism."""

import numpy as np
import pytest

from course_lib.motion import foot_contacts
from course_lib.synthetic import (
    ACTIONS,
    GAITS,
    ControlProgram,
    add_noise,
    generate_action,
    generate_locomotion,
    integrate_root,
    make_subject,
    make_subjects,
    random_control_program,
)
from course_lib.synthetic.report import clip_figures, jump_figures, realism_report

STEADY = {"idle": 0.0, "walk": 1.3, "jog": 2.6, "run": 4.2, "sidestep": 0.45, "backward": 0.8, "turn": 0.0}


@pytest.fixture(scope="module")
def subjects():
    return make_subjects(4, seed=0)


@pytest.fixture(scope="module")
def steady(subjects):
    """{gait: [clips]}: 4 s of each gait at a typical speed, two subjects (styles A and B)."""
    out = {}
    for g, v in STEADY.items():
        w = 1.5 if g == "turn" else 0.0
        out[g] = [generate_locomotion(s, ControlProgram.constant(g, v, 4.0, heading_rate=w), seed=i)
                  for i, s in enumerate(subjects[:2])]
    return out


@pytest.fixture(scope="module")
def random_clips(subjects):
    return [generate_locomotion(subjects[i % 4], None, duration=4.0, seed=100 + i) for i in range(6)]


@pytest.fixture(scope="module")
def actions(subjects):
    return {a: [generate_action(subjects[i], a, style="AB"[i % 2], seed=10 + i) for i in range(2)] for a in ACTIONS}


def all_clips(steady, random_clips, actions):
    return [m for ms in steady.values() for m in ms] + random_clips + [m for ms in actions.values() for m in ms]


def test_feet_planted_no_penetration_rigid_bones(steady, random_clips, actions):
    rep = realism_report(all_clips(steady, random_clips, actions))
    for label in list(GAITS) + ["jump", "lift"]:
        r = rep[label]
        assert r["skate_cm_s"] <= 3.0, (label, r["skate_cm_s"])   # toe joint < rest + 2 cm: <= 3 cm/s
        assert r["min_foot_cm"] >= -0.5, (label, r["min_foot_cm"])
        assert r["bone_err_m"] <= 1e-6, (label, r["bone_err_m"])
        assert not r["nan"]


def test_ground_truth_contacts_agree_with_derived(steady, random_clips):
    for m in [m for ms in steady.values() for m in ms] + random_clips:
        derived = foot_contacts(m.positions(), m.skeleton, m.fps)
        assert (derived == m.meta["contacts"]).mean() > 0.9


def test_control_integrates_to_root_path(random_clips):
    for m in random_clips:
        path = integrate_root(m.meta["velocity"], m.meta["heading_rate"], m.fps, origin=0)
        assert np.linalg.norm(path[-1, :2] - m.meta["root_path"][-1, :2]) < 0.01  # 1 cm after 4 s
        assert abs(path[-1, 2] - m.meta["root_path"][-1, 2]) < 1e-3
        hips = m.root_positions[:, [0, 2]]
        assert np.linalg.norm(hips - m.meta["root_path"][:, :2], axis=-1).max() < 0.07  # only sway / weight shifts


def test_steady_speed_cadence_duty_in_human_ranges(steady):
    cadence_range = {"walk": (95, 125), "jog": (140, 175), "run": (150, 195)}
    for g, ms in steady.items():
        for m in ms:
            f = clip_figures(m)
            c = m.meta["contacts"]
            speed = np.linalg.norm(m.root_positions[-1, [0, 2]] - m.root_positions[0, [0, 2]]) / m.duration
            if g in ("walk", "jog", "run", "backward", "sidestep"):
                assert abs(speed - STEADY[g]) < 0.1 * STEADY[g], (g, speed)
            if g in cadence_range:
                steps = (c[1:] & ~c[:-1]).sum() / m.duration * 60
                lo, hi = cadence_range[g]
                assert lo <= steps <= hi, (g, steps)
            flight = (~c.any(-1)).mean()
            if g == "walk":
                assert 0.55 < c.mean() < 0.68 and flight == 0
            if g == "run":
                assert c.mean() < 0.4 and flight > 0.2
            if g == "idle":
                assert c.all() and speed < 0.02 and f["speed"].max() < 0.15
    turn = steady["turn"][0].meta["root_path"][:, 2]
    assert abs((turn[-1] - turn[0]) / 4.0 - 1.5) < 0.1  # turning on the spot at 1.5 rad/s


def test_random_programs_respect_limits():
    for seed in range(25):
        p = random_control_program(4.0, seed=seed)
        c = p.sample(120, 0, 4)
        speed = np.linalg.norm(c["velocity"], axis=-1)
        assert np.abs(c["heading_rate"]).max() <= np.radians(120) + 1e-9
        assert speed.max() <= 5.0 + 1e-9
        assert (np.abs(c["heading_rate"]) * speed).max() <= 3.5 + 1e-6  # lateral acceleration of turns
    gaits = {g for s in range(40) for g in random_control_program(4.0, seed=s).gaits}
    assert gaits == set(GAITS)


def test_jump_is_ballistic(actions):
    for m in actions["jump"]:
        j = jump_figures(m)
        assert abs(j["flight_s"] - m.meta["flight_time"]) <= 1.5 / m.fps
        assert abs(j["height_m"] - 9.81 * j["flight_s"] ** 2 / 8) < 0.02  # h = g t^2 / 8
        air = ~m.meta["contacts"].any(-1)
        t = np.nonzero(air)[0] / m.fps
        a2 = np.polyfit(t, m.root_positions[air, 1], 2)[0]
        assert abs(2 * a2 + 9.81) < 1e-6  # y'' = -g during flight
        assert 0.12 <= m.meta["apex"] <= 0.4


def test_lift_reaches_down_and_carries_in_front(actions):
    for m in actions["lift"]:
        P = m.positions()
        hands = P[:, [m.skeleton.index("LeftHand"), m.skeleton.index("RightHand")]]
        assert hands[..., 1].min() < 0.3  # reaches the box handles (0.25 m) near the floor
        end = m.meta["root_path"][-1, 2]
        fwd = np.array([np.sin(end), np.cos(end)])
        ahead = (hands[-1, :, [0, 2]].T - P[-1, 0, [0, 2]]) @ fwd
        assert (ahead > 0.15).all()  # carried in front of the body
        assert m.action == "lift" and m.style in ("A", "B")


def test_same_seed_same_data_different_seed_differs(subjects):
    a = generate_locomotion(subjects[0], None, seed=3)
    b = generate_locomotion(subjects[0], None, seed=3)
    c = generate_locomotion(subjects[0], None, seed=4)
    assert np.array_equal(a.rotations, b.rotations) and np.array_equal(a.root_positions, b.root_positions)
    assert not np.allclose(a.rotations, c.rotations)
    j1, j2 = (generate_action(subjects[1], "jump", seed=s) for s in (5, 5))
    assert np.array_equal(j1.rotations, j2.rotations)
    assert np.array_equal(make_subject(2, 7).scale, make_subject(2, 7).scale)
    assert not np.array_equal(make_subject(2, 7).scale, make_subject(2, 8).scale)


def test_subjects_symmetric_varied_and_styled():
    subs = make_subjects(20, seed=1)
    sk0 = subs[0].skeleton()
    mm = sk0.mirror_map
    for s in subs:
        assert np.array_equal(s.scale, s.scale[list(mm)])  # left/right symmetric: mirroring stays exact
        assert 0.85 < s.scale.min() and s.scale.max() < 1.16
    width = {st: np.mean([s.scale[sk0.index("LeftArm")] / s.scale[sk0.index("LeftUpLeg")] for s in subs
                          if s.style == st]) for st in "AB"}
    assert width["B"] < 0.95 * width["A"]  # narrower shoulders relative to hips
    assert np.mean([s.arm_swing for s in subs if s.style == "B"]) < np.mean([s.arm_swing for s in subs
                                                                             if s.style == "A"])


def test_mirror_is_exact(subjects):
    m = generate_locomotion(subjects[1], None, seed=9)
    P, Pm = m.positions(), m.mirror().positions()
    assert np.abs(Pm[:, list(m.skeleton.mirror_map)] * np.array([-1, 1, 1]) - P).max() < 1e-9


def test_resample_keeps_meta_in_step(subjects):
    m = generate_locomotion(subjects[0], None, duration=4.0, fps=30, seed=1)
    assert m.fps == 30 and len(m) == 121
    assert m.meta["contacts"].shape == (121, 2) and m.meta["gait"].shape == (121,)


def test_noise_model(subjects):
    clean = generate_locomotion(subjects[0], ControlProgram.constant("walk", 1.2, 4.0), seed=2)
    noisy = add_noise(clean, jitter_sd=0.02, spike_rate=0.02, drop_rate=0.05, seed=1)
    assert noisy.meta["clean"] is clean
    n = noisy.meta["noise"]
    ok = ~n["dropped"]
    ok[n["spike_frames"]] = False
    dot = np.abs(np.sum(noisy.rotations * clean.rotations, -1))[ok]
    angle = 2 * np.arccos(np.clip(dot, -1, 1))  # |eps| of a 3-D Gaussian: mean sd * sqrt(8 / pi)
    assert abs(angle.mean() / (0.02 * np.sqrt(8 / np.pi)) - 1) < 0.05
    d = np.nonzero(n["dropped"])[0]
    assert len(d) > 0 and np.array_equal(noisy.rotations[d], noisy.rotations[d - 1])
    assert len(n["spike_frames"]) > 0
    assert np.array_equal(add_noise(clean, seed=1).rotations, add_noise(clean, seed=1).rotations)


def test_bad_inputs_raise(subjects):
    with pytest.raises(ValueError, match="action"):
        generate_action(subjects[0], "dance")
    with pytest.raises(ValueError, match="gaits"):
        ControlProgram(np.array([0.0, 1.0]), ("moonwalk",), [1.0], [0.0], [0.0])
    with pytest.raises(ValueError, match="duration"):
        generate_locomotion(subjects[0], None, duration=0.0)
    with pytest.raises(ValueError, match="jump"):
        generate_action(subjects[0], "jump", duration=0.5)
    with pytest.raises(ValueError, match="drop_rate"):
        add_noise(generate_action(subjects[0], "jump"), drop_rate=1.5)


def test_knees_never_flip_pop_or_overflex(steady, random_clips, actions):
    for m in all_clips(steady, random_clips, actions):
        P, sk = m.positions(), m.skeleton
        for side in ("Left", "Right"):
            hip, knee, ankle, toe = (P[:, sk.index(side + n)] for n in ("UpLeg", "Leg", "Foot", "ToeBase"))
            u = (ankle - hip) / np.linalg.norm(ankle - hip, axis=-1, keepdims=True)
            out = (knee - hip) - np.sum((knee - hip) * u, -1, keepdims=True) * u  # knee off the hip-ankle line
            fwd = (toe - ankle) * np.array([1, 0, 1])
            bent = np.linalg.norm(out, axis=-1) > 0.05
            cos = np.sum(out * fwd, -1) / np.linalg.norm(out, axis=-1) / np.linalg.norm(fwd, axis=-1)
            assert (cos[bent] > 0).all()  # the knee points the way the foot does
            t1, t2 = knee - hip, ankle - knee
            flex = np.degrees(np.arccos(np.clip(np.sum(t1 * t2, -1) / np.linalg.norm(t1, axis=-1)
                                                / np.linalg.norm(t2, axis=-1), -1, 1)))
            assert 1.0 < flex.min() and flex.max() <= 140.0 + 1e-6  # never locked straight, never over-flexed


def test_local_rotations_are_continuous(steady, random_clips, actions):
    """No joint's local rotation jumps between frames (a 180-degree frame flip of the shin once did
    while positions stayed right, corrupting every rotation representation)."""
    for m in all_clips(steady, random_clips, actions):
        q = m.rotations
        dot = np.abs(np.sum(q[1:] * q[:-1], -1)).clip(0.0, 1.0)
        step = np.degrees(2 * np.arccos(dot)) * (120.0 / m.fps)  # degrees per 1/120 s
        assert step.max() < 30.0, (m.action, m.subject, step.max(), np.unravel_index(step.argmax(), step.shape))
