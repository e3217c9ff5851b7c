"""Procedural locomotion driven by a control program: idle, walk, jog, run, side-steps, backwards, turns.

Pipeline (all numpy, vectorised over time; only the 1-D gait phase is a scalar loop):

1. a `ControlProgram` (piecewise-constant targets: gait, speed, direction, heading rate) is
   sampled and smoothed -> local velocity v(t) (m/s, body frame), heading rate w(t) (rad/s),
   soft gait weights;
2. the root path integrates it: yaw(t) = int w dt, x(t) = int R_y(yaw) v dt (trapezoid);
3. a gait phase phi(t) (cycles) integrates the cadence f(v, gait) / 2; each foot touches down
   when its phase (phi, phi + 1/2) crosses an integer and lifts off `duty` later;
4. footholds: a foot plants where the root will be at mid-stance plus a lateral offset and
   stays there for the whole stance (foot skate ~ 0), lifting early only if the root outruns it
   (sudden speed-ups); heel strike rolls about the heel,
   heel-off about the toe joint (ball), so the toe joint never slides; swing is a
   minimum-jerk path with a clearance arc;
5. the body (body.py): pelvis bob (2x step frequency), sway and list (1x), twist with
   counter-rotating chest, lean with speed, acceleration and turning (atan(a / g)), arm swing
   opposite to the legs, stabilised head; legs by two-bone IK, pelvis lowered when a foot is
   out of reach.

Ranges (as in human data): walk 0.8-1.8 m/s at ~95-125 steps/min, jog 2-3.2 m/s, run 3.2-5 m/s
with a flight phase (duty < 0.5), heading rate up to 120 deg/s.

Taught in notebooks/00_data_and_skeletons.ipynb.  Differs from mocap: see the data card
(`course_lib/synthetic/__init__.py`).
"""

from __future__ import annotations

from dataclasses import dataclass, fields

import numpy as np
from scipy.ndimage import gaussian_filter1d

from course_lib.motion import Motion
from course_lib.synthetic.body import (
    BodyTargets,
    LegGeometry,
    arm_swing_local,
    leg_geometry,
    lift_into_reach,
    pose_body,
    reach_drop,
)
from course_lib.synthetic.ik import apply, rot
from course_lib.synthetic.subjects import Subject

FPS = 120.0        # generation frame rate
PAD = 1.5          # seconds simulated before and after a clip, so it starts and ends mid-stride
G = 9.81           # m/s^2
GAITS = ("idle", "walk", "jog", "run", "sidestep", "backward", "turn")
PARK = (0.05, 0.55)  # gait phases where both feet are down (double support): idle parks the phase there
SWING_DELAY = 0.08  # fraction of swing at each end with vertical motion only (no sliding near the floor)
APPROACH_SLOPE = 2.0  # toe height gain per metre of horizontal travel near lift-off and touch-down
STANCE_REACH = 0.75  # the root may travel this x leg length past mid-stance before the foot must lift
SWING_RAMP = 0.25  # fraction of the swing path over which the foot accelerates (and brakes)


@dataclass(frozen=True)
class GaitParams:
    """Parameters of one gait; angles in degrees, lengths in metres."""

    speed: tuple[float, float]  # m/s range of random programs
    cadence: float              # steps/s at speed v0
    cadence_slope: float        # d cadence / d speed, (steps/s) / (m/s)
    v0: float                   # m/s
    duty: float                 # stance fraction of a gait cycle (< 0.5: flight phase)
    heel_strike: float          # toe-up pitch at touch-down, rolls about the heel
    toe_off: float              # heel-up pitch at lift-off, rolls about the ball
    heel_off: float             # stance fraction where the heel starts to rise
    clearance: float            # swing arc height of the toe joint
    width: float                # lateral foot offset, x hip half-width
    bob: float                  # pelvis vertical half-amplitude (2 per cycle)
    bob_low: float              # gait phase of the lowest pelvis
    crouch: float               # pelvis lowered below standing height
    lean: float                 # forward trunk lean
    arm: float                  # shoulder swing amplitude
    elbow: float                # elbow flexion
    twist: float                # pelvis yaw amplitude
    roll: float                 # pelvis list amplitude
    sway: float                 # pelvis lateral sway amplitude
    plant: float                # stance fraction at which the ankle passes under the hip


GAIT_PARAMS = {
    # speed, cadence, slope, v0, duty, heel strike, toe off, heel off, clearance, width, bob, bob_low, crouch,
    # lean, arm, elbow, twist, roll, sway, plant  (see GaitParams)
    "idle": GaitParams((0.0, 0.0), 1.9, 0.4, 1.3, 0.75, 0, 0, 1.0, 0.05, 1.1, 0.0, 0.0, 0.005, 0, 0, 10, 0, 0, 0, 0.5),
    "walk": GaitParams((0.8, 1.8), 1.9, 0.45, 1.3, 0.6, 15, 55, 0.45, 0.08, 0.65, 0.01, 0.06, 0.005, 3, 18, 18, 6, 4,
                       0.022, 0.43),
    "jog": GaitParams((2.0, 3.2), 2.6, 0.2, 2.5, 0.44, 8, 60, 0.35, 0.17, 0.5, 0.02, 0.22, 0.03, 7, 30, 80, 7, 3,
                      0.012, 0.45),
    "run": GaitParams((3.2, 5.0), 2.85, 0.15, 4.0, 0.3, 4, 65, 0.3, 0.28, 0.4, 0.025, 0.155, 0.04, 11, 40, 90, 9, 3,
                      0.008, 0.45),
    "sidestep": GaitParams((0.25, 0.55), 2.1, 0.6, 0.4, 0.6, 0, 10, 0.6, 0.06, 0.8, 0.01, 0.08, 0.02, 1, 3, 15, 0, 2,
                           0.0, 0.5),
    "backward": GaitParams((0.4, 1.1), 1.7, 0.4, 0.8, 0.64, 0, 15, 0.7, 0.06, 0.7, 0.01, 0.07, 0.02, -2, 10, 15, 3,
                           3, 0.015, 0.6),
    "turn": GaitParams((0.0, 0.0), 1.7, 0.0, 0.0, 0.66, 3, 10, 0.6, 0.06, 1.1, 0.008, 0.08, 0.015, 0, 4, 12, 0, 2,
                       0.01, 0.5),
}
# steps/s bounds per gait after the subject's cadence factor (walk: 96-125 steps/min, as in human data)
CADENCE_BOUNDS = {"idle": (1.6, 2.08), "walk": (1.6, 2.08), "jog": (2.35, 2.85), "run": (2.6, 3.2),
                  "sidestep": (1.7, 2.4), "backward": (1.5, 2.1), "turn": (1.5, 2.0)}
_NAMES = [f.name for f in fields(GaitParams)][1:]  # numeric fields, blended by gait weights
_TABLE = np.array([[getattr(GAIT_PARAMS[g], n) for n in _NAMES] for g in GAITS])  # (G, P)
DIRECTIONS = {"walk": 0.0, "jog": 0.0, "run": 0.0, "backward": np.pi, "idle": 0.0, "turn": 0.0}


@dataclass
class ControlProgram:
    """K segments: boundaries times (K+1,) s, gaits (K,) names, speeds (K,) m/s, directions (K,) rad of the
    velocity in the body frame (0 forward, pi backwards, +pi/2 to the left), heading_rates (K,) rad/s."""

    times: np.ndarray
    gaits: tuple[str, ...]
    speeds: np.ndarray
    directions: np.ndarray
    heading_rates: np.ndarray
    smoothing: float = 0.3  # s, Gaussian smoothing of the velocity targets (acceleration limit)

    def __post_init__(self):
        self.times = np.asarray(self.times, np.float64)
        K = len(self.gaits)
        for name in ("speeds", "directions", "heading_rates"):
            setattr(self, name, np.asarray(getattr(self, name), np.float64))
            if getattr(self, name).shape != (K,):
                raise ValueError(f"ControlProgram: {name} must be ({K},), got {getattr(self, name).shape}")
        if self.times.shape != (K + 1,) or np.any(np.diff(self.times) <= 0):
            raise ValueError(f"ControlProgram: times must be ({K + 1},) increasing, got {self.times}")
        bad = [g for g in self.gaits if g not in GAITS]
        if bad:
            raise ValueError(f"ControlProgram: unknown gaits {bad}; known: {GAITS}")

    @classmethod
    def constant(cls, gait: str, speed: float, duration: float, heading_rate: float = 0.0,
                 direction: float | None = None) -> "ControlProgram":
        """One segment of `gait` at `speed` m/s for `duration` s."""
        d = DIRECTIONS.get(gait, np.pi / 2) if direction is None else direction
        return cls(np.array([0.0, duration]), (gait,), [speed], [d], [heading_rate])

    def sample(self, fps: float, t0: float, t1: float) -> dict:
        """Smoothed per-frame controls on frames t0, t0 + 1/fps, ... <= t1 (segments extend past the ends).

        -> dict t (T,), velocity (T, 2) body-frame (x left, z forward) m/s, heading_rate (T,) rad/s,
        weights (T, G) soft gait weights, gait (T,) int index of the dominant gait.
        """
        t = t0 + np.arange(int(np.floor((t1 - t0) * fps + 1e-9)) + 1) / fps
        k = np.clip(np.searchsorted(self.times, t, side="right") - 1, 0, len(self.gaits) - 1)
        v = self.speeds[k, None] * np.stack([np.sin(self.directions[k]), np.cos(self.directions[k])], -1)
        onehot = np.array([[g == name for name in GAITS] for g in self.gaits], np.float64)[k]
        sig = self.smoothing * fps
        v = gaussian_filter1d(v, sig, axis=0, mode="nearest")
        w = gaussian_filter1d(self.heading_rates[k], 0.8 * sig, mode="nearest")
        weights = gaussian_filter1d(onehot, 0.6 * sig, axis=0, mode="nearest")
        return dict(t=t, velocity=v, heading_rate=w, weights=weights, gait=weights.argmax(-1))


def random_control_program(duration: float = 4.0, seed: int | None = None, rng: np.random.Generator | None = None,
                           gaits: tuple[str, ...] = GAITS, segment: tuple[float, float] = (0.8, 2.2),
                           turn_prob: float = 0.5) -> ControlProgram:
    """Smooth random targets over `duration` s: segments of random gait, speed, direction and heading rate.

    Heading rates stay within +-120 deg/s and |v w| <= 3.5 m/s^2 (lateral acceleration of a turn);
    idle, side-steps, backwards and turns on the spot only neighbour walking, never jog/run.
    """
    rng = rng if rng is not None else np.random.default_rng(seed)
    unknown = set(gaits) - set(GAITS)
    if unknown:
        raise ValueError(f"random_control_program: unknown gaits {sorted(unknown)}; known: {GAITS}")
    prob = np.array([{"idle": 0.1, "walk": 0.3, "jog": 0.14, "run": 0.12, "sidestep": 0.1, "backward": 0.1,
                      "turn": 0.1}[g] for g in gaits])
    times, names, speeds, dirs, rates = [0.0], [], [], [], []
    while times[-1] < duration:
        g = str(rng.choice(gaits, p=prob / prob.sum()))
        slow, fast = {"idle", "sidestep", "backward", "turn"}, {"jog", "run"}
        if names and ((g in slow and names[-1] in fast) or (g in fast and names[-1] in slow)) and "walk" in gaits:
            g = "walk"
        p = GAIT_PARAMS[g]
        v = float(rng.uniform(*p.speed))
        d = DIRECTIONS.get(g, float(rng.choice([-1.0, 1.0])) * np.pi / 2)
        if g == "turn":
            w = float(rng.choice([-1.0, 1.0]) * rng.uniform(0.8, 2.0))
        elif g in ("walk", "jog", "run") and rng.random() < turn_prob:
            w = float(rng.uniform(-1.0, 1.0) * min(2.0, 3.5 / max(v, 1e-3)))
        elif g in ("sidestep", "backward"):
            w = float(rng.uniform(-0.3, 0.3))
        else:
            w = 0.0
        names.append(g)
        speeds.append(v)
        dirs.append(d)
        rates.append(w)
        times.append(times[-1] + float(rng.uniform(*segment)))
    return ControlProgram(np.array(times), tuple(names), np.array(speeds), np.array(dirs), np.array(rates))


def integrate_root(velocity: np.ndarray, heading_rate: np.ndarray, fps: float, origin: int = 0) -> np.ndarray:
    """Root path from controls: velocity (T, 2) body frame (x, z), heading_rate (T,) -> (T, 3) (x, z, yaw).

    yaw(t) = int w dt;  p(t) = int R_y(yaw) v dt  (trapezoid rule), with p = 0, yaw = 0 at frame `origin`.
    """
    dt = 1.0 / fps
    yaw = np.concatenate([[0.0], np.cumsum(0.5 * (heading_rate[1:] + heading_rate[:-1]) * dt)])
    yaw -= yaw[origin]
    c, s = np.cos(yaw), np.sin(yaw)
    # R_y(yaw) (x, 0, z) = (c x + s z, 0, -s x + c z)
    vw = np.stack([c * velocity[:, 0] + s * velocity[:, 1], -s * velocity[:, 0] + c * velocity[:, 1]], -1)
    p = np.concatenate([np.zeros((1, 2)), np.cumsum(0.5 * (vw[1:] + vw[:-1]) * dt, 0)])
    p -= p[origin]
    return np.concatenate([p, yaw[:, None]], -1)


def _smooth(x):
    """Smoothstep 3x^2 - 2x^3 on [0, 1] (clipped)."""
    x = np.clip(x, 0.0, 1.0)
    return x * x * (3 - 2 * x)


def _ramp_profile(x, r):
    """Position on [0, 1] of a move whose speed ramps up (smoothstep) over [0, r], stays constant, and ramps
    down over [1 - r, 1]; zero velocity at both ends.  int_0^u (3t^2 - 2t^3) dt = u^3 - u^4 / 2."""
    V = 1.0 / (1.0 - r)
    u, w = np.clip(x / r, 0, 1), np.clip((1 - x) / r, 0, 1)
    return np.where(x < r, V * r * (u ** 3 - u ** 4 / 2),
                    np.where(x > 1 - r, 1 - V * r * (w ** 3 - w ** 4 / 2), V * (r / 2 + x - r)))


def _min_jerk(x):
    """Minimum-jerk profile 10x^3 - 15x^4 + 6x^5 on [0, 1] (zero velocity and acceleration at both ends)."""
    x = np.clip(x, 0.0, 1.0)
    return x ** 3 * (10 - 15 * x + 6 * x * x)


def gait_phase(rate: np.ndarray, park: np.ndarray, fps: float, phase0: float) -> np.ndarray:
    """Gait phase phi (T,) cycles from rate (T,) cycles/s; where park (T,) is True (idle, standing still)
    the phase walks on to the next double-support point of PARK and stops there, so both feet stay planted."""
    phi = np.empty(len(rate))
    p = phase0
    points = np.array(PARK)
    for i in range(len(rate)):  # scalar loop: cheap, and parking is sequential by nature
        step = rate[i] / fps
        if park[i]:
            gap = (points - p) % 1.0
            gap[gap > 1 - 1e-9] = 0.0
            step = min(max(step, 0.8 / fps), gap.min())
        p += step
        phi[i] = p
    return phi


def stance_intervals(psi: np.ndarray, t: np.ndarray, duty: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """One foot's phase psi (T,) (non-decreasing), frame times t (T,), duty (T,) -> touch-down and
    lift-off times (K,), (K,): touch-down when psi crosses an integer k, lift-off when it crosses
    k + duty(touch-down).  The first stance may have begun before t[0] (-inf if the phase is frozen);
    lift-offs beyond t[-1] are +inf; a virtual last stance follows a final swing."""
    dt = t[1] - t[0]
    k = np.floor(psi)
    jumps = np.nonzero(k[1:] > k[:-1])[0] + 1
    rate0 = (psi[1] - psi[0]) / dt

    def cross(level, j):  # time psi reaches level between frames j-1 and j
        return t[j - 1] + (level - psi[j - 1]) / np.maximum(psi[j] - psi[j - 1], 1e-12) * dt

    td0 = t[0] - (psi[0] - k[0]) / rate0 if rate0 > 1e-9 else -np.inf
    td = np.concatenate([[td0], cross(k[jumps], jumps)])
    level = np.concatenate([[k[0]], k[jumps]]) + duty[np.concatenate([[0], jumps])]
    j = np.searchsorted(psi, level, side="left")
    lo = np.full(len(level), np.inf)
    inside = (j > 0) & (j < len(psi))
    lo[inside] = cross(level[inside], j[inside])
    before = j == 0
    lo[before] = t[0] - (psi[0] - level[before]) / max(rate0, 1e-9)
    if np.isfinite(lo[-1]):  # the clip ends in swing: add the next touch-down
        td = np.append(td, max(lo[-1], t[-1]) + 0.3)
        lo = np.append(lo, np.inf)
    return td, lo


def _stance_index(td, lo, t):
    """(K,), (K,), (T,) -> stance index k (T,) of the last touch-down <= t, and stance flag (T,)."""
    k = np.clip(np.searchsorted(td, t, side="right") - 1, 0, len(td) - 1)
    return k, t < lo[k]


def foot_track(t, td, lo, plant, yaw, prm, geo: LegGeometry, root_xz: np.ndarray) -> dict:
    """Toe joint, foot pitch/yaw and toe flexion of one foot on frames t (T,), root path root_xz (T, 2).

    td, lo (K,) stance times; plant (K, 3) toe joint position when flat; yaw (K,) foot yaw;
    prm: dict of (K,) arrays heel_strike, toe_off (rad), heel_off, clearance -> dict of
    toe (T, 3), pitch (T,) (toe up +), yaw (T,), flex (T,) toe relative to foot, stance (T,) bool.
    """
    k, stance = _stance_index(td, lo, t)
    heel_to_toe = geo.toe - geo.heel
    heel = plant + apply(rot("y", yaw), -heel_to_toe)  # (K, 3) heel contact points
    k1 = np.minimum(k + 1, len(td) - 1)
    # stance: heel strike rolls the foot flat about the heel, heel-off lifts the heel about the ball
    with np.errstate(invalid="ignore"):
        dur = np.minimum(lo[k] - td[k], 10.0)  # open-ended stances (idle) count as long ones
        t_hs = np.maximum(np.minimum(0.1, 0.3 * dur), 1e-6)
        t_ho = np.maximum(np.minimum((1 - prm["heel_off"][k]) * dur, 0.3), 1e-6)
        p_st = prm["heel_strike"][k] * (1 - _smooth((t - td[k]) / t_hs)) \
            - prm["toe_off"][k] * _smooth((t - (lo[k] - t_ho)) / t_ho)
    pivot = heel[k] + apply(rot("y", yaw[k]) @ rot("x", -np.maximum(p_st, 0.0)), heel_to_toe)
    toe_st = np.where((p_st > 0)[:, None], pivot, plant[k])
    # swing: minimum-jerk from lift-off to the heel-strike pose of the next stance, plus a clearance arc
    land = heel[k1] + apply(rot("y", yaw[k1]) @ rot("x", -prm["heel_strike"][k1]), heel_to_toe)
    with np.errstate(invalid="ignore"):
        s = np.clip((t - lo[k]) / (td[k1] - lo[k]), 0.0, 1.0)
    # horizontal: lift first (SWING_DELAY), then a smooth-ramped, nearly constant-velocity path to the landing
    # point, set down vertically at the end; monotone in the world, zero velocity at lift-off and touch-down
    x = np.clip((s - SWING_DELAY) / (1 - 1.5 * SWING_DELAY), 0.0, 1.0)
    e = _ramp_profile(x, SWING_RAMP)[:, None]
    toe_sw = plant[k] + (land - plant[k]) * e
    toe_sw[:, 1] = plant[k][:, 1] + (land[:, 1] - plant[k][:, 1]) * _min_jerk(s)
    arc = prm["clearance"][k] * 6.75 * s * (1 - s) ** 2  # peaks at s = 1/3: knee flexion after toe-off
    # leave and approach the floor at >= APPROACH_SLOPE: no sliding with the toe just above the floor
    near = np.minimum(np.linalg.norm((toe_sw - plant[k])[:, [0, 2]], axis=-1),
                      np.linalg.norm((land - toe_sw)[:, [0, 2]], axis=-1))
    toe_sw[:, 1] += np.maximum(arc, np.minimum(APPROACH_SLOPE * near, 0.06))
    p_sw = -prm["toe_off"][k] + (prm["toe_off"][k] + prm["heel_strike"][k1]) * _smooth(s)
    yaw_sw = yaw[k] + (yaw[k1] - yaw[k]) * _min_jerk(s)
    flex_sw = prm["toe_off"][k] * (1 - _smooth(s / 0.4))
    return dict(toe=np.where(stance[:, None], toe_st, toe_sw), pitch=np.where(stance, p_st, p_sw),
                yaw=np.where(stance, yaw[k], yaw_sw), flex=np.where(stance, np.maximum(-p_st, 0.0), flex_sw),
                stance=stance)


def _blend(weights: np.ndarray) -> dict:
    """weights (T, G) -> dict name -> (T,) of gait parameters blended by weight."""
    P = weights @ _TABLE / np.maximum(weights.sum(-1, keepdims=True), 1e-9)
    return {n: P[:, i] for i, n in enumerate(_NAMES)}


def _cadence(speed: np.ndarray, weights: np.ndarray, factor: float) -> np.ndarray:
    """Steps per second (T,): sum_g w_g clip(factor (f_g + slope_g (v - v0_g)), CADENCE_BOUNDS[g])."""
    f = np.zeros(len(speed))
    for i, g in enumerate(GAITS):
        p = GAIT_PARAMS[g]
        v = np.clip(speed, 0.7 * p.speed[0], 1.2 * p.speed[1])
        f += weights[:, i] * np.clip(factor * (p.cadence + p.cadence_slope * (v - p.v0)), *CADENCE_BOUNDS[g])
    return f / np.maximum(weights.sum(-1), 1e-9)


def plan_feet(ctl: dict, path: np.ndarray, phi: np.ndarray, prm: dict, subject_geo: dict) -> dict:
    """Footholds and foot tracks of both feet on the padded frames -> side -> foot_track dict."""
    t = ctl["t"]
    out = {}
    for side, offset, sign in (("Left", 0.0, 1.0), ("Right", 0.5, -1.0)):
        geo = subject_geo[side]
        td, lo = stance_intervals(phi + offset, t, prm["duty"])
        with np.errstate(invalid="ignore"):
            fr0 = np.clip(np.round((np.clip(td, t[0], t[-1]) - t[0]) * FPS).astype(int), 0, len(t) - 1)
            before = np.minimum(prm["plant"][fr0] * (lo - td), 0.3)
            tm = np.where(np.isfinite(td), td + before, np.where(np.isfinite(lo), lo - 0.3, t[0]))
        tm = np.clip(tm, t[0], t[-1])
        x, z, yaw = (np.interp(tm, t, path[:, i]) for i in range(3))
        # half stance width; moving sideways, each foot also sits S/4 further out (S = lateral stride per cycle),
        # so the trailing foot closes in to the nominal width and never crosses the leading one
        lateral_stride = np.abs(ctl["velocity"][:, 0]) * 2.0 / np.maximum(ctl["cadence"], 1e-3)
        width = np.interp(tm, t, prm["width"] * abs(geo.hip[0]) + lateral_stride / 4)
        # toe joint at mid-stance: lateral offset, ankle under the hip (toe ahead by the foot's length)
        local = np.stack([sign * width, np.full_like(width, geo.toe_height), np.full_like(width, geo.toe[2])], -1)
        plant = np.stack([x, np.zeros_like(x), z], -1) + apply(rot("y", yaw), local)
        foot_yaw = yaw + sign * np.radians(6.0)  # toe-out
        lo = _reach_liftoff(t, td, lo, tm, path, STANCE_REACH * (geo.l1 + geo.l2))
        fp = {n: prm[n][fr0] for n in ("heel_off", "clearance")}
        fp.update({n: np.radians(prm[n][fr0]) for n in ("heel_strike", "toe_off")})
        out[side] = foot_track(t, td, lo, plant, foot_yaw, fp, geo, path[:, :2])
    return out


def _reach_liftoff(t, td, lo, tm, path, reach: float) -> np.ndarray:
    """Lift-off times (K,): the phase's, or earlier, once the root has moved `reach` metres from where it
    was at mid-stance (a sudden speed-up would otherwise leave a planted foot out of reach)."""
    lo = lo.copy()
    for k in np.nonzero(np.isfinite(td))[0]:
        i0 = int(np.searchsorted(t, tm[k]))
        d = np.linalg.norm(path[i0:, :2] - path[min(i0, len(t) - 1), :2], axis=-1)
        far = np.nonzero(d > reach)[0]
        if len(far):
            lo[k] = min(lo[k], t[i0 + far[0]])
    return lo


def _body_acceleration(path: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Root path (T, 3) (x, z, yaw) -> body-frame acceleration (lateral x, forward z), (T,), (T,) m/s^2."""
    vel = np.gradient(path[:, :2], axis=0) * FPS
    acc = np.gradient(vel, axis=0) * FPS
    c, s = np.cos(path[:, 2]), np.sin(path[:, 2])
    return c * acc[:, 0] - s * acc[:, 1], s * acc[:, 0] + c * acc[:, 1]


def body_targets(subject: Subject, ctl: dict, path: np.ndarray, phi: np.ndarray, prm: dict, feet: dict,
                 geo: dict, sway_phase: float = 0.0) -> BodyTargets:
    """Pelvis, trunk, head and arms of a locomotion clip, plus the IK leg targets from `feet`."""
    t, yaw, wts = ctl["t"], path[:, 2], ctl["weights"]
    cyc = 2 * np.pi * phi
    a_x, a_z = _body_acceleration(path)
    idle = wts[:, GAITS.index("idle")]
    # sway and list over the stance foot (left stance peaks near phase 0.3), slow weight shifts when idle
    shift = idle * 0.025 * np.sin(2 * np.pi * 0.22 * t + sway_phase)
    sway = subject.hip_sway * prm["sway"] * np.cos(cyc - 2 * np.pi * 0.3) + shift
    roll_list = subject.hip_sway * np.radians(prm["roll"]) * np.cos(cyc - 2 * np.pi * 0.3) + 1.5 * shift
    twist = -np.radians(prm["twist"]) * np.cos(cyc)  # left hip forward at left touch-down (phase 0)
    # pelvis bob, 2 per cycle, lowest at double support (walk) or mid-stance (jog, run)
    bob = sum(wts[:, i] * GAIT_PARAMS[g].bob * -np.cos(2 * cyc - 4 * np.pi * GAIT_PARAMS[g].bob_low)
              for i, g in enumerate(GAITS)) / np.maximum(wts.sum(-1), 1e-9)
    # lean with acceleration and into turns: tan(lean) = a / g
    lean = np.radians(prm["lean"] + 0.5 * subject.torso_lean) + 0.8 * np.arctan(a_z / G)
    roll = -0.8 * np.arctan(a_x / G) + roll_list
    pos = np.stack([path[:, 0], geo["Left"].hips_height - prm["crouch"] + bob, path[:, 1]], -1)
    pos += apply(rot("y", yaw), np.stack([sway, 0 * sway, 0 * sway], -1))
    prot = rot("y", yaw) @ rot("x", 0.6 * lean) @ rot("z", roll) @ rot("y", twist)
    chest = rot("y", -0.8 * twist) @ rot("z", -0.5 * roll_list) @ rot("x", 0.2 * lean)
    head = rot("y", yaw + np.clip(0.3 * ctl["heading_rate"], -0.5, 0.5)) @ rot("x", np.full(len(t), 0.08))
    tg = BodyTargets(pos, prot, np.stack([chest, chest], 1), head)
    amp = np.radians(prm["arm"]) * subject.arm_swing
    for side, sign in (("Left", 1.0), ("Right", -1.0)):
        swing = -sign * amp * np.cos(cyc) + np.radians(4.0)  # opposite to the same-side leg
        elbow = np.radians(prm["elbow"]) + 0.4 * np.maximum(swing, 0.0)
        tg.arm_local[side] = arm_swing_local(swing, elbow, np.full(len(t), np.radians(80.0)), side)
        f = feet[side]
        tg.foot_rot[side] = rot("y", f["yaw"]) @ rot("x", -f["pitch"])
        tg.toe_rot[side] = rot("x", -f["flex"])
        tg.ankle[side] = f["toe"] - apply(tg.foot_rot[side], geo[side].toe)
        tg.knee_pole[side] = apply(rot("y", f["yaw"]), np.array([0.0, 0.0, 1.0])) + \
            apply(rot("y", yaw), np.array([0.0, 0.0, 1.0]))
    skel = subject.skeleton()
    stance = {side: feet[side]["stance"] for side in feet}
    tg.pelvis_pos[:, 1] -= reach_drop(skel, tg.pelvis_pos, tg.pelvis_rot, tg.ankle, FPS, stance)
    for side in feet:  # a swing foot out of reach is lifted (knee flexion) rather than the body lowered
        tg.ankle[side] = lift_into_reach(skel, side, tg.pelvis_pos, tg.pelvis_rot, tg.ankle[side], ~stance[side])
    return tg


def crop_targets(tg: BodyTargets, sl: slice) -> BodyTargets:
    """The frames `sl` of every per-frame target."""
    out = BodyTargets(tg.pelvis_pos[sl], tg.pelvis_rot[sl], tg.spine[sl], tg.head[sl])
    for name in ("ankle", "foot_rot", "toe_rot", "knee_pole", "arm_local", "hand", "elbow_pole"):
        setattr(out, name, {k: v[sl] for k, v in getattr(tg, name).items()})
    return out


def resample_motion(motion: Motion, fps: float) -> Motion:
    """Motion.resample plus nearest-frame resampling of per-frame meta arrays (length T)."""
    if fps == motion.fps:
        return motion
    T = len(motion)
    out = motion.resample(fps)
    idx = np.clip(np.round(np.arange(len(out)) * motion.fps / fps).astype(int), 0, T - 1)
    out.meta = {k: (v[idx] if isinstance(v, np.ndarray) and v.ndim and len(v) == T else v)
                for k, v in motion.meta.items()}
    return out


def locomotion_targets(subject: Subject, program: ControlProgram | None, duration: float,
                       rng: np.random.Generator) -> tuple[BodyTargets, dict]:
    """Body targets of a locomotion clip (cropped to the clip's frames at FPS) and its per-frame meta."""
    if not duration > 0:
        raise ValueError(f"generate_locomotion: duration must be positive, got {duration}")
    if program is None:
        program = random_control_program(duration, rng=rng)
    ctl = program.sample(FPS, -PAD, duration + PAD)
    i0, n = int(round(PAD * FPS)), int(np.floor(duration * FPS + 1e-9)) + 1
    path = integrate_root(ctl["velocity"], ctl["heading_rate"], FPS, origin=i0)
    prm = _blend(ctl["weights"])
    speed = np.linalg.norm(ctl["velocity"], axis=-1)
    cadence = _cadence(speed, ctl["weights"], subject.cadence / subject.step_length)  # steps/s
    # park the gait (both feet down) only when idle *and* the body is still: never drag a planted foot
    park = (ctl["weights"][:, GAITS.index("idle")] > 0.5) & (speed < 0.1) & (np.abs(ctl["heading_rate"]) < 0.2)
    phi = gait_phase(cadence / 2, park, FPS, float(rng.uniform()))
    skel = subject.skeleton()
    geo = {s: leg_geometry(skel, s) for s in ("Left", "Right")}
    feet = plan_feet(dict(ctl, cadence=cadence), path, phi, prm, geo)
    tg = body_targets(subject, ctl, path, phi, prm, feet, geo, float(rng.uniform(0, 2 * np.pi)))
    sl = slice(i0, i0 + n)
    meta = dict(program=program, speed=speed[sl], velocity=ctl["velocity"][sl],
                heading_rate=ctl["heading_rate"][sl], gait=ctl["gait"][sl], gait_names=GAITS,
                contacts=np.stack([feet["Left"]["stance"][sl], feet["Right"]["stance"][sl]], -1),
                root_path=path[sl], phase=phi[sl], cadence=cadence[sl], idle_weight=ctl["weights"][sl, 0])
    return crop_targets(tg, sl), meta


def generate_locomotion(subject: Subject, program: ControlProgram | None = None, duration: float = 4.0,
                        fps: float = FPS, seed: int = 0) -> Motion:
    """A locomotion clip of `duration` s following `program` (random from `seed` when None).

    -> Motion on subject.skeleton() at `fps` (generated at 120 and resampled), action = dominant gait;
    meta: seed, program, speed (T,) m/s, velocity (T, 2) body frame, heading_rate (T,) rad/s,
    gait (T,) index into GAITS, gait_names, contacts (T, 2) bool ground truth (stance), root_path (T, 3)
    (x, z, yaw) integrated from the controls, phase (T,) gait cycles, cadence (T,) steps/s.
    """
    tg, meta = locomotion_targets(subject, program, duration, np.random.default_rng(seed))
    skel = subject.skeleton()
    action = GAITS[int(np.bincount(meta["gait"], minlength=len(GAITS)).argmax())]
    motion = Motion(pose_body(skel, tg), tg.pelvis_pos, skel, FPS, action=action, style=subject.style,
                    subject=subject.name, meta=dict(meta, seed=seed))
    return resample_motion(motion, fps)
