"""Pair sets for the benchmarks: consecutive, skip, and revisit pairs of a log with
reference poses (shared by ``accuracy.py`` and the other benchmarks).

* consecutive: ``(i, i + 1)``;
* skip: ``(i, i + 3)``;
* revisit: scans at least 50 apart in the log whose reference positions are less than 2 m
  apart and where at least half of B's points lie within 0.2 m of A's points under the
  reference relative pose (so that the two scans really see the same place).

A pair *succeeds* when the estimated relative pose is within 0.20 m and 2 degrees of the
reference ``ref_a.inverse() @ ref_b``.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.spatial import cKDTree

SUCCESS_TRANSLATION = 0.20  # metres
SUCCESS_ROTATION = math.radians(2.0)
REVISIT_MIN_GAP = 50
REVISIT_MAX_DISTANCE = 2.0
REVISIT_MIN_OVERLAP = 0.5
REVISIT_OVERLAP_DISTANCE = 0.2


def reference_pose(scans, i, j):
    """Reference pose of scan j's frame in scan i's frame (maps j's points into i)."""
    return scans[i].reference.inverse() @ scans[j].reference


def overlap(scan_a, scan_b, pose_a_b, distance=REVISIT_OVERLAP_DISTANCE) -> float:
    """Fraction of B's points within ``distance`` of A's points under ``pose_a_b``."""
    pa, pb = scan_a.points(), scan_b.points()
    if len(pa) == 0 or len(pb) == 0:
        return 0.0
    d, _ = cKDTree(pa).query(pose_a_b.transform(pb), distance_upper_bound=distance)
    return float(np.mean(np.isfinite(d)))


def evenly(pairs: list, cap: int | None) -> list:
    """At most ``cap`` pairs, evenly spread over the list (all when cap is None)."""
    if cap is None or len(pairs) <= cap:
        return list(pairs)
    idx = np.linspace(0, len(pairs) - 1, cap).round().astype(int)
    return [pairs[k] for k in np.unique(idx)]


def consecutive_pairs(n: int, step: int = 1) -> list[tuple[int, int]]:
    return [(i, i + step) for i in range(n - step)]


def revisit_pairs(scans, cap: int | None = None, seed: int = 0) -> list[tuple[int, int]]:
    """Revisit pairs (see the module docstring), at most ``cap``, drawn at random with a
    fixed seed among all candidates and kept when their overlap passes."""
    pos = np.array([[s.reference.x, s.reference.y] for s in scans])
    cand = [
        (i, j)
        for i, j in sorted(cKDTree(pos).query_pairs(REVISIT_MAX_DISTANCE))
        if j - i >= REVISIT_MIN_GAP
    ]
    rng = np.random.default_rng(seed)
    order = rng.permutation(len(cand))
    out = []
    for k in order:
        i, j = cand[k]
        if overlap(scans[i], scans[j], reference_pose(scans, i, j)) >= REVISIT_MIN_OVERLAP:
            out.append((i, j))
            if cap is not None and len(out) >= cap:
                break
    return sorted(out)


def pair_sets(scans, cap: int | None = None, seed: int = 0) -> dict[str, list[tuple[int, int]]]:
    """The three pair sets of a log, each at most ``cap`` pairs."""
    n = len(scans)
    return {
        "consecutive": evenly(consecutive_pairs(n, 1), cap),
        "skip3": evenly(consecutive_pairs(n, 3), cap),
        "revisit": revisit_pairs(scans, cap, seed),
    }


def is_success(t_err: float, r_err: float) -> bool:
    return t_err <= SUCCESS_TRANSLATION and r_err <= SUCCESS_ROTATION
