"""Compiled loops of the signature (numba), loaded on first use by
:mod:`scanclique.places.signature`; the NumPy functions there are the reference these
must agree with (``tests/test_places_signature.py``)."""

from __future__ import annotations

import math

import numpy as np
from numba import njit


@njit(cache=True)
def _soft_add(h, u):
    n = h.shape[0]
    if u < 0.0:
        u = 0.0
    if u > n - 1.0:
        u = n - 1.0
    lo = int(math.floor(u))
    hi = lo + 1 if lo + 1 < n else n - 1
    w = u - lo
    h[lo] += 1.0 - w
    h[hi] += w


@njit(cache=True)
def distance_hist(pts, n_bins, far):
    """Soft histogram of the square-root-scaled distances of all pairs of ``pts``."""
    h = np.zeros(n_bins)
    m = pts.shape[0]
    for i in range(m):
        for j in range(i + 1, m):
            dx = pts[j, 0] - pts[i, 0]
            dy = pts[j, 1] - pts[i, 1]
            d = math.sqrt(dx * dx + dy * dy)
            _soft_add(h, math.sqrt(d / far) * (n_bins - 1))
    return h


@njit(cache=True)
def normal_pair_hists(pts, nrm, n_norm, nd, na, far):
    """The ``normal`` block (soft histogram of the folded angles between normals) and
    the ``pair`` block (joint hard histogram of distance, smaller and larger |cos|)."""
    h_norm = np.zeros(n_norm)
    h_pair = np.zeros(nd * na * na)
    m = pts.shape[0]
    ang = np.empty(m)
    for i in range(m):
        ang[i] = math.atan2(nrm[i, 1], nrm[i, 0])
    half = math.pi / 2
    for i in range(m):
        for j in range(i + 1, m):
            da = abs(ang[i] - ang[j]) % math.pi
            if math.pi - da < da:
                da = math.pi - da
            _soft_add(h_norm, da / half * (n_norm - 1))
            dx = pts[j, 0] - pts[i, 0]
            dy = pts[j, 1] - pts[i, 1]
            length = math.sqrt(dx * dx + dy * dy)
            inv = 1.0 / max(length, 1e-12)
            ux, uy = dx * inv, dy * inv
            c1 = abs(nrm[i, 0] * ux + nrm[i, 1] * uy)
            c2 = abs(nrm[j, 0] * ux + nrm[j, 1] * uy)
            lo, hi = (c1, c2) if c1 <= c2 else (c2, c1)
            bd = math.floor(math.sqrt(min(length, far) / far) * nd)
            bd = min(max(bd, 0.0), nd - 1.0)
            b1 = min(max(math.floor(lo * na), 0.0), na - 1.0)
            b2 = min(max(math.floor(hi * na), 0.0), na - 1.0)
            h_pair[int((bd * na + b1) * na + b2)] += 1.0
    return h_norm, h_pair
