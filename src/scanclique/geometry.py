"""Rigid motions of the plane: the :class:`Pose2` value type and angle helpers.

A ``Pose2`` ``T_a_b`` (read "pose of frame b in frame a") maps points expressed in
frame b into frame a::

    p_a = R(theta) @ p_b + (x, y)

Composition follows the same convention: ``T_a_c = T_a_b @ T_b_c``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .errors import ScanError

__all__ = [
    "Pose2", "wrap_angle", "rotation_matrix", "interpolate_poses", "pose_at", "align_se2",
    "align_poses",
]  # fmt: skip


def wrap_angle(angle):
    """Wrap angles (radians, scalar or array) into [-pi, pi).

    >>> float(wrap_angle(3 * np.pi / 2))
    -1.5707963267948966
    """
    a = (np.asarray(angle, dtype=float) + np.pi) % (2.0 * np.pi) - np.pi
    # floating point can round the result up to +pi; keep the half-open interval
    return np.where(a >= np.pi, a - 2.0 * np.pi, a)


def _wrap_scalar(a: float) -> float:
    """:func:`wrap_angle` for one Python float (no NumPy call: poses are built often)."""
    a = (a + math.pi) % (2.0 * math.pi) - math.pi
    return a - 2.0 * math.pi if a >= math.pi else a


def interpolate_poses(rows, times) -> np.ndarray:
    """Poses ``(N, 3)`` at ``times`` (s) from ``(T, 4)`` rows ``time x y theta`` in time
    order: x and y linear, the heading along the shorter arc, wrapped to [-pi, pi); times
    outside the rows' span take the nearest row's pose.

    >>> rows = [[0.0, 0.0, 0.0, 3.0], [2.0, 2.0, 4.0, -3.0]]
    >>> interpolate_poses(rows, [1.0, 5.0]).round(4).tolist()
    [[1.0, 2.0, -3.1416], [2.0, 4.0, -3.0]]
    """
    rows = np.asarray(rows, float)
    times = np.asarray(times, float)
    th = np.unwrap(rows[:, 3])
    return np.column_stack(
        [
            np.interp(times, rows[:, 0], rows[:, 1]),
            np.interp(times, rows[:, 0], rows[:, 2]),
            wrap_angle(np.interp(times, rows[:, 0], th)),
        ]
    )


def pose_at(times, poses, t: float, tol: float = 0.0) -> Pose2 | None:
    """The pose at time ``t`` from poses at sorted times.

    Parameters
    ----------
    times : array_like, shape (T,)
        Seconds, non-decreasing.
    poses : array_like, shape (T, 3)
        ``x y theta`` at each time.
    t : float
        Query time, same clock.
    tol : float
        Seconds: a time within ``tol`` of ``t`` counts as ``t``.

    Returns
    -------
    Pose2 or None
        The pose of the last time within ``tol`` of ``t`` (the last logged, if several
        share it); else linear between the two poses around ``t`` (x and y linearly,
        theta along the shorter arc); None before the first time or after the last (by
        more than ``tol``), or without poses.

    >>> pose_at([0.0, 2.0], [[0.0, 0.0, 3.0], [2.0, 4.0, -3.0]], 1.0)
    Pose2(x=1.0000, y=2.0000, theta=-3.1416)
    >>> pose_at([0.0, 2.0], [[0.0, 0.0, 3.0], [2.0, 4.0, -3.0]], 2.5) is None
    True
    """
    ts = np.asarray(times, dtype=np.float64)
    i = int(np.searchsorted(ts, t - tol, side="left"))  # the first time >= t - tol
    j = int(np.searchsorted(ts, t + tol, side="right")) - 1  # the last time <= t + tol
    if j >= i:
        return Pose2(*(float(v) for v in poses[j]))
    if j < 0 or i >= len(ts):
        return None
    (x0, y0, th0), (x1, y1, th1) = (tuple(float(v) for v in poses[k]) for k in (j, i))
    alpha = (t - ts[j]) / (ts[i] - ts[j])
    dth = float(wrap_angle(th1 - th0))
    return Pose2(x0 + alpha * (x1 - x0), y0 + alpha * (y1 - y0), th0 + alpha * dth)


def align_se2(src, dst):
    """Least-squares rotation ``Rm`` (2, 2) and translation ``t`` (2,) with
    ``dst ~ src @ Rm.T + t`` for point sets ``src``, ``dst`` (N, 2), and the rotation's
    angle (radians): the rigid motion of the plane (no scale) that best maps ``src`` onto
    ``dst`` (Umeyama, 1991).

    >>> Rm, t, ang = align_se2([[0, 0], [1, 0]], [[2, 1], [2, 2]])
    >>> round(ang, 6), t.round(6).tolist()
    (1.570796, [2.0, 1.0])
    """
    src = np.asarray(src, float)
    dst = np.asarray(dst, float)
    ms, md = src.mean(0), dst.mean(0)
    H = (src - ms).T @ (dst - md)
    ang = math.atan2(H[0, 1] - H[1, 0], H[0, 0] + H[1, 1])
    c, s = math.cos(ang), math.sin(ang)
    Rm = np.array([[c, -s], [s, c]])
    return Rm, md - Rm @ ms, ang


def align_poses(a, b, sigma_xy: float, sigma_theta: float) -> tuple[float, float, float]:
    """The rigid motion ``T = (x, y, theta)`` that best carries poses ``a`` onto poses
    ``b`` (rows ``(x, y, theta)``, (N, 3); m, rad), positions and headings alike: it
    minimises ``sum |R a_xy + t - b_xy|^2 / sigma_xy^2 + sum wrap(b_th - a_th -
    theta)^2 / sigma_theta^2``. Poses bunched together fix the rotation by their headings
    (:func:`align_se2`, by positions alone, leaves it loose there); poses far apart by
    their positions. One pair gives its own motion ``b a^-1``.

    The rotation is found on a 0.5 degree grid, then by Newton's method; the translation
    follows in closed form.

    >>> x, y, th = align_poses([[0, 0, 0], [1, 0, 0]], [[2, 1, 1.5708], [2, 2, 1.5708]],
    ...                        0.1, 0.01)
    >>> round(x, 4), round(y, 4), round(th, 4)
    (2.0, 1.0, 1.5708)
    """
    a = np.asarray(a, dtype=float).reshape(-1, 3)
    b = np.asarray(b, dtype=float).reshape(-1, 3)
    ma, mb = a[:, :2].mean(0), b[:, :2].mean(0)
    ac, bc = a[:, :2] - ma, b[:, :2] - mb
    # the positions' cost is const - 2 r cos(theta - phi)
    dot = float(np.sum(ac * bc))
    cross = float(np.sum(ac[:, 0] * bc[:, 1] - ac[:, 1] * bc[:, 0]))
    r, phi = math.hypot(dot, cross), math.atan2(cross, dot)
    d = b[:, 2] - a[:, 2]
    wp, wt = 1.0 / sigma_xy**2, 1.0 / sigma_theta**2

    def cost(th):
        return -2.0 * r * wp * np.cos(th - phi) + wt * np.sum(
            wrap_angle(d[None, :] - np.atleast_1d(th)[:, None]) ** 2, axis=1
        )

    grid = np.radians(np.arange(-180.0, 180.0, 0.5))
    th = float(grid[np.argmin(cost(grid))])
    for _ in range(30):
        e = wrap_angle(d - th)
        g = 2.0 * r * wp * math.sin(th - phi) - 2.0 * wt * float(np.sum(e))
        h = 2.0 * r * wp * math.cos(th - phi) + 2.0 * wt * len(d)
        if h <= 0.0:
            break
        step = g / h
        th -= step
        if abs(step) < 1e-13:
            break
    th = float(wrap_angle(th))
    t = mb - rotation_matrix(th) @ ma
    return float(t[0]), float(t[1]), th


def rotation_matrix(theta: float) -> np.ndarray:
    """The 2x2 rotation matrix R(theta), counter-clockwise, radians."""
    c, s = math.cos(theta), math.sin(theta)
    return np.array([[c, -s], [s, c]])


@dataclass(frozen=True, slots=True)
class Pose2:
    """A rigid motion of the plane, ``p_a = R(theta) p_b + (x, y)``.

    Build it through the named constructors (:meth:`from_xytheta`, :meth:`from_matrix`,
    :meth:`identity`); read it through :meth:`as_matrix`, :meth:`as_array` or the
    attributes. ``theta`` is kept wrapped to [-pi, pi).

    Attributes
    ----------
    x, y : float
        Translation, metres: the origin of frame b expressed in frame a.
    theta : float
        Rotation, radians: the heading of frame b's x axis in frame a.

    Examples
    --------
    >>> T_a_b = Pose2.from_xytheta(1.0, 0.0, np.pi / 2)
    >>> T_a_b.transform(np.array([[1.0, 0.0]])).round(12)
    array([[1., 1.]])
    >>> (T_a_b @ T_a_b.inverse()).as_array().round(12)
    array([0., 0., 0.])
    """

    x: float
    y: float
    theta: float

    def __post_init__(self) -> None:
        x, y, t = float(self.x), float(self.y), float(self.theta)
        if not (math.isfinite(x) and math.isfinite(y) and math.isfinite(t)):
            raise ScanError(f"Pose2 needs finite x, y, theta; got {(self.x, self.y, self.theta)}")
        object.__setattr__(self, "x", x)
        object.__setattr__(self, "y", y)
        object.__setattr__(self, "theta", _wrap_scalar(t))

    # -- constructors ---------------------------------------------------------------
    @classmethod
    def from_xytheta(cls, x: float, y: float, theta: float) -> Pose2:
        """Pose from translation (metres) and rotation (radians)."""
        return cls(x, y, theta)

    @classmethod
    def from_array(cls, xytheta) -> Pose2:
        """Pose from a length-3 array ``(x, y, theta)``."""
        a = np.asarray(xytheta, dtype=float).reshape(-1)
        if a.shape != (3,):
            raise ScanError(f"Pose2.from_array expects 3 values, got shape {np.shape(xytheta)}")
        return cls(a[0], a[1], a[2])

    @classmethod
    def from_matrix(cls, matrix) -> Pose2:
        """Pose from a 3x3 homogeneous matrix (the rotation block is re-orthonormalised)."""
        m = np.asarray(matrix, dtype=float)
        if m.shape != (3, 3):
            raise ScanError(f"Pose2.from_matrix expects a 3x3 matrix, got {m.shape}")
        return cls(m[0, 2], m[1, 2], math.atan2(m[1, 0] - m[0, 1], m[0, 0] + m[1, 1]))

    @classmethod
    def identity(cls) -> Pose2:
        """The identity motion."""
        return cls(0.0, 0.0, 0.0)

    # -- converters -----------------------------------------------------------------
    def as_array(self) -> np.ndarray:
        """``(x, y, theta)`` as a float64 array."""
        return np.array([self.x, self.y, self.theta])

    def as_matrix(self) -> np.ndarray:
        """The 3x3 homogeneous matrix mapping b-frame points into frame a."""
        m = np.eye(3)
        m[:2, :2] = rotation_matrix(self.theta)
        m[0, 2], m[1, 2] = self.x, self.y
        return m

    @property
    def rotation(self) -> np.ndarray:
        """R(theta), 2x2."""
        return rotation_matrix(self.theta)

    @property
    def translation(self) -> np.ndarray:
        """(x, y), shape (2,)."""
        return np.array([self.x, self.y])

    # -- algebra --------------------------------------------------------------------
    def inverse(self) -> Pose2:
        """``T_b_a`` from ``T_a_b``: maps frame-a points into frame b."""
        c, s = math.cos(self.theta), math.sin(self.theta)
        return Pose2(-(c * self.x + s * self.y), s * self.x - c * self.y, -self.theta)

    def __matmul__(self, other: Pose2) -> Pose2:
        """Composition ``T_a_c = T_a_b @ T_b_c``."""
        if not isinstance(other, Pose2):
            return NotImplemented
        c, s = math.cos(self.theta), math.sin(self.theta)
        return Pose2(
            self.x + c * other.x - s * other.y,
            self.y + s * other.x + c * other.y,
            self.theta + other.theta,
        )

    def transform(self, points_b) -> np.ndarray:
        """Map ``(N, 2)`` points from frame b into frame a."""
        p = np.asarray(points_b, dtype=float)
        if p.ndim != 2 or p.shape[1] != 2:
            raise ScanError(f"transform expects (N, 2) points, got shape {p.shape}")
        return p @ self.rotation.T + self.translation

    def distance_to(self, other: Pose2) -> tuple[float, float]:
        """``(translation error in metres, |rotation error| in radians)`` between two poses:
        the length and angle of ``self.inverse() @ other`` (a rotation keeps lengths, so
        the translation error is the distance between the two positions)."""
        return (
            math.hypot(other.x - self.x, other.y - self.y),
            abs(_wrap_scalar(other.theta - self.theta)),
        )

    def twist_to(self, other: Pose2, seconds: float) -> tuple[float, float, float]:
        """The constant velocity ``(vx, vy, omega)`` in this pose's own (body) frame
        (m/s, m/s, rad/s) that carries it to ``other`` in ``seconds``: the logarithm of
        ``self.inverse() @ other`` (a ride along an arc; the turn the shorter way) over
        ``seconds`` (positive).

        >>> [round(v, 4) for v in Pose2(0, 0, 0).twist_to(Pose2(1, 1, math.pi / 2), 2.0)]
        [0.7854, 0.0, 0.7854]
        """
        if not (seconds > 0 and math.isfinite(seconds)):
            raise ScanError(f"twist_to needs a positive finite time, got {seconds!r}")
        u = self.inverse() @ other
        th = u.theta
        if abs(th) < 1e-6:
            a, b = 1.0 - th * th / 6.0, 0.5 * th
        else:
            a, b = math.sin(th) / th, (1.0 - math.cos(th)) / th
        d = a * a + b * b
        return (
            (a * u.x + b * u.y) / d / seconds,
            (a * u.y - b * u.x) / d / seconds,
            th / seconds,
        )

    def __repr__(self) -> str:
        return f"Pose2(x={self.x:.4f}, y={self.y:.4f}, theta={self.theta:.4f})"
