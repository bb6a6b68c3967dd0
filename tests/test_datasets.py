"""The data registry: where data are looked for, what happens when they are missing, caching."""

from __future__ import annotations

import gzip
import os

import numpy as np
import pytest
from conftest import require_log

from scanclique import datasets
from scanclique.datasets import (
    DATASETS,
    ENV_VAR,
    data_dir,
    data_dir_candidates,
    dataset_path,
    dimacs_dir,
    load_log,
    relations_path,
    resolve_log,
)
from scanclique.errors import DataNotFoundError


def _flaser(value: float, t: float) -> str:
    return f"FLASER 3 {value} {value} {value} 1 2 0.5 1 2 0.5 {t} host {t}\n"


@pytest.fixture
def fake_data(tmp_path, monkeypatch):
    """A data directory with a tiny stand-in for the Intel log, pointed at by SCANCLIQUE_DATA."""
    root = tmp_path / "data"
    (root / "carmen").mkdir(parents=True)
    (root / "relations").mkdir()
    (root / "dimacs").mkdir()
    (root / "relations" / "intel.relations").write_text("1 2 0 0 0 0 0 0\n")
    log = root / DATASETS["intel"].relpath
    log.write_bytes(gzip.compress((_flaser(1.0, 1.0) + _flaser(2.0, 2.0)).encode()))
    monkeypatch.setenv(ENV_VAR, str(root))
    datasets.clear_cache()
    yield root
    datasets.clear_cache()


@pytest.fixture
def no_data(tmp_path, monkeypatch):
    empty = tmp_path / "empty"
    empty.mkdir()
    monkeypatch.setenv(ENV_VAR, str(empty))
    return empty


def test_registry():
    assert set(DATASETS) == {"intel", "csail", "freiburg", "intel-raw", "fr079-raw"}
    assert {
        k: (d.scans, d.beams, d.has_odometry, d.has_reference) for k, d in DATASETS.items()
    } == {
        "intel": (910, 180, True, True),
        "csail": (406, 361, True, True),
        "freiburg": (4791, 360, False, True),
        "intel-raw": (13631, 180, True, False),
        "fr079-raw": (4934, 360, True, False),
    }
    for key, d in DATASETS.items():
        suffix = ".log.gz" if d.has_reference else ".clf.bz2"
        assert d.name == key and d.relpath.startswith("carmen/") and d.relpath.endswith(suffix)
        assert d.description and ("Radish" in d.source or "Freiburg" in d.source)
    with pytest.raises(TypeError):
        DATASETS["x"] = DATASETS["intel"]


def test_env_var_wins(fake_data):
    assert data_dir_candidates() == [fake_data]
    assert data_dir() == fake_data
    assert dataset_path("intel") == fake_data / "carmen" / "intel-odometry.log.gz"
    assert dataset_path("INTEL") == dataset_path("intel-lab") == dataset_path("intel")
    assert relations_path() == fake_data / "relations" / "intel.relations"
    assert dimacs_dir() == fake_data / "dimacs"


def test_default_location_beside_checkout(monkeypatch, tmp_path):
    monkeypatch.delenv(ENV_VAR, raising=False)
    repo_root = datasets._repo_root()
    assert (repo_root / "pyproject.toml").is_file()
    (tmp_path / "work").mkdir()
    monkeypatch.chdir(tmp_path / "work")
    candidates = data_dir_candidates()
    assert candidates == [repo_root.parent / "shared" / "data", tmp_path / "shared" / "data"]
    # run from the checkout, the two are one directory: listed once (messages said it twice)
    monkeypatch.chdir(repo_root)
    assert data_dir_candidates() == [repo_root.parent / "shared" / "data"]


def test_missing_data_message(no_data):
    with pytest.raises(DataNotFoundError) as info:
        dataset_path("csail")
    msg = str(info.value)
    for part in ("csail", "carmen/csail-odometry.log.gz", str(no_data), ENV_VAR, "Radish"):
        assert part in msg
    assert isinstance(info.value, FileNotFoundError)
    with pytest.raises(DataNotFoundError, match="relations/intel.relations"):
        relations_path()
    with pytest.raises(DataNotFoundError, match="dimacs"):
        dimacs_dir()
    assert data_dir() == no_data


def test_unknown_name():
    with pytest.raises(
        DataNotFoundError, match="registered are csail, fr079-raw, freiburg, intel, intel-raw"
    ):
        dataset_path("victoria")


def test_resolve_log(fake_data, tmp_path):
    assert resolve_log("intel") == dataset_path("intel")
    other = tmp_path / "other.log"
    other.write_text(_flaser(3.0, 1.0))
    assert resolve_log(other) == other
    assert resolve_log(str(other)) == other
    with pytest.raises(DataNotFoundError, match="neither an existing file nor a registered"):
        resolve_log(tmp_path / "missing.log")
    with pytest.raises(DataNotFoundError, match="freiburg"):
        resolve_log("freiburg-079")  # registered alias, file absent from the fake directory


def test_load_log_caches_and_notices_changes(fake_data):
    a = load_log("intel")
    b = load_log("intel")
    assert [s.ranges[0] for s in a] == [1.0, 2.0]
    assert a is not b and all(x is y for x, y in zip(a, b, strict=True))  # new list, shared scans
    assert load_log("intel", max_range=1.5)[1].n_valid == 0  # options are part of the key
    log = fake_data / DATASETS["intel"].relpath
    log.write_bytes(gzip.compress(_flaser(5.0, 1.0).encode()))
    os.utime(log, ns=(1, 1))  # a different modification time
    assert [s.ranges[0] for s in load_log("intel")] == [5.0]


def test_require_log_skips_with_reason(no_data):
    with pytest.raises(pytest.skip.Exception) as info:
        require_log("intel")
    msg = str(info.value)
    assert msg.startswith(f"real data not found: set {ENV_VAR} (looked in {no_data}")


@pytest.mark.realdata
@pytest.mark.parametrize("name", sorted(DATASETS))
def test_real_registry_matches_files(name):
    require_log(name)
    scans = load_log(name)
    d = DATASETS[name]
    assert len(scans) == d.scans
    assert {s.n_beams for s in scans} == {d.beams}
    if d.has_reference:
        same = np.array([s.odometry == s.reference for s in scans])
        assert bool(same.all()) == (not d.has_odometry)
    else:  # raw logs: every pose is odometry, and it moves
        assert all(s.odometry is not None for s in scans)
        assert scans[0].odometry != scans[-1].odometry


@pytest.mark.realdata
def test_real_shared_files(data_dir):
    assert relations_path().is_file()
    assert len(list(dimacs_dir().glob("*.clq"))) == 27
    assert data_dir == datasets.data_dir()
