"""The front end: consecutive association of scans (issue 12, part 1).

Each scan is matched by the library's matcher (paper §4–§6) against the current keyframe.

* With wheel odometry (:func:`associate`, :func:`contest_by_odometry`,
  :func:`icp_fallback`) the match is validated (paper §7) against the odometry; when it is
  rejected, ambiguous or has no pose, ICP of the raw scans from the odometry, then the
  odometry increment itself with its noise model.
* Without odometry (the paper's setting: :func:`associate_by_scans`) the match is
  validated on its own evidence, and where it fails or turns unexpectedly the raw scans
  choose among ICP candidates (:func:`scan_candidates`, :func:`choose_by_scans`), a
  learnt constant-velocity model (:class:`VelocityModel`) only weighing in where they
  leave a choice; where even they cannot place the scan, the prediction does, with the
  heading uncertainty the prediction has proved to have.

A scan placed by a prior is flagged (:attr:`Step.kind`), never an exception.
"""

from __future__ import annotations

import bisect
import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from ..config import MatchConfig
from ..geometry import Pose2, rotation_matrix
from ..match import PreparedScan, distinct_poses, match_prepared, pose_score, prepare_scan
from ..refine import agreement, icp_covariance, icp_point_to_line, weak_direction
from ..scan import Scan
from ..uncertainty import pose_difference
from ..validation import (
    AMBIGUOUS,
    GATE_99,
    REJECTED_ODOMETRY,
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
    "reversed_increment",
    "odometry_sees_reversing",
    "ReversingWatch",
    "along_corridor",
    "corridor_direction",
    "contest_by_odometry",
    "associate",
    "VelocityModel",
    "soften",
    "scan_candidates",
    "surprise",
    "choose_by_scans",
    "associate_by_scans",
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
    words when the scan was not placed by a match. ``loose`` (without odometry): the
    ``(2, 2)`` part of ``covariance``'s translation block that the motion model added
    along a direction the raw scans fix loosely (:func:`soften`, a corridor's axis), or
    all of it for a scan placed by the prediction alone, in the earlier scan's frame; None
    when it added nothing. The next prediction inherits it
    (:meth:`VelocityModel.carried`). ``along_prior``: a match whose position along a
    corridor is the prior's (:func:`along_corridor`), which it therefore cannot
    confirm."""

    pose: Pose2
    covariance: np.ndarray
    kind: str
    verdict: str
    score: float
    reason: str | None = None
    loose: np.ndarray | None = None
    along_prior: bool = False


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


def reversed_increment(rel: Pose2) -> Pose2:
    """The odometry increment ``rel`` (x, y in m, theta in rad: the later pose in the
    earlier one's frame) driven backwards: the same wheel speeds with the translation's sign
    flipped, ``(-x, -y, theta)``. For odometry that measures the speed's magnitude only.

    >>> reversed_increment(Pose2(0.1, 0.01, 0.05)).as_array().round(3).tolist()
    [-0.1, -0.01, 0.05]
    """
    return Pose2(-rel.x, -rel.y, rel.theta)


class ReversingWatch:
    """:func:`odometry_sees_reversing` one scan at a time, for a log still being recorded:
    :meth:`see` each scan's odometry (None for a scan without), then :attr:`sees_reversing`
    is the answer over the scans seen so far.

    >>> w = ReversingWatch()
    >>> for i in range(60):
    ...     w.see(Pose2(0.1 * i, 0.0, 0.0))
    >>> w.sees_reversing
    False
    """

    def __init__(self, min_step: float = 0.01, min_moving: int = 50) -> None:
        self.min_step, self.min_moving = min_step, min_moving
        self.moving = 0  # increments forwards by more than min_step so far
        self.backwards = False  # some increment backwards by more than min_step
        self.prev: Pose2 | None = None

    def see(self, odometry: Pose2 | None) -> None:
        """Take the next scan's odometry pose (None: the scan carries none)."""
        if odometry is None:
            return
        if self.prev is not None:
            dx = (self.prev.inverse() @ odometry).x
            self.backwards = self.backwards or dx < -self.min_step
            self.moving += dx > self.min_step
        self.prev = odometry

    @property
    def sees_reversing(self) -> bool:
        return self.backwards or self.moving < self.min_moving


def odometry_sees_reversing(
    scans: Sequence[Scan], min_step: float = 0.01, min_moving: int = 50
) -> bool:
    """Whether the scans' wheel odometry can report the robot backing up: True when some
    consecutive odometry increment moves backwards by more than ``min_step`` (m, along its
    own heading), or when fewer than ``min_moving`` increments move more than ``min_step``
    at all (too little driving to tell). False for odometry that only ever moves forwards
    over a whole log although it drives: it measures the speed's magnitude, and a robot
    that reverses is logged as driving forwards (the raw fr079 log: 0 of 4062 moving steps
    backwards, while its scans and its benchmark relations back up at scans 1400-1434).
    :class:`ReversingWatch` tells it as the scans come.

    >>> from scanclique.scan import Scan
    >>> fwd = [Scan([1.0], [0.0], odometry=Pose2(0.1 * i, 0.0, 0.0)) for i in range(60)]
    >>> odometry_sees_reversing(fwd), odometry_sees_reversing(fwd[::-1])
    (False, True)
    >>> odometry_sees_reversing(fwd[:10])  # too little driving to tell
    True
    """
    watch = ReversingWatch(min_step, min_moving)
    for s in scans:
        watch.see(s.odometry)
        if watch.backwards:
            return True
    return watch.sees_reversing


def step_scale(steps, min_step: float = 0.02) -> tuple[float, int]:
    """The median ratio of the odometry's step length to the scans' over ``steps``, pairs
    ``(scan_step, odometry_step)`` of :class:`Pose2` increments, counting those whose scan
    step moves at least ``min_step`` m; ``(nan, 0)`` when none does. About 1 for right
    odometry (the shared logs: 0.92-1.06), 0 for one that never moves or stopped
    changing, about 1000 for one in millimetres.

    >>> step_scale([(Pose2(0.2, 0.0, 0.0), Pose2(0.19, 0.01, 0.0)),
    ...             (Pose2(0.01, 0.0, 0.0), Pose2(0.0, 0.0, 0.0))])   # the second: too short
    (0.951315, 1)
    """
    r = [
        math.hypot(o.x, o.y) / math.hypot(s.x, s.y)
        for s, o in steps
        if math.hypot(s.x, s.y) >= min_step
    ]
    return (round(float(np.median(r)), 6), len(r)) if r else (math.nan, 0)


def sample_odometry_scale(
    scans: Sequence[Scan],
    config: MatchConfig,
    enough: int = 30,
    tries: int = 240,
    min_step: float = 0.02,
) -> tuple[float, int]:
    """:func:`step_scale` of consecutive pairs of scans spread over the log, each matched
    with no prior and accepted by its own validation (paper §7: no rival, enough
    features; the odometry plays no part), against the scans' odometry: ``(median ratio,
    pairs)``. It tries up to ``tries`` pairs evenly spaced over the log, in an order that
    spreads any prefix of them over the whole log, until ``enough`` have moved at least
    ``min_step`` m, each scan prepared with ``config``. What
    :func:`~scanclique.mapping.map_scans` checks before it trusts a log's odometry: a
    converted log whose odometry is all zeros, an odometry that froze, or one in
    millimetres."""
    n = len(scans)
    if n < 2:
        return math.nan, 0
    grid = np.unique(np.linspace(0, n - 2, min(tries, n - 1)).astype(int))
    order = grid[np.argsort((np.arange(len(grid)) * 0.6180339887498949) % 1.0, kind="stable")]
    steps = []
    for k in order.tolist():
        a, b = scans[k], scans[k + 1]
        if a.odometry is None or b.odometry is None:
            continue
        v = validate_match(match_prepared(prepare_scan(a, config), prepare_scan(b, config)))
        if v.accepted and v.pose is not None and math.hypot(v.pose.x, v.pose.y) >= min_step:
            steps.append((v.pose, a.odometry.inverse() @ b.odometry))
            if len(steps) >= enough:
                break
    return step_scale(steps, min_step)


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
) -> tuple[Pose2, np.ndarray, bool]:
    """A consecutive match in a corridor: when the raw scans do not fix ``pose`` (maps B
    into A) along one direction ``e`` (:func:`corridor_direction`), only the features
    place it along ``e``, and doors and pillars repeat along corridors; the component along
    ``e`` is then the wheel odometry's (``prior_a^-1 prior_b``), with the odometry's
    variance along ``e`` added to ``cov``, as the ICP fallback does (:func:`icp_fallback`).
    Returns ``(pose, cov, taken)``, ``taken`` whether the prior's component was taken (the
    pose then cannot confirm the prior along ``e``); ``(pose, cov, False)`` unchanged
    otherwise, or without a front-end config."""
    e = corridor_direction(pk, pj, pose, fe)
    if e is None:
        return pose, cov, False
    return *_prior_along(pose, cov, e, *odometry_prior(prior_a, prior_b, noise)), True


def corridor_direction(pk: PreparedScan, pj: PreparedScan, pose: Pose2, fe) -> np.ndarray | None:
    """The unit direction (A's frame) along which the raw scans leave ``pose`` (maps B into
    A) free (:func:`weak_direction` below ``fe.icp_min_constraint``: a corridor), where
    :func:`along_corridor` takes the prior's component: a pose matched against a prior
    cannot confirm that prior along it. None when the scans fix every direction, or without
    a front-end config (or with ``fe.icp_fallback`` off)."""
    if fe is None or not fe.icp_fallback:
        return None
    weak = weak_direction(pk.cloud, np.ascontiguousarray(pj.points), pose, 0.1)
    return None if weak is None or weak[1] >= fe.icp_min_constraint else weak[0]


def _prior_along(pose: Pose2, cov: np.ndarray, e: np.ndarray, prior: Pose2, prior_cov):
    """``pose`` (maps B into A) with its translation's component along the unit direction
    ``e`` (A's frame) taken from ``prior``, and ``cov`` with the prior's variance along
    ``e`` added: what a corridor's raw scans leave to the motion model."""
    shift = e * float(e @ np.array([prior.x - pose.x, prior.y - pose.y]))
    cov = cov.copy()
    cov[:2, :2] += float(e @ prior_cov[:2, :2] @ e) * np.outer(e, e)
    return Pose2(pose.x + shift[0], pose.y + shift[1], pose.theta), cov


def contest_by_odometry(
    pk: PreparedScan,
    pj: PreparedScan,
    step: Step,
    odometry: Pose2,
    fe,
    config: MatchConfig,
    odometry_cov: np.ndarray | None = None,
) -> Step:
    """A consecutive match the wheel odometry disagrees with: when the match's position
    lies outside the refinement's basin around the odometry increment ``odometry`` (farther
    than ``fe.refine_max_shift`` m), point-to-line ICP of the raw scans from the odometry;
    when it converges outside the match's own 99 % ellipse (its covariance) and nearer the
    odometry, and overlaps the keyframe (its fitness) by ``fe.icp_min_fitness`` or at least
    as much as the match's pose does (its :func:`~scanclique.refine.agreement`: a scanner
    with centimetres of range noise leaves few points within the last 5 cm at any pose), it
    is a second hypothesis. The raw scans decide between the two
    (:func:`scanclique.match.pose_score`), each score less its :func:`surprise` against the
    odometry when ``odometry_cov`` (the odometry increment's covariance) is given: the
    raw-scan score of a corridor favours the pose of most overlap (standing still), so a
    match slid along it must outscore the odometry's pose by more than the odometry's own
    evidence against it. When they cannot decide (within ``fe.icp_score_tie``, e.g. slid
    along a corridor whose doors repeat), the one nearer the odometry is taken, as in
    :func:`icp_fallback`. ``step`` unchanged otherwise."""
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
    if icp.fitness < fe.icp_min_fitness and icp.fitness < agreement(
        pk.cloud, pj.points, step.pose, fe.refine_min_correspondence
    ):
        return step
    if mahalanobis_sq(icp.pose, np.zeros((3, 3)), step.pose, step.covariance) <= GATE_99:
        return step  # ICP from the odometry went back to the match: one hypothesis
    if icp.pose.distance_to(odometry)[0] >= t:
        return step
    s_match = pose_score(pk, pj, step.pose, config)
    s_icp = pose_score(pk, pj, icp.pose, config)
    v_match, v_icp = s_match, s_icp
    if odometry_cov is not None:
        v_match -= surprise(step.pose, odometry, odometry_cov, fe)
        v_icp -= surprise(icp.pose, odometry, odometry_cov, fe)
    if v_icp < v_match - fe.icp_score_tie:
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

    def accepted(pose: Pose2, cov: np.ndarray, verdict: str) -> Step:
        pose = pose if front_end is None else refine_pose(pk, pj, pose, front_end)
        cov, along = floored(cov, *sigma_floor), False
        if not weak_prior:
            pose, cov, along = along_corridor(pk, pj, pose, cov, prior_a, prior_b, noise,
                                              front_end)  # fmt: skip
        return Step(pose, cov, MATCH, verdict, float(m.score), along_prior=along)

    if quick is not None:
        return accepted(quick, m.covariance, "accepted")
    if weak_prior:
        # no odometry (the paper's setting): the match validates itself (§7: enough
        # features that fix the pose, no rival); the prediction only breaks a tie
        v = validate_match(m)
        if v.verdict == AMBIGUOUS:
            v = validate_match(m, prior_a, prior_b, noise, path=path)
    else:
        v = validate_match(m, prior_a, prior_b, noise, path=path)
    if v.accepted and v.pose is not None:
        return accepted(v.pose, v.covariance if v.covariance is not None else m.covariance,
                        v.verdict)  # fmt: skip
    reason = "; ".join(v.reasons) if v.reasons else (m.reason or v.verdict)
    seed = m.pose if m.pose is not None else prior_a.inverse() @ prior_b
    return Step(seed, np.eye(3), "rejected", v.verdict, float(m.score), reason)


def icp_from_seeds(
    pk: PreparedScan, pj: PreparedScan, seeds, fe, config: MatchConfig, min_fitness=None
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
        if icp.fitness >= (fe.icp_min_fitness if min_fitness is None else min_fitness):
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
) -> Step | None:
    """With wheel odometry, when the feature match fails: point-to-line ICP of all of scan
    ``j``'s points onto keyframe ``k``'s cloud from each seed (the priors, a rejected
    match's pose). Each ICP pose is valued by its raw-scan score less its
    :func:`surprise` against the odometry (the first prior); poses valued alike (within
    ``fe.icp_score_tie`` of the best, e.g. slid along a corridor) go to the one nearest
    the odometry. Accepted (kind ``"icp"``) when its raw-scan score
    (:func:`scanclique.match.pose_score`) is at least ``fe.icp_min_score``, ICP paired at
    least ``fe.icp_min_fitness`` of the points, and it lies within ``fe.icp_gate`` sigma
    (per coordinate) of at least one of the ``priors`` (wheel odometry and, when the scan
    before was placed by a feature match, the constant-velocity prediction of the chain:
    two independent motion estimates, so that a wheel slip or a reversing robot whose
    odometry disagrees with the scans does not break the chain; the caller leaves the
    prediction out after a step ICP placed, whose error it would carry); its covariance
    is ``2 x`` the floor plus a hundredth of the first prior's, and in a corridor
    (:func:`weak_direction` below ``fe.icp_min_constraint``) the component along it is
    the odometry's. Where the odometry turned at least
    ``fe.sharp_turn`` and no pose meets those bounds, ICP from the two priors is held to
    ``fe.scan_min_fitness`` and ``fe.scan_min_score`` instead (little overlap), and the
    pose's translation keeps the odometry's covariance. None otherwise. (Without odometry
    the front end is :func:`associate_by_scans`.)"""
    found = icp_from_seeds(pk, pj, seeds, fe, config)
    small_overlap = False
    if not found or max(sc for _, sc in found) < fe.icp_min_score:
        if abs(priors[0][0].theta) < fe.sharp_turn:
            return None
        # a sharp turn: the scans overlap little; the bounds of the front end without
        # odometry, from the motion priors
        found = [
            f for f in icp_from_seeds(pk, pj, [p for p, _ in priors], fe, config,
                                      fe.scan_min_fitness)
            if f[1] >= fe.scan_min_score
        ]  # fmt: skip
        if not found:
            return None
        small_overlap = True
    p0, c0 = priors[0]
    # each pose's raw-scan score less its surprise against the odometry (a corridor's
    # score favours the pose of most overlap: standing still)
    value = [sc - surprise(p, p0, c0, fe) for p, sc in found]
    top = max(value)
    pose, score = min(
        (f for f, v in zip(found, value, strict=True) if v >= top - fe.icp_score_tie),
        key=lambda f: mahalanobis_sq(f[0], np.zeros((3, 3)), p0, c0),
    )
    if not any(
        within_gate(pose, prior, np.sqrt(np.diag(prior_cov)), fe.icp_gate)
        for prior, prior_cov in priors
    ):
        return None
    cov = floored(priors[0][1] * 0.01, 2 * fe.sigma_floor_metres, 2 * fe.sigma_floor_radians)
    if small_overlap:
        cov[:2, :2] = priors[0][1][:2, :2]
    weak = weak_direction(pk.cloud, np.ascontiguousarray(pj.points), pose, 0.1)
    if weak is not None and weak[1] < fe.icp_min_constraint:
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


class SortedHistory:
    """Values observed so far, kept sorted as they come, with their running sum: a quantile
    reads two of them instead of sorting the whole history again (which made the front end
    without odometry quadratic in the log's length: 17 ms per scan after 100000 scans, a
    40 Hz scanner's 42 minutes).

    >>> h = SortedHistory()
    >>> for v in (3.0, 1.0, 2.0, 4.0):
    ...     h.add(v)
    >>> len(h), h.total, h.quantile(0.5) == float(np.quantile([3.0, 1.0, 2.0, 4.0], 0.5))
    (4, 10.0, True)
    """

    __slots__ = ("values", "total")

    def __init__(self) -> None:
        self.values: list[float] = []
        self.total = 0.0

    def add(self, value: float) -> None:
        bisect.insort(self.values, value)
        self.total += value

    def __len__(self) -> int:
        return len(self.values)

    def quantile(self, q: float) -> float:
        """``np.quantile(values, q)`` (its default, linear method), to the bit: the two
        values around the virtual index ``(n - 1) q``, interpolated by numpy itself."""
        v = self.values
        pos = (len(v) - 1) * q
        lo = math.floor(pos)
        pair = [v[lo], v[min(lo + 1, len(v) - 1)]]
        return float(np.quantile(pair, pos - lo))


class VelocityModel:
    """The motion model of the front end without odometry, learnt from the steps the scans
    placed (state carried across scans).

    * :meth:`predict`: the last motion repeated (:func:`constant_velocity`), per unit of
      time (timestamps) or per scan, whichever has predicted the scan-placed poses better so
      far: a log recorded at a steady rate moves as far per second, one thinned by distance
      travelled (the corrected Intel log: 1 m between scans however long the robot stood
      still, timestamps 0.01 to 14 s apart) as far per scan.
    * :meth:`max_translation`: how far a scan may lie from a keyframe ``span`` scans back:
      ``fe.jump_factor`` times the 90th percentile of the per-scan steps measured so far,
      times ``span``, plus ``fe.jump_floor`` (a robot turns as sharply as it likes, but does
      not jump); no bound before the scans have measured ``fe.jump_min_path`` m of path.
    """

    def __init__(self, fe) -> None:
        self.fe = fe
        self.steps = SortedHistory()  # per-scan translation of scan-placed steps (m)
        self.errors = [0.0, 0.0]  # summed translation errors: per second, per scan
        self.turns = SortedHistory()  # heading errors of the prediction used (rad)
        # Step.loose of the last two scans (world frame, m²), the older first
        self.loose = (np.zeros((2, 2)), np.zeros((2, 2)))

    def predict(self, prev2, prev, times=(None, None, None), by_time=None) -> Pose2:
        """Predicted pose (world frame) of the next scan from the last two, ``prev2`` and
        ``prev``; ``times`` the timestamps of those two and of the next scan."""
        if by_time is None:
            by_time = self.errors[0] <= self.errors[1]
        return constant_velocity(prev2, prev, *(times if by_time else (None, None, None)))

    def observe(self, prev2, prev, times, placed: Pose2, rel: Pose2, span: int) -> None:
        """Record a scan the scans placed: at ``placed`` (world frame), ``rel`` from a
        keyframe ``span`` scans back."""
        self.steps.add(math.hypot(rel.x, rel.y) / span)
        if prev2 is not None:
            self.turns.add(self.predict(prev2, prev, times).distance_to(placed)[1])
            for m, by_time in enumerate((True, False)):
                self.errors[m] += self.predict(prev2, prev, times, by_time).distance_to(placed)[0]

    def heading_sigma(self) -> float:
        """Standard deviation of the heading of a scan placed by the prediction: the 95th
        percentile of the prediction's heading errors on the scan-placed steps so far (as
        unsure as it has proved: a smooth drive keeps it small, a robot that turns sharply
        before walls makes it large), at most ``fe.guess_sigma_radians``, which it is
        before ten steps have been measured."""
        if len(self.turns) < 10:
            return self.fe.guess_sigma_radians
        return min(self.turns.quantile(0.95), self.fe.guess_sigma_radians)

    def placed(self, loose: np.ndarray | None) -> None:
        """Record the :attr:`Step.loose` of the scan just placed (world frame, m², or None).
        Only looseness beyond the keyframe spacing (largest eigenvalue at least
        ``fe.keyframe_distance ** 2``) is kept for the next prediction: less is left to the
        next match (passing all of it on loosened the dense logs' corridors, measured in
        session 18)."""
        keep = loose is not None and np.linalg.eigvalsh(loose)[-1] >= self.fe.keyframe_distance**2
        self.loose = (self.loose[1], loose if keep else np.zeros((2, 2)))

    def carried(self, through_last: bool) -> np.ndarray:
        """The ``(2, 2)`` translation variance (m², world frame) a constant-velocity
        prediction inherits from the loose steps before it (:meth:`placed`): that of the
        last scan when the prediction runs through it (``through_last``: it lies relative
        to the same keyframe as the predicted one), plus that of the last motion (the last
        two scans' looseness), scaled down so that its largest eigenvalue is at most the
        squared 90th percentile of the per-scan steps (the robot's speed is unknown along a
        loose direction, not unbounded)."""
        older, last = self.loose
        position = last if through_last else np.zeros((2, 2))
        if not self.steps.total:
            return position
        velocity = last + older
        cap = self.steps.quantile(0.9) ** 2
        top = float(np.linalg.eigvalsh(velocity)[-1])
        return position + (velocity if top <= cap else velocity * (cap / top))

    def max_translation(self, span: int) -> float | None:
        if self.steps.total < self.fe.jump_min_path:
            return None
        q = self.steps.quantile(0.9)
        return self.fe.jump_factor * q * span + self.fe.jump_floor


#: how many standard errors (a delete-a-block jackknife's, :data:`DRIFT_BLOCKS` blocks
#: of consecutive matches) a term of the odometry's steady heading drift
#: (:meth:`OdometryFit.drift`) must stand from zero to be taken out. Simulated campus
#: odometry has none: its terms stand up to 6.3 errors from zero by least squares' own
#: errors, 0.1-2.7 by the jackknife's (RPLIDAR drives 0, 1, 2, 6); all taken out, 4 of
#: 9 LDS-01 drives mapped worse. fr079-raw's stand 3.4-3.9; the simulated ring's 0.003
#: rad/m 34, the Intel wheels' 0.06 rad/m 27-34.
DRIFT_T = 5.0
DRIFT_BLOCKS = 20
#: :meth:`OdometryFit.scale` is refitted once this many matches (or a twentieth more,
#: whichever is more) have come since its last fit: the jackknife refits it 21 times
SCALE_REFIT = 25
#: the least standard deviation (m) along the odometry's step a match is weighted by in
#: :meth:`OdometryFit.scale` (a covariance of zero would weigh one match as all)
SCALE_SIGMA_MIN = 1e-3


def _shown_terms(A: np.ndarray, y: np.ndarray) -> tuple[float, ...]:
    """Least-squares ``x`` of ``A x = y`` (``(n, m)``, rows in time order), each term set
    to 0 unless it stands :data:`DRIFT_T` standard errors from zero, the errors by a
    delete-a-block jackknife (:data:`DRIFT_BLOCKS` blocks of consecutive rows): matches
    from one keyframe share its odometry, so their residuals are correlated and least
    squares' own error is too small (simulated campus odometry without drift: t up to
    6.3; by blocks 2.7). The terms left are fitted again without the others."""
    keep = (A != 0).any(axis=0)  # a term never measured (no turn) is not fitted
    blocks = np.array_split(np.arange(len(y)), min(DRIFT_BLOCKS, len(y)))
    sol = np.zeros(A.shape[1])
    while keep.any():
        B = A[:, keep]
        s = np.linalg.lstsq(B, y, rcond=None)[0]
        jack = np.array([np.linalg.lstsq(np.delete(B, k, 0), np.delete(y, k), rcond=None)[0]
                         for k in blocks])  # fmt: skip
        var = (len(blocks) - 1) / len(blocks) * ((jack - jack.mean(axis=0)) ** 2).sum(axis=0)
        shown = np.abs(s) >= DRIFT_T * np.sqrt(var)
        if shown.all():
            sol[keep] = s
            break
        keep[np.flatnonzero(keep)[~shown]] = False
    return tuple(float(v) for v in sol)


def _steady_step_error(rows: np.ndarray, sigma: np.ndarray) -> float:
    """The odometry's distance's steady relative error in :class:`OdometryFit`'s
    ``rows`` (the residual along each step regressed on the step's length, each row
    weighed by ``sigma``, m), 0 unless shown (:func:`_shown_terms`):
    :meth:`OdometryFit.steps_off` weighs by the model's sigma, :meth:`OdometryFit.scale`
    by each match's own sigma along the step."""
    return _shown_terms((rows[:, 2] / sigma)[:, None], rows[:, 4] / sigma)[0]


def _scaled(cov: np.ndarray, scales: tuple[float, float]) -> np.ndarray:
    """An ``(x, y, theta)`` covariance with its standard deviations scaled by ``scales``
    (translation, heading): :meth:`OdometryFit.fitted` and :meth:`OdometryFit.corrected`."""
    k = np.array([scales[0], scales[0], scales[1]])
    return cov * np.outer(k, k)


class OdometryFit:
    """How good the wheel odometry has proved against the scans (state carried across
    scans): the residuals of the odometry increments against the feature matches the
    front end accepted, in units of the odometry noise model's standard deviations.

    The noise model (``fe.odometry_noise``) is written for poor odometry (the raw odometry
    of the Intel and CSAIL logs, twice over); a robot whose wheels track well is many
    times better. :meth:`fitted` scales the model's covariance down to what the log has
    shown: the 95th percentiles of the residuals (translation: a 2-D Rayleigh's at 2.448
    sigma; heading: a half-normal's at 1.960) set each component's scale, never below
    ``fe.odometry_fit_floor`` nor above 1 (never looser than the model), and only once
    ``fe.odometry_fit_min`` matches have been measured. The ICP fallback then gates and
    values its poses by the odometry as good as it has proved: a 3.5 m scanner outdoors
    whose ICP steps turn 8 degrees from odometry right to half a degree (the model's
    gate let 16 through) places those scans by the odometry instead. A scan the scans
    could not place at all is placed by the odometry as unsure as it has proved
    (:meth:`placing`).
    """

    __slots__ = ("fe", "xy", "th", "rows", "_scale")

    def __init__(self, fe) -> None:
        self.fe = fe
        self.xy = SortedHistory()  # translation residuals / model sigma
        self.th = SortedHistory()  # heading residuals / model sigma
        # per match, for :meth:`drift`, :meth:`steps_off` and :meth:`scale`: the heading
        # residual (rad) and its model sigma (rad), the odometry's step (m) and signed turn
        # (rad) over the span, the residual along that step (m), the model's translation
        # sigma (m) and the match's own sigma along the step (m; NaN when not given)
        self.rows: list[tuple[float, ...]] = []
        self._scale: tuple[int, float] | None = None  # (matches, value) of the last fit

    def observe(
        self, match: Pose2, odo: Pose2, cov: np.ndarray, match_cov: np.ndarray | None = None
    ) -> None:
        """Record a feature match ``match`` (keyframe to scan) against the odometry's
        increment ``odo`` over the same span and the model's covariance ``cov`` of it;
        ``match_cov``, the match's own covariance, weighs it in :meth:`scale`."""
        e = pose_difference(match, odo)
        s_xy, s_th = math.sqrt(cov[0, 0]), math.sqrt(cov[2, 2])
        self.xy.add(math.hypot(e[0], e[1]) / s_xy)
        self.th.add(abs(e[2]) / s_th)
        d = math.hypot(odo.x, odo.y)
        u = (e[0] * odo.x + e[1] * odo.y) / d if d > 0 else 0.0
        along = math.nan  # the match's own standard deviation along the odometry's step
        if match_cov is not None and d > 0:
            v = np.array([odo.x, odo.y]) / d
            along = math.sqrt(max(float(v @ match_cov[:2, :2] @ v), 0.0))
        self.rows.append((e[2], s_th, d, odo.theta, u, s_xy, along))

    def scale(self) -> float:
        """The odometry's distance's steady relative error as the accepted matches read it,
        each weighted by its own standard deviation along the odometry's step (the
        scans' step is the odometry's times ``1 +`` it); 0 unless it stands
        :data:`DRIFT_T` jackknife errors from zero (:func:`_shown_terms`), and before
        ``fe.odometry_fit_min`` matches with a covariance. Refitted once a twentieth more
        matches (at least :data:`SCALE_REFIT`) have come.

        Wheels of a wrong radius are a steady error within the odometry's noise on every
        step, and where the scans fix no position along a corridor the odometry alone
        places the robot along it: 2 % long over a 640 m loop put the far end a door or
        two along, where look-alike closures agreed with it (the simulated 200 x 120 m
        ring, seed 0: 45 of 48 closures 4-6 m off, 4.15 m of mean error). Matches fixed
        along the step read that error right (the ring: -2.2 % for 2 % long, +1.8 % for 2
        % short, nothing shown with exact steps), while those a corridor leaves loose stay
        partly where the odometry seeded them; their own sigma weighs them down (their
        unweighted :meth:`steps_off` reads -0.2 % of the same 2 %)."""
        n = len(self.rows)
        least = max(self.fe.odometry_fit_min, 3)
        if n < least:
            return 0.0
        if self._scale is not None and n < self._scale[0] + max(SCALE_REFIT, n // 20):
            return self._scale[1]
        r = np.asarray(self.rows)
        sm = r[:, 6]
        ok = np.isfinite(sm) & (sm > 0) & (r[:, 2] > 0)
        value = 0.0
        if ok.sum() >= least:
            value = _steady_step_error(r[ok], np.maximum(sm[ok], SCALE_SIGMA_MIN))
        self._scale = (n, value)
        return value

    @staticmethod
    def scaled(pose: Pose2, scale: float) -> Pose2:
        """An odometry increment ``pose`` with its translation times ``1 + scale`` (the
        steady error :meth:`scale` reads taken out; its heading unchanged)."""
        f = 1.0 + scale
        return Pose2(pose.x * f, pose.y * f, pose.theta)

    def steps_off(self) -> float:
        """The odometry's distance's steady relative error as the accepted matches read
        it (the scans' step is the odometry's times 1 + it), 0 unless it stands
        :data:`DRIFT_T` jackknife errors from zero (:func:`_shown_terms`). Not taken out
        of anything: matches along a street or corridor stay partly where their seed put
        them, so they read steps short themselves (the simulated campus LDS-01 with exact
        odometry: 2.9 % on one drive of nine); a steady disagreement only says that one
        of the two is steadily wrong (:meth:`_Mapper.odometry_factors
        <scanclique.mapping.pipeline._Mapper.odometry_factors>`)."""
        if len(self.rows) < max(self.fe.odometry_fit_min, 3):
            return 0.0
        r = np.asarray(self.rows)
        return _steady_step_error(r, r[:, 5])

    def drift(self) -> tuple[float, float] | None:
        """The odometry's steady heading error, fitted to the accepted matches by least
        squares: ``(per_metre, per_radian)``, the heading the odometry loses per metre
        travelled (rad/m: wheels of slightly different diameters) and per radian it
        turns (rad/rad: a wrong wheel base), signed so that the scans' heading change is
        the odometry's plus ``per_metre * distance + per_radian * turn``; a term whose
        estimate stands less than :data:`DRIFT_T` standard errors from zero is left out
        (0: the matches' own errors are not taken for the odometry's). None before
        ``fe.odometry_fit_min`` matches. A steady error is within the noise model's
        sigma on every step (0.003 rad/m is 0.1 sigma of a 0.25 m step fitted to the
        floor) and 33 degrees over 200 m, which independent edges in a graph cannot say
        (:meth:`corrected`)."""
        if len(self.rows) < max(self.fe.odometry_fit_min, 3):
            return None
        r = np.asarray(self.rows)
        per_metre, per_radian = _shown_terms(r[:, 2:4] / r[:, 1:2], r[:, 0] / r[:, 1])
        return per_metre, per_radian

    def calibration(self) -> tuple[tuple[float, float], tuple[float, float]] | None:
        """``(drift, scales)``: the odometry's steady heading error (:meth:`drift`) and the
        factors of the model's sigmas the residuals left once it is taken out need
        (:meth:`scales` of them); None before the odometry has been measured."""
        d = self.drift()
        m = self.scales(d)
        return None if d is None or m is None else (d, m)

    @staticmethod
    def corrected(prior: tuple[Pose2, np.ndarray], distance: float, calibration):
        """The odometry ``prior`` (increment, model covariance) over a span of
        ``distance`` metres with its steady heading error taken out and its covariance
        scaled as the odometry has proved (``calibration``, from :meth:`calibration`):
        what the batch back end's odometry edges carry. The translation is turned by half
        the heading correction (the error accumulates along the span)."""
        (per_metre, per_radian), m = calibration
        z, cov = prior
        dth = per_metre * distance + per_radian * z.theta
        c, s = math.cos(dth / 2), math.sin(dth / 2)
        z = Pose2(c * z.x - s * z.y, s * z.x + c * z.y, z.theta + dth)
        return z, _scaled(cov, m)

    def scales(self, drift: tuple[float, float] | None = None) -> tuple[float, float] | None:
        """``(translation, heading)`` factors of the model's standard deviations the
        odometry has proved to need, or None before ``fe.odometry_fit_min`` matches.
        With ``drift`` (:meth:`drift`), the heading's is that of the residuals left once
        that steady error is taken out."""
        if len(self.th) < max(self.fe.odometry_fit_min, 1):
            return None
        lo = self.fe.odometry_fit_floor
        m_xy = min(max(self.xy.quantile(0.95) / 2.448, lo), 1.0)
        if drift is None:
            q = self.th.quantile(0.95)
        else:
            r = np.asarray(self.rows)
            q = float(np.quantile(np.abs(r[:, 0] - r[:, 2:4] @ drift) / r[:, 1], 0.95))
        m_th = min(max(q / 1.960, lo), 1.0)
        return m_xy, m_th

    def fitted(self, prior: tuple[Pose2, np.ndarray]) -> tuple[Pose2, np.ndarray]:
        """The odometry ``prior`` (increment, model covariance) with the covariance scaled
        to what the odometry has proved (unchanged before it has been measured)."""
        m = self.scales()
        return prior if m is None else (prior[0], _scaled(prior[1], m))

    @staticmethod
    def doubts(verdict: str) -> bool:
        """Whether a step of this verdict says the odometry itself is wrong there: its
        match was rejected for disagreeing with it (a slip). Such a scan is neither placed
        by the fitted odometry (:meth:`placing`) nor crossed by the batch back end's
        odometry edges (:attr:`~scanclique.mapping.config.BackEndConfig.odometry_factors`)."""
        return verdict == REJECTED_ODOMETRY

    def placing(self, step: Step) -> Step:
        """``step``, a scan placed by the odometry (:func:`prior_step`), with the
        covariance the odometry has proved (:meth:`fitted`) where the scans could not
        place it (too few features, too little overlap): the loops weigh a closure's shift
        against the front end's uncertainty along the chain, and the model's loose one let
        look-alike streets 18-28 m off through (campus LDS-01 drives with odometry 3.08 ->
        1.23 m). Unchanged where the match was rejected for disagreeing with the odometry
        (verdict ``"rejected_odometry"``): there the odometry itself is suspect (a slip
        4.7 sigma of the model off; trusted, office LDS-01 drive 1 went 0.228 -> 0.922 m)."""
        if self.doubts(step.verdict):
            return step
        _, cov = self.fitted((step.pose, step.covariance))
        return Step(step.pose, cov, step.kind, step.verdict, step.score, step.reason, step.loose)


def soften(
    pk: PreparedScan,
    pj: PreparedScan,
    pose: Pose2,
    cov: np.ndarray,
    prior: Pose2,
    fe,
    carried: np.ndarray | None = None,
) -> np.ndarray:
    """``cov`` of a step ``pose`` (maps scan ``j`` into ``k``) made as unsure, along the
    direction the raw scans fix least, as ``pose`` and the motion model's ``prior``
    disagree along it, when the raw scans fix that direction loosely
    (:func:`weak_direction` below ``fe.soft_constraint``: a corridor, whose doors repeat
    and whose raw-scan score favours the pose of most overlap, standing still). Without
    odometry nothing else tells where along a corridor the robot went; an edge as sure as
    its features or its ICP would keep the loops from putting it right. Where the two
    agree (a dense log, a steady walk) the edge is left as it is, unless the prior is
    itself unsure along that direction: ``carried`` (``(2, 2)``, k's frame, m²), the
    variance the prior inherited from earlier steps placed this way
    (:meth:`VelocityModel.carried`), is added along it too, since agreeing with a
    prediction that the previous loose steps made proves nothing (a corridor driven at
    1 m per scan that ICP and the prediction both call standing still)."""
    weak = weak_direction(pk.cloud, np.ascontiguousarray(pj.points), pose, 0.1)
    if weak is None or weak[1] >= fe.soft_constraint:
        return cov
    e = weak[0]
    d = float(e @ [pose.x - prior.x, pose.y - prior.y])
    var = d * d + (0.0 if carried is None else float(e @ carried @ e))
    cov = cov.copy()
    cov[:2, :2] += var * np.outer(e, e)
    return cov


def scan_candidates(
    pk: PreparedScan, pj: PreparedScan, m, pred: Pose2, fe, config: MatchConfig
) -> list[tuple[Pose2, float]]:
    """Poses of scan ``j`` in keyframe ``k`` that the raw scans may support, with their
    raw-scan scores (:func:`scanclique.match.pose_score`): point-to-line ICP from each of
    the first ``fe.max_seeds`` distinct hypotheses of the match ``m``, from the prediction
    ``pred``, from standing still and from the prediction turned by each multiple of
    ``360 / fe.turn_seeds`` degrees (a sharp turn no velocity predicts, which may leave the
    matcher without a right hypothesis), kept when ICP paired at least
    ``fe.scan_min_fitness`` of the points; and the hypotheses as they are (ICP may lose a
    sharp turn's small overlap)."""
    hyps: list[Pose2] = []
    for h in m.hypotheses:
        if len(hyps) >= fe.max_seeds:
            break
        if all(distinct_poses(h.pose, s, config) for s in hyps):
            hyps.append(h.pose)
    turns = [
        pred @ Pose2(0.0, 0.0, 2 * math.pi * i / fe.turn_seeds) for i in range(1, fe.turn_seeds)
    ]
    found = icp_from_seeds(pk, pj, [*hyps, pred, Pose2.identity(), *turns], fe, config,
                           fe.scan_min_fitness)  # fmt: skip
    return found + [(h, float(pose_score(pk, pj, h, config))) for h in hyps]


def swung(pose: Pose2, pred: Pose2, start: Pose2 | None) -> Pose2:
    """The prediction ``pred`` nearest ``pose`` among those its step could have taken had
    the robot made the turn by which ``pose`` departs from it (``d``) at any moment of the
    step: the predicted step from ``start`` (where it begins, the previous scan; all three
    in one frame) swung about ``start`` by an angle between 0 and ``d``
    (:data:`ARC_SAMPLES` of them), its heading turned as much. ``pred`` itself without
    ``start`` or without an unexpected turn."""
    if start is None:
        return pred
    d = pose_difference(pose, pred)[2]
    if d == 0.0:
        return pred
    v = np.array([pred.x - start.x, pred.y - start.y])
    best, out = math.inf, pred
    for a in np.linspace(0.0, d, ARC_SAMPLES):
        x, y = np.array([start.x, start.y]) + rotation_matrix(float(a)) @ v
        e = math.hypot(pose.x - x, pose.y - y)
        if e < best:
            best, out = e, Pose2(x, y, pred.theta + float(a))
    return out


#: the predicted steps :func:`swung` tries (both ends included)
ARC_SAMPLES = 9


def surprise(
    pose: Pose2, pred: Pose2, pred_cov: np.ndarray, fe, start: Pose2 | None = None
) -> float:
    """The raw-scan score a pose must pay for departing from the prediction ``pred``:
    ``fe.shift_cost`` per standard deviation of translation and ``fe.turn_cost`` per
    standard deviation of heading (``pred_cov``). A robot's heading is much less
    predictable than its translation (it turns in place, or sharply before a wall), so a
    sigma of unexpected turn costs less than a sigma of unexpected shift. With ``start``
    (where the predicted step begins) the shift is measured from the predicted step swung
    by the pose's unexpected turn (:func:`swung`): a robot that turned more than predicted
    may also have moved in a direction the prediction did not expect."""
    e = pose_difference(pose, pred)
    near = swung(pose, pred, start)
    return fe.shift_cost * math.hypot(pose.x - near.x, pose.y - near.y) / math.sqrt(
        pred_cov[0, 0]
    ) + (fe.turn_cost * abs(e[2]) / math.sqrt(pred_cov[2, 2]))


def _same_heading(p: Pose2, q: Pose2, config: MatchConfig) -> bool:
    return not distinct_poses(Pose2(0.0, 0.0, p.theta), Pose2(0.0, 0.0, q.theta), config)


def choose_by_scans(
    candidates: list[tuple[Pose2, float]],
    pred: Pose2,
    pred_cov: np.ndarray | None,
    fe,
    config: MatchConfig,
    weak_at=None,
    start: Pose2 | None = None,
) -> tuple[Pose2, float, np.ndarray, np.ndarray | None] | str:
    """The candidate (pose, raw-scan score) the scans and the motion agree on best: the
    highest raw-scan score less its :func:`surprise` (the score alone when ``pred_cov`` is
    None: no velocity known yet). Returns ``(pose, score, spread)``, ``spread`` the
    ``(2, 2)`` covariance the other candidates at the same heading add (a quarter of
    their squared offsets: the translation aliases of a small overlap, or of a corridor
    whose raw scans favour the pose of most overlap), or the reason in words when distinct
    headings come within ``fe.icp_score_tie`` of the best (the scans and the motion cannot
    tell a turn from a look-alike). ``weak_at(pose)``, when given, returns the unit vector
    along which the raw scans leave ``pose`` free (a corridor's axis, which the caller
    takes from the prediction) or None: poses that differ only along it are one; it is
    returned last. ``start``: where the predicted step begins (:func:`surprise`)."""
    if not candidates:
        return "no candidate"

    def value(f):
        return f[1] if pred_cov is None else f[1] - surprise(f[0], pred, pred_cov, fe, start)

    ranked = sorted(((p, sc, value((p, sc))) for p, sc in candidates), key=lambda f: -f[2])
    pose, score, best = ranked[0]
    weak = None if weak_at is None else weak_at(pose)

    def same(p: Pose2, q: Pose2) -> bool:
        if weak is None:
            return not distinct_poses(p, q, config)
        across = abs(float(np.array([-weak[1], weak[0]]) @ [p.x - q.x, p.y - q.y]))
        return across <= config.refine.distinct_metres and _same_heading(p, q, config)

    tie: list[Pose2] = []  # one per distinct pose, best first
    for p, _, va in ranked:
        if va >= best - fe.icp_score_tie and all(not same(p, q) for q in tie):
            tie.append(p)
    if any(not _same_heading(p, pose, config) for p in tie):
        return f"{len(tie)} distinct poses explain the raw scans alike, at distinct headings"
    spread = np.zeros((2, 2))
    for p, _, _ in ranked[1:]:
        if _same_heading(p, pose, config):
            d = np.array([p.x - pose.x, p.y - pose.y])
            spread += np.outer(d, d) / 4.0
    return pose, score, spread, weak


def associate_by_scans(
    pk: PreparedScan,
    pj: PreparedScan,
    pred: Pose2,
    pred_cov: np.ndarray | None,
    config: MatchConfig,
    fe,
    sigma_floor: tuple[float, float],
    max_translation: float | None = None,
    carried: np.ndarray | None = None,
    start: Pose2 | None = None,
) -> Step:
    """Without odometry (the paper's setting): place scan ``j`` relative to keyframe ``k``
    by the scans' own evidence, the constant-velocity prediction ``pred`` (maps ``j`` into
    ``k``, covariance ``pred_cov``; None when no velocity is known yet) only weighing in
    where the scans leave a choice.

    1. The feature match, validated on its own (§7: enough features fixing the pose, no
       rival), is taken when its heading lies within the prediction's 99 % gate (or no
       velocity is known) and its translation within ``max_translation`` m
       (:meth:`VelocityModel.max_translation`); its covariance :func:`soften`-ed.
    2. Otherwise (rejected, ambiguous, imprecise, or a turn the prediction did not expect):
       the :func:`scan_candidates` within ``max_translation`` scoring at least
       ``fe.scan_min_score`` compete (:func:`choose_by_scans`); the winner's covariance is
       the alignment's (:func:`scanclique.refine.icp_covariance`, floored at twice the
       front end's floor) plus the spread of its translation aliases, :func:`soften`-ed.
       A tie at distinct headings is refused (``"ambiguous"``).
    3. Where the raw scans leave the winner free along one direction (a corridor:
       :func:`weak_direction` below ``fe.icp_min_constraint``), the component along it is
       the prediction's, with its variance.

    ``start`` (k's frame, or None): where the predicted step begins (the previous scan);
    a candidate that turned more than predicted is judged against the predicted step
    swung by its turn (:func:`swung`), in the competition of 2 and as the prior of 3.

    ``carried`` (``(2, 2)``, k's frame, or None): the translation variance the prediction
    inherited from loose steps before it (:meth:`VelocityModel.carried`); it is added to
    the prediction's variance along a loose direction in 1 to 3 (:func:`soften`), and the
    step reports what the motion model added as :attr:`Step.loose`.

    Returns a Step of kind ``"match"`` (1) or ``"icp"`` (2), or ``"rejected"`` with the
    reason (the caller places the scan by the prediction).
    """
    m = match_prepared(pk, pj, config)
    known = pred_cov is not None
    pts = np.ascontiguousarray(pj.points)

    def plausible(p: Pose2) -> bool:
        return max_translation is None or math.hypot(p.x, p.y) <= max_translation

    def softened(pose: Pose2, cov: np.ndarray) -> np.ndarray:
        return soften(pk, pj, pose, cov, swung(pose, pred, start), fe, carried) if known else cov

    def loose(before: np.ndarray, after: np.ndarray) -> np.ndarray | None:
        added = after[:2, :2] - before[:2, :2]
        return added if np.any(added) else None

    def expected_turn(p: Pose2) -> bool:
        return not known or abs(pose_difference(p, pred)[2]) <= math.sqrt(GATE_99 * pred_cov[2, 2])

    v = validate_match(m)
    if v.accepted and v.pose is not None and plausible(v.pose) and expected_turn(v.pose):
        cov = floored(v.covariance if v.covariance is not None else m.covariance, *sigma_floor)
        pose = refine_pose(pk, pj, v.pose, fe)
        soft = softened(pose, cov)
        return Step(pose, soft, MATCH, v.verdict, float(m.score), loose=loose(cov, soft))
    why = "; ".join(v.reasons) if v.reasons else (m.reason or v.verdict)
    found = [
        f for f in scan_candidates(pk, pj, m, pred, fe, config)
        if plausible(f[0]) and f[1] >= fe.scan_min_score
    ]  # fmt: skip
    if not found:
        return Step(pred, np.eye(3), "rejected", v.verdict, float(m.score),
                    f"{why}; no pose within reach scores at least {fe.scan_min_score:g} "
                    "on the raw scans")  # fmt: skip

    def axis_at(pose: Pose2) -> np.ndarray | None:
        weak = weak_direction(pk.cloud, pts, pose, 0.1) if known else None
        return weak[0] if weak is not None and weak[1] < fe.icp_min_constraint else None

    chosen = choose_by_scans(found, pred, pred_cov, fe, config, axis_at, start)
    if isinstance(chosen, str):
        return Step(pred, np.eye(3), "rejected", "ambiguous", float(m.score), f"{why}; {chosen}")
    pose, score, spread, axis = chosen
    cov = icp_covariance(pk.cloud, pts, pose, fe.refine_min_correspondence)
    if cov is None:
        cov = np.diag([fe.icp_gate * sigma_floor[0]] * 2 + [fe.icp_gate * sigma_floor[1]]) ** 2
    cov = floored(cov, 2 * sigma_floor[0], 2 * sigma_floor[1])
    cov[:2, :2] += spread
    before = cov
    if axis is not None:
        prior_cov = pred_cov.copy()
        if carried is not None:
            prior_cov[:2, :2] += carried
        pose, cov = _prior_along(pose, cov, axis, swung(pose, pred, start), prior_cov)
        score = float(pose_score(pk, pj, pose, config))
    else:
        cov = softened(pose, cov)
    return Step(pose, cov, ICP, "scans", score, f"{v.verdict}: {why}; placed by the raw scans",
                loose(before, cov))  # fmt: skip
