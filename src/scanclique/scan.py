"""The scan model: one batch observation of a 2D range sensor (stage 1 of the pipeline).

Readers build :class:`Scan` records; nothing downstream parses files. A scan keeps the
ranges exactly as given (copied and made read-only): invalid returns (NaN, inf, at or
below ``range_min``, at or beyond ``range_max``) are *masked* by :attr:`Scan.valid`, never
altered, and never become features.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np

from ._records import readonly as _readonly
from .errors import ScanError
from .geometry import Pose2

__all__ = [
    "Scan", "beam_angles", "deskew", "deskew_along", "retime", "sweep_velocity",
    "sweep_velocity_of", "measured_before",
    "MAX_ANGLE_SPAN", "MAX_POSE_COORDINATE", "MAX_SWEEP", "MAX_SWEEP_SPEED", "MAX_SWEEP_TURN",
    "TIMINGS",
]  # fmt: skip

#: a scan's odometry or reference pose farther than this from its frame's origin (metres,
#: in x or y) is refused: 10^9 m is beyond any robot's frame (UTM coordinates are below
#: 10^7 m), and such a value is a corrupt field whose square overflows the uncertainty
#: arithmetic downstream
MAX_POSE_COORDINATE = 1e9


def beam_angles(n: int, angle_min: float, angle_increment: float) -> np.ndarray:
    """Beam angles (radians, sensor frame, counter-clockwise from the x axis) of ``n`` beams."""
    return angle_min + angle_increment * np.arange(n, dtype=float)


#: the largest span of a scan's beam angles (rad): two turns, so that a scan that overlaps
#: itself is kept, and a field of view in degrees (180, 270, 360) is refused
MAX_ANGLE_SPAN = 4.0 * math.pi

#: the longest time between a scan's ``timestamp`` and any of its beams (seconds): a 2D
#: scanner sweeps in well under a second (a 5 Hz lidar in 0.2 s); more is a time in other
#: units (milliseconds for seconds) or a corrupt field
MAX_SWEEP = 1.0

#: the fastest motion :func:`sweep_velocity` takes for a sweep (m/s, rad/s): a car at
#: 180 km/h, two turns a second; beyond is an odometry jump (a reset, a glitch), and
#: de-skewing by it would bend the scan by metres
MAX_SWEEP_SPEED = 50.0
MAX_SWEEP_TURN = 4.0 * math.pi


@dataclass(frozen=True, slots=True, eq=False)
class Scan:
    """One 2D range scan.

    Attributes
    ----------
    ranges : ndarray, shape (N,)
        Measured ranges in metres, as given (NaN/inf/out-of-limits are kept, and masked).
    angles : ndarray, shape (N,)
        Beam angles in radians in the sensor frame, counter-clockwise, x forward.
        Must be strictly increasing (the clustering walks beams in this order) and span at
        most :data:`MAX_ANGLE_SPAN` (two turns: more is degrees given for radians).
    range_min, range_max : float
        Valid returns satisfy ``range_min < r < range_max`` (metres).
    timestamp : float or None
        Seconds (absolute or relative, as the log has it).
    odometry : Pose2 or None
        Odometry pose of the sensor in the odometry frame (drifts).
    reference : Pose2 or None
        Reference ("ground truth" / corrected) pose of the sensor in the world frame.
        Both poses within :data:`MAX_POSE_COORDINATE` of their frame's origin.
    source : str
        Where the scan came from, e.g. ``"intel-odometry.log.gz:17"``, for messages.
    beam_times : ndarray, shape (N,), or None
        Seconds after ``timestamp`` at which each beam was measured (a rotating scanner
        sweeps: ROS's ``time_increment``), each within :data:`MAX_SWEEP`; None when the
        beams are taken as measured at once (CARMEN logs, and a scanner fast against the
        motion). A moving robot's rotating scanner sees its sweep skewed by the motion;
        :func:`deskew` takes the skew out.
    """

    ranges: np.ndarray
    angles: np.ndarray
    range_min: float = 0.0
    range_max: float = 80.0
    timestamp: float | None = None
    odometry: Pose2 | None = None
    reference: Pose2 | None = None
    source: str = ""
    beam_times: np.ndarray | None = None
    valid: np.ndarray = field(init=False, repr=False)

    def __post_init__(self) -> None:
        where = f"{self.source}: " if self.source else ""
        try:
            r = np.array(self.ranges, dtype=np.float64, copy=True)
            a = np.array(self.angles, dtype=np.float64, copy=True)
        except (TypeError, ValueError) as exc:
            raise ScanError(f"{where}ranges and angles must be numeric arrays ({exc})") from None
        if r.ndim != 1 or a.ndim != 1:
            raise ScanError(f"{where}ranges and angles must be 1-D, got {r.shape} and {a.shape}")
        if r.shape != a.shape:
            raise ScanError(f"{where}{r.size} ranges but {a.size} beam angles")
        if not np.all(np.isfinite(a)):
            raise ScanError(f"{where}beam angles must be finite")
        if a.size > 1 and not np.all(np.diff(a) > 0):
            raise ScanError(f"{where}beam angles must be strictly increasing")
        if a.size > 1 and a[-1] - a[0] > MAX_ANGLE_SPAN:
            raise ScanError(
                f"{where}beam angles span {a[-1] - a[0]:g} rad, more than two turns: they are "
                f"radians (degrees? the same span in radians is {math.radians(a[-1] - a[0]):g})"
            )
        rmin, rmax = float(self.range_min), float(self.range_max)
        if not (math.isfinite(rmin) and rmin >= 0 and rmax > rmin):
            raise ScanError(f"{where}need 0 <= range_min < range_max, got {rmin}, {rmax}")
        for name in ("odometry", "reference"):
            v = getattr(self, name)
            if v is not None and not isinstance(v, Pose2):
                raise ScanError(f"{where}{name} must be a Pose2 or None, got {type(v).__name__}")
            if v is not None and max(abs(v.x), abs(v.y)) > MAX_POSE_COORDINATE:
                raise ScanError(
                    f"{where}{name} ({v.x:g}, {v.y:g}) lies beyond {MAX_POSE_COORDINATE:g} m "
                    "of its frame's origin: not a pose"
                )
        if self.timestamp is not None:
            t = float(self.timestamp)
            if not math.isfinite(t):
                raise ScanError(f"{where}timestamp must be finite, got {self.timestamp}")
            object.__setattr__(self, "timestamp", t)
        if self.beam_times is not None:
            try:
                bt = np.array(self.beam_times, dtype=np.float64, copy=True)
            except (TypeError, ValueError) as exc:
                raise ScanError(f"{where}beam_times must be a numeric array ({exc})") from None
            if bt.shape != r.shape:
                raise ScanError(f"{where}{r.size} ranges but beam_times of shape {bt.shape}")
            if not np.all(np.isfinite(bt)):
                raise ScanError(f"{where}beam_times must be finite")
            if bt.size and float(np.max(np.abs(bt))) > MAX_SWEEP:
                raise ScanError(
                    f"{where}a beam measured {float(np.max(np.abs(bt))):g} s from the scan's "
                    f"timestamp, more than {MAX_SWEEP:g} s: beam_times are seconds (a 2D "
                    "scanner sweeps in well under one)"
                )
            object.__setattr__(self, "beam_times", _readonly(bt))
        with np.errstate(invalid="ignore"):
            valid = np.isfinite(r) & (r > rmin) & (r < rmax)
        object.__setattr__(self, "ranges", _readonly(r))
        object.__setattr__(self, "angles", _readonly(a))
        object.__setattr__(self, "range_min", rmin)
        object.__setattr__(self, "range_max", rmax)
        object.__setattr__(self, "valid", _readonly(valid))

    @classmethod
    def from_ranges(
        cls,
        ranges,
        *,
        angle_min: float = -math.pi / 2,
        angle_increment: float | None = None,
        fov: float = math.pi,
        **kwargs,
    ) -> Scan:
        """Scan from ranges with evenly spaced beams.

        ``angle_increment`` defaults to ``fov / (N - 1)`` (first and last beam at the edges
        of the field of view), the CARMEN convention for 181/361-beam scans.
        """
        r = np.asarray(ranges, dtype=float).reshape(-1)
        n = r.size
        if angle_increment is None:
            angle_increment = fov / (n - 1) if n > 1 else 0.0
        return cls(r, beam_angles(n, angle_min, angle_increment), **kwargs)

    @property
    def n_beams(self) -> int:
        return int(self.ranges.size)

    @property
    def n_valid(self) -> int:
        return int(self.valid.sum())

    @property
    def no_return(self) -> np.ndarray:
        """``(N,)`` bool: beams that saw nothing within reach, at or beyond ``range_max``
        (a CARMEN max-range reading, ROS's ``+inf``, REP 117). NaN, ``-inf`` and readings at
        or below ``range_min`` are not: they say nothing of the space ahead."""
        with np.errstate(invalid="ignore"):
            return ~self.valid & (self.ranges >= self.range_max)  # NaN compares False

    def points(self) -> np.ndarray:
        """Valid returns as ``(M, 2)`` Cartesian points in the sensor frame (metres)."""
        r = self.ranges[self.valid]
        a = self.angles[self.valid]
        return np.column_stack((r * np.cos(a), r * np.sin(a)))

    def xy(self) -> np.ndarray:
        """All beams as ``(N, 2)`` points; invalid beams are NaN."""
        r = np.where(self.valid, self.ranges, np.nan)
        return np.column_stack((r * np.cos(self.angles), r * np.sin(self.angles)))

    def __repr__(self) -> str:
        return (
            f"Scan({self.source or 'unnamed'}, beams={self.n_beams}, valid={self.n_valid}, "
            f"t={self.timestamp}, odometry={self.odometry}, reference={self.reference})"
        )


def sweep_velocity(
    a: Pose2 | None, b: Pose2 | None, t_a: float | None, t_b: float | None
) -> tuple[float, float, float] | None:
    """The velocity :func:`deskew` takes for a scan, from two poses of its sensor (wheel
    odometry, or the mapper's estimate) at times ``t_a < t_b`` (s): the constant velocity
    carrying ``a`` to ``b`` (:meth:`Pose2.twist_to`). None when a pose or a time is
    missing, the times are not increasing or are more than :data:`MAX_SWEEP` apart (a gap
    in the log says nothing of the motion during the sweep), or the velocity is beyond
    :data:`MAX_SWEEP_SPEED` or :data:`MAX_SWEEP_TURN` (an odometry jump, not a motion).

    >>> sweep_velocity(Pose2(0, 0, 0), Pose2(0.1, 0, 0), 0.0, 0.2)
    (0.5, 0.0, 0.0)
    >>> sweep_velocity(Pose2(0, 0, 0), Pose2(0.1, 0, 0), 0.0, 3.0) is None
    True
    >>> sweep_velocity(Pose2(0, 0, 0), Pose2(20.0, 0, 0), 0.0, 0.2) is None   # 100 m/s
    True
    """
    if a is None or b is None or t_a is None or t_b is None:
        return None
    dt = t_b - t_a
    if not 0.0 < dt <= MAX_SWEEP:
        return None
    v = a.twist_to(b, dt)
    if math.hypot(v[0], v[1]) > MAX_SWEEP_SPEED or abs(v[2]) > MAX_SWEEP_TURN:
        return None
    return v


def sweep_velocity_of(
    scans, k: int, pose, before: bool | None = None
) -> tuple[float, float, float] | None:
    """The velocity of scan ``k``'s sweep along a trajectory of its scans: the step its
    sweep lies in, from ``pose(k)`` to ``pose(k + 1)`` when its beams follow its stamp
    (REP 117), from ``pose(k - 1)`` when they precede it (``before``; None: when its beam
    times are mostly negative, a scan stamped when complete), else the other step (the
    last scan, or one beside a scan without a pose); ``pose(i)`` gives scan ``i``'s sensor
    pose (odometry, map) or None. :func:`sweep_velocity` of the two, at the scans'
    timestamps."""
    if before is None:
        before = measured_before(scans[k])
    steps = (k - 1, k) if before else (k, k - 1)
    for a in steps:
        if 0 <= a and a + 1 < len(scans):
            v = sweep_velocity(pose(a), pose(a + 1), scans[a].timestamp, scans[a + 1].timestamp)
            if v is not None:
                return v
    return None


#: how a driver may have given its beams' times (:func:`retime`): ``"given"`` as REP 117
#: says (the stamp is the first beam's, ``time_increment`` in the order of the ranges);
#: ``"negated"`` the other way round from the stamp (the beams stored against the order
#: they were measured in and the scan stamped at its end, as some 360 degree lidar
#: drivers do); ``"reversed"`` stored against their order, stamped at the start;
#: ``"shifted"`` in order, stamped at the end; ``"none"``: not to be trusted
TIMINGS = ("given", "negated", "reversed", "shifted", "none")


def retime(scan: Scan, timing: str) -> Scan:
    """The scan with its beam times read as ``timing`` (:data:`TIMINGS`) says the driver
    gave them: ``t`` (given), ``-t`` (negated), ``T - t`` (reversed) or ``t - T``
    (shifted), ``T`` the sweep's span; ``"none"`` drops them. A scan without beam times is
    returned as it is.

    ``reversed`` and ``shifted`` move the stamp to the sweep's other end; when that would
    put a beam more than :data:`MAX_SWEEP` from the stamp (times that already run up to
    the stamp from before it, ``-0.9 ... 0`` s, shifted to ``-1.8 ... -0.9``), it is no
    possible reading of the scan, and the reading of the same direction that keeps the
    stamp where the times put it is returned instead: ``given`` for ``shifted``,
    ``negated`` for ``reversed`` (the two readings of a direction differ only by where
    the stamp lies). A log's scans are each read so: a reading possible for a scan is
    taken as it is.

    >>> s = Scan([1.0, 1.0, 1.0], [0.0, 0.1, 0.2], beam_times=[0.0, 0.05, 0.1])
    >>> [retime(s, t).beam_times.tolist() for t in ("negated", "reversed", "shifted")]
    [[-0.0, -0.05, -0.1], [0.1, 0.05, 0.0], [-0.1, -0.05, 0.0]]
    >>> late = Scan([1.0, 1.0, 1.0], [0.0, 0.1, 0.2], beam_times=[-0.9, -0.45, 0.0])
    >>> retime(late, "shifted").beam_times.tolist()   # not -1.8 ... -0.9: as given
    [-0.9, -0.45, 0.0]
    """
    if timing not in TIMINGS:
        raise ScanError(f"retime: timing must be one of {', '.join(TIMINGS)}, got {timing!r}")
    t = scan.beam_times
    if t is None or timing == "given":
        return scan
    if timing == "none":
        return replace(scan, beam_times=None)
    span = float(t.max() - t.min()) if t.size else 0.0
    new = {"negated": -t, "reversed": span - t, "shifted": t - span}[timing]
    if new.size and float(np.max(np.abs(new))) > MAX_SWEEP:  # (never negated: |-t| = |t|)
        return retime(scan, _SAME_DIRECTION[timing])
    return replace(scan, beam_times=new)


#: the reading :func:`retime` takes for one that would move a beam beyond MAX_SWEEP
_SAME_DIRECTION = {"shifted": "given", "reversed": "negated"}


def measured_before(scan: Scan) -> bool:
    """Whether the scan's beams were measured before its stamp (beam times mostly
    negative: stamped when the sweep was complete)."""
    t = scan.beam_times
    return t is not None and t.size > 0 and float(t.mean()) < 0


def deskew_along(scans, k: int, pose, timing: str = "given") -> Scan:
    """Scan ``k`` of ``scans`` de-skewed (:func:`deskew`) along their trajectory
    ``pose(i)`` (odometry, map; Pose2 or None), its beam times read as ``timing`` says
    (:func:`retime`), at the velocity of the step its sweep lies in
    (:func:`sweep_velocity_of`); as it is without beam times or a velocity."""
    s = retime(scans[k], timing)
    if s.beam_times is None:
        return s
    v = sweep_velocity_of(scans, k, pose, measured_before(s))
    return s if v is None else deskew(s, v)


def _sweep_poses(times: np.ndarray, velocity) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(theta, x, y)`` arrays: the sensor's pose at each of ``times`` (s) in its frame at
    time 0, moving at the constant body ``velocity`` ``(vx, vy, omega)`` (m/s, m/s,
    rad/s): the exponential of the twist, exact on the arc."""
    vx, vy, w = (float(v) for v in velocity)
    th = w * times
    small = np.abs(th) < 1e-6
    safe = np.where(small, 1.0, th)
    a = np.where(small, 1.0 - th * th / 6.0, np.sin(safe) / safe)  # sin(th) / th
    b = np.where(small, 0.5 * th, (1.0 - np.cos(safe)) / safe)  # (1 - cos(th)) / th
    return th, times * (vx * a - vy * b), times * (vx * b + vy * a)


def deskew(scan: Scan, velocity) -> Scan:
    """The scan as its sensor would have seen it at ``scan.timestamp``, had it stood still
    for its sweep: each beam measured ``beam_times[i]`` seconds after the timestamp, from
    where the sensor had moved by then, is expressed in the sensor's frame at the
    timestamp (beyond the paper, which takes a scan as one instant).

    ``velocity`` is the sensor's ``(vx, vy, omega)`` in its own frame (m/s, m/s, rad/s),
    taken as constant over the sweep (the twist between two poses ``dt`` apart,
    :func:`scanclique.geometry.Pose2.twist_to`, say). A valid return becomes the range and
    angle of its point in the frame at the timestamp; an invalid one (NaN, inf, out of
    limits) keeps its range, its angle turned with the sensor; a valid return the move
    would take out of ``(range_min, range_max)`` keeps its range too (its validity is the
    sensor's). The beams are sorted by their new angles (strictly increasing); a full
    circle whose last beams turned beyond its first (turning counter-clockwise) has them
    wrapped back among the first, so that no direction is seen twice. Everything else
    is kept; ``beam_times`` becomes None. A scan without ``beam_times``, or standing
    still, is returned as it is.

    >>> s = Scan([2.0, 2.0], [0.0, 0.1], beam_times=[0.0, 0.1])
    >>> d = deskew(s, (0.0, 0.0, 1.0))   # turning at 1 rad/s: the second beam at 0.2 rad
    >>> d.angles.round(6).tolist(), d.ranges.tolist(), d.beam_times
    ([0.0, 0.2], [2.0, 2.0], None)
    >>> deskew(s, (1.0, 0.0, 0.0)).ranges.round(4).tolist()   # 1 m/s ahead: 0.1 m on
    [2.0, 2.0995]
    """
    v = np.asarray(velocity, dtype=float).reshape(-1)
    if v.size != 3 or not np.all(np.isfinite(v)):
        raise ScanError(f"{scan.source or 'deskew'}: velocity must be three finite numbers")
    if scan.beam_times is None or not np.any(v) or scan.n_beams == 0:
        return scan
    th, tx, ty = _sweep_poses(scan.beam_times, v)
    a = scan.angles + th
    r = scan.ranges.copy()
    ok = scan.valid
    px = r[ok] * np.cos(a[ok]) + tx[ok]
    py = r[ok] * np.sin(a[ok]) + ty[ok]
    moved = np.hypot(px, py)
    keep = (moved > scan.range_min) & (moved < scan.range_max)
    turn = np.arctan2(py, px) - a[ok]
    turn = (turn + np.pi) % (2.0 * np.pi) - np.pi
    idx = np.flatnonzero(ok)[keep]
    r[idx] = moved[keep]
    a[idx] += turn[keep]
    if a.max() - a.min() >= 2.0 * np.pi:  # a full circle turned onto itself: one turn
        a = a.min() + np.mod(a - a.min(), 2.0 * np.pi)
    order = np.argsort(a, kind="stable")
    r, a = r[order], a[order]
    for k in np.flatnonzero(np.diff(a) <= 0) + 1:  # ties (measure zero): kept in order
        a[k] = max(a[k], np.nextafter(a[k - 1], np.inf))
    return Scan(
        r, a, scan.range_min, scan.range_max, scan.timestamp, scan.odometry,
        scan.reference, scan.source,
    )  # fmt: skip
