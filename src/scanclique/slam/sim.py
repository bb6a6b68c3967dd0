"""Simulated landmark worlds with known truth, for the filter's consistency (NEES) and its
association's correctness.

Two scenarios:

* :func:`simulate_park`: the Victoria Park car (:class:`~scanclique.slam.Ackermann`)
  driving laps of a rounded rectangle through a park of trees (points, at least
  ``min_spacing`` apart, none on the track); the laser sees trees within ``max_range`` in
  its 180 deg field of view with probability ``p_detect`` and range/bearing noise of the
  filter's :class:`~scanclique.slam.SlamConfig` (the documented noise of the data); the
  logged controls carry the model's control noise, and the true motion the config's
  additive slip noise. Controls at 40 Hz and scans at 5 Hz, as in the data set.
* :func:`simulate_room`: a differential-drive robot (:class:`~scanclique.slam.Unicycle`,
  wheel odometry ``(v, omega)`` at a high rate) wandering between random waypoints in a
  room with a few point landmarks, seen by a short-range, narrow-field sensor (by default
  the UTIAS MRCLAM setting: 15 landmarks in a 15 x 8 m room, a camera with a 60 deg field
  of view, 0.3-5 m, range sigma 0.15 m, bearing sigma 3 deg, odometry at 67 Hz, frames at
  7 Hz asynchronous to it), without attributes; revisits from every heading.

Both draw every noise from the :class:`~scanclique.slam.SlamConfig` the filter is given
(sensor noise ``R``, field of view, range limits, slip) and the motion model's control
noise, so that a filter run with the same config is run at the true noise.

(The project's laser-scan simulator is :mod:`scanclique.sim`; these scenarios live here,
beside the filter they test.)
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..config import require_count, require_nonneg, require_positive
from ..errors import ConfigError
from .ekf import SlamConfig, slip_variance
from .models import Ackermann, Unicycle, observe, wrap
from .reader import Step

__all__ = ["SimRun", "ParkRun", "simulate_park", "simulate_room", "room_config"]


@dataclass(frozen=True, slots=True, eq=False)
class SimRun:
    """A simulated log and its truth.

    Attributes
    ----------
    steps : list of Step
    times : (N,) ndarray
    poses : (N, 3) ndarray
        True vehicle pose at each step's time.
    landmarks : (T, 2) ndarray
        True landmark positions.
    truth : list of (k,) int64 ndarrays
        Per step with observations (steps that see nothing are left out), the landmark
        index of each observation (-1: clutter); aligned with
        :attr:`SlamResult.associations <scanclique.slam.SlamResult.associations>`.
    """

    steps: list
    times: np.ndarray
    poses: np.ndarray
    landmarks: np.ndarray
    truth: list

    @property
    def trees(self) -> np.ndarray:
        """The park's name of :attr:`landmarks`."""
        return self.landmarks


#: The tree park's run (the former name of :class:`SimRun`).
ParkRun = SimRun


def _frame(rng, x, landmarks, sensor, R, ranges, fov, p_detect, n_clutter, clutter_ranges):
    """One batch observation from the vehicle pose ``x``: each landmark within ``ranges``
    (min, max) and the field of view ``fov`` of the sensor at ``sensor`` (vehicle frame),
    detected with probability ``p_detect``, with noise ``R`` (a detection whose noisy range
    is negative is missed); then ``n_clutter`` spurious
    detections uniform in ``clutter_ranges`` and the field of view; shuffled. Returns
    ``(z (k, 2), ids (k,))``, ids the landmark of each detection (-1: clutter)."""
    z, _, _ = observe(x, landmarks, sensor[0], sensor[1])
    vis = np.flatnonzero(
        (z[:, 0] >= ranges[0])
        & (z[:, 0] <= ranges[1])
        & (np.abs(z[:, 1]) <= 0.5 * fov)
        & (rng.random(len(z)) < p_detect)
    )
    zt = z[vis] + rng.multivariate_normal(np.zeros(2), R, len(vis))
    zt[:, 1] = wrap(zt[:, 1])
    ids = vis.astype(np.int64)
    # a landmark nearer than its range noise can draw a range not above 0, which no sensor
    # reports: that detection is missed (drawn all the same, so the draws that follow
    # are those of every other frame)
    real = zt[:, 0] > 0.0
    zt, ids = zt[real], ids[real]
    if n_clutter:
        zc = np.column_stack(
            [rng.uniform(*clutter_ranges, n_clutter), rng.uniform(-0.5 * fov, 0.5 * fov, n_clutter)]
        )
        zt = np.vstack([zt, zc])
        ids = np.r_[ids, np.full(n_clutter, -1, np.int64)]
    order = rng.permutation(len(zt))
    return zt[order], ids[order]


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
) -> SimRun:
    """Simulate laps of a tree park (see the module docstring).

    Returns
    -------
    SimRun
        ``steps`` start at the vehicle's true initial pose ``(0, 0, 0)``.

    Raises
    ------
    ConfigError
        A count that is not an integer (``laps`` >= 1, ``n_trees``, ``clutter`` >= 0), a
        length, speed or period that is not a positive number, ``p_detect`` outside [0, 1].
    """
    where = "simulate_park: "
    require_count(where, 1, laps=laps)
    require_count(where, 0, n_trees=n_trees, clutter=clutter)
    require_positive(
        where, length=length, width=width, radius=radius, speed=speed, min_spacing=min_spacing,
        max_range=max_range, control_dt=control_dt, scan_dt=scan_dt,
    )  # fmt: skip
    _check_p_detect(where, p_detect)
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
    slip = cfg.slip
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
        x_was = x
        x, _, _ = model.predict(x, u, control_dt)
        if u[0] != 0:
            x = x + rng.normal(0.0, np.sqrt(slip_variance(slip, x_was, x, control_dt)))
            x[2] = wrap(x[2])
        t = (q + 1) * control_dt
        if t >= next_scan - 1e-9:
            next_scan += scan_dt
            zt, ids = _frame(
                rng,
                x,
                trees,
                (sx, sy),
                R,
                (0.0, max_range),
                cfg.sensor_fov,
                p_detect,
                clutter,
                (1.0, max_range),
            )
            if len(zt) == 0:
                continue
            steps.append(Step(t, None, zt))
            times.append(t)
            poses.append(x.copy())
            truth.append(ids)
    return SimRun(steps, np.asarray(times), np.asarray(poses), trees, truth)


def _chol2(S):
    """Lower Cholesky factor of a 2 x 2 covariance (positive semi-definite)."""
    a = math.sqrt(max(S[0, 0], 0.0))
    b = S[1, 0] / a if a > 0 else 0.0
    return np.array([[a, 0.0], [b, math.sqrt(max(S[1, 1] - b * b, 0.0))]])


def room_config(**overrides) -> SlamConfig:
    """The :class:`~scanclique.slam.SlamConfig` of :func:`simulate_room`'s default sensor
    and robot (UTIAS MRCLAM-like), by :meth:`SlamConfig.for_sensor
    <scanclique.slam.SlamConfig.for_sensor>`: range sigma 0.15 m, bearing sigma 3 deg,
    5 m, a 60 deg field of view; slip 0.02 m and 1 deg per square root of second while
    moving (about 8 % of the distance and 4 deg per metre at 0.25 m/s over a second), and
    none per metre or per radian (the defaults' forms). Keyword arguments replace fields.

    >>> cfg = room_config()
    >>> cfg.max_range, round(math.degrees(cfg.sensor_fov)), cfg.visible_range
    (5.0, 60, 5.0)
    """
    base = dict(
        sigma_range=0.15,
        sigma_bearing=math.radians(3.0),
        max_range=5.0,
        fov=math.radians(60.0),
        sigma_xy_rate=0.02,
        sigma_theta_rate=math.radians(1.0),
        sigma_xy_distance=0.0,
        sigma_theta_distance=0.0,
        sigma_theta_turn=0.0,
    )
    if "sensor_fov" in overrides:
        overrides["fov"] = overrides.pop("sensor_fov")
    base.update(overrides)
    return SlamConfig.for_sensor(**base)


def _check_p_detect(where: str, p_detect) -> None:
    require_nonneg(where, p_detect=p_detect)
    if p_detect > 1.0:
        raise ConfigError(f"{where}p_detect must be a probability in [0, 1], got {p_detect!r}")


def _room_landmarks(rng, room, n, min_spacing):
    """``n`` points in the room, at least ``min_spacing`` apart (fewer if they do not fit)."""
    return _trees(
        rng, (np.zeros(2), np.asarray(room, float)), n, min_spacing, np.full((1, 2), -1e9), 0.0
    )


def simulate_room(
    seed: int = 0,
    *,
    duration: float = 300.0,
    room: tuple[float, float] = (15.0, 8.0),
    n_landmarks: int = 15,
    min_spacing: float = 1.5,
    speed: float = 0.25,
    max_turn_rate: float = 0.6,
    turn_in_place: float | None = math.radians(90.0),
    p_detect: float = 0.9,
    min_range: float = 0.3,
    control_rate: float = 67.0,
    observation_rate: float = 7.0,
    clutter: float = 0.0,
    model: Unicycle | None = None,
    config: SlamConfig | None = None,
) -> SimRun:
    """Simulate a wheeled robot wandering in a room of point landmarks (see the module
    docstring).

    The robot steers towards random waypoints (at least 1 m inside the walls) at about
    ``speed`` m/s, turning at most ``max_turn_rate`` rad/s and slowing in sharp turns;
    when the waypoint lies more than ``turn_in_place`` rad off its heading it stops and
    turns on the spot (None: never). Its wheel odometry (the logged control ``(v, omega)``) comes at
    ``control_rate`` Hz with the noise of ``model.control_covariance``; the true motion
    adds ``config``'s slip. Observation frames come at ``observation_rate`` Hz at times
    that fall between the odometry's (steps with observations and no control; frames
    that see nothing are steps with no observations); each sees the landmarks within
    [``min_range``, ``config.max_range``] and half of ``config.sensor_fov`` of the
    heading with probability ``p_detect``, with noise ``config.R``, plus
    Poisson(``clutter``) spurious detections uniform in that range and field of view.

    Parameters
    ----------
    seed : int
    duration : float
        Seconds.
    room : (2,) float
        Width and depth of the room (m); the robot starts at its centre heading along x.
    n_landmarks, min_spacing : int, float
        Landmarks, uniform in the room at least ``min_spacing`` m apart.
    model : Unicycle, optional
        The robot and its odometry noise (default: ``Unicycle()``, sensor at the axle).
    config : SlamConfig, optional
        The sensor and slip noise (default: :func:`room_config`).

    Returns
    -------
    SimRun

    Examples
    --------
    >>> run = simulate_room(0, duration=20.0)
    >>> len(run.landmarks), run.steps[1].control is None or run.steps[1].n_observations == 0
    (15, True)

    Raises
    ------
    ConfigError
        ``n_landmarks`` not an integer >= 0; a duration, size, speed, turn rate or rate
        that is not a positive number; ``clutter`` or ``min_range`` negative, ``p_detect``
        outside [0, 1].
    """
    where = "simulate_room: "
    require_count(where, 0, n_landmarks=n_landmarks)
    try:
        width, depth = room
    except (TypeError, ValueError):
        raise ConfigError(f"{where}room must be (width, depth) in m, got {room!r}") from None
    require_positive(
        where, duration=duration, room_width=width, room_depth=depth, min_spacing=min_spacing,
        speed=speed, max_turn_rate=max_turn_rate, control_rate=control_rate,
        observation_rate=observation_rate,
    )  # fmt: skip
    if turn_in_place is not None:
        require_positive(where, turn_in_place=turn_in_place)
    require_nonneg(where, clutter=clutter, min_range=min_range)
    _check_p_detect(where, p_detect)
    rng = np.random.default_rng(seed)
    model = model or Unicycle()
    cfg = config or room_config()
    W, D = float(room[0]), float(room[1])
    lms = _room_landmarks(rng, (W, D), n_landmarks, min_spacing)
    max_range = cfg.max_range if cfg.max_range is not None else math.inf
    R = cfg.R
    slip = cfg.slip
    dt_c = 1.0 / control_rate
    n_ctrl = int(math.floor(duration * control_rate))
    # frames between the controls: a phase that never meets the control grid, and jitter
    dt_o = 1.0 / observation_rate
    t_obs = (np.arange(int(duration * observation_rate)) + 0.5) * dt_o
    t_obs = t_obs + rng.uniform(-0.25, 0.25, len(t_obs)) * min(dt_c, dt_o)
    margin = 1.0

    def waypoint():
        return rng.uniform([margin, margin], [W - margin, D - margin])

    x = np.array([0.5 * W, 0.5 * D, 0.0])
    goal = waypoint()
    steps, times, poses, truth = [], [], [], []
    empty = np.zeros((0, 2))
    o = 0  # next frame

    def move(x, u, dt):
        x_was = x
        x, _, _ = model.predict(x, u, dt)
        x = x + rng.normal(0.0, np.sqrt(slip_variance(slip, x_was, x, dt)))
        x[2] = wrap(x[2])
        return x

    for q in range(n_ctrl):
        t = q * dt_c
        # the controller, on the true pose: head for the waypoint
        d = goal - x[:2]
        if math.hypot(*d) < 0.5:
            goal = waypoint()
            d = goal - x[:2]
        err = float(wrap(math.atan2(d[1], d[0]) - x[2]))
        w = float(np.clip(2.0 * err, -max_turn_rate, max_turn_rate))
        if turn_in_place is not None and abs(err) > turn_in_place:
            v, w = 0.0, math.copysign(max_turn_rate, err)
        else:
            v = speed * max(0.2, math.cos(err))
        u = np.array([v, w])
        u_meas = u + _chol2(model.control_covariance(u)) @ rng.standard_normal(2)
        if v == 0.0:
            u_meas[0] = 0.0  # wheels that turn on the spot log no forward speed
        steps.append(Step(t, u_meas, empty))
        times.append(t)
        poses.append(x.copy())
        t_next = (q + 1) * dt_c
        while o < len(t_obs) and t_obs[o] < t_next:
            to = t_obs[o]
            o += 1
            if to > t:
                x = move(x, u, to - t)
                t = to
            nc = rng.poisson(clutter) if clutter > 0 else 0
            zt, ids = _frame(
                rng,
                x,
                lms,
                (model.sensor_x, model.sensor_y),
                R,
                (min_range, max_range),
                cfg.sensor_fov,
                p_detect,
                nc,
                (min_range, min(max_range, math.hypot(W, D))),
            )
            steps.append(Step(to, None, zt))
            times.append(to)
            poses.append(x.copy())
            if len(zt):
                truth.append(ids)
        x = move(x, u, t_next - t)
    return SimRun(steps, np.asarray(times), np.asarray(poses), lms, truth)
