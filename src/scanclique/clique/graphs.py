"""Graphs in, bitsets out: the input side of the clique engine (see
:mod:`scanclique.clique`).

Any undirected graph will do: a boolean adjacency matrix (the pipeline's case), an edge
list, a networkx graph or a DIMACS ``.clq`` file. A graph given by its vertex count (an
edge list, a networkx graph, a DIMACS header) is refused before anything is allocated when
its adjacency matrix would exceed :data:`MAX_VERTICES` vertices (see
:func:`check_vertex_count`).
"""

from __future__ import annotations

import os

import numpy as np

from ..errors import GraphError
from ._load import kernels

__all__ = [
    "MAX_VERTICES",
    "as_adjacency",
    "bitsets_from_adjacency",
    "check_vertex_count",
    "adjacency_bytes",
]

#: the largest vertex count accepted from a graph that is not an adjacency matrix already
#: (edge lists, networkx graphs, DIMACS files): 2**15, a 1 GiB boolean matrix plus its
#: 128 MiB of bitsets. Override per call (``max_vertices=``) or per process with the
#: environment variable ``SCANCLIQUE_MAX_VERTICES``.
MAX_VERTICES = 1 << 15


def adjacency_bytes(n: int) -> int:
    """Bytes the solver allocates for a graph of ``n`` vertices: the ``(n, n)`` boolean
    matrix and its bitset rows (``n * ceil(n / 64)`` 64-bit words)."""
    n = int(n)
    return n * n + 8 * n * ((n + 63) // 64)


def _bytes_text(b: float) -> str:
    for unit in ("B", "KiB", "MiB", "GiB", "TiB", "PiB", "EiB"):
        if b < 1024 or unit == "EiB":
            return f"{b:.0f} {unit}" if unit == "B" else f"{b:.1f} {unit}"
        b /= 1024
    raise AssertionError  # pragma: no cover


def _max_vertices(max_vertices) -> int:
    if max_vertices is not None:
        v = max_vertices
        what = "max_vertices"
    else:
        env = os.environ.get("SCANCLIQUE_MAX_VERTICES")
        if env is None:
            return MAX_VERTICES
        v, what = env, "SCANCLIQUE_MAX_VERTICES"
        try:
            v = int(env)
        except ValueError:
            raise GraphError(
                f"environment variable SCANCLIQUE_MAX_VERTICES must be a whole number of "
                f"vertices, got {env!r}"
            ) from None
    if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or v < 0:
        raise GraphError(f"{what} must be a non-negative int, got {v!r}")
    return int(v)


def check_vertex_count(n: int, *, source: str = "graph", max_vertices: int | None = None) -> int:
    """Refuse a vertex count whose adjacency matrix would exceed the bound, before
    anything is allocated.

    Parameters
    ----------
    n : int
        The vertex count.
    source : str
        What declares it, for the message (``"edge list"``, ``"g.clq:1: p line"``).
    max_vertices : int, optional
        The bound; default :data:`MAX_VERTICES`, or ``SCANCLIQUE_MAX_VERTICES`` from the
        environment when set.

    Returns
    -------
    int
        ``n``.

    Raises
    ------
    GraphError
        ``n`` above the bound; the message gives the memory it would need.

    Examples
    --------
    >>> check_vertex_count(100_000_001, source="edge list")  # doctest: +ELLIPSIS
    Traceback (most recent call last):
    ...
    scanclique.errors.GraphError: edge list: 100000001 vertices would need 10.0 PiB ...
    """
    bound = _max_vertices(max_vertices)
    n = int(n)
    if n > bound:
        raise GraphError(
            f"{source}: {n} vertices would need {_bytes_text(adjacency_bytes(n))} for the "
            f"adjacency matrix and its bitsets; the limit is {bound} vertices "
            f"({_bytes_text(adjacency_bytes(bound))}): pass max_vertices= or set "
            f"SCANCLIQUE_MAX_VERTICES to raise it"
        )
    return n


def as_adjacency(graph, *, max_vertices: int | None = None) -> np.ndarray:
    """Normalise a graph to its boolean adjacency matrix.

    Parameters
    ----------
    graph : one of
        - ``(n, n)`` boolean ndarray: symmetric, False diagonal (returned as is);
        - ``(m, 2)`` integer ndarray of 0-based edges (``n = max + 1``), or a tuple
          ``(edges, n)``;
        - a ``networkx.Graph``: vertex ``i`` is ``list(G)[i]``;
        - a path (``str`` or path-like) to a DIMACS ``.clq`` file.
    max_vertices : int, optional
        Bound on ``n`` for every form but the matrix (see :func:`check_vertex_count`).

    Returns
    -------
    (n, n) bool ndarray
        Symmetric with a False diagonal.

    Raises
    ------
    GraphError
        Not square, not symmetric, self loops, a directed networkx graph, an edge index
        out of range, more vertices than the bound, or a type that is not a graph.

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
        from ..io.dimacs import read_dimacs  # the one file format the solver reads

        g = read_dimacs(graph)
        check_vertex_count(g.n, source=os.fspath(graph), max_vertices=max_vertices)
        return g.adjacency()
    if isinstance(graph, tuple) and len(graph) == 2:
        n = graph[1]
        if isinstance(n, bool) or not isinstance(n, (int, np.integer)):
            raise GraphError(f"vertex count of an (edges, n) graph must be an int, got {n!r}")
        return _from_edges(graph[0], int(n), max_vertices)
    if isinstance(graph, np.ndarray):
        if graph.dtype == np.bool_:
            return _check_adjacency(graph)
        if graph.ndim == 2 and graph.shape[1] == 2 and np.issubdtype(graph.dtype, np.integer):
            n = int(graph.max()) + 1 if graph.size else 0
            return _from_edges(graph, n, max_vertices)
        raise GraphError(
            f"expected a bool (n, n) adjacency or an integer (m, 2) edge list, got dtype "
            f"{graph.dtype} shape {graph.shape}; convert 0/1 matrices with .astype(bool)"
        )
    if hasattr(graph, "adj") and hasattr(graph, "nodes") and hasattr(graph, "is_directed"):
        return _from_networkx(graph, max_vertices)
    raise GraphError(f"cannot read a graph from {type(graph).__name__}")


def _check_adjacency(adj: np.ndarray) -> np.ndarray:
    _bits_checked(adj)
    return adj


def _bits_checked(adj: np.ndarray) -> np.ndarray:
    """Bitset rows of a boolean adjacency matrix, after checking it (square, symmetric,
    no self loop)."""
    adj = _square(adj)
    bits, u, v = kernels().pack_checked(adj)
    if u >= 0:
        _defect(adj, u, v)
    return bits


def _square(adj: np.ndarray) -> np.ndarray:
    """``adj`` C-contiguous, after checking that it is square."""
    if adj.ndim != 2 or adj.shape[0] != adj.shape[1]:
        raise GraphError(f"adjacency matrix must be square, got shape {adj.shape}")
    return adj if adj.flags.c_contiguous else np.ascontiguousarray(adj)


def _defect(adj: np.ndarray, u: int, v: int):
    """Raise the GraphError for the defect ``(u, v)`` that ``pack_checked`` found."""
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


def _from_edges(edges, n: int, max_vertices=None) -> np.ndarray:
    e = np.asarray(edges)
    if e.size == 0:
        e = np.zeros((0, 2), dtype=np.int64)
    if e.ndim != 2 or e.shape[1] != 2 or not np.issubdtype(e.dtype, np.integer):
        raise GraphError(f"edge list must be an integer (m, 2) array, got {e.dtype} {e.shape}")
    if n < 0:
        raise GraphError(f"vertex count must be non-negative, got {n}")
    if e.size and (e.min() < 0 or e.max() >= n):
        raise GraphError(f"edge list refers to vertices outside 0..{n - 1}")
    check_vertex_count(n, source="edge list", max_vertices=max_vertices)
    if (e[:, 0] == e[:, 1]).any():
        v = int(e[e[:, 0] == e[:, 1]][0, 0])
        raise GraphError(f"edge list has a self loop at vertex {v}")
    adj = np.zeros((n, n), dtype=bool)
    adj[e[:, 0], e[:, 1]] = True
    adj[e[:, 1], e[:, 0]] = True
    return adj


def _from_networkx(G, max_vertices=None) -> np.ndarray:
    if G.is_directed():
        raise GraphError("the clique solver takes undirected graphs; got a directed networkx graph")
    check_vertex_count(len(G), source="networkx graph", max_vertices=max_vertices)
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
