"""The second verification path of place recognition: a pose hypothesis (the triangle
prefilter's) refined and checked on the raw scans (places.verify.verify_seeded), and the
alias score of a pose."""

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
