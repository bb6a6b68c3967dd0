"""TUM trajectories read as planar poses (:mod:`scanclique.io.tum`), and given to a log's
scans by their timestamps."""

from __future__ import annotations

import math

import numpy as np
import pytest

from scanclique.errors import ArgumentError, DataNotFoundError, ParseError
from scanclique.geometry import Pose2
from scanclique.io import poses_at, read_tum, write_tum


def _quat(yaw, roll=0.0):
    """(qx, qy, qz, qw) of a roll about x, then a yaw about z."""
    cr, sr, cy, sy = math.cos(roll / 2), math.sin(roll / 2), math.cos(yaw / 2), math.sin(yaw / 2)
    return (sr * cy, sr * sy, cr * sy, cr * cy)


def test_what_scanclique_map_writes_reads_back_with_the_log_order_kept(tmp_path):
    """``trajectory.tum`` as ``scanclique map`` writes it (intel's clock goes back; a scan
    it could not place has no row; a scan without a timestamp is written at its index)
    gives every scan its own pose back, and None to the one without a row."""
    poses = [Pose2(0.1 * k, -0.2 * k, 0.5 * k - 3.0) for k in range(6)]
    poses[3] = None
    times = [100.0, 100.2, 100.1, 100.3, None, 100.5]  # back at 2; none at 4
    p = tmp_path / "trajectory.tum"
    assert write_tum(p, poses, times) == 5
    rows = read_tum(p)
    assert rows.shape == (5, 4)
    got = poses_at(rows, times)
    assert got[3] is None
    for want, have in zip(poses, got, strict=True):
        if want is not None:
            dt, dr = want.distance_to(have)
            assert dt < 1e-5 and dr < 1e-7


def test_another_systems_trajectory_is_interpolated_by_time(tmp_path):
    """A trajectory in time order at its own rate (and a 3D one with a little roll and a
    height): each scan's pose between the rows around it; None before, after, and across
    a gap longer than ``max_gap``."""
    p = tmp_path / "other.txt"
    lines = ["# timestamp tx ty tz qx qy qz qw"]
    for t, x, yaw in ((0.0, 0.0, 3.0), (0.1, 1.0, -3.0), (0.2, 2.0, -2.9), (5.0, 3.0, 0.0)):
        q = _quat(yaw, roll=0.05)
        lines.append(f"{t} {x} 0.5 1.2 " + " ".join(f"{v:.9f}" for v in q))
    p.write_text("\n".join(lines) + "\n")
    rows = read_tum(p)
    np.testing.assert_allclose(rows[:, 3], [3.0, -3.0, -2.9, 0.0], atol=1e-7)
    got = poses_at(rows, [-1.0, 0.05, 0.1, 0.15, 1.0, None, 6.0])
    assert got[0] is None and got[4] is None and got[5] is None and got[6] is None
    assert got[1].x == pytest.approx(0.5)  # halfway, heading across +-pi the short way
    assert abs(abs(got[1].theta) - math.pi) < 1e-6
    assert got[2].x == pytest.approx(1.0) and got[3].theta == pytest.approx(-2.95)
    assert poses_at(rows, [1.0], max_gap=10.0)[0].x == pytest.approx(2 + 0.8 / 4.8)


@pytest.mark.parametrize(
    ("text", "line", "words"),
    [
        ("0 1 2 0 0 0 0 1\n0.1 1 2 0 0 0 1\n", 2, "expected 8 numbers"),
        ("0 1 2 0 0 0 0 1\n0.1 1 nan 0 0 0 0 1\n", 2, "not finite"),
        ("0 1 2 0 0 0 0 1\n# fine\n0.1 1 2 0 0 0 0 2\n", 3, "not a rotation"),
        ("0 1 2 0 0 0 0 1\n0.1 1 2 0 0.7071068 0 0 0.7071068\n", 2, "tilts the z axis by 90"),
        ("# nothing\n\n", None, "holds no poses"),
        # (its evaluation failed with a bare ScanError naming no file: session 46's fuzz)
        ("0 1 2 0 0 0 0 1\n0.1 -1e308 2 0 0 0 0 1\n", 2, "beyond 1e\\+09 m"),
    ],
)
def test_a_bad_trajectory_file_names_the_line(tmp_path, text, line, words):
    p = tmp_path / "t.tum"
    p.write_text(text)
    with pytest.raises(ParseError, match=words) as e:
        read_tum(p)
    assert e.value.line == line and e.value.path == str(p)


def test_a_missing_file_and_a_trajectory_of_another_log_are_named(tmp_path):
    with pytest.raises(DataNotFoundError):
        read_tum(tmp_path / "none.tum")
    rows = np.array([[10.0, 0, 0, 0], [11.0, 1, 0, 0]])
    with pytest.raises(ArgumentError, match="no scan lies within the trajectory"):
        poses_at(rows, [20.0, 21.0])
    back = np.array([[10.0, 0, 0, 0], [9.0, 1, 0, 0]])  # out of order, not the scans'
    with pytest.raises(ArgumentError, match="neither one per scan"):
        poses_at(back, [9.5, 10.5])
    with pytest.raises(ArgumentError, match="no rows"):
        poses_at(np.zeros((0, 4)), [1.0])
    with pytest.raises(ArgumentError, match=r"\(N, 4\); got \(2, 3\)"):
        poses_at(np.zeros((2, 3)), [1.0])
