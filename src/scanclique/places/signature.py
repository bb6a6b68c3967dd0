"""Rotation-invariant signatures of prepared scans: the prefilter of place recognition.

A place database cannot run the clique matcher (a few milliseconds per pair) against tens
of thousands of places per query. The prefilter ranks the places by a cheap distance
between *signatures*, vectors computed once per scan from what the pipeline already has
(:class:`scanclique.match.PreparedScan`), and only the best few candidates are verified
by the matcher (:mod:`scanclique.places.verify`).

A signature is a concatenation of histograms ("blocks"), each invariant to a rotation of
the sensor, and all but the first to a translation of the same surfaces too:

``range``
    the valid ranges (distance of each return from the sensor);
``distance``
    the distances between pairs of the scan's sample points (the D2 shape distribution of
    Osada et al. 2002);
``normal``
    the angles between the surface normals of pairs of points, folded to ``[0, pi/2]``
    (angle-histogram matching, Weiss et al. 1994, made rotation-free by differencing);
``feature``
    the invariant edge labels of the feature graph (paper §5.1) by kind pair:
    point–point distances, point–line perpendicular distances, line–line acute angles;
``pair``
    a joint histogram of *point pair features* (Drost et al. 2010, in 2D): for pairs of
    points with surface normals, the distance between them and the two angles between
    their normals and the segment joining them (as ``|cos|``, the smaller first, since a
    normal's sign is arbitrary): 8 distance bins x 4 x 4 angle bins. Joint, it tells a
    corridor (pairs across it meet both walls head-on) from a room of the same size.
``local``
    the same joint histogram over *local* pairs only, at most :data:`LOCAL_RADIUS`
    apart (distance bins linear up to it), of the cloud's points thinned to about one per
    :data:`LOCAL_SPACING` of the scan's length: a histogram of the local shapes of the
    surfaces in view, to which each stretch of surface adds its own counts whatever else
    is in view. A revisit that shares only part of the view (the other half of the
    field of view is elsewhere, e.g. a corridor walked the other way) keeps the shared
    part's counts, where every pair of the whole scan (``distance``, ``pair``) mixes the
    shared part with the rest. It has as much weight as all the other blocks together.

The prefilter's recall (a place it drops can never be recognised) is measured by
``benchmarks/places.py``; each block alone ranks a true place among the first 10 for
about half to two thirds of the queries on the shared logs, together somewhat more. The
revisits it misses are mostly seen from a very different heading (a corridor crossing
entered from the side: the same walls, but not the same half of them in view).

Each histogram is soft-binned (every value split linearly between its two nearest bins),
normalised to unit sum and square-rooted, then scaled by the block's weight with the
squared weights summing to one. The distance (:func:`signature_distance`) is the squared
Euclidean distance of two signatures: per block ``2 - 2 BC`` with ``BC`` the
Bhattacharyya coefficient of the two histograms, i.e. twice the squared Hellinger
distance, weighted. It lies in ``[0, 2]``; 0 for identical histograms. Being a squared
Euclidean distance it is searched exactly by one matrix product (:mod:`.index`).

Examples
--------
>>> import numpy as np, scanclique as sc
>>> from scanclique.match import prepare_scan
>>> pair = sc.sim.simulate_pair(np.random.default_rng(0))
>>> sa = scan_signature(prepare_scan(pair.scan_a))
>>> sa.shape == (SIGNATURE_SIZE,), sa.dtype
(True, dtype('float64'))
>>> float(signature_distance(sa, sa))
0.0
"""

from __future__ import annotations

import math

import numpy as np

__all__ = [
    "SIGNATURE_VERSION",
    "SIGNATURE_BLOCKS",
    "SIGNATURE_SIZE",
    "scan_signature",
    "signature_distance",
]

#: bump when the signature changes: stored signatures of another version are recomputed
#: (:class:`scanclique.places.PlaceDB`)
SIGNATURE_VERSION = 3

#: metres: ranges and distances are binned on a square-root scale up to this (farther
#: values go to the last bin)
_FAR = 30.0
#: at most this many points enter the pairwise histograms (evenly spaced in beam order)
_PAIR_POINTS = 120

#: metres: the ``local`` block's pairs are at most this far apart (a few metres of
#: surface, about what a revisit a couple of metres off still sees of the same stretch)
LOCAL_RADIUS = 2.0
#: metres: the ``local`` block's points are thinned to about one per this length of the
#: scan (arc length in beam order), so that its counts follow the length of surface in
#: view and not the beam density, which falls with range
LOCAL_SPACING = 0.25

#: (name, number of bins, weight before normalisation); ``local`` weighs as much as the
#: others together (its squared weight is the sum of theirs)
SIGNATURE_BLOCKS: tuple[tuple[str, int, float], ...] = (
    ("range", 24, 1.0),
    ("distance", 24, 1.0),
    ("normal", 12, 1.0),
    ("feature", 24, 1.0),
    ("pair", 128, 2.0),
    ("local", 128, math.sqrt(8.0)),
)
_PAIR_DIST_BINS = 8
_PAIR_ANGLE_BINS = 4
SIGNATURE_SIZE = sum(n for _, n, _ in SIGNATURE_BLOCKS)
_W = np.array([w for _, _, w in SIGNATURE_BLOCKS], dtype=float)
_W = _W / math.sqrt(float(np.sum(_W**2)))


def _soft_hist(u: np.ndarray, n: int) -> np.ndarray:
    """Histogram of ``u`` (already scaled so that bin centres are 0 .. n-1; values are
    clipped into that range), each value split linearly between its two nearest bins."""
    out = np.zeros(n)
    if u.size == 0:
        return out
    u = np.clip(np.asarray(u, dtype=float), 0.0, n - 1.0)
    lo = np.floor(u).astype(np.int64)
    hi = np.minimum(lo + 1, n - 1)
    w_hi = u - lo
    out += np.bincount(lo, weights=1.0 - w_hi, minlength=n)[:n]
    out += np.bincount(hi, weights=w_hi, minlength=n)[:n]
    return out


def _sqrt_scale(v: np.ndarray, n: int, far: float = _FAR) -> np.ndarray:
    """Values in metres mapped to bin coordinates on a square-root scale over ``[0, far]``."""
    return np.sqrt(np.maximum(v, 0.0) / far) * (n - 1)


def _pair_values(x: np.ndarray) -> np.ndarray:
    """Indices ``(i, j)``, ``i < j`` of ``len(x)`` items, as two arrays."""
    return np.triu_indices(len(x), k=1)


def _evenly(n: int, k: int) -> np.ndarray:
    if n <= k:
        return np.arange(n)
    return np.linspace(0, n - 1, k).round().astype(np.int64)


def _cloud_with_normals(prepared, cap: int | None = _PAIR_POINTS) -> tuple[np.ndarray, np.ndarray]:
    """The cloud's points that have a surface normal and their normals, in beam order
    (the cloud keeps them by bearing, which a rotation of the sensor would cut at
    another point), at most ``cap`` of them evenly spaced (all when None)."""
    pts = np.asarray(prepared.cloud.points, dtype=float).reshape(-1, 2)
    nrm = np.asarray(prepared.cloud.normals, dtype=float).reshape(-1, 2)
    has = np.any(nrm != 0.0, axis=1)
    pts, nrm = pts[has], nrm[has]
    angles = prepared.scan.angles
    if len(pts) and len(angles):
        rel = np.mod(np.arctan2(pts[:, 1], pts[:, 0]) - angles[0] + 1e-9, 2 * math.pi)
        order = np.argsort(rel, kind="stable")
        pts, nrm = pts[order], nrm[order]
    if cap is None:
        return pts, nrm
    sel = _evenly(len(pts), cap)
    return pts[sel], nrm[sel]


def _thinned(pts: np.ndarray, spacing: float) -> np.ndarray:
    """Indices of points ``(N, 2)`` (in scan order) kept one per ``spacing`` metres of
    arc length along them: the first point of each ``spacing`` of the cumulative length
    of the polyline through them (jumps between surfaces included). Depends only on the
    points' distances, so a rotation or translation of the sensor keeps the same ones."""
    if len(pts) == 0:
        return np.zeros(0, dtype=np.int64)
    step = np.hypot(*np.diff(pts, axis=0).T) if len(pts) > 1 else np.zeros(0)
    arc = np.concatenate(([0.0], np.cumsum(step)))
    cell = np.floor(arc / spacing)
    return np.flatnonzero(np.concatenate(([True], np.diff(cell) > 0)))


def _local_hist(prepared, cloud: tuple[np.ndarray, np.ndarray] | None = None) -> np.ndarray:
    """The ``local`` block: the joint histogram (hard bins) of (distance, smaller |cos|,
    larger |cos|) over the pairs at most :data:`LOCAL_RADIUS` apart of the cloud's points
    that have a normal, thinned (:func:`_thinned`, :data:`LOCAL_SPACING`); distance bins
    linear over ``[0, LOCAL_RADIUS]``. Counts, not normalised: shape
    ``(_PAIR_DIST_BINS * _PAIR_ANGLE_BINS ** 2,)``, all zero for fewer than two points.
    ``cloud``: ``_cloud_with_normals(prepared, cap=None)`` when the caller has it."""
    from scipy.spatial import cKDTree

    nd, na = _PAIR_DIST_BINS, _PAIR_ANGLE_BINS
    out = np.zeros(nd * na * na)
    pts, nrm = _cloud_with_normals(prepared, cap=None) if cloud is None else cloud
    keep = _thinned(pts, LOCAL_SPACING)
    pts, nrm = pts[keep], nrm[keep]
    if len(pts) < 2:
        return out
    ij = cKDTree(pts).query_pairs(LOCAL_RADIUS, output_type="ndarray")
    if len(ij) == 0:
        return out
    return _pair_feature_hist(pts, nrm, ij[:, 0], ij[:, 1], lambda length: length / LOCAL_RADIUS)


_KERNELS = None


def _kernels():
    """The compiled loops (:mod:`._kernels`), imported (and numba loaded) on first use."""
    global _KERNELS
    if _KERNELS is None:
        from . import _kernels as k

        _KERNELS = k
    return _KERNELS


def _blocks(prepared) -> list[np.ndarray]:
    """The raw (unnormalised) histograms of the blocks of :data:`SIGNATURE_BLOCKS`; the
    pairwise ones by the compiled loops of :mod:`._kernels`, the same values as
    :func:`_blocks_reference` (up to the order of summation)."""
    K = _kernels()
    scan = prepared.scan
    nb = {name: n for name, n, _ in SIGNATURE_BLOCKS}
    r = scan.ranges[scan.valid]
    h_range = _soft_hist(_sqrt_scale(r, nb["range"]), nb["range"])
    pts = np.ascontiguousarray(np.asarray(prepared.sample, dtype=float).reshape(-1, 2))
    pts = np.ascontiguousarray(pts[_evenly(len(pts), _PAIR_POINTS)])
    h_dist = K.distance_hist(pts, nb["distance"], _FAR)
    # all the cloud's points with a normal (the local block's), and the evenly spaced
    # ones of the pair blocks: _cloud_with_normals(prepared) without sorting twice
    cloud = _cloud_with_normals(prepared, cap=None)
    sel = _evenly(len(cloud[0]), _PAIR_POINTS)
    cp, cn = cloud[0][sel], cloud[1][sel]
    h_norm, h_pair = K.normal_pair_hists(
        np.ascontiguousarray(cp), np.ascontiguousarray(cn), nb["normal"],
        _PAIR_DIST_BINS, _PAIR_ANGLE_BINS, _FAR,
    )  # fmt: skip
    h_feat = _feature_hist(prepared, nb["feature"])
    return [h_range, h_dist, h_norm, h_feat, h_pair, _local_hist(prepared, cloud)]


def _blocks_reference(prepared) -> list[np.ndarray]:
    """The raw (unnormalised) histograms of the blocks of :data:`SIGNATURE_BLOCKS`, in
    NumPy: the reference of :func:`_blocks`."""
    scan = prepared.scan
    nb = {name: n for name, n, _ in SIGNATURE_BLOCKS}
    # range: distance of each valid return from the sensor
    r = scan.ranges[scan.valid]
    h_range = _soft_hist(_sqrt_scale(r, nb["range"]), nb["range"])
    # distance: pairwise distances of (at most _PAIR_POINTS) sample points
    pts = np.asarray(prepared.sample, dtype=float).reshape(-1, 2)
    pts = pts[_evenly(len(pts), _PAIR_POINTS)]
    i, j = _pair_values(pts)
    d = np.hypot(*(pts[i] - pts[j]).T) if len(i) else np.zeros(0)
    h_dist = _soft_hist(_sqrt_scale(d, nb["distance"]), nb["distance"])
    # normal: angles between surface normals of pairs of points, folded to [0, pi/2]
    _, nrm = _cloud_with_normals(prepared)
    a = np.arctan2(nrm[:, 1], nrm[:, 0])
    i, j = _pair_values(a)
    da = np.abs(a[i] - a[j]) % math.pi
    da = np.minimum(da, math.pi - da)
    h_norm = _soft_hist(da / (math.pi / 2) * (nb["normal"] - 1), nb["normal"])
    # feature: invariant edge labels of the feature graph by kind pair (paper §5.1)
    h_feat = _feature_hist(prepared, nb["feature"])
    # pair: joint histogram of 2D point pair features
    h_pair = _pair_hist(prepared)
    # local: the joint histogram of local pairs (the same function: no compiled copy)
    return [h_range, h_dist, h_norm, h_feat, h_pair, _local_hist(prepared)]


def _pair_hist(prepared) -> np.ndarray:
    """Joint histogram (hard bins) of (distance, smaller |cos|, larger |cos|) over pairs
    of (at most ``_PAIR_POINTS``) cloud points that have a normal; the cosines are of the
    angles between each point's normal and the segment joining the two points."""
    nd, na = _PAIR_DIST_BINS, _PAIR_ANGLE_BINS
    pts, nrm = _cloud_with_normals(prepared)
    i, j = _pair_values(pts)
    if len(i) == 0:
        return np.zeros(nd * na * na)
    return _pair_feature_hist(
        pts, nrm, i, j, lambda length: np.sqrt(np.minimum(length, _FAR) / _FAR)
    )


def _pair_feature_hist(pts, nrm, i, j, distance_unit) -> np.ndarray:
    """Counts ``(_PAIR_DIST_BINS * _PAIR_ANGLE_BINS ** 2,)`` of the point pairs ``(i[k],
    j[k])`` by (distance, smaller |cos|, larger |cos|), the cosines of the angles between
    each point's normal and the segment joining them; ``distance_unit`` maps a distance (m)
    to ``[0, 1]`` over the distance bins (hard bins, clipped)."""
    nd, na = _PAIR_DIST_BINS, _PAIR_ANGLE_BINS
    d = pts[j] - pts[i]
    length = np.hypot(d[:, 0], d[:, 1])
    u = d / np.maximum(length, 1e-12)[:, None]
    c1 = np.abs(np.sum(nrm[i] * u, axis=1))
    c2 = np.abs(np.sum(nrm[j] * u, axis=1))
    lo, hi = np.minimum(c1, c2), np.maximum(c1, c2)
    bd = np.clip(np.floor(distance_unit(length) * nd), 0, nd - 1)
    b1 = np.clip(np.floor(lo * na), 0, na - 1)
    b2 = np.clip(np.floor(hi * na), 0, na - 1)
    code = ((bd * na + b1) * na + b2).astype(np.int64)
    return np.bincount(code, minlength=nd * na * na).astype(float)


def _feature_hist(prepared, n: int) -> np.ndarray:
    """Three sub-histograms of ``n // 3`` bins: point–point distances, |point–line|
    distances, line–line acute angles, each over all unordered pairs of features."""
    m = n // 3
    f = prepared.features
    xy = np.asarray(f.points_xy, dtype=float).reshape(-1, 2)
    ra = np.asarray(f.lines_rho_alpha, dtype=float).reshape(-1, 2)
    i, j = _pair_values(xy)
    pp = np.hypot(*(xy[i] - xy[j]).T) if len(i) else np.zeros(0)
    if len(xy) and len(ra):
        pl = np.abs(xy @ np.column_stack((np.cos(ra[:, 1]), np.sin(ra[:, 1]))).T - ra[:, 0])
        pl = pl.ravel()
    else:
        pl = np.zeros(0)
    i, j = _pair_values(ra)
    ll = np.abs(ra[i, 1] - ra[j, 1]) % math.pi
    ll = np.minimum(ll, math.pi - ll)
    return np.concatenate(
        (
            _soft_hist(_sqrt_scale(pp, m), m),
            _soft_hist(_sqrt_scale(pl, m), m),
            _soft_hist(ll / (math.pi / 2) * (m - 1), n - 2 * m),
        )
    )


def scan_signature(prepared) -> np.ndarray:
    """The rotation-invariant signature of one prepared scan (see the module docstring).

    Parameters
    ----------
    prepared : scanclique.match.PreparedScan
        From :func:`scanclique.prepare_scan`: the signature reads its scan's ranges, its
        sample points, its cloud's surface normals and its features.

    Returns
    -------
    ndarray, shape (SIGNATURE_SIZE,), float64
        Blocks of :data:`SIGNATURE_BLOCKS` in order; each block is the square root of a
        unit-sum histogram times its weight (zero when the scan gives the block no value,
        e.g. no features). Compare two with :func:`signature_distance`.
    """
    out = []
    for h, w in zip(_blocks(prepared), _W, strict=True):
        s = float(h.sum())
        out.append(np.sqrt(h / s) * w if s > 0 else np.zeros_like(h))
    return np.concatenate(out)


def signature_distance(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Distance of signatures: the squared Euclidean distance, in ``[0, 2]``.

    ``a`` and ``b`` broadcast over leading axes: ``(D,)`` against ``(N, D)`` gives
    ``(N,)``. Per block it is ``w² (2 - 2 BC)``, BC the Bhattacharyya coefficient of the
    two histograms (``w²`` when one of them is empty); 0 means identical histograms.
    """
    a = np.asarray(a, dtype=float)
    b = np.asarray(b, dtype=float)
    return np.sum((a - b) ** 2, axis=-1)
