"""Verification of a place candidate: the clique matcher, then validation (paper §5–§7).

The prefilter (:mod:`.index`) only ranks; a place is recognised when the matcher finds
the mapping of the features common to the stored observation and the query and the
validation (:func:`scanclique.validation.validate_match`) accepts it. Without a prior
(a place query has no odometry between the place and the query) the validation rests on
the match's own evidence: enough mapped features, a constellation that fixes the pose,
and no rival hypothesis (symmetry) explaining the scans nearly as well.

A candidate's verdict, with the meanings of pairwise validation:

``accepted``
    the validation accepted the match (and its raw-scan score is at least ``min_score``):
    the pose can be used;
``ambiguous``
    distinct hypotheses explain the scans about equally well (the place repeats), or a
    distinct pose explains them nearly as well while the place's points lie where the
    query saw through (:func:`look_alike`), or (a
    place query, :class:`.database.PlaceDB`) the hit's :func:`confidence` is below
    ``min_confidence``: the pose is the best one's, and must not be used without other
    evidence;
``rejected``
    no pose, too few mapped features, a constellation that does not fix the pose, or an
    accepted match whose score is below ``min_score`` or that maps fewer than
    ``min_features`` features.
"""

from __future__ import annotations

import dataclasses
import math
import time
from dataclasses import dataclass

import numpy as np

from .._records import readonly
from ..config import MatchConfig
from ..geometry import Pose2
from ..match import PreparedScan, conflict_fraction, distinct_poses, match_prepared, pose_score
from ..refine import icp_point_to_line, weak_direction
from ..validation import ACCEPTED as _V_ACCEPTED
from ..validation import AMBIGUOUS as _V_AMBIGUOUS
from ..validation import ValidationConfig, validate_match

__all__ = [
    "ALIAS_TURNS",
    "SEED_MIN_CONSTRAINT",
    "SEED_MIN_FITNESS",
    "verify_seeded",
    "alias_score",
    "ACCEPTED",
    "AMBIGUOUS",
    "REJECTED",
    "VERDICTS",
    "ACCEPT_MIN_SCORE",
    "ACCEPT_MIN_FEATURES",
    "ALIAS_SURPRISE",
    "LOOK_ALIKE_RIVAL",
    "LOOK_ALIKE_CONFLICT",
    "look_alike",
    "Verification",
    "verify_pair",
    "ACCEPT_MIN_CONFIDENCE",
    "CONFIDENCE_WEIGHTS",
    "clique_surprise",
    "conflict_fraction",
    "confidence",
    "rival_ratio",
    "below_confidence",
]

ACCEPTED = "accepted"
AMBIGUOUS = "ambiguous"
REJECTED = "rejected"
VERDICTS = (ACCEPTED, AMBIGUOUS, REJECTED)
#: the default ``min_score`` of place recognition: a place is recognised only when the raw
#: scans agree on at least this under the match's pose (the score is the fraction of
#: points within ``refine.inlier_distance`` of the other scan, less the points in its
#: free space); the mapping back end's floor for a loop closure
#: (``LoopConfig.min_score``). Pairwise validation alone accepts the geometric aliases of
#: a building (a corridor's doors, rooms alike) far too often when there is no odometry
#: to veto them; until session 9 this was 0.5 for that reason. The hit's
#: :func:`confidence` now weighs the free-space conflicts that tell aliases apart, and a
#: low score without conflicts is a small overlap, mostly right: with 0.3 instead of 0.5
#: the default answers (confidence 0.99) recall 0.728 / 0.342 / 0.648 of the queries with
#: a true place instead of 0.700 / 0.316 / 0.604 (intel / csail / freiburg; 5 candidates,
#: before :data:`.database.ESCALATE`), still all right (``benchmarks/places.py``; 0.3
#: recalls as much as any lower floor).
ACCEPT_MIN_SCORE = 0.3
#: the default ``min_features`` of place recognition: a place is recognised only when at
#: least this many mapped features agree with the pose; pairwise validation's 3
#: (``ValidationConfig.min_features``). A place query has no odometry to veto a
#: building's geometric aliases, which mostly map 3 or 4 features: until session 9 this
#: was 5 for that reason (39 of the 51 wrong answers that passed the score test mapped 3
#: or 4, against 48 of 924 right ones). The hit's :func:`confidence` now tells aliases
#: from revisits by their free-space conflicts (:func:`conflict_fraction`), and with 3 the
#: recall at 99 % precision, each log under the confidence fitted on the two others,
#: rose from 0.761 / 0.395 / 0.702 (intel / csail / freiburg, with 5) to 0.770 / 0.474 /
#: 0.714 (``benchmarks/places.py --calibrate --min-features``, 5 candidates, before
#: :data:`.database.ESCALATE`).
ACCEPT_MIN_FEATURES = 3
#: the least information the raw scans give about the translation along their weakest
#: direction for a pose found on the raw scans alone (:func:`verify_seeded`): the smallest
#: eigenvalue of the mean outer product of the paired points' unit normals (0: the scans
#: slide freely along a corridor; 0.5: every direction alike). The mapping back end's
#: rule for a closure the raw scans place (``FrontEndConfig.icp_min_constraint``), for
#: the same reason: along a corridor only features fix a pose, and doors repeat.
SEED_MIN_CONSTRAINT = 0.05
#: the least fraction of the query's sampled points ICP pairs at its final
#: correspondence distance (``FrontEndConfig.icp_min_fitness``, the same rule)
SEED_MIN_FITNESS = 0.6
#: the turns of the alternatives a pose found on the raw scans must beat
#: (:func:`verify_seeded`): a room, a corridor crossing or a hall looks alike turned by a
#: quarter or a half turn, the aliases of indoor places
ALIAS_TURNS = (0.5 * np.pi, np.pi, 1.5 * np.pi)
#: an accepted match whose clique's :func:`clique_surprise` is below this (a clique of
#: mapped features about as likely between unrelated places: mostly 3 or 4 features) has
#: its pose's quarter- and half-turn aliases scored on the raw scans too
#: (:func:`alias_score`), the best as its rival: the raw scans alone vouch for such a pose,
#: and a corridor or a room seen the other way can score as well. On the shared logs
#: degraded to a 5.6 m range (``benchmarks/places.py --degrade range-5.6``) the confidence
#: fitted on 80 m scans accepted half-turn aliases of 3 mapped features scoring above 0.9:
#: the defaults' answers were wrong 1 / 2 / 2 times (intel / csail / freiburg), and are
#: 0 / 0 / 2 times with this (recall at 100 % precision 0.364 -> 0.687 on intel; the two
#: left have surprising cliques). On the logs as recorded it costs the defaults 2 right
#: answers on intel and 1 on freiburg (recall 0.746 -> 0.737, 0.662 -> 0.661; at 99 %
#: precision 0.826 -> 0.836 on intel, the others unchanged).
ALIAS_SURPRISE = 1.0
#: an accepted pose is a look-alike (:func:`look_alike`) when a distinct pose explains
#: the raw scans at least this fraction as well (:func:`rival_ratio`) ...
LOOK_ALIKE_RIVAL = 0.8
#: ... and more than this fraction of either scan's points lies where the other saw
#: through (:func:`conflict_fraction`). Each is a sign of a look-alike place that
#: :func:`confidence` weighs; together they are close to proof of one: of the hits the
#: validation accepted on the shared logs (``benchmarks/places.py``, session 37's run)
#: the two together mark 149 wrong ones and 11 right ones. Weighed one by one, the
#: evidence of a large clique outweighs them: on a campus of streets lined with trees
#: (``benchmarks/places_sensors.py --world campus``) a noisy 360-degree scanner's cliques
#: of 7-16 alike trees across streets scored surprises of 14-97, and 60 of the 230 answers
#: of confidence 0.99 were wrong; 40 of the 60 had both signs, 1 of the 170 right ones
#: (whose conflicts are mostly 0; the 90th percentile 0.008). With the rule that
#: scanner's precision is 0.896 instead of 0.739 (recall 0.726 instead of 0.715); the
#: other scanners', outdoors and indoors, are the same, as are the shared logs' default
#: answers (precision 1.000, recall 0.737 / 0.342 / 0.661) and their recall at 99 %
#: precision but for one Freiburg query (0.836 / 0.447 / 0.735 instead of 0.736).
LOOK_ALIKE_CONFLICT = 0.01
#: the logistic model of :func:`confidence`: log-odds that a verified pose is right =
#: ``w0 + w_score * score + w_surprise * surprise + w_rival * rival_ratio
#: + w_conflict * conflict``. Fitted (L2-regularised logistic regression) on every accepted
#: hit of the recognition runs on the three shared logs (``benchmarks/places.py
#: --calibrate``, session 9: 5 candidates, escalation 5). Fitted on two logs and scored on
#: the third, the recall at 99 % precision is 0.826 / 0.447 / 0.735 (intel / csail /
#: freiburg), at 100 % 0.812 / 0.447 / 0.692, the default answers (confidence 0.99) all
#: right; the weights of those fits: w0 1.1 to 1.7, w_score 3.9 to 5.3, w_surprise 0.13
#: to 0.15, w_rival -2.6 to -4.0, w_conflict -66 to -81.
CONFIDENCE_WEIGHTS = (1.567, 4.909, 0.141, -3.711, -68.595)
#: the default ``min_confidence`` of place recognition: an accepted hit whose
#: :func:`confidence` is below this is ``ambiguous`` ("right unless said otherwise")
ACCEPT_MIN_CONFIDENCE = 0.99
#: order of verdicts when ranking hits (best first)
VERDICT_RANK = {ACCEPTED: 0, AMBIGUOUS: 1, REJECTED: 2}


@dataclass(frozen=True, slots=True, eq=False)
class Verification:
    """The verdict on one (place, query) pair.

    Attributes
    ----------
    verdict : str
        ``"accepted"``, ``"ambiguous"`` or ``"rejected"`` (module docstring).
    pose : Pose2 or None
        Pose of the query's sensor frame in the place's frame (maps query points into
        the place's frame); None when rejected.
    covariance : ndarray (3, 3) or None
        Covariance of ``pose`` from the mapped features (m², m·rad, rad²).
    score : float
        Raw-scan agreement of the match's pose (:func:`scanclique.match.pose_score`,
        at most 1); 0 without a pose.
    n_features : int
        Mapped features that agree with the pose.
    validation : str
        The pairwise validation's verdict (``accepted``, ``ambiguous``,
        ``too_few_features``).
    reason : str
        Why, in words.
    seconds : float
        Time of the match and its validation.
    clique_size : int
        Size of the chosen clique (0 without one, and for a seeded pose).
    graph_nodes, graph_edges : int
        Nodes and edges of the match's correspondence graph (:mod:`scanclique.correspondence`).
    place_features, query_features : int
        Features of the place and of the query.
    rival_score : float
        Best raw-scan score of a hypothesis with a pose distinct from the chosen one: the
        match's other hypotheses (:func:`scanclique.match.distinct_poses`; scored on every
        third sample point for all but the best few), and for an accepted clique whose
        surprise is below :data:`ALIAS_SURPRISE` also the pose's best alias; for a seeded
        pose its best alias (:func:`alias_score`); 0 without one.
    confidence : float
        Probability that ``pose`` is right (:func:`confidence`); 0 without a pose.
    conflict : float
        :func:`conflict_fraction` at ``pose`` (0 without a pose).
    """

    verdict: str
    pose: Pose2 | None
    covariance: np.ndarray | None
    score: float
    n_features: int
    validation: str
    reason: str
    seconds: float
    clique_size: int = 0
    graph_nodes: int = 0
    graph_edges: int = 0
    place_features: int = 0
    query_features: int = 0
    rival_score: float = 0.0
    confidence: float = 0.0
    conflict: float = 0.0

    @property
    def surprise(self) -> float:
        """:func:`clique_surprise` of the mapped features in the correspondence graph."""
        return clique_surprise(self.n_features, self.graph_nodes, self.graph_edges)

    def __post_init__(self) -> None:
        object.__setattr__(self, "covariance", readonly(self.covariance, dtype=float, copy=True))

    def to_dict(self) -> dict:
        p = self.pose
        return {
            "verdict": self.verdict,
            "pose": None if p is None else {"x": p.x, "y": p.y, "theta": p.theta},
            "score": self.score,
            "n_features": self.n_features,
            "validation": self.validation,
            "reason": self.reason,
            "confidence": self.confidence,
            "conflict": self.conflict,
        }


def clique_surprise(n: int, nodes: int, edges: int) -> float:
    """How unlikely ``n`` mutually consistent correspondences are by chance: ``-log10``
    of the expected number of cliques of ``n`` nodes in a random graph with the
    correspondence graph's ``nodes`` and ``edges`` (Erdős–Rényi, edge probability
    ``p = edges / C(nodes, 2)``), ``E = C(nodes, n) p^(n (n - 1) / 2)``.

    The null model of two unrelated places: their features pair up as often as the
    tolerances let them (the graph's size) and pairs of pairs agree as often as they do
    here (its density), but no pose links them. A clique that such a graph would hold
    many times (surprise below 0) is no evidence of a place; each decade above 0 is one
    more of evidence. Denser graphs (repetitive, Manhattan geometry) make a clique of a
    given size less surprising. 0 when ``n < 2``, ``nodes < 2`` or ``n > nodes`` (no
    clique to judge); ``p`` is floored at ``1e-12`` (a graph without edges).

    >>> round(clique_surprise(6, 80, 400), 2)
    4.99
    >>> clique_surprise(8, 80, 400) > clique_surprise(6, 80, 400) > clique_surprise(6, 80, 800)
    True
    """
    n, V, E = int(n), int(nodes), int(edges)
    if n < 2 or V < 2 or n > V:
        return 0.0
    p = min(1.0, max(E / (V * (V - 1) / 2), 1e-12))
    log_choose = math.lgamma(V + 1) - math.lgamma(n + 1) - math.lgamma(V - n + 1)
    return -(log_choose + n * (n - 1) / 2 * math.log(p)) / math.log(10)


def rival_ratio(score: float, rival_score: float) -> float:
    """``rival_score / score`` clipped to ``[0, 1]`` (1 when ``score <= 0``): how nearly a
    distinct pose explains the same scans, as :func:`confidence` reads it."""
    s = float(score)
    return min(1.0, max(0.0, float(rival_score)) / s) if s > 0 else 1.0


def confidence(
    score: float, surprise: float = 0.0, rival_score: float = 0.0, conflict: float = 0.0
) -> float:
    """Probability that a verified pose is right, from the evidence the verification
    has: a logistic model (:data:`CONFIDENCE_WEIGHTS`) of

    * ``score``, the raw scans' agreement under the pose (:func:`scanclique.match.pose_score`);
    * ``surprise``, how unlikely its clique of mapped features is between unrelated places
      (:func:`clique_surprise`; 0 for a pose with no mapped features);
    * the rival ratio ``rival_score / score`` (clipped to ``[0, 1]``; 1 when ``score <= 0``):
      how nearly a distinct pose explains the same scans (paper §7's symmetry; a place
      that looks alike turned by a quarter turn gives a ratio near 1);
    * ``conflict``, the larger fraction of either scan's points lying in the other's
      observed free space (:func:`conflict_fraction`): what tells a twin room from the
      same room.

    Increasing in ``score`` and ``surprise``, decreasing in ``rival_score`` and
    ``conflict``; in ``(0, 1)``, and 0 when ``score <= 0`` (no raw point supports the
    pose more than contradicts it: nothing to confirm it by).

    A low score with no conflict is a small overlap, not a wrong pose: on the shared
    logs 94 % of the accepted hits scoring 0.15-0.3 with under 0.5 % of conflicting points
    were right, 8 % of those with over 2 %.

    >>> confidence(0.9, 20.0, 0.1) > 0.99 > confidence(0.5, 2.0, 0.4)
    True
    >>> confidence(0.9, 20.0, 0.1, conflict=0.1) < 0.99 < confidence(0.9, 20.0, 0.1)
    True
    """
    if float(score) <= 0.0:
        return 0.0
    w0, ws, wn, wr, wc = CONFIDENCE_WEIGHTS
    z = (
        w0
        + ws * float(score)
        + wn * float(surprise)
        + wr * rival_ratio(score, rival_score)
        + wc * float(conflict)
    )
    return 1.0 / (1.0 + math.exp(-z)) if z > -700 else 0.0


def below_confidence(v: Verification, min_confidence: float) -> Verification:
    """``v``, an accepted verification whose confidence is below ``min_confidence`` made
    ``ambiguous`` (the pose kept, the reason saying why)."""
    if v.verdict != ACCEPTED or v.confidence >= min_confidence:
        return v
    return dataclasses.replace(
        v,
        verdict=AMBIGUOUS,
        reason=f"confidence {v.confidence:.3f} below min_confidence {min_confidence:g}; "
        + v.reason,
    )


def look_alike(v: Verification) -> Verification:
    """``v``, an accepted verification, made ``ambiguous`` when two independent signs say
    its place only looks like the query's: a distinct pose explains the raw scans nearly
    as well (a rival ratio of at least :data:`LOOK_ALIKE_RIVAL`, paper §7's symmetry) and
    the scans contradict each other under the pose (a :attr:`Verification.conflict` above
    :data:`LOOK_ALIKE_CONFLICT`: a tree, a pillar or a wall of one where the other saw
    free space). The pose is kept, the reason says why.

    >>> from scanclique.geometry import Pose2
    >>> v = Verification(ACCEPTED, Pose2(0, 0, 0), None, 0.7, 12, "accepted", "", 0.0,
    ...                  rival_score=0.63, confidence=0.999, conflict=0.03)
    >>> look_alike(v).verdict, look_alike(dataclasses.replace(v, conflict=0.0)).verdict
    ('ambiguous', 'accepted')
    """
    if v.verdict != ACCEPTED or v.pose is None:
        return v
    ratio = rival_ratio(v.score, v.rival_score)
    if ratio < LOOK_ALIKE_RIVAL or v.conflict <= LOOK_ALIKE_CONFLICT:
        return v
    return dataclasses.replace(
        v,
        verdict=AMBIGUOUS,
        reason=f"a look-alike: a distinct pose scores {ratio:.2f} of the pose's score and "
        f"{100 * v.conflict:.1f} % of the points conflict; " + v.reason,
    )


def verify_pair(
    place: PreparedScan,
    query: PreparedScan,
    config: MatchConfig | None = None,
    *,
    min_score: float = ACCEPT_MIN_SCORE,
    min_features: int = ACCEPT_MIN_FEATURES,
    min_confidence: float = ACCEPT_MIN_CONFIDENCE,
    validation: ValidationConfig | None = None,
) -> Verification:
    """Match ``query`` against ``place`` and validate the match (no odometry).

    Parameters
    ----------
    place, query : PreparedScan
        The stored observation (scan A of the match) and the query (scan B).
    config : MatchConfig, optional
    min_score : float
        An accepted match whose raw-scan score is below this is ``rejected`` (0: the
        validation alone decides).
    min_features : int
        An accepted match mapping fewer features than this is ``rejected``.
    min_confidence : float
        An accepted match whose :func:`confidence` is below this is ``ambiguous`` (0:
        the validation, ``min_score`` and ``min_features`` alone decide).
    validation : ValidationConfig, optional

    Returns
    -------
    Verification
        ``pose`` maps the query's points into the place's frame.
    """
    t0 = time.perf_counter()
    cfg = config or MatchConfig()
    m = match_prepared(place, query, cfg)
    v = validate_match(m, config=validation)
    reason = v.reasons[0] if v.reasons else ""
    if v.verdict == _V_ACCEPTED and m.score >= min_score and v.n_features >= min_features:
        verdict = ACCEPTED
    elif v.verdict == _V_ACCEPTED and m.score < min_score:
        verdict = REJECTED
        reason = f"raw-scan score {m.score:.3f} below min_score {min_score:g}; {reason}"
    elif v.verdict == _V_ACCEPTED:
        verdict = REJECTED
        reason = (
            f"{v.n_features} mapped features agree with the pose, fewer than "
            f"min_features={min_features}; {reason}"
        )
    elif v.verdict == _V_AMBIGUOUS:
        verdict = AMBIGUOUS
    else:
        verdict = REJECTED
    pose = v.pose if verdict != REJECTED else None
    cov = v.covariance if verdict != REJECTED else None
    rival = 0.0
    if m.pose is not None:
        rival = max(
            (h.score for h in m.hypotheses[1:] if distinct_poses(h.pose, m.pose, cfg)),
            default=0.0,
        )
    score = float(m.score) if m.pose is not None else 0.0
    surprise = clique_surprise(v.n_features, m.n_correspondence_nodes, m.n_correspondence_edges)
    if verdict == ACCEPTED and surprise < ALIAS_SURPRISE:
        # a clique no rarer than chance: the raw scans alone vouch for the pose, and they
        # must also tell it from its own quarter- and half-turn aliases
        rival = max(rival, alias_score(place, query, pose, cfg)[0])
    conflict = conflict_fraction(place, query, pose, cfg) if pose is not None else 0.0
    v = Verification(
        verdict,
        pose,
        cov,
        score,
        int(v.n_features),
        v.verdict,
        reason,
        time.perf_counter() - t0,
        int(m.clique_size),
        int(m.n_correspondence_nodes),
        int(m.n_correspondence_edges),
        len(place.features),
        len(query.features),
        float(rival),
        confidence(score, surprise, rival, conflict) if pose is not None else 0.0,
        conflict,
    )
    return below_confidence(look_alike(v), min_confidence)


def _icp(place: PreparedScan, query: PreparedScan, seed: Pose2, cfg: MatchConfig):
    r = cfg.refine
    return icp_point_to_line(
        place.cloud,
        query.sample,
        seed,
        iterations=2 * r.iterations,
        max_correspondence=r.max_correspondence,
        min_correspondence=r.inlier_distance,
    )


def weakest_constraint(place: PreparedScan, query: PreparedScan, pose: Pose2, dist: float):
    """How well the raw scans fix the translation of ``pose`` (maps query into place) in
    their weakest direction: the smallest eigenvalue of the mean outer product of the
    unit normals of the place's points the query's sampled points pair with within
    ``dist`` metres (0: a corridor, free along it; 0.5: every direction alike); 0 when
    fewer than 10 points pair."""
    weak = weak_direction(place.cloud, query.sample, pose, dist)
    return 0.0 if weak is None else weak[1]


def alias_score(
    place: PreparedScan, query: PreparedScan, pose: Pose2, config: MatchConfig | None = None
) -> tuple[float, Pose2 | None]:
    """The best raw-scan score of the aliases of ``pose``: the pose turned by each of
    :data:`ALIAS_TURNS` about the centroid of the query's sampled points (in the place's
    frame), each refined by ICP; only aliases that stay distinct from ``pose``
    (:func:`scanclique.match.distinct_poses`) count. ``(0, None)`` without one."""
    cfg = config or MatchConfig()
    pts = query.sample
    if len(pts) < 3:
        return 0.0, None
    c, s = np.cos(pose.theta), np.sin(pose.theta)
    cx, cy = (pts @ np.array([[c, s], [-s, c]])).mean(axis=0) + (pose.x, pose.y)
    best, where = 0.0, None
    for turn in ALIAS_TURNS:
        spin = Pose2(cx, cy, float(turn)) @ Pose2(-cx, -cy, 0.0)  # turn about the centroid
        alt = _icp(place, query, spin @ pose, cfg).pose
        if not distinct_poses(alt, pose, cfg):
            continue
        sc = pose_score(place, query, alt, cfg)
        if sc > best:
            best, where = sc, alt
    return float(best), where


def verify_seeded(
    place: PreparedScan,
    query: PreparedScan,
    seed: Pose2,
    config: MatchConfig | None = None,
    *,
    min_score: float = ACCEPT_MIN_SCORE,
    tolerance: tuple[float, float] = (1.0, 0.25),
    min_confidence: float = ACCEPT_MIN_CONFIDENCE,
) -> Verification:
    """Verify a pose hypothesis found without the clique matcher (the triangle
    prefilter's best pose bin, :meth:`.hashing.TriangleIndex.votes`) on the raw scans.

    ``seed`` (maps the query's points into the place's frame) is refined by point-to-line
    ICP of the query's sampled points onto the place's cloud (the core's
    :func:`scanclique.refine.icp_point_to_line`) and scored
    (:func:`scanclique.match.pose_score`). It is ``accepted`` only when every piece of
    evidence agrees:

    1. ICP pairs at least :data:`SEED_MIN_FITNESS` of the points;
    2. the refined pose stays within ``tolerance`` (metres, radians: one pose bin of the
       votes) of the seed: the triangles and the raw scans agree on the pose;
    3. the raw-scan score is at least ``min_score``;
    4. the raw scans fix the translation in every direction (:func:`weakest_constraint`
       at least :data:`SEED_MIN_CONSTRAINT`);
    5. no alias (:func:`alias_score`: the pose turned by a quarter or a half turn)
       scores ``refine.ambiguous_score`` of the pose's score or more (the matcher's own
       ambiguity rule, :func:`scanclique.match.near_rival`): otherwise ``ambiguous``.

    Otherwise ``rejected``; an accepted pose whose :func:`confidence` is below
    ``min_confidence`` is ``ambiguous``. ``n_features`` is 0 and ``covariance`` None (no
    features were mapped); ``validation`` is ``"seeded"``.
    """
    t0 = time.perf_counter()
    cfg = config or MatchConfig()
    r = cfg.refine

    def out(verdict, pose, score, reason, alias=0.0):
        conflict = conflict_fraction(place, query, pose, cfg) if pose is not None else 0.0
        return Verification(
            verdict, pose, None, float(score), 0, "seeded", reason, time.perf_counter() - t0,
            rival_score=float(alias),
            confidence=confidence(score, 0.0, alias, conflict) if pose is not None else 0.0,
            conflict=conflict,
        )  # fmt: skip

    if len(query.sample) < 10 or len(place.cloud.points) < 10:
        return out(REJECTED, None, 0.0, "too few points to align")
    icp = _icp(place, query, seed, cfg)
    pose = icp.pose
    score = pose_score(place, query, pose, cfg)
    if icp.fitness < SEED_MIN_FITNESS:
        return out(REJECTED, None, score, f"ICP paired {icp.fitness:.2f} of the points only")
    dt, dr = pose.distance_to(seed)
    if dt > tolerance[0] or dr > tolerance[1]:
        return out(
            REJECTED, None, score,
            f"ICP moved {dt:.2f} m, {np.degrees(dr):.1f} deg from the triangles' pose",
        )  # fmt: skip
    if score < min_score:
        return out(REJECTED, None, score, f"raw-scan score {score:.3f} below {min_score:g}")
    weak = weakest_constraint(place, query, pose, r.inlier_distance)
    if weak < SEED_MIN_CONSTRAINT:
        return out(
            REJECTED, None, score,
            f"the raw scans do not fix the pose in one direction (eigenvalue {weak:.3f})",
        )  # fmt: skip
    alias, _ = alias_score(place, query, pose, cfg)
    if alias >= r.ambiguous_score * score:
        return out(
            AMBIGUOUS, pose, score,
            f"the pose turned by a quarter or half turn scores {alias:.3f} (of {score:.3f})",
            alias,
        )  # fmt: skip
    return below_confidence(
        look_alike(out(
            ACCEPTED, pose, score,
            f"triangles' pose refined on the raw scans: score {score:.3f}, weakest direction "
            f"{weak:.3f}, best alias {alias:.3f}",
            alias,
        )),
        min_confidence,
    )  # fmt: skip
