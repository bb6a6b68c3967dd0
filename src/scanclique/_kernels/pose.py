"""Poses from mapped features (paper §6): closed form, pair consistency, weighted
Gauss-Newton with covariance.

Part of the matcher's kernels (private; gathered in :mod:`scanclique._match_kernels`)."""

# ruff: noqa: E402 (ensure_cache() runs before numba caches anything)
from __future__ import annotations

import math

from . import ensure_cache

ensure_cache()

import numpy as np

from .algebra import smallest_eigvec2, solve3, wrap
from .jit import njit

_njit = njit(cache=True, nogil=True)
#: for the helpers called once per point: inlined into the caller at numba IR level, so
#: that the arrays they take are not reference-counted on every call
_inline = njit(cache=True, nogil=True, inline="always")


@_njit
def closed_form(pairs, npa, npb, Pa, Pb, La, Lb, out):  # pragma: no cover - compiled
    """Quick pose of mapped node pairs ``pairs`` (K, 2): the rotation from Arun et al. on
    the points (two or more, spread over 0.2 m) or else the circular mean of the line
    rotations; then the least-squares translation from points and line offsets (the
    minimum-norm solution when they do not fix it). See
    :func:`scanclique.pose.closed_form_pose`. Writes ``out`` and returns False when no
    rotation can be fixed."""
    K = pairs.shape[0]
    kp = 0
    cax = cay = cbx = cby = 0.0
    minx = miny = math.inf
    maxx = maxy = -math.inf
    for k in range(K):
        a = pairs[k, 0]
        if a < npa:
            b = pairs[k, 1]
            kp += 1
            cax += Pa[a, 0]
            cay += Pa[a, 1]
            cbx += Pb[b, 0]
            cby += Pb[b, 1]
            minx = min(minx, Pb[b, 0])
            maxx = max(maxx, Pb[b, 0])
            miny = min(miny, Pb[b, 1])
            maxy = max(maxy, Pb[b, 1])
    kl = K - kp
    if kp >= 2 and max(maxx - minx, maxy - miny) > 0.2:
        cax /= kp
        cay /= kp
        cbx /= kp
        cby /= kp
        ss = 0.0
        sc = 0.0
        for k in range(K):
            a = pairs[k, 0]
            if a < npa:
                b = pairs[k, 1]
                qax, qay = Pa[a, 0] - cax, Pa[a, 1] - cay
                qbx, qby = Pb[b, 0] - cbx, Pb[b, 1] - cby
                ss += qbx * qay - qby * qax
                sc += qbx * qax + qby * qay
        th = math.atan2(ss, sc)
    elif kl > 0:
        ss = 0.0
        sc = 0.0
        for k in range(K):
            a = pairs[k, 0]
            if a >= npa:
                rot = La[a - npa, 1] - Lb[pairs[k, 1] - npb, 1]
                ss += math.sin(rot)
                sc += math.cos(rot)
        th = math.atan2(ss, sc)
    else:
        return False
    c = math.cos(th)
    s = math.sin(th)
    # normal equations N t = v of the translation rows (points: identity; lines: n^T)
    n00 = n01 = n11 = v0 = v1 = 0.0
    for k in range(K):
        a = pairs[k, 0]
        b = pairs[k, 1]
        if a < npa:
            n00 += 1.0
            n11 += 1.0
            v0 += Pa[a, 0] - (c * Pb[b, 0] - s * Pb[b, 1])
            v1 += Pa[a, 1] - (s * Pb[b, 0] + c * Pb[b, 1])
        else:
            ap = Lb[b - npb, 1] + th
            nx, ny = math.cos(ap), math.sin(ap)
            rhs = La[a - npa, 0] - Lb[b - npb, 0]
            n00 += nx * nx
            n01 += nx * ny
            n11 += ny * ny
            v0 += nx * rhs
            v1 += ny * rhs
    rows = 2 * kp + kl
    # eigen-decomposition of N; singular values of the row matrix are their square roots;
    # keep those above numpy.linalg.lstsq's default cut-off (minimum-norm solution)
    h = 0.5 * (n00 - n11)
    rad = math.sqrt(h * h + n01 * n01)
    l1 = 0.5 * (n00 + n11) + rad
    l2 = 0.5 * (n00 + n11) - rad
    if l1 <= 0.0:
        return False
    e1x, e1y = smallest_eigvec2(-n00, -n01, -n11)  # eigenvector of the largest eigenvalue
    e2x, e2y = -e1y, e1x
    cut = 2.220446049250313e-16 * max(rows, 2)
    tx = (e1x * v0 + e1y * v1) / l1 * e1x
    ty = (e1x * v0 + e1y * v1) / l1 * e1y
    if l2 > 0.0 and math.sqrt(l2) > cut * math.sqrt(l1):
        p2 = (e2x * v0 + e2y * v1) / l2
        tx += p2 * e2x
        ty += p2 * e2y
    out[0] = tx
    out[1] = ty
    out[2] = th
    return True


@_njit
def consistent(
    pairs, npa, npb, Pa, Pb, La, Lb, x, point_tol, angle_tol, offset_tol
):  # pragma: no cover
    """Which mapped pairs agree with the pose ``x``; see
    :func:`scanclique.pose.pair_consistent` (same order as ``pairs``)."""
    c = math.cos(x[2])
    s = math.sin(x[2])
    out = np.empty(pairs.shape[0], np.bool_)
    for k in range(pairs.shape[0]):
        a = pairs[k, 0]
        b = pairs[k, 1]
        if a < npa:
            dx = c * Pb[b, 0] - s * Pb[b, 1] + x[0] - Pa[a, 0]
            dy = s * Pb[b, 0] + c * Pb[b, 1] + x[1] - Pa[a, 1]
            out[k] = math.sqrt(dx * dx + dy * dy) <= point_tol
        else:
            ap = Lb[b - npb, 1] + x[2]
            off = Lb[b - npb, 0] + math.cos(ap) * x[0] + math.sin(ap) * x[1] - La[a - npa, 0]
            out[k] = abs(wrap(ap - La[a - npa, 1])) <= angle_tol and abs(off) <= offset_tol
    return out


@_njit
def closed_form_batch(pairs, indptr, npa, npb, Pa, Pb, La, Lb, poses, ok):  # pragma: no cover
    """:func:`closed_form` of every clique: clique ``i`` is ``pairs[indptr[i]:indptr[i+1]]``."""
    out = np.empty(3)
    for i in range(indptr.shape[0] - 1):
        ok[i] = closed_form(pairs[indptr[i] : indptr[i + 1]], npa, npb, Pa, Pb, La, Lb, out)
        poses[i, 0] = out[0]
        poses[i, 1] = out[1]
        poses[i, 2] = out[2]


@_njit
def _blocks(pairs, npa, npb, Pa, PCa, La, LCa, Pb, PCb, Lb, LCb, x, r, J, Ci):  # pragma: no cover
    """Residual ``r[k]`` (2), Jacobian ``J[k]`` (2x3) and inverse combined covariance
    ``Ci[k]`` (2x2) of each mapped pair at pose ``x``; see
    :func:`scanclique.pose._residuals_jacobian`."""
    c = math.cos(x[2])
    s = math.sin(x[2])
    for k in range(pairs.shape[0]):
        a = pairs[k, 0]
        b = pairs[k, 1]
        for i in range(2):
            for j in range(3):
                J[k, i, j] = 0.0
        if a < npa:
            bx, by = Pb[b, 0], Pb[b, 1]
            r[k, 0] = c * bx - s * by + x[0] - Pa[a, 0]
            r[k, 1] = s * bx + c * by + x[1] - Pa[a, 1]
            J[k, 0, 0] = 1.0
            J[k, 1, 1] = 1.0
            J[k, 0, 2] = -s * bx - c * by
            J[k, 1, 2] = c * bx - s * by
            # C = Ca + R Cb R^T
            p00, p01, p11 = PCb[b, 0, 0], PCb[b, 0, 1], PCb[b, 1, 1]
            q01 = PCb[b, 1, 0]
            r00 = c * c * p00 - c * s * (p01 + q01) + s * s * p11
            r01 = c * s * p00 + c * c * p01 - s * s * q01 - s * c * p11
            r10 = c * s * p00 - s * s * p01 + c * c * q01 - s * c * p11
            r11 = s * s * p00 + s * c * (p01 + q01) + c * c * p11
            c00 = PCa[a, 0, 0] + r00
            c01 = PCa[a, 0, 1] + r01
            c10 = PCa[a, 1, 0] + r10
            c11 = PCa[a, 1, 1] + r11
        else:
            ia = a - npa
            ib = b - npb
            ap = Lb[ib, 1] + x[2]
            nx, ny = math.cos(ap), math.sin(ap)
            lever = -ny * x[0] + nx * x[1]
            r[k, 0] = Lb[ib, 0] + nx * x[0] + ny * x[1] - La[ia, 0]
            r[k, 1] = wrap(ap - La[ia, 1])
            J[k, 0, 0] = nx
            J[k, 0, 1] = ny
            J[k, 0, 2] = lever
            J[k, 1, 2] = 1.0
            # C = Ca + G Cb G^T, G = [[1, lever], [0, 1]]
            b00, b01, b10, b11 = LCb[ib, 0, 0], LCb[ib, 0, 1], LCb[ib, 1, 0], LCb[ib, 1, 1]
            g00 = b00 + lever * (b10 + b01) + lever * lever * b11
            g01 = b01 + lever * b11
            g10 = b10 + lever * b11
            c00 = LCa[ia, 0, 0] + g00
            c01 = LCa[ia, 0, 1] + g01
            c10 = LCa[ia, 1, 0] + g10
            c11 = LCa[ia, 1, 1] + b11
        c00 += 1e-12
        c11 += 1e-12
        det = c00 * c11 - c01 * c10
        Ci[k, 0, 0] = c11 / det
        Ci[k, 0, 1] = -c01 / det
        Ci[k, 1, 0] = -c10 / det
        Ci[k, 1, 1] = c00 / det


@_njit
def _normal_equations(r, J, Ci, H, g):  # pragma: no cover - compiled
    """``H = sum J^T Ci J``, ``g = sum J^T Ci r`` over the blocks."""
    H[:] = 0.0
    g[:] = 0.0
    for k in range(r.shape[0]):
        for i in range(3):
            # (J^T Ci)[i, :] for this block
            t0 = J[k, 0, i] * Ci[k, 0, 0] + J[k, 1, i] * Ci[k, 1, 0]
            t1 = J[k, 0, i] * Ci[k, 0, 1] + J[k, 1, i] * Ci[k, 1, 1]
            g[i] += t0 * r[k, 0] + t1 * r[k, 1]
            for j in range(3):
                H[i, j] += t0 * J[k, 0, j] + t1 * J[k, 1, j]


@_njit
def lsq_pose(
    pairs, npa, npb, Pa, PCa, La, LCa, Pb, PCb, Lb, LCb, x0, iterations, info, maha
):  # pragma: no cover - compiled
    """Gauss–Newton weighted least squares of the pose of mapped pairs (``pairs``, points
    first) from ``x0``; see :func:`scanclique.pose.estimate_pose_lsq`.

    Returns ``(x, ssr)``: the pose and the sum of squared Mahalanobis residuals at it, and
    writes the information matrix ``info`` (3x3) and each pair's Mahalanobis residual
    ``maha`` (K) at the pose."""
    K = pairs.shape[0]
    r = np.empty((K, 2))
    J = np.empty((K, 2, 3))
    Ci = np.empty((K, 2, 2))
    H = np.empty((3, 3))
    g = np.empty(3)
    dx = np.empty(3)
    x = np.empty(3)
    x[:] = x0[:]
    for _ in range(iterations):
        _blocks(pairs, npa, npb, Pa, PCa, La, LCa, Pb, PCb, Lb, LCb, x, r, J, Ci)
        _normal_equations(r, J, Ci, H, g)
        reg = 1e-9 * max(H[0, 0] + H[1, 1] + H[2, 2], 1e-12)
        for i in range(3):
            H[i, i] += reg
        if not solve3(H, g, dx):
            break
        x[0] -= dx[0]
        x[1] -= dx[1]
        x[2] = wrap(x[2] - dx[2])
        if max(abs(dx[0]), abs(dx[1]), abs(dx[2])) < 1e-6:
            break
    _blocks(pairs, npa, npb, Pa, PCa, La, LCa, Pb, PCb, Lb, LCb, x, r, J, Ci)
    _normal_equations(r, J, Ci, info, g)
    ssr = 0.0
    for k in range(K):
        q = r[k, 0] * (Ci[k, 0, 0] * r[k, 0] + Ci[k, 0, 1] * r[k, 1]) + r[k, 1] * (
            Ci[k, 1, 0] * r[k, 0] + Ci[k, 1, 1] * r[k, 1]
        )
        q = max(q, 0.0)
        maha[k] = math.sqrt(q)
        ssr += q
    return x, ssr


@_njit
def covariance(info, scale, cov):  # pragma: no cover - compiled
    """Covariance of ``info / scale`` (3x3 information) into ``cov``; directions with an
    eigenvalue below 1e-9 of the largest get ``inf`` in exactly the entries they touch.
    Returns True when every direction is constrained."""
    w, v = np.linalg.eigh(info / scale)
    top = max(w[2], 1e-300)
    cov[:] = 0.0
    full = True
    for k in range(3):
        if w[k] > 1e-9 * top:
            for i in range(3):
                for j in range(3):
                    cov[i, j] += v[i, k] * v[j, k] / w[k]
        else:
            full = False
    if not full:
        for k in range(3):
            if not w[k] > 1e-9 * top:
                for i in range(3):
                    if abs(v[i, k]) > 1e-9:
                        for j in range(3):
                            if abs(v[j, k]) > 1e-9:
                                cov[i, j] = math.inf
    return full
