"""The correspondence graph of two feature graphs (paper §5.2; pipeline stage 5).

Barrow & Burstall (1976): the nodes are all pairings ``(a, b)`` of same-labelled nodes of
graphs A and B (whose node attributes agree, for kinds that have them, see
:mod:`scanclique.kinds`); an edge joins ``(a1, b1)`` and ``(a2, b2)`` when ``a1 != a2``,
``b1 != b2`` and every invariant that applies to both node pairs agrees within tolerance:
``|inv_A[k, a1, a2] - inv_B[k, b1, b2]| <= tol`` (modulo 2π on angle layers). A clique of
this graph is a set of pairings whose geometry agrees mutually; the maximum clique is the
maximum common subgraph, i.e. the association.

The edges are computed by a compiled kernel over all node pairs (no Python loop over
pairs of pairs), straight into a dense boolean adjacency matrix for the clique solver.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ._lazy import kernel_module
from ._records import readonly
from .config import CorrespondenceConfig
from .errors import ConfigError, GraphError
from .graph import FeatureGraph

_K = kernel_module("scanclique._kernels.correspondence")

__all__ = ["CorrespondenceGraph", "correspondence_graph", "candidate_pairs", "count_pairs"]


@dataclass(frozen=True, slots=True, eq=False)
class CorrespondenceGraph:
    """Pairings of nodes of graphs A and B, and which pairings agree.

    Attributes
    ----------
    pairs : ndarray, shape (n, 2), int64
        ``pairs[u] = (a, b)``: node ``a`` of A paired with node ``b`` of B.
    adjacency : ndarray, shape (n, n), bool
        Symmetric, False diagonal.
    """

    pairs: np.ndarray
    adjacency: np.ndarray

    def __post_init__(self) -> None:
        for name in ("pairs", "adjacency"):
            object.__setattr__(self, name, readonly(getattr(self, name)))

    @property
    def n_nodes(self) -> int:
        return int(self.pairs.shape[0])

    @property
    def n_edges(self) -> int:
        return int(np.count_nonzero(self.adjacency)) // 2

    @property
    def density(self) -> float:
        n = self.n_nodes
        return 0.0 if n < 2 else 2.0 * self.n_edges / (n * (n - 1))


def _has_attributes(a, b) -> bool:
    return (
        isinstance(a, FeatureGraph)
        and isinstance(b, FeatureGraph)
        and a.attributes.shape[1] > 0
        and b.attributes.shape[1] > 0
    )


def _pair_mask(graph_a: FeatureGraph, graph_b: FeatureGraph) -> np.ndarray:
    """(N_A, N_B) bool: same label, and, for nodes of one kind, every node attribute
    within the kind's tolerance (an attribute either node lacks, NaN, does not veto)."""
    ok = graph_a.labels[:, None] == graph_b.labels[None, :]
    same_kind = graph_a.kinds[:, None] == graph_b.kinds[None, :]
    A = min(graph_a.attributes.shape[1], graph_b.attributes.shape[1])
    for k in range(A):
        diff = np.abs(graph_a.attributes[:, None, k] - graph_b.attributes[None, :, k])
        ok &= ~(same_kind & (diff > graph_a.attribute_tolerances[:, None, k]))
    return ok


def _labels(x) -> np.ndarray:
    """Node labels of a feature graph, or the label array itself."""
    return np.asarray(x.labels if isinstance(x, FeatureGraph) else x, dtype=np.int64).ravel()


def count_pairs(labels_a, labels_b) -> int:
    """How many pairings :func:`candidate_pairs` forms, without forming them.

    For label arrays (or graphs without node attributes), the sum over labels of
    (count in A) x (count in B); for feature graphs with node attributes, the count of
    the attribute test's mask (at most ``max_features``² booleans).
    """
    if _has_attributes(labels_a, labels_b):
        return int(np.count_nonzero(_pair_mask(labels_a, labels_b)))
    a, b = _labels(labels_a), _labels(labels_b)
    if a.size == 0 or b.size == 0:
        return 0
    lo = int(min(a.min(), b.min()))
    size = int(max(a.max(), b.max())) - lo + 1
    return int(np.dot(np.bincount(a - lo, minlength=size), np.bincount(b - lo, minlength=size)))


def candidate_pairs(labels_a, labels_b) -> np.ndarray:
    """The pairings ``(a, b)`` that may correspond, shape (n, 2), ordered by a then b.

    Parameters
    ----------
    labels_a, labels_b : ndarray, shape (N,), or FeatureGraph
        Node labels: same-label nodes pair (paper §5.2). Given two feature graphs, a pair
        of nodes of one kind must also agree in every node attribute of the kind within
        its tolerance (:attr:`scanclique.kinds.FeatureKind.attribute_tolerances`), e.g.
        two tree trunks of different diameters never pair.
    """
    if _has_attributes(labels_a, labels_b):
        ia, ib = np.nonzero(_pair_mask(labels_a, labels_b))
    else:
        ia, ib = np.nonzero(_labels(labels_a)[:, None] == _labels(labels_b)[None, :])
    return np.column_stack((ia, ib)).astype(np.int64)


def correspondence_graph(
    graph_a: FeatureGraph, graph_b: FeatureGraph, config: CorrespondenceConfig | None = None
) -> CorrespondenceGraph:
    """Build the correspondence graph of two feature graphs (paper §5.2).

    Parameters
    ----------
    graph_a, graph_b : FeatureGraph
        Built with the same configuration (same layers).
    config : CorrespondenceConfig, optional
        ``max_nodes`` bounds the number of pairings (memory and work grow as its square;
        the count is checked before anything of that size is allocated). Defaults to the
        configuration ``graph_a`` was built with; the graphs' tolerances must match it.

    Returns
    -------
    CorrespondenceGraph

    Raises
    ------
    GraphError
        When the graphs have different layers, or the pairing count exceeds ``max_nodes``.
    ConfigError
        When a graph was built with other tolerances or invariants than ``config``.
    """
    cfg = config or graph_a.config
    if graph_a.invariants.shape[0] != graph_b.invariants.shape[0]:
        raise GraphError(
            f"feature graphs have {graph_a.invariants.shape[0]} and "
            f"{graph_b.invariants.shape[0]} invariant layers; build both with one config"
        )
    for name, g in (("graph_a", graph_a), ("graph_b", graph_b)):
        if g.config.tolerances() != cfg.tolerances() or g.typed_edges != graph_a.typed_edges:
            raise ConfigError(
                f"correspondence_graph: {name} was built with other tolerances or invariants "
                f"({g.config}) than {cfg}; build both feature graphs with the configuration "
                "you match with"
            )
    n = count_pairs(graph_a, graph_b)
    if n > cfg.max_nodes:  # refused before anything of size n is allocated
        raise GraphError(
            f"correspondence graph would have {n} nodes ({graph_a.n_nodes} x {graph_b.n_nodes} "
            f"features; its adjacency {n * n / 2**20:.0f} MiB and about {n * n / 2e9:.1f} G "
            f"invariant tests), more than max_nodes={cfg.max_nodes}; raise the limit or "
            "extract fewer features"
        )
    try:
        pairs = candidate_pairs(graph_a, graph_b)
        adj = np.zeros((n, n), dtype=np.bool_)
    except MemoryError:  # a max_nodes raised beyond what this machine holds
        raise GraphError(
            f"correspondence graph of {n} nodes needs {n * n / 2**30:.1f} GiB for its "
            f"adjacency, more than this machine can allocate (max_nodes={cfg.max_nodes})"
        ) from None
    if n > 1:
        _K.edges(
            np.ascontiguousarray(pairs[:, 0]),
            np.ascontiguousarray(pairs[:, 1]),
            graph_a.invariants,
            graph_b.invariants,
            graph_a.tolerances,
            graph_b.tolerances,
            np.asarray(graph_a.circular | graph_b.circular),
            adj,
        )
    return CorrespondenceGraph(pairs=pairs, adjacency=adj)
