"""Reader for CARMEN log files (plain, gzip or bzip2): laser messages become :class:`Scan` records.

Messages read (one per line, fields separated by white space)::

    FLASER n r_1 .. r_n x y theta odom_x odom_y odom_theta ipc_timestamp hostname logger_timestamp
    RLASER (same layout as FLASER)
    LASER3, LASER4 n r_1 .. r_n ipc_timestamp hostname logger_timestamp (or the FLASER layout)
    ROBOTLASER1 laser_type start_angle fov angular_res max_range accuracy remission_mode
        n r_1 .. r_n m rem_1 .. rem_m laser_x laser_y laser_theta robot_x robot_y robot_theta
        tv rv forward_safety side_safety turn_axis timestamp hostname logger_timestamp
    ROBOTLASER2 (same layout as ROBOTLASER1)
    RAWLASER1 .. RAWLASER4 laser_type start_angle fov angular_res max_range accuracy
        remission_mode n r_1 .. r_n m rem_1 .. rem_m timestamp hostname logger_timestamp
    ODOM x y theta tv rv accel timestamp hostname logger_timestamp
    PARAM name value ipc_timestamp hostname logger_timestamp

Lines starting with ``#`` are comments, blank lines are ignored, and any other message
type (``SYNC``, ``TRUEPOS``, ``NEFF``, ...) is skipped and counted in
:attr:`CarmenLog.skipped` under ``"unknown:<TYPE>"`` (logged at debug level).

Conventions
-----------
* **One scan per laser message, in file order.** ``Scan.source`` is ``"<file>:<line>"``.
* **FLASER / RLASER beams**: ``n`` beams starting at ``-pi/2`` (the sensor's right), spaced
  ``pi / (2 * (n // 2))`` counter-clockwise: 180 and 181 beams are 1 degree apart, 360 and
  361 beams 0.5 degree (:func:`flaser_angles`). RLASER scans are kept in their own sensor
  frame with the same angles (no ``pi`` is added: the rear laser's mounting is for the
  caller to apply). ``x y theta`` becomes ``Scan.reference`` and ``odom_x odom_y odom_theta``
  ``Scan.odometry``; the timestamp is ``ipc_timestamp``.
* **No-return readings.** FLASER, RLASER, LASER3 and LASER4 carry no maximum range, so
  ``Scan.range_max`` is the reader's ``max_range`` (default :data:`FLASER_MAX_RANGE`,
  80 m): readings at or beyond it are masked as invalid (they are kept as logged). The shared
  logs mark no return with 81.83 (Intel) and 81.91 (CSAIL, Freiburg 079), while their
  largest genuine readings are about 25.4, 35.1 and 36.6 m, so 80 m separates the two in
  all three; a SICK LMS cannot measure beyond about 80 m anyway. Logs that mark no return
  with a smaller value (some use 50) are recognised: the value repeats exactly across many
  beams at the top of the range distribution of the first 200 such messages
  (:func:`detect_no_return`); it then becomes those scans' ``range_max`` (a reading exactly
  equal to ``range_max`` is invalid), is recorded in :attr:`CarmenLog.no_return` and
  logged. Passing ``max_range`` turns the detection off.
* **LASER3 / LASER4** (CARMEN's old-format third and fourth lasers): the beams of FLASER.
  CARMEN's logger writes them without a pose, so ``Scan.odometry`` is interpolated from
  the ODOM messages as for RAWLASER and ``Scan.reference`` is None; a line in the FLASER
  layout (six pose fields, as some converters write them) is read as FLASER is. The
  field count tells the two apart.
* **ROBOTLASER1 / ROBOTLASER2** (the front and the rear laser): angles
  ``start_angle + i * angular_res``; ``Scan.range_max`` is the message's ``max_range``
  (the reader's ``max_range`` when that is not positive).
  ``Scan.odometry`` is the *laser* pose ``laser_x laser_y laser_theta`` (the pose of the
  sensor, which is what a Scan's poses describe; the robot pose differs by the mounting
  offset) and ``Scan.reference`` is None: the message does not say whether its poses are
  raw odometry or corrected, so nothing is claimed as reference.
* **RAWLASER1..4** carry no pose: ``Scan.odometry`` is interpolated from the log's ODOM
  messages at the scan's timestamp (linear in x and y, along the shorter arc in theta);
  None outside the time span of the ODOM messages. ``Scan.reference`` is None.
* **PARAM** values are recorded as strings in :attr:`CarmenLog.params` (a later value of
  the same name replaces an earlier one); they do not change how scans are read.
* An empty file (or one with only comments) gives no scans.

Errors
------
A malformed line raises :class:`~scanclique.errors.ParseError` naming the file, the 1-based
line and the field, with what was expected and what was found, e.g.
``intel.log:1042: FLASER expects 180 ranges, found 179`` or
``intel.log:7: range[17]: FLASER expects a number, found 'abc'``. NaN and inf *ranges* are
not errors (they are kept and masked by :class:`~scanclique.scan.Scan`); non-finite poses and
timestamps are. Counts above ``max_beams`` are errors (a corrupt count would otherwise
allocate absurdly). Binary data, undecodable bytes and truncated gzip or bzip2 files
raise ``ParseError`` too (see :func:`scanclique.io.text.read_lines`). With
``strict=False`` malformed or undecodable lines are skipped, counted in
:attr:`CarmenLog.skipped` under ``"malformed:<TYPE>"`` / ``"undecodable"`` (a truncated
or corrupt compressed stream under ``"truncated gzip"`` or ``"truncated bzip2"``, keeping
the part that could be read) and logged at warning level.

Examples
--------
>>> import tempfile, pathlib
>>> path = pathlib.Path(tempfile.mkdtemp()) / "tiny.log"
>>> _ = path.write_text(
...     "# a comment\\n"
...     "PARAM robot_front_laser_max 81.9 0.0 host 0.0\\n"
...     "FLASER 4 1.0 2.0 81.91 3.0 0.5 0.0 0.1 0.4 0.0 0.1 12.5 host 12.5\\n"
...     "SYNC whatever\\n"
... )
>>> log = read_carmen(path)
>>> scan = log.scans[0]
>>> scan.n_beams, scan.n_valid, scan.timestamp, scan.source
(4, 3, 12.5, 'tiny.log:3')
>>> np.degrees(scan.angles).round(6).tolist()
[-90.0, -45.0, 0.0, 45.0]
>>> scan.reference, scan.odometry
(Pose2(x=0.5000, y=0.0000, theta=0.1000), Pose2(x=0.4000, y=0.0000, theta=0.1000))
>>> dict(log.params), dict(log.skipped)
({'robot_front_laser_max': '81.9'}, {'unknown:SYNC': 1})
"""

from __future__ import annotations

import logging
import math
import os
from collections.abc import Callable, Iterator, Mapping
from dataclasses import dataclass
from dataclasses import field as _field
from types import MappingProxyType

import numpy as np

from ..errors import ArgumentError, ConfigError, ParseError, ScanError
from ..geometry import Pose2, pose_at
from ..scan import Scan, beam_angles
from .text import (
    LineSource,
    parse_count,
    parse_float_fields,
    parse_plain_float_fields,
    plain_float,
    plain_number,
)

__all__ = [
    "FLASER_MAX_RANGE",
    "DEFAULT_MAX_BEAMS",
    "LASER_MESSAGES",
    "KNOWN_MESSAGES",
    "MAIN_LASER_ORDER",
    "CarmenLog",
    "flaser_angles",
    "detect_no_return",
    "interpolate_odometry",
    "parse_carmen",
    "iter_carmen",
    "read_carmen",
    "check_laser",
    "select_laser",
]

logger = logging.getLogger(__name__)

FLASER_MAX_RANGE = 80.0
"""Default ``Scan.range_max`` (metres) for messages without a maximum range (FLASER, RLASER)."""

DEFAULT_MAX_BEAMS = 100_000
"""Largest accepted beam (or remission) count in one message."""

LASER_MESSAGES = frozenset(
    {
        "FLASER",
        "RLASER",
        "LASER3",
        "LASER4",
        "ROBOTLASER1",
        "ROBOTLASER2",
        "RAWLASER1",
        "RAWLASER2",
        "RAWLASER3",
        "RAWLASER4",
    }
)
"""CARMEN message types that become scans."""

KNOWN_MESSAGES = LASER_MESSAGES | {"ODOM", "PARAM"}
"""CARMEN message types this reader interprets (others are skipped and counted)."""

MAIN_LASER_ORDER = (
    "FLASER",
    "ROBOTLASER1",
    "RAWLASER1",
    "RAWLASER2",
    "RAWLASER3",
    "RAWLASER4",
    "LASER3",
    "LASER4",
    "RLASER",
    "ROBOTLASER2",
)
"""Which laser is a log's main one when it holds several (:func:`select_laser`): the front
laser (FLASER, which carries the odometry and the reference pose, before ROBOTLASER1, which
some logs write beside it for the same scans), then the lowest-numbered raw laser, the
old-format third and fourth, the rear laser last (RLASER before ROBOTLASER2, as at the
front)."""


def check_laser(laser) -> None:
    """``laser`` is None, ``"main"`` or a laser message type (:data:`LASER_MESSAGES`), else
    an :class:`~scanclique.errors.ArgumentError` listing them (:func:`select_laser`'s
    argument, checked by :func:`~scanclique.io.read_scans` before it reads a file)."""
    if laser is not None and laser != "main" and laser not in LASER_MESSAGES:
        raise ArgumentError(
            f"laser must be 'main' or a CARMEN laser message type "
            f"({', '.join(MAIN_LASER_ORDER)}), got {laser!r}"
        )


def select_laser(log: CarmenLog, laser: str | None) -> tuple[list[Scan], str | None]:
    """The scans of one laser of ``log``, and a sentence for the user when others were
    left out (None when nothing was).

    A trajectory is one sensor's: a log with a front and a rear laser (FLASER and RLASER,
    or RAWLASER1 and RAWLASER2) interleaves two views in file order, which a mapper would
    take for one robot jumping back and forth.

    Parameters
    ----------
    log : CarmenLog
    laser : str or None
        None: every laser message (:func:`~scanclique.io.read_scans`' default); a sentence
        only when the log holds more than one type. ``"main"``: the first of
        :data:`MAIN_LASER_ORDER` the log holds. A message type (``"RLASER"``): its scans.

    Raises
    ------
    ArgumentError
        ``laser`` is not None, ``"main"`` or a laser message type, or the log holds scans
        but none of that type.

    >>> from scanclique.scan import Scan
    >>> s = Scan(np.array([1.0]), np.array([0.0]))
    >>> log = CarmenLog("two.log", (s, s, s), ("FLASER", "RLASER", "FLASER"), {}, {},
    ...                 np.empty((0, 4)))
    >>> scans, note = select_laser(log, "main")
    >>> len(scans)
    2
    >>> print(note)  # doctest: +NORMALIZE_WHITESPACE
    two.log holds 2 FLASER and 1 RLASER scans: using the 2 FLASER scans (--laser RLASER for
    the others)
    """
    check_laser(laser)
    counts: dict[str, int] = {}
    for t in log.message_types:
        counts[t] = counts.get(t, 0) + 1
    name = os.path.basename(log.path)
    held = " and ".join(f"{counts[t]} {t}" for t in MAIN_LASER_ORDER if t in counts)
    others = [t for t in MAIN_LASER_ORDER if t in counts]
    if laser is None:
        if len(counts) < 2:
            return list(log.scans), None
        return list(log.scans), (
            f"{name} holds {held} scans, interleaved in file order: one trajectory needs one "
            f"sensor (laser='main' or --laser {others[0]} keeps the {others[0]} scans)"
        )
    if not counts:
        return [], None
    pick = others[0] if laser == "main" else laser
    if pick not in counts:
        raise ArgumentError(f"{name} holds no {pick} scans (it holds {held})")
    if len(counts) < 2:
        return list(log.scans), None
    rest = " or ".join(t for t in others if t != pick)
    return [s for s, t in zip(log.scans, log.message_types, strict=True) if t == pick], (
        f"{name} holds {held} scans: using the {counts[pick]} {pick} scans "
        f"(--laser {rest} for the others)"
    )


_FLASER_KINDS = frozenset({"FLASER", "RLASER", "LASER3", "LASER4"})
"""Messages with FLASER's beams and no maximum range (the no-return probe looks at them)."""

NO_RETURN_PROBE_SCANS = 200
"""FLASER-like messages (RLASER, LASER3, LASER4 too) at the head of a log looked at to
find its no-return value."""

NO_RETURN_MIN_COUNT = 10
"""Readings that must sit exactly at a value for it to be taken as the no-return mark."""

_MAX_WARNINGS = 10  # malformed lines logged one by one; the rest are summarised

_FLASER_TAIL = ("x", "y", "theta", "odom_x", "odom_y", "odom_theta", "ipc_timestamp")
_LASER_HEADER = (
    "laser_type",
    "start_angle",
    "fov",
    "angular_res",
    "max_range",
    "accuracy",
    "remission_mode",
)
_ROBOTLASER_TAIL = (
    "laser_x",
    "laser_y",
    "laser_theta",
    "robot_x",
    "robot_y",
    "robot_theta",
    "tv",
    "rv",
    "forward_safety",
    "side_safety",
    "turn_axis",
    "timestamp",
)
_ODOM_FIELDS = ("x", "y", "theta", "tv", "rv", "accel", "timestamp")


@dataclass(frozen=True, slots=True, eq=False)
class CarmenLog:
    """Everything :func:`read_carmen` got from a CARMEN log.

    Attributes
    ----------
    path : str
        The file, as given.
    scans : tuple of Scan
        One per laser message, in file order.
    message_types : tuple of str
        The message type of each scan (``"FLASER"``, ``"RLASER"``, ``"ROBOTLASER1"``, ...),
        parallel to :attr:`scans`.
    params : Mapping[str, str]
        PARAM name -> value (as logged, a string).
    skipped : Mapping[str, int]
        Lines not turned into anything, per reason: ``"unknown:<TYPE>"``,
        ``"malformed:<TYPE>"``, ``"undecodable"``, and ``"truncated gzip"`` or
        ``"truncated bzip2"`` (1: the compressed stream could be read only in part); all
        but the first only with ``strict=False``. Comments and blank lines are not counted.
    odom : ndarray, shape (M, 4)
        The ODOM messages in file order, columns ``timestamp, x, y, theta``.
    no_return : Mapping[str, float]
        Message type -> the no-return value found in the log below 80 m
        (:func:`detect_no_return`), which became those scans' ``range_max``; empty when
        none was found or ``max_range`` was given.
    """

    path: str
    scans: tuple[Scan, ...]
    message_types: tuple[str, ...]
    params: Mapping[str, str]
    skipped: Mapping[str, int]
    odom: np.ndarray
    no_return: Mapping[str, float] = _field(default_factory=dict)

    def __post_init__(self) -> None:
        object.__setattr__(self, "scans", tuple(self.scans))
        object.__setattr__(self, "message_types", tuple(self.message_types))
        object.__setattr__(self, "params", MappingProxyType(dict(self.params)))
        object.__setattr__(self, "skipped", MappingProxyType(dict(self.skipped)))
        object.__setattr__(self, "no_return", MappingProxyType(dict(self.no_return)))
        odom = np.array(self.odom, dtype=np.float64).reshape(-1, 4)
        odom.setflags(write=False)
        object.__setattr__(self, "odom", odom)

    @property
    def n_skipped(self) -> int:
        """Total number of skipped lines."""
        return sum(self.skipped.values())

    def __repr__(self) -> str:
        return (
            f"CarmenLog({os.path.basename(self.path)!r}, scans={len(self.scans)}, "
            f"params={len(self.params)}, odom={len(self.odom)}, skipped={dict(self.skipped)})"
        )


def detect_no_return(rows, max_range: float = FLASER_MAX_RANGE) -> tuple[float, int, int] | None:
    """The value a log writes for "no return", when it is below ``max_range``.

    Some CARMEN logs mark a beam without return by a fixed value well below the sensor's
    80 m (50 m is in use); taken as a hit it makes phantom features tens of metres out.
    Such a value repeats *exactly* across many beams at the very top of the range
    distribution, while genuine long readings vary from beam to beam. The rule: among the
    finite readings below ``max_range``, take the most frequent exact value of the top 2 %;
    it is the no-return mark when it occurs at least :data:`NO_RETURN_MIN_COUNT` times in
    at least 3 scans, at most a tenth as many readings lie above it, and no more readings
    lie within 5 % below it than at it exactly.

    Parameters
    ----------
    rows : sequence of 1-D arrays
        Ranges (metres) of some scans of one laser.
    max_range : float
        Readings at or beyond it are no return already (80 m by default).

    Returns
    -------
    (value, count, n_scans) or None
        The mark, how many readings sit at it and in how many scans; None when no value
        qualifies (the logs that mark no return at 80 m or more, such as the shared ones).

    >>> rng = np.random.default_rng(0)
    >>> rows = [np.where(rng.random(180) < 0.2, 50.0, rng.uniform(0.5, 20, 180))
    ...         for _ in range(20)]
    >>> detect_no_return(rows)[0]
    50.0
    >>> detect_no_return([rng.uniform(0.5, 20, 180) for _ in range(20)]) is None
    True
    """
    if not len(rows):
        return None
    r = np.concatenate([np.asarray(x, dtype=np.float64).ravel() for x in rows])
    r = r[np.isfinite(r) & (r > 0) & (r < max_range)]
    if r.size < NO_RETURN_MIN_COUNT:
        return None
    top = r[r >= np.quantile(r, 0.98)]
    values, counts = np.unique(top, return_counts=True)
    k = int(np.argmax(counts))
    value, count = float(values[k]), int(counts[k])
    if count < NO_RETURN_MIN_COUNT:
        return None
    above = int(np.count_nonzero(r > value))
    near = int(np.count_nonzero((r >= 0.95 * value) & (r < value)))
    n_rows = sum(1 for x in rows if np.any(np.asarray(x) == value))
    if above * 10 > count or near > count or n_rows < 3:
        return None
    return value, count, n_rows


def flaser_angles(n: int) -> np.ndarray:
    """Beam angles of an ``n``-beam FLASER/RLASER message (radians, sensor frame).

    The first beam points right (``-pi/2``); beams are ``pi / (2 * (n // 2))`` apart, so
    180 and 181 beams are 1 degree apart and 360 and 361 beams 0.5 degree.

    >>> np.degrees(flaser_angles(181)[[0, 90, 180]]).round(9).tolist()
    [-90.0, 0.0, 90.0]
    >>> np.degrees(flaser_angles(180)[[0, 179]]).round(9).tolist()
    [-90.0, 89.0]
    """
    inc = math.pi / (2 * (n // 2)) if n >= 2 else 0.0
    return beam_angles(n, -math.pi / 2, inc)


def interpolate_odometry(odom: np.ndarray, t: float) -> Pose2 | None:
    """Odometry pose at time ``t`` from timestamped poses, or None outside their time span.

    Parameters
    ----------
    odom : array_like, shape (M, 4)
        Rows ``timestamp, x, y, theta`` in any order (sorted here, stably).
    t : float
        Query time, same clock.

    Returns
    -------
    Pose2 or None
        Linear interpolation between the two poses bracketing ``t`` (x and y linearly,
        theta along the shorter arc); the pose itself at an exact timestamp (the last one
        logged, if several share it); None if ``t`` is before the first or after the last
        timestamp, or there are no poses.

    >>> odom = np.array([[0.0, 0.0, 0.0, 3.0], [2.0, 2.0, 4.0, -3.0]])
    >>> interpolate_odometry(odom, 1.0)
    Pose2(x=1.0000, y=2.0000, theta=-3.1416)
    >>> interpolate_odometry(odom, 2.5) is None
    True
    """
    o = np.asarray(odom, dtype=np.float64).reshape(-1, 4)
    o = o[np.argsort(o[:, 0], kind="stable")]
    return pose_at(o[:, 0], o[:, 1:], t)


# ---------------------------------------------------------------------------------------
# Message parsers: each takes the tokens of one line and a context, and returns a pending
# scan record (or None) or raises ParseError through ``ctx.err``.
# ---------------------------------------------------------------------------------------
@dataclass(slots=True)
class _Pending:
    line_no: int
    kind: str
    ranges: np.ndarray
    angles: np.ndarray
    range_max: float
    timestamp: float
    odometry: Pose2 | None
    reference: Pose2 | None
    needs_odometry: bool


class _Context:
    """Per-file parsing state (internal)."""

    def __init__(self, path: str, max_beams: int, max_range: float):
        self.path = path
        self.max_beams = max_beams
        self.max_range = max_range
        self.line_no = 0
        self.kind = ""
        #: the parser of number fields: parse_float_fields, or its twin that does not look
        #: at them again when the line is plain_number text (set per line)
        self.floats = parse_float_fields
        self.params: dict[str, str] = {}
        self.odom: list[tuple[float, float, float, float]] = []
        self._angles: dict[int, np.ndarray] = {}

    def err(self, field: str | None, message: str) -> ParseError:
        return ParseError(self.path, self.line_no, f"{self.kind} {message}", field=field)

    def flaser_angles(self, n: int) -> np.ndarray:
        a = self._angles.get(n)
        if a is None:
            a = self._angles[n] = flaser_angles(n)
        return a


def _is_number(token: str) -> bool:
    try:
        plain_float(token)
    except ValueError:
        return False
    return True


def _check_pose(values, names, ctx: _Context) -> None:
    for v, name in zip(values, names, strict=True):
        if not math.isfinite(v):
            raise ctx.err(name, f"expects a finite pose, found {v!r}")


def _pose(values, names, ctx: _Context) -> Pose2:
    _check_pose(values, names, ctx)
    return Pose2(*values)


def _timestamp(value: float, name: str, ctx: _Context) -> float:
    if not math.isfinite(value):
        raise ctx.err(name, f"expects a finite timestamp, found {value!r}")
    return value


def _parse_flaser(tok: list[str], ctx: _Context) -> _Pending:
    if len(tok) < 2:
        raise ctx.err("num_readings", "expects a beam count, found nothing (truncated line?)")
    n = parse_count(tok[1], "num_readings", ctx.max_beams, ctx.err)
    expected = n + 11
    if len(tok) != expected:
        found = len(tok) - 11
        tail_ok = (
            found >= 0
            and not _is_number(tok[-2])
            and all(_is_number(t) for t in tok[-9:-2])
            and _is_number(tok[-1])
        )
        if tail_ok:
            raise ctx.err(None, f"expects {n} ranges, found {found}")
        raise ctx.err(
            None,
            f"with {n} ranges expects {expected} fields, found {len(tok)} (truncated line?)",
        )
    last = n + 2

    def name(i: int) -> str:
        return f"range[{i - 2}]" if i < last else _FLASER_TAIL[i - last]

    v = ctx.floats(tok, 2, n + 9, name, ctx.err)
    tail = v[n:].tolist()
    reference = _pose(tail[0:3], _FLASER_TAIL[0:3], ctx)
    odometry = _pose(tail[3:6], _FLASER_TAIL[3:6], ctx)
    t = _timestamp(tail[6], "ipc_timestamp", ctx)
    return _Pending(
        ctx.line_no,
        ctx.kind,
        v[:n],
        ctx.flaser_angles(n),
        ctx.max_range,
        t,
        odometry,
        reference,
        False,
    )


def _parse_old_laser(tok: list[str], ctx: _Context) -> _Pending:
    """LASER3 / LASER4: ``n r_1 .. r_n ipc_timestamp hostname logger_timestamp`` as
    CARMEN's logger writes them (no pose: the odometry comes from ODOM), or the FLASER
    layout, told apart by the field count."""
    if len(tok) < 2:
        raise ctx.err("num_readings", "expects a beam count, found nothing (truncated line?)")
    n = parse_count(tok[1], "num_readings", ctx.max_beams, ctx.err)
    if len(tok) == n + 11:
        return _parse_flaser(tok, ctx)
    if len(tok) != n + 5:
        raise ctx.err(
            None,
            f"with {n} ranges expects {n + 5} fields (or {n + 11} in the FLASER layout), "
            f"found {len(tok)} (truncated line?)",
        )
    v = ctx.floats(
        tok, 2, n + 3, lambda i: f"range[{i - 2}]" if i < n + 2 else "ipc_timestamp", ctx.err
    )
    t = _timestamp(float(v[n]), "ipc_timestamp", ctx)
    return _Pending(
        ctx.line_no, ctx.kind, v[:n], ctx.flaser_angles(n), ctx.max_range, t, None, None, True
    )


def _parse_laser_header(tok: list[str], ctx: _Context):
    """Shared head of ROBOTLASERx/RAWLASERx: header, ranges, remissions; returns the pieces."""
    if len(tok) < 9:
        raise ctx.err(
            None, f"expects at least 9 leading fields, found {len(tok)} (truncated line?)"
        )
    header = ctx.floats(tok, 1, 8, lambda i: _LASER_HEADER[i - 1], ctx.err).tolist()
    _, start, _fov, res, max_range, _acc, _mode = header
    for value, field in ((start, "start_angle"), (res, "angular_res")):
        if not math.isfinite(value):
            raise ctx.err(field, f"expects a finite angle, found {value!r}")
    n = parse_count(tok[8], "num_readings", ctx.max_beams, ctx.err)
    if n > 1 and not res > 0:
        raise ctx.err("angular_res", f"expects a positive angular resolution, found {res!r}")
    k = 9 + n  # index of num_remissions
    if len(tok) <= k:
        raise ctx.err(
            None, f"expects {n} ranges and a remission count, found {len(tok) - 9} fields"
        )
    ranges = ctx.floats(tok, 9, k, lambda i: f"range[{i - 9}]", ctx.err)
    m = parse_count(tok[k], "num_remissions", ctx.max_beams, ctx.err)
    if not (math.isfinite(max_range) and max_range > 0):
        max_range = ctx.max_range
    return n, m, k + 1 + m, ranges, beam_angles(n, start, res), float(max_range)


def _parse_robotlaser(tok: list[str], ctx: _Context) -> _Pending:
    n, m, tail_start, ranges, angles, rmax = _parse_laser_header(tok, ctx)
    expected = tail_start + len(_ROBOTLASER_TAIL) + 2
    if len(tok) != expected:
        raise ctx.err(
            None,
            f"with {n} ranges and {m} remissions expects {expected} fields, found {len(tok)}",
        )
    ctx.floats(
        tok, tail_start - m, tail_start, lambda i: f"remission[{i - tail_start + m}]", ctx.err
    )
    tail = ctx.floats(
        tok, tail_start, tail_start + 12, lambda i: _ROBOTLASER_TAIL[i - tail_start], ctx.err
    ).tolist()
    laser_pose = _pose(tail[0:3], _ROBOTLASER_TAIL[0:3], ctx)
    _check_pose(tail[3:6], _ROBOTLASER_TAIL[3:6], ctx)  # the robot pose must be valid too
    t = _timestamp(tail[11], "timestamp", ctx)
    return _Pending(ctx.line_no, ctx.kind, ranges, angles, rmax, t, laser_pose, None, False)


def _parse_rawlaser(tok: list[str], ctx: _Context) -> _Pending:
    n, m, tail_start, ranges, angles, rmax = _parse_laser_header(tok, ctx)
    expected = tail_start + 3
    if len(tok) != expected:
        raise ctx.err(
            None,
            f"with {n} ranges and {m} remissions expects {expected} fields, found {len(tok)}",
        )
    ctx.floats(
        tok, tail_start - m, tail_start, lambda i: f"remission[{i - tail_start + m}]", ctx.err
    )
    t = float(ctx.floats(tok, tail_start, tail_start + 1, lambda i: "timestamp", ctx.err)[0])
    t = _timestamp(t, "timestamp", ctx)
    return _Pending(ctx.line_no, ctx.kind, ranges, angles, rmax, t, None, None, True)


def _parse_odom(tok: list[str], ctx: _Context) -> None:
    if len(tok) != 10:
        raise ctx.err(None, f"expects 10 fields, found {len(tok)}")
    v = ctx.floats(tok, 1, 8, lambda i: _ODOM_FIELDS[i - 1], ctx.err).tolist()
    _check_pose(v[0:3], _ODOM_FIELDS[0:3], ctx)
    t = _timestamp(v[6], "timestamp", ctx)
    ctx.odom.append((t, v[0], v[1], v[2]))


def _parse_param(tok: list[str], ctx: _Context) -> None:
    if len(tok) < 3:
        raise ctx.err(None, f"expects a name and a value, found {len(tok) - 1} fields")
    value = " ".join(tok[2:-3]) if len(tok) >= 6 else " ".join(tok[2:])
    name = tok[1]
    if name in ctx.params and ctx.params[name] != value:
        logger.debug("%s:%d: PARAM %s redefined", ctx.path, ctx.line_no, name)
    ctx.params[name] = value


_PARSERS: dict[str, Callable[[list[str], _Context], _Pending | None]] = {
    "FLASER": _parse_flaser,
    "RLASER": _parse_flaser,
    "LASER3": _parse_old_laser,
    "LASER4": _parse_old_laser,
    "ROBOTLASER1": _parse_robotlaser,
    "ROBOTLASER2": _parse_robotlaser,
    **{f"RAWLASER{k}": _parse_rawlaser for k in range(1, 5)},
    "ODOM": _parse_odom,
    "PARAM": _parse_param,
}


class _CarmenReader:
    """One pass over the lines of a CARMEN log (internal).

    :meth:`scans` yields ``(index, message type, Scan)`` in file order for the laser
    messages whose index ``wanted`` accepts (all when None); after it is exhausted,
    :attr:`n_scans` (None when it stopped early), :attr:`ctx` (PARAM values, ODOM poses)
    and :attr:`skipped` are complete. In strict mode a laser message that is not wanted is
    counted from its type token alone, never parsed; with ``strict=False`` every line is
    parsed, since a malformed line is skipped and must not count as a scan.
    """

    def __init__(self, lines, strict: bool, max_beams: int, max_range: float | None):
        detect = max_range is None
        if detect:
            max_range = FLASER_MAX_RANGE
        if not (
            isinstance(max_range, (int, float))
            and not isinstance(max_range, bool)
            and math.isfinite(max_range)
            and max_range > 0
        ):
            raise ConfigError(f"max_range must be a positive number, got {max_range!r}")
        if isinstance(max_beams, bool) or not isinstance(max_beams, (int, np.integer)):
            raise ConfigError(f"max_beams must be a positive integer, got {max_beams!r}")
        if max_beams < 1:
            raise ConfigError(f"max_beams must be a positive integer, got {max_beams!r}")
        self.lines = lines
        self.strict = strict
        self.ctx = _Context(lines.path, int(max_beams), float(max_range))
        self.skipped: dict[str, int] = {}
        self.n_scans: int | None = None
        self._n_warned = 0
        #: message type -> the no-return value detected (FLASER-like, below max_range)
        self.no_return: dict[str, float] = {}
        self._probing = detect
        self._sample: dict[str, list[np.ndarray]] = {}
        self._n_sampled = 0

    def _skip_malformed(self, reason: str, exc: ParseError) -> None:
        self.skipped[reason] = self.skipped.get(reason, 0) + 1
        self._n_warned += 1
        if self._n_warned <= _MAX_WARNINGS:
            logger.warning("skipped malformed line: %s", exc)

    def _build(self, p: _Pending, odom: np.ndarray) -> Scan | None:
        odometry = interpolate_odometry(odom, p.timestamp) if p.needs_odometry else p.odometry
        range_max = self.no_return.get(p.kind, p.range_max)
        source = f"{self.lines.name}:{p.line_no}"
        try:
            return Scan(
                p.ranges, p.angles, 0.0, range_max, p.timestamp, odometry, p.reference, source
            )
        except ScanError as exc:  # the error names file and line: not the source again
            why = str(exc).removeprefix(f"{source}: ")
            err = ParseError(self.lines.path, p.line_no, f"{p.kind}: {why}")
            if self.strict:
                raise err from None
            self._skip_malformed(f"malformed:{p.kind}", err)
            return None

    def _flush(self, waiting, odom, wanted) -> Iterator[tuple[int, str, Scan]]:
        """Build and yield the deferred records; returns (via StopIteration) how many a
        lenient read refused (later indices move up by that many)."""
        shift = 0
        for k, record in waiting:
            scan = self._build(record, odom)
            if scan is None:
                shift += 1  # lenient: later scans move up one index
                continue
            if wanted is None or wanted(k - shift):
                yield k - shift, record.kind, scan
        waiting.clear()
        return shift

    def _probe(self, record: _Pending) -> None:
        """Add a FLASER-like message to the no-return sample; decide when it is full."""
        self._sample.setdefault(record.kind, []).append(record.ranges)
        self._n_sampled += 1
        if self._n_sampled >= NO_RETURN_PROBE_SCANS:
            self._decide()

    def _decide(self) -> None:
        self._probing = False
        for kind, rows in self._sample.items():
            found = detect_no_return(rows, self.ctx.max_range)
            if found is None:
                continue
            value, count, n_rows = found
            self.no_return[kind] = value
            logger.warning(
                "%s: %s marks no return with %g m (%d readings in %d of the first %d scans "
                "sit exactly there, at the top of the ranges): readings at or beyond %g m "
                "are masked as no return (pass max_range to override)",
                self.lines.path,
                kind,
                value,
                count,
                n_rows,
                len(rows),
                value,
                extra={"user_note": True},  # the CLI prints it as a note instead
            )
        self._sample = {}

    def scans(
        self, wanted: Callable[[int], bool] | None = None, last: int | None = None
    ) -> Iterator[tuple[int, str, Scan]]:
        """See the class docstring; ``last``: stop after the laser message of this index
        (strict mode, when no scan waits for later ODOM messages or for the no-return
        probe of the first :data:`NO_RETURN_PROBE_SCANS` FLASER-like messages)."""
        ctx, skipped, strict = self.ctx, self.skipped, self.strict
        index = 0  # index of the next laser message
        waiting: list[tuple[int, _Pending]] = []  # deferred: need ODOM, or the probe
        needs_odom = False
        stopped = False
        for line_no, line in self.lines:
            if line is None:  # undecodable (strict=False only)
                ctx.line_no, ctx.kind = line_no, "line"
                self._skip_malformed(
                    "undecodable", ParseError(self.lines.path, line_no, "undecodable bytes")
                )
                continue
            tok = line.split()
            if not tok or tok[0][0] == "#":
                continue
            kind = tok[0]
            parser = _PARSERS.get(kind)
            if parser is None:
                key = f"unknown:{kind[:40]}"
                skipped[key] = skipped.get(key, 0) + 1
                continue
            is_laser = kind in LASER_MESSAGES
            probing = self._probing and kind in _FLASER_KINDS
            if is_laser and strict and wanted is not None and not wanted(index) and not probing:
                index += 1
                if last is not None and index > last and not waiting:
                    stopped = True
                    break
                continue
            ctx.line_no, ctx.kind = line_no, kind
            # "1_0" and "١٢" are no numbers: the line looked at once, its fields only then
            ctx.floats = parse_plain_float_fields if plain_number(line) else parse_float_fields
            try:
                record = parser(tok, ctx)
            except ParseError as exc:
                if strict:
                    raise
                self._skip_malformed(f"malformed:{kind}", exc)
                continue
            if record is None:
                continue
            if probing:
                self._probe(record)
            if record.needs_odometry or waiting or self._probing:
                if wanted is None or not strict or wanted(index):
                    waiting.append((index, record))
                    needs_odom = needs_odom or record.needs_odometry
                index += 1
                if not self._probing and not needs_odom:
                    index -= yield from self._flush(waiting, _NO_ODOM, wanted)
                if strict and last is not None and index > last and not waiting:
                    stopped = True
                    break
                continue
            scan = self._build(record, _NO_ODOM)
            if scan is None:
                continue  # a lenient read does not count a refused scan
            if wanted is None or wanted(index):
                yield index, kind, scan
            index += 1
            if strict and last is not None and index > last and not waiting:
                stopped = True
                break
        if self.lines.truncated:
            skipped[_truncated_key(self.lines.truncated)] = 1
        if self._probing:
            self._decide()
        if waiting:
            index -= yield from self._flush(waiting, self.odom, wanted)
        self.n_scans = None if stopped else index
        for reason, count in sorted(skipped.items()):
            if reason.startswith("unknown:"):
                logger.debug(
                    "%s: skipped %d %s messages (unknown type)", self.lines.path, count, reason[8:]
                )
            else:
                logger.warning("%s: skipped %d lines (%s)", self.lines.path, count, reason)

    @property
    def odom(self) -> np.ndarray:
        return np.array(self.ctx.odom, dtype=np.float64).reshape(-1, 4)


_NO_ODOM = np.zeros((0, 4))


def _truncated_key(why: str) -> str:
    """The :attr:`CarmenLog.skipped` key of a compressed stream read only in part, from
    the line source's reason, which names the format as ``"<gzip|bzip2> stream"``
    (``"truncated bzip2 stream: ..."``, ``"corrupt gzip stream (...)"``)."""
    return "truncated bzip2" if "bzip2 stream" in why else "truncated gzip"


def parse_carmen(
    lines,
    *,
    strict: bool = True,
    max_beams: int = DEFAULT_MAX_BEAMS,
    max_range: float | None = None,
) -> CarmenLog:
    """Parse the lines of a CARMEN log (see :func:`read_carmen` and the module docstring).

    ``lines`` is a :class:`~scanclique.io.text.LineSource` (streamed) or a
    :class:`~scanclique.io.text.TextLines`.
    """
    reader = _CarmenReader(lines, strict, max_beams, max_range)
    scans: list[Scan] = []
    kinds: list[str] = []
    for _, kind, scan in reader.scans():
        scans.append(scan)
        kinds.append(kind)
    params, skipped = reader.ctx.params, reader.skipped
    return CarmenLog(
        lines.path, tuple(scans), tuple(kinds), params, skipped, reader.odom, reader.no_return
    )


def iter_carmen(
    path: str | os.PathLike,
    *,
    strict: bool = True,
    max_beams: int = DEFAULT_MAX_BEAMS,
    max_range: float | None = None,
    wanted: Callable[[int], bool] | None = None,
    last: int | None = None,
    reader_out: list | None = None,
) -> Iterator[tuple[int, Scan]]:
    """Stream the scans of a CARMEN log: ``(index, Scan)`` in file order.

    Memory is bounded by one line plus the scans the caller keeps (and, for RAWLASER
    messages, which wait for the ODOM messages of the whole log, the wanted ones of them).

    Parameters
    ----------
    path, strict, max_beams, max_range
        As for :func:`read_carmen`.
    wanted : callable(int) -> bool, optional
        Only the scans of these indices are built (with ``strict``, the other laser
        messages are not even parsed); default all.
    last : int, optional
        Stop reading after the laser message of this index (with ``strict``).
    reader_out : list, optional
        Receives the internal reader, whose ``n_scans`` (None if stopped early),
        ``ctx.params`` and ``skipped`` are complete once the iterator is exhausted.
    """
    from .text import LineSource

    reader = _CarmenReader(
        LineSource(path, strict=strict, comments=False), strict, max_beams, max_range
    )
    if reader_out is not None:
        reader_out.append(reader)
    for index, _, scan in reader.scans(wanted, last):
        yield index, scan


def read_carmen(
    path: str | os.PathLike,
    *,
    strict: bool = True,
    max_beams: int = DEFAULT_MAX_BEAMS,
    max_range: float | None = None,
) -> CarmenLog:
    """Read a CARMEN log (plain, gzip or bzip2, detected by magic bytes).

    Parameters
    ----------
    path : str or path-like
        The log file.
    strict : bool
        If True (default) the first malformed line raises :class:`ParseError`. If False,
        malformed and undecodable lines are skipped, counted in :attr:`CarmenLog.skipped`
        and logged at warning level; a truncated gzip or bzip2 stream keeps what could
        be read.
    max_beams : int
        Largest accepted beam or remission count in one message.
    max_range : float, optional
        ``Scan.range_max`` (metres) for messages that carry no maximum range (FLASER,
        RLASER, LASER3, LASER4) or a non-positive one; readings at or beyond it are masked
        as no return. Default 80 m, or for the first four the log's own no-return value
        when it marks no return below 80 m (:func:`detect_no_return` on its first 200 such messages;
        recorded in :attr:`CarmenLog.no_return` and logged at warning level).

    Returns
    -------
    CarmenLog
        Scans (one per laser message, in file order), PARAM values, skip counts and the
        ODOM poses.

    Raises
    ------
    ParseError
        A malformed line (file, line, field, expected and found), binary or undecodable
        data, a truncated or corrupt gzip or bzip2 stream.
    DataNotFoundError
        If there is no such file.
    """
    lines = LineSource(path, strict=strict, comments=False)
    return parse_carmen(lines, strict=strict, max_beams=max_beams, max_range=max_range)
