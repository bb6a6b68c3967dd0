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

import numba
import numpy as np
from scipy.spatial import cKDTree

from .geometry import Pose2, rotation_matrix, wrap_angle
from .scan import Scan

__all__ = [
    "ReferenceCloud",
    "reference_cloud",
    "agreement",
    "free_space_conflicts",
    "nearest",
    "icp_point_to_line",
    "IcpResult",
]


@dataclass(frozen=True, slots=True, eq=False)
class ReferenceCloud:
    """Scan A's valid points prepared for nearest-neighbour queries.

    Attributes
    ----------
    points : ndarray, shape (M, 2)
    normals : ndarray, shape (M, 2)
        Unit surface normals from a PCA of each point's neighbourhood (zero where the
        neighbourhood is too thin to say).
    tree : scipy.spatial.cKDTree
    """

    points: np.ndarray
    normals: np.ndarray
    tree: cKDTree


def reference_cloud(points: np.ndarray, k: int = 5, radius: float = 0.3) -> ReferenceCloud:
    """Prepare ``(M, 2)`` points (sensor frame of A) for :func:`agreement` and ICP."""
    p = np.ascontiguousarray(points, dtype=float).reshape(-1, 2)
    tree = cKDTree(p)
    normals = np.zeros_like(p)
    if len(p) >= 3:
        kk = min(k, len(p))
        d, idx = tree.query(p, k=kk)
        nb = p[idx]  # (M, k, 2)
        w = (d <= radius).astype(float)
        cnt = w.sum(axis=1)
        mean = np.einsum("mk,mkd->md", w, nb) / np.maximum(cnt, 1)[:, None]
        q = (nb - mean[:, None, :]) * w[:, :, None]
        cov = np.einsum("mki,mkj->mij", q, q)
        _, vec = np.linalg.eigh(cov)
        normals = vec[:, :, 0]
        normals[cnt < 3] = 0.0
    return ReferenceCloud(p, normals, tree)


#: Reference clouds up to this many points are searched by compiled brute force (exact, and
#: far cheaper than a KD-tree query's overhead at scan sizes); larger ones by the KD-tree.
BRUTE_FORCE_MAX = 4096


@numba.njit(cache=True, nogil=True)
def _nearest_kernel(ref, pts, c, s, tx, ty, dmax2, idx_out, d2_out):  # pragma: no cover
    """For each point of ``pts`` moved by (R(c, s), t): index of and squared distance to its
    nearest ``ref`` point within ``sqrt(dmax2)`` (index -1 and dmax2 when none)."""
    for i in range(pts.shape[0]):
        x = c * pts[i, 0] - s * pts[i, 1] + tx
        y = s * pts[i, 0] + c * pts[i, 1] + ty
        best = dmax2
        bj = -1
        for j in range(ref.shape[0]):
            dx = ref[j, 0] - x
            dy = ref[j, 1] - y
            d2 = dx * dx + dy * dy
            if d2 < best:
                best = d2
                bj = j
        idx_out[i] = bj
        d2_out[i] = best


@numba.njit(cache=True, nogil=True)
def _agreement_kernel(ref, pts, c, s, tx, ty, d2max):  # pragma: no cover
    """How many moved ``pts`` have a ``ref`` point within ``sqrt(d2max)``."""
    count = 0
    for i in range(pts.shape[0]):
        x = c * pts[i, 0] - s * pts[i, 1] + tx
        y = s * pts[i, 0] + c * pts[i, 1] + ty
        for j in range(ref.shape[0]):
            dx = ref[j, 0] - x
            dy = ref[j, 1] - y
            if dx * dx + dy * dy < d2max:
                count += 1
                break
    return count


@numba.njit(cache=True, nogil=True)
def _conflict_kernel(angles, free, pts, c, s, tx, ty, margin, ratio):  # pragma: no cover
    """How many moved ``pts`` lie in the free space seen along the nearest beams."""
    n = angles.size
    half = 0.5 * (angles[n - 1] - angles[0]) / (n - 1)
    count = 0
    for i in range(pts.shape[0]):
        x = c * pts[i, 0] - s * pts[i, 1] + tx
        y = s * pts[i, 0] + c * pts[i, 1] + ty
        phi = math.atan2(y, x)
        if phi < angles[0] - half or phi > angles[n - 1] + half:
            continue
        r = math.sqrt(x * x + y * y)
        k = np.searchsorted(angles, phi)
        k = min(max(k, 1), n - 1)
        if abs(angles[k - 1] - phi) < abs(angles[k] - phi):
            k -= 1
        lo = free[k]
        if k > 0:
            lo = min(lo, free[k - 1])
        if k < n - 1:
            lo = min(lo, free[k + 1])
        if r < lo - (margin + ratio * r):
            count += 1
    return count


def _moved(pose: Pose2 | None):
    if pose is None:
        return 1.0, 0.0, 0.0, 0.0
    return math.cos(pose.theta), math.sin(pose.theta), pose.x, pose.y


def nearest(ref: ReferenceCloud, points_b: np.ndarray, pose: Pose2, max_distance: float):
    """Nearest A point of each B point moved by ``pose`` (maps B into A), within
    ``max_distance``: ``(index, distance)`` arrays, index -1 and distance inf when none."""
    pts = np.ascontiguousarray(points_b, dtype=float).reshape(-1, 2)
    if len(ref.points) <= BRUTE_FORCE_MAX:
        idx = np.empty(len(pts), dtype=np.int64)
        d2 = np.empty(len(pts))
        _nearest_kernel(ref.points, pts, *_moved(pose), max_distance**2, idx, d2)
        found = idx >= 0
        return idx, np.where(found, np.sqrt(d2), np.inf)
    d, idx = ref.tree.query(pose.transform(pts), k=1, distance_upper_bound=max_distance)
    found = np.isfinite(d)
    return np.where(found, idx, -1), d


def agreement(
    ref: ReferenceCloud, points_b: np.ndarray, pose: Pose2, inlier_distance: float
) -> float:
    """Fraction of B's points within ``inlier_distance`` of A's points under ``pose``
    (``pose`` maps B's frame into A's). 0 when B has no points."""
    pts = np.ascontiguousarray(points_b, dtype=float).reshape(-1, 2)
    if len(pts) == 0 or len(ref.points) == 0:
        return 0.0
    if len(ref.points) <= BRUTE_FORCE_MAX:
        count = _agreement_kernel(ref.points, pts, *_moved(pose), inlier_distance**2)
        return count / len(pts)
    d, _ = ref.tree.query(pose.transform(pts), k=1, distance_upper_bound=inlier_distance)
    return float(np.mean(np.isfinite(d)))


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
    # free range along each beam: the measured range where valid, unknown (0) otherwise;
    # a point conflicts only when its beam and both neighbours saw past it
    free = np.where(scan.valid, scan.ranges, 0.0)
    count = _conflict_kernel(scan.angles, free, p, *_moved(pose), float(margin), float(ratio))
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
    pts = np.asarray(points_b, dtype=float).reshape(-1, 2)
    x = initial.as_array()
    fitness, rmse, it = 0.0, math.inf, 0
    if len(pts) < 3 or len(ref.points) < 3:
        return IcpResult(initial, 0.0, math.inf, 0)
    eps = 0.05
    for it in range(1, iterations + 1):
        dmax = max(min_correspondence, max_correspondence * 0.7 ** (it - 1))
        R = rotation_matrix(x[2])
        pb = pts @ R.T + x[:2]
        idx, d = nearest(ref, pts, Pose2.from_array(x), dmax)
        ok = idx >= 0
        if ok.sum() < 3:
            break
        p, q, n = pb[ok], ref.points[idx[ok]], ref.normals[idx[ok]]
        src = pts[ok]
        diff = p - q
        # rotation derivative of R p about the current estimate: dR/dθ p = J p
        rp = src @ R.T
        dp = np.column_stack((-rp[:, 1], rp[:, 0]))
        r_line = np.einsum("kd,kd->k", n, diff)
        J_line = np.column_stack((n[:, 0], n[:, 1], np.einsum("kd,kd->k", n, dp)))
        scale = 0.05
        w = np.where(np.abs(r_line) < scale, 1.0, scale / np.maximum(np.abs(r_line), 1e-12))
        H = (J_line * w[:, None]).T @ J_line
        g = (J_line * w[:, None]).T @ r_line
        # weak point-to-point term
        Jx = np.column_stack((np.ones(len(p)), np.zeros(len(p)), dp[:, 0]))
        Jy = np.column_stack((np.zeros(len(p)), np.ones(len(p)), dp[:, 1]))
        H += eps * (Jx.T @ Jx + Jy.T @ Jy)
        g += eps * (Jx.T @ diff[:, 0] + Jy.T @ diff[:, 1])
        H += np.eye(3) * 1e-9
        dx = -np.linalg.solve(H, g)
        x = x + dx
        x[2] = float(wrap_angle(x[2]))
        fitness = float(ok.mean())
        rmse = float(np.sqrt(np.mean(r_line**2)))
        if np.abs(dx[:2]).max() < 1e-4 and abs(dx[2]) < 1e-5 and dmax <= min_correspondence:
            break
    return IcpResult(Pose2.from_array(x), fitness, rmse, it)
