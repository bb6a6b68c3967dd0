"""Compiled kernels of the matching stages (private; see :mod:`scanclique.refine`,
:mod:`scanclique.pose` and :mod:`scanclique.match`).

Everything that runs once per hypothesis or once per point of a hypothesis lives here, so
that a whole scan match costs a handful of calls from Python instead of thousands of
small NumPy operations.

Nearest-neighbour search without a tree. A scan's points are sorted by bearing (the angle
of the point seen from the sensor, in ``(-pi, pi]``). A reference point within distance
``d`` of a query point at range ``r > d`` has a bearing within ``asin(d / r)`` of the
query's (the distance from the query to the ray at angle ``dphi`` is ``r sin(dphi)``), so
only that window of the sorted points is searched: exact, and a few points per query on a
laser scan. A query nearer than ``d`` to the sensor searches everything.

Caching: every kernel is compiled once and cached in ``__pycache__`` (``cache=True``).
:func:`hypothesis_cliques` calls :func:`scanclique._clique_kernels.solve`; numba keys a
cache by its own source file only, so after editing ``_clique_kernels.py`` in a working
tree, delete ``__pycache__/_match_kernels.*`` (an installed release replaces both files
and the cache with them).

Poses are ``(x, y, theta)`` mapping B's frame into A's: ``p_a = R(theta) p_b + (x, y)``.
Feature arrays follow :class:`scanclique.features.Features`: points ``(Np, 2)`` with
covariances ``(Np, 2, 2)``, lines ``(Nl, 2)`` as ``(rho, alpha)`` with covariances; node
``k`` of a feature graph is point ``k`` when ``k < Np`` and line ``k - Np`` otherwise.
"""

# ruff: noqa: E402 (ensure_cache() runs before numba caches anything)
from __future__ import annotations

import math

from ._kernels import ensure_cache

ensure_cache()

import numba
import numpy as np

from ._kernels.bitset import ctpop, now, setbit
from ._kernels.clique_search import maximum_until, search_until
from ._kernels.codes import Status
from ._kernels.ordering import induced_rows

#: statuses of the hypothesis search (:func:`hypothesis_cliques`), as compile-time ints
_FINISHED = int(Status.FINISHED)
_TIME_LIMIT = int(Status.TIME_LIMIT)
_NODE_LIMIT = int(Status.NODE_LIMIT)

_njit = numba.njit(cache=True, nogil=True)
#: for the helpers called once per point: inlined into the caller at numba IR level, so
#: that the arrays they take are not reference-counted on every call
_inline = numba.njit(cache=True, nogil=True, inline="always")

#: Huber scale (m) and weight of the point-to-point term of the ICP (see icp_point_to_line)
ICP_HUBER = 0.05
ICP_POINT_WEIGHT = 0.05
#: the ICP has converged when a step moves less than this (metres, radians), once the
#: correspondence distance has shrunk to its minimum
ICP_STEP_T = 5e-4
ICP_STEP_R = 5e-5


# --------------------------------------------------------------------------------------
# Small dense algebra
# --------------------------------------------------------------------------------------
@_inline
def wrap(a):  # pragma: no cover - compiled
    """Angle wrapped to ``[-pi, pi)`` (as :func:`scanclique.geometry.wrap_angle`)."""
    w = (a + math.pi) % (2.0 * math.pi) - math.pi
    return w - 2.0 * math.pi if w >= math.pi else w


@_inline
def solve3(H, g, out):  # pragma: no cover - compiled
    """``out = H^-1 g`` for a 3x3 system, Gaussian elimination with partial pivoting.
    Returns False when ``H`` is singular."""
    M = np.empty((3, 4))
    for i in range(3):
        for j in range(3):
            M[i, j] = H[i, j]
        M[i, 3] = g[i]
    for col in range(3):
        piv = col
        for r in range(col + 1, 3):
            if abs(M[r, col]) > abs(M[piv, col]):
                piv = r
        if M[piv, col] == 0.0:
            return False
        if piv != col:
            for j in range(4):
                tmp = M[col, j]
                M[col, j] = M[piv, j]
                M[piv, j] = tmp
        for r in range(col + 1, 3):
            f = M[r, col] / M[col, col]
            for j in range(col, 4):
                M[r, j] -= f * M[col, j]
    for i in range(2, -1, -1):
        s = M[i, 3]
        for j in range(i + 1, 3):
            s -= M[i, j] * out[j]
        out[i] = s / M[i, i]
    return True


@_inline
def smallest_eigvec2(a, b, c):  # pragma: no cover - compiled
    """Unit eigenvector of the smallest eigenvalue of the symmetric ``[[a, b], [b, c]]``."""
    if b == 0.0:
        return (1.0, 0.0) if a <= c else (0.0, 1.0)
    h = 0.5 * (a - c)
    lam = 0.5 * (a + c) - math.sqrt(h * h + b * b)
    u0, u1 = lam - c, b
    v0, v1 = b, lam - a
    nu = math.hypot(u0, u1)
    nv = math.hypot(v0, v1)
    if nu >= nv:
        return (u0 / nu, u1 / nu)
    return (v0 / nv, v1 / nv)


# --------------------------------------------------------------------------------------
# Bearing-window search
# --------------------------------------------------------------------------------------
@_njit
def make_index(a, bins_per_item):  # pragma: no cover - compiled
    """A search index over the ascending array ``a``: ``(a, bins, lo, scale)`` where
    ``bins[q]`` is the first index with ``a[i] >= lo + q / scale``. :func:`lower` then
    binary-searches one or two bins instead of the whole array."""
    n = a.shape[0]
    nb = max(1, min(int(bins_per_item * n) + 1, 1 << 16))
    lo = a[0] if n > 0 else 0.0
    hi = a[n - 1] if n > 0 else 1.0
    span = hi - lo
    scale = nb / span if span > 0.0 else 1.0
    bins = np.empty(nb + 1, np.int64)
    i = 0
    for q in range(nb + 1):
        edge = lo + q / scale
        while i < n and a[i] < edge:
            i += 1
        bins[q] = i
    return (a, bins, lo, scale)


@_inline
def lower(ix, x):  # pragma: no cover - compiled
    """First index ``i`` with ``a[i] >= x`` for the index ``ix`` of ``a``
    (:func:`make_index`)."""
    a, bins, lo, scale = ix
    nb = bins.shape[0] - 1
    f = (x - lo) * scale
    if not f < nb - 1:  # also NaN
        i0 = bins[max(nb - 2, 0)]
        i1 = a.shape[0]
    elif f < 1.0:
        i0 = 0
        i1 = bins[min(2, nb)]
    else:
        q = int(f)
        i0 = bins[q - 1]
        i1 = bins[q + 2]
    while i0 < i1:
        mid = (i0 + i1) >> 1
        if a[mid] < x:
            i0 = mid + 1
        else:
            i1 = mid
    return i0


@_inline
def upper(ix, x):  # pragma: no cover - compiled
    """First index ``i`` with ``a[i] > x`` (see :func:`lower`)."""
    a = ix[0]
    i = lower(ix, x)
    while i < a.shape[0] and a[i] <= x:
        i += 1
    return i


@_inline
def _window(ix, x, y, d, rng):  # pragma: no cover - compiled
    """Index ranges ``[rng[0], rng[1])``, ``[rng[2], rng[3])``, ``[rng[4], rng[5])`` of
    the points (bearings indexed by ``ix``) that can lie within ``d`` of ``(x, y)``."""
    n = ix[0].shape[0]
    rng[2] = rng[3] = rng[4] = rng[5] = 0
    r = math.sqrt(x * x + y * y)
    if r <= d:
        rng[0] = 0
        rng[1] = n
        return
    w = math.asin(d / r) + 1e-9
    phi = math.atan2(y, x)
    lo, hi = phi - w, phi + w
    rng[0] = lower(ix, lo)
    rng[1] = upper(ix, hi)
    if lo < -math.pi:
        rng[2] = lower(ix, lo + 2.0 * math.pi)
        rng[3] = n
    if hi > math.pi:
        rng[5] = upper(ix, hi - 2.0 * math.pi)


@_inline
def _half_window(z):  # pragma: no cover - compiled
    """An upper bound of ``asin(z)`` for ``0 <= z < 1`` (``tan(asin z)``, cheaper), plus a
    little: the half-width in bearing of a disc of radius ``z r`` at range ``r``."""
    if z >= 0.999:
        return math.pi
    return z / math.sqrt(1.0 - z * z) + 1e-9


@_njit
def has_near(ix, pts, x, y, d, rng):  # pragma: no cover - compiled
    """Whether some point of ``pts`` (bearings indexed by ``ix``) lies strictly within
    ``d`` of ``(x, y)``."""
    return has_near_polar(ix, pts, x, y, math.sqrt(x * x + y * y), math.atan2(y, x), d, rng)


@_inline
def has_near_polar(ix, pts, x, y, r, phi, d, rng):  # pragma: no cover - compiled
    """:func:`has_near` given the range ``r`` and bearing ``phi`` of ``(x, y)``."""
    return _search(ix, pts, x, y, r, phi, d, True, rng)[0] >= 0


@_inline
def nearest_one(ix, pts, x, y, dmax, rng):  # pragma: no cover - compiled
    """``(index, squared distance)`` of the nearest point of ``pts`` strictly within
    ``dmax`` of ``(x, y)``; ``(-1, dmax**2)`` when there is none."""
    r = math.sqrt(x * x + y * y)
    return _search(ix, pts, x, y, r, math.atan2(y, x), dmax, False, rng)


@_inline
def _search(ix, pts, x, y, r, phi, dmax, first, rng):  # pragma: no cover - compiled
    """``(index, squared distance)`` of a point of ``pts`` strictly within ``dmax`` of
    ``(x, y)`` (range ``r``, bearing ``phi``): the first one met when ``first``, else the
    nearest; ``(-1, dmax**2)`` when there is none.

    Walks outwards from the query's bearing (a hit is usually the next beam), both ways
    until the bearings leave the window, which narrows to the best distance found so far;
    the general window (:func:`_window`) near the sensor or across +-pi."""
    best = dmax * dmax
    bj = -1
    bear = ix[0]
    n = bear.shape[0]
    if r > dmax and n > 0:
        w = _half_window(dmax / r)
        if phi - w >= -math.pi and phi + w <= math.pi:
            k = lower(ix, phi)
            lo = k - 1
            hi = k
            lo_ok = lo >= 0
            hi_ok = hi < n
            while lo_ok or hi_ok:
                for side in range(2):
                    j = hi if side == 0 else lo
                    if not (hi_ok if side == 0 else lo_ok):
                        continue
                    if abs(bear[j] - phi) > w:
                        if side == 0:
                            hi_ok = False
                        else:
                            lo_ok = False
                        continue
                    dx = pts[j, 0] - x
                    dy = pts[j, 1] - y
                    d2 = dx * dx + dy * dy
                    if d2 < best:
                        best = d2
                        bj = j
                        if first:
                            return bj, best
                        w = _half_window(math.sqrt(d2) / r)
                    if side == 0:
                        hi += 1
                        hi_ok = hi < n
                    else:
                        lo -= 1
                        lo_ok = lo >= 0
            return bj, best
    _window(ix, x, y, dmax, rng)
    for kk in range(3):
        for j in range(rng[2 * kk], rng[2 * kk + 1]):
            dx = pts[j, 0] - x
            dy = pts[j, 1] - y
            d2 = dx * dx + dy * dy
            if d2 < best:
                best = d2
                bj = j
                if first:
                    return bj, best
    return bj, best


@_njit
def nearest_many(ix, ref, pts, c, s, tx, ty, dmax, idx_out, d2_out):  # pragma: no cover
    """:func:`nearest_one` for every point of ``pts`` moved by ``(R(c, s), t)``."""
    rng = np.empty(6, np.int64)
    for i in range(pts.shape[0]):
        x = c * pts[i, 0] - s * pts[i, 1] + tx
        y = s * pts[i, 0] + c * pts[i, 1] + ty
        j, d2 = nearest_one(ix, ref, x, y, dmax, rng)
        idx_out[i] = j
        d2_out[i] = d2


@_njit
def agreement_count(ix, ref, pts, c, s, tx, ty, d):  # pragma: no cover - compiled
    """How many points of ``pts`` moved by ``(R(c, s), t)`` have a ``ref`` point within
    ``d``."""
    rng = np.empty(6, np.int64)
    count = 0
    for i in range(pts.shape[0]):
        x = c * pts[i, 0] - s * pts[i, 1] + tx
        y = s * pts[i, 0] + c * pts[i, 1] + ty
        if has_near(ix, ref, x, y, d, rng):
            count += 1
    return count


@_inline
def _keep_nearest(bd, bi, m, k, d2, j):  # pragma: no cover - compiled
    """Insert candidate ``j`` at squared distance ``d2`` into the ascending list
    ``bd``/``bi`` of the ``m`` (at most ``k``) nearest so far; returns the new ``m``."""
    if m == k and d2 >= bd[m - 1]:
        return m
    p = m if m < k else k - 1
    while p > 0 and bd[p - 1] > d2:
        bd[p] = bd[p - 1]
        bi[p] = bi[p - 1]
        p -= 1
    bd[p] = d2
    bi[p] = j
    return m + 1 if m < k else m


@_njit
def cloud_normals(ix, pts, k, radius, normals):  # pragma: no cover - compiled
    """Unit normal of each point: the direction of least spread of its ``k`` nearest
    points (itself included) within ``radius``; zero when fewer than 3 are that near.

    ``pts`` are sorted by bearing (indexed by ``ix``): the search walks outwards from
    the point's own index, the bearing window narrowing to the ``k``-th distance found."""
    n = pts.shape[0]
    r2 = radius * radius
    rng = np.empty(6, np.int64)
    bd = np.empty(k)
    bi = np.empty(k, np.int64)
    bear = ix[0]
    for i in range(n):
        x, y = pts[i, 0], pts[i, 1]
        r = math.sqrt(x * x + y * y)
        m = 0
        w = _half_window(radius / r) if r > 0.0 else math.pi
        if w < math.pi and bear[i] - w >= -math.pi and bear[i] + w <= math.pi:
            m = _keep_nearest(bd, bi, m, k, 0.0, i)
            lo = i - 1
            hi = i + 1
            lo_ok = lo >= 0
            hi_ok = hi < n
            while lo_ok or hi_ok:
                if hi_ok:
                    if bear[hi] - bear[i] > w:
                        hi_ok = False
                    else:
                        dx = pts[hi, 0] - x
                        dy = pts[hi, 1] - y
                        d2 = dx * dx + dy * dy
                        if d2 <= r2:
                            m = _keep_nearest(bd, bi, m, k, d2, hi)
                            if m == k:
                                w = min(w, _half_window(math.sqrt(bd[k - 1]) / r))
                        hi += 1
                        hi_ok = hi < n
                if lo_ok:
                    if bear[i] - bear[lo] > w:
                        lo_ok = False
                    else:
                        dx = pts[lo, 0] - x
                        dy = pts[lo, 1] - y
                        d2 = dx * dx + dy * dy
                        if d2 <= r2:
                            m = _keep_nearest(bd, bi, m, k, d2, lo)
                            if m == k:
                                w = min(w, _half_window(math.sqrt(bd[k - 1]) / r))
                        lo -= 1
                        lo_ok = lo >= 0
        else:
            _window(ix, x, y, radius, rng)
            for kk in range(3):
                for j in range(rng[2 * kk], rng[2 * kk + 1]):
                    dx = pts[j, 0] - x
                    dy = pts[j, 1] - y
                    d2 = dx * dx + dy * dy
                    if d2 <= r2:
                        m = _keep_nearest(bd, bi, m, k, d2, j)
        if m < 3:
            normals[i, 0] = 0.0
            normals[i, 1] = 0.0
            continue
        mx = 0.0
        my = 0.0
        for q in range(m):
            mx += pts[bi[q], 0]
            my += pts[bi[q], 1]
        mx /= m
        my /= m
        a = 0.0
        b = 0.0
        cc = 0.0
        for q in range(m):
            ux = pts[bi[q], 0] - mx
            uy = pts[bi[q], 1] - my
            a += ux * ux
            b += ux * uy
            cc += uy * uy
        nx, ny = smallest_eigvec2(a, b, cc)
        normals[i, 0] = nx
        normals[i, 1] = ny


@_njit
def cloud_arrays(points, k, radius, with_normals):  # pragma: no cover - compiled
    """A reference cloud's arrays from ``(M, 2)`` points: the points sorted by bearing
    (stable), their bearings, the bearing index (:func:`make_index`) and, when
    ``with_normals``, the normals (:func:`cloud_normals`; zeros otherwise)."""
    n = points.shape[0]
    bear = np.empty(n)
    for i in range(n):
        bear[i] = math.atan2(points[i, 1], points[i, 0])
    ordered = True
    for i in range(1, n):
        if bear[i] < bear[i - 1]:
            ordered = False
            break
    p = np.empty((n, 2))
    if ordered:
        p[:, :] = points
    else:
        order = np.argsort(bear, kind="mergesort")
        b2 = bear[order]
        for i in range(n):
            p[i, 0] = points[order[i], 0]
            p[i, 1] = points[order[i], 1]
        bear = b2
    index = make_index(bear, 2.0)
    normals = np.zeros((n, 2))
    if with_normals and n >= 3:
        cloud_normals(index, p, k, radius, normals)
    return p, bear, index, normals


@_njit
def _evenly_idx(m, n):  # pragma: no cover - compiled
    """Indices of at most ``n`` of ``m`` items, evenly spaced (all when ``m <= n``), as
    ``numpy.linspace(0, m - 1, n).round()``."""
    if m <= n:
        return np.arange(m)
    return np.rint(np.linspace(0.0, m - 1.0, n)).astype(np.int64)


@_njit
def scan_arrays(ranges, angles, valid, n_cloud, n_sample):  # pragma: no cover - compiled
    """What a prepared scan needs from its beams, in one pass: the valid points (sensor
    frame, beam order), at most ``n_cloud`` and ``n_sample`` of them evenly spaced, the
    free range of each beam (the range where valid, 0 otherwise) and the index of the
    beam angles (:func:`make_index`)."""
    nb = ranges.shape[0]
    m = 0
    for i in range(nb):
        if valid[i]:
            m += 1
    pts = np.empty((m, 2))
    free = np.zeros(nb)
    k = 0
    for i in range(nb):
        if valid[i]:
            pts[k, 0] = ranges[i] * math.cos(angles[i])
            pts[k, 1] = ranges[i] * math.sin(angles[i])
            free[i] = ranges[i]
            k += 1
    ic = _evenly_idx(m, n_cloud)
    cloud = np.empty((ic.shape[0], 2))
    for i in range(ic.shape[0]):
        cloud[i, 0] = pts[ic[i], 0]
        cloud[i, 1] = pts[ic[i], 1]
    js = _evenly_idx(m, n_sample)
    sample = np.empty((js.shape[0], 2))
    for i in range(js.shape[0]):
        sample[i, 0] = pts[js[i], 0]
        sample[i, 1] = pts[js[i], 1]
    return pts, cloud, sample, free, make_index(angles.copy(), 2.0)


# --------------------------------------------------------------------------------------
# Free space
# --------------------------------------------------------------------------------------
@_inline
def _in_free_space(aix, free, half, r, phi, margin, ratio):  # pragma: no cover - compiled
    """Whether the point at range ``r`` and bearing ``phi`` lies nearer than the nearest
    beam and both its neighbours by more than ``margin + ratio * r`` (``half``: half the
    mean beam spacing; ``aix`` the index of the beam angles)."""
    angles = aix[0]
    n = angles.shape[0]
    if phi < angles[0] - half or phi > angles[n - 1] + half:
        return False
    k = lower(aix, phi)
    k = min(max(k, 1), n - 1)
    if abs(angles[k - 1] - phi) < abs(angles[k] - phi):
        k -= 1
    lo = free[k]
    if k > 0:
        lo = min(lo, free[k - 1])
    if k < n - 1:
        lo = min(lo, free[k + 1])
    return r < lo - (margin + ratio * r)


@_njit
def conflict_count(aix, free, pts, c, s, tx, ty, margin, ratio):  # pragma: no cover
    """How many ``pts`` moved by ``(R(c, s), t)`` lie in the free space seen along the
    nearest beam and both its neighbours (``free``: measured range, 0 when invalid):
    nearer than all three by more than ``margin + ratio * range``; ``aix``: the index of
    the beam angles, :func:`make_index`)."""
    angles = aix[0]
    n = angles.size
    if n < 2:
        return 0
    half = 0.5 * (angles[n - 1] - angles[0]) / (n - 1)
    count = 0
    for i in range(pts.shape[0]):
        x = c * pts[i, 0] - s * pts[i, 1] + tx
        y = s * pts[i, 0] + c * pts[i, 1] + ty
        r = math.sqrt(x * x + y * y)
        if _in_free_space(aix, free, half, r, math.atan2(y, x), margin, ratio):
            count += 1
    return count


@_njit
def _one_way(
    ix, ref, aix, free, pts, c, s, tx, ty, d, conflicts, margin, ratio
):  # pragma: no cover
    """Fractions of ``pts`` moved by ``(R(c, s), t)`` that agree with (are within ``d``
    of) ``ref`` (bearings indexed by ``ix``), and (when ``conflicts``) that lie in the
    free space of the scan whose beam angles are indexed by ``aix``, free ranges
    ``free``."""
    m = pts.shape[0]
    if m == 0:
        return 0.0, 0.0
    angles = aix[0]
    n = angles.shape[0]
    half = 0.5 * (angles[n - 1] - angles[0]) / (n - 1) if n >= 2 else 0.0
    check_free = conflicts and n >= 2
    has_ref = ref.shape[0] > 0
    rng = np.empty(6, np.int64)
    agree = 0
    conflict = 0
    for i in range(m):
        x = c * pts[i, 0] - s * pts[i, 1] + tx
        y = s * pts[i, 0] + c * pts[i, 1] + ty
        r = math.sqrt(x * x + y * y)
        phi = math.atan2(y, x)
        if has_ref and has_near_polar(ix, ref, x, y, r, phi, d, rng):
            agree += 1
        if check_free and _in_free_space(aix, free, half, r, phi, margin, ratio):
            conflict += 1
    return agree / m, conflict / m


@_njit
def pose_score(
    a_ix,
    a_ref,
    a_aix,
    a_free,
    a_sample,
    b_ix,
    b_ref,
    b_aix,
    b_free,
    b_sample,
    x,
    y,
    th,
    d,
    conflict_weight,
    margin,
    ratio,
):  # pragma: no cover - compiled
    """Symmetric raw-scan score of the pose ``(x, y, th)`` (maps B into A): the mean of
    the fractions of B's sample near A's points and of A's sample near B's points, minus
    ``conflict_weight`` times the mean fraction of samples in the other scan's free
    space. See :func:`scanclique.match.pose_score`."""
    c = math.cos(th)
    s = math.sin(th)
    inv_x = -(c * x + s * y)
    inv_y = -(-s * x + c * y)
    conflicts = conflict_weight > 0.0
    ag_ab, c_ab = _one_way(
        a_ix, a_ref, a_aix, a_free, b_sample, c, s, x, y, d, conflicts, margin, ratio
    )
    ag_ba, c_ba = _one_way(
        b_ix, b_ref, b_aix, b_free, a_sample, c, -s, inv_x, inv_y, d, conflicts, margin, ratio
    )
    score = 0.5 * (ag_ab + ag_ba)
    if conflicts:
        score -= conflict_weight * 0.5 * (c_ab + c_ba)
    return score


# --------------------------------------------------------------------------------------
# ICP
# --------------------------------------------------------------------------------------
@_njit
def icp(ix, ref, normals, pts, x0, iterations, max_corr, min_corr, out):  # pragma: no cover
    """Point-to-line ICP of ``pts`` (B) onto ``ref`` (A, bearings indexed by ``ix``, with
    ``normals``) from ``x0``; see :func:`scanclique.refine.icp_point_to_line`.

    Writes the pose to ``out`` and returns ``(fitness, rmse, iterations run)``."""
    x = np.empty(3)
    x[:] = x0[:]
    n = pts.shape[0]
    fitness = 0.0
    rmse = math.inf
    it = 0
    rng = np.empty(6, np.int64)
    H = np.empty((3, 3))
    g = np.empty(3)
    dx = np.empty(3)
    J = np.empty(3)
    eps = ICP_POINT_WEIGHT
    for it in range(1, iterations + 1):
        dmax = max(min_corr, max_corr * 0.7 ** (it - 1))
        c = math.cos(x[2])
        s = math.sin(x[2])
        H[:] = 0.0
        g[:] = 0.0
        ok = 0
        ssr = 0.0
        for i in range(n):
            rpx = c * pts[i, 0] - s * pts[i, 1]
            rpy = s * pts[i, 0] + c * pts[i, 1]
            px = rpx + x[0]
            py = rpy + x[1]
            j, _ = nearest_one(ix, ref, px, py, dmax, rng)
            if j < 0:
                continue
            ok += 1
            ddx = px - ref[j, 0]
            ddy = py - ref[j, 1]
            nx = normals[j, 0]
            ny = normals[j, 1]
            dpx = -rpy
            dpy = rpx
            r = nx * ddx + ny * ddy
            ssr += r * r
            J[0] = nx
            J[1] = ny
            J[2] = nx * dpx + ny * dpy
            ar = abs(r)
            w = 1.0 if ar < ICP_HUBER else ICP_HUBER / max(ar, 1e-12)
            for a in range(3):
                g[a] += w * J[a] * r
                for b in range(3):
                    H[a, b] += w * J[a] * J[b]
            # weak point-to-point term: Jx = (1, 0, dpx), Jy = (0, 1, dpy)
            H[0, 0] += eps
            H[1, 1] += eps
            H[0, 2] += eps * dpx
            H[2, 0] += eps * dpx
            H[1, 2] += eps * dpy
            H[2, 1] += eps * dpy
            H[2, 2] += eps * (dpx * dpx + dpy * dpy)
            g[0] += eps * ddx
            g[1] += eps * ddy
            g[2] += eps * (dpx * ddx + dpy * ddy)
        if ok < 3:
            break
        for a in range(3):
            H[a, a] += 1e-9
        if not solve3(H, g, dx):
            break
        x[0] -= dx[0]
        x[1] -= dx[1]
        x[2] = wrap(x[2] - dx[2])
        fitness = ok / n
        rmse = math.sqrt(ssr / ok)
        if (
            max(abs(dx[0]), abs(dx[1])) < ICP_STEP_T
            and abs(dx[2]) < ICP_STEP_R
            and dmax <= min_corr
        ):
            break
    out[:] = x[:]
    return fitness, rmse, it


# --------------------------------------------------------------------------------------
# Poses from mapped features (paper §6)
# --------------------------------------------------------------------------------------
@_njit
def closed_form(pairs, npa, npb, Pa, Pb, La, Lb, out):  # pragma: no cover - compiled
    """Quick pose of mapped node pairs ``pairs`` (K, 2): the rotation from Arun et al. on
    the points (two or more, spread over 0.2 m) or else the circular mean of the line
    rotations; then the least-squares translation from points and line offsets (the
    minimum-norm solution when they do not fix it). See
    :func:`scanclique.pose.closed_form_pose`. Writes ``out`` and returns False when no
    rotation can be fixed."""
    K = pairs.shape[0]
    kp = 0
    cax = cay = cbx = cby = 0.0
    minx = miny = math.inf
    maxx = maxy = -math.inf
    for k in range(K):
        a = pairs[k, 0]
        if a < npa:
            b = pairs[k, 1]
            kp += 1
            cax += Pa[a, 0]
            cay += Pa[a, 1]
            cbx += Pb[b, 0]
            cby += Pb[b, 1]
            minx = min(minx, Pb[b, 0])
            maxx = max(maxx, Pb[b, 0])
            miny = min(miny, Pb[b, 1])
            maxy = max(maxy, Pb[b, 1])
    kl = K - kp
    if kp >= 2 and max(maxx - minx, maxy - miny) > 0.2:
        cax /= kp
        cay /= kp
        cbx /= kp
        cby /= kp
        ss = 0.0
        sc = 0.0
        for k in range(K):
            a = pairs[k, 0]
            if a < npa:
                b = pairs[k, 1]
                qax, qay = Pa[a, 0] - cax, Pa[a, 1] - cay
                qbx, qby = Pb[b, 0] - cbx, Pb[b, 1] - cby
                ss += qbx * qay - qby * qax
                sc += qbx * qax + qby * qay
        th = math.atan2(ss, sc)
    elif kl > 0:
        ss = 0.0
        sc = 0.0
        for k in range(K):
            a = pairs[k, 0]
            if a >= npa:
                rot = La[a - npa, 1] - Lb[pairs[k, 1] - npb, 1]
                ss += math.sin(rot)
                sc += math.cos(rot)
        th = math.atan2(ss, sc)
    else:
        return False
    c = math.cos(th)
    s = math.sin(th)
    # normal equations N t = v of the translation rows (points: identity; lines: n^T)
    n00 = n01 = n11 = v0 = v1 = 0.0
    for k in range(K):
        a = pairs[k, 0]
        b = pairs[k, 1]
        if a < npa:
            n00 += 1.0
            n11 += 1.0
            v0 += Pa[a, 0] - (c * Pb[b, 0] - s * Pb[b, 1])
            v1 += Pa[a, 1] - (s * Pb[b, 0] + c * Pb[b, 1])
        else:
            ap = Lb[b - npb, 1] + th
            nx, ny = math.cos(ap), math.sin(ap)
            rhs = La[a - npa, 0] - Lb[b - npb, 0]
            n00 += nx * nx
            n01 += nx * ny
            n11 += ny * ny
            v0 += nx * rhs
            v1 += ny * rhs
    rows = 2 * kp + kl
    # eigen-decomposition of N; singular values of the row matrix are their square roots;
    # keep those above numpy.linalg.lstsq's default cut-off (minimum-norm solution)
    h = 0.5 * (n00 - n11)
    rad = math.sqrt(h * h + n01 * n01)
    l1 = 0.5 * (n00 + n11) + rad
    l2 = 0.5 * (n00 + n11) - rad
    if l1 <= 0.0:
        return False
    e1x, e1y = smallest_eigvec2(-n00, -n01, -n11)  # eigenvector of the largest eigenvalue
    e2x, e2y = -e1y, e1x
    cut = 2.220446049250313e-16 * max(rows, 2)
    tx = (e1x * v0 + e1y * v1) / l1 * e1x
    ty = (e1x * v0 + e1y * v1) / l1 * e1y
    if l2 > 0.0 and math.sqrt(l2) > cut * math.sqrt(l1):
        p2 = (e2x * v0 + e2y * v1) / l2
        tx += p2 * e2x
        ty += p2 * e2y
    out[0] = tx
    out[1] = ty
    out[2] = th
    return True


@_njit
def consistent(
    pairs, npa, npb, Pa, Pb, La, Lb, x, point_tol, angle_tol, offset_tol
):  # pragma: no cover
    """Which mapped pairs agree with the pose ``x``; see
    :func:`scanclique.pose.pair_consistent` (same order as ``pairs``)."""
    c = math.cos(x[2])
    s = math.sin(x[2])
    out = np.empty(pairs.shape[0], np.bool_)
    for k in range(pairs.shape[0]):
        a = pairs[k, 0]
        b = pairs[k, 1]
        if a < npa:
            dx = c * Pb[b, 0] - s * Pb[b, 1] + x[0] - Pa[a, 0]
            dy = s * Pb[b, 0] + c * Pb[b, 1] + x[1] - Pa[a, 1]
            out[k] = math.sqrt(dx * dx + dy * dy) <= point_tol
        else:
            ap = Lb[b - npb, 1] + x[2]
            off = Lb[b - npb, 0] + math.cos(ap) * x[0] + math.sin(ap) * x[1] - La[a - npa, 0]
            out[k] = abs(wrap(ap - La[a - npa, 1])) <= angle_tol and abs(off) <= offset_tol
    return out


@_njit
def closed_form_batch(pairs, indptr, npa, npb, Pa, Pb, La, Lb, poses, ok):  # pragma: no cover
    """:func:`closed_form` of every clique: clique ``i`` is ``pairs[indptr[i]:indptr[i+1]]``."""
    out = np.empty(3)
    for i in range(indptr.shape[0] - 1):
        ok[i] = closed_form(pairs[indptr[i] : indptr[i + 1]], npa, npb, Pa, Pb, La, Lb, out)
        poses[i, 0] = out[0]
        poses[i, 1] = out[1]
        poses[i, 2] = out[2]


@_inline
def _same_pose(poses, i, among, upto):  # pragma: no cover - compiled
    """The first ``j < upto`` with ``among[j]`` whose pose is within 2 cm and 0.2 degrees
    of pose ``i``; -1 when none."""
    for j in range(upto):
        if (
            among[j]
            and abs(poses[i, 0] - poses[j, 0]) < 0.02
            and abs(poses[i, 1] - poses[j, 1]) < 0.02
            and abs(wrap(poses[i, 2] - poses[j, 2])) < 0.0035
        ):
            return j
    return -1


@_njit
def score_batch(
    poses, ok, sizes, size_weight, keep,
    a_ix, a_ref, a_aix, a_free, a_sample,
    b_ix, b_ref, b_aix, b_free, b_sample,
    d, conflict_weight, margin, ratio,
    scores, exact,
):  # fmt: skip  # pragma: no cover - compiled
    """:func:`pose_score` of the poses with ``ok`` set (others get ``-inf``), coarse to
    fine: every pose is first scored on every third sample point of each scan; the
    ``keep`` best by rank (score plus ``size_weight`` per clique vertex, ``sizes``) are
    scored again on the full samples (``exact`` set). Cliques that share most of an
    association give nearly the same pose: a pose within 2 cm and 0.2 degrees of one
    already scored gets that one's score."""
    n = poses.shape[0]
    a_part = a_sample[::3].copy()
    b_part = b_sample[::3].copy()
    for i in range(n):
        exact[i] = False
        if not ok[i]:
            scores[i] = -math.inf
            continue
        same = _same_pose(poses, i, ok, i)
        if same >= 0:
            scores[i] = scores[same]
            continue
        scores[i] = pose_score(
            a_ix, a_ref, a_aix, a_free, a_part,
            b_ix, b_ref, b_aix, b_free, b_part,
            poses[i, 0], poses[i, 1], poses[i, 2], d, conflict_weight, margin, ratio,
        )  # fmt: skip
    rank = np.empty(n)
    for i in range(n):
        rank[i] = scores[i] + size_weight * sizes[i]
    order = np.argsort(-rank, kind="mergesort")
    done = 0
    for q in range(n):
        i = order[q]
        if done >= keep or not ok[i]:
            break
        same = _same_pose(poses, i, exact, n)
        if same >= 0:
            scores[i] = scores[same]
        else:
            scores[i] = pose_score(
                a_ix, a_ref, a_aix, a_free, a_sample,
                b_ix, b_ref, b_aix, b_free, b_sample,
                poses[i, 0], poses[i, 1], poses[i, 2], d, conflict_weight, margin, ratio,
            )  # fmt: skip
            done += 1
        exact[i] = True


@_njit
def _blocks(pairs, npa, npb, Pa, PCa, La, LCa, Pb, PCb, Lb, LCb, x, r, J, Ci):  # pragma: no cover
    """Residual ``r[k]`` (2), Jacobian ``J[k]`` (2x3) and inverse combined covariance
    ``Ci[k]`` (2x2) of each mapped pair at pose ``x``; see
    :func:`scanclique.pose._residuals_jacobian`."""
    c = math.cos(x[2])
    s = math.sin(x[2])
    for k in range(pairs.shape[0]):
        a = pairs[k, 0]
        b = pairs[k, 1]
        for i in range(2):
            for j in range(3):
                J[k, i, j] = 0.0
        if a < npa:
            bx, by = Pb[b, 0], Pb[b, 1]
            r[k, 0] = c * bx - s * by + x[0] - Pa[a, 0]
            r[k, 1] = s * bx + c * by + x[1] - Pa[a, 1]
            J[k, 0, 0] = 1.0
            J[k, 1, 1] = 1.0
            J[k, 0, 2] = -s * bx - c * by
            J[k, 1, 2] = c * bx - s * by
            # C = Ca + R Cb R^T
            p00, p01, p11 = PCb[b, 0, 0], PCb[b, 0, 1], PCb[b, 1, 1]
            q01 = PCb[b, 1, 0]
            r00 = c * c * p00 - c * s * (p01 + q01) + s * s * p11
            r01 = c * s * p00 + c * c * p01 - s * s * q01 - s * c * p11
            r10 = c * s * p00 - s * s * p01 + c * c * q01 - s * c * p11
            r11 = s * s * p00 + s * c * (p01 + q01) + c * c * p11
            c00 = PCa[a, 0, 0] + r00
            c01 = PCa[a, 0, 1] + r01
            c10 = PCa[a, 1, 0] + r10
            c11 = PCa[a, 1, 1] + r11
        else:
            ia = a - npa
            ib = b - npb
            ap = Lb[ib, 1] + x[2]
            nx, ny = math.cos(ap), math.sin(ap)
            lever = -ny * x[0] + nx * x[1]
            r[k, 0] = Lb[ib, 0] + nx * x[0] + ny * x[1] - La[ia, 0]
            r[k, 1] = wrap(ap - La[ia, 1])
            J[k, 0, 0] = nx
            J[k, 0, 1] = ny
            J[k, 0, 2] = lever
            J[k, 1, 2] = 1.0
            # C = Ca + G Cb G^T, G = [[1, lever], [0, 1]]
            b00, b01, b10, b11 = LCb[ib, 0, 0], LCb[ib, 0, 1], LCb[ib, 1, 0], LCb[ib, 1, 1]
            g00 = b00 + lever * (b10 + b01) + lever * lever * b11
            g01 = b01 + lever * b11
            g10 = b10 + lever * b11
            c00 = LCa[ia, 0, 0] + g00
            c01 = LCa[ia, 0, 1] + g01
            c10 = LCa[ia, 1, 0] + g10
            c11 = LCa[ia, 1, 1] + b11
        c00 += 1e-12
        c11 += 1e-12
        det = c00 * c11 - c01 * c10
        Ci[k, 0, 0] = c11 / det
        Ci[k, 0, 1] = -c01 / det
        Ci[k, 1, 0] = -c10 / det
        Ci[k, 1, 1] = c00 / det


@_njit
def _normal_equations(r, J, Ci, H, g):  # pragma: no cover - compiled
    """``H = sum J^T Ci J``, ``g = sum J^T Ci r`` over the blocks."""
    H[:] = 0.0
    g[:] = 0.0
    for k in range(r.shape[0]):
        for i in range(3):
            # (J^T Ci)[i, :] for this block
            t0 = J[k, 0, i] * Ci[k, 0, 0] + J[k, 1, i] * Ci[k, 1, 0]
            t1 = J[k, 0, i] * Ci[k, 0, 1] + J[k, 1, i] * Ci[k, 1, 1]
            g[i] += t0 * r[k, 0] + t1 * r[k, 1]
            for j in range(3):
                H[i, j] += t0 * J[k, 0, j] + t1 * J[k, 1, j]


@_njit
def lsq_pose(
    pairs, npa, npb, Pa, PCa, La, LCa, Pb, PCb, Lb, LCb, x0, iterations, info, maha
):  # pragma: no cover - compiled
    """Gauss–Newton weighted least squares of the pose of mapped pairs (``pairs``, points
    first) from ``x0``; see :func:`scanclique.pose.estimate_pose_lsq`.

    Returns ``(x, ssr)``: the pose and the sum of squared Mahalanobis residuals at it, and
    writes the information matrix ``info`` (3x3) and each pair's Mahalanobis residual
    ``maha`` (K) at the pose."""
    K = pairs.shape[0]
    r = np.empty((K, 2))
    J = np.empty((K, 2, 3))
    Ci = np.empty((K, 2, 2))
    H = np.empty((3, 3))
    g = np.empty(3)
    dx = np.empty(3)
    x = np.empty(3)
    x[:] = x0[:]
    for _ in range(iterations):
        _blocks(pairs, npa, npb, Pa, PCa, La, LCa, Pb, PCb, Lb, LCb, x, r, J, Ci)
        _normal_equations(r, J, Ci, H, g)
        reg = 1e-9 * max(H[0, 0] + H[1, 1] + H[2, 2], 1e-12)
        for i in range(3):
            H[i, i] += reg
        if not solve3(H, g, dx):
            break
        x[0] -= dx[0]
        x[1] -= dx[1]
        x[2] = wrap(x[2] - dx[2])
        if max(abs(dx[0]), abs(dx[1]), abs(dx[2])) < 1e-6:
            break
    _blocks(pairs, npa, npb, Pa, PCa, La, LCa, Pb, PCb, Lb, LCb, x, r, J, Ci)
    _normal_equations(r, J, Ci, info, g)
    ssr = 0.0
    for k in range(K):
        q = r[k, 0] * (Ci[k, 0, 0] * r[k, 0] + Ci[k, 0, 1] * r[k, 1]) + r[k, 1] * (
            Ci[k, 1, 0] * r[k, 0] + Ci[k, 1, 1] * r[k, 1]
        )
        q = max(q, 0.0)
        maha[k] = math.sqrt(q)
        ssr += q
    return x, ssr


@_njit
def covariance(info, scale, cov):  # pragma: no cover - compiled
    """Covariance of ``info / scale`` (3x3 information) into ``cov``; directions with an
    eigenvalue below 1e-9 of the largest get ``inf`` in exactly the entries they touch.
    Returns True when every direction is constrained."""
    w, v = np.linalg.eigh(info / scale)
    top = max(w[2], 1e-300)
    cov[:] = 0.0
    full = True
    for k in range(3):
        if w[k] > 1e-9 * top:
            for i in range(3):
                for j in range(3):
                    cov[i, j] += v[i, k] * v[j, k] / w[k]
        else:
            full = False
    if not full:
        for k in range(3):
            if not w[k] > 1e-9 * top:
                for i in range(3):
                    if abs(v[i, k]) > 1e-9:
                        for j in range(3):
                            if abs(v[j, k]) > 1e-9:
                                cov[i, j] = math.inf
    return full


# --------------------------------------------------------------------------------------
# Clique hypotheses (paper §5.3 and this library's additions)
# --------------------------------------------------------------------------------------
@_njit
def _append(store, count, clique):  # pragma: no cover - compiled
    """Append ``clique`` to the flat store ``(data, indptr)``; returns the new store."""
    data, indptr = store
    start = indptr[count]
    need = start + clique.shape[0]
    if need > data.shape[0]:
        nd = np.empty(max(2 * data.shape[0], need), np.int64)
        nd[:start] = data[:start]
        data = nd
    if count + 2 > indptr.shape[0]:
        ni = np.zeros(2 * indptr.shape[0] + 2, np.int64)
        ni[: count + 1] = indptr[: count + 1]
        indptr = ni
    data[start:need] = clique
    indptr[count + 1] = need
    return (data, indptr)


@_njit
def _maximum_of(A, verts, deadline, node_limit):  # pragma: no cover - compiled
    """A maximum clique of the subgraph of ``A`` induced by ``verts`` (at least one), as
    positions in ``verts``, sorted: the lean path of ``clique.max_clique``
    (:func:`scanclique._kernels.clique_search.maximum_until`), and the search nodes it
    used and its status. The best found when ``node_limit`` nodes are spent or the clock
    passes ``deadline`` (the outer guard)."""
    m = verts.shape[0]
    alive = np.zeros(A.shape[1], np.uint64)
    for v in verts:
        setbit(alive, v)
    out = np.empty(m, np.int64)
    size, nodes, status = maximum_until(
        induced_rows(A, verts, m, alive), m, 0, deadline, node_limit, out
    )
    return out[:size], nodes, status


@_njit
def hypothesis_cliques(
    A, n, limit, peel, per_vertex, min_size, node_limit, deadline, opts
):  # pragma: no cover - compiled
    """The cliques that become association hypotheses, in one compiled call.

    1. every maximum clique of ``A`` (bitset rows, ``n`` vertices), at most ``limit``;
    2. ``peel`` times: the maximum clique of the vertices no clique so far uses (stops
       below ``min_size`` vertices);
    3. for the ``per_vertex`` vertices of highest degree (ties to the lower label): the
       maximum clique containing the vertex, when at least ``min_size`` large. A vertex
       of a maximum clique is skipped when step 1 listed every maximum clique (its
       clique would be one of them).

    The budget that decides the result is ``node_limit`` search nodes for all steps
    together (the same graph gives the same cliques on every machine); ``deadline``
    (``time.perf_counter`` clock, ``inf`` for none) is an outer guard only. Returns
    ``(data, indptr, count, omega, optimal, complete, stop, nodes)``: clique ``i`` is
    ``data[indptr[i]:indptr[i + 1]]`` (sorted labels), each distinct clique of at least
    ``min_size`` vertices once, in the order found; ``optimal`` when omega was proven,
    ``complete`` when step 1 listed every maximum clique; ``stop`` the status that cut
    the search short (``NODE_LIMIT`` or ``TIME_LIMIT``), ``FINISHED`` when nothing did;
    ``nodes`` the search nodes used.
    """
    store = (np.empty(64, np.int64), np.zeros(16, np.int64))
    count = 0
    best, used, status, found, status_all = search_until(
        A, n, 0, 2, limit, deadline, node_limit, opts
    )
    optimal = status == 0
    complete = optimal and status_all == 0
    stop = _FINISHED
    if status == _NODE_LIMIT or status_all == _NODE_LIMIT:
        stop = _NODE_LIMIT
    elif status == _TIME_LIMIT or status_all == _TIME_LIMIT:
        stop = _TIME_LIMIT
    omega = best.shape[0]
    in_max = np.zeros(n, np.bool_)
    for r in range(found.shape[0]):
        for v in found[r]:
            in_max[v] = True
    if limit > 0:
        if found.shape[0] > 0:
            for r in range(found.shape[0]):
                store = _append(store, count, found[r])
                count += 1
        else:
            store = _append(store, count, best)
            count += 1
    # 2. peeling
    alive = np.ones(n, np.bool_)
    for _ in range(peel):
        data, indptr = store
        for j in range(indptr[count]):
            alive[data[j]] = False
        left = np.flatnonzero(alive)
        if left.shape[0] < min_size:
            break
        if used >= node_limit:
            stop = _NODE_LIMIT
            break
        if now() >= deadline:
            stop = _TIME_LIMIT
            break
        r, k, st = _maximum_of(A, left, deadline, node_limit - used)
        used += k
        if st != _FINISHED and stop == _FINISHED:
            stop = st
        if r.shape[0] < min_size:
            break
        store = _append(store, count, np.sort(left[r]))
        count += 1
    # 3. vertex-guided cliques
    if per_vertex > 0:
        deg = np.zeros(n, np.int64)
        for v in range(n):
            for w in range(A.shape[1]):
                deg[v] += np.int64(ctpop(A[v, w]))
        order = np.argsort(-deg, kind="mergesort")
        one = np.uint64(1)
        for q in range(min(per_vertex, n)):
            v = order[q]
            if deg[v] + 1 < min_size:
                break
            if used >= node_limit:
                stop = _NODE_LIMIT
                break
            if now() >= deadline:
                stop = _TIME_LIMIT
                break
            if complete and in_max[v]:
                continue
            nb = np.empty(deg[v], np.int64)
            m = 0
            for u in range(n):
                if (A[v, u >> 6] >> np.uint64(u & 63)) & one:
                    nb[m] = u
                    m += 1
            r = np.empty(0, np.int64)
            if m > 0:
                r, k, st = _maximum_of(A, nb, deadline, node_limit - used)
                used += k
                if st != _FINISHED and stop == _FINISHED:
                    stop = st
            if r.shape[0] + 1 >= min_size:
                c = np.empty(r.shape[0] + 1, np.int64)
                c[: r.shape[0]] = nb[r]
                c[r.shape[0]] = v
                store = _append(store, count, np.sort(c))
                count += 1
    data, indptr = store
    data, indptr, count = _distinct_cliques(data, indptr, count, min_size)
    return data, indptr, count, omega, optimal, complete, stop, used


@_njit
def _distinct_cliques(data, indptr, count, min_size):  # pragma: no cover - compiled
    """The cliques of the flat store with at least ``min_size`` vertices, each once (the
    first occurrence; the vertex lists are sorted), order kept: ``(data, indptr, count)``."""
    keep = np.zeros(count, np.bool_)
    for i in range(count):
        a0, a1 = indptr[i], indptr[i + 1]
        if a1 - a0 < min_size:
            continue
        dup = False
        for j in range(i):
            if not keep[j]:
                continue
            b0, b1 = indptr[j], indptr[j + 1]
            if b1 - b0 != a1 - a0:
                continue
            same = True
            for q in range(a1 - a0):
                if data[a0 + q] != data[b0 + q]:
                    same = False
                    break
            if same:
                dup = True
                break
        keep[i] = not dup
    out = np.empty(indptr[count], np.int64)
    optr = np.zeros(count + 1, np.int64)
    k = 0
    for i in range(count):
        if keep[i]:
            n = indptr[i + 1] - indptr[i]
            out[optr[k] : optr[k] + n] = data[indptr[i] : indptr[i + 1]]
            optr[k + 1] = optr[k] + n
            k += 1
    return out[: optr[k]], optr[: k + 1].copy(), k


# --------------------------------------------------------------------------------------
# The best few hypotheses: full estimate, score, ICP, score (one call for all)
# --------------------------------------------------------------------------------------
@_njit
def _points_first_into(pairs, npa, out):  # pragma: no cover - compiled
    """``pairs`` reordered points first, then lines, each in their order, into ``out``."""
    k = 0
    for i in range(pairs.shape[0]):
        if pairs[i, 0] < npa:
            out[k, 0] = pairs[i, 0]
            out[k, 1] = pairs[i, 1]
            k += 1
    for i in range(pairs.shape[0]):
        if pairs[i, 0] >= npa:
            out[k, 0] = pairs[i, 0]
            out[k, 1] = pairs[i, 1]
            k += 1


@_njit
def refine_candidates(
    pairs, indptr, npa, npb,
    Pa, PCa, La, LCa, Pb, PCb, Lb, LCb,
    a_ix, a_ref, a_normals, a_aix, a_free, a_sample,
    b_ix, b_ref, b_aix, b_free, b_sample,
    min_pairs, outlier, d, conflict_weight, margin, ratio,
    icp_on, iterations, max_corr, min_corr,
    ok, x_est, info, ssr, used, maha, score_est, x_icp, score_icp,
):  # fmt: skip  # pragma: no cover - compiled
    """For each candidate clique ``pairs[indptr[i]:indptr[i+1]]``: the weighted least
    squares pose from the closed form (5 Gauss–Newton steps), once more without the pairs
    whose Mahalanobis residual exceeds ``outlier`` when at least ``min_pairs`` remain;
    its raw-scan score; then (``icp_on``) point-to-line ICP of B's sample onto A from it,
    and the ICP pose's score.

    Writes per candidate: ``ok`` (a pose was found), ``x_est`` (3), ``info`` (3x3) and
    ``ssr`` at the estimate, ``used`` (pairs kept), ``maha`` (their Mahalanobis residuals,
    points first, at ``indptr[i]``...), ``score_est``, ``x_icp`` and ``score_icp``
    (``-inf`` when no ICP ran).
    """
    K = pairs.shape[0]
    ordered = np.empty((K, 2), np.int64)
    start_x = np.empty(3)
    out_icp = np.empty(3)
    for i in range(indptr.shape[0] - 1):
        s0 = indptr[i]
        s1 = indptr[i + 1]
        sub = ordered[s0:s1]
        _points_first_into(pairs[s0:s1], npa, sub)
        ok[i] = closed_form(sub, npa, npb, Pa, Pb, La, Lb, start_x)
        score_icp[i] = -math.inf
        if not ok[i]:
            continue
        m = maha[s0:s1]
        x, q = lsq_pose(sub, npa, npb, Pa, PCa, La, LCa, Pb, PCb, Lb, LCb, start_x, 5, info[i], m)
        n_used = s1 - s0
        n_good = 0
        for k in range(s1 - s0):
            if m[k] <= outlier:
                n_good += 1
        if n_good < s1 - s0 and n_good >= min_pairs:
            keep = np.empty((n_good, 2), np.int64)
            g = 0
            for k in range(s1 - s0):
                if m[k] <= outlier:
                    keep[g, 0] = sub[k, 0]
                    keep[g, 1] = sub[k, 1]
                    g += 1
            x, q = lsq_pose(
                keep, npa, npb, Pa, PCa, La, LCa, Pb, PCb, Lb, LCb, x, 5, info[i], m[:n_good]
            )
            n_used = n_good
        used[i] = n_used
        ssr[i] = q
        x_est[i, 0] = x[0]
        x_est[i, 1] = x[1]
        x_est[i, 2] = x[2]
        score_est[i] = pose_score(
            a_ix, a_ref, a_aix, a_free, a_sample,
            b_ix, b_ref, b_aix, b_free, b_sample,
            x[0], x[1], x[2], d, conflict_weight, margin, ratio,
        )  # fmt: skip
        if icp_on and b_sample.shape[0] >= 3:
            if a_ref.shape[0] >= 3:
                icp(a_ix, a_ref, a_normals, b_sample, x, iterations, max_corr, min_corr, out_icp)
            else:
                out_icp[:] = x[:]
            x_icp[i, 0] = out_icp[0]
            x_icp[i, 1] = out_icp[1]
            x_icp[i, 2] = out_icp[2]
            score_icp[i] = pose_score(
                a_ix, a_ref, a_aix, a_free, a_sample,
                b_ix, b_ref, b_aix, b_free, b_sample,
                out_icp[0], out_icp[1], out_icp[2], d, conflict_weight, margin, ratio,
            )  # fmt: skip


# --------------------------------------------------------------------------------------
# Pose search on the raw scans (for matches whose features explain the scans poorly)
# --------------------------------------------------------------------------------------
@_njit
def _orientation_histogram(normals, bins):  # pragma: no cover - compiled
    """Histogram of the surface orientations (normal angle modulo pi) of ``normals``
    (zero rows skipped) in ``bins`` bins over ``[0, pi)``, smoothed by ``[1/2, 1, 1/2]``."""
    h = np.zeros(bins)
    for k in range(normals.shape[0]):
        nx = normals[k, 0]
        ny = normals[k, 1]
        if nx == 0.0 and ny == 0.0:
            continue
        a = math.atan2(ny, nx) % math.pi
        h[int(a / math.pi * bins) % bins] += 1.0
    out = np.empty(bins)
    for i in range(bins):
        out[i] = h[i] + 0.5 * (h[(i - 1) % bins] + h[(i + 1) % bins])
    return out


@_njit
def rotation_candidates(a_normals, b_normals, bins, n_peaks, out):  # pragma: no cover
    """Rotations of B into A that align the two scans' surface orientations: the
    ``n_peaks`` highest peaks (at least 5 bins apart) of the circular cross-correlation of
    their orientation histograms (``bins`` bins over pi), each with its opposite (+pi),
    since a surface orientation does not say which way it faces. Writes ``out`` (2 *
    n_peaks) and returns how many were written."""
    ha = _orientation_histogram(a_normals, bins)
    hb = _orientation_histogram(b_normals, bins)
    corr = np.empty(bins)
    for s in range(bins):
        acc = 0.0
        for i in range(bins):
            acc += ha[i] * hb[(i - s) % bins]
        corr[s] = acc
    n = 0
    for _ in range(n_peaks):
        best = -1
        for s in range(bins):
            if corr[s] > 0.0 and (best < 0 or corr[s] > corr[best]):
                best = s
        if best < 0:
            break
        th = best * math.pi / bins
        out[n] = wrap(th)
        out[n + 1] = wrap(th + math.pi)
        n += 2
        for d in range(-5, 6):
            corr[(best + d) % bins] = -1.0
    return n


#: translation_votes' grid has at most this many cells a side (coarser cells beyond), and
#: it keeps this many leading cells while voting
VOTE_GRID_MAX = 256
VOTE_LEADERS = 16


@_njit
def translation_votes(A, B, th, cell, top, out):  # pragma: no cover - compiled
    """Translations of B into A under the rotation ``th``, by vote (a Hough transform):
    every pair of points ``(A[i], B[j])`` votes for ``A[i] - R(th) B[j]`` in square
    cells of ``cell`` metres (coarser when the votes would span more than
    ``VOTE_GRID_MAX`` cells a side); the pairs of one surface seen in both scans vote for
    the same cell. Writes to ``out`` (top, 3) up to ``top`` of the most voted cells, each
    not a neighbour of a better one, as ``(tx, ty, votes)`` with the mean of the votes in
    the 3 x 3 cells around the peak; returns how many were written.

    The leading cells are tracked while voting (the ``VOTE_LEADERS`` best so far), so the
    grid is read once per vote."""
    na = A.shape[0]
    nb = B.shape[0]
    if na == 0 or nb == 0:
        return 0
    c = math.cos(th)
    s = math.sin(th)
    Bx = np.empty(nb)
    By = np.empty(nb)
    for j in range(nb):
        Bx[j] = c * B[j, 0] - s * B[j, 1]
        By[j] = s * B[j, 0] + c * B[j, 1]
    x0 = A[:, 0].min() - Bx.max()
    y0 = A[:, 1].min() - By.max()
    span = max(A[:, 0].max() - Bx.min() - x0, A[:, 1].max() - By.min() - y0)
    cell = max(cell, span / (VOTE_GRID_MAX - 1))
    side = int(span / cell) + 1
    inv = 1.0 / cell
    # cell coordinates: gx = int(ax[i] - bx[j]) with both shifted to stay non-negative
    ax = np.empty(na)
    ay = np.empty(na)
    for i in range(na):
        ax[i] = (A[i, 0] - x0) * inv
        ay[i] = (A[i, 1] - y0) * inv
    bx = np.empty(nb)
    by = np.empty(nb)
    for j in range(nb):
        bx[j] = Bx[j] * inv
        by[j] = By[j] * inv
    grid = np.zeros((side, side), np.int32)
    sum_x = np.zeros((side, side))
    sum_y = np.zeros((side, side))
    L = VOTE_LEADERS
    lead = np.full(L, -1, np.int64)  # cell index gx * side + gy, best first
    lead_n = np.zeros(L, np.int64)
    for j in range(nb):
        for i in range(na):
            gx = min(int(ax[i] - bx[j]), side - 1)
            gy = min(int(ay[i] - by[j]), side - 1)
            v = grid[gx, gy] + 1
            grid[gx, gy] = v
            sum_x[gx, gy] += A[i, 0] - Bx[j]
            sum_y[gx, gy] += A[i, 1] - By[j]
            if v > lead_n[L - 1]:
                g = gx * side + gy
                k = L - 1
                for q in range(L):  # the cell's place if it leads already
                    if lead[q] == g:
                        k = q
                        break
                while k > 0 and lead_n[k - 1] < v:
                    lead[k] = lead[k - 1]
                    lead_n[k] = lead_n[k - 1]
                    k -= 1
                lead[k] = g
                lead_n[k] = v
    n = 0
    px = np.empty(top, np.int64)
    py = np.empty(top, np.int64)
    for q in range(L):
        if n >= top or lead[q] < 0:
            break
        gx = lead[q] // side
        gy = lead[q] % side
        near = False
        for p in range(n):
            if abs(gx - px[p]) <= 1 and abs(gy - py[p]) <= 1:
                near = True
        if not near:
            px[n] = gx
            py[n] = gy
            out[n, 2] = lead_n[q]
            n += 1
    sx = np.zeros(top)
    sy = np.zeros(top)
    sn = np.zeros(top)
    for p in range(n):
        for gx in range(max(px[p] - 1, 0), min(px[p] + 2, side)):
            for gy in range(max(py[p] - 1, 0), min(py[p] + 2, side)):
                sx[p] += sum_x[gx, gy]
                sy[p] += sum_y[gx, gy]
                sn[p] += grid[gx, gy]
    for p in range(n):
        out[p, 0] = sx[p] / sn[p]
        out[p, 1] = sy[p] / sn[p]
    return n


@_njit
def search_seeds(
    a_normals, b_normals, a_sample, b_sample, bins, n_peaks, cell, top
):  # pragma: no cover - compiled
    """Pose seeds of the raw-scan search: for each of :func:`rotation_candidates`, the
    :func:`translation_votes` of the two samples. Returns ``(m, 3)`` poses."""
    rot = np.empty(2 * n_peaks)
    nr = rotation_candidates(a_normals, b_normals, bins, n_peaks, rot)
    seeds = np.empty((nr * top, 3))
    t = np.empty((top, 3))
    m = 0
    for r in range(nr):
        k = translation_votes(a_sample, b_sample, rot[r], cell, top, t)
        for q in range(k):
            seeds[m, 0] = t[q, 0]
            seeds[m, 1] = t[q, 1]
            seeds[m, 2] = rot[r]
            m += 1
    return seeds[:m]
