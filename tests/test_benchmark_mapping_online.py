"""The online benchmark's measures (benchmarks/mapping_online.py): the lag behind a log
replayed at its rate, and the relation errors of what was known when a relation's later
scan came (each relation's two scans in the same estimate)."""

import math
import sys
from pathlib import Path

import numpy as np
import pytest

from scanclique.eval.relations import Relation
from scanclique.geometry import Pose2

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
import mapping_online as bench  # noqa: E402


def test_lag_catches_up_only_when_the_mapper_is_faster_than_the_scans():
    ts = np.arange(6) * 0.1
    np.testing.assert_allclose(bench.lag(ts, np.full(6, 0.05)), 0.05)  # keeps up
    slow = bench.lag(ts, np.full(6, 0.15))  # falls behind 0.05 s a scan
    np.testing.assert_allclose(slow, 0.15 + 0.05 * np.arange(6))
    spike = bench.lag(ts, np.array([0.01, 0.35, 0.01, 0.01, 0.01, 0.01]))
    np.testing.assert_allclose(spike, [0.01, 0.35, 0.26, 0.17, 0.08, 0.01])


class _Mapper:
    """Stands in for an OnlineMapper: poses of the truth, the newest ``shift`` m off in x
    (the later scan placed wrong) or every scan seen after ``moved_from`` shifted alike
    (the whole estimate moved: a relation's two scans still agree)."""

    def __init__(self, truth, shift=0.0, moved_from=None):
        self.truth, self.shift, self.moved_from, self.n = truth, shift, moved_from, 0

    def pose(self, k):
        p = self.truth[k]
        moved = self.moved_from is not None and self.n > self.moved_from
        off = self.shift if (k == self.n - 1 or moved) else 0.0
        return Pose2(p.x + off, p.y, p.theta)


@pytest.mark.parametrize("shift, moved_from, expected", [(0.0, None, 0.0), (0.1, None, 0.1),
                                                         (0.3, 1, None)])  # fmt: skip
def test_known_then_compares_a_relation_within_one_estimate(shift, moved_from, expected):
    truth = [Pose2(0.5 * k, 0.1 * k, 0.05 * k) for k in range(6)]
    ts = [float(k) for k in range(6)]
    rels = [Relation(ts[a], ts[b], truth[a].inverse() @ truth[b]) for a, b in
            ((0, 1), (1, 2), (0, 5), (3, 4))]  # fmt: skip
    watch, errors = bench.known_then(rels, ts, None)
    m = _Mapper(truth, shift, moved_from)
    for j in range(6):
        m.n = j + 1
        watch(m, j)
    e = errors()
    if expected is None:  # the estimate moved as a whole: both ends alike, no error
        assert e["all_m"] == pytest.approx(0.0, abs=1e-12)
    else:
        assert e["all_m"] == pytest.approx(expected, abs=1e-9)
        assert e["short_m"] == pytest.approx(expected, abs=1e-9)
    assert math.isnan(e["long_m"])  # no relation spans more than 10 s
