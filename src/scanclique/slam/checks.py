"""Plausibility checks of an EKF-SLAM log before the filter runs: what a log adapted from
another data set gets wrong without an error of its own (units, conventions), found from
the log itself and said in a warning.

* :func:`far_between`: how far the controls carry the vehicle between consecutive
  observations (times in milliseconds carry it kilometres);
* :func:`bearing_turns`: whether the observations' bearings turn as the controls turn the
  vehicle (counter-clockwise bearings, as :class:`~scanclique.slam.Step` says) or the
  other way (a sensor's clockwise bearings, or a mirrored mounting).
"""

from __future__ import annotations

import itertools
import math

import numpy as np

from .models import MotionModel, inverse_observe, observe, wrap

__all__ = ["far_between", "bearing_turns", "mirrored"]


def far_between(held, dts, obs_steps) -> float:
    """The median distance (m) the vehicle travels between consecutive observations, by
    its first control (the speed) integrated over the steps' times, over the intervals in
    which it moves (0 when it never does, or with fewer than 3 observation steps).

    ``held``, ``dts``: :func:`~scanclique.slam.ekf.held_controls`'s; ``obs_steps``: the
    indices of the steps with observations."""
    if len(obs_steps) < 3:
        return 0.0
    run = np.concatenate([[0.0], np.cumsum(np.nan_to_num(np.abs(held[:, 0])) * dts)])
    gaps = np.diff(run[np.asarray(obs_steps) + 1])
    gaps = gaps[gaps > 0]
    return float(np.median(gaps)) if len(gaps) else 0.0


def bearing_turns(
    steps,
    model: MotionModel,
    sigmas: tuple[float, float],
    max_range: float | None,
    *,
    frames: int = 200,
    max_steps: int = 200_000,
) -> tuple[int, int]:
    """How many observations of a frame an earlier frame's explain, carried by the controls
    through a turn, with the bearings as given and mirrored: ``(as given, mirrored)``, over
    up to ``frames`` pairs of observation frames.

    Each pair is an anchor frame and the first later frame by which the controls have
    turned the vehicle (``model``'s noise-free prediction) by more than the bearing
    tolerance, before they carry it a third of ``max_range`` (10 m without one) from the
    anchor (then the later frame becomes the anchor). The anchor's observations are
    carried to the later frame once with the bearings as given (counter-clockwise) and
    once mirrored (clockwise), and an observation of the later frame counts when one
    carried observation lies within 3 ``sigmas`` (range m, bearing rad) of it. Only a
    turn tells the two apart: a mirrored world drives straight the same way. Bearings
    as :class:`~scanclique.slam.Step` says give far more of the first count, mirrored
    ones the reverse (:func:`mirrored`). It reads at most ``max_steps`` steps (the
    prediction is Python's: about 2 s)."""
    tol_r, tol_b = 3.0 * sigmas[0], 3.0 * sigmas[1]
    reach = (max_range if max_range is not None else 30.0) / 3.0
    sx, sy = model.sensor_x, model.sensor_y
    pose = np.zeros(3)
    control = None
    anchor = None  # (pose, observations) of the anchor frame
    counts = np.zeros(2, np.int64)
    used = 0
    t_prev = None
    for s in itertools.islice(steps, max_steps):
        if t_prev is not None and control is not None and s.time > t_prev:
            pose = model.predict(pose, control, s.time - t_prev)[0]
        t_prev = s.time
        if s.control is not None:
            control = s.control
        if not s.n_observations:
            continue
        z = s.observations
        if anchor is not None and math.hypot(*(pose[:2] - anchor[0][:2])) > reach:
            anchor = None
        if anchor is None:
            anchor = (pose.copy(), z)
            continue
        if abs(wrap(pose[2] - anchor[0][2])) <= tol_b:
            continue
        for h, sign in enumerate((1.0, -1.0)):
            world = inverse_observe(anchor[0], anchor[1] * (1.0, sign), sx, sy)[0]
            carried = observe(pose, world, sx, sy)[0]
            z1 = z * (1.0, sign)
            near = (np.abs(z1[:, None, 0] - carried[None, :, 0]) <= tol_r) & (
                np.abs(wrap(z1[:, None, 1] - carried[None, :, 1])) <= tol_b
            )
            counts[h] += int(near.any(axis=1).sum())
        used += 1
        if used >= frames:
            break
        anchor = (pose.copy(), z)
    return int(counts[0]), int(counts[1])


def mirrored(counts: tuple[int, int], least: int = 30) -> bool:
    """Whether :func:`bearing_turns`'s counts say the bearings turn the wrong way: the
    mirrored bearings explain at least ``least`` observations and more than twice as many
    as the bearings as given."""
    given, mirror = counts
    return mirror >= least and mirror > 2 * given
