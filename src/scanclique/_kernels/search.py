"""Pose search on the raw scans (orientation histograms, Hough votes of translations)
for matches whose features explain the scans poorly.

Part of the matcher's kernels (private; gathered in :mod:`scanclique._match_kernels`)."""

# ruff: noqa: E402 (ensure_cache() runs before numba caches anything)
from __future__ import annotations

import math

from . import ensure_cache

ensure_cache()

import numpy as np

from .algebra import wrap
from .jit import njit

_njit = njit(cache=True, nogil=True)
#: for the helpers called once per point: inlined into the caller at numba IR level, so
#: that the arrays they take are not reference-counted on every call
_inline = njit(cache=True, nogil=True, inline="always")


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
