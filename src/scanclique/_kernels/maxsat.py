"""MaxSAT-style filtering of branching vertices (private): Re-NUMBER (Tomita et al.
2010) and failed-literal detection by unit propagation over colour classes (MaxCLQ, Li &
Quan 2010). Used by the full search on dense graphs, where colouring is loose.
"""

# ruff: noqa: E402 (ensure_cache() runs before numba is imported)
from __future__ import annotations

from . import ensure_cache

ensure_cache()  # before any njit(cache=True) below picks its cache location

import numpy as np

from .bitset import ONE, ZERO, clearbit, ctpop, cttz, setbit
from .jit import njit


@njit(cache=True)
def try_vertex(v, B, W, need, CL, P, S):
    """Can ``v`` join the ``need`` classes without raising their clique bound?

    Returns 1 when ``v`` was put into a class: directly (no neighbour there) or by
    Tomita's Re-NUMBER (its single neighbour ``u`` in class ``k`` moves to a class with no
    neighbour of ``u``; MCS, 2010). Returns 2 when unit propagation from ``v`` fails
    (MaxCLQ, Li & Quan 2010): classes are clauses "the clique takes one of these", ``v``
    is set true, every class keeps only the vertices adjacent to all true ones, a class
    left with one vertex makes it true, and a class left empty is a conflict. The classes
    that took part (traced back through the reasons ``RS``) are written to ``SX``:
    together with ``v`` they hold no clique with one vertex per class. Returns 0 otherwise.
    """
    RS, SX, SU, T, D, col, left, active, queued, fired, queue, uvert = S
    WC = (need + 63) >> 6
    nunits = 0
    for k in range(need):
        if not active[k]:
            continue
        c = 0
        for w in range(W):
            c += int(ctpop(CL[k, w] & B[v, w]))
        if c == 0:
            setbit(CL[k], v)
            col[v] = k
            return 1
        left[k] = c
        fired[k] = False
        queued[k] = c == 1
        for w in range(WC):
            RS[k, w] = ZERO
        if c == 1:
            queue[nunits] = k
            for w in range(W):
                x = CL[k, w] & B[v, w]
                if x != ZERO:
                    uvert[nunits] = w * 64 + int(cttz(x))
                    break
            nunits += 1
    # Re-NUMBER: keeps every class, so it is tried before anything is consumed. The class
    # that takes u must not be in SU, the conflicts of this candidate colour not yet
    # retired: their proofs assumed the classes as they were, and u (unlike v, which is
    # not adjacent to the candidates of its colour) could complete a clique there
    for qi in range(nunits):
        k = queue[qi]
        u = uvert[qi]
        for l in range(need):
            if l == k or not active[l] or (SU[l >> 6] >> np.uint64(l & 63)) & ONE:
                continue
            ok = True
            for w in range(W):
                if CL[l, w] & B[u, w]:
                    ok = False
                    break
            if ok:
                clearbit(CL[k], u)
                setbit(CL[k], v)
                setbit(CL[l], u)
                col[v] = k
                col[u] = l
                return 1
    for w in range(W):
        T[w] = B[v, w] & P[w]
    qh = 0
    conflict = -1
    while qh < nunits and conflict < 0:
        # invariant: T = P ∩ N(v) ∩ N(every fired unit); left[l] = |CL[l] ∩ T| for the
        # live classes; RS[l] = the fired classes whose units shrank class l (closed
        # under their own reasons)
        k = queue[qh]
        u = uvert[qh]
        if u < 0:
            for w in range(W):
                x = CL[k, w] & T[w]
                if x != ZERO:
                    u = w * 64 + int(cttz(x))
                    break
        qh += 1
        fired[k] = True
        setbit(RS[k], k)
        for w in range(W):
            t = T[w]
            D[w] = t & ~B[u, w]
            T[w] = t & B[u, w]
        for w in range(W):
            x = D[w]
            while x:
                b = cttz(x)
                x &= x - ONE
                l = col[w * 64 + int(b)]
                if l < 0 or not active[l] or fired[l]:
                    continue
                left[l] -= 1
                for w2 in range(WC):
                    RS[l, w2] |= RS[k, w2]
                if left[l] == 0:
                    conflict = l
                    break
                if left[l] == 1 and not queued[l]:
                    queued[l] = True
                    queue[nunits] = l
                    uvert[nunits] = -1
                    nunits += 1
            if conflict >= 0:
                break
    if conflict < 0:
        return 0
    for w in range(WC):
        SX[w] = RS[conflict, w]
    setbit(SX, conflict)
    return 2


@njit(cache=True)
def absorb(B, W, need, CL, P, ord_v, ord_c, base, cnt, S):
    """Drop from the branching list the vertices the MaxSAT-style reasoning absorbs.

    ``CL[:need]`` are the first ``need`` colour classes of the candidate set ``P``,
    ``ord_*[base:base + cnt]`` the branching candidates (colour > need) in non-decreasing
    colour. Candidates are taken a colour class at a time; each is tried by
    :func:`try_vertex`. The classes consumed by the failed-literal conflicts of one
    candidate class are retired together (a clause and the conflicts of each of its
    literals form one inconsistent subset, so they may overlap), and later candidates
    work with the classes left. Invariant: the retired subsets and the active classes,
    with the absorbed vertices, hold no clique larger than ``need``; so branching on the
    survivors alone is exact. Returns how many survive.
    """
    RS, SX, SU, T, D, col, left, active, queued, fired, queue, uvert = S
    WC = (need + 63) >> 6
    for k in range(need):
        active[k] = True
    out = 0
    i = 0
    while i < cnt:
        c = ord_c[base + i]
        j = i
        while j < cnt and ord_c[base + j] == c:
            j += 1
        for w in range(WC):
            SU[w] = ZERO
        for t in range(i, j):
            v = ord_v[base + t]
            r = try_vertex(v, B, W, need, CL, P, S)
            if r == 0:
                ord_v[base + out] = v
                ord_c[base + out] = c
                out += 1
            elif r == 2:
                for w in range(WC):
                    SU[w] |= SX[w]
        for w in range(WC):
            x = SU[w]
            while x:
                b = cttz(x)
                x &= x - ONE
                active[w * 64 + int(b)] = False
        i = j
    return out


@njit(cache=True)
def maxsat_scratch(n, W):
    """Scratch of :func:`absorb` and :func:`try_vertex` for ``n`` vertices and classes,
    sets of ``W`` words, in four allocations (row views of three blocks): the search
    allocates it once per call, which matters on the pipeline's small graphs."""
    V = np.empty((4, W), np.uint64)
    I = np.empty((4, n + 1), np.int64)
    F = np.empty((3, n + 1), np.bool_)
    col = I[0]
    for i in range(n + 1):
        col[i] = -1
    return (
        np.empty((n + 1, W), np.uint64),  # RS: reasons, a bitset of classes per class
        V[0],  # SX: the classes of one conflict
        V[1],  # SU: the classes consumed by one candidate class
        V[2],  # T: vertices still compatible with the true ones
        V[3],  # D: vertices a new unit removes from T
        col,  # col: class index of each vertex, -1 if none
        I[1],  # left: |class ∩ T|
        F[0],  # active
        F[1],  # queued
        F[2],  # fired
        I[2],  # queue of unit classes
        I[3],  # their vertices (-1: not known yet)
    )
