"""Pairwise consistency maximisation (PCM; Mangelson, Dominic, Eustice and Vasudevan,
"Pairwise consistent measurement set maximization for robust multi-robot map merging",
ICRA 2018) as a maximum clique problem, solved with this library's clique engine.

Two loop closures ``a = (i1, j1, Z1)`` and ``b = (i2, j2, Z2)`` are *pairwise consistent*
when the cycle they close with the odometry chain (here: the front end's chained matches)
closes within its uncertainty::

    e_ab = Z1^-1 · C(i1, i2) · Z2 · C(j2, j1)        (identity when both are right)

where ``C(u, v)`` is the chained relative pose of keyframe ``v`` in keyframe ``u``. With
``S_ab`` the covariance of the cycle (the two closures' covariances plus the chain's, which
grows with the path between the ends), ``a`` and ``b`` are consistent when the squared
Mahalanobis distance ``e_ab^T S_ab^-1 e_ab`` is within the chi-square gate (3 dof). The
largest set of mutually consistent closures is the maximum clique of that consistency
graph (Mangelson et al. 2018, eq. 5): wrong closures, from places that look alike, rarely
agree with each other *and* with the right ones.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence

import numpy as np
from scipy.special import chdtri

from ..clique import max_clique
from ..geometry import Pose2
from ..validation import compose_covariance, mahalanobis_sq

__all__ = ["consistency_graph", "pcm_select"]

Chain = Callable[[int, int], tuple[Pose2, np.ndarray]]


def _cycle(
    a: tuple[int, int, Pose2, np.ndarray], b: tuple[int, int, Pose2, np.ndarray], chain: Chain
) -> float:
    i1, j1, Z1, P1 = a
    i2, j2, Z2, P2 = b
    C1, S1 = chain(i1, i2)
    C2, S2 = chain(j2, j1)
    # i1 -> j1 directly (Z1) against i1 -> i2 -> j2 -> j1 (C1 Z2 C2)
    T = C1 @ Z2
    S = compose_covariance(C1, S1, Z2, P2)
    T2 = T @ C2
    S = compose_covariance(T, S, C2, S2)
    return mahalanobis_sq(Z1, P1, T2, S)


def consistency_graph(
    closures: Sequence[tuple[int, int, Pose2, np.ndarray]],
    chain: Chain,
    gate: float = 0.99,
) -> np.ndarray:
    """Boolean ``(n, n)`` adjacency: closures ``a`` and ``b`` joined when their cycle with
    the chain closes within the chi-square ``gate`` (3 dof)."""
    n = len(closures)
    thr = float(chdtri(3, 1.0 - gate))
    A = np.zeros((n, n), dtype=bool)
    for u in range(n):
        for v in range(u + 1, n):
            d2 = _cycle(closures[u], closures[v], chain)
            if math.isfinite(d2) and d2 <= thr:
                A[u, v] = A[v, u] = True
    return A


def pcm_select(
    closures: Sequence[tuple[int, int, Pose2, np.ndarray]],
    chain: Chain,
    gate: float = 0.99,
    time_limit: float = 0.5,
    node_limit: int = 200_000,
    anchors: Sequence[tuple[int, int, Pose2, np.ndarray]] = (),
) -> np.ndarray:
    """Indices of the largest pairwise-consistent subset of ``closures`` (sorted).

    ``anchors``: closures accepted before (incremental PCM: the new closures must be
    consistent with what the graph already holds); a closure inconsistent with any of them
    is dropped first. Of the rest, one closure alone is returned as is; with several, only
    those in the maximum clique of :func:`consistency_graph`, and none when no two agree.
    The clique search spends at most ``node_limit`` search nodes (the budget that decides
    the result, the same on every machine); ``time_limit`` seconds is an outer guard.
    """
    n = len(closures)
    thr = float(chdtri(3, 1.0 - gate))
    alive = np.array(
        [
            all(math.isfinite(d2 := _cycle(c, a, chain)) and d2 <= thr for a in anchors)
            for c in closures
        ],
        dtype=bool,
    ).reshape(n)
    idx = np.flatnonzero(alive)
    if len(idx) <= 1:
        return idx
    A = consistency_graph([closures[k] for k in idx], chain, gate)
    if not A.any():
        return np.zeros(0, dtype=int)
    res = max_clique(A, time_limit=time_limit, node_limit=node_limit)
    return np.sort(idx[np.asarray(res.vertices, dtype=int)])
