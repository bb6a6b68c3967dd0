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
    conflict_fraction,
    look_alike,
    verify_pair,
    verify_seeded,
    weakest_constraint,
)
from scanclique.places.verify import LOOK_ALIKE_CONFLICT as ALIKE_C
from scanclique.places.verify import LOOK_ALIKE_RIVAL as ALIKE_R


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
    by_conflict = [confidence(0.7, 10.0, 0.1, c) for c in grid * 0.3]
    assert all(b > a for a, b in zip(by_score, by_score[1:], strict=False))
    assert all(b > a for a, b in zip(by_surprise, by_surprise[1:], strict=False))
    assert all(b < a for a, b in zip(by_rival, by_rival[1:], strict=False))
    assert all(b < a for a, b in zip(by_conflict, by_conflict[1:], strict=False))
    # a twin room: walls agree, a tenth of the points stand in the other's free space,
    # which the default acceptance (0.99) refuses and the same room passes
    assert confidence(0.8, 20.0, 0.1, 0.1) < 0.99 < confidence(0.8, 20.0, 0.1, 0.0)
    # a rival better than the pose counts as an equal one; edge cases stay defined
    assert confidence(0.7, 10.0, 2.0) == confidence(0.7, 10.0, 0.7)
    assert confidence(0.7, 10.0, -0.3) == confidence(0.7, 10.0, 0.0)
    for args in ((0.0,), (0.0, 0.0, 0.5), (-0.2, 0.0, 0.0), (1.0, 0.0, 0.0), (1.0, 1e6, 0.0)):
        c = confidence(*args)
        assert 0.0 <= c <= 1.0 and np.isfinite(c)
    # no raw-scan support, nothing to confirm; a clear match is sure
    assert confidence(0.0) == 0.0 and confidence(-0.2, 50.0) == 0.0
    assert confidence(0.95, 30.0, 0.0) > 0.99


def test_a_verified_pair_carries_its_evidence_and_confidence(pair):
    p, a, b = pair
    v = verify_pair(a, b, min_score=0.0)
    assert v.pose is not None and v.graph_nodes > 0 and v.graph_edges > 0
    assert v.clique_size >= v.n_features > 0 and v.place_features == len(a.features)
    assert v.surprise == clique_surprise(v.n_features, v.graph_nodes, v.graph_edges)
    assert v.conflict == conflict_fraction(a, b, v.pose)
    assert v.confidence == confidence(v.score, v.surprise, v.rival_score, v.conflict)
    assert 0.0 < v.confidence < 1.0 and v.to_dict()["confidence"] == v.confidence
    r = verify_pair(a, b, min_score=1.01)
    assert r.verdict == REJECTED and r.confidence == 0.0


def test_conflict_fraction_tells_a_twin_room_from_the_same_room():
    """Two views of one room agree without conflicts; the same second view taken in a
    twin room with a cupboard where the first view saw free floor puts the cupboard's
    points in the first view's free space, and lowers the confidence of the same pose."""
    room = np.array([[[0, 0], [6, 0]], [[6, 0], [6, 5]], [[6, 5], [0, 5]], [[0, 5], [0, 0]]])
    box = np.array([[[3.0, 2.0], [3.6, 2.0]], [[3.6, 2.0], [3.6, 2.6]],
                    [[3.6, 2.6], [3.0, 2.6]], [[3.0, 2.6], [3.0, 2.0]]])  # fmt: skip
    same = sc.sim.World(room, circle_centres=[[1.5, 4.0]], circle_radii=[0.15])
    twin = sc.sim.World(np.concatenate([room, box]), circle_centres=[[1.5, 4.0]],
                        circle_radii=[0.15])  # fmt: skip
    pa, pb = Pose2(1.0, 1.0, 0.6), Pose2(1.6, 0.8, 0.9)
    kw = dict(n_beams=361, range_sigma=0.0)
    a = prepare_scan(sc.sim.simulate_scan(same, pa, **kw))
    b = prepare_scan(sc.sim.simulate_scan(same, pb, **kw))
    c = prepare_scan(sc.sim.simulate_scan(twin, pb, **kw))
    truth = pa.inverse() @ pb
    same_room, twin_room = conflict_fraction(a, b, truth), conflict_fraction(a, c, truth)
    assert same_room < 0.01 and twin_room > 0.03
    # symmetric: the place's points in the query's free space count the same way
    assert conflict_fraction(c, a, truth.inverse()) > 0.03
    assert confidence(0.8, 10.0, 0.1, twin_room) < confidence(0.8, 10.0, 0.1, same_room)


def test_a_clique_that_is_no_evidence_has_its_aliases_as_rivals(pair, monkeypatch):
    """An accepted match whose clique's surprise is below ALIAS_SURPRISE gets the best of
    its pose's quarter- and half-turn aliases as a rival (a short-range scanner's
    half-turn aliases of 3 features scored above 0.9); a surprising clique does not pay
    for the three ICP runs."""
    import scanclique.places.verify as ver

    _, a, b = pair
    base = verify_pair(a, b, min_score=0.0, min_confidence=0.0)
    assert base.verdict == ACCEPTED and base.surprise >= ver.ALIAS_SURPRISE
    calls = []

    def fake_alias(place, query, pose, cfg=None):
        calls.append(pose)
        return 0.97 * base.score, pose

    monkeypatch.setattr(ver, "alias_score", fake_alias)
    assert (
        verify_pair(a, b, min_score=0.0, min_confidence=0.0).rival_score == base.rival_score
        and not calls
    )
    monkeypatch.setattr(ver, "clique_surprise", lambda *args: ver.ALIAS_SURPRISE - 0.5)
    v = verify_pair(a, b, min_score=0.0, min_confidence=0.0)
    assert len(calls) == 1 and calls[0].distance_to(v.pose) == (0.0, 0.0)
    assert v.rival_score == max(base.rival_score, 0.97 * base.score)
    assert v.confidence == confidence(v.score, v.surprise, v.rival_score, v.conflict)
    assert v.confidence < confidence(v.score, v.surprise, base.rival_score, v.conflict)


def test_a_look_alike_needs_both_a_rival_and_a_conflict():
    """An accepted verification becomes ambiguous only when a distinct pose scores at
    least LOOK_ALIKE_RIVAL of its score *and* more than LOOK_ALIKE_CONFLICT of the points
    conflict; either sign alone leaves it to the confidence, and other verdicts pass."""
    import dataclasses

    from scanclique.places.verify import Verification

    assert 0.63 / 0.7 >= ALIKE_R
    v = Verification(ACCEPTED, Pose2(1.0, 2.0, 0.3), None, 0.7, 12, "accepted", "why", 0.01,
                     rival_score=0.63, confidence=0.999, conflict=2 * ALIKE_C)  # fmt: skip
    alike = look_alike(v)
    assert alike.verdict == AMBIGUOUS and "look-alike" in alike.reason
    assert alike.reason.endswith("why") and alike.pose == v.pose and alike.confidence == 0.999
    for other in (
        dataclasses.replace(v, conflict=ALIKE_C),  # at the bound: not above it
        dataclasses.replace(v, conflict=0.0),
        dataclasses.replace(v, rival_score=0.99 * ALIKE_R * 0.7),  # a rival ratio below
        dataclasses.replace(v, verdict=REJECTED),
        dataclasses.replace(v, verdict=AMBIGUOUS, reason="rivals"),
    ):
        assert look_alike(other) is other


def test_streets_alike_are_look_alikes_not_places():
    """Outdoors, a noisy 360-degree 10 m scanner (RPLIDAR class) sees streets lined with
    trees and walls alike: the clique of 14 alike trees and wall ends between two streets
    24 m apart has a confidence above 0.99, but a pose half a turn away explains the raw
    scans as well and the place's trees stand in the query's free space: ambiguous. A
    scan and its neighbour 0.6 m on, the same street, stay accepted."""
    rng = np.random.default_rng(101)
    world = sc.sim.campus_world(rng)
    scans = sc.sim.simulate_trajectory(
        rng, world, 300, step=0.3, n_beams=360, fov=2 * np.pi * 359 / 360, angle_min=-np.pi,
        max_range=10.0, range_sigma=0.0, range_sigma_per_m=0.015, dropout=0.07,
    )  # fmt: skip
    place, query = prepare_scan(scans[100]), prepare_scan(scans[14])
    v = verify_pair(place, query, min_confidence=0.0)
    truth = scans[100].reference.inverse() @ scans[14].reference
    assert v.pose.distance_to(truth)[0] > 5.0  # a wrong pose ...
    assert v.confidence > 0.99 and v.verdict == AMBIGUOUS and "look-alike" in v.reason
    near = verify_pair(prepare_scan(scans[16]), query, min_confidence=0.0)
    truth = scans[16].reference.inverse() @ scans[14].reference
    assert near.verdict == ACCEPTED and near.pose.distance_to(truth)[0] < 0.2
