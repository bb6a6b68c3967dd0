"""Pair sets for the benchmarks: consecutive, skip, and revisit pairs of a log with
reference poses (shared by ``accuracy.py`` and the other benchmarks). The pair sets are
those of the library, :mod:`scanclique.pairsets` (the same as ``scanclique validate``):

* consecutive: ``(i, i + 1)``;
* skip: ``(i, i + 3)``;
* revisit: scans at least 50 apart in the log whose reference positions are less than 2 m
  apart and where at least half of B's points lie within 0.2 m of A's points under the
  reference relative pose (so that the two scans really see the same place).

A pair *succeeds* when the estimated relative pose is within 0.20 m and 2 degrees of the
reference ``ref_a.inverse() @ ref_b`` (:func:`scanclique.eval.success.is_right`).
"""

from __future__ import annotations

from scanclique import pairsets
from scanclique.eval.success import RIGHT_ROTATION as SUCCESS_ROTATION
from scanclique.eval.success import RIGHT_TRANSLATION as SUCCESS_TRANSLATION
from scanclique.eval.success import is_success
from scanclique.pairsets import *  # noqa: F403 (this module re-exports the library's pair sets)

__all__ = ["SUCCESS_TRANSLATION", "SUCCESS_ROTATION", *pairsets.__all__, "is_success"]
