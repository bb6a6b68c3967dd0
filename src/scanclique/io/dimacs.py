"""DIMACS ``.clq`` graphs: the format of the second DIMACS challenge (1993).

A file is a sequence of lines::

    c any comment
    p edge N M          # N vertices, M edges (``p col`` is accepted as well)
    e u v               # an edge, vertices numbered 1..N
    n v w               # optional: weight w of vertex v (weighted instances)

Vertices are 1-based in the file and 0-based in memory. Duplicate edges (some files list
both directions) are merged; a declared edge count that disagrees with the lines found is
logged, not fatal. Malformed lines raise :class:`scanclique.errors.ParseError` naming the
file, the line and the field.

Examples
--------
>>> import tempfile, os
>>> d = tempfile.mkdtemp()
>>> path = os.path.join(d, "triangle.clq")
>>> adj = np.array([[0, 1, 1], [1, 0, 1], [1, 1, 0]], dtype=bool)
>>> write_dimacs(path, adj, comments=["a triangle"])
>>> g = read_dimacs(path)
>>> g.n, g.edges.tolist()
(3, [[0, 1], [0, 2], [1, 2]])
>>> bool((g.adjacency() == adj).all())
True
"""

from __future__ import annotations

import logging
import os
from array import array
from collections.abc import Iterable
from dataclasses import dataclass

import numpy as np

from ..errors import GraphError, ParseError
from .text import plain_float, plain_number

__all__ = ["DimacsGraph", "read_dimacs", "write_dimacs"]

log = logging.getLogger(__name__)


@dataclass(frozen=True, slots=True, eq=False)
class DimacsGraph:
    """An undirected graph read from a DIMACS file.

    Attributes
    ----------
    n : int
        Number of vertices (from the ``p`` line).
    edges : (m, 2) int64 ndarray, read-only
        Distinct edges, 0-based, ``u < v``, sorted lexicographically.
    weights : (n,) float64 ndarray or None, read-only
        Vertex weights from ``n v w`` lines (vertices without a line weigh 1), or None
        when the file has no ``n`` line.
    comments : tuple of str
        The text of the ``c`` lines, in order (the first 1000, each cut at 1000
        characters).
    """

    n: int
    edges: np.ndarray
    weights: np.ndarray | None = None
    comments: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        self.edges.flags.writeable = False
        if self.weights is not None:
            self.weights.flags.writeable = False

    @property
    def m(self) -> int:
        """Number of distinct edges."""
        return int(self.edges.shape[0])

    def adjacency(self) -> np.ndarray:
        """The ``(n, n)`` boolean adjacency matrix (symmetric, False diagonal)."""
        adj = np.zeros((self.n, self.n), dtype=bool)
        adj[self.edges[:, 0], self.edges[:, 1]] = True
        adj[self.edges[:, 1], self.edges[:, 0]] = True
        return adj


def _int_field(path, lineno, tok, field):
    try:
        if not plain_number(tok):  # int("1_0") is 10, int("١٢") 12
            raise ValueError(tok)
        return int(tok)
    except ValueError:
        raise ParseError(path, lineno, f"expected an integer, found {tok!r}", field) from None


MAX_COMMENTS = 1000
"""``c`` lines kept in :attr:`DimacsGraph.comments` (later ones are read and dropped)."""
MAX_COMMENT_CHARS = 1000


def read_dimacs(path: str | os.PathLike, *, max_vertices: int | None = None) -> DimacsGraph:
    """Read a DIMACS ``.clq`` (``p edge``) file, streamed line by line.

    Memory: the edges as two int64 columns (16 bytes per ``e`` line) and ``8 N`` bytes of
    weights when there are ``n`` lines; ``N`` is checked against ``max_vertices`` before
    anything is allocated, with the memory its adjacency matrix would need in the message.

    Parameters
    ----------
    path : str or path-like
        The file (a regular file: FIFOs and devices are refused).
    max_vertices : int, optional
        Largest accepted ``N``: the clique solver's bound
        (:func:`scanclique.clique.check_vertex_count`: ``MAX_VERTICES``, or
        ``SCANCLIQUE_MAX_VERTICES`` from the environment), checked on the ``p`` line.

    Returns
    -------
    DimacsGraph
        Vertex count, distinct 0-based edges, optional vertex weights and the comments.

    Raises
    ------
    ParseError
        An unknown line type, a missing or repeated ``p`` line, a non-integer field, more
        edge lines than ``N (N - 1)``, a vertex outside ``1..N`` or a self loop; the message
        names the file, line and field.
    GraphError
        ``N`` above ``max_vertices`` (the message gives the memory its adjacency would
        need), checked before anything is allocated.
    scanclique.errors.DataNotFoundError
        The file does not exist.
    """
    from ..clique.graphs import check_vertex_count
    from .text import LineSource

    src = LineSource(path)
    path_s = src.path
    n = -1
    m_declared = 0
    max_lines = 0
    us = array("q")
    vs = array("q")
    comments: list[str] = []
    weights: np.ndarray | None = None
    for lineno, raw in src:
        line = raw.strip()
        if not line:
            continue
        tag = line[0]
        if tag == "c":
            if len(comments) < MAX_COMMENTS:
                comments.append(line[1:].strip()[:MAX_COMMENT_CHARS])
            continue
        toks = line.split()
        if tag == "e" and toks[0] == "e":
            if n < 0:
                raise ParseError(path_s, lineno, "edge line before the 'p edge N M' line", "e")
            if len(toks) != 3:
                raise ParseError(
                    path_s, lineno, f"expected 'e u v', found {len(toks) - 1} fields", "e"
                )
            u = _int_field(path_s, lineno, toks[1], "u")
            v = _int_field(path_s, lineno, toks[2], "v")
            for name, x in (("u", u), ("v", v)):
                if not 1 <= x <= n:
                    raise ParseError(path_s, lineno, f"vertex must be in 1..{n}, found {x}", name)
            if u == v:
                raise ParseError(path_s, lineno, f"self loop on vertex {u}", "v")
            if len(us) >= max_lines:
                raise ParseError(
                    path_s,
                    lineno,
                    f"more edge lines than N (N - 1) = {max_lines} (each edge at most once "
                    "in each direction)",
                    "e",
                )
            us.append(u)
            vs.append(v)
        elif tag == "p" and toks[0] == "p":
            if n >= 0:
                raise ParseError(path_s, lineno, "a second 'p' line", "p")
            if len(toks) != 4 or toks[1] not in ("edge", "col"):
                raise ParseError(path_s, lineno, f"expected 'p edge N M', found {line!r}", "p")
            n = _int_field(path_s, lineno, toks[2], "N")
            m_declared = _int_field(path_s, lineno, toks[3], "M")
            if n < 0 or m_declared < 0:
                raise ParseError(path_s, lineno, "N and M must be non-negative", "p")
            check_vertex_count(n, source=f"{path_s}:{lineno}: p line", max_vertices=max_vertices)
            max_lines = n * (n - 1)
        elif tag == "n" and toks[0] == "n":
            if n < 0:
                raise ParseError(path_s, lineno, "weight line before the 'p edge N M' line", "n")
            if len(toks) != 3:
                raise ParseError(path_s, lineno, "expected 'n v w'", "n")
            v = _int_field(path_s, lineno, toks[1], "v")
            if not 1 <= v <= n:
                raise ParseError(path_s, lineno, f"vertex must be in 1..{n}, found {v}", "v")
            try:
                w = plain_float(toks[2])
            except ValueError:
                raise ParseError(
                    path_s, lineno, f"expected a number, found {toks[2]!r}", "w"
                ) from None
            if weights is None:
                weights = np.ones(n, dtype=np.float64)
            weights[v - 1] = w
        else:
            raise ParseError(
                path_s, lineno, f"unknown line type {toks[0]!r} (expected c, p, e or n)", "type"
            )
    if n < 0:
        raise ParseError(path_s, None, "no 'p edge N M' line")
    e = np.empty((len(us), 2), dtype=np.int64)
    e[:, 0] = np.frombuffer(us, dtype=np.int64) if len(us) else 0
    e[:, 1] = np.frombuffer(vs, dtype=np.int64) if len(vs) else 0
    e -= 1
    del us, vs
    e.sort(axis=1)
    e = np.unique(e, axis=0) if e.shape[0] else e
    if e.shape[0] != m_declared:
        log.debug("%s: 'p' line declares %d edges, found %d distinct", path_s, m_declared, len(e))
    return DimacsGraph(
        n=n, edges=np.ascontiguousarray(e), weights=weights, comments=tuple(comments)
    )


def write_dimacs(
    path: str | os.PathLike,
    graph,
    *,
    comments: Iterable[str] = (),
    weights: np.ndarray | None = None,
) -> None:
    """Write a graph as a DIMACS ``p edge`` file (1-based vertices, each edge once).

    Parameters
    ----------
    path : str or path-like
        Destination.
    graph : (n, n) bool ndarray, DimacsGraph or tuple ``(edges, n)``
        The graph; ``edges`` is ``(m, 2)``, 0-based.
    comments : iterable of str
        Written as ``c`` lines at the top.
    weights : (n,) array, optional
        Vertex weights, written as ``n v w`` lines.
    """
    if isinstance(graph, DimacsGraph):
        n, edges = graph.n, graph.edges
        if weights is None:
            weights = graph.weights
    elif isinstance(graph, tuple) and len(graph) == 2:
        edges, n = np.asarray(graph[0], dtype=np.int64).reshape(-1, 2), int(graph[1])
    else:
        adj = np.asarray(graph)
        if adj.ndim != 2 or adj.shape[0] != adj.shape[1]:
            raise GraphError(f"adjacency must be square, got shape {adj.shape}")
        n = adj.shape[0]
        iu, ju = np.nonzero(np.triu(adj.astype(bool), 1))
        edges = np.stack([iu, ju], axis=1)
    edges = np.sort(np.asarray(edges, dtype=np.int64), axis=1)
    edges = np.unique(edges, axis=0) if edges.shape[0] else edges
    parts = [f"c {c}\n" for c in comments]
    parts.append(f"p edge {n} {edges.shape[0]}\n")
    if weights is not None:
        w = np.asarray(weights, dtype=np.float64)
        parts.extend(f"n {i + 1} {x:.17g}\n" for i, x in enumerate(w))
    e1 = edges + 1
    parts.extend(f"e {u} {v}\n" for u, v in e1.tolist())
    with open(os.fspath(path), "w", encoding="utf-8") as fh:
        fh.write("".join(parts))
