"""Small dense algebra of the matching kernels: angle wrapping, 3x3 solves, 2x2 eigenvectors.

Part of the matcher's kernels (private; gathered in :mod:`scanclique._match_kernels`)."""

# ruff: noqa: E402 (ensure_cache() runs before numba caches anything)
from __future__ import annotations

import math

from . import ensure_cache

ensure_cache()

import numpy as np

from .jit import njit

_njit = njit(cache=True, nogil=True)
#: for the helpers called once per point: inlined into the caller at numba IR level, so
#: that the arrays they take are not reference-counted on every call
_inline = njit(cache=True, nogil=True, inline="always")


@_inline
def wrap(a):  # pragma: no cover - compiled
    """Angle wrapped to ``[-pi, pi)`` (as :func:`scanclique.geometry.wrap_angle`)."""
    w = (a + math.pi) % (2.0 * math.pi) - math.pi
    return w - 2.0 * math.pi if w >= math.pi else w


@_inline
def solve3(H, g, out):  # pragma: no cover - compiled
    """``out = H^-1 g`` for a 3x3 system, Gaussian elimination with partial pivoting.
    Returns False when ``H`` is singular."""
    M = np.empty((3, 4))
    for i in range(3):
        for j in range(3):
            M[i, j] = H[i, j]
        M[i, 3] = g[i]
    for col in range(3):
        piv = col
        for r in range(col + 1, 3):
            if abs(M[r, col]) > abs(M[piv, col]):
                piv = r
        if M[piv, col] == 0.0:
            return False
        if piv != col:
            for j in range(4):
                tmp = M[col, j]
                M[col, j] = M[piv, j]
                M[piv, j] = tmp
        for r in range(col + 1, 3):
            f = M[r, col] / M[col, col]
            for j in range(col, 4):
                M[r, j] -= f * M[col, j]
    for i in range(2, -1, -1):
        s = M[i, 3]
        for j in range(i + 1, 3):
            s -= M[i, j] * out[j]
        out[i] = s / M[i, i]
    return True


@_inline
def smallest_eigvec2(a, b, c):  # pragma: no cover - compiled
    """Unit eigenvector of the smallest eigenvalue of the symmetric ``[[a, b], [b, c]]``."""
    if b == 0.0:
        return (1.0, 0.0) if a <= c else (0.0, 1.0)
    h = 0.5 * (a - c)
    lam = 0.5 * (a + c) - math.sqrt(h * h + b * b)
    u0, u1 = lam - c, b
    v0, v1 = b, lam - a
    nu = math.hypot(u0, u1)
    nv = math.hypot(v0, v1)
    if nu >= nv:
        return (u0 / nu, u1 / nu)
    return (v0 / nv, v1 / nv)
