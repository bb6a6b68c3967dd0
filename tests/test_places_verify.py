"""Place recognition's verification: the hit confidence (places.verify.clique_surprise,
confidence), and the second path, a pose hypothesis (the triangle prefilter's) refined and
checked on the raw scans (places.verify.verify_seeded), and the alias score of a pose."""

from __future__ import annotations

import numpy as np
import pytest

import scanclique as sc
from scanclique.geometry import Pose2
from scanclique.match import prepare_scan
from scanclique.places.verify import (
    ACCEPTED,
    AMBIGUOUS,
    REJECTED,
    alias_score,
    clique_surprise,
    confidence,
    verify_pair,
    verify_seeded,
    weakest_constraint,
)


@pytest.fixture(scope="module")
def pair():
    p = sc.sim.simulate_pair(np.random.default_rng(4))
    return p, prepare_scan(p.scan_a), prepare_scan(p.scan_b)


def test_a_seed_near_the_pose_is_refined_to_it(pair):
    p, a, b = pair
    truth = p.pose_a_b
    seed = truth @ Pose2(0.25, -0.2, 0.08)
    v = verify_seeded(a, b, seed)
    assert v.verdict in (ACCEPTED, AMBIGUOUS), v.reason
    t_err, r_err = v.pose.distance_to(truth)
    assert t_err < 0.1 and r_err < 0.02
    assert v.validation == "seeded" and v.n_features == 0 and v.covariance is None
    if v.verdict == ACCEPTED:
        alias, _ = alias_score(a, b, v.pose)
        assert alias < 0.9 * v.score


def test_a_seed_far_from_any_pose_is_rejected(pair):
    _, a, b = pair
    v = verify_seeded(a, b, Pose2(7.0, -6.0, 2.5))
    assert v.verdict == REJECTED and v.pose is None and v.reason


def test_a_score_floor_above_the_match_rejects_it(pair):
    p, a, b = pair
    v = verify_seeded(a, b, p.pose_a_b, min_score=1.01)
    assert v.verdict == REJECTED and "below" in v.reason


def test_a_corridor_does_not_fix_the_pose_along_it():
    """Two parallel walls: the raw scans leave the translation along them free."""
    ang = np.linspace(-np.pi / 2, np.pi / 2, 181)
    # walls at y = +-1.5 m, the sensor between them looking along x
    with np.errstate(divide="ignore"):
        r = np.abs(1.5 / np.sin(ang))
    r[r > 30.0] = np.inf  # no return down the corridor
    scan = sc.Scan(ranges=r, angles=ang)
    pc = prepare_scan(scan)
    assert weakest_constraint(pc, pc, Pose2(0.0, 0.0, 0.0), 0.15) < 0.05


def test_clique_surprise_grows_with_the_clique_and_falls_with_the_density():
    sizes = [clique_surprise(n, 80, 400) for n in range(3, 16)]
    assert all(b > a for a, b in zip(sizes, sizes[1:], strict=False))
    dens = [clique_surprise(6, 80, e) for e in (100, 400, 1600, 3160)]
    assert all(b < a for a, b in zip(dens, dens[1:], strict=False))
    # a complete graph holds C(V, n) cliques of n: no evidence at all
    assert clique_surprise(6, 80, 80 * 79 // 2) < -5
    # defined where there is no clique to judge, finite without edges
    for n, v, e in ((0, 80, 400), (1, 80, 400), (5, 0, 0), (5, 1, 0), (9, 5, 10)):
        assert clique_surprise(n, v, e) == 0.0
    assert np.isfinite(clique_surprise(5, 40, 0)) and clique_surprise(5, 40, 0) > 0


def test_confidence_is_a_probability_monotone_in_its_evidence():
    grid = np.linspace(0.0, 1.0, 11)
    by_score = [confidence(s, 10.0, 0.1) for s in grid[1:]]
    by_surprise = [confidence(0.7, x, 0.1) for x in (-10.0, 0.0, 5.0, 20.0, 80.0)]
    by_rival = [confidence(0.7, 10.0, r) for r in grid * 0.7]
    assert all(b > a for a, b in zip(by_score, by_score[1:], strict=False))
    assert all(b > a for a, b in zip(by_surprise, by_surprise[1:], strict=False))
    assert all(b < a for a, b in zip(by_rival, by_rival[1:], strict=False))
    # a rival better than the pose counts as an equal one; edge cases stay defined
    assert confidence(0.7, 10.0, 2.0) == confidence(0.7, 10.0, 0.7)
    assert confidence(0.7, 10.0, -0.3) == confidence(0.7, 10.0, 0.0)
    for args in ((0.0,), (0.0, 0.0, 0.5), (-0.2, 0.0, 0.0), (1.0, 0.0, 0.0), (1.0, 1e6, 0.0)):
        c = confidence(*args)
        assert 0.0 <= c <= 1.0 and np.isfinite(c)
    assert confidence(0.0) < 0.01 and confidence(0.95, 30.0, 0.0) > 0.99


def test_a_verified_pair_carries_its_evidence_and_confidence(pair):
    p, a, b = pair
    v = verify_pair(a, b, min_score=0.0)
    assert v.pose is not None and v.graph_nodes > 0 and v.graph_edges > 0
    assert v.clique_size >= v.n_features > 0 and v.place_features == len(a.features)
    assert v.surprise == clique_surprise(v.n_features, v.graph_nodes, v.graph_edges)
    assert v.confidence == confidence(v.score, v.surprise, v.rival_score)
    assert 0.0 < v.confidence < 1.0 and v.to_dict()["confidence"] == v.confidence
    r = verify_pair(a, b, min_score=1.01)
    assert r.verdict == REJECTED and r.confidence == 0.0
