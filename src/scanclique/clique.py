"""Maximum cliques: the association step of the matcher (paper §5.3), as a general tool.

The correspondence graph of two scans has one vertex per feature pairing and an edge where
two pairings agree geometrically; its maximum clique is the largest mutually consistent
association (Bailey et al. 2000, after Barrow & Burstall 1976). The paper enumerated
maximal cliques with Bron–Kerbosch; this module keeps that as the slow reference
(:func:`bron_kerbosch`) and answers the questions the matcher asks with exact branch and
bound over bitsets (:func:`max_clique`, :func:`all_maximum_cliques`, :func:`top_cliques`).

Any undirected graph will do: a boolean adjacency matrix (the pipeline's case), an edge
list, a networkx graph or a DIMACS ``.clq`` file (see :func:`as_adjacency`). Vertices are
reported as 0-based indices (for networkx graphs: positions in ``list(G)``).

The search runs in compiled kernels (:mod:`scanclique._clique_kernels`, numba, cached on
disk: the first call in a fresh environment compiles for about half a minute, later
processes load the cache in well under a second). ``benchmarks/clique.py`` compares it
with igraph (cliquer), networkx and cliquematch on the DIMACS graphs.

Examples
--------
>>> adj = np.zeros((5, 5), dtype=bool)
>>> for u, v in [(0, 1), (0, 2), (1, 2), (2, 3), (3, 4)]:
...     adj[u, v] = adj[v, u] = True
>>> r = max_clique(adj)
>>> r.vertices.tolist(), r.size, r.optimal
([0, 1, 2], 3, True)
"""

from __future__ import annotations

import logging
import math
import os
import time
from collections.abc import Iterator
from dataclasses import dataclass

import numpy as np

from .errors import GraphError

__all__ = [
    "CliqueResult",
    "AllCliquesResult",
    "max_clique",
    "all_maximum_cliques",
    "top_cliques",
    "bron_kerbosch",
    "as_adjacency",
    "bitsets_from_adjacency",
    "solve_file",
]

log = logging.getLogger(__name__)


# --------------------------------------------------------------------------------------
# Results
# --------------------------------------------------------------------------------------
def _frozen_vertices(v) -> np.ndarray:
    if type(v) is np.ndarray and v.dtype == np.int64 and v.ndim == 1 and not v.flags.writeable:
        return v  # frozen already (the kernels return sorted vertices)
    a = np.sort(np.asarray(v, dtype=np.int64).reshape(-1))  # a fresh, sorted copy
    a.setflags(write=False)
    return a


def _sealed(v: np.ndarray) -> np.ndarray:
    """A fresh sorted int64 array from a kernel, made read-only."""
    v.setflags(write=False)
    return v


def _result(vertices, optimal, nodes, elapsed, weight=None) -> CliqueResult:
    """A :class:`CliqueResult` from trusted parts (sorted, read-only int64 vertices),
    without the generated ``__init__``: on graphs of a few dozen vertices building the
    record would otherwise cost as much as the search.

    The fields are stored on a :class:`_Draft` (same slots, plain attribute stores), which
    then becomes a ``CliqueResult`` by ``__class__`` assignment (allowed between classes of
    the same layout): a third of the cost of five ``object.__setattr__`` calls.
    """
    r = _Draft()
    r.vertices = vertices
    r.optimal = optimal
    r.nodes = nodes
    r.elapsed = elapsed
    r.weight = weight
    r.__class__ = CliqueResult
    return r


_K = None


def _kernels():
    """The compiled kernels, imported on first use (importing numba takes a moment)."""
    global _K
    if _K is None:
        from . import _clique_kernels

        _K = _clique_kernels
    return _K


@dataclass(frozen=True, slots=True, eq=False)
class CliqueResult:
    """A clique and how it was found.

    Attributes
    ----------
    vertices : (k,) int64 ndarray, read-only
        The clique's vertices, sorted.
    optimal : bool
        True when the search proved that no larger (heavier, when weighted) clique exists;
        False when the time limit stopped it first, or when ``lower_bound`` was above the
        clique number.
    nodes : int
        Search-tree nodes expanded. Without weights: the nodes of the lean search (see
        :func:`max_clique`), plus those of the full search where it took over; 1 when
        the k-core proves the greedy clique maximum.
    elapsed : float
        Wall-clock seconds, including input conversion.
    weight : float or None
        Total vertex weight of the clique when weights were given, else None.
    """

    vertices: np.ndarray
    optimal: bool
    nodes: int
    elapsed: float
    weight: float | None = None

    def __post_init__(self) -> None:
        object.__setattr__(self, "vertices", _frozen_vertices(self.vertices))

    @property
    def size(self) -> int:
        """Number of vertices in the clique."""
        return int(self.vertices.shape[0])


#: a mutable twin of :class:`CliqueResult` (the same slots), filled in by :func:`_result`
_Draft = type("_Draft", (), {"__slots__": CliqueResult.__slots__})


@dataclass(frozen=True, slots=True, eq=False)
class AllCliquesResult:
    """Every maximum clique of a graph (or as many as the limit allowed).

    Attributes
    ----------
    cliques : tuple of (omega,) int64 ndarrays, read-only
        The maximum cliques, each sorted, the tuple in lexicographic order.
    omega : int
        The clique number (the largest size found when ``optimal`` is False).
    complete : bool
        True when ``cliques`` holds every maximum clique; False when the limit cut the list
        or the time ran out.
    optimal : bool
        True when ``omega`` is proven to be the clique number.
    elapsed : float
        Wall-clock seconds.
    """

    cliques: tuple[np.ndarray, ...]
    omega: int
    complete: bool
    optimal: bool
    elapsed: float

    def __post_init__(self) -> None:
        cl = [_frozen_vertices(c) for c in self.cliques]
        cl.sort(key=lambda c: c.tolist())
        object.__setattr__(self, "cliques", tuple(cl))


# --------------------------------------------------------------------------------------
# Input
# --------------------------------------------------------------------------------------
def as_adjacency(graph) -> np.ndarray:
    """Normalise a graph to its boolean adjacency matrix.

    Parameters
    ----------
    graph : one of
        - ``(n, n)`` boolean ndarray: symmetric, False diagonal (returned as is);
        - ``(m, 2)`` integer ndarray of 0-based edges (``n = max + 1``), or a tuple
          ``(edges, n)``;
        - a ``networkx.Graph``: vertex ``i`` is ``list(G)[i]``;
        - a path (``str`` or path-like) to a DIMACS ``.clq`` file.

    Returns
    -------
    (n, n) bool ndarray
        Symmetric with a False diagonal.

    Raises
    ------
    GraphError
        Not square, not symmetric, self loops, a directed networkx graph, an edge index
        out of range, or a type that is not a graph.

    Examples
    --------
    >>> as_adjacency((np.array([[0, 1], [1, 2]]), 4)).astype(int)
    array([[0, 1, 0, 0],
           [1, 0, 1, 0],
           [0, 1, 0, 0],
           [0, 0, 0, 0]])
    >>> as_adjacency(np.array([[False, True], [False, False]]))
    Traceback (most recent call last):
    ...
    scanclique.errors.GraphError: adjacency matrix is not symmetric: (0, 1) is True, (1, 0) is False
    """
    if isinstance(graph, (str, os.PathLike)):
        from .io.dimacs import read_dimacs  # the one file format the solver reads

        return read_dimacs(graph).adjacency()
    if isinstance(graph, tuple) and len(graph) == 2:
        return _from_edges(graph[0], int(graph[1]))
    if isinstance(graph, np.ndarray):
        if graph.dtype == np.bool_:
            return _check_adjacency(graph)
        if graph.ndim == 2 and graph.shape[1] == 2 and np.issubdtype(graph.dtype, np.integer):
            n = int(graph.max()) + 1 if graph.size else 0
            return _from_edges(graph, n)
        raise GraphError(
            f"expected a bool (n, n) adjacency or an integer (m, 2) edge list, got dtype "
            f"{graph.dtype} shape {graph.shape}; convert 0/1 matrices with .astype(bool)"
        )
    if hasattr(graph, "adj") and hasattr(graph, "nodes") and hasattr(graph, "is_directed"):
        return _from_networkx(graph)
    raise GraphError(f"cannot read a graph from {type(graph).__name__}")


def _check_adjacency(adj: np.ndarray) -> np.ndarray:
    _bits_checked(adj)
    return adj


def _bits_checked(adj: np.ndarray) -> np.ndarray:
    """Bitset rows of a boolean adjacency matrix, after checking it (square, symmetric,
    no self loop)."""
    adj = _square(adj)
    bits, u, v = _kernels().pack_checked(adj)
    if u >= 0:
        _defect(adj, u, v)
    return bits


def _square(adj: np.ndarray) -> np.ndarray:
    """``adj`` C-contiguous, after checking that it is square."""
    if adj.ndim != 2 or adj.shape[0] != adj.shape[1]:
        raise GraphError(f"adjacency matrix must be square, got shape {adj.shape}")
    return adj if adj.flags.c_contiguous else np.ascontiguousarray(adj)


def _defect(adj: np.ndarray, u: int, v: int):
    """Raise the GraphError for the defect ``(u, v)`` that :func:`pack_checked` found."""
    if u == v:
        raise GraphError(f"adjacency matrix has a self loop at vertex {u}")
    raise GraphError(
        f"adjacency matrix is not symmetric: ({u}, {v}) is {bool(adj[u, v])}, "
        f"({v}, {u}) is {bool(adj[v, u])}"
    )


def _bits_of(graph) -> np.ndarray:
    """Checked bitset rows of any graph :func:`as_adjacency` accepts."""
    if isinstance(graph, np.ndarray) and graph.dtype == np.bool_:
        return _bits_checked(graph)
    return bitsets_from_adjacency(as_adjacency(graph))


def _from_edges(edges, n: int) -> np.ndarray:
    e = np.asarray(edges)
    if e.size == 0:
        e = np.zeros((0, 2), dtype=np.int64)
    if e.ndim != 2 or e.shape[1] != 2 or not np.issubdtype(e.dtype, np.integer):
        raise GraphError(f"edge list must be an integer (m, 2) array, got {e.dtype} {e.shape}")
    if n < 0:
        raise GraphError(f"vertex count must be non-negative, got {n}")
    if e.size and (e.min() < 0 or e.max() >= n):
        raise GraphError(f"edge list refers to vertices outside 0..{n - 1}")
    if (e[:, 0] == e[:, 1]).any():
        v = int(e[e[:, 0] == e[:, 1]][0, 0])
        raise GraphError(f"edge list has a self loop at vertex {v}")
    adj = np.zeros((n, n), dtype=bool)
    adj[e[:, 0], e[:, 1]] = True
    adj[e[:, 1], e[:, 0]] = True
    return adj


def _from_networkx(G) -> np.ndarray:
    if G.is_directed():
        raise GraphError("the clique solver takes undirected graphs; got a directed networkx graph")
    index = {v: i for i, v in enumerate(G)}
    n = len(index)
    adj = np.zeros((n, n), dtype=bool)
    for u, nbrs in G.adj.items():
        i = index[u]
        for v in nbrs:
            if v == u:
                raise GraphError(f"networkx graph has a self loop at node {u!r}")
            adj[i, index[v]] = True
    return adj


def bitsets_from_adjacency(adj: np.ndarray) -> np.ndarray:
    """Pack a boolean adjacency matrix into bitset rows, vectorised.

    Parameters
    ----------
    adj : (n, n) bool ndarray

    Returns
    -------
    (n, ceil(n / 64)) uint64 ndarray
        Bit ``j % 64`` of word ``j // 64`` of row ``i`` is ``adj[i, j]``.

    Examples
    --------
    >>> adj = np.zeros((3, 70), dtype=bool); adj[0, [0, 2]] = True; adj[1, 65] = True
    >>> bitsets_from_adjacency(adj)[:2].tolist()
    [[5, 0], [0, 2]]
    """
    adj = np.asarray(adj, dtype=bool)
    n, ncols = adj.shape
    words = (ncols + 63) // 64
    packed = np.packbits(adj, axis=1, bitorder="little")
    if packed.shape[1] != words * 8:  # pad each row to whole 64-bit words
        full = np.zeros((n, words * 8), dtype=np.uint8)
        full[:, : packed.shape[1]] = packed
        packed = full
    out = np.ascontiguousarray(packed).view("<u8")
    return out.astype(np.uint64, copy=False).reshape(n, words)


# --------------------------------------------------------------------------------------
# Exact maximum clique
# --------------------------------------------------------------------------------------
# the dense path of max_clique, kept lean (see _max_clique_dense)
_clock = time.perf_counter
_BOOL = np.dtype(np.bool_)  # the dtype of every bool array (others take the general path)
_INT64 = np.dtype(np.int64)  # np.empty(n, dtype) is quicker with a dtype than a type
_solve_dense = None


def _limit(time_limit) -> float:
    if time_limit is None:
        return math.inf
    t = float(time_limit)
    if not t >= 0:
        raise GraphError(f"time_limit must be a non-negative number of seconds, got {time_limit}")
    return t


def _run(A, floor, mode, limit, time_limit, t0, opts=None):
    K = _kernels()
    opts = K.OPT_DEFAULT if opts is None else opts
    n = A.shape[0]
    return K.solve(A, n, int(floor), int(mode), int(limit), float(time_limit), float(t0), opts)


def max_clique(graph, *, time_limit=None, lower_bound=None, weights=None) -> CliqueResult:
    """A maximum clique (maximum-weight clique when ``weights`` are given).

    Parameters
    ----------
    graph : bool (n, n) ndarray, edge list, networkx graph or DIMACS path
        See :func:`as_adjacency`.
    time_limit : float, optional
        Seconds. When reached, the best clique found so far is returned with
        ``optimal=False``.
    lower_bound : int, optional
        A clique size known to be reachable (e.g. from the previous scan pair). Branches
        that cannot reach it are pruned from the start. If the graph has no clique that
        large, the best clique found is returned with ``optimal=False``.
    weights : (n,) array of non-negative numbers, optional
        Vertex weights; the clique then maximises total weight.

    Returns
    -------
    CliqueResult
        ``vertices`` sorted, ``optimal``, ``nodes``, ``elapsed`` and ``weight``.

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
    and of steps 3 and 4. The clock is read
    every few hundred microseconds of work, so ``time_limit`` is met within a few
    milliseconds. Worst case exponential (the problem is NP-hard); a node costs
    O(|P| n / 64) word operations for the colouring, plus the propagation.

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
    tl = math.inf if time_limit is None else _limit(time_limit)
    if weights is None and type(graph) is np.ndarray and graph.dtype is _BOOL:
        return _max_clique_dense(graph, t0, tl, lower_bound)
    return _max_clique(_bits_of(graph), t0, tl, lower_bound, weights)


def _max_clique_dense(adj, t0, tl, lower_bound) -> CliqueResult:
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
    floor = 0 if lower_bound is None else max(int(lower_bound) - 1, 0)
    if n == 0:
        return CliqueResult(np.empty(0, np.int64), True, 0, _clock() - t0)
    if _solve_dense is None:
        _solve_dense = _kernels().solve_dense
    out = np.empty(n, _INT64)
    size, nodes, status, u, v = _solve_dense(adj, floor, t0 + tl, out)
    if status < 0:
        _defect(adj, u, v)
    return _found(out, size, nodes, status, floor, t0)


def _found(out, size, nodes, status, floor, t0) -> CliqueResult:
    """The :class:`CliqueResult` of a search that wrote ``size`` vertices to ``out``."""
    optimal = status == 0 and size > floor
    verts = out[:size]
    # write=False, passed by position: numpy's stubs say keyword-only, but the keyword
    # costs a fifth of a microsecond more to parse (numpy 2.4)
    verts.setflags(False)  # type: ignore[call-arg]
    return _result(verts, optimal, nodes, _clock() - t0)


def _max_clique(A, t0, tl, lower_bound, weights) -> CliqueResult:
    n = A.shape[0]
    if weights is not None:
        w = np.asarray(weights, dtype=np.float64).reshape(-1)
        if w.shape[0] != n or not np.isfinite(w).all() or (w < 0).any():
            raise GraphError(f"weights must be {n} finite non-negative numbers")
        if n == 0:
            return CliqueResult(np.empty(0, np.int64), True, 0, time.perf_counter() - t0, 0.0)
        verts, _, nodes, timed_out = _kernels().solve_weighted(A, n, w, tl, t0)
        wsum = float(w[verts].sum())
        return CliqueResult(
            _sealed(verts), not timed_out, int(nodes), time.perf_counter() - t0, wsum
        )
    floor = 0 if lower_bound is None else max(int(lower_bound) - 1, 0)
    if n == 0:
        return CliqueResult(np.empty(0, np.int64), True, 0, time.perf_counter() - t0)
    out = np.empty(n, _INT64)
    size, nodes, status = _kernels().solve_bits(A, n, floor, t0 + tl, out)
    return _found(out, size, nodes, status, floor, t0)


def all_maximum_cliques(graph, *, limit=100, time_limit=None) -> AllCliquesResult:
    """Every maximum clique: first the clique number, then all cliques of that size.

    Parameters
    ----------
    graph : bool (n, n) ndarray, edge list, networkx graph or DIMACS path
    limit : int
        At most this many cliques are returned; ``complete`` is False if there are more.
    time_limit : float, optional
        Seconds for both phases together.

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
    t0 = time.perf_counter()
    tl = _limit(time_limit)
    return _all_maximum(_bits_of(graph), t0, tl, int(limit))


def _all_maximum(A, t0, tl, limit) -> AllCliquesResult:
    n = A.shape[0]
    if n == 0:
        return AllCliquesResult((), 0, True, True, time.perf_counter() - t0)
    best, _, status, found, status_all = _run(A, 0, 2, max(limit, 0), tl, t0)
    optimal = status == 0
    # status_all: 0 = all enumerated, 1 = out of time, 3 = more than `limit`, -1 = not run
    cl = list(found) if found.shape[0] else [best]
    if limit <= 0:
        cl = []
    for c in cl:
        c.flags.writeable = False
    complete = optimal and status_all == 0
    return AllCliquesResult(tuple(cl), best.shape[0], complete, optimal, time.perf_counter() - t0)


def top_cliques(graph, k, *, time_limit=None) -> tuple[np.ndarray, ...]:
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
        Seconds; when reached the best cliques seen so far are returned.

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
    t0 = time.perf_counter()
    tl = _limit(time_limit)
    A = _bits_of(graph)
    k = int(k)
    n = A.shape[0]
    if n == 0 or k <= 0:
        return ()
    tops, sizes, count, _ = _kernels().solve_top(A, n, k, tl, t0)
    cl = [_frozen_vertices(tops[i, : sizes[i]]) for i in range(count)]
    cl.sort(key=lambda c: (-c.shape[0], c.tolist()))
    return tuple(cl)


# --------------------------------------------------------------------------------------
# Reference
# --------------------------------------------------------------------------------------
def bron_kerbosch(graph, *, min_size: int = 0) -> Iterator[np.ndarray]:
    """Every maximal clique, by Bron–Kerbosch with Tomita's pivot: the slow reference.

    Parameters
    ----------
    graph : bool (n, n) ndarray, edge list, networkx graph or DIMACS path
    min_size : int
        Only the maximal cliques of at least this many vertices. Branches that cannot
        reach it are not explored: ``|R|`` plus the number of colours of a greedy
        colouring of ``P`` (each colour an independent set, so a clique takes at most one
        vertex of each) is below ``min_size``.

    Yields
    ------
    (k,) int64 ndarray
        Each maximal clique once, sorted. The empty graph has none.

    Notes
    -----
    The algorithm the paper used (§5.3). ``R`` is the growing clique, ``P`` the
    candidates that extend it, ``X`` the vertices that extend it but were already
    explored. The pivot ``u`` maximises ``|P ∩ N(u)|``; only ``P \\ N(u)`` is branched on,
    which bounds the run time by O(3^(n/3)), the number of maximal cliques in the worst
    case (Tomita, Tanaka, Takahashi 2006).

    References
    ----------
    .. [1] C. Bron, J. Kerbosch, "Algorithm 457: finding all cliques of an undirected
       graph", Comm. ACM 16 (1973).
    .. [2] E. Tomita, A. Tanaka, H. Takahashi, "The worst-case time complexity for
       generating all maximal cliques", Theor. Comput. Sci. 363 (2006).

    Examples
    --------
    >>> import networkx as nx
    >>> sorted(c.tolist() for c in bron_kerbosch(nx.path_graph(3)))
    [[0, 1], [1, 2]]
    >>> [c.tolist() for c in bron_kerbosch(nx.lollipop_graph(4, 2), min_size=3)]
    [[0, 1, 2, 3]]
    """
    adj = as_adjacency(graph)
    n = adj.shape[0]
    if n == 0:
        return
    # sets as Python ints: bit v of N[v'] says v ~ v'
    N = [int.from_bytes(np.packbits(row, bitorder="little").tobytes(), "little") for row in adj]
    R: list[int] = []
    P = (1 << n) - 1
    X = 0
    stack: list[list] = []  # frames [R, P, X, todo]
    while True:
        # invariant: every vertex of P and X is adjacent to all of R; the cliques still to
        # report are those R ∪ S, S ⊆ P, that no vertex of X extends
        if len(R) + P.bit_count() >= min_size and len(R) + _colours(P, N) >= min_size:
            if not P and not X:
                yield np.array(sorted(R), dtype=np.int64)
            if P:
                u = max(_bits(P | X), key=lambda x: (P & N[x]).bit_count())
                stack.append([R, P, X, P & ~N[u]])
        while stack:
            frame = stack[-1]
            R, P, X, todo = frame
            if todo:
                low = todo & -todo
                v = low.bit_length() - 1
                frame[1], frame[2], frame[3] = P ^ low, X | low, todo ^ low
                R, P, X = R + [v], P & N[v], X & N[v]
                break
            stack.pop()
        else:
            return


def _colours(P: int, N: list[int]) -> int:
    """Number of classes of the greedy colouring of ``P`` in label order."""
    k = 0
    while P:
        # one class: repeatedly take the lowest vertex not adjacent to the class so far
        k += 1
        Q = P
        while Q:
            low = Q & -Q
            P ^= low
            Q &= ~N[low.bit_length() - 1] & ~low
    return k


def _bits(x: int) -> Iterator[int]:
    while x:
        low = x & -x
        yield low.bit_length() - 1
        x ^= low


# --------------------------------------------------------------------------------------
# Command-line helper
# --------------------------------------------------------------------------------------
def solve_file(path, *, all=False, time_limit=None) -> dict:  # noqa: A002 (CLI flag name)
    """Solve a DIMACS file and return a JSON-ready summary (used by ``scanclique clique``).

    Parameters
    ----------
    path : str or path-like
        A DIMACS ``.clq`` file.
    all : bool
        Also enumerate every maximum clique (up to 1000).
    time_limit : float, optional
        Seconds.

    Returns
    -------
    dict
        ``file, n, m, omega, optimal, clique`` (1-based vertex numbers, as in the file),
        ``nodes, elapsed`` (seconds of the search) and ``load`` (seconds to load the
        compiled kernels, paid once per process); with ``all``: ``cliques`` (1-based,
        lexicographic) and ``complete``.
    """
    from .io.dimacs import read_dimacs

    g = read_dimacs(path)
    A = bitsets_from_adjacency(g.adjacency())
    t = time.perf_counter()
    _run(bitsets_from_adjacency(np.zeros((2, 2), bool)), 0, 0, 0, math.inf, t)
    load = time.perf_counter() - t
    t0 = time.perf_counter()
    tl = _limit(time_limit)
    if g.n == 0:
        best, nodes, status, found, status_all = np.empty(0, np.int64), 0, 0, (), 0
    else:  # with `all`, one search: the clique number, then every clique of that size
        best, nodes, status, found, status_all = _run(A, 0, 2 if all else 0, 1000, tl, t0)
    elapsed = time.perf_counter() - t0
    out = {
        "file": os.fspath(path),
        "n": g.n,
        "m": g.m,
        "omega": int(best.shape[0]),
        "optimal": status == 0,
        "clique": (best + 1).tolist(),
        "nodes": int(nodes),
        "elapsed": elapsed,
        "load": load,
    }
    if all:
        out["cliques"] = sorted((c + 1).tolist() for c in found) or [out["clique"]] * (g.n > 0)
        out["complete"] = status == 0 and status_all == 0
    return out
