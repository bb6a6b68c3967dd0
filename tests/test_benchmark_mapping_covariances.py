"""The covariance benchmark's relative covariance (benchmarks/mapping_covariances.py:
_relative_covariance), from the joint marginal of two nodes of a pose graph, against the
edges that join them: the benchmark's d2 is only as honest as this."""

import math
import sys
from pathlib import Path

import numpy as np
import pytest

from scanclique.geometry import Pose2
from scanclique.uncertainty import compose_covariance

gtsam = pytest.importorskip("gtsam")

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
import mapping_covariances as bench  # noqa: E402


def test_relative_covariance_of_two_nodes_is_that_of_the_edges_between_them():
    from scanclique.mapping.backend import PoseGraph

    Z = [
        Pose2(1.0, 0.5, math.radians(90.0)),
        Pose2(2.0, -0.3, math.radians(30.0)),
        Pose2(0.7, 0.2, math.radians(-50.0)),
    ]
    P = [
        np.diag([0.01, 0.04, 0.001]),
        np.array([[0.02, 0.003, 0.001], [0.003, 0.005, 0.0], [0.001, 0.0, 0.002]]),
        np.diag([0.003, 0.002, 0.0005]),
    ]
    g = PoseGraph()
    pose = Pose2.identity()
    g.add_node(0, pose)
    for k, z in enumerate(Z):
        pose = pose @ z
        g.add_node(k + 1, pose)
    for k, (z, p) in enumerate(zip(Z, P, strict=True)):
        g.add_edge(k, k + 1, z, p)
    out = g.optimize()
    m = gtsam.Marginals(g.graph, g.result)
    # nodes 1 and 3: the two edges between them, composed
    got = bench._relative_covariance(m, 1, 3, out[1], out[3])
    np.testing.assert_allclose(got, compose_covariance(Z[1], P[1], Z[2], P[2]), atol=1e-9)
    # neighbours: their edge's own covariance
    np.testing.assert_allclose(bench._relative_covariance(m, 2, 3, out[2], out[3]), P[2], atol=1e-9)
