"""Relative pose from mapped features (paper §6; pipeline stage 7).

Given pairs of features of scans A and B known to be the same physical features, find the
pose ``T_a_b`` of B's sensor frame in A's frame (it maps B points into A:
``p_a = R(theta) p_b + t``).

* :func:`estimate_pose_median` — the paper's method: the median rotation, then, with B
  rotated by it, the median translation that overlays the features.
* :func:`estimate_pose_lsq` — weighted least squares: Arun et al. (1987) closed form for
  the points as a start, then Gauss–Newton on all residuals, points and lines together.
  A line pair ``(rho_a, alpha_a) ~ (rho_b, alpha_b)`` adds a normal-direction residual
  ``alpha_b + theta - alpha_a`` and an offset residual ``rho_b + n(alpha_b + theta)·t -
  rho_a``. The covariance is the inverse information ``(J^T W J)^-1`` at the solution: the
  precision the constellation of mapped features allows (paper §7), so a corridor seen only
  along its walls shows a large along-corridor variance.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np
from scipy.special import chdtri

from ._lazy import kernel_module
from .features import Features
from .geometry import Pose2, rotation_matrix, wrap_angle

K = kernel_module("scanclique._match_kernels")

__all__ = [
    "PoseEstimate",
    "MappedFeatures",
    "mapped_features",
    "estimate_pose_lsq",
    "estimate_pose_median",
    "arun_2d",
    "closed_form_pose",
    "pair_consistent",
    "points_first",
    "closed_form_pose_pairs",
    "estimate_pose_lsq_pairs",
    "covariance_from_information",
]


@dataclass(frozen=True, slots=True, eq=False)
class MappedFeatures:
    """The geometry of mapped feature pairs, gathered from two :class:`Features`.

    ``points_a[k]`` corresponds to ``points_b[k]``; ``lines_a[k]`` (rho, alpha) to
    ``lines_b[k]``. Covariances come along for weighting.
    """

    points_a: np.ndarray  # (Kp, 2)
    points_b: np.ndarray  # (Kp, 2)
    points_cov_a: np.ndarray  # (Kp, 2, 2)
    points_cov_b: np.ndarray  # (Kp, 2, 2)
    lines_a: np.ndarray  # (Kl, 2) rho, alpha
    lines_b: np.ndarray  # (Kl, 2)
    lines_cov_a: np.ndarray  # (Kl, 2, 2)
    lines_cov_b: np.ndarray  # (Kl, 2, 2)
    lines_mid_b: np.ndarray  # (Kl, 2) segment mid point of B's line

    @property
    def n_points(self) -> int:
        return int(self.points_a.shape[0])

    @property
    def n_lines(self) -> int:
        return int(self.lines_a.shape[0])


def mapped_features(fa: Features, fb: Features, node_pairs: np.ndarray) -> MappedFeatures:
    """Gather the geometry of mapped node pairs (node order: points first, then lines)."""
    node_pairs = np.asarray(node_pairs, dtype=np.int64).reshape(-1, 2)
    pa, pb = fa.n_points, fb.n_points
    is_pt = node_pairs[:, 0] < pa
    ip = node_pairs[is_pt]
    il = node_pairs[~is_pt] - np.array([pa, pb])
    return MappedFeatures(
        points_a=fa.points_xy[ip[:, 0]],
        points_b=fb.points_xy[ip[:, 1]],
        points_cov_a=fa.points_cov[ip[:, 0]],
        points_cov_b=fb.points_cov[ip[:, 1]],
        lines_a=fa.lines_rho_alpha[il[:, 0]],
        lines_b=fb.lines_rho_alpha[il[:, 1]],
        lines_cov_a=fa.lines_cov[il[:, 0]],
        lines_cov_b=fb.lines_cov[il[:, 1]],
        lines_mid_b=fb.lines_ends[il[:, 1]].mean(axis=1),
    )


@dataclass(frozen=True, slots=True, eq=False)
class PoseEstimate:
    """A pose with its quality.

    Attributes
    ----------
    pose : Pose2
        ``T_a_b``: maps points of B's frame into A's frame.
    covariance : ndarray, shape (3, 3)
        Covariance of ``(x, y, theta)`` (m², m·rad, rad²); ``inf`` on the diagonal in
        directions the features do not constrain.
    rms : float
        Root mean square of the normalised residuals (1 for a fit at the assumed noise).
    residuals : ndarray, shape (K,)
        Mahalanobis distance of each mapped pair at the solution (points first, then lines).
    degenerate : bool
        True when the features do not fix all three degrees of freedom.
    """

    pose: Pose2
    covariance: np.ndarray
    rms: float
    residuals: np.ndarray
    degenerate: bool

    def __post_init__(self) -> None:
        for name in ("covariance", "residuals"):
            a = np.array(getattr(self, name), dtype=float)
            a.setflags(write=False)
            object.__setattr__(self, name, a)


def arun_2d(points_a: np.ndarray, points_b: np.ndarray, weights=None) -> Pose2:
    """Least-squares rigid motion mapping ``points_b`` onto ``points_a`` (Arun et al. 1987).

    Minimises ``sum_k w_k |R p_b,k + t - p_a,k|²``; needs at least two distinct points.

    Examples
    --------
    >>> T = Pose2.from_xytheta(1.0, -2.0, 0.5)
    >>> pb = np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 2.0]])
    >>> arun_2d(T.transform(pb), pb).as_array().round(9)
    array([ 1. , -2. ,  0.5])
    """
    a = np.asarray(points_a, float)
    b = np.asarray(points_b, float)
    w = np.ones(len(a)) if weights is None else np.asarray(weights, float)
    w = w / w.sum()
    ca, cb = w @ a, w @ b
    qa, qb = a - ca, b - cb
    # 2D: theta = atan2(sum w (qb x qa), sum w (qb . qa))
    s = float(np.sum(w * (qb[:, 0] * qa[:, 1] - qb[:, 1] * qa[:, 0])))
    c = float(np.sum(w * (qb[:, 0] * qa[:, 0] + qb[:, 1] * qa[:, 1])))
    theta = math.atan2(s, c)
    t = ca - rotation_matrix(theta) @ cb
    return Pose2(t[0], t[1], theta)


def _circular_median(angles: np.ndarray) -> float:
    """Median of angles about their circular mean (robust to a few outliers)."""
    ref = math.atan2(np.sin(angles).sum(), np.cos(angles).sum())
    return float(wrap_angle(ref + np.median(wrap_angle(angles - ref))))


def estimate_pose_median(m: MappedFeatures) -> PoseEstimate | None:
    """The paper's §6 estimate: median rotation, then median translation.

    Rotation candidates come from every mapped line pair (``alpha_a - alpha_b``) and every
    pair of mapped points (the change of direction of the segment joining them); the
    translation from every mapped point (``p_a - R p_b``) and, when there are fewer than two
    points, from line offsets by least squares. Returns None when the features cannot fix
    a pose. The covariance is that of the least-squares estimate at the median pose.
    """
    rots = []
    if m.n_lines:
        rots.append(wrap_angle(m.lines_a[:, 1] - m.lines_b[:, 1]))
    if m.n_points >= 2:
        i, j = np.triu_indices(m.n_points, 1)
        va = m.points_a[j] - m.points_a[i]
        vb = m.points_b[j] - m.points_b[i]
        keep = (np.linalg.norm(va, axis=1) > 0.3) & (np.linalg.norm(vb, axis=1) > 0.3)
        rots.append(
            wrap_angle(np.arctan2(va[keep, 1], va[keep, 0]) - np.arctan2(vb[keep, 1], vb[keep, 0]))
        )
    rots = np.concatenate(rots) if rots else np.zeros(0)
    if rots.size == 0:
        return None
    theta = _circular_median(rots)
    R = rotation_matrix(theta)
    if m.n_points >= 2 or (m.n_points >= 1 and m.n_lines == 0):
        t = np.median(m.points_a - m.points_b @ R.T, axis=0)
    else:
        t = _translation_lsq(m, theta)
        if t is None:
            return None
    pose = Pose2(t[0], t[1], theta)
    cov, res, rms, degenerate = _information(m, pose)
    return PoseEstimate(pose, cov, rms, res, degenerate)


def _translation_lsq(m: MappedFeatures, theta: float) -> np.ndarray | None:
    """Translation given the rotation, from points (two rows each) and line offsets (one
    row each: ``n(alpha_b + theta) · t = rho_a - rho_b``), unweighted least squares."""
    R = rotation_matrix(theta)
    ap = m.lines_b[:, 1] + theta
    A = np.concatenate(
        (np.tile(np.eye(2), (m.n_points, 1)), np.column_stack((np.cos(ap), np.sin(ap))))
    )
    b = np.concatenate(
        ((m.points_a - m.points_b @ R.T).reshape(-1), m.lines_a[:, 0] - m.lines_b[:, 0])
    )
    if A.shape[0] == 0:
        return None
    t, *_ = np.linalg.lstsq(A, b, rcond=None)
    return t


def closed_form_pose(m: MappedFeatures) -> Pose2 | None:
    """A quick pose from mapped features: rotation from Arun et al. on the points (two or
    more, spread over 0.2 m) or else the circular mean of the line normal rotations, then the
    least-squares translation. The start of :func:`estimate_pose_lsq`. None when the
    features cannot fix a rotation.

    The NumPy reference: the pipeline runs the compiled
    :func:`scanclique._match_kernels.closed_form` (:func:`closed_form_pose_pairs`), which
    the tests hold to this."""
    if m.n_points >= 2 and np.ptp(m.points_b, axis=0).max() > 0.2:
        theta = arun_2d(m.points_a, m.points_b).theta
    elif m.n_lines:
        rot = wrap_angle(m.lines_a[:, 1] - m.lines_b[:, 1])
        theta = math.atan2(np.sin(rot).sum(), np.cos(rot).sum())
    else:
        return None
    t = _translation_lsq(m, theta)
    return None if t is None else Pose2(t[0], t[1], theta)


def pair_consistent(
    m: MappedFeatures, pose: Pose2, point_tol: float, line_angle_tol: float, line_offset_tol: float
) -> np.ndarray:
    """Which mapped pairs agree with ``pose`` (maps B into A): points within ``point_tol``
    metres; lines within ``line_angle_tol`` radians and ``line_offset_tol`` metres.
    Boolean array, points first then lines (the order of :func:`mapped_features`).

    The NumPy reference of :func:`pair_consistent_pairs` (compiled), which the pipeline
    and validation run and the tests hold to this."""
    ok_p = (
        np.linalg.norm(pose.transform(m.points_b) - m.points_a, axis=1) <= point_tol
        if m.n_points
        else np.zeros(0, bool)
    )
    if m.n_lines:
        ap = m.lines_b[:, 1] + pose.theta
        off = m.lines_b[:, 0] + np.cos(ap) * pose.x + np.sin(ap) * pose.y - m.lines_a[:, 0]
        ok_l = (np.abs(wrap_angle(ap - m.lines_a[:, 1])) <= line_angle_tol) & (
            np.abs(off) <= line_offset_tol
        )
    else:
        ok_l = np.zeros(0, bool)
    return np.concatenate((ok_p, ok_l))


def _residuals_jacobian(m: MappedFeatures, pose: Pose2):
    """Stacked residuals r, Jacobian J (w.r.t. x, y, theta) and per-residual-block
    covariances for all mapped pairs, at ``pose``."""
    th = pose.theta
    R = rotation_matrix(th)
    dR = np.array([[-math.sin(th), -math.cos(th)], [math.cos(th), -math.sin(th)]])
    t = pose.translation
    r_list, J_list, C_list = [], [], []
    if m.n_points:
        pred = m.points_b @ R.T + t
        r = pred - m.points_a  # (Kp, 2)
        J = np.zeros((m.n_points, 2, 3))
        J[:, :, 0] = [1.0, 0.0]
        J[:, :, 1] = [0.0, 1.0]
        J[:, :, 2] = m.points_b @ dR.T
        C = m.points_cov_a + R @ m.points_cov_b @ R.T
        r_list.append(r)
        J_list.append(J)
        C_list.append(C)
    if m.n_lines:
        rho_a, al_a = m.lines_a[:, 0], m.lines_a[:, 1]
        rho_b, al_b = m.lines_b[:, 0], m.lines_b[:, 1]
        ap = al_b + th
        n = np.column_stack((np.cos(ap), np.sin(ap)))
        dn = np.column_stack((-np.sin(ap), np.cos(ap)))
        r = np.column_stack((rho_b + n @ t - rho_a, wrap_angle(ap - al_a)))
        J = np.zeros((m.n_lines, 2, 3))
        J[:, 0, 0:2] = n
        J[:, 0, 2] = dn @ t
        J[:, 1, 2] = 1.0
        # B's line expressed in A is (rho_b + n(alpha_b + theta)·t, alpha_b + theta): its
        # offset moves with alpha_b through the lever arm dn·t, so B's (rho, alpha)
        # covariance enters through G = [[1, dn·t], [0, 1]]; A's enters as it is.
        G = np.zeros((m.n_lines, 2, 2))
        G[:, 0, 0] = G[:, 1, 1] = 1.0
        G[:, 0, 1] = dn @ t
        C = m.lines_cov_a + G @ m.lines_cov_b @ G.transpose(0, 2, 1)
        r_list.append(r)
        J_list.append(J)
        C_list.append(C)
    return np.concatenate(r_list), np.concatenate(J_list), np.concatenate(C_list)


@functools.lru_cache(maxsize=256)
def _chi2_99(dof: int) -> float:
    """The 99 % quantile of the chi-square distribution with ``dof`` degrees of freedom."""
    return float(chdtri(dof, 0.01))


def _information(m: MappedFeatures, pose: Pose2):
    r, J, C = _residuals_jacobian(m, pose)
    Ci = np.linalg.inv(C + np.eye(2) * 1e-12)
    info = np.einsum("kai,kab,kbj->ij", J, Ci, J)
    maha = np.sqrt(np.maximum(np.einsum("ka,kab,kb->k", r, Ci, r), 0.0))
    cov, rms, degenerate = covariance_from_information(info, float(np.sum(maha**2)), len(r))
    return cov, maha, rms, degenerate


def covariance_from_information(info: np.ndarray, ssr: float, n_pairs: int):
    """Pose covariance from the information matrix ``info`` (3x3) of ``n_pairs`` mapped
    pairs (two residuals each) whose squared Mahalanobis residuals sum to ``ssr``.

    Returns ``(covariance, rms, degenerate)``: ``rms`` is the root mean square normalised
    residual (``sqrt(ssr / dof)``, ``dof = 2 n - 3``); when the residuals fail the
    chi-square test at 1 % the covariance is scaled by ``rms**2`` (the constellation
    disagrees with the assumed feature noise, and a misfit pair biases the pose beyond
    it). Directions the features do not constrain get ``inf`` in exactly the entries they
    touch (an axis-aligned corridor keeps finite across-corridor and heading variances).
    """
    dof = max(2 * n_pairs - 3, 1)
    rms = float(math.sqrt(ssr / dof))
    scale = rms**2 if 2 * n_pairs > 3 and ssr > _chi2_99(dof) else 1.0
    cov = np.empty((3, 3))
    full = K.covariance(np.ascontiguousarray(info, dtype=float), float(scale), cov)
    return cov, rms, not full


def estimate_pose_lsq(
    m: MappedFeatures, initial: Pose2 | None = None, iterations: int = 5
) -> PoseEstimate | None:
    """Weighted least-squares pose from mapped points and lines, with covariance.

    Starts from ``initial`` or from a closed form (Arun et al. on the points when there are
    two or more, else the circular mean of the line normal rotations), then runs
    Gauss–Newton on all residuals weighted by the inverse of the pairs' combined
    covariances. Returns None when the features cannot fix the rotation (fewer than two
    points and no line).

    The NumPy reference of :func:`estimate_pose_lsq_pairs` (compiled), which the pipeline
    and validation run and the tests hold to this.
    """
    if initial is None:
        initial = closed_form_pose(m)
        if initial is None:
            return None
    x = initial.as_array()
    for _ in range(iterations):
        pose = Pose2.from_array(x)
        r, J, C = _residuals_jacobian(m, pose)
        Ci = np.linalg.inv(C + np.eye(2) * 1e-12)
        H = np.einsum("kai,kab,kbj->ij", J, Ci, J)
        g = np.einsum("kai,kab,kb->i", J, Ci, r)
        H = H + np.eye(3) * 1e-9 * max(np.trace(H), 1e-12)
        dx = -np.linalg.lstsq(H, g, rcond=None)[0]
        x = x + dx
        x[2] = float(wrap_angle(x[2]))
        if np.abs(dx).max() < 1e-6:
            break
    pose = Pose2.from_array(x)
    cov, res, rms, degenerate = _information(m, pose)
    return PoseEstimate(pose, cov, rms, res, degenerate)


# --------------------------------------------------------------------------------------
# The same estimates straight from two Features and node pairs (compiled)
# --------------------------------------------------------------------------------------
def points_first(node_pairs: np.ndarray, n_points_a: int) -> np.ndarray:
    """Node pairs ``(K, 2)`` reordered points first, then lines, each in their order (the
    order of :func:`mapped_features` and of the residuals)."""
    node_pairs = np.asarray(node_pairs, dtype=np.int64).reshape(-1, 2)
    order = np.argsort(node_pairs[:, 0] >= n_points_a, kind="stable")
    return np.ascontiguousarray(node_pairs[order])


def closed_form_pose_pairs(fa: Features, fb: Features, node_pairs: np.ndarray) -> Pose2 | None:
    """:func:`closed_form_pose` of ``mapped_features(fa, fb, node_pairs)``, compiled."""
    pairs = np.ascontiguousarray(node_pairs, dtype=np.int64).reshape(-1, 2)
    out = np.empty(3)
    ok = K.closed_form(
        pairs,
        fa.n_points,
        fb.n_points,
        fa.points_xy,
        fb.points_xy,
        fa.lines_rho_alpha,
        fb.lines_rho_alpha,
        out,
    )
    return Pose2.from_array(out) if ok else None


def pair_consistent_pairs(
    fa: Features,
    fb: Features,
    node_pairs: np.ndarray,
    pose: Pose2,
    point_tol: float,
    line_angle_tol: float,
    line_offset_tol: float,
) -> np.ndarray:
    """:func:`pair_consistent` of ``mapped_features(fa, fb, node_pairs)``, compiled: which
    of the node pairs ``(K, 2)`` (in their given order) agree with ``pose`` (maps B into
    A) within the tolerances (metres, radians, metres)."""
    pairs = np.ascontiguousarray(node_pairs, dtype=np.int64).reshape(-1, 2)
    return K.consistent(
        pairs, fa.n_points, fb.n_points, fa.points_xy, fb.points_xy,
        fa.lines_rho_alpha, fb.lines_rho_alpha, pose.as_array(),
        float(point_tol), float(line_angle_tol), float(line_offset_tol),
    )  # fmt: skip


def estimate_pose_lsq_pairs(
    fa: Features,
    fb: Features,
    node_pairs: np.ndarray,
    initial: Pose2 | None = None,
    iterations: int = 5,
) -> PoseEstimate | None:
    """:func:`estimate_pose_lsq` of ``mapped_features(fa, fb, node_pairs)``: the same
    weighted Gauss–Newton and covariance, compiled, without gathering the features.
    Residuals are in points-first order (:func:`points_first`)."""
    pairs = points_first(node_pairs, fa.n_points)
    if initial is None:
        initial = closed_form_pose_pairs(fa, fb, pairs)
        if initial is None:
            return None
    info = np.empty((3, 3))
    maha = np.empty(len(pairs))
    x, ssr = K.lsq_pose(
        pairs,
        fa.n_points,
        fb.n_points,
        fa.points_xy,
        fa.points_cov,
        fa.lines_rho_alpha,
        fa.lines_cov,
        fb.points_xy,
        fb.points_cov,
        fb.lines_rho_alpha,
        fb.lines_cov,
        initial.as_array(),
        int(iterations),
        info,
        maha,
    )
    cov, rms, degenerate = covariance_from_information(info, float(ssr), len(pairs))
    return PoseEstimate(Pose2.from_array(x), cov, rms, maha, degenerate)
