"""Motion and observation models of EKF-SLAM, with their Jacobians.

Two vehicle models share one interface (:class:`MotionModel`): the state of the vehicle is
``(x, y, theta)`` of its reference point (the rear-axle centre for :class:`Ackermann`, the
wheel-axle centre for :class:`Unicycle`) in the world frame, theta counter-clockwise from
the world's x axis. A range-bearing sensor sits at ``(sensor_x, sensor_y)`` in the vehicle
frame (x forward, y left) with the vehicle's heading. Landmarks are world points.

``predict(state, control, dt)`` integrates the model over ``dt`` seconds (one Euler step;
the controls of a log come every few tens of milliseconds) and returns the new state, the
Jacobian ``F`` = d new state / d state (3, 3) and ``G`` = d new state / d control (3, 2).
``observe(state, landmarks)`` returns the predicted range/bearing of each landmark from the
sensor with the Jacobians with respect to the vehicle state and to the landmark;
``inverse(state, z)`` is the landmark at range/bearing ``z`` with its Jacobians.

References
----------
J. Guivant and E. Nebot, "Optimization of the simultaneous localization and map-building
algorithm for real-time implementation", IEEE Trans. Robotics and Automation 17(3), 2001
(the vehicle model of the Victoria Park data set: Ackermann steering, encoder on the rear
left wheel, laser ahead of the rear axle).
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass, fields
from typing import ClassVar

import numpy as np

from ..errors import ArgumentError, ConfigError

__all__ = [
    "wrap",
    "MotionModel",
    "Ackermann",
    "Unicycle",
    "controls_from_odometry",
    "observe",
    "inverse_observe",
]

log = logging.getLogger(__name__)

#: :func:`controls_from_odometry` warns when more than this fraction of the odometry's path
#: runs across its heading (a heading not in radians, or not the wheels')
SIDEWAYS_WARNING = 0.2


def wrap(angle):
    """Angle(s) wrapped to [-pi, pi) (radians); arrays and scalars alike.

    >>> round(float(wrap(3 * math.pi / 2)), 6)
    -1.570796
    """
    return (np.asarray(angle) + np.pi) % (2.0 * np.pi) - np.pi


#: the models' own parameters: numbers, finite; the sigmas >= 0, the wheelbase > 0
_NUMBERS = frozenset(
    {"sensor_x", "sensor_y", "wheelbase", "encoder_offset", "sigma_speed", "sigma_speed_rel",
     "sigma_steering", "sigma_v", "sigma_v_rel", "sigma_omega"}
)  # fmt: skip


def _check_parameters(model) -> None:
    """Make ``model``'s own parameters floats, or raise a :class:`ConfigError` naming the
    model and the parameter that is not a finite number, a negative sigma or a wheelbase
    that is not positive (a subclass's other fields are left alone)."""
    kind = type(model).__name__
    for f in fields(model):
        if f.name not in _NUMBERS:
            continue
        v = getattr(model, f.name)
        name = getattr(model, "_ALIASES", {}).get(f.name, f.name)  # as the user gave it
        ok = not isinstance(v, (bool, np.bool_)) and isinstance(v, (int, float, np.number))
        if not ok or not math.isfinite(v):
            raise ConfigError(f"{kind}: {name} must be a finite number, got {v!r}")
        if f.name.startswith("sigma_") and v < 0:
            raise ConfigError(f"{kind}: {name} must be >= 0, got {v!r}")
        if f.name == "wheelbase" and v <= 0:
            raise ConfigError(f"{kind}: wheelbase must be > 0 m, got {v!r}")
        object.__setattr__(model, f.name, float(v))


def require_model(where: str, name: str, model) -> None:
    """``model`` is a :class:`MotionModel`, else an :class:`ArgumentError` naming ``where``
    and the argument ``name`` (the filter's and the smoother's check)."""
    if not isinstance(model, MotionModel):
        raise ArgumentError(
            f"{where}{name} must be a slam.MotionModel (slam.Ackermann, slam.Unicycle or "
            f"a subclass), got {type(model).__name__}"
        )


@dataclass(frozen=True, slots=True)
class MotionModel:
    """Common part of the vehicle models: the sensor's position on the vehicle.

    Attributes
    ----------
    sensor_x, sensor_y : float
        Position of the range-bearing sensor in the vehicle frame (m; x forward, y left).

    Raises
    ------
    ConfigError
        For every model: a parameter that is not a finite number, a negative sigma, a
        wheelbase that is not positive (a NaN wheelbase gave NaN poses, silently).
    """

    sensor_x: float = 0.0
    sensor_y: float = 0.0

    def __post_init__(self) -> None:
        _check_parameters(self)

    def predict(self, state, control, dt):  # pragma: no cover - abstract
        raise NotImplementedError

    def control_covariance(self, control) -> np.ndarray:  # pragma: no cover - abstract
        raise NotImplementedError

    def kernel(self):
        """``(kind, params)`` of the compiled prediction, or None (Python steps)."""
        return None

    #: the bound on the second control's magnitude (None: no bound), and what it is
    control_bound: ClassVar[tuple[float, str] | None] = None

    def implausible_control(self, controls: np.ndarray) -> tuple[int, str] | None:
        """The first of ``controls`` (M, 2) whose second component lies beyond this
        model's :attr:`control_bound` (an angle given in degrees), as ``(index, what is
        wrong)``, or None."""
        if self.control_bound is None or not len(controls):
            return None
        bound, what = self.control_bound
        bad = np.flatnonzero(np.abs(controls[:, 1]) >= bound)
        if not len(bad):
            return None
        k = int(bad[0])
        v = float(controls[k, 1])
        return k, (
            f"{what} {v} is at or beyond {bound:.5g}: radians? ({v} in degrees is "
            f"{math.radians(v):.6g})"
        )

    def moving(self, control) -> bool:
        """Whether the vehicle moves under ``control`` (the filter's additive slip
        noise applies only then): a speed other than zero."""
        return abs(float(control[0])) > 1e-6

    def observe(self, state, landmarks):
        """See :func:`observe` (with this model's sensor offset)."""
        return observe(state, landmarks, self.sensor_x, self.sensor_y)

    def inverse(self, state, z):
        """See :func:`inverse_observe` (with this model's sensor offset)."""
        return inverse_observe(state, z, self.sensor_x, self.sensor_y)

    def sensor_pose(self, state) -> np.ndarray:
        """World pose ``(x, y, theta)`` of the sensor for the vehicle ``state``."""
        x, y, th = state
        c, s = math.cos(th), math.sin(th)
        return np.array(
            [
                x + c * self.sensor_x - s * self.sensor_y,
                y + s * self.sensor_x + c * self.sensor_y,
                th,
            ]
        )


@dataclass(frozen=True, slots=True)
class Ackermann(MotionModel):
    """Car-like vehicle with a speed encoder on the rear left wheel and a steering sensor
    (Guivant and Nebot 2001; the Victoria Park utility vehicle).

    Control ``(v_e, alpha)``: the encoder's speed (m/s) and the steering angle (rad). The
    rear-axle centre moves at ``v_c = v_e / (1 - tan(alpha) H / L)`` and::

        x'     = v_c cos(theta)
        y'     = v_c sin(theta)
        theta' = v_c tan(alpha) / L

    The laser sits ``laser_a`` ahead of and ``laser_b`` left of the rear-axle centre.

    Parameters
    ----------
    wheelbase : float
        ``L`` (m).
    encoder_offset : float
        ``H``: lateral offset of the encoder wheel from the vehicle's centre line (m).
    laser_a, laser_b : float
        Sensor position (m) ahead of / left of the rear axle centre.
    sigma_speed : float
        Standard deviation of the encoder speed (m/s), plus ``sigma_speed_rel`` times the
        speed.
    sigma_steering : float
        Standard deviation of the steering angle (rad).

    Examples
    --------
    >>> m = Ackermann(wheelbase=2.83, encoder_offset=0.76, laser_a=3.78, laser_b=0.5)
    >>> x, F, G = m.predict(np.zeros(3), np.array([1.0, 0.0]), 1.0)
    >>> x.round(6).tolist()
    [1.0, 0.0, 0.0]
    """

    wheelbase: float = 2.83
    encoder_offset: float = 0.76
    sigma_speed: float = 0.05
    sigma_speed_rel: float = 0.05
    sigma_steering: float = math.radians(1.0)
    #: a steering angle of pi/2 turns the wheels sideways (tan is infinite there)
    control_bound = (math.pi / 2, "steering angle (rad)")
    _ALIASES = {"sensor_x": "laser_a", "sensor_y": "laser_b"}  # the constructor's names

    def __init__(
        self,
        wheelbase: float = 2.83,
        encoder_offset: float = 0.76,
        laser_a: float = 3.78,
        laser_b: float = 0.5,
        *,
        sigma_speed: float = 0.05,
        sigma_speed_rel: float = 0.05,
        sigma_steering: float = math.radians(1.0),
    ) -> None:
        object.__setattr__(self, "sensor_x", laser_a)
        object.__setattr__(self, "sensor_y", laser_b)
        object.__setattr__(self, "wheelbase", wheelbase)
        object.__setattr__(self, "encoder_offset", encoder_offset)
        object.__setattr__(self, "sigma_speed", sigma_speed)
        object.__setattr__(self, "sigma_speed_rel", sigma_speed_rel)
        object.__setattr__(self, "sigma_steering", sigma_steering)
        _check_parameters(self)

    @property
    def laser_a(self) -> float:
        return self.sensor_x

    @property
    def laser_b(self) -> float:
        return self.sensor_y

    def predict(self, state, control, dt):
        """One Euler step of ``dt`` s: ``(new_state, F (3,3), G (3,2))``."""
        x, y, th = state
        ve, al = control
        L, H = self.wheelbase, self.encoder_offset
        ta = math.tan(al)
        den = 1.0 - ta * H / L
        vc = ve / den
        c, s = math.cos(th), math.sin(th)
        new = np.array([x + dt * vc * c, y + dt * vc * s, wrap(th + dt * vc * ta / L)])
        F = np.array([[1.0, 0.0, -dt * vc * s], [0.0, 1.0, dt * vc * c], [0.0, 0.0, 1.0]])
        # d vc / d ve, d vc / d alpha
        sec2 = 1.0 + ta * ta
        dvc_dve = 1.0 / den
        dvc_dal = ve * (H / L) * sec2 / (den * den)
        G = np.array(
            [
                [dt * c * dvc_dve, dt * c * dvc_dal],
                [dt * s * dvc_dve, dt * s * dvc_dal],
                [dt * ta / L * dvc_dve, dt / L * (dvc_dal * ta + vc * sec2)],
            ]
        )
        return new, F, G

    def control_covariance(self, control) -> np.ndarray:
        """Covariance (2, 2) of ``(speed, steering)``."""
        sv = self.sigma_speed + self.sigma_speed_rel * abs(float(control[0]))
        return np.diag([sv * sv, self.sigma_steering**2])

    def kernel(self):
        if type(self) is not Ackermann:
            return None
        return 0, np.array(
            [
                self.wheelbase,
                self.encoder_offset,
                self.sigma_speed,
                self.sigma_speed_rel,
                self.sigma_steering,
            ]
        )


@dataclass(frozen=True, slots=True)
class Unicycle(MotionModel):
    """Differential-drive robot with wheel odometry: control ``(v m/s, omega rad/s)``::

        x' = v cos(theta),  y' = v sin(theta),  theta' = omega

    Parameters
    ----------
    sensor_x, sensor_y : float
        Sensor position in the vehicle frame (m).
    sigma_v, sigma_omega : float
        Standard deviations of the controls (m/s, rad/s); ``sigma_v_rel`` adds a part
        proportional to the speed. The filter treats this noise as independent from one
        control to the next, so its effect on the pose shrinks with the control rate: at
        67 Hz, 0.05 m/s adds 0.006 m and 2 deg/s 0.24 deg per square root of second. The
        odometry's systematic error (wheel radii, slip) belongs in the filter's additive
        process noise, :attr:`SlamConfig.slip <scanclique.slam.SlamConfig.slip>` (per
        metre travelled, per radian turned, per second).

    Examples
    --------
    >>> x, F, G = Unicycle().predict(np.zeros(3), np.array([1.0, 0.5]), 2.0)
    >>> x.round(6).tolist()
    [2.0, 0.0, 1.0]
    """

    sigma_v: float = 0.05
    sigma_v_rel: float = 0.05
    sigma_omega: float = math.radians(2.0)
    #: two turns a second (720 deg/s): no wheeled robot of a SLAM log turns faster
    control_bound = (4.0 * math.pi, "turn rate (rad/s)")

    def predict(self, state, control, dt):
        """One Euler step of ``dt`` s: ``(new_state, F (3,3), G (3,2))``."""
        x, y, th = state
        v, w = control
        c, s = math.cos(th), math.sin(th)
        new = np.array([x + dt * v * c, y + dt * v * s, wrap(th + dt * w)])
        F = np.array([[1.0, 0.0, -dt * v * s], [0.0, 1.0, dt * v * c], [0.0, 0.0, 1.0]])
        G = np.array([[dt * c, 0.0], [dt * s, 0.0], [0.0, dt]])
        return new, F, G

    def control_covariance(self, control) -> np.ndarray:
        sv = self.sigma_v + self.sigma_v_rel * abs(float(control[0]))
        return np.diag([sv * sv, self.sigma_omega**2])

    def moving(self, control) -> bool:
        """A speed or a turn rate other than zero: a differential-drive robot turning on
        the spot slips too."""
        return abs(float(control[0])) > 1e-6 or abs(float(control[1])) > 1e-6

    def kernel(self):
        if type(self) is not Unicycle:
            return None
        return 1, np.array([self.sigma_v, self.sigma_v_rel, self.sigma_omega])


def controls_from_odometry(times, poses) -> np.ndarray:
    """The controls of a :class:`Unicycle` that move it through wheel odometry given as
    poses: ``(time, v m/s, omega rad/s)`` rows, as a landmark log's ``controls.txt`` holds
    them, for odometry that comes as ``x, y, theta`` of the robot (a ``nav_msgs/Odometry``
    pose, a CARMEN ``ODOM`` line, a data set's odometry file).

    Over each interval between consecutive poses, ``omega`` is the heading change (wrapped
    to (-pi, pi]) over the interval's time and ``v`` the distance moved over it, negative
    when the robot moved backwards (its displacement points behind its heading half-way
    through the turn). A :meth:`Unicycle.predict` step with these controls moves exactly
    as far and turns exactly as much as the odometry; the direction of its move differs
    by half the interval's turn (the Euler step's usual first-order error, which the
    filter's slip covers). A pose's own frame does not matter (only increments are used).
    Motion across the heading is not a unicycle's and is left out: when more than
    :data:`SIDEWAYS_WARNING` of the path runs across it, a warning asks whether theta is
    in radians and the robot's (its wheels', not a sensor's mounted turned).

    Parameters
    ----------
    times : (N,) array_like
        Seconds, increasing (equal times only for equal poses).
    poses : (N, 3) array_like
        ``x, y`` in metres and ``theta`` in radians, counter-clockwise.

    Returns
    -------
    (N, 3) ndarray
        One row per pose: the control from that pose to the next; the last row ``(time,
        0, 0)`` (no motion after the odometry ends).

    Raises
    ------
    ArgumentError
        Shapes that do not match, values not finite, a time going back, or a move in no
        time (the row named, 0-based).

    Examples
    --------
    >>> c = controls_from_odometry([0.0, 2.0], [[0.0, 0.0, 0.0], [-2.0, 0.0, 0.0]])
    >>> c.tolist()  # two metres backwards in two seconds, then standing
    [[0.0, -1.0, 0.0], [2.0, 0.0, 0.0]]
    """
    t = np.asarray(times, dtype=float)
    p = np.asarray(poses, dtype=float)
    if t.ndim != 1 or p.ndim != 2 or p.shape != (len(t), 3):
        raise ArgumentError(
            f"controls_from_odometry: times must be (N,) and poses (N, 3), got {t.shape} and "
            f"{p.shape}"
        )
    fault = odometry_fault(t, p)
    if fault is not None:
        raise ArgumentError(f"controls_from_odometry: row {fault[0]}: {fault[1]}")
    return unicycle_controls(t, p)


def unicycle_controls(t: np.ndarray, p: np.ndarray) -> np.ndarray:
    """:func:`controls_from_odometry` of times ``t`` (N,) and poses ``p`` (N, 3) that
    :func:`odometry_fault` has passed (the reader checks them itself, to name the line)."""
    dt = np.diff(t)
    c, s = np.cos(p[:-1, 2]), np.sin(p[:-1, 2])
    dx, dy = np.diff(p[:, 0]), np.diff(p[:, 1])
    fwd, side = c * dx + s * dy, -s * dx + c * dy  # in the frame of the interval's start
    turn = wrap(np.diff(p[:, 2]))
    h = 0.5 * turn
    along = np.cos(h) * fwd + np.sin(h) * side  # along the heading half-way through
    dist = np.hypot(dx, dy)
    moved = dt > 0
    out = np.zeros((len(t), 3))
    out[:, 0] = t
    out[:-1, 1] = np.where(moved, np.copysign(dist, along) / np.where(moved, dt, 1.0), 0.0)
    out[:-1, 2] = np.where(moved, turn / np.where(moved, dt, 1.0), 0.0)
    path = dist.sum()
    across = np.abs(np.cos(h) * side - np.sin(h) * fwd).sum()
    if path > 0 and across > SIDEWAYS_WARNING * path:
        log.warning(
            "%.0f%% of the odometry's path runs across its heading: is theta in radians, "
            "and the heading of the robot (of its wheels' axle, not of a sensor mounted "
            "turned)? A unicycle moves along its heading; the sideways part is left out",
            100.0 * across / path,
        )
    return out


def odometry_fault(times: np.ndarray, poses: np.ndarray) -> tuple[int, str] | None:
    """The first row (0-based) of odometry ``times`` (N,) and ``poses`` (N, 3) that
    :func:`controls_from_odometry` cannot take, with what is wrong, or None: a value not
    finite, a time before the row before it, or a pose other than the row before it at
    the same time."""
    bad = ~np.isfinite(times) | ~np.isfinite(poses).all(axis=1)
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        return i, f"not finite: time {times[i]}, pose {poses[i].tolist()}"
    dt = np.diff(times)
    still = (np.diff(poses, axis=0) == 0).all(axis=1)
    wrong = (dt < 0) | ((dt == 0) & ~still)
    if not wrong.any():
        return None
    i = int(np.flatnonzero(wrong)[0]) + 1
    if dt[i - 1] < 0:
        return i, f"time goes back: {times[i]} after {times[i - 1]}"
    a, b = poses[i - 1].tolist(), poses[i].tolist()
    return i, f"the pose moves in no time: {a} -> {b} at {times[i]} s"


def observe(state, landmarks, sensor_x: float = 0.0, sensor_y: float = 0.0):
    """Predicted range and bearing of world landmarks from the vehicle's sensor.

    Parameters
    ----------
    state : (3,) array
        Vehicle pose ``(x, y, theta)`` in the world.
    landmarks : (k, 2) array
        World positions.
    sensor_x, sensor_y : float
        Sensor position in the vehicle frame.

    Returns
    -------
    z : (k, 2) ndarray
        Range (m) and bearing (rad, wrapped to [-pi, pi), counter-clockwise from the heading).
    Hx : (k, 2, 3) ndarray
        d z / d state.
    Hm : (k, 2, 2) ndarray
        d z / d landmark.
    """
    x, y, th = state
    lm = np.asarray(landmarks, float).reshape(-1, 2)
    c, s = math.cos(th), math.sin(th)
    sx = x + c * sensor_x - s * sensor_y
    sy = y + s * sensor_x + c * sensor_y
    dsx = -s * sensor_x - c * sensor_y  # d sensor / d theta
    dsy = c * sensor_x - s * sensor_y
    dx = lm[:, 0] - sx
    dy = lm[:, 1] - sy
    q = dx * dx + dy * dy
    r = np.sqrt(q)
    z = np.column_stack([r, wrap(np.arctan2(dy, dx) - th)])
    k = len(lm)
    Hm = np.empty((k, 2, 2))
    Hm[:, 0, 0] = dx / r
    Hm[:, 0, 1] = dy / r
    Hm[:, 1, 0] = -dy / q
    Hm[:, 1, 1] = dx / q
    Hx = np.empty((k, 2, 3))
    Hx[:, :, 0] = -Hm[:, :, 0]
    Hx[:, :, 1] = -Hm[:, :, 1]
    Hx[:, :, 2] = -(Hm[:, :, 0] * dsx + Hm[:, :, 1] * dsy)
    Hx[:, 1, 2] -= 1.0
    return z, Hx, Hm


def inverse_observe(state, z, sensor_x: float = 0.0, sensor_y: float = 0.0):
    """World positions of features at range/bearing ``z`` from the vehicle's sensor.

    Returns
    -------
    m : (k, 2) ndarray
        World positions.
    Gx : (k, 2, 3) ndarray
        d m / d state.
    Gz : (k, 2, 2) ndarray
        d m / d z.
    """
    x, y, th = state
    z = np.asarray(z, float).reshape(-1, 2)
    c, s = math.cos(th), math.sin(th)
    sx = x + c * sensor_x - s * sensor_y
    sy = y + s * sensor_x + c * sensor_y
    dsx = -s * sensor_x - c * sensor_y
    dsy = c * sensor_x - s * sensor_y
    r, b = z[:, 0], z[:, 1]
    ang = th + b
    ca, sa = np.cos(ang), np.sin(ang)
    m = np.column_stack([sx + r * ca, sy + r * sa])
    k = len(z)
    Gx = np.zeros((k, 2, 3))
    Gx[:, 0, 0] = 1.0
    Gx[:, 1, 1] = 1.0
    Gx[:, 0, 2] = dsx - r * sa
    Gx[:, 1, 2] = dsy + r * ca
    Gz = np.empty((k, 2, 2))
    Gz[:, 0, 0] = ca
    Gz[:, 0, 1] = -r * sa
    Gz[:, 1, 0] = sa
    Gz[:, 1, 1] = r * ca
    return m, Gx, Gz
