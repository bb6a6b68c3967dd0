"""Result records of the clique engine (see :mod:`scanclique.clique`)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["CliqueResult", "AllCliquesResult", "REASONS"]

#: why a search is not proven complete (the ``reason`` field; None when it is)
REASONS = {
    "node_limit": "the node limit stopped the search",
    "time_limit": "the time limit (a wall-clock guard) stopped the search",
    "lower_bound": "no clique reaches lower_bound",
    "clique_limit": "more maximum cliques than the limit",
}


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


@dataclass(frozen=True, slots=True, eq=False)
class CliqueResult:
    """A clique and how it was found.

    Attributes
    ----------
    vertices : (k,) int64 ndarray, read-only
        The clique's vertices, sorted.
    optimal : bool
        True when the search proved that no larger (heavier, when weighted) clique exists;
        False when a limit stopped it first, or when ``lower_bound`` was above the clique
        number (``reason`` says which).
    nodes : int
        Search-tree nodes expanded. Without weights: the nodes of the lean search (see
        :func:`max_clique`), plus those of the full search where it took over; 1 when
        the k-core proves the greedy clique maximum.
    elapsed : float
        Wall-clock seconds, including input conversion (and, on the first call in a
        process, numba's loading or compiling of the kernels).
    weight : float or None
        Total vertex weight of the clique when weights were given, else None.
    reason : str or None
        None when ``optimal``; else ``"node_limit"`` (the node limit stopped the search:
        the same answer on every machine), ``"time_limit"`` (the wall-clock guard stopped
        it: the answer depends on the machine's speed) or ``"lower_bound"`` (the search
        finished, and no clique reaches ``lower_bound``). See :data:`REASONS`.
    """

    vertices: np.ndarray
    optimal: bool
    nodes: int
    elapsed: float
    weight: float | None = None
    reason: str | None = None

    def __post_init__(self) -> None:
        object.__setattr__(self, "vertices", _frozen_vertices(self.vertices))

    @property
    def size(self) -> int:
        """Number of vertices in the clique."""
        return int(self.vertices.shape[0])


#: a mutable twin of :class:`CliqueResult` (the same slots), filled in by :func:`_result`
_Draft = type("_Draft", (), {"__slots__": CliqueResult.__slots__})


def _result(vertices, optimal, nodes, elapsed, weight=None, reason=None) -> CliqueResult:
    """A :class:`CliqueResult` from trusted parts (sorted, read-only int64 vertices),
    without the generated ``__init__``: on graphs of a few dozen vertices building the
    record would otherwise cost as much as the search.

    The fields are stored on a :class:`_Draft` (same slots, plain attribute stores), which
    then becomes a ``CliqueResult`` by ``__class__`` assignment (allowed between classes of
    the same layout): a third of the cost of six ``object.__setattr__`` calls.
    """
    r = _Draft()
    r.vertices = vertices
    r.optimal = optimal
    r.nodes = nodes
    r.elapsed = elapsed
    r.weight = weight
    r.reason = reason
    r.__class__ = CliqueResult
    return r


@dataclass(frozen=True, slots=True, eq=False)
class AllCliquesResult:
    """Every maximum clique of a graph (or as many as the limits allowed).

    Attributes
    ----------
    cliques : tuple of (omega,) int64 ndarrays, read-only
        The maximum cliques, each sorted, the tuple in lexicographic order.
    omega : int
        The clique number (the largest size found when ``optimal`` is False).
    complete : bool
        True when ``cliques`` holds every maximum clique; False when the limit cut the list
        or a limit stopped the search.
    optimal : bool
        True when ``omega`` is proven to be the clique number.
    elapsed : float
        Wall-clock seconds.
    nodes : int
        Search-tree nodes of both phases.
    reason : str or None
        None when ``complete``; else ``"node_limit"``, ``"time_limit"`` or
        ``"clique_limit"`` (more maximum cliques than ``limit``). See :data:`REASONS`.
    """

    cliques: tuple[np.ndarray, ...]
    omega: int
    complete: bool
    optimal: bool
    elapsed: float
    nodes: int = 0
    reason: str | None = None

    def __post_init__(self) -> None:
        cl = [_frozen_vertices(c) for c in self.cliques]
        cl.sort(key=lambda c: c.tolist())
        object.__setattr__(self, "cliques", tuple(cl))
