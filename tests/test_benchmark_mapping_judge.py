"""The mapping benchmark's closure judge by the relations' own trajectory
(benchmarks/mapping.py: relations_trajectory, judge_by_trajectory), on a planted
trajectory with known truth: the judge is only as honest as this makes it."""

import math
import sys
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from scanclique.eval import Relation
from scanclique.geometry import Pose2

pytest.importorskip("gtsam")

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
import mapping as bench  # noqa: E402  (benchmarks/mapping.py)
from test_mapping_stages import _truth_chain  # noqa: E402


def _relations(truth, rng, sxy, sth):
    """Consecutive relations and relations across the loop, with planted noise."""
    n = len(truth)
    pairs = [(k, k + 1) for k in range(n - 1)] + [(k, k + n // 2) for k in range(0, n // 2, 2)]
    pairs += [(k, k + 2) for k in range(0, n - 2, 3)]
    rels = []
    for a, b in pairs:
        d = truth[a].inverse() @ truth[b]
        e = Pose2(rng.normal(0, sxy), rng.normal(0, sxy), rng.normal(0, sth))
        rels.append(Relation(float(a), float(b), d @ e))
    return rels


def test_relations_trajectory_recovers_the_planted_poses_and_noise():
    rng = np.random.default_rng(3)
    truth = _truth_chain(40)  # a loop, one pose per second
    scans = [SimpleNamespace(timestamp=float(k)) for k in range(len(truth))]
    sxy, sth = 0.01, math.radians(0.3)
    poses, comp, rotation_sigma = bench.relations_trajectory(
        scans, _relations(truth, rng, sxy, sth), None
    )
    assert set(poses) == set(range(len(truth))) and len(set(comp.values())) == 1
    # relative poses of distant scans agree with the truth to a few relation sigmas
    for a, b in [(0, 20), (5, 33), (11, 39)]:
        t, r = (poses[a].inverse() @ poses[b]).distance_to(truth[a].inverse() @ truth[b])
        assert t < 0.05 and r < math.radians(1.0)
    est_xy, est_th = rotation_sigma.relation_sigma
    assert 0.4 * sxy < est_xy < 2.5 * sxy and 0.4 * sth < est_th < 2.5 * sth
    assert 0.0 < rotation_sigma(0, 20) < math.radians(1.0) and rotation_sigma(4, 4) == 0.0


def test_judge_by_trajectory_counts_right_and_wrong_closures(monkeypatch):
    rng = np.random.default_rng(4)
    truth = _truth_chain(40)  # a loop, one pose per second
    scans = [SimpleNamespace(timestamp=float(k)) for k in range(len(truth))]
    traj = bench.relations_trajectory(scans, _relations(truth, rng, 0.005, math.radians(0.1)), None)
    monkeypatch.setattr(bench, "_raw_scans_side_with_closure", lambda *a: False)

    def closure(i, j, err):
        return SimpleNamespace(
            i=i, j=j, pose=(truth[i].inverse() @ truth[j]) @ err, source="local", score=0.9
        )

    closures = [
        closure(2, 22, Pose2(0.02, -0.01, math.radians(0.2))),  # right
        closure(7, 30, Pose2(0.0, 0.0, math.radians(3.0))),  # 3 deg off: wrong
        closure(9, 35, Pose2(0.5, 0.0, 0.0)),  # 0.5 m off: wrong
    ]
    out = bench.judge_by_trajectory(closures, scans, traj, chained=truth)
    assert out["judged"] == 3 and out["right"] == 1
    assert sorted((w["i"], w["j"]) for w in out["wrong"]) == [(7, 30), (9, 35)]
    # the reference's noise allowance never forgives 3 deg when the reference is this tight
    assert out["right_allowing_reference_noise"] == 1
    # a closure whose scan has no relation scan within the bridge is not judged: scan n+2
    # (at t = 2.6 s) lies 0.4 s from the nearest relation scan
    n = len(truth)
    more = scans + [SimpleNamespace(timestamp=k + 0.6) for k in range(n)]
    traj2 = bench.relations_trajectory(more, _relations(truth, rng, 0.005, math.radians(0.1)), None)
    c = SimpleNamespace(i=n + 2, j=22, pose=closures[0].pose, source="local", score=0.9)
    chained = truth + [truth[k] for k in range(n)]
    assert bench.judge_by_trajectory([c], more, traj2, chained, bridge=0.3)["judged"] == 0
    assert bench.judge_by_trajectory([c], more, traj2, chained, bridge=0.5)["judged"] == 1
