"""Odometry that never reports backing up (it logs the speed's magnitude: the raw fr079
log's, 0 of its 4062 moving steps backwards while its scans back up): while the scans
say the robot is backing up, the front end validates a match against the odometry
reversed first, and against the odometry as logged when that rejects it."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

import scanclique.mapping.frontend as frontend
import scanclique.mapping.pipeline as pipeline
from scanclique.mapping import MapConfig, map_scans
from scanclique.mapping.frontend import odometry_sees_reversing, reversed_increment
from scanclique.sim import office_world, simulate_trajectory


def _forth_and_back(seed: int = 3, n: int = 30, step: float = 0.3):
    """A drive of ``n`` scans and then the same poses backwards (the robot backs up along
    its path, seeing what it saw), with odometry that logs every step as forwards."""
    rng = np.random.default_rng(seed)
    fwd = simulate_trajectory(rng, office_world(rng, length=14.0), n, step=step)
    drive = fwd + fwd[-2::-1]
    odo = [drive[0].reference]
    for a, b in zip(drive, drive[1:], strict=False):
        u = a.reference.inverse() @ b.reference
        odo.append(odo[-1] @ (reversed_increment(u) if u.x < 0 else u))
    return [dataclasses.replace(s, odometry=o) for s, o in zip(drive, odo, strict=True)]


def _chain_config() -> MapConfig:
    cfg = MapConfig()
    return dataclasses.replace(cfg, loops=dataclasses.replace(cfg.loops, enabled=False))


def _worst_step_error(scans, poses) -> float:
    worst = 0.0
    for i in range(1, len(scans)):
        true = scans[i - 1].reference.inverse() @ scans[i].reference
        est = poses[i - 1].inverse() @ poses[i]
        worst = max(worst, true.distance_to(est)[0])
    return worst


def test_odometry_sees_reversing():
    scans = _forth_and_back()
    assert not odometry_sees_reversing(scans)
    signed = [dataclasses.replace(s, odometry=s.reference) for s in scans]
    assert odometry_sees_reversing(signed)
    assert odometry_sees_reversing([])  # nothing to tell from


def test_backing_up_with_forward_only_odometry(monkeypatch):
    scans = _forth_and_back()
    res = map_scans(scans, config=_chain_config())
    reversed_matches = [r for r in res.reasons.values() if "odometry reversed" in r]
    assert reversed_matches  # the backing up was seen as such
    fixed = _worst_step_error(scans, res.poses)
    # the same drive with the odometry taken as it is (as before the rule)
    monkeypatch.setattr(pipeline, "odometry_sees_reversing", lambda s: True)
    before = map_scans(scans, config=_chain_config())
    assert not [r for r in before.reasons.values() if "odometry reversed" in r]
    assert fixed < 0.05
    assert fixed < _worst_step_error(scans, before.poses)


@pytest.mark.parametrize("seed", [5, 6])
def test_a_drive_forwards_with_the_rule_on(monkeypatch, seed):
    """The rule on (as for a log whose odometry never backs up) leaves a forward drive
    mapped as well as with it off: a rejected match is not taken for a backing up."""
    rng = np.random.default_rng(seed)
    scans = simulate_trajectory(rng, office_world(rng, length=14.0), 40, step=0.3)
    monkeypatch.setattr(pipeline, "odometry_sees_reversing", lambda s: False)
    on = map_scans(scans, config=_chain_config())
    monkeypatch.setattr(pipeline, "odometry_sees_reversing", lambda s: True)
    off = map_scans(scans, config=_chain_config())
    assert _worst_step_error(scans, on.poses) <= _worst_step_error(scans, off.poses) + 0.01
    assert _worst_step_error(scans, on.poses) < 0.05


def test_a_wrong_match_that_agrees_with_the_forward_odometry_is_not_taken():
    # fr079 backs up at scans 1400-1434 while its odometry logs forwards. With every second
    # scan (0.2 m steps), the match of scan 1408 against its keyframe 1400 agreed with the
    # forward odometry but was 14 degrees and 0.7 m off: validated against the odometry as
    # logged first, it was taken (the relation 1400-1408 0.9 m off); against the odometry
    # reversed first, as the scans say the robot still backs up, the right one is
    from conftest import require_log

    from scanclique import datasets
    from scanclique.eval import frame_mounting, read_relations, relation_metrics

    require_log("fr079-raw")
    scans = datasets.load_log("fr079-raw")[1300:1500:2]
    assert not odometry_sees_reversing(scans)
    r = map_scans(scans, use_odometry=True)
    rels = read_relations(datasets.data_dir() / datasets.DATASETS["fr079-raw"].relations)
    m = relation_metrics(
        rels, list(r.poses), [s.timestamp for s in scans], mounting=frame_mounting(scans)
    ).to_dict()["all"]
    assert m["n"] >= 10
    assert m["translation_max"] < 0.2  # 0.899 m before
    assert any("odometry reversed" in why for why in r.reasons.values())


def test_a_corridor_does_not_say_the_robot_is_still_backing_up(monkeypatch):
    """A 3.5 m scanner (a TurtleBot3's LDS-01) driving along a corridor, with odometry that
    never reports backing up: one slid match reads as a step backwards, and the match
    against the odometry reversed, free along the corridor, took its position there from
    that reversed odometry (``along_corridor``), so every next step said "still backing
    up" (8 scans, the chain 0.66 m off). Such a match (``Step.along_prior``) is not
    taken."""
    from conftest import short_reach_drive

    scans = short_reach_drive(2)[:80]
    assert not odometry_sees_reversing(scans)

    # the drive as recorded (session 37): each lost return an edge, as before session 40
    # bridged them (FrontEndConfig.fit_scanner), which moves the slid match elsewhere
    cfg = _chain_config()
    cfg = dataclasses.replace(cfg, front_end=dataclasses.replace(cfg.front_end, fit_scanner=False))

    def run():
        res = map_scans(scans, use_odometry=True, config=cfg)
        r0 = scans[0].reference.inverse()
        worst = max(
            p.distance_to(r0 @ s.reference)[0] for p, s in zip(res.chained, scans, strict=True)
        )
        return sum("odometry reversed" in r for r in res.reasons.values()), worst

    reversed_now, worst_now = run()
    along = frontend.along_corridor
    # as before: the position along the corridor still the prior's, but not said so
    monkeypatch.setattr(frontend, "along_corridor", lambda *a: (*along(*a)[:2], False))
    reversed_before, worst_before = run()
    assert reversed_now <= 1 < 4 <= reversed_before
    assert worst_now < 0.3 < worst_before


def test_a_match_taken_against_the_reversed_odometry_is_not_flipped_by_icp_from_it():
    """Simulated campus drive 1 (RPLIDAR class, 65 poses), which never backs up: its odometry
    never moves backwards, so it may be blind to reversing, and a step the noisy scanner's
    keyframe matches place a few centimetres back makes the next prior the odometry
    reversed. The next match (forwards, right) passes against it; ICP from the reversed
    odometry then slid back along the street and, the match being far from that prior,
    won the contest: the step placed 0.3-0.6 m backwards, and the next prior reversed
    again. A match taken against the reversed odometry is no longer contested from it."""
    from test_mapping_sensors import RPLIDAR

    from scanclique.sim import campus_world, simulate_sensor_drive

    rng = np.random.default_rng(1)
    scans = simulate_sensor_drive(rng, campus_world(rng), 65, 0.25, **RPLIDAR)
    assert not odometry_sees_reversing(scans)
    res = map_scans(scans, use_odometry=True, config=_chain_config())
    assert _worst_step_error(scans, res.poses) < 0.3
