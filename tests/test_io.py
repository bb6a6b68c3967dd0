"""Readers and writers: CARMEN logs, the scan text format, .npz archives, dispatch."""

from __future__ import annotations

import gzip
import logging
import math

import numpy as np
import pytest
from conftest import require_log
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from scanclique import Pose2, Scan
from scanclique.errors import ArgumentError, DataNotFoundError, ParseError
from scanclique.io import (
    FLASER_MAX_RANGE,
    detect_format,
    flaser_angles,
    interpolate_odometry,
    is_gzip,
    read_carmen,
    read_scans,
    read_scans_npz,
    read_scans_text,
    write_scans_npz,
    write_scans_text,
)

# ---------------------------------------------------------------------------------------
# Helpers: build CARMEN lines
# ---------------------------------------------------------------------------------------


def flaser(ranges, ref=(1.0, 2.0, 0.5), odom=(1.5, 2.5, 0.25), t=100.0, kind="FLASER"):
    r = " ".join(str(x) for x in ranges)
    pose = " ".join(str(v) for v in (*ref, *odom))
    return f"{kind} {len(ranges)} {r} {pose} {t} nohost {t}"


def robotlaser(ranges, start=-1.0, fov=2.0, res=0.5, max_range=20.0, remissions=(7, 8),
               laser=(1.0, 2.0, 0.3), robot=(0.9, 2.0, 0.3), t=5.0, k=1):  # fmt: skip
    r = " ".join(str(x) for x in ranges)
    rem = " ".join(str(x) for x in remissions)
    tail = " ".join(str(v) for v in (*laser, *robot, 0.1, 0.2, 0.3, 0.4, 0.5))
    return (
        f"ROBOTLASER{k} 0 {start} {fov} {res} {max_range} 0.01 0 {len(ranges)} {r} "
        f"{len(remissions)} {rem} {tail} {t} host {t}"
    )


def rawlaser(ranges, t, k=1, start=-0.5, res=0.25, max_range=30.0):
    r = " ".join(str(x) for x in ranges)
    return f"RAWLASER{k} 0 {start} 1.0 {res} {max_range} 0.01 0 {len(ranges)} {r} 0 {t} host {t}"


def odom(x, y, theta, t):
    return f"ODOM {x} {y} {theta} 0 0 0 {t} host {t}"


def write(tmp_path, name, *lines, compress=False):
    text = "".join(line + "\n" for line in lines).encode()
    path = tmp_path / name
    path.write_bytes(gzip.compress(text) if compress else text)
    return path


def same_scan(a: Scan, b: Scan, source=True) -> None:
    np.testing.assert_array_equal(a.ranges, b.ranges)
    np.testing.assert_array_equal(a.angles, b.angles)
    assert a.ranges.tobytes() == b.ranges.tobytes() or np.isnan(a.ranges).any()
    assert a.angles.tobytes() == b.angles.tobytes()
    assert (a.range_min, a.range_max, a.timestamp) == (b.range_min, b.range_max, b.timestamp)
    for name in ("odometry", "reference"):
        pa, pb = getattr(a, name), getattr(b, name)
        assert (pa is None) == (pb is None)
        if pa is not None:
            assert (pa.x, pa.y, pa.theta) == (pb.x, pb.y, pb.theta)
    if source:
        assert a.source == b.source


# ---------------------------------------------------------------------------------------
# CARMEN: messages
# ---------------------------------------------------------------------------------------


def test_flaser_fields(tmp_path):
    path = write(tmp_path, "a.log", "# header", "", flaser([1.0, 2.0, 81.83, 3.0], t=12.5))
    (scan,) = read_scans(path)
    assert scan.ranges.tolist() == [1.0, 2.0, 81.83, 3.0]
    assert scan.valid.tolist() == [True, True, False, True]
    assert scan.range_max == FLASER_MAX_RANGE == 80.0
    assert scan.reference == Pose2(1.0, 2.0, 0.5)
    assert scan.odometry == Pose2(1.5, 2.5, 0.25)
    assert scan.timestamp == 12.5
    assert scan.source == "a.log:3"


@pytest.mark.parametrize(
    ("n", "step_deg", "last_deg"),
    [(180, 1.0, 89.0), (181, 1.0, 90.0), (360, 0.5, 89.5), (361, 0.5, 90.0)],
)
def test_flaser_beam_angle_convention(tmp_path, n, step_deg, last_deg):
    path = write(tmp_path, "a.log", flaser([1.0] * n))
    (scan,) = read_scans(path)
    deg = np.degrees(scan.angles)
    assert deg[0] == pytest.approx(-90.0)
    np.testing.assert_allclose(np.diff(deg), step_deg)
    assert deg[-1] == pytest.approx(last_deg)
    np.testing.assert_array_equal(scan.angles, flaser_angles(n))


def test_rlaser_kept_in_sensor_frame(tmp_path):
    path = write(tmp_path, "a.log", flaser([1.0] * 181), flaser([2.0] * 181, kind="RLASER"))
    log = read_carmen(path)
    assert log.message_types == ("FLASER", "RLASER")
    np.testing.assert_array_equal(log.scans[1].angles, log.scans[0].angles)


def _two_lasers(tmp_path):
    """A front and a rear laser interleaved, and a third laser type once (RAWLASER2)."""
    lines = []
    for i in range(3):
        lines += [
            flaser([1.0 + i] * 181, t=10.0 + i),
            flaser([5.0] * 181, t=10.5 + i, kind="RLASER"),
        ]
    return write(tmp_path, "two.log", *lines, rawlaser([3.0] * 5, t=20.0, k=2))


def test_a_log_of_several_lasers_is_read_one_laser_at_a_time(tmp_path, caplog):
    path = _two_lasers(tmp_path)
    with caplog.at_level(logging.WARNING, logger="scanclique"):
        every = read_scans(path)  # the contract: one scan per laser message, in file order
    assert len(every) == 7
    assert "holds 3 FLASER and 1 RAWLASER2 and 3 RLASER scans, interleaved" in caplog.text
    caplog.clear()
    with caplog.at_level(logging.WARNING, logger="scanclique"):
        main = read_scans(path, laser="main")
    assert [s.ranges[0] for s in main] == [1.0, 2.0, 3.0]
    assert [s.source for s in main] == ["two.log:1", "two.log:3", "two.log:5"]
    assert "using the 3 FLASER scans (--laser RAWLASER2 or RLASER for the others)" in caplog.text
    rear = read_scans(path, laser="RLASER")
    assert [s.timestamp for s in rear] == [10.5, 11.5, 12.5]
    assert len(read_scans(path, laser="RAWLASER2")) == 1
    with pytest.raises(ArgumentError, match="two.log holds no ROBOTLASER1 scans"):
        read_scans(path, laser="ROBOTLASER1")
    with pytest.raises(ArgumentError, match="laser must be 'main' or"):
        read_scans(path, laser="rear")


def test_a_log_of_one_laser_is_read_whole_and_quietly(tmp_path, caplog):
    path = write(tmp_path, "a.log", flaser([1.0] * 181), flaser([2.0] * 181, t=101.0))
    with caplog.at_level(logging.WARNING, logger="scanclique"):
        assert len(read_scans(path, laser="main")) == len(read_scans(path)) == 2
    assert caplog.text == ""
    assert read_scans(write(tmp_path, "empty.log", "# nothing"), laser="RLASER") == []


def test_the_map_reads_the_main_laser(tmp_path):
    from scanclique.errors import ScanCliqueError
    from scanclique.mapping.run import load_map_log

    path = _two_lasers(tmp_path)
    scans, label = load_map_log(path)
    assert label == "two.log" and [s.ranges[0] for s in scans] == [1.0, 2.0, 3.0]
    assert [s.ranges[0] for s in load_map_log(path, laser="RLASER")[0]] == [5.0] * 3
    with pytest.raises(ScanCliqueError, match="--topic applies to ROS bags only"):
        load_map_log(path, topic="/scan")


def test_max_range_option(tmp_path):
    path = write(tmp_path, "a.log", flaser([1.0, 49.9, 50.0, 60.0]))
    (scan,) = read_scans(path, max_range=50.0)
    assert scan.valid.tolist() == [True, True, False, False]


def test_robotlaser1(tmp_path):
    path = write(tmp_path, "a.log", robotlaser([1.0, 25.0, 3.0], t=7.25))
    log = read_carmen(path)
    (scan,) = log.scans
    np.testing.assert_allclose(scan.angles, [-1.0, -0.5, 0.0])
    assert scan.range_max == 20.0
    assert scan.valid.tolist() == [True, False, True]
    assert scan.odometry == Pose2(1.0, 2.0, 0.3)  # the laser pose
    assert scan.reference is None
    assert scan.timestamp == 7.25
    assert log.message_types == ("ROBOTLASER1",)


def test_robotlaser1_nonpositive_max_range_falls_back(tmp_path):
    path = write(tmp_path, "a.log", robotlaser([1.0, 85.0], max_range=0))
    (scan,) = read_scans(path)
    assert scan.range_max == FLASER_MAX_RANGE
    assert scan.valid.tolist() == [True, False]


def test_rawlaser_odometry_interpolated_from_odom(tmp_path):
    path = write(
        tmp_path,
        "a.log",
        odom(0.0, 0.0, 3.0, t=10.0),
        rawlaser([1.0, 2.0], t=9.0),  # before the first ODOM
        rawlaser([1.0, 2.0], t=11.0, k=2),  # halfway
        odom(2.0, 4.0, -3.0, t=12.0),
        rawlaser([1.0, 2.0], t=12.0, k=3),  # exactly on an ODOM
        rawlaser([1.0, 2.0], t=13.0, k=4),  # after the last ODOM
    )
    log = read_carmen(path)
    assert [s.odometry is None for s in log.scans] == [True, False, False, True]
    mid = log.scans[1].odometry
    assert (mid.x, mid.y) == pytest.approx((1.0, 2.0))
    assert abs(mid.theta) == pytest.approx(math.pi)  # across the +-pi seam, not through 0
    assert log.scans[2].odometry == Pose2(2.0, 4.0, -3.0)
    assert all(s.reference is None for s in log.scans)
    np.testing.assert_allclose(log.scans[0].angles, [-0.5, -0.25])
    assert log.scans[0].range_max == 30.0
    assert log.odom.shape == (2, 4)
    assert log.message_types == ("RAWLASER1", "RAWLASER2", "RAWLASER3", "RAWLASER4")


def test_robotlaser2_is_the_rear_laser_in_the_robotlaser_layout(tmp_path):
    path = write(
        tmp_path,
        "a.log",
        robotlaser([1.0, 2.0], t=5.0),
        robotlaser([3.0, 4.0], t=5.1, k=2, laser=(0.7, 2.0, 3.44)),
    )
    log = read_carmen(path)
    assert log.message_types == ("ROBOTLASER1", "ROBOTLASER2")
    assert log.scans[1].odometry == Pose2(0.7, 2.0, 3.44)  # the rear laser's pose
    np.testing.assert_allclose(log.scans[1].angles, [-1.0, -0.5])
    assert [s.ranges[0] for s in read_scans(path, laser="main")] == [1.0]
    assert [s.ranges[0] for s in read_scans(path, laser="ROBOTLASER2")] == [3.0]


def test_laser3_and_laser4_as_carmen_writes_them_take_the_odom(tmp_path):
    """CARMEN's logger writes LASER3/LASER4 without a pose (``n r.. t host t``)."""
    path = write(
        tmp_path,
        "a.log",
        odom(0.0, 0.0, 0.0, t=10.0),
        "LASER3 4 1.0 2.0 81.9 3.0 11.0 host 11.0",
        odom(2.0, 4.0, 0.5, t=12.0),
        "LASER4 2 5.0 6.0 13.0 host 13.0",  # after the last ODOM
    )
    log = read_carmen(path)
    assert log.message_types == ("LASER3", "LASER4")
    a, b = log.scans
    np.testing.assert_array_equal(a.angles, flaser_angles(4))
    assert a.valid.tolist() == [True, True, False, True]  # 81.9 m: no return, as FLASER
    assert (a.odometry.x, a.odometry.y, a.odometry.theta) == pytest.approx((1.0, 2.0, 0.25))
    assert a.reference is None and a.timestamp == 11.0
    assert b.odometry is None and b.ranges.tolist() == [5.0, 6.0]


def test_laser3_in_the_flaser_layout_is_read_as_flaser(tmp_path):
    """Some converters write LASER3/LASER4 with FLASER's six pose fields."""
    line = flaser([1.0, 2.0, 3.0], kind="LASER3")
    (scan,) = read_carmen(write(tmp_path, "a.log", line)).scans
    (twin,) = read_carmen(write(tmp_path, "b.log", flaser([1.0, 2.0, 3.0]))).scans
    same_scan(scan, twin, source=False)
    assert scan.reference == Pose2(1.0, 2.0, 0.5)


@pytest.mark.parametrize(
    ("line", "match"),
    [
        ("LASER3", "a.log:1: num_readings: LASER3 expects a beam count"),
        ("LASER4 3 1.0 2.0 9.0 host", "LASER4 with 3 ranges expects 8 fields .or 14 in the"),
        ("LASER3 2 1.0 abc 9.0 host 9.0", "range.1.: LASER3 expects a number, found 'abc'"),
        ("LASER3 2 1.0 2.0 nan host 9.0", "ipc_timestamp: LASER3 expects a finite timestamp"),
        ("ROBOTLASER2 0 -1 2 0.5 20 0.01 0 2 1.0", "ROBOTLASER2 expects 2 ranges and a"),
    ],
)
def test_errors_of_the_other_laser_messages_name_line_and_field(tmp_path, line, match):
    with pytest.raises(ParseError, match=match):
        read_carmen(write(tmp_path, "a.log", line))


def test_interpolate_odometry_unsorted_and_duplicates():
    o = np.array([[2.0, 2.0, 0.0, 0.0], [0.0, 0.0, 0.0, 0.0], [2.0, 4.0, 0.0, 0.0]])
    assert interpolate_odometry(o, 1.0).x == pytest.approx(1.0)
    assert interpolate_odometry(o, 2.0).x == 4.0  # the last logged at that time
    assert interpolate_odometry(np.zeros((0, 4)), 1.0) is None


def test_param_comments_unknown_types(tmp_path):
    path = write(
        tmp_path,
        "a.log",
        "# message formats defined: PARAM FLASER",
        "PARAM robot_front_laser_max 80.99 1.0 host 1.0",
        "PARAM laser_front_laser_resolution 0.5 1.0 host 1.0",
        "PARAM robot_front_laser_max 81.5 2.0 host 2.0",
        "NEFF 10",
        "SYNC a b c",
        "NEFF 12",
        "   ",
        flaser([1.0, 2.0]),
    )
    log = read_carmen(path)
    assert len(log.scans) == 1
    assert dict(log.params) == {
        "robot_front_laser_max": "81.5",
        "laser_front_laser_resolution": "0.5",
    }
    assert dict(log.skipped) == {"unknown:NEFF": 2, "unknown:SYNC": 1}
    assert log.n_skipped == 3
    with pytest.raises(TypeError):
        log.params["x"] = "y"  # read-only


def test_gzip_detected_by_magic_not_suffix(tmp_path):
    lines = [flaser([1.0, 2.0, 3.0]), flaser([4.0, 5.0, 6.0], t=101.0)]
    plain = write(tmp_path, "plain.log", *lines)
    gz = write(tmp_path, "packed.log", *lines, compress=True)  # gzip without .gz suffix
    fake = write(tmp_path, "fake.log.gz", *lines)  # .gz suffix, plain text
    assert is_gzip(gz) and not is_gzip(plain) and not is_gzip(fake)
    ref = read_scans(plain)
    for other in (gz, fake):
        got = read_scans(other)
        assert len(got) == 2
        for a, b in zip(ref, got, strict=True):
            same_scan(a, b, source=False)


def test_crlf_line_ends(tmp_path):
    path = tmp_path / "dos.log"
    path.write_bytes(f"# c\r\n{flaser([1.0, 2.0])}\r\nPARAM a b 1 h 1\r\n".encode())
    log = read_carmen(str(path))
    assert log.scans[0].source == "dos.log:2" and dict(log.params) == {"a": "b"}


def test_multi_member_gzip(tmp_path):
    path = tmp_path / "two.log.gz"
    path.write_bytes(
        gzip.compress(f"{flaser([1.0])}\n".encode()) + gzip.compress(f"{flaser([2.0])}\n".encode())
    )
    assert [s.ranges[0] for s in read_scans(path)] == [1.0, 2.0]


def test_empty_file(tmp_path):
    assert read_scans(write(tmp_path, "empty.log")) == []
    assert read_scans(write(tmp_path, "comments.log", "# only", "# comments")) == []
    log = read_carmen(write(tmp_path, "empty2.log.gz", compress=True))
    assert log.scans == () and log.odom.shape == (0, 4)


def test_nan_and_inf_ranges_are_kept_and_masked(tmp_path):
    (scan,) = read_scans(write(tmp_path, "a.log", flaser([1.0, "nan", "inf", 2.0])))
    assert np.isnan(scan.ranges[1]) and np.isinf(scan.ranges[2])
    assert scan.valid.tolist() == [True, False, False, True]


def test_missing_file_raises_data_not_found(tmp_path):
    with pytest.raises(DataNotFoundError, match="no such file"):
        read_scans(tmp_path / "nope.log")


# ---------------------------------------------------------------------------------------
# CARMEN: errors name file, line, field, expected and found
# ---------------------------------------------------------------------------------------


def _error(tmp_path, *lines, name="bad.log", compress=False, **kw) -> ParseError:
    path = write(tmp_path, name, *lines, compress=compress)
    with pytest.raises(ParseError) as info:
        read_carmen(path, **kw)
    assert info.value.path == str(path)
    return info.value


def test_error_wrong_range_count(tmp_path):
    line = flaser([1.0] * 180).replace("FLASER 180 1.0 ", "FLASER 180 ", 1)  # 179 ranges
    e = _error(tmp_path, "# c", line)
    assert str(e) == f"{tmp_path / 'bad.log'}:2: FLASER expects 180 ranges, found 179"
    assert e.line == 2


def test_error_non_numeric_range(tmp_path):
    ranges = [1.0] * 20
    ranges[17] = "abc"
    e = _error(tmp_path, flaser(ranges))
    assert (e.line, e.field) == (1, "range[17]")
    assert "expects a number, found 'abc'" in str(e)
    assert str(e).startswith(f"{tmp_path / 'bad.log'}:1: range[17]: FLASER")


def test_error_non_numeric_pose_field(tmp_path):
    e = _error(tmp_path, flaser([1.0, 2.0], odom=(1.0, "x?", 0.0)))
    assert e.field == "odom_y"


def test_error_truncated_line(tmp_path):
    e = _error(tmp_path, flaser([1.0] * 10), flaser([1.0] * 10)[:40])
    assert e.line == 2
    assert "expects 21 fields" in str(e) and "truncated" in str(e)


def test_error_truncated_before_count(tmp_path):
    e = _error(tmp_path, "FLASER")
    assert e.field == "num_readings"


@pytest.mark.parametrize(("pose", "field"), [((1.0, "nan", 0.0), "y"), (("inf", 0.0, 0.0), "x")])
def test_error_nonfinite_reference_pose(tmp_path, pose, field):
    e = _error(tmp_path, flaser([1.0, 2.0], ref=pose))
    assert e.field == field
    assert "finite pose" in str(e)


def test_error_nonfinite_odom_message(tmp_path):
    e = _error(tmp_path, odom(0.0, 0.0, "nan", 1.0))
    assert (e.line, e.field) == (1, "theta")


def test_error_nonfinite_timestamp(tmp_path):
    e = _error(tmp_path, flaser([1.0], t="inf"))
    assert e.field == "ipc_timestamp"


@pytest.mark.parametrize("count", ["10000000", "-3", "1.5", "lots"])
def test_error_absurd_or_bad_count(tmp_path, count):
    e = _error(tmp_path, f"FLASER {count} 1.0 2.0")
    assert e.field == "num_readings"
    if count == "10000000":
        assert "max_beams=100000" in str(e)


def test_max_beams_option(tmp_path):
    e = _error(tmp_path, flaser([1.0] * 10), max_beams=5)
    assert "max_beams=5" in str(e)


def test_error_binary_garbage(tmp_path):
    path = tmp_path / "garbage.log"
    path.write_bytes(flaser([1.0]).encode() + b"\n\xff\xfe\x00\x81garbage\x9c\n")
    with pytest.raises(ParseError) as info:
        read_scans(path)
    assert info.value.line == 2
    assert "binary" in str(info.value)


def test_error_nul_bytes(tmp_path):
    path = tmp_path / "nul.log"
    path.write_bytes(b"\x00\x01\x02\x03" * 10)
    with pytest.raises(ParseError, match="NUL byte"):
        read_carmen(path)


def test_error_truncated_gzip(tmp_path):
    data = gzip.compress("".join(flaser([1.0] * 50, t=i) + "\n" for i in range(50)).encode())
    path = tmp_path / "cut.log.gz"
    path.write_bytes(data[: len(data) // 2])
    with pytest.raises(ParseError) as info:
        read_scans(path)
    assert info.value.path == str(path) and info.value.line is None
    assert "truncated gzip" in str(info.value)


def test_error_corrupt_gzip(tmp_path):
    data = bytearray(gzip.compress(b"FLASER 1 1.0 0 0 0 0 0 0 1 h 1\n" * 100))
    data[20:30] = b"\xff" * 10
    path = tmp_path / "corrupt.log.gz"
    path.write_bytes(bytes(data))
    with pytest.raises(ParseError, match="corrupt.log.gz"):
        read_scans(path)


def test_error_robotlaser_field_count(tmp_path):
    e = _error(tmp_path, robotlaser([1.0, 2.0]) + " extra")
    assert "expects" in str(e) and e.line == 1


def test_error_robotlaser_bad_resolution(tmp_path):
    e = _error(tmp_path, robotlaser([1.0, 2.0], res=0.0))
    assert e.field == "angular_res"


# ---------------------------------------------------------------------------------------
# CARMEN: strict=False
# ---------------------------------------------------------------------------------------


def test_non_strict_skips_counts_and_warns(tmp_path, caplog):
    bad_count = flaser([1.0] * 5).replace("FLASER 5", "FLASER 6", 1)
    path = write(
        tmp_path,
        "a.log",
        flaser([1.0, 2.0]),
        bad_count,
        flaser([1.0, "abc"]),
        "NEFF 3",
        odom(1, 2, "x", 3),
        flaser([3.0, 4.0], t=101.0),
    )
    with pytest.raises(ParseError):
        read_carmen(path)
    with caplog.at_level(logging.WARNING, logger="scanclique.io"):
        log = read_carmen(path, strict=False)
    assert [s.source for s in log.scans] == ["a.log:1", "a.log:6"]
    assert dict(log.skipped) == {"malformed:FLASER": 2, "malformed:ODOM": 1, "unknown:NEFF": 1}
    warnings = [r.getMessage() for r in caplog.records if r.levelno == logging.WARNING]
    assert any("a.log:2" in m for m in warnings)
    assert any("skipped 2 lines (malformed:FLASER)" in m for m in warnings)


def test_non_strict_undecodable_lines(tmp_path):
    path = tmp_path / "a.log"
    path.write_bytes(f"{flaser([1.0])}\n\xff\xfe junk\n{flaser([2.0])}\n".encode("latin-1"))
    log = read_carmen(path, strict=False)
    assert len(log.scans) == 2 and log.skipped["undecodable"] == 1


def test_non_strict_truncated_gzip_keeps_what_was_read(tmp_path, caplog):
    data = gzip.compress("".join(flaser([1.0] * 50, t=i) + "\n" for i in range(200)).encode())
    path = tmp_path / "cut.log.gz"
    path.write_bytes(data[: len(data) // 2])
    with caplog.at_level(logging.WARNING, logger="scanclique.io"):
        log = read_carmen(path, strict=False)
    assert 0 < len(log.scans) < 200
    assert log.skipped["truncated gzip"] == 1
    assert any("truncated gzip" in r.getMessage() for r in caplog.records)


# ---------------------------------------------------------------------------------------
# The scan text format
# ---------------------------------------------------------------------------------------


def test_text_format_example(tmp_path):
    path = write(
        tmp_path,
        "a.scan",
        "# comment",
        "SCAN 1.5 -1.0 0.5 0.1 10.0 3 1.0 nan 20.0 ODOM 1 2 0.5",
        "",
        "SCAN - 0.0 0.1 0.0 80.0 2 1.0 2.0 REF 3 4 -0.5 ANGLES 0.0 0.3",
    )
    a, b = read_scans(path)
    np.testing.assert_allclose(a.angles, [-1.0, -0.5, 0.0])
    assert a.valid.tolist() == [True, False, False]
    assert (a.timestamp, a.odometry, a.reference) == (1.5, Pose2(1, 2, 0.5), None)
    assert (b.timestamp, b.odometry, b.reference) == (None, None, Pose2(3, 4, -0.5))
    assert b.angles.tolist() == [0.0, 0.3]
    assert (a.source, b.source) == ("a.scan:2", "a.scan:4")


@pytest.mark.parametrize(
    ("line", "field", "text"),
    [
        ("SCAN 1 0 0.1 0 10 3 1 2", None, "expects 3 ranges, found 2"),
        ("SCAN 1 0 0.1 0 10 3 1 x 2", "range[1]", "found 'x'"),
        ("SCAN 1 0 0.1 0 10 2 1 2 ODOM 1 2", "ODOM", "expects 3 values"),
        ("SCAN 1 0 0.1 0 10 2 1 2 WHAT 1 2 3", None, "found 'WHAT'"),
        ("SCAN 1 0 0.1 0 10 2 1 2 REF 1 nan 0", "REF", "finite pose"),
        ("SCAN 1 0 0.1", None, "truncated"),
        ("SCAN 1 0 -0.1 0 10 2 1 2", None, "strictly increasing"),
        # a field of view in degrees: -90 to 90 "rad" (increment 1 "rad", 181 beams)
        ("SCAN 1 -90 1 0 10 181 " + " ".join(["1"] * 181), None, "span 180 rad"),
    ],
)
def test_text_format_errors(tmp_path, line, field, text):
    path = write(tmp_path, "bad.scan", "# header", line)
    with pytest.raises(ParseError) as info:
        read_scans_text(path)
    assert info.value.line == 2 and info.value.field == field
    assert text in str(info.value)


def test_text_non_strict(tmp_path):
    path = write(tmp_path, "a.scan", "SCAN - 0 0.1 0 10 1 1.0", "SCAN - 0 0.1 0 10 2 1.0", "junk")
    assert len(read_scans(path, strict=False)) == 1


finite = st.floats(-1e6, 1e6, allow_nan=False)
range_value = st.one_of(
    st.floats(0.0, 100.0), st.sampled_from([math.nan, math.inf, -math.inf, 81.83, 0.0])
)


@st.composite
def scans(draw, n=None):
    """Arbitrary valid scans: odd ranges, regular or irregular angles, optional poses."""
    if n is None:
        n = draw(st.integers(0, 12))
    ranges = draw(st.lists(range_value, min_size=n, max_size=n))
    if draw(st.booleans()):
        angles = -math.pi / 2 + draw(st.floats(1e-4, 0.1)) * np.arange(n)
    else:
        steps = draw(st.lists(st.floats(1e-3, 1.0), min_size=n, max_size=n))
        angles = draw(st.floats(-4, 4)) + np.cumsum(steps)
    rmin = draw(st.floats(0.0, 1.0))
    rmax = draw(st.one_of(st.floats(rmin + 0.01, 1e3), st.just(math.inf)))
    pose = st.one_of(st.none(), st.builds(Pose2, finite, finite, st.floats(-10, 10)))
    t = draw(st.one_of(st.none(), st.floats(-1e10, 1e10)))
    return Scan(
        ranges, angles, rmin, rmax, t, draw(pose), draw(pose), draw(st.sampled_from(["", "x:1"]))
    )


@settings(
    max_examples=60, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)
@given(batch=st.lists(scans(), max_size=4))
def test_text_round_trip(tmp_path, batch):
    path = tmp_path / "rt.scan"
    write_scans_text(path, batch)
    back = read_scans_text(path)
    assert len(back) == len(batch)
    for a, b in zip(batch, back, strict=True):
        same_scan(a, b, source=False)


def test_text_round_trip_gzip(tmp_path):
    batch = [Scan.from_ranges(np.linspace(0.5, 3, 361), timestamp=1.0, odometry=Pose2(1, 2, 3))]
    path = tmp_path / "rt.scan.gz"
    write_scans_text(path, batch)
    assert is_gzip(path)
    same_scan(batch[0], read_scans(path)[0], source=False)


# ---------------------------------------------------------------------------------------
# .npz
# ---------------------------------------------------------------------------------------


@settings(
    max_examples=60, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)
@given(data=st.data())
def test_npz_round_trip(tmp_path, data):
    n = data.draw(st.one_of(st.none(), st.integers(0, 12)))  # int: the (S, N) layout
    batch = data.draw(st.lists(scans(n=n), max_size=4))
    path = tmp_path / "rt.npz"
    write_scans_npz(path, batch)
    back = read_scans_npz(path)
    assert len(back) == len(batch)
    for a, b in zip(batch, back, strict=True):
        same_scan(a, b)


def test_npz_layouts(tmp_path):
    same = [Scan.from_ranges([1.0, 2.0, 3.0], timestamp=float(i)) for i in range(3)]
    ragged = [*same, Scan.from_ranges([1.0])]
    for name, batch in (("same.npz", same), ("ragged.npz", ragged)):
        write_scans_npz(tmp_path / name, batch)
    with np.load(tmp_path / "same.npz") as z:
        assert z["ranges"].shape == (3, 3) and "offsets" not in z.files
    with np.load(tmp_path / "ragged.npz") as z:
        assert z["ranges"].shape == (10,) and z["offsets"].tolist() == [0, 3, 6, 9, 10]
    for a, b in zip(ragged, read_scans(tmp_path / "ragged.npz"), strict=True):
        same_scan(a, b)


def test_npz_minimal_foreign_file(tmp_path):
    path = tmp_path / "foreign.npz"
    np.savez(path, ranges=np.ones((2, 4)), angles=np.linspace(-1, 1, 4))
    a, b = read_scans(path)
    assert (a.range_max, a.timestamp, a.odometry, b.source) == (80.0, None, None, "foreign.npz[1]")


def test_npz_never_unpickles(tmp_path):
    path = tmp_path / "evil.npz"
    np.savez(path, ranges=np.array([[1.0]]), angles=np.array([object()], dtype=object))
    with pytest.raises(ParseError, match="unpickling"):
        read_scans(path)


@pytest.mark.parametrize(
    ("arrays", "field"),
    [
        ({"angles": np.zeros((1, 2))}, "ranges"),
        ({"ranges": np.ones((1, 2)), "angles": np.zeros((1, 3))}, "angles"),
        (
            {"ranges": np.ones((1, 2)), "angles": [[0, 1]], "odometry": [[1, np.nan, 0]]},
            "odometry[0]",
        ),
        ({"ranges": np.ones(3), "angles": [0, 1, 2], "offsets": [0, 2]}, "offsets"),
        ({"ranges": np.ones((1, 2)), "angles": [[1, 0]]}, "scan[0]"),
    ],
)
def test_npz_errors_name_the_array(tmp_path, arrays, field):
    path = tmp_path / "bad.npz"
    np.savez(path, **{k: np.asarray(v) for k, v in arrays.items()})
    with pytest.raises(ParseError) as info:
        read_scans_npz(path)
    assert info.value.field == field


def test_npz_not_an_archive(tmp_path):
    path = tmp_path / "text.npz"
    path.write_text("hello")
    with pytest.raises(ParseError, match="text.npz"):
        read_scans(path)


# ---------------------------------------------------------------------------------------
# Dispatch
# ---------------------------------------------------------------------------------------


def test_detect_format(tmp_path):
    scan = Scan.from_ranges([1.0, 2.0])
    write_scans_text(tmp_path / "a.dat", [scan])  # content says SCAN
    write_scans_npz(tmp_path / "noext", [scan])  # zip magic, no suffix
    write(tmp_path, "b.txt")  # empty .txt: our text format by suffix
    write(tmp_path, "c.log", flaser([1.0]), compress=True)
    write(tmp_path, "d.txt", "# carmen in a .txt", flaser([1.0]))
    got = {p: detect_format(tmp_path / p) for p in ("a.dat", "noext", "b.txt", "c.log", "d.txt")}
    assert got == {
        "a.dat": "text",
        "noext": "npz",
        "b.txt": "text",
        "c.log": "carmen",
        "d.txt": "carmen",
    }
    assert len(read_scans(tmp_path / "noext")) == 1
    assert len(read_scans(tmp_path / "a.dat")) == 1
    assert len(read_scans(tmp_path / "d.txt")) == 1


# ---------------------------------------------------------------------------------------
# Real data (the shared CARMEN logs)
# ---------------------------------------------------------------------------------------

REAL = {
    # name: (scans, beams, first ranges, reference, odometry, timestamp, no-return value)
    "intel": (
        910, 180, [1.09, 1.08, 1.08], (0.600266, -0.032033, -0.354665),
        (0.698, -0.015, -0.463373), 976052890.244111, 81.83,
    ),
    "csail": (
        406, 361, [81.91, 81.91, 81.91], (0.154, 0.068, 0.562729),
        (576.48068, -0.103068, -1.487635), 1134864642.914187, 81.91,
    ),
    "freiburg": (
        4791, 360, [1.65, 1.66, 1.63], (0.00123601, -0.00106807, 2.85e-05),
        (0.00123601, -0.00106807, 2.85e-05), 0.227623, 81.91,
    ),
}  # fmt: skip


@pytest.fixture(scope="module")
def real_logs():
    cache = {}

    def get(name):
        if name not in cache:
            cache[name] = read_carmen(require_log(name))
        return cache[name]

    return get


@pytest.mark.realdata
@pytest.mark.parametrize("name", sorted(REAL))
def test_real_log(real_logs, name):
    n_scans, beams, first, ref, odo, t, no_return = REAL[name]
    log = real_logs(name)
    scans = log.scans
    assert len(scans) == n_scans
    assert {s.n_beams for s in scans} == {beams}
    assert all(s.reference is not None and s.odometry is not None for s in scans)
    s0 = scans[0]
    assert s0.ranges[:3].tolist() == first
    assert s0.reference.as_array() == pytest.approx(ref, abs=1e-12)
    assert s0.odometry.as_array() == pytest.approx(odo, abs=1e-12)
    assert s0.timestamp == t
    np.testing.assert_array_equal(s0.angles, flaser_angles(beams))
    # every reading at or beyond 80 m is the log's no-return marker, every other is below 40
    r = np.concatenate([s.ranges for s in scans])
    assert set(np.unique(r[r >= FLASER_MAX_RANGE]).tolist()) == {no_return}
    assert r[r < FLASER_MAX_RANGE].max() < 40.0
    stamps = [s.timestamp for s in scans]
    assert all(b > a for a, b in zip(stamps, stamps[1:], strict=False))


@pytest.mark.realdata
def test_real_freiburg_extras(real_logs):
    log = real_logs("freiburg")
    assert dict(log.skipped) == {"unknown:NEFF": 4791}
    assert log.params["robot_front_laser_max"] == "80.99"
    assert log.params["laser_front_laser_resolution"] == "0.5"
    assert log.odom.shape == (9725, 4)
    assert all(s.odometry == s.reference for s in log.scans[:50])


@pytest.mark.realdata
def test_real_read_scans_matches_read_carmen(real_logs):
    log = real_logs("intel")
    scans = read_scans(require_log("intel"))
    for a, b in zip(log.scans[::97], scans[::97], strict=True):
        same_scan(a, b)
