"""A rotating scanner's sweep: ``Scan.beam_times``, ``deskew``, ``Pose2.twist_to``, the
simulator's swept scans, the readers and stores that carry the times, and the mapper
that takes the skew out before matching."""

from __future__ import annotations

import dataclasses
import logging
import math

import numpy as np
import pytest
from scipy.spatial import cKDTree

from scanclique.errors import ConfigError, ParseError, ScanError
from scanclique.geometry import Pose2
from scanclique.io.npz import read_scans_npz, write_scans_npz
from scanclique.scan import Scan, _sweep_poses, deskew, sweep_velocity
from scanclique.sim import office_world, room_world, simulate_scan, simulate_sensor_drive

#: the simulated TurtleBot3 LDS-01 of benchmarks/mapping_sensors.py (its `lds` profile)
LDS = dict(
    n_beams=360, fov=2 * math.pi * 359 / 360, angle_min=0.0, max_range=3.5, range_sigma=0.0,
    range_sigma_per_m=0.015, dropout=0.05, scan_rate=5.0, speed=0.2,
)  # fmt: skip


# -- the record ----------------------------------------------------------------------------
def test_beam_times_are_checked_and_kept_read_only():
    s = Scan([1.0, 2.0], [0.0, 0.1], beam_times=[0.0, 0.01])
    assert s.beam_times.tolist() == [0.0, 0.01] and not s.beam_times.flags.writeable
    assert Scan([1.0], [0.0]).beam_times is None
    with pytest.raises(ScanError, match="beam_times of shape"):
        Scan([1.0, 2.0], [0.0, 0.1], beam_times=[0.0])
    with pytest.raises(ScanError, match="finite"):
        Scan([1.0, 2.0], [0.0, 0.1], beam_times=[0.0, np.nan])
    with pytest.raises(ScanError, match="more than 1 s"):  # milliseconds given for seconds
        Scan([1.0, 2.0], [0.0, 0.1], beam_times=[0.0, 100.0])
    with pytest.raises(ScanError, match="numeric"):
        Scan([1.0, 2.0], [0.0, 0.1], beam_times=["a", "b"])


# -- the motion ----------------------------------------------------------------------------
@pytest.mark.parametrize("seed", range(6))
def test_twist_to_is_the_logarithm_of_the_sweep_motion(seed):
    rng = np.random.default_rng(seed)
    a = Pose2(*rng.uniform(-5, 5, 2), rng.uniform(-3, 3))
    u = Pose2(*rng.uniform(-0.5, 0.5, 2), rng.uniform(-1.5, 1.5) * (seed % 2))  # 0 turn too
    dt = rng.uniform(0.05, 0.5)
    v = a.twist_to(a @ u, dt)
    th, x, y = _sweep_poses(np.array([dt]), v)
    got = Pose2(float(x[0]), float(y[0]), float(th[0]))
    t_err, r_err = got.distance_to(u)
    assert t_err < 1e-9 and r_err < 1e-9
    with pytest.raises(ScanError, match="positive"):
        a.twist_to(a @ u, 0.0)


def test_sweep_velocity_needs_both_poses_and_a_short_gap():
    a, b = Pose2(0, 0, 0), Pose2(0.1, 0, 0.05)
    assert sweep_velocity(a, b, 0.0, 0.1) == pytest.approx(a.twist_to(b, 0.1))
    jumps = ((a, Pose2(9.0, 0, 0), 0.0, 0.1), (a, Pose2(0, 0, 3.0), 0.0, 0.1))  # 90 m/s, 30 rad/s
    gaps = ((None, b, 0.0, 0.1), (a, b, None, 0.1), (a, b, 0.1, 0.1), (a, b, 0.0, 2.0))
    for args in gaps + jumps:
        assert sweep_velocity(*args) is None


# -- deskew --------------------------------------------------------------------------------
def _room():
    return room_world(6.0, 4.0, rng=np.random.default_rng(3), doorways=1, pillars=2, clutter=2)


def _swept_scan(velocity, n=720, sweep=0.2, fov=2 * math.pi * 719 / 720, angle_min=-math.pi):
    """A noise-free full circle swept in ``sweep`` s from (2, 2, 0.3) at a constant
    ``velocity``, and the scan taken at once there (eight times the beams: the surfaces
    between the swept beams too)."""
    world, start = _room(), Pose2(2.0, 2.0, 0.3)
    times = np.arange(n) * (sweep / n)
    th, x, y = _sweep_poses(times, velocity)
    poses = np.array(
        [(start @ Pose2(a, b, c)).as_array() for a, b, c in zip(x, y, th, strict=True)]
    )
    poses[:, 2] = start.theta + th  # unwrapped
    kw = dict(fov=fov, angle_min=angle_min, max_range=8.0, range_sigma=0.0)
    swept = simulate_scan(world, start, n_beams=n, sweep_poses=poses, beam_times=times, **kw)
    return swept, simulate_scan(world, start, n_beams=8 * n, **kw)


@pytest.mark.parametrize("velocity", [(0.0, 0.0, 1.5), (0.0, 0.0, -1.5), (0.5, 0.1, 0.8)])
def test_deskew_gives_the_scan_taken_at_once(velocity):
    swept, still = _swept_scan(velocity)
    tree = cKDTree(still.points())
    skewed = np.percentile(tree.query(swept.points())[0], 90)
    d = deskew(swept, velocity)
    fixed = np.percentile(tree.query(d.points())[0], 90)
    assert skewed > 0.05 and fixed < 0.01, (skewed, fixed)
    assert np.all(np.diff(d.angles) > 0) and d.angles[-1] - d.angles[0] < 2 * math.pi
    assert d.beam_times is None and d.n_valid == swept.n_valid
    assert (d.timestamp, d.odometry, d.reference) == (
        swept.timestamp,
        swept.odometry,
        swept.reference,
    )


def test_deskew_keeps_invalid_beams_and_validity():
    s = Scan(
        [np.inf, 3.0, np.nan, 0.01, 9.99], np.linspace(0.0, 0.4, 5), range_min=0.02,
        range_max=10.0, beam_times=np.linspace(0.0, 0.04, 5),
    )  # fmt: skip
    d = deskew(s, (1.0, 0.0, 0.5))  # the last return would move beyond range_max: kept
    assert d.valid.tolist() == [False, True, False, False, True]
    assert np.isinf(d.ranges[0]) and np.isnan(d.ranges[2]) and d.ranges[3] == 0.01
    assert d.ranges[4] == 9.99 and d.ranges[1] != 3.0
    turned = s.angles + 0.5 * s.beam_times  # invalid beams turn with the sensor
    assert d.angles[[0, 2, 3]] == pytest.approx(turned[[0, 2, 3]])


def test_deskew_of_a_scan_without_times_or_motion_is_the_scan():
    s = Scan([1.0, 2.0], [0.0, 0.1], beam_times=[0.0, 0.1])
    assert deskew(s, (0.0, 0.0, 0.0)) is s
    plain = Scan([1.0, 2.0], [0.0, 0.1])
    assert deskew(plain, (1.0, 0.0, 1.0)) is plain
    empty = Scan([], [], beam_times=[])
    assert deskew(empty, (1.0, 0.0, 1.0)) is empty
    with pytest.raises(ScanError, match="three finite"):
        deskew(s, (np.nan, 0.0, 0.0))


def test_retime_reads_the_times_each_way():
    from scanclique.scan import retime

    s = Scan([1.0, 1.0], [0.0, 0.1], beam_times=[0.0, 0.1])
    assert retime(s, "given") is s and retime(s, "none").beam_times is None
    assert retime(Scan([1.0], [0.0]), "negated").beam_times is None
    with pytest.raises(ScanError, match="timing must be one of"):
        retime(s, "backwards")


# -- the simulator -------------------------------------------------------------------------
def test_swept_drive_carries_beam_times_and_the_stamp_pose():
    rng = np.random.default_rng(0)
    world = office_world(rng)
    scans = simulate_sensor_drive(rng, world, 4, 0.25, sweep=0.2, **LDS)
    assert all(s.beam_times is not None and s.beam_times[-1] < 0.2 for s in scans)
    rng = np.random.default_rng(0)
    still = simulate_sensor_drive(rng, office_world(rng), 4, 0.25, **LDS)
    assert still[3].beam_times is None
    assert still[3].reference.distance_to(scans[3].reference) == (0.0, 0.0)
    with pytest.raises(ConfigError, match="longer than a scan period"):
        simulate_sensor_drive(rng, world, 4, 0.25, sweep=0.3, **LDS)
    with pytest.raises(ConfigError, match="sweep_poses"):
        simulate_scan(
            world, Pose2(1, 1, 0), n_beams=3, range_sigma=0.0, sweep_poses=np.zeros((2, 3))
        )


# -- readers and stores --------------------------------------------------------------------
def test_npz_keeps_beam_times(tmp_path):
    a = Scan([1.0, 2.0], [0.0, 0.1], beam_times=[0.0, 0.05])
    b = Scan([3.0, 4.0], [0.0, 0.1])
    c = Scan([5.0], [0.0], beam_times=[0.01])
    for scans in ([a, b], [a, b, c]):  # (S, N) and ragged
        write_scans_npz(tmp_path / "s.npz", scans)
        back = read_scans_npz(tmp_path / "s.npz")
        assert [None if s.beam_times is None else s.beam_times.tolist() for s in back] == [
            None if s.beam_times is None else s.beam_times.tolist() for s in scans
        ]
    np.savez(tmp_path / "bad.npz", ranges=np.ones((1, 2)), angles=np.array([[0.0, 0.1]]),
             beam_times=np.array([[0.0, np.nan]]))  # fmt: skip
    with pytest.raises(ParseError, match="not all"):
        read_scans_npz(tmp_path / "bad.npz")
    np.savez(tmp_path / "int.npz", ranges=np.ones((1, 2)), angles=np.array([[0.0, 0.1]]),
             beam_times=np.array([[0, 1]]))  # fmt: skip
    with pytest.raises(ParseError, match="floats like ranges"):
        read_scans_npz(tmp_path / "int.npz")


def test_the_scan_text_format_keeps_beam_times(tmp_path):
    from scanclique.io.text import read_scans_text, write_scans_text

    a = Scan([1.0, 2.0], [0.0, 0.1], timestamp=1.0, beam_times=[0.0, 0.05])
    b = Scan([3.0, 4.0], [0.0, 0.1], timestamp=2.0)
    write_scans_text(tmp_path / "s.scan", [a, b])
    back = read_scans_text(tmp_path / "s.scan")
    assert back[0].beam_times.tolist() == [0.0, 0.05] and back[1].beam_times is None
    head = "# scanclique scans v1\nSCAN 1.0 0.0 0.1 0.0 80.0 2 1.0 2.0 "
    for tail, msg in (
        ("TIMES 0.0 0.1 TIMES 0.0 0.1", "TIMES given twice"),
        ("TIMES 0.0", "TIMES expects 2 values"),
        ("TIMES 0.0 5.0", "more than 1 s"),
        ("TIMES 0.0 x", "time"),
    ):
        (tmp_path / "bad.scan").write_text(head + tail + "\n")
        with pytest.raises(ParseError, match=msg):
            read_scans_text(tmp_path / "bad.scan")


def test_a_place_keeps_its_beam_times(tmp_path):
    from scanclique.places import PlaceDB

    swept, _ = _swept_scan((0.2, 0.0, 0.5), n=181, fov=math.pi, angle_min=-math.pi / 2)
    with PlaceDB(tmp_path / "p.db") as db:
        pid = db.add(swept)
    with PlaceDB(tmp_path / "p.db") as db:
        assert np.array_equal(db.get(pid).scan.beam_times, swept.beam_times)


def test_a_bag_gives_each_beam_its_time(tmp_path, caplog):
    pytest.importorskip("rosbags")
    from test_rosbag import _ros2_msgs, _write_bag2

    from scanclique.io.rosbag import read_bag

    laser, _, _ = _ros2_msgs()
    inc = 2 * math.pi / 360
    full = Scan(np.linspace(1.0, 2.0, 360), np.arange(360) * inc, range_max=8.0, timestamp=1.0)
    at = [dataclasses.replace(full, timestamp=1.0 + 0.1 * n) for n in range(3)]  # 0.1 s apart
    fine = dataclasses.replace(laser(at[0], 0), time_increment=1e-4)  # a 36 ms sweep
    bogus = dataclasses.replace(laser(at[1], 1), time_increment=0.01)  # a 3.6 s sweep
    nan = dataclasses.replace(laser(at[2], 2), time_increment=float("nan"))
    rows = [("/scan", 1_000_000_000, fine), ("/scan", 1_100_000_000, bogus)]
    _write_bag2(tmp_path / "b", [*rows, ("/scan", 1_200_000_000, nan)])  # 0.1 s apart
    with caplog.at_level(logging.WARNING):
        got = read_bag(tmp_path / "b", topic="/scan")
    # a full circle from 0 is rolled to start at -pi: each beam keeps its own time; a
    # sweep of 36 ms for circles 0.1 s apart is not a rotating lidar's: its revolution's
    idx = np.rint(np.mod(got[0].angles, 2 * math.pi) / inc).astype(int) % 360
    np.testing.assert_allclose(got[0].ranges, np.float32(full.ranges)[idx])
    assert "more than 1 s" in caplog.text and "sweeps in its period" in caplog.text
    for g in got:  # the bogus and the NaN time_increment too
        np.testing.assert_allclose(g.beam_times, (0.1 / 360) * idx, atol=1e-9)
    caplog.clear()
    rows = [
        ("/scan", 1_000_000_000 + n * 100_000_000,
         dataclasses.replace(laser(at[n], n), time_increment=0.1 / 360))
        for n in range(3)
    ]  # fmt: skip
    _write_bag2(tmp_path / "c", rows)
    with caplog.at_level(logging.WARNING):
        got = read_bag(tmp_path / "c", topic="/scan")
    np.testing.assert_allclose(got[0].beam_times, (0.1 / 360) * idx, atol=1e-9)
    assert "time" not in caplog.text  # as published


# -- the mapper ----------------------------------------------------------------------------
def _swept_drive(seed: int, steps: int = 30):
    rng = np.random.default_rng(seed)
    return simulate_sensor_drive(rng, office_world(rng), steps, 0.25, sweep=0.2, **LDS)


def _mapped(scans, use_odometry: bool, **front_end):
    from scanclique.mapping import MapConfig, map_scans

    cfg = MapConfig()
    cfg = dataclasses.replace(cfg, front_end=dataclasses.replace(cfg.front_end, **front_end))
    return map_scans(scans, use_odometry=use_odometry, config=cfg)


def _worst_turn_between_scans(result, scans) -> float:
    """Degrees: the largest heading error of a step between consecutive scans."""
    return max(
        math.degrees((a.inverse() @ b).distance_to(sa.reference.inverse() @ sb.reference)[1])
        for a, b, sa, sb in zip(result.poses, result.poses[1:], scans, scans[1:], strict=False)
    )


def test_mapping_a_swept_lidar_with_odometry_takes_the_skew_out():
    scans = _swept_drive(3)  # the LDS-01 at 5 Hz turns up to 18 degrees in a sweep
    raw, fixed = _mapped(scans, True, deskew=False), _mapped(scans, True)
    before = _worst_turn_between_scans(raw, scans)
    after = _worst_turn_between_scans(fixed, scans)
    assert before > 4.0 and after < 1.5, (before, after)
    assert fixed.counts()["deskewed"] == len(scans) and raw.deskewed == 0


def _true_sweep_velocities(scans):
    return np.array(
        [a.reference.twist_to(b.reference, 0.2) for a, b in zip(scans, scans[1:], strict=False)]
    )


def test_online_without_odometry_the_deskew_velocity_is_the_estimates_over_a_window(
    monkeypatch,
):
    import scanclique.mapping.pipeline as pipeline
    from scanclique.mapping import MapConfig

    scans = _swept_drive(0)
    true = _true_sweep_velocities(scans)
    seen = []

    def spy(scan, velocity):
        seen.append((int(scan.source.split(":")[1]), np.asarray(velocity)))
        return deskew(scan, velocity)

    monkeypatch.setattr(pipeline, "deskew", spy)

    def speed_error(window):
        seen.clear()
        cfg = MapConfig.online()
        fe = dataclasses.replace(cfg.front_end, deskew_window=window)
        # the online mapper's front end, its beam times' reading decided (as the online
        # mapper does once the scans tell it, mapping.sweep)
        m = pipeline._Mapper(False, False, dataclasses.replace(cfg, front_end=fe), 1)
        m.timing = "given"
        try:
            for s in scans:
                m.add_scan(s)
        finally:
            m.verifier.close()
        assert seen and min(j for j, _ in seen) >= 2  # the first scans: no velocity yet
        return np.median([abs(v[0] - true[j][0]) for j, v in seen if j < len(true)])

    # over a single step the matches' errors come back through the de-skew
    assert speed_error(0.5) < 0.02 and speed_error(0.01) > 0.1


def test_without_odometry_map_scans_takes_the_sweeps_velocities_from_a_first_pass():
    from scanclique.mapping import MapConfig
    from scanclique.mapping.pipeline import sweep_velocities

    scans = _swept_drive(1)
    got = sweep_velocities(scans, MapConfig())
    assert len(got) == len(scans) and all(v is not None for v in got)
    err = np.abs(np.array(got[:-1]) - _true_sweep_velocities(scans))
    assert np.median(err[:, 0]) < 0.04 and np.median(err[:, 2]) < 0.05, np.median(err, axis=0)
    assert "sweeps" in _mapped(scans, False).seconds
    assert _mapped(scans, False).sweep_timing == "given"


@pytest.mark.parametrize(
    ("timing", "published"),
    [
        ("given", lambda t: t),
        ("negated", lambda t: -t),  # stored against their order, stamped at the end
        ("reversed", lambda t: t.max() - t),  # stored against their order
        ("shifted", lambda t: t + t.max()),  # stamped at the end
        ("none", lambda t: 0.25 * np.sin(40 * t)),  # nonsense
    ],
)
def test_a_drivers_beam_times_are_read_as_the_log_agrees(timing, published):
    from scanclique.mapping.sweep import sweep_timing

    scans = _swept_drive(3)
    given = [dataclasses.replace(s, beam_times=published(s.beam_times)) for s in scans]
    found, scores, pairs = sweep_timing(given, lambda i: given[i].odometry)
    assert found == timing and pairs >= 20, scores
    if timing in ("negated", "none"):  # mapped as if given right, or not de-skewed
        result = _mapped(given, True)
        assert result.sweep_timing == timing
        assert (result.deskewed == 0) == (timing == "none")
        if timing == "negated":
            assert _worst_turn_between_scans(result, given) < 1.5


def test_a_swept_lidars_bag_is_mapped_deskewed(tmp_path):
    """End to end as a user runs it: a ROS 2 bag of a 5 Hz 360-degree lidar with its
    time_increment and odometry on tf, read and mapped."""
    pytest.importorskip("rosbags")
    from test_rosbag import _ros2_msgs, _write_bag2

    from scanclique.io.rosbag import read_bag

    scans = [dataclasses.replace(s, timestamp=s.timestamp + 100.0) for s in _swept_drive(3)]
    laser, _, tf = _ros2_msgs()
    rows = []
    for k, s in enumerate(scans):
        t_ns = int(round(s.timestamp * 1e9))
        msg = dataclasses.replace(laser(s, k), time_increment=0.2 / 360)
        rows += [("/tf", t_ns, tf(s.timestamp, s.odometry, k)), ("/scan", t_ns + 1, msg)]
    _write_bag2(tmp_path / "swept", rows)
    got = read_bag(tmp_path / "swept", topic="/scan")
    assert len(got) == len(scans) and all(g.beam_times is not None for g in got)
    # a bag has no truth: the simulator's, to score
    got = [dataclasses.replace(g, reference=s.reference) for g, s in zip(got, scans, strict=True)]
    before = _worst_turn_between_scans(_mapped(got, True, deskew=False), got)
    after = _worst_turn_between_scans(_mapped(got, True), got)
    assert before > 4.0 and after < 1.5, (before, after)
    # the command's run: its table says so, and the map is written
    from scanclique.mapping.run import run_map

    run = run_map(tmp_path / "swept", tmp_path / "out", topic="/scan", plot=False)
    rows = {m: v for m, v, _u in run.rows()}
    assert rows["de-skewed (a rotating lidar's sweep)"] == str(len(scans))
    assert rows["beam times read"] == "given" and (tmp_path / "out" / "map.pgm").is_file()


def test_a_bag_like_the_lds01_drivers_is_read_and_mapped_right(tmp_path, caplog):
    """The TurtleBot3 LDS-01 driver's way: the beams stored against the order they were
    measured in, the scan stamped when complete, and a time_increment far too short (a
    sweep of about 11 ms for a 200 ms revolution). The reader takes the revolution's
    times, the mapper finds them negated, and the map is as good as from a right bag."""
    pytest.importorskip("rosbags")
    from test_rosbag import _ros2_msgs, _write_bag2

    from scanclique.io.rosbag import read_bag

    scans = [dataclasses.replace(s, timestamp=s.timestamp + 100.0) for s in _swept_drive(3)]
    laser, _, tf = _ros2_msgs()
    rows = []
    for k, s in enumerate(scans):
        end = dataclasses.replace(s, timestamp=s.timestamp + 0.2 * 359 / 360)
        msg = dataclasses.replace(
            laser(end, k), angle_min=float(s.angles[-1]), angle_max=float(s.angles[0]),
            angle_increment=-float(s.angles[1] - s.angles[0]), time_increment=3e-5,
            ranges=np.asarray(s.ranges[::-1], dtype=np.float32),
        )  # fmt: skip
        t_ns = int(round(s.timestamp * 1e9))
        rows += [("/tf", t_ns, tf(s.timestamp, s.odometry, k)), ("/scan", t_ns + 1, msg)]
    _write_bag2(tmp_path / "lds", rows)
    with caplog.at_level(logging.WARNING):
        got = read_bag(tmp_path / "lds", topic="/scan")
    assert "sweeps in its period" in caplog.text
    result = _mapped(got, True)
    assert result.sweep_timing == "negated" and "negated" in caplog.text
    # the stamps are the sweeps' ends: where the robot is at the next scan's start
    ends = [
        dataclasses.replace(g, reference=s.reference) for g, s in zip(got, scans[1:], strict=False)
    ]
    assert _worst_turn_between_scans(result, ends) < 1.5


def test_times_given_to_scans_measured_at_once_are_found_wrong():
    """A simulator's lidar (Gazebo's) measures every beam at once and publishes no
    time_increment, so the reader gives its full circles a revolution's times: the
    check finds that no reading agrees better than none, and the map is the plain one."""
    from scanclique.mapping.sweep import sweep_timing

    rng = np.random.default_rng(3)
    at_once = simulate_sensor_drive(rng, office_world(rng), 30, 0.25, **LDS)
    times = np.arange(360) * (0.2 / 360)
    given = [dataclasses.replace(s, beam_times=times) for s in at_once]
    assert sweep_timing(given, lambda i: given[i].odometry)[0] == "none"
    plain, checked = _mapped(at_once, True), _mapped(given, True)
    assert checked.sweep_timing == "none" and checked.deskewed == 0
    assert [p.as_array().tolist() for p in checked.poses] == [
        p.as_array().tolist() for p in plain.poses
    ]


def test_online_the_beam_times_are_read_once_the_scans_tell():
    """Online the log's end is not known: the mapper tries the reading at the 25th, 50th,
    100th, ... scan and de-skews from when one direction of the times clearly leads."""
    from scanclique.mapping import map_online

    scans = [dataclasses.replace(s, beam_times=-s.beam_times) for s in _swept_drive(3, 60)]
    result = map_online(scans, use_odometry=True).result
    assert result.sweep_timing == "negated" and 0 < result.deskewed < len(scans)
    short = map_online(scans[:20], use_odometry=True).result  # too few to tell
    assert short.sweep_timing == "none" and short.deskewed == 0
