"""Pose from mapped features (paper §6): known poses from exact data, Arun against brute force,
covariance (paper §7) for well- and ill-conditioned constellations, LSQ against median."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.optimize import minimize_scalar

from scanclique.features import Features
from scanclique.geometry import Pose2, rotation_matrix
from scanclique.pose import (
    MappedFeatures,
    arun_2d,
    estimate_pose_lsq,
    estimate_pose_median,
    mapped_features,
)

SIG_P = 0.01  # point position sigma (metres) per scan
SIG_RHO, SIG_ALPHA = 0.01, 0.002


def lines_into_a(T: Pose2, lines_b) -> np.ndarray:
    """(rho, alpha) of B's lines in A's frame, for ``T`` mapping B into A (rho stays >= 0
    for the lines used here)."""
    out = []
    for rho, alpha in np.asarray(lines_b, float).reshape(-1, 2):
        a = alpha + T.theta
        out.append((rho + np.array([math.cos(a), math.sin(a)]) @ T.translation, a))
    return np.array(out).reshape(-1, 2)


def mapped(T: Pose2, points_b=(), lines_b=(), rng=None, noise=0.0) -> MappedFeatures:
    """Exact (or noisy) mapped features of a known pose ``T`` (maps B into A)."""
    pb = np.asarray(points_b, float).reshape(-1, 2)
    lb = np.asarray(lines_b, float).reshape(-1, 2)
    pa = T.transform(pb) if len(pb) else pb.copy()
    la = lines_into_a(T, lb)
    if noise:
        pa = pa + rng.normal(0, noise, pa.shape)
        pb = pb + rng.normal(0, noise, pb.shape)
    kp, kl = len(pb), len(lb)
    pc = np.tile(np.eye(2) * SIG_P**2, (kp, 1, 1))
    lc = np.tile(np.diag([SIG_RHO**2, SIG_ALPHA**2]), (kl, 1, 1))
    return MappedFeatures(pa, pb, pc, pc.copy(), la, lb, lc, lc.copy(), np.zeros((kl, 2)))


POSES = [
    Pose2(0.3, -0.2, 0.1),
    Pose2(-1.0, 0.5, -2.5),
    Pose2(0.8, 0.9, math.pi / 2),
    Pose2(0.0, 0.0, 0.0),
]
PTS = [[1.0, 2.0], [3.0, -1.0], [-2.0, 0.5], [4.0, 4.0], [0.5, -3.0]]
LINES = [[3.0, 0.2], [2.5, 1.9], [4.0, -1.3]]  # pairwise non-parallel, far from the sensor
MIXES = {
    "points": (PTS, []),
    "two-points": (PTS[:2], []),
    "lines": ([], LINES),
    "two-lines": ([], LINES[:2]),
    "point+lines": (PTS[:1], LINES[:2]),
    "points+lines": (PTS, LINES),
}


# -- Arun et al. (1987) -----------------------------------------------------------------------
def test_arun_known_answer():
    pb = np.array([[0.0, 0.0], [1.0, 0.0]])
    pa = np.array([[1.0, 1.0], [1.0, 2.0]])
    assert arun_2d(pa, pb).as_array() == pytest.approx([1.0, 1.0, math.pi / 2], abs=1e-12)


def test_arun_half_turn():
    pb = np.array([[1.0, 0.0], [-1.0, 0.0], [0.0, 2.0]])
    assert arun_2d(-pb, pb).as_array() == pytest.approx([0.0, 0.0, -math.pi], abs=1e-12)


def brute_force(pa, pb, w):
    """Minimise sum w |R pb + t - pa|^2 over theta on a grid then locally; t is closed-form
    for a given theta (the weighted centroid difference)."""
    w = w / w.sum()
    ca, cb = w @ pa, w @ pb

    def cost(th):
        t = ca - rotation_matrix(th) @ cb
        r = pb @ rotation_matrix(th).T + t - pa
        return float(np.sum(w * np.sum(r * r, axis=1)))

    grid = np.linspace(-math.pi, math.pi, 721)
    th0 = grid[int(np.argmin([cost(t) for t in grid]))]
    res = minimize_scalar(
        cost, bounds=(th0 - 0.01, th0 + 0.01), method="bounded", options={"xatol": 1e-12}
    )
    th = float(res.x)
    t = ca - rotation_matrix(th) @ cb
    return Pose2(t[0], t[1], th), cost


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), n=st.integers(2, 12), weighted=st.booleans())
def test_arun_matches_brute_force(seed, n, weighted):
    rng = np.random.default_rng(seed)
    pb = rng.uniform(-5, 5, (n, 2))
    T = Pose2(rng.uniform(-2, 2), rng.uniform(-2, 2), rng.uniform(-math.pi, math.pi))
    pa = T.transform(pb) + rng.normal(0, 0.3, (n, 2))
    w = rng.uniform(0.1, 3.0, n) if weighted else np.ones(n)
    got = arun_2d(pa, pb, w if weighted else None)
    ref, cost = brute_force(pa, pb, w)
    assert cost(got.theta) <= cost(ref.theta) + 1e-9
    t_err, r_err = got.distance_to(ref)
    assert r_err < 1e-5 and t_err < 1e-4


@pytest.mark.parametrize("T", POSES)
def test_arun_exact(T):
    pb = np.array(PTS)
    assert arun_2d(T.transform(pb), pb).distance_to(T) == pytest.approx((0.0, 0.0), abs=1e-12)


# -- known poses from exact data ---------------------------------------------------------------
@pytest.mark.parametrize("mix", list(MIXES))
@pytest.mark.parametrize("T", POSES)
@pytest.mark.parametrize("method", ["lsq", "median"])
def test_exact_data_give_the_pose(method, T, mix):
    m = mapped(T, *MIXES[mix])
    est = (estimate_pose_lsq if method == "lsq" else estimate_pose_median)(m)
    assert est is not None
    t_err, r_err = est.pose.distance_to(T)
    assert t_err < 1e-8 and r_err < 1e-9
    assert not est.degenerate
    assert np.all(np.isfinite(est.covariance))
    np.testing.assert_allclose(est.covariance, est.covariance.T, atol=1e-15)
    assert np.all(np.linalg.eigvalsh(est.covariance) > 0)
    assert est.residuals.shape == (m.n_points + m.n_lines,)
    assert np.all(est.residuals < 1e-5)


def test_lsq_from_a_poor_initial_guess():
    T = POSES[1]
    m = mapped(T, PTS, LINES)
    est = estimate_pose_lsq(m, initial=T @ Pose2(0.3, -0.3, 0.2), iterations=20)
    assert est.pose.distance_to(T) == pytest.approx((0.0, 0.0), abs=1e-8)


@pytest.mark.parametrize("method", [estimate_pose_lsq, estimate_pose_median])
def test_too_few_features_give_none(method):
    T = POSES[0]
    assert method(mapped(T)) is None  # nothing at all
    assert method(mapped(T, PTS[:1])) is None  # one point fixes no rotation


# -- covariance (paper §7: precision of the constellation) ------------------------------------
CORRIDOR_B = [[1.0, math.pi / 2], [1.5, -math.pi / 2]]  # walls y = 1 and y = -1.5 in B


@pytest.mark.parametrize("method", [estimate_pose_lsq, estimate_pose_median])
@pytest.mark.parametrize("theta", [0.0, 0.3, -2.0])
def test_corridor_is_degenerate_along_its_axis(method, theta):
    T = Pose2(0.4, -0.2, theta)
    est = method(mapped(T, [], CORRIDOR_B))
    assert est is not None
    assert est.degenerate
    along = np.array([math.cos(theta), math.sin(theta)])  # B's x axis, in A
    across = np.array([-math.sin(theta), math.cos(theta)])
    # the pose is right where the walls say: heading and across-corridor position
    assert abs(est.pose.theta - T.theta) < 1e-9
    assert across @ est.pose.translation == pytest.approx(across @ T.translation, abs=1e-9)
    # and its variance along the corridor is unbounded
    var_along = (
        along @ est.covariance[:2, :2] @ along if np.all(np.isfinite(est.covariance)) else np.inf
    )
    assert not var_along < 1e6


def test_corridor_covariance_keeps_the_determined_directions():
    est = estimate_pose_lsq(mapped(Pose2(0.4, -0.2, 0.0), [], CORRIDOR_B))
    assert est.degenerate
    assert not est.covariance[0, 0] < 1e6  # along the corridor (x): unbounded
    assert est.covariance[1, 1] < 1e-3  # across (y): two walls 1 cm each
    assert est.covariance[2, 2] < 1e-3  # heading: two walls 0.002 rad each


def test_corridor_with_a_point_is_not_degenerate():
    T = Pose2(0.4, -0.2, 0.3)
    est = estimate_pose_lsq(mapped(T, [[3.0, 0.0]], CORRIDOR_B))
    assert not est.degenerate
    assert np.all(np.isfinite(est.covariance))
    assert est.pose.distance_to(T) == pytest.approx((0.0, 0.0), abs=1e-8)


def test_covariance_shrinks_with_more_features():
    T = POSES[0]
    few = estimate_pose_lsq(mapped(T, PTS[:2]))
    many = estimate_pose_lsq(mapped(T, PTS))
    assert np.all(np.diag(many.covariance) < np.diag(few.covariance))


def test_two_points_known_covariance():
    # points (+-d, 0) in B, identity pose, each pair with combined covariance 2 s^2 I:
    # var(x) = var(y) = 2 s^2 / 2, var(theta) = 2 s^2 / (2 d^2)
    d = 2.0
    est = estimate_pose_lsq(mapped(Pose2.identity(), [[-d, 0.0], [d, 0.0]]))
    s2 = 2 * SIG_P**2
    np.testing.assert_allclose(
        np.diag(est.covariance), [s2 / 2, s2 / 2, s2 / (2 * d * d)], rtol=1e-6
    )


def test_lsq_covariance_matches_monte_carlo():
    rng = np.random.default_rng(11)
    T = POSES[1]
    m0 = mapped(T, PTS, LINES[:2])
    poses = []
    for _ in range(400):
        m = mapped(T, PTS, LINES[:2])
        pa = m.points_a + rng.normal(0, SIG_P, m.points_a.shape)
        pb = m.points_b + rng.normal(0, SIG_P, m.points_b.shape)
        la = m.lines_a + rng.normal(0, [SIG_RHO, SIG_ALPHA], m.lines_a.shape) * math.sqrt(2)
        m = MappedFeatures(
            pa,
            pb,
            m.points_cov_a,
            m.points_cov_b,
            la,
            m.lines_b,
            m.lines_cov_a,
            m.lines_cov_b,
            m.lines_mid_b,
        )
        poses.append(estimate_pose_lsq(m).pose.as_array())
    emp = np.cov(np.array(poses).T)
    pred = estimate_pose_lsq(m0).covariance
    np.testing.assert_allclose(np.diag(emp), np.diag(pred), rtol=0.25)


# -- noise: weighted least squares beats the paper's medians on average -----------------------
def test_lsq_beats_median_with_noise():
    rng = np.random.default_rng(2)
    errs = {"lsq": [], "median": []}
    for _ in range(150):
        T = Pose2(rng.uniform(-1, 1), rng.uniform(-1, 1), rng.uniform(-math.pi, math.pi))
        pb = rng.uniform(-5, 5, (8, 2))
        m = mapped(T, pb, LINES, rng=rng, noise=0.02)
        for name, f in (("lsq", estimate_pose_lsq), ("median", estimate_pose_median)):
            t, r = f(m).pose.distance_to(T)
            errs[name].append((t, r))
    lsq, med = np.array(errs["lsq"]), np.array(errs["median"])
    assert lsq[:, 0].mean() <= med[:, 0].mean()
    assert lsq[:, 1].mean() <= med[:, 1].mean()
    # and both are sensible at this noise level
    assert med[:, 0].mean() < 0.05 and lsq[:, 0].mean() < 0.03


def test_median_resists_a_gross_outlier():
    T = POSES[0]
    m = mapped(T, PTS)
    pa = m.points_a.copy()
    pa[0] += [3.0, -2.0]  # one wrong association
    bad = MappedFeatures(
        pa,
        m.points_b,
        m.points_cov_a,
        m.points_cov_b,
        m.lines_a,
        m.lines_b,
        m.lines_cov_a,
        m.lines_cov_b,
        m.lines_mid_b,
    )
    med = estimate_pose_median(bad)
    t, r = med.pose.distance_to(T)
    assert t < 0.05 and r < 0.02
    lsq = estimate_pose_lsq(bad)
    assert lsq.residuals[0] == max(lsq.residuals)  # the outlier stands out


# -- gathering mapped features -----------------------------------------------------------------
def test_mapped_features_gathers_by_node_order():
    def feats(points, lines):
        P, L = len(points), len(lines)
        return Features(
            np.array(points, float).reshape(P, 2),
            np.zeros(P, np.int8),
            np.arange(P * 4, dtype=float).reshape(P, 2, 2),
            np.arange(P),
            np.array(lines, float).reshape(L, 2),
            np.arange(L * 4, dtype=float).reshape(L, 2, 2),
            np.arange(L * 4, dtype=float).reshape(L, 2, 2) + 100,
            np.zeros((L, 2), np.int64),
            np.full(L, 8),
            np.zeros((0, 2), np.int64),
        )

    fa = feats([[1, 1], [2, 2]], [[3.0, 0.1], [4.0, 0.2]])
    fb = feats([[9, 9]], [[5.0, 0.3], [6.0, 0.4], [7.0, 0.5]])
    # node pairs: A point 1 <-> B point 0; A line 0 (node 2) <-> B line 2 (node 3)
    m = mapped_features(fa, fb, np.array([[1, 0], [2, 3]]))
    assert m.n_points == 1 and m.n_lines == 1
    np.testing.assert_array_equal(m.points_a, [[2, 2]])
    np.testing.assert_array_equal(m.points_b, [[9, 9]])
    np.testing.assert_array_equal(m.points_cov_a, fa.points_cov[[1]])
    np.testing.assert_array_equal(m.lines_a, [[3.0, 0.1]])
    np.testing.assert_array_equal(m.lines_b, [[7.0, 0.5]])
    np.testing.assert_array_equal(m.lines_cov_b, fb.lines_cov[[2]])
    np.testing.assert_array_equal(m.lines_mid_b, [fb.lines_ends[2].mean(axis=0)])
