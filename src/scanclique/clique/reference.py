"""Bron–Kerbosch with Tomita's pivot: the algorithm the paper used (§5.3), kept as the slow
reference the fast searches are tested against (see :mod:`scanclique.clique`)."""

from __future__ import annotations

from collections.abc import Iterator

import numpy as np

from .graphs import as_adjacency

__all__ = ["bron_kerbosch"]


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
