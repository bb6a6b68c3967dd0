"""Loop-closure candidates and their verification (issue 12, part 2).

Candidates for keyframe ``j`` (:func:`candidates`):

* by the estimate: earlier keyframes whose estimated position lies within a radius that
  grows with the drift the estimate may have accumulated between them (the path since
  the last accepted closure, or since the candidate, whichever is shorter), nearest first,
  at least ``separation`` keyframes apart;
* by appearance (:func:`appearance_candidates`): the keyframes whose rotation-invariant
  signature (:func:`scanclique.places.signature.scan_signature`, when that module is
  installed) is nearest, whatever the estimate says: they catch a loop after a drift
  larger than the radius.

Each candidate is verified by the matcher and the §7 validation with the current estimate
as the prior (:func:`verify`): ambiguous and contested matches are not closures.
"""

from __future__ import annotations

import importlib
import logging
import math
from dataclasses import dataclass

import numpy as np

from ..config import MatchConfig
from ..geometry import Pose2
from ..match import PreparedScan, match_prepared, pose_score
from ..refine import weak_direction
from ..validation import OdometryNoise, validate_match
from .config import LoopConfig
from .frontend import _quick_accept, floored, refine_pose

__all__ = [
    "LoopClosure",
    "drift_std",
    "candidates",
    "signature_module",
    "appearance_candidates",
    "verify",
]

log = logging.getLogger(__name__)


@dataclass(frozen=True, slots=True, eq=False)
class LoopClosure:
    """One verified loop-closure candidate between scans ``i < j``.

    ``pose`` maps points of scan ``j`` into scan ``i`` (None when the match had none);
    ``covariance`` of its ``(x, y, theta)``; ``verdict`` is the §7 verdict
    (``accepted``, ``rejected_odometry`` meaning here *rejected by the estimate's prior*,
    ``ambiguous``, ``too_few_features``) or ``"pcm_rejected"``, ``"low_score"``,
    ``"imprecise"`` (its covariance too loose: :class:`~.config.LoopConfig`) or
    ``"degenerate"`` (the raw scans do not fix the pose in one direction, a corridor;
    :func:`scanclique.refine.weak_direction`); ``accepted`` whether it
    entered the pose graph; ``local`` True for a match with a nearby keyframe on the
    local chain (not a loop); ``source`` ``"estimate"`` or ``"appearance"``; ``score``
    the raw-scan agreement; ``reason`` in words."""

    i: int
    j: int
    pose: Pose2 | None
    covariance: np.ndarray | None
    verdict: str
    accepted: bool
    local: bool
    source: str
    score: float
    reason: str = ""

    def to_dict(self) -> dict:
        p = self.pose
        return {
            "i": self.i,
            "j": self.j,
            "pose": None if p is None else [p.x, p.y, p.theta],
            "verdict": self.verdict,
            "accepted": self.accepted,
            "local": self.local,
            "source": self.source,
            "score": self.score if math.isfinite(self.score) else None,
            "reason": self.reason,
        }


def drift_std(path: float, cfg: LoopConfig) -> tuple[float, float]:
    """``(sigma_xy m, sigma_theta rad)`` the estimate may have drifted over ``path`` metres
    (a third of the candidate radius, the radius being a 3-sigma bound)."""
    r = min(cfg.radius + cfg.growth * path, cfg.max_radius)
    s_th = math.radians(2.0) + cfg.heading_growth * path
    return r / 3.0, min(s_th, math.radians(30.0))


def candidates(
    j: int,
    xy: np.ndarray,
    cum_path: np.ndarray,
    since_closure: float,
    cfg: LoopConfig,
    exclude: set[int] | frozenset[int] = frozenset(),
) -> list[int]:
    """Loop candidates of keyframe ``j`` by the estimate (keyframe indices, nearest first).

    Parameters
    ----------
    j : int
        Index of the keyframe (into ``xy``); candidates are ``i < j`` with a path of at
        least ``cfg.min_path`` between them.
    xy : ndarray (>= j + 1, 2)
        Estimated keyframe positions (map frame).
    cum_path : ndarray (>= j + 1,)
        Path length travelled up to each keyframe (m).
    since_closure : float
        Path travelled since the last accepted closure (m); ``inf`` before the first.
    """
    far = np.flatnonzero(cum_path[j] - cum_path[:j] >= cfg.min_path)
    if far.size == 0:
        return []
    drift = np.minimum(cum_path[j] - cum_path[far], since_closure)
    radius = np.minimum(cfg.radius + cfg.growth * drift, cfg.max_radius)
    d = np.hypot(*(xy[far] - xy[j]).T)
    inside = far[d <= radius]
    order = inside[np.argsort(d[d <= radius], kind="stable")]
    chosen: list[int] = []
    for i in order.tolist():
        if i in exclude:
            continue
        if all(abs(i - c) >= cfg.separation for c in chosen):
            chosen.append(i)
        if len(chosen) >= cfg.per_keyframe:
            break
    return chosen


def signature_module():
    """``scanclique.places.signature`` when it exists (the place-recognition package),
    else None: appearance candidates are then not proposed."""
    try:
        return importlib.import_module("scanclique.places.signature")
    except ImportError:
        return None


def appearance_candidates(
    j: int, signatures: np.ndarray, cum_path: np.ndarray, cfg: LoopConfig, k: int = 1
) -> list[int]:
    """The ``k`` earlier keyframes (path at least ``cfg.min_path`` back) whose signature is
    nearest to keyframe ``j``'s (squared Euclidean distance of signatures)."""
    far = np.flatnonzero(cum_path[j] - cum_path[:j] >= cfg.min_path)
    if far.size == 0:
        return []
    d = ((signatures[far] - signatures[j]) ** 2).sum(axis=1)
    return far[np.argsort(d, kind="stable")[:k]].tolist()


def verify(
    pi: PreparedScan,
    pj: PreparedScan,
    est_i: Pose2,
    est_j: Pose2,
    sigma: tuple[float, float],
    config: MatchConfig,
    sigma_floor: tuple[float, float],
    front_end=None,
    quick: bool = False,
    strict: bool = False,
) -> tuple[Pose2 | None, np.ndarray | None, str, float, str]:
    """Match scan ``j`` against scan ``i`` and validate the match (§7) against the current
    estimate ``est_i^-1 est_j`` with standard deviations ``sigma`` (m, rad).

    ``quick``: accept through the cheap form of the test first
    (:func:`scanclique.mapping.frontend._quick_accept`; for the local neighbours, whose
    prior is the well-known chain). Otherwise (a loop candidate) the prior may not choose
    another hypothesis than the matcher's best, and the returned score is the raw-scan
    agreement at the refined pose, and the raw scans must fix that pose in every direction
    (verdict ``"degenerate"`` otherwise: in a corridor only the features place a closure,
    and doors repeat along corridors). ``strict`` (appearance candidates): the match must be
    accepted without the prior too.

    Returns ``(pose, covariance, verdict, score, reason)``; pose and covariance are None
    unless the verdict is ``accepted``.
    """
    m = match_prepared(pi, pj, config)
    noise = OdometryNoise(0.0, 0.0, 0.0, sigma[0], sigma[1])
    if quick:
        q = _quick_accept(m, est_i, est_j, noise, None)
        if q is not None:
            pose = q if front_end is None else refine_pose(pi, pj, q, front_end)
            return pose, floored(m.covariance, *sigma_floor), "accepted", float(m.score), ""
    if strict:
        # appearance candidates: the match must stand on its own (no rival anywhere, §7),
        # and the prior may only veto it, never choose another hypothesis
        v0 = validate_match(m)
        if not v0.accepted:
            return None, None, v0.verdict, float(m.score), "; ".join(v0.reasons)
    v = validate_match(m, est_i, est_j, noise)
    if not quick and v.accepted and v.hypothesis != 0:
        # a loop's prior (the drift model) is too broad to choose between the matcher's
        # hypotheses: it may only veto the best one
        return None, None, "ambiguous", float(m.score), "the prior chose another hypothesis"
    reason = "; ".join(v.reasons)
    if v.accepted and v.pose is not None:
        cov = v.covariance if v.covariance is not None else m.covariance
        pose = v.pose if front_end is None else refine_pose(pi, pj, v.pose, front_end)
        score = float(m.score)
        if not quick:
            # the pose that enters the graph is the refined one: score the raw scans there
            score = float(pose_score(pi, pj, pose, config))
            if front_end is not None:
                weak = weak_direction(pi.cloud, np.ascontiguousarray(pj.points), pose, 0.1)
                if weak is not None and weak[1] < front_end.icp_min_constraint:
                    # a corridor: the raw scans do not fix the closure along it, only the
                    # features do, and doors and pillars repeat along corridors
                    e = weak[0]
                    why = (
                        f"the raw scans do not fix the pose along ({e[0]:.2f}, {e[1]:.2f}) "
                        f"(eigenvalue {weak[1]:.3f} < front_end.icp_min_constraint="
                        f"{front_end.icp_min_constraint:g})"
                    )
                    return None, None, "degenerate", score, why
        return pose, floored(cov, *sigma_floor), v.verdict, score, reason
    return None, None, v.verdict, float(m.score), reason
