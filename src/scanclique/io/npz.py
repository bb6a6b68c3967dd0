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
``beam_times``
    Seconds after each scan's timestamp at which its beams were measured
    (:attr:`Scan.beam_times`), laid out like ``ranges``; a scan's all-NaN row is None
    (written only when some scan has them; all None when absent).
``format_version``
    Scalar integer, 1.

Only ``ranges`` and ``angles`` are required. Files are always loaded with
``allow_pickle=False``: an archive holding object arrays is refused, never unpickled.
:func:`write_scans_npz` followed by :func:`read_scans_npz` gives back the same ranges,
angles, limits, timestamps, poses, sources and beam times, bit for bit.

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
from collections.abc import Iterable

import numpy as np

from ..errors import ParseError, ScanError
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
    "beam_times",
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
    if any(s.beam_times is not None for s in scans):
        rows = [np.full(s.n_beams, np.nan) if s.beam_times is None else s.beam_times for s in scans]
        bt = np.concatenate(rows) if "offsets" in arrays else np.array(rows, dtype=np.float64)
        arrays["beam_times"] = bt.reshape(arrays["ranges"].shape)
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


def _beam_times(arrays, spath: str, rows_r: list, bounds: list | None) -> list:
    """Each scan's beam times (None for an all-NaN row), laid out like ``ranges``."""
    S = len(rows_r)
    if "beam_times" not in arrays:
        return [None] * S
    bt = arrays["beam_times"]
    shape = (
        (sum(len(r) for r in rows_r),) if bounds is not None else (S, len(rows_r[0]) if S else 0)
    )
    if bt.dtype.kind != "f" or bt.shape != shape:
        raise ParseError(
            spath, None, f"expected {shape} floats like ranges, found {bt.dtype} {bt.shape}",
            field="beam_times",
        )  # fmt: skip
    rows = [bt[bounds[i] : bounds[i + 1]] for i in range(S)] if bounds is not None else list(bt)
    out = []
    for i, row in enumerate(rows):
        nan = np.isnan(row)
        if nan.all():  # (a scan of no beams too)
            out.append(None)
        elif nan.any():
            raise ParseError(
                spath, None, f"scan {i}: some beam times NaN, not all", field="beam_times"
            )
        else:
            out.append(row)
    return out


MAX_NPZ_ARRAY_BYTES = 2 * 2**30
"""Largest array (decompressed bytes) read from an ``.npz``, checked against the archive's
directory and the array's header before anything is decompressed."""

MAX_NPZ_SCANS = 1_000_000
"""Most scans in one ``.npz`` (each costs a :class:`Scan` even with no beams)."""

_NPY_MAGIC = b"\x93NUMPY"


def _head_bytes(spath: str) -> bytes:
    from .text import _read_bytes

    return _read_bytes(spath, 64)


def _describe_non_zip(spath: str) -> str:
    """Why a file named ``.npz`` is not an archive: what it is instead."""
    from .text import _read_bytes

    head = _read_bytes(spath, 64)
    if head.startswith(_NPY_MAGIC):
        return "expected an .npz archive, found a single .npy array"
    if not head:
        return "expected an .npz archive, found an empty file"
    if head[:2] == b"\x1f\x8b" or head[:3] == b"BZh":
        return "expected an .npz archive, found a gzip or bzip2 file (a compressed log?)"
    sample = head.split(b"\n", 1)[0][:40]
    if all(32 <= c < 127 or c in (9, 13) for c in sample):
        return (
            f"expected an .npz archive (a zip file), found text starting {sample.decode()!r} "
            "(a log or scan text named .npz?)"
        )
    return "expected an .npz archive (a zip file), found other binary data"


def _read_member(zf: zipfile.ZipFile, key: str, spath: str, max_bytes: int) -> np.ndarray:
    """The array ``key`` of the archive, after checking its header: no object dtype, a
    shape whose size agrees with the directory's uncompressed size and stays within
    ``max_bytes``."""
    info = zf.getinfo(key + ".npy")
    if info.file_size > max_bytes + 4096:
        raise ParseError(
            spath,
            None,
            f"array of {info.file_size} bytes exceeds the limit of {max_bytes} bytes",
            field=key,
        )
    with zf.open(info) as fh:
        try:
            version = np.lib.format.read_magic(fh)
            if version == (1, 0):
                shape, fortran, dtype = np.lib.format.read_array_header_1_0(fh)
            elif version in ((2, 0), (3, 0)):
                shape, fortran, dtype = np.lib.format.read_array_header_2_0(fh)
            else:  # pragma: no cover - numpy refuses other versions in read_magic
                raise ValueError(f"unsupported .npy version {version}")
        except ValueError as exc:
            raise ParseError(
                spath, None, f"not a readable .npy member ({exc})", field=key
            ) from None
        if dtype.hasobject:
            raise ParseError(
                spath,
                None,
                "refused: an object array (reading it would need unpickling)",
                field=key,
            )
        n_items = math.prod(shape)
        n_bytes = n_items * dtype.itemsize
        header = fh.tell()
        if n_bytes != info.file_size - header:
            raise ParseError(
                spath,
                None,
                f"header says shape {shape} of {dtype} ({n_bytes} bytes) but the member holds "
                f"{info.file_size - header} bytes",
                field=key,
            )
        if n_bytes > max_bytes:
            raise ParseError(
                spath,
                None,
                f"array of {n_bytes} bytes exceeds the limit of {max_bytes} bytes",
                field=key,
            )
        if len(shape) > 2:
            why = f"expected at most 2 dimensions, found {shape}"
            raise ParseError(spath, None, why, field=key)
        ragged = key in ("ranges", "angles") and len(shape) == 1
        if shape and not ragged and shape[0] > MAX_NPZ_SCANS + 1:
            raise ParseError(
                spath, None, f"shape {shape}: more than {MAX_NPZ_SCANS} scans", field=key
            )
        data = fh.read(n_bytes)
    if len(data) != n_bytes:  # pragma: no cover - zipfile checks sizes and CRC
        raise ParseError(spath, None, "truncated member", field=key)
    a = np.frombuffer(data, dtype=dtype)
    if fortran:
        a = a.reshape(shape[::-1]).transpose()
    else:
        a = a.reshape(shape)
    return a


def _load(path: str, max_bytes: int = MAX_NPZ_ARRAY_BYTES) -> dict[str, np.ndarray]:
    """The arrays of the archive that the reader uses (others are never decompressed)."""
    from .text import open_regular

    spath = path
    with open_regular(spath) as fh:
        try:
            zf = zipfile.ZipFile(fh)
        except zipfile.BadZipFile as exc:
            head = _head_bytes(spath)
            why = (
                f"not a readable .npz archive (a damaged zip file: {exc})"
                if head.startswith((b"PK\x03\x04", b"PK\x05\x06"))
                else _describe_non_zip(spath)
            )
            raise ParseError(spath, None, why) from None
        except Exception as exc:  # noqa: BLE001 - zipfile's many ways to fail on bad bytes
            why = f"not a readable .npz archive ({type(exc).__name__}: {exc})"
            raise ParseError(spath, None, why) from None
        with zf:
            names = zf.namelist()
            present = {n[:-4] for n in names if n.endswith(".npy")}
            unknown = sorted(present - _KNOWN) + sorted(n for n in names if not n.endswith(".npy"))
            if unknown:
                logger.debug("%s: ignoring unknown members %s", spath, unknown[:20])
            out: dict[str, np.ndarray] = {}
            for key in sorted(present & _KNOWN):
                try:
                    out[key] = _read_member(zf, key, spath, max_bytes)
                except ParseError:
                    raise
                except Exception as exc:  # noqa: BLE001 - damaged members: bad CRC or
                    # deflate stream, unsupported zip features, encrypted members
                    why = f"not a readable .npz archive ({type(exc).__name__}: {exc})"
                    raise ParseError(spath, None, why, field=key) from None
            return out


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


def read_scans_npz(
    path: str | os.PathLike, *, max_beams: int = 100_000, max_bytes: int = MAX_NPZ_ARRAY_BYTES
) -> list[Scan]:
    """Read scans from an ``.npz`` archive (layout in the module docstring).

    Parameters
    ----------
    path : str or path-like
        The archive. Never unpickled: object arrays are refused.
    max_beams : int
        Largest accepted beam count of one scan.
    max_bytes : int
        Largest accepted array (decompressed bytes), checked against the archive's
        directory and each array's header before it is decompressed. Only the arrays of
        the layout are read; others are never decompressed.

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
    from .text import check_path

    spath = check_path(path)
    name = os.path.basename(spath)
    arrays = _load(spath, max_bytes)
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
        S = off.size - 1
        if S > MAX_NPZ_SCANS:
            raise ParseError(spath, None, f"more than {MAX_NPZ_SCANS} scans", field="offsets")
        if S and int(np.max(np.diff(off))) > max_beams:
            raise ParseError(
                spath,
                None,
                f"a scan of {int(np.max(np.diff(off)))} beams exceeds max_beams={max_beams}",
                field="offsets",
            )
        bounds = off.tolist()
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
        if ranges.shape[1] > max_beams:
            raise ParseError(
                spath,
                None,
                f"{ranges.shape[1]} beams per scan exceed max_beams={max_beams}",
                field="ranges",
            )
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

    times = _beam_times(arrays, spath, rows_r, bounds if "offsets" in arrays else None)
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
                    times[i],
                )
            )
        except ScanError as exc:
            raise ParseError(spath, None, str(exc), field=f"scan[{i}]") from None
    return scans
