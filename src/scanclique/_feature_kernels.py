"""Compiled kernels of feature extraction and feature graphs (private).

:func:`extract` is the whole of :func:`scanclique.features.extract_features` in one call
(clustering, chains, recursive split, total-least-squares fits, collinear merging, foreground
edges and points, the crowd filter, corners), and :func:`graph_layers` the arrays of
:func:`scanclique.graph.feature_graph`. Both follow, step by step and in the same order, the
readable NumPy implementations kept as references in those modules
(``features._extract_features_reference``, ``graph._feature_graph_reference``); the tests
require the two to agree to round-off on simulated scenes and real logs. A scan is a few
hundred beams, so the cost of the NumPy versions was almost all per-call overhead (a few
microseconds per small array operation, thousands of them per scan); here it is one call.

Every kernel is ``njit(cache=True)`` (:mod:`scanclique._kernels.jit`): the first call in a
fresh environment compiles (about half a minute), later processes load the cache from
``__pycache__`` (a second).

Line records live in parallel arrays indexed by a *slot*; the scan points behind a line are
a sorted run of beam indices in one growing pool (``pool[start[s] : start[s] + count[s]]``),
so a merged line is the sorted merge of two runs. Adjacent pieces of a split share their
split point, so a beam may appear twice in one run, as it does in the reference.
"""

from __future__ import annotations

import math
import typing
from typing import NamedTuple

import numpy as np

from ._kernels.jit import njit

#: point labels (the same values as :mod:`scanclique.features`, which is the public home)
_FOREGROUND_POINT = 0
_EDGE_CW = 1
_EDGE_CCW = 2
_CORNER = 3
_LINE = 8  #: node label of lines in feature graphs (:data:`scanclique.graph.LINE`)


class Params(NamedTuple):
    """The scalar settings of :func:`extract` (a ``ClusterConfig`` and a ``FeatureConfig``
    flattened, with fixed types so that numba compiles one specialisation)."""

    c1: float
    c2: float
    max_gap_beams: int
    foreground_edges: bool
    foreground_points: bool
    lines: bool
    corners: bool
    point_max_extent: float
    split_distance: float
    split_ratio: float
    line_min_points: int
    line_min_length: float
    line_max_gap: float
    line_gap_ratio: float
    line_max_rms: float
    merge_angle: float
    merge_distance: float
    corner_min_angle: float
    corner_reach: float
    range_sigma: float
    min_edge_jump: float
    min_cluster_beams: int
    crowd_radius: float
    reach_edges: bool


def params(cfg, ccfg) -> Params:
    """:class:`Params` from a ``FeatureConfig`` and a ``ClusterConfig``: each field is
    the config field of the same name (the cluster section's first), cast to the
    field's type, so the two cannot drift apart (a field with no config field of its
    name raises ``AttributeError`` at the first extraction)."""
    cluster = set(type(ccfg).__dataclass_fields__)
    return Params(
        *(
            t(getattr(ccfg if name in cluster else cfg, name))
            for name, t in typing.get_type_hints(Params).items()
        )
    )


# --------------------------------------------------------------------------------------
# small helpers
# --------------------------------------------------------------------------------------
@njit(cache=True)
def _max(a, b):
    """Python's ``max(a, b)``: ``a`` unless ``b > a``."""
    return b if b > a else a


@njit(cache=True)
def _min(a, b):
    """Python's ``min(a, b)``: ``a`` unless ``b < a``."""
    return b if b < a else a


@njit(cache=True)
def _wrap(x):
    """``(x + pi) % (2 pi) - pi``: an angle difference in [-pi, pi)."""
    return (x + math.pi) % (2.0 * math.pi) - math.pi


@njit(cache=True)
def _grown(a, need):
    """``a`` itself, or a copy at least ``need`` long (doubling) with ``a`` at its start."""
    if need <= a.size:
        return a
    b = np.empty(max(need, 2 * a.size), a.dtype)
    b[: a.size] = a
    return b


# --------------------------------------------------------------------------------------
# lines: total least squares (features.fit_line_tls) and recursive split
# --------------------------------------------------------------------------------------
@njit(cache=True)
def _fit_line(xy, beams, lo, hi, sigma, out, o):
    """Total-least-squares fit to the points ``xy[beams[lo:hi]]`` (in that order).

    Writes ``(rho, alpha, rms, cov00, cov01, cov11, e0x, e0y, e1x, e1y)`` to ``out[o]``.
    The normal is the minor axis of the scatter matrix ``[[sxx, sxy], [sxy, syy]]``; its
    major axis lies at ``phi = atan2(2 sxy, sxx - syy) / 2`` (the closed form of the 2x2
    eigenproblem, which ``fit_line_tls`` solves with ``eigh``).
    """
    n = hi - lo
    sx = 0.0
    sy = 0.0
    for k in range(lo, hi):
        sx += xy[beams[k], 0]
        sy += xy[beams[k], 1]
    cx = sx / n
    cy = sy / n
    sxx = 0.0
    sxy = 0.0
    syy = 0.0
    for k in range(lo, hi):
        qx = xy[beams[k], 0] - cx
        qy = xy[beams[k], 1] - cy
        sxx += qx * qx
        sxy += qx * qy
        syy += qy * qy
    phi = 0.5 * math.atan2(2.0 * sxy, sxx - syy)
    nx = -math.sin(phi)
    ny = math.cos(phi)
    rho = nx * cx + ny * cy
    if rho < 0:
        nx, ny, rho = -nx, -ny, -rho
    alpha = math.atan2(ny, nx)
    tx, ty = -ny, nx
    suu = 0.0
    srr = 0.0
    u_first = 0.0
    u_last = 0.0
    for k in range(lo, hi):
        qx = xy[beams[k], 0] - cx
        qy = xy[beams[k], 1] - cy
        u = qx * tx + qy * ty
        r = qx * nx + qy * ny
        suu += u * u
        srr += r * r
        if k == lo:
            u_first = u
        u_last = u
    s2 = sigma * sigma
    var_alpha = s2 / _max(suu, 1e-12)
    m = cx * tx + cy * ty
    out[o, 0] = rho
    out[o, 1] = alpha
    out[o, 2] = math.sqrt(srr / n)
    out[o, 3] = s2 / n + m * m * var_alpha
    out[o, 4] = m * var_alpha
    out[o, 5] = var_alpha
    fx = rho * nx
    fy = rho * ny
    out[o, 6] = fx + (m + u_first) * tx
    out[o, 7] = fy + (m + u_first) * ty
    out[o, 8] = fx + (m + u_last) * tx
    out[o, 9] = fy + (m + u_last) * ty


@njit(cache=True)
def _split(xy, ranges, beams, lo, hi, split_distance, split_ratio, pieces):
    """Recursive split (``features.split_and_merge``) of the chain ``beams[lo:hi]``.

    Writes the pieces' ``[start, stop)`` (absolute positions in ``beams``) to ``pieces``
    in order and returns their number.
    """
    stack = np.empty((hi - lo + 1, 2), np.int64)
    top = 0
    stack[0, 0] = lo
    stack[0, 1] = hi
    top = 1
    n_out = 0
    while top > 0:
        top -= 1
        a = stack[top, 0]
        b = stack[top, 1]
        if b - a < 3:
            pieces[n_out, 0] = a
            pieces[n_out, 1] = b
            n_out += 1
            continue
        p0x = xy[beams[a], 0]
        p0y = xy[beams[a], 1]
        dx = xy[beams[b - 1], 0] - p0x
        dy = xy[beams[b - 1], 1] - p0y
        norm = math.hypot(dx, dy)
        k = 0
        best = -1.0
        for i in range(b - a):
            sx = xy[beams[a + i], 0] - p0x
            sy = xy[beams[a + i], 1] - p0y
            if norm < 1e-9:
                dist = math.hypot(sx, sy)
            else:
                dist = abs(sx * dy - sy * dx) / norm
            if dist > best:  # the first maximum, as argmax
                best = dist
                k = i
        if best > split_distance + split_ratio * ranges[beams[a + k]] and 0 < k < b - a - 1:
            # the split point belongs to both halves; push right first so left pops first
            stack[top, 0] = a + k
            stack[top, 1] = b
            stack[top + 1, 0] = a
            stack[top + 1, 1] = a + k + 1
            top += 2
        else:
            pieces[n_out, 0] = a
            pieces[n_out, 1] = b
            n_out += 1
    return n_out


# --------------------------------------------------------------------------------------
# point features
# --------------------------------------------------------------------------------------
@njit(cache=True)
def _point_cov(r, a, sigma, beam_width, cov, o):
    """``features._point_cov`` into ``cov[o]``: range noise along the beam, half a beam
    width of bearing across it."""
    ux = math.cos(a)
    uy = math.sin(a)
    vx, vy = -uy, ux
    s_across = _max(r * beam_width / 2.0, sigma)
    s2 = sigma * sigma
    a2 = s_across * s_across
    cov[o, 0, 0] = s2 * (ux * ux) + a2 * (vx * vx)
    cov[o, 0, 1] = s2 * (ux * uy) + a2 * (vx * vy)
    cov[o, 1, 0] = s2 * (uy * ux) + a2 * (vy * vx)
    cov[o, 1, 1] = s2 * (uy * uy) + a2 * (vy * vy)


@njit(cache=True)
def _continues(xy, start, stop, at_end, fx, fy):
    """``features._continues``: does the far point ``(fx, fy)`` continue the cluster's
    surface near one end?"""
    k = min(5, stop - start)
    if k < 2:
        return False
    s0 = stop - k if at_end else start
    s1 = stop - 1 if at_end else start + k - 1
    dx = xy[s1, 0] - xy[s0, 0]
    dy = xy[s1, 1] - xy[s0, 1]
    norm = math.hypot(dx, dy)
    if norm < 1e-6:
        return False
    e = s1 if at_end else s0
    wx = fx - xy[e, 0]
    wy = fy - xy[e, 1]
    dist = math.hypot(wx, wy)
    perp = abs(wx * dy - wy * dx) / norm
    return perp < 0.05 + 0.1 * dist


@njit(cache=True)
def _neighbour_range(beam, valid, ranges, no_return):
    """Range beyond a cluster end (``beam`` already stepped past it): the beam's range if
    valid, inf for a no-return, NaN when unknown (scan border, other invalid returns)."""
    if beam < 0 or beam >= valid.size:
        return np.nan
    if valid[beam]:
        return ranges[beam]
    if no_return[beam]:
        return np.inf
    return np.nan


@njit(cache=True)
def _leaves_reach(r_end, far, range_max, c1, c2):
    """``features.leaves_reach``: is a cluster end beside a no-return (``far`` inf) within
    one clustering step (``c1 + c2 * r_end``) of the sensor's reach?"""
    return math.isinf(far) and r_end + c1 + c2 * r_end >= range_max


# --------------------------------------------------------------------------------------
# the whole extraction
# --------------------------------------------------------------------------------------
@njit(cache=True)
def extract(ranges, angles, valid, range_max, p):
    """Features of one scan; see ``features.extract_features``.

    Returns the arrays of a ``Features`` record in field order: points_xy, points_label,
    points_cov, points_beam, lines_rho_alpha, lines_ends, lines_cov, lines_beams,
    lines_n_points, clusters.
    """
    n = ranges.size
    xy = np.empty((n, 2))
    idx_buf = np.empty(n, np.int64)
    nv = 0
    for i in range(n):
        if valid[i]:
            xy[i, 0] = ranges[i] * math.cos(angles[i])
            xy[i, 1] = ranges[i] * math.sin(angles[i])
            idx_buf[nv] = i
            nv += 1
        else:
            xy[i, 0] = np.nan
            xy[i, 1] = np.nan
    idx = idx_buf[:nv]  # the valid beams, in order

    # -- stage 2: clusters (features.cluster_scan) --------------------------------------
    clusters = np.empty((nv, 2), np.int64)
    nc = 0
    if nv > 0:
        clusters[0, 0] = idx[0]
        for m in range(1, nv):
            r0 = ranges[idx[m - 1]]
            r1 = ranges[idx[m]]
            join = abs(r1 - r0) < p.c1 + p.c2 * min(r0, r1) and (
                idx[m] - idx[m - 1] <= 1 + p.max_gap_beams
            )
            if not join:
                clusters[nc, 1] = idx[m - 1] + 1
                nc += 1
                clusters[nc, 0] = idx[m]
        clusters[nc, 1] = idx[nv - 1] + 1
        nc += 1
    clusters = clusters[:nc].copy()

    beam_width = np.median(np.diff(angles)) if n > 1 else 0.0
    no_return = np.empty(n, np.bool_)
    for i in range(n):
        # at or beyond range_max, +inf included (REP 117's nothing within reach); never NaN
        no_return[i] = (not valid[i]) and (not np.isnan(ranges[i])) and ranges[i] >= range_max

    # -- lines, fitted on chains looser than the clusters ---------------------------------
    # fit[s] = (rho, alpha, rms, cov00, cov01, cov11, e0x, e0y, e1x, e1y) of line slot s
    cap = nv + 1
    fit = np.empty((cap, 10))
    lstart = np.empty(cap, np.int64)
    lcount = np.empty(cap, np.int64)
    pool = np.empty(2 * nv + 2, np.int64)
    n_pool = 0
    n_slots = 0
    interior = np.zeros(n, np.bool_)  # beams strictly inside a fitted piece
    pieces = np.empty((nv + 1, 2), np.int64)
    if (p.lines or p.corners) and nv > 0:
        min_pts = max(2, p.line_min_points)
        c0 = 0
        for m in range(1, nv + 1):
            if m < nv:
                b0 = idx[m - 1]
                b1 = idx[m]
                gap = math.hypot(xy[b1, 0] - xy[b0, 0], xy[b1, 1] - xy[b0, 1])
                lim = p.line_max_gap + p.line_gap_ratio * min(ranges[b0], ranges[b1])
                if gap < lim:
                    continue
            # the chain idx[c0:m] is complete
            lo, hi = c0, m
            c0 = m
            if hi - lo < p.line_min_points:
                continue
            n_pieces = _split(xy, ranges, idx, lo, hi, p.split_distance, p.split_ratio, pieces)
            for q in range(n_pieces):
                a = pieces[q, 0]
                b = pieces[q, 1]
                # too few points, or a chord too short, for the line tests: skip the fit
                if b - a < min_pts:
                    continue
                chord = math.hypot(
                    xy[idx[b - 1], 0] - xy[idx[a], 0], xy[idx[b - 1], 1] - xy[idx[a], 1]
                )
                if chord < 0.9 * p.line_min_length:
                    continue
                _fit_line(xy, idx, a, b, p.range_sigma, fit, n_slots)
                length = math.sqrt(
                    (fit[n_slots, 8] - fit[n_slots, 6]) ** 2
                    + (fit[n_slots, 9] - fit[n_slots, 7]) ** 2
                )
                if (
                    b - a >= p.line_min_points
                    and length >= p.line_min_length
                    and fit[n_slots, 2] <= p.line_max_rms
                ):
                    pool = _grown(pool, n_pool + b - a)
                    pool[n_pool : n_pool + b - a] = idx[a:b]
                    lstart[n_slots] = n_pool
                    lcount[n_slots] = b - a
                    n_pool += b - a
                    n_slots += 1
                    for k in range(a + 1, b - 1):
                        interior[idx[k]] = True

    # -- merge collinear lines (features._merge_collinear) ----------------------------------
    # ``order`` is the reference's list of lines, as slots; a merge overwrites entry i with a
    # new slot and deletes entry j, then the scan restarts from the first pair
    order = np.arange(n_slots)
    n_lines = n_slots
    scratch = np.empty(1, np.int64)
    merged = True
    while merged and n_lines > 1:
        merged = False
        for i in range(n_lines):
            for j in range(i + 1, n_lines):
                sa = order[i]
                sb = order[j]
                dalpha = abs(_wrap(fit[sa, 1] - fit[sb, 1]))
                if dalpha > p.merge_angle:
                    continue
                # offsets of each segment's ends from the other line
                nax = math.cos(fit[sa, 1])
                nay = math.sin(fit[sa, 1])
                nbx = math.cos(fit[sb, 1])
                nby = math.sin(fit[sb, 1])
                da = _max(
                    abs(fit[sb, 6] * nax + fit[sb, 7] * nay - fit[sa, 0]),
                    abs(fit[sb, 8] * nax + fit[sb, 9] * nay - fit[sa, 0]),
                )
                db = _max(
                    abs(fit[sa, 6] * nbx + fit[sa, 7] * nby - fit[sb, 0]),
                    abs(fit[sa, 8] * nbx + fit[sa, 9] * nby - fit[sb, 0]),
                )
                if _max(da, db) > p.merge_distance:
                    continue
                # stable merge of the two sorted runs of beams (a's first on ties)
                na_ = lcount[sa]
                nb_ = lcount[sb]
                if scratch.size < na_ + nb_:
                    scratch = np.empty(2 * (na_ + nb_), np.int64)
                ia = lstart[sa]
                ib = lstart[sb]
                ea = ia + na_
                eb = ib + nb_
                k = 0
                while ia < ea or ib < eb:
                    if ib >= eb or (ia < ea and pool[ia] <= pool[ib]):
                        scratch[k] = pool[ia]
                        ia += 1
                    else:
                        scratch[k] = pool[ib]
                        ib += 1
                    k += 1
                if n_slots >= fit.shape[0]:
                    fit2 = np.empty((2 * fit.shape[0], 10))
                    fit2[: fit.shape[0]] = fit
                    fit = fit2
                    lstart = _grown(lstart, 2 * lstart.size)
                    lcount = _grown(lcount, 2 * lcount.size)
                _fit_line(xy, scratch, 0, k, p.range_sigma, fit, n_slots)
                if fit[n_slots, 2] > p.line_max_rms:
                    continue
                pool = _grown(pool, n_pool + k)
                pool[n_pool : n_pool + k] = scratch[:k]
                lstart[n_slots] = n_pool
                lcount[n_slots] = k
                n_pool += k
                order[i] = n_slots
                n_slots += 1
                for t in range(j, n_lines - 1):
                    order[t] = order[t + 1]
                n_lines -= 1
                merged = True
                break
            if merged:
                break

    # -- foreground edges and points ------------------------------------------------------
    cap_p = 2 * nc + 1
    pxy = np.empty((cap_p, 2))
    plabel = np.empty(cap_p, np.int8)
    pcov = np.empty((cap_p, 2, 2))
    pbeam = np.empty(cap_p, np.int64)
    npt = 0
    for c in range(nc):
        start = clusters[c, 0]
        stop = clusters[c, 1]
        n_in = 0
        for i in range(start, stop):
            if valid[i]:
                n_in += 1
        if n_in < p.min_cluster_beams:
            continue
        first = start
        last = stop - 1
        r_first = ranges[first]
        r_last = ranges[last]
        left = _neighbour_range(first - 1, valid, ranges, no_return)  # clockwise
        right = _neighbour_range(last + 1, valid, ranges, no_return)  # counter-clockwise
        near_cw = (not np.isnan(left)) and left - r_first >= p.min_edge_jump
        near_ccw = (not np.isnan(right)) and right - r_last >= p.min_edge_jump
        # grazing-incidence walls: the far neighbour continues the surface, or the end lies
        # inside a fitted line
        near_cw = near_cw and not interior[first]
        near_ccw = near_ccw and not interior[last]
        if near_cw and math.isfinite(left):
            if _continues(xy, first, stop, False, xy[first - 1, 0], xy[first - 1, 1]):
                near_cw = False
        if near_ccw and math.isfinite(right):
            if _continues(xy, first, stop, True, xy[last + 1, 0], xy[last + 1, 1]):
                near_ccw = False
        ex = xy[last, 0] - xy[first, 0]
        ey = xy[last, 1] - xy[first, 1]
        extent = math.sqrt(ex * ex + ey * ey)
        if near_cw and near_ccw and extent <= p.point_max_extent:
            if p.foreground_points:
                sx = 0.0
                sy = 0.0
                cnt = 0
                for i in range(first, last + 1):
                    if not np.isnan(xy[i, 0]):
                        sx += xy[i, 0]
                        sy += xy[i, 1]
                        cnt += 1
                cx = sx / cnt
                cy = sy / cnt
                pxy[npt, 0] = cx
                pxy[npt, 1] = cy
                plabel[npt] = _FOREGROUND_POINT
                pbeam[npt] = (first + last) // 2
                _point_cov(
                    math.hypot(cx, cy), math.atan2(cy, cx), p.range_sigma, beam_width, pcov, npt
                )
                e2 = (extent / 4) ** 2
                pcov[npt, 0, 0] += e2
                pcov[npt, 1, 1] += e2
                npt += 1
            continue
        if p.foreground_edges and stop - start >= 2:
            # an end where the surface may leave the sensor's reach, unless asked for
            if not p.reach_edges:
                if near_cw and _leaves_reach(r_first, left, range_max, p.c1, p.c2):
                    near_cw = False
                if near_ccw and _leaves_reach(r_last, right, range_max, p.c1, p.c2):
                    near_ccw = False
            if near_cw:
                pxy[npt, 0] = xy[first, 0]
                pxy[npt, 1] = xy[first, 1]
                plabel[npt] = _EDGE_CW
                pbeam[npt] = first
                _point_cov(r_first, angles[first], p.range_sigma, beam_width, pcov, npt)
                npt += 1
            if near_ccw:
                pxy[npt, 0] = xy[last, 0]
                pxy[npt, 1] = xy[last, 1]
                plabel[npt] = _EDGE_CCW
                pbeam[npt] = last
                _point_cov(r_last, angles[last], p.range_sigma, beam_width, pcov, npt)
                npt += 1

    # crowd filter: drop foreground points with another foreground point within the radius
    keep = np.ones(npt, np.bool_)
    if p.crowd_radius > 0 and npt > 0:
        n_fp = 0
        for i in range(npt):
            if plabel[i] == _FOREGROUND_POINT:
                n_fp += 1
        if n_fp > 1:
            for i in range(npt):
                if plabel[i] != _FOREGROUND_POINT:
                    continue
                nearest = np.inf
                for j in range(npt):
                    if j != i and plabel[j] == _FOREGROUND_POINT:
                        dx = pxy[j, 0] - pxy[i, 0]
                        dy = pxy[j, 1] - pxy[i, 1]
                        d = math.sqrt(dx * dx + dy * dy)
                        if d < nearest:
                            nearest = d
                keep[i] = not (nearest < p.crowd_radius)

    # -- corners (features._corners) ----------------------------------------------------------
    cap_c = n_lines * (n_lines - 1) // 2 if p.corners else 0
    cxy = np.empty((cap_c, 2))
    ccov = np.empty((cap_c, 2, 2))
    cbeam = np.empty(cap_c, np.int64)
    ncr = 0
    if p.corners:
        for i in range(n_lines):
            for j in range(i + 1, n_lines):
                s1 = order[i]
                s2 = order[j]
                d = abs(_wrap(fit[s1, 1] - fit[s2, 1]))
                if _min(d, math.pi - d) < p.corner_min_angle:
                    continue
                n1x = math.cos(fit[s1, 1])
                n1y = math.sin(fit[s1, 1])
                n2x = math.cos(fit[s2, 1])
                n2y = math.sin(fit[s2, 1])
                # corner = M^-1 (rho1, rho2) with M = [n1; n2]
                det = n1x * n2y - n1y * n2x
                i00 = n2y / det
                i01 = -n1y / det
                i10 = -n2x / det
                i11 = n1x / det
                x = i00 * fit[s1, 0] + i01 * fit[s2, 0]
                y = i10 * fit[s1, 0] + i11 * fit[s2, 0]
                reach1 = _min(
                    math.hypot(fit[s1, 6] - x, fit[s1, 7] - y),
                    math.hypot(fit[s1, 8] - x, fit[s1, 9] - y),
                )
                reach2 = _min(
                    math.hypot(fit[s2, 6] - x, fit[s2, 7] - y),
                    math.hypot(fit[s2, 8] - x, fit[s2, 9] - y),
                )
                if _max(reach1, reach2) > p.corner_reach:
                    continue
                # d corner / d alpha_k = -M^-1 (e_k t_k . corner); J = [j0 j1 j2 j3] (2x4)
                g1 = -n1y * x + n1x * y  # t1 . corner
                g2 = -n2y * x + n2x * y
                j0x, j0y = i00, i10
                j1x, j1y = -i00 * g1, -i10 * g1
                j2x, j2y = i01, i11
                j3x, j3y = -i01 * g2, -i11 * g2
                # cov = J blockdiag(C1, C2) J^T
                a00, a01, a11 = fit[s1, 3], fit[s1, 4], fit[s1, 5]
                b00, b01, b11 = fit[s2, 3], fit[s2, 4], fit[s2, 5]
                # rows of J C (2x4 times 4x4 block diagonal), then times J^T
                u0 = j0x * a00 + j1x * a01
                u1 = j0x * a01 + j1x * a11
                u2 = j2x * b00 + j3x * b01
                u3 = j2x * b01 + j3x * b11
                w0 = j0y * a00 + j1y * a01
                w1 = j0y * a01 + j1y * a11
                w2 = j2y * b00 + j3y * b01
                w3 = j2y * b01 + j3y * b11
                cxy[ncr, 0] = x
                cxy[ncr, 1] = y
                ccov[ncr, 0, 0] = u0 * j0x + u1 * j1x + u2 * j2x + u3 * j3x
                ccov[ncr, 0, 1] = u0 * j0y + u1 * j1y + u2 * j2y + u3 * j3y
                ccov[ncr, 1, 0] = w0 * j0x + w1 * j1x + w2 * j2x + w3 * j3x
                ccov[ncr, 1, 1] = w0 * j0y + w1 * j1y + w2 * j2y + w3 * j3y
                phi = math.atan2(y, x)
                best = np.inf
                bb = 0
                for k in range(n):
                    dd = abs(angles[k] - phi)
                    if dd < best:
                        best = dd
                        bb = k
                cbeam[ncr] = bb
                ncr += 1

    # -- assemble ---------------------------------------------------------------------------
    n_keep = 0
    for i in range(npt):
        if keep[i]:
            n_keep += 1
    P = n_keep + ncr
    points_xy = np.empty((P, 2))
    points_label = np.empty(P, np.int8)
    points_cov = np.empty((P, 2, 2))
    points_beam = np.empty(P, np.int64)
    k = 0
    for i in range(npt):
        if keep[i]:
            points_xy[k] = pxy[i]
            points_label[k] = plabel[i]
            points_cov[k] = pcov[i]
            points_beam[k] = pbeam[i]
            k += 1
    for i in range(ncr):
        points_xy[k] = cxy[i]
        points_label[k] = _CORNER
        points_cov[k] = ccov[i]
        points_beam[k] = cbeam[i]
        k += 1

    L = n_lines if p.lines else 0
    rho_alpha = np.empty((L, 2))
    ends = np.empty((L, 2, 2))
    lcov = np.empty((L, 2, 2))
    lbeams = np.empty((L, 2), np.int64)
    lnpts = np.empty(L, np.int64)
    for q in range(L):
        s = order[q]
        rho_alpha[q, 0] = fit[s, 0]
        rho_alpha[q, 1] = fit[s, 1]
        ends[q, 0, 0] = fit[s, 6]
        ends[q, 0, 1] = fit[s, 7]
        ends[q, 1, 0] = fit[s, 8]
        ends[q, 1, 1] = fit[s, 9]
        lcov[q, 0, 0] = fit[s, 3]
        lcov[q, 0, 1] = fit[s, 4]
        lcov[q, 1, 0] = fit[s, 4]
        lcov[q, 1, 1] = fit[s, 5]
        lbeams[q, 0] = pool[lstart[s]]  # runs are sorted: first and last are min and max
        lbeams[q, 1] = pool[lstart[s] + lcount[s] - 1]
        lnpts[q] = lcount[s]
    return (
        points_xy,
        points_label,
        points_cov,
        points_beam,
        rho_alpha,
        ends,
        lcov,
        lbeams,
        lnpts,
        clusters,
    )


# --------------------------------------------------------------------------------------
# feature graphs
# --------------------------------------------------------------------------------------
@njit(cache=True)
def graph_layers(
    points_xy,
    points_label,
    points_cov,
    rho_alpha,
    typed,
    point_point,
    point_line,
    line_line,
    signed,
    parallel_offset,
    adaptive,
    parallel_sin,
):
    """Node labels and kinds, invariants and tolerances of ``graph.feature_graph``."""
    P = points_xy.shape[0]
    L = rho_alpha.shape[0]
    N = P + L
    kinds = np.empty(N, np.int64)
    labels = np.empty(N, np.int64)
    for i in range(N):
        kinds[i] = points_label[i] if i < P else _LINE
        labels[i] = kinds[i] if typed or kinds[i] == _LINE else 0
    inv = np.full((3, N, N), np.nan)
    tol = np.zeros((3, N, N))

    # layer 0: point–point distance
    lam = np.empty(P)
    if adaptive > 0:
        for i in range(P):
            # largest eigenvalue of the covariance (its lower triangle, as eigvalsh reads it)
            a = points_cov[i, 0, 0]
            b = points_cov[i, 1, 0]
            c = points_cov[i, 1, 1]
            h = 0.5 * (a - c)
            lam[i] = 0.5 * (a + c) + math.sqrt(h * h + b * b)
    for i in range(P):
        for j in range(P):
            dx = points_xy[i, 0] - points_xy[j, 0]
            dy = points_xy[i, 1] - points_xy[j, 1]
            inv[0, i, j] = math.sqrt(dx * dx + dy * dy)
            if adaptive > 0:
                tol[0, i, j] = max(point_point, adaptive * math.sqrt(2.0 * (lam[i] + lam[j])))
            else:
                tol[0, i, j] = point_point

    # layer 0: point–line (signed) perpendicular distance, normal from sensor to line
    for j in range(L):
        nx = math.cos(rho_alpha[j, 1])
        ny = math.sin(rho_alpha[j, 1])
        for i in range(P):
            s = points_xy[i, 0] * nx + points_xy[i, 1] * ny - rho_alpha[j, 0]
            if not signed:
                s = abs(s)
            inv[0, i, P + j] = s
            inv[0, P + j, i] = s
            tol[0, i, P + j] = point_line
            tol[0, P + j, i] = point_line

    # layers 1 and 2: line–line angle and parallel offset
    for i in range(L):
        for j in range(L):
            da = rho_alpha[j, 1] - rho_alpha[i, 1]  # from line i's normal to line j's
            if signed:
                ang = _wrap(da)
            else:
                a = abs(da) % math.pi
                ang = min(a, math.pi - a)  # acute angle magnitude in [0, pi/2]
            inv[1, P + i, P + j] = ang
            tol[1, P + i, P + j] = line_line
            if parallel_offset:
                if abs(math.sin(da)) < parallel_sin:
                    # parallel: rho_j - rho_i is invariant; antiparallel: rho_j + rho_i
                    if math.cos(da) > 0:
                        off = rho_alpha[j, 0] - rho_alpha[i, 0]
                    else:
                        off = rho_alpha[j, 0] + rho_alpha[i, 0]
                    inv[2, P + i, P + j] = off if signed else abs(off)
                tol[2, P + i, P + j] = point_line
        for k in range(3):
            inv[k, P + i, P + i] = np.nan
    return labels, kinds, inv, tol
