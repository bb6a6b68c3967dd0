"""Point-to-line ICP on the bearing-window search.

Part of the matcher's kernels (private; gathered in :mod:`scanclique._match_kernels`)."""

# ruff: noqa: E402 (ensure_cache() runs before numba caches anything)
from __future__ import annotations

import math

from . import ensure_cache

ensure_cache()

import numpy as np

from .algebra import solve3, wrap
from .jit import njit
from .neighbours import nearest_one

_njit = njit(cache=True, nogil=True)
#: for the helpers called once per point: inlined into the caller at numba IR level, so
#: that the arrays they take are not reference-counted on every call
_inline = njit(cache=True, nogil=True, inline="always")

#: Huber scale (m) and weight of the point-to-point term of the ICP (see icp_point_to_line)
ICP_HUBER = 0.05

ICP_POINT_WEIGHT = 0.05

#: the ICP has converged when a step moves less than this (metres, radians), once the
#: correspondence distance has shrunk to its minimum
ICP_STEP_T = 5e-4

ICP_STEP_R = 5e-5


@_njit
def icp(ix, ref, normals, pts, x0, iterations, max_corr, min_corr, out):  # pragma: no cover
    """Point-to-line ICP of ``pts`` (B) onto ``ref`` (A, bearings indexed by ``ix``, with
    ``normals``) from ``x0``; see :func:`scanclique.refine.icp_point_to_line`.

    Writes the pose to ``out`` and returns ``(fitness, rmse, iterations run)``."""
    x = np.empty(3)
    x[:] = x0[:]
    n = pts.shape[0]
    fitness = 0.0
    rmse = math.inf
    it = 0
    rng = np.empty(6, np.int64)
    H = np.empty((3, 3))
    g = np.empty(3)
    dx = np.empty(3)
    J = np.empty(3)
    eps = ICP_POINT_WEIGHT
    for it in range(1, iterations + 1):
        dmax = max(min_corr, max_corr * 0.7 ** (it - 1))
        c = math.cos(x[2])
        s = math.sin(x[2])
        H[:] = 0.0
        g[:] = 0.0
        ok = 0
        ssr = 0.0
        for i in range(n):
            rpx = c * pts[i, 0] - s * pts[i, 1]
            rpy = s * pts[i, 0] + c * pts[i, 1]
            px = rpx + x[0]
            py = rpy + x[1]
            j, _ = nearest_one(ix, ref, px, py, dmax, rng)
            if j < 0:
                continue
            ok += 1
            ddx = px - ref[j, 0]
            ddy = py - ref[j, 1]
            nx = normals[j, 0]
            ny = normals[j, 1]
            dpx = -rpy
            dpy = rpx
            r = nx * ddx + ny * ddy
            ssr += r * r
            J[0] = nx
            J[1] = ny
            J[2] = nx * dpx + ny * dpy
            ar = abs(r)
            w = 1.0 if ar < ICP_HUBER else ICP_HUBER / max(ar, 1e-12)
            for a in range(3):
                g[a] += w * J[a] * r
                for b in range(3):
                    H[a, b] += w * J[a] * J[b]
            # weak point-to-point term: Jx = (1, 0, dpx), Jy = (0, 1, dpy)
            H[0, 0] += eps
            H[1, 1] += eps
            H[0, 2] += eps * dpx
            H[2, 0] += eps * dpx
            H[1, 2] += eps * dpy
            H[2, 1] += eps * dpy
            H[2, 2] += eps * (dpx * dpx + dpy * dpy)
            g[0] += eps * ddx
            g[1] += eps * ddy
            g[2] += eps * (dpx * ddx + dpy * ddy)
        if ok < 3:
            break
        for a in range(3):
            H[a, a] += 1e-9
        if not solve3(H, g, dx):
            break
        x[0] -= dx[0]
        x[1] -= dx[1]
        x[2] = wrap(x[2] - dx[2])
        fitness = ok / n
        rmse = math.sqrt(ssr / ok)
        if (
            max(abs(dx[0]), abs(dx[1])) < ICP_STEP_T
            and abs(dx[2]) < ICP_STEP_R
            and dmax <= min_corr
        ):
            break
    out[:] = x[:]
    return fitness, rmse, it
