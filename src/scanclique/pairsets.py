"""Scan pairs with known truth: the pair sets of ``scanclique validate`` and of the
benchmarks (``benchmarks/pairs.py``) for a log with reference poses.

* consecutive: ``(i, i + 1)``;
* skip3: ``(i, i + 3)``;
* revisit: scans at least 50 apart in the log whose reference positions are less than 2 m
  apart and where at least half of B's points lie within 0.2 m of A's points under the
  reference relative pose (so that the two scans really see the same place).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from .errors import ScanError
from .geometry import Pose2
from .scan import Scan

__all__ = [
    "REVISIT_MIN_GAP",
    "REVISIT_MAX_DISTANCE",
    "REVISIT_MIN_OVERLAP",
    "REVISIT_OVERLAP_DISTANCE",
    "reference_pose",
    "relative_reference",
    "overlap",
    "evenly",
    "consecutive_pairs",
    "revisit_pairs",
    "pair_sets",
]

REVISIT_MIN_GAP = 50
REVISIT_MAX_DISTANCE = 2.0  # metres
REVISIT_MIN_OVERLAP = 0.5
REVISIT_OVERLAP_DISTANCE = 0.2  # metres


def relative_reference(a: Scan, b: Scan) -> Pose2 | None:
    """Reference pose of scan b's frame in scan a's frame (maps b's points into a), the
    truth a match of the pair is judged against; None when either has no reference."""
    if a.reference is None or b.reference is None:
        return None
    return a.reference.inverse() @ b.reference


def reference_pose(scans: Sequence[Scan], i: int, j: int) -> Pose2:
    """Reference pose of scan j's frame in scan i's frame (:func:`relative_reference`)."""
    ref = relative_reference(scans[i], scans[j])
    if ref is None:
        raise ScanError(f"scans {i} and {j}: a reference pose is missing")
    return ref


def overlap(
    scan_a: Scan, scan_b: Scan, pose_a_b: Pose2, distance: float = REVISIT_OVERLAP_DISTANCE
) -> float:
    """Fraction of B's points within ``distance`` of A's points under ``pose_a_b`` (which
    maps points from B's frame into A's)."""
    from scipy.spatial import cKDTree

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
    """``(i, i + step)`` for every scan ``i`` of a log of ``n`` scans."""
    return [(i, i + step) for i in range(n - step)]


def _check_references(scans: Sequence[Scan]) -> None:
    for k, s in enumerate(scans):
        if s.reference is None:
            raise ScanError(f"pair_sets needs reference poses; scan {k} ({s.source}) has none")


def revisit_pairs(
    scans: Sequence[Scan], cap: int | None = None, seed: int = 0
) -> list[tuple[int, int]]:
    """Revisit pairs (see the module docstring), at most ``cap``, drawn at random with a
    fixed seed among all candidates and kept when their overlap passes; sorted.

    Raises
    ------
    ScanError
        If a scan has no reference pose.
    """
    from scipy.spatial import cKDTree

    _check_references(scans)
    if len(scans) <= REVISIT_MIN_GAP:
        return []
    pos = np.array([[s.reference.x, s.reference.y] for s in scans])
    cand = [
        (i, j)
        for i, j in sorted(cKDTree(pos).query_pairs(REVISIT_MAX_DISTANCE))
        if j - i >= REVISIT_MIN_GAP
    ]
    out: list[tuple[int, int]] = []
    for k in np.random.default_rng(seed).permutation(len(cand)):
        i, j = cand[k]
        if overlap(scans[i], scans[j], reference_pose(scans, i, j)) >= REVISIT_MIN_OVERLAP:
            out.append((i, j))
            if cap is not None and len(out) >= cap:
                break
    return sorted(out)


def pair_sets(
    scans: Sequence[Scan], cap: int | None = None, seed: int = 0
) -> dict[str, list[tuple[int, int]]]:
    """The pair sets of the benchmarks for a log with reference poses.

    * ``consecutive``: ``(i, i + 1)``; ``skip3``: ``(i, i + 3)``; at most ``cap`` each,
      evenly spread over the log;
    * ``revisit``: scans at least 50 apart in the log whose reference positions are less
      than 2 m apart and where at least half of B's points lie within 0.2 m of A's under
      the reference relative pose; at most ``cap``, drawn at random (``seed``) among the
      candidates.

    Raises
    ------
    ScanError
        If a scan has no reference pose.
    """
    _check_references(scans)
    n = len(scans)
    return {
        "consecutive": evenly(consecutive_pairs(n, 1), cap),
        "skip3": evenly(consecutive_pairs(n, 3), cap),
        "revisit": revisit_pairs(scans, cap, seed),
    }
