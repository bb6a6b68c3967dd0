"""Validation of scan matches (paper §7; pipeline stage 8).

The maximum clique cannot map features wrongly by chance: a false mapping needs a set of
features that happens to repeat the geometry of another (symmetry in the environment).
Paper §7: such a mapping shows as a pose that disagrees with another estimate of the
motion (odometry) or with other matches, and the threshold of that test can follow from
the precision the constellation of mapped features allows.

* :mod:`~scanclique.validation.verdict` — the verdict on one match
  (:func:`validate_match`: ``accepted``, ``rejected_odometry``, ``ambiguous``,
  ``too_few_features``), the feature estimate and its covariance, odometry choosing among
  hypotheses;
* :mod:`~scanclique.validation.cycles` — cycles A→B→C against A→C
  (:func:`triple_consistency`, :func:`flag_inconsistent`).

The covariance algebra and the odometry error model they use are in
:mod:`scanclique.uncertainty`; the thresholds in :class:`scanclique.config.ValidationConfig`
(``MatchConfig.validation``, read from the match's own configuration).
"""

from ..config import ValidationConfig
from ..uncertainty import (
    GATE_99,
    OdometryNoise,
    compose_covariance,
    constellation_std,
    mahalanobis_sq,
    odometry_prior,
    pose_difference,
)
from .cycles import Consistency, flag_inconsistent, triple_consistency
from .verdict import (
    ACCEPTED,
    AMBIGUOUS,
    REJECTED_ODOMETRY,
    TOO_FEW_FEATURES,
    VERDICTS,
    HypothesisCheck,
    Validation,
    check_hypotheses,
    choose_by_odometry,
    feature_estimate,
    validate_match,
)

__all__ = [
    "ACCEPTED",
    "REJECTED_ODOMETRY",
    "AMBIGUOUS",
    "TOO_FEW_FEATURES",
    "VERDICTS",
    "GATE_99",
    "OdometryNoise",
    "ValidationConfig",
    "HypothesisCheck",
    "Validation",
    "Consistency",
    "feature_estimate",
    "constellation_std",
    "odometry_prior",
    "pose_difference",
    "mahalanobis_sq",
    "check_hypotheses",
    "choose_by_odometry",
    "validate_match",
    "compose_covariance",
    "triple_consistency",
    "flag_inconsistent",
]
