"""Place recognition end to end on simulated scans (PlaceDB.query, find_loops)."""

from __future__ import annotations

import math

import numpy as np
import pytest

import scanclique as sc
from scanclique.errors import ConfigError
from scanclique.places import ACCEPTED, AMBIGUOUS, REJECTED, PlaceDB, PlaceHit
from scanclique.places.database import CONFIDENCE_DIGITS
from scanclique.places.loops import find_loops


@pytest.fixture(scope="module")
def worlds():
    """Three short drives, each through its own simulated office."""
    rng = np.random.default_rng(11)
    out = []
    for _ in range(3):
        world = sc.sim.office_world(rng)
        out.append(sc.sim.simulate_trajectory(rng, world, 6, step=0.25))
    return out


def test_query_recognises_the_place_and_its_pose(tmp_path, worlds):
    with PlaceDB(tmp_path / "p.db") as db:
        for w, traj in enumerate(worlds):
            for k in (0, 2, 4):
                db.add(traj[k], name=f"w{w}s{k}")
        assert len(db) == 9
        for w, traj in enumerate(worlds):
            q = traj[3]  # between two stored places of its world
            hits = db.query(q, k=3, candidates=5)
            assert all(isinstance(h, PlaceHit) for h in hits) and len(hits) == 3
            best = hits[0]
            assert best.verdict == ACCEPTED and best.name.startswith(f"w{w}")
            place = db.get(best.place_id).scan
            # the hit's pose composed with the place's reference gives the query's
            t_err, r_err = (place.reference @ best.pose).distance_to(q.reference)
            assert t_err < 0.1 and r_err < 0.02
            for h in hits:
                assert (h.pose is None) == (h.verdict == REJECTED)
                if h.verdict == ACCEPTED:  # precision: every accepted hit is right
                    ref = db.get(h.place_id).scan.reference
                    assert (ref @ h.pose).distance_to(q.reference)[0] < 0.2
            # ranked: verdict first, then confidence; accepted means confident
            keys = [
                (
                    {"accepted": 0, "ambiguous": 1, "rejected": 2}[h.verdict],
                    -round(h.confidence, CONFIDENCE_DIGITS),
                )
                for h in hits
            ]
            assert keys == sorted(keys)
            assert all(h.confidence >= db.min_confidence for h in hits if h.verdict == ACCEPTED)
            assert all(h.confidence == 0.0 for h in hits if h.pose is None)


def test_a_place_keeps_its_map_pose(tmp_path, worlds):
    from scanclique.errors import ArgumentError, PlaceDatabaseError
    from scanclique.geometry import Pose2

    traj = worlds[0]
    with PlaceDB(tmp_path / "p.db") as db:
        a = db.add(traj[0], name="a", pose=Pose2(1.0, -2.0, 0.5))
        b = db.add(traj[2], name="b")
        for bad in ((1.0, 2.0, 0.0), "here", np.zeros(3)):
            with pytest.raises(ArgumentError, match="pose must be a Pose2"):
                db.add(traj[4], pose=bad)
        assert len(db) == 2  # nothing stored for the refused ones
    with PlaceDB(tmp_path / "p.db", readonly=True) as db:  # read back from the file
        assert db.map_pose(a).distance_to(Pose2(1.0, -2.0, 0.5)) == (0.0, 0.0)
        assert db.map_pose(b) is None
        with pytest.raises(PlaceDatabaseError, match="no place with id 7"):
            db.map_pose(7)


def test_a_log_whose_scanner_loses_returns_is_stored_and_searched_bridged(tmp_path):
    """A new database of ``run_add`` (``scanclique places add``) and ``find_loops`` read
    one lost return inside a surface as such (``max_gap_beams = 1``) when the log's
    scanner loses returns (features.drops_returns); a clean log keeps the defaults, an
    existing database its own configuration, and a given configuration is used as it is."""
    from scanclique.config import MatchConfig
    from scanclique.places.run import run_add

    kw = dict(n_beams=360, fov=2 * np.pi * 359 / 360, angle_min=-np.pi, max_range=10.0)
    rng = np.random.default_rng(2)
    world = sc.sim.office_world(rng)
    lossy = sc.sim.simulate_trajectory(rng, world, 8, step=0.3, dropout=0.07, **kw)
    clean = sc.sim.simulate_trajectory(rng, world, 8, step=0.3, **kw)
    gap = lambda path: PlaceDB(path, readonly=True).config.clustering.max_gap_beams  # noqa: E731
    said = dict((m, v) for m, v, _ in run_add(tmp_path / "lossy.db", lossy, every=4).rows())
    assert said["lost returns bridged inside a surface"] == "up to 1"
    said = dict((m, v) for m, v, _ in run_add(tmp_path / "clean.db", clean, every=4).rows())
    assert "lost returns bridged inside a surface" not in said
    assert gap(tmp_path / "lossy.db") == 1 and gap(tmp_path / "clean.db") == 0
    run_add(tmp_path / "clean.db", lossy, every=4)  # an existing database keeps its own
    assert gap(tmp_path / "clean.db") == 0
    run_add(tmp_path / "given.db", lossy, every=4, config=MatchConfig())
    assert gap(tmp_path / "given.db") == 0
    assert find_loops(lossy, candidates=2, min_gap=3).config.clustering.max_gap_beams == 1
    assert find_loops(clean, candidates=2, min_gap=3).config.clustering.max_gap_beams == 0
    given = find_loops(lossy, candidates=2, min_gap=3, config=MatchConfig())
    assert given.config.clustering.max_gap_beams == 0


def test_a_log_whose_scanner_meets_its_reach_is_stored_without_edges_there(tmp_path):
    """A new database of ``run_add`` and ``find_loops`` leave out the foreground edges
    where a wall only leaves the sensor's reach (``FeatureConfig.reach_edges``) when the
    log's scanner meets its reach (features.meets_reach: a 3.5 m 360-degree lidar in an
    office), keep them when it does not (30 m there), and a given configuration is used
    as it is; the table of ``places add`` says so."""
    from scanclique.config import MatchConfig
    from scanclique.features import meets_reach
    from scanclique.places.run import run_add

    kw = dict(n_beams=360, fov=2 * np.pi * 359 / 360, angle_min=-np.pi)
    rng = np.random.default_rng(3)
    world = sc.sim.office_world(rng)
    short = sc.sim.simulate_trajectory(rng, world, 8, step=0.3, max_range=3.5, **kw)
    long = sc.sim.simulate_trajectory(rng, world, 8, step=0.3, max_range=30.0, **kw)
    assert meets_reach(short) and not meets_reach(long)
    edges = lambda path: PlaceDB(path, readonly=True).config.features.reach_edges  # noqa: E731
    said = dict((m, v) for m, v, _ in run_add(tmp_path / "short.db", short, every=4).rows())
    assert said["edges where a wall leaves the reach"] == "left out"
    said = dict((m, v) for m, v, _ in run_add(tmp_path / "long.db", long, every=4).rows())
    assert "edges where a wall leaves the reach" not in said
    assert not edges(tmp_path / "short.db") and edges(tmp_path / "long.db")
    run_add(tmp_path / "given.db", short, every=4, config=MatchConfig())
    assert edges(tmp_path / "given.db")
    assert not find_loops(short, candidates=2, min_gap=3).config.features.reach_edges
    assert find_loops(long, candidates=2, min_gap=3).config.features.reach_edges


def test_a_database_written_before_a_setting_existed_reads_it_as_its_default(tmp_path):
    """A place database's stored configuration that lacks a value (written by a version
    before it existed, as ``features.reach_edges`` before session 42) is compared at that
    value's default: opened with the defaults it is not refused, with another value it
    is."""
    import dataclasses
    import json
    import sqlite3

    from scanclique.config import MatchConfig
    from scanclique.errors import PlaceDatabaseError

    path = tmp_path / "old.db"
    with PlaceDB(path) as db:
        db.add(sc.Scan.from_ranges(np.full(90, 2.0)), name="a")
    con = sqlite3.connect(path)
    cfg = json.loads(con.execute("SELECT value FROM meta WHERE key = 'config'").fetchone()[0])
    del cfg["features"]["reach_edges"]
    con.execute("UPDATE meta SET value = ? WHERE key = 'config'", (json.dumps(cfg),))
    con.commit()
    con.close()
    with PlaceDB(path, MatchConfig()) as db:
        assert db.config.features.reach_edges and len(db) == 1
    off = MatchConfig()
    off = dataclasses.replace(off, features=dataclasses.replace(off.features, reach_edges=False))
    with pytest.raises(PlaceDatabaseError, match="reach_edges"):
        PlaceDB(path, off)


def test_run_add_gives_each_place_the_pose_given_for_its_scan(tmp_path, worlds):
    """``run_add(poses=...)`` with one Pose2 or None per scan: the places added get theirs
    (counted in ``posed``); added again, a place without a map pose gets one, a place
    with one keeps it; a list of another length is an ArgumentError before anything is
    added."""
    from scanclique.errors import ArgumentError, PlaceDatabaseError
    from scanclique.geometry import Pose2
    from scanclique.places.run import run_add

    traj = worlds[1]
    poses = [Pose2(k, -k, 0.1 * k) if k % 2 else None for k in range(len(traj))]
    run = run_add(tmp_path / "p.db", traj, every=2, start=1, poses=poses)
    assert (
        run.added == 3
        and run.posed == 3
        and ("of them with a map pose", "3 of 3", "") in run.rows()
    )
    with PlaceDB(tmp_path / "p.db", readonly=True) as db:
        for pid, k in zip(run.ids, (1, 3, 5), strict=True):
            assert db.map_pose(pid).distance_to(poses[k]) == (0.0, 0.0)
    # added again with other poses: places without one get theirs, the others keep theirs
    other = [Pose2(-k, k, 0.0) for k in range(len(traj))]
    assert run_add(tmp_path / "r.db", traj, stop=4, poses=poses).posed == 2  # scans 1, 3
    again = run_add(tmp_path / "r.db", traj, stop=4, poses=other)
    assert again.added == 0 and again.skipped == 4 and again.posed_present == 2
    with PlaceDB(tmp_path / "r.db") as db:
        names = {v: k for k, v in db.store.names(db.ids).items()}
        for k in range(4):
            want = poses[k] if poses[k] is not None else other[k]
            assert db.map_pose(names[f"scans:{k}"]).distance_to(want) == (0.0, 0.0)
        with pytest.raises(PlaceDatabaseError, match="no place with id 99"):
            db.set_map_pose(99, Pose2(0, 0, 0))
        with pytest.raises(ArgumentError, match="pose must be a Pose2"):
            db.set_map_pose(names["scans:1"], (1.0, 2.0, 0.0))
    with pytest.raises(ArgumentError, match="one Pose2 or None per scan"):
        run_add(tmp_path / "q.db", traj, poses=poses[:3])
    with pytest.raises(
        ArgumentError,
        match=r"rows: a trajectory must be rows time x y theta, \(N, 4\); got \(6, 3\)",
    ):
        run_add(tmp_path / "q.db", traj, poses=np.zeros((6, 3)))
    assert not (tmp_path / "q.db").exists()


def test_consensus_motion_takes_the_motion_most_pairs_agree_on():
    """Six pairs carried by one motion and two by others: the six win, refitted exactly;
    one pair is its own motion; none gives None."""
    import math

    from scanclique.geometry import Pose2
    from scanclique.places.run import consensus_motion

    T = Pose2(3.0, -1.0, 0.7)
    good = [(Pose2(k, 0.5 * k, 0.1 * k), T @ Pose2(k, 0.5 * k, 0.1 * k)) for k in range(6)]
    bad = [(Pose2(9, 9, 0), Pose2(-20, 4, 1)), (Pose2(1, 2, 3), Pose2(5, 5, 0))]
    got, agree, rms = consensus_motion(bad[:1] + good + bad[1:])
    assert agree == (1, 2, 3, 4, 5, 6) and rms < 1e-12
    assert got.distance_to(T) == pytest.approx((0, 0), abs=1e-12)
    got, agree, rms = consensus_motion(bad[:1])
    assert agree == (0,) and rms == 0.0 and (got @ bad[0][0]).distance_to(bad[0][1])[0] < 1e-12
    got, agree, rms = consensus_motion([])
    assert got is None and agree == () and math.isnan(rms)


def test_hits_that_disagree_on_where_the_query_is_are_not_accepted(tmp_path):
    """A ring corridor with every corner alike (sim.simulate_ring_drive, seed 0): the first
    lap's every 4th scan as places, queried with second-lap scans whose first accepted hit
    is a look-alike 30-52 m away (confidence >= 0.99). With the places' poses in the map,
    four of the five have a confident hit of the right place that puts the query elsewhere:
    no accepted hit for them; the fifth's right hit is below RIVAL_CONFIDENCE."""
    from scanclique.sim import simulate_ring_drive

    scans = simulate_ring_drive(np.random.default_rng(0), loops=2.0)
    first = range(0, len(scans) // 2, 4)
    start = scans[0].reference.inverse()

    def first_accepted(db, ids, q):
        acc = [h for h in db.query(scans[q], k=5) if h.verdict == ACCEPTED]
        if not acc:
            return None
        k = ids[acc[0].place_id]
        return acc[0].pose.distance_to(scans[k].reference.inverse() @ scans[q].reference)[0]

    queries = (817, 1117, 1137, 1257)
    with PlaceDB(tmp_path / "plain.db") as db:
        ids = {db.add(scans[k]): k for k in first}
        assert all(first_accepted(db, ids, q) > 25.0 for q in queries)  # look-alikes
        assert all(h.map_pose is None for h in db.query(scans[817], k=5))
    with PlaceDB(tmp_path / "posed.db") as db:
        ids = {db.add(scans[k], pose=start @ scans[k].reference): k for k in first}
        assert all(first_accepted(db, ids, q) is None for q in queries)
        hits = db.query(scans[817], k=5)
        assert any("puts the query" in h.reason and h.verdict == AMBIGUOUS for h in hits)
        for h in hits:  # where each hit puts the query in the map
            if h.pose is None:
                assert h.map_pose is None
            else:
                want = db.map_pose(h.place_id) @ h.pose
                assert want.distance_to(h.map_pose) == pytest.approx((0.0, 0.0), abs=1e-12)


def test_a_hit_the_other_hits_support_outweighs_a_weaker_rival(tmp_path, worlds):
    """Intel's scan 447 (with places mapped by map_scans) got two right hits at
    confidence 0.998 and a quarter-turn look-alike 10 m away at 0.951: the right place,
    supported by a second place agreeing with it, stays accepted (together a thousandth
    as likely wrong as the look-alike: RIVAL_RATIO); alone at 0.998 it is ambiguous, and
    the reason names the rival."""
    from scanclique.geometry import Pose2
    from scanclique.places.database import RIVAL_RATIO

    traj = worlds[2]
    with PlaceDB(tmp_path / "p.db") as db:
        here, there = Pose2(1.0, 2.0, 0.3), Pose2(11.0, 2.0, 0.3 + np.pi / 2)
        a, b, c = (db.add(traj[k], pose=p) for k, p in ((0, here), (1, here), (2, there)))

        def hit(pid, verdict, conf):
            return PlaceHit(pid, None, Pose2(0.2, 0.0, 0.01), 0.8, verdict, 0.1, 0, 5, None, "",
                            confidence=conf)  # fmt: skip

        both = db._disagreeing([hit(a, ACCEPTED, 0.998), hit(b, ACCEPTED, 0.9978),
                                hit(c, AMBIGUOUS, 0.951)])  # fmt: skip
        assert [h.verdict for h in both] == [ACCEPTED, ACCEPTED, AMBIGUOUS]
        assert 0.049 / (0.002 * 0.0022) > RIVAL_RATIO > 0.049 / 0.002
        alone = db._disagreeing([hit(a, ACCEPTED, 0.998), hit(c, AMBIGUOUS, 0.951)])
        assert alone[0].verdict == AMBIGUOUS and f"place {c} (ambiguous" in alone[0].reason
        assert alone[0].map_pose.distance_to(here @ Pose2(0.2, 0.0, 0.01)) == (0.0, 0.0)
        weak = db._disagreeing([hit(a, ACCEPTED, 0.998), hit(c, AMBIGUOUS, 0.85)])
        assert weak[0].verdict == ACCEPTED  # below RIVAL_CONFIDENCE: not a rival


def test_exclude_and_candidates(tmp_path, worlds):
    traj = worlds[0]
    with PlaceDB(tmp_path / "p.db") as db:
        ids = [db.add(s) for s in traj]
        got, d = db.candidates(traj[2], n=2)
        assert got[0] == ids[2] and d[0] < 1e-6
        got, _ = db.candidates(traj[2], n=6, exclude=[ids[2]])
        assert ids[2] not in got.tolist() and len(got) == 5
        assert db.best(traj[2]).place_id == ids[2]


def test_find_loops_refuses_a_progress_that_is_not_a_function(worlds):
    from scanclique.errors import ArgumentError

    with pytest.raises(ArgumentError, match="find_loops: progress must be a function or None"):
        find_loops(worlds[0], min_gap=3, progress=True)


def test_find_loops_backends_identical(worlds):
    scans = [s for traj in worlds for s in traj]
    serial = find_loops(scans, candidates=2, min_gap=3)
    assert serial.backend == "serial" and len(serial.loops) > 0
    assert [(lp.i, lp.j) for lp in serial.loops] == sorted((lp.i, lp.j) for lp in serial.loops)
    assert all(lp.j <= lp.i - 3 for lp in serial.loops)
    local = find_loops(scans, candidates=2, min_gap=3, workers=2)
    assert local.backend == "processes" and local.keys() == serial.keys()
    distributed = pytest.importorskip("distributed")
    with distributed.LocalCluster(
        n_workers=2, threads_per_worker=1, processes=False, dashboard_address=":0"
    ) as cluster:
        d = find_loops(scans, candidates=2, min_gap=3, scheduler=cluster.scheduler_address)
    assert d.backend == "dask" and d.keys() == serial.keys()
    # accepted loops within one world's drive: the pose is right (across worlds the
    # reference frames are unrelated: simulated offices repeat their geometry)
    same = [lp for lp in serial.accepted if lp.i // 6 == lp.j // 6]
    assert same
    for lp in same:
        t_err, _ = (scans[lp.j].reference @ lp.pose).distance_to(scans[lp.i].reference)
        assert t_err < 0.2
    # a pair is accepted only as confident as min_confidence asks; below, ambiguous
    sure = find_loops(scans, candidates=2, min_gap=3, min_confidence=1.0)
    assert [(lp.i, lp.j) for lp in sure.loops] == [(lp.i, lp.j) for lp in serial.loops]
    was_accepted = {(lp.i, lp.j) for lp in serial.accepted}
    assert not sure.accepted
    assert {lp.verdict for lp in sure.loops if (lp.i, lp.j) in was_accepted} == {AMBIGUOUS}


def test_find_loops_bad_arguments():
    with pytest.raises(ConfigError):
        find_loops([], candidates=0)
    with pytest.raises(ConfigError):
        find_loops([], workers=-1)
    assert find_loops([], min_gap=1).loops == ()


def _broken_task(token, chunk, *rest):
    raise ModuleNotFoundError("No module named 'scanclique'")


def test_find_loops_on_a_cluster_that_cannot_do_it(worlds, monkeypatch):
    # a cluster without workers, and workers that fail (as one without scanclique
    # would): named errors, not a wait without end or a worker's bare traceback
    distributed = pytest.importorskip("distributed")
    from scanclique import places
    from scanclique.errors import ScanCliqueError

    scans = worlds[0]
    with (
        distributed.LocalCluster(n_workers=0, processes=False, dashboard_address=":0") as cluster,
        distributed.Client(cluster, timeout="2s") as client,  # the wait is the client's
    ):
        with pytest.raises(ScanCliqueError, match="has no worker to take the scans"):
            find_loops(scans, min_gap=3, scheduler=client)
        assert client.status == "running"  # the caller's client is left open
    monkeypatch.setattr(places.loops, "_signature_task", _broken_task)
    with distributed.LocalCluster(
        n_workers=1, threads_per_worker=1, processes=False, dashboard_address=":0"
    ) as cluster:
        with pytest.raises(
            ScanCliqueError, match=r"a Dask worker failed on _broken_task of chunk \d+ "
            r"\(ModuleNotFoundError: No module named 'scanclique'\); each worker needs "
            r"scanclique \S+ installed",
        ):  # fmt: skip
            find_loops(scans, min_gap=3, scheduler=cluster.scheduler_address)


def test_hits_name_their_source_and_seeded_adds_only_triangle_candidates(tmp_path, worlds):
    from scanclique.places.database import SEED_MIN_VOTES

    with PlaceDB(tmp_path / "p.db", seeded=4) as db:
        for w, traj in enumerate(worlds):
            for k in (0, 2, 4):
                db.add(traj[k], name=f"w{w}s{k}")
        q = db.prepare(worlds[1][3])
        ids0, _, _, _ = db._candidates(q, 2, None, extra=0)
        ids, _, votes, poses = db._candidates(q, 2, None, extra=4)
        assert len(ids0) == 2 and np.array_equal(ids[:2], ids0) and len(ids) <= 6
        assert np.all(votes[2:] >= SEED_MIN_VOTES)
        assert np.all(np.isfinite(poses[votes >= SEED_MIN_VOTES]))
        assert np.all(np.isnan(poses[votes < SEED_MIN_VOTES]))
        hits = db.query(q, k=2, candidates=2)
        assert {h.source for h in hits} <= {"clique", "triangles"}
        assert all(h.source == "triangles" for h in hits if h.rank >= 2)
        assert hits[0].verdict == ACCEPTED and hits[0].name.startswith("w1")
        assert hits[0].to_dict()["source"] == hits[0].source


def test_fused_loop_candidates_keep_the_gap_and_both_rankings(worlds):
    from scanclique.match import prepare_scan
    from scanclique.places.hashing import feature_triangles
    from scanclique.places.loops import fused_loop_candidates, loop_candidates
    from scanclique.places.signature import scan_signature

    scans = [s for traj in worlds for s in traj]
    ps = [prepare_scan(s) for s in scans]
    sigs = np.array([scan_signature(p) for p in ps])
    tris = [feature_triangles(p.features.points_xy, p.features.points_label) for p in ps]
    fused = fused_loop_candidates(sigs, tris, 3, 4)
    by_i: dict[int, list[int]] = {}
    for i, j, rank, d in fused:
        assert j <= i - 4 and rank == len(by_i.get(i, []))
        assert d == pytest.approx(float(np.sum((sigs[i] - sigs[j]) ** 2)))
        by_i.setdefault(i, []).append(j)
    assert all(len(js) == len(set(js)) <= 3 for js in by_i.values())
    first_sig = {i: j for i, j, rank, _ in loop_candidates(sigs, 3, 4) if rank == 0}
    assert first_sig and all(first_sig[i] in by_i[i] for i in first_sig)
    # a later scan of the same office finds an earlier one of it through the triangles
    assert any(i // 6 == j // 6 for i, js in by_i.items() for j in js)


def test_an_empty_database_answers_nothing(tmp_path, worlds):
    with PlaceDB(tmp_path / "p.db") as db:
        assert db.query(worlds[0][0], k=3) == []
        assert db.best(worlds[0][0]) is None


def test_a_hit_the_confidence_doubts_is_ambiguous_with_its_reason(tmp_path, worlds):
    """min_confidence turns accepted hits into ambiguous ones (pose kept, reason given),
    and changes neither the confidence nor the order of the hits."""
    traj = worlds[0]
    found = {}
    for floor in (0.0, 1.0):
        with PlaceDB(tmp_path / f"p{floor}.db", min_confidence=floor) as db:
            for k in (0, 2, 4):
                db.add(traj[k], name=f"s{k}")
            found[floor] = db.query(traj[3], k=3)
    trusting, doubting = found[0.0], found[1.0]
    assert trusting[0].verdict == ACCEPTED and 0.0 < trusting[0].confidence < 1.0
    assert [h.place_id for h in doubting] == [h.place_id for h in trusting]
    for a, b in zip(trusting, doubting, strict=True):
        assert a.confidence == b.confidence
        if a.verdict == ACCEPTED:
            assert b.verdict == AMBIGUOUS and b.pose is not None
            assert b.reason.startswith("confidence ") and "below min_confidence 1" in b.reason
        else:
            assert b.verdict == a.verdict
    assert trusting[0].to_dict()["confidence"] == trusting[0].confidence


def test_a_hard_query_escalates_to_more_candidates(tmp_path, worlds, monkeypatch):
    """A query with no confidently accepted candidate among its first ``candidates`` has
    the next ``escalate`` verified too; a query answered with confidence does not."""
    calls = []
    original = PlaceDB._verify_clique

    def counting(self, pid, p):
        calls.append(pid)
        return original(self, pid, p)

    monkeypatch.setattr(PlaceDB, "_verify_clique", counting)
    with PlaceDB(tmp_path / "p.db", escalate=3) as db:
        for traj in worlds[1:]:
            for s in traj:
                db.add(s)
        own = db.add(worlds[0][3])
        # the scan itself is in the database: its first candidate answers it surely
        calls.clear()
        hits = db.query(worlds[0][3], k=2)
        assert hits[0].place_id == own and hits[0].confidence >= 0.99 and len(calls) == 2
        # without it, only other offices: nothing sure, so 2 + 3 candidates verified
        calls.clear()
        hits = db.query(worlds[0][3], k=2, exclude=[own])
        assert not any(h.verdict == ACCEPTED and h.confidence >= 0.99 for h in hits)
        assert len(calls) == 5 and len(set(calls)) == 5 and len(hits) <= 2


def test_verify_one_place_as_a_query_verifies_a_candidate(tmp_path, worlds):
    """PlaceDB.verify gives a stored place's verdict without the prefilter: the same
    verdict, pose and confidence as the query gives that place as a candidate; an
    unknown or non-integer id is a named error."""
    from scanclique.errors import ArgumentError, PlaceDatabaseError

    traj = worlds[0]
    with PlaceDB(tmp_path / "v.db") as db:
        ids = [db.add(traj[k]) for k in (0, 2, 4)]
        other = db.add(worlds[1][0])
        q = traj[3]
        v = db.verify(ids[1], q)
        assert v.verdict == ACCEPTED
        t_err, r_err = (traj[2].reference @ v.pose).distance_to(q.reference)
        assert t_err < 0.1 and r_err < 0.02
        hit = next(h for h in db.query(q, k=4, candidates=4) if h.place_id == ids[1])
        assert (hit.verdict, hit.score, hit.confidence) == (v.verdict, v.score, v.confidence)
        assert hit.pose.distance_to(v.pose) == (0.0, 0.0)
        # another office's place: not accepted (the validation may accept it, the
        # confidence does not)
        assert db.verify(other, q).verdict != ACCEPTED
        with pytest.raises(PlaceDatabaseError, match="no place with id 99"):
            db.verify(99, q)
        with pytest.raises(ArgumentError, match="integer"):
            db.verify("1", q)


def test_bad_scans_are_refused_naming_the_method(tmp_path, worlds):
    """A non-scan gets a ScanError naming the PlaceDB method the user called (not an
    inner function), and a scan prepared with another configuration a ConfigError: its
    features and signature are not comparable with the stored places' (the prefilter
    alone used to rank with it silently)."""
    import dataclasses

    from scanclique.config import MatchConfig
    from scanclique.errors import ArgumentError, ScanError
    from scanclique.match import prepare_scan

    traj = worlds[0]
    with PlaceDB(tmp_path / "p.db") as db:
        for k in (0, 2, 4):
            db.add(traj[k])
        for where, call in (
            ("add", lambda s: db.add(s)),
            ("query", lambda s: db.query(s)),
            ("verify", lambda s: db.verify(1, s)),
            ("candidates", lambda s: db.candidates(s)),
        ):
            for bad in ("scan", None, [1.0, 2.0]):
                with pytest.raises(ScanError, match=rf"^PlaceDB\.{where}: scan must be a Scan"):
                    call(bad)
        for bad_name in (5, b"corridor", ("a",)):
            with pytest.raises(ArgumentError, match=r"^PlaceDB\.add: name must be a str or None"):
                db.add(traj[1], name=bad_name)
        assert db.info()["places"] == 3  # nothing was added
        cfg = MatchConfig()
        other = dataclasses.replace(cfg, features=dataclasses.replace(cfg.features, lines=False))
        p = prepare_scan(traj[3], other)
        for where, call in (
            ("query", lambda: db.query(p)),
            ("verify", lambda: db.verify(1, p)),
            ("candidates", lambda: db.candidates(p)),
        ):
            with pytest.raises(ConfigError, match=rf"^PlaceDB\.{where}: .*features differ"):
                call()
        # prepared alike (not the same object): taken as it is, same answers as the scan
        same = prepare_scan(traj[3], MatchConfig())
        assert [h.place_id for h in db.query(same, k=2)] == [
            h.place_id for h in db.query(traj[3], k=2)
        ]
        assert db.verify(2, same).verdict == db.verify(2, traj[3]).verdict


def test_bend_onto_brings_a_bent_run_back_onto_its_fixes():
    """A straight 40 m run whose own map bends (0.2 deg more heading a metre): carried
    rigidly by its first fixes it ends metres off; bent onto fixes at both ends (and a
    wrong one 5 m off, which the Cauchy kernel outweighs) it follows the truth."""
    from scanclique.geometry import Pose2
    from scanclique.places.run import bend_onto

    truth = [Pose2(0.5 * k, 0.0, 0.0) for k in range(81)]
    own, p = [truth[0]], truth[0]
    for _ in range(1, 81):
        p = p @ Pose2(0.5, 0.0, math.radians(0.1))
        own.append(p)
    rigid = list(own)  # the first scans' fixes agree with the own map
    fixes = [(0, truth[0]), (5, truth[5]), (75, truth[75]), (80, truth[80]),
             (40, truth[40] @ Pose2(0.0, 5.0, 0.0))]  # fmt: skip
    bent = bend_onto(own, rigid, fixes)
    err_rigid = max(q.distance_to(t)[0] for q, t in zip(rigid, truth, strict=True))
    err_bent = max(q.distance_to(t)[0] for q, t in zip(bent, truth, strict=True))
    assert err_rigid > 2.0 and err_bent < 0.3, (err_rigid, err_bent)
    assert bend_onto([None, *own[1:]], [None, *rigid[1:]], fixes[1:])[0] is None
