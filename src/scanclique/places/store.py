"""The persistent store of a place database: one SQLite file (standard library ``sqlite3``).

Layout (schema version :data:`SCHEMA_VERSION`)::

    PRAGMA application_id = 0x53435043 ("SCPC")   -- refuses any other SQLite file
    PRAGMA user_version   = SCHEMA_VERSION        -- refuses a newer (or older) schema
    meta(key TEXT PRIMARY KEY, value TEXT)        -- format, versions, the config (JSON)
    places(id INTEGER PRIMARY KEY, name TEXT UNIQUE, source, timestamp, range_min,
           range_max, ref_x, ref_y, ref_theta, odo_x, odo_y, odo_theta, n_features, added)
    arrays(place_id, name, dtype, shape, crc32, data)      -- the scan's and features' arrays
    signatures(place_id PRIMARY KEY, dtype, shape, crc32, data)  -- the prefilter's vectors

Arrays are *typed blobs*: the raw C-order bytes, their NumPy dtype string (``"<f8"``),
their shape (JSON) and a CRC-32 of the bytes; reading checks all four (never pickle).
The journal is in WAL mode: several processes may read while one adds, and a reader
never blocks the writer. Each :meth:`PlaceStore.add` is one transaction, committed
before it returns, with ``synchronous=NORMAL``: a place whose add returned survives the
adding process being killed (SIGKILL) at any moment; a half-done add leaves nothing
behind. (``synchronous=NORMAL`` may lose the last commits on a *power* loss, never
corrupting the file; pass ``durable=True`` for ``FULL``.)

Every failure a user can cause (not a database, another application's database, a
newer schema, a corrupted page or blob, a name used twice) is a
:class:`~scanclique.errors.PlaceDatabaseError` naming the file.
"""

from __future__ import annotations

import contextlib
import json
import logging
import math
import os
import sqlite3
import time
import urllib.parse
import zlib
from collections.abc import Callable, Iterator, Mapping
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import PlaceDatabaseError
from ..geometry import Pose2
from ..scan import Scan

__all__ = [
    "APPLICATION_ID",
    "SCHEMA_VERSION",
    "FORMAT",
    "PlaceRecord",
    "PlaceStore",
    "encode_array",
    "decode_array",
]

log = logging.getLogger(__name__)

APPLICATION_ID = 0x53435043  #: "SCPC" in the SQLite header: a scanclique place database
SCHEMA_VERSION = 1
FORMAT = "scanclique-places"
#: dtypes a typed blob may have (kinds: bool, signed/unsigned int, float)
_BLOB_KINDS = "biuf"

_SCHEMA = """
CREATE TABLE meta (key TEXT PRIMARY KEY, value TEXT NOT NULL);
CREATE TABLE places (
    id INTEGER PRIMARY KEY,
    name TEXT UNIQUE,
    source TEXT NOT NULL,
    timestamp REAL,
    range_min REAL NOT NULL,
    range_max REAL NOT NULL,
    ref_x REAL, ref_y REAL, ref_theta REAL,
    odo_x REAL, odo_y REAL, odo_theta REAL,
    n_features INTEGER NOT NULL,
    added REAL NOT NULL
);
CREATE TABLE arrays (
    place_id INTEGER NOT NULL REFERENCES places(id),
    name TEXT NOT NULL,
    dtype TEXT NOT NULL,
    shape TEXT NOT NULL,
    crc32 INTEGER NOT NULL,
    data BLOB NOT NULL,
    PRIMARY KEY (place_id, name)
) WITHOUT ROWID;
CREATE TABLE signatures (
    place_id INTEGER PRIMARY KEY REFERENCES places(id),
    dtype TEXT NOT NULL,
    shape TEXT NOT NULL,
    crc32 INTEGER NOT NULL,
    data BLOB NOT NULL
);
"""
_TABLES = {"meta", "places", "arrays", "signatures"}
#: ids in one ``IN (...)`` list: SQLite builds before 3.32 allow 999 parameters a
#: statement (later ones 32766 by default), and a database may hold more places
IN_CHUNK = 900
#: the stored array of a place's pose in a map (x, y, theta), when
#: :meth:`~scanclique.places.PlaceDB.add` was given one
MAP_POSE = "map_pose"


def _chunks(ids) -> Iterator[list[int]]:
    """``ids`` as lists of at most :data:`IN_CHUNK` ints."""
    ids = [int(i) for i in ids]
    for k in range(0, len(ids), IN_CHUNK):
        yield ids[k : k + IN_CHUNK]


# ---------------------------------------------------------------------------------------
# Typed blobs
# ---------------------------------------------------------------------------------------
def encode_array(a: np.ndarray) -> tuple[str, str, int, bytes]:
    """``(dtype, shape, crc32, data)`` of an array: its dtype string (explicit byte
    order), its shape as JSON, the CRC-32 of its C-order bytes and the bytes.

    >>> encode_array(np.arange(3, dtype=np.int64))[:2]
    ('<i8', '[3]')
    """
    a = np.asarray(a)
    if a.dtype.kind not in _BLOB_KINDS:
        raise PlaceDatabaseError(f"cannot store an array of dtype {a.dtype} (only bool/int/float)")
    dt = a.dtype.newbyteorder("<") if a.dtype.byteorder == ">" else a.dtype
    data = a.astype(dt, copy=False).tobytes(order="C")
    return dt.str, json.dumps(list(a.shape)), zlib.crc32(data), data


def decode_array(dtype: str, shape: str, crc: int, data: bytes, where: str = "") -> np.ndarray:
    """The array of a typed blob (read-only), after checking its dtype, shape, length and
    CRC-32; a :class:`PlaceDatabaseError` naming ``where`` otherwise.

    >>> decode_array(*encode_array(np.eye(2))).tolist()
    [[1.0, 0.0], [0.0, 1.0]]
    """
    try:
        dt = np.dtype(dtype)
    except TypeError:
        raise PlaceDatabaseError(f"{where}: unknown dtype {dtype!r}") from None
    if dt.kind not in _BLOB_KINDS:
        raise PlaceDatabaseError(f"{where}: dtype {dtype!r} is not a plain numeric type")
    try:
        shp = tuple(int(s) for s in json.loads(shape))
    except (ValueError, TypeError):
        raise PlaceDatabaseError(f"{where}: shape {shape!r} is not a JSON list of ints") from None
    if any(s < 0 for s in shp):
        raise PlaceDatabaseError(f"{where}: negative extent in shape {list(shp)}")
    data = bytes(data)
    need = math.prod(shp) * dt.itemsize
    if len(data) != need:
        raise PlaceDatabaseError(
            f"{where}: corrupted blob: {len(data)} bytes stored, shape {list(shp)} of "
            f"{dtype} needs {need}"
        )
    if zlib.crc32(data) != int(crc):
        raise PlaceDatabaseError(f"{where}: corrupted blob: CRC-32 mismatch")
    a = np.frombuffer(data, dtype=dt).reshape(shp)
    return a  # frombuffer on bytes is read-only


# ---------------------------------------------------------------------------------------
# Records
# ---------------------------------------------------------------------------------------
@dataclass(frozen=True, slots=True, eq=False)
class PlaceRecord:
    """One stored place: its id and name, the scan it was made from, and its arrays.

    ``arrays`` maps names to read-only arrays: ``"ranges"`` and ``"angles"`` of the scan
    (and its ``"beam_times"`` when it has them), and ``"features.<field>"`` for each array field of
    :class:`scanclique.features.Features`.
    """

    place_id: int
    name: str | None
    scan: Scan
    n_features: int
    added: float
    arrays: Mapping[str, np.ndarray]


def _pose(x, y, th) -> Pose2 | None:
    return None if x is None else Pose2(float(x), float(y), float(th))


def _xyt(p: Pose2 | None) -> tuple:
    return (None, None, None) if p is None else (float(p.x), float(p.y), float(p.theta))


# ---------------------------------------------------------------------------------------
# The store
# ---------------------------------------------------------------------------------------
class PlaceStore:
    """A place database file: create when absent, check when present.

    Parameters
    ----------
    path : str or PathLike
        The SQLite file. Created (with ``meta``) when it does not exist or is empty.
    meta : dict, optional
        Values for the ``meta`` table of a new file (``config`` JSON, versions); ignored
        when the file exists.
    readonly : bool
        Open an existing file for reading only (no file is created).
    durable : bool
        ``synchronous=FULL`` (survives power loss) instead of ``NORMAL``.
    timeout : float
        Seconds to wait for another process's write lock.

    Raises
    ------
    PlaceDatabaseError
        Not a SQLite file, a SQLite file of another application, a newer or older schema,
        a corrupted file; ``readonly`` and no such file.
    """

    def __init__(
        self,
        path: str | os.PathLike,
        meta: Mapping[str, str] | None = None,
        *,
        readonly: bool = False,
        durable: bool = False,
        timeout: float = 10.0,
    ) -> None:
        if not isinstance(path, (str, os.PathLike)):
            raise PlaceDatabaseError(f"expected a file path, got {type(path).__name__}")
        self.path = Path(path)
        self._where = os.fspath(path)
        self.readonly = bool(readonly)
        exists = self.path.exists() and self.path.stat().st_size > 0
        if readonly and not exists:
            raise PlaceDatabaseError(f"{self._where}: no such place database")
        if self.path.is_dir():
            raise PlaceDatabaseError(f"{self._where}: is a directory, not a place database")
        try:
            # the path is quoted: in a URI ``?`` and ``#`` would end it and ``%`` escape,
            # so ``a?b.db`` would open a file named ``a``
            where = urllib.parse.quote(self.path.resolve().as_posix(), safe="/")
            uri = f"file:{where}?mode={'ro' if readonly else 'rwc'}"
            self._conn = sqlite3.connect(
                uri, uri=True, timeout=timeout, isolation_level=None, check_same_thread=False
            )
        except sqlite3.Error as exc:
            raise PlaceDatabaseError(f"{self._where}: cannot open ({exc})") from None
        try:
            with self._errors("open"):
                self._conn.execute(f"PRAGMA busy_timeout = {int(timeout * 1000)}")
                if exists:
                    self._check()
                else:
                    self._create(dict(meta or {}))
                if not readonly:
                    self._conn.execute("PRAGMA journal_mode = WAL")
                self._conn.execute(f"PRAGMA synchronous = {'FULL' if durable else 'NORMAL'}")
                self.meta = dict(self._conn.execute("SELECT key, value FROM meta").fetchall())
        except BaseException:
            self._conn.close()
            raise

    # -- errors --------------------------------------------------------------------------
    @contextlib.contextmanager
    def _errors(self, what: str) -> Iterator[None]:
        """SQLite errors as :class:`PlaceDatabaseError` naming the file."""
        try:
            yield
        except PlaceDatabaseError:
            raise
        except sqlite3.DatabaseError as exc:
            msg = str(exc)
            if "not a database" in msg or "malformed" in msg or "corrupt" in msg:
                msg = f"not a place database, or corrupted ({exc})"
            raise PlaceDatabaseError(f"{self._where}: {what}: {msg}") from None

    @contextlib.contextmanager
    def _write(self) -> Iterator[sqlite3.Connection]:
        """One write transaction (``BEGIN IMMEDIATE``: the write lock from the start),
        committed when the block ends unless it rolled back itself; rolled back on any
        exception."""
        c = self._conn
        c.execute("BEGIN IMMEDIATE")
        try:
            yield c
            if c.in_transaction:
                c.execute("COMMIT")
        except BaseException:
            if c.in_transaction:
                c.execute("ROLLBACK")
            raise

    # -- opening ---------------------------------------------------------------------------
    def _create(self, meta: dict) -> None:
        with self._write() as c:
            tables = {r[0] for r in c.execute("SELECT name FROM sqlite_master WHERE type='table'")}
            if tables:  # raced with another creator, or a foreign empty-ish file
                c.execute("ROLLBACK")
            else:
                c.execute(f"PRAGMA application_id = {APPLICATION_ID}")
                c.execute(f"PRAGMA user_version = {SCHEMA_VERSION}")
                for statement in _SCHEMA.split(";"):
                    if statement.strip():
                        c.execute(statement)
                rows = {"format": FORMAT, "schema_version": str(SCHEMA_VERSION)}
                rows.update({str(k): str(v) for k, v in meta.items()})
                rows.setdefault("created", repr(time.time()))
                c.executemany("INSERT INTO meta VALUES (?, ?)", sorted(rows.items()))
        if tables:
            self._check()

    def _check(self) -> None:
        c = self._conn
        app_id = c.execute("PRAGMA application_id").fetchone()[0]
        version = c.execute("PRAGMA user_version").fetchone()[0]
        tables = {r[0] for r in c.execute("SELECT name FROM sqlite_master WHERE type='table'")}
        if app_id != APPLICATION_ID:
            shown = ", ".join(sorted(tables)) or "none"
            raise PlaceDatabaseError(
                f"{self._where}: not a scanclique place database (SQLite application_id "
                f"{app_id:#x}, expected {APPLICATION_ID:#x}; tables: {shown})"
            )
        if version > SCHEMA_VERSION:
            raise PlaceDatabaseError(
                f"{self._where}: written by a newer scanclique (schema version {version}, "
                f"this one reads {SCHEMA_VERSION}); upgrade scanclique"
            )
        if version < SCHEMA_VERSION:
            raise PlaceDatabaseError(
                f"{self._where}: schema version {version} is older than {SCHEMA_VERSION} "
                "and cannot be upgraded; rebuild the database"
            )
        missing = _TABLES - tables
        if missing:
            raise PlaceDatabaseError(
                f"{self._where}: corrupted place database: missing tables "
                f"{', '.join(sorted(missing))}"
            )
        fmt = c.execute("SELECT value FROM meta WHERE key = 'format'").fetchone()
        if fmt is None or fmt[0] != FORMAT:
            raise PlaceDatabaseError(
                f"{self._where}: meta.format is {None if fmt is None else fmt[0]!r}, "
                f"expected {FORMAT!r}"
            )

    def integrity_check(self) -> list[str]:
        """SQLite's ``PRAGMA quick_check`` (O(file size)): empty when the file is sound,
        else the problems it lists."""
        with self._errors("integrity check"):
            rows = [r[0] for r in self._conn.execute("PRAGMA quick_check").fetchall()]
        return [] if rows == ["ok"] else rows

    # -- writing -----------------------------------------------------------------------
    def add(
        self,
        scan: Scan,
        arrays: Mapping[str, np.ndarray],
        signature: np.ndarray,
        *,
        name: str | None = None,
        n_features: int = 0,
    ) -> int:
        """Store one place in one transaction; returns its id (1, 2, ...).

        ``arrays`` are stored as typed blobs besides the scan's ``ranges`` and
        ``angles``; ``signature`` in the signature table.

        Raises
        ------
        PlaceDatabaseError
            ``name`` is already used by another place.
        """
        blobs = [("ranges", *encode_array(scan.ranges)), ("angles", *encode_array(scan.angles))]
        if scan.beam_times is not None:
            blobs.append(("beam_times", *encode_array(scan.beam_times)))
        blobs += [(k, *encode_array(v)) for k, v in arrays.items()]
        sig = encode_array(np.asarray(signature))
        with self._errors("add"), self._write() as c:
            if name is not None:
                row = c.execute("SELECT id FROM places WHERE name = ?", (name,)).fetchone()
                if row is not None:
                    raise PlaceDatabaseError(
                        f"{self._where}: the name {name!r} is already used by place {row[0]}"
                    )
            cur = c.execute(
                "INSERT INTO places (name, source, timestamp, range_min, range_max, ref_x, "
                "ref_y, ref_theta, odo_x, odo_y, odo_theta, n_features, added) "
                "VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?)",
                (
                    name,
                    scan.source,
                    scan.timestamp,
                    scan.range_min,
                    scan.range_max,
                    *_xyt(scan.reference),
                    *_xyt(scan.odometry),
                    int(n_features),
                    time.time(),
                ),
            )
            pid = int(cur.lastrowid)
            c.executemany(
                "INSERT INTO arrays VALUES (?, ?, ?, ?, ?, ?)", [(pid, *b) for b in blobs]
            )
            c.execute("INSERT INTO signatures VALUES (?, ?, ?, ?, ?)", (pid, *sig))
        return pid

    def set_array(self, place_id: int, name: str, array: np.ndarray) -> None:
        """Store (or replace) the array ``name`` of the existing place ``place_id``, in one
        transaction.

        Raises
        ------
        PlaceDatabaseError
            No such place.
        """
        blob = encode_array(np.asarray(array))
        with self._errors("set an array"), self._write() as c:
            if c.execute("SELECT 1 FROM places WHERE id = ?", (int(place_id),)).fetchone() is None:
                raise PlaceDatabaseError(f"{self._where}: no place with id {int(place_id)}")
            c.execute(
                "INSERT OR REPLACE INTO arrays VALUES (?, ?, ?, ?, ?, ?)",
                (int(place_id), name, *blob),
            )

    def rewrite_signatures(
        self, signature_of: Callable[[Scan], np.ndarray], meta: Mapping[str, str]
    ) -> int:
        """Replace every place's signature by ``signature_of(scan)`` of its stored scan and
        set the ``meta`` values, in one transaction; returns how many were rewritten.

        The write lock is held throughout, so no place is added meanwhile; when the
        ``meta`` values are already stored (another process rewrote them first) nothing
        is done and 0 returned. For a database whose signatures are of an older version
        (:data:`~scanclique.places.signature.SIGNATURE_VERSION`).
        """
        meta = {str(k): str(v) for k, v in meta.items()}
        with self._errors("rewrite signatures"):
            with self._write() as c:
                now = dict(c.execute("SELECT key, value FROM meta").fetchall())
                ids = []
                if any(now.get(k) != v for k, v in meta.items()):
                    ids = [int(r[0]) for r in c.execute("SELECT id FROM places ORDER BY id")]
                    rows = []
                    for pid in ids:
                        scan = self.get(pid, arrays=False).scan
                        rows.append((*encode_array(np.asarray(signature_of(scan))), pid))
                    c.executemany(
                        "UPDATE signatures SET dtype = ?, shape = ?, crc32 = ?, data = ? "
                        "WHERE place_id = ?",
                        rows,
                    )
                    c.executemany("INSERT OR REPLACE INTO meta VALUES (?, ?)", sorted(meta.items()))
            self.meta = dict(self._conn.execute("SELECT key, value FROM meta").fetchall())
        if not ids:  # another process rewrote them first
            return 0
        log.info("%s: recomputed the signatures of %d places", self._where, len(ids))
        return len(ids)

    # -- reading -----------------------------------------------------------------------
    def __len__(self) -> int:
        with self._errors("count"):
            return int(self._conn.execute("SELECT COUNT(*) FROM places").fetchone()[0])

    def max_id(self) -> int:
        """The largest place id (0 when empty)."""
        with self._errors("read"):
            return int(self._conn.execute("SELECT COALESCE(MAX(id), 0) FROM places").fetchone()[0])

    def signatures_after(self, after: int) -> tuple[np.ndarray, np.ndarray]:
        """``(ids, signatures)`` of the places with id greater than ``after``, by id."""
        with self._errors("read signatures"):
            rows = self._conn.execute(
                "SELECT place_id, dtype, shape, crc32, data FROM signatures "
                "WHERE place_id > ? ORDER BY place_id",
                (int(after),),
            ).fetchall()
        if not rows:
            return np.zeros(0, dtype=np.int64), np.zeros((0, 0))
        ids = np.array([r[0] for r in rows], dtype=np.int64)
        sigs = [decode_array(*r[1:], where=f"{self._where}: place {r[0]} signature") for r in rows]
        if len({s.shape for s in sigs}) != 1:
            raise PlaceDatabaseError(f"{self._where}: signatures of different lengths")
        return ids, np.stack(sigs)

    def arrays_after(
        self, after: int, names: tuple[str, ...], upto: int | None = None
    ) -> tuple[np.ndarray, list[dict]]:
        """``(ids, arrays)`` of the places with id greater than ``after`` (and at most
        ``upto``), by id: for each, a dict of its stored arrays among ``names`` (e.g.
        ``"features.points_xy"``)."""
        names = tuple(names)
        q = ",".join("?" * len(names))
        with self._errors("read arrays"):
            rows = self._conn.execute(
                f"SELECT place_id, name, dtype, shape, crc32, data FROM arrays "
                f"WHERE place_id > ? AND place_id <= ? AND name IN ({q}) ORDER BY place_id",
                (int(after), int(upto) if upto is not None else 2**62, *names),
            ).fetchall()
        out: dict[int, dict] = {}
        for r in rows:
            out.setdefault(int(r[0]), {})[r[1]] = decode_array(
                *r[2:], where=f"{self._where}: place {r[0]} array {r[1]!r}"
            )
        ids = np.array(sorted(out), dtype=np.int64)
        return ids, [out[int(i)] for i in ids]

    def array_of(self, ids, name: str) -> dict[int, np.ndarray]:
        """The stored array ``name`` of each of the places ``ids`` that has one (by primary
        key; :data:`IN_CHUNK` places a statement)."""
        rows = []
        with self._errors("read arrays"):
            for chunk in _chunks(ids):
                q = ",".join("?" * len(chunk))
                rows += self._conn.execute(
                    f"SELECT place_id, dtype, shape, crc32, data FROM arrays "
                    f"WHERE name = ? AND place_id IN ({q})",
                    (name, *chunk),
                ).fetchall()
        return {
            int(r[0]): decode_array(*r[1:], where=f"{self._where}: place {r[0]} array {name!r}")
            for r in rows
        }

    def names(self, ids) -> dict[int, str | None]:
        """Names of the places ``ids``."""
        out = {}
        with self._errors("read"):
            for chunk in _chunks(ids):
                q = ",".join("?" * len(chunk))
                rows = self._conn.execute(f"SELECT id, name FROM places WHERE id IN ({q})", chunk)
                out.update((int(i), n) for i, n in rows.fetchall())
        return out

    def get(self, place_id: int, arrays: bool = True) -> PlaceRecord:
        """The stored place ``place_id`` (with all its arrays, or only the scan's).

        Raises
        ------
        PlaceDatabaseError
            No such place, or a corrupted record.
        """
        pid = int(place_id)
        with self._errors(f"read place {pid}"):
            row = self._conn.execute(
                "SELECT name, source, timestamp, range_min, range_max, ref_x, ref_y, "
                "ref_theta, odo_x, odo_y, odo_theta, n_features, added FROM places WHERE id = ?",
                (pid,),
            ).fetchone()
            if row is None:
                raise PlaceDatabaseError(f"{self._where}: no place with id {pid}")
            sel = "" if arrays else " AND name IN ('ranges', 'angles', 'beam_times')"
            blobs = self._conn.execute(
                f"SELECT name, dtype, shape, crc32, data FROM arrays WHERE place_id = ?{sel}",
                (pid,),
            ).fetchall()
        arr = {
            b[0]: decode_array(*b[1:], where=f"{self._where}: place {pid} array {b[0]!r}")
            for b in blobs
        }
        if "ranges" not in arr or "angles" not in arr:
            raise PlaceDatabaseError(f"{self._where}: place {pid}: corrupted record (no scan)")
        name, source, ts, rmin, rmax, rx, ry, rt, ox, oy, ot, nf, added = row
        try:
            scan = Scan(
                arr["ranges"],
                arr["angles"],
                range_min=rmin,
                range_max=rmax,
                timestamp=ts,
                odometry=_pose(ox, oy, ot),
                reference=_pose(rx, ry, rt),
                source=source,
                beam_times=arr.get("beam_times"),
            )
        except Exception as exc:  # a ScanError from a record that is not a scan
            raise PlaceDatabaseError(
                f"{self._where}: place {pid}: corrupted scan ({exc})"
            ) from None
        return PlaceRecord(pid, name, scan, int(nf), float(added), arr)

    def stats(self) -> dict:
        """Counts and sizes: places (and those with a map pose), array bytes, file bytes
        (with the WAL)."""
        with self._errors("stats"):
            n = len(self)
            blob = self._conn.execute(
                "SELECT COALESCE(SUM(LENGTH(data)), 0) FROM arrays"
            ).fetchone()[0]
            sig = self._conn.execute(
                "SELECT COALESCE(SUM(LENGTH(data)), 0) FROM signatures"
            ).fetchone()[0]
            posed = self._conn.execute(
                "SELECT COUNT(*) FROM arrays WHERE name = ?", (MAP_POSE,)
            ).fetchone()[0]
        size = self.path.stat().st_size if self.path.exists() else 0
        wal = Path(f"{self.path}-wal")
        return {
            "places": n,
            "places_with_map_pose": int(posed),
            "array_bytes": int(blob),
            "signature_bytes": int(sig),
            "file_bytes": int(size),
            "wal_bytes": int(wal.stat().st_size) if wal.exists() else 0,
        }

    def close(self) -> None:
        with contextlib.suppress(sqlite3.Error):
            self._conn.close()

    def __enter__(self) -> PlaceStore:
        return self

    def __exit__(self, *exc) -> None:
        self.close()
