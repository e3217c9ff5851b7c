"""rotations.py against scipy.spatial.transform.Rotation: property tests (hypothesis), float64.

Also: gradients are finite at the identity and at 180 degrees, and wrong shapes raise.
"""

from __future__ import annotations

import itertools
import re

import numpy as np
import pytest
import torch
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays
from scipy.spatial.transform import Rotation, Slerp

from course_lib import rotations as rot

ORDERS = ["".join(p) for p in itertools.permutations("XYZ")]
ATOL = 1e-5
SETTINGS = settings(max_examples=200, deadline=None)

_unit = st.floats(-1.0, 1.0, allow_nan=False, allow_subnormal=False)


@st.composite
def quats(draw, max_n: int = 6) -> np.ndarray:
    """(n, 4) unit quaternions; hypothesis' edge values give exact identities and 180-degree turns."""
    n = draw(st.integers(1, max_n))
    q = draw(arrays(np.float64, (n, 4), elements=_unit))
    q[np.linalg.norm(q, axis=-1) < 0.1] += np.array([1.0, 0.0, 0.0, 0.0])
    return q / np.linalg.norm(q, axis=-1, keepdims=True)


def angles(n_max: int = 6, high: float = np.pi) -> st.SearchStrategy:
    return st.integers(1, n_max).flatmap(
        lambda n: arrays(np.float64, (n, 3), elements=st.floats(-high, high, allow_subnormal=False)))


def t64(x: np.ndarray) -> torch.Tensor:
    return torch.as_tensor(np.array(x), dtype=torch.float64)


def scipy_q(q: np.ndarray) -> Rotation:
    return Rotation.from_quat(q, scalar_first=True)


def same_rotation(q1, q2, atol: float = ATOL) -> None:
    """q1, q2 (n, 4): equal up to sign."""
    dots = np.abs(np.sum(np.asarray(q1) * np.asarray(q2), -1))
    np.testing.assert_allclose(dots, 1.0, atol=atol)


# ---------------------------------------------------------------- conversions vs scipy


@SETTINGS
@given(quats())
def test_quat_matrix_round_trip_and_scipy(q):
    m = rot.quat_to_matrix(t64(q))
    np.testing.assert_allclose(m.numpy(), scipy_q(q).as_matrix(), atol=ATOL)
    back = rot.matrix_to_quat(m).numpy()
    assert (back[:, 0] >= 0).all()
    same_rotation(back, q)
    np.testing.assert_allclose(np.linalg.norm(back, axis=-1), 1.0, atol=1e-12)


@SETTINGS
@given(quats())
def test_quat_expmap_round_trip_and_scipy(q):
    r = rot.quat_to_expmap(t64(q)).numpy()
    ref = scipy_q(q).as_rotvec()
    # at exactly 180 degrees r and -r are the same rotation
    np.testing.assert_allclose(np.minimum(np.abs(r - ref), np.abs(r + ref)), 0.0, atol=ATOL)
    assert (np.linalg.norm(r, axis=-1) <= np.pi + 1e-9).all()
    same_rotation(rot.expmap_to_quat(t64(r)).numpy(), q)


@SETTINGS
@given(angles(high=3.1))
def test_expmap_quat_round_trip(r):
    r = r * (np.linalg.norm(r, axis=-1, keepdims=True) < 3.1)  # |r| < pi: the expmap is unique
    np.testing.assert_allclose(rot.quat_to_expmap(rot.expmap_to_quat(t64(r))).numpy(), r, atol=ATOL)
    same_rotation(rot.expmap_to_quat(t64(r)).numpy(), Rotation.from_rotvec(r).as_quat(scalar_first=True))


@SETTINGS
@given(angles(high=3.1))
def test_expmap_to_matrix_is_rodrigues_and_the_quaternion_route(r):
    """Rodrigues' matrix equals scipy's rotvec matrix and quat_to_matrix(expmap_to_quat(r)), also at r = 0."""
    r = np.concatenate((r, np.zeros((1, 3)), np.full((1, 3), 1e-7)))
    m = rot.expmap_to_matrix(t64(r)).numpy()
    np.testing.assert_allclose(m, Rotation.from_rotvec(r).as_matrix(), atol=ATOL)
    np.testing.assert_allclose(m, rot.quat_to_matrix(rot.expmap_to_quat(t64(r))).numpy(), atol=ATOL)


@SETTINGS
@given(a=angles())
def test_euler_matches_scipy_and_round_trips(a):
    """All six intrinsic (BVH) orders and their extrinsic twins, on the same angles."""
    for order in ORDERS + [o.lower() for o in ORDERS]:
        ref = Rotation.from_euler(order, a)
        q = rot.euler_to_quat(t64(a), order).numpy()
        same_rotation(q, ref.as_quat(scalar_first=True))
        back = rot.quat_to_euler(t64(q), order).numpy()
        assert (np.abs(back[:, 1]) <= np.pi / 2 + 1e-9).all(), (order, back)
        same_rotation(rot.euler_to_quat(t64(back), order).numpy(), q)
        # away from gimbal lock the angles are unique: they equal scipy's
        ok = np.abs(np.cos(back[:, 1])) > 1e-3
        diff = np.angle(np.exp(1j * (back - ref.as_euler(order))))
        np.testing.assert_allclose(diff[ok], 0.0, atol=ATOL, err_msg=order)


def test_euler_bvh_channel_meaning():
    """'ZYX' = channels Zrotation Yrotation Xrotation: R = Rz(a0) Ry(a1) Rx(a2)."""
    a = t64([[0.3, -0.7, 1.1]])
    rz, ry, rx = (rot.axis_angle_to_quat(t64(ax), a[:, i]) for i, ax in enumerate(([0, 0, 1], [0, 1, 0], [1, 0, 0])))
    same_rotation(rot.euler_to_quat(a, "ZYX").numpy(), rot.quat_mul(rot.quat_mul(rz, ry), rx).numpy(), atol=1e-12)
    a = t64(np.random.default_rng(0).uniform(-np.pi, np.pi, (50, 3)))
    for order in ORDERS + [o.lower() for o in ORDERS]:
        np.testing.assert_allclose(rot.euler_to_matrix(a, order).numpy(), Rotation.from_euler(order, a).as_matrix(),
                                   atol=1e-12)


@pytest.mark.parametrize("order", ORDERS)
def test_euler_gimbal_lock_round_trip(order):
    a = t64([[0.4, np.pi / 2, -1.2], [-2.0, -np.pi / 2, 0.3]])
    q = rot.euler_to_quat(a, order)
    back = rot.quat_to_euler(q, order)
    assert back[:, 2].abs().max() < 1e-12  # scipy's convention: the third angle is 0
    same_rotation(rot.euler_to_quat(back, order).numpy(), q.numpy(), atol=1e-9)


@SETTINGS
@given(quats())
def test_sixd_round_trips(q):
    m = rot.quat_to_matrix(t64(q))
    d6 = rot.matrix_to_sixd(m)
    np.testing.assert_allclose(d6.numpy(), np.concatenate((m[..., :, 0], m[..., :, 1]), -1), atol=0)
    np.testing.assert_allclose(rot.sixd_to_matrix(d6).numpy(), m.numpy(), atol=ATOL)
    same_rotation(rot.sixd_to_quat(rot.quat_to_sixd(t64(q))).numpy(), q)


@SETTINGS
@given(quats(), arrays(np.float64, (6, 6), elements=st.floats(-0.3, 0.3)))
def test_gram_schmidt_gives_rotation_and_fixes_rotations(q, noise):
    m = rot.quat_to_matrix(t64(q))
    np.testing.assert_allclose(rot.gram_schmidt(m).numpy(), m.numpy(), atol=ATOL)
    noisy = t64(m.numpy() + noise[: len(q)].reshape(-1, 3, 2).repeat(2, -1)[..., :3] * 0.5)
    g = rot.gram_schmidt(noisy).numpy()
    np.testing.assert_allclose(g @ g.transpose(0, 2, 1), np.broadcast_to(np.eye(3), g.shape), atol=ATOL)
    np.testing.assert_allclose(np.linalg.det(g), 1.0, atol=ATOL)
    # the first column keeps its direction, the second stays in the span of the first two
    c0 = noisy[..., :, 0].numpy()
    np.testing.assert_allclose(g[..., :, 0], c0 / np.linalg.norm(c0, axis=-1, keepdims=True), atol=ATOL)
    np.testing.assert_allclose(np.einsum("ni,ni->n", g[..., :, 2], noisy[..., :, 1].numpy()), 0.0, atol=ATOL)


# ---------------------------------------------------------------- products, rotation, slerp


@SETTINGS
@given(quats(max_n=1), quats(max_n=1))
def test_quat_mul_is_scipy_composition(a, b):
    ab = rot.quat_mul(t64(a), t64(b)).numpy()
    same_rotation(ab, (scipy_q(a) * scipy_q(b)).as_quat(scalar_first=True))
    np.testing.assert_allclose(np.linalg.norm(ab, axis=-1), 1.0, atol=1e-12)


@SETTINGS
@given(quats(), arrays(np.float64, (6, 3), elements=st.floats(-10, 10)))
def test_quat_rotate_is_scipy_apply(q, v):
    v = v[: len(q)]
    np.testing.assert_allclose(rot.quat_rotate(t64(q), t64(v)).numpy(), scipy_q(q).apply(v), atol=ATOL)
    np.testing.assert_allclose(rot.quat_rotate(t64(q), t64(v)).numpy(),
                               (rot.quat_to_matrix(t64(q)) @ t64(v)[..., None])[..., 0].numpy(), atol=ATOL)


@SETTINGS
@given(quats(max_n=1), quats(max_n=1), st.floats(0.0, 1.0))
def test_slerp_matches_scipy(q0, q1, t):
    if abs(np.sum(q0 * q1)) < 1e-3:
        # a half-turn apart has two shortest arcs: tilt q1 towards q0 (a fixed-axis turn can leave the dot at 0)
        q1 = q1 + 0.1 * q0
        q1 = q1 / np.linalg.norm(q1, axis=-1, keepdims=True)
    ours = rot.quat_slerp(t64(q0), t64(q1), t).numpy()
    ref = Slerp([0.0, 1.0], Rotation.concatenate([scipy_q(q0), scipy_q(q1)]))([t]).as_quat(scalar_first=True)
    same_rotation(ours, ref)


# ---------------------------------------------------------------- geodesic distances


@SETTINGS
@given(quats(), quats())
def test_geodesics_match_scipy_magnitude(q1, q2):
    n = min(len(q1), len(q2))
    q1, q2 = q1[:n], q2[:n]
    angle = (scipy_q(q1).inv() * scipy_q(q2)).magnitude()  # in [0, pi]
    a, b = t64(q1), t64(q2)
    np.testing.assert_allclose(rot.quat_geodesic(a, b, "d1").numpy(), angle, atol=ATOL)
    np.testing.assert_allclose(rot.quat_geodesic(a, -b, "d1").numpy(), angle, atol=ATOL)  # double cover
    # d2 = 1 - |q.q'| = 1 - cos(angle/2);  d3 = min |q -+ q'|^2 = 2 (1 - |q.q'|)   (Ghorbani eq. 18-20)
    np.testing.assert_allclose(rot.quat_geodesic(a, b, "d2").numpy(), 1 - np.cos(angle / 2), atol=ATOL)
    np.testing.assert_allclose(rot.quat_geodesic(a, b, "d3").numpy(), 2 * (1 - np.cos(angle / 2)), atol=ATOL)
    m1, m2 = rot.quat_to_matrix(a), rot.quat_to_matrix(b)
    np.testing.assert_allclose(rot.matrix_geodesic(m1, m2).numpy(), angle, atol=ATOL)


def test_geodesic_known_values():
    ident = rot.quat_identity((), torch.float64)
    half_turn = t64([0.0, 0.0, 1.0, 0.0])
    quarter = rot.axis_angle_to_quat(t64([0.0, 0.0, 1.0]), t64(np.pi / 2))
    assert rot.quat_geodesic(ident, half_turn).item() == pytest.approx(np.pi, abs=1e-12)
    assert rot.quat_geodesic(ident, quarter).item() == pytest.approx(np.pi / 2, abs=1e-12)
    assert rot.quat_geodesic(ident, ident).item() == 0.0
    assert rot.matrix_geodesic(rot.quat_to_matrix(ident), rot.quat_to_matrix(half_turn)).item() == pytest.approx(np.pi)


# ---------------------------------------------------------------- finite gradients at 0 and 180 degrees

_S = np.sqrt(0.5)
SPECIAL = t64([
    [1.0, 0, 0, 0],  # identity
    [0.0, 1, 0, 0], [0.0, 0, 1, 0], [0.0, 0, 0, 1],  # 180 degrees about x, y, z
    [0.0, _S, _S, 0], [0.0, _S, 0, _S],  # 180 degrees about diagonals (the second is gimbal lock for XYZ)
])


def _grad(f, *xs: torch.Tensor) -> list[torch.Tensor]:
    xs = [x.clone().requires_grad_(True) for x in xs]
    y = f(*xs)
    w = torch.linspace(0.5, 1.5, y.numel(), dtype=y.dtype).reshape(y.shape)  # a generic direction
    return list(torch.autograd.grad((y * w).sum(), xs, allow_unused=False))


def _finite(grads: list[torch.Tensor]) -> bool:
    return all(bool(torch.isfinite(g).all()) for g in grads)


CONVERSIONS = {
    "quat_to_matrix": (rot.quat_to_matrix, lambda: [SPECIAL]),
    "matrix_to_quat": (rot.matrix_to_quat, lambda: [rot.quat_to_matrix(SPECIAL)]),
    "quat_to_expmap": (rot.quat_to_expmap, lambda: [SPECIAL]),
    "expmap_to_quat": (rot.expmap_to_quat, lambda: [rot.quat_to_expmap(SPECIAL)]),
    "expmap_to_matrix": (rot.expmap_to_matrix, lambda: [rot.quat_to_expmap(SPECIAL)]),
    "quat_to_sixd": (rot.quat_to_sixd, lambda: [SPECIAL]),
    "sixd_to_quat": (rot.sixd_to_quat, lambda: [rot.quat_to_sixd(SPECIAL)]),
    "sixd_to_matrix": (rot.sixd_to_matrix, lambda: [rot.quat_to_sixd(SPECIAL)]),
    "matrix_to_sixd": (rot.matrix_to_sixd, lambda: [rot.quat_to_matrix(SPECIAL)]),
    "gram_schmidt": (rot.gram_schmidt, lambda: [rot.quat_to_matrix(SPECIAL)]),
    "quat_mul": (rot.quat_mul, lambda: [SPECIAL, SPECIAL.flip(0)]),
    "quat_rotate": (rot.quat_rotate, lambda: [SPECIAL, t64(np.ones((6, 3)))]),
    "quat_slerp": (lambda a, b: rot.quat_slerp(a, b, 0.3), lambda: [SPECIAL, SPECIAL]),
    "quat_slerp_opposite": (lambda a, b: rot.quat_slerp(a, b, 0.3), lambda: [SPECIAL, -SPECIAL]),
    "axis_angle_to_quat": (rot.axis_angle_to_quat, lambda: [t64(np.eye(3)), t64([0.0, np.pi, 2 * np.pi])]),
    **{f"quat_to_euler_{o}": (lambda q, o=o: rot.quat_to_euler(q, o), lambda: [SPECIAL]) for o in ORDERS},
    **{f"euler_to_quat_{o}": (lambda a, o=o: rot.euler_to_quat(a, o), lambda o=o: [rot.quat_to_euler(SPECIAL, o)])
       for o in ORDERS},
    # distance 0 (same rotation, also q vs -q) and distance pi (180 degrees apart)
    **{f"quat_geodesic_{k}_{case}": (lambda a, b, k=k: rot.quat_geodesic(a, b, k), pair)
       for k in ("d1", "d2", "d3") for case, pair in (
           ("zero", lambda: [SPECIAL, SPECIAL]), ("sign", lambda: [SPECIAL, -SPECIAL]),
           ("pi", lambda: [SPECIAL, rot.quat_mul(SPECIAL, t64([0.0, 0, 0, 1]))]))},
    "matrix_geodesic_zero": (rot.matrix_geodesic, lambda: [rot.quat_to_matrix(SPECIAL)] * 2),
    "matrix_geodesic_pi": (rot.matrix_geodesic, lambda: [
        rot.quat_to_matrix(SPECIAL), rot.quat_to_matrix(rot.quat_mul(SPECIAL, t64([0.0, 1, 0, 0])))]),
}


@pytest.mark.parametrize("name", sorted(CONVERSIONS))
def test_gradients_finite_at_identity_and_half_turn(name):
    f, inputs = CONVERSIONS[name]
    xs = inputs()
    assert torch.isfinite(f(*xs)).all(), f"{name}: non-finite value"
    assert _finite(_grad(f, *xs)), f"{name}: NaN/inf gradient at identity or 180 degrees"


def test_d1_gradient_is_the_unit_rate_of_the_angle():
    """d/dt d1(q, q exp(t axis)) = 1: the safe form keeps the true derivative away from 0."""
    q = rot.quat_normalize(t64([0.3, -0.2, 0.9, 0.1]))
    t = t64(0.4).requires_grad_(True)
    d = rot.quat_geodesic(q, rot.quat_mul(q, rot.expmap_to_quat(t * t64([0.0, 0.6, 0.8]))))
    (g,) = torch.autograd.grad(d, t)
    assert d.item() == pytest.approx(0.4, abs=1e-12) and g.item() == pytest.approx(1.0, abs=1e-9)


def test_matrix_to_quat_gradient_matches_finite_differences_near_half_turn():
    r = t64([np.pi - 1e-3, 0.2, -0.1])
    f = lambda x: rot.quat_to_expmap(rot.matrix_to_quat(rot.quat_to_matrix(rot.expmap_to_quat(x)))).sum()  # noqa: E731
    assert torch.autograd.gradcheck(f, (r.clone().requires_grad_(True),), eps=1e-7, atol=1e-5)


# ---------------------------------------------------------------- errors


@pytest.mark.parametrize("call, message", [
    (lambda: rot.quat_mul(torch.zeros(3), torch.zeros(4)), "quat_mul a"),
    (lambda: rot.quat_rotate(torch.zeros(4), torch.zeros(4)), "quat_rotate v"),
    (lambda: rot.quat_to_matrix(torch.zeros(2, 3)), "quat_to_matrix"),
    (lambda: rot.matrix_to_quat(torch.zeros(3, 4)), r"\(\.\.\., 3, 3\)"),
    (lambda: rot.euler_to_quat(torch.zeros(2, 4), "XYZ"), "euler_to_quat"),
    (lambda: rot.euler_to_quat(torch.zeros(3), "XYX"), "permutation"),
    (lambda: rot.euler_to_quat(torch.zeros(3), "XyZ"), "permutation"),
    (lambda: rot.quat_to_euler(torch.zeros(3), "XYZ"), "quat_to_euler"),
    (lambda: rot.sixd_to_matrix(torch.zeros(5)), "sixd_to_matrix"),
    (lambda: rot.matrix_to_sixd(torch.zeros(3, 2)), "matrix_to_sixd"),
    (lambda: rot.gram_schmidt(torch.zeros(2, 2)), "gram_schmidt"),
    (lambda: rot.quat_geodesic(torch.zeros(4), torch.zeros(4), "d4"), "kind"),
    (lambda: rot.quat_geodesic(torch.zeros(4), torch.zeros(3)), "quat_geodesic q2"),
    (lambda: rot.matrix_geodesic(torch.eye(3), torch.zeros(4, 4)), "matrix_geodesic m2"),
    (lambda: rot.quat_normalize(torch.zeros(4)), "zero norm"),
])
def test_wrong_shapes_raise_clear_errors(call, message):
    with pytest.raises(ValueError, match=message):
        call()


# ---------------------------------------------------------------------------
# Invalid rotations are errors, numpy inputs are tensors
# ---------------------------------------------------------------------------

@pytest.mark.parametrize("q, words", [
    ([0.0, 0.0, 0.0, 0.0], "norm 0 (a zero quaternion is no rotation)"),
    ([1.0, 1.0, 0.0, 0.0], "norm 1.41421"),
    ([float("nan"), 0.0, 0.0, 0.0], "norm nan"),
    ([1.02, 0.0, 0.0, 0.0], "norm 1.02"),
])
@pytest.mark.parametrize("fn", [rot.quat_to_matrix, rot.quat_to_expmap, lambda q: rot.quat_to_euler(q, "ZYX"),
                                rot.quat_to_sixd])
def test_invalid_quaternions_raise(fn, q, words):
    with pytest.raises(ValueError, match=re.escape(words) + ".*normalise with quat_normalize"):
        fn(torch.tensor([[1.0, 0.0, 0.0, 0.0], q], dtype=torch.float64))


def test_near_unit_quaternions_are_used_as_given():
    """Within UNIT_TOL nothing is normalised: the plain formula's numbers, bit for bit."""
    q = torch.tensor([1.005, 0.0, 0.0, 0.0], dtype=torch.float64)
    assert rot.quat_to_matrix(q)[1, 1] == 1 - 2 * 0.0 and rot.quat_to_matrix(q)[0, 0] == 1.0
    q = rot.quat_normalize(torch.randn(50, 4, dtype=torch.float64)) * 1.004
    w, x, y, z = q.unbind(-1)
    assert torch.equal(rot.quat_to_matrix(q)[:, 0, 1], 2 * (x * y - w * z))


def test_numpy_inputs_give_tensors():
    rng = np.random.default_rng(3)
    q = rng.normal(size=(5, 4))
    q /= np.linalg.norm(q, axis=-1, keepdims=True)
    m = rot.quat_to_matrix(q)
    assert isinstance(m, torch.Tensor) and m.dtype == torch.float64
    torch.testing.assert_close(m, rot.quat_to_matrix(torch.from_numpy(q)))
    torch.testing.assert_close(rot.quat_mul(q, q), rot.quat_mul(torch.from_numpy(q), torch.from_numpy(q)))
    ones = torch.ones(5, 3, dtype=torch.float64)
    torch.testing.assert_close(rot.quat_rotate(q, np.ones((5, 3))), rot.quat_rotate(torch.from_numpy(q), ones))
    torch.testing.assert_close(rot.matrix_to_quat(m.numpy()), rot.quat_canonical(torch.from_numpy(q)))
    torch.testing.assert_close(rot.quat_to_euler(q[:, None].repeat(2, 1), "ZYX"),
                               rot.quat_to_euler(torch.from_numpy(q)[:, None].repeat(1, 2, 1), "ZYX"))


def test_axis_angle_zero_axis():
    with pytest.raises(ValueError, match="zero length"):
        rot.axis_angle_to_quat(torch.zeros(3), torch.tensor(0.5))
    with pytest.raises(ValueError, match="NaN or inf"):
        rot.axis_angle_to_quat(torch.tensor([float("nan"), 0.0, 1.0]), torch.tensor(0.5))
    # a zero axis with a zero angle is the identity (no direction needed), next to a normal one
    q = rot.axis_angle_to_quat(np.array([[0.0, 0.0, 0.0], [0.0, 2.0, 0.0]]), np.array([0.0, np.pi]))
    torch.testing.assert_close(q, torch.tensor([[1.0, 0, 0, 0], [np.cos(np.pi / 2), 0, 1, 0]], dtype=torch.float64))
    assert torch.isfinite(q).all()


def test_matrix_to_quat_refuses_a_reflection():
    reflect = torch.diag(torch.tensor([-1.0, 1.0, 1.0], dtype=torch.float64))
    with pytest.raises(ValueError, match="determinant -1, not 1: not a rotation"):
        rot.matrix_to_quat(torch.stack([torch.eye(3, dtype=torch.float64), reflect]))
    with pytest.raises(ValueError, match="determinant nan"):
        rot.matrix_to_quat(torch.full((3, 3), float("nan")))
    with pytest.raises(ValueError, match="determinant 8"):
        rot.matrix_to_quat(2 * torch.eye(3))
