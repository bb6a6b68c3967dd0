"""The online mapper (scanclique.mapping.online, issue 12 part 3): scans one at a time,
each answered at once with its pose as then estimated; the finished map is map_scans'."""

from __future__ import annotations

import math

import numpy as np
import pytest
from conftest import circle_drive, require_log

from scanclique import read_scans
from scanclique.errors import ArgumentError, ConfigError, ScanError
from scanclique.geometry import Pose2
from scanclique.mapping import MapConfig, OnlineMapper, map_scans
from scanclique.mapping.frontend import ReversingWatch, odometry_sees_reversing
from scanclique.scan import Scan


def _array(poses):
    return np.array([p.as_array() for p in poses])


def _key(c):
    p = None if c.pose is None else tuple(c.pose.as_array().tolist())
    return (c.i, c.j, c.verdict, c.accepted, c.local, c.source, c.score, p)


def _assert_same_map(a, b):
    np.testing.assert_array_equal(_array(a.poses), _array(b.poses))
    assert a.keyframes == b.keyframes and a.placed_by == b.placed_by
    assert [_key(c) for c in a.loop_closures] == [_key(c) for c in b.loop_closures]
    assert [(e.i, e.j, e.kind) for e in a.edges] == [(e.i, e.j, e.kind) for e in b.edges]
    assert a.used_odometry == b.used_odometry


def _online(scans, **kw):
    """The online map of ``scans``, the pose each ``add`` returned, and every scan's pose
    under the estimate just before ``finish``."""
    with OnlineMapper(**kw) as m:
        live = [m.add(s) for s in scans]
        assert len(m) == len(scans)
        before = m.poses()
        return m.finish(), live, before


@pytest.mark.parametrize("use_odometry", [True, False])
def test_the_finished_map_is_map_scans(use_odometry):
    scans = circle_drive(np.random.default_rng(5), n_per_lap=30)
    batch = map_scans(scans, use_odometry=use_odometry, config=MapConfig.online())
    reverses = odometry_sees_reversing(scans)
    online, live, _ = _online(scans, use_odometry=use_odometry, odometry_reverses=reverses)
    assert len(batch.accepted_closures) >= 3  # there are closures to agree on
    _assert_same_map(batch, online)
    assert online.seconds["total"] > 0 and "optimize" in online.seconds


def test_the_poses_as_they_come():
    """Each scan's answer is its pose as then estimated: near the truth on a drive whose
    odometry drifts 3 % (the truth in scan 0's frame), the first exactly the origin, and
    the last lap's answers already corrected by the closures of the first."""
    scans = circle_drive(np.random.default_rng(5), n_per_lap=30)
    online, live, before = _online(scans)
    assert live[0].as_array().tolist() == [0.0, 0.0, 0.0]
    r0 = scans[0].reference.inverse()
    err_live = [p.distance_to(r0 @ s.reference)[0] for p, s in zip(live, scans, strict=True)]
    err_odo = [
        (scans[0].odometry.inverse() @ s.odometry).distance_to(r0 @ s.reference)[0] for s in scans
    ]
    assert max(err_live) < 0.15 < max(err_odo)
    # the newest scan's answer is what pose() gives for it (no later scan has moved it)
    np.testing.assert_array_equal(live[-1].as_array(), before[-1].as_array())
    # the last scans' answers (the end of a loop the first lap closed) are each within
    # 0.1 m of the finished map's
    final = online.poses
    assert max(live[j].distance_to(final[j])[0] for j in range(-5, 0)) < 0.1


def test_use_odometry_is_told_by_the_first_scan():
    scans = circle_drive(np.random.default_rng(3), laps=1, n_per_lap=12)
    assert _online(scans)[0].used_odometry
    bare = [Scan(s.ranges, s.angles, timestamp=s.timestamp) for s in scans]
    assert not _online(bare)[0].used_odometry


def test_the_reversing_watch_is_the_whole_log_rule_on_every_prefix():
    rng = np.random.default_rng(2)
    steps = rng.uniform(-0.005, 0.03, size=160)
    steps[130] = -0.05  # one step backwards, after 50 moving ones
    odo, x = [], 0.0
    for d in steps:
        x += d
        odo.append(Pose2(x, 0.0, 0.0))
    scans = [Scan([1.0], [0.0], odometry=o) for o in odo]
    scans.insert(30, Scan([1.0], [0.0]))  # a scan without odometry is skipped
    w = ReversingWatch()
    answers = []
    for k, s in enumerate(scans):
        w.see(s.odometry)
        assert w.sees_reversing == odometry_sees_reversing(scans[: k + 1])
        answers.append(w.sees_reversing)
    assert True in answers and False in answers  # the rule changes its answer on the way


def test_an_online_mapper_without_scans_or_after_it_is_done():
    m = OnlineMapper()
    assert len(m) == 0 and m.poses() == () and m.keyframes == () and m.loop_closures == ()
    empty = m.finish()
    assert empty.poses == () and m.finish() is empty  # finishing again gives the same
    scan = Scan(np.full(5, 2.0), np.linspace(-1, 1, 5))
    with pytest.raises(ArgumentError, match="finished"):
        m.add(scan)
    closed = OnlineMapper()
    closed.add(scan)
    closed.close()
    with pytest.raises(ArgumentError, match="finished"):
        closed.add(scan)
    with pytest.raises(ArgumentError, match="closed without a result"):
        closed.finish()


def test_bad_arguments():
    with pytest.raises(ConfigError, match="config must be a MapConfig"):
        OnlineMapper(config={"loops": None})
    with pytest.raises(ConfigError, match="workers"):
        OnlineMapper(workers=0)
    with pytest.raises(ArgumentError, match="use_odometry"):
        OnlineMapper(use_odometry="yes")
    with pytest.raises(ArgumentError, match="odometry_reverses"):
        OnlineMapper(odometry_reverses=1)
    m = OnlineMapper(config=MapConfig())
    with pytest.raises(ScanError, match="OnlineMapper.add: scan must be a Scan, got list"):
        m.add([1.0, 2.0])
    m.add(Scan(np.full(5, 2.0), np.linspace(-1, 1, 5)))
    assert m.pose(0) == m.pose(-1)
    for bad in (1, -2, 0.5, "0", True, None):
        with pytest.raises(ArgumentError, match="OnlineMapper.pose"):
            m.pose(bad)
    assert m.pose(np.int64(0)).as_array().tolist() == [0.0, 0.0, 0.0]
    m.close()
    # the batch mapper and map_online check the same before any scan is mapped
    scans = [Scan(np.full(5, 2.0), np.linspace(-1, 1, 5))] * 2
    with pytest.raises(ArgumentError, match="map_scans: use_odometry must be True, False or None"):
        map_scans(scans, use_odometry="no")  # a string counted as True
    with pytest.raises(ArgumentError, match="map_scans: progress must be a function or None"):
        map_scans(scans, progress=50)
    from scanclique.mapping.online import map_online

    for name in ("progress", "watch"):
        with pytest.raises(ArgumentError, match=f"map_online: {name} must be a function"):
            map_online(scans, **{name: "tick"})
    assert len(map_scans(scans, use_odometry=np.bool_(False)).poses) == 2


def test_workers_give_the_serial_online_map():
    scans = circle_drive(np.random.default_rng(5), n_per_lap=30)
    serial, live1, _ = _online(scans)
    parallel, live2, _ = _online(scans, workers=2)
    _assert_same_map(serial, parallel)
    np.testing.assert_array_equal(_array(live1), _array(live2))


@pytest.mark.realdata
def test_the_finished_map_of_a_real_log_is_map_scans():
    """The raw fr079 log's first 600 scans (odometry that never reports backing up),
    odometry told as it comes: the finished map is map_scans' (which reads the whole
    prefix), and the answers as they came are within a metre of it."""
    scans = read_scans(require_log("fr079-raw"))[:600]
    batch = map_scans(scans, config=MapConfig.online())
    online, live, _ = _online(scans)
    _assert_same_map(batch, online)
    worst = max(p.distance_to(q)[0] for p, q in zip(live, online.poses, strict=True))
    assert worst < 1.0 and math.isfinite(worst)


def test_map_online_keeps_each_answer_and_the_command_writes_them(drive_log, tmp_path):
    """map_online: the live poses are the answers of add (the first the origin), one time
    per scan; run_map(online=True) writes them as trajectory_live.tum beside the finished
    map, whose trajectory.tum is the batch map's here (the drive's odometry is too short
    to tell reversing: taken alike)."""
    import json

    from scanclique.mapping import map_online, run_map

    scans = read_scans(drive_log)
    calls, seen = [], []
    orun = map_online(
        scans, progress=lambda *a: calls.append(a),
        watch=lambda m, j: seen.append((j, len(m), m.pose(j))),
    )  # fmt: skip
    assert len(orun.live) == len(scans) == orun.add_seconds.size
    # the watch is called after each add, with what is known then
    assert [(j, n) for j, n, _ in seen] == [(j, j + 1) for j in range(len(scans))]
    assert [p for *_, p in seen] == list(orun.live)
    assert orun.live[0].as_array().tolist() == [0.0, 0.0, 0.0]
    assert not orun.add_seconds.flags.writeable and (orun.add_seconds > 0).all()
    assert calls and calls[-1][:2] == (len(scans), len(scans))
    _assert_same_map(map_scans(scans, config=MapConfig.online()), orun.result)
    online = run_map(drive_log, tmp_path / "o", plot=False, online=True)
    batch = run_map(drive_log, tmp_path / "b", plot=False, config=MapConfig.online())
    tum = [(tmp_path / d / "trajectory.tum").read_text() for d in ("o", "b")]
    assert tum[0] == tum[1]
    live = np.loadtxt(tmp_path / "o/trajectory_live.tum")
    np.testing.assert_allclose(live[:, 1:3], _array(orun.live)[:, :2], atol=1e-6)
    report = json.loads((tmp_path / "o/report.json").read_text())
    assert set(report["online"]["add_ms"]) == {"p50", "p95", "max"}
    assert report["online"]["first_ms"] > 0
    assert online.online == report["online"] and batch.online is None
    names = [r[0] for r in online.rows()]
    assert "time per scan online (median / p95 / max)" in names
    assert "first scan online (kernels load)" in names
    with pytest.raises(ArgumentError, match="map_online: scans must be a sequence of Scan"):
        map_online(str(drive_log))
    with pytest.raises(ScanError, match=r"map_online: scans\[1\] is a str"):
        map_online([scans[0], "scan"])


def test_the_online_defaults_decide_closures_every_5_keyframes():
    """OnlineMapper, map_online and run_map(online=True) default to MapConfig.online()
    (PCM every 5 keyframes, the anchors' and corroboration's reach kept in keyframes);
    map_scans keeps the batch defaults (10)."""
    on, batch = MapConfig.online().loops, MapConfig().loops
    assert (on.pcm_batch, batch.pcm_batch) == (5, 10)
    assert on.pcm_batch * on.pcm_anchor_batches == batch.pcm_batch * batch.pcm_anchor_batches
    assert on.pcm_batch * on.corroborate_batches == batch.pcm_batch * batch.corroborate_batches
    assert MapConfig.online().match == MapConfig().match
    with OnlineMapper() as m:
        assert m._cfg == MapConfig.online()
    given = MapConfig()
    with OnlineMapper(config=given) as m:
        assert m._cfg is given  # a given configuration is taken as it is


def test_online_the_odometry_is_used_from_its_first_message():
    """A bag's first laser message can come before its first odometry message: online,
    the odometry is used from the first of the first scans that carries it."""
    import dataclasses

    from scanclique.mapping import map_online
    from scanclique.mapping.online import ODOMETRY_FIRST_SCANS
    from scanclique.sim import office_world, simulate_trajectory

    rng = np.random.default_rng(5)
    scans = simulate_trajectory(rng, office_world(rng), 40, n_beams=181)
    late = [dataclasses.replace(s, odometry=None) if k < 2 else s for k, s in enumerate(scans)]
    assert map_online(late).result.used_odometry
    never = [
        dataclasses.replace(s, odometry=None) if k < ODOMETRY_FIRST_SCANS else s
        for k, s in enumerate(scans)
    ]
    assert not map_online(never).result.used_odometry
