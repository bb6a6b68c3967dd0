"""Maximum-weight clique by branch and bound with the weighted colouring bound
(Kumlander 2004) (private; see :func:`scanclique.clique.max_clique`).
"""

# ruff: noqa: E402 (ensure_cache() runs before numba is imported)
from __future__ import annotations

from . import ensure_cache

ensure_cache()  # before any njit(cache=True) below picks its cache location

import numpy as np

from .bitset import (
    check_mask,
    child_set,
    fill,
    grow_pair,
    head,
    mapped_sorted,
    now,
    spent,
)
from .codes import FINISHED as _FINISHED
from .codes import NODE_LIMIT as _NODE_LIMIT
from .colouring import colour_weighted
from .heuristics import greedy_from
from .jit import njit
from .ordering import degeneracy_order, relabel


@njit(cache=True)
def solve_weighted(A, n, weights, time_limit, node_limit):
    """Maximum-weight clique by branch and bound with the weighted colouring bound.

    ``time_limit``: seconds from the call (the wall-clock guard), ``node_limit``: search
    nodes. Returns ``(clique, weight, nodes, status)`` in the caller's labels; status
    :class:`~scanclique._kernels.codes.Status` ``FINISHED``, ``TIME_LIMIT`` or
    ``NODE_LIMIT``.
    """
    deadline = now() + time_limit
    W = A.shape[1]
    order, core = degeneracy_order(A, n)
    B = relabel(A, n, order)
    wt = np.empty(n)
    for i in range(n):
        wt[i] = weights[order[i]]
    # initial clique: from each of the first 128 vertices (densest core), add the
    # heaviest candidate until none is left
    U = np.empty(W, np.uint64)
    Q = np.empty(W, np.uint64)
    best = np.empty(0, np.int64)
    best_w = -1.0
    cur = np.empty(n, np.int64)
    for s in range(min(n, 128)):
        if (s & 15) == 15 and now() > deadline:
            break
        size = greedy_from(B, s, wt, cur, U, 0)
        tot = 0.0
        for i in range(size):
            tot += wt[cur[i]]
        if tot > best_w:
            best_w = tot
            best = head(cur, size)

    maxd = n + 2
    Pst = np.empty((maxd, W), np.uint64)
    pos = np.empty(maxd, np.int64)
    base = np.empty(maxd, np.int64)
    cnt = np.empty(maxd, np.int64)
    C = np.empty(maxd, np.int64)
    Cw = np.zeros(maxd)
    cap = 4 * n + 64
    ord_v = np.empty(cap, np.int64)
    ord_b = np.empty(cap)
    mask = check_mask(n, W)
    nodes = 1
    status = _FINISHED
    fill(Pst[0], n)
    base[0] = 0
    c = colour_weighted(Pst[0], B, W, wt, best_w, U, Q, ord_v, ord_b, 0)
    cnt[0] = c
    pos[0] = c - 1
    depth = 0
    while depth >= 0:
        # invariant: C[:depth] is a clique of weight Cw[depth]; the branching candidates
        # left are ord_*[base + 0 .. base + pos], each with a bound on the weight it can add
        p = pos[depth]
        if p < 0:
            depth -= 1
            continue
        b0 = base[depth]
        v = ord_v[b0 + p]
        if Cw[depth] + ord_b[b0 + p] <= best_w:
            pos[depth] = -1
            continue
        pos[depth] = p - 1
        size = child_set(Pst, depth, B, v, W)
        C[depth] = v
        Cw[depth + 1] = Cw[depth] + wt[v]
        if size == 0:
            if Cw[depth + 1] > best_w:
                best_w = Cw[depth + 1]
                best = head(C, depth + 1)
            continue
        nodes += 1
        status = spent(nodes, node_limit, mask, deadline, _NODE_LIMIT)
        if status != _FINISHED:
            break
        nb = b0 + cnt[depth]
        if nb + size > cap:
            cap = 2 * (nb + size)
            ord_v, ord_b = grow_pair(ord_v, ord_b, nb, cap)
        c = colour_weighted(
            Pst[depth + 1], B, W, wt, best_w - Cw[depth + 1], U, Q, ord_v, ord_b, nb
        )
        if c == 0:
            continue
        depth += 1
        base[depth] = nb
        cnt[depth] = c
        pos[depth] = c - 1
    return mapped_sorted(best, best.shape[0], order), best_w, nodes, status
