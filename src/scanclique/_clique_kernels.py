"""Compiled kernels of the maximum clique engine (private; see :mod:`scanclique.clique`).

Graphs arrive here as bitset adjacency rows: ``A[v, w]`` is a ``uint64`` word whose bit ``b``
says whether ``v`` is adjacent to ``64 * w + b``. All kernels are ``numba.njit(cache=True)``:
the first call in a fresh environment compiles them (a few seconds), later runs load the
cache from ``__pycache__``.

numba pitfall kept in mind throughout: mixing ``uint64`` with ``int64`` promotes to
``float64``, so every word operation uses ``uint64`` operands only (``_ONE``, ``_ZERO``).
"""

from __future__ import annotations

import time

import numba
import numpy as np
from llvmlite import ir
from numba import types
from numba.extending import intrinsic

_ONE = np.uint64(1)
_ZERO = np.uint64(0)
_ALL = np.uint64(0xFFFFFFFFFFFFFFFF)


@intrinsic
def _cttz(typingctx, x):
    """Count trailing zeros of a non-zero ``uint64`` (one ``tzcnt`` instruction)."""
    sig = types.uint64(types.uint64)

    def codegen(context, builder, signature, args):
        return builder.cttz(args[0], ir.Constant(ir.IntType(1), 1))

    return sig, codegen


@intrinsic
def _ctpop(typingctx, x):
    """Population count of a ``uint64`` (one ``popcnt`` instruction)."""
    sig = types.uint64(types.uint64)

    def codegen(context, builder, signature, args):
        return builder.ctpop(args[0])

    return sig, codegen


@numba.njit(cache=True)
def _now():
    with numba.objmode(t="float64"):
        t = time.perf_counter()
    return t


@numba.njit(cache=True, inline="always")
def _popcount(P, W):
    s = 0
    for w in range(W):
        s += int(_ctpop(P[w]))
    return s


# --------------------------------------------------------------------------------------
# Initial order, renumbering, initial clique
# --------------------------------------------------------------------------------------
@numba.njit(cache=True)
def degeneracy_order(A, n):
    """Min-degree peeling: ``order`` (densest core first) and the core number of each vertex.

    ``order[n - 1]`` is the first vertex peeled (minimum degree), ``order[0]`` the last.
    O(n^2 + m): an argmin over the remaining vertices per step.
    """
    W = A.shape[1]
    deg = np.empty(n, np.int64)
    for v in range(n):
        deg[v] = _popcount(A[v], W)
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
        if bd > k:
            k = bd
        core[best] = k
        order[n - 1 - i] = best
        removed[best] = True
        for w in range(W):
            x = A[best, w]
            while x:
                b = _cttz(x)
                x &= x - _ONE
                u = w * 64 + int(b)
                if not removed[u]:
                    deg[u] -= 1
    return order, core


@numba.njit(cache=True)
def relabel(A, n, order):
    """Bitset rows of the graph renumbered so that new vertex ``i`` is old ``order[i]``."""
    W = A.shape[1]
    pos = np.empty(n, np.int64)
    for i in range(n):
        pos[order[i]] = i
    B = np.zeros_like(A)
    for i in range(n):
        v = order[i]
        for w in range(W):
            x = A[v, w]
            while x:
                b = _cttz(x)
                x &= x - _ONE
                j = pos[w * 64 + int(b)]
                B[i, j >> 6] |= _ONE << np.uint64(j & 63)
    return B


@numba.njit(cache=True)
def greedy_clique(B, n, starts, P, Q):
    """Best of the greedy cliques grown from each start vertex of ``starts``.

    From ``s``: candidates ``N(s)``, then repeatedly add the lowest-numbered candidate (in
    the degeneracy numbering: the one deepest in the core) and intersect. O(|starts| w W).
    """
    W = B.shape[1]
    best = np.empty(n, np.int64)
    bsize = 0
    cur = np.empty(n, np.int64)
    for s in starts:
        for w in range(W):
            P[w] = B[s, w]
        cur[0] = s
        size = 1
        w0 = 0
        while True:
            while w0 < W and P[w0] == _ZERO:
                w0 += 1
            if w0 == W:
                break
            u = w0 * 64 + int(_cttz(P[w0]))
            cur[size] = u
            size += 1
            for w in range(w0, W):
                P[w] &= B[u, w]
        if size > bsize:
            bsize = size
            for i in range(size):
                best[i] = cur[i]
    return best[:bsize].copy()


# --------------------------------------------------------------------------------------
# Colouring bound
# --------------------------------------------------------------------------------------
@numba.njit(cache=True)
def colour_sort(P, B, W, kmin, U, Q, ord_v, ord_c, base):
    """Greedy sequential colouring of ``P`` in bit order (BBMC, San Segundo et al. 2011).

    Colour classes are built one at a time: each is a maximal independent set taken from
    the uncoloured vertices in increasing index. Only vertices with colour ``>= kmin``
    are written to ``ord_v[base:], ord_c[base:]`` (the k-min filter of Tomita's MCQ): the
    others can never lead to a clique better than the incumbent. Entries are in
    non-decreasing colour. Returns how many were written.
    """
    w0 = W
    for w in range(W):
        U[w] = P[w]
        if P[w] != _ZERO and w < w0:
            w0 = w
    k = 0
    cnt = 0
    while True:
        # invariant: U = vertices of P not yet coloured; U[:w0] is empty
        while w0 < W and U[w0] == _ZERO:
            w0 += 1
        if w0 == W:
            break
        k += 1
        for w in range(w0, W):
            Q[w] = U[w]
        wq = w0
        while True:
            # invariant: Q = uncoloured vertices not adjacent to any vertex of class k
            while wq < W and Q[wq] == _ZERO:
                wq += 1
            if wq == W:
                break
            b = _cttz(Q[wq])
            v = wq * 64 + int(b)
            bit = ~(_ONE << b)
            Q[wq] &= bit
            U[wq] &= bit
            for w in range(wq, W):
                Q[w] &= ~B[v, w]
            if k >= kmin:
                ord_v[base + cnt] = v
                ord_c[base + cnt] = k
                cnt += 1
    return cnt


# --------------------------------------------------------------------------------------
# Branch and bound
# --------------------------------------------------------------------------------------
@numba.njit(cache=True)
def bb_search(B, n, P0, init, floor, mode, limit, time_limit, t0, check_mask):
    """Branch and bound for cliques larger than ``floor`` (mode 0) or of size ``floor + 1``.

    Parameters
    ----------
    B : (n, W) uint64, renumbered adjacency (bit order = branching order).
    P0 : (W,) uint64, root candidate set.
    init : int64 array, an initial clique (the incumbent) in the new numbering.
    floor : int, cliques of size <= floor are of no interest.
    mode : 0 = maximum clique (the bar rises with each improvement), 1 = enumerate every
        clique of size ``floor + 1`` (the bar stays), at most ``limit`` of them.

    Returns ``(best, nodes, timed_out, found, nfound, overflow)``.
    """
    W = B.shape[1]
    bar = floor
    if mode == 0 and init.shape[0] > bar:
        bar = init.shape[0]
    best = init.copy()
    target = floor + 1
    found = np.empty((max(limit, 0) if mode == 1 else 0, target), np.int64)
    nfound = 0
    overflow = False

    maxd = n + 2
    Pst = np.empty((maxd, W), np.uint64)
    pos = np.empty(maxd, np.int64)
    base = np.empty(maxd, np.int64)
    cnt = np.empty(maxd, np.int64)
    C = np.empty(maxd, np.int64)
    U = np.empty(W, np.uint64)
    Q = np.empty(W, np.uint64)
    cap = 4 * n + 64
    ord_v = np.empty(cap, np.int64)
    ord_c = np.empty(cap, np.int64)

    nodes = 1
    timed_out = False
    for w in range(W):
        Pst[0, w] = P0[w]
    base[0] = 0
    need = _popcount(P0, W)
    if need > cap:
        cap = 2 * need
        ord_v = np.empty(cap, np.int64)
        ord_c = np.empty(cap, np.int64)
    cnt[0] = colour_sort(Pst[0], B, W, bar + 1, U, Q, ord_v, ord_c, 0)
    pos[0] = cnt[0] - 1
    depth = 0
    while depth >= 0:
        # invariant: C[:depth] is a clique, Pst[depth] its common neighbours not yet
        # branched on; ord_*[base+0 .. base+pos] are the branching candidates left
        p = pos[depth]
        if p < 0:
            depth -= 1
            continue
        b0 = base[depth]
        v = ord_v[b0 + p]
        if depth + ord_c[b0 + p] <= bar:
            pos[depth] = -1
            continue
        pos[depth] = p - 1
        nonempty = False
        for w in range(W):
            x = Pst[depth, w] & B[v, w]
            Pst[depth + 1, w] = x
            if x != _ZERO:
                nonempty = True
        Pst[depth, v >> 6] &= ~(_ONE << np.uint64(v & 63))
        C[depth] = v
        if not nonempty:
            size = depth + 1
            if mode == 0:
                if size > bar:
                    bar = size
                    best = C[:size].copy()
            elif size == target:
                if nfound < limit:
                    for i in range(size):
                        found[nfound, i] = C[i]
                    nfound += 1
                else:
                    overflow = True
                    break
            continue
        nodes += 1
        if (nodes & check_mask) == 0:
            if _now() - t0 > time_limit:
                timed_out = True
                break
        nb = b0 + cnt[depth]
        need = nb + _popcount(Pst[depth + 1], W)
        if need > cap:
            cap = 2 * need
            nv = np.empty(cap, np.int64)
            nc = np.empty(cap, np.int64)
            nv[:nb] = ord_v[:nb]
            nc[:nb] = ord_c[:nb]
            ord_v = nv
            ord_c = nc
        c = colour_sort(Pst[depth + 1], B, W, bar - depth, U, Q, ord_v, ord_c, nb)
        if c == 0:
            continue
        depth += 1
        base[depth] = nb
        cnt[depth] = c
        pos[depth] = c - 1
    return best, nodes, timed_out, found[:nfound].copy(), nfound, overflow


@numba.njit(cache=True)
def solve(A, n, floor, mode, limit, time_limit, t0):
    """Whole pipeline on original bitsets: order, renumber, initial clique, prune, search.

    Returns ``(clique, nodes, timed_out, found, nfound, overflow)`` in original labels.
    """
    W = A.shape[1]
    order, core = degeneracy_order(A, n)
    B = relabel(A, n, order)
    P = np.empty(W, np.uint64)
    Q = np.empty(W, np.uint64)
    if mode == 0:
        starts = np.arange(n)
        init = greedy_clique(B, n, starts, P, Q)
    else:
        init = np.empty(0, np.int64)
    bar = floor
    if init.shape[0] > bar:
        bar = init.shape[0]
    # k-core pruning: a clique of size bar + 1 lies inside the bar-core
    P0 = np.zeros(W, np.uint64)
    for i in range(n):
        if core[order[i]] >= bar:
            P0[i >> 6] |= _ONE << np.uint64(i & 63)
    # check the clock about every 5 ms of colouring work: a node costs ~|P| W word ops
    work = n * W + 1
    mask = 1
    while mask < 4096 and mask * work < 2_000_000:
        mask = mask * 2 + 1
    best, nodes, timed_out, found, nfound, overflow = bb_search(
        B, n, P0, init, floor, mode, limit, time_limit, t0, mask
    )
    best_o = np.empty(best.shape[0], np.int64)
    for i in range(best.shape[0]):
        best_o[i] = order[best[i]]
    found_o = np.empty_like(found)
    for r in range(found.shape[0]):
        for i in range(found.shape[1]):
            found_o[r, i] = order[found[r, i]]
    return best_o, nodes, timed_out, found_o, nfound, overflow
