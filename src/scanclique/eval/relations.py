"""The relation metric of Kümmerle et al. 2009 ("On measuring the accuracy of SLAM
algorithms", Autonomous Robots 27(4)).

A *relation* is a relative pose ``delta*`` of the robot at time ``t2`` in its frame at time
``t1``, obtained independently of any SLAM system (scan alignment checked by hand). The
files of the Freiburg SLAM benchmark hold one per line::

    t1 t2 x y z roll pitch yaw

(metres and radians; ``z``, ``roll`` and ``pitch`` are 0 for the planar logs). For estimated
poses ``x1``, ``x2`` at ``t1`` and ``t2`` the error of the relation is (as Cartographer's
``compute_relations_metrics`` computes it)::

    E = (x1^-1 x2) delta*^-1

and the metric is the mean ± standard deviation over all relations of ``|translation(E)|``
(metres) and ``|angle(E)|`` (degrees), and of their squares (m², deg²). The published
figures of the benchmark (graph mapping, Cartographer, ...) are the means of the absolute
errors over all relations of a log.

Examples
--------
>>> from scanclique.geometry import Pose2
>>> rel = [Relation(0.0, 1.0, Pose2(1.0, 0.0, 0.0))]
>>> poses = {0.0: Pose2(0.0, 0.0, 0.0), 1.0: Pose2(1.1, 0.0, 0.0)}
>>> m = relation_metrics(rel, poses)
>>> round(m.all.translation_mean, 6), m.all.n
(0.1, 1)
"""

from __future__ import annotations

import math
import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import ArgumentError, ParseError, ScanError
from ..geometry import Pose2
from ..io.text import plain_float
from ..io.tum import MAX_GAP, poses_at

__all__ = [
    "frame_mounting",
    "Relation",
    "RelationErrors",
    "SplitErrors",
    "SHORT_SECONDS",
    "read_relations",
    "join_relations",
    "relation_errors",
    "relation_metrics",
    "relation_rows",
    "trajectory_relation_metrics",
]

#: relations spanning at most this many seconds are "short" (consecutive-ish), the others
#: "long" (loop closures are what brings those down)
SHORT_SECONDS = 10.0

#: timestamps are joined after rounding to this many decimals (the files print microseconds)
TIME_DECIMALS = 6


@dataclass(frozen=True, slots=True)
class Relation:
    """One relation: ``delta`` is the pose at ``t2`` in the frame at ``t1`` (maps points of
    the frame at ``t2`` into the frame at ``t1``)."""

    t1: float
    t2: float
    delta: Pose2

    @property
    def span(self) -> float:
        """``|t2 - t1|`` in seconds."""
        return abs(self.t2 - self.t1)


def read_relations(path: str | os.PathLike) -> list[Relation]:
    """Read a relations file (``t1 t2 x y z roll pitch yaw`` per line; ``#`` comments and
    blank lines skipped).

    Raises
    ------
    ParseError
        Naming the file, line and field when a line does not have 8 numbers, or when
        ``z``, ``roll`` or ``pitch`` is not 0 (not a planar relation), or when the file
        cannot be read.
    """
    p = Path(path)
    try:
        text = p.read_text(encoding="utf-8-sig")  # a byte order mark at the head is dropped
    except (OSError, UnicodeDecodeError) as exc:
        raise ParseError(str(path), None, f"cannot read relations file ({exc})") from None
    names = ("t1", "t2", "x", "y", "z", "roll", "pitch", "yaw")
    out: list[Relation] = []
    for lineno, line in enumerate(text.splitlines(), 1):
        s = line.strip()
        if not s or s.startswith("#"):
            continue
        fields = s.split()
        if len(fields) != 8:
            raise ParseError(
                str(path),
                lineno,
                f"expected 8 numbers (t1 t2 x y z roll pitch yaw), found {len(fields)}",
            )
        vals = []
        for name, f in zip(names, fields, strict=True):
            try:
                v = plain_float(f)
            except ValueError:
                raise ParseError(
                    str(path), lineno, f"expected a number, found {f!r}", name
                ) from None
            if not math.isfinite(v):
                raise ParseError(str(path), lineno, f"expected a finite number, found {f!r}", name)
            vals.append(v)
        t1, t2, x, y, z, roll, pitch, yaw = vals
        for name, v in (("z", z), ("roll", roll), ("pitch", pitch)):
            if abs(v) > 1e-9:
                raise ParseError(
                    str(path), lineno, f"expected 0 for a planar relation, found {v}", name
                )
        out.append(Relation(t1, t2, Pose2.from_xytheta(x, y, yaw)))
    return out


def _key(t: float) -> float:
    return round(float(t), TIME_DECIMALS)


def join_relations(
    relations: Sequence[Relation],
    timestamps: Sequence[float | None],
) -> tuple[np.ndarray, np.ndarray]:
    """Scan indices of each relation's two timestamps.

    Parameters
    ----------
    relations : sequence of Relation
    timestamps : sequence of float or None
        One per scan (``Scan.timestamp``); a timestamp seen twice keeps its first scan.

    Returns
    -------
    (ndarray of int, ndarray of bool)
        ``(n, 2)`` indices (``-1`` where a timestamp has no scan) and a mask of the
        relations whose both timestamps joined exactly (after rounding to microseconds).
    """
    index: dict[float, int] = {}
    for i, t in enumerate(timestamps):
        if t is not None:
            index.setdefault(_key(t), i)
    ij = np.array(
        [[index.get(_key(r.t1), -1), index.get(_key(r.t2), -1)] for r in relations], dtype=int
    ).reshape(-1, 2)
    return ij, (ij >= 0).all(axis=1)


def frame_mounting(scans: Sequence) -> Pose2 | None:
    """The constant pose of the robot frame in the laser frame of a log whose laser lines
    carry both poses (CARMEN's FLASER: ``Scan.reference`` the laser's odometry pose,
    ``Scan.odometry`` the robot's; in the raw fr079 log the laser sits 0.04 m behind the
    robot), the ``mounting`` of :func:`relation_errors` for relations given in the robot
    frame. None when the two coincide, vary from scan to scan (more than 1e-3 in any
    component over about 50 scans sampled along the log), or are missing.

    >>> from scanclique.scan import Scan
    >>> s = Scan([1.0, 1.0], [0.0, 0.1], reference=Pose2(1.0, 2.0, 0.5),
    ...          odometry=Pose2(1.0, 2.0, 0.5) @ Pose2(0.04, 0.0, 0.0))
    >>> frame_mounting([s, s]).as_array().round(6).tolist()
    [0.04, 0.0, 0.0]
    """
    offs = [
        s.reference.inverse() @ s.odometry
        for s in scans[:: max(1, len(scans) // 50)]
        if s.reference is not None and s.odometry is not None
    ]
    if not offs:
        return None
    a = np.array([o.as_array() for o in offs])
    if np.ptp(a, axis=0).max() > 1e-3 or np.abs(a.mean(axis=0)).max() < 1e-4:
        return None
    return Pose2.from_array(a.mean(axis=0))


def relation_errors(
    relations: Sequence[Relation],
    poses: Mapping[float, Pose2 | None] | Sequence[Pose2 | None],
    timestamps: Sequence[float | None] | None = None,
    *,
    mounting: Pose2 | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Translation (m) and rotation (rad) error of each relation, and its span (s).

    Parameters
    ----------
    relations : sequence of Relation
    poses : mapping timestamp -> Pose2, or sequence of Pose2 (one per scan, with
        ``timestamps``)
        Estimated poses in any common world frame. ``None`` poses (unplaced scans) make the
        relation's error NaN.
    timestamps : sequence of float, optional
        Needed when ``poses`` is a sequence.
    mounting : Pose2, optional
        Pose of the frame the relations refer to (the robot's) in the frame the estimates
        are of (the sensor's): ``x_robot = x_sensor @ mounting``. Default: the same frame.

    Returns
    -------
    (t_err, r_err, span) : three ndarrays of shape (n,)
        ``|translation(E)|``, ``|angle(E)|`` with ``E = (x1^-1 x2) delta*^-1``; NaN where a
        timestamp did not join or a pose is None.
    """
    if isinstance(poses, Mapping):
        keyed = {_key(t): p for t, p in poses.items()}
        pairs = [(keyed.get(_key(r.t1)), keyed.get(_key(r.t2))) for r in relations]
    else:
        if timestamps is None or len(timestamps) != len(poses):
            raise ScanError("relation_errors: a sequence of poses needs one timestamp per pose")
        ij, _ = join_relations(relations, timestamps)
        pairs = [
            (poses[i] if i >= 0 else None, poses[j] if j >= 0 else None) for i, j in ij.tolist()
        ]
    n = len(relations)
    t_err = np.full(n, np.nan)
    r_err = np.full(n, np.nan)
    span = np.array([r.span for r in relations], dtype=float)
    m_inv = None if mounting is None else mounting.inverse()
    for k, (r, (p1, p2)) in enumerate(zip(relations, pairs, strict=True)):
        if p1 is None or p2 is None:
            continue
        rel = p1.inverse() @ p2
        if mounting is not None:
            rel = m_inv @ rel @ mounting
        E = rel @ r.delta.inverse()
        t_err[k] = math.hypot(E.x, E.y)
        r_err[k] = abs(E.theta)
    return t_err, r_err, span


@dataclass(frozen=True, slots=True)
class RelationErrors:
    """Summary of relation errors over a set of relations.

    ``translation_*`` in metres (``translation_sq_*`` in m²), ``rotation_*`` in degrees
    (``rotation_sq_*`` in deg²); ``n`` relations counted, ``missing`` that could not be
    evaluated (a timestamp without a scan, or an unplaced scan)."""

    n: int
    missing: int
    translation_mean: float
    translation_std: float
    rotation_mean: float
    rotation_std: float
    translation_sq_mean: float
    translation_sq_std: float
    rotation_sq_mean: float
    rotation_sq_std: float
    translation_max: float

    @classmethod
    def of(cls, t_err: np.ndarray, r_err: np.ndarray) -> RelationErrors:
        ok = np.isfinite(t_err) & np.isfinite(r_err)
        t = t_err[ok]
        r = np.degrees(r_err[ok])

        def ms(a):
            return (float(a.mean()), float(a.std())) if a.size else (math.nan, math.nan)

        tm, ts = ms(t)
        rm, rs = ms(r)
        tqm, tqs = ms(t**2)
        rqm, rqs = ms(r**2)
        return cls(
            int(ok.sum()),
            int((~ok).sum()),
            tm,
            ts,
            rm,
            rs,
            tqm,
            tqs,
            rqm,
            rqs,
            float(t.max()) if t.size else math.nan,
        )

    def to_dict(self) -> dict:
        return {k: (None if isinstance(v, float) and not math.isfinite(v) else v)
                for k, v in ((s, getattr(self, s)) for s in self.__slots__)}  # fmt: skip


@dataclass(frozen=True, slots=True)
class SplitErrors:
    """Relation errors over all relations, those spanning at most ``short_seconds`` and the
    longer ones."""

    all: RelationErrors
    short: RelationErrors
    long: RelationErrors
    short_seconds: float = SHORT_SECONDS

    @classmethod
    def of(
        cls,
        t_err: np.ndarray,
        r_err: np.ndarray,
        span: np.ndarray,
        short_seconds: float = SHORT_SECONDS,
    ) -> SplitErrors:
        """From per-relation translation (m) and rotation (rad) errors and spans (s), as
        :func:`relation_errors` gives them."""
        t, r = np.asarray(t_err, dtype=float), np.asarray(r_err, dtype=float)
        short = np.asarray(span, dtype=float) <= short_seconds
        return cls(
            RelationErrors.of(t, r),
            RelationErrors.of(t[short], r[short]),
            RelationErrors.of(t[~short], r[~short]),
            short_seconds,
        )

    def to_dict(self) -> dict:
        return {
            "all": self.all.to_dict(),
            "short": self.short.to_dict(),
            "long": self.long.to_dict(),
            "short_seconds": self.short_seconds,
        }


def relation_metrics(
    relations: Sequence[Relation],
    poses: Mapping[float, Pose2 | None] | Sequence[Pose2 | None],
    timestamps: Sequence[float | None] | None = None,
    *,
    mounting: Pose2 | None = None,
    short_seconds: float = SHORT_SECONDS,
) -> SplitErrors:
    """The relation metric (module docstring) over all relations and split by span.

    See :func:`relation_errors` for the parameters.
    """
    t, r, span = relation_errors(relations, poses, timestamps, mounting=mounting)
    return SplitErrors.of(t, r, span, short_seconds)


def trajectory_relation_metrics(
    trajectory,
    relations: Sequence[Relation],
    *,
    mounting: Pose2 | None = None,
    max_gap: float = MAX_GAP,
    short_seconds: float = SHORT_SECONDS,
) -> SplitErrors:
    """The relation metric of a trajectory at any rate (any system's, or the
    ``trajectory.tum`` of ``scanclique map``), as the benchmark's own evaluator scores one.

    Each relation's two poses are the trajectory's at its two times
    (:func:`scanclique.io.poses_at` on the rows in time order): the row at that time
    (within :data:`scanclique.io.tum.TIME_TOLERANCE`), else interpolated between the two
    rows around it when they are at most ``max_gap`` seconds apart. A relation with a time
    outside the rows or in a larger gap is counted as missing (``RelationErrors.missing``),
    not scored.

    Parameters
    ----------
    trajectory : array_like, shape (N, 4)
        Rows ``time x y theta`` (:func:`scanclique.io.read_tum`), in any order.
    relations : sequence of Relation
    mounting : Pose2, optional
        As for :func:`relation_errors`: the pose of the relations' frame (the robot's) in
        the trajectory's (the laser's, for ``scanclique map``'s trajectory of a log whose
        laser sits off the robot's centre: :func:`frame_mounting`).
    max_gap, short_seconds : float
        Seconds.

    Raises
    ------
    ArgumentError
        No relation's time lies within the trajectory (another log's, or another clock's),
        or the rows are not ``time x y theta``.

    >>> rows = [[0.0, 0.0, 0.0, 0.0], [1.0, 1.1, 0.0, 0.0], [3.0, 3.0, 0.0, 0.0]]
    >>> rels = [Relation(0.0, 0.5, Pose2(0.5, 0.0, 0.0)), Relation(0.0, 2.0, Pose2(2.0, 0, 0))]
    >>> m = trajectory_relation_metrics(rows, rels)  # 0.5 s interpolated; 2 s in a 2 s gap
    >>> round(m.all.translation_mean, 6), m.all.n, m.all.missing
    (0.05, 1, 1)
    """
    rows = np.asarray(trajectory, dtype=float)
    if rows.ndim != 2 or rows.shape[1] != 4 or not len(rows):
        raise ArgumentError(f"a trajectory must be rows time x y theta, (N, 4); got {rows.shape}")
    rows = rows[np.argsort(rows[:, 0], kind="stable")]  # a log's clock may go back
    times = sorted({t for r in relations for t in (r.t1, r.t2)})
    try:
        poses = poses_at(rows, times, max_gap=max_gap) if times else ()
    except ArgumentError:
        raise ArgumentError(
            f"no relation's time lies within the trajectory (trajectory {len(rows)} rows, "
            f"{rows[0, 0]:.3f} to {rows[-1, 0]:.3f} s; relations {times[0]:.3f} to "
            f"{times[-1]:.3f} s): is it of another log or clock?"
        ) from None
    keyed = dict(zip(times, poses, strict=True))
    return relation_metrics(relations, keyed, mounting=mounting, short_seconds=short_seconds)


def relation_rows(metrics: Mapping) -> list[tuple[str, str, str]]:
    """Metric / Value / Units rows of a relation metric (:meth:`SplitErrors.to_dict`):
    the counts, the mean ± standard deviation of the absolute and of the squared errors
    (the two the benchmark publishes), the largest translation error, and the mean errors
    of the relations spanning at most and more than ``short_seconds``."""

    def pm(e: Mapping, key: str, digits: int) -> str:
        m, s = e[f"{key}_mean"], e[f"{key}_std"]
        return "n/a" if m is None else f"{m:.{digits}f} ± {s:.{digits}f}"

    a, cut = metrics["all"], metrics["short_seconds"]
    rows = [
        ("relations", str(a["n"]), ""),
        ("relations missing (no pose)", str(a["missing"]), ""),
        ("relation error (translation)", pm(a, "translation", 4), "m"),
        ("relation error (rotation)", pm(a, "rotation", 3), "deg"),
        ("squared error (translation)", pm(a, "translation_sq", 5), "m^2"),
        ("squared error (rotation)", pm(a, "rotation_sq", 3), "deg^2"),
        ("largest translation error", "n/a" if a["translation_max"] is None
         else f"{a['translation_max']:.4f}", "m"),
    ]  # fmt: skip
    for part, label in (("short", f"<= {cut:g} s"), ("long", f"> {cut:g} s")):
        e = metrics[part]
        rows += [
            (f"relations {label}", str(e["n"]), ""),
            (f"  their error ({label})", "n/a" if e["translation_mean"] is None
             else f"{e['translation_mean']:.4f} / {e['rotation_mean']:.3f}", "m / deg"),
        ]  # fmt: skip
    return rows
