"""Configuration of :func:`scanclique.mapping.map_scans` (one frozen dataclass per stage).

Distances in metres, angles in radians. The defaults work out of the box on 2D laser logs
recorded indoors at walking speed (the SLAM benchmark logs of Kümmerle et al. 2009).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from ..config import MatchConfig
from ..config import check_positive as _positive
from ..errors import ConfigError
from ..validation import OdometryNoise

__all__ = [
    "FrontEndConfig",
    "LoopConfig",
    "BackEndConfig",
    "OccupancyConfig",
    "MapConfig",
]


@dataclass(frozen=True, slots=True)
class FrontEndConfig:
    """Consecutive association (issue 12, part 1).

    Each scan is matched against the current *keyframe* (the last scan that moved at
    least ``keyframe_distance`` or turned ``keyframe_angle`` from the keyframe before it):
    a robot standing still or creeping accumulates no drift, and every match spans a
    baseline the features can measure.

    Attributes
    ----------
    keyframe_distance, keyframe_angle : float
        A scan this far (m) or turned this much (rad) from the keyframe becomes the next
        keyframe.
    odometry_noise : OdometryNoise
        Error model of the wheel odometry (the prior of the §7 gate, and the covariance of
        an odometry edge when a match fails): twice the validation's default, which covers
        99 % of *consecutive* increments, because keyframes lie several scans apart and
        sparse logs (CSAIL: 1 m and up to 78 degrees between scans) move much more per
        match.
    velocity_noise : OdometryNoise
        Without odometry: the error model of the constant-velocity prediction, the prior
        of the gate and the (inflated) covariance of a constant-velocity edge.
    sigma_floor_metres, sigma_floor_radians : float
        Standard deviations added to every match's feature covariance before it weighs an
        edge (the feature estimate alone is often optimistic).
    refine, refine_iterations, refine_max_correspondence, refine_min_correspondence :
        Beyond the matcher: an accepted match (consecutive or closure) is refined by
        point-to-line ICP of *all* the new scan's points onto the other's full cloud
        (the matcher scores and refines on a sample of 120), correspondence distance
        shrinking from ``refine_max_correspondence`` to ``refine_min_correspondence`` m;
        kept when it stays within ``refine_max_shift`` m and ``refine_max_turn`` rad of the
        match and keeps at least ``refine_min_fitness`` of the points paired.
    icp_fallback, icp_min_score, icp_min_fitness, icp_gate :
        When the feature match fails (rejected, ambiguous, too few features): ICP from the
        prior and from the rejected match's pose, accepted when the raw scans agree
        (score, fitness) and it lies within ``icp_gate`` sigma of the prior
        (:func:`scanclique.mapping.frontend.icp_fallback`); only then the prior itself.
        Without odometry, an ICP pose scoring at least ``icp_ungated_score`` is accepted
        outside the gate of the constant-velocity prediction, when within
        ``icp_ungated_max_turn`` rad and ``icp_ungated_max_shift`` m of it.
        ``icp_min_constraint``: when the smallest eigenvalue of the mean outer product
        of the paired points' normals is below it (the scans let ICP slide along one
        direction, as in a corridor: 0 for two parallel walls, 0.5 for a room; see
        :func:`scanclique.refine.weak_direction`), the pose along that
        direction is the prior's, with the prior's variance. ``icp_score_tie``: ICP
        results (from the several seeds) whose raw-scan scores lie within it of the best
        are a tie the scans cannot break; the one nearest the first prior is taken.
    """

    keyframe_distance: float = 0.30
    keyframe_angle: float = math.radians(10.0)
    odometry_noise: OdometryNoise = field(default_factory=lambda: OdometryNoise().scaled(2.0))
    velocity_noise: OdometryNoise = field(
        default_factory=lambda: OdometryNoise(
            per_metre=0.3,
            per_radian=0.3,
            rot_per_metre=math.radians(5.0),
            floor_metres=0.15,
            floor_radians=math.radians(8.0),
        )
    )
    sigma_floor_metres: float = 0.01
    sigma_floor_radians: float = math.radians(0.25)
    refine: bool = True
    refine_iterations: int = 15
    refine_max_correspondence: float = 0.3
    refine_min_correspondence: float = 0.05
    refine_max_shift: float = 0.15
    refine_max_turn: float = math.radians(2.0)
    refine_min_fitness: float = 0.5
    icp_fallback: bool = True
    icp_min_score: float = 0.5
    icp_min_fitness: float = 0.6
    icp_gate: float = 4.0
    icp_ungated_score: float = 0.75
    icp_ungated_max_turn: float = math.radians(90.0)
    icp_ungated_max_shift: float = 1.0
    icp_min_constraint: float = 0.05
    icp_score_tie: float = 0.05

    def __post_init__(self) -> None:
        _positive(
            self, "keyframe_distance", "keyframe_angle", "sigma_floor_metres", "sigma_floor_radians"
        )


@dataclass(frozen=True, slots=True)
class LoopConfig:
    """Loop-closure candidates and their verification (issue 12, part 2).

    A keyframe ``j`` is tried against earlier keyframes ``i`` whose estimated position
    lies within ``radius + growth * D`` of its own, where ``D`` is the path travelled
    since the last accepted closure or since ``i``, whichever is shorter (the drift the
    estimate may have accumulated), capped at ``max_radius``.

    Attributes
    ----------
    enabled : bool
        False: chained consecutive matching only.
    radius, growth, max_radius : float
        Candidate radius (m), its growth per metre of path (m/m) and its cap (m).
    heading_growth : float
        Heading uncertainty per metre of path (rad/m) of the prior that gates candidates.
    min_path : float
        Keyframes less than this path length (m) apart are *local* neighbours (matched to
        tie the local chain, not loop closures).
    local : int
        How many local neighbours (besides the previous keyframe) each keyframe is
        matched to.
    per_keyframe : int
        How many loop candidates (path beyond ``min_path``) each keyframe verifies at most.
    every : int
        Loop candidates are searched on every ``every``-th keyframe.
    separation : int
        Loop candidates of one keyframe are at least this many keyframes apart.
    pcm_batch : int
        Pairwise consistency maximisation runs over the closures of this many keyframes.
    pcm_gate : float
        Probability of the chi-square gate (3 dof) of pairwise consistency.
    pcm_anchor_batches : int
        Incremental PCM: the closures accepted over the last ``pcm_anchor_batches``
        batches (their newer keyframe that recent) anchor the new ones; a new closure
        must be pairwise consistent with each of them (0: each batch on its own).
    min_score : float
        A loop closure's match needs at least this raw-scan agreement
        (:func:`scanclique.match.pose_score`; the matcher's own floor is 0.1): a revisit
        seen from afar, or a look-alike place, often maps a few features at a pose the
        scans hardly support.
    appearance : bool
        Also propose candidates by appearance (``scanclique.places.signature``) when that
        module exists.
    max_sigma_metres, max_sigma_radians : float
        A loop closure enters the graph only when its own covariance (the match's, with the
        front end's sigma floor) fixes it precisely enough to be a right closure by the
        issue's rule (within 0.20 m and 1 degree) with 99.5 % probability: the largest
        standard deviation of its translation at most ``0.20 / sqrt(chi2_2(0.995))``
        = 0.20 / 3.255 m, of its heading at most ``1 deg / 2.807`` (two-sided normal
        99.5 % quantile); 1 degree is also the angular resolution of the benchmark's
        scanners (181 beams over 180 degrees). Others get the verdict ``"imprecise"``.
    """

    enabled: bool = True
    radius: float = 1.5
    growth: float = 0.05
    max_radius: float = 6.0
    heading_growth: float = math.radians(0.5)
    min_path: float = 3.0
    local: int = 2
    per_keyframe: int = 2
    every: int = 1
    separation: int = 5
    pcm_batch: int = 10
    pcm_gate: float = 0.99
    pcm_anchor_batches: int = 2
    min_score: float = 0.3
    appearance: bool = True
    max_sigma_metres: float = 0.20 / 3.255
    max_sigma_radians: float = math.radians(1.0) / 2.807

    def __post_init__(self) -> None:
        _positive(
            self, "radius", "max_radius", "min_path", "pcm_batch", "every", "max_sigma_metres",
            "max_sigma_radians",
        )  # fmt: skip
        if not 0 < self.pcm_gate < 1:
            raise ConfigError(f"LoopConfig.pcm_gate must be in (0, 1), got {self.pcm_gate!r}")


@dataclass(frozen=True, slots=True)
class BackEndConfig:
    """SE(2) pose-graph optimisation with GTSAM (issue 12, part 3).

    ``robust``: the M-estimator on loop-closure edges (``"cauchy"``, ``"huber"``,
    ``"none"``) with scale ``robust_scale`` (in units of the edge's sigma), the second line
    of defence after PCM. ``max_iterations`` of Levenberg–Marquardt."""

    robust: str = "cauchy"
    robust_scale: float = 1.0
    max_iterations: int = 100

    def __post_init__(self) -> None:
        if self.robust not in ("cauchy", "huber", "none"):
            raise ConfigError(
                f"BackEndConfig.robust must be 'cauchy', 'huber' or 'none', got {self.robust!r}"
            )
        _positive(self, "robust_scale", "max_iterations")


@dataclass(frozen=True, slots=True)
class OccupancyConfig:
    """The occupancy grid (issue 12, part 4): ``resolution`` m per cell, log-odds added per
    hit and per pass, clamped to ``clamp``; beams longer than ``max_range`` are cut (and
    mark only free space); no-return beams (max range, invalid) are skipped unless
    ``free_on_no_return`` (then free up to ``max_range``: a window or an open door would
    paint free space beyond the walls); every ``scan_stride``-th scan is cast."""

    resolution: float = 0.05
    log_odds_hit: float = 0.85
    log_odds_miss: float = -0.4
    clamp: float = 5.0
    max_range: float = 30.0
    scan_stride: int = 1
    margin: float = 1.0
    free_on_no_return: bool = False

    def __post_init__(self) -> None:
        _positive(self, "resolution", "log_odds_hit", "clamp", "max_range", "scan_stride")


@dataclass(frozen=True, slots=True)
class MapConfig:
    """Everything :func:`scanclique.mapping.map_scans` uses."""

    match: MatchConfig = field(default_factory=MatchConfig)
    front_end: FrontEndConfig = field(default_factory=FrontEndConfig)
    loops: LoopConfig = field(default_factory=LoopConfig)
    back_end: BackEndConfig = field(default_factory=BackEndConfig)
    occupancy: OccupancyConfig = field(default_factory=OccupancyConfig)
