"""The filter's additive process noise (slip) per second, per metre travelled and per
radian turned: one definition (:attr:`SlamConfig.slip`, :func:`slip_variance`) used by the
compiled and the Python prediction alike."""

from __future__ import annotations

import math

import numpy as np
import pytest

from scanclique import slam
from scanclique.slam.ekf import slip_variance

QUIET = slam.Unicycle(sigma_v=0.0, sigma_v_rel=0.0, sigma_omega=0.0)


def _drive(control, seconds, rate=20.0):
    """Steps of a constant control at ``rate`` Hz for ``seconds``, no observations."""
    n = int(round(seconds * rate))
    u = np.asarray(control, float)
    return [slam.Step(k / rate, u, np.zeros((0, 2))) for k in range(n + 1)]


def _final_cov(steps, cfg, model=QUIET):
    r = slam.ekf_slam(steps, model, association="nn", config=cfg)
    return r.pose_covariances[-1]


def test_slip_variance_adds_the_three_forms():
    cfg = slam.SlamConfig(
        sigma_xy_rate=0.1, sigma_theta_rate=0.01, sigma_xy_distance=0.2,
        sigma_theta_distance=0.03, sigma_theta_turn=0.05,
    )  # fmt: skip
    q = slip_variance(cfg.slip, (1.0, 1.0, 3.0), (4.0, 5.0, -2.9), 2.0)
    turn = 2 * math.pi - 5.9  # the heading change, wrapped
    xy = 0.1**2 * 2 + 0.2**2 * 5
    np.testing.assert_allclose(q, [xy, xy, 0.01**2 * 2 + 0.03**2 * 5 + 0.05**2 * turn])
    none = dict(sigma_xy_distance=0.0, sigma_theta_distance=0.0, sigma_theta_turn=0.0)
    assert not slam.SlamConfig(**none).slip.any()


@pytest.mark.parametrize("speed_scale_sigma", [None, 0.0])  # compiled, Python prediction
def test_distance_slip_follows_the_path_not_the_clock(speed_scale_sigma):
    """10 m at 1 m/s and at 0.5 m/s: the same variance with slip per metre, twice as
    much for the slow drive with slip per second."""
    per_m = slam.SlamConfig(
        sigma_xy_distance=0.1, sigma_theta_distance=0.0, sigma_theta_turn=0.0,
        speed_scale_sigma=speed_scale_sigma, initial_sigma=(0.0, 0.0, 0.0),
    )  # fmt: skip
    fast = _final_cov(_drive((1.0, 0.0), 10.0), per_m)
    slow = _final_cov(_drive((0.5, 0.0), 20.0), per_m)
    np.testing.assert_allclose(np.diag(fast)[:2], [0.1, 0.1], rtol=1e-9)
    np.testing.assert_allclose(fast, slow, rtol=1e-9, atol=1e-15)
    per_s = slam.SlamConfig(
        sigma_xy_rate=0.1, sigma_xy_distance=0.0, sigma_theta_distance=0.0,
        sigma_theta_turn=0.0, speed_scale_sigma=speed_scale_sigma,
        initial_sigma=(0.0, 0.0, 0.0),
    )  # fmt: skip
    fast = _final_cov(_drive((1.0, 0.0), 10.0), per_s)
    slow = _final_cov(_drive((0.5, 0.0), 20.0), per_s)
    np.testing.assert_allclose(np.diag(slow)[:2], 2 * np.diag(fast)[:2], rtol=1e-9)


@pytest.mark.parametrize("speed_scale_sigma", [None, 0.0])
def test_turn_slip_follows_the_angle_turned(speed_scale_sigma):
    """A unicycle turning on the spot, one turn at 1 rad/s and at 0.5 rad/s: heading
    variance sigma_theta_turn**2 * 2 pi both times, and nothing in x and y."""
    cfg = slam.SlamConfig(
        sigma_xy_distance=0.0, sigma_theta_distance=0.0, sigma_theta_turn=0.02,
        speed_scale_sigma=speed_scale_sigma, initial_sigma=(0.0, 0.0, 0.0),
    )  # fmt: skip
    for w in (1.0, 0.5):
        P = _final_cov(_drive((0.0, w), 2 * math.pi / w, rate=50.0), cfg)
        assert P[2, 2] == pytest.approx(0.02**2 * 2 * math.pi, rel=1e-2)
        assert abs(P[0, 0]) < 1e-20 and abs(P[1, 1]) < 1e-20


def test_compiled_and_python_predictions_agree_with_every_form():
    """The car on a curve, all three forms and control noise: the compiled prediction
    (no calibration state) and the Python one (a speed-scale state with no prior) give
    the same pose covariance."""
    cfg = dict(
        sigma_xy_rate=0.05, sigma_theta_rate=0.01, sigma_xy_distance=0.03,
        sigma_theta_distance=0.004, sigma_theta_turn=0.02,
    )  # fmt: skip
    steps = _drive((3.0, 0.1), 15.0)
    a = _final_cov(steps, slam.SlamConfig(speed_scale_sigma=None, **cfg), slam.Ackermann())
    b = _final_cov(steps, slam.SlamConfig(speed_scale_sigma=0.0, **cfg), slam.Ackermann())
    np.testing.assert_allclose(a, b, rtol=1e-9)
    only_t = dict(sigma_xy_distance=0.0, sigma_theta_distance=0.0, sigma_theta_turn=0.0)
    c = _final_cov(
        steps, slam.SlamConfig(speed_scale_sigma=None, **{**cfg, **only_t}), slam.Ackermann()
    )
    assert a[2, 2] > c[2, 2]  # the per-metre and per-radian forms add to the heading's


def test_simulated_truth_slips_per_metre():
    """The simulator draws the true slip from the same definition: with slip per metre
    in x and y only (the heading, hence the path, untouched), the truth's departure from
    the slip-free drive is exactly proportional to ``sigma_xy_distance``, and its spread
    after a lap matches ``sigma_xy_distance**2`` per metre travelled."""
    from scanclique.slam.sim import simulate_park

    def truth(sigma):
        cfg = slam.SlamConfig(
            sigma_xy_distance=sigma, sigma_theta_distance=0.0, sigma_theta_turn=0.0
        )
        run = simulate_park(
            3, laps=1, length=40.0, width=20.0, n_trees=30, p_detect=0.0, config=cfg
        )
        return run.poses  # no detections: every draw but the slip is the same for each sigma

    free, one, two = truth(0.0), truth(0.05), truth(0.1)
    d1, d2 = one - free, two - free
    assert np.abs(d1[:, :2]).max() > 0.05 and not d1[:, 2].any()
    np.testing.assert_allclose(d2, 2 * d1, atol=1e-9)
    # per-step increments of d1 are N(0, 0.05**2 * step length) per axis
    step = np.hypot(*np.diff(free[:, :2], axis=0).T)
    inc = np.diff(d1[:, :2], axis=0)[step > 0] / np.sqrt(step[step > 0])[:, None]
    assert np.std(inc) == pytest.approx(0.05, rel=0.05)


def test_default_slip_is_per_metre_and_per_radian():
    """The defaults carry over between vehicles: the same path at half the speed gets the
    same covariance, and a turn on the spot adds heading noise only."""
    cfg = slam.SlamConfig(speed_scale_sigma=None, initial_sigma=(0.0, 0.0, 0.0))
    assert cfg.sigma_xy_rate == cfg.sigma_theta_rate == 0.0
    fast = _final_cov(_drive((1.0, 0.0), 10.0), cfg)
    slow = _final_cov(_drive((0.5, 0.0), 20.0), cfg)
    # the same up to the steps' discretisation (heading noise enters y step by step)
    np.testing.assert_allclose(fast, slow, rtol=1e-2, atol=1e-12)
    assert fast[1, 1] > 10 * cfg.sigma_xy_distance**2  # the heading's share is there
    spin = _final_cov(_drive((0.0, 1.0), 2 * math.pi, rate=50.0), cfg)
    assert spin[2, 2] == pytest.approx(cfg.sigma_theta_turn**2 * 2 * math.pi, rel=1e-2)
