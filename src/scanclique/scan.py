"""The scan model: one batch observation of a 2D range sensor (stage 1 of the pipeline).

Readers build :class:`Scan` records; nothing downstream parses files. A scan keeps the
ranges exactly as given (copied and made read-only): invalid returns (NaN, inf, at or
below ``range_min``, at or beyond ``range_max``) are *masked* by :attr:`Scan.valid`, never
altered, and never become features.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ._records import readonly as _readonly
from .errors import ScanError
from .geometry import Pose2

__all__ = ["Scan", "beam_angles", "MAX_ANGLE_SPAN", "MAX_POSE_COORDINATE"]

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
    """

    ranges: np.ndarray
    angles: np.ndarray
    range_min: float = 0.0
    range_max: float = 80.0
    timestamp: float | None = None
    odometry: Pose2 | None = None
    reference: Pose2 | None = None
    source: str = ""
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
