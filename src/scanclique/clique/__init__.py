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

Budgets: ``node_limit`` (search nodes) decides results, the same on every machine;
``time_limit`` (seconds) is an outer guard that reports itself (``optimal=False``,
``reason="time_limit"``) when it bites, and never counts kernel compilation.

The package, by concern: :mod:`~scanclique.clique.graphs` (input forms, checks, the
vertex bound, bitsets), :mod:`~scanclique.clique.search` (the exact searches),
:mod:`~scanclique.clique.results` (the records), :mod:`~scanclique.clique.reference`
(Bron–Kerbosch), :mod:`~scanclique.clique.files` (DIMACS files, for the CLI). The search
runs in compiled kernels (:mod:`scanclique._kernels`, numba, cached on disk in a directory
stamped with the kernel sources' hash: the first call in a fresh environment compiles for
about half a minute, later processes load the cache in well under a second).
``benchmarks/clique.py`` compares it with igraph (cliquer), networkx and cliquematch on the
DIMACS graphs and on correspondence graphs of real scans.

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

import numpy as np  # noqa: F401 (the examples above use it)

from .files import solve_file
from .graphs import (
    MAX_VERTICES,
    adjacency_bytes,
    as_adjacency,
    bitsets_from_adjacency,
    check_vertex_count,
)
from .reference import bron_kerbosch
from .results import REASONS, AllCliquesResult, CliqueResult
from .search import all_maximum_cliques, max_clique, top_cliques

__all__ = [
    "CliqueResult",
    "AllCliquesResult",
    "REASONS",
    "max_clique",
    "all_maximum_cliques",
    "top_cliques",
    "bron_kerbosch",
    "as_adjacency",
    "bitsets_from_adjacency",
    "check_vertex_count",
    "adjacency_bytes",
    "MAX_VERTICES",
    "solve_file",
]
