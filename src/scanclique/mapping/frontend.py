"""The front end: consecutive association of scans (issue 12, part 1).

Each scan is matched by the library's matcher (paper §4–§6) against the current keyframe,
and the match is validated (paper §7) against a prior: the wheel odometry when the log has
it, else a constant-velocity prediction. When the match is rejected, ambiguous or has no
pose, the scan is placed by the prior itself: the odometry increment with its noise model,
or the constant-velocity prediction with an inflated covariance; the scan is flagged
(:attr:`Step.kind`), never an exception.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..config import MatchConfig
from ..geometry import Pose2
from ..match import PreparedScan, match_prepared, pose_score
from ..refine import icp_point_to_line, weak_direction
from ..uncertainty import pose_difference
from ..validation import (
    AMBIGUOUS,
    GATE_99,
    OdometryNoise,
    ValidationConfig,
    constellation_std,
    mahalanobis_sq,
    odometry_prior,
    validate_match,
)

_VALIDATION = ValidationConfig()

__all__ = [
    "MATCH",
    "ICP",
    "ODOMETRY",
    "CONSTANT_VELOCITY",
    "Step",
    "floored",
    "constant_velocity",
    "along_corridor",
    "contest_by_odometry",
    "associate",
]

MATCH = "match"
ICP = "icp"
ODOMETRY = "odometry"
CONSTANT_VELOCITY = "constant_velocity"


@dataclass(frozen=True, slots=True, eq=False)
class Step:
    """How one scan was placed relative to an earlier one.

    ``pose`` maps points of the new scan into the earlier scan's frame; ``covariance`` of
    its ``(x, y, theta)``; ``kind`` is ``"match"``, ``"odometry"`` or
    ``"constant_velocity"``; ``verdict`` the §7 verdict of the match (or why there was
    none); ``score`` the match's raw-scan agreement (NaN without a match); ``reason`` in
    words when the scan was not placed by a match."""

    pose: Pose2
    covariance: np.ndarray
    kind: str
    verdict: str
    score: float
    reason: str | None = None


def floored(P: np.ndarray | None, sigma_m: float, sigma_rad: float) -> np.ndarray:
    """``P`` plus ``diag(sigma_m², sigma_m², sigma_rad²)``; a missing or non-finite ``P``
    is replaced by a large one."""
    F = np.diag([sigma_m**2, sigma_m**2, sigma_rad**2])
    if P is None:
        return F * 1e4
    P = np.array(P, dtype=float)
    if not np.all(np.isfinite(P)):
        d = np.diag(P)
        P = np.diag(np.where(np.isfinite(d), d, 1e4))
    return 0.5 * (P + P.T) + F


def constant_velocity(
    prev2: Pose2 | None, prev: Pose2, t2: float | None, t1: float | None, t: float | None
) -> Pose2:
    """Predicted pose of the next scan from the last two (world frame): the last motion
    ``prev2^-1 prev`` repeated, scaled by the ratio of the time steps when timestamps are
    known (clipped to [0, 3])."""
    if prev2 is None:
        return prev
    v = prev2.inverse() @ prev
    ratio = 1.0
    if t2 is not None and t1 is not None and t is not None and t1 - t2 > 1e-6:
        ratio = float(np.clip((t - t1) / (t1 - t2), 0.0, 3.0))
    return prev @ Pose2(v.x * ratio, v.y * ratio, v.theta * ratio)


def refine_pose(pa: PreparedScan, pb: PreparedScan, pose: Pose2, fe) -> Pose2:
    """``pose`` (maps B into A) refined by point-to-line ICP of all of B's valid points onto
    A's full cloud (``fe`` a :class:`~scanclique.mapping.config.FrontEndConfig`); the
    pose unchanged when ICP strays more than ``fe.refine_max_shift`` / ``refine_max_turn``
    from it or pairs fewer than ``fe.refine_min_fitness`` of the points."""
    if not fe.refine or len(pb.points) < 10 or len(pa.points) < 10:
        return pose
    icp = icp_point_to_line(
        pa.cloud,
        np.ascontiguousarray(pb.points),
        pose,
        iterations=fe.refine_iterations,
        max_correspondence=fe.refine_max_correspondence,
        min_correspondence=fe.refine_min_correspondence,
    )
    t, r = icp.pose.distance_to(pose)
    if t > fe.refine_max_shift or r > fe.refine_max_turn or icp.fitness < fe.refine_min_fitness:
        return pose
    return icp.pose


def _quick_accept(m, prior_a, prior_b, noise, path) -> Pose2 | None:
    """The common case of the §7 test, cheaply: the match is not ambiguous, maps at least
    ``ValidationConfig.min_features`` features, its own covariance fixes the pose within
    the validation's limits, and it lies inside the chi-square gate of the odometry prior.
    Then :func:`~scanclique.validation.validate_match` would accept it too (it re-estimates
    the covariance from the agreeing features and looks for rivals, which the odometry
    gate settles here); anything else goes to the full validation."""
    if m.pose is None or m.ambiguous or m.covariance is None:
        return None
    vc = _VALIDATION
    if len(m.pairs) < vc.min_features or not np.all(np.isfinite(m.covariance)):
        return None
    s_xy, s_th = constellation_std(m.covariance)
    if s_xy > vc.max_std_metres or s_th > vc.max_std_radians:
        return None
    prior, prior_cov = odometry_prior(prior_a, prior_b, noise, path=path)
    if mahalanobis_sq(m.pose, m.covariance, prior, prior_cov) > GATE_99:
        return None
    return m.pose


def along_corridor(
    pk: PreparedScan,
    pj: PreparedScan,
    pose: Pose2,
    cov: np.ndarray,
    prior_a: Pose2,
    prior_b: Pose2,
    noise: OdometryNoise,
    fe,
) -> tuple[Pose2, np.ndarray]:
    """A consecutive match in a corridor: when the raw scans do not fix ``pose`` (maps B
    into A) along one direction ``e`` (:func:`weak_direction` below
    ``fe.icp_min_constraint``), only the features place it along ``e``, and doors and
    pillars repeat along corridors; the component along ``e`` is then the wheel
    odometry's (``prior_a^-1 prior_b``), with the odometry's variance along ``e`` added to
    ``cov``, as the ICP fallback does (:func:`icp_fallback`). ``(pose, cov)`` unchanged
    otherwise, or without a front-end config."""
    if fe is None or not fe.icp_fallback:
        return pose, cov
    weak = weak_direction(pk.cloud, np.ascontiguousarray(pj.points), pose, 0.1)
    if weak is None or weak[1] >= fe.icp_min_constraint:
        return pose, cov
    return _prior_along(pose, cov, weak[0], *odometry_prior(prior_a, prior_b, noise))


def _prior_along(pose: Pose2, cov: np.ndarray, e: np.ndarray, prior: Pose2, prior_cov):
    """``pose`` (maps B into A) with its translation's component along the unit direction
    ``e`` (A's frame) taken from ``prior``, and ``cov`` with the prior's variance along
    ``e`` added: what a corridor's raw scans leave to the motion model."""
    shift = e * float(e @ np.array([prior.x - pose.x, prior.y - pose.y]))
    cov = cov.copy()
    cov[:2, :2] += float(e @ prior_cov[:2, :2] @ e) * np.outer(e, e)
    return Pose2(pose.x + shift[0], pose.y + shift[1], pose.theta), cov


def contest_by_odometry(
    pk: PreparedScan, pj: PreparedScan, step: Step, odometry: Pose2, fe, config: MatchConfig
) -> Step:
    """A consecutive match the wheel odometry disagrees with: when the match's position
    lies outside the refinement's basin around the odometry increment ``odometry``
    (farther than ``fe.refine_max_shift`` m), point-to-line ICP of the raw scans from the
    odometry; when it converges outside the match's own 99 % ellipse (its covariance) and
    nearer the odometry, it is a second hypothesis. The raw scans decide between the
    two (:func:`scanclique.match.pose_score`); when they cannot (scores within
    ``fe.icp_score_tie``, e.g. slid along a corridor whose doors repeat), the one nearer
    the odometry is taken, as in :func:`icp_fallback`. ``step`` unchanged otherwise."""
    if fe is None or not fe.icp_fallback or step.kind != MATCH:
        return step
    t, r = step.pose.distance_to(odometry)
    if t <= fe.refine_max_shift:
        return step
    icp = icp_point_to_line(
        pk.cloud, np.ascontiguousarray(pj.points), odometry, iterations=2 * fe.refine_iterations,
        max_correspondence=fe.refine_max_correspondence,
        min_correspondence=fe.refine_min_correspondence,
    )  # fmt: skip
    if icp.fitness < fe.icp_min_fitness:
        return step
    if mahalanobis_sq(icp.pose, np.zeros((3, 3)), step.pose, step.covariance) <= GATE_99:
        return step  # ICP from the odometry went back to the match: one hypothesis
    if icp.pose.distance_to(odometry)[0] >= t:
        return step
    s_match = pose_score(pk, pj, step.pose, config)
    s_icp = pose_score(pk, pj, icp.pose, config)
    if s_icp < s_match - fe.icp_score_tie:
        return step
    cov = step.covariance.copy()
    d = np.array([icp.pose.x - step.pose.x, icp.pose.y - step.pose.y])
    # the two hypotheses' separation is the uncertainty the features left along it
    cov[:2, :2] += np.outer(d, d) / 4.0
    return Step(icp.pose, cov, ICP, "contested_by_odometry", float(s_icp),
                f"match {s_match:.2f} vs ICP from odometry {s_icp:.2f}")  # fmt: skip


def associate(
    pk: PreparedScan,
    pj: PreparedScan,
    prior_a: Pose2,
    prior_b: Pose2,
    noise: OdometryNoise,
    config: MatchConfig,
    *,
    path: list[Pose2] | None = None,
    sigma_floor: tuple[float, float] = (0.01, math.radians(0.25)),
    front_end=None,
    weak_prior: bool = False,
) -> Step:
    """Match scan ``j`` against keyframe ``k`` and validate it against the prior (the two
    scans' odometry poses, or predicted poses, ``prior_a``, ``prior_b``).

    With ``weak_prior`` (a constant-velocity prediction, not odometry) the match is
    validated on its own evidence first (no rival, enough well-placed features), and the
    prior only chooses among the hypotheses of an ambiguous match: a robot may turn
    sharply between two scans, which no velocity model predicts.

    Returns the accepted :class:`Step` (kind ``"match"``; the pose the validation chose,
    its feature covariance plus ``sigma_floor``), or a Step of kind ``"rejected"`` whose
    ``verdict``/``reason`` say why (the caller then places the scan by its prior).
    """
    m = match_prepared(pk, pj, config)
    quick = None if weak_prior else _quick_accept(m, prior_a, prior_b, noise, path)
    if quick is not None:
        pose = quick if front_end is None else refine_pose(pk, pj, quick, front_end)
        cov = floored(m.covariance, *sigma_floor)
        if not weak_prior:
            pose, cov = along_corridor(pk, pj, pose, cov, prior_a, prior_b, noise, front_end)
        return Step(pose, cov, MATCH, "accepted", float(m.score))
    if weak_prior:
        # no odometry (the paper's setting): the match validates itself (§7: enough
        # features that fix the pose, no rival); the prediction only breaks a tie
        v = validate_match(m)
        if v.verdict == AMBIGUOUS:
            v = validate_match(m, prior_a, prior_b, noise, path=path)
    else:
        v = validate_match(m, prior_a, prior_b, noise, path=path)
    if v.accepted and v.pose is not None:
        cov = v.covariance if v.covariance is not None else m.covariance
        pose = v.pose if front_end is None else refine_pose(pk, pj, v.pose, front_end)
        cov = floored(cov, *sigma_floor)
        if not weak_prior:
            pose, cov = along_corridor(pk, pj, pose, cov, prior_a, prior_b, noise, front_end)
        return Step(pose, cov, MATCH, v.verdict, float(m.score))
    reason = "; ".join(v.reasons) if v.reasons else (m.reason or v.verdict)
    seed = m.pose if m.pose is not None else prior_a.inverse() @ prior_b
    return Step(seed, np.eye(3), "rejected", v.verdict, float(m.score), reason)


def icp_from_seeds(
    pk: PreparedScan, pj: PreparedScan, seeds, fe, config: MatchConfig
) -> list[tuple[Pose2, float]]:
    """Point-to-line ICP of all of scan ``j``'s points onto scan ``k``'s cloud from each
    of ``seeds`` (poses mapping ``j`` into ``k``): ``(pose, raw-scan score)`` of each run
    that paired at least ``fe.icp_min_fitness`` of the points, in seed order."""
    pts = np.ascontiguousarray(pj.points)
    found = []
    for seed in seeds:
        icp = icp_point_to_line(
            pk.cloud,
            pts,
            seed,
            iterations=2 * fe.refine_iterations,
            max_correspondence=0.5,
            min_correspondence=fe.refine_min_correspondence,
        )
        if icp.fitness >= fe.icp_min_fitness:
            found.append((icp.pose, float(pose_score(pk, pj, icp.pose, config))))
    return found


def within_gate(pose: Pose2, prior: Pose2, sigmas, gate: float) -> bool:
    """Whether each of ``pose``'s ``(x, y, theta)`` lies within ``gate`` standard
    deviations ``sigmas`` (m, m, rad) of ``prior``'s (the angle wrapped)."""
    return bool(np.all(np.abs(pose_difference(pose, prior)) <= gate * np.asarray(sigmas)))


def icp_fallback(
    pk: PreparedScan,
    pj: PreparedScan,
    seeds: list[Pose2],
    priors: list[tuple[Pose2, np.ndarray]],
    fe,
    config: MatchConfig,
    ungated: float | None = None,
) -> Step | None:
    """When the feature match fails: point-to-line ICP of all of scan ``j``'s points onto
    keyframe ``k``'s cloud from each seed (the priors, a rejected match's pose), the one
    the raw scans agree with best. Accepted (kind ``"icp"``) when its raw-scan score
    (:func:`scanclique.match.pose_score`) is at least ``fe.icp_min_score``, ICP paired at
    least ``fe.icp_min_fitness`` of the points, and it lies within ``fe.icp_gate`` sigma
    (per coordinate) of at least one of the ``priors`` (wheel odometry and the
    constant-velocity prediction of the chain: two independent motion estimates, so that
    a wheel slip or a reversing robot whose odometry disagrees with the scans does not
    break the chain), or scores at least ``ungated`` and lies within
    ``fe.icp_ungated_max_turn`` / ``icp_ungated_max_shift`` of the first prior (without
    odometry: a sharp turn no velocity model predicts, that the raw scans confirm, but no
    half-turn: a corridor turned by 180 degrees matches as well); its covariance is ``2 x``
    the floor plus a hundredth of the first prior's. With wheel odometry (``ungated`` None)
    ICP poses the scans cannot tell apart (scores within ``fe.icp_score_tie``) go to the
    one nearest the odometry, and in a corridor (:func:`weak_direction` below
    ``fe.icp_min_constraint``) the component along it is the odometry's. None otherwise."""
    found = icp_from_seeds(pk, pj, seeds, fe, config)
    if not found or max(sc for _, sc in found) < fe.icp_min_score:
        return None
    # poses the raw scans cannot tell apart (scores within ``icp_score_tie`` of the best,
    # e.g. slid along a corridor): the wheel odometry (the first prior) decides; without
    # it the best score does (a constant-velocity guess is no measurement: a robot that
    # stops at a door moves nothing where it predicts a full step)
    top = max(sc for _, sc in found)
    p0, c0 = priors[0]
    measured = ungated is None
    pose, score = min(
        (f for f in found if f[1] >= top - fe.icp_score_tie) if measured else found,
        key=lambda f: mahalanobis_sq(f[0], np.zeros((3, 3)), p0, c0) if measured else -f[1],
    )
    inside = any(
        within_gate(pose, prior, np.sqrt(np.diag(prior_cov)), fe.icp_gate)
        for prior, prior_cov in priors
    )
    if not inside:
        if ungated is None or score < ungated:
            return None
        # ungated (no odometry): still a plausible motion from the first prior; a corridor
        # turned by 180 degrees explains the scans as well as the right pose does
        d = priors[0][0].inverse() @ pose
        if (
            abs(d.theta) > fe.icp_ungated_max_turn
            or math.hypot(d.x, d.y) > fe.icp_ungated_max_shift
        ):
            return None
    cov = floored(priors[0][1] * 0.01, 2 * fe.sigma_floor_metres, 2 * fe.sigma_floor_radians)
    weak = (
        weak_direction(pk.cloud, np.ascontiguousarray(pj.points), pose, 0.1) if measured else None
    )
    if measured and weak is not None and weak[1] < fe.icp_min_constraint:
        # the scans do not fix the pose along ``e`` (a corridor): ICP slides along it as
        # far as its seed allows; take that component from the prior (the first one, the
        # motion model) and give the edge the prior's uncertainty along it
        pose, cov = _prior_along(pose, cov, weak[0], *priors[0])
        score = pose_score(pk, pj, pose, config)
    return Step(pose, cov, ICP, "icp", float(score))


def prior_step(
    a: Pose2, b: Pose2, noise: OdometryNoise, kind: str, reason: str, verdict: str, score: float
) -> Step:
    """Place ``b`` relative to ``a`` by the prior itself (odometry or constant velocity),
    with the covariance of the noise model."""
    rel, cov = odometry_prior(a, b, noise)
    return Step(rel, cov, kind, verdict, score, reason)
