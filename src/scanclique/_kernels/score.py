"""The raw-scan score of a pose: agreement of the two scans' points and conflicts with
the free space each scan saw through (single poses and batches).

Part of the matcher's kernels (private; gathered in :mod:`scanclique._match_kernels`)."""

# ruff: noqa: E402 (ensure_cache() runs before numba caches anything)
from __future__ import annotations

import math

from . import ensure_cache

ensure_cache()

import numpy as np

from .algebra import wrap
from .jit import njit
from .neighbours import has_near_polar, lower

_njit = njit(cache=True, nogil=True)
#: for the helpers called once per point: inlined into the caller at numba IR level, so
#: that the arrays they take are not reference-counted on every call
_inline = njit(cache=True, nogil=True, inline="always")


@_inline
def _in_free_space(aix, free, half, r, phi, margin, ratio):  # pragma: no cover - compiled
    """Whether the point at range ``r`` and bearing ``phi`` lies nearer than the nearest
    beam and both its neighbours by more than ``margin + ratio * r`` (``half``: half the
    mean beam spacing; ``aix`` the index of the beam angles)."""
    angles = aix[0]
    n = angles.shape[0]
    # beam angles may run past pi (a full turn published from 0 to 2 pi): the bearing a
    # turn on or back is the same direction (for angles within [-pi, pi] the turned
    # bearing falls outside the scan as the bearing did: no change)
    if phi < angles[0] - half:
        phi += 2.0 * math.pi
    elif phi > angles[n - 1] + half:
        phi -= 2.0 * math.pi
    if phi < angles[0] - half or phi > angles[n - 1] + half:
        return False
    k = lower(aix, phi)
    k = min(max(k, 1), n - 1)
    if abs(angles[k - 1] - phi) < abs(angles[k] - phi):
        k -= 1
    lo = free[k]
    if k > 0:
        lo = min(lo, free[k - 1])
    if k < n - 1:
        lo = min(lo, free[k + 1])
    return r < lo - (margin + ratio * r)


@_njit
def conflict_count(aix, free, pts, c, s, tx, ty, margin, ratio):  # pragma: no cover
    """How many ``pts`` moved by ``(R(c, s), t)`` lie in the free space seen along the
    nearest beam and both its neighbours (``free``: measured range, 0 when invalid):
    nearer than all three by more than ``margin + ratio * range``; ``aix``: the index of
    the beam angles, :func:`make_index`)."""
    angles = aix[0]
    n = angles.size
    if n < 2:
        return 0
    half = 0.5 * (angles[n - 1] - angles[0]) / (n - 1)
    count = 0
    for i in range(pts.shape[0]):
        x = c * pts[i, 0] - s * pts[i, 1] + tx
        y = s * pts[i, 0] + c * pts[i, 1] + ty
        r = math.sqrt(x * x + y * y)
        if _in_free_space(aix, free, half, r, math.atan2(y, x), margin, ratio):
            count += 1
    return count


@_njit
def _one_way(
    ix, ref, aix, free, pts, c, s, tx, ty, d, conflicts, margin, ratio
):  # pragma: no cover
    """Fractions of ``pts`` moved by ``(R(c, s), t)`` that agree with (are within ``d``
    of) ``ref`` (bearings indexed by ``ix``), and (when ``conflicts``) that lie in the
    free space of the scan whose beam angles are indexed by ``aix``, free ranges
    ``free``."""
    m = pts.shape[0]
    if m == 0:
        return 0.0, 0.0
    angles = aix[0]
    n = angles.shape[0]
    half = 0.5 * (angles[n - 1] - angles[0]) / (n - 1) if n >= 2 else 0.0
    check_free = conflicts and n >= 2
    has_ref = ref.shape[0] > 0
    rng = np.empty(6, np.int64)
    agree = 0
    conflict = 0
    for i in range(m):
        x = c * pts[i, 0] - s * pts[i, 1] + tx
        y = s * pts[i, 0] + c * pts[i, 1] + ty
        r = math.sqrt(x * x + y * y)
        phi = math.atan2(y, x)
        if has_ref and has_near_polar(ix, ref, x, y, r, phi, d, rng):
            agree += 1
        if check_free and _in_free_space(aix, free, half, r, phi, margin, ratio):
            conflict += 1
    return agree / m, conflict / m


@_njit
def pose_score(
    a_ix,
    a_ref,
    a_aix,
    a_free,
    a_sample,
    b_ix,
    b_ref,
    b_aix,
    b_free,
    b_sample,
    x,
    y,
    th,
    d,
    conflict_weight,
    margin,
    ratio,
):  # pragma: no cover - compiled
    """Symmetric raw-scan score of the pose ``(x, y, th)`` (maps B into A): the mean of
    the fractions of B's sample near A's points and of A's sample near B's points, minus
    ``conflict_weight`` times the mean fraction of samples in the other scan's free
    space. See :func:`scanclique.match.pose_score`."""
    c = math.cos(th)
    s = math.sin(th)
    inv_x = -(c * x + s * y)
    inv_y = -(-s * x + c * y)
    conflicts = conflict_weight > 0.0
    ag_ab, c_ab = _one_way(
        a_ix, a_ref, a_aix, a_free, b_sample, c, s, x, y, d, conflicts, margin, ratio
    )
    ag_ba, c_ba = _one_way(
        b_ix, b_ref, b_aix, b_free, a_sample, c, -s, inv_x, inv_y, d, conflicts, margin, ratio
    )
    score = 0.5 * (ag_ab + ag_ba)
    if conflicts:
        score -= conflict_weight * 0.5 * (c_ab + c_ba)
    return score


@_inline
def _same_pose(poses, i, among, upto):  # pragma: no cover - compiled
    """The first ``j < upto`` with ``among[j]`` whose pose is within 2 cm and 0.2 degrees
    of pose ``i``; -1 when none."""
    for j in range(upto):
        if (
            among[j]
            and abs(poses[i, 0] - poses[j, 0]) < 0.02
            and abs(poses[i, 1] - poses[j, 1]) < 0.02
            and abs(wrap(poses[i, 2] - poses[j, 2])) < 0.0035
        ):
            return j
    return -1


@_njit
def score_batch(
    poses, ok, sizes, size_weight, keep,
    a_ix, a_ref, a_aix, a_free, a_sample,
    b_ix, b_ref, b_aix, b_free, b_sample,
    d, conflict_weight, margin, ratio,
    scores, exact,
):  # fmt: skip  # pragma: no cover - compiled
    """:func:`pose_score` of the poses with ``ok`` set (others get ``-inf``), coarse to
    fine: every pose is first scored on every third sample point of each scan; the
    ``keep`` best by rank (score plus ``size_weight`` per clique vertex, ``sizes``) are
    scored again on the full samples (``exact`` set). Cliques that share most of an
    association give nearly the same pose: a pose within 2 cm and 0.2 degrees of one
    already scored gets that one's score."""
    n = poses.shape[0]
    a_part = a_sample[::3].copy()
    b_part = b_sample[::3].copy()
    for i in range(n):
        exact[i] = False
        if not ok[i]:
            scores[i] = -math.inf
            continue
        same = _same_pose(poses, i, ok, i)
        if same >= 0:
            scores[i] = scores[same]
            continue
        scores[i] = pose_score(
            a_ix, a_ref, a_aix, a_free, a_part,
            b_ix, b_ref, b_aix, b_free, b_part,
            poses[i, 0], poses[i, 1], poses[i, 2], d, conflict_weight, margin, ratio,
        )  # fmt: skip
    rank = np.empty(n)
    for i in range(n):
        rank[i] = scores[i] + size_weight * sizes[i]
    order = np.argsort(-rank, kind="mergesort")
    done = 0
    for q in range(n):
        i = order[q]
        if done >= keep or not ok[i]:
            break
        same = _same_pose(poses, i, exact, n)
        if same >= 0:
            scores[i] = scores[same]
        else:
            scores[i] = pose_score(
                a_ix, a_ref, a_aix, a_free, a_sample,
                b_ix, b_ref, b_aix, b_free, b_sample,
                poses[i, 0], poses[i, 1], poses[i, 2], d, conflict_weight, margin, ratio,
            )  # fmt: skip
            done += 1
        exact[i] = True
