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
``TIMES s_1 ... s_n``
    Seconds after ``t`` at which each beam was measured (a rotating lidar's sweep:
    :attr:`Scan.beam_times <scanclique.scan.Scan.beam_times>`).

:func:`write_scans_text` writes floats with ``repr`` (shortest round-tripping form), so
reading back what it wrote gives the same ranges, angles, limits, timestamps, poses and
beam times bit for bit (NaN payloads and the sign of a NaN excepted). The ``source`` of a
scan read back is ``"<file name>:<line>"``, not the original one. A path ending in ``.gz``
is written gzip compressed.

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
import re
import stat
import zlib
from collections.abc import Iterable, Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import ArgumentError, DataNotFoundError, ParseError, ScanError
from ..geometry import Pose2
from ..scan import Scan, beam_angles

__all__ = [
    "GZIP_MAGIC",
    "TextLines",
    "is_gzip",
    "plain_number",
    "plain_float",
    "read_lines",
    "parse_float_fields",
    "parse_plain_float_fields",
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
MAX_LINE_BYTES = 16 * 2**20
"""Longest accepted line (bytes): a CARMEN line of 100 000 beams and as many remissions
is about 2.5 MB; longer lines are binary data or a corrupt file."""

MAX_TEXT_BYTES = 4 * 2**30
"""Most bytes of text read from one file (after decompression)."""

MAX_EXPANSION = 200
"""Largest accepted ratio of decompressed to compressed bytes once more than
:data:`EXPANSION_CHECK_BYTES` are out: text logs expand 5-15 times; a file of newlines,
comments or NUL bytes expands about 1000 times (gzip) or far more (bzip2)."""

EXPANSION_CHECK_BYTES = 8 * 2**20

_CHUNK = 2**20  # bytes read from the file at a time, and most bytes decompressed per step
_UTF8_BOM = b"\xef\xbb\xbf"
_NONEMPTY = re.compile(rb"[^\n]+")
# a line holding something other than white space and not starting with "#"
_RECORD = re.compile(rb"(?m)^[ \t\r\f\v]*[^\s#][^\n]*")


def _file_kind(mode: int) -> str:
    if stat.S_ISFIFO(mode):
        return "a FIFO (named pipe)"
    if stat.S_ISCHR(mode):
        return "a character device"
    if stat.S_ISBLK(mode):
        return "a block device"
    if stat.S_ISSOCK(mode):
        return "a socket"
    return "not a regular file"


def check_path(path, what: str = "path"):
    """``path`` as a str, or :class:`~scanclique.errors.ArgumentError` when it is not a
    str or path-like (``None``, a number, an open file, ...)."""
    if isinstance(path, bytes):
        return os.fsdecode(path)
    if not isinstance(path, (str, os.PathLike)):
        raise ArgumentError(f"{what} must be a file path (str or path-like), got {path!r}")
    s = os.fspath(path)
    if not isinstance(s, str):
        s = os.fsdecode(s)
    if "\x00" in s:
        raise ArgumentError(f"{what} must not contain a NUL character, got {s!r}")
    return s


def open_regular(path: _PathLike, what: str = "file"):
    """Open ``path`` for binary reading after checking that it is a regular file.

    FIFOs, devices and sockets are refused before they are opened (opening a FIFO blocks
    until a writer appears; ``/dev/zero`` never ends), so no reader of
    :mod:`scanclique.io` can hang or read without end on them.

    Raises
    ------
    DataNotFoundError
        No such file.
    ParseError
        A directory, a FIFO, a device or a socket, or a file that cannot be opened.
    """
    spath = check_path(path)
    try:
        st = os.stat(spath)
    except (FileNotFoundError, NotADirectoryError):
        raise DataNotFoundError(f"{spath}: no such {what}") from None
    except OSError as exc:
        raise ParseError(spath, None, f"cannot read: {exc.strerror or exc}") from None
    if stat.S_ISDIR(st.st_mode):
        raise ParseError(spath, None, "is a directory, expected a file")
    if not stat.S_ISREG(st.st_mode):
        raise ParseError(
            spath,
            None,
            f"is {_file_kind(st.st_mode)}, expected a regular file (scanclique reads only "
            "regular files: a pipe or device could block or never end)",
        )
    try:
        return open(spath, "rb")  # noqa: SIM115 - the caller closes it
    except FileNotFoundError:
        raise DataNotFoundError(f"{spath}: no such {what}") from None
    except OSError as exc:
        raise ParseError(spath, None, f"cannot read: {exc.strerror or exc}") from None


class _StreamEnd(Exception):
    """Bytes after the last compressed member that do not start another member."""

    def __init__(self, tail: bytes):
        self.tail = tail


class _Decoder:
    """Streaming decompression of concatenated gzip or bzip2 members, at most
    :data:`_CHUNK` bytes of output per step."""

    def __init__(self, kind: str):
        self.kind = kind
        self.magic = GZIP_MAGIC if kind == "gzip" else BZIP2_MAGIC
        self.hold = b""  # the start of a next member's magic, cut by a chunk boundary
        self._new()

    def _new(self) -> None:
        if self.kind == "gzip":
            self.d = zlib.decompressobj(wbits=16 + zlib.MAX_WBITS)
        else:
            self.d = bz2.BZ2Decompressor()
        self.started = False

    @property
    def done(self) -> bool:
        """Whether the input so far ends exactly at the end of a member."""
        return self.d.eof and not self.hold

    def _next_member(self, tail: bytes) -> bytes | None:
        """``tail`` when it starts a new member (the decoder is reset), None when it is
        too short to tell (held back); raises :class:`_StreamEnd` otherwise."""
        if tail.startswith(self.magic):
            self._new()
            return tail
        if self.magic.startswith(tail):
            self.hold = tail
            return None
        raise _StreamEnd(tail)

    def feed(self, data: bytes) -> Iterator[bytes]:
        """Decompress ``data``, yielding the output in pieces of at most :data:`_CHUNK`."""
        if self.hold:
            data, self.hold = self.hold + data, b""
        if self.d.eof and data:
            data = self._next_member(data)
            if data is None:
                return
        while True:
            self.started = True
            out = self.d.decompress(data, _CHUNK)
            if self.kind == "gzip":
                data = self.d.unconsumed_tail
                more = bool(data) or len(out) == _CHUNK
            else:
                data = b""
                more = not self.d.eof and not self.d.needs_input
            if out:
                yield out
            if self.d.eof:
                tail = self.d.unused_data
                if not tail:
                    return
                data = self._next_member(tail)
                if data is None:
                    return
                continue
            if not more:
                return


class LineSource:
    """The lines of a text file (plain, gzip or bzip2), read as a stream.

    Iterating yields ``(line_no, line)``: 1-based line numbers and the decoded line without
    its end-of-line characters, skipping empty lines (their numbers are counted), and with
    ``comments=False`` also lines of white space and lines whose first other character is
    ``#`` (skipped by a regular expression, not line by line in Python). With
    ``strict=False`` an undecodable or over-long line is yielded as ``None``; otherwise it
    raises :class:`~scanclique.errors.ParseError`. Memory stays bounded whatever the file
    holds: one compressed chunk (1 MiB), one decompressed chunk (1 MiB) and one line (at
    most :data:`MAX_LINE_BYTES`).

    Attributes
    ----------
    path : str
        The file as given by the caller (used in messages).
    compressed : bool
        Whether the file is gzip or bzip2 compressed (known once iteration started).
    truncated : str or None
        With ``strict=False``: why the compressed stream could not be read to its end
        (known once iteration ended), else None.
    """

    def __init__(
        self,
        path: _PathLike,
        *,
        strict: bool = True,
        max_line_bytes: int = MAX_LINE_BYTES,
        max_bytes: int = MAX_TEXT_BYTES,
        comments: bool = True,
        quiet: bool = False,
    ):
        self.path = check_path(path)
        self.strict = strict
        self.quiet = quiet  # no warning for a truncated stream (a caller that only peeks)
        self.max_line_bytes = int(max_line_bytes)
        self.max_bytes = int(max_bytes)
        self.compressed = False
        self.truncated: str | None = None
        self.lines_read = 0
        self._pattern = _NONEMPTY if comments else _RECORD

    @property
    def name(self) -> str:
        """The file's base name, for scan ``source`` strings."""
        return os.path.basename(self.path)

    def _fail(self, line: int | None, why: str) -> ParseError:
        return ParseError(self.path, line, why)

    def _chunks(self, fh) -> Iterator[bytes]:
        """The file's (decompressed) bytes, chunk by chunk, with the size checks."""
        first = fh.read(_CHUNK)
        kind = "gzip" if first[:2] == GZIP_MAGIC else "bzip2" if first[:3] == BZIP2_MAGIC else None
        total_out = 0
        if kind is None:
            data = first
            while data:
                total_out += len(data)
                if total_out > self.max_bytes:
                    raise self._fail(None, f"larger than the limit of {_size(self.max_bytes)}")
                yield data
                data = fh.read(_CHUNK)
            return
        self.compressed = True
        dec = _Decoder(kind)
        total_in = 0
        data = first
        try:
            while data:
                total_in += len(data)
                for out in dec.feed(data):
                    total_out += len(out)
                    if total_out > self.max_bytes:
                        raise self._fail(
                            None,
                            f"decompresses to more than the limit of {_size(self.max_bytes)}",
                        )
                    if total_out > EXPANSION_CHECK_BYTES and total_out > MAX_EXPANSION * total_in:
                        raise self._fail(
                            None,
                            f"expands more than {MAX_EXPANSION}:1 ({_size(total_out)} from "
                            f"{_size(total_in)} read so far): not a log (text logs expand "
                            "5-15 times; a decompression bomb?)",
                        )
                    yield out
                data = fh.read(_CHUNK)
        except _StreamEnd as end:
            tail = end.tail + fh.read(_CHUNK)
            if tail.strip(b"\x00"):  # zero padding after the last member is harmless
                why = f"{len(end.tail)} bytes of trailing garbage after the {kind} stream"
                if self.strict:
                    raise self._fail(None, why) from None
                self.truncated = why
            return
        except (zlib.error, OSError, EOFError) as exc:
            why = f"corrupt {kind} stream ({exc})"
            if self.strict:
                raise self._fail(None, why) from None
            self.truncated = why
            return
        if not dec.done:
            why = (
                f"truncated {kind} stream: the compressed data end before the {kind} end "
                "marker (incomplete download or copy?)"
            )
            if self.strict:
                raise self._fail(None, why)
            self.truncated = why

    def _decode(self, line_no: int, bline: bytes) -> str | None:
        if b"\x00" not in bline:
            try:
                return bline.decode("utf-8").rstrip("\r")
            except UnicodeDecodeError:
                pass
        if self.strict:
            raise self._fail(line_no, _bad_bytes_message(bline))
        return None

    def __iter__(self) -> Iterator[tuple[int, str | None]]:
        with open_regular(self.path) as fh:
            yield from self._lines(fh)
        if self.truncated and not self.quiet:
            logger.warning("%s: %s; reading what was recovered", self.path, self.truncated)

    def _too_long(self, line_no: int) -> ParseError:
        return self._fail(
            line_no,
            f"line longer than {_size(self.max_line_bytes)} (binary data or a corrupt file?)",
        )

    @staticmethod
    def _without_bom(chunks: Iterator[bytes]) -> Iterator[bytes]:
        """``chunks`` less a UTF-8 byte order mark at the head of the text.

        Editors on Windows save one; left in place it would glue itself to the first
        record's type (``\\ufeffFLASER``) and that record would be skipped as an unknown
        message, silently. The mark is not content, so it is dropped, whether the file is
        plain or compressed; a mark anywhere else is content and kept.
        """
        head = b""
        for chunk in chunks:
            head += chunk
            if len(head) < len(_UTF8_BOM) and _UTF8_BOM.startswith(head):
                continue  # too short to tell yet
            break
        else:  # the text ended within three bytes: a part of a mark is content
            if head:
                yield head
            return
        yield head[len(_UTF8_BOM) :] if head.startswith(_UTF8_BOM) else head
        yield from chunks

    def _lines(self, fh) -> Iterator[tuple[int, str | None]]:
        line_no = 1  # number of the line that starts at the head of ``pending``
        pending = b""
        skipping = False  # discarding the rest of an over-long line (strict=False)
        limit = self.max_line_bytes
        for chunk in self._without_bom(self._chunks(fh)):
            if skipping:
                k = chunk.find(b"\n")
                if k < 0:
                    continue
                chunk = chunk[k + 1 :]
                line_no += 1
                skipping = False
            data = pending + chunk if pending else chunk
            last = data.rfind(b"\n")
            if last < 0:
                pending = data
                if len(pending) > limit:
                    if self.strict:
                        raise self._too_long(line_no)
                    yield line_no, None
                    pending, skipping = b"", True
                continue
            pos = 0
            for m in self._pattern.finditer(data, 0, last):
                start = m.start()
                line_no += data.count(b"\n", pos, start)
                bline = m.group()
                if len(bline) > limit:
                    if self.strict:
                        raise self._too_long(line_no)
                    yield line_no, None
                else:
                    yield line_no, self._decode(line_no, bline)
                self.lines_read = line_no
                pos = start
            line_no += data.count(b"\n", pos, last + 1)
            pending = data[last + 1 :]
            if len(pending) > limit:
                if self.strict:
                    raise self._too_long(line_no)
                yield line_no, None
                pending, skipping = b"", True
        if pending and not skipping and self._pattern.match(pending):
            yield line_no, self._decode(line_no, pending)
            self.lines_read = line_no


def _size(n: float) -> str:
    for unit, k in (("GiB", 2**30), ("MiB", 2**20), ("KiB", 2**10)):
        if n >= k:
            return f"{n / k:.1f} {unit}"
    return f"{int(n)} bytes"


@dataclass(frozen=True, slots=True, eq=False)
class TextLines:
    """The lines of a text file, loaded whole by :func:`read_lines` (small files; the
    readers stream through :class:`LineSource` instead).

    Attributes
    ----------
    path : str
        The file as given by the caller (used in messages).
    lines : tuple of (str or None)
        Line ``k`` (1-based) is ``lines[k - 1]``, without its end-of-line characters.
        ``None`` marks a line that could not be decoded (only with ``strict=False``).
    truncated : str or None
        With ``strict=False``: why the (compressed) file could not be read to its end.
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

    def __iter__(self) -> Iterator[tuple[int, str | None]]:
        """``(line_no, line)`` of the non-empty lines, as :class:`LineSource` yields them."""
        for k, line in enumerate(self.lines, start=1):
            if line is None or line:
                yield k, line


def is_gzip(path: _PathLike) -> bool:
    """Whether the file starts with the gzip magic bytes ``1f 8b`` (whatever its suffix).

    Raises
    ------
    DataNotFoundError
        If there is no such file.
    """
    return _read_bytes(path, head=2) == GZIP_MAGIC


def _read_bytes(path: _PathLike, head: int) -> bytes:
    """The first ``head`` bytes of a regular file (see :func:`open_regular`)."""
    with open_regular(path) as fh:
        return fh.read(head)


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
    """Load a text file (plain, gzip or bzip2, detected by magic bytes) as lines, whole.

    The readers stream through :class:`LineSource`; this keeps every line in memory and
    is meant for small files.

    Parameters
    ----------
    path : str or path-like
        The file.
    strict : bool
        If True (default) any problem raises. If False, a truncated or corrupt compressed
        stream keeps what could be decompressed (reported in :attr:`TextLines.truncated`)
        and undecodable lines become ``None``.

    Returns
    -------
    TextLines
        An empty file gives no lines.

    Raises
    ------
    DataNotFoundError
        If there is no such file.
    ParseError
        Not a regular file, truncated/corrupt compression (names the file), undecodable
        bytes or NUL bytes (names the file and the line).
    """
    src = LineSource(path, strict=strict)
    lines: list[str | None] = []
    for k, line in src:
        lines.extend([""] * (k - 1 - len(lines)))
        lines.append(line)
    return TextLines(src.path, tuple(lines), src.truncated, src.compressed)


# ---------------------------------------------------------------------------------------
# Field parsing shared by the readers
# ---------------------------------------------------------------------------------------
def parse_float_fields(tokens: Sequence[str], start: int, stop: int, field_name, err) -> np.ndarray:
    """Parse ``tokens[start:stop]`` as float64 in one NumPy call.

    ``nan``/``inf`` are accepted; an underscore or a non-ASCII digit is not
    (:func:`plain_number`). On failure, the first offending token is located and
    ``err(field_name(i), "expects a number, found 'abc'")`` is raised, ``i`` being the
    token's index in ``tokens``.
    """
    if not plain_number("".join(tokens[start:stop])):
        raise _bad_number(tokens, start, stop, field_name, err)
    return parse_plain_float_fields(tokens, start, stop, field_name, err)


def parse_plain_float_fields(
    tokens: Sequence[str], start: int, stop: int, field_name, err
) -> np.ndarray:
    """:func:`parse_float_fields` of tokens the caller knows to be :func:`plain_number`
    text (it looked at the whole line at once: a reader's hot path)."""
    try:
        return np.array(tokens[start:stop], dtype=np.float64)
    except ValueError:
        raise _bad_number(tokens, start, stop, field_name, err) from None


def plain_number(text: str) -> bool:
    """Whether ``text`` can hold numbers only as data files write them: ASCII, without an
    underscore. Python's ``float``/``int`` and NumPy also read PEP 515's digit grouping
    (``"1_0"`` is 10) and any Unicode digit (``"١٢"`` is 12), which no log means."""
    return "_" not in text and text.isascii()


def plain_float(token: str) -> float:
    """``float(token)`` of :func:`plain_number` text only: ``"1_0"`` or ``"١٢"`` raises
    ValueError like ``"abc"``. For the readers that parse one field at a time (Victoria
    Park tables, relations files)."""
    if not plain_number(token):
        raise ValueError(f"could not convert string to float: {token!r}")
    return float(token)


def _bad_number(tokens: Sequence[str], start: int, stop: int, field_name, err):
    """The error of the first token of ``tokens[start:stop]`` that is not a number."""
    for i in range(start, stop):
        try:
            plain_float(tokens[i])
        except ValueError:
            return err(field_name(i), f"expects a number, found {tokens[i]!r}")
    return err(None, "expects numbers")  # pragma: no cover


def parse_count(token: str, field: str, limit: int, err) -> int:
    """Parse a non-negative integer count no larger than ``limit``; ``err(field, msg)`` else
    (one that is not :func:`plain_number` text included: ``int("1_0")`` is 10)."""
    try:
        if not plain_number(token):
            raise ValueError(token)
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
_SECTIONS = ("ODOM", "REF", "ANGLES", "TIMES")
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
    if scan.beam_times is not None:
        parts.append("TIMES")
        parts.extend(map(repr, scan.beam_times.tolist()))
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
    odometry = reference = angles = times = None
    i = 7 + n
    while i < len(tokens):
        key = tokens[i]
        if key not in _SECTIONS:
            raise err(None, f"expected ODOM, REF, ANGLES or TIMES after the ranges, found {key!r}")
        if (key == "ODOM" and odometry is not None) or (key == "REF" and reference is not None):
            raise err(key, f"{key} given twice")
        if key == "ODOM":
            odometry, i = _pose_section(tokens, i, "ODOM", err)
        elif key == "REF":
            reference, i = _pose_section(tokens, i, "REF", err)
        else:
            if (angles if key == "ANGLES" else times) is not None:
                raise err(key, f"{key} given twice")
            if i + 1 + n > len(tokens):
                raise err(key, f"{key} expects {n} values, found {len(tokens) - i - 1}")
            one = "angle" if key == "ANGLES" else "time"
            values = parse_float_fields(
                tokens, i + 1, i + 1 + n, lambda k, i=i, one=one: f"{one}[{k - i - 1}]", err
            )
            if key == "ANGLES":
                angles = values
            else:
                times = values
            i += 1 + n
    if angles is None:
        if not (math.isfinite(a0) and math.isfinite(inc)):
            raise err("angle_min", f"SCAN expects finite angles, found {a0}, {inc}")
        angles = beam_angles(n, a0, inc)
    try:
        return Scan(ranges, angles, rmin, rmax, t, odometry, reference, source, times)
    except ScanError as exc:  # the error names file and line: not the scan's source again
        raise err(None, str(exc).removeprefix(f"{source}: ")) from None


class _TextReader:
    """One pass over the lines of a scan text file (internal; see
    :class:`scanclique.io.carmen._CarmenReader` for ``wanted``, ``last`` and ``n_scans``)."""

    def __init__(self, lines, strict: bool, max_beams: int):
        self.lines = lines
        self.strict = strict
        self.max_beams = int(max_beams)
        self.n_scans: int | None = None
        self.skipped = 0

    def scans(self, wanted=None, last: int | None = None) -> Iterator[tuple[int, Scan]]:
        lines, strict = self.lines, self.strict
        index = 0
        stopped = False
        for line_no, line in lines:
            if line is None:
                self.skipped += 1
                logger.warning("%s:%d: skipped an undecodable line", lines.path, line_no)
                continue
            tokens = line.split()
            if not tokens or tokens[0].startswith("#"):
                continue

            def err(field, message, _ln=line_no):
                return ParseError(lines.path, _ln, message, field=field)

            if strict and wanted is not None and tokens[0] == "SCAN" and not wanted(index):
                index += 1
            else:
                try:
                    if tokens[0] != "SCAN":
                        raise err(None, f"expected a SCAN record, found {tokens[0][:40]!r}")
                    scan = _parse_scan_line(tokens, self.max_beams, err, f"{lines.name}:{line_no}")
                except ParseError as exc:
                    if strict:
                        raise
                    self.skipped += 1
                    logger.warning("skipped malformed line: %s", exc)
                    continue
                if wanted is None or wanted(index):
                    yield index, scan
                index += 1
            if strict and last is not None and index > last:
                stopped = True
                break
        if self.skipped:
            logger.warning(
                "%s: skipped %d malformed or undecodable lines", lines.path, self.skipped
            )
        self.n_scans = None if stopped else index


def parse_scans_text(lines, *, strict: bool = True, max_beams: int = 100_000) -> list[Scan]:
    """Scans from the lines of a scan text file (see the module docstring): a
    :class:`LineSource` (streamed) or :class:`TextLines`.

    With ``strict=False`` malformed and undecodable lines are skipped and logged at warning
    level; otherwise the first one raises :class:`~scanclique.errors.ParseError`.
    """
    return [scan for _, scan in _TextReader(lines, strict, max_beams).scans()]


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
    lines = LineSource(path, strict=strict, comments=False)
    return parse_scans_text(lines, strict=strict, max_beams=max_beams)
