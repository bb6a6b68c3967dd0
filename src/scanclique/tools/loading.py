"""Loading what a command works on: one scan, a pair of scans, a configuration.

Plain functions (no typer, no rich) that ``scanclique`` commands and scripts call alike.
A source is a path to a log (CARMEN, ``.npz``, scan text; gzip or bzip2) or the name of
a registered data set (``"intel"``, see :mod:`scanclique.datasets`). Only the scans asked
for are built (:func:`scanclique.io.read_scans_at`): ``load_scan_pair("intel", 120, 121)``
parses two laser lines and stops reading after the second.
"""

from __future__ import annotations

import logging
import os
from pathlib import Path

from .. import datasets
from ..config import MatchConfig, paper_config
from ..errors import ArgumentError, ScanIndexError
from ..io import read_scans_at
from ..scan import Scan

__all__ = ["load_scan", "load_scan_pair", "load_config", "odometry_path", "read_options"]

log = logging.getLogger(__name__)


def read_options(max_range: float | None = None, max_beams: int | None = None) -> dict:
    """The keyword arguments of :func:`scanclique.io.read_scans` that were given (None:
    the reader's default)."""
    out: dict = {}
    if max_range is not None:
        out["max_range"] = max_range
    if max_beams is not None:
        out["max_beams"] = max_beams
    return out


def _parse_index(text: str | int, what: str) -> int:
    if isinstance(text, bool):
        raise ScanIndexError(f"{what} must be an integer scan index, got {text!r}")
    if isinstance(text, int):
        return text
    try:
        return int(str(text).strip())
    except ValueError:
        raise ScanIndexError(f"{what} must be an integer scan index, got {text!r}") from None


def _label(source: str | os.PathLike) -> str:
    """A short name for messages: a registered name as given, a file by its name."""
    s = os.fspath(source)
    return s if not Path(s).exists() and "/" not in s else Path(s).name


def _out_of_range(source, index: int, n: int) -> ScanIndexError:
    if n == 0:
        return ScanIndexError(f"{os.fspath(source)}: holds no scan")
    return ScanIndexError(
        f"{os.fspath(source)}: scan index {index} out of range: the log has {n} scans (0..{n - 1})"
    )


def _check_source(source) -> None:
    if not isinstance(source, (str, os.PathLike)):
        raise ArgumentError(f"source must be a path or a registered data set name, got {source!r}")


def _read(
    source, indices: list[int], count: bool, options: dict, notes: list | None = None
) -> tuple[dict, int | None]:
    """Scans of ``indices`` (all non-negative) and the scan count (None if unknown); the
    reader's notes (a no-return value found) are appended to ``notes``."""
    _check_source(source)
    path = datasets.resolve_log(source)
    sel = read_scans_at(path, indices, count=count, **options)
    if notes is not None:
        notes.extend(sel.notes())
    return dict(sel.scans), sel.n_scans


def load_scan(
    source: str | os.PathLike, index: int | None = None, **options
) -> tuple[Scan, str, list[str]]:
    """One scan of a log (a path or a registered name such as ``"intel"``).

    ``index`` None means the file holds one scan; if it holds several the first is used
    and a note says so. Only that scan is built.

    Parameters
    ----------
    source : str or path-like
    index : int, optional
    **options
        ``max_range``, ``max_beams``, ``strict``: passed to the reader.

    Returns
    -------
    (scan, name, notes)
        ``name`` is ``"<label>:<index>"``; ``notes`` are messages for the user.

    Raises
    ------
    DataNotFoundError
        No such file or registered data set.
    ParseError
        The file is malformed.
    ScanIndexError
        ``index`` out of range, or no scan in the file.
    """
    label = _label(source) if isinstance(source, (str, os.PathLike)) else str(source)
    notes: list[str] = []
    if index is None:
        got, n = _read(source, [0], True, options, notes)
        if not got:
            raise ScanIndexError(f"{os.fspath(source)}: holds no scan")
        if n is not None and n > 1:
            notes.append(f"{os.fspath(source)} holds {n} scans; using the first (index 0)")
        return got[0], f"{label}:0", notes
    index = _parse_index(index, "index")
    if index < 0:
        _, n = _read(source, [], True, options)
        raise _out_of_range(source, index, n or 0)
    got, n = _read(source, [index], False, options, notes)
    if index not in got:
        raise _out_of_range(source, index, n or 0)
    return got[index], f"{label}:{index}", notes


def load_scan_pair(
    source: str | os.PathLike, a: str | int | None = None, b: str | int | None = None, **options
) -> tuple[Scan, Scan, tuple[str, str], list[str]]:
    """The two scans of ``scanclique match``, in either form.

    * ``load_scan_pair(LOG, 120, 125)``: scans 120 and 125 of a log (a path, or a
      registered name such as ``"intel"``), read in one pass that stops after scan 125;
    * ``load_scan_pair("a.txt", "b.txt")``: the scan in each file (the first if a file
      holds several; a note says so).

    ``options`` (``max_range``, ``max_beams``, ``strict``) go to the reader.

    Returns
    -------
    (scan_a, scan_b, (name_a, name_b), notes)
    """
    if b is not None:
        ia = _parse_index(a, "A") if a is not None else 0
        ib = _parse_index(b, "B")
        label = _label(source) if isinstance(source, (str, os.PathLike)) else str(source)
        bad = [i for i in (ia, ib) if i < 0]
        if bad:
            _, n = _read(source, [], True, options)
            raise _out_of_range(source, bad[0], n or 0)
        notes: list[str] = []
        got, n = _read(source, [ia, ib], False, options, notes)
        for i in (ia, ib):
            if i not in got:
                raise _out_of_range(source, i, n or 0)
        return got[ia], got[ib], (f"{label}:{ia}", f"{label}:{ib}"), notes
    if a is None:
        raise ScanIndexError(
            "need two scans: SOURCE A B (a log and two scan indices) or A B (two scan files)"
        )
    second = os.fspath(a) if not isinstance(a, int) else str(a)
    if not Path(second).exists() and second.strip().lstrip("-").isdigit():
        raise ScanIndexError(
            f"{second!r} is not a file: give a log and two scan indices "
            f"(scanclique match {os.fspath(source)} {second} <B>) or two scan files"
        )
    scan_a, name_a, notes_a = load_scan(source, **options)
    scan_b, name_b, notes_b = load_scan(second, **options)
    notes = notes_a + [n for n in notes_b if n not in notes_a]
    return scan_a, scan_b, (name_a, name_b), notes


def load_config(path: str | os.PathLike | None = None, paper: bool = False) -> MatchConfig:
    """The configuration of a run: ``paper_config()`` with ``paper`` else ``MatchConfig()``,
    then the keys of the TOML file ``path`` (if any) on top."""
    base = paper_config() if paper else MatchConfig()
    if path is None:
        return base
    from ..io.config import read_config

    return read_config(path, base=base)


def odometry_path(
    source: str | os.PathLike, a: str | int | None, b: str | int | None, **options
) -> list | None:
    """The odometry poses (:class:`~scanclique.geometry.Pose2`) of the scans from A to B
    when the scans are ``a`` and ``b`` of the log ``source`` (for the distance travelled,
    see :func:`scanclique.validation.odometry_prior`); None when the scans come from two
    files or a scan in between has no odometry. Reads the log up to the later scan."""
    if b is None:
        return None
    ia = _parse_index(a, "A") if a is not None else 0
    ib = _parse_index(b, "B")
    lo, hi = min(ia, ib), max(ia, ib)
    if lo < 0:
        return None
    got, _ = _read(source, list(range(lo, hi + 1)), False, options)
    if len(got) != hi - lo + 1:
        return None
    path = [got[k].odometry for k in range(lo, hi + 1)]
    if any(p is None for p in path):
        return None
    return path if ia <= ib else path[::-1]
