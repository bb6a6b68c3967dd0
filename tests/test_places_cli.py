"""``scanclique places add/query/info`` and ``scanclique loops`` through typer's CliRunner."""

from __future__ import annotations

import json
import sqlite3

import pytest
from typer.testing import CliRunner

from scanclique import cli

runner = CliRunner()


def invoke(*args):
    return runner.invoke(cli.app, [str(a) for a in args])


@pytest.fixture(scope="module")
def log(drive_log):
    """A short simulated drive written as a scan text log (conftest's ``drive_log``)."""
    return drive_log


def test_add_query_info(tmp_path, log):
    db = tmp_path / "p.db"
    r = invoke("places", "add", db, log, "--every", "2")
    assert r.exit_code == 0, r.output
    assert "added 6 places" in r.output and "Metric" in r.output
    r = invoke("places", "add", db, log, "--every", "2", "--json")  # again: all skipped
    d = json.loads(r.stdout)
    assert d["added"] == 0 and d["skipped"] == 6 and d["total"] == 6
    r = invoke("places", "query", db, log, 5, "--top", "2", "--min-features", "5", "--json")
    assert r.exit_code == 0, r.output
    for h in json.loads(r.stdout)["hits"]:  # the simulated office has few features
        assert h["verdict"] != "accepted" or h["n_features"] >= 5
        why = h["reason"]
        assert h["verdict"] == "accepted" or "min_features=5" in why or "confidence" in why
    r = invoke("places", "query", db, log, 5, "--top", "2", "--json")  # min_features 3
    assert r.exit_code == 0, r.output
    hits = json.loads(r.stdout)["hits"]
    # the neighbouring places, with a pose; a few features in a bare office may leave
    # the confidence just under the 0.99 that accepts, which the reason then says
    assert len(hits) == 2 and hits[0]["name"] in ("drive.txt:4", "drive.txt:6")
    assert hits[0]["pose"] is not None and hits[0]["confidence"] > 0.9
    assert hits[0]["verdict"] == "accepted" or "below min_confidence" in hits[0]["reason"]
    r = invoke("places", "query", db, log, 5)
    assert r.exit_code == 0 and "Metric" in r.output and "accepted / ambiguous" in r.output
    r = invoke("places", "info", db, "--check", "--json")
    d = json.loads(r.stdout)
    assert d["places"] == 6 and d["integrity"] == ["ok"] and d["schema_version"] == 1


def test_user_errors_exit_2(tmp_path, log):
    r = invoke("places", "info", tmp_path / "missing.db")
    assert r.exit_code == 2 and "error:" in r.output and "no such place database" in r.output
    foreign = tmp_path / "foreign.db"
    con = sqlite3.connect(foreign)
    con.execute("CREATE TABLE t (x)")
    con.commit()
    con.close()
    r = invoke("places", "add", foreign, log)
    assert r.exit_code == 2 and "not a scanclique place database" in r.output
    assert "Traceback" not in r.output
    db = tmp_path / "p.db"
    invoke("places", "add", db, log, "--stop", "2")
    r = invoke("places", "query", db, log, 99)
    assert r.exit_code == 2 and "out of range" in r.output
    r = invoke("places", "add", db, log, "--paper")  # features prepared differently
    assert r.exit_code == 2 and "configuration differs" in r.output
    empty = tmp_path / "empty.log"
    empty.write_text("")
    for args in (("places", "add", tmp_path / "e.db", empty), ("loops", empty)):
        r = invoke(*args)
        assert r.exit_code == 2 and "holds no laser scans" in r.output, r.output
    assert not (tmp_path / "e.db").exists()


def test_loops(tmp_path, log):
    out = tmp_path / "loops.json"
    r = invoke("loops", log, "--min-gap", "4", "--candidates", "2", "--out", out)
    assert r.exit_code == 0, r.output
    d = json.loads(out.read_text())
    assert d["n_scans"] == 12 and d["n_pairs"] == 15
    assert all(lp["i"] - lp["j"] >= 4 for lp in d["loops"])
    r2 = invoke("loops", log, "--min-gap", "4", "--candidates", "2", "--workers", "2", "--json")
    d2 = json.loads(r2.stdout)
    assert d2["backend"] == "processes" and d2["loops"] == d["loops"]
    assert d["right"] is None or d["right"] <= d["n_accepted"]


@pytest.mark.realdata
def test_a_log_added_by_name_and_by_path_is_one_log(tmp_path, log_path):
    """``places add db intel`` and ``places add db <intel's path>`` name the places alike,
    so the second run skips them all (it used to add a second set)."""
    path = log_path("intel")
    db = tmp_path / "p.db"
    r = invoke("places", "add", db, "intel", "--every", "300", "--json")
    assert r.exit_code == 0, r.output
    first = json.loads(r.stdout)
    assert first["source"] == "intel" and first["added"] == 4
    r = invoke("places", "add", db, path, "--every", "300", "--json")
    d = json.loads(r.stdout)
    assert d["source"] == "intel" and d["added"] == 0 and d["skipped"] == 4
    assert d["total"] == 4


def test_places_added_with_a_map_give_a_query_its_pose_in_the_map(tmp_path, log):
    """``places add --map DIR`` (the ``--out`` of ``scanclique map``) gives each place its
    pose from ``DIR/trajectory.tum`` by timestamp; a query's hits then carry the query's
    pose in that map. A directory without the file, a bad file and a trajectory of
    another log are each one ``error:`` line, and no database is created."""
    from scanclique.geometry import Pose2
    from scanclique.io import read_scans, write_tum

    scans = read_scans(log)
    start = scans[0].reference.inverse()
    poses = [start @ s.reference for s in scans]  # the map: the true drive from scan 0
    out = tmp_path / "map"
    out.mkdir()
    write_tum(out / "trajectory.tum", poses, [s.timestamp for s in scans])
    db = tmp_path / "p.db"
    r = invoke("places", "add", db, log, "--every", "2", "--map", out, "--json")
    assert r.exit_code == 0, r.output
    d = json.loads(r.stdout)
    assert d["added"] == 6 and d["posed"] == 6 and d["poses"].endswith("trajectory.tum")
    assert json.loads(invoke("places", "info", db, "--json").stdout)["places_with_map_pose"] == 6
    r = invoke("places", "query", db, log, 5, "--top", "2", "--json")
    hit = json.loads(r.stdout)["hits"][0]
    m = hit["map_pose"]
    dt, dr = Pose2(m["x"], m["y"], m["theta"]).distance_to(poses[5])
    assert dt < 0.05 and dr < 0.02, (dt, dr)
    r = invoke("places", "query", db, log, 5, "--top", "2")
    assert r.exit_code == 0 and "in the map: the query's pose" in r.output
    bad = tmp_path / "bad.tum"
    bad.write_text("0 1 2 0 0 0 0 1\n1 2 3\n")
    other = tmp_path / "other.tum"
    other.write_text("1e9 0 0 0 0 0 0 1\n1000000001 1 0 0 0 0 0 1\n")
    for given, words in (
        (tmp_path, "without trajectory.tum"),
        (bad, "bad.tum:2: expected 8 numbers"),
        (other, "no scan lies within the trajectory"),
    ):
        r = invoke("places", "add", tmp_path / "q.db", log, "--map", given)
        assert r.exit_code == 2 and "error:" in r.output and words in r.output, r.output
        assert "Traceback" not in r.output
    assert not (tmp_path / "q.db").exists()


def test_locate_places_a_logs_scans_in_the_map_of_the_database(tmp_path, log):
    """``places locate DB LOG`` queries each scan and gives it the pose its first
    accepted hit gives it in the map (``--out``: a TUM trajectory of those); a database
    without map poses, and an ``--out`` in a missing directory, are one ``error:`` line."""
    from scanclique.geometry import Pose2
    from scanclique.io import read_scans, read_tum, write_tum

    scans = read_scans(log)
    start = scans[0].reference.inverse()
    truth = [start @ s.reference for s in scans]
    write_tum(tmp_path / "truth.tum", truth, [s.timestamp for s in scans])
    db = tmp_path / "p.db"
    assert (
        invoke("places", "add", db, log, "--every", "3", "--map", tmp_path / "truth.tum").exit_code
        == 0
    )
    out = tmp_path / "located.tum"
    r = invoke("places", "locate", db, log, "--start", "1", "--every", "2", "--out", out, "--json",
               "--candidates", "4")  # fmt: skip
    assert r.exit_code == 0, r.output
    d = json.loads(r.stdout)
    assert d["queried"] == 6 and d["located"] >= 4 and d["mapped_places"] == 4
    rows = read_tum(out)
    assert len(rows) == d["located"]
    for s in d["scans"]:
        if s["status"] == "located":
            p = s["pose"]
            dt, dr = Pose2(p["x"], p["y"], p["theta"]).distance_to(truth[s["index"]])
            assert dt < 0.05 and dr < 0.02, (s, dt, dr)
        else:
            assert s["pose"] is None
    r = invoke("places", "locate", db, log)
    assert r.exit_code == 0 and "located in the map" in r.output and "Metric" in r.output
    whole = tmp_path / "whole.tum"  # the log mapped on its own, carried into the map
    fig = tmp_path / "located.png"
    r = invoke("places", "locate", db, log, "--every", "2", "--trajectory", whole, "--json",
               "--plot", fig)  # fmt: skip
    assert r.exit_code == 0, r.output
    assert fig.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    d = json.loads(r.stdout)
    assert d["anchor_inliers"] >= 3 and d["anchor_rms"] < 0.05
    rows = read_tum(whole)
    assert len(rows) == len(scans)
    for (_, x, y, th), want in zip(rows, truth, strict=True):
        dt, dr = Pose2(x, y, th).distance_to(want)
        assert dt < 0.1 and dr < 0.03, (dt, dr)
    r = invoke("places", "locate", db, log, "--track", "--no-odometry", "--json", "--out", out)
    assert r.exit_code == 0, r.output
    d = json.loads(r.stdout)  # tracking places what recognition leaves, never fewer
    assert d["tracking"] is True and d["tracked"] >= 1 and d["located"] + d["tracked"] >= 10
    assert len(read_tum(out)) == d["located"] + d["tracked"]
    r = invoke("places", "locate", db, log, "--track", "--plot", tmp_path / "tracked.png")
    assert r.exit_code == 0 and "tracked (a place near where the run predicts it)" in r.output
    assert (tmp_path / "tracked.png").read_bytes()[:4] == b"\x89PNG"
    plain = tmp_path / "plain.db"
    invoke("places", "add", plain, log, "--every", "3")
    r = invoke("places", "locate", plain, log)
    assert r.exit_code == 2 and "none of its 4 places has a map pose" in r.output, r.output
    r = invoke("places", "locate", db, log, "--out", tmp_path / "no" / "x.tum")
    assert r.exit_code == 2 and "does not exist" in r.output
    r = invoke("places", "locate", db, log, "--plot", tmp_path / "figure.txt")
    assert r.exit_code == 2 and "a figure file must end in" in r.output


def test_locate_says_when_the_run_was_bent_onto_its_placed_scans(tmp_path, log, monkeypatch):
    from scanclique.geometry import Pose2
    from scanclique.places import run as prun

    def fake(path, source, **kw):
        assert kw["whole"] is True
        return prun.LocateRun(
            str(path), "fake", (0,), (0.0,), ("located",), (Pose2(0, 0, 0),), (1,), (1.0,),
            (1.0,), 1, 1, 0.1, anchor=Pose2(0, 0, 0), anchor_inliers=3, anchor_rms=0.01,
            trajectory=(Pose2(0, 0, 0),), trajectory_indices=(0,), trajectory_times=(0.0,),
            anchor_spread=1.0, run_extent=50.0, bent=True,
        )  # fmt: skip

    monkeypatch.setattr(prun, "run_locate", fake)
    db = tmp_path / "p.db"
    r = invoke("places", "locate", db, log, "--trajectory", tmp_path / "run.tum")
    assert r.exit_code == 0, r.output
    assert "the run was bent onto all of them" in r.output
    assert "small turn of the carry" not in r.output
