"""Shared fixtures: where the real data are, and skipping cleanly when they are not.

Use ``require_log("intel")`` (importable as ``from conftest import require_log``, or through
the ``log_path`` fixture) in tests marked ``@pytest.mark.realdata``: it returns the log's
path, or skips the test saying where the data were looked for and how to point at them.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from scanclique import datasets
from scanclique.errors import DataNotFoundError
from scanclique.geometry import Pose2
from scanclique.sim import room_world, simulate_scan


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


def circle_drive(rng, laps=2, n_per_lap=36, people=False):
    """A simulated drive around a circle of radius 1.5 m in a room, ``laps`` times: the
    later laps revisit the first (loop closures); the odometry drifts (3 % long, 4 % over
    in turning). Importable as ``from conftest import circle_drive``."""
    world = room_world(8.0, 7.0, rng=rng, pillars=0, clutter=6)
    cx = (4.0, 3.5)
    scans = []
    odo = Pose2.identity()
    prev = None
    for k in range(laps * n_per_lap):
        a = 2 * math.pi * k / n_per_lap
        ref = Pose2(cx[0] + 1.5 * math.cos(a), cx[1] + 1.5 * math.sin(a), a + math.pi / 2)
        if prev is not None:
            u = prev.inverse() @ ref
            odo = odo @ Pose2(u.x * 1.03, u.y + 0.01, u.theta * 1.04 + 0.003)
        prev = ref
        crowd = None
        if people:
            crowd = (np.array([[cx[0] + 2.6 * math.cos(0.3 * k), cx[1] + 0.4]]), np.array([0.2]))
        scans.append(
            simulate_scan(world, ref, rng=rng, timestamp=0.2 * k, odometry=odo, people=crowd,
                          source=f"circle:{k}")
        )  # fmt: skip
    return scans


def short_reach_drive(seed: int):
    """Drive ``seed`` of ``benchmarks/mapping_sensors.py``'s ``lds`` profile (a TurtleBot3's
    LDS-01: 360 beams, 3.5 m reach, 1.5 % range noise per metre, 5 % dropout, 5 Hz at
    0.2 m/s) through a simulated office (60 poses 0.25 m apart, 414 scans), with its
    odometry. Importable as ``from conftest import short_reach_drive``."""
    from scanclique.sim import office_world, simulate_sensor_drive

    rng = np.random.default_rng(seed)
    world = office_world(rng)
    return simulate_sensor_drive(
        rng, world, 60, 0.25, n_beams=360, fov=2 * math.pi * 359 / 360, angle_min=0.0,
        max_range=3.5, range_sigma=0.0, range_sigma_per_m=0.015, dropout=0.05,
        scan_rate=5.0, speed=0.2,
    )  # fmt: skip
