"""The success rule of the benchmarks (DESIGN.md): one home for it.

A scan pair is a **success** when the estimated relative pose is within 0.20 m and 2° of
the reference. ``benchmarks/``, ``scanclique validate`` and the CLI's error rows all ask
this module.

>>> from scanclique.geometry import Pose2
>>> is_right(Pose2(0.1, 0.1, 0.01), Pose2(0.0, 0.0, 0.0))
True
>>> is_success(0.25, 0.0)
False
"""

from __future__ import annotations

import math

from ..geometry import Pose2

__all__ = ["RIGHT_ROTATION", "RIGHT_TRANSLATION", "is_right", "is_success"]

RIGHT_TRANSLATION = 0.20
"""Largest translation error of a success (metres)."""
RIGHT_ROTATION = math.radians(2.0)
"""Largest rotation error of a success (radians)."""


def is_success(t_err: float, r_err: float) -> bool:
    """True when a translation error ``t_err`` (m) and a rotation error ``r_err`` (rad)
    make a success (at most 0.20 m and 2 degrees)."""
    return t_err <= RIGHT_TRANSLATION and r_err <= RIGHT_ROTATION


def is_right(pose: Pose2 | None, reference: Pose2) -> bool:
    """True when ``pose`` is within 0.20 m and 2 degrees of ``reference`` (False when
    there is no pose)."""
    if pose is None:
        return False
    return is_success(*pose.distance_to(reference))
