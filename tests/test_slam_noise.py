"""The sensor noise matched to the innovations (``SlamConfig.noise_window``): a filter
told a better sensor than it has raises its noise to what the innovations show; a filter
told the right noise keeps it."""

from __future__ import annotations

import logging
import math
from dataclasses import replace

import numpy as np
import pytest

from scanclique import slam
from scanclique.errors import ConfigError
from scanclique.slam import ekf as E
from scanclique.slam.sim import room_config, simulate_room

CFG = room_config()  # the room's true sensor: 0.15 m, 3 deg


def _pairs(rng, m, r_true, spred):
    """``m`` observations of landmarks predicted at (10 m, 0.3 rad) with the prediction
    variances ``spred`` (2,), the truth's sensor variances ``r_true`` (2,)."""
    zhat = np.tile([10.0, 0.3], (m, 1))
    z = zhat + rng.normal(0.0, np.sqrt(spred + r_true), (m, 2))
    Sz = np.diag(np.tile(spred, m))
    return z, zhat, Sz, np.arange(m)


def test_matched_noise_by_hand():
    """Innovations of a sensor four times noisier (in variance) than configured, in
    batches of 10 pairs: nothing changes before the first check (a quarter window, 50
    pairs), then the variance is matched to within sampling error; a right noise stays
    exactly as configured."""
    rng = np.random.default_rng(0)
    R0 = np.diag([0.1, math.radians(1.0)]) ** 2
    spred = np.array([0.05, math.radians(0.5)]) ** 2
    noisy = E._MatchedNoise(R0, 200, 1.5)
    right = E._MatchedNoise(R0, 200, 1.5)
    for k in range(100):
        R_noisy = noisy.add(*_pairs(rng, 10, 4.0 * np.diag(R0), spred))
        R_right = right.add(*_pairs(rng, 10, np.diag(R0), spred))
        if k < 4:  # 40 pairs: no check yet
            np.testing.assert_array_equal(R_noisy, R0)
    np.testing.assert_allclose(np.diag(R_noisy), 4.0 * np.diag(R0), rtol=0.35)
    np.testing.assert_array_equal(R_right, R0)
    assert noisy.checks == right.checks == 1000 // 50
    assert noisy.raised_checks == noisy.checks and right.raised_checks == 0


def test_matched_noise_wraps_bearings():
    """A bearing innovation across +-pi is the small angle between, not 2 pi less: a
    sensor seeing behind it does not look noisy."""
    R0 = np.diag([0.1, math.radians(1.0)]) ** 2
    mn = E._MatchedNoise(R0, 20, 1.5)
    m = 40
    z = np.column_stack([np.full(m, 5.0), np.full(m, math.pi - 0.001)])
    zhat = np.column_stack([np.full(m, 5.0), np.full(m, -math.pi + 0.001)])
    R = mn.add(z, zhat, np.diag(np.full(2 * m, 1e-6)), np.arange(m))
    np.testing.assert_array_equal(R, R0)


def test_a_filter_told_a_better_sensor_learns_its_noise(caplog):
    """The room's sensor (3 deg) given to the filter as 1.5 deg: the run ends with about
    the true bearing noise (a window's estimate: 2.3-3.5 deg over three rooms of 150 and
    300 s), the right range noise untouched, and says so."""
    run = simulate_room(4, duration=150.0, config=CFG)
    cfg = replace(CFG, sigma_bearing=math.radians(1.5))
    with caplog.at_level(logging.WARNING, logger="scanclique.slam.ekf"):
        r = slam.ekf_slam(
            run.steps, slam.Unicycle(), association="clique", config=cfg,
            initial_pose=run.poses[0],
        )  # fmt: skip
    sr, sb = r.observation_noise
    assert sr == CFG.sigma_range
    assert math.radians(1.9) < sb < math.radians(4.5)
    assert r.noise_raised >= 0.9
    assert "noisier than configured" in caplog.text and "SlamConfig.for_sensor" in caplog.text


def test_a_right_noise_is_left_alone():
    """At the true noise the innovations never ask for more."""
    run = simulate_room(4, duration=150.0, config=CFG)
    r = slam.ekf_slam(
        run.steps, slam.Unicycle(), association="nn", config=CFG, initial_pose=run.poses[0]
    )
    assert r.observation_noise == (CFG.sigma_range, CFG.sigma_bearing)
    assert r.noise_raised == 0.0


def test_without_a_window_the_noise_is_the_configured_one():
    run = simulate_room(4, duration=30.0, config=CFG)
    cfg = replace(CFG, sigma_bearing=math.radians(1.5), noise_window=None)
    r = slam.ekf_slam(
        run.steps, slam.Unicycle(), association="nn", config=cfg, initial_pose=run.poses[0]
    )
    assert r.observation_noise is None and math.isnan(r.noise_raised)


@pytest.mark.parametrize(
    "kw",
    [
        {"noise_window": 0},
        {"noise_window": -5},
        {"noise_window": 2.5},
        {"noise_window": 10**12},
        {"noise_trigger": 0.9},
        {"noise_trigger": float("nan")},
        {"noise_trigger": float("inf")},
    ],
)
def test_bad_noise_settings(kw):
    with pytest.raises(ConfigError, match=next(iter(kw))):
        slam.SlamConfig(**kw)
