"""The ring benchmark's measures (benchmarks/mapping_ring.py): the online rows' configuration
and the count of accepted loop closures that the truth says are wrong."""

import math
import sys
from pathlib import Path
from types import SimpleNamespace

import numpy as np

from scanclique.geometry import Pose2
from scanclique.mapping import MapConfig

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
import mapping_ring as bench  # noqa: E402


def test_online_rows_take_the_online_loop_settings_and_keep_the_rows_own():
    online = MapConfig.online().loops
    for name, cfg in bench.CONFIGS.items():
        got = bench.online_config(cfg)
        for k in bench.ONLINE_LOOPS:
            assert getattr(got.loops, k) == getattr(online, k), (name, k)
        # what the row changes (max_turn, max_shift, max_conflict, enabled) is kept
        for k in ("max_turn", "max_shift", "max_conflict", "enabled"):
            assert getattr(got.loops, k) == getattr(cfg.loops, k), (name, k)
    assert bench.online_config(MapConfig()) == MapConfig.online()


def _closure(i, j, pose, accepted=True, local=False):
    return SimpleNamespace(i=i, j=j, pose=pose, accepted=accepted, local=local)


def test_wrong_closures_counts_accepted_loop_closures_off_the_truth_only():
    truth = [Pose2(0.0, 0.0, 0.0), Pose2(1.0, 0.0, 0.0), Pose2(10.0, 2.0, math.pi / 2)]
    right = truth[0].inverse() @ truth[2]
    off = Pose2(right.x + 1.5, right.y, right.theta)  # 1.5 m off: a door along
    turned = Pose2(right.x, right.y, right.theta + math.radians(8.0))
    result = SimpleNamespace(
        loop_closures=[
            _closure(0, 2, right),
            _closure(0, 2, off),
            _closure(0, 2, turned),
            _closure(0, 2, off, accepted=False),  # refused: not counted
            _closure(0, 1, Pose2(5.0, 0.0, 0.0), local=True),  # a local match: not counted
        ]
    )
    assert bench.wrong_closures(result, truth) == 2
    assert bench.wrong_closures(result, truth, metres=2.0, degrees=10.0) == 0
    assert np.isclose(off.distance_to(right)[0], 1.5)
