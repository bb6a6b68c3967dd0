"""Text files: loading lines (plain or gzip) and scanclique's own scan text format.

Loading lines
-------------
:func:`read_lines` is what every text reader in :mod:`scanclique.io` starts from. It
detects gzip by its magic bytes (``1f 8b``), not by the suffix, and turns every way a file
can be unreadable into a :class:`~scanclique.errors.ParseError` that names the file (and
the line, where there is one): a truncated or corrupt gzip stream, undecodable bytes
(UTF-8 is expected; ASCII is a subset) and NUL bytes (binary data). With ``strict=False``
the readable part is kept and the problems are reported in the returned
:class:`TextLines` so that the caller can count and log them.

The scan text format
--------------------
One scan per line; ``#`` starts a comment line; blank lines are ignored::

    # scanclique scans v1
    SCAN t angle_min angle_increment range_min range_max n r_1 ... r_n [sections]

``t``
    Timestamp in seconds, or ``-`` when the scan has none.
``angle_min angle_increment``
    Beam ``i`` (0-based) is at ``angle_min + i * angle_increment`` radians, sensor frame,
    counter-clockwise, x forward.
``range_min range_max``
    Valid returns satisfy ``range_min < r < range_max`` (metres).
``n r_1 ... r_n``
    The number of beams and the ranges in metres; ``nan``, ``inf`` and ``-inf`` are allowed
    (they are kept and masked as invalid by :class:`~scanclique.scan.Scan`).

Optional sections follow the ranges, each at most once, in any order:

``ODOM x y theta``
    Odometry pose of the sensor (:attr:`Scan.odometry <scanclique.scan.Scan.odometry>`).
``REF x y theta``
    Reference pose of the sensor (:attr:`Scan.reference <scanclique.scan.Scan.reference>`).
``ANGLES a_1 ... a_n``
    Explicit beam angles, for scans whose angles are not evenly spaced; when present they
    replace ``angle_min + i * angle_increment``. :func:`write_scans_text` writes this
    section only when the evenly spaced form would not reproduce the angles exactly.

:func:`write_scans_text` writes floats with ``repr`` (shortest round-tripping form), so
reading back what it wrote gives the same ranges, angles, limits, timestamps and poses bit
for bit (NaN payloads and the sign of a NaN excepted). The ``source`` of a scan read back is
``"<file name>:<line>"``, not the original one. A path ending in ``.gz`` is written gzip
compressed.

Examples
--------
>>> import tempfile, pathlib
>>> from scanclique import Scan
>>> scan = Scan.from_ranges([1.0, 2.5, float("nan")], timestamp=3.0)
>>> path = pathlib.Path(tempfile.mkdtemp()) / "two.scan"
>>> write_scans_text(path, [scan, scan])
>>> back = read_scans_text(path)
>>> len(back), back[1].source, back[0].ranges.tolist()[:2], back[0].timestamp
(2, 'two.scan:4', [1.0, 2.5], 3.0)
"""

from __future__ import annotations

import bz2
import gzip
import logging
import math
import os
import zlib
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import DataNotFoundError, ParseError, ScanError
from ..geometry import Pose2
from ..scan import Scan, beam_angles

__all__ = [
    "GZIP_MAGIC",
    "TextLines",
    "is_gzip",
    "read_lines",
    "parse_float_fields",
    "parse_count",
    "read_scans_text",
    "parse_scans_text",
    "write_scans_text",
    "format_scan_line",
]

logger = logging.getLogger(__name__)

GZIP_MAGIC = b"\x1f\x8b"
BZIP2_MAGIC = b"BZh"

_PathLike = str | os.PathLike


# ---------------------------------------------------------------------------------------
# Loading lines
# ---------------------------------------------------------------------------------------
@dataclass(frozen=True, slots=True, eq=False)
class TextLines:
    """The lines of a text file, as loaded by :func:`read_lines`.

    Attributes
    ----------
    path : str
        The file as given by the caller (used in messages).
    lines : tuple of (str or None)
        Line ``k`` (1-based) is ``lines[k - 1]``, without its end-of-line characters.
        ``None`` marks a line that could not be decoded (only with ``strict=False``).
    truncated : str or None
        With ``strict=False``: why the (gzip) file could not be read to its end, else None.
    compressed : bool
        Whether the file was gzip or bzip2 compressed.
    """

    path: str
    lines: tuple[str | None, ...]
    truncated: str | None = None
    compressed: bool = False

    @property
    def name(self) -> str:
        """The file's base name, for scan ``source`` strings."""
        return os.path.basename(self.path)

    @property
    def undecodable(self) -> int:
        """How many lines could not be decoded."""
        return sum(1 for line in self.lines if line is None)


def is_gzip(path: _PathLike) -> bool:
    """Whether the file starts with the gzip magic bytes ``1f 8b`` (whatever its suffix).

    Raises
    ------
    DataNotFoundError
        If there is no such file.
    """
    return _read_bytes(path, head=2) == GZIP_MAGIC


def _read_bytes(path: _PathLike, head: int | None = None) -> bytes:
    p = Path(path)
    try:
        with open(p, "rb") as fh:
            return fh.read() if head is None else fh.read(head)
    except FileNotFoundError:
        raise DataNotFoundError(f"{os.fspath(path)}: no such file") from None
    except IsADirectoryError:
        raise ParseError(os.fspath(path), None, "is a directory, expected a file") from None


def _gunzip(raw: bytes, path: str, strict: bool) -> tuple[bytes, str | None]:
    """Decompress all gzip members of ``raw``; returns (data, why it stopped early or None)."""
    chunks: list[bytes] = []
    data = raw
    while data:
        d = zlib.decompressobj(wbits=16 + zlib.MAX_WBITS)
        try:
            chunks.append(d.decompress(data))
        except zlib.error as exc:
            why = f"corrupt gzip stream ({exc})"
            if strict:
                raise ParseError(path, None, why) from None
            return b"".join(chunks), why
        if not d.eof:
            chunks.append(d.flush())
            why = (
                "truncated gzip stream: the compressed data end before the gzip end marker "
                "(incomplete download or copy?)"
            )
            if strict:
                raise ParseError(path, None, why)
            return b"".join(chunks), why
        data = d.unused_data
        if data and not data.startswith(GZIP_MAGIC):
            if data.strip(b"\x00"):
                why = f"{len(data)} bytes of trailing garbage after the gzip stream"
                if strict:
                    raise ParseError(path, None, why)
                return b"".join(chunks), why
            break  # zero padding after the last member is harmless
    return b"".join(chunks), None


def _bunzip2(raw: bytes, path: str, strict: bool) -> tuple[bytes, str | None]:
    """Decompress all bzip2 streams of ``raw``; returns (data, why it stopped early or None)."""
    chunks: list[bytes] = []
    data = raw
    while data:
        d = bz2.BZ2Decompressor()
        try:
            chunks.append(d.decompress(data))
        except OSError as exc:
            why = f"corrupt bzip2 stream ({exc})"
            if strict:
                raise ParseError(path, None, why) from None
            return b"".join(chunks), why
        if not d.eof:
            why = (
                "truncated bzip2 stream: the compressed data end before the bzip2 end marker "
                "(incomplete download or copy?)"
            )
            if strict:
                raise ParseError(path, None, why)
            return b"".join(chunks), why
        data = d.unused_data
        if data and not data.startswith(BZIP2_MAGIC):
            if data.strip(b"\x00"):
                why = f"{len(data)} bytes of trailing garbage after the bzip2 stream"
                if strict:
                    raise ParseError(path, None, why)
                return b"".join(chunks), why
            break
    return b"".join(chunks), None


def _bad_bytes_message(line: bytes) -> str:
    if b"\x00" in line:
        col = line.index(b"\x00") + 1
        return f"expected text, found a NUL byte at column {col} (binary data?)"
    try:
        line.decode("utf-8")
    except UnicodeDecodeError as exc:
        snippet = line[exc.start : exc.start + 4]
        return (
            f"expected UTF-8/ASCII text, found undecodable bytes {snippet!r} at column "
            f"{exc.start + 1} (binary data?)"
        )
    return "expected text"  # pragma: no cover - only called for bad lines


def read_lines(path: _PathLike, *, strict: bool = True) -> TextLines:
    """Load a text file (plain, gzip or bzip2, detected by magic bytes) as lines.

    Parameters
    ----------
    path : str or path-like
        The file.
    strict : bool
        If True (default) any problem raises. If False, a truncated or corrupt gzip stream
        keeps what could be decompressed (reported in :attr:`TextLines.truncated`) and
        undecodable lines become ``None``.

    Returns
    -------
    TextLines
        An empty file gives no lines.

    Raises
    ------
    DataNotFoundError
        If there is no such file.
    ParseError
        Truncated/corrupt gzip (names the file), undecodable bytes or NUL bytes (names the
        file and the line).
    """
    spath = os.fspath(path)
    raw = _read_bytes(path)
    truncated = None
    compressed = raw[:2] == GZIP_MAGIC or raw[:3] == BZIP2_MAGIC
    if raw[:2] == GZIP_MAGIC:
        raw, truncated = _gunzip(raw, spath, strict)
    elif raw[:3] == BZIP2_MAGIC:
        raw, truncated = _bunzip2(raw, spath, strict)
    if truncated:
        logger.warning("%s: %s; reading what was recovered", spath, truncated)
    lines: list[str | None] = []
    try:
        if b"\x00" in raw:
            raise UnicodeError("NUL byte")
        text = raw.decode("utf-8")
    except UnicodeError:
        for k, bline in enumerate(raw.split(b"\n"), start=1):
            try:
                if b"\x00" in bline:
                    raise UnicodeError("NUL byte")
                lines.append(bline.decode("utf-8").rstrip("\r"))
            except UnicodeError:
                if strict:
                    raise ParseError(spath, k, _bad_bytes_message(bline)) from None
                lines.append(None)
    else:
        lines.extend(text.replace("\r\n", "\n").split("\n"))
    if lines and lines[-1] == "":
        lines.pop()
    return TextLines(spath, tuple(lines), truncated, compressed)


# ---------------------------------------------------------------------------------------
# Field parsing shared by the readers
# ---------------------------------------------------------------------------------------
def parse_float_fields(tokens: Sequence[str], start: int, stop: int, field_name, err) -> np.ndarray:
    """Parse ``tokens[start:stop]`` as float64 in one NumPy call.

    ``nan``/``inf`` are accepted. On failure, the first offending token is located and
    ``err(field_name(i), "expects a number, found 'abc'")`` is raised, ``i`` being the
    token's index in ``tokens``.
    """
    try:
        return np.array(tokens[start:stop], dtype=np.float64)
    except ValueError:
        for i in range(start, stop):
            try:
                float(tokens[i])
            except ValueError:
                raise err(field_name(i), f"expects a number, found {tokens[i]!r}") from None
        raise err(None, "expects numbers") from None  # pragma: no cover


def parse_count(token: str, field: str, limit: int, err) -> int:
    """Parse a non-negative integer count no larger than ``limit``; ``err(field, msg)`` else."""
    try:
        n = int(token)
    except ValueError:
        raise err(field, f"expects a non-negative integer, found {token!r}") from None
    if n < 0:
        raise err(field, f"expects a non-negative integer, found {token!r}")
    if n > limit:
        raise err(
            field,
            f"{n} exceeds the limit max_beams={limit} (corrupt line? pass a larger max_beams "
            "to accept it)",
        )
    return n


# ---------------------------------------------------------------------------------------
# The scan text format
# ---------------------------------------------------------------------------------------
_SECTIONS = ("ODOM", "REF", "ANGLES")
_HEADER = (
    "# scanclique scans v1\n"
    "# SCAN t angle_min angle_increment range_min range_max n r_1 .. r_n"
    " [ODOM x y theta] [REF x y theta] [ANGLES a_1 .. a_n]\n"
)


def _fmt(x: float) -> str:
    return repr(float(x))


def _evenly_spaced(angles: np.ndarray) -> tuple[float, float, bool]:
    """(angle_min, angle_increment, exact) such that beam_angles reproduces ``angles``."""
    n = angles.size
    if n == 0:
        return 0.0, 0.0, True
    a0 = float(angles[0])
    if n == 1:
        return a0, 0.0, bool(np.array_equal(beam_angles(1, a0, 0.0), angles))
    candidates = ((float(angles[-1]) - a0) / (n - 1), float(angles[1]) - a0)
    for inc in candidates:
        if np.array_equal(beam_angles(n, a0, inc), angles):
            return a0, inc, True
    return a0, candidates[0], False


def format_scan_line(scan: Scan) -> str:
    """One ``SCAN ...`` line (without newline) for ``scan``; see the module docstring."""
    a0, inc, exact = _evenly_spaced(scan.angles)
    t = "-" if scan.timestamp is None else _fmt(scan.timestamp)
    parts = [
        "SCAN",
        t,
        _fmt(a0),
        _fmt(inc),
        _fmt(scan.range_min),
        _fmt(scan.range_max),
        str(scan.n_beams),
    ]
    parts.extend(map(repr, scan.ranges.tolist()))
    if scan.odometry is not None:
        parts.append("ODOM")
        parts.extend(map(_fmt, (scan.odometry.x, scan.odometry.y, scan.odometry.theta)))
    if scan.reference is not None:
        parts.append("REF")
        parts.extend(map(_fmt, (scan.reference.x, scan.reference.y, scan.reference.theta)))
    if not exact:
        parts.append("ANGLES")
        parts.extend(map(repr, scan.angles.tolist()))
    return " ".join(parts)


def write_scans_text(path: _PathLike, scans: Iterable[Scan]) -> None:
    """Write scans in the scan text format (gzip compressed when ``path`` ends in ``.gz``).

    Parameters
    ----------
    path : str or path-like
        Output file, overwritten.
    scans : iterable of Scan
        Written one per line, in order.
    """
    body = _HEADER + "".join(format_scan_line(s) + "\n" for s in scans)
    data = body.encode("ascii")
    if os.fspath(path).endswith(".gz"):
        data = gzip.compress(data, mtime=0)
    Path(path).write_bytes(data)


def _pose_section(tokens, i, name, err) -> tuple[Pose2, int]:
    if i + 4 > len(tokens):
        raise err(name, f"{name} expects 3 values (x y theta), found {len(tokens) - i - 1}")
    fields = (f"{name} x", f"{name} y", f"{name} theta")
    xyt = parse_float_fields(tokens, i + 1, i + 4, lambda k: fields[k - i - 1], err)
    if not np.all(np.isfinite(xyt)):
        raise err(name, f"{name} expects a finite pose, found {xyt.tolist()}")
    return Pose2(*xyt.tolist()), i + 4


def _parse_scan_line(tokens: list[str], max_beams: int, err, source: str) -> Scan:
    if len(tokens) < 7:
        raise err(None, f"SCAN expects at least 7 fields, found {len(tokens)} (truncated line?)")
    t: float | None
    if tokens[1] == "-":
        t = None
    else:
        t = float(parse_float_fields(tokens, 1, 2, lambda _: "t", err)[0])
        if not math.isfinite(t):
            raise err("t", f"SCAN expects a finite timestamp or '-', found {tokens[1]!r}")
    names = ("t", "angle_min", "angle_increment", "range_min", "range_max")
    a0, inc, rmin, rmax = parse_float_fields(tokens, 2, 6, lambda k: names[k - 1], err).tolist()
    n = parse_count(tokens[6], "n", max_beams, err)
    if len(tokens) < 7 + n:
        raise err(None, f"SCAN expects {n} ranges, found {len(tokens) - 7}")
    ranges = parse_float_fields(tokens, 7, 7 + n, lambda k: f"range[{k - 7}]", err)
    odometry = reference = angles = None
    i = 7 + n
    while i < len(tokens):
        key = tokens[i]
        if key not in _SECTIONS:
            raise err(None, f"expected ODOM, REF or ANGLES after the ranges, found {key!r}")
        if (key == "ODOM" and odometry is not None) or (key == "REF" and reference is not None):
            raise err(key, f"{key} given twice")
        if key == "ODOM":
            odometry, i = _pose_section(tokens, i, "ODOM", err)
        elif key == "REF":
            reference, i = _pose_section(tokens, i, "REF", err)
        else:
            if angles is not None:
                raise err(key, "ANGLES given twice")
            if i + 1 + n > len(tokens):
                raise err("ANGLES", f"ANGLES expects {n} values, found {len(tokens) - i - 1}")
            angles = parse_float_fields(
                tokens, i + 1, i + 1 + n, lambda k, i=i: f"angle[{k - i - 1}]", err
            )
            i += 1 + n
    if angles is None:
        if not (math.isfinite(a0) and math.isfinite(inc)):
            raise err("angle_min", f"SCAN expects finite angles, found {a0}, {inc}")
        angles = beam_angles(n, a0, inc)
    try:
        return Scan(ranges, angles, rmin, rmax, t, odometry, reference, source)
    except ScanError as exc:
        raise err(None, str(exc)) from None


def parse_scans_text(
    lines: TextLines, *, strict: bool = True, max_beams: int = 100_000
) -> list[Scan]:
    """Scans from the lines of a scan text file (see the module docstring).

    With ``strict=False`` malformed and undecodable lines are skipped and logged at warning
    level; otherwise the first one raises :class:`~scanclique.errors.ParseError`.
    """
    scans: list[Scan] = []
    skipped = 0
    name = lines.name
    for line_no, line in enumerate(lines.lines, start=1):
        if line is None:
            skipped += 1
            logger.warning("%s:%d: skipped an undecodable line", lines.path, line_no)
            continue
        tokens = line.split()
        if not tokens or tokens[0].startswith("#"):
            continue

        def err(field, message, _ln=line_no):
            return ParseError(lines.path, _ln, message, field=field)

        try:
            if tokens[0] != "SCAN":
                raise err(None, f"expected a SCAN record, found {tokens[0][:40]!r}")
            scans.append(_parse_scan_line(tokens, max_beams, err, f"{name}:{line_no}"))
        except ParseError as exc:
            if strict:
                raise
            skipped += 1
            logger.warning("skipped malformed line: %s", exc)
    if skipped:
        logger.warning("%s: skipped %d malformed or undecodable lines", lines.path, skipped)
    return scans


def read_scans_text(
    path: _PathLike, *, strict: bool = True, max_beams: int = 100_000
) -> list[Scan]:
    """Read a scan text file (plain or gzip); one :class:`~scanclique.scan.Scan` per line.

    Parameters
    ----------
    path : str or path-like
        The file.
    strict : bool
        If True (default) the first malformed line raises; if False malformed lines are
        skipped and logged at warning level.
    max_beams : int
        Largest accepted ``n`` (guards against corrupt counts).

    Returns
    -------
    list of Scan
        In file order; an empty file (or one with only comments) gives an empty list.

    Raises
    ------
    ParseError
        Naming the file, the 1-based line and the field, with what was expected and found.
    """
    return parse_scans_text(read_lines(path, strict=strict), strict=strict, max_beams=max_beams)
