"""Shared fixtures: where the real data are, and skipping cleanly when they are not.

Use ``require_log("intel")`` (importable as ``from conftest import require_log``, or through
the ``log_path`` fixture) in tests marked ``@pytest.mark.realdata``: it returns the log's
path, or skips the test saying where the data were looked for and how to point at them.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from scanclique import datasets
from scanclique.errors import DataNotFoundError


def assert_clean_error(result, *words: str) -> None:
    """A command line run (typer's ``CliRunner``) that failed as a user should see it:
    exit code 2, one line on stderr starting with ``error:`` and naming each of
    ``words``, no traceback. Importable as ``from conftest import assert_clean_error``."""
    assert result.exit_code == 2, (result.exit_code, result.output)
    err = result.stderr.strip()
    assert err.startswith("error:"), err
    assert len(err.splitlines()) == 1, err
    assert "Traceback" not in result.output
    for w in words:
        assert w in err, err


def _looked_in() -> str:
    return ", ".join(str(p) for p in datasets.data_dir_candidates())


def require_log(name: str) -> Path:
    """Path of the registered log ``name``, or skip the calling test with a clear reason."""
    try:
        return datasets.dataset_path(name)
    except DataNotFoundError:
        pytest.skip(
            f"real data not found: set {datasets.ENV_VAR} (looked in {_looked_in()} for "
            f"{datasets.DATASETS[name].relpath if name in datasets.DATASETS else name})"
        )


@pytest.fixture
def data_dir() -> Path:
    """The shared data directory; skips the test when it does not exist."""
    d = datasets.data_dir()
    if not d.is_dir():
        pytest.skip(f"real data not found: set {datasets.ENV_VAR} (looked in {_looked_in()})")
    return d


@pytest.fixture
def log_path():
    """``require_log`` as a fixture: ``log_path("intel")`` -> Path, or the test is skipped."""
    return require_log


@pytest.fixture(scope="session")
def drive_log(tmp_path_factory) -> Path:
    """A short simulated drive written as a scan text log (12 scans 0.2 m apart)."""
    import numpy as np

    import scanclique as sc
    from scanclique.io import write_scans_text

    rng = np.random.default_rng(21)
    scans = sc.sim.simulate_trajectory(rng, sc.sim.office_world(rng), 12, step=0.2)
    path = tmp_path_factory.mktemp("log") / "drive.txt"
    write_scans_text(path, scans)
    return path
