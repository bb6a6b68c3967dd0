"""The verdict on one scan match (paper §7; pipeline stage 8).

The maximum clique cannot map features wrongly by chance: a false mapping needs a set of
features that happens to repeat the geometry of another (symmetry in the environment).
Paper §7: such a mapping shows as a pose that disagrees with another estimate of the
motion (odometry) or with other matches, and the threshold of that test can follow from
the precision the constellation of mapped features allows (like the dilution of precision
of a GPS constellation). This module does all of it, as pure functions over a
:class:`~scanclique.match.ScanMatch`:

* :func:`feature_estimate` — the feature-based pose of a match and its covariance: the
  chosen clique's pairs that agree with the final pose, re-estimated by weighted least
  squares (:func:`scanclique.pose.estimate_pose_lsq_pairs`). A corridor seen only along its
  walls shows an along-corridor variance that is large (or infinite).
* :func:`odometry_prior` — the relative pose of two scans from their odometry poses, with
  a covariance that grows with the distance travelled and the angle turned
  (:class:`OdometryNoise`).
* :func:`validate_match` — the verdict on one match (:class:`Validation`): ``accepted``,
  ``rejected_odometry``, ``ambiguous`` or ``too_few_features``, with its numbers. A match
  is contested (*rivals*) by a distinct pose that explains the raw scans nearly as well,
  or by a larger mapping of features elsewhere; odometry settles a contest only when it
  is decisive (posterior probability). :func:`choose_by_odometry` picks among the
  hypotheses of an ambiguous match.
* cycles of several matches are in :mod:`scanclique.validation.cycles`.

The scan pairs with known truth on which the verdicts are measured and the success rule
live with the evaluation code (:mod:`scanclique.pairsets`, :mod:`scanclique.eval.success`).

Poses are ``T_a_b``: they map points of B's sensor frame into A's
(``p_a = R(theta) p_b + (x, y)``); covariances are of ``(x, y, theta)`` of ``T_a_b``, in
m², m·rad and rad².

Examples
--------
>>> import scanclique as sc
>>> pair = sc.sim.simulate_pair(np.random.default_rng(3))
>>> m = sc.match_scans(pair.scan_a, pair.scan_b)
>>> v = validate_match(m)
>>> v.verdict, v.n_features >= 3
('accepted', True)

With odometry, the match must also agree with the motion it measured:

>>> odom_a = Pose2(0.0, 0.0, 0.0)
>>> validate_match(m, odom_a, odom_a @ pair.pose_a_b).verdict
'accepted'
>>> far = Pose2(0.8, 0.0, 0.35) @ pair.pose_a_b     # odometry 0.8 m and 20 deg off
>>> v = validate_match(m, odom_a, far)
>>> v.verdict, v.mahalanobis_sq > v.gate
('rejected_odometry', True)
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from .._records import readonly
from ..config import ValidationConfig, require_config
from ..errors import ConfigError, ScanError
from ..geometry import Pose2
from ..match import Hypothesis, ScanMatch, distinct_poses, near_rival
from ..pose import (
    PoseEstimate,
    estimate_pose_lsq_pairs,
    pair_consistent_pairs,
    points_first,
)
from ..uncertainty import (
    GATE_99,
    OdometryNoise,
    check_covariance,
    check_pose,
    chi2_quantile,
    constellation_std,
    mahalanobis_sq,
    odometry_prior,
)

__all__ = [
    "ACCEPTED",
    "REJECTED_ODOMETRY",
    "AMBIGUOUS",
    "TOO_FEW_FEATURES",
    "VERDICTS",
    "HypothesisCheck",
    "Validation",
    "feature_estimate",
    "check_hypotheses",
    "choose_by_odometry",
    "validate_match",
]

ACCEPTED = "accepted"
REJECTED_ODOMETRY = "rejected_odometry"
AMBIGUOUS = "ambiguous"
TOO_FEW_FEATURES = "too_few_features"
VERDICTS = (ACCEPTED, REJECTED_ODOMETRY, AMBIGUOUS, TOO_FEW_FEATURES)
"""Every verdict :func:`validate_match` can give."""


# ---------------------------------------------------------------------------------------
# Records
# ---------------------------------------------------------------------------------------
@dataclass(frozen=True, slots=True, eq=False)
class HypothesisCheck:
    """One hypothesis of a match tested against the odometry prior.

    ``index`` into ``match.hypotheses``; ``pose`` (maps B into A) and ``covariance`` used;
    ``mahalanobis_sq`` the squared Mahalanobis distance from the prior (covariances
    added); ``passed`` whether it is within the gate; ``score`` and ``clique_size`` as in
    the hypothesis; ``rival`` True for the match's own hypothesis and its rivals (tested
    first; see :func:`validate_match`), False for the other contenders."""

    index: int
    pose: Pose2
    covariance: np.ndarray
    mahalanobis_sq: float
    passed: bool
    score: float
    clique_size: int
    rival: bool = True

    def __post_init__(self) -> None:
        object.__setattr__(self, "covariance", readonly(self.covariance, dtype=float, copy=True))


@dataclass(frozen=True, slots=True, eq=False)
class Validation:
    """The verdict on one match (paper §7) and the numbers behind it.

    Attributes
    ----------
    verdict : str
        ``"accepted"``: the pose can be used. ``"rejected_odometry"``: no hypothesis of
        the match agrees with the odometry (or the one that does is not decisively
        better than the others, or is no match by itself). ``"ambiguous"``: distinct
        hypotheses explain the scans about equally well, or a larger feature mapping
        points elsewhere than the raw scans (symmetry), and nothing chooses among them.
        ``"too_few_features"``: no pose, too few mapped features, or a constellation
        that does not fix the pose.
    pose : Pose2 or None
        The chosen pose ``T_a_b`` (maps B into A): ``match.pose``, or the hypothesis
        odometry chose. None when the match has none.
    covariance : ndarray (3, 3) or None
        Covariance of ``pose`` from the mapped features (:func:`feature_estimate`).
    hypothesis : int or None
        Index of the chosen hypothesis in ``match.hypotheses`` (0: the match's own).
    mahalanobis_sq : float or None
        Squared Mahalanobis distance of ``pose`` from the odometry prior; None without
        odometry.
    gate : float
        The gate on ``mahalanobis_sq`` (chi-square, 3 dof).
    prior, prior_covariance : Pose2, ndarray (3, 3), or None
        The odometry prior (:func:`odometry_prior`).
    n_features : int
        Mapped features of the chosen hypothesis that agree with its pose.
    std : (float, float) or None
        ``(largest translation std in m, heading std in rad)`` the constellation allows.
    checks : tuple of HypothesisCheck
        The hypotheses tested against odometry (empty without odometry).
    reasons : tuple of str
        Why, in words, with the numbers.
    rivals : tuple of int
        Indices in ``match.hypotheses`` of the rivals of the match's own hypothesis
        (:func:`validate_match`, step 2): empty when nothing contests it.
    posterior : float or None
        When odometry had to choose (rivals, or the match's own pose outside the gate):
        the posterior probability of the hypothesis it favoured among the contenders.
        None when it only vetoed, or without odometry.
    """

    verdict: str
    pose: Pose2 | None
    covariance: np.ndarray | None
    hypothesis: int | None
    mahalanobis_sq: float | None
    gate: float
    prior: Pose2 | None
    prior_covariance: np.ndarray | None
    n_features: int
    std: tuple[float, float] | None
    checks: tuple[HypothesisCheck, ...]
    reasons: tuple[str, ...]
    rivals: tuple[int, ...] = ()
    posterior: float | None = None

    def __post_init__(self) -> None:
        if self.verdict not in VERDICTS:
            raise ScanError(f"Validation.verdict must be one of {VERDICTS}, got {self.verdict!r}")
        object.__setattr__(self, "covariance", readonly(self.covariance, dtype=float, copy=True))
        prior = readonly(self.prior_covariance, dtype=float, copy=True)
        object.__setattr__(self, "prior_covariance", prior)
        object.__setattr__(self, "checks", tuple(self.checks))
        object.__setattr__(self, "reasons", tuple(self.reasons))
        object.__setattr__(self, "rivals", tuple(int(k) for k in self.rivals))

    @property
    def accepted(self) -> bool:
        return self.verdict == ACCEPTED

    def to_dict(self) -> dict:
        """A JSON-ready summary (non-finite numbers become None)."""

        def pose(p):
            return None if p is None else {"x": p.x, "y": p.y, "theta": p.theta}

        def mat(a):
            return None if a is None else np.where(np.isfinite(a), a, None).tolist()

        def num(v):
            return None if v is None or not math.isfinite(v) else float(v)

        return {
            "verdict": self.verdict,
            "pose": pose(self.pose),
            "covariance": mat(self.covariance),
            "hypothesis": self.hypothesis,
            "mahalanobis_sq": num(self.mahalanobis_sq),
            "gate": self.gate,
            "prior": pose(self.prior),
            "prior_covariance": mat(self.prior_covariance),
            "n_features": self.n_features,
            "std": None if self.std is None else [num(self.std[0]), num(self.std[1])],
            "checks": [
                {
                    "hypothesis": c.index,
                    "pose": pose(c.pose),
                    "mahalanobis_sq": num(c.mahalanobis_sq),
                    "passed": c.passed,
                    "score": c.score,
                    "clique_size": c.clique_size,
                }
                for c in self.checks
            ],
            "reasons": list(self.reasons),
            "rivals": list(self.rivals),
            "posterior": num(self.posterior),
        }


# ---------------------------------------------------------------------------------------
# The precision of a constellation (paper §7)
# ---------------------------------------------------------------------------------------
def _hypothesis_estimate(
    match: ScanMatch, h: Hypothesis, gate_probability: float
) -> tuple[PoseEstimate | None, int]:
    """Feature estimate about ``h.pose`` and the number of pairs it keeps."""
    fa, fb = match.features_a, match.features_b
    ordered = points_first(h.node_pairs, fa.n_points)
    if len(ordered) == 0:
        return h.estimate, 0
    at_pose = estimate_pose_lsq_pairs(fa, fb, ordered, initial=h.pose, iterations=0)
    if at_pose is None:
        return h.estimate, 0
    keep = at_pose.residuals <= math.sqrt(chi2_quantile(gate_probability, 2))
    n_keep = int(keep.sum())
    if n_keep >= 2:
        est = estimate_pose_lsq_pairs(fa, fb, ordered[keep], initial=h.pose)
        if est is not None:
            return est, n_keep
    return h.estimate, n_keep


def feature_estimate(
    match: ScanMatch, hypothesis: int = 0, *, gate_probability: float = 0.999
) -> PoseEstimate | None:
    """The feature-based estimate of a match's pose, with its covariance (paper §7).

    ``match.pose`` may be refined by ICP on the raw points, while ``match.covariance``
    belongs to the weighted least-squares estimate of the whole clique, which a pair
    mapped wrongly within tolerance (a nearly collinear wall, an edge beside another) can
    bias far beyond its covariance. This estimate keeps the pairs of the chosen clique
    whose Mahalanobis residual at ``match.pose`` passes the chi-square gate
    ``gate_probability`` (2 dof, 99.9 %: 3.7 standard deviations) and re-estimates the
    pose from them (:func:`scanclique.pose.estimate_pose_lsq_pairs`, starting at
    ``match.pose``). Its covariance is the inverse information of those features: the
    precision their geometry and measurement noise allow, large (or infinite) along a
    corridor seen only along its walls. When fewer than two pairs pass, the clique's own
    estimate (``hypotheses[hypothesis].estimate``) is returned.

    Over 600 simulated pairs the normalised estimation error squared of this estimate
    lies in the 95 % chi-square band (``benchmarks/validation.py --nees``).

    Parameters
    ----------
    match : ScanMatch
    hypothesis : int
        Which hypothesis (0: the chosen one).
    gate_probability : float
        Probability of the per-pair gate.

    Returns
    -------
    PoseEstimate or None
        None when the match has no pose (or that hypothesis none).
    """
    if match.pose is None or not 0 <= hypothesis < len(match.hypotheses):
        return None
    est, _ = _hypothesis_estimate(match, match.hypotheses[hypothesis], gate_probability)
    return est


# ---------------------------------------------------------------------------------------
# Verdicts
# ---------------------------------------------------------------------------------------
def _distinct(match: ScanMatch, p: Pose2, q: Pose2) -> bool:
    return distinct_poses(p, q, match.config)


def _hyp_cov(match: ScanMatch, k: int, h: Hypothesis, est: PoseEstimate | None) -> np.ndarray:
    if est is not None:
        return np.asarray(est.covariance)
    if h.estimate is not None:
        return np.asarray(h.estimate.covariance)
    if match.covariance is not None:
        return np.asarray(match.covariance)
    return np.diag([0.05**2, 0.05**2, math.radians(1.0) ** 2])


def _rivals(match: ScanMatch, min_score: float) -> list[int]:
    """Indices of the hypotheses that make a match ambiguous: the best-ranked hypothesis
    of each pose distinct from the chosen one (:func:`scanclique.match.distinct_poses`
    under the match's configuration) that

    * explains the raw scans nearly as well (the rule of
      :func:`scanclique.match.match_prepared`, counted when ``match.ambiguous``), or
    * maps more features than the chosen one (a larger clique) and explains the raw
      scans at least as well as the matcher demands of any pose (score at least
      ``min_score``): *conflicting evidence*, see :func:`validate_match`.
    """
    hyps = match.hypotheses
    if not hyps:
        return []
    best = hyps[0]
    out: list[int] = []
    for k, h in enumerate(hyps[1:], start=1):
        near = match.ambiguous and near_rival(h, best, match.config)
        larger = h.clique_size > best.clique_size and h.score >= min_score
        if (
            (near or larger)
            and _distinct(match, h.pose, best.pose)
            and all(_distinct(match, h.pose, hyps[j].pose) for j in out)
        ):
            out.append(k)
    return out


def _larger_rivals(match: ScanMatch, rivals: Sequence[int]) -> list[int]:
    best = match.hypotheses[0]
    return [k for k in rivals if match.hypotheses[k].clique_size > best.clique_size]


def _contenders(match: ScanMatch, cfg: ValidationConfig) -> tuple[list[int], list[int]]:
    """The hypotheses odometry may choose among, in two tiers: first the match's own and
    its rivals (:func:`_rivals`); then the best-ranked hypothesis of every other
    distinct pose whose score is at least ``contender_score`` of the best and whose
    clique has ``min_features`` (looked at only when the first tier all disagree with
    odometry)."""
    hyps = match.hypotheses
    if not hyps:
        return [], []
    first = [0, *_rivals(match, cfg.rival_min_score)]
    best = hyps[0]
    second: list[int] = []
    for k, h in enumerate(hyps[1:], start=1):
        if k in first or h.clique_size < cfg.min_features:
            continue
        if h.score < cfg.contender_score * best.score:
            continue
        if all(_distinct(match, h.pose, hyps[j].pose) for j in first + second):
            second.append(k)
    return first, second


def check_hypotheses(
    match: ScanMatch,
    prior: Pose2,
    prior_covariance,
    gate: float = GATE_99,
    *,
    config: ValidationConfig | None = None,
) -> tuple[HypothesisCheck, ...]:
    """Test the contending hypotheses of a match against an odometry prior.

    The contenders are the match's chosen hypothesis, its rivals (``rival=True``; see
    :func:`validate_match`, step 2), then the best-ranked hypothesis of every other distinct
    pose (0.3 m or 5 degrees apart) whose score is at least ``config.contender_score`` of
    the best. Each is tested with its feature covariance (:func:`feature_estimate`; the
    match's covariance for hypotheses that carry only a closed-form pose).
    """
    cfg = config or match.config.validation
    prior = check_pose(prior, "prior")
    prior_cov = check_covariance(prior_covariance, "prior_covariance")
    first, second = _contenders(match, cfg)
    out = []
    for k in first + second:
        h = match.hypotheses[k]
        est = (
            _hypothesis_estimate(match, h, cfg.feature_gate)[0]
            if (k == 0 or h.estimate is not None)
            else None
        )
        cov = _hyp_cov(match, k, h, est)
        d2 = mahalanobis_sq(h.pose, cov, prior, prior_cov)
        out.append(
            HypothesisCheck(k, h.pose, cov, d2, d2 <= gate, h.score, h.clique_size, k in first)
        )
    return tuple(out)


def choose_by_odometry(
    match: ScanMatch,
    prior: Pose2,
    prior_covariance,
    gate: float = GATE_99,
    *,
    config: ValidationConfig | None = None,
) -> Hypothesis | None:
    """The one hypothesis of a match that odometry supports, or None.

    The match's own hypothesis and its rivals (:func:`validate_match`, step 2) are tested
    first (:func:`check_hypotheses`): when those within the gate all give one pose, the
    best-ranked of them is returned, provided odometry is decisive when there were rivals
    (posterior at least ``config.decisive``); when distinct poses pass, None (odometry
    cannot tell the symmetric places apart). When none of them passes, the other
    contenders are tested the same way, decisiveness required. None when nothing passes
    or odometry is not decisive.
    """
    cfg = config or match.config.validation
    checks = check_hypotheses(match, prior, prior_covariance, gate, config=cfg)
    k, _ = _choose(checks, cfg.decisive)
    return None if k is None else match.hypotheses[checks[k].index]


def _posterior(checks: Sequence[HypothesisCheck], k: int, pool: Sequence[int]) -> float:
    """Probability that ``checks[k]`` is the right one among the (mutually distinct)
    hypotheses ``pool``, given odometry: Gaussian likelihoods ``exp(-d2 / 2)``, equal
    priors. The normalising determinants are taken equal (the odometry covariance
    dominates every sum)."""
    d0 = checks[k].mahalanobis_sq
    rest = sum(math.exp(-0.5 * min(checks[j].mahalanobis_sq - d0, 1400.0)) for j in pool if j != k)
    return 1.0 / (1.0 + rest)


def _choose(
    checks: Sequence[HypothesisCheck], decisive: float = 0.99
) -> tuple[int | None, float | None]:
    """Index into ``checks`` of the chosen one and its posterior among the contenders
    odometry had to choose from (None when it only vetoed: the match's own hypothesis
    with no rivals). The index is None when nothing passed, or when the most probable of
    those that passed in the tier that decides has a posterior below ``decisive``."""
    for tier in (True, False):
        passed = [k for k, c in enumerate(checks) if c.rival is tier and c.passed]
        if not passed:
            continue
        pool = [j for j, c in enumerate(checks) if c.rival or not tier]
        if len(pool) == 1:
            return passed[0], None
        k = min(passed, key=lambda j: checks[j].mahalanobis_sq)
        post = _posterior(checks, k, pool)
        return (k if post >= decisive else None), post
    return None, None


def _features_used(
    match: ScanMatch, k: int, cfg: ValidationConfig
) -> tuple[int, tuple[float, float], PoseEstimate | None]:
    """For hypothesis ``k``: how many of its pairs agree with its pose (within the paper's
    §6 tolerances), the precision its constellation allows, and its feature estimate."""
    h = match.hypotheses[k]
    est, _ = _hypothesis_estimate(match, h, cfg.feature_gate)
    fa, fb = match.features_a, match.features_b
    ordered = points_first(h.node_pairs, fa.n_points)
    tol = match.config.correspondence
    n = int(
        pair_consistent_pairs(
            fa, fb, ordered, h.pose, tol.point_point, tol.line_line, tol.point_line
        ).sum()
    )
    std = constellation_std(est.covariance) if est is not None else (math.inf, math.inf)
    return n, std, est


def validate_match(
    match: ScanMatch,
    odom_a: Pose2 | None = None,
    odom_b: Pose2 | None = None,
    noise: OdometryNoise | None = None,
    gate: float = GATE_99,
    *,
    path: Sequence[Pose2] | None = None,
    config: ValidationConfig | None = None,
) -> Validation:
    """The verdict on a match (paper §7), with odometry when both poses are given.

    In order:

    1. ``too_few_features`` — the match has no pose, or the chosen hypothesis maps fewer
       than ``config.min_features`` features that agree with its pose, or the precision
       its constellation allows (:func:`constellation_std`) is worse than
       ``config.max_std_metres`` / ``max_std_radians``. The defaults, 0.10 m and 1 degree,
       are half the accuracy a match is wanted to (0.2 m, 2 degrees): the two-sigma
       region of a well-fixed pose lies within it.
    2. Rivals (:attr:`Validation.rivals`): hypotheses with a pose distinct from the
       chosen one (0.3 m or 5 degrees) that

       a. explain the raw scans nearly as well (``match.ambiguous``: a raw-scan score at
          least 0.9 of the best, a clique at most one smaller), or
       b. map *more* features than the chosen one. The paper takes the maximum clique as
          the association; the matcher ranks by raw-scan score and may prefer a smaller
          clique. Then the two kinds of evidence point at distinct poses, and the
          raw-scan score cannot confirm the choice it made itself: a third, independent
          one must decide. A larger mapping elsewhere also says that the place repeats,
          the symmetry behind every false association (§7).

       Without odometry a match with rivals is ``ambiguous``, else ``accepted``.
    3. With odometry (:func:`odometry_prior`): every contending hypothesis is tested with
       a chi-square gate on its squared Mahalanobis distance ``d2`` from the prior
       (:func:`check_hypotheses`; with a right match and a right noise model ``d2`` is
       chi-square with 3 degrees of freedom, so the 99 % gate rejects 1 % of right
       matches). The match's own hypothesis and its rivals are tested first:

       * the own passes and it has no rival: ``accepted`` (odometry only vetoes the
         raw-scan ranking);
       * some pass and there are rivals: odometry has to choose, and does so only when it
         is *decisive*: the most probable of them has a posterior probability among the
         own and its rivals (likelihoods ``exp(-d2 / 2)``, equal priors) of at least
         ``config.decisive`` (0.99); else ``ambiguous``. Passing the gate only says a
         pose is possible; choosing needs the others to be improbable;
       * none passes: the other contenders are tested; the most probable one that
         passes is chosen if decisive among all contenders, else ``ambiguous`` when
         several pass and ``rejected_odometry`` when one does (or none).

       A hypothesis other than the match's own that odometry chose must itself pass
       step 1, else ``rejected_odometry``.

    Parameters
    ----------
    match : ScanMatch
    odom_a, odom_b : Pose2, optional
        Odometry poses of the two scans' sensor (e.g. ``scan.odometry``); both or none.
    noise : OdometryNoise, optional
        The odometry error model.
    gate : float
        Gate on the squared Mahalanobis distance (default: chi-square 99 %, 3 dof).
    path : sequence of Pose2, optional
        Odometry poses from A to B, for the distance travelled (see
        :func:`odometry_prior`).
    config : ValidationConfig, optional

    Returns
    -------
    Validation

    Raises
    ------
    ScanError
        One odometry pose without the other, or a pose that is not a Pose2.
    """
    if not isinstance(match, ScanMatch):
        raise ScanError(f"validate_match expects a ScanMatch, got {type(match).__name__}")
    require_config("validate_match: ", config, ValidationConfig)
    cfg = config or match.config.validation
    if not (isinstance(gate, (int, float)) and math.isfinite(gate) and gate > 0):
        raise ConfigError(f"gate must be a positive number, got {gate!r}")
    if (odom_a is None) != (odom_b is None):
        raise ScanError("validate_match needs both odometry poses or neither")
    prior = prior_cov = None
    if odom_a is not None and odom_b is not None:
        prior, prior_cov = odometry_prior(odom_a, odom_b, noise, path=path)

    rivals = tuple(_rivals(match, cfg.rival_min_score)) if match.hypotheses else ()

    def result(verdict, k, reasons, mahal=None, checks=(), n=0, std=None, est=None, post=None):
        pose = None if k is None else match.hypotheses[k].pose
        cov = None if est is None else est.covariance
        return Validation(
            verdict,
            pose,
            cov,
            k,
            mahal,
            float(gate),
            prior,
            prior_cov,
            n,
            std,
            checks,
            reasons,
            rivals,
            post,
        )

    # 1. does the constellation fix the pose? (paper §7: its precision, like GPS DOP)
    if match.pose is None or not match.hypotheses:
        return result(TOO_FEW_FEATURES, None, (f"no pose: {match.reason}",))
    n, std, est = _features_used(match, 0, cfg)
    if n < cfg.min_features:
        return result(
            TOO_FEW_FEATURES,
            0,
            (f"{n} mapped features agree with the pose, fewer than {cfg.min_features}",),
            n=n,
            std=std,
            est=est,
        )
    if std[0] > cfg.max_std_metres or std[1] > cfg.max_std_radians:
        return result(
            TOO_FEW_FEATURES,
            0,
            (
                f"the {n} mapped features fix the pose to {_fmt_std(std)} only (limits "
                f"{cfg.max_std_metres:g} m, {math.degrees(cfg.max_std_radians):g} deg)",
            ),
            n=n,
            std=std,
            est=est,
        )

    # 2. without odometry: the match's own evidence of symmetry
    if prior is None:
        if match.ambiguous or rivals:
            return result(
                AMBIGUOUS,
                0,
                (_ambiguity_reason(match, rivals),),
                n=n,
                std=std,
                est=est,
            )
        return result(
            ACCEPTED,
            0,
            (f"{n} mapped features, pose fixed to {_fmt_std(std)}",),
            n=n,
            std=std,
            est=est,
        )

    # 3. with odometry: which of the contending hypotheses does it support?
    checks = check_hypotheses(match, prior, prior_cov, gate, config=cfg)
    chosen, post = _choose(checks, cfg.decisive)
    c0 = checks[0]
    sig0 = math.sqrt(c0.mahalanobis_sq)
    if chosen is None:
        passed = [c for c in checks if c.passed]
        if not passed:
            why = f"pose is {sig0:.1f} sigma from odometry (gate {math.sqrt(gate):.1f})"
            if len(checks) == 2:
                why += "; nor does the other contending hypothesis"
            elif len(checks) > 2:
                why += f"; nor do the {len(checks) - 1} other contending hypotheses"
            return result(REJECTED_ODOMETRY, 0, (why,), c0.mahalanobis_sq, checks, n, std, est)
        tier = [c for c in passed if c.rival is passed[0].rival]
        if len(tier) > 1:
            ks = ", ".join(f"{c.index} ({math.sqrt(c.mahalanobis_sq):.1f} sigma)" for c in tier)
            why = (
                f"distinct hypotheses {ks} all agree with odometry (the most probable has "
                f"posterior {post:.3f} < {cfg.decisive:g})"
            )
            return result(AMBIGUOUS, 0, (why,), c0.mahalanobis_sq, checks, n, std, est, post)
        # one hypothesis passed, but odometry does not single it out (posterior < decisive)
        c = tier[0]
        undecided = (
            f"hypothesis {c.index} is {math.sqrt(c.mahalanobis_sq):.1f} sigma from odometry "
            f"but its posterior among the contenders is only {post:.3f} "
            f"(< {cfg.decisive:g})"
        )
        if c.rival:
            return result(AMBIGUOUS, 0, (undecided,), c0.mahalanobis_sq, checks, n, std, est, post)
        why0 = f"pose is {sig0:.1f} sigma from odometry (gate {math.sqrt(gate):.1f}); {undecided}"
        return result(REJECTED_ODOMETRY, 0, (why0,), c0.mahalanobis_sq, checks, n, std, est, post)
    c = checks[chosen]
    if c.index == 0:
        why = f"{n} mapped features; {sig0:.1f} sigma from odometry"
        n_rivals = sum(1 for c in checks[1:] if c.rival)
        if n_rivals:
            why += " (odometry resolved the ambiguity: "
            why += "its rival disagrees" if n_rivals == 1 else f"its {n_rivals} rivals disagree"
            why += f", posterior {post:.3f})"
        return result(ACCEPTED, 0, (why,), c.mahalanobis_sq, checks, n, std, est, post)
    n_c, std_c, est_c = _features_used(match, c.index, cfg)
    why = (
        f"odometry chose hypothesis {c.index} ({n_c} mapped features, "
        f"{math.sqrt(c.mahalanobis_sq):.1f} sigma from odometry, posterior {post:.3f}) over "
        f"the match's own ({sig0:.1f} sigma)"
    )
    weak = None
    if n_c < cfg.min_features:
        weak = f"only {n_c} of its features agree with its pose (fewer than {cfg.min_features})"
    elif std_c[0] > cfg.max_std_metres or std_c[1] > cfg.max_std_radians:
        weak = f"its features fix the pose to {_fmt_std(std_c)} only"
    if weak is not None:
        # the match's own pose disagrees with odometry, and what agrees is not a match
        why0 = f"pose is {sig0:.1f} sigma from odometry (gate {math.sqrt(gate):.1f}); "
        why0 += f"hypothesis {c.index} agrees with odometry but {weak}"
        return result(REJECTED_ODOMETRY, 0, (why0,), c0.mahalanobis_sq, checks, n, std, est, post)
    return result(ACCEPTED, c.index, (why,), c.mahalanobis_sq, checks, n_c, std_c, est_c, post)


def _fmt_std(std) -> str:
    s_xy, s_th = std
    if not math.isfinite(s_xy) or not math.isfinite(s_th):
        return "nothing in some direction (degenerate)"
    return f"{s_xy:.3f} m, {math.degrees(s_th):.2f} deg (1 sigma)"


def _ambiguity_reason(match: ScanMatch, rivals: Sequence[int]) -> str:
    best = match.hypotheses[0]
    if not rivals:
        return "the match is flagged ambiguous"
    k = rivals[0]
    h = match.hypotheses[k]
    t, r = h.pose.distance_to(best.pose)
    more = f"; {len(rivals)} distinct rival poses" if len(rivals) > 1 else ""
    if h.clique_size > best.clique_size:
        what = (
            f"hypothesis {k} maps more features ({h.clique_size}, score {h.score:.2f}) than "
            f"the chosen one ({best.clique_size}, score {best.score:.2f}) at a pose "
        )
    else:
        what = (
            f"hypothesis {k} ({h.clique_size} features, score {h.score:.2f}) explains the "
            f"scans nearly as well as the chosen one ({best.clique_size} features, score "
            f"{best.score:.2f}) at a pose "
        )
    return what + f"{t:.2f} m and {math.degrees(r):.1f} deg away{more}"
