"""Scans in a NumPy ``.npz`` archive: compact, exact, and never unpickled.

Layout (``S`` scans)
--------------------
``ranges``
    ``(S, N)`` float64 when every scan has ``N`` beams; otherwise the ranges of all scans
    concatenated, shape ``(sum N_i,)``, with ``offsets``.
``offsets``
    ``(S + 1,)`` integers, only for ragged scans: scan ``i`` is
    ``ranges[offsets[i]:offsets[i + 1]]``; ``offsets[0] == 0``, ``offsets[-1] == len(ranges)``.
``angles``
    Beam angles (radians), laid out like ``ranges``. A file written elsewhere may instead
    give one ``(N,)`` row shared by all scans of a ``(S, N)`` ``ranges``.
``range_min``, ``range_max``
    ``(S,)`` metres (defaults 0 and 80 when absent).
``timestamp``
    ``(S,)`` seconds, NaN for a scan without one (all None when absent).
``odometry``, ``reference``
    ``(S, 3)`` rows ``x, y, theta``; a row of NaN is None (all None when absent).
``source``
    ``(S,)`` unicode strings (``"<file name>[i]"`` when absent).
``format_version``
    Scalar integer, 1.

Only ``ranges`` and ``angles`` are required. Files are always loaded with
``allow_pickle=False``: an archive holding object arrays is refused, never unpickled.
:func:`write_scans_npz` followed by :func:`read_scans_npz` gives back the same ranges,
angles, limits, timestamps, poses and sources, bit for bit.

Examples
--------
>>> import tempfile, pathlib
>>> from scanclique import Scan
>>> scans = [Scan.from_ranges([1.0, 2.0, 3.0]), Scan.from_ranges([4.0, 5.0], source="b")]
>>> path = pathlib.Path(tempfile.mkdtemp()) / "scans.npz"
>>> write_scans_npz(path, scans)
>>> back = read_scans_npz(path)
>>> [s.ranges.tolist() for s in back], back[1].source
([[1.0, 2.0, 3.0], [4.0, 5.0]], 'b')
"""

from __future__ import annotations

import logging
import math
import os
import zipfile
import zlib
from collections.abc import Iterable

import numpy as np

from ..errors import DataNotFoundError, ParseError, ScanError
from ..geometry import Pose2
from ..scan import Scan

__all__ = ["NPZ_FORMAT_VERSION", "read_scans_npz", "write_scans_npz"]

logger = logging.getLogger(__name__)

NPZ_FORMAT_VERSION = 1

_KNOWN = {
    "ranges",
    "offsets",
    "angles",
    "range_min",
    "range_max",
    "timestamp",
    "odometry",
    "reference",
    "source",
    "format_version",
}


def _pose_rows(poses) -> np.ndarray:
    out = np.full((len(poses), 3), np.nan)
    for i, p in enumerate(poses):
        if p is not None:
            out[i] = (p.x, p.y, p.theta)
    return out


def write_scans_npz(path: str | os.PathLike, scans: Iterable[Scan]) -> None:
    """Write scans to a compressed ``.npz`` archive (layout in the module docstring).

    Parameters
    ----------
    path : str or path-like
        Output file, overwritten; written exactly there (no ``.npz`` is appended).
    scans : iterable of Scan
        Stored in order.
    """
    scans = list(scans)
    lengths = [s.n_beams for s in scans]
    arrays: dict[str, np.ndarray] = {}
    if len(set(lengths)) <= 1:
        n = lengths[0] if lengths else 0
        arrays["ranges"] = np.array([s.ranges for s in scans], dtype=np.float64).reshape(
            len(scans), n
        )
        arrays["angles"] = np.array([s.angles for s in scans], dtype=np.float64).reshape(
            len(scans), n
        )
    else:
        arrays["ranges"] = np.concatenate([s.ranges for s in scans])
        arrays["angles"] = np.concatenate([s.angles for s in scans])
        arrays["offsets"] = np.concatenate(([0], np.cumsum(lengths))).astype(np.int64)
    arrays["range_min"] = np.array([s.range_min for s in scans], dtype=np.float64)
    arrays["range_max"] = np.array([s.range_max for s in scans], dtype=np.float64)
    arrays["timestamp"] = np.array(
        [np.nan if s.timestamp is None else s.timestamp for s in scans], dtype=np.float64
    )
    arrays["odometry"] = _pose_rows([s.odometry for s in scans])
    arrays["reference"] = _pose_rows([s.reference for s in scans])
    arrays["source"] = np.array([s.source for s in scans], dtype=np.str_)
    arrays["format_version"] = np.array(NPZ_FORMAT_VERSION)
    with open(path, "wb") as fh:
        np.savez_compressed(fh, **arrays)  # type: ignore[arg-type]


def _load(path: str | os.PathLike) -> dict[str, np.ndarray]:
    spath = os.fspath(path)
    try:
        with np.load(path, allow_pickle=False) as z:
            if not isinstance(z, np.lib.npyio.NpzFile):  # pragma: no cover - np.load returns
                raise ParseError(spath, None, "expected an .npz archive")
            return {k: z[k] for k in z.files}
    except FileNotFoundError:
        raise DataNotFoundError(f"{spath}: no such file") from None
    except AttributeError:
        # a single .npy array: np.load returned an ndarray, which has no context manager
        raise ParseError(
            spath, None, "expected an .npz archive, found a single .npy array"
        ) from None
    except ValueError as exc:
        if "pickle" in str(exc):
            raise ParseError(
                spath, None, "refused: the file needs unpickling (object arrays or not an .npz)"
            ) from None
        raise ParseError(spath, None, f"not a readable .npz archive ({exc})") from None
    except (OSError, EOFError, zipfile.BadZipFile, zlib.error, NotImplementedError) as exc:
        # damaged archives: truncated, bad CRC or deflate stream, unsupported zip features
        raise ParseError(spath, None, f"not a readable .npz archive ({exc})") from None


def _float_array(arrays, key, path, shape=None) -> np.ndarray:
    a = arrays[key]
    if a.dtype.kind not in "fiub":
        raise ParseError(path, None, f"expected real numbers, found dtype {a.dtype}", field=key)
    a = a.astype(np.float64)
    if shape is not None and a.shape != shape:
        raise ParseError(path, None, f"expected shape {shape}, found {a.shape}", field=key)
    return a


def _poses(arrays, key, path, S) -> list[Pose2 | None]:
    if key not in arrays:
        return [None] * S
    rows = _float_array(arrays, key, path, (S, 3))
    out: list[Pose2 | None] = []
    for i, row in enumerate(rows):
        if np.all(np.isnan(row)):
            out.append(None)
        elif np.all(np.isfinite(row)):
            out.append(Pose2(*row.tolist()))
        else:
            raise ParseError(
                path,
                None,
                f"expected a finite pose or a row of NaN, found {row.tolist()}",
                field=f"{key}[{i}]",
            )
    return out


def read_scans_npz(path: str | os.PathLike) -> list[Scan]:
    """Read scans from an ``.npz`` archive (layout in the module docstring).

    Parameters
    ----------
    path : str or path-like
        The archive. Loaded with ``allow_pickle=False``.

    Returns
    -------
    list of Scan
        In stored order.

    Raises
    ------
    ParseError
        Not a readable archive, object (pickled) arrays, a missing or malformed array
        (the field names the array), or values a :class:`Scan` refuses.
    DataNotFoundError
        If there is no such file.
    """
    spath = os.fspath(path)
    name = os.path.basename(spath)
    arrays = _load(path)
    for key in ("ranges", "angles"):
        if key not in arrays:
            raise ParseError(
                spath, None, f"missing array {key!r} (found {sorted(arrays)})", field=key
            )
    unknown = sorted(set(arrays) - _KNOWN)
    if unknown:
        logger.debug("%s: ignoring unknown arrays %s", spath, unknown)
    ranges = _float_array(arrays, "ranges", spath)
    angles = _float_array(arrays, "angles", spath)

    if "offsets" in arrays:
        off = arrays["offsets"]
        if off.dtype.kind not in "iu" or off.ndim != 1 or off.size < 1:
            raise ParseError(
                spath,
                None,
                f"expected a 1-D integer array, found {off.dtype} {off.shape}",
                field="offsets",
            )
        if ranges.ndim != 1 or angles.shape != ranges.shape:
            raise ParseError(
                spath,
                None,
                "with offsets, ranges and angles must be 1-D of equal length, found "
                f"{ranges.shape} and {angles.shape}",
                field="ranges",
            )
        if off[0] != 0 or off[-1] != ranges.size or np.any(np.diff(off) < 0):
            raise ParseError(
                spath,
                None,
                f"expected non-decreasing offsets from 0 to {ranges.size}",
                field="offsets",
            )
        bounds = off.tolist()
        S = len(bounds) - 1
        rows_r = [ranges[bounds[i] : bounds[i + 1]] for i in range(S)]
        rows_a = [angles[bounds[i] : bounds[i + 1]] for i in range(S)]
    else:
        if ranges.ndim != 2:
            raise ParseError(
                spath,
                None,
                f"expected shape (S, N) (or 1-D with offsets), found {ranges.shape}",
                field="ranges",
            )
        S = ranges.shape[0]
        if angles.shape == ranges.shape:
            rows_a = list(angles)
        elif angles.ndim == 1 and angles.shape[0] == ranges.shape[1]:
            rows_a = [angles] * S
        else:
            raise ParseError(
                spath,
                None,
                f"expected shape {ranges.shape} or ({ranges.shape[1]},), found {angles.shape}",
                field="angles",
            )
        rows_r = list(ranges)

    rmin = _float_array(arrays, "range_min", spath, (S,)) if "range_min" in arrays else np.zeros(S)
    rmax = (
        _float_array(arrays, "range_max", spath, (S,))
        if "range_max" in arrays
        else np.full(S, 80.0)
    )
    if "timestamp" in arrays:
        ts = _float_array(arrays, "timestamp", spath, (S,))
        if np.any(np.isinf(ts)):
            raise ParseError(
                spath, None, "expected finite timestamps or NaN, found inf", field="timestamp"
            )
        stamps = [None if math.isnan(t) else t for t in ts.tolist()]
    else:
        stamps = [None] * S
    odometry = _poses(arrays, "odometry", spath, S)
    reference = _poses(arrays, "reference", spath, S)
    if "source" in arrays:
        src = arrays["source"]
        if src.dtype.kind not in "US" or src.shape != (S,):
            raise ParseError(
                spath, None, f"expected {S} strings, found {src.dtype} {src.shape}", field="source"
            )
        sources = [
            s.decode("utf-8", "replace") if isinstance(s, bytes) else str(s) for s in src.tolist()
        ]
    else:
        sources = [f"{name}[{i}]" for i in range(S)]

    scans = []
    for i in range(S):
        try:
            scans.append(
                Scan(
                    rows_r[i],
                    rows_a[i],
                    rmin[i],
                    rmax[i],
                    stamps[i],
                    odometry[i],
                    reference[i],
                    sources[i],
                )
            )
        except ScanError as exc:
            raise ParseError(spath, None, str(exc), field=f"scan[{i}]") from None
    return scans
