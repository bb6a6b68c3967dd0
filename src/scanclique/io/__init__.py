"""Readers and writers: files in, :class:`~scanclique.scan.Scan` records out.

:func:`read_scans` is the one entry point; it picks the reader from the file itself:

* a NumPy ``.npz`` archive (suffix ``.npz`` or zip magic bytes) -> :mod:`.npz`;
* scanclique's scan text format (first record ``SCAN ...``, or suffix ``.txt``/``.scan``,
  optionally ``.gz``) -> :mod:`.text`;
* anything else -> a CARMEN log (plain or gzip, detected by magic bytes) -> :mod:`.carmen`.

Nothing downstream of the readers parses files.
"""

from __future__ import annotations

import os
from pathlib import Path

from ..scan import Scan
from .carmen import (
    DEFAULT_MAX_BEAMS,
    FLASER_MAX_RANGE,
    KNOWN_MESSAGES,
    CarmenLog,
    flaser_angles,
    interpolate_odometry,
    parse_carmen,
    read_carmen,
)
from .npz import read_scans_npz, write_scans_npz
from .text import (
    TextLines,
    _read_bytes,
    is_gzip,
    parse_scans_text,
    read_lines,
    read_scans_text,
    write_scans_text,
)

__all__ = [
    "read_scans",
    "detect_format",
    "read_carmen",
    "CarmenLog",
    "read_scans_text",
    "write_scans_text",
    "read_scans_npz",
    "write_scans_npz",
    "read_lines",
    "is_gzip",
    "flaser_angles",
    "interpolate_odometry",
    "FLASER_MAX_RANGE",
    "DEFAULT_MAX_BEAMS",
]

_ZIP_MAGIC = b"PK\x03\x04"
_EMPTY_ZIP_MAGIC = b"PK\x05\x06"
_TEXT_SUFFIXES = (".txt", ".scan", ".scans")


def _head(path: str | os.PathLike, size: int = 4) -> bytes:
    return _read_bytes(path, head=size)


def _stem_suffix(path: str | os.PathLike) -> str:
    """The suffix that names the content: ``a.scan.gz`` -> ``.scan``."""
    p = Path(path)
    if p.suffix.lower() == ".gz":
        p = p.with_suffix("")
    return p.suffix.lower()


def _format_of_lines(lines: TextLines, path) -> str:
    for line in lines.lines:
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

    Raises
    ------
    DataNotFoundError
        If there is no such file.
    """
    head = _head(path)
    if head.startswith((_ZIP_MAGIC, _EMPTY_ZIP_MAGIC)) or _stem_suffix(path) == ".npz":
        return "npz"
    return _format_of_lines(read_lines(path, strict=False), path)


def read_scans(
    path: str | os.PathLike,
    *,
    strict: bool = True,
    max_beams: int = DEFAULT_MAX_BEAMS,
    max_range: float = FLASER_MAX_RANGE,
) -> list[Scan]:
    """Read every scan of a file: one :class:`~scanclique.scan.Scan` per laser message.

    Parameters
    ----------
    path : str or path-like
        A CARMEN log (plain or gzip), a scan text file, or an ``.npz`` archive; the format
        is detected from the content (see the module docstring).
    strict : bool
        If True (default) the first malformed line raises
        :class:`~scanclique.errors.ParseError`; if False malformed lines are skipped,
        counted and logged at warning level (text formats only; an ``.npz`` is all or
        nothing).
    max_beams : int
        Largest accepted beam count in one message or record (guards corrupt counts).
    max_range : float
        CARMEN only: ``Scan.range_max`` (metres) for messages without a maximum range
        (FLASER, RLASER); readings at or beyond it are no return. Default 80 m, right for
        the SICK logs of the shared data (no return logged as 81.83 or 81.91).

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

    See Also
    --------
    read_carmen : the CARMEN reader, also returning PARAM values and skip counts.
    """
    head = _head(path)
    if head.startswith((_ZIP_MAGIC, _EMPTY_ZIP_MAGIC)) or _stem_suffix(path) == ".npz":
        return read_scans_npz(path)
    lines = read_lines(path, strict=strict)
    if _format_of_lines(lines, path) == "text":
        return parse_scans_text(lines, strict=strict, max_beams=max_beams)
    log = parse_carmen(lines, strict=strict, max_beams=max_beams, max_range=max_range)
    return list(log.scans)
