"""Greedy colouring bounds of the branch and bound (private).

A colour class is an independent set, so a clique takes at most one vertex per class: the
number of classes of a greedy colouring bounds the clique number of a candidate set (the
heaviest vertex per class bounds its weight). Classes are built in bit order, which the
full search makes the degeneracy order (BBMC, San Segundo et al. 2011).

One greedy colouring, three bounds: :func:`_open_class` and :func:`_take` (inlined) build
the classes; :func:`colour_classes` (the k-min filter of the unweighted search),
:func:`colour_count` (the number of classes) and :func:`colour_weighted` (Kumlander's
weighted bound) differ only in what they record per vertex and per class.
:func:`colour_word` is the same colouring on one word (see its docstring).
"""

# ruff: noqa: E402 (ensure_cache() runs before numba is imported)
from __future__ import annotations

from . import ensure_cache

ensure_cache()  # before any njit(cache=True) below picks its cache location

import numpy as np

from .bitset import ONE, ZERO, cttz
from .jit import njit


@njit(inline="always")
def _open_class(U, Q, W, w0):
    """Start a colour class: the first non-empty word of the uncoloured set ``U`` at or
    after ``w0`` (``W``: everything is coloured), and ``Q[w0:] = U[w0:]``, the vertices
    the class may still take."""
    while w0 < W and U[w0] == ZERO:
        w0 += 1
    for w in range(w0, W):
        Q[w] = U[w]
    return w0


@njit(inline="always")
def _take(U, Q, B, W, wq):
    """Add the lowest vertex ``v`` of ``Q`` (``Q[:wq]`` is empty) to the current class: it
    leaves ``U`` and ``Q``, and its neighbours leave ``Q``. Returns ``v``, ``-1`` when
    ``Q`` is empty (the class is maximal); the next call may start at word ``v >> 6``.

    (No inlined helper is called from here: a nested ``inline="always"`` call, for the
    word scan above, made :func:`colour_classes` 2 to 6 times slower, measured.)"""
    while wq < W and Q[wq] == ZERO:
        wq += 1
    if wq == W:
        return -1
    b = cttz(Q[wq])
    v = wq * 64 + int(b)
    one = ONE << b
    Q[wq] &= ~one
    U[wq] &= ~one
    for w in range(wq, W):
        Q[w] &= ~B[v, w]
    return v


@njit(cache=True)
def colour_classes(P, B, W, kmin, U, Q, CL, ord_v, ord_c, base, col):
    """Greedy sequential colouring of ``P`` in bit order (BBMC, San Segundo et al. 2011).

    Classes are built one at a time, each a maximal independent set taken from the
    uncoloured vertices in increasing index. Classes ``1 .. kmin - 1`` are kept as bitsets
    in ``CL[0 .. kmin - 2]``; vertices of colour ``>= kmin`` go to ``ord_v[base:]`` with
    their colour in ``ord_c[base:]``, in non-decreasing colour (Tomita's k-min filter:
    only they can lead to a clique that beats the incumbent). Returns how many.
    """
    for w in range(W):
        U[w] = P[w]
    w0 = 0
    k = 0
    cnt = 0
    while True:
        # invariant: U = vertices of P not yet coloured, and U[:w0] is empty
        w0 = _open_class(U, Q, W, w0)
        if w0 == W:
            break
        k += 1
        rec = k < kmin
        if rec:
            for w in range(W):
                CL[k - 1, w] = ZERO
        wq = w0
        while True:
            # invariant: Q = uncoloured vertices not adjacent to any vertex of class k
            v = _take(U, Q, B, W, wq)
            if v < 0:
                break
            wq = v >> 6
            if rec:
                CL[k - 1, wq] |= ONE << np.uint64(v & 63)
                col[v] = k - 1
            else:
                col[v] = -1
                ord_v[base + cnt] = v
                ord_c[base + cnt] = k
                cnt += 1
    return cnt


@njit(cache=True)
def colour_count(P, B, W, U, Q):
    """Number of classes of the greedy colouring of ``P``: an upper bound on its clique."""
    for w in range(W):
        U[w] = P[w]
    k = 0
    w0 = 0
    while True:
        w0 = _open_class(U, Q, W, w0)
        if w0 == W:
            return k
        k += 1
        wq = w0
        while True:
            v = _take(U, Q, B, W, wq)
            if v < 0:
                break
            wq = v >> 6


@njit(cache=True)
def colour_word(S, P, kmin, ord_v, ord_c, base):
    """:func:`colour_classes` for a one-word candidate set, without the class bitsets:
    the vertices of colour ``>= kmin`` go to ``ord_*[base:]``. Returns how many.

    The same colouring as :func:`colour_classes`, kept on purpose for the one-word search
    (``_bb_word`` in :mod:`.clique_search`): sets are single words in registers, not rows
    of words in memory. The row form (``bb_search`` on one-word rows) took 4.07 times as
    long on the pipeline's graphs of up to 64 vertices (see ``_bb_word``)."""
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


@njit(cache=True)
def colour_weighted(P, B, W, wt, need, U, Q, ord_v, ord_b, base):
    """Weighted colouring bound (Kumlander 2004): classes built as in BBMC; the bound of
    the ``i``-th vertex is the heaviest vertex of each earlier class plus the heaviest of
    its own class up to ``i``. Only entries with a bound above ``need`` are written."""
    for w in range(W):
        U[w] = P[w]
    w0 = 0
    acc = 0.0
    cnt = 0
    while True:
        w0 = _open_class(U, Q, W, w0)
        if w0 == W:
            break
        wq = w0
        cmax = 0.0
        while True:
            v = _take(U, Q, B, W, wq)
            if v < 0:
                break
            wq = v >> 6
            if wt[v] > cmax:
                cmax = wt[v]
            if acc + cmax > need:
                ord_v[base + cnt] = v
                ord_b[base + cnt] = acc + cmax
                cnt += 1
        acc += cmax
    return cnt
