r"""Tables of numbers in plain text: one row per line, whitespace- or comma-separated, with
comments, blank lines and a header row skipped (the landmark logs of
:mod:`scanclique.slam.reader`, TUM trajectories of :mod:`.tum`).

>>> import tempfile, os
>>> p = os.path.join(tempfile.mkdtemp(), "t.csv")
>>> _ = open(p, "w").write("time,x\n# a comment\n0.5,1\n1.5,2\n")
>>> read_table(p, ("time", "x")).tolist()
[[0.5, 1.0], [1.5, 2.0]]
>>> table_line(p, 1)
4
"""

from __future__ import annotations

import io
import math
import os
import warnings
from pathlib import Path

import numpy as np

from ..errors import DataNotFoundError, ParseError
from .text import plain_float

__all__ = ["read_table", "table_line", "is_header"]


def read_table(
    path: str | os.PathLike,
    columns: tuple[str, ...],
    *,
    ordered: bool = True,
    optional: tuple[str, ...] = (),
) -> np.ndarray:
    """A table of floats, one row per non-empty line, separated by whitespace or, when the
    first row holds a comma, by commas (CSV).

    Lines starting with ``#`` and blank lines are skipped, and so is a first row whose
    fields are all names (words, not numbers: a CSV header of column names). Every row must hold
    ``len(columns)`` finite numbers and, when ``ordered``, the first column (time) must
    not decrease. When the first data row holds ``len(columns) + len(optional)`` fields,
    the ``optional`` columns are read too, and every row must hold them (the table's
    width is that of its first data row).

    Raises
    ------
    ParseError
        Names the file, the 1-based line and the field that is wrong.
    """
    path = Path(path)
    n = len(columns)
    try:
        data = path.read_bytes()
    except FileNotFoundError:
        raise DataNotFoundError(f"{path}: no such file") from None
    except OSError as exc:  # a directory, no permission, an I/O error
        raise ParseError(str(path), None, f"cannot be read ({exc.strerror or exc})") from None
    try:  # -sig: a byte order mark at the head is dropped (as the log readers do)
        text = data.decode("utf-8-sig")
    except UnicodeDecodeError as exc:  # binary data, or text in another encoding
        body = exc.object  # the data after the mark, which exc.start counts in
        raise ParseError(
            str(path),
            body.count(b"\n", 0, exc.start) + 1,
            f"expected UTF-8/ASCII text, found the byte {body[exc.start : exc.start + 1]!r} "
            "(binary data?)",
        ) from None
    lines = text.splitlines()
    content = (k for k, ln in enumerate(lines) if ln.strip() and not ln.lstrip().startswith("#"))
    first = next(content, None)
    csv = first is not None and "," in lines[first]

    def split(line: str) -> list[str]:
        return _fields(line, csv)

    header = first is not None and is_header(lines[first])
    row = next(content, None) if header else first  # the first data row
    if optional and row is not None and len(split(lines[row].strip())) == n + len(optional):
        columns = (*columns, *optional)
        n = len(columns)
    try:  # fast path: a well-formed file
        if csv or header:
            raise ValueError  # the fast path reads whitespace-separated numbers only
        with warnings.catch_warnings():  # an empty table is a result, not a warning
            warnings.simplefilter("ignore", UserWarning)
            arr = np.loadtxt(io.StringIO(text), dtype=float, comments="#", ndmin=2)
        if arr.size == 0:
            arr = arr.reshape(0, n)
        in_order = not ordered or (np.diff(arr[:, 0]) >= 0).all()
        if arr.shape[1] == n and np.isfinite(arr).all() and in_order:
            return arr
    except ValueError:
        pass
    rows = []
    last_t = -math.inf
    for lineno, line in enumerate(lines, start=1):
        s = line.strip()
        if not s or s.startswith("#") or (header and lineno == first + 1):
            continue
        parts = split(s)
        if len(parts) != n:
            raise ParseError(
                str(path), lineno, f"expected {n} numbers ({' '.join(columns)}), found {len(parts)}"
            )
        vals = []
        for name, p in zip(columns, parts, strict=False):
            try:
                v = plain_float(p)
            except ValueError:
                raise ParseError(str(path), lineno, f"not a number: {p!r}", field=name) from None
            if not math.isfinite(v):
                raise ParseError(str(path), lineno, f"not finite: {p!r}", field=name)
            vals.append(v)
        if ordered and vals[0] < last_t:
            raise ParseError(
                str(path), lineno, f"time goes back: {vals[0]} after {last_t}", field=columns[0]
            )
        last_t = vals[0]
        rows.append(vals)
    return np.array(rows, dtype=float).reshape(-1, n)


def _fields(line: str, csv: bool) -> list[str]:
    """The fields of a table's row: comma-separated (stripped) when ``csv``, else
    whitespace-separated."""
    return [p.strip() for p in line.split(",")] if csv else line.split()


def is_header(line: str) -> bool:
    """Whether a table's first row is a header: its fields (comma- or whitespace-
    separated, as :func:`read_table` splits them) all names, none a number."""
    s = line.strip()
    parts = _fields(s, "," in s)
    return all(p[:1].isalpha() and not _is_number(p) for p in parts)


def _is_number(text: str) -> bool:
    try:
        plain_float(text)
    except ValueError:
        return False
    return True


def table_line(path: str | os.PathLike, row: int) -> int:
    """1-based line number of data row ``row`` (comments, blank lines and a header row
    skipped, as :func:`read_table` skips them)."""
    k = -1
    first = True
    with open(path, encoding="utf-8-sig", errors="replace") as fh:
        for lineno, line in enumerate(fh, start=1):
            s = line.strip()
            if s and not s.startswith("#"):
                if first and is_header(s):
                    first = False
                    continue
                first = False
                k += 1
                if k == row:
                    return lineno
    return k + 1
