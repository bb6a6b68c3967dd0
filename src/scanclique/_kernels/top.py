"""The k largest maximal cliques: Bron–Kerbosch with Tomita's pivot, pruned by the
colouring bound (private; see :func:`scanclique.clique.top_cliques`).
"""

# ruff: noqa: E402 (ensure_cache() runs before numba is imported)
from __future__ import annotations

from . import ensure_cache

ensure_cache()  # before any njit(cache=True) below picks its cache location

import numpy as np

from .bitset import (
    ONE,
    check_mask,
    clearbit,
    ctpop,
    cttz,
    fill,
    grow,
    head,
    mapped_sorted,
    now,
    popcount,
    setbit,
    spent,
)
from .codes import FINISHED as _FINISHED
from .codes import NODE_LIMIT as _NODE_LIMIT
from .colouring import colour_count
from .jit import njit
from .ordering import degeneracy_order, relabel


@njit(cache=True)
def solve_top(A, n, k, time_limit, node_limit):
    """Bron–Kerbosch with Tomita's pivot, pruned by the colouring bound once ``k``
    maximal cliques are held: a branch whose clique plus colour count cannot exceed the
    smallest one kept is cut. ``time_limit``: seconds from the call (the wall-clock
    guard), ``node_limit``: search nodes. Returns ``(tops, sizes, count, status)``;
    status ``FINISHED``, ``TIME_LIMIT`` or ``NODE_LIMIT`` (:class:`~.codes.Status`)."""
    deadline = now() + time_limit
    W = A.shape[1]
    order, core = degeneracy_order(A, n)
    B = relabel(A, n, order)
    tops = np.zeros((k, n), np.int64)
    tsize = np.zeros(k, np.int64)
    count = 0
    maxd = n + 2
    Pst = np.zeros((maxd, W), np.uint64)
    Xst = np.zeros((maxd, W), np.uint64)
    pos = np.empty(maxd, np.int64)
    base = np.empty(maxd, np.int64)
    cnt = np.empty(maxd, np.int64)
    R = np.empty(maxd, np.int64)
    U = np.empty(W, np.uint64)
    Q = np.empty(W, np.uint64)
    cap = 4 * n + 64
    lst = np.empty(cap, np.int64)
    mask = check_mask(n, W)
    nodes = 0
    status = _FINISHED
    fill(Pst[0], n)
    depth = 0
    base[0] = 0
    fresh = True  # the node at `depth` has not been expanded yet
    while depth >= 0:
        if fresh:
            fresh = False
            nodes += 1
            status = spent(nodes, node_limit, mask, deadline, _NODE_LIMIT)
            if status != _FINISHED:
                break
            np_ = popcount(Pst[depth], W)
            nx_ = popcount(Xst[depth], W)
            if np_ == 0:
                if nx_ == 0:  # R[:depth] is a maximal clique
                    j = count
                    if count == k:  # replace the smallest kept, if this one is larger
                        j = 0
                        for r in range(1, k):
                            if tsize[r] < tsize[j]:
                                j = r
                        if depth <= tsize[j]:
                            j = -1
                    else:
                        count += 1
                    if j >= 0:
                        for i in range(depth):
                            tops[j, i] = R[i]
                        tsize[j] = depth
                depth -= 1
                continue
            if count == k:
                smallest = n
                for r in range(k):
                    smallest = min(smallest, tsize[r])
                if depth + colour_count(Pst[depth], B, W, U, Q) <= smallest:
                    depth -= 1
                    continue
            # pivot u in P ∪ X maximising |P ∩ N(u)|; branch on P minus N(u)
            bu = -1
            bc = -1
            for src in range(2):
                for w in range(W):
                    x = Pst[depth, w] if src == 0 else Xst[depth, w]
                    while x:
                        b = cttz(x)
                        x &= x - ONE
                        u = w * 64 + int(b)
                        c = 0
                        for w2 in range(W):
                            c += int(ctpop(Pst[depth, w2] & B[u, w2]))
                        if c > bc:
                            bc = c
                            bu = u
            nb = base[depth]
            if nb + np_ > cap:
                cap = 2 * (nb + np_)
                lst = grow(lst, nb, cap)
            c = 0
            for w in range(W):
                x = Pst[depth, w] & ~B[bu, w]
                while x:
                    b = cttz(x)
                    x &= x - ONE
                    lst[nb + c] = w * 64 + int(b)
                    c += 1
            cnt[depth] = c
            pos[depth] = 0
        # invariant: the vertices lst[base + pos[depth] ..] of this node are still to branch
        if pos[depth] >= cnt[depth]:
            depth -= 1
            continue
        v = lst[base[depth] + pos[depth]]
        pos[depth] += 1
        for w in range(W):
            Pst[depth + 1, w] = Pst[depth, w] & B[v, w]
            Xst[depth + 1, w] = Xst[depth, w] & B[v, w]
        clearbit(Pst[depth], v)
        setbit(Xst[depth], v)
        R[depth] = v
        base[depth + 1] = base[depth] + cnt[depth]
        depth += 1
        fresh = True
    out = np.zeros((count, n), np.int64)
    for r in range(count):
        row = mapped_sorted(tops[r], tsize[r], order)
        for i in range(tsize[r]):
            out[r, i] = row[i]
    return out, head(tsize, count), count, status
