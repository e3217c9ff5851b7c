"""Adversarial refiner (Wang, Chai et al. 2021, sec. 4.2-4.3): kinematics in torch vs. representations.py,
R and D shapes, losses of eq. (9), (10), (13) on hand-made inputs, history buffer, schedule."""

import math

import numpy as np
import pytest
import torch

from course_lib.models.refiner import (
    AdversarialSchedule,
    Discriminator,
    HistoryBuffer,
    Refiner,
    RefinerConfig,
    discriminator_loss,
    end_effector_features,
    local_positions,
    pose_regularisation,
    refiner_adversarial_loss,
    refiner_loss,
    root_regularisation,
    root_trajectory,
)
from course_lib.motion import Motion
from course_lib.representations import encode_state_features, root_yaw_pitch_roll
from course_lib.rotations import euler_to_quat, expmap_to_quat
from course_lib.skeleton import Skeleton

SK = Skeleton.canonical()


def tiny(**kw) -> RefinerConfig:
    return RefinerConfig.cpu(**{"fc_width": 16, "lstm_width": 16, "d_fc_width": 16, "d_lstm_width": 8, **kw})


def turning_motion(T: int = 24, fps: float = 30.0, seed: int = 0) -> Motion:
    """A character walking on a curve with tilted root and random smooth joint rotations."""
    rng = np.random.default_rng(seed)
    t = np.arange(T) / fps
    axis_angle = 0.3 * np.sin(2 * t[:, None, None] + rng.uniform(0, 6, (1, SK.num_joints, 3)))
    yaw = 0.8 * t + 0.3
    axis_angle[:, 0] = 0.0
    rot = expmap_to_quat(torch.from_numpy(axis_angle)).numpy()
    ypr = np.stack((yaw, 0.1 + 0 * yaw, 0.05 * np.cos(3 * t)), -1)  # R_y(yaw) R_x(pitch) R_z(roll)
    rot[:, 0] = euler_to_quat(torch.from_numpy(ypr), "YXZ").numpy()
    root = np.stack((np.sin(yaw) * t, 0.95 + 0.02 * np.sin(5 * t), 1.2 * t), -1)
    return Motion(rot, root, SK, fps)


def test_torch_kinematics_match_the_motion():
    """root_trajectory (eq. 4) + local_positions rebuild Motion.positions(); v_end is the finite difference
    of the world end-effector positions in the previous frame's floor frame."""
    m = turning_motion()
    f = torch.from_numpy(encode_state_features(m))
    yaw0 = float(root_yaw_pitch_roll(m)[0, 0])
    root, yaw = root_trajectory(f, (m.root_positions[0, 0], m.root_positions[0, 2], yaw0))
    assert np.abs(root.numpy() - m.root_positions).max() < 1e-9
    local = local_positions(f, SK).numpy()  # (T, J, 3)
    c, s = np.cos(yaw.numpy())[:, None], np.sin(yaw.numpy())[:, None]
    world = np.stack((c * local[..., 0] + s * local[..., 2] + root.numpy()[:, None, 0], local[..., 1],
                      -s * local[..., 0] + c * local[..., 2] + root.numpy()[:, None, 2]), -1)
    assert np.abs(world - m.positions()).max() < 1e-6
    p_end, v_end = end_effector_features(f, SK, m.fps)
    E = list(SK.end_effectors)
    assert p_end.shape == v_end.shape == (len(m), 15)
    dw = np.diff(m.positions()[:, E], axis=0) * m.fps  # (T-1, E, 3) world velocities
    c, s = np.cos(yaw.numpy()[:-1])[:, None], np.sin(yaw.numpy()[:-1])[:, None]
    local_v = np.stack((c * dw[..., 0] - s * dw[..., 2], dw[..., 1], s * dw[..., 0] + c * dw[..., 2]), -1)
    assert np.abs(v_end.numpy()[1:].reshape(-1, 5, 3) - local_v).max() < 1e-6
    assert torch.equal(v_end[0], v_end[1])


def test_refiner_and_discriminator_shapes_and_near_identity():
    torch.manual_seed(0)
    c = tiny()
    R, D = Refiner(c), Discriminator(c)
    x = 0.3 * torch.randn(4, 12, 68)
    y = R(x)
    assert y.shape == (4, 12, 68)
    assert 0 < (y - x).abs().max() < 0.05  # residual with a small last layer: R(x) ~ x
    p, v = R.end_effectors(x)
    assert p.shape == v.shape == (4, 12, 15)
    prob = D(p, v)
    assert prob.shape == (4,) and ((prob > 0) & (prob < 1)).all()
    assert torch.allclose(prob, torch.sigmoid(D.logits(p, v)))
    assert R.fc1.in_features == 68 + 30 and D.fc1.in_features == 30
    paper = RefinerConfig()
    assert (paper.fc_width, paper.lstm_width, paper.lam, paper.buffer_size, paper.d_batch) == (500, 1000, 20.0, 320, 32)


def test_gan1_leaves_contacts_unchanged():
    torch.manual_seed(0)
    R = Refiner(tiny(contacts=False, residual_init_scale=1.0))
    x = 0.3 * torch.randn(2, 6, 68)
    y = R(x)
    assert R.fc1.in_features == 66 + 30
    assert torch.equal(y[..., 66:], x[..., 66:]) and (y[..., :66] - x[..., :66]).abs().max() > 1e-3


def test_losses_on_hand_made_inputs():
    big = torch.tensor([50.0, 50.0])
    # D(real) = 1, D(fake) = 0: eq. (10) is 0; D = 0.5 everywhere (chance): the mean cross-entropy log 2,
    # below the balance rule's halving threshold 1 (eq. 10's sum, 2 log 2 = 1.39, was above it)
    assert discriminator_loss(big, -big).item() == pytest.approx(0.0, abs=1e-12)
    assert discriminator_loss(torch.zeros(3), torch.zeros(3)).item() == pytest.approx(math.log(2))
    assert math.log(2) < RefinerConfig().d_loss_high
    # D(real) = 0.9 on every real motion, D(fake) = 0.2: (-log 0.9 - log 0.8) / 2
    l_real, l_fake = torch.full((4,), math.log(9.0)), torch.full((2,), math.log(0.25))
    assert discriminator_loss(l_real, l_fake).item() == pytest.approx(-(math.log(0.9) + math.log(0.8)) / 2)
    # eq. (9): -log D(R(x)) with D = 0.25 (logit log(1/3))
    assert refiner_adversarial_loss(torch.full((2,), math.log(1 / 3))).item() == pytest.approx(-math.log(0.25))
    # eq. (13): refined motion shifted by 0.1 m in height -> ||.||^2 = 0.01 on every frame
    x = torch.zeros(2, 5, 68)
    refined = x.clone()
    refined[..., 3] += 0.1
    assert root_regularisation(x, refined).item() == pytest.approx(0.01)
    # a forward step of 0.1 m on frame 2 only: frames 2..4 are 0.1 m off, frames 0-1 not: 3/5 * 0.01
    refined = x.clone()
    refined[:, 2, 1] = 0.1
    assert root_regularisation(x, refined).item() == pytest.approx(0.006)
    out = refiner_loss(torch.zeros(2), x, refined, lam=20.0)
    assert out["loss"].item() == pytest.approx(math.log(2) + 20 * 0.006)


def test_gradients_flow_from_d_loss_to_refiner():
    """The kinematics are torch: D's loss on R's output reaches every parameter of R."""
    torch.manual_seed(0)
    c = tiny()
    R, D = Refiner(c), Discriminator(c)
    x_rnn, x_real = 0.3 * torch.randn(3, 8, 68), 0.3 * torch.randn(3, 8, 68)
    fake = D.logits(*R.end_effectors(R(x_rnn)))
    real = D.logits(*R.end_effectors(x_real))
    discriminator_loss(real, fake).backward()
    for name, p in R.named_parameters():
        assert p.grad is not None and p.grad.abs().sum() > 0, name


def test_history_buffer_semantics():
    g = torch.Generator().manual_seed(0)
    buf = HistoryBuffer(320, generator=g)
    with pytest.raises(RuntimeError, match="fill"):
        buf.sample(4)
    buf.fill(torch.arange(320.0)[:, None, None].expand(320, 3, 2))
    assert len(buf) == 320
    current = -torch.ones(16, 3, 2)
    batch = buf.discriminator_batch(current)
    assert batch.shape == (32, 3, 2)
    assert torch.equal(batch[:16], current) and (batch[16:] >= 0).all()  # half current, half history
    assert len(set(batch[16:, 0, 0].tolist())) == 16  # distinct buffer entries
    before = buf.data.clone()
    idx = buf.replace(current)
    changed = (buf.data != before).any(-1).any(-1)
    assert changed.sum().item() == 16 and len(buf) == 320  # b/2 entries replaced, size fixed
    assert torch.equal(torch.nonzero(changed)[:, 0], idx.sort().values)
    # the same seed gives the same choice
    again = HistoryBuffer(320, generator=torch.Generator().manual_seed(0))
    again.fill(before.clone() * 0 + torch.arange(320.0)[:, None, None])
    assert torch.equal(again.discriminator_batch(current), batch)
    with pytest.raises(ValueError, match="exactly 320"):
        buf.fill(torch.zeros(10, 3, 2))


def test_adversarial_schedule_doubles_and_halves():
    s = AdversarialSchedule.from_config(RefinerConfig())
    assert s.next_round() == (75, 75)  # warm-up: each network 75 times
    assert s.next_round() == (5, 1)
    assert s.record(0.5) == 5  # in range: unchanged
    assert s.record(0.005) == 10  # D too strong: R trained twice as often
    assert s.next_round() == (10, 1)
    assert s.record(0.001) == 20
    assert s.record(2.0) == 10 and s.record(3.0) == 5 and s.record(3.0) == 2 and s.record(3.0) == 1
    assert s.record(5.0) == 1  # never below one update
    assert s.history == [5, 10]
    with pytest.raises(FloatingPointError):
        s.record(float("nan"))


def test_bad_input_errors():
    R = Refiner(tiny())
    with pytest.raises(ValueError, match=r"\(\.\.\., T, 68\)"):
        R(torch.randn(2, 5, 67))
    with pytest.raises(ValueError, match="NaN"):
        R(torch.full((2, 5, 68), float("nan")))
    with pytest.raises(ValueError, match="T >= 2"):
        R(torch.randn(2, 1, 68))
    with pytest.raises(ValueError, match=r"\(N, T, 30\)"):
        Discriminator(tiny())(torch.randn(2, 5, 15), torch.randn(2, 5, 12))
    with pytest.raises(ValueError, match=r"offsets must be \(N=2, 21, 3\)"):
        R(torch.randn(2, 5, 68), torch.zeros(3, 21, 3))
    with pytest.raises(ValueError, match="discriminator_contacts needs contacts"):
        RefinerConfig(contacts=False, discriminator_contacts=True)
    with pytest.raises(ValueError, match="d_batch"):
        RefinerConfig(d_batch=31)


def test_schedule_smoothing_ignores_a_single_spike():
    paper, smooth = AdversarialSchedule(warmup=0), AdversarialSchedule(warmup=0, smooth=4)
    for s in (paper, smooth):
        for loss in (0.3, 0.3, 0.3, 2.5):  # one batch above high = 1
            s.next_round()
            s.record(loss)
    assert paper.r_updates == 2  # halved by the spike
    assert smooth.r_updates == 5  # mean of the last 4 = 0.85 < 1: unchanged
    smooth.next_round()
    assert smooth.record(2.5) == 2  # mean (0.3 + 0.3 + 2.5 + 2.5) / 4 = 1.4 > 1
    with pytest.raises(ValueError, match="smooth"):
        AdversarialSchedule(smooth=0)


def test_each_motion_uses_its_own_skeleton():
    """p_end and v_end of a motion scale with its own skeleton: motion 0 on the canonical offsets, motion 1 on a
    10 % taller subject (root height scaled too) gives 1.1 x the end-effector positions and velocities."""
    m = turning_motion()
    f = torch.from_numpy(encode_state_features(m)).float()
    tall = f.clone()
    tall[:, 3] *= 1.1  # the root height scales with the legs
    R = Refiner(tiny(), stats=(np.zeros(68), np.ones(68)))
    off = torch.stack((torch.as_tensor(SK.offsets), 1.1 * torch.as_tensor(SK.offsets))).float()  # (2, J, 3)
    x = torch.stack((f, tall))  # (2, T, 68)
    p, v = R.end_effectors(x, off)
    p0, v0 = R.end_effectors(f[None])
    torch.testing.assert_close(p[0], p0[0])
    torch.testing.assert_close(p[1], 1.1 * p0[0], rtol=1e-5, atol=1e-5)
    # v_end: the joint-angle part scales, the root's floor displacement (dx, dz) does not -> the direct kinematics
    direct = end_effector_features(tall.double(), SK, 30.0, 1.1 * torch.as_tensor(SK.offsets))[1]
    torch.testing.assert_close(v[1], direct.float(), rtol=1e-4, atol=1e-4)
    torch.testing.assert_close(v[0], v0[0])
    p_canon, _ = R.end_effectors(x)  # without offsets: both motions on the canonical skeleton
    assert (p_canon[1] - p[1]).abs().max() > 0.05  # a 10 % taller subject's hands and head sit elsewhere
    y = R(x, off)
    assert y.shape == x.shape


def test_discriminator_sees_binary_contact_bits_with_a_straight_through_gradient():
    torch.manual_seed(0)
    c = tiny(discriminator_contacts=True)
    R, D = Refiner(c), Discriminator(c)
    assert c.d_input_dim == 32 and D.fc1.in_features == 32
    assert tiny().d_input_dim == 30 and RefinerConfig().d_input_dim == 30  # the paper's D: p_end, v_end only
    x = torch.zeros(2, 6, 68, requires_grad=True)
    with torch.no_grad():
        x[0, :, 66] = 0.7  # a soft "in contact" bit (raw units, stats are identity here)
        x[1, :, 66] = 0.2
    d_in = R.discriminator_input(x)
    assert d_in.shape == (2, 6, 32)
    assert torch.equal(d_in[0, :, -2], torch.ones(6)) and torch.equal(d_in[1, :, -2], torch.zeros(6))  # 0/1 only
    d_in[..., -2].sum().backward()
    assert torch.equal(x.grad[..., 66], torch.ones(2, 6))  # identity gradient to the soft bit
    assert D(d_in).shape == (2,)


def test_contact_bit_gradient_stops_outside_zero_one():
    """A bit already past 0 or 1 gets no gradient: R cannot push it without bound (the shipped GAN2's raw bits
    reached +-135 when the straight-through gradient passed at any value)."""
    R = Refiner(tiny(discriminator_contacts=True))
    x = torch.zeros(3, 4, 68)
    x[:, :, 66] = torch.tensor([1.7, -0.4, 0.6])[:, None]
    x.requires_grad_(True)
    d_in = R.discriminator_input(x)
    assert torch.equal(d_in[:, 0, -2], torch.tensor([1.0, 0.0, 1.0]))
    d_in[..., -2].sum().backward()
    assert torch.equal(x.grad[:, :, 66], torch.tensor([0.0, 0.0, 1.0])[:, None].expand(3, 4))


def test_pose_regularisation_known_answer_and_columns():
    """mean (R(x) - x)^2 over the pose columns: a change of 2 sd on one of 66 pose columns gives 4 / 66;
    a change of the contact bits costs nothing; GAN1's pose columns exclude the bits it never changes."""
    c = tiny(pose_lam=3.0)
    assert c.pose_dims == tuple(range(66)) and tiny(contacts=False).pose_dims == tuple(range(66))
    x = torch.randn(2, 5, 68)
    y = x.clone()
    y[..., 10] += 2.0
    assert pose_regularisation(x, y, c.pose_dims).item() == pytest.approx(4.0 / 66, rel=1e-6)
    y[..., 66:] += 5.0
    assert pose_regularisation(x, y, c.pose_dims).item() == pytest.approx(4.0 / 66, rel=1e-6)
    with pytest.raises(ValueError, match="pose_lam"):
        tiny(pose_lam=-1.0)


def test_balance_rule_keeps_r_at_chance_and_reacts_on_both_sides():
    """With D's loss at chance (ln 2) r stays; a D near perfect doubles it, a D fooled (loss > 1) halves it."""
    s = AdversarialSchedule(warmup=0)
    s.next_round()
    for _ in range(10):
        assert s.record(math.log(2)) == 5
    assert s.record(0.005) == 10 and s.record(1.5) == 5


def test_leg_pose_lam_adds_the_leg_angles_mean_squared_change_to_the_loss():
    """RefinerConfig.leg_pose_lam: the loss gains leg_pose_lam times the mean squared change (sd units) of the hip,
    knee and ankle angle columns (contact_cleanup.leg_columns) alone; the other columns do not enter that term."""
    from course_lib.models import refiner as M
    from course_lib.models.contact_cleanup import leg_columns

    cfg = M.RefinerConfig.cpu(leg_pose_lam=30.0, residual_init_scale=1.0)
    torch.manual_seed(0)
    R, D = M.Refiner(cfg), M.Discriminator(cfg)
    x = 0.1 * torch.randn(2, 8, cfg.dim)
    legs = leg_columns(R.skeleton)
    with torch.no_grad():
        change = R(x) - x
    expect = float(change[..., legs].pow(2).mean())
    assert expect > 0 and len(legs) == 18
    lr0 = torch.optim.SGD(R.parameters(), lr=0.0)  # lr 0: the step reports the terms without moving R
    with_legs = M._refiner_step(R, D, lr0, (x, None), lam=20.0, adversarial=False)
    assert with_legs["legs"] == pytest.approx(expect, rel=1e-5)
    R.config = M.RefinerConfig.cpu(residual_init_scale=1.0)  # leg_pose_lam 0: no leg term
    without = M._refiner_step(R, D, lr0, (x, None), lam=20.0, adversarial=False)
    assert "legs" not in without
    assert with_legs["loss"] - without["loss"] == pytest.approx(30.0 * expect, rel=1e-4)
    with pytest.raises(ValueError, match="leg_pose_lam"):
        M.RefinerConfig(leg_pose_lam=-1.0)
