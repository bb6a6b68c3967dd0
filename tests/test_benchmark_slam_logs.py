"""The SLAM benchmark's landmark-log section (benchmarks/slam.py --logs): every method on
one's own logs, side by side against their truth."""

import json
import sys
from pathlib import Path

import numpy as np
import pytest

from scanclique import slam
from scanclique.slam.outputs import write_landmark_log
from scanclique.slam.run import run_slam
from scanclique.slam.sim import room_config, simulate_room

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
import slam as bench  # noqa: E402


def test_the_logs_section_runs_each_method_against_the_truth(tmp_path):
    run = simulate_room(3, duration=40.0, config=room_config())
    log = write_landmark_log(
        tmp_path / "room3",
        run.steps,
        model=slam.Unicycle(),
        truth=np.column_stack([run.times, run.poses]),
        landmarks=run.landmarks,
    )
    out = tmp_path / "bench"
    bench.main(
        ["--logs", str(log), "--methods", "nn,clique", "--sections", "", "--no-smooth",
         "--out", str(out)]
    )  # fmt: skip
    result = json.loads(out.with_suffix(".json").read_text())
    runs = result["landmark_logs"]
    assert [r["method"] for r in runs] == ["nn", "clique"]
    assert result["victoria_park"] == [] and result["room"] == {}
    direct = run_slam(log, association="clique")
    got = runs[1]["metrics"]["pose RMSE (start alignment)"]
    assert got == pytest.approx(direct.truth.rmse_start)
    md = out.with_suffix(".md").read_text()
    assert "| room3 | clique | " in md
    ratio = got / runs[0]["metrics"]["pose RMSE (start alignment)"]
    assert f"pose RMSE (start alignment) clique / best of nn = {ratio:.3f}" in md


def test_log_table_without_truth_leaves_the_cells_empty():
    rows, ratios = bench.log_table(
        [{"log": "/x/a", "method": "nn", "metrics": {"landmarks": 3}},
         {"log": "/x/a", "method": "clique", "metrics": {"landmarks": 4}}]
    )  # fmt: skip
    assert rows[2].startswith("| a | nn | ") and ratios == []


def test_the_logs_section_needs_logs():
    with pytest.raises(SystemExit):
        bench.main(["--sections", "logs"])
