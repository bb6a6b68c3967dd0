"""The benchmark's pair sets and success criterion (benchmarks/pairs.py)."""

import dataclasses
import math
import sys
from pathlib import Path

import numpy as np

from scanclique import Pose2
from scanclique.sim import room_world, simulate_scan

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
import pairs as P  # noqa: E402


def test_consecutive_and_skip_pairs():
    assert P.consecutive_pairs(5) == [(0, 1), (1, 2), (2, 3), (3, 4)]
    assert P.consecutive_pairs(5, 3) == [(0, 3), (1, 4)]


def test_evenly_keeps_ends_and_caps():
    pairs = [(i, i + 1) for i in range(100)]
    out = P.evenly(pairs, 10)
    assert len(out) == 10 and out[0] == pairs[0] and out[-1] == pairs[-1]
    assert P.evenly(pairs, None) == pairs


def test_success_threshold_is_inclusive_at_20cm_and_2deg():
    assert P.is_success(0.20, math.radians(2.0))
    assert not P.is_success(0.2001, 0.0)
    assert not P.is_success(0.0, math.radians(2.01))


def test_revisit_pairs_need_gap_distance_and_overlap():
    rng = np.random.default_rng(0)
    world = room_world(8.0, 6.0, rng=rng, doorways=0, pillars=1, clutter=2)
    # 60 scans standing at one spot then 60 more: every (i, i+50..) pair revisits it
    poses = [Pose2(3.0, 3.0, 0.0)] * 60 + [Pose2(3.5, 3.2, 0.1)] * 60
    scans = [simulate_scan(world, p, rng=rng) for p in poses]
    rev = P.revisit_pairs(scans, cap=20)
    assert len(rev) == 20
    assert all(j - i >= P.REVISIT_MIN_GAP for i, j in rev)
    # a far-away second half: no revisits
    far = [Pose2(3.0, 3.0, 0.0)] * 60 + [Pose2(7.5, 5.5, 0.0)] * 60
    scans_far = scans[:60] + [simulate_scan(world, p, rng=rng) for p in far[60:]]
    far_pairs = P.revisit_pairs(scans_far, cap=50)
    assert far_pairs and all((i < 60) == (j < 60) for i, j in far_pairs)


def test_overlap_is_one_for_a_scan_with_itself():
    rng = np.random.default_rng(1)
    world = room_world(6.0, 5.0, rng=rng)
    s = simulate_scan(world, Pose2(2.0, 2.0, 0.3), rng=rng)
    assert P.overlap(s, s, Pose2.identity()) == 1.0
    assert P.overlap(s, s, Pose2(1.0, 0.0, 0.5)) < 0.5


def test_reference_disputed_flags_a_reference_the_raw_scans_refute():
    import validation as V  # benchmarks/validation.py

    import scanclique as sc
    from scanclique.match import match_prepared, prepare_scan

    cfg = sc.MatchConfig()
    pair = sc.sim.simulate_pair(np.random.default_rng(3))
    pa, pb = prepare_scan(pair.scan_a, cfg), prepare_scan(pair.scan_b, cfg)
    m = match_prepared(pa, pb, cfg)
    truth = pair.pose_a_b
    assert m.pose is not None and m.pose.distance_to(truth)[0] < 0.05
    # a right match is never disputed
    assert not V.reference_disputed(pa, pb, m, truth, cfg)
    # a reference turned by 3 degrees: the scans pull ICP back to the match's pose
    off = truth @ Pose2(0.0, 0.0, math.radians(3.0))
    assert V.reference_disputed(pa, pb, m, off, cfg)
    # a reference that is right while the match is 1 m off: the scans side with the
    # reference, so the wrong match is not excused
    wrong = truth @ Pose2(1.0, 0.0, 0.0)
    assert not V.reference_disputed(pa, pb, dataclasses.replace(m, pose=wrong), truth, cfg)
