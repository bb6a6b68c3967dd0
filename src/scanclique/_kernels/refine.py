"""The best few hypotheses of a match in one call: full estimate, score, ICP, score.

Part of the matcher's kernels (private; gathered in :mod:`scanclique._match_kernels`)."""

# ruff: noqa: E402 (ensure_cache() runs before numba caches anything)
from __future__ import annotations

import math
from collections import namedtuple

from . import ensure_cache

ensure_cache()

import numpy as np

from .icp import icp
from .jit import njit
from .pose import closed_form, lsq_pose
from .score import pose_score

#: one scan's features, as :func:`refine_candidates` reads them (see
#: :class:`scanclique.features.Features`)
FeatureArrays = namedtuple("FeatureArrays", "n_points points points_cov lines lines_cov")
#: one prepared scan's raw-point arrays (see :class:`scanclique.match.PreparedScan`): the
#: cloud's bearing index, points and normals, the beam-angle index, free ranges, sample
CloudArrays = namedtuple("CloudArrays", "index points normals angle_index free sample")
#: the raw-scan score's settings (``RefineConfig``: inlier_distance, conflict_*)
ScoreParams = namedtuple(
    "ScoreParams", "inlier_distance conflict_weight conflict_margin conflict_ratio"
)
#: the refinement's settings: ``min_pairs`` (``PoseConfig``), ``outlier``
#: (``PoseConfig.outlier_mahalanobis``), ``icp`` on/off, its ``iterations`` and its
#: correspondence distance shrinking from ``max_correspondence`` to ``min_correspondence``
RefineParams = namedtuple(
    "RefineParams", "min_pairs outlier icp iterations max_correspondence min_correspondence"
)
#: what :func:`refine_candidates` writes, one row per candidate (``maha`` per pair)
RefineOut = namedtuple("RefineOut", "ok x_est info ssr used maha score_est x_icp score_icp")

_njit = njit(cache=True, nogil=True)
#: for the helpers called once per point: inlined into the caller at numba IR level, so
#: that the arrays they take are not reference-counted on every call
_inline = njit(cache=True, nogil=True, inline="always")


@_njit
def _points_first_into(pairs, npa, out):  # pragma: no cover - compiled
    """``pairs`` reordered points first, then lines, each in their order, into ``out``."""
    k = 0
    for i in range(pairs.shape[0]):
        if pairs[i, 0] < npa:
            out[k, 0] = pairs[i, 0]
            out[k, 1] = pairs[i, 1]
            k += 1
    for i in range(pairs.shape[0]):
        if pairs[i, 0] >= npa:
            out[k, 0] = pairs[i, 0]
            out[k, 1] = pairs[i, 1]
            k += 1


@_njit
def refine_candidates(pairs, indptr, fa, fb, ca, cb, sp, rp, out):  # pragma: no cover
    """For each candidate clique ``pairs[indptr[i]:indptr[i+1]]``: the weighted least
    squares pose from the closed form (5 Gauss–Newton steps), once more without the pairs
    whose Mahalanobis residual exceeds ``rp.outlier`` when at least ``rp.min_pairs``
    remain; its raw-scan score; then (``rp.icp``) point-to-line ICP of B's sample onto A
    from it, and the ICP pose's score.

    ``fa``, ``fb`` are :data:`FeatureArrays`, ``ca``, ``cb`` :data:`CloudArrays` of scans A
    and B, ``sp`` the :data:`ScoreParams`, ``rp`` the :data:`RefineParams`. Writes into
    ``out`` (:data:`RefineOut`) per candidate: ``ok`` (a pose was found), ``x_est`` (3),
    ``info`` (3x3) and ``ssr`` at the estimate, ``used`` (pairs kept), ``maha`` (their
    Mahalanobis residuals, points first, at ``indptr[i]``...), ``score_est``, ``x_icp``
    and ``score_icp`` (``-inf`` when no ICP ran).
    """
    npa, npb = fa.n_points, fb.n_points
    Pa, PCa, La, LCa = fa.points, fa.points_cov, fa.lines, fa.lines_cov
    Pb, PCb, Lb, LCb = fb.points, fb.points_cov, fb.lines, fb.lines_cov
    a_ix, a_ref, a_normals, a_aix, a_free, a_sample = ca
    b_ix, b_ref, _, b_aix, b_free, b_sample = cb
    d, conflict_weight, margin, ratio = sp
    min_pairs, outlier, icp_on, iterations, max_corr, min_corr = rp
    ok, x_est, info, ssr, used, maha, score_est, x_icp, score_icp = out
    K = pairs.shape[0]
    ordered = np.empty((K, 2), np.int64)
    start_x = np.empty(3)
    out_icp = np.empty(3)
    for i in range(indptr.shape[0] - 1):
        s0 = indptr[i]
        s1 = indptr[i + 1]
        sub = ordered[s0:s1]
        _points_first_into(pairs[s0:s1], npa, sub)
        ok[i] = closed_form(sub, npa, npb, Pa, Pb, La, Lb, start_x)
        score_icp[i] = -math.inf
        if not ok[i]:
            continue
        m = maha[s0:s1]
        x, q = lsq_pose(sub, npa, npb, Pa, PCa, La, LCa, Pb, PCb, Lb, LCb, start_x, 5, info[i], m)
        n_used = s1 - s0
        n_good = 0
        for k in range(s1 - s0):
            if m[k] <= outlier:
                n_good += 1
        if n_good < s1 - s0 and n_good >= min_pairs:
            keep = np.empty((n_good, 2), np.int64)
            g = 0
            for k in range(s1 - s0):
                if m[k] <= outlier:
                    keep[g, 0] = sub[k, 0]
                    keep[g, 1] = sub[k, 1]
                    g += 1
            x, q = lsq_pose(
                keep, npa, npb, Pa, PCa, La, LCa, Pb, PCb, Lb, LCb, x, 5, info[i], m[:n_good]
            )
            n_used = n_good
        used[i] = n_used
        ssr[i] = q
        x_est[i, 0] = x[0]
        x_est[i, 1] = x[1]
        x_est[i, 2] = x[2]
        score_est[i] = pose_score(
            a_ix, a_ref, a_aix, a_free, a_sample,
            b_ix, b_ref, b_aix, b_free, b_sample,
            x[0], x[1], x[2], d, conflict_weight, margin, ratio,
        )  # fmt: skip
        if icp_on and b_sample.shape[0] >= 3:
            if a_ref.shape[0] >= 3:
                icp(a_ix, a_ref, a_normals, b_sample, x, iterations, max_corr, min_corr, out_icp)
            else:
                out_icp[:] = x[:]
            x_icp[i, 0] = out_icp[0]
            x_icp[i, 1] = out_icp[1]
            x_icp[i, 2] = out_icp[2]
            score_icp[i] = pose_score(
                a_ix, a_ref, a_aix, a_free, a_sample,
                b_ix, b_ref, b_aix, b_free, b_sample,
                out_icp[0], out_icp[1], out_icp[2], d, conflict_weight, margin, ratio,
            )  # fmt: skip
