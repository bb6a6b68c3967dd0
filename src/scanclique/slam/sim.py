"""A simulated tree park with known truth, for the filter's consistency (NEES).

The vehicle is the Victoria Park car (:class:`~scanclique.slam.Ackermann`) driving laps of
a rounded rectangle through a park of trees (points, at least ``min_spacing`` apart,
none on the track); the laser sees trees within ``max_range`` in its 180 deg field of
view with probability ``p_detect`` and range/bearing noise of the filter's
:class:`~scanclique.slam.SlamConfig` (the documented noise of the data); the logged
controls carry the model's control noise, and the true motion the config's additive slip
noise. Controls at 40 Hz and scans at 5 Hz, as in the data set.

(The project's laser-scan simulator is :mod:`scanclique.sim`; this scenario lives here,
beside the filter it tests, and may move there.)
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .ekf import SlamConfig
from .models import Ackermann, observe, wrap
from .reader import Step

__all__ = ["ParkRun", "simulate_park"]


@dataclass(frozen=True, slots=True, eq=False)
class ParkRun:
    """A simulated log and its truth.

    Attributes
    ----------
    steps : list of Step
    times : (N,) ndarray
    poses : (N, 3) ndarray
        True vehicle pose after each step.
    trees : (T, 2) ndarray
        True tree positions.
    truth : list of (k,) int64 ndarrays
        Per step with observations (scans that see nothing are left out), the tree index
        of each observation (-1: clutter).
    """

    steps: list
    times: np.ndarray
    poses: np.ndarray
    trees: np.ndarray
    truth: list


def _trees(rng, box, n, min_spacing, track, clearance):
    pts = []
    tries = 0
    while len(pts) < n and tries < 50 * n:
        tries += 1
        p = rng.uniform(box[0], box[1])
        if np.min(np.hypot(*(track - p).T)) < clearance:
            continue
        if pts and np.min(np.hypot(*(np.asarray(pts) - p).T)) < min_spacing:
            continue
        pts.append(p)
    return np.asarray(pts).reshape(-1, 2)


def simulate_park(
    seed: int = 0,
    *,
    laps: int = 2,
    length: float = 80.0,
    width: float = 50.0,
    radius: float = 10.0,
    speed: float = 3.0,
    n_trees: int = 150,
    min_spacing: float = 3.0,
    p_detect: float = 0.9,
    max_range: float = 20.0,
    clutter: int = 0,
    model: Ackermann | None = None,
    config: SlamConfig | None = None,
    control_dt: float = 0.025,
    scan_dt: float = 0.2,
) -> ParkRun:
    """Simulate laps of a tree park (see the module docstring).

    Returns
    -------
    ParkRun
        ``steps`` start at the vehicle's true initial pose ``(0, 0, 0)``.
    """
    rng = np.random.default_rng(seed)
    model = model or Ackermann()
    cfg = config or SlamConfig()
    L, H = model.wheelbase, model.encoder_offset
    alpha = math.atan(L / radius)
    ve_turn = speed * (1 - math.tan(alpha) * H / L)
    # one lap: straight, quarter turn, ... as (duration, ve, steering)
    seg = []
    t_turn = (0.5 * math.pi * radius) / speed
    for straight in (length, width, length, width):
        seg.append((straight / speed, speed, 0.0))
        seg.append((t_turn, ve_turn, alpha))
    plan = [(0.0, 0.0, 0.0)] + seg * laps
    # the true track, noise-free, to keep trees off it
    t_end = sum(p[0] for p in plan)
    n_ctrl = int(round(t_end / control_dt))
    tc = np.arange(n_ctrl) * control_dt
    edges = np.cumsum([p[0] for p in plan])
    which = np.minimum(np.searchsorted(edges, tc, side="right"), len(plan) - 1)
    u_true = np.array([[plan[w][1], plan[w][2]] for w in which])
    x = np.zeros(3)
    track = [x[:2].copy()]
    for q in range(n_ctrl):
        x, _, _ = model.predict(x, u_true[q], control_dt)
        track.append(x[:2].copy())
    track = np.asarray(track)
    lo, hi = track.min(0) - max_range, track.max(0) + max_range
    trees = _trees(rng, (lo, hi), n_trees, min_spacing, track, 3.0)
    # drive: true motion with slip, logged controls with noise, scans at scan_dt
    sx, sy = model.sensor_x, model.sensor_y
    R = cfg.R
    qadd = np.array([cfg.sigma_xy_rate**2, cfg.sigma_xy_rate**2, cfg.sigma_theta_rate**2])
    steps, times, poses, truth = [], [], [], []
    x = np.zeros(3)
    next_scan = scan_dt
    t = 0.0
    empty = np.zeros((0, 2))
    for q in range(n_ctrl):
        u = u_true[q]
        u_meas = rng.multivariate_normal(u, model.control_covariance(u)) if u[0] != 0 else u.copy()
        steps.append(Step(t, u_meas, empty))
        times.append(t)
        poses.append(x.copy())
        x, _, _ = model.predict(x, u, control_dt)
        if u[0] != 0:
            x = x + rng.normal(0.0, np.sqrt(qadd * control_dt))
            x[2] = wrap(x[2])
        t = (q + 1) * control_dt
        if t >= next_scan - 1e-9:
            next_scan += scan_dt
            z, _, _ = observe(x, trees, sx, sy)
            vis = np.flatnonzero(
                (z[:, 0] <= max_range)
                & (np.abs(z[:, 1]) <= 0.5 * cfg.sensor_fov)
                & (rng.random(len(z)) < p_detect)
            )
            zt = z[vis] + rng.multivariate_normal(np.zeros(2), R, len(vis))
            zt[:, 1] = wrap(zt[:, 1])
            ids = vis.astype(np.int64)
            if clutter:
                zc = np.column_stack(
                    [
                        rng.uniform(1.0, max_range, clutter),
                        rng.uniform(-0.5 * cfg.sensor_fov, 0.5 * cfg.sensor_fov, clutter),
                    ]
                )
                zt = np.vstack([zt, zc])
                ids = np.r_[ids, np.full(clutter, -1, np.int64)]
            if len(zt) == 0:
                continue
            order = rng.permutation(len(zt))
            steps.append(Step(t, None, zt[order]))
            times.append(t)
            poses.append(x.copy())
            truth.append(ids[order])
    return ParkRun(steps, np.asarray(times), np.asarray(poses), trees, truth)
