"""Compiled kernel of the mapper (numba; imported on first use only).

``most_certain_paths`` is Dijkstra's label-setting search over the keyframe graph (chain
steps, local matches, accepted loop closures) from one keyframe, where a path's cost is
the translation variance the front end's model gives it: its edges' summed translation
variances plus their summed heading variance acting on a third of the square of the
path's length (the lever arm of :func:`scanclique.mapping.pipeline._chain_sigma_xy`).
That cost is not a sum over edges, but it never decreases as a path grows, so the search
is well defined; the path it settles on is the most certain one by that cost, up to the
greedy choice at each node.
"""

# ruff: noqa: E402 (ensure_cache() runs before numba caches anything)
from __future__ import annotations

import heapq

from .._kernels import ensure_cache

ensure_cache()

import numpy as np

from .._kernels.jit import njit


@njit(cache=True, nogil=True)
def most_certain_paths(n, a, b, var_xy, var_theta, length, m, source):  # pragma: no cover
    """Summed ``(var_xy m², var_theta rad², length m)`` along the most certain path from
    node ``source`` to each of the nodes ``0 .. n - 1`` (module docstring), over the
    first ``m`` edges ``a[e] - b[e]`` (undirected; both ends below ``n``) with those
    quantities each. Returns ``(n, 3)``; ``inf`` for a node no path reaches."""
    start = np.zeros(n + 1, np.int64)
    for e in range(m):
        start[a[e] + 1] += 1
        start[b[e] + 1] += 1
    for k in range(n):
        start[k + 1] += start[k]
    fill = start[:-1].copy()
    incident = np.empty(2 * m, np.int64)
    for e in range(m):
        incident[fill[a[e]]] = e
        fill[a[e]] += 1
        incident[fill[b[e]]] = e
        fill[b[e]] += 1
    out = np.full((n, 3), np.inf)
    cost = np.full(n, np.inf)
    settled = np.zeros(n, np.bool_)
    out[source, :] = 0.0
    cost[source] = 0.0
    heap = [(0.0, source)]
    while len(heap) > 0:
        _, u = heapq.heappop(heap)
        if settled[u]:
            continue
        settled[u] = True
        for q in range(start[u], start[u + 1]):
            e = incident[q]
            v = b[e] if a[e] == u else a[e]
            if settled[v]:
                continue
            vxy = out[u, 0] + var_xy[e]
            vth = out[u, 1] + var_theta[e]
            ln = out[u, 2] + length[e]
            c = vxy + vth * ln * ln / 3.0
            if c < cost[v]:
                cost[v] = c
                out[v, 0] = vxy
                out[v, 1] = vth
                out[v, 2] = ln
                heapq.heappush(heap, (c, v))
    return out
