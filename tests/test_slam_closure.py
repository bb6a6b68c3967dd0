"""Closure support (``AssociationConfig.closure_crowding``): a pair whose gate is crowded
(a loop closure after a long drift) is kept only with the support of other such pairs."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from scanclique import slam
from scanclique.errors import ConfigError
from scanclique.slam import association as A
from scanclique.slam.models import observe

METHODS = ("nn", "jcbb", "clique", "clique-jcbb")
R = np.diag([0.1, math.radians(0.5)]) ** 2
DEFAULT = A.AssociationConfig().closure_crowding


def _grid(spacing=6.0):
    """A park of trees on a jittered grid ahead of the vehicle."""
    rng = np.random.default_rng(4)
    g = np.array([(x, y) for x in range(2, 6) for y in range(-2, 3)], float) * spacing
    return g + rng.uniform(-1.0, 1.0, g.shape)


def _associate(lm, seen, pose_sigma, method, crowding, shift=(0.0, 0.0)):
    """Observe landmarks ``seen`` from a vehicle at the origin whose estimate is
    ``shift`` off, with ``pose_sigma`` (m) of uncertainty and a well-known map."""
    z, _, _ = observe(np.zeros(3), lm[seen])
    pose = np.array([shift[0], shift[1], 0.0])
    pose_cov = np.diag([pose_sigma**2, pose_sigma**2, math.radians(0.5) ** 2])
    map_cov = np.tile(np.eye(2) * 0.05**2, (len(lm), 1, 1))
    cfg = replace(A.AssociationConfig(), closure_crowding=crowding)
    return A.associate(z, R, lm, map_cov, pose, pose_cov, method, config=cfg)


def test_gate_crowding_by_hand():
    lm = np.array([[10.0, 0.0], [10.0, 4.0], [16.0, 0.0]])
    z, _, _ = observe(np.zeros(3), lm[[0]])
    P = np.zeros((9, 9))
    P[:3, :3] = np.diag([0.5**2, 0.5**2, 0.01**2])
    pred = A.predict_map(np.r_[0.0, 0.0, 0.0, lm.reshape(-1)], P, slam.Unicycle())
    got = A.gate_crowding(z, pred, [[0, 0]], 0.99)
    # by hand: nearest-neighbour distances 4, 4, 6 -> median 4
    density = math.log(2) / (math.pi * 16.0)
    # the drift alone (the sensor noise left out), 10 m straight ahead: range sigma 0.5 m
    # (x), across it 0.5 m (y) and 10 m x 0.01 rad (heading)
    sd_across = math.hypot(0.5, 10 * 0.01)
    area = math.pi * A.chi2_bound(2, 0.99) * 0.5 * sd_across
    assert got[0] == pytest.approx(density * area, rel=1e-9)
    # a map of one landmark has no spacing to compare with
    pred1 = A.predict_map(np.r_[0.0, 0.0, 0.0, lm[0]], P[:5, :5], slam.Unicycle())
    assert A.gate_crowding(z, pred1, [[0, 0]], 0.99)[0] == 0.0


@pytest.mark.parametrize("method", METHODS)
def test_a_lone_closure_is_refused(method):
    lm = _grid()
    seen = [7]
    off = _associate(lm, seen, 2.0, method, None, shift=(1.5, -1.0))
    # paired without the rule: a single tree in a gate of metres, not always the right one
    assert off.n_pairs == 1
    on = _associate(lm, seen, 2.0, method, DEFAULT, shift=(1.5, -1.0))
    # unpaired, and it starts no landmark (too close to one to be another)
    assert on.landmarks.tolist() == [A.REJECTED]
    assert on.n_pairs == 0


@pytest.mark.parametrize("method", METHODS)
def test_supported_closures_are_kept(method):
    lm = _grid()
    seen = [6, 7, 12, 13]
    on = _associate(lm, seen, 2.0, method, DEFAULT, shift=(1.5, -1.0))
    assert on.landmarks.tolist() == seen


def _crowding(lm, j, pose_sigma):
    """:func:`gate_crowding` of landmark ``j`` seen from the origin."""
    z, _, _ = observe(np.zeros(3), lm[[j]])
    var = np.r_[pose_sigma**2, pose_sigma**2, math.radians(0.5) ** 2, np.full(2 * len(lm), 0.05**2)]
    pred = A.predict_map(np.r_[0.0, 0.0, 0.0, lm.reshape(-1)], np.diag(var), slam.Unicycle())
    return A.gate_crowding(z, pred, [[0, j]], 0.99)[0]


@pytest.mark.parametrize("method", METHODS)
def test_a_well_known_landmark_needs_no_support(method):
    lm = _grid()
    assert _crowding(lm, 7, 0.05) < DEFAULT < _crowding(lm, 7, 2.0)
    on = _associate(lm, [7], 0.05, method, DEFAULT)
    assert on.landmarks.tolist() == [7]


def test_the_wrong_closure_of_a_simulated_park_is_refused():
    """Park 3 of the simulator: without the rule the clique closes the loop on a
    neighbouring tree and the filter diverges (ANEES 241, session 23); with it the run
    stays consistent."""
    from scanclique.slam.metrics import nees
    from scanclique.slam.sim import simulate_park

    cfg = slam.SlamConfig()  # the rule is on by default
    run = simulate_park(3, config=cfg, max_range=cfg.max_range or 20.0)
    r = slam.ekf_slam(run.steps, slam.Ackermann(), association="clique", config=cfg)
    e = r.poses - run.poses
    e[:, 2] = slam.wrap(e[:, 2])
    mask = np.array([s.n_observations > 0 for s in run.steps])
    assert float(nees(e, r.pose_covariances)[mask].mean()) < 10.0


@pytest.mark.parametrize(
    "kw", [{"closure_crowding": -0.1}, {"closure_crowding": math.nan}, {"closure_support": 0}]
)
def test_bad_closure_settings(kw):
    with pytest.raises(ConfigError, match=next(iter(kw))):
        A.AssociationConfig(**kw)
