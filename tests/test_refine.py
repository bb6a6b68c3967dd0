"""Raw-scan agreement, free-space conflicts and point-to-line ICP on simulated scans."""

from __future__ import annotations

import math

import numpy as np
import pytest

from scanclique.geometry import Pose2
from scanclique.refine import agreement, free_space_conflicts, icp_point_to_line, reference_cloud
from scanclique.scan import Scan
from scanclique.sim import World, simulate_pair, simulate_scan

SEEDS = [0, 1, 3, 4, 5]


def pair(seed):
    return simulate_pair(np.random.default_rng(seed), moving_people=0)


# -- reference cloud ---------------------------------------------------------------------------
def test_reference_cloud_normals_of_a_wall():
    y = np.linspace(-2, 2, 41)
    pts = np.column_stack((np.full(41, 3.0), y))
    ref = reference_cloud(pts)
    assert ref.points.shape == (41, 2)
    np.testing.assert_allclose(np.abs(ref.normals[:, 0]), 1.0, atol=1e-9)
    np.testing.assert_allclose(ref.normals[:, 1], 0.0, atol=1e-9)


def test_reference_cloud_of_few_points():
    ref = reference_cloud(np.array([[1.0, 0.0], [2.0, 0.0]]))
    assert np.all(ref.normals == 0.0)
    assert reference_cloud(np.zeros((0, 2))).points.shape == (0, 2)


# -- agreement -------------------------------------------------------------------------------
@pytest.mark.parametrize("seed", SEEDS)
def test_agreement_is_one_for_a_scan_against_itself(seed):
    a = pair(seed).scan_a
    pts = a.points()
    ref = reference_cloud(pts)
    assert agreement(ref, pts, Pose2.identity(), 0.15) == 1.0
    # a wrong pose (half a metre and ten degrees off) loses much of it
    assert agreement(ref, pts, Pose2(0.5, 0.0, 0.0), 0.15) < 0.8
    assert agreement(ref, pts, Pose2(0.0, 0.0, math.radians(10)), 0.15) < 0.8


@pytest.mark.parametrize("seed", SEEDS)
def test_agreement_peaks_at_the_true_pose(seed):
    p = pair(seed)
    ref = reference_cloud(p.scan_a.points())
    pb = p.scan_b.points()
    at_truth = agreement(ref, pb, p.pose_a_b, 0.15)
    assert at_truth > 0.6
    for d in (Pose2(0.4, 0.0, 0.0), Pose2(0.0, -0.4, 0.0), Pose2(0.0, 0.0, 0.15)):
        assert agreement(ref, pb, p.pose_a_b @ d, 0.15) < at_truth


def test_agreement_known_fraction():
    ref = reference_cloud(np.array([[0.0, 0.0], [1.0, 0.0], [2.0, 0.0]]))
    pts_b = np.array([[0.05, 0.0], [1.0, 0.1], [5.0, 5.0], [2.0, 0.5]])
    assert agreement(ref, pts_b, Pose2.identity(), 0.15) == pytest.approx(0.5)
    # shifting B by (-5, -5) puts its third point on A's origin, and nothing else
    assert agreement(ref, pts_b, Pose2(-5.0, -5.0, 0.0), 0.15) == pytest.approx(0.25)


def test_agreement_empty():
    ref = reference_cloud(np.array([[0.0, 0.0]]))
    assert agreement(ref, np.zeros((0, 2)), Pose2.identity(), 0.15) == 0.0
    assert (
        agreement(reference_cloud(np.zeros((0, 2))), np.ones((3, 2)), Pose2.identity(), 0.15) == 0.0
    )


# -- free-space conflicts -----------------------------------------------------------------------
def wall_scan(n=181):
    """A 180-degree scan of the wall x = 3 (sensor at the origin, no noise)."""
    world = World(np.array([[[3.0, -30.0], [3.0, 30.0]]]))
    return simulate_scan(world, Pose2.identity(), n_beams=n, range_sigma=0.0)


def test_free_space_conflicts_known_answer():
    s = wall_scan()
    pts = np.array(
        [
            [1.0, 0.0],  # in front of the wall, where the beam saw through: conflict
            [3.0, 0.0],  # on the wall
            [5.0, 0.0],  # behind the wall: unseen, no conflict
            [-1.0, 0.0],  # behind the sensor, outside its field of view
        ]
    )
    assert free_space_conflicts(s, pts) == pytest.approx(0.25)
    assert free_space_conflicts(s, pts[1:]) == 0.0
    assert free_space_conflicts(s, np.zeros((0, 2))) == 0.0


def test_free_space_margin():
    s = wall_scan()
    # 3 m wall: margin 0.2 + 0.02 * r; a point 0.1 m in front is within it, 0.5 m is not
    assert free_space_conflicts(s, np.array([[2.9, 0.0]])) == 0.0
    assert free_space_conflicts(s, np.array([[2.5, 0.0]])) == 1.0


def test_free_space_invalid_beams_are_no_evidence():
    r = np.full(181, 3.0)
    r[80:101] = np.nan  # no information around straight ahead
    s = Scan.from_ranges(r)
    assert free_space_conflicts(s, np.array([[1.0, 0.0]])) == 0.0
    assert free_space_conflicts(s, np.array([[0.0, 1.0]])) == 1.0  # 90 degrees left: seen


@pytest.mark.parametrize("seed", SEEDS)
def test_free_space_conflicts_true_vs_slid_pose(seed):
    p = pair(seed)
    a, b = p.scan_a, p.scan_b
    pb = b.points()
    assert free_space_conflicts(a, p.pose_a_b.transform(pb)) < 0.01
    # sliding B's points half a metre both ways along A's x axis pushes some of them into
    # the space A saw through
    worst = max(
        free_space_conflicts(a, (Pose2(dx, 0.0, 0.0) @ p.pose_a_b).transform(pb))
        for dx in (-0.5, 0.5)
    )
    assert worst > 0.05


# -- ICP --------------------------------------------------------------------------------------
@pytest.mark.parametrize("seed", SEEDS)
@pytest.mark.parametrize("k", range(4))
def test_icp_converges_from_a_perturbation(seed, k):
    p = pair(seed)
    ref = reference_cloud(p.scan_a.points())
    pb = p.scan_b.points()
    phi = k * math.pi / 2 + 0.4
    sign = 1 if k % 2 else -1
    start = p.pose_a_b @ Pose2(0.2 * math.cos(phi), 0.2 * math.sin(phi), sign * math.radians(5))
    t0, r0 = start.distance_to(p.pose_a_b)
    assert t0 > 0.15 and r0 > math.radians(4)
    res = icp_point_to_line(ref, pb, start)
    t, r = res.pose.distance_to(p.pose_a_b)
    assert t < 0.03 and r < math.radians(0.5), (t, math.degrees(r))
    assert res.fitness > 0.6
    assert 1 <= res.iterations <= 15
    assert res.rmse < 0.05


def test_icp_at_the_truth_stays():
    p = pair(4)
    res = icp_point_to_line(reference_cloud(p.scan_a.points()), p.scan_b.points(), p.pose_a_b)
    t, r = res.pose.distance_to(p.pose_a_b)
    assert t < 0.01 and r < math.radians(0.2)


def test_icp_with_too_few_points_returns_initial():
    start = Pose2(1.0, 2.0, 0.3)
    ref = reference_cloud(np.random.default_rng(0).uniform(0, 5, (50, 2)))
    res = icp_point_to_line(ref, np.array([[1.0, 1.0], [2.0, 2.0]]), start)
    assert res.pose == start and res.iterations == 0 and res.fitness == 0.0
