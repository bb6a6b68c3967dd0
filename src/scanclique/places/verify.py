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
    distinct hypotheses explain the scans about equally well (the place repeats): the
    pose is the best one's, and must not be used without other evidence;
``rejected``
    no pose, too few mapped features, a constellation that does not fix the pose, or an
    accepted match whose score is below ``min_score`` or that maps fewer than
    ``min_features`` features.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from .._records import readonly
from ..config import MatchConfig
from ..geometry import Pose2
from ..match import PreparedScan, match_prepared
from ..validation import ACCEPTED as _V_ACCEPTED
from ..validation import AMBIGUOUS as _V_AMBIGUOUS
from ..validation import ValidationConfig, validate_match

__all__ = [
    "ACCEPTED",
    "AMBIGUOUS",
    "REJECTED",
    "VERDICTS",
    "ACCEPT_MIN_SCORE",
    "ACCEPT_MIN_FEATURES",
    "Verification",
    "verify_pair",
]

ACCEPTED = "accepted"
AMBIGUOUS = "ambiguous"
REJECTED = "rejected"
VERDICTS = (ACCEPTED, AMBIGUOUS, REJECTED)
#: the default ``min_score`` of place recognition: a place is recognised only when the raw
#: scans agree on at least half their points under the match's pose (the score is the
#: fraction of points within ``refine.inlier_distance`` of the other scan, less the
#: points in its free space), the same half the revisit rule of
#: :mod:`scanclique.pairsets` asks of a true place. Pairwise validation alone accepts
#: the geometric aliases of a building (a corridor's doors, rooms alike) far too often
#: when there is no odometry to veto them: on the shared logs most of the wrong
#: accepted answers score below 0.5, most right ones above (``benchmarks/places.py``).
ACCEPT_MIN_SCORE = 0.5
#: the default ``min_features`` of place recognition: a place is recognised only when at
#: least this many mapped features agree with the pose. Pairwise validation asks for 3
#: (``ValidationConfig.min_features``) because odometry can veto an alias; a place query
#: has no odometry, and the chance that a constellation repeats elsewhere in a building
#: falls fast with its size (paper §7). On the three shared logs, 39 of the 51 wrong
#: answers that pass the score test map 3 or 4 features, against 48 of the 924 right
#: ones (``benchmarks/places.py`` at cf7172d, where 3 sufficed).
ACCEPT_MIN_FEATURES = 5
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
    """

    verdict: str
    pose: Pose2 | None
    covariance: np.ndarray | None
    score: float
    n_features: int
    validation: str
    reason: str
    seconds: float

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
        }


def verify_pair(
    place: PreparedScan,
    query: PreparedScan,
    config: MatchConfig | None = None,
    *,
    min_score: float = ACCEPT_MIN_SCORE,
    min_features: int = ACCEPT_MIN_FEATURES,
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
    return Verification(
        verdict,
        pose,
        cov,
        float(m.score) if m.pose is not None else 0.0,
        int(v.n_features),
        v.verdict,
        reason,
        time.perf_counter() - t0,
    )
