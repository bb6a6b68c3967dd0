"""The calibration benchmark's z (benchmarks/mapping_calibration.py: calibrate): a chain
whose heading errors are drawn with the sigma its edges claim gives a z rms of 1, one
three times noisier 3, an exact one 0."""

import math
import sys
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from scanclique.geometry import Pose2

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
import mapping_calibration as bench  # noqa: E402


def _chain(noise: float, n: int = 600, sigma: float = 0.01, seed: int = 0):
    """Keyframes 1 m apart on a straight reference; the chain's headings drift by
    ``noise`` rad per edge (Gaussian) where each edge claims ``sigma``."""
    rng = np.random.default_rng(seed)
    ref = [Pose2(float(k), 0.0, 0.0) for k in range(n)]
    chained, edges, pose = [Pose2.identity()], [], Pose2.identity()
    for k in range(1, n):
        step = Pose2(1.0, 0.0, float(rng.normal(0.0, noise)) if noise else 0.0)
        pose = pose @ step
        chained.append(pose)
        cov = np.diag([1e-4, 1e-4, sigma**2])
        edges.append(SimpleNamespace(i=k - 1, j=k, pose=step, covariance=cov))
    result = SimpleNamespace(keyframes=tuple(range(n)), edges=tuple(edges), chained=chained)
    return [SimpleNamespace(reference=p) for p in ref], result


@pytest.mark.parametrize(("noise", "z_rms"), [(0.01, 1.0), (0.03, 3.0), (0.0, 0.0)])
def test_z_rms_is_the_ratio_of_the_real_heading_noise_to_the_claimed(noise, z_rms):
    scans, result = _chain(noise)
    rows = bench.calibrate(scans, result, [10.0, 50.0])
    assert [r["length"] for r in rows] == [10.0, 50.0]
    for r in rows:
        assert r["z_rms"] == pytest.approx(z_rms, abs=0.25 * max(z_rms, 1.0))
        assert r["heading_sigma_deg"] == pytest.approx(math.degrees(0.01 * math.sqrt(r["length"])))
