"""Initial cliques for the branch and bound (private): greedy cliques and a tabu local
search. They only raise the bar the exact search must beat; nothing here decides a result
on its own.
"""

# ruff: noqa: E402 (ensure_cache() runs before numba is imported)
from __future__ import annotations

from . import ensure_cache

ensure_cache()  # before any njit(cache=True) below picks its cache location

import numpy as np

from .bitset import ONE, ZERO, cttz, head, now, popcount
from .jit import njit


@njit(cache=True)
def greedy_clique(B, n, P, deadline, core):
    """Best of the greedy cliques grown from each vertex (until the kernel clock passes
    ``deadline``).

    From ``s``: candidates ``N(s)``, then repeatedly add the lowest-numbered candidate (in
    the degeneracy numbering: the one deepest in the core) and intersect. O(n w W).
    ``core[s]`` is the core number of ``s`` (non-increasing in the degeneracy numbering):
    a clique through ``s`` has at most ``core[s] + 1`` vertices, so the starts end once
    that cannot beat the best.
    """
    W = B.shape[1]
    best = np.empty(n, np.int64)
    bsize = 0
    cur = np.empty(n, np.int64)
    for s in range(n):
        if core[s] + 1 <= bsize:
            break
        if (s & 1023) == 1023 and now() > deadline:
            break
        for w in range(W):
            P[w] = B[s, w]
        cur[0] = s
        size = 1
        w0 = 0
        while True:
            # invariant: cur[:size] is a clique, P its common neighbourhood
            while w0 < W and P[w0] == ZERO:
                w0 += 1
            if w0 == W:
                break
            u = w0 * 64 + int(cttz(P[w0]))
            cur[size] = u
            size += 1
            for w in range(w0, W):
                P[w] &= B[u, w]
        if size > bsize:
            bsize = size
            for i in range(size):
                best[i] = cur[i]
    return head(best, bsize)


@njit(inline="always")
def greedy_from(A, s, key, cur, P, bsize):
    """A greedy clique from ``s``, by ``key``: candidates ``N(s)``; repeatedly add the
    candidate of highest ``key`` (the lowest label among equals) and intersect, until no
    candidate is left or the clique cannot have more than ``bsize`` vertices. Writes it to
    ``cur``, returns its size (``P``: scratch for a set). ``key >= 0``.

    The greedy of :func:`greedy_by_degree` (``key`` the degrees) and of the weighted
    search's initial clique (``key`` the weights, ``bsize = 0``: no size bound)."""
    W = A.shape[1]
    for w in range(W):
        P[w] = A[s, w]
    cur[0] = s
    size = 1
    while True:
        # invariant: cur[:size] is a clique, P its common neighbourhood
        if size + popcount(P, W) <= bsize:
            break  # cannot beat the best
        u = -1
        ku = -1
        for w in range(W):
            x = P[w]
            while x:
                b = cttz(x)
                x &= x - ONE
                j = w * 64 + int(b)
                if key[j] > ku:
                    ku = key[j]
                    u = j
        if u < 0:
            break
        cur[size] = u
        size += 1
        for w in range(W):
            P[w] &= A[u, w]
    return size


@njit(cache=True)
def greedy_by_degree(A, deg, order, starts, best, cur, P):
    """Best of the greedy cliques grown from ``order[:starts]`` (highest degree first).

    From ``s``: candidates ``N(s)``; repeatedly add the candidate of highest degree and
    intersect, until no candidate is left or the clique cannot beat the best one
    (:func:`greedy_from`). A clique through ``s`` has at most ``deg[s] + 1`` vertices, so
    the starts end once that cannot beat the best. Writes the clique to ``best``, returns
    its size (``cur``: scratch for a clique, ``P``: for a set).
    """
    bsize = 0
    for t in range(starts):
        s = order[t]
        if deg[s] + 1 <= bsize:
            break
        size = greedy_from(A, s, deg, cur, P, bsize)
        if size > bsize:
            bsize = size
            for i in range(size):
                best[i] = cur[i]
    return bsize


@njit(cache=True)
def _rand(state, k):
    """Uniform integer in ``[0, k)`` from a xorshift64 generator (Marsaglia 2003) kept in
    ``state[0]``: deterministic, and numba's global generator is left alone."""
    x = state[0]
    x ^= x << np.uint64(13)
    x ^= x >> np.uint64(7)
    x ^= x << np.uint64(17)
    state[0] = x
    return int(x % np.uint64(k))


@njit(cache=True)
def _ls_add(B, n, W, v, miss, sign):
    # every vertex u != v not adjacent to v gains (loses) one missing clique neighbour
    for w in range(W):
        x = ~B[v, w]
        if w == W - 1 and (n & 63) != 0:
            x &= (ONE << np.uint64(n & 63)) - ONE
        while x:
            b = cttz(x)
            x &= x - ONE
            miss[w * 64 + int(b)] += sign
    miss[v] -= sign


@njit(inline="always")
def _ls_join(B, n, W, v, miss, inC, where, C, size):
    """``v`` joins the clique ``C[:size]``; returns the new size."""
    _ls_add(B, n, W, v, miss, 1)
    inC[v] = True
    where[v] = size
    C[size] = v
    return size + 1


@njit(inline="always")
def _ls_leave(B, n, W, u, miss, inC, where, C, size):
    """``u`` leaves the clique ``C[:size]`` (the last vertex takes its place); returns the
    new size."""
    _ls_add(B, n, W, u, miss, -1)
    inC[u] = False
    i = where[u]
    size -= 1
    C[i] = C[size]
    where[C[i]] = i
    return size


@njit(cache=True)
def local_search(B, n, init, max_iter, stall, deadline, seed):
    """Tabu plateau search from ``init``: add moves, (1,1)-swaps, and drops when stuck.

    ``miss[v]`` counts the clique vertices not adjacent to ``v``: ``v`` can be added when
    it is 0 and swapped in (for its one non-neighbour) when it is 1. A vertex swapped or
    dropped out is tabu for a few iterations. After ``stall`` iterations without a new
    best, the search restarts from a random vertex. After Grosso, Locatelli & Pullan (2008)
    and Wu & Hao (2012), much simplified.
    """
    W = B.shape[1]
    rng = np.full(1, np.uint64(seed) | ONE, np.uint64)
    inC = np.zeros(n, np.bool_)
    C = np.empty(n + 1, np.int64)
    where = np.empty(n, np.int64)
    miss = np.zeros(n, np.int64)
    tabu = np.zeros(n, np.int64)
    cand_a = np.empty(n, np.int64)
    cand_s = np.empty(n, np.int64)
    size = 0
    for v in init:
        size = _ls_join(B, n, W, v, miss, inC, where, C, size)
    best = head(init, init.shape[0])
    last = 0
    for it in range(max_iter):
        # invariant: C[:size] is a clique; miss[v] = |C minus N(v) minus {v}|
        if (it & 255) == 255 and now() > deadline:
            break
        if it - last > stall:  # restart from a random vertex
            while size > 0:
                size -= 1
                _ls_add(B, n, W, C[size], miss, -1)
                inC[C[size]] = False
            size = _ls_join(B, n, W, _rand(rng, n), miss, inC, where, C, 0)
            last = it
            continue
        na = 0
        ns = 0
        for v in range(n):
            if inC[v] or tabu[v] > it:
                continue
            if miss[v] == 0:
                cand_a[na] = v
                na += 1
            elif miss[v] == 1:
                cand_s[ns] = v
                ns += 1
        if na > 0:
            v = cand_a[_rand(rng, na)]
        elif ns > 0:
            v = cand_s[_rand(rng, ns)]
            # the one clique vertex not adjacent to v leaves
            u = -1
            for i in range(size):
                c = C[i]
                if (B[v, c >> 6] >> np.uint64(c & 63)) & ONE == ZERO:
                    u = c
                    break
            size = _ls_leave(B, n, W, u, miss, inC, where, C, size)
            tabu[u] = it + 7 + _rand(rng, ns + 1)
        else:
            if size == 0:
                break
            u = C[_rand(rng, size)]
            size = _ls_leave(B, n, W, u, miss, inC, where, C, size)
            tabu[u] = it + 7
            continue
        size = _ls_join(B, n, W, v, miss, inC, where, C, size)
        if size > best.shape[0]:
            best = head(C, size)
            last = it
    return best
