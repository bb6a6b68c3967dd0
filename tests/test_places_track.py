"""Tracking in a place database's map (``run_locate(track=True)``, ``places.track``)."""

from __future__ import annotations

import pytest

from scanclique.geometry import Pose2
from scanclique.io import read_scans
from scanclique.places import PlaceDB, locate
from scanclique.places import track as tr
from scanclique.places.run import LOCATED, TRACKED, UNKNOWN, run_add, run_locate


@pytest.fixture(scope="module")
def mapped_db(drive_log, tmp_path_factory):
    """Every 3rd scan of the simulated drive stored with its true pose in the map (the
    first scan's frame); returns (database, scans, true poses)."""
    scans = read_scans(drive_log)
    start = scans[0].reference.inverse()
    truth = [start @ s.reference for s in scans]
    path = tmp_path_factory.mktemp("track") / "p.db"
    run_add(path, scans, every=3, poses=truth)
    return path, scans, truth


def _recognise_first_only(monkeypatch):
    """Recognition answers the first query only: every later scan is left to tracking."""
    real, calls = PlaceDB.query, []

    def query(self, scan, k=5, **kw):
        calls.append(1)
        return real(self, scan, k, **kw) if len(calls) == 1 else []

    monkeypatch.setattr(PlaceDB, "query", query)


def test_tracking_places_the_scans_recognition_leaves(mapped_db, monkeypatch):
    """After one recognised scan, the others are placed by the places near where the
    run's own motion predicts them, at their true pose; without tracking they are not."""
    path, scans, truth = mapped_db
    _recognise_first_only(monkeypatch)
    run = run_locate(path, scans, start=1, track=True, use_odometry=False)
    assert run.status[0] == LOCATED and run.tracked
    tracked = [k for k, s in enumerate(run.status) if s == TRACKED]
    assert len(tracked) >= 8, run.status
    for k in tracked:
        dt, dr = run.poses[k].distance_to(truth[run.indices[k]])
        assert dt < 0.05 and dr < 0.02, (run.indices[k], dt, dr)
        assert run.places[k] is not None and run.confidences[k] != run.confidences[k]  # NaN
    assert len(run.track_ms) == len(run.indices)
    d = run.to_dict()
    assert d["tracked"] == len(tracked) and d["tracking"] is True and d["contested"] == 0
    assert not any(s["contested"] for s in d["scans"])
    assert all(s["confidence"] is None for s in d["scans"] if s["status"] == TRACKED)
    assert any("tracked" in what for what, _, _ in run.rows())
    monkeypatch.undo()
    _recognise_first_only(monkeypatch)
    plain = run_locate(path, scans, start=1)
    assert plain.status[0] == LOCATED and set(plain.status[1:]) == {UNKNOWN}
    assert not plain.tracked and not plain.track_ms


def test_the_track_is_dropped_after_its_longest_path(mapped_db, monkeypatch):
    path, scans, _ = mapped_db
    _recognise_first_only(monkeypatch)
    monkeypatch.setattr(locate, "TRACK_MAX_PATH", 0.0)
    run = run_locate(path, scans, start=1, track=True, use_odometry=False)
    assert run.status[0] == LOCATED and set(run.status[1:]) == {UNKNOWN}


def test_fix_near_needs_the_prediction_to_agree(mapped_db):
    """A place near the prediction fixes the scan at its true pose; a prediction a metre
    off with a tight prior is refused by the gate, and one with no place near is None."""
    from scanclique.mapping import MapConfig

    path, scans, truth = mapped_db
    fe = MapConfig.online().front_end
    with PlaceDB(path, readonly=True) as db:
        poses = db.map_poses()
        assert sorted(poses) == [1, 2, 3, 4]
        q = db.prepare(scans[4])
        got = tr.fix_near(db, q, truth[4], (0.5, 0.05), tr.MapPoses.of(poses), fe)
        assert got is not None and got.place_id in poses and got.tried >= 1
        dt, dr = got.map_pose.distance_to(truth[4])
        assert dt < 0.05 and dr < 0.02
        off = truth[4] @ Pose2(1.0, 0.0, 0.0)
        assert tr.fix_near(db, q, off, (0.05, 0.01), tr.MapPoses.of(poses), fe) is None
        far = truth[4] @ Pose2(50.0, 0.0, 0.0)
        assert tr.fix_near(db, q, far, (0.05, 0.01), tr.MapPoses.of(poses), fe) is None


def test_near_places_orders_by_distance_then_heading():
    poses = tr.MapPoses.of(
        {7: Pose2(1, 0, 3.0), 3: Pose2(1, 0, 0.1), 5: Pose2(0, 2.5, 0), 9: Pose2(-1, 0, 0)}
    )
    assert tr.near_places(poses, Pose2(0, 0, 0), 2.0, 5) == [9, 3, 7]
    assert tr.near_places(poses, Pose2(0, 0, 0), 2.0, 1) == [9]
    assert tr.near_places(tr.MapPoses.of({}), Pose2(0, 0, 0), 2.0, 5) == []
    with pytest.raises(KeyError):
        poses.pose(4)


def test_localiser_streams_what_run_locate_gives(mapped_db, tmp_path):
    """``Localiser.add`` scan by scan is ``run_locate``: the same statuses and poses; a
    scan added with ``query=False`` only feeds the tracker."""
    from scanclique.places.locate import Localiser

    path, scans, _ = mapped_db
    run = run_locate(path, scans, start=2, every=2, track=True, use_odometry=False)
    with PlaceDB(path, readonly=True) as db, Localiser(db, track=True, use_odometry=False) as loc:
        assert loc.tracking and sorted(loc.map_poses) == [1, 2, 3, 4]
        got = [loc.add(s, query=(i - 2) % 2 == 0) for i, s in enumerate(scans[2:], start=2)]
    streamed = [g for g in got if g is not None]
    assert [g.index for g in streamed] == [i - 2 for i in run.indices]
    assert [g.status for g in streamed] == list(run.status)
    for g, p in zip(streamed, run.poses, strict=True):
        assert (g.pose is None) == (p is None) and g.placed == (p is not None)
        assert p is None or g.pose.distance_to(p)[0] < 1e-9


def test_localiser_refuses_what_it_cannot_use(mapped_db, tmp_path):
    from scanclique.errors import ArgumentError, PlaceDatabaseError, ScanError
    from scanclique.places.locate import Localiser

    path, scans, _ = mapped_db
    with pytest.raises(ArgumentError, match="must be an open PlaceDB"):
        Localiser(str(path))
    with PlaceDB(path, readonly=True) as db:
        with pytest.raises(ArgumentError, match="use_odometry"):
            Localiser(db, use_odometry="yes")
        with Localiser(db) as loc, pytest.raises(ScanError, match="must be a Scan"):
            loc.add([1.0, 2.0])
    plain = tmp_path / "plain.db"
    run_add(plain, scans, every=4)
    with PlaceDB(plain, readonly=True) as db, pytest.raises(PlaceDatabaseError, match="map pose"):
        Localiser(db)


def _look_alike_at(monkeypatch, call: int, shift):
    """Recognition puts the ``call``-th query (from 1) ``shift`` away, confidently: the
    first accepted hit's map pose moved, as a look-alike's would be."""
    from dataclasses import replace

    real, calls = PlaceDB.query, []

    def query(self, scan, k=5, **kw):
        calls.append(1)
        hits = real(self, scan, k, **kw)
        if len(calls) != call:
            return hits
        return [
            replace(h, map_pose=h.map_pose @ shift) if h.verdict == "accepted" else h for h in hits
        ]

    monkeypatch.setattr(PlaceDB, "query", query)


def test_a_look_alike_recognised_against_a_verified_track_is_not_followed(mapped_db, monkeypatch):
    """A scan recognition puts 3 m from where the track predicts it, while a place near
    the prediction verifies it there: it is tracked at its true pose (contested), and
    the scans after it too."""
    from scanclique.places.locate import Localiser

    path, scans, truth = mapped_db
    _look_alike_at(monkeypatch, 4, Pose2(3.0, 0.0, 0.0))
    with PlaceDB(path, readonly=True) as db, Localiser(db, track=True, use_odometry=False) as loc:
        got = [loc.add(s) for s in scans]
    assert got[3].status == TRACKED and got[3].contested
    for g in got:
        assert g.pose is not None and g.pose.distance_to(truth[g.index])[0] < 0.05
    assert sum(g.contested for g in got) == 1


def test_recognition_elsewhere_decides_when_the_track_cannot_be_verified(mapped_db, monkeypatch):
    """A robot carried elsewhere (the kidnapped robot): recognition places the scan 3 m
    from the prediction and no place near the prediction verifies it: located where
    recognition says, and the track follows from there."""
    from scanclique.places.locate import Localiser

    path, scans, truth = mapped_db
    _look_alike_at(monkeypatch, 4, Pose2(3.0, 0.0, 0.0))
    real = locate.fix_near

    def fix_near(*a, **kw):
        return None if a[1].scan is scans[3] else real(*a, **kw)

    monkeypatch.setattr(locate, "fix_near", fix_near)
    with PlaceDB(path, readonly=True) as db, Localiser(db, track=True, use_odometry=False) as loc:
        got = [loc.add(s) for s in scans]
    assert got[3].status == LOCATED and not got[3].contested
    assert got[3].pose.distance_to(truth[3])[0] == pytest.approx(3.0, abs=0.05)


def test_places_added_while_localising_are_tracked_against(mapped_db, tmp_path):
    """A place another connection adds (with its map pose) while the localiser runs is
    among its places from the next query on."""
    import shutil

    from scanclique.places.locate import Localiser

    path, scans, truth = mapped_db
    copy = tmp_path / "grow.db"
    shutil.copy(path, copy)
    with PlaceDB(copy, readonly=True) as db, Localiser(db, track=True, use_odometry=False) as loc:
        loc.add(scans[0])
        assert len(loc.map_poses) == 4
        with PlaceDB(copy) as writer:
            new = writer.add(scans[1], name="late", pose=truth[1])
        loc.add(scans[1])
        assert new in loc.map_poses and len(loc.map_poses) == 5


def test_tracking_and_the_whole_run_map_the_run_once(mapped_db, monkeypatch):
    """With ``track`` and ``whole`` the tracker's online map of the span is the run's map
    carried into the database's (no second mapping of the log); it covers every scan."""
    import scanclique.mapping as mapping

    def no(*a, **kw):
        raise AssertionError("the run was mapped a second time")

    path, scans, truth = mapped_db
    monkeypatch.setattr(mapping, "map_scans", no)
    run = run_locate(path, scans, start=1, every=3, track=True, whole=True, use_odometry=False)
    assert run.anchor is not None and len(run.trajectory) == len(scans) - 1
    for i, q in zip(run.trajectory_indices, run.trajectory, strict=True):
        assert q.distance_to(truth[i])[0] < 0.1


def test_scans_before_the_first_fix_are_tracked_backwards(mapped_db, monkeypatch):
    """Recognition answers only the last query: the forward tracker has nothing to start
    from, and ``run_locate`` tracks the scans before it backwards, at their true poses;
    the streaming ``Localiser`` (no future) leaves them."""
    from scanclique.places.locate import Localiser

    path, scans, truth = mapped_db
    real = PlaceDB.query
    last = scans[-1]

    def query(self, scan, k=5, **kw):
        return real(self, scan, k, **kw) if scan.scan is last else []

    monkeypatch.setattr(PlaceDB, "query", query)
    run = run_locate(path, scans, start=1, track=True, use_odometry=False)
    assert run.status[-1] == LOCATED
    back = [k for k, s in enumerate(run.status[:-1]) if s == TRACKED]
    assert len(back) >= 8, run.status
    for k in back:
        assert run.poses[k].distance_to(truth[run.indices[k]])[0] < 0.05
    with PlaceDB(path, readonly=True) as db, Localiser(db, track=True, use_odometry=False) as loc:
        got = [loc.add(s) for s in scans[1:]]
    assert all(g.status == UNKNOWN for g in got[:-1]) and got[-1].status == LOCATED
