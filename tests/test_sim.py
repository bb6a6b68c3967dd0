"""Tests for the laser simulator: hand-computed ray casts, pair consistency, determinism."""

from __future__ import annotations

import math

import numpy as np
import pytest

from scanclique.errors import ConfigError, ScanCliqueError
from scanclique.geometry import Pose2
from scanclique.scan import Scan
from scanclique.sim import (
    SimPair,
    World,
    cast_rays,
    corridor_world,
    office_world,
    random_world,
    room_world,
    simulate_pair,
    simulate_scan,
    simulate_trajectory,
)


def box_walls(x0, y0, x1, y1):
    """The four walls of an axis-aligned rectangle, shape (4, 2, 2)."""
    c = [(x0, y0), (x1, y0), (x1, y1), (x0, y1)]
    return np.array([[c[i], c[(i + 1) % 4]] for i in range(4)], dtype=float)


def rng(seed=0):
    return np.random.default_rng(seed)


# -- slow exact references --------------------------------------------------------------
def ray_reference(world, origin, angle):
    """First hit along one ray, one segment / circle at a time (plain Python)."""
    ox, oy = origin
    dx, dy = math.cos(angle), math.sin(angle)
    best = math.inf
    for (px, py), (qx, qy) in world.walls:
        ex, ey = qx - px, qy - py
        den = dx * ey - dy * ex
        if abs(den) < 1e-12:
            continue
        wx, wy = px - ox, py - oy
        t = (wx * ey - wy * ex) / den
        s = (wx * dy - wy * dx) / den
        if t > 1e-9 and -1e-9 <= s <= 1 + 1e-9:
            best = min(best, t)
    for (cx, cy), r in zip(world.circle_centres, world.circle_radii, strict=True):
        b = dx * (ox - cx) + dy * (oy - cy)
        c = (ox - cx) ** 2 + (oy - cy) ** 2 - r * r
        disc = b * b - c
        if disc >= 0:
            for t in (-b - math.sqrt(disc), -b + math.sqrt(disc)):
                if t > 1e-9:
                    best = min(best, t)
                    break
    return best


def distance_reference(world, p):
    """Distance from one point to the nearest wall or circle boundary (plain Python)."""
    best = math.inf
    for a, b in world.walls:
        ab = b - a
        t = min(1.0, max(0.0, float(np.dot(p - a, ab) / max(np.dot(ab, ab), 1e-18))))
        best = min(best, float(np.linalg.norm(p - (a + t * ab))))
    for c, r in zip(world.circle_centres, world.circle_radii, strict=True):
        best = min(best, abs(float(np.linalg.norm(p - c)) - r))
    return best


# -- ray casting against hand-computed answers --------------------------------------------
def test_centre_beam_reads_distance_to_facing_wall():
    world = World(box_walls(-2, -2, 2, 2))
    scan = simulate_scan(world, Pose2(0.0, 0.0, 0.0), range_sigma=0.0)
    assert scan.n_beams == 361
    assert scan.ranges[180] == pytest.approx(2.0, abs=1e-12)
    a = scan.angles
    expected = np.minimum(2 / np.abs(np.cos(a) + 1e-300), 2 / np.abs(np.sin(a) + 1e-300))
    np.testing.assert_allclose(scan.ranges, expected, atol=1e-9)
    assert scan.valid.all()


def test_sensor_heading_and_position_are_used():
    world = World(box_walls(0, 0, 4, 4))
    # Heading +y: the rightmost beam (-pi/2) points along world +x, the leftmost along -x.
    scan = simulate_scan(world, Pose2(1.0, 2.0, np.pi / 2), range_sigma=0.0)
    assert scan.ranges[0] == pytest.approx(3.0)
    assert scan.ranges[180] == pytest.approx(2.0)
    assert scan.ranges[360] == pytest.approx(1.0)
    np.testing.assert_allclose(scan.reference.transform(scan.points())[180], [1.0, 4.0])


def test_pillar_blocks_the_beams_that_hit_it():
    world = World(box_walls(-5, -5, 5, 5), circle_centres=[[3.0, 0.0]], circle_radii=[0.5])
    scan = simulate_scan(world, Pose2(0.0, 0.0, 0.0), range_sigma=0.0)
    a = scan.angles
    on_pillar = np.abs(np.sin(a)) * 3.0 < 0.5
    # |t (cos a, sin a) - (3, 0)| = 0.5, nearer root.
    t_pillar = 3 * np.cos(a) - np.sqrt(np.maximum(0.25 - 9 * np.sin(a) ** 2, 0))
    t_wall = np.minimum(5 / np.abs(np.cos(a) + 1e-300), 5 / np.abs(np.sin(a) + 1e-300))
    expected = np.where(on_pillar, t_pillar, t_wall)
    assert scan.ranges[180] == pytest.approx(2.5)
    assert 10 < on_pillar.sum() < 40
    np.testing.assert_allclose(scan.ranges, expected, atol=1e-9)


def test_beams_past_max_range_return_max_range_and_are_invalid():
    world = World(box_walls(-1, -10, 2, 10))
    scan = simulate_scan(world, Pose2.identity(), range_sigma=0.0, max_range=5.0)
    a = scan.angles
    cosa = np.cos(a)
    t_front = np.where(cosa > 1e-12, 2 / np.where(cosa > 1e-12, cosa, 1), np.inf)
    expected = np.minimum(t_front, 10 / np.maximum(np.abs(np.sin(a)), 1e-300))
    far = expected >= 5.0
    assert 0 < far.sum() < scan.n_beams
    assert np.all(scan.ranges[far] == 5.0)
    assert not scan.valid[far].any()
    assert scan.valid[~far].all()
    np.testing.assert_allclose(scan.ranges[~far], expected[~far], atol=1e-9)
    assert scan.range_max == 5.0


def test_empty_world_returns_only_no_returns():
    scan = simulate_scan(World(np.zeros((0, 2, 2))), Pose2.identity(), range_sigma=0.0)
    assert np.all(scan.ranges == 30.0)
    assert scan.n_valid == 0


def test_people_are_extra_circles_for_this_scan_only():
    world = World(box_walls(-5, -5, 5, 5))
    people = (np.array([[2.0, 0.0]]), np.array([0.2]))
    with_people = simulate_scan(world, Pose2.identity(), range_sigma=0.0, people=people)
    without = simulate_scan(world, Pose2.identity(), range_sigma=0.0)
    assert with_people.ranges[180] == pytest.approx(1.8)
    assert without.ranges[180] == pytest.approx(5.0)
    assert world.n_circles == 0


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_vectorised_ray_casting_agrees_with_reference(seed):
    world = office_world(rng(seed))
    g = rng(100 + seed)
    origin = world.free_regions[0, :2] + 0.5
    angles = g.uniform(-np.pi, np.pi, 60)
    fast = cast_rays(world, origin, angles)
    slow = np.array([ray_reference(world, origin, a) for a in angles])
    np.testing.assert_allclose(fast, slow, rtol=1e-12, atol=1e-12)


def test_world_distance_agrees_with_reference():
    world = office_world(rng(3))
    pts = rng(4).uniform(world.bounds[:2], world.bounds[2:], size=(25, 2))
    np.testing.assert_allclose(
        world.distance(pts), [distance_reference(world, p) for p in pts], atol=1e-12
    )


# -- noise and dropout --------------------------------------------------------------------
def test_range_noise_has_the_requested_sigma():
    world = World(box_walls(-3, -3, 3, 3))
    exact = simulate_scan(world, Pose2.identity(), n_beams=2000, range_sigma=0.0)
    noisy = simulate_scan(world, Pose2.identity(), n_beams=2000, range_sigma=0.05, rng=rng())
    assert np.std(noisy.ranges - exact.ranges) == pytest.approx(0.05, rel=0.1)


def test_dropout_fraction_is_roughly_right():
    world = World(box_walls(-3, -3, 3, 3))
    scan = simulate_scan(
        world, Pose2.identity(), n_beams=4000, range_sigma=0.0, dropout=0.3, rng=rng()
    )
    dropped = np.mean(scan.ranges == scan.range_max)
    assert dropped == pytest.approx(0.3, abs=0.04)
    assert scan.n_valid == np.sum(scan.ranges < scan.range_max)


def test_noise_without_rng_is_refused():
    with pytest.raises(ConfigError, match="rng"):
        simulate_scan(World(box_walls(0, 0, 1, 1)), Pose2(0.5, 0.5, 0.0), range_sigma=0.01)


# -- pairs ----------------------------------------------------------------------------------
@pytest.mark.parametrize("seed", range(8))
def test_pair_points_of_b_land_on_walls_seen_from_a(seed):
    sigma = 0.01
    pair = simulate_pair(rng(seed), moving_people=0, range_sigma=sigma)
    assert isinstance(pair, SimPair)
    ref_a, ref_b = pair.scan_a.reference, pair.scan_b.reference
    np.testing.assert_allclose(
        pair.pose_a_b.as_array(), (ref_a.inverse() @ ref_b).as_array(), atol=1e-12
    )
    # Map scan b into frame a with pose_a_b, then into the world with a's reference.
    pts_world = ref_a.transform(pair.pose_a_b.transform(pair.scan_b.points()))
    assert np.median(pair.world.distance(pts_world)) < 3 * sigma
    pts_world_a = ref_a.transform(pair.scan_a.points())
    assert np.median(pair.world.distance(pts_world_a)) < 3 * sigma


def test_pair_motion_is_within_bounds():
    for seed in range(10):
        pair = simulate_pair(rng(seed), max_translation=0.5, max_rotation=0.2, moving_people=0)
        t, r = Pose2.identity().distance_to(pair.pose_a_b)
        assert t <= 0.5 + 1e-9
        assert r <= 0.2 + 1e-9


@pytest.mark.parametrize("seed", range(6))
def test_pair_poses_are_in_free_space(seed):
    pair = simulate_pair(rng(seed))
    world = pair.world
    for scan in (pair.scan_a, pair.scan_b):
        p = scan.reference.translation
        assert world.is_free(p, clearance=0.3)[0]
        assert distance_reference(world, p) >= 0.3 - 1e-12
        reg = world.free_regions
        inside = (
            (reg[:, 0] <= p[0]) & (p[0] <= reg[:, 2]) & (reg[:, 1] <= p[1]) & (p[1] <= reg[:, 3])
        )
        assert inside.any()
        assert np.all(np.linalg.norm(world.circle_centres - p, axis=1) > world.circle_radii)
        assert scan.n_valid >= 0.5 * scan.n_beams


def test_same_seed_same_pair_other_seed_other_pair():
    a = simulate_pair(rng(42), dropout=0.05)
    b = simulate_pair(rng(42), dropout=0.05)
    c = simulate_pair(rng(43), dropout=0.05)
    np.testing.assert_array_equal(a.world.walls, b.world.walls)
    np.testing.assert_array_equal(a.scan_a.ranges, b.scan_a.ranges)
    np.testing.assert_array_equal(a.scan_b.ranges, b.scan_b.ranges)
    np.testing.assert_array_equal(a.people_b[0], b.people_b[0])
    assert a.pose_a_b == b.pose_a_b
    assert not np.array_equal(a.scan_a.ranges, c.scan_a.ranges)


def test_people_move_between_the_scans_and_are_seen():
    world = room_world(8.0, 6.0, rng=rng(1), doorways=1, pillars=0, clutter=0)
    pair = simulate_pair(rng(5), world=world, moving_people=2, range_sigma=0.0)
    (ca, ra), (cb, rb) = pair.people_a, pair.people_b
    assert ca.shape == cb.shape == (2, 2)
    np.testing.assert_array_equal(ra, rb)
    assert np.all((ra >= 0.15) & (ra <= 0.25))
    step = np.linalg.norm(ca - cb, axis=1)
    assert np.all((step >= 0.3 - 1e-9) & (step <= 1.0 + 1e-9))
    pts = pair.scan_a.reference.transform(pair.scan_a.points())
    on_person = np.abs(np.linalg.norm(pts[:, None] - ca[None], axis=2) - ra).min(axis=1) < 1e-6
    assert on_person.any()
    assert world.is_free(ca, clearance=0.0).all() and world.is_free(cb, clearance=0.0).all()


def test_impossible_world_raises_a_clear_error():
    cupboard = World(box_walls(0, 0, 0.5, 0.5), name="cupboard")
    with pytest.raises(ScanCliqueError, match="cupboard.*not in free space"):
        simulate_pair(rng(), world=cupboard, max_attempts=50)


def test_world_that_shows_too_little_raises():
    lone_wall = World([[[0.0, 0.0], [1.0, 0.0]]], free_regions=[[-20, -20, 20, 20]], name="field")
    with pytest.raises(ScanCliqueError, match="seeing too little"):
        simulate_pair(rng(), world=lone_wall, max_attempts=30)


def test_world_without_free_space_raises():
    with pytest.raises(ScanCliqueError, match="no free regions"):
        simulate_pair(rng(), world=World([[[0.0, 0.0], [1.0, 0.0]]]))


# -- worlds ---------------------------------------------------------------------------------
@pytest.mark.parametrize("seed", range(5))
def test_office_looks_like_a_building(seed):
    world = office_world(rng(seed))
    reg = world.free_regions
    size = np.column_stack((reg[:, 2] - reg[:, 0], reg[:, 3] - reg[:, 1]))
    corridor, rooms = size[0], size[1:]
    assert 1.5 <= corridor[1] <= 3.0 and corridor[0] >= 10.0
    assert len(rooms) >= 2
    assert np.all((rooms >= 3.0 - 1e-9) & (rooms <= 10.0))
    assert np.all((world.circle_radii >= 0.1) & (world.circle_radii <= 0.3))
    assert world.solids.shape[0] >= 1
    assert world.n_walls > 4 * len(rooms)
    assert world.is_free(world.circle_centres).sum() == 0


def test_room_world_builds_what_was_asked():
    world = room_world(6.0, 4.0, rng=rng(2), doorways=2, pillars=2, clutter=3)
    np.testing.assert_array_equal(world.free_regions, [[0.0, 0.0, 6.0, 4.0]])
    assert world.n_circles == 2
    bare = room_world(6.0, 4.0, rng=rng(2), doorways=0, pillars=0, clutter=0)
    np.testing.assert_array_equal(bare.walls, box_walls(0, 0, 6, 4))


def test_boxes_are_solid():
    world = office_world(rng(0))
    centres = world.solids.mean(axis=1)
    assert not world.is_free(centres).any()


def test_corridor_world_and_its_limits():
    world = corridor_world(15.0, 2.0, rng=rng(3), side_rooms=3, doorways=2)
    assert world.free_regions.shape[0] == 4
    np.testing.assert_array_equal(world.free_regions[-1], [0.0, 0.0, 15.0, 2.0])
    with pytest.raises(ConfigError, match="do not fit"):
        corridor_world(5.0, 2.0, rng=rng(), side_rooms=4)


def test_random_world_is_deterministic_and_varied():
    worlds = [random_world(rng(s)) for s in range(12)]
    again = random_world(rng(5))
    np.testing.assert_array_equal(worlds[5].walls, again.walls)
    kinds = {w.name.split()[0] for w in worlds}
    assert len(kinds) >= 2


@pytest.mark.parametrize(
    "call",
    [
        lambda: room_world(-1.0, 3.0, rng=rng()),
        lambda: room_world(3.0, 3.0, rng=0),
        lambda: room_world(3.0, 3.0, rng=rng(), pillars=1.5),
        lambda: World(np.zeros((3, 2))),
        lambda: World(box_walls(0, 0, 1, 1), circle_centres=[[0, 0]], circle_radii=[-1.0]),
        lambda: simulate_scan(World(box_walls(0, 0, 1, 1)), Pose2.identity(), dropout=1.5),
    ],
)
def test_bad_arguments_raise_config_error(call):
    with pytest.raises(ConfigError):
        call()


# -- trajectories -----------------------------------------------------------------------
def test_trajectory_drives_through_free_space():
    world = office_world(rng(0))
    scans = simulate_trajectory(rng(1), world, 30, step=0.3, n_beams=181)
    assert len(scans) == 30 and all(isinstance(s, Scan) for s in scans)
    xy = np.array([s.reference.translation for s in scans])
    np.testing.assert_allclose(np.linalg.norm(np.diff(xy, axis=0), axis=1), 0.3, atol=1e-9)
    assert world.is_free(xy, clearance=0.3).all()
    assert [s.timestamp for s in scans] == pytest.approx([0.5 * i for i in range(30)])
    assert scans[0].odometry == scans[0].reference


def test_trajectory_odometry_is_exact_without_noise_and_drifts_with_it():
    world = room_world(8.0, 6.0, rng=rng(2), pillars=1, clutter=2)
    kw = dict(range_sigma=0.0, n_beams=91)
    exact = simulate_trajectory(
        rng(3), world, 20, trans_noise_per_m=0, rot_noise_per_m=0, rot_noise_per_rad=0, **kw
    )
    for s in exact:
        t, r = s.reference.distance_to(s.odometry)
        assert t < 1e-9 and r < 1e-9
    noisy = simulate_trajectory(rng(3), world, 20, **kw)
    assert [s.reference for s in noisy] == [s.reference for s in exact]
    drift = [s.reference.distance_to(s.odometry)[0] for s in noisy]
    assert drift[-1] > 0
    for prev, cur in zip(noisy[:-1], noisy[1:], strict=True):
        du = (prev.odometry.inverse() @ cur.odometry).inverse() @ (
            prev.reference.inverse() @ cur.reference
        )
        assert math.hypot(du.x, du.y) < 0.1 and abs(du.theta) < 0.1


def test_trajectory_start_must_be_free():
    world = room_world(5.0, 5.0, rng=rng(), pillars=0, clutter=0)
    with pytest.raises(ScanCliqueError, match="not in free space"):
        simulate_trajectory(rng(), world, 5, start=Pose2(0.1, 0.1, 0.0))


def test_a_ring_drive_goes_round_its_corridor():
    from scanclique.sim import ring_world, simulate_ring_drive

    scans = simulate_ring_drive(np.random.default_rng(0), length=30.0, width=20.0, loops=1.0)
    ref = np.array([[s.reference.x, s.reference.y, s.reference.theta] for s in scans])
    step = np.hypot(*np.diff(ref[:, :2], axis=0).T)
    assert np.allclose(step, 0.25, atol=0.002)  # the corners' chords a little shorter
    turned = np.angle(np.exp(1j * (ref[-1, 2] - ref[0, 2])))
    assert abs(turned) < 0.35 and np.hypot(*(ref[-1, :2] - ref[0, :2])) < 0.3  # round once
    world = ring_world(np.random.default_rng(0), 30.0, 20.0)
    assert world.is_free(ref[:, :2], 0.3).all()
    odo = scans[0].odometry.inverse() @ scans[-1].odometry
    drift = np.angle(np.exp(1j * (odo.theta - turned)))
    assert 0.15 < drift < 0.4  # the odometry's steady heading drift: 0.003 rad/m over 89 m
    with pytest.raises(ConfigError, match="leaves no block"):
        ring_world(np.random.default_rng(0), 6.0, 4.0, corridor=2.0)
    # wheels of a wrong radius: every odometry step 5 % short, the true path unchanged
    short = simulate_ring_drive(
        np.random.default_rng(0), length=30.0, width=20.0, loops=1.0, scale_error=-0.05,
        trans_noise_per_m=0.0,
    )  # fmt: skip
    assert [s.reference for s in short] == [s.reference for s in scans]
    steps = [math.hypot(*(a.odometry.inverse() @ b.odometry).as_array()[:2])
             for a, b in zip(short[:-1], short[1:], strict=True)]  # fmt: skip
    assert np.allclose(steps, 0.95 * step)
    for bad in ({"scale_error": -1.0}, {"scale_error": math.nan}, {"heading_bias_per_m": math.inf}):
        with pytest.raises(ConfigError, match="scale_error|heading_bias_per_m"):
            simulate_ring_drive(np.random.default_rng(0), length=30.0, width=20.0, **bad)


def test_a_campus_has_streets_lined_with_trees_and_clear_lanes():
    from scanclique.sim import campus_world, simulate_scan, simulate_sensor_drive

    world = campus_world(np.random.default_rng(3), blocks=(3, 2), street=10.0)
    assert len(world.free_regions) == 3 + 4  # streets across and along, the outer ones too
    c = world.circle_centres
    assert len(c) > 50 and np.all((world.circle_radii >= 0.1) & (world.circle_radii <= 0.4))
    # every tree stands near a street's edge, none in a lane's middle
    for x0, y0, x1, y1 in world.free_regions:
        inside = (c[:, 0] >= x0) & (c[:, 0] <= x1) & (c[:, 1] >= y0) & (c[:, 1] <= y1)
        across = c[inside, 1] - y0 if x1 - x0 > y1 - y0 else c[inside, 0] - x0
        width = min(x1 - x0, y1 - y0)
        assert np.all((across <= 2.0 + 1e-9) | (across >= width - 2.0 - 1e-9))
    # a drive stays on the streets, and a scan sees trunks and façades, not a wall ahead
    rng = np.random.default_rng(3)
    scans = simulate_sensor_drive(rng, campus_world(rng), 40, n_beams=181, max_range=30.0)
    ref = np.array([[s.reference.x, s.reference.y] for s in scans])
    assert campus_world(np.random.default_rng(3)).is_free(ref, 0.05).all()  # rides cut corners
    s = simulate_scan(world, Pose2(5.0, 5.0, 0.0), n_beams=361, max_range=30.0, range_sigma=0.0)
    assert 0.2 < s.valid.mean() < 1.0
    with pytest.raises(ConfigError, match="leaves no lane"):
        campus_world(np.random.default_rng(0), street=4.0)
    with pytest.raises(ConfigError, match="at least"):
        campus_world(np.random.default_rng(0), blocks=(0, 2))
