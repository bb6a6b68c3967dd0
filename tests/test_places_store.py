"""The SQLite store of the place database (scanclique.places.store, .database)."""

from __future__ import annotations

import json
import os
import signal
import sqlite3
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

import scanclique as sc
from scanclique.config import MatchConfig, config_to_dict
from scanclique.errors import PlaceDatabaseError, ScanCliqueError
from scanclique.places import PlaceDB, PlaceStore
from scanclique.places.store import SCHEMA_VERSION, decode_array, encode_array
from scanclique.scan import Scan

SRC = str(Path(__file__).resolve().parents[1] / "src")


def wavy_scan(seed: int, n: int = 181) -> Scan:
    """A cheap scan with structure: ranges of a few random sinusoids and steps."""
    rng = np.random.default_rng(seed)
    t = np.linspace(0, 1, n)
    r = 4 + sum(
        rng.uniform(0.2, 1.0) * np.sin(2 * np.pi * (k + 1) * t + rng.uniform(0, 6))
        for k in range(4)
    )
    r += np.where(rng.random(n) < 0.02, -2.0, 0.0).cumsum() * 0  # keep continuous
    r[rng.integers(0, n, 3)] = np.nan
    return Scan.from_ranges(r, timestamp=float(seed), source=f"wavy:{seed}")


@settings(max_examples=60, deadline=None)
@given(
    hnp.arrays(
        dtype=st.sampled_from([np.float64, np.float32, np.int64, np.int8, np.bool_]),
        shape=hnp.array_shapes(min_dims=0, max_dims=3, min_side=0, max_side=4),
    )
)
def test_typed_blob_round_trip(a):
    b = decode_array(*encode_array(a))
    assert b.dtype == a.dtype and b.shape == a.shape
    assert np.array_equal(a, b, equal_nan=a.dtype.kind == "f")
    assert not b.flags.writeable


@pytest.mark.parametrize(
    "mutate, msg",
    [
        (lambda d, s, c, x: (d, s, c, x[:-1]), "bytes stored"),
        (lambda d, s, c, x: (d, s, c ^ 1, x), "CRC-32"),
        (lambda d, s, c, x: ("|O", s, c, x), "numeric"),
        (lambda d, s, c, x: (d, "[3, x]", c, x), "JSON list"),
        (lambda d, s, c, x: ("<q7", s, c, x), "dtype"),
    ],
)
def test_corrupted_blob_is_refused(mutate, msg):
    enc = encode_array(np.arange(6.0).reshape(2, 3))
    with pytest.raises(PlaceDatabaseError, match=msg):
        decode_array(*mutate(*enc), where="x.db: place 1")


def test_object_arrays_are_not_stored():
    with pytest.raises(PlaceDatabaseError):
        encode_array(np.array([{}, None], dtype=object))


@pytest.fixture
def db_path(tmp_path):
    return tmp_path / "places.db"


def test_create_add_reopen_identical(db_path):
    scans = [wavy_scan(s) for s in range(6)]
    with PlaceDB(db_path) as db:
        ids = [db.add(s, name=f"w{k}") for k, s in enumerate(scans)]
        assert ids == list(range(1, 7)) and len(db) == 6
        before = [(h.place_id, h.verdict, h.score, h.distance) for h in db.query(scans[2], k=3)]
        rec = db.get(3)
    assert rec.name == "w2" and np.array_equal(rec.scan.ranges, scans[2].ranges, equal_nan=True)
    assert rec.scan.timestamp == 2.0 and rec.scan.source == "wavy:2"
    assert "features.points_xy" in rec.arrays and rec.n_features >= 0
    with PlaceDB(db_path) as db:
        after = [(h.place_id, h.verdict, h.score, h.distance) for h in db.query(scans[2], k=3)]
        assert len(db) == 6
    assert before == after
    assert before[0][0] == 3  # a scan finds itself first


def test_reads_of_many_places_go_in_chunks(db_path, monkeypatch):
    """``names`` and ``array_of`` of more places than one ``IN (...)`` list may hold (999
    parameters in SQLite before 3.32) read them in chunks: all of them come back."""
    import scanclique.places.store as store

    with PlaceDB(db_path) as db:
        ids = [db.add(wavy_scan(s), name=f"w{s}", pose=sc.Pose2(s, 0.0, 0.0)) for s in range(5)]
        monkeypatch.setattr(store, "IN_CHUNK", 2)
        assert db.store.names(ids) == {i: f"w{k}" for k, i in enumerate(ids)}
        got = db.store.array_of(ids, "map_pose")
        assert sorted(got) == ids and [float(got[i][0]) for i in ids] == [0, 1, 2, 3, 4]


def test_journal_is_wal_and_config_stored(db_path):
    cfg = sc.paper_config()
    PlaceDB(db_path, cfg).close()
    con = sqlite3.connect(db_path)
    assert con.execute("PRAGMA journal_mode").fetchone()[0] == "wal"
    stored = json.loads(con.execute("SELECT value FROM meta WHERE key='config'").fetchone()[0])
    con.close()
    assert stored == json.loads(json.dumps(config_to_dict(cfg)))
    with PlaceDB(db_path) as db:  # no config given: the stored one
        assert config_to_dict(db.config) == config_to_dict(cfg)


def test_incompatible_config_refused_compatible_allowed(db_path):
    PlaceDB(db_path).close()
    from dataclasses import replace

    base = MatchConfig()
    bad = replace(base, clustering=replace(base.clustering, c1=0.2))
    with pytest.raises(PlaceDatabaseError, match="clustering.c1"):
        PlaceDB(db_path, bad)
    # matching-only settings do not change the stored features: allowed
    ok = replace(base, clique=replace(base.clique, time_limit=1.0))
    PlaceDB(db_path, ok).close()


def test_duplicate_name_refused_and_nothing_half_written(db_path):
    with PlaceDB(db_path) as db:
        db.add(wavy_scan(1), name="a")
        with pytest.raises(PlaceDatabaseError, match="already used by place 1"):
            db.add(wavy_scan(2), name="a")
        assert len(db) == 1 and db.add(wavy_scan(3)) == 2


def test_foreign_sqlite_file_refused(db_path):
    con = sqlite3.connect(db_path)
    con.execute("CREATE TABLE t (x)")
    con.commit()
    con.close()
    with pytest.raises(PlaceDatabaseError, match="not a scanclique place database"):
        PlaceDB(db_path)


def test_non_database_file_refused(db_path):
    db_path.write_bytes(b"FLASER 180 1.0 2.0\n" * 300)
    with pytest.raises(ScanCliqueError, match="not a place database, or corrupted"):
        PlaceDB(db_path)


def test_newer_schema_refused(db_path):
    PlaceDB(db_path).close()
    con = sqlite3.connect(db_path)
    con.execute(f"PRAGMA user_version = {SCHEMA_VERSION + 1}")
    con.commit()
    con.close()
    with pytest.raises(PlaceDatabaseError, match="newer scanclique"):
        PlaceDB(db_path)


def test_corrupted_pages_refused(db_path):
    with PlaceDB(db_path) as db:
        for s in range(40):
            db.add(wavy_scan(s))
    con = sqlite3.connect(db_path)
    con.execute("PRAGMA wal_checkpoint(TRUNCATE)")
    con.close()
    raw = bytearray(db_path.read_bytes())
    page = 4096
    rng = np.random.default_rng(0)
    for p in range(2, len(raw) // page):  # every page but the header page
        raw[p * page + 8 : p * page + 400] = rng.integers(0, 256, 392, dtype=np.uint8).tobytes()
    db_path.write_bytes(bytes(raw))
    with pytest.raises(PlaceDatabaseError):
        with PlaceDB(db_path) as db:
            for pid in db.ids:
                db.get(int(pid))


def test_flipped_blob_byte_caught_by_crc(db_path):
    with PlaceDB(db_path) as db:
        db.add(wavy_scan(0), name="x")
    con = sqlite3.connect(db_path)
    data = bytearray(con.execute("SELECT data FROM arrays WHERE name='ranges'").fetchone()[0])
    data[17] ^= 0xFF
    con.execute("UPDATE arrays SET data=? WHERE name='ranges'", (bytes(data),))
    con.commit()
    con.close()
    with PlaceDB(db_path) as db, pytest.raises(PlaceDatabaseError, match="CRC-32"):
        db.get(1)


def test_readonly_missing_file(tmp_path):
    with pytest.raises(PlaceDatabaseError, match="no such place database"):
        PlaceStore(tmp_path / "nope.db", readonly=True)


_ADDER = textwrap.dedent(
    """
    import sys, numpy as np
    sys.path.insert(0, {src!r})
    sys.path.insert(0, {tests!r})
    from test_places_store import wavy_scan
    from scanclique.places import PlaceDB
    db = PlaceDB(sys.argv[1])
    start, n = int(sys.argv[2]), int(sys.argv[3])
    print("ready", flush=True)
    for k in range(start, start + n):
        pid = db.add(wavy_scan(k), name=f"s{{k}}")
        print(pid, k, flush=True)
    print("done", flush=True)
    """
)


def _adder(tmp_path: Path, db_path: Path, start: int, n: int) -> subprocess.Popen:
    script = tmp_path / "adder.py"
    script.write_text(_ADDER.format(src=SRC, tests=str(Path(__file__).parent)))
    return subprocess.Popen(
        [sys.executable, str(script), str(db_path), str(start), str(n)],
        stdout=subprocess.PIPE,
        text=True,
        env={**os.environ, "PYTHONPATH": SRC},
    )


def test_sigkill_mid_add_loses_nothing_committed(tmp_path, db_path):
    PlaceDB(db_path).close()
    committed: dict[int, int] = {}
    rng = np.random.default_rng(1)
    start = 0
    for _round in range(3):
        proc = _adder(tmp_path, db_path, start, 10_000)
        assert proc.stdout.readline().strip() == "ready"
        want = int(rng.integers(5, 25))
        for _ in range(want):
            pid, k = map(int, proc.stdout.readline().split())
            committed[pid] = k
        os.kill(proc.pid, signal.SIGKILL)  # while it is adding the next ones
        proc.wait(timeout=10)
        start += 10_000
        with PlaceDB(db_path) as db:
            assert db.store.integrity_check() == []
            have = set(int(i) for i in db.ids)
            assert set(committed) <= have
            for pid, k in committed.items():
                rec = db.get(pid)
                assert rec.name == f"s{k}"
                assert np.array_equal(rec.scan.ranges, wavy_scan(k).ranges, equal_nan=True)
            # whatever else is there was committed whole
            for pid in have - set(committed):
                db.get(pid)


def test_second_process_reads_while_first_adds(tmp_path, db_path):
    with PlaceDB(db_path) as db:
        db.add(wavy_scan(999), name="first")
    proc = _adder(tmp_path, db_path, 0, 15)
    seen = []
    q = wavy_scan(3)
    with PlaceDB(db_path, readonly=True) as reader:
        deadline = time.monotonic() + 60
        while proc.poll() is None and time.monotonic() < deadline:
            ids, _ = reader.candidates(q, n=3)
            seen.append(len(reader))
            assert len(ids) == min(3, len(reader))
        proc.wait(timeout=30)
        reader.refresh()
        assert len(reader) == 16
        ids, _ = reader.candidates(q, n=1)
        assert reader.store.names(ids)[int(ids[0])] == "s3"
    assert seen[-1] >= seen[0] and len(set(seen)) > 1  # it saw places arrive


def _set_signature_version(db_path, version: str, size: int | None = None) -> None:
    """Mark the file's signatures as of ``version`` (and, with ``size``, store zero
    signatures of that length, as an older scanclique would have left them)."""
    con = sqlite3.connect(db_path)
    con.execute("UPDATE meta SET value=? WHERE key='signature_version'", (version,))
    if size is not None:
        con.execute("UPDATE meta SET value=? WHERE key='signature_size'", (str(size),))
        dt, shape, crc, data = encode_array(np.zeros(size))
        con.execute(
            "UPDATE signatures SET dtype=?, shape=?, crc32=?, data=?", (dt, shape, crc, data)
        )
    con.commit()
    con.close()


def test_older_signatures_recomputed_on_open(db_path):
    from scanclique.places import SIGNATURE_SIZE, scan_signature
    from scanclique.places.signature import SIGNATURE_VERSION

    scans = [wavy_scan(s) for s in range(4)]
    with PlaceDB(db_path) as db:
        ids = [db.add(s, name=f"w{k}") for k, s in enumerate(scans)]
        want = np.stack([scan_signature(db.prepare(s)) for s in scans])
        before = [h.place_id for h in db.query(scans[2], k=2)]
    _set_signature_version(db_path, str(SIGNATURE_VERSION - 1), size=12)
    # read-only cannot rewrite them: a clear refusal
    with pytest.raises(PlaceDatabaseError, match="open it once for writing"):
        PlaceDB(db_path, readonly=True)
    with PlaceDB(db_path) as db:  # recomputed from the stored scans, in the file
        assert db.index.signatures.shape == (4, SIGNATURE_SIZE)
        np.testing.assert_allclose(db.index.signatures, want, rtol=0, atol=1e-6)
        assert db.info()["signature_version"] == SIGNATURE_VERSION
        assert [h.place_id for h in db.query(scans[2], k=2)] == before
    with PlaceDB(db_path, readonly=True) as db:  # and stay so: a reader opens it now
        np.testing.assert_allclose(db.store.signatures_after(0)[1], want, rtol=0, atol=1e-6)
        assert db.ids.tolist() == ids


@pytest.mark.parametrize("version", ["99", "x"])
def test_newer_or_unknown_signature_version_refused(db_path, version):
    PlaceDB(db_path).close()
    _set_signature_version(db_path, version)
    with pytest.raises(PlaceDatabaseError, match=f"signatures of version {version}"):
        PlaceDB(db_path)


def test_readonly_refuses_add(db_path):
    with PlaceDB(db_path) as db:
        db.add(wavy_scan(0))
    with PlaceDB(db_path, readonly=True) as db, pytest.raises(PlaceDatabaseError):
        db.add(wavy_scan(1))
