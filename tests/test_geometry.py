"""Pose2 and angle helpers: hand-computed answers and algebraic properties (hypothesis)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from scanclique.errors import ScanError
from scanclique.geometry import Pose2, rotation_matrix, wrap_angle

finite = st.floats(min_value=-50.0, max_value=50.0, allow_nan=False, allow_infinity=False)
angles = st.floats(min_value=-20.0, max_value=20.0, allow_nan=False, allow_infinity=False)
poses = st.builds(Pose2.from_xytheta, finite, finite, angles)
points = st.lists(st.tuples(finite, finite), min_size=1, max_size=6).map(
    lambda p: np.array(p, dtype=float)
)


def close(p: Pose2, q: Pose2, tol: float = 1e-9) -> bool:
    t, r = p.distance_to(q)
    return t < tol * (1 + abs(p.x) + abs(p.y)) and r < tol


# -- constructors and converters -------------------------------------------------------
def test_constructors_agree():
    a = Pose2.from_xytheta(1.5, -2.0, 0.25)
    b = Pose2.from_array([1.5, -2.0, 0.25])
    m = np.array(
        [[math.cos(0.25), -math.sin(0.25), 1.5], [math.sin(0.25), math.cos(0.25), -2.0], [0, 0, 1]]
    )
    c = Pose2.from_matrix(m)
    for p in (a, b, c):
        assert p.as_array() == pytest.approx([1.5, -2.0, 0.25], abs=1e-12)
    np.testing.assert_allclose(a.as_matrix(), m, atol=1e-15)
    np.testing.assert_allclose(a.rotation, m[:2, :2], atol=1e-15)
    np.testing.assert_allclose(a.translation, [1.5, -2.0])
    assert Pose2.identity().as_array().tolist() == [0.0, 0.0, 0.0]


def test_from_matrix_reorthonormalises():
    # a slightly scaled rotation block still gives the right angle
    m = np.eye(3)
    m[:2, :2] = 1.01 * rotation_matrix(0.7)
    assert Pose2.from_matrix(m).theta == pytest.approx(0.7, abs=1e-12)


@pytest.mark.parametrize(
    ("theta", "wrapped"),
    [
        (0.0, 0.0),
        (math.pi, -math.pi),
        (-math.pi, -math.pi),
        (3 * math.pi / 2, -math.pi / 2),
        (-7.0, -7.0 + 2 * math.pi),
    ],
)
def test_theta_is_wrapped(theta, wrapped):
    assert Pose2(0.0, 0.0, theta).theta == pytest.approx(wrapped, abs=1e-12)


@pytest.mark.parametrize(
    "args",
    [(math.nan, 0, 0), (0, math.inf, 0), (0, 0, -math.inf), (0, 0, math.nan)],
)
def test_non_finite_rejected(args):
    with pytest.raises(ScanError):
        Pose2(*args)
    with pytest.raises(ScanError):
        Pose2.from_array(args)


def test_matrix_with_non_finite_rejected():
    m = np.eye(3)
    m[0, 2] = np.nan
    with pytest.raises(ScanError):
        Pose2.from_matrix(m)


@pytest.mark.parametrize("bad", [[1.0, 2.0], [1.0, 2.0, 3.0, 4.0], np.zeros((2, 2))])
def test_from_array_shape_error(bad):
    with pytest.raises(ScanError):
        Pose2.from_array(bad)


@pytest.mark.parametrize("bad", [np.eye(2), np.eye(4), np.zeros(9)])
def test_from_matrix_shape_error(bad):
    with pytest.raises(ScanError):
        Pose2.from_matrix(bad)


@pytest.mark.parametrize("bad", [np.zeros(2), np.zeros((3, 3)), np.zeros((2, 2, 2))])
def test_transform_shape_error(bad):
    with pytest.raises(ScanError):
        Pose2.identity().transform(bad)


def test_pose_is_frozen():
    p = Pose2(1.0, 2.0, 0.5)
    with pytest.raises(AttributeError):
        p.x = 3.0  # type: ignore[misc]


# -- known answers -----------------------------------------------------------------------
def test_transform_maps_b_into_a():
    # frame b sits at (1, 0) in frame a, turned 90 degrees: b's x axis is a's y axis
    T_a_b = Pose2(1.0, 0.0, math.pi / 2)
    pts_b = np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0], [2.0, 3.0]])
    expected_a = np.array([[1.0, 0.0], [1.0, 1.0], [0.0, 0.0], [-2.0, 2.0]])
    np.testing.assert_allclose(T_a_b.transform(pts_b), expected_a, atol=1e-12)
    np.testing.assert_allclose(T_a_b.inverse().transform(expected_a), pts_b, atol=1e-12)


def test_compose_known_answer():
    # a -> b: move 1 forward and turn left; b -> c: move 1 forward (along a's y axis)
    T_a_b = Pose2(1.0, 0.0, math.pi / 2)
    T_b_c = Pose2(1.0, 0.0, 0.0)
    T_a_c = T_a_b @ T_b_c
    assert T_a_c.as_array() == pytest.approx([1.0, 1.0, math.pi / 2], abs=1e-12)
    # and the other order is different (rigid motions do not commute)
    assert (T_b_c @ T_a_b).as_array() == pytest.approx([2.0, 0.0, math.pi / 2], abs=1e-12)


def test_inverse_known_answer():
    inv = Pose2(1.0, 0.0, math.pi / 2).inverse()
    assert inv.as_array() == pytest.approx([0.0, 1.0, -math.pi / 2], abs=1e-12)


def test_matmul_rejects_non_pose():
    with pytest.raises(TypeError):
        Pose2.identity() @ (1.0, 2.0, 3.0)  # noqa: B018


@pytest.mark.parametrize(
    ("p", "q", "dist", "ang"),
    [
        (Pose2(0, 0, 0), Pose2(3, 4, 0.5), 5.0, 0.5),
        (Pose2(1, 1, math.pi / 2), Pose2(1, 1, -math.pi / 2), 0.0, math.pi),
        (Pose2(0, 0, 3.1), Pose2(0, 0, -3.1), 0.0, 2 * math.pi - 6.2),
        (Pose2(2, 0, math.pi / 2), Pose2(2, 3, 0.0), 3.0, math.pi / 2),
    ],
)
def test_distance_to_known(p, q, dist, ang):
    d, a = p.distance_to(q)
    assert d == pytest.approx(dist, abs=1e-12)
    assert a == pytest.approx(ang, abs=1e-12)
    d2, a2 = q.distance_to(p)
    assert (d2, a2) == pytest.approx((dist, ang), abs=1e-12)


@pytest.mark.parametrize(
    ("angle", "expected"),
    [
        (0.0, 0.0),
        (math.pi / 2, math.pi / 2),
        (3 * math.pi / 2, -math.pi / 2),
        (-3 * math.pi / 2, math.pi / 2),
        (math.pi, -math.pi),
        (10.0, 10.0 - 4 * math.pi),
    ],
)
def test_wrap_angle_known(angle, expected):
    assert float(wrap_angle(angle)) == pytest.approx(expected, abs=1e-12)


def test_wrap_angle_array():
    a = np.array([0.0, 4.0, -4.0, 7.0])
    np.testing.assert_allclose(
        wrap_angle(a), [0.0, 4.0 - 2 * math.pi, -4.0 + 2 * math.pi, 7.0 - 2 * math.pi]
    )


def test_wrap_angle_just_below_minus_pi_stays_in_range():
    a = np.nextafter(-math.pi, -10.0)
    assert float(wrap_angle(a)) < math.pi
    assert Pose2(0.0, 0.0, a).theta < math.pi


# -- properties --------------------------------------------------------------------------
@given(st.floats(min_value=-1e3, max_value=1e3, allow_nan=False))
def test_wrap_angle_range_and_equivalence(a):
    w = float(wrap_angle(a))
    assert -math.pi <= w <= math.pi
    assert math.cos(w) == pytest.approx(math.cos(a), abs=1e-9)
    assert math.sin(w) == pytest.approx(math.sin(a), abs=1e-9)


@settings(max_examples=200)
@given(poses, poses, poses)
def test_composition_associative(a, b, c):
    assert close((a @ b) @ c, a @ (b @ c), 1e-9)


@given(poses)
def test_inverse_is_inverse(p):
    ident = Pose2.identity()
    assert close(p @ p.inverse(), ident, 1e-9)
    assert close(p.inverse() @ p, ident, 1e-9)
    assert close(p.inverse().inverse(), p, 1e-9)


@given(poses, poses)
def test_composition_matches_matrices(a, b):
    np.testing.assert_allclose((a @ b).as_matrix(), a.as_matrix() @ b.as_matrix(), atol=1e-9)
    np.testing.assert_allclose(a.inverse().as_matrix(), np.linalg.inv(a.as_matrix()), atol=1e-9)


@given(poses, points)
def test_transform_consistent_with_matrix(p, pts):
    homog = np.column_stack((pts, np.ones(len(pts))))
    expected = (p.as_matrix() @ homog.T).T[:, :2]
    np.testing.assert_allclose(p.transform(pts), expected, atol=1e-9)


@given(poses, poses, points)
def test_transform_of_composition(a, b, pts):
    np.testing.assert_allclose((a @ b).transform(pts), a.transform(b.transform(pts)), atol=1e-8)


@given(poses)
def test_matrix_round_trip(p):
    assert close(Pose2.from_matrix(p.as_matrix()), p, 1e-12)
    assert close(Pose2.from_array(p.as_array()), p, 1e-12)


@given(poses, poses)
def test_distance_is_symmetric_and_rigid(p, q):
    d1, a1 = p.distance_to(q)
    d2, a2 = q.distance_to(p)
    assert d1 == pytest.approx(d2, abs=1e-9)
    assert a1 == pytest.approx(a2, abs=1e-9)
    assert 0.0 <= a1 <= math.pi
    # the distance between two poses does not depend on the frame they are expressed in
    g = Pose2(3.0, -1.0, 0.7)
    d3, a3 = (g @ p).distance_to(g @ q)
    assert d3 == pytest.approx(d1, abs=1e-8)
    assert a3 == pytest.approx(a1, abs=1e-9)


def test_align_poses_recovers_a_motion_and_uses_the_headings():
    """Exact pairs give the motion back; poses bunched within a metre with 5 cm of
    position noise but exact headings give the rotation from the headings (a hundredth of
    the error of align_se2, by positions alone); one pair gives its own motion."""
    from scanclique.geometry import Pose2, align_poses, align_se2

    rng = np.random.default_rng(4)
    T = Pose2(3.0, -2.0, 2.5)
    a = [Pose2(*rng.uniform(-20, 20, 2), rng.uniform(-3, 3)) for _ in range(12)]
    b = [T @ p for p in a]
    A = np.array([p.as_array() for p in a])
    B = np.array([p.as_array() for p in b])
    got = Pose2(*align_poses(A, B, 0.1, 0.01))
    assert got.distance_to(T)[0] < 1e-9 and got.distance_to(T)[1] < 1e-9
    near = A.copy()
    near[:, :2] = rng.uniform(-0.5, 0.5, (12, 2))
    B = np.array([(T @ Pose2.from_array(p)).as_array() for p in near])
    B[:, :2] += rng.normal(0.0, 0.05, (12, 2))
    th = Pose2(*align_poses(near, B, 0.1, np.radians(1.0))).theta
    _, _, th_pos = align_se2(near[:, :2], B[:, :2])
    assert 100 * abs(th - T.theta) < abs(th_pos - T.theta), (th, th_pos)
    one = Pose2(*align_poses(A[:1], B[:1], 0.1, 0.01))
    want = Pose2.from_array(B[0]) @ Pose2.from_array(A[0]).inverse()
    assert one.distance_to(want)[0] < 1e-9 and one.distance_to(want)[1] < 1e-9
