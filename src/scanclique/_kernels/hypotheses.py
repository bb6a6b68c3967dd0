"""The clique hypotheses of a match (paper §5.3 and this library's additions): all maximum
cliques, peeled and vertex-guided cliques, under a node budget.

Part of the matcher's kernels (private; gathered in :mod:`scanclique._match_kernels`)."""

# ruff: noqa: E402 (ensure_cache() runs before numba caches anything)
from __future__ import annotations

from . import ensure_cache

ensure_cache()

import numpy as np

from .bitset import ctpop, now, setbit
from .clique_search import maximum_until, search_until
from .codes import FINISHED as _FINISHED
from .codes import NODE_LIMIT as _NODE_LIMIT
from .codes import TIME_LIMIT as _TIME_LIMIT
from .jit import njit
from .ordering import induced_rows

_njit = njit(cache=True, nogil=True)
#: for the helpers called once per point: inlined into the caller at numba IR level, so
#: that the arrays they take are not reference-counted on every call
_inline = njit(cache=True, nogil=True, inline="always")


@_inline
def _out_of_budget(used, node_limit, deadline):  # pragma: no cover - compiled
    """Before another search of the hypothesis phases: ``Status.NODE_LIMIT`` when the
    node budget is spent, ``Status.TIME_LIMIT`` when the clock has passed ``deadline``,
    else ``Status.FINISHED`` (go on). (The searches themselves check through
    ``bitset.spent``, which reads the clock only every few thousand nodes.)"""
    if used >= node_limit:
        return _NODE_LIMIT
    if now() >= deadline:
        return _TIME_LIMIT
    return _FINISHED


@_njit
def _append(store, count, clique):  # pragma: no cover - compiled
    """Append ``clique`` to the flat store ``(data, indptr)``; returns the new store."""
    data, indptr = store
    start = indptr[count]
    need = start + clique.shape[0]
    if need > data.shape[0]:
        nd = np.empty(max(2 * data.shape[0], need), np.int64)
        nd[:start] = data[:start]
        data = nd
    if count + 2 > indptr.shape[0]:
        ni = np.zeros(2 * indptr.shape[0] + 2, np.int64)
        ni[: count + 1] = indptr[: count + 1]
        indptr = ni
    data[start:need] = clique
    indptr[count + 1] = need
    return (data, indptr)


@_njit
def _maximum_of(A, verts, deadline, node_limit):  # pragma: no cover - compiled
    """A maximum clique of the subgraph of ``A`` induced by ``verts`` (at least one), as
    positions in ``verts``, sorted: the lean path of ``clique.max_clique``
    (:func:`scanclique._kernels.clique_search.maximum_until`), and the search nodes it
    used and its status. The best found when ``node_limit`` nodes are spent or the clock
    passes ``deadline`` (the outer guard)."""
    m = verts.shape[0]
    alive = np.zeros(A.shape[1], np.uint64)
    for v in verts:
        setbit(alive, v)
    out = np.empty(m, np.int64)
    size, nodes, status = maximum_until(
        induced_rows(A, verts, m, alive), m, 0, deadline, node_limit, out
    )
    return out[:size], nodes, status


@_njit
def hypothesis_cliques(
    A, n, limit, peel, per_vertex, min_size, node_limit, deadline, opts
):  # pragma: no cover - compiled
    """The cliques that become association hypotheses, in one compiled call.

    1. every maximum clique of ``A`` (bitset rows, ``n`` vertices), at most ``limit``;
    2. ``peel`` times: the maximum clique of the vertices no clique so far uses (stops
       below ``min_size`` vertices);
    3. for the ``per_vertex`` vertices of highest degree (ties to the lower label): the
       maximum clique containing the vertex, when at least ``min_size`` large. A vertex
       of a maximum clique is skipped when step 1 listed every maximum clique (its
       clique would be one of them).

    The budget that decides the result is ``node_limit`` search nodes for all steps
    together (the same graph gives the same cliques on every machine); ``deadline``
    (``time.perf_counter`` clock, ``inf`` for none) is an outer guard only. Returns
    ``(data, indptr, count, omega, optimal, complete, stop, nodes)``: clique ``i`` is
    ``data[indptr[i]:indptr[i + 1]]`` (sorted labels), each distinct clique of at least
    ``min_size`` vertices once, in the order found; ``optimal`` when omega was proven,
    ``complete`` when step 1 listed every maximum clique; ``stop`` the status that cut
    the search short (``NODE_LIMIT`` or ``TIME_LIMIT``), ``FINISHED`` when nothing did;
    ``nodes`` the search nodes used.
    """
    store = (np.empty(64, np.int64), np.zeros(16, np.int64))
    count = 0
    best, used, status, found, status_all = search_until(
        A, n, 0, 2, limit, deadline, node_limit, opts
    )
    optimal = status == 0
    complete = optimal and status_all == 0
    stop = _FINISHED
    if status == _NODE_LIMIT or status_all == _NODE_LIMIT:
        stop = _NODE_LIMIT
    elif status == _TIME_LIMIT or status_all == _TIME_LIMIT:
        stop = _TIME_LIMIT
    omega = best.shape[0]
    in_max = np.zeros(n, np.bool_)
    for r in range(found.shape[0]):
        for v in found[r]:
            in_max[v] = True
    if limit > 0:
        if found.shape[0] > 0:
            for r in range(found.shape[0]):
                store = _append(store, count, found[r])
                count += 1
        else:
            store = _append(store, count, best)
            count += 1
    # 2. peeling
    alive = np.ones(n, np.bool_)
    for _ in range(peel):
        data, indptr = store
        for j in range(indptr[count]):
            alive[data[j]] = False
        left = np.flatnonzero(alive)
        if left.shape[0] < min_size:
            break
        out = _out_of_budget(used, node_limit, deadline)
        if out != _FINISHED:
            stop = out
            break
        r, k, st = _maximum_of(A, left, deadline, node_limit - used)
        used += k
        if st != _FINISHED and stop == _FINISHED:
            stop = st
        if r.shape[0] < min_size:
            break
        store = _append(store, count, np.sort(left[r]))
        count += 1
    # 3. vertex-guided cliques
    if per_vertex > 0:
        deg = np.zeros(n, np.int64)
        for v in range(n):
            for w in range(A.shape[1]):
                deg[v] += np.int64(ctpop(A[v, w]))
        order = np.argsort(-deg, kind="mergesort")
        one = np.uint64(1)
        for q in range(min(per_vertex, n)):
            v = order[q]
            if deg[v] + 1 < min_size:
                break
            out = _out_of_budget(used, node_limit, deadline)
            if out != _FINISHED:
                stop = out
                break
            if complete and in_max[v]:
                continue
            nb = np.empty(deg[v], np.int64)
            m = 0
            for u in range(n):
                if (A[v, u >> 6] >> np.uint64(u & 63)) & one:
                    nb[m] = u
                    m += 1
            r = np.empty(0, np.int64)
            if m > 0:
                r, k, st = _maximum_of(A, nb, deadline, node_limit - used)
                used += k
                if st != _FINISHED and stop == _FINISHED:
                    stop = st
            if r.shape[0] + 1 >= min_size:
                c = np.empty(r.shape[0] + 1, np.int64)
                c[: r.shape[0]] = nb[r]
                c[r.shape[0]] = v
                store = _append(store, count, np.sort(c))
                count += 1
    data, indptr = store
    data, indptr, count = _distinct_cliques(data, indptr, count, min_size)
    return data, indptr, count, omega, optimal, complete, stop, used


@_njit
def _distinct_cliques(data, indptr, count, min_size):  # pragma: no cover - compiled
    """The cliques of the flat store with at least ``min_size`` vertices, each once (the
    first occurrence; the vertex lists are sorted), order kept: ``(data, indptr, count)``."""
    keep = np.zeros(count, np.bool_)
    for i in range(count):
        a0, a1 = indptr[i], indptr[i + 1]
        if a1 - a0 < min_size:
            continue
        dup = False
        for j in range(i):
            if not keep[j]:
                continue
            b0, b1 = indptr[j], indptr[j + 1]
            if b1 - b0 != a1 - a0:
                continue
            same = True
            for q in range(a1 - a0):
                if data[a0 + q] != data[b0 + q]:
                    same = False
                    break
            if same:
                dup = True
                break
        keep[i] = not dup
    out = np.empty(indptr[count], np.int64)
    optr = np.zeros(count + 1, np.int64)
    k = 0
    for i in range(count):
        if keep[i]:
            n = indptr[i + 1] - indptr[i]
            out[optr[k] : optr[k] + n] = data[indptr[i] : indptr[i + 1]]
            optr[k + 1] = optr[k] + n
            k += 1
    return out[: optr[k]], optr[: k + 1].copy(), k
