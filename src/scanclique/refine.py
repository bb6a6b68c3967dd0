"""Raw-scan agreement and point-to-line ICP refinement (beyond the paper; stage 7's option).

The clique gives an association and a pose from a handful of features. Two things use
the raw points as well:

* :func:`agreement` scores a pose hypothesis by the fraction of B's points that land
  within ``inlier_distance`` of A's points. It ranks the hypotheses of distinct maximum
  cliques (environmental symmetry, paper §7).
* :func:`icp_point_to_line` refines a pose on the raw points (point-to-line ICP, seeded by
  the clique's pose; it never starts from nothing).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ._lazy import kernel_module
from .geometry import Pose2
from .scan import Scan

K = kernel_module("scanclique._match_kernels")

__all__ = [
    "ReferenceCloud",
    "reference_cloud",
    "agreement",
    "free_space_conflicts",
    "nearest",
    "weak_direction",
    "icp_covariance",
    "free_ranges",
    "search_index",
    "icp_point_to_line",
    "IcpResult",
]


@dataclass(frozen=True, slots=True, eq=False)
class ReferenceCloud:
    """A scan's valid points prepared for nearest-neighbour queries.

    Attributes
    ----------
    points : ndarray, shape (M, 2)
        The points (sensor frame), sorted by bearing (stable: a scan's beam order).
    normals : ndarray, shape (M, 2)
        Unit surface normals from a PCA of each point's neighbourhood (its 5 nearest
        points within 0.3 m; zero where fewer than 3 are that near).
    bearings : ndarray, shape (M,)
        ``atan2(y, x)`` of each point, ascending.
    index : tuple
        The search index of ``bearings`` (:func:`scanclique._match_kernels.make_index`).
        Queries search a window of bearings (exact, compiled; see
        :mod:`scanclique._match_kernels`): a few candidates per query on a laser scan. The
        pipeline caps its clouds at ``scanclique.match.CLOUD_MAX_POINTS`` points, where a
        window stays small.
    """

    points: np.ndarray
    normals: np.ndarray
    bearings: np.ndarray
    index: tuple


def reference_cloud(points: np.ndarray, k: int = 5, radius: float = 0.3) -> ReferenceCloud:
    """Prepare ``(M, 2)`` points (sensor frame, the sensor at the origin) for
    :func:`agreement`, :func:`nearest` and the ICP."""
    p = np.ascontiguousarray(points, dtype=float).reshape(-1, 2)
    p, bear, index, normals = K.cloud_arrays(p, int(k), float(radius), True)
    return ReferenceCloud(p, normals, bear, index)


def search_index(values: np.ndarray) -> tuple:
    """A compiled search index over ascending ``values`` (bearings, beam angles): two
    bins per value, each holding where its values start."""
    return K.make_index(np.array(values, dtype=float), 2.0)


def _moved(pose: Pose2 | None):
    if pose is None:
        return 1.0, 0.0, 0.0, 0.0
    return math.cos(pose.theta), math.sin(pose.theta), pose.x, pose.y


def nearest(ref: ReferenceCloud, points_b: np.ndarray, pose: Pose2, max_distance: float):
    """Nearest A point of each B point moved by ``pose`` (maps B into A), within
    ``max_distance``: ``(index into ref.points, distance)`` arrays, index -1 and distance
    inf when none."""
    pts = np.ascontiguousarray(points_b, dtype=float).reshape(-1, 2)
    idx = np.empty(len(pts), dtype=np.int64)
    d2 = np.empty(len(pts))
    K.nearest_many(ref.index, ref.points, pts, *_moved(pose), max_distance, idx, d2)
    found = idx >= 0
    return idx, np.where(found, np.sqrt(d2), np.inf)


def weak_direction(
    ref: ReferenceCloud, points_b: np.ndarray, pose: Pose2, max_distance: float
) -> tuple[np.ndarray, float] | None:
    """The direction of translation the point-to-line alignment of ``points_b`` onto
    ``ref`` (at ``pose``, which maps B into A) constrains least, and how much it
    constrains it: the eigenvector of smallest eigenvalue of ``mean(n n^T)`` over the unit
    normals ``n`` (A's frame) of the A points that B's points pair with within
    ``max_distance`` m, with that eigenvalue (0: the scans slide freely along it, as in a
    featureless corridor; 0.5: every direction alike). None when fewer than 10 points
    pair (or have a normal)."""
    idx, d = nearest(ref, points_b, pose, max_distance)
    n = ref.normals[idx[np.isfinite(d)]]
    n = n[np.einsum("ij,ij->i", n, n) > 0.5]
    if len(n) < 10:
        return None
    w, v = np.linalg.eigh(n.T @ n / len(n))
    return v[:, 0], float(w[0])


def icp_covariance(
    ref: ReferenceCloud, points_b: np.ndarray, pose: Pose2, max_distance: float
) -> np.ndarray | None:
    """Covariance ``(3, 3)`` of ``(x, y, theta)`` (m, rad) of a point-to-line alignment of
    ``points_b`` onto ``ref`` at ``pose`` (maps B into A), from the curvature of its cost:
    ``s^2 (J^T J)^-1`` with one row ``J_k = (n_x, n_y, n . (R' p_k))`` per B point paired
    within ``max_distance`` m with an A point of unit normal ``n`` (``R'`` the derivative
    of the rotation, ``p_k`` the B point), and ``s^2`` the mean squared point-to-line
    residual of the pairs (at least ``(max_distance / 10)^2``: a perfect fit is no
    perfect measurement).

    The pairs' errors are treated as independent, which neighbouring points on one wall
    are not: the result is a lower bound (Censi 2007), to be floored by the caller. None
    when fewer than 10 points pair (or have a normal), or when the pairs leave a direction
    unconstrained (singular ``J^T J``).
    """
    pts = np.ascontiguousarray(points_b, dtype=float).reshape(-1, 2)
    idx, d = nearest(ref, pts, pose, max_distance)
    ok = np.isfinite(d)
    n = ref.normals[idx[ok]]
    good = np.einsum("ij,ij->i", n, n) > 0.5
    n, a, p = n[good], ref.points[idx[ok]][good], pts[ok][good]
    if len(n) < 10:
        return None
    c, s = math.cos(pose.theta), math.sin(pose.theta)
    rp = p @ np.array([[c, s], [-s, c]])  # R p, row-wise
    q = rp + (pose.x, pose.y)
    res = np.einsum("ij,ij->i", n, q - a)
    J = np.column_stack((n, n[:, 0] * -rp[:, 1] + n[:, 1] * rp[:, 0]))
    H = J.T @ J
    if np.linalg.cond(H) > 1e12:
        return None
    s2 = max(float(np.mean(res**2)), (max_distance / 10.0) ** 2)
    cov = s2 * np.linalg.inv(H)
    return 0.5 * (cov + cov.T)


def agreement(
    ref: ReferenceCloud, points_b: np.ndarray, pose: Pose2, inlier_distance: float
) -> float:
    """Fraction of B's points within ``inlier_distance`` of A's points under ``pose``
    (``pose`` maps B's frame into A's). 0 when B has no points."""
    pts = np.ascontiguousarray(points_b, dtype=float).reshape(-1, 2)
    if len(pts) == 0 or len(ref.points) == 0:
        return 0.0
    count = K.agreement_count(ref.index, ref.points, pts, *_moved(pose), float(inlier_distance))
    return count / len(pts)


def free_ranges(scan: Scan) -> np.ndarray:
    """The free range along each beam of ``scan``: the measured range where valid, 0
    (nothing known) otherwise."""
    return np.where(scan.valid, scan.ranges, 0.0)


def free_space_conflicts(
    scan: Scan,
    points: np.ndarray,
    margin: float = 0.2,
    ratio: float = 0.02,
    pose: Pose2 | None = None,
) -> float:
    """Fraction of ``points`` (in ``scan``'s sensor frame, or moved there by ``pose`` when
    given) that lie in the space the scan saw through: nearer than the measured ranges of
    the nearest beams by more than ``margin + ratio * range`` metres.

    A point there contradicts the scan (the beam would have stopped on it), so a wrong pose
    — a corridor slid along itself, a symmetric room turned around — shows conflicts that
    a mere nearest-neighbour agreement misses. Beams with no valid return are no evidence
    either way. 0 when there are no points.
    """
    p = np.ascontiguousarray(points, dtype=float).reshape(-1, 2)
    n = scan.n_beams
    if len(p) == 0 or n < 2:
        return 0.0
    # a point conflicts only when its beam and both neighbours saw past it
    count = K.conflict_count(
        search_index(scan.angles), free_ranges(scan), p, *_moved(pose), float(margin), float(ratio)
    )
    return count / len(p)


@dataclass(frozen=True, slots=True, eq=False)
class IcpResult:
    """Outcome of :func:`icp_point_to_line`: the refined pose (maps B into A), the fraction of
    B's points within the final correspondence distance, their RMS point-to-line error, and
    the iterations run."""

    pose: Pose2
    fitness: float
    rmse: float
    iterations: int


def icp_point_to_line(
    ref: ReferenceCloud,
    points_b: np.ndarray,
    initial: Pose2,
    *,
    iterations: int = 15,
    max_correspondence: float = 0.5,
    min_correspondence: float = 0.1,
) -> IcpResult:
    """Point-to-line ICP of B's points onto A's, from ``initial`` (maps B into A).

    Each iteration pairs every transformed B point with its nearest A point within a
    correspondence distance that shrinks geometrically from ``max_correspondence`` to
    ``min_correspondence``, then solves the linearised point-to-line problem
    ``min sum w (n·(R p + t - q))² + eps |R p + t - q|²`` (the small point-to-point term
    keeps sliding along a corridor bounded) with Huber weights.
    """
    pts = np.ascontiguousarray(points_b, dtype=float).reshape(-1, 2)
    if len(pts) < 3 or len(ref.points) < 3:
        return IcpResult(initial, 0.0, math.inf, 0)
    out = np.empty(3)
    fitness, rmse, it = K.icp(
        ref.index,
        ref.points,
        ref.normals,
        pts,
        initial.as_array(),
        int(iterations),
        float(max_correspondence),
        float(min_correspondence),
        out,
    )
    return IcpResult(Pose2.from_array(out), float(fitness), float(rmse), int(it))
