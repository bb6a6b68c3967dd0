"""Readers and writers: files in, :class:`~scanclique.scan.Scan` records out.

:func:`read_scans` is the one entry point; it picks the reader from the file itself:

* a NumPy ``.npz`` archive (suffix ``.npz`` or zip magic bytes) -> :mod:`.npz`;
* scanclique's scan text format (first record ``SCAN ...``, or suffix ``.txt``/``.scan``,
  optionally ``.gz``) -> :mod:`.text`;
* anything else -> a CARMEN log (plain or gzip, detected by magic bytes) -> :mod:`.carmen`.

Nothing downstream of the readers parses files.
"""

from __future__ import annotations

import logging
import math
import os
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from dataclasses import field as _field
from pathlib import Path
from types import MappingProxyType

from ..errors import ArgumentError, ConfigError
from ..scan import Scan
from .carmen import (
    DEFAULT_MAX_BEAMS,
    FLASER_MAX_RANGE,
    KNOWN_MESSAGES,
    CarmenLog,
    _CarmenReader,
    check_laser,
    flaser_angles,
    interpolate_odometry,
    iter_carmen,
    parse_carmen,
    read_carmen,
    select_laser,
)
from .npz import read_scans_npz, write_scans_npz
from .table import read_table
from .text import (
    LineSource,
    TextLines,
    _read_bytes,
    _TextReader,
    check_path,
    is_gzip,
    parse_scans_text,
    read_lines,
    read_scans_text,
    write_scans_text,
)
from .tum import poses_at, read_tum, write_tum

__all__ = [
    "read_scans",
    "read_scans_at",
    "odometry_is_reference",
    "poses_carried",
    "ScanSelection",
    "iter_carmen",
    "LineSource",
    "detect_format",
    "read_carmen",
    "select_laser",
    "CarmenLog",
    "read_scans_text",
    "write_scans_text",
    "read_scans_npz",
    "write_scans_npz",
    "read_lines",
    "read_table",
    "read_tum",
    "write_tum",
    "poses_at",
    "TextLines",
    "is_gzip",
    "flaser_angles",
    "interpolate_odometry",
    "FLASER_MAX_RANGE",
    "DEFAULT_MAX_BEAMS",
]

_logger = logging.getLogger(__name__)

_ZIP_MAGIC = b"PK\x03\x04"
_EMPTY_ZIP_MAGIC = b"PK\x05\x06"
_TEXT_SUFFIXES = (".txt", ".scan", ".scans")
_DETECT_LINES = 1000  # records looked at to tell a CARMEN log from scan text


def _head(path: str | os.PathLike, size: int = 4) -> bytes:
    return _read_bytes(path, head=size)


def _stem_suffix(path: str | os.PathLike) -> str:
    """The suffix that names the content: ``a.scan.gz`` -> ``.scan``."""
    p = Path(path)
    if p.suffix.lower() == ".gz":
        p = p.with_suffix("")
    return p.suffix.lower()


def _format_of_lines(lines, path) -> str:
    for k, (_, line) in enumerate(lines):
        if k >= _DETECT_LINES:
            break
        if line is None:
            continue
        tok = line.split(maxsplit=1)
        if not tok or tok[0].startswith("#"):
            continue
        if tok[0] == "SCAN":
            return "text"
        if tok[0] in KNOWN_MESSAGES:
            return "carmen"
        break
    return "text" if _stem_suffix(path) in _TEXT_SUFFIXES else "carmen"


def detect_format(path: str | os.PathLike) -> str:
    """Which reader :func:`read_scans` uses for ``path``: ``"npz"``, ``"text"`` or ``"carmen"``.

    Reads the first bytes and, for text, the lines up to the first record.

    Raises
    ------
    DataNotFoundError
        If there is no such file.
    ParseError
        Not a regular file, or unreadable.
    """
    spath = check_path(path)
    head = _head(spath)
    if head.startswith((_ZIP_MAGIC, _EMPTY_ZIP_MAGIC)) or _stem_suffix(spath) == ".npz":
        return "npz"
    # quiet: the reader that follows says what is wrong with a damaged stream, once
    lines = LineSource(spath, strict=False, comments=False, quiet=True)
    return _format_of_lines(lines, spath)


def _check_options(strict, max_beams, max_range, laser=None) -> None:
    check_laser(laser)
    if not isinstance(strict, bool):
        raise ArgumentError(f"strict must be True or False, got {strict!r}")
    if isinstance(max_beams, bool) or not isinstance(max_beams, int) or max_beams < 1:
        raise ArgumentError(f"max_beams must be a positive integer, got {max_beams!r}")
    if max_range is not None and (
        isinstance(max_range, bool) or not isinstance(max_range, (int, float))
    ):
        raise ArgumentError(f"max_range must be a positive number of metres, got {max_range!r}")
    if max_range is not None and not (math.isfinite(max_range) and max_range > 0):
        # the CARMEN reader's own check, for every format: a log's format should not
        # decide whether a bad value is refused or silently ignored
        raise ConfigError(f"max_range must be a positive number, got {max_range!r}")


def read_scans(
    path: str | os.PathLike,
    *,
    strict: bool = True,
    max_beams: int = DEFAULT_MAX_BEAMS,
    max_range: float | None = None,
    laser: str | None = None,
) -> list[Scan]:
    """Read every scan of a file: one :class:`~scanclique.scan.Scan` per laser message.

    The file is streamed line by line (scan by scan for an ``.npz``), so memory is the
    scans returned plus a bounded buffer (see the README's limits table); to read a few
    scans of a large log use :func:`read_scans_at`.

    Parameters
    ----------
    path : str or path-like
        A CARMEN log (plain, gzip or bzip2), a scan text file, an ``.npz`` archive, or a
        ROS bag (a ``.bag`` file or a ROS 2 bag directory, read by
        :func:`~scanclique.io.rosbag.read_bag`: its only LaserScan topic, or the one
        ``laser`` names); the format is
        detected from the content (see the module docstring). Must be a regular file (or a
        ROS 2 bag directory): FIFOs and devices are refused.
    strict : bool
        If True (default) the first malformed line raises
        :class:`~scanclique.errors.ParseError`; if False malformed lines are skipped,
        counted and logged at warning level (text formats only; an ``.npz`` is all or
        nothing).
    max_beams : int
        Largest accepted beam count in one message or record (guards corrupt counts).
    max_range : float, optional
        CARMEN only: ``Scan.range_max`` (metres) for messages without a maximum range
        (FLASER, RLASER, LASER3, LASER4); readings at or beyond it are no return.
        Default: 80 m (right for the SICK logs of the shared data, which log no return as
        81.83 or 81.91), or the log's own no-return value when it marks no return below
        80 m (found in its first 200 such messages by
        :func:`~scanclique.io.carmen.detect_no_return`, logged at warning level, and then
        the ``range_max`` of those scans). Ignored by the other formats, but checked for
        all: not a finite number > 0 is a :class:`~scanclique.errors.ConfigError`.
    laser : str, optional
        CARMEN only: None (default) keeps every laser message; a log that holds more than
        one laser (FLASER and RLASER, RAWLASER1 and RAWLASER2, ...) interleaves their views
        in file order, which is logged at warning level. ``"main"`` keeps the log's main
        laser (:data:`~scanclique.io.carmen.MAIN_LASER_ORDER`: FLASER first, RLASER last)
        and logs what it left out; a message type (``"RLASER"``) keeps that one's scans.
        What the mapping and place commands read (``--laser``, default ``"main"``). A
        ROS bag: the LaserScan topic (``"/front/scan"``); None or ``"main"``, its only one.

    Returns
    -------
    list of Scan
        In file order. An empty file gives an empty list.

    Raises
    ------
    ParseError
        Naming the file, the 1-based line and the field, with what was expected and found.
    DataNotFoundError
        If there is no such file.
    ArgumentError
        ``path`` is not a path (``None``, a number, ...), or an option of the wrong type;
        ``laser`` names a type the CARMEN log holds no scans of.

    See Also
    --------
    read_carmen : the CARMEN reader, also returning PARAM values and skip counts.
    """
    spath = check_path(path)
    from .rosbag import is_bag

    if is_bag(spath):  # a ROS 1 .bag or a ROS 2 bag: the laser is a LaserScan topic
        if laser is not None and not isinstance(laser, str):
            raise ArgumentError(f"laser must be a LaserScan topic of the bag, got {laser!r}")
        _check_options(strict, max_beams, max_range)
        from .rosbag import read_bag

        return read_bag(spath, topic=None if laser in (None, "main") else laser)
    _check_options(strict, max_beams, max_range, laser)
    fmt = detect_format(spath)
    if fmt == "npz":
        return read_scans_npz(spath, max_beams=max_beams)
    lines = LineSource(spath, strict=strict, comments=False)
    if fmt == "text":
        return parse_scans_text(lines, strict=strict, max_beams=max_beams)
    log = parse_carmen(lines, strict=strict, max_beams=max_beams, max_range=max_range)
    scans, note = select_laser(log, laser)
    if note:
        _logger.warning("%s", note)
    if scans:
        _logger.info("%s: %d scans, poses: %s", spath, len(scans), poses_carried(scans))
    return scans


@dataclass(frozen=True, slots=True, eq=False)
class ScanSelection:
    """Some scans of a file, read by :func:`read_scans_at`.

    Attributes
    ----------
    path : str
        The file.
    scans : Mapping[int, Scan]
        The scans asked for that the file holds, by index.
    n_scans : int or None
        How many scans the file holds; None when reading stopped after the last index
        asked for (the file holds at least that many).
    no_return : Mapping[str, float]
        CARMEN: message type -> the no-return value found below 80 m (see
        :func:`read_scans`), empty when none.
    """

    path: str
    scans: Mapping[int, Scan]
    n_scans: int | None
    no_return: Mapping[str, float] = _field(default_factory=dict)

    def __post_init__(self) -> None:
        object.__setattr__(self, "scans", MappingProxyType(dict(self.scans)))
        object.__setattr__(self, "no_return", MappingProxyType(dict(self.no_return)))

    def notes(self) -> list[str]:
        """Messages for the user: the no-return values found."""
        name = os.path.basename(self.path)
        return [
            f"{name} marks no return with {v:g} m in its {k} messages: readings at or "
            f"beyond {v:g} m are masked (--max-range to override)"
            for k, v in sorted(self.no_return.items())
        ]


def read_scans_at(
    path: str | os.PathLike,
    indices: Iterable[int],
    *,
    count: bool = False,
    strict: bool = True,
    max_beams: int = DEFAULT_MAX_BEAMS,
    max_range: float | None = None,
) -> ScanSelection:
    """Read only the scans of ``indices`` (0-based, file order) of a log.

    With ``strict`` (default) the other laser messages are counted from their first word,
    never parsed, and reading stops after the last index asked for (unless ``count``, or
    an index lies beyond the end, or the log's RAWLASER scans need its ODOM messages):
    ``scanclique match LOG 120 121`` reads 122 laser lines of the log, not all of them.
    The scans are the same as :func:`read_scans` gives at those indices. An ``.npz`` is
    read whole (within its size bounds) and the scans picked.

    Parameters
    ----------
    path : str or path-like
    indices : iterable of int
        Non-negative indices.
    count : bool
        Read to the end to count the scans (:attr:`ScanSelection.n_scans`).
    strict, max_beams, max_range
        As for :func:`read_scans`.

    Raises
    ------
    ArgumentError
        A negative or non-integer index, or as :func:`read_scans`.
    """
    spath = check_path(path)
    _check_options(strict, max_beams, max_range)
    want: set[int] = set()
    for i in indices:
        if isinstance(i, bool) or not hasattr(i, "__index__"):
            raise ArgumentError(f"scan indices must be integers, got {i!r}")
        if i.__index__() < 0:
            raise ArgumentError(f"scan indices must be non-negative, got {i!r}")
        want.add(i.__index__())
    fmt = detect_format(spath)
    if fmt == "npz":
        scans = read_scans_npz(spath, max_beams=max_beams)
        return ScanSelection(spath, {i: scans[i] for i in want if i < len(scans)}, len(scans))
    last = None if count or not want else max(want)
    lines = LineSource(spath, strict=strict, comments=False)
    if fmt == "text":
        reader = _TextReader(lines, strict, max_beams)
        got = dict(reader.scans(want.__contains__, last))
        return ScanSelection(spath, got, reader.n_scans)
    creader = _CarmenReader(lines, strict, max_beams, max_range)
    got = {i: scan for i, _, scan in creader.scans(want.__contains__, last)}
    return ScanSelection(spath, got, creader.n_scans, creader.no_return)


def odometry_is_reference(scans, tol: float = 1e-9) -> bool:
    """Whether every scan carries both poses and its odometry equals its reference pose
    (within ``tol`` in x, y and theta): the odometry fields then repeat the corrected
    pose, and validating against "odometry" would use ground truth. False for no scans."""
    scans = list(scans)
    if not scans:
        return False
    for s in scans:
        o, r = s.odometry, s.reference
        if o is None or r is None:
            return False
        if abs(o.x - r.x) > tol or abs(o.y - r.y) > tol or abs(o.theta - r.theta) > tol:
            return False
    return True


def poses_carried(scans, has_reference: bool = True) -> str:
    """Which poses the scans carry, in words, for tables: ``"reference and odometry"``,
    ``"reference only (the odometry fields repeat it)"``, ``"odometry only"``,
    ``"reference only"`` or ``"none"``. ``has_reference=False`` (a registered raw log,
    whose ``x y theta`` are odometry too) counts reference poses as odometry."""
    scans = list(scans)
    has_o = bool(scans) and all(s.odometry is not None for s in scans)
    has_r = bool(scans) and all(s.reference is not None for s in scans)
    if not has_reference:
        return "odometry only" if has_o or has_r else "none"
    if has_r and has_o:
        if odometry_is_reference(scans):
            return "reference only (the odometry fields repeat it)"
        return "reference and odometry"
    if has_r:
        return "reference only"
    return "odometry only" if has_o else "none"
