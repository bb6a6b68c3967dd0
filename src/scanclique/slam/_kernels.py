"""Compiled kernels of the SLAM association (numba; imported on first use only).

``jcbb_search`` is the branch and bound of Neira and Tardos (2001) over a precomputed
innovation covariance of all candidate pairs, with the joint Mahalanobis distance grown
pair by pair through a Cholesky factor: the factor of a leading block of a symmetric
positive definite matrix is the leading block of its factor, so a hypothesis one pair
longer adds two rows to the factor of its parent (O(d^2) per node, d the depth).
"""

from __future__ import annotations

import numpy as np

from .._kernels.jit import njit


@njit(cache=True)
def _extend(S, nu, L, y, chosen, n, p):
    """Joint distance increment of adding pair ``p`` to the ``n`` chosen pairs.

    Writes rows ``2n, 2n+1`` of ``L`` and entries of ``y``; returns the increment of
    D^2 or -1.0 when the extended covariance is not positive definite."""
    m = 2 * n
    # b = L^-1 S[H, p]  (m x 2), forward substitution
    b = np.empty((m, 2))
    for c in range(2):
        pc = 2 * p + c
        for r in range(m):
            hr = 2 * chosen[r // 2] + (r % 2)
            s = S[hr, pc]
            for q in range(r):
                s -= L[r, q] * b[q, c]
            b[r, c] = s / L[r, r]
    a00 = S[2 * p, 2 * p]
    a01 = S[2 * p, 2 * p + 1]
    a11 = S[2 * p + 1, 2 * p + 1]
    w0 = nu[2 * p]
    w1 = nu[2 * p + 1]
    for r in range(m):
        a00 -= b[r, 0] * b[r, 0]
        a01 -= b[r, 0] * b[r, 1]
        a11 -= b[r, 1] * b[r, 1]
        w0 -= b[r, 0] * y[r]
        w1 -= b[r, 1] * y[r]
    if a00 <= 0.0:
        return -1.0
    l00 = np.sqrt(a00)
    l10 = a01 / l00
    t = a11 - l10 * l10
    if t <= 0.0:
        return -1.0
    l11 = np.sqrt(t)
    for r in range(m):
        L[m, r] = b[r, 0]
        L[m + 1, r] = b[r, 1]
    L[m, m] = l00
    L[m, m + 1] = 0.0
    L[m + 1, m] = l10
    L[m + 1, m + 1] = l11
    y0 = w0 / l00
    y1 = (w1 - l10 * y0) / l11
    y[m] = y0
    y[m + 1] = y1
    return y0 * y0 + y1 * y1


@njit(cache=True)
def jcbb_search(S, nu, cand_start, cand, lm_of, n_lm, gate, limit):
    """Largest jointly compatible hypothesis (ties: least D^2), depth-first.

    Parameters
    ----------
    S : (2C, 2C) float64
        Innovation covariance of all C candidate pairs.
    nu : (2C,) float64
        Their innovations.
    cand_start, cand : int64 arrays
        Candidates of observation i are ``cand[cand_start[i]:cand_start[i+1]]``.
    lm_of : (C,) int64
        Landmark (local index) of each pair.
    gate : (K+1,) float64
        ``gate[n]`` = chi-square bound of n pairs (2n degrees of freedom).
    limit : int
        Node budget.

    Returns
    -------
    (best pairs (n,) int64, D^2, nodes)

    Notes
    -----
    Level ``i`` decides observation ``i``: each compatible candidate whose landmark is
    free and whose joint distance stays under the gate, then the null branch (``i``
    unpaired), taken only while ``pairs + observations left`` can beat the best
    (Neira and Tardos 2001). Invariant: rows ``[0, 2n)`` of ``L`` are the Cholesky factor
    of the chosen pairs' covariance, ``y[:2n] = L^-1 nu_H``, ``d2 = |y[:2n]|^2``.
    """
    k = cand_start.shape[0] - 1
    L = np.zeros((2 * k + 2, 2 * k + 2))
    y = np.zeros(2 * k + 2)
    chosen = np.zeros(k + 1, np.int64)
    best = np.zeros(k + 1, np.int64)
    used = np.zeros(n_lm, np.bool_)
    cursor = np.zeros(k + 1, np.int64)
    null_done = np.zeros(k + 1, np.bool_)
    taken = np.full(k + 1, -1, np.int64)
    n_at = np.zeros(k + 1, np.int64)
    d2_at = np.zeros(k + 1)
    best_n = 0
    best_d2 = 0.0
    nodes = 0
    i = 0
    n = 0
    d2 = 0.0
    cursor[0] = cand_start[0]
    null_done[0] = False
    while i >= 0:
        if i == k:
            if n > best_n or (n == best_n and d2 < best_d2):
                best_n = n
                best_d2 = d2
                for q in range(n):
                    best[q] = chosen[q]
            i -= 1
            if i >= 0:
                if taken[i] >= 0:
                    used[lm_of[taken[i]]] = False
                n = n_at[i]
                d2 = d2_at[i]
            continue
        descended = False
        if nodes < limit:
            while cursor[i] < cand_start[i + 1]:
                p = cand[cursor[i]]
                cursor[i] += 1
                j = lm_of[p]
                if used[j]:
                    continue
                inc = _extend(S, nu, L, y, chosen, n, p)
                if inc < 0.0 or d2 + inc > gate[n + 1]:
                    continue
                nodes += 1
                taken[i] = p
                n_at[i] = n
                d2_at[i] = d2
                chosen[n] = p
                used[j] = True
                n += 1
                d2 += inc
                i += 1
                cursor[i] = cand_start[i] if i < k else 0
                null_done[i] = False
                descended = True
                break
            if not descended and not null_done[i]:
                null_done[i] = True
                if n + (k - i - 1) > best_n:
                    nodes += 1
                    taken[i] = -1
                    n_at[i] = n
                    d2_at[i] = d2
                    i += 1
                    cursor[i] = cand_start[i] if i < k else 0
                    null_done[i] = False
                    descended = True
        if descended:
            continue
        # level i exhausted: back to its parent and undo the parent's choice
        i -= 1
        if i >= 0:
            if taken[i] >= 0:
                used[lm_of[taken[i]]] = False
            n = n_at[i]
            d2 = d2_at[i]
    return best[:best_n].copy(), best_d2, nodes


@njit(cache=True, fastmath=True)
def sym_update(P, d, K, Mt):
    """``P[:d, :d] += K Mt^T + Mt K^T`` (K, Mt: (d, r)), upper triangle computed and
    mirrored: the covariance update of the filter in O(d^2 r), on one core."""
    r = K.shape[1]
    for i in range(d):
        for j in range(i, d):
            s = 0.0
            for q in range(r):
                s += K[i, q] * Mt[j, q] + Mt[i, q] * K[j, q]
            v = P[i, j] + s
            P[i, j] = v
            P[j, i] = v


@njit(cache=True)
def predict_segment(kind, params, x, Pvv, Fcum, dts, controls, slip, poses, covs, out0):
    """Integrate the vehicle over consecutive controls (one Euler step each).

    ``kind`` 0: Ackermann, params (L, H, sigma_v, sigma_v_rel, sigma_steer); 1: unicycle,
    params (sigma_v, sigma_v_rel, sigma_omega). Updates ``x`` (3,), ``Pvv`` (3, 3) and the
    accumulated Jacobian ``Fcum`` (3, 3) in place; writes the pose and covariance after
    step ``q`` to ``poses[out0 + q]``, ``covs[out0 + q]``. ``slip`` (3, 3): additive process
    variances while moving (see :meth:`scanclique.slam.models.MotionModel.moving`) per
    second, per metre travelled and per radian turned (:attr:`SlamConfig.slip
    <scanclique.slam.SlamConfig.slip>`)."""
    F = np.eye(3)
    G = np.zeros((3, 2))
    Q = np.zeros((2, 2))
    for q in range(dts.shape[0]):
        dt = dts[q]
        if dt > 0.0 and not np.isnan(controls[q, 0]):
            th = x[2]
            c = np.cos(th)
            s = np.sin(th)
            v0 = controls[q, 0]
            u1 = controls[q, 1]
            if kind == 0:
                L = params[0]
                H = params[1]
                ta = np.tan(u1)
                den = 1.0 - ta * H / L
                vc = v0 / den
                sec2 = 1.0 + ta * ta
                dvc_dve = 1.0 / den
                dvc_dal = v0 * (H / L) * sec2 / (den * den)
                G[0, 0] = dt * c * dvc_dve
                G[0, 1] = dt * c * dvc_dal
                G[1, 0] = dt * s * dvc_dve
                G[1, 1] = dt * s * dvc_dal
                G[2, 0] = dt * ta / L * dvc_dve
                G[2, 1] = dt / L * (dvc_dal * ta + vc * sec2)
                w = vc * ta / L
                sv = params[2] + params[3] * abs(v0)
                Q[0, 0] = sv * sv
                Q[1, 1] = params[4] * params[4]
            else:
                vc = v0
                w = u1
                G[0, 0] = dt * c
                G[0, 1] = 0.0
                G[1, 0] = dt * s
                G[1, 1] = 0.0
                G[2, 0] = 0.0
                G[2, 1] = dt
                sv = params[0] + params[1] * abs(v0)
                Q[0, 0] = sv * sv
                Q[1, 1] = params[2] * params[2]
            F[0, 2] = -dt * vc * s
            F[1, 2] = dt * vc * c
            x[0] += dt * vc * c
            x[1] += dt * vc * s
            a = x[2] + dt * w
            x[2] = (a + np.pi) % (2.0 * np.pi) - np.pi
            Pn = F @ Pvv @ F.T + G @ Q @ G.T
            if abs(v0) > 1e-6 or (kind == 1 and abs(u1) > 1e-6):
                dist = abs(vc) * dt
                turn = abs(w) * dt
                for r in range(3):
                    Pn[r, r] += slip[0, r] * dt + slip[1, r] * dist + slip[2, r] * turn
            Pvv[:, :] = Pn
            Fcum[:, :] = F @ Fcum
        poses[out0 + q, :] = x
        covs[out0 + q, :, :] = Pvv


@njit(cache=True)
def correspondence_adjacency(z, R, pos, Pm, oi, lj, sig2):
    """Adjacency (C, C) of the correspondence graph of point features (see
    :func:`scanclique.slam.association.correspondence_graph`): pairs ``a = (oi[a], lj[a])``
    and ``b`` are joined when ``oi`` and ``lj`` differ and the squared difference of the
    observed and mapped point-point distances is at most ``sig2`` times the sum of their
    first-order variances. ``z`` (k, 2) range/bearing, ``R`` (k, 2, 2), ``pos`` (n, 2),
    ``Pm`` (2n, 2n) joint covariance of the landmarks."""
    k = z.shape[0]
    pts = np.empty((k, 2))
    C = np.empty((k, 2, 2))
    for i in range(k):
        r = z[i, 0]
        c = np.cos(z[i, 1])
        s = np.sin(z[i, 1])
        pts[i, 0] = r * c
        pts[i, 1] = r * s
        j00, j01, j10, j11 = c, -r * s, s, r * c
        a00, a01, a10, a11 = R[i, 0, 0], R[i, 0, 1], R[i, 1, 0], R[i, 1, 1]
        # J R J^T
        t00 = j00 * a00 + j01 * a10
        t01 = j00 * a01 + j01 * a11
        t10 = j10 * a00 + j11 * a10
        t11 = j10 * a01 + j11 * a11
        C[i, 0, 0] = t00 * j00 + t01 * j01
        C[i, 0, 1] = t00 * j10 + t01 * j11
        C[i, 1, 0] = t10 * j00 + t11 * j01
        C[i, 1, 1] = t10 * j10 + t11 * j11
    n = oi.shape[0]
    A = np.zeros((n, n), np.bool_)
    for a in range(n):
        i = oi[a]
        j = lj[a]
        for b in range(a + 1, n):
            kk = oi[b]
            ll = lj[b]
            if i == kk or j == ll:
                continue
            dx = pts[i, 0] - pts[kk, 0]
            dy = pts[i, 1] - pts[kk, 1]
            do = np.sqrt(dx * dx + dy * dy)
            mx = pos[j, 0] - pos[ll, 0]
            my = pos[j, 1] - pos[ll, 1]
            dm = np.sqrt(mx * mx + my * my)
            # the distances' directions; two points that coincide (an observation given
            # twice, two landmarks at one place) take the other pair's, or x
            if do > 0.0:
                ux = dx / do
                uy = dy / do
            elif dm > 0.0:
                ux = mx / dm
                uy = my / dm
            else:
                ux = 1.0
                uy = 0.0
            if dm > 0.0:
                wx = mx / dm
                wy = my / dm
            else:
                wx = ux
                wy = uy
            vo = (
                ux * ux * (C[i, 0, 0] + C[kk, 0, 0])
                + 2 * ux * uy * (C[i, 0, 1] + C[kk, 0, 1])
                + uy * uy * (C[i, 1, 1] + C[kk, 1, 1])
            )
            # var of u^T (m_j - m_l): blocks jj + ll - jl - lj
            s00 = Pm[2 * j, 2 * j] + Pm[2 * ll, 2 * ll] - 2 * Pm[2 * j, 2 * ll]
            s11 = (
                Pm[2 * j + 1, 2 * j + 1]
                + Pm[2 * ll + 1, 2 * ll + 1]
                - 2 * Pm[2 * j + 1, 2 * ll + 1]
            )
            s01 = (
                Pm[2 * j, 2 * j + 1]
                + Pm[2 * ll, 2 * ll + 1]
                - Pm[2 * j, 2 * ll + 1]
                - Pm[2 * ll, 2 * j + 1]
            )
            vm = wx * wx * s00 + 2 * wx * wy * s01 + wy * wy * s11
            if vm < 0.0:
                vm = 0.0
            dd = do - dm
            if dd * dd <= sig2 * (vo + vm):
                A[a, b] = True
                A[b, a] = True
    return A
