"""Scoring a trajectory by the benchmark's relations: ``trajectory_relation_metrics``,
``scanclique evaluate`` and ``scanclique map --relations``."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from conftest import require_log
from typer.testing import CliRunner

from scanclique import cli, datasets
from scanclique.errors import ArgumentError, ConfigError, DataNotFoundError, ParseError
from scanclique.eval import relation_rows, trajectory_relation_metrics
from scanclique.eval.relations import Relation
from scanclique.geometry import Pose2
from scanclique.io import read_scans, write_tum
from scanclique.mapping.evaluate import run_evaluate

runner = CliRunner()


def invoke(*args):
    return runner.invoke(cli.app, [str(a) for a in args])


def test_poses_between_rows_are_interpolated_and_times_outside_are_missing():
    # straight along x at 1 m/s, heading 0; rows 0.5 s apart, the last two 3 s apart
    rows = [[0.0, 0.0, 0.0, 0.0], [0.5, 0.5, 0.0, 0.0], [1.0, 1.0, 0.0, 0.0],
            [4.0, 4.0, 0.0, 0.0]]  # fmt: skip
    rels = [
        Relation(0.25, 0.75, Pose2(0.5, 0.0, 0.0)),  # both interpolated: exact
        Relation(0.0, 1.0, Pose2(0.9, 0.0, 0.0)),  # on rows: 0.1 m off
        Relation(1.0, 2.0, Pose2(1.0, 0.0, 0.0)),  # 2.0 lies in a 3 s gap: missing
        Relation(0.0, 9.0, Pose2(9.0, 0.0, 0.0)),  # after the last row: missing
    ]
    m = trajectory_relation_metrics(rows, rels)
    assert (m.all.n, m.all.missing) == (2, 2)
    assert m.all.translation_mean == pytest.approx(0.05, abs=1e-12)
    assert m.all.translation_max == pytest.approx(0.1, abs=1e-12)
    # a gap allowed: the relation at 2.0 counts (on the straight line: right)
    m = trajectory_relation_metrics(rows, rels, max_gap=5.0)
    assert (m.all.n, m.all.missing) == (3, 1)


def test_rows_in_any_order_and_a_clock_going_back():
    # trajectory.tum keeps a log's order where its clock goes back: rows 0, 2, 1, 3
    rows = np.array([[0.0, 0.0, 0.0, 0.0], [2.0, 2.0, 0.0, 0.0], [1.0, 1.1, 0.0, 0.0],
                     [3.0, 3.0, 0.0, 0.0]])  # fmt: skip
    rels = [Relation(0.0, 1.0, Pose2(1.0, 0.0, 0.0)), Relation(1.0, 3.0, Pose2(2.0, 0.0, 0.0))]
    m = trajectory_relation_metrics(rows, rels)
    assert m.all.n == 2 and m.all.translation_mean == pytest.approx(0.1, abs=1e-12)
    assert trajectory_relation_metrics(rows[::-1], rels).to_dict() == m.to_dict()


def test_the_mounting_moves_the_relations_into_the_robot_frame():
    # the laser 0.5 m ahead of the robot's centre; the robot turns a quarter on the spot:
    # the laser moves, the robot's centre does not
    m = Pose2(-0.5, 0.0, 0.0)  # the robot's frame in the laser's
    laser = [Pose2(0.5, 0.0, 0.0), Pose2(0.0, 0.5, math.pi / 2)]
    rows = [[float(t), p.x, p.y, p.theta] for t, p in enumerate(laser)]
    rel = [Relation(0.0, 1.0, Pose2(0.0, 0.0, math.pi / 2))]
    assert trajectory_relation_metrics(rows, rel, mounting=m).all.translation_mean < 1e-12
    assert trajectory_relation_metrics(rows, rel).all.translation_mean > 0.7


def test_a_trajectory_of_another_clock_or_shape_is_refused():
    rels = [Relation(100.0, 101.0, Pose2(1.0, 0.0, 0.0))]
    with pytest.raises(ArgumentError, match="no relation's time lies within the trajectory"):
        trajectory_relation_metrics([[0.0, 0, 0, 0], [1.0, 1, 0, 0]], rels)
    with pytest.raises(ArgumentError, match="rows time x y theta"):
        trajectory_relation_metrics([[0.0, 0.0, 0.0]], rels)


def test_rows_of_the_table_and_of_nothing_scored():
    rels = [Relation(0.0, 20.0, Pose2(1.0, 0.0, 0.0))]
    m = trajectory_relation_metrics([[0.0, 0, 0, 0], [20.0, 1.2, 0, 0]], rels, max_gap=30.0)
    rows = dict((k, v) for k, v, _ in relation_rows(m.to_dict()))
    assert rows["relation error (translation)"] == "0.2000 ± 0.0000"
    assert rows["relations <= 10 s"] == "0" and rows["  their error (<= 10 s)"] == "n/a"
    assert rows["relations > 10 s"] == "1"


def _files(tmp_path):
    traj = tmp_path / "t.tum"
    write_tum(traj, [Pose2(0.0, 0.0, 0.0), Pose2(1.05, 0.0, 0.0)], [10.0, 11.0])
    rels = tmp_path / "a.relations"
    rels.write_text("10.0 11.0 1.0 0 0 0 0 0\n")
    return traj, rels


def test_evaluate_command_table_and_json(tmp_path):
    traj, rels = _files(tmp_path)
    r = invoke("evaluate", traj, rels)
    assert r.exit_code == 0, r.output
    assert "0.0500 ± 0.0000" in r.stdout and "the trajectory's (none)" in r.stdout
    r = invoke("evaluate", traj, rels, "--json", "--mounting", "0.5,0,0")
    assert r.exit_code == 0, r.output
    out = json.loads(r.stdout)
    assert out["mounting"] == [0.5, 0.0, 0.0] and out["mounting_source"] == "given"
    assert out["metrics"]["all"]["translation_mean"] == pytest.approx(0.05, abs=1e-9)


@pytest.mark.parametrize(
    ("args", "expected"),
    [
        (("--mounting", "0.5,0"), "--mounting expects three finite numbers"),
        (("--mounting", "a,b,c"), "--mounting expects three finite numbers"),
        (("--mounting", "nan,0,0"), "--mounting expects three finite numbers"),
        (("--mounting", "1_0,0,0"), "--mounting expects three finite numbers"),
    ],
)
def test_evaluate_bad_mounting(tmp_path, args, expected):
    traj, rels = _files(tmp_path)
    r = invoke("evaluate", traj, rels, *args)
    assert r.exit_code == 2 and expected in r.stderr and "Traceback" not in r.output


def test_evaluate_bad_inputs_are_named(tmp_path):
    traj, rels = _files(tmp_path)
    with pytest.raises(DataNotFoundError, match="neither a relations file nor a registered"):
        run_evaluate(traj, tmp_path / "none.relations")
    bad = tmp_path / "bad.relations"
    bad.write_text("10.0 11.0 1.0 0 0 0 0\n")
    with pytest.raises(ParseError, match="bad.relations:1"):
        run_evaluate(traj, bad)
    r = invoke("evaluate", tmp_path / "missing.tum", rels)
    assert r.exit_code == 2 and "missing.tum" in r.stderr
    other = tmp_path / "other.relations"
    other.write_text("500.0 501.0 1.0 0 0 0 0 0\n")
    r = invoke("evaluate", traj, other)
    assert r.exit_code == 2 and "another log or clock" in r.stderr


@pytest.mark.parametrize(
    "kw, what",
    [
        ({"short_seconds": "x"}, "run_evaluate: short_seconds must be a positive number"),
        ({"short_seconds": math.nan}, "run_evaluate: short_seconds must be a positive number"),
        ({"short_seconds": -1.0}, "run_evaluate: short_seconds must be a positive number"),
        ({"mounting": (0.1, 0.0, 0.0)}, "mounting must be a Pose2"),
        ({"relations": None}, "relations must be a file path"),
        ({"relations": 5}, "relations must be a file path"),
        ({"trajectory": None}, "trajectory must be a file path"),
    ],
)
def test_run_evaluate_names_an_argument_of_the_wrong_kind(tmp_path, kw, what):
    """Found by fuzzing (session 46): these escaped as numpy's, pathlib's and Pose2's own
    TypeError and AttributeError."""
    traj, rels = _files(tmp_path)
    args = {"trajectory": traj, "relations": rels, **kw}
    with pytest.raises(ConfigError if "short" in what else ArgumentError, match=what):
        run_evaluate(args.pop("trajectory"), args.pop("relations"), **args)


def test_map_reports_the_relations_it_is_given(drive_log, tmp_path):
    scans = read_scans(drive_log)
    rels = tmp_path / "drive.relations"
    lines = []
    for a, b in ((0, 3), (2, 7), (5, 11)):
        d = scans[a].reference.inverse() @ scans[b].reference
        lines.append(f"{scans[a].timestamp} {scans[b].timestamp} {d.x} {d.y} 0 0 0 {d.theta}")
    rels.write_text("\n".join(lines) + "\n")
    r = invoke("map", drive_log, "--out", tmp_path / "run", "--relations", rels, "--json")
    assert r.exit_code == 0, r.output
    metrics = json.loads(r.stdout)["metrics"]
    assert metrics["relations"] == str(rels) and metrics["all"]["n"] == 3
    assert metrics["all"]["translation_mean"] < 0.05
    # the same figure from the trajectory it wrote
    run = run_evaluate(tmp_path / "run" / "trajectory.tum", rels)
    assert run.metrics["all"]["translation_mean"] == pytest.approx(
        metrics["all"]["translation_mean"], abs=1e-5
    )
    bad = tmp_path / "bad.relations"
    bad.write_text("0 1 2\n")
    r = invoke("map", drive_log, "--out", tmp_path / "run2", "--relations", bad)
    assert r.exit_code == 2 and "bad.relations:1" in r.stderr


@pytest.mark.realdata
def test_a_registered_log_is_scored_in_its_robot_frame(tmp_path):
    require_log("fr079-raw")
    scans = datasets.load_log("fr079-raw", laser="main")[:300]
    traj = tmp_path / "odo.tum"
    write_tum(traj, [s.reference for s in scans], [s.timestamp for s in scans])
    run = run_evaluate(traj, "fr079")  # the laser's odometry poses, 0.04 m behind
    assert run.mounting is not None and run.mounting.x == pytest.approx(0.04, abs=1e-3)
    assert run.mounting_source == "fr079's laser lines"
    assert run.metrics["all"]["n"] > 0 and run.metrics["all"]["missing"] > 0
    assert datasets.log_relations("fr079") == datasets.log_relations("fr079-raw")
    assert datasets.log_relations("csail") is None
