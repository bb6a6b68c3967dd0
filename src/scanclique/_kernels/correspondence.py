"""Compiled kernel of the correspondence graph (paper §5.2; see
:mod:`scanclique.correspondence`)."""

import math

from .jit import njit


@njit(cache=True, nogil=True)
def edges(ia, ib, inv_a, inv_b, tol_a, tol_b, circular, out):  # pragma: no cover - compiled
    """Fill ``out`` (n, n) bool: pairing u = (ia[u], ib[u]) is joined to v when
    ia[u] != ia[v], ib[u] != ib[v] and every invariant layer k that applies to both node
    pairs agrees, ``|inv_a[k, a1, a2] - inv_b[k, b1, b2]| <= max(tol_a, tol_b)`` (modulo
    2 pi where ``circular[k]``)."""
    n = ia.size
    K = inv_a.shape[0]
    two_pi = 2.0 * math.pi
    for u in range(n):
        a1 = ia[u]
        b1 = ib[u]
        for v in range(u + 1, n):
            a2 = ia[v]
            b2 = ib[v]
            if a1 == a2 or b1 == b2:
                continue
            ok = True
            for k in range(K):
                x = inv_a[k, a1, a2]
                y = inv_b[k, b1, b2]
                if math.isnan(x) or math.isnan(y):
                    continue
                d = abs(x - y)
                if circular[k]:
                    d = d % two_pi
                    if d > math.pi:
                        d = two_pi - d
                t = max(tol_a[k, a1, a2], tol_b[k, b1, b2])
                if d > t:
                    ok = False
                    break
            if ok:
                out[u, v] = True
                out[v, u] = True
