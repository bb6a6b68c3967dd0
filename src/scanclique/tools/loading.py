"""Loading what a command works on: one scan, a pair of scans, a configuration.

Plain functions (no typer, no rich) that ``scanclique`` commands and scripts call alike.
A source is a path to a log (CARMEN, ``.npz``, scan text; gzip or bzip2) or the name of
a registered data set (``"intel"``, see :mod:`scanclique.datasets`).
"""

from __future__ import annotations

import logging
import os
from pathlib import Path

from .. import datasets
from ..config import MatchConfig, paper_config
from ..errors import ScanIndexError
from ..scan import Scan

__all__ = ["load_scan", "load_scan_pair", "load_config", "odometry_path"]

log = logging.getLogger(__name__)


def _parse_index(text: str | int, what: str) -> int:
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


def load_scan(source: str | os.PathLike, index: int | None = None) -> tuple[Scan, str, list[str]]:
    """One scan of a log (a path or a registered name such as ``"intel"``).

    ``index`` None means the file holds one scan; if it holds several the first is used
    and a note says so.

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
    scans = datasets.load_log(source)
    label = _label(source)
    notes: list[str] = []
    if not scans:
        raise ScanIndexError(f"{os.fspath(source)}: holds no scan")
    if index is None:
        if len(scans) > 1:
            notes.append(f"{os.fspath(source)} holds {len(scans)} scans; using the first (index 0)")
        index = 0
    elif not 0 <= index < len(scans):
        raise ScanIndexError(
            f"{os.fspath(source)}: scan index {index} out of range: "
            f"the log has {len(scans)} scans (0..{len(scans) - 1})"
        )
    return scans[index], f"{label}:{index}", notes


def load_scan_pair(
    source: str | os.PathLike, a: str | int | None = None, b: str | int | None = None
) -> tuple[Scan, Scan, tuple[str, str], list[str]]:
    """The two scans of ``scanclique match``, in either form.

    * ``load_scan_pair(LOG, 120, 125)``: scans 120 and 125 of a log (a path, or a
      registered name such as ``"intel"``);
    * ``load_scan_pair("a.txt", "b.txt")``: the scan in each file (the first if a file
      holds several; a note says so).

    Returns
    -------
    (scan_a, scan_b, (name_a, name_b), notes)
    """
    if b is not None:
        ia = _parse_index(a, "A") if a is not None else 0
        ib = _parse_index(b, "B")
        scan_a, name_a, notes_a = load_scan(source, ia)
        scan_b, name_b, notes_b = load_scan(source, ib)
        return scan_a, scan_b, (name_a, name_b), notes_a + notes_b
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
    scan_a, name_a, notes_a = load_scan(source)
    scan_b, name_b, notes_b = load_scan(second)
    return scan_a, scan_b, (name_a, name_b), notes_a + notes_b


def load_config(path: str | os.PathLike | None = None, paper: bool = False) -> MatchConfig:
    """The configuration of a run: ``paper_config()`` with ``paper`` else ``MatchConfig()``,
    then the keys of the TOML file ``path`` (if any) on top."""
    base = paper_config() if paper else MatchConfig()
    if path is None:
        return base
    from ..io.config import read_config

    return read_config(path, base=base)


def odometry_path(
    source: str | os.PathLike, a: str | int | None, b: str | int | None
) -> list | None:
    """The odometry poses (:class:`~scanclique.geometry.Pose2`) of the scans from A to B
    when the scans are ``a`` and ``b`` of the log ``source`` (for the distance travelled,
    see :func:`scanclique.validation.odometry_prior`); None when the scans come from two
    files or a scan in between has no odometry."""
    if b is None:
        return None
    ia = _parse_index(a, "A") if a is not None else 0
    ib = _parse_index(b, "B")
    scans = datasets.load_log(source)
    lo, hi = min(ia, ib), max(ia, ib)
    if not (0 <= lo and hi < len(scans)):
        return None
    path = [s.odometry for s in scans[lo : hi + 1]]
    if any(p is None for p in path):
        return None
    return path if ia <= ib else path[::-1]
