"""Greedy colouring bounds of the branch and bound (private).

A colour class is an independent set, so a clique takes at most one vertex per class: the
number of classes of a greedy colouring bounds the clique number of a candidate set (the
heaviest vertex per class bounds its weight). Classes are built in bit order, which the
full search makes the degeneracy order (BBMC, San Segundo et al. 2011).
"""

# ruff: noqa: E402 (ensure_cache() runs before numba is imported)
from __future__ import annotations

from . import ensure_cache

ensure_cache()  # before any njit(cache=True) below picks its cache location

import numba

from .bitset import ONE, ZERO, cttz


@numba.njit(cache=True)
def colour_classes(P, B, W, kmin, U, Q, CL, ord_v, ord_c, base, col):
    """Greedy sequential colouring of ``P`` in bit order (BBMC, San Segundo et al. 2011).

    Classes are built one at a time, each a maximal independent set taken from the
    uncoloured vertices in increasing index. Classes ``1 .. kmin - 1`` are kept as bitsets
    in ``CL[0 .. kmin - 2]``; vertices of colour ``>= kmin`` go to ``ord_v[base:]`` with
    their colour in ``ord_c[base:]``, in non-decreasing colour (Tomita's k-min filter:
    only they can lead to a clique that beats the incumbent). Returns how many.
    """
    w0 = W
    for w in range(W):
        U[w] = P[w]
        if P[w] != ZERO and w < w0:
            w0 = w
    k = 0
    cnt = 0
    while True:
        # invariant: U = vertices of P not yet coloured, and U[:w0] is empty
        while w0 < W and U[w0] == ZERO:
            w0 += 1
        if w0 == W:
            break
        k += 1
        rec = k < kmin
        if rec:
            for w in range(W):
                CL[k - 1, w] = ZERO
        for w in range(w0, W):
            Q[w] = U[w]
        wq = w0
        while True:
            # invariant: Q = uncoloured vertices not adjacent to any vertex of class k
            while wq < W and Q[wq] == ZERO:
                wq += 1
            if wq == W:
                break
            b = cttz(Q[wq])
            v = wq * 64 + int(b)
            one = ONE << b
            Q[wq] &= ~one
            U[wq] &= ~one
            for w in range(wq, W):
                Q[w] &= ~B[v, w]
            if rec:
                CL[k - 1, wq] |= one
                col[v] = k - 1
            else:
                col[v] = -1
                ord_v[base + cnt] = v
                ord_c[base + cnt] = k
                cnt += 1
    return cnt


@numba.njit(cache=True)
def colour_count(P, B, W, U, Q):
    """Number of classes of the greedy colouring of ``P``: an upper bound on its clique."""
    for w in range(W):
        U[w] = P[w]
    k = 0
    w0 = 0
    while True:
        while w0 < W and U[w0] == ZERO:
            w0 += 1
        if w0 == W:
            return k
        k += 1
        for w in range(w0, W):
            Q[w] = U[w]
        wq = w0
        while True:
            while wq < W and Q[wq] == ZERO:
                wq += 1
            if wq == W:
                break
            b = cttz(Q[wq])
            v = wq * 64 + int(b)
            one = ONE << b
            Q[wq] &= ~one
            U[wq] &= ~one
            for w in range(wq, W):
                Q[w] &= ~B[v, w]


@numba.njit(cache=True)
def colour_word(S, P, kmin, ord_v, ord_c, base):
    """:func:`colour_classes` for a one-word candidate set, without the class bitsets:
    the vertices of colour ``>= kmin`` go to ``ord_*[base:]``. Returns how many."""
    U = P
    k = 0
    cnt = 0
    while U != ZERO:
        # invariant: U = vertices of P not yet coloured
        k += 1
        Q = U
        while Q != ZERO:
            # invariant: Q = uncoloured vertices not adjacent to any vertex of class k
            b = cttz(Q)
            one = ONE << b
            U &= ~one
            Q &= ~(one | S[b])
            if k >= kmin:
                ord_v[base + cnt] = int(b)
                ord_c[base + cnt] = k
                cnt += 1
    return cnt


@numba.njit(cache=True)
def colour_weighted(P, B, W, wt, need, U, Q, ord_v, ord_b, base):
    """Weighted colouring bound (Kumlander 2004): classes built as in BBMC; the bound of
    the ``i``-th vertex is the heaviest vertex of each earlier class plus the heaviest of
    its own class up to ``i``. Only entries with a bound above ``need`` are written."""
    w0 = W
    for w in range(W):
        U[w] = P[w]
        if P[w] != ZERO and w < w0:
            w0 = w
    acc = 0.0
    cnt = 0
    while True:
        while w0 < W and U[w0] == ZERO:
            w0 += 1
        if w0 == W:
            break
        for w in range(w0, W):
            Q[w] = U[w]
        wq = w0
        cmax = 0.0
        while True:
            while wq < W and Q[wq] == ZERO:
                wq += 1
            if wq == W:
                break
            b = cttz(Q[wq])
            v = wq * 64 + int(b)
            one = ONE << b
            Q[wq] &= ~one
            U[wq] &= ~one
            for w in range(wq, W):
                Q[w] &= ~B[v, w]
            if wt[v] > cmax:
                cmax = wt[v]
            if acc + cmax > need:
                ord_v[base + cnt] = v
                ord_b[base + cnt] = acc + cmax
                cnt += 1
        acc += cmax
    return cnt
