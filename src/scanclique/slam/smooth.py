"""Batch smoothing after the filter: a pose graph with landmarks, with the filter's associations.

The EKF fixes each pose once, from the past only, and linearises each update once. This
optional pass (``smooth=True`` of :func:`~scanclique.slam.run.run_slam`, ``--smooth`` of the
CLI) re-estimates every observation step's pose and every final landmark together, by
nonlinear least squares (GTSAM, Levenberg-Marquardt):

- one variable per observation step: the *sensor's* world pose (``Pose2``), so that
  GTSAM's range-bearing factors, measured from a pose's origin, apply directly;
- a prior on the first step's pose: the filter's initial pose and ``initial_sigma``
  (moved to the first observation by the controls, as in the filter);
- between consecutive observation steps, an odometry factor: the controls (corrected by
  the filter's final estimates of its calibration states, the speed's scale and the
  second control's bias, when it had them) integrated with the motion model from the
  identity, with the filter's control and additive process noise
  propagated alongside (the same noise model as the filter's prediction), moved to the
  sensor frame through the adjoint of the sensor's mounting;
- per observation that the filter paired with a landmark of the final map (or that
  started one), a range-bearing factor with the filter's ``R``.

The associations are the filter's, whichever method chose them; nothing is re-associated.
The result is reported beside the filter's, never in its place.

References
----------
F. Dellaert and M. Kaess, "Square Root SAM", IJRR 25(12), 2006 (smoothing and mapping as
sparse least squares). Bailey et al., ICRA 2000, section 2 (the associations).
"""

from __future__ import annotations

import logging
import math
import time
from dataclasses import dataclass

import numpy as np

from ..config import require_config, require_count
from ..errors import ArgumentError, StepError, solving
from .association import NEW
from .ekf import SlamConfig, SlamResult, held_controls, slip_variance
from .models import require_model

__all__ = ["SmoothResult", "smooth"]

log = logging.getLogger(__name__)

# a floor under the odometry covariance (0.1 mm, 0.1 mrad squared): at rest the filter's
# prediction adds no noise, and a singular factor would make the graph ill-posed
_FLOOR = 1e-8 * np.eye(3)


@dataclass(frozen=True, slots=True, eq=False)
class SmoothResult:
    """The smoothed trajectory and map.

    Attributes
    ----------
    times : (S,) ndarray
        Times of the observation steps (s).
    poses : (S, 3) ndarray
        Smoothed vehicle poses ``(x, y, theta)`` at those times (world frame, rad).
    landmarks : (n, 2) ndarray
        Smoothed final landmarks, in the order of the filter's ``landmark_ids``.
    landmark_ids : (n,) int64 ndarray
    factors : int
        Range-bearing factors used.
    initial_error, final_error : float
        The graph's error (half the sum of squared whitened residuals) before and after.
    seconds, cpu_seconds : float
        Wall and CPU time of the pass (integration, graph, optimisation).
    """

    times: np.ndarray
    poses: np.ndarray
    landmarks: np.ndarray
    landmark_ids: np.ndarray
    factors: int
    initial_error: float
    final_error: float
    seconds: float
    cpu_seconds: float


def _odometry(model, held, dts, a, b, slip):
    """Controls ``held[a:b]`` over ``dts[a:b]`` integrated from the identity: the end pose
    ``(x, y, theta)`` in the start frame and its covariance (3, 3), propagated as the
    filter's prediction does (control noise through G, additive noise while moving)."""
    x = np.zeros(3)
    P = np.zeros((3, 3))
    for k in range(a, b):
        if dts[k] > 0 and not np.isnan(held[k, 0]):
            u = held[k]
            x_was = x
            x, F, G = model.predict(x, u, dts[k])
            P = F @ P @ F.T + G @ model.control_covariance(u) @ G.T
            if model.moving(u):
                P[np.diag_indices(3)] += slip_variance(slip, x_was, x, dts[k])
    return x, P


def _landmark_of_new(result: SlamResult) -> list[np.ndarray]:
    """Per observation step: the landmark id of each observation, with the observations
    that started a landmark (``NEW``) given the id the filter assigned (ids are handed out
    in order of creation: step by step, observation by observation)."""
    out = []
    nxt = 0
    for a in result.associations:
        a = np.array(a, np.int64)
        for i in np.flatnonzero(a == NEW):
            a[i] = nxt
            nxt += 1
        out.append(a)
    return out


def smooth(
    steps,
    model,
    result: SlamResult,
    *,
    config: SlamConfig | None = None,
    initial_pose=(0.0, 0.0, 0.0),
    max_iterations: int = 50,
) -> SmoothResult:
    """Smooth a filter run: every observation step's pose and the final map at once.

    Parameters
    ----------
    steps : sequence of Step
        The steps the filter ran on (with any clutter it saw).
    model : MotionModel
        The filter's motion model.
    result : SlamResult
        The filter's run (its associations, initial pose, final landmark ids and
        positions as the starting point).
    config : SlamConfig, optional
        Noise model; default ``result.config``. The sensor's noise is the larger of this
        one's and the one the filter ended with (:attr:`SlamResult.observation_noise`),
        as the controls are read with the filter's calibration estimates.
    initial_pose : (3,) float
        The filter's ``initial_pose`` (its default: the origin).
    max_iterations : int
        Levenberg-Marquardt iterations.

    Returns
    -------
    SmoothResult
        Empty (no poses, no landmarks, no factors) when the run has no observation step:
        the smoothed variables are the observation steps' poses.

    Raises
    ------
    ArgumentError
        ``model`` is not a :class:`~scanclique.slam.models.MotionModel` or ``result`` not
        a :class:`SlamResult`.
    ConfigError
        ``config`` is not a :class:`SlamConfig`, or ``max_iterations`` not an integer >= 1.
    StepError
        ``steps`` hold another number of observation steps than the filter's run.
    """
    require_model("smooth: ", "model", model)
    if not isinstance(result, SlamResult):
        raise ArgumentError(
            f"smooth: result must be the filter's SlamResult, got {type(result).__name__}"
        )
    require_config("smooth: ", config, SlamConfig)
    require_count("smooth: ", 1, max_iterations=max_iterations)
    import gtsam

    t0 = time.perf_counter()
    c0 = time.process_time()
    cfg = config or result.config
    times, held, dts = held_controls(steps)
    # the controls as the filter ended up reading them: its calibration states' final
    # estimates applied (the speed's relative error, the second control's bias)
    if result.speed_scale is not None:
        held[:, 0] *= 1.0 + result.speed_scale[0]
    if result.control_bias is not None:
        held[:, 1] += result.control_bias[0]
    slip = cfg.slip
    obs_steps = [k for k, s in enumerate(steps) if s.n_observations]
    if len(obs_steps) != len(result.associations):
        raise StepError(
            f"smooth: the steps are not the ones the filter ran on ({len(obs_steps)} "
            f"observation steps, the run has {len(result.associations)})"
        )
    if not obs_steps:  # nothing to smooth (GTSAM would fail on a prior of no variable)
        return SmoothResult(
            times[:0], np.zeros((0, 3)), np.zeros((0, 2)), np.zeros(0, np.int64), 0, 0.0, 0.0,
            time.perf_counter() - t0, time.process_time() - c0,
        )  # fmt: skip
    mount = gtsam.Pose2(model.sensor_x, model.sensor_y, 0.0)
    ad = mount.inverse().AdjointMap()  # body-frame perturbation, vehicle -> sensor

    def sensor(p):
        return gtsam.Pose2(*map(float, p)).compose(mount)

    X = lambda i: gtsam.symbol("x", i)  # noqa: E731
    Lk = lambda j: gtsam.symbol("l", j)  # noqa: E731
    graph = gtsam.NonlinearFactorGraph()
    init = gtsam.Values()
    # the first observation step: the initial pose moved there by the controls
    s0 = obs_steps[0] if obs_steps else 0
    d0, P0 = _odometry(model, held, dts, 0, s0 + 1, slip)
    start = np.asarray(initial_pose, float)  # ekf_slam's initial_pose
    p_first = gtsam.Pose2(*start).compose(gtsam.Pose2(*d0))
    sig0 = np.asarray(cfg.initial_sigma, float)

    def at_sensor(d, P):
        """The covariance ``P`` of a motion ``d`` (start frame) in the frame of its end,
        moved to the sensor (GTSAM's body-frame perturbation), floored."""
        J = np.eye(3)
        c, s = math.cos(d[2]), math.sin(d[2])
        J[:2, :2] = [[c, s], [-s, c]]
        return ad @ (J @ P @ J.T) @ ad.T + _FLOOR

    Ps = at_sensor(d0, np.diag(sig0**2) + P0)
    graph.add(
        gtsam.PriorFactorPose2(
            X(0), p_first.compose(mount), gtsam.noiseModel.Gaussian.Covariance(Ps)
        )
    )
    for o, k in enumerate(obs_steps):
        init.insert(X(o), sensor(result.poses[k]))
        if o == 0:
            continue
        d, P = _odometry(model, held, dts, obs_steps[o - 1] + 1, k + 1, slip)
        Ps = at_sensor(d, P)
        rel = mount.inverse().compose(gtsam.Pose2(*d)).compose(mount)
        graph.add(
            gtsam.BetweenFactorPose2(X(o - 1), X(o), rel, gtsam.noiseModel.Gaussian.Covariance(Ps))
        )
    ids = np.asarray(result.landmark_ids, np.int64)
    final = {int(i): q for q, i in enumerate(ids)}
    for q, i in enumerate(ids):
        init.insert(Lk(int(i)), np.asarray(result.landmarks[q], float))
    # the sensor's noise as the filter ended up taking it (SlamConfig.noise_window)
    sr, sb = cfg.sigma_range, cfg.sigma_bearing
    if result.observation_noise is not None:
        sr, sb = max(sr, result.observation_noise[0]), max(sb, result.observation_noise[1])
    noise = gtsam.noiseModel.Diagonal.Sigmas(np.array([sb, sr]))
    nf = 0
    for o, (k, a) in enumerate(zip(obs_steps, _landmark_of_new(result), strict=True)):
        z = steps[k].observations
        for i in np.flatnonzero(a >= 0):
            if int(a[i]) not in final:
                continue
            graph.add(
                gtsam.BearingRangeFactor2D(
                    X(o), Lk(int(a[i])), gtsam.Rot2(float(z[i, 1])), float(z[i, 0]), noise
                )
            )
            nf += 1
    e0 = graph.error(init)
    params = gtsam.LevenbergMarquardtParams()
    params.setMaxIterations(int(max_iterations))
    with solving(
        "slam.smooth", "Are the controls and observations in metres, seconds and radians?"
    ):
        est = gtsam.LevenbergMarquardtOptimizer(graph, init, params).optimize()
    e1 = graph.error(est)
    inv = mount.inverse()
    poses = np.empty((len(obs_steps), 3))
    for o in range(len(obs_steps)):
        p = est.atPose2(X(o)).compose(inv)
        poses[o] = (p.x(), p.y(), p.theta())
    lms = np.array([est.atPoint2(Lk(int(i))) for i in ids]).reshape(-1, 2)
    sec = time.perf_counter() - t0
    log.info(
        "smoothing: %d poses, %d landmarks, %d factors, error %.1f -> %.1f, %.1f s",
        len(obs_steps),
        len(ids),
        nf,
        e0,
        e1,
        sec,
    )
    return SmoothResult(
        times[obs_steps], poses, lms, ids, nf, float(e0), float(e1), sec, time.process_time() - c0
    )
