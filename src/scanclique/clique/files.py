"""Solving a DIMACS file: the library function behind ``scanclique clique``."""

from __future__ import annotations

import os
import time

import numpy as np

from ..errors import GraphError
from ._load import kernels as _kernels
from .graphs import bitsets_from_adjacency, check_vertex_count
from .search import _REASON, _node_limit, _time_limit

__all__ = ["solve_file"]


def solve_file(  # noqa: A002 (CLI flag name)
    path,
    *,
    all=False,  # noqa: A002
    time_limit=None,
    node_limit=None,
    weights=None,
    max_vertices=None,
) -> dict:
    """Solve a DIMACS file and return a JSON-ready summary (used by ``scanclique clique``).

    Parameters
    ----------
    path : str or path-like
        A DIMACS ``.clq`` file.
    all : bool
        Also enumerate every maximum clique (up to 1000).
    time_limit : float, optional
        Seconds, a wall-clock guard (see :func:`~scanclique.clique.max_clique`).
    node_limit : int, optional
        Search nodes, the budget that decides results.
    weights : bool, optional
        The file's vertex weights (``n v w`` lines): None (default) uses them when the
        file has any, solving the maximum-weight clique; False ignores them (maximum
        cardinality); True requires them (a file without ``n`` lines is refused).
        Enumerating (``all``) is by cardinality: a weighted file with ``all`` is refused
        unless ``weights=False``.
    max_vertices : int, optional
        Bound on the file's vertex count (see
        :func:`~scanclique.clique.check_vertex_count`).

    Returns
    -------
    dict
        ``file, n, m``; ``size`` (vertices of the clique found) and ``omega`` (the clique
        number: ``size`` when the search finished, else None); ``optimal``, ``reason``
        (None, ``"node_limit"`` or ``"time_limit"``), ``clique`` (1-based vertex numbers,
        as in the file), ``weighted`` (whether weights were used) and ``weight`` (the
        clique's total weight, None when unweighted), ``nodes``, ``elapsed`` (seconds of
        the search) and ``load`` (seconds to load the compiled kernels, paid once per
        process); with ``all``: ``cliques`` (1-based, lexicographic) and ``complete``.

    Raises
    ------
    GraphError
        The weight rules above, or a vertex count above the bound.
    ParseError
        A malformed file.
    """
    from ..io.dimacs import read_dimacs

    path_s = os.fspath(path)
    g = read_dimacs(path)
    check_vertex_count(g.n, source=path_s, max_vertices=max_vertices)
    tl = _time_limit(time_limit)
    nl = _node_limit(node_limit)
    if weights not in (None, True, False):
        raise GraphError(f"weights must be None, True or False, got {weights!r}")
    has_w = g.weights is not None
    if weights is True and not has_w:
        raise GraphError(f"{path_s}: weights=True, but the file has no 'n v w' weight lines")
    use_w = has_w and weights is not False
    if use_w and all:
        raise GraphError(
            f"{path_s}: the file has vertex weights ('n v w' lines); enumerating every "
            f"maximum clique is by cardinality: pass weights=False (CLI: ignore the "
            f"weights) or drop all"
        )
    A = bitsets_from_adjacency(g.adjacency())
    K = _kernels()
    t = time.perf_counter()
    two = bitsets_from_adjacency(np.zeros((2, 2), bool))
    if use_w:
        K.solve_weighted(two, 2, np.ones(2), 0.0, 0)
    else:
        K.solve(two, 2, 0, 0, 0, 0.0, 0, K.OPT_DEFAULT)
    load = time.perf_counter() - t
    t0 = time.perf_counter()
    found: list = []
    status_all = 0
    wsum = None
    if g.n == 0:
        best, nodes, status = np.empty(0, np.int64), 0, 0
        wsum = 0.0 if use_w else None
    elif use_w:
        w = np.asarray(g.weights, dtype=np.float64)
        best, _, nodes, status = K.solve_weighted(A, g.n, w, tl, nl)
        wsum = float(w[best].sum())
    else:  # with `all`, one search: the clique number, then every clique of that size
        mode = int(K.Mode.ALL_MAXIMUM if all else K.Mode.MAXIMUM)
        best, nodes, status, found, status_all = K.solve(
            A, g.n, 0, mode, 1000, tl, nl, K.OPT_DEFAULT
        )
    elapsed = time.perf_counter() - t0
    optimal = status == 0
    out = {
        "file": path_s,
        "n": g.n,
        "m": g.m,
        "size": int(best.shape[0]),
        "omega": int(best.shape[0]) if optimal and not use_w else None,
        "optimal": optimal,
        "reason": _REASON[status],
        "clique": (best + 1).tolist(),
        "weighted": use_w,
        "weight": wsum,
        "nodes": int(nodes),
        "elapsed": elapsed,
        "load": load,
    }
    if all:
        out["cliques"] = sorted((c + 1).tolist() for c in found) or [out["clique"]] * (g.n > 0)
        out["complete"] = optimal and status_all == 0
    return out
