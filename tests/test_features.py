"""Clustering and feature extraction (paper §4) on hand-made ranges and simulated scenes."""

from __future__ import annotations

import math

import numpy as np
import pytest
from conftest import require_log
from hypothesis import given, settings
from hypothesis import strategies as st

from scanclique.config import ClusterConfig, FeatureConfig
from scanclique.datasets import load_log
from scanclique.features import (
    CORNER,
    EDGE_CCW,
    EDGE_CW,
    FOREGROUND_POINT,
    Features,
    _extract_features_reference,
    cluster_scan,
    extract_features,
    fit_line_tls,
    split_and_merge,
)
from scanclique.geometry import Pose2
from scanclique.scan import Scan
from scanclique.sim import World, random_world, room_world, simulate_scan


# -- helpers ---------------------------------------------------------------------------------
def scene(walls, circles=(), radii=(), *, pose=None, n_beams=361, sigma=0.0, seed=0):
    """A noise-free (by default) 180-degree scan of hand-placed walls and circles, from the
    origin facing +x unless ``pose`` says otherwise."""
    pose = Pose2.identity() if pose is None else pose
    world = World(
        np.asarray(walls, dtype=float),
        circle_centres=np.asarray(circles, dtype=float).reshape(-1, 2),
        circle_radii=np.asarray(radii, dtype=float),
    )
    return simulate_scan(
        world, pose, n_beams=n_beams, range_sigma=sigma, rng=np.random.default_rng(seed)
    )


def hesse(p, q):
    """(rho, alpha) of the infinite line through p and q, rho >= 0."""
    p, q = np.asarray(p, float), np.asarray(q, float)
    d = q - p
    n = np.array([-d[1], d[0]]) / math.hypot(*d)
    rho = float(n @ p)
    if rho < 0:
        n, rho = -n, -rho
    return rho, math.atan2(n[1], n[0])


def angle_diff(a, b):
    return abs((a - b + math.pi) % (2 * math.pi) - math.pi)


def of_label(f: Features, label: int) -> np.ndarray:
    return f.points_xy[f.points_label == label]


def near(points: np.ndarray, target, tol: float) -> int:
    if len(points) == 0:
        return 0
    return int(np.sum(np.linalg.norm(points - np.asarray(target, float), axis=1) < tol))


ROOM = [[[-1, -6], [5, -6]], [[5, -6], [5, 6]], [[5, 6], [-1, 6]], [[-1, 6], [-1, -6]]]


def box(x0, y0, x1, y1):
    return [[[x0, y0], [x1, y0]], [[x1, y0], [x1, y1]], [[x1, y1], [x0, y1]], [[x0, y1], [x0, y0]]]


# -- clustering (paper §4) -------------------------------------------------------------------
# c1 = 0.25, c2 = 0.125 are exact in binary, so the threshold can be hit exactly.
EXACT = ClusterConfig(c1=0.25, c2=0.125)


@pytest.mark.parametrize(
    ("ranges", "expected"),
    [
        ([2.0, 2.5], [[0, 1], [1, 2]]),  # |dR| = 0.5 = c1 + c2 * 2: not strictly less -> break
        ([2.0, 2.4375], [[0, 2]]),  # just below the threshold -> join
        ([2.5, 2.0], [[0, 1], [1, 2]]),  # the threshold uses min(Ri, Ri+1)
        ([4.0, 4.75], [[0, 1], [1, 2]]),  # 0.25 + 0.125 * 4 = 0.75
        ([4.0, 4.6875], [[0, 2]]),
        ([4.0, 3.25], [[0, 1], [1, 2]]),  # min is 3.25: threshold 0.65625 < 0.75
        ([1.0, 1.0, 1.0, 8.0, 8.0], [[0, 3], [3, 5]]),
    ],
)
def test_cluster_rule_exact_threshold(ranges, expected):
    assert cluster_scan(Scan.from_ranges(ranges), EXACT).tolist() == expected


@pytest.mark.parametrize(("delta", "joined"), [(-1e-6, True), (1e-6, False)])
@pytest.mark.parametrize("r", [0.5, 2.0, 10.0])
def test_cluster_rule_paper_constants(r, delta, joined):
    limit = 0.07 + 0.04 * r  # paper §4 defaults
    got = cluster_scan(Scan.from_ranges([r, r + limit + delta]))
    assert (len(got) == 1) is joined


@pytest.mark.parametrize(
    ("ranges", "kw", "expected"),
    [
        ([1.0, np.nan, 1.0], {}, [[0, 1], [2, 3]]),
        ([1.0, np.inf, 1.0], {}, [[0, 1], [2, 3]]),
        ([1.0, -1.0, 1.0], {}, [[0, 1], [2, 3]]),
        ([1.0, 1.0, 10.0, 1.0, 1.0], {"range_max": 10.0}, [[0, 2], [3, 5]]),
        ([1.0, 1.0, 0.05, 1.0], {"range_min": 0.1}, [[0, 2], [3, 4]]),
        ([np.nan, 1.0, 1.0, np.nan], {}, [[1, 3]]),
    ],
)
def test_invalid_beams_break_clusters(ranges, kw, expected):
    assert cluster_scan(Scan.from_ranges(ranges, **kw)).tolist() == expected


def test_max_gap_beams_bridges_invalid_beams():
    s = Scan.from_ranges([1.0, 1.0, np.nan, 1.0, 1.0, np.nan, np.nan, 1.0])
    assert cluster_scan(s, ClusterConfig(max_gap_beams=1)).tolist() == [[0, 5], [7, 8]]
    assert cluster_scan(s, ClusterConfig(max_gap_beams=2)).tolist() == [[0, 8]]
    assert cluster_scan(s).tolist() == [[0, 2], [3, 5], [7, 8]]


def test_dropout_fraction_counts_lost_returns_inside_surfaces():
    """One invalid beam between two returns the clustering rule joins is a lost return;
    a run of two, one at the border, or one between a near and a far return is not."""
    from scanclique.features import dropout_fraction

    s = Scan.from_ranges([2.0, np.inf, 2.02, 2.0, np.nan, 2.01, 1.0, np.inf, 5.0, np.inf])
    assert dropout_fraction(s) == 2 / 10
    assert dropout_fraction(Scan.from_ranges([2.0, np.inf, np.inf, 2.0])) == 0.0
    assert dropout_fraction(Scan.from_ranges([np.inf, 2.0])) == 0.0
    assert dropout_fraction(Scan.from_ranges([1.0, 1.0, 1.0])) == 0.0
    loose = ClusterConfig(c1=4.0)  # the rule joins 1 m and 5 m: a lost return too
    assert dropout_fraction(s, loose) == 3 / 10


def test_a_scanner_that_loses_returns_is_told_from_a_clean_one():
    """``drops_returns`` reads the median scan: a 360-degree scanner losing 7 % of its
    beams does, the same scanner without losses does not, and one lossy scan among clean
    ones does not make the scanner lossy."""
    from scanclique.features import DROPOUT_BRIDGE, dropout_fraction, drops_returns
    from scanclique.sim import office_world, simulate_trajectory

    kw = dict(n_beams=360, fov=2 * np.pi * 359 / 360, angle_min=-np.pi, max_range=10.0,
              range_sigma_per_m=0.015)  # fmt: skip
    rng = np.random.default_rng(3)
    world = office_world(rng)
    lossy = simulate_trajectory(rng, world, 9, step=0.3, dropout=0.07, **kw)
    clean = simulate_trajectory(rng, world, 9, step=0.3, **kw)
    assert min(dropout_fraction(x) for x in lossy) > DROPOUT_BRIDGE
    assert drops_returns(lossy) and not drops_returns(clean) and not drops_returns([])
    assert not drops_returns(clean[:5] + lossy[:1])
    assert drops_returns(lossy, sample=2)  # the first and the last scan


def test_range_noise_is_read_from_the_scans():
    """``range_noise`` recovers a noise that grows with the range (1.5 %) and reads a
    centimetre's as far less; ``for_scanner`` widens the clustering's range term for the
    first only (to 3 sigma of a difference of two ranges), bridges lost returns only for a
    scanner that loses them, and leaves a clean scanner's configuration as it is."""
    import math

    from scanclique.config import MatchConfig
    from scanclique.features import NOISE_SIGMAS, for_scanner, range_noise
    from scanclique.sim import office_world, simulate_trajectory

    kw = dict(n_beams=360, fov=2 * np.pi * 359 / 360, angle_min=-np.pi, max_range=10.0)
    rng = np.random.default_rng(3)
    world = office_world(rng)
    noisy = simulate_trajectory(rng, world, 9, step=0.3, range_sigma=0.0,
                                range_sigma_per_m=0.015, **kw)  # fmt: skip
    sick = simulate_trajectory(rng, world, 9, step=0.3, range_sigma=0.01, **kw)
    assert 0.013 < range_noise(noisy) < 0.017 and range_noise(sick) < 0.006
    assert math.isnan(range_noise([])) and math.isnan(range_noise([Scan.from_ranges([3.0] * 9)]))
    wide = for_scanner(None, noisy).clustering
    assert wide.max_gap_beams == 0  # no lost returns
    assert wide.c2 == round(NOISE_SIGMAS * math.sqrt(2) * range_noise(noisy), 3) > 0.06
    assert for_scanner(None, noisy, widen=False) == MatchConfig()  # place recognition's
    assert for_scanner(None, sick) == MatchConfig() and for_scanner(None, []) == MatchConfig()
    given = MatchConfig()
    assert for_scanner(given, sick) is given


def test_fitting_to_a_scanner_names_bad_input():
    from scanclique.errors import ArgumentError, ConfigError, ScanError
    from scanclique.features import dropout_fraction, drops_returns, for_scanner, range_noise

    with pytest.raises(ScanError, match="dropout_fraction"):
        dropout_fraction([1.0, 2.0])
    for bad in (None, 5, "intel.clf"):
        for f in (drops_returns, range_noise):
            with pytest.raises(ArgumentError, match="sequence of Scan"):
                f(bad)
    with pytest.raises(ConfigError, match="for_scanner"):
        for_scanner("defaults", [])
    # what is not a scan among scans is left to the caller's checks, not read
    assert not drops_returns([None, "x"]) and math.isnan(range_noise([None]))


def test_clusters_cover_valid_beams_once():
    rng = np.random.default_rng(4)
    r = rng.uniform(0.5, 8.0, 200)
    r[rng.random(200) < 0.1] = np.nan
    s = Scan.from_ranges(r)
    c = cluster_scan(s)
    assert np.all(c[:, 0] < c[:, 1])
    assert np.all(c[1:, 0] >= c[:-1, 1])
    covered = np.zeros(200, bool)
    for a, b in c:
        covered[a:b] = True
        assert s.valid[a] and s.valid[b - 1]
    np.testing.assert_array_equal(covered, s.valid)


# -- degenerate scans ------------------------------------------------------------------------
@pytest.mark.parametrize(
    "ranges",
    [
        [np.nan] * 50,
        [80.0] * 50,
        [100.0] * 50,
        [np.inf] * 10,
        [-1.0] * 10,
        [2.0],
        [],
        [2.0, 2.0],
        [0.0] * 5,
    ],
    ids=["nan", "max", "beyond-max", "inf", "negative", "one", "empty", "two", "zero"],
)
def test_degenerate_scans_give_empty_features(ranges):
    f = extract_features(Scan.from_ranges(ranges))
    assert len(f) == 0 and f.n_points == 0 and f.n_lines == 0
    assert f.points_xy.shape == (0, 2)
    assert f.points_cov.shape == (0, 2, 2)
    assert f.lines_rho_alpha.shape == (0, 2)
    assert f.lines_ends.shape == (0, 2, 2)
    assert f.lines_cov.shape == (0, 2, 2)
    assert set(f.counts().values()) == {0}


# -- lines: total least squares --------------------------------------------------------------
@pytest.mark.parametrize(
    ("p", "q", "rho", "alpha"),
    [
        ((2.0, -1.0), (2.0, 1.0), 2.0, 0.0),  # x = 2
        ((-1.0, 3.0), (1.0, 3.0), 3.0, math.pi / 2),  # y = 3
        ((-1.0, -2.5), (1.0, -2.5), 2.5, -math.pi / 2),  # y = -2.5
        ((-2.0, -1.0), (-2.0, 1.0), 2.0, math.pi),  # x = -2: normal points to -x
        ((0.0, 1.0), (1.0, 2.0), math.sqrt(0.5), 3 * math.pi / 4),  # y = x + 1
        ((1.0, 0.0), (0.0, 1.0), math.sqrt(0.5), math.pi / 4),  # x + y = 1
    ],
)
def test_fit_line_tls_known(p, q, rho, alpha):
    t = np.linspace(0.0, 1.0, 7)[:, None]
    pts = np.asarray(p) + t * (np.asarray(q) - np.asarray(p))
    r, a, cov, rms, ends = fit_line_tls(pts)
    assert r == pytest.approx(rho, abs=1e-12)
    assert angle_diff(a, alpha) < 1e-12
    assert rms == pytest.approx(0.0, abs=1e-12)
    np.testing.assert_allclose(ends, [p, q], atol=1e-12)
    assert cov.shape == (2, 2)
    np.testing.assert_allclose(cov, cov.T)
    assert np.all(np.linalg.eigvalsh(cov) > 0)


def test_fit_line_tls_residual_and_covariance_known():
    # each y twice, 1 cm either side of x = 2: the fit is exactly x = 2, residuals +-1 cm
    y = np.repeat(np.linspace(-1.0, 1.0, 10), 2)
    x = 2.0 + 0.01 * np.tile([1.0, -1.0], 10)
    rho, alpha, cov, rms, ends = fit_line_tls(np.column_stack((x, y)), sigma=0.02)
    assert rho == pytest.approx(2.0, abs=1e-12)
    assert alpha == pytest.approx(0.0, abs=1e-12)
    assert rms == pytest.approx(0.01, rel=1e-9)
    # centroid at the foot of the normal: var(rho) = s^2/N, cov(rho, alpha) = 0,
    # var(alpha) = s^2 / sum(u^2)
    assert cov[0, 0] == pytest.approx(0.02**2 / 20, rel=1e-9)
    assert cov[1, 1] == pytest.approx(0.02**2 / np.sum(y**2), rel=1e-9)
    assert abs(cov[0, 1]) < 1e-12
    np.testing.assert_allclose(ends, [[2.0, -1.0], [2.0, 1.0]], atol=1e-12)


def test_fit_line_tls_variance_decreases_with_points():
    var_a, var_r = [], []
    for n in (5, 10, 40, 160):
        y = np.linspace(1.0, 3.0, n)
        _, _, cov, _, _ = fit_line_tls(np.column_stack((np.full(n, 2.0), y)))
        var_r.append(cov[0, 0])
        var_a.append(cov[1, 1])
    assert np.all(np.diff(var_a) < 0)
    assert np.all(np.diff(var_r) < 0)
    # longer segments pin the angle down better at equal point count
    short = fit_line_tls(np.column_stack((np.full(10, 2.0), np.linspace(0, 0.5, 10))))[2][1, 1]
    long_ = fit_line_tls(np.column_stack((np.full(10, 2.0), np.linspace(0, 2.0, 10))))[2][1, 1]
    assert long_ < short / 10


def test_fit_line_tls_covariance_matches_monte_carlo():
    rng = np.random.default_rng(7)
    sigma = 0.02
    # an off-centre segment of y = 1.5 (alpha = pi/2), so rho and alpha correlate
    xs = np.linspace(0.5, 2.5, 15)
    truth = np.column_stack((xs, np.full(15, 1.5)))
    fits = []
    for _ in range(1500):
        rho, alpha, cov, _, _ = fit_line_tls(truth + rng.normal(0.0, sigma, truth.shape), sigma)
        fits.append((rho, alpha))
    fits = np.array(fits)
    emp = np.cov(fits.T)
    assert emp[0, 0] == pytest.approx(cov[0, 0], rel=0.15)
    assert emp[1, 1] == pytest.approx(cov[1, 1], rel=0.15)
    assert emp[0, 1] == pytest.approx(cov[0, 1], rel=0.2)
    assert np.mean(fits[:, 0]) == pytest.approx(1.5, abs=0.003)


def test_split_and_merge_splits_an_l_at_the_corner():
    a = np.column_stack((np.linspace(0, 2, 11), np.zeros(11)))
    b = np.column_stack((np.full(10, 2.0), np.linspace(0.2, 2.0, 10)))
    pts = np.vstack((a, b))
    pieces = split_and_merge(pts, np.hypot(pts[:, 0], pts[:, 1]) + 1.0, FeatureConfig())
    assert pieces == [(0, 11), (10, 21)]  # the corner point (index 10) is in both pieces


def test_split_and_merge_keeps_a_straight_run():
    pts = np.column_stack((np.linspace(-2, 2, 30), np.full(30, 3.0)))
    assert split_and_merge(pts, np.full(30, 3.0), FeatureConfig()) == [(0, 30)]


# -- features on scenes ------------------------------------------------------------------------
def visible_walls(world, scan, min_hits=12):
    """Walls hit by at least ``min_hits`` beams of a noise-free scan of ``world``."""
    hits = scan.reference.transform(scan.points())
    counts = []
    for p, q in world.walls:
        d = q - p
        t = np.clip(((hits - p) @ d) / (d @ d), 0, 1)
        dist = np.linalg.norm(hits - (p + t[:, None] * d), axis=1)
        counts.append(int(np.sum(dist < 1e-6)))
    return [k for k, c in enumerate(counts) if c >= min_hits]


@pytest.mark.parametrize(
    "pose",
    [
        Pose2(2.0, 1.5, 0.3),
        Pose2(4.5, 3.0, -2.5),
        Pose2(1.0, 1.0, 0.8),
        Pose2(3.0, 2.0, math.pi / 2),
    ],
)
@pytest.mark.parametrize("sigma", [0.0, 0.01])
def test_room_walls_are_lines(pose, sigma):
    world = room_world(6.0, 4.0, rng=np.random.default_rng(0), doorways=0, pillars=0, clutter=0)
    clean = simulate_scan(world, pose, range_sigma=0.0)
    s = simulate_scan(world, pose, range_sigma=sigma, rng=np.random.default_rng(1))
    f = extract_features(s)
    walls = visible_walls(world, clean)
    assert len(walls) >= 2
    assert f.n_lines == len(walls)  # one line per visible wall, nothing spurious
    assert np.all(f.lines_rho_alpha[:, 0] >= 0)
    inv = pose.inverse()
    for k in walls:
        rho, alpha = hesse(*inv.transform(world.walls[k]))
        # within 3 sigma of the fit's own covariance (range_sigma 0.02 is twice the
        # simulated noise) plus 2 cm / 0.01 rad for discretisation at the segment ends
        match = [
            i
            for i, ((r, a), c) in enumerate(zip(f.lines_rho_alpha, f.lines_cov, strict=True))
            if abs(r - rho) < 0.02 + 3 * math.sqrt(c[0, 0])
            and angle_diff(a, alpha) < 0.01 + 3 * math.sqrt(c[1, 1])
        ]
        assert len(match) == 1, (k, rho, alpha, f.lines_rho_alpha)
    # only corners are point features in an empty room, and they sit at room corners
    assert set(f.points_label.tolist()) <= {CORNER}
    corners_s = inv.transform(np.array([[0, 0], [6, 0], [6, 4], [0, 4]], dtype=float))
    for c in f.points_xy:
        assert np.min(np.linalg.norm(corners_s - c, axis=1)) < 0.05


def test_corner_of_two_walls():
    s = scene(ROOM)
    f = extract_features(s)
    corners = of_label(f, CORNER)
    # the two far corners of the room are in view (the near ones are behind the sensor)
    assert near(corners, (5, -6), 0.03) == 1
    assert near(corners, (5, 6), 0.03) == 1
    assert len(corners) == 2
    # covariance: symmetric positive definite
    for c in f.points_cov[f.points_label == CORNER]:
        np.testing.assert_allclose(c, c.T)
        assert np.all(np.linalg.eigvalsh(c) > 0)


def test_corners_switch_off():
    f = extract_features(scene(ROOM), FeatureConfig(corners=False))
    assert f.counts()["corner"] == 0
    assert f.n_lines == 3


def test_pole_in_front_of_wall_is_one_foreground_point():
    centre, radius = (1.5, -1.0), 0.1
    f = extract_features(scene(ROOM, [centre], [radius]))
    fp = of_label(f, FOREGROUND_POINT)
    assert len(fp) == 1
    assert np.linalg.norm(fp[0] - centre) < radius
    assert f.counts()["edge_cw"] == 0 and f.counts()["edge_ccw"] == 0
    # the pole's shadow does not cut the back wall into two lines
    assert sum(abs(r - 5.0) < 0.02 and angle_diff(a, 0.0) < 0.01 for r, a in f.lines_rho_alpha) == 1


def test_foreground_points_switch_off():
    f = extract_features(scene(ROOM, [(1.5, -1.0)], [0.1]), FeatureConfig(foreground_points=False))
    assert f.counts()["foreground_point"] == 0


def test_box_edge_in_front_of_far_wall():
    # box x in [2, 3], y in [0.5, 2]: the sensor at the origin sees its faces y = 0.5 and
    # x = 2; the back wall x = 5 shows on either side of it.
    f = extract_features(scene(ROOM + box(2.0, 0.5, 3.0, 2.0)))
    cw, ccw = of_label(f, EDGE_CW), of_label(f, EDGE_CCW)
    # near ends of the box: the background lies clockwise of (3, 0.5), counter-clockwise
    # of (2, 2)
    assert len(cw) == 1 and np.linalg.norm(cw[0] - (3.0, 0.5)) < 0.05
    assert len(ccw) == 1 and np.linalg.norm(ccw[0] - (2.0, 2.0)) < 0.05
    # the far (occluded) ends on the back wall are no features of any kind
    for occluded in ((5.0, 5.0 * 0.5 / 3.0), (5.0, 5.0)):
        assert near(f.points_xy, occluded, 0.3) == 0, occluded
    # the box's own corner is a corner
    assert near(of_label(f, CORNER), (2.0, 0.5), 0.03) == 1


def test_edge_labels_on_hand_made_ranges():
    ang = np.radians(np.arange(-30.0, 30.0, 1.0))
    # a near object (2 m) spanning beams 20..44 in front of a far background (5 m)
    r = np.full(ang.size, 5.0)
    r[20:45] = 2.0
    f = extract_features(Scan(r, ang))
    assert f.points_beam[f.points_label == EDGE_CW].tolist() == [20]
    assert f.points_beam[f.points_label == EDGE_CCW].tolist() == [44]
    np.testing.assert_allclose(
        of_label(f, EDGE_CW)[0], 2.0 * np.array([np.cos(ang[20]), np.sin(ang[20])])
    )
    # the far cluster ends next to it (beams 19 and 45) are occluded: not features
    assert not set(f.points_beam.tolist()) & {19, 45}


@pytest.mark.parametrize(
    ("near_first", "label", "beam"), [(False, EDGE_CW, 30), (True, EDGE_CCW, 29)]
)
def test_single_step_gives_one_edge_on_the_near_side(near_first, label, beam):
    ang = np.radians(np.arange(-30.0, 30.0, 1.0))
    r = np.where((np.arange(ang.size) < 30) == near_first, 2.0, 5.0)
    f = extract_features(Scan(r, ang))
    edges = f.points_label != CORNER
    assert f.points_label[edges].tolist() == [label]
    assert f.points_beam[edges].tolist() == [beam]
    assert r[beam] == 2.0


def test_small_near_cluster_is_a_foreground_point_not_edges():
    ang = np.radians(np.arange(-30.0, 30.0, 1.0))
    r = np.full(ang.size, 5.0)
    r[28:32] = 2.0  # 4 beams at 2 m: about 0.1 m across
    f = extract_features(Scan(r, ang))
    assert f.points_label.tolist() == [FOREGROUND_POINT]
    expected = np.mean(2.0 * np.column_stack((np.cos(ang[28:32]), np.sin(ang[28:32]))), axis=0)
    np.testing.assert_allclose(f.points_xy[0], expected, atol=1e-12)


def test_edges_switch_off():
    ang = np.radians(np.arange(-30.0, 30.0, 1.0))
    r = np.full(ang.size, 5.0)
    r[20:45] = 2.0
    f = extract_features(Scan(r, ang), FeatureConfig(foreground_edges=False))
    assert f.counts()["edge_cw"] == 0 and f.counts()["edge_ccw"] == 0


def test_collinear_segments_across_a_gap_merge():
    # one wall x = 3 with a 1 m doorway (nothing behind it within range), the upper part
    # 3 cm off: two chains of points, one line after merging
    walls = [[[3.0, -4.0], [3.0, -0.5]], [[3.03, 0.5], [3.03, 4.0]]]
    s = scene(walls)
    f = extract_features(s)
    assert f.n_lines == 1
    assert f.lines_n_points[0] == s.n_valid  # every wall return is behind the merged line
    rho, alpha = f.lines_rho_alpha[0]
    assert rho == pytest.approx(3.015, abs=0.01)
    assert angle_diff(alpha, 0.0) < 0.01
    # the merged segment spans both parts
    ys = np.sort(f.lines_ends[0][:, 1])
    assert ys[0] < -3.5 and ys[1] > 3.5
    # with a merge tolerance below the 3 cm offset they stay apart
    f2 = extract_features(s, FeatureConfig(merge_distance=0.01))
    assert f2.n_lines == 2


def test_lines_switch_off():
    f = extract_features(scene(ROOM), FeatureConfig(lines=False))
    assert f.n_lines == 0
    # corners still come from the (internal) line fits
    assert f.counts()["corner"] == 2


def test_features_are_read_only_and_consistent():
    s = scene(ROOM + box(2.0, 0.5, 3.0, 2.0), [(1.5, -2.0)], [0.15], sigma=0.01)
    f = extract_features(s)
    assert len(f) == f.n_points + f.n_lines
    assert sum(f.counts().values()) == len(f)
    assert f.points_label.dtype == np.int8
    with pytest.raises(ValueError):
        f.points_xy[0, 0] = 1.0
    assert np.all(f.lines_rho_alpha[:, 0] >= 0)
    assert np.all(np.abs(f.lines_rho_alpha[:, 1]) <= math.pi)
    assert np.all(f.lines_n_points >= FeatureConfig().line_min_points)
    # every point feature sits within a beam or two of a valid return... or at a corner
    pts = s.points()
    for p, lab in zip(f.points_xy, f.points_label, strict=True):
        if lab != CORNER:
            assert np.min(np.linalg.norm(pts - p, axis=1)) < 0.2
    # each line's end points lie on the line
    for (rho, alpha), ends in zip(f.lines_rho_alpha, f.lines_ends, strict=True):
        n = np.array([math.cos(alpha), math.sin(alpha)])
        np.testing.assert_allclose(ends @ n, rho, atol=1e-9)


# -- the compiled kernel agrees with the NumPy reference -------------------------------------
# extract_features runs one numba kernel; _extract_features_reference is the same algorithm
# written with the stage functions above. They must agree to round-off: same features, same
# kinds, same order.
FIELDS = [
    "points_xy",
    "points_label",
    "points_cov",
    "points_beam",
    "lines_rho_alpha",
    "lines_ends",
    "lines_cov",
    "lines_beams",
    "lines_n_points",
    "clusters",
]

AGREEMENT_CONFIGS = {
    "default": (FeatureConfig(), ClusterConfig()),
    "paper": (FeatureConfig(corners=False, typed_edges=False), ClusterConfig()),
    "no-lines": (FeatureConfig(lines=False), ClusterConfig()),
    "no-corners": (FeatureConfig(corners=False), ClusterConfig()),
    "no-points": (FeatureConfig(foreground_points=False, foreground_edges=False), ClusterConfig()),
    "no-crowd": (FeatureConfig(crowd_radius=0.0, min_cluster_beams=1), ClusterConfig()),
    "no-reach-edges": (FeatureConfig(reach_edges=False), ClusterConfig(c2=0.065)),
    "gaps": (
        FeatureConfig(line_min_points=2, line_min_length=0.05, crowd_radius=1.0),
        ClusterConfig(max_gap_beams=2),
    ),
    "loose": (
        FeatureConfig(
            merge_angle=0.3,
            merge_distance=0.5,
            line_max_rms=0.2,
            corner_reach=3.0,
            split_distance=0.2,
        ),
        ClusterConfig(),
    ),
}


def assert_same_features(fast: Features, ref: Features) -> None:
    for name in FIELDS:
        a, b = getattr(fast, name), getattr(ref, name)
        assert a.shape == b.shape and a.dtype == b.dtype, (name, a.shape, b.shape)
        if a.dtype.kind == "f":
            np.testing.assert_allclose(a, b, rtol=1e-9, atol=1e-12, err_msg=name)
        else:
            np.testing.assert_array_equal(a, b, err_msg=name)


def random_scan(seed: int) -> Scan:
    """A simulated scan of a random building; every third one with its ranges corrupted by
    NaN, inf, negative, max-range and stray returns (range_min 0.1)."""
    rng = np.random.default_rng(seed)
    world = random_world(rng)
    x0, y0, x1, y1 = world.free_regions[int(rng.integers(len(world.free_regions)))]
    pose = Pose2(rng.uniform(x0, x1), rng.uniform(y0, y1), rng.uniform(-math.pi, math.pi))
    s = simulate_scan(
        world,
        pose,
        n_beams=int(rng.choice([181, 361, 720])),
        max_range=float(rng.choice([6.0, 30.0])),
        range_sigma=float(rng.choice([0.0, 0.01, 0.03])),
        dropout=float(rng.choice([0.0, 0.05])),
        rng=rng,
    )
    if seed % 3 == 2:
        r = np.array(s.ranges)
        u = rng.random(r.size)
        r[u < 0.03] = np.nan
        r[(u >= 0.03) & (u < 0.05)] = np.inf
        r[(u >= 0.05) & (u < 0.07)] = -1.0
        r[(u >= 0.07) & (u < 0.10)] = s.range_max
        stray = (u >= 0.10) & (u < 0.15)
        r[stray] = rng.uniform(0.2, 3.0, int(stray.sum()))
        s = Scan(r, s.angles, range_min=0.1, range_max=s.range_max)
    return s


@pytest.mark.parametrize("config", AGREEMENT_CONFIGS.values(), ids=AGREEMENT_CONFIGS.keys())
def test_kernel_agrees_with_reference_on_simulated_scans(config):
    fcfg, ccfg = config
    for seed in range(40):
        s = random_scan(seed)
        assert_same_features(
            extract_features(s, fcfg, ccfg), _extract_features_reference(s, fcfg, ccfg)
        )


def test_kernel_agrees_with_reference_on_hand_made_scenes():
    scans = [
        scene(ROOM),
        scene(ROOM + box(2.0, 0.5, 3.0, 2.0), [(1.5, -2.0)], [0.15], sigma=0.01),
        scene([[[3.0, -4.0], [3.0, -0.5]], [[3.03, 0.5], [3.03, 4.0]]]),  # merged across a gap
        scene(ROOM, [(1.5, -1.0), (1.5, -0.8)], [0.05, 0.05]),  # two poles: crowded
    ]
    scans += [Scan.from_ranges(r) for r in ([np.nan] * 5, [2.0], [], [2.0, 2.0], [0.0] * 5)]
    for s in scans:
        assert_same_features(extract_features(s), _extract_features_reference(s))


@settings(max_examples=60, deadline=None)
@given(
    st.lists(
        st.one_of(
            st.floats(0.05, 12.0),
            st.sampled_from([np.nan, np.inf, -1.0, 80.0]),
        ),
        min_size=0,
        max_size=120,
    ),
    st.integers(1, 8),
)
def test_kernel_agrees_with_reference_on_piecewise_ranges(values, run):
    # runs of equal or slowly changing ranges, so that clusters, lines and edges all occur
    r = np.repeat(np.asarray(values, float), run)
    r = r + 0.001 * np.arange(r.size) % 0.05
    s = Scan.from_ranges(r)
    assert_same_features(extract_features(s), _extract_features_reference(s))


@pytest.mark.realdata
@pytest.mark.parametrize("log", ["intel", "csail"])
def test_kernel_agrees_with_reference_on_real_scans(log):
    require_log(log)
    scans = load_log(log)
    for s in scans[:: max(1, len(scans) // 60)]:
        assert_same_features(extract_features(s), _extract_features_reference(s))


@pytest.mark.parametrize("no_return", [80.0, 100.0, math.inf])
def test_a_no_return_beside_a_cluster_makes_an_edge_whatever_its_value(no_return):
    # an object 2 m away with nothing within reach on either side: a CARMEN log marks
    # those beams with the maximum range (or more), a ROS LaserScan with +inf (REP 117);
    # both are no-returns, and both ends of the object are foreground edges (+inf was
    # taken for an unknown reading, and ROS bags lost the edges beside open space)
    ang = np.radians(np.arange(-30.0, 30.0, 1.0))
    r = np.full(ang.size, no_return)
    r[20:45] = 2.0
    s = Scan(r, ang, range_max=80.0)
    for f in (extract_features(s), _extract_features_reference(s)):
        assert f.points_beam[f.points_label == EDGE_CW].tolist() == [20]
        assert f.points_beam[f.points_label == EDGE_CCW].tolist() == [44]


@pytest.mark.parametrize("unknown", [math.nan, -math.inf, 0.0])
def test_an_unknown_reading_beside_a_cluster_makes_no_edge(unknown):
    # NaN (failed), -inf (too close, REP 117) and readings at or below range_min say
    # nothing of what lies behind the object's ends: no edge is claimed there
    ang = np.radians(np.arange(-30.0, 30.0, 1.0))
    r = np.full(ang.size, unknown)
    r[20:45] = 2.0
    s = Scan(r, ang, range_max=80.0)
    for f in (extract_features(s), _extract_features_reference(s)):
        assert f.counts()["edge_cw"] == 0 and f.counts()["edge_ccw"] == 0


@pytest.mark.parametrize("extract", [extract_features, _extract_features_reference])
def test_a_wall_leaving_the_reach_has_no_edge_where_it_leaves(extract):
    # a wall 1.5 m ahead, ending 0.8 m to the left, running on to the right past a 3.5 m
    # reach: its end on the left is an edge (open space beyond, well within reach); where
    # it leaves the reach (about 3.16 m to the right) it does not end, and a 3.5 m
    # scanner's "edge" there matched any wall of any place outdoors (session 42):
    # FeatureConfig.reach_edges=False leaves it out, the default keeps it (mapping)
    world = World(np.array([[[1.5, -10.0], [1.5, 0.8]]]))
    short = simulate_scan(world, Pose2.identity(), n_beams=361, max_range=3.5, range_sigma=0.0)
    off = FeatureConfig(reach_edges=False)
    f = extract(short, off)
    assert len(of_label(f, EDGE_CW)) == 0
    ccw = of_label(f, EDGE_CCW)
    assert len(ccw) == 1 and np.linalg.norm(ccw[0] - (1.5, 0.8)) < 0.05
    cw = of_label(extract(short), EDGE_CW)
    assert len(cw) == 1 and abs(np.hypot(*cw[0]) - 3.5) < 0.05
    # the same visible piece as a whole wall within a 30 m reach: both ends are edges
    world = World(np.array([[[1.5, -math.sqrt(3.5**2 - 1.5**2)], [1.5, 0.8]]]))
    f = extract(
        simulate_scan(world, Pose2.identity(), n_beams=361, max_range=30.0, range_sigma=0), off
    )
    assert len(of_label(f, EDGE_CW)) == 1 and len(of_label(f, EDGE_CCW)) == 1
