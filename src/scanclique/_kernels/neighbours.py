"""Nearest neighbours without a tree: the bearing-window search over a scan's points
sorted by bearing, surface normals, and the arrays of a prepared scan.

Part of the matcher's kernels (private; gathered in :mod:`scanclique._match_kernels`)."""

# ruff: noqa: E402 (ensure_cache() runs before numba caches anything)
from __future__ import annotations

import math

from . import ensure_cache

ensure_cache()

import numpy as np

from .algebra import smallest_eigvec2
from .jit import njit

_njit = njit(cache=True, nogil=True)
#: for the helpers called once per point: inlined into the caller at numba IR level, so
#: that the arrays they take are not reference-counted on every call
_inline = njit(cache=True, nogil=True, inline="always")


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


@_inline
def _offer(pts, j, x, y, r, r2, bd, bi, m, k, w):  # pragma: no cover - compiled
    """Offer point ``j`` to the ``k`` nearest of ``(x, y)`` (at range ``r``) when within
    ``sqrt(r2)``; once ``k`` are held, narrow the bearing half-window ``w`` to the k-th
    distance. Returns the new ``(m, w)``."""
    dx = pts[j, 0] - x
    dy = pts[j, 1] - y
    d2 = dx * dx + dy * dy
    if d2 <= r2:
        m = _keep_nearest(bd, bi, m, k, d2, j)
        if m == k:
            w = min(w, _half_window(math.sqrt(bd[k - 1]) / r))
    return m, w


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
                        m, w = _offer(pts, hi, x, y, r, r2, bd, bi, m, k, w)
                        hi += 1
                        hi_ok = hi < n
                if lo_ok:
                    if bear[i] - bear[lo] > w:
                        lo_ok = False
                    else:
                        m, w = _offer(pts, lo, x, y, r, r2, bd, bi, m, k, w)
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
