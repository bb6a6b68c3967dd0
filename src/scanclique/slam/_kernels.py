"""Compiled kernels of the SLAM association (numba; imported on first use only).

``jcbb_search`` is the branch and bound of Neira and Tardos (2001) over a precomputed
innovation covariance of all candidate pairs, with the joint Mahalanobis distance grown
pair by pair through a Cholesky factor: the factor of a leading block of a symmetric
positive definite matrix is the leading block of its factor, so a hypothesis one pair
longer adds two rows to the factor of its parent (O(d^2) per node, d the depth).
"""

from __future__ import annotations

import numpy as np
from numba import njit


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
def _rec(i, n, d2, k, S, nu, cand_start, cand, lm_of, gate, L, y, chosen, used, best, state, limit):
    state[2] += 1
    if state[2] > limit:
        return
    if i == k:
        if n > state[0] or (n == state[0] and d2 < state[1]):
            state[0] = n
            state[1] = d2
            for q in range(n):
                best[q] = chosen[q]
        return
    for c in range(cand_start[i], cand_start[i + 1]):
        p = cand[c]
        j = lm_of[p]
        if used[j]:
            continue
        inc = _extend(S, nu, L, y, chosen, n, p)
        if inc < 0.0:
            continue
        if d2 + inc <= gate[n + 1]:
            chosen[n] = p
            used[j] = True
            _rec(i + 1, n + 1, d2 + inc, k, S, nu, cand_start, cand, lm_of, gate, L, y,
                 chosen, used, best, state, limit)
            used[j] = False
    # the null branch: observation i unpaired, only if it can still beat the best
    if n + (k - i - 1) > state[0]:
        _rec(i + 1, n, d2, k, S, nu, cand_start, cand, lm_of, gate, L, y, chosen, used,
             best, state, limit)


@njit(cache=True)
def jcbb_search(S, nu, cand_start, cand, lm_of, n_lm, gate, limit):
    """Largest jointly compatible hypothesis (ties: least D^2).

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
    """
    k = cand_start.shape[0] - 1
    L = np.zeros((2 * k + 2, 2 * k + 2))
    y = np.zeros(2 * k + 2)
    chosen = np.zeros(k + 1, np.int64)
    best = np.zeros(k + 1, np.int64)
    used = np.zeros(n_lm, np.bool_)
    state = np.zeros(3)
    state[0] = 0.0
    state[1] = 0.0
    _rec(0, 0, 0.0, k, S, nu, cand_start, cand, lm_of, gate, L, y, chosen, used, best,
         state, limit)
    nb = int(state[0])
    return best[:nb].copy(), state[1], int(state[2])


@njit(cache=True)
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
