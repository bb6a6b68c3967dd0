"""Compiled loops of the signature (numba), loaded on first use by
:mod:`scanclique.places.signature`; the NumPy functions there are the reference these
must agree with (``tests/test_places_signature.py``)."""

from __future__ import annotations

import math

import numpy as np

from .._kernels.jit import njit


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


@njit(cache=True)
def _key_ranges(keys, qk):
    """``(lo, hi)``: the rows of the sorted ``keys`` equal to each of the sorted needles
    ``qk`` (``np.searchsorted`` left and right; each needle's binary search starts at the
    previous one's lower bound, and equal keys are walked)."""
    nk = keys.shape[0]
    nq = qk.shape[0]
    lo = np.empty(nq, dtype=np.int64)
    hi = np.empty(nq, dtype=np.int64)
    start = 0
    for m in range(nq):
        x = qk[m]
        if m > 0 and x == qk[m - 1]:
            lo[m] = lo[m - 1]
            hi[m] = hi[m - 1]
            continue
        a = start
        b = nk
        while a < b:
            mid = (a + b) >> 1
            if keys[mid] < x:
                a = mid + 1
            else:
                b = mid
        e = a
        while e < nk and keys[e] == x:
            e += 1
        lo[m] = a
        hi[m] = e
        start = a
    return lo, hi


@njit(cache=True)
def triangle_gather(keys, rows, frames, qk, qt, qf, qc, qs):
    """The votes of the sorted query keys ``qk`` (triangle ``qt`` of frame ``qf``, with
    its cosine and sine ``qc``, ``qs``) in one sorted segment of the triangle index:
    ``(place rows, (theta, x, y) of T_place_query)`` (:meth:`.hashing.TriangleIndex.votes`)."""
    nq = qk.shape[0]
    lo, hi = _key_ranges(keys, qk)
    tot = 0
    for m in range(nq):
        tot += hi[m] - lo[m]
    r = np.empty(tot, dtype=np.int64)
    v = np.empty((tot, 3))
    k = 0
    for m in range(nq):
        t = qt[m]
        cq, sq = qc[t], qs[t]
        qx, qy = qf[t, 0], qf[t, 1]
        for pos in range(lo[m], hi[m]):
            fx = np.float64(frames[pos, 0])
            fy = np.float64(frames[pos, 1])
            fc = np.float64(frames[pos, 2])
            fs = np.float64(frames[pos, 3])
            c = fc * cq + fs * sq
            s = fs * cq - fc * sq
            r[k] = rows[pos]
            v[k, 0] = math.atan2(s, c)
            v[k, 1] = fx - (c * qx - s * qy)
            v[k, 2] = fy - (s * qx + c * qy)
            k += 1
    return r, v


@njit(cache=True)
def triangle_reduce(r, v, n_rows, vote_xy, vote_theta, nxy, nt, scores, poses, min_pose=0):
    """Bin the votes ``(r, v)`` by place and pose (``vote_xy`` m, ``vote_theta`` rad, bins
    centred on the identity) and write each place's most votes in one bin to ``scores``
    and that bin's mean pose (the first such bin in key order) to ``poses``.

    The votes are grouped by place (a counting sort, stable), then each place's by bin
    (stable): the order of a global stable sort by ``(place, bin)``, so each bin's mean
    sums its votes in the order given. Only each place's best bin has its mean computed,
    and only when it has at least ``min_pose`` votes (the other places' rows of ``poses``
    are left as they are)."""
    n = r.shape[0]
    if n == 0:
        return
    two_pi = 2.0 * math.pi
    half = nxy // 2
    sub = np.empty(n, dtype=np.int64)  # the pose bin of each vote, within its place
    start = np.zeros(n_rows + 1, dtype=np.int64)
    for i in range(n):
        th = (v[i, 0] + 0.5 * vote_theta) % two_pi
        bt = min(int(th / vote_theta), nt - 1)
        bx = int(math.floor(v[i, 1] / vote_xy + 0.5)) + half
        by = int(math.floor(v[i, 2] / vote_xy + 0.5)) + half
        bx = min(max(bx, 0), nxy - 1)
        by = min(max(by, 0), nxy - 1)
        sub[i] = (bx * nxy + by) * nt + bt
        start[r[i] + 1] += 1
    for j in range(n_rows):
        start[j + 1] += start[j]
    fill = start[:-1].copy()
    o = np.empty(n, dtype=np.int64)
    for i in range(n):
        row = r[i]
        o[fill[row]] = i
        fill[row] += 1
    for row in range(n_rows):
        a = start[row]
        b = start[row + 1]
        m = b - a
        if m == 0:
            continue
        if m <= 24:  # a stable insertion sort of the place's votes by bin
            for x in range(a + 1, b):
                e = o[x]
                ke = sub[e]
                y = x - 1
                while y >= a and sub[o[y]] > ke:
                    o[y + 1] = o[y]
                    y -= 1
                o[y + 1] = e
        else:
            seg = o[a:b].copy()
            so = np.argsort(sub[seg], kind="mergesort")
            for x in range(m):
                o[a + x] = seg[so[x]]
        # the first bin (in key order) with the most votes, if more than scores[row]
        best = scores[row]
        bi = -1
        bj = -1
        i = a
        while i < b:
            key = sub[o[i]]
            j = i + 1
            while j < b and sub[o[j]] == key:
                j += 1
            if j - i > best:
                best = j - i
                bi = i
                bj = j
            i = j
        if bi < 0:
            continue
        scores[row] = best
        if best < min_pose:
            continue
        sc = 0.0
        ss = 0.0
        sx = 0.0
        sy = 0.0
        for x in range(bi, bj):
            e = o[x]
            sc += math.cos(v[e, 0])
            ss += math.sin(v[e, 0])
            sx += v[e, 1]
            sy += v[e, 2]
        poses[row, 0] = sx / best
        poses[row, 1] = sy / best
        poses[row, 2] = math.atan2(ss / best, sc / best)


@njit(cache=True)
def triangle_corners(D, k, min_side, max_side):
    """The local triangles of :func:`.hashing.feature_triangles` from the distances ``D``
    (``(P, P)``) of the point features, each feature with pairs of its ``k`` nearest (a
    stable sort of its row of ``D``, itself first): ``(V, s)``, the corners opposite the
    sorted sides and those sides, rows in the order of the triangles' sorted corner
    indices, only triangles with sides within ``[min_side, max_side]``."""
    P = D.shape[0]
    npair = k * (k - 1) // 2
    codes = np.empty(P * npair, dtype=np.int64)
    n = 0
    for i in range(P):
        nn = np.argsort(D[i], kind="mergesort")[1 : k + 1]
        for b in range(k):
            for c in range(b + 1, k):
                a0, a1, a2 = i, nn[b], nn[c]
                if a0 > a1:
                    a0, a1 = a1, a0
                if a1 > a2:
                    a1, a2 = a2, a1
                if a0 > a1:
                    a0, a1 = a1, a0
                codes[n] = (a0 * P + a1) * P + a2
                n += 1
    codes = np.sort(codes[:n])
    V = np.empty((n, 3), dtype=np.int64)
    s = np.empty((n, 3))
    m = 0
    for t in range(n):
        if t > 0 and codes[t] == codes[t - 1]:
            continue
        code = codes[t]
        i = code // (P * P)
        j = (code // P) % P
        q = code % P
        v = (i, j, q)
        d = (D[j, q], D[i, q], D[i, j])  # the side opposite i, j, q
        if max(d[0], max(d[1], d[2])) > max_side or min(d[0], min(d[1], d[2])) < min_side:
            continue
        # a stable sort of the three sides (ties keep the order i, j, q)
        o0, o1, o2 = 0, 1, 2
        if d[o1] < d[o0]:
            o0, o1 = o1, o0
        if d[o2] < d[o1]:
            o1, o2 = o2, o1
            if d[o1] < d[o0]:
                o0, o1 = o1, o0
        s[m, 0], s[m, 1], s[m, 2] = d[o0], d[o1], d[o2]
        V[m, 0], V[m, 1], V[m, 2] = v[o0], v[o1], v[o2]
        m += 1
    return V[:m], s[:m]
