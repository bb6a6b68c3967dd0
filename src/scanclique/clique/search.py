"""The exact searches of the clique engine: maximum clique, every maximum clique, the k
largest maximal cliques (see :mod:`scanclique.clique`).

Budgets. ``node_limit`` (search nodes) is the budget that decides results: the same graph
and limit give the same answer on every machine. ``time_limit`` (seconds) is an outer
guard only; when it bites, the result says so (``optimal=False``, ``reason="time_limit"``).
Its clock starts inside the compiled kernels, after numba has loaded or compiled them.
"""

from __future__ import annotations

import math
import numbers
import time

import numpy as np

from ..errors import GraphError
from ._load import kernels as _kernels
from .graphs import _bits_of, _defect, _square
from .results import AllCliquesResult, CliqueResult, _frozen_vertices, _result, _sealed

__all__ = ["max_clique", "all_maximum_cliques", "top_cliques"]

# the dense path of max_clique, kept lean (see _max_clique_dense)
_clock = time.perf_counter
_BOOL = np.dtype(np.bool_)  # the dtype of every bool array (others take the general path)
_INT64 = np.dtype(np.int64)  # np.empty(n, dtype) is quicker with a dtype than a type
_NO_LIMIT = 1 << 62  # as scanclique._kernels.codes.NO_LIMIT (not imported: no numba here)
#: kernel statuses (scanclique._kernels.codes.Status) -> the results' reason
_REASON = {0: None, 1: "time_limit", 3: "clique_limit", 4: "node_limit"}
_solve_dense = None


def _time_limit(time_limit) -> float:
    """Seconds (``inf`` for None), after checking the argument."""
    if time_limit is None:
        return math.inf
    if isinstance(time_limit, bool) or not isinstance(time_limit, numbers.Real):
        raise GraphError(
            f"time_limit must be a number of seconds or None, got "
            f"{type(time_limit).__name__} {time_limit!r}"
        )
    t = float(time_limit)
    if not t >= 0:
        raise GraphError(f"time_limit must be a non-negative number of seconds, got {time_limit}")
    return t


def _node_limit(node_limit) -> int:
    """Search nodes (no limit for None), after checking the argument."""
    if node_limit is None:
        return _NO_LIMIT
    if isinstance(node_limit, bool) or not isinstance(node_limit, numbers.Integral):
        raise GraphError(
            f"node_limit must be an int number of search nodes or None, got "
            f"{type(node_limit).__name__} {node_limit!r}"
        )
    if node_limit < 0:
        raise GraphError(f"node_limit must be non-negative, got {node_limit}")
    return min(int(node_limit), _NO_LIMIT)


def _floor(lower_bound) -> int:
    if lower_bound is None:
        return 0
    if isinstance(lower_bound, bool) or not isinstance(lower_bound, numbers.Integral):
        raise GraphError(f"lower_bound must be an int or None, got {lower_bound!r}")
    return max(int(lower_bound) - 1, 0)


def max_clique(
    graph, *, time_limit=None, node_limit=None, lower_bound=None, weights=None
) -> CliqueResult:
    """A maximum clique (maximum-weight clique when ``weights`` are given).

    Parameters
    ----------
    graph : bool (n, n) ndarray, edge list, networkx graph or DIMACS path
        See :func:`as_adjacency`.
    time_limit : float, optional
        Seconds: a wall-clock guard. When it bites, the best clique found so far is
        returned with ``optimal=False`` and ``reason="time_limit"``; such a result depends
        on the machine's speed. The clock starts once the compiled kernels are loaded
        (compiling them on a cold cache never counts against it).
    node_limit : int, optional
        Search nodes: the budget that decides results. When reached, the best clique
        found so far is returned with ``optimal=False`` and ``reason="node_limit"``; the
        same graph and limit give the same result on every machine and every run.
    lower_bound : int, optional
        A clique size known to be reachable (e.g. from the previous scan pair). Branches
        that cannot reach it are pruned from the start. If the graph has no clique that
        large, the best clique found is returned with ``optimal=False``.
    weights : (n,) array of non-negative numbers, optional
        Vertex weights; the clique then maximises total weight.

    Returns
    -------
    CliqueResult
        ``vertices`` sorted, ``optimal``, ``nodes``, ``elapsed``, ``weight`` and
        ``reason``.

    Notes
    -----
    Exact branch and bound over bitsets, compiled with numba (BBMC [2]_ after Tomita's
    MCQ/MCS [1]_ [3]_). Small and sparse graphs, the pipeline's (tens to hundreds of
    vertices, density below 0.3), take a lean path whose set-up costs no more than their
    search:

    a. up to 64 vertices: every vertex set is one machine word. At each node ``(C, P)``
       a greedy colouring of ``P`` in label order; a vertex of colour ``k`` can only
       lead to a clique of ``|C| + k`` vertices, so only vertices with ``|C| + k`` above
       the incumbent are branched on (the k-min filter);
    b. more vertices: a greedy clique of size ``k`` grown from the vertices of highest
       degree, then the ``k``-core (vertices of degree below ``k`` peeled repeatedly
       [6]_), which holds any larger clique. An empty core proves the greedy clique
       maximum; a core of at most 64 vertices is renumbered by degree and searched as in
       a; a larger core of density at most 1/4 is searched the same way with multi-word
       sets.

    A denser graph (or core), and a lean search that needs more than a few hundred
    (dense, up to 64 vertices) or 2000 nodes (larger sparse cores), go to the full
    search, on the core when the peeling removed anything:

    1. vertices renumbered in degeneracy order (densest core first), so that bit order
       is colouring order; core numbers come with it [6]_;
    2. an initial clique: the best greedy clique grown from each vertex. If the search
       then needs more than a thousand nodes, a tabu local search [5]_ improves it and the
       search restarts with the higher bar;
    3. k-core pruning: a clique of ``k + 1`` vertices lies in the ``k``-core, so vertices
       of lower core number than the incumbent's size never enter the search;
    4. at each node ``(C, P)``, a greedy colouring of ``P`` in bit order; a vertex of
       colour ``k`` can only lead to a clique of ``|C| + k`` vertices, so only vertices
       with ``|C| + k`` above the incumbent are branched on (the k-min filter);
    5. MaxSAT-style reasoning where colouring is loose (dense graphs): each of those
       vertices is first offered to the colour classes below the bar (directly, or by
       Tomita's Re-NUMBER), then tested by unit propagation over the classes (failed
       literal detection, as in MaxCLQ [4]_); a vertex whose propagation fails is not
       branched on, and the classes of the conflict are used up.

    ``lower_bound`` raises the bar from the start: of the peeling and the lean search,
    and of steps 3 and 4. ``node_limit`` counts the nodes of every phase together (the
    lean search, the first try and the full search). The clock is read every few hundred
    microseconds of work, so ``time_limit`` is met within a few milliseconds. Worst case
    exponential (the problem is NP-hard); a node costs O(|P| n / 64) word operations for
    the colouring, plus the propagation.

    References
    ----------
    .. [1] E. Tomita, T. Kameda, "An efficient branch-and-bound algorithm for finding a
       maximum clique with computational experiments", J. Global Optim. 37 (2007).
    .. [2] P. San Segundo, D. Rodríguez-Losada, A. Jiménez, "An exact bit-parallel
       algorithm for the maximum clique problem", Comput. Oper. Res. 38 (2011).
    .. [3] E. Tomita, Y. Sutani, T. Higashi, S. Takahashi, M. Wakatsuki, "A simple and
       faster branch-and-bound algorithm for finding a maximum clique", WALCOM (2010).
    .. [4] C.-M. Li, Z. Quan, "An efficient branch-and-bound algorithm based on MaxSAT
       for the maximum clique problem", AAAI (2010).
    .. [5] A. Grosso, M. Locatelli, W. Pullan, "Simple ingredients leading to very
       efficient heuristics for the maximum clique problem", J. Heuristics 14 (2008).
    .. [6] V. Batagelj, M. Zaversnik, "An O(m) algorithm for cores decomposition of
       networks", arXiv:cs/0310049 (2003).

    With ``weights``: the full search with the weighted colouring bound (each colour
    class counts its heaviest vertex, Kumlander 2004), without steps 3 and 5.

    Examples
    --------
    >>> import networkx as nx
    >>> max_clique(nx.petersen_graph()).size
    2
    >>> r = max_clique(nx.complete_graph(4), weights=[1, 2, 3, 4])
    >>> r.vertices.tolist(), r.weight
    ([0, 1, 2, 3], 10.0)
    """
    t0 = _clock()
    # the checks inlined for the common None (the pipeline's graphs take microseconds)
    tl = math.inf if time_limit is None else _time_limit(time_limit)
    nl = _NO_LIMIT if node_limit is None else _node_limit(node_limit)
    if weights is None and type(graph) is np.ndarray and graph.dtype is _BOOL:
        return _max_clique_dense(graph, t0, tl, nl, lower_bound)
    return _max_clique(_bits_of(graph), t0, tl, nl, lower_bound, weights)


def _max_clique_dense(adj, t0, tl, nl, lower_bound) -> CliqueResult:
    """:func:`max_clique` of a boolean matrix: one kernel call checks, packs and solves.

    The fixed cost per call matters here (the pipeline's graphs take microseconds), so the
    steps are inlined: :func:`_square`, then the kernel with as few arguments as possible
    (numba's dispatch cost grows with each), then :func:`_result`.
    """
    global _solve_dense  # the kernel, looked up once
    shape = adj.shape
    if len(shape) != 2 or shape[0] != shape[1]:
        _square(adj)  # raises
    if not adj.flags.c_contiguous:
        adj = np.ascontiguousarray(adj)
    n = shape[0]
    floor = 0 if lower_bound is None else _floor(lower_bound)
    if n == 0:
        return CliqueResult(np.empty(0, np.int64), True, 0, _clock() - t0)
    if _solve_dense is None:
        _solve_dense = _kernels().solve_dense
    out = np.empty(n, _INT64)
    size, nodes, status, u, v = _solve_dense(adj, floor, tl, nl, out)
    if status < 0:
        _defect(adj, u, v)
    return _found(out, size, nodes, status, floor, t0)


def _found(out, size, nodes, status, floor, t0) -> CliqueResult:
    """The :class:`CliqueResult` of a search that wrote ``size`` vertices to ``out``."""
    verts = out[:size]
    # write=False, passed by position: numpy's stubs say keyword-only, but the keyword
    # costs a fifth of a microsecond more to parse (numpy 2.4)
    verts.setflags(False)  # type: ignore[call-arg]
    if status == 0 and size > floor:  # the common case first
        return _result(verts, True, nodes, _clock() - t0)
    reason = "lower_bound" if status == 0 else _REASON[status]
    return _result(verts, False, nodes, _clock() - t0, None, reason)


def _max_clique(A, t0, tl, nl, lower_bound, weights) -> CliqueResult:
    n = A.shape[0]
    if weights is not None:
        w = np.asarray(weights, dtype=np.float64).reshape(-1)
        if w.shape[0] != n or not np.isfinite(w).all() or (w < 0).any():
            raise GraphError(f"weights must be {n} finite non-negative numbers")
        if n == 0:
            return CliqueResult(np.empty(0, np.int64), True, 0, _clock() - t0, 0.0)
        verts, _, nodes, status = _kernels().solve_weighted(A, n, w, tl, nl)
        wsum = float(w[verts].sum())
        return CliqueResult(
            _sealed(verts), status == 0, int(nodes), _clock() - t0, wsum, _REASON[status]
        )
    floor = _floor(lower_bound)
    if n == 0:
        return CliqueResult(np.empty(0, np.int64), True, 0, _clock() - t0)
    out = np.empty(n, _INT64)
    size, nodes, status = _kernels().solve_packed(A, n, floor, tl, nl, out)
    return _found(out, size, nodes, status, floor, t0)


def all_maximum_cliques(graph, *, limit=100, time_limit=None, node_limit=None) -> AllCliquesResult:
    """Every maximum clique: first the clique number, then all cliques of that size.

    Parameters
    ----------
    graph : bool (n, n) ndarray, edge list, networkx graph or DIMACS path
    limit : int
        At most this many cliques are returned; ``complete`` is False if there are more.
    time_limit : float, optional
        Seconds for both phases together: a wall-clock guard (see :func:`max_clique`).
    node_limit : int, optional
        Search nodes for both phases together: the budget that decides results.

    Returns
    -------
    AllCliquesResult

    Notes
    -----
    Phase 1 is :func:`max_clique`. Phase 2 reruns the branch and bound with the bar fixed
    at ``omega - 1``, so that every branch that could hold an ``omega``-clique is explored
    and each such clique is met exactly once (branching on ``v`` then removing it
    partitions the search space). Symmetric environments show up here as several cliques.

    Examples
    --------
    >>> import networkx as nx
    >>> r = all_maximum_cliques(nx.cycle_graph(4))
    >>> [c.tolist() for c in r.cliques], r.omega, r.complete
    ([[0, 1], [0, 3], [1, 2], [2, 3]], 2, True)
    """
    t0 = _clock()
    tl = _time_limit(time_limit)
    nl = _node_limit(node_limit)
    if isinstance(limit, bool) or not isinstance(limit, numbers.Integral):
        raise GraphError(f"limit must be an int number of cliques, got {limit!r}")
    return _all_maximum(_bits_of(graph), t0, tl, nl, int(limit))


def _all_maximum(A, t0, tl, nl, limit) -> AllCliquesResult:
    n = A.shape[0]
    if n == 0:
        return AllCliquesResult((), 0, True, True, _clock() - t0)
    K = _kernels()
    best, nodes, status, found, status_all = K.solve(
        A, n, 0, int(K.Mode.ALL_MAXIMUM), max(limit, 0), tl, nl, K.OPT_DEFAULT
    )
    optimal = status == 0
    cl = list(found) if found.shape[0] else [best]
    if limit <= 0:
        cl = []
    for c in cl:
        c.flags.writeable = False
    complete = optimal and status_all == 0
    reason = None if complete else _REASON[status if not optimal else status_all]
    return AllCliquesResult(
        tuple(cl), best.shape[0], complete, optimal, _clock() - t0, int(nodes), reason
    )


def top_cliques(graph, k, *, time_limit=None, node_limit=None) -> tuple[np.ndarray, ...]:
    """The ``k`` largest distinct maximal cliques, largest first.

    For ranking association hypotheses when the true one is not the unique maximum.
    Cliques of equal size are listed lexicographically; which of several equally large
    cliques make the cut at position ``k`` is up to the search.

    Parameters
    ----------
    graph : bool (n, n) ndarray, edge list, networkx graph or DIMACS path
    k : int
        How many cliques (fewer if the graph has fewer maximal cliques).
    time_limit : float, optional
        Seconds, a wall-clock guard; when reached the best cliques seen so far are
        returned.
    node_limit : int, optional
        Search nodes; when reached the best cliques seen so far are returned (the same on
        every machine).

    Returns
    -------
    tuple of int64 ndarrays
        Sorted vertex arrays, in non-increasing size.

    Notes
    -----
    Bron–Kerbosch with Tomita's pivot over bitsets (see :func:`bron_kerbosch`), which
    keeps the ``k`` largest maximal cliques met so far; once it holds ``k``, a branch
    whose clique plus the colour count of its candidates cannot beat the smallest of them
    is cut.

    Examples
    --------
    >>> import networkx as nx
    >>> G = nx.Graph([(0, 1), (0, 2), (1, 2), (2, 3), (3, 4)])
    >>> [c.tolist() for c in top_cliques(G, 2)]
    [[0, 1, 2], [2, 3]]
    """
    tl = _time_limit(time_limit)
    nl = _node_limit(node_limit)
    A = _bits_of(graph)
    if isinstance(k, bool) or not isinstance(k, numbers.Integral):
        raise GraphError(f"k must be an int number of cliques, got {k!r}")
    k = int(k)
    n = A.shape[0]
    if n == 0 or k <= 0:
        return ()
    tops, sizes, count, _ = _kernels().solve_top(A, n, k, tl, nl)
    cl = [_frozen_vertices(tops[i, : sizes[i]]) for i in range(count)]
    cl.sort(key=lambda c: (-c.shape[0], c.tolist()))
    return tuple(cl)
