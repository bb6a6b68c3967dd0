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
from ..refine import icp_covariance, weak_direction
from ..validation import OdometryNoise, validate_match
from .config import LoopConfig
from .frontend import _quick_accept, floored, icp_from_seeds, refine_pose, within_gate

__all__ = [
    "LoopClosure",
    "drift_std",
    "candidates",
    "signature_module",
    "appearance_candidates",
    "verify",
    "verify_by_icp",
    "closure_doubt",
    "LOOK_ALIKES",
]

log = logging.getLogger(__name__)

#: the verdicts of the closures refused as look-alike places (:class:`LoopClosure`): a
#: corner a quarter or half turn round, a door or two along a corridor, a twin room
LOOK_ALIKES = ("turned", "shifted", "conflicting")


@dataclass(frozen=True, slots=True, eq=False)
class LoopClosure:
    """One verified loop-closure candidate between scans ``i < j``.

    ``pose`` maps points of scan ``j`` into scan ``i`` (None when the match had none);
    ``covariance`` of its ``(x, y, theta)``; ``verdict`` is the §7 verdict
    (``accepted``, ``rejected_odometry`` meaning here *rejected by the estimate's prior*,
    ``ambiguous``, ``too_few_features``) or ``"pcm_rejected"``, ``"low_score"``,
    ``"imprecise"`` (its covariance too loose: :class:`~.config.LoopConfig`),
    ``"turned"`` (it turns the estimate by more than ``max_turn``: a look-alike a quarter
    or half turn round), ``"shifted"`` (it moves the estimate by more than ``max_shift``
    of the path between the two: a look-alike along the way), ``"conflicting"`` (it moves
    the estimate beyond the front end's and the drift model's bounds and its raw scans see
    through each other's points: a twin place), ``"uncorroborated"`` or
    ``"degenerate"`` (the raw scans do not fix the pose in one direction, a corridor;
    :func:`scanclique.refine.weak_direction`); ``accepted`` whether it
    entered the pose graph; ``local`` True for a match with a nearby keyframe on the
    local chain (not a loop); ``source`` ``"estimate"``, ``"chain"`` (near where the front
    end's chain puts ``j``, where it and the estimate disagree) or ``"appearance"``; ``score``
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
    front_sigma: np.ndarray | None = None,
    among: np.ndarray | None = None,
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
    since_closure : float or ndarray (>= j,)
        Path travelled since the last accepted closure (m; ``inf`` before the first), or
        per keyframe the path over which the estimate may have drifted from it (the
        mapper's ``drift_path``); the chain's path is used where shorter.
    among : ndarray of bool (>= j,), optional
        The keyframes that may be candidates (all when None).
    """
    far = np.flatnonzero(cum_path[j] - cum_path[:j] >= cfg.min_path)
    if among is not None:
        far = far[among[far]]
    if far.size == 0:
        return []
    since = np.asarray(since_closure)[far] if np.ndim(since_closure) else since_closure
    drift = np.minimum(cum_path[j] - cum_path[far], since)
    radius = np.minimum(cfg.radius + cfg.growth * drift, cfg.max_radius)
    if front_sigma is not None:
        radius = np.maximum(radius, 3.0 * front_sigma[far])
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
    # the path grows along the keyframes, so ``far`` is mostly their first ones: a view
    # then, not a copy
    rows = slice(0, far.size) if far[-1] == far.size - 1 else far
    d = ((signatures[rows] - signatures[j]) ** 2).sum(axis=1)
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
    if v.verdict == "too_few_features" and not strict and front_end is not None:
        if front_end.icp_fallback:
            # too few features to map (a corridor, a bare room): the raw scans alone, from
            # the estimate, when they fix the pose on their own
            return verify_by_icp(pi, pj, est_i.inverse() @ est_j, sigma, config, sigma_floor,
                                 front_end)  # fmt: skip
    return None, None, v.verdict, float(m.score), reason


def closure_doubt(cov: np.ndarray, score: float, cfg: LoopConfig) -> tuple[str, str] | None:
    """Why a loop closure that :func:`verify` accepted is still not taken: its raw-scan
    ``score`` below ``cfg.min_score`` (verdict ``"low_score"``), or its covariance
    ``cov`` giving a standard deviation above ``cfg.max_sigma_metres`` (largest of the
    position's) or ``cfg.max_sigma_radians`` (``"imprecise"``). Returns ``(verdict,
    reason)``, None when neither."""
    if score < cfg.min_score:
        return "low_score", f"raw-scan score {score:.2f} < loops.min_score={cfg.min_score:g}"
    s_xy = math.sqrt(max(float(np.linalg.eigvalsh(cov[:2, :2])[-1]), 0.0))
    s_th = math.sqrt(max(float(cov[2, 2]), 0.0))
    if s_xy > cfg.max_sigma_metres or s_th > cfg.max_sigma_radians:
        return "imprecise", (
            f"its covariance gives sigma {s_xy:.3f} m / {math.degrees(s_th):.2f} deg > "
            f"loops.max_sigma_metres={cfg.max_sigma_metres:.3f} / max_sigma_radians="
            f"{math.degrees(cfg.max_sigma_radians):.2f} deg"
        )
    return None


def verify_by_icp(
    pi: PreparedScan,
    pj: PreparedScan,
    prior: Pose2,
    sigma: tuple[float, float],
    config: MatchConfig,
    sigma_floor: tuple[float, float],
    fe,
) -> tuple[Pose2 | None, np.ndarray | None, str, float, str]:
    """A loop candidate that maps too few features, verified on the raw scans alone.

    Point-to-line ICP of all of scan ``j``'s points onto scan ``i``'s cloud from the
    estimate ``prior`` (maps ``j`` into ``i``) and from six seeds one ``sigma`` (m, rad:
    the drift the estimate may have) away from it along x, y and theta. It is
    ``accepted`` only when all of these hold (else the verdict in brackets):

    1. the best-scoring converged pose (ICP paired at least ``fe.icp_min_fitness`` of the
       points) has a raw-scan score of at least ``fe.icp_min_score`` [``low_score``];
    2. every converged seed that scores within ``fe.icp_score_tie`` of it lands within
       0.05 m and 0.5 deg of it: one basin, not a corridor's or a look-alike's several
       [``ambiguous``];
    3. it lies within ``fe.icp_gate`` sigma (per coordinate) of the estimate
       [``rejected_odometry``];
    4. the raw scans fix its translation in every direction
       (:func:`scanclique.refine.weak_direction` at least ``fe.icp_min_constraint``)
       [``degenerate``].

    Its covariance is the alignment's curvature
    (:func:`scanclique.refine.icp_covariance`) floored by ``sigma_floor``. Returns
    ``(pose, covariance, verdict, score, reason)`` as :func:`verify` does.
    """
    pts = np.ascontiguousarray(pj.points)
    s_xy, s_th = sigma
    seeds = [prior] + [
        prior @ Pose2(dx, dy, dt)
        for dx, dy, dt in (
            (s_xy, 0, 0), (-s_xy, 0, 0), (0, s_xy, 0), (0, -s_xy, 0), (0, 0, s_th), (0, 0, -s_th)
        )
    ]  # fmt: skip
    found = icp_from_seeds(pi, pj, seeds, fe, config)
    pose, score = max(found, key=lambda f: f[1]) if found else (None, 0.0)

    def no(verdict: str, reason: str):
        return None, None, verdict, score, reason

    if pose is None or score < fe.icp_min_score:
        return no("low_score", f"ICP: raw-scan score {score:.3f} < {fe.icp_min_score:g}")
    for other, sc in found:
        dt, dr = other.distance_to(pose)
        if sc >= score - fe.icp_score_tie and (dt > 0.05 or dr > math.radians(0.5)):
            why = f"ICP from another seed: {dt:.2f} m, {math.degrees(dr):.1f} deg away, {sc:.3f}"
            return no("ambiguous", why)
    if not within_gate(pose, prior, (s_xy, s_xy, s_th), fe.icp_gate):
        return no("rejected_odometry", f"ICP pose beyond {fe.icp_gate:g} sigma of the estimate")
    weak = weak_direction(pi.cloud, pts, pose, 0.1)
    if weak is None or weak[1] < fe.icp_min_constraint:
        return no("degenerate", "ICP: the raw scans do not fix the pose in one direction")
    cov = icp_covariance(pi.cloud, pts, pose, fe.refine_min_correspondence)
    if cov is None:
        return no("degenerate", "ICP: the pairs leave the pose unconstrained")
    why = f"too few features: ICP from the estimate, score {score:.3f}, weakest {weak[1]:.3f}"
    return pose, floored(cov, *sigma_floor), "accepted", score, why
