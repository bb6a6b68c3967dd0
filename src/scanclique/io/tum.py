"""TUM trajectories (``timestamp x y z qx qy qz qw``, one pose per line), read as planar
poses, and each scan of a log given its pose in one.

The format is the one ``scanclique map`` writes (``trajectory.tum``, the pose of each
scan's sensor frame in the map) and the one evo and most SLAM systems read and write. A
place database takes a log's places with their poses in a map from it
(``scanclique places add DB LOG --map runs/intel``).

>>> import tempfile, os
>>> p = os.path.join(tempfile.mkdtemp(), "trajectory.tum")
>>> _ = open(p, "w").write("10.0 1 2 0 0 0 0.7071068 0.7071068\\n10.5 2 2 0 0 0 0 1\\n")
>>> read_tum(p).round(4).tolist()
[[10.0, 1.0, 2.0, 1.5708], [10.5, 2.0, 2.0, 0.0]]
>>> poses_at(read_tum(p), [10.0, 10.25, 10.5, 11.0])
(Pose2(x=1.0000, y=2.0000, theta=1.5708), None, Pose2(x=2.0000, y=2.0000, theta=0.0000), None)
"""

from __future__ import annotations

import math
import os
from collections.abc import Sequence

import numpy as np

from ..errors import ArgumentError, ParseError
from ..geometry import Pose2, interpolate_poses
from ..scan import MAX_POSE_COORDINATE
from .table import read_table, table_line

__all__ = [
    "read_tum",
    "write_tum",
    "poses_at",
    "TUM_COLUMNS",
    "TIME_TOLERANCE",
    "MAX_GAP",
    "MAX_TILT",
]

TUM_COLUMNS = ("timestamp", "x", "y", "z", "qx", "qy", "qz", "qw")
#: a row and a scan are at the same time when this close (s): the 1 microsecond that
#: ``trajectory.tum`` is written to, and a millisecond of another tool's rounding
TIME_TOLERANCE = 1e-3
#: a scan between two rows further apart than this (s) gets no interpolated pose
MAX_GAP = 1.0
#: a row's rotation may tilt the z axis by this much (radians, 25 degrees): a planar
#: robot's trajectory from a 3D system (the tilt of a bag's laser that is still read as
#: level, :mod:`.rosbag`)
MAX_TILT = math.radians(25.0)
#: a quaternion whose norm is further than this from 1 is not a rotation
QUATERNION_TOLERANCE = 0.01


def write_tum(path: str | os.PathLike, poses, timestamps) -> int:
    """Write a TUM trajectory: one row ``timestamp x y 0 0 0 qz qw`` per pose (the rotation
    ``theta`` about z), in the given order; a pose that is None is left out. Returns the
    rows written.

    Parameters
    ----------
    poses : sequence of Pose2 or None, or array_like (N, 3)
        ``x y theta`` (metres, radians).
    timestamps : sequence of float or None
        One per pose (seconds); a missing one is written as the pose's index.

    Raises
    ------
    ArgumentError
        Not one timestamp per pose, a pose that is not a Pose2, None or three numbers, or
        a pose or timestamp that is not finite; nothing is written.
    """
    if len(timestamps) != len(poses):
        raise ArgumentError(
            f"write_tum: {len(timestamps)} timestamps for {len(poses)} poses (one per pose)"
        )
    lines = []
    for k, p in enumerate(poses):
        if p is None:
            continue
        if isinstance(p, Pose2):
            x, y, th = p.x, p.y, p.theta
        else:
            try:
                x, y, th = (float(v) for v in p)
            except (TypeError, ValueError):
                raise ArgumentError(
                    f"write_tum: poses[{k}] must be a Pose2, None or x y theta, got {p!r}"
                ) from None
        t = timestamps[k] if timestamps[k] is not None else float(k)
        if not all(isinstance(v, (int, float, np.number)) and math.isfinite(v)
                   for v in (t, x, y, th)):  # fmt: skip
            raise ArgumentError(
                f"write_tum: poses[{k}] ({x}, {y}, {th}) at timestamps[{k}] {t!r} must be finite"
            )
        h = 0.5 * th
        lines.append(
            f"{t:.6f} {x:.6f} {y:.6f} 0.000000 0.000000 0.000000 {math.sin(h):.9f} "
            f"{math.cos(h):.9f}"
        )
    with open(path, "w") as fh:
        fh.write("\n".join(lines) + ("\n" if lines else ""))
    return len(lines)


def read_tum(path: str | os.PathLike) -> np.ndarray:
    """The planar poses of a TUM trajectory file.

    Parameters
    ----------
    path : str or path-like
        Rows ``timestamp x y z qx qy qz qw`` (seconds, metres, a unit quaternion), one per
        line, separated by whitespace or commas; ``#`` comments and blank lines skipped.
        Rows may come in any time order (``trajectory.tum`` keeps a log's order where its
        clock goes back).

    Returns
    -------
    ndarray, shape (N, 4)
        Rows ``time x y theta`` in the file's order: theta the rotation's yaw about z
        (radians, counter-clockwise). ``z`` and a small roll and pitch (at most
        :data:`MAX_TILT`) are dropped: the poses of a map in the plane.

    Raises
    ------
    ParseError
        Names the file, the line and the field: not 8 finite numbers, a position beyond
        :data:`~scanclique.scan.MAX_POSE_COORDINATE` of the origin (as the logs' poses), a
        quaternion that is not of unit norm, a rotation tilted more than :data:`MAX_TILT`,
        or no rows at all.
    DataNotFoundError
        No such file.
    """
    a = read_table(path, TUM_COLUMNS, ordered=False)
    if not len(a):
        raise ParseError(os.fspath(path), None, "holds no poses (timestamp x y z qx qy qz qw)")
    far = np.abs(a[:, 1:3]).max(axis=1)
    _refuse(path, far > MAX_POSE_COORDINATE, "x y", lambda r: (
        f"x y = {a[r, 1]:g} {a[r, 2]:g} lies beyond {MAX_POSE_COORDINATE:g} m of the frame's "
        "origin: not a pose"))  # fmt: skip
    q = a[:, 4:8]
    norm = np.linalg.norm(q, axis=1)
    _refuse(path, ~(np.abs(norm - 1.0) <= QUATERNION_TOLERANCE), "qw", lambda r: (
        f"qx qy qz qw = {' '.join(f'{v:g}' for v in q[r])} is not a rotation (norm "
        f"{norm[r]:.4g}, not 1)"))  # fmt: skip
    qx, qy, qz, qw = (q / norm[:, None]).T
    # the z axis of the rotated frame, z component: cos of the tilt
    tilt = np.arccos(np.clip(1.0 - 2.0 * (qx * qx + qy * qy), -1.0, 1.0))
    _refuse(path, tilt > MAX_TILT, "qx qy", lambda r: (
        f"the rotation tilts the z axis by {math.degrees(tilt[r]):.1f} deg (at most "
        f"{math.degrees(MAX_TILT):.0f}): not a trajectory in the plane"))  # fmt: skip
    yaw = np.arctan2(2.0 * (qw * qz + qx * qy), 1.0 - 2.0 * (qy * qy + qz * qz))
    return np.column_stack([a[:, 0], a[:, 1], a[:, 2], yaw])


def _refuse(path, bad: np.ndarray, field: str, message) -> None:
    """A :class:`ParseError` naming the line of the first row where ``bad`` is True (data
    rows counted as :func:`read_table` counts them), ``message(row)`` saying why."""
    rows = np.flatnonzero(bad)
    if len(rows):
        r = int(rows[0])
        raise ParseError(os.fspath(path), table_line(path, r), message(r), field=field)


def poses_at(
    trajectory, timestamps: Sequence[float | None], *, max_gap: float = MAX_GAP
) -> tuple[Pose2 | None, ...]:
    """Each scan's pose in a trajectory, by the scans' timestamps.

    Two ways, the first that fits:

    1. **One row per scan, in the scans' order** (the ``trajectory.tum`` that
       ``scanclique map`` wrote for these scans: a row for each scan it placed, in the
       log's order even where the log's clock goes back, a scan without a timestamp
       written at its index): each row is the next scan whose time is within
       :data:`TIME_TOLERANCE` of the row's; the scans without a row get None.
    2. **Rows in time order** (another system's trajectory, at its own rate): each scan's
       pose interpolated between the two rows around its timestamp (x and y linearly, the
       heading along the shorter arc; a scan at a row's time within
       :data:`TIME_TOLERANCE` takes the row's pose); None for a scan without a
       timestamp, outside the rows' time span, or between rows more than ``max_gap``
       seconds apart.

    Parameters
    ----------
    trajectory : array_like, shape (N, 4)
        Rows ``time x y theta`` (:func:`read_tum`).
    timestamps : sequence of float or None
        One per scan, in the log's order (:attr:`scanclique.scan.Scan.timestamp`).
    max_gap : float
        Seconds; see 2.

    Returns
    -------
    tuple of Pose2 or None
        One per scan: the pose of its frame in the trajectory's.

    Raises
    ------
    ArgumentError
        The rows follow the scans in neither way (times out of order that are not the
        scans' own), or no scan gets a pose (the trajectory is of another log, or of
        another clock): the message gives both time spans.
    """
    rows = np.asarray(trajectory, dtype=float)
    if rows.ndim != 2 or rows.shape[1] != 4:
        raise ArgumentError(f"a trajectory must be rows time x y theta, (N, 4); got {rows.shape}")
    if not len(rows):
        raise ArgumentError("the trajectory has no rows")
    ts = [float(k) if t is None else float(t) for k, t in enumerate(timestamps)]
    out: list[Pose2 | None] = [None] * len(ts)
    j = 0
    for t, x, y, th in rows:  # 1. one row per scan, in order
        while j < len(ts) and not abs(ts[j] - t) <= TIME_TOLERANCE:
            j += 1
        if j == len(ts):
            break
        out[j] = Pose2(float(x), float(y), float(th))
        j += 1
    else:
        return tuple(out)
    span = _span(rows[:, 0])
    scans = _span(np.array([t for t in timestamps if t is not None], dtype=float))
    if not np.all(np.diff(rows[:, 0]) >= 0):
        raise ArgumentError(
            f"the trajectory's rows are neither one per scan in the scans' order nor in time "
            f"order (trajectory {span}; scans {scans})"
        )
    out = [None] * len(ts)
    have = [k for k, t in enumerate(timestamps) if t is not None]
    if have:
        t = np.array([ts[k] for k in have])
        i = np.searchsorted(rows[:, 0], t)
        lo = rows[np.clip(i - 1, 0, len(rows) - 1), 0]
        hi = rows[np.clip(i, 0, len(rows) - 1), 0]
        at = (np.abs(t - lo) <= TIME_TOLERANCE) | (np.abs(hi - t) <= TIME_TOLERANCE)
        inside = (i > 0) & (i < len(rows)) & (hi - lo <= max_gap)
        ok = at | inside
        p = interpolate_poses(rows, t)
        for k, good, (x, y, th) in zip(have, ok, p, strict=True):
            if good:
                out[k] = Pose2(float(x), float(y), float(th))
    if not any(p is not None for p in out):
        raise ArgumentError(
            f"no scan lies within the trajectory: its rows' times and the scans' do not "
            f"overlap (trajectory {span}; scans {scans}): is it of another log or clock?"
        )
    return tuple(out)


def _span(t: np.ndarray) -> str:
    if not len(t):
        return "no timestamps"
    return f"{len(t)} times, {t.min():.3f} to {t.max():.3f} s"
