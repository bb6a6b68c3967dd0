"""Uncertainty of relative poses: covariance algebra, Mahalanobis tests and the odometry
error model (paper §7's tools; used by validation, mapping and SLAM).

Poses are ``T_a_b``: they map points of B's sensor frame into A's
(``p_a = R(theta) p_b + (x, y)``); covariances are of ``(x, y, theta)`` of ``T_a_b``, in
m², m·rad and rad². An infinite variance marks a direction the features do not fix (a
corridor seen along its walls); sums treat it as very large.

* :class:`OdometryNoise` and :func:`odometry_prior` — the relative pose of two scans from
  their odometry and a covariance that grows with the path;
* :func:`pose_difference`, :func:`mahalanobis_sq` — the innovation of two estimates of one
  pose and its squared Mahalanobis distance;
* :func:`compose_covariance`, :func:`inverse_covariance` — first-order propagation through
  composition and inversion;
* :func:`constellation_std` — the precision a covariance allows (paper §7's dilution of
  precision).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy.special import chdtri

from .config import check_nonneg, check_positive, require_positive
from .errors import ScanError
from .geometry import Pose2, wrap_angle

__all__ = [
    "GATE_99",
    "OdometryNoise",
    "chi2_quantile",
    "check_covariance",
    "check_pose",
    "compose_covariance",
    "constellation_std",
    "finite_covariance",
    "inverse_covariance",
    "mahalanobis_sq",
    "odometry_prior",
    "pose_difference",
]


def chi2_quantile(p: float, dof: int) -> float:
    return float(chdtri(dof, 1.0 - p))


GATE_99 = chi2_quantile(0.99, 3)
"""The 99 % quantile of chi-square with 3 degrees of freedom (11.34): the default gate on
the squared Mahalanobis distance of a pose ``(x, y, theta)``."""


_BIG_VARIANCE = 1e6  # stands for an infinite variance in sums of covariances (m², rad²)


@dataclass(frozen=True, slots=True)
class OdometryNoise:
    """How wrong wheel odometry may be between two scans (one standard deviation).

    The model is linear in the path: odometry errors are mostly systematic (wheel
    diameters, wheel base), so they grow with the distance travelled ``D`` (metres) and
    the angle turned ``Phi`` (radians, summed absolute heading changes), not with their
    square roots::

        sigma_theta = floor_radians + per_radian * Phi + rot_per_metre * D
        sigma_xy    = floor_metres  + per_metre * D + D / 2 * (sigma_theta - floor_radians)

    The last term is the lever arm of the heading error picked up along the way. The
    covariance of ``(x, y, theta)`` is ``diag(sigma_xy², sigma_xy², sigma_theta²)``.

    Attributes
    ----------
    per_metre : float
        Translation error per metre travelled (m/m).
    per_radian : float
        Heading error per radian turned (rad/rad).
    rot_per_metre : float
        Heading error per metre travelled (rad/m): drift while driving straight.
    floor_metres, floor_radians : float
        Error that is there even without motion (timing between the laser and the wheel
        encoders, vibration), metres and radians.

    The defaults suit the raw wheel odometry of the Intel and CSAIL logs (10 % of the
    distance, 10 % of the angle, 1 degree per metre, 5 cm and 2 degrees): they cover
    about 99 % of the consecutive-scan odometry increments of both logs.
    """

    per_metre: float = 0.10
    per_radian: float = 0.10
    rot_per_metre: float = math.radians(1.0)
    floor_metres: float = 0.05
    floor_radians: float = math.radians(2.0)

    def __post_init__(self) -> None:
        check_nonneg(self, "per_metre", "per_radian", "rot_per_metre")
        # the floors keep the covariance invertible: a zero one cannot be tested against
        check_positive(self, "floor_metres", "floor_radians")

    def scaled(self, factor: float) -> OdometryNoise:
        """Every term multiplied by ``factor`` (a worse or better odometer)."""
        require_positive("OdometryNoise.scaled: ", factor=factor)
        return OdometryNoise(
            self.per_metre * factor,
            self.per_radian * factor,
            self.rot_per_metre * factor,
            self.floor_metres * factor,
            self.floor_radians * factor,
        )

    def std(self, distance: float, turn: float) -> tuple[float, float]:
        """``(sigma_xy, sigma_theta)`` after travelling ``distance`` m and turning ``turn``
        rad."""
        s_th = self.floor_radians + self.per_radian * turn + self.rot_per_metre * distance
        s_xy = (
            self.floor_metres
            + self.per_metre * distance
            + 0.5 * distance * (s_th - self.floor_radians)
        )
        return s_xy, s_th


def constellation_std(covariance) -> tuple[float, float]:
    """``(largest translation std m, heading std rad)`` of a pose covariance: the square
    root of the largest eigenvalue of its ``(x, y)`` block (the worst direction: along a
    corridor) and of its ``theta`` variance. Infinite when a direction is unconstrained.

    >>> constellation_std(np.diag([0.01**2, 4.0, 1e-6]))
    (2.0, 0.001)
    """
    P = np.asarray(covariance, dtype=float)
    if P.shape != (3, 3):
        raise ScanError(f"constellation_std expects a 3x3 covariance, got shape {P.shape}")
    if not np.all(np.isfinite(P[:2, :2])):
        s_xy = math.inf
    else:
        s_xy = math.sqrt(max(float(np.linalg.eigvalsh(P[:2, :2]).max()), 0.0))
    s_th = math.sqrt(P[2, 2]) if math.isfinite(P[2, 2]) and P[2, 2] >= 0 else math.inf
    return s_xy, s_th


def check_pose(p, name: str) -> Pose2:
    if not isinstance(p, Pose2):
        raise ScanError(f"{name} must be a Pose2, got {type(p).__name__}")
    return p


def check_covariance(P, name: str) -> np.ndarray:
    try:
        a = np.array(P, dtype=float)
    except (TypeError, ValueError):
        raise ScanError(f"{name} must be a 3x3 covariance matrix, got {P!r}") from None
    if a.shape != (3, 3):
        raise ScanError(f"{name} must be a 3x3 covariance matrix, got shape {a.shape}")
    # one test for the usual all-finite matrix (called per match and per PCM pair)
    if not np.isfinite(a).all() and (np.isnan(a).any() or (np.isinf(a) & (a < 0)).any()):
        raise ScanError(f"{name} holds NaN or -inf")
    if a[0, 0] < 0 or a[1, 1] < 0 or a[2, 2] < 0:
        raise ScanError(f"{name} has a negative variance: {np.diag(a).tolist()}")
    return a


def travel(poses: Sequence[Pose2]) -> tuple[float, float]:
    """The distance travelled (m) and the angle turned (rad, absolute values summed)
    along ``poses`` in order."""
    d = t = 0.0
    for p, q in zip(poses[:-1], poses[1:], strict=True):
        u = p.inverse() @ q
        d += math.hypot(u.x, u.y)
        t += abs(u.theta)
    return d, t


def odometry_prior(
    odom_a: Pose2,
    odom_b: Pose2,
    noise: OdometryNoise | None = None,
    *,
    path: Sequence[Pose2] | None = None,
) -> tuple[Pose2, np.ndarray]:
    """The relative pose of two scans from their odometry poses, and its covariance.

    Parameters
    ----------
    odom_a, odom_b : Pose2
        Odometry poses of the sensor at scans A and B, in the odometry frame (only their
        relative pose matters: the frame may be offset or drift).
    noise : OdometryNoise, optional
        The error model (defaults: :class:`OdometryNoise`).
    path : sequence of Pose2, optional
        The odometry poses from A to B in order (e.g. of every scan in between, both ends
        included): the distance travelled and the angle turned are summed along it.
        Without it, the straight line from A to B and the net heading change are used,
        which understates the travel of a long, winding path.

    Returns
    -------
    (Pose2, ndarray (3, 3))
        ``odom_a.inverse() @ odom_b`` (maps B into A, like a match's pose) and the
        covariance of its ``(x, y, theta)``.

    Examples
    --------
    >>> odom_a = Pose2(1.0, 2.0, 0.5)
    >>> prior, cov = odometry_prior(odom_a, odom_a @ Pose2(1.0, 0.0, 0.0))
    >>> prior, np.sqrt(np.diag(cov)).round(3).tolist()
    (Pose2(x=1.0000, y=0.0000, theta=0.0000), [0.159, 0.159, 0.052])
    """
    noise = noise or OdometryNoise()
    a, b = check_pose(odom_a, "odom_a"), check_pose(odom_b, "odom_b")
    rel = a.inverse() @ b
    if path is None:
        dist, turn = math.hypot(rel.x, rel.y), abs(rel.theta)
    else:
        poses = [check_pose(p, f"path[{k}]") for k, p in enumerate(path)]
        if len(poses) < 2:
            poses = [a, b]
        dist, turn = travel(poses)
    s_xy, s_th = noise.std(dist, turn)
    s = np.array([s_xy, s_xy, s_th])
    with np.errstate(over="ignore"):  # a sigma beyond 1e154: an infinite variance
        return rel, np.diag(s * s)


def pose_difference(p: Pose2, q: Pose2) -> np.ndarray:
    """``(x, y, theta)`` of ``p`` minus those of ``q``, the angle wrapped to [-pi, pi): the
    innovation of two estimates of one relative pose, in the coordinates their
    covariances are given in."""
    e = p.as_array() - q.as_array()
    e[2] = float(wrap_angle(e[2]))
    return e


def finite_covariance(P: np.ndarray) -> np.ndarray:
    """A covariance whose infinite variances are large and infinite covariances zero:
    a direction the features do not fix then adds no information to a sum."""
    P = np.array(P, dtype=float)
    bad = ~np.isfinite(P)
    if bad.any():
        d = np.diag(P).copy()
        P[bad] = 0.0
        np.fill_diagonal(P, np.where(np.isfinite(d), d, _BIG_VARIANCE))
    return P


def mahalanobis_sq(pose: Pose2, covariance, prior: Pose2, prior_covariance) -> float:
    """Squared Mahalanobis distance between two estimates of one relative pose, with their
    covariances added (independent errors). Infinite variances (directions the features
    do not fix) count as very large.

    >>> p, q = Pose2(0.3, 0.0, 0.0), Pose2(0.0, 0.0, 0.0)
    >>> round(mahalanobis_sq(p, np.eye(3) * 0.01, q, np.eye(3) * 0.08), 9)
    1.0
    """
    e = pose_difference(check_pose(pose, "pose"), check_pose(prior, "prior"))
    S = finite_covariance(check_covariance(covariance, "covariance")) + finite_covariance(
        check_covariance(prior_covariance, "prior_covariance")
    )
    try:
        d2 = float(e @ np.linalg.solve(S, e))
    except np.linalg.LinAlgError:  # a singular sum: zero variance in some direction
        d2 = float(e @ np.linalg.pinv(S) @ e)
    return d2 if math.isfinite(d2) and d2 >= 0 else float(e @ np.linalg.pinv(S) @ e)


def compose_covariance(T_ab: Pose2, cov_ab, T_bc: Pose2, cov_bc) -> np.ndarray:
    """Covariance of ``(x, y, theta)`` of ``T_ab @ T_bc`` to first order, the two
    independent."""
    c, s = math.cos(T_ab.theta), math.sin(T_ab.theta)
    rt = np.array([c * T_bc.x - s * T_bc.y, s * T_bc.x + c * T_bc.y])
    J1 = np.array([[1.0, 0.0, -rt[1]], [0.0, 1.0, rt[0]], [0.0, 0.0, 1.0]])
    J2 = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    A, B = (
        finite_covariance(check_covariance(cov_ab, "cov_ab")),
        finite_covariance(check_covariance(cov_bc, "cov_bc")),
    )
    return J1 @ A @ J1.T + J2 @ B @ J2.T


def inverse_covariance(T: Pose2, cov) -> np.ndarray:
    """Covariance of ``T.inverse()`` to first order."""
    c, s = math.cos(T.theta), math.sin(T.theta)
    # T^-1 = (-R^T t, -theta); d/dt = -R^T, d/dtheta = -dR^T/dtheta t, theta' = -theta
    J = np.array(
        [
            [-c, -s, -(-s * T.x + c * T.y)],
            [s, -c, -(-c * T.x - s * T.y)],
            [0.0, 0.0, -1.0],
        ]
    )
    return J @ finite_covariance(check_covariance(cov, "covariance")) @ J.T
