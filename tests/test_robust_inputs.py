"""Robustness audit (s12): small malformed inputs through the public entry points.

Each case either raises a named :class:`~scanclique.errors.ScanCliqueError` naming the
file (line, field) or gives the documented result; the CLI exits 2 with one ``error:``
line and no traceback. Cases already covered elsewhere (``test_io``, ``test_fuzz``,
``test_hostile``, ``test_slam_reader``, ``test_places_*``) are not repeated here.
"""

from __future__ import annotations

import bz2
import gzip
import logging
import math
from pathlib import Path

import numpy as np
import pytest
from conftest import assert_clean_error
from typer.testing import CliRunner

import scanclique as sc
from scanclique import cli, slam
from scanclique.errors import (
    ArgumentError,
    ConfigError,
    ParseError,
    PlaceDatabaseError,
    ScanCliqueError,
    ScanError,
)
from scanclique.geometry import Pose2
from scanclique.io import detect_format, write_scans_text
from scanclique.io.carmen import read_carmen
from scanclique.mapping.occupancy import occupancy_grid
from scanclique.places import PlaceDB
from scanclique.slam.run import run_slam

runner = CliRunner()
BOM = b"\xef\xbb\xbf"


def invoke(*args):
    return runner.invoke(cli.app, [str(a) for a in args])


def flaser(ranges, t: float) -> str:
    rs = " ".join(str(r) for r in ranges)
    return f"FLASER {len(ranges)} {rs} 0 0 0 0 0 0 {t} host {t}\n"


def carmen_text(n: int = 3, beams: int = 180) -> bytes:
    return "".join(flaser([1.0 + 0.01 * k] * beams, float(k)) for k in range(n)).encode()


# ---------------------------------------------------------------------------------------
# readers: a UTF-8 byte order mark was glued to the first record's type, which was then
# skipped as an unknown message (debug log only): the first scan was lost
# ---------------------------------------------------------------------------------------
@pytest.mark.parametrize("pack", [bytes, gzip.compress, bz2.compress], ids=["plain", "gz", "bz2"])
def test_a_byte_order_mark_does_not_lose_the_first_scan(tmp_path, pack):
    p = tmp_path / "bom.log"
    p.write_bytes(pack(BOM + carmen_text(3)))
    scans = sc.read_scans(p)
    assert len(scans) == 3 and scans[0].ranges[0] == 1.0


def test_a_byte_order_mark_before_scan_text_and_comments(tmp_path):
    scans = sc.sim.simulate_trajectory(
        np.random.default_rng(0), sc.sim.office_world(np.random.default_rng(0)), 2
    )
    plain = tmp_path / "a.txt"
    write_scans_text(plain, scans)
    marked = tmp_path / "b.txt"
    marked.write_bytes(BOM + plain.read_bytes())
    assert detect_format(marked) == "text"
    assert len(sc.read_scans(marked)) == len(sc.read_scans(plain)) == 2
    only = tmp_path / "c.log"
    only.write_bytes(BOM + b"# a comment\n" + carmen_text(1))
    assert len(sc.read_scans(only)) == 1
    (tmp_path / "d.log").write_bytes(BOM)  # the mark alone: an empty log
    assert sc.read_scans(tmp_path / "d.log") == []


def test_part_of_a_byte_order_mark_is_content_and_refused(tmp_path):
    p = tmp_path / "e.log"
    p.write_bytes(BOM[:2] + carmen_text(1))
    with pytest.raises(ParseError, match=r"e\.log:1:"):
        sc.read_scans(p)


def test_a_truncated_stream_is_reported_once_not_also_as_recovered(tmp_path, caplog):
    p = tmp_path / "t.clf.bz2"
    p.write_bytes(bz2.compress(carmen_text(3))[:-20])
    with caplog.at_level(logging.WARNING), pytest.raises(ParseError, match="truncated bzip2"):
        sc.read_scans(p)
    assert "reading what was recovered" not in caplog.text  # strict: nothing is recovered


# ---------------------------------------------------------------------------------------
# map_scans and the occupancy grid
# ---------------------------------------------------------------------------------------
@pytest.mark.parametrize("bad", [None, 3, "intel.log"])
def test_map_scans_of_something_not_a_sequence_of_scans(bad):
    with pytest.raises(ArgumentError, match="sequence of Scan"):
        sc.map_scans(bad)


def test_map_scans_of_no_scans_is_an_empty_map():
    r = sc.map_scans([])
    assert r.poses == () and r.keyframes == ()


def test_occupancy_grid_of_scans_without_any_beam_is_unknown():
    angles = np.linspace(-math.pi / 2, math.pi / 2, 5)
    nan = sc.Scan(np.full(5, np.nan), angles, 0.0, 80.0)
    none = sc.Scan(np.zeros(0), np.zeros(0), 0.0, 80.0)
    g = occupancy_grid([nan, none], [Pose2(0.0, 0.0, 0.0), Pose2(1.0, 2.0, 0.5)])
    assert g.log_odds.size > 0 and not g.log_odds.any()


@pytest.mark.parametrize("ranges", [["nan"] * 4, []], ids=["all NaN", "no beams"])
def test_map_command_on_a_log_without_a_single_return(tmp_path, ranges):
    log = tmp_path / "dark.log"
    log.write_text(flaser(ranges, 1.0) + flaser(ranges, 2.0))
    r = invoke("map", log, "--out", tmp_path / "out")
    assert r.exit_code == 0, r.output
    assert (tmp_path / "out" / "map.pgm").is_file()


# ---------------------------------------------------------------------------------------
# Victoria Park reader and EKF-SLAM
# ---------------------------------------------------------------------------------------
def _vp(d: Path, meas, inputs=b"0.0 1.0 0.0\n", gps=b"0.0 0.0 0.0\n") -> Path:
    d.mkdir(parents=True, exist_ok=True)
    for name, data in (("measurements.dat", meas), ("inputs.dat", inputs), ("gps.dat", gps)):
        (d / name).write_bytes(data if isinstance(data, bytes) else data.encode())
    return d


@pytest.mark.parametrize(
    "data, line",
    [(b"\x89PNG\r\n\x1a\n\x00\xff", 1), (b"0.5 10.0 1.0 0.3\n# caf\xe9\n", 2)],
    ids=["binary", "latin-1 comment"],
)
def test_victoria_park_file_that_is_not_text(tmp_path, data, line):
    d = _vp(tmp_path / "vp", data)
    with pytest.raises(ParseError) as ei:
        slam.read_victoria_park(d)
    assert ei.value.path.endswith("measurements.dat") and ei.value.line == line
    assert_clean_error(invoke("slam", d), "measurements.dat", "UTF-8")


def test_victoria_park_empty_tables_without_warnings(tmp_path, recwarn):
    d = _vp(tmp_path / "vp", "", "0.0 1.0 0.0\n0.5 1.0 0.0\n")
    steps = slam.read_victoria_park(d)
    assert len(steps) == 2 and all(s.n_observations == 0 for s in steps)
    assert not [w for w in recwarn if "loadtxt" in str(w.message)]


def test_victoria_park_bad_arguments(tmp_path):
    d = _vp(tmp_path / "vp", "0.5 10.0 1.0 0.3\n")
    with pytest.raises(ConfigError, match="max_range"):
        slam.read_victoria_park(d, max_range=float("nan"))  # would drop every detection
    with pytest.raises(ArgumentError):
        slam.read_victoria_park(None)


def test_slam_command_with_no_steps_and_with_gps_outside_the_run(tmp_path):
    empty = _vp(tmp_path / "empty", "# nothing\n", "")
    with pytest.raises(ParseError, match="holds no steps"):
        run_slam(empty)
    assert_clean_error(invoke("slam", empty), "holds no steps")
    late = _vp(tmp_path / "late", "0.5 10.0 1.0 0.3\n1.0 10.0 1.0 0.3\n", gps=b"50 0 0\n")
    r = invoke("slam", late, "--json")
    assert r.exit_code == 0, r.output
    assert r.stderr.count("no GPS error") == 1
    r = invoke("slam", late, "--json", "--smooth")  # said once, not again for the smoothing
    assert r.exit_code == 0, r.output
    assert r.stderr.count("no GPS error") == 1


def test_ekf_slam_arguments():
    model = slam.Ackermann()
    assert len(slam.ekf_slam([], model).poses) == 0
    with pytest.raises(ArgumentError):
        slam.ekf_slam(None, model)
    with pytest.raises(ArgumentError, match=r"steps\[1\]"):
        slam.ekf_slam([slam.Step(0.0, None, []), None], model)
    quiet = [slam.Step(0.0, (1.0, 0.0), []), slam.Step(1.0, None, [])]
    with pytest.raises(ConfigError, match="association"):  # checked without observations
        slam.ekf_slam(quiet, model, association="foo")
    r = slam.ekf_slam(iter(quiet), model)  # any iterable of steps
    assert r.poses.shape == (2, 3)


# ---------------------------------------------------------------------------------------
# place database
# ---------------------------------------------------------------------------------------
@pytest.mark.parametrize("name", ["a?b.db", "c#d.db", "e%41f.db"])
def test_place_database_path_is_taken_literally(tmp_path, name):
    """SQLite URIs end the path at ``?`` / ``#`` and decode ``%``: ``a?b.db`` was ``a``."""
    with PlaceDB(tmp_path / name) as db:
        db.add(sc.Scan(np.full(10, 2.0), np.linspace(-1.0, 1.0, 10), 0.0, 80.0))
    stray = {p.name for p in tmp_path.iterdir()} - {name, f"{name}-wal", f"{name}-shm"}
    assert (tmp_path / name).is_file() and not stray
    with PlaceDB(tmp_path / name, readonly=True) as db:
        assert len(db) == 1


def test_place_database_bad_paths(tmp_path):
    with pytest.raises(PlaceDatabaseError, match="file path"):
        PlaceDB(None)
    (tmp_path / "dir.db").mkdir()
    (tmp_path / "text.db").write_text("hello\n")
    log = tmp_path / "one.log"
    log.write_text(flaser([1.0] * 10, 1.0))
    assert_clean_error(invoke("places", "add", tmp_path / "dir.db", log), "is a directory")
    assert_clean_error(invoke("places", "query", tmp_path / "text.db", log, 0), "corrupted")


def test_place_database_empty_and_featureless_scans(tmp_path):
    angles = np.linspace(-1.5, 1.5, 180)
    nan = sc.Scan(np.full(180, np.nan), angles, 0.0, 80.0)
    none = sc.Scan(np.zeros(0), np.zeros(0), 0.0, 80.0)
    with PlaceDB(tmp_path / "p.db") as db:
        assert db.query(nan) == [] and db.best(none) is None  # an empty database
        db.add(nan)
        db.add(none)
        hits = db.query(nan)
        assert hits and all(h.verdict == "rejected" and "no features" in h.reason for h in hits)
    with PlaceDB(tmp_path / "p.db") as db, pytest.raises(ScanCliqueError):
        db.add(None)


# ---------------------------------------------------------------------------------------
# ROS bags
# ---------------------------------------------------------------------------------------
def test_a_bag_with_a_non_finite_odometry_pose_names_the_bag_and_message(tmp_path):
    pytest.importorskip("rosbags")
    from rosbags.rosbag1 import Writer
    from rosbags.typesys import Stores, get_typestore

    from scanclique.io.rosbag import read_bag

    ts = get_typestore(Stores.ROS1_NOETIC)
    T = ts.types

    def header(t: float, frame: str):
        stamp = T["builtin_interfaces/msg/Time"](sec=int(t), nanosec=0)
        return T["std_msgs/msg/Header"](seq=0, stamp=stamp, frame_id=frame)

    def odom(t: float, x: float):
        v = T["geometry_msgs/msg/Vector3"](x=0.0, y=0.0, z=0.0)
        pose = T["geometry_msgs/msg/Pose"](
            position=T["geometry_msgs/msg/Point"](x=x, y=0.0, z=0.0),
            orientation=T["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=0.0, w=1.0),
        )
        return T["nav_msgs/msg/Odometry"](
            header=header(t, "odom"), child_frame_id="base_link",
            pose=T["geometry_msgs/msg/PoseWithCovariance"](pose=pose, covariance=np.zeros(36)),
            twist=T["geometry_msgs/msg/TwistWithCovariance"](
                twist=T["geometry_msgs/msg/Twist"](linear=v, angular=v), covariance=np.zeros(36)
            ),
        )  # fmt: skip

    def laser(t: float, range_max: float = 30.0):
        return T["sensor_msgs/msg/LaserScan"](
            header=header(t, "laser"), angle_min=-1.0, angle_max=1.0, angle_increment=0.5,
            time_increment=0.0, scan_time=0.0, range_min=0.0, range_max=range_max,
            ranges=np.full(5, 2.0, np.float32), intensities=np.zeros(0, np.float32),
        )  # fmt: skip

    path = tmp_path / "nan-odom.bag"
    with Writer(path) as w:
        cs = w.add_connection("/scan", "sensor_msgs/msg/LaserScan", typestore=ts)
        co = w.add_connection("/odom", "nav_msgs/msg/Odometry", typestore=ts)
        for k, x in enumerate([0.0, math.nan]):
            t = 1.0 + k
            w.write(co, int(t * 1e9), ts.serialize_ros1(odom(t, x), "nav_msgs/msg/Odometry"))
            w.write(cs, int(t * 1e9) + 1, ts.serialize_ros1(laser(t), "sensor_msgs/msg/LaserScan"))
    with pytest.raises(ParseError, match=r"nan-odom\.bag: /odom message 1: Pose2 needs finite"):
        read_bag(path)
    path = tmp_path / "nan-max.bag"
    with Writer(path) as w:
        cs = w.add_connection("/scan", "sensor_msgs/msg/LaserScan", typestore=ts)
        msg = ts.serialize_ros1(laser(1.0, math.nan), "sensor_msgs/msg/LaserScan")
        w.write(cs, int(1e9), msg)
    with pytest.raises(ParseError) as ei:
        read_bag(path)
    assert str(ei.value).count("nan-max.bag") == 1  # named once, not again as the source
    assert "/scan message 0: need 0 <= range_min < range_max" in str(ei.value)


def test_a_scan_error_in_a_text_log_names_the_file_once(tmp_path):
    p = tmp_path / "flat.scan"
    p.write_text("SCAN 1.0 0 0 0 80 3 1 2 3\n")  # angle_increment 0
    with pytest.raises(ParseError) as ei:
        sc.read_scans(p)
    assert str(ei.value) == f"{p}:1: beam angles must be strictly increasing"


def test_beam_angles_in_degrees_are_refused():
    """A scan whose beams span more than two turns holds degrees, not radians: a
    ScanError that gives the span converted; a full turn, and a self-overlapping scan up to
    two turns, are kept."""
    from scanclique.scan import MAX_ANGLE_SPAN, Scan

    with pytest.raises(ScanError, match=r"span 270 rad.*in radians is 4\.71239"):
        Scan.from_ranges(np.ones(541), angle_min=-135.0, fov=270.0)
    assert Scan.from_ranges(np.ones(360), angle_min=-math.pi, fov=2 * math.pi).n_beams == 360
    s = Scan(np.ones(3), np.array([0.0, 1.0, MAX_ANGLE_SPAN]))
    assert s.n_valid == 3


def test_smoothing_a_run_without_observations_is_empty(tmp_path):
    pytest.importorskip("gtsam")
    from scanclique.slam.smooth import smooth

    steps = [slam.Step(0.0, (1.0, 0.0), []), slam.Step(1.0, None, [])]
    model = slam.Ackermann()
    sm = smooth(steps, model, slam.ekf_slam(steps, model))
    assert sm.poses.shape == (0, 3) and sm.landmarks.shape == (0, 2) and sm.factors == 0
    d = _vp(tmp_path / "vp", "", "0.0 1.0 0.0\n0.5 1.0 0.0\n")
    r = invoke("slam", d, "--smooth", "--json")
    assert r.exit_code == 0, r.output


def test_wrong_configuration_and_scan_arguments_of_map_scans_and_find_loops():
    from scanclique.places.loops import find_loops

    with pytest.raises(ConfigError, match="MapConfig"):
        sc.map_scans([], config=sc.MatchConfig())  # was an AttributeError: front_end
    with pytest.raises(ArgumentError, match="sequence of Scan"):
        find_loops(None)
    with pytest.raises(ConfigError, match="MatchConfig"):
        find_loops([], "paper")
    assert find_loops([]).loops == ()


def test_of_two_controls_at_one_time_the_last_holds(tmp_path):
    """The first of two equal-time controls used to hold, the second was dropped."""
    d = _vp(tmp_path / "vp", "0.5 10.0 1.0 0.3\n", "0.0 1.0 0.0\n0.5 1.0 0.1\n0.5 2.0 0.2\n")
    steps = slam.read_victoria_park(d)
    assert [s.time for s in steps] == [0.0, 0.5]
    assert steps[1].control.tolist() == [2.0, 0.2] and steps[1].n_observations == 1


def test_a_byte_order_mark_before_a_table_or_relations_file(tmp_path):
    from scanclique.eval import read_relations

    d = _vp(tmp_path / "vp", BOM + b"0.5 10.0 1.0 0.3\n", BOM + b"0.0 1.0 0.0\n")
    steps = slam.read_victoria_park(d)
    assert [s.time for s in steps] == [0.0, 0.5] and steps[1].n_observations == 1
    bad = _vp(tmp_path / "bad", BOM + b"0.5 10.0 1.0 0.3\n\xff\n")
    with pytest.raises(ParseError) as ei:
        slam.read_victoria_park(bad)
    assert ei.value.line == 2
    rel = tmp_path / "r.relations"
    rel.write_bytes(BOM + b"1.0 2.0 0.5 0.0 0 0 0 0.1\n")
    (r,) = read_relations(rel)
    assert (r.t1, r.t2) == (1.0, 2.0)


def test_a_byte_order_mark_before_a_configuration_file(tmp_path):
    from scanclique.config import MatchConfig, paper_config
    from scanclique.io.config import read_config, write_config

    plain = tmp_path / "plain.toml"
    write_config(plain, paper_config())
    marked = tmp_path / "marked.toml"
    marked.write_bytes(BOM + plain.read_bytes())
    assert read_config(marked, cls=MatchConfig) == read_config(plain, cls=MatchConfig)
    bad = tmp_path / "bad.toml"
    bad.write_bytes(BOM + b"[a]\n\xff\n")
    with pytest.raises(ConfigError, match=r"bad\.toml: not UTF-8 text \(byte 7\)"):
        read_config(bad, cls=MatchConfig)


# --- PlaceDB arguments of the wrong type (a ConfigError / ArgumentError, no file) ---------
@pytest.mark.parametrize(
    "kw",
    [
        {"cache": -1},
        {"cache": 2.5},
        {"escalate": -1},
        {"seeded": True},
        {"min_features": "3"},
        {"min_score": float("nan")},
        {"min_confidence": 1.5},
        {"config": {"features": {}}},
    ],
)
def test_placedb_refuses_bad_arguments_before_creating_the_file(tmp_path, kw):
    path = tmp_path / "p.db"
    with pytest.raises(ConfigError, match="PlaceDB: "):
        PlaceDB(path, **kw)
    assert not path.exists()


def test_placedb_query_arguments_are_checked(tmp_path):
    pair = sc.sim.simulate_pair(np.random.default_rng(3))
    with PlaceDB(tmp_path / "p.db") as db:
        pid = db.add(pair.scan_a)
        for kw in ({"k": float("nan")}, {"k": -1}, {"candidates": 1.5}):
            with pytest.raises(ConfigError):
                db.query(pair.scan_b, **kw)
        for bad in ("12", [1, "x"], 3):
            with pytest.raises(ArgumentError, match="exclude|place id"):
                db.query(pair.scan_b, exclude=bad)
        with pytest.raises(ArgumentError, match="place id"):
            db.get("x")
        with pytest.raises(ArgumentError, match="place id"):
            db.prepared(1.0)
        # the accepted forms still work: a range, a list, a numpy array, None
        for ex in (range(pid, pid + 1), [pid], np.array([pid]), None):
            hits = db.query(pair.scan_b, k=1, exclude=ex)
            assert [h.place_id for h in hits] == ([] if ex is not None else [pid])
        assert db.get(np.int64(pid)).scan.n_beams == pair.scan_a.n_beams


# --- an absurd pose (a corrupt field) is refused where the scan is built -----------------
def test_a_pose_beyond_any_frame_is_refused_with_its_line(tmp_path):
    ok = flaser([1.0] * 180, 0.0)
    bad = ok.replace(" 0 0 0 0 0 0 ", " 0 0 0 1e300 0 0 ").replace(" 0.0 host 0.0", " 1.0 host 1.0")
    p = tmp_path / "absurd.log"
    p.write_text(ok + bad)
    with pytest.raises(ParseError, match=r"absurd\.log.*2.*odometry .*not a pose"):
        sc.read_scans(p, strict=True)
    assert len(sc.read_scans(p, strict=False)) == 1  # lenient: the line is skipped, warned
    with pytest.raises(ScanCliqueError, match="reference"):
        sc.Scan.from_ranges([1.0, 2.0], reference=Pose2(0.0, -2e9, 0.0))
    assert sc.Scan.from_ranges([1.0, 2.0], odometry=Pose2(5e6, 4e6, 0.0)).odometry.x == 5e6


# ---------------------------------------------------------------------------------------
# s14: a read-only place database left SQLite's -wal and -shm files behind
# ---------------------------------------------------------------------------------------
def _wall_scan(k: int) -> sc.Scan:
    return sc.Scan(np.full(10, 2.0 + 0.1 * k), np.linspace(-1.0, 1.0, 10), 0.0, 80.0)


def test_a_read_only_open_leaves_the_directory_as_it_found_it(tmp_path):
    path = tmp_path / "p.db"
    with PlaceDB(path) as db:
        db.add(_wall_scan(0), name="a")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["p.db"]
    with PlaceDB(path, readonly=True) as db:
        assert len(db) == 1
    assert sorted(p.name for p in tmp_path.iterdir()) == ["p.db"]
    with pytest.raises(PlaceDatabaseError, match="configuration differs"):
        PlaceDB(path, sc.paper_config(), readonly=True)  # a refused open, too
    assert sorted(p.name for p in tmp_path.iterdir()) == ["p.db"]


def test_a_read_only_open_keeps_what_a_writer_commits_meanwhile(tmp_path):
    path = tmp_path / "p.db"
    with PlaceDB(path) as db:
        db.add(_wall_scan(0), name="a")
    reader = PlaceDB(path, readonly=True)
    with PlaceDB(path) as writer:  # closes while the reader is open: its WAL stays
        writer.add(_wall_scan(1), name="b")
        with PlaceDB(path, readonly=True) as other:  # found the files: leaves them
            assert len(other) == 2
    assert (tmp_path / "p.db-wal").exists()
    reader.close()  # the last one: the writer's place goes into the file, the WAL away
    assert sorted(p.name for p in tmp_path.iterdir()) == ["p.db"]
    with PlaceDB(path, readonly=True) as db:
        assert sorted(db.store.names(db.ids).values()) == ["a", "b"]


# ---------------------------------------------------------------------------------------
# s14: a truncated bzip2 log was counted under "truncated gzip"
# ---------------------------------------------------------------------------------------
@pytest.mark.parametrize(
    "pack, key", [(gzip.compress, "truncated gzip"), (bz2.compress, "truncated bzip2")]
)
def test_a_truncated_stream_is_counted_under_its_format(tmp_path, pack, key):
    p = tmp_path / "t.log.z"
    p.write_bytes(pack(carmen_text(40))[:-30])
    log = read_carmen(p, strict=False)  # the last line, cut, is malformed too
    keys = {k for k in log.skipped if k.startswith("truncated")}
    assert keys == {key} and log.skipped[key] == 1 and len(log.scans) < 40


# ---------------------------------------------------------------------------------------
# s14: float("1_0") and int("1_0") are 10 (PEP 515): a field "1_0" was read as 10
# ---------------------------------------------------------------------------------------
_OK = flaser([1.0] * 4, 1.0)


@pytest.mark.parametrize(
    "line, field",
    [
        (_OK.replace("FLASER 4 1.0 1.0 1.0", "FLASER 4 1.0 1.0 1_0"), r"range\[2\]"),
        (_OK.replace("FLASER 4", "FLASER 0_4"), "num_readings"),
        (_OK.replace(" 0 0 0 0 0 0 ", " 0 0 0 1_0 0 0 "), "odom_x"),
        (_OK.replace("1.0 host 1.0", "1_0.5 host 1.0"), "ipc_timestamp"),
        ("ODOM 0 0 0 0 0 0 1_0 host 1.0\n", "timestamp"),
        ("ROBOTLASER1 0 -1.5 3 1.5 80 0.1 0 2 1.0 1_0 0 0 0 0 0 0 0 0 0 0 0 0 1 h 1\n", "range"),
    ],
    ids=["range", "count", "odometry", "timestamp", "ODOM", "ROBOTLASER1"],
)
def test_an_underscore_in_a_carmen_number_is_refused(tmp_path, line, field):
    p = tmp_path / "u.log"
    p.write_text(_OK + line)
    with pytest.raises(ParseError, match=rf"u\.log:2: {field}.*'[0-9._]*_[0-9._]*'"):
        sc.read_scans(p)
    assert len(sc.read_scans(p, strict=False)) == 1  # lenient: the line is skipped


def test_underscores_outside_the_numbers_of_a_carmen_line_are_kept(tmp_path):
    p = tmp_path / "host.log"
    p.write_text("PARAM robot_front_laser_max 81.9 0.0 my_host 0.0\n" + _OK.replace("host", "a_b"))
    assert sc.read_scans(p)[0].ranges.tolist() == [1.0] * 4


def test_an_underscore_in_a_scan_text_or_dimacs_number_is_refused(tmp_path):
    from scanclique.io.dimacs import read_dimacs

    p = tmp_path / "u.txt"
    p.write_text("SCAN 1.0 -1.0 0.5 0.0 80.0 3 1.0 2_0 3.0\n")
    with pytest.raises(ParseError, match=r"u\.txt:1: range\[1\].*'2_0'"):
        sc.read_scans(p)
    p.write_text("SCAN 1.0 -1.0 0.5 0.0 80.0 1_0 1.0 2.0 3.0\n")
    with pytest.raises(ParseError, match=r"u\.txt:1: n.*'1_0'"):
        sc.read_scans(p)
    for text, field in (("p edge 1_0 0\n", "N"), ("p edge 3 1\ne 1 1_0\n", "v")):
        (tmp_path / "u.clq").write_text(text)
        with pytest.raises(ParseError, match=rf"u\.clq:\d: {field}.*'1_0'"):
            read_dimacs(tmp_path / "u.clq")
    (tmp_path / "u.clq").write_text("p edge 3 1\nn 2 1_5\n")
    with pytest.raises(ParseError, match=r"u\.clq:2: w.*'1_5'"):
        read_dimacs(tmp_path / "u.clq")


# ---------------------------------------------------------------------------------------
# s14: places add --start beyond the log said "added 0 places"
# ---------------------------------------------------------------------------------------
def test_places_add_with_a_start_beyond_the_log_is_an_error(tmp_path, drive_log):
    db = tmp_path / "p.db"
    r = invoke("places", "add", db, drive_log, "--start", 12)
    assert_clean_error(r, "--start 12", "12 scans")
    assert not db.exists()  # refused before the database is created
    for stop in (5, 3):  # nothing between --start and --stop: said, not "added 0 places"
        r = invoke("places", "add", db, drive_log, "--start", 5, "--stop", stop)
        assert_clean_error(r, f"--stop {stop}", "--start 5")
        assert not db.exists()
    r = invoke("places", "add", db, drive_log, "--start", 11, "--json")
    assert r.exit_code == 0 and '"added": 1' in r.stdout, r.output


# ---------------------------------------------------------------------------------------
# s14: loops --out replaced an existing file without a word (map and slam --out say so)
# ---------------------------------------------------------------------------------------
def test_loops_says_it_replaces_an_existing_out_file(tmp_path, drive_log):
    out = tmp_path / "loops.json"
    out.write_text("an earlier run\n")
    r = invoke("loops", drive_log, "--min-gap", 11, "--candidates", 1, "--out", out)
    assert r.exit_code == 0, r.output
    assert "note:" in r.stderr and f"{out} exists" in r.stderr.replace("\n", "")
    assert out.read_text().startswith("{")


def test_loops_refuses_to_write_over_its_input_log(tmp_path, drive_log):
    """`loops LOG --out LOG` would replace the log with the pairs: refused before the
    search, the log intact (also through another path to the same file)."""
    before = Path(drive_log).read_bytes()
    link = tmp_path / "same-log.txt"
    link.symlink_to(drive_log)
    for out in (drive_log, link):
        r = invoke("loops", drive_log, "--min-gap", 11, "--candidates", 1, "--out", out)
        assert_clean_error(r, "is the input log", "overwritten")
    assert Path(drive_log).read_bytes() == before


def test_an_underscore_in_a_victoria_park_or_relations_number_is_refused(tmp_path):
    """`1_0` (which float() reads as 10) in a Victoria Park table or a relations file is
    a ParseError naming the file, line and field, like `abc`."""
    from scanclique.eval import read_relations

    d = _vp(tmp_path / "vp", "0.5 10.0 1.0 0.3\n0.7 1_0.0 1.0 0.3\n")
    with pytest.raises(ParseError, match="1_0.0") as ei:
        slam.read_victoria_park(d)
    assert ei.value.path.endswith("measurements.dat") and ei.value.line == 2
    assert_clean_error(invoke("slam", d), "measurements.dat", "1_0.0")
    rel = tmp_path / "r.relations"
    rel.write_text("1.0 2.0 0.5 0.0 0 0 0 0.1\n1.0 2.0 0.5 0.0 0 0 0 1_0\n")
    with pytest.raises(ParseError, match="1_0") as ei:
        read_relations(rel)
    assert ei.value.line == 2


@pytest.mark.parametrize(
    "digits",
    ["\u0661\u0660", "\uff11\uff10", "1\u00b2"],
    ids=["arabic", "fullwidth", "superscript"],
)
def test_a_non_ascii_digit_in_a_number_is_refused(tmp_path, digits):
    """float() and NumPy read Unicode digits ('١٠' is 10): no log means them. A number
    field holding one is a ParseError naming the field, like 'abc', in every reader; text
    that is not a number (a host name) may hold any character."""
    from scanclique.eval import read_relations
    from scanclique.io.dimacs import read_dimacs

    p = tmp_path / "u.log"
    p.write_text(_OK + _OK.replace("FLASER 4 1.0 1.0 1.0", f"FLASER 4 1.0 1.0 {digits}"))
    with pytest.raises(ParseError, match=r"u\.log:2: range\[2\]"):
        sc.read_scans(p)
    p.write_text(_OK + f"ODOM 0 0 0 0 0 0 {digits} host 1.0\n")
    with pytest.raises(ParseError, match=r"u\.log:2: timestamp"):
        sc.read_scans(p)
    t = tmp_path / "u.txt"
    t.write_text(f"SCAN 1.0 -1.0 0.5 0.0 80.0 3 1.0 {digits} 3.0\n")
    with pytest.raises(ParseError, match=r"u\.txt:1: range\[1\]"):
        sc.read_scans(t)
    (tmp_path / "u.clq").write_text(f"p edge 3 1\ne 1 {digits}\n")
    with pytest.raises(ParseError, match="v"):
        read_dimacs(tmp_path / "u.clq")
    d = _vp(tmp_path / "vp", f"0.5 10.0 1.0 0.3\n0.7 {digits} 1.0 0.3\n")
    with pytest.raises(ParseError) as ei:
        slam.read_victoria_park(d)
    assert ei.value.line == 2
    rel = tmp_path / "r.relations"
    rel.write_text(f"1.0 2.0 0.5 0.0 0 0 0 {digits}\n")
    with pytest.raises(ParseError) as ei:
        read_relations(rel)
    assert ei.value.line == 1


def test_a_non_ascii_host_name_in_a_carmen_line_is_kept(tmp_path):
    p = tmp_path / "host.log"
    p.write_text(_OK.replace("host", "h\u00f6st-\u0661"), encoding="utf-8")
    assert sc.read_scans(p)[0].ranges.tolist() == [1.0] * 4


def test_a_scan_without_features_says_what_it_lacks():
    """The match of a scan with no features says why: no beams, no valid return, or every
    beam beyond range_max (ranges in millimetres: before, only "has no features")."""
    from scanclique.sim import simulate_pair

    p = simulate_pair(np.random.default_rng(0))
    mm = sc.Scan.from_ranges(p.scan_a.ranges * 1000.0, angle_min=-math.pi / 2, fov=math.pi)
    r = sc.match_scans(mm, p.scan_b)
    assert r.pose is None
    assert r.reason == (
        "scan A has no features: none of its 361 beams returns below range_max (80 m); "
        "are its ranges in metres?"
    )
    nan = sc.Scan.from_ranges(np.full(10, np.nan), angle_min=0.0, fov=1.0)
    assert sc.match_scans(p.scan_a, nan).reason.endswith(
        "none of its 10 beams is a valid return (0 at or beyond range_max)"
    )
    assert (
        sc.match_scans(p.scan_a, sc.Scan([], [])).reason
        == "scan B has no features: it has no beams"
    )
