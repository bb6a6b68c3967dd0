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
from scipy.spatial import cKDTree

from . import _match_kernels as K
from .geometry import Pose2, rotation_matrix, wrap_angle
from .scan import Scan

__all__ = [
    "ReferenceCloud",
    "reference_cloud",
    "agreement",
    "free_space_conflicts",
    "nearest",
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
    tree : scipy.spatial.cKDTree or None
        Built only for clouds of more than :data:`BRUTE_FORCE_MAX` points; smaller ones
        are searched by bearing window (exact, compiled; see
        :mod:`scanclique._match_kernels`).
    """

    points: np.ndarray
    normals: np.ndarray
    bearings: np.ndarray
    index: tuple
    tree: cKDTree | None

    @property
    def windowed(self) -> bool:
        """True when queries use the compiled bearing-window search."""
        return self.tree is None


#: Clouds up to this many points are searched by bearing window (a few candidates per
#: query on a scan); larger ones (a dense window would hold thousands) by a KD-tree.
BRUTE_FORCE_MAX = 4096


def reference_cloud(points: np.ndarray, k: int = 5, radius: float = 0.3) -> ReferenceCloud:
    """Prepare ``(M, 2)`` points (sensor frame, the sensor at the origin) for
    :func:`agreement`, :func:`nearest` and the ICP."""
    p = np.ascontiguousarray(points, dtype=float).reshape(-1, 2)
    small = len(p) <= BRUTE_FORCE_MAX
    p, bear, index, normals = K.cloud_arrays(p, int(k), float(radius), small)
    if small:
        return ReferenceCloud(p, normals, bear, index, None)
    tree = cKDTree(p)
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
    return ReferenceCloud(p, normals, bear, index, tree)


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
    if ref.windowed:
        idx = np.empty(len(pts), dtype=np.int64)
        d2 = np.empty(len(pts))
        K.nearest_many(ref.index, ref.points, pts, *_moved(pose), max_distance, idx, d2)
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
    if ref.windowed:
        count = K.agreement_count(ref.index, ref.points, pts, *_moved(pose), float(inlier_distance))
        return count / len(pts)
    d, _ = ref.tree.query(pose.transform(pts), k=1, distance_upper_bound=inlier_distance)
    return float(np.mean(np.isfinite(d)))


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
    if ref.windowed:
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
    return _icp_tree(ref, pts, initial, iterations, max_correspondence, min_correspondence)


def _icp_tree(ref, pts, initial, iterations, max_correspondence, min_correspondence):
    """:func:`icp_point_to_line` over a KD-tree (clouds too large for the window search)."""
    x = initial.as_array()
    fitness, rmse, it = 0.0, math.inf, 0
    eps = K.ICP_POINT_WEIGHT
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
        scale = K.ICP_HUBER
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
        if (
            np.abs(dx[:2]).max() < K.ICP_STEP_T
            and abs(dx[2]) < K.ICP_STEP_R
            and dmax <= min_correspondence
        ):
            break
    return IcpResult(Pose2.from_array(x), fitness, rmse, it)
