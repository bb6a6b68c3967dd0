"""Vertex orders, cores and induced subgraphs for the clique kernels (private).

Degeneracy (smallest-last) order with core numbers, k-core peeling, renumbering of
bitset rows, degree sorting and the rows of induced subgraphs (one-word or multi-word).
"""

# ruff: noqa: E402 (ensure_cache() runs before numba is imported)
from __future__ import annotations

from . import ensure_cache

ensure_cache()  # before any njit(cache=True) below picks its cache location

import numpy as np

from .bitset import ONE, ZERO, clearbit, cttz, popcount, setbit
from .jit import njit


@njit(cache=True)
def _swap(vert, pos, p, q):
    """Exchange the vertices at positions ``p`` and ``q`` of ``vert`` (``pos`` its inverse)."""
    x = vert[p]
    y = vert[q]
    vert[p] = y
    pos[y] = p
    vert[q] = x
    pos[x] = q


@njit(cache=True)
def degeneracy_order(A, n):
    """Smallest-last order (densest core first) and each vertex's core number.

    Vertices are peeled one at a time, each time one of minimum degree in the graph that
    remains; ``order[n - 1]`` is the first peeled, ``order[0]`` the last, so that the
    search meets the densest core first (the initial order of MCQ/MCS), and the core
    number of a vertex is the largest minimum degree seen up to its removal. Dense graphs
    of up to 1024 vertices (density above 1/4, where the search is hard) break ties by
    the lowest label, in O(n^2); other graphs keep the vertices sorted by remaining degree
    in one array of buckets (Matula & Beck 1983, with the swaps of Batagelj & Zaversnik
    2003), O(n W + m).
    """
    W = A.shape[1]
    deg = np.empty(n, np.int64)
    dmax = 0
    m2 = 0
    for v in range(n):
        deg[v] = popcount(A[v], W)
        dmax = max(dmax, deg[v])
        m2 += deg[v]
    if n <= 1024 and 4 * m2 > n * n:
        return _peel_exact(A, n, deg)
    # vert: vertices sorted by remaining degree, bucket e starting at start[e]; the
    # first i entries are peeled
    start = np.zeros(dmax + 2, np.int64)
    for v in range(n):
        start[deg[v] + 1] += 1
    for e in range(dmax + 1):
        start[e + 1] += start[e]
    vert = np.empty(n, np.int64)
    pos = np.empty(n, np.int64)
    fill = start.copy()
    for v in range(n):
        pos[v] = fill[deg[v]]
        vert[pos[v]] = v
        fill[deg[v]] += 1
    order = np.empty(n, np.int64)
    core = np.empty(n, np.int64)
    k = 0
    for i in range(n):
        # invariant: vert[i:] hold the remaining vertices in non-decreasing remaining
        # degree; bucket deg[vert[i]] begins at i, every higher bucket e at start[e]
        # (after the two assignments below: buckets d - 1 and d begin at i + 1)
        v = vert[i]
        d = deg[v]
        start[d] = i + 1
        if d > 0:
            start[d - 1] = i + 1  # empty: a vertex falling below d opens it
        k = max(k, d)
        core[v] = k
        order[n - 1 - i] = v
        for w in range(W):
            x = A[v, w]
            while x:
                b = cttz(x)
                x &= x - ONE
                u = w * 64 + int(b)
                pu = pos[u]
                if pu <= i:  # peeled already
                    continue
                # swap u to the front of bucket e and move the bucket's start past it:
                # u ends bucket e - 1; then swap it to the front of that bucket, so that
                # among equal degrees the vertex that lost a neighbour last is peeled first
                e = deg[u]
                pw = start[e]
                _swap(vert, pos, pu, pw)
                start[e] = pw + 1
                _swap(vert, pos, pw, start[e - 1])
                deg[u] = e - 1
    return order, core


@njit(cache=True)
def _peel_exact(A, n, deg):
    """Smallest-last peeling by an argmin per step (see :func:`degeneracy_order`).

    A second implementation of the same order, kept on purpose: it breaks ties by the
    lowest label, where the buckets break them by the last vertex to lose a neighbour,
    so on dense graphs it gives another order (and the order decides the search's node
    counts); its O(n^2) is cheap exactly where it is used (dense, n <= 1024)."""
    W = A.shape[1]
    removed = np.zeros(n, np.bool_)
    order = np.empty(n, np.int64)
    core = np.empty(n, np.int64)
    k = 0
    for i in range(n):
        # invariant: deg[u] = |N(u) minus removed| for every remaining u
        best = -1
        bd = n + 1
        for v in range(n):
            if not removed[v] and deg[v] < bd:
                bd = deg[v]
                best = v
        k = max(k, bd)
        core[best] = k
        order[n - 1 - i] = best
        removed[best] = True
        for w in range(W):
            x = A[best, w]
            while x:
                b = cttz(x)
                x &= x - ONE
                u = w * 64 + int(b)
                if not removed[u]:
                    deg[u] -= 1
    return order, core


@njit(cache=True)
def relabel(A, n, order):
    """Bitset rows of the graph renumbered so that new vertex ``i`` is old ``order[i]``."""
    W = A.shape[1]
    pos = np.empty(n, np.int64)
    for i in range(n):
        pos[order[i]] = i
    B = np.zeros((n, W), np.uint64)
    for i in range(n):
        v = order[i]
        for w in range(W):
            x = A[v, w]
            while x:
                b = cttz(x)
                x &= x - ONE
                setbit(B[i], pos[w * 64 + int(b)])
    return B


@njit(cache=True)
def peel_core(A, n, deg, k, alive, stack):
    """The ``k``-core: ``alive`` (all ``n`` bits set on entry) keeps the vertices with at
    least ``k`` neighbours among the kept ones; ``deg`` becomes their degree there.
    Returns how many. A clique of ``k + 1`` vertices lies in the ``k``-core. ``stack``:
    scratch for ``n`` vertices."""
    W = A.shape[1]
    top = 0
    for v in range(n):
        if deg[v] < k:
            clearbit(alive, v)
            stack[top] = v
            top += 1
    left = n - top
    while top > 0:
        # invariant: the stacked vertices are out of `alive` but still counted in the
        # degrees of their kept neighbours
        top -= 1
        v = stack[top]
        for w in range(W):
            x = A[v, w] & alive[w]
            while x:
                b = cttz(x)
                x &= x - ONE
                u = w * 64 + int(b)
                deg[u] -= 1
                if deg[u] < k:
                    clearbit(alive, u)
                    stack[top] = u
                    top += 1
                    left -= 1
    return left


@njit(cache=True)
def sort_by_degree(items, m, deg, dmax, out):
    """``out[:m]`` = ``items[:m]`` in non-increasing ``deg`` (ties in the given order):
    a counting sort, O(m + dmax)."""
    start = np.zeros(dmax + 2, np.int64)
    for i in range(m):
        start[dmax - deg[items[i]] + 1] += 1
    for e in range(dmax + 1):
        start[e + 1] += start[e]
    for i in range(m):
        v = items[i]
        e = dmax - deg[v]
        out[start[e]] = v
        start[e] += 1


@njit(cache=True)
def word_rows(A, verts, m, alive, pos, S):
    """``S[:m]``: one-word adjacency rows of the subgraph induced by ``verts[:m]``
    (``m <= 64``, ``alive`` their bitset), renumbered so that new vertex ``i`` is
    ``verts[i]`` (``pos``: scratch for the inverse, one entry per vertex of ``A``)."""
    W = A.shape[1]
    for i in range(m):
        pos[verts[i]] = i
    for i in range(m):
        v = verts[i]
        r = ZERO
        for w in range(W):
            x = A[v, w] & alive[w]
            while x:
                b = cttz(x)
                x &= x - ONE
                r |= ONE << np.uint64(pos[w * 64 + int(b)])
        S[i] = r
    return S


@njit(cache=True)
def induced_rows(A, verts, m, alive):
    """Multi-word rows of the subgraph induced by ``verts[:m]`` (``alive`` their
    bitset), renumbered so that new vertex ``i`` is ``verts[i]``."""
    W = A.shape[1]
    pos = np.empty(A.shape[0], np.int64)
    for i in range(m):
        pos[verts[i]] = i
    B = np.zeros((m, (m + 63) >> 6), np.uint64)
    for i in range(m):
        v = verts[i]
        for w in range(W):
            x = A[v, w] & alive[w]
            while x:
                b = cttz(x)
                x &= x - ONE
                setbit(B[i], pos[w * 64 + int(b)])
    return B
