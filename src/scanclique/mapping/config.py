"""Configuration of :func:`scanclique.mapping.map_scans` (one frozen dataclass per stage).

Distances in metres, angles in radians. The defaults work out of the box on 2D laser logs
recorded indoors at walking speed (the SLAM benchmark logs of Kümmerle et al. 2009).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from ..config import MAX_ITERATIONS, MAX_SIGMA_METRES, MatchConfig
from ..config import check_at_most as _at_most
from ..config import check_below_inf as _below_inf
from ..config import check_choice as _choice
from ..config import check_nonneg as _nonneg
from ..config import check_positive as _positive
from ..config import check_probability as _probability
from ..config import check_radians as _radians
from ..config import check_types as _check_types
from ..errors import ConfigError
from ..validation import OdometryNoise

__all__ = [
    "FrontEndConfig",
    "LoopConfig",
    "BackEndConfig",
    "OccupancyConfig",
    "MapConfig",
    "MIN_RESOLUTION",
    "MAX_OCCUPANCY_RANGE",
    "MAX_SIGMA_FLOOR_RADIANS",
]

MAX_SIGMA_FLOOR_RADIANS = 2.0 * math.pi
"""Largest ``FrontEndConfig.sigma_floor_radians``: a heading sigma of a full turn says
nothing of the heading already (the metres' bound is
:data:`scanclique.config.MAX_SIGMA_METRES`)."""


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
        keyframe. Without odometry, so does a scan whose translation relative to the
        keyframe is unsure by more than ``keyframe_distance`` (1 sigma, largest axis: a
        corridor, look-alike poses), so that the back end and the loops can move it; and
        a step the motion model placed that unsurely passes its looseness on to the next
        prediction (:meth:`~scanclique.mapping.frontend.VelocityModel.carried`).
    odometry_noise : OdometryNoise
        Error model of the wheel odometry (the prior of the §7 gate, and the covariance of
        an odometry edge when a match fails): twice the validation's default, which covers
        99 % of *consecutive* increments, because keyframes lie several scans apart and
        sparse logs (CSAIL: 1 m and up to 78 degrees between scans) move much more per
        match.
    velocity_noise : OdometryNoise
        Without odometry: the error model of the constant-velocity prediction (the
        :class:`~scanclique.mapping.frontend.VelocityModel`'s, per second or per scan),
        whose sigmas scale the motion's :func:`~scanclique.mapping.frontend.surprise` and
        make the covariance of a step placed by the prediction (its heading sigma
        widened as below).
    sigma_floor_metres, sigma_floor_radians : float
        Standard deviations added to every match's feature covariance before it weighs an
        edge (the feature estimate alone is often optimistic); at most
        :data:`~scanclique.config.MAX_SIGMA_METRES` and :data:`MAX_SIGMA_FLOOR_RADIANS`
        (1e200 overflowed its square).
    refine, refine_iterations, refine_max_correspondence, refine_min_correspondence :
        Beyond the matcher: an accepted match (consecutive or closure) is refined by
        point-to-line ICP of *all* the new scan's points onto the other's full cloud
        (the matcher scores and refines on a sample of 120), correspondence distance
        shrinking from ``refine_max_correspondence`` to ``refine_min_correspondence`` m;
        kept when it stays within ``refine_max_shift`` m and ``refine_max_turn`` rad of the
        match and keeps at least ``refine_min_fitness`` of the points paired.
        ``refine_iterations`` at most :data:`~scanclique.config.MAX_ITERATIONS` (2**62 ran
        without end).
    icp_fallback, icp_min_score, icp_min_fitness, icp_gate :
        With odometry, when the feature match fails (rejected, ambiguous, too few
        features): ICP from the prior and from the rejected match's pose, accepted when the
        raw scans agree (score, fitness) and it lies within ``icp_gate`` sigma of the prior
        (:func:`scanclique.mapping.frontend.icp_fallback`); only then the prior itself.
        ``icp_min_score`` below inf (as ``RefineConfig.min_score``; -inf: no floor).
        Without odometry ``icp_fallback`` switches on the front end below (False: the
        matcher alone, the constant-velocity prediction breaking its ties).
        ``icp_min_constraint``: when the smallest eigenvalue of the mean outer product
        of the paired points' normals is below it (the scans let ICP slide along one
        direction, as in a corridor: 0 for two parallel walls, 0.5 for a room; see
        :func:`scanclique.refine.weak_direction`), the pose along that
        direction is the prior's, with the prior's variance. ``icp_score_tie``: ICP
        results (from the several seeds) whose raw-scan scores lie within it of the best
        are a tie the scans cannot break; the one nearest the first prior is taken.
        ``sharp_turn``: where the odometry turned at least this much (rad) between the
        keyframe and the scan, the two scans overlap too little for those bounds (a right
        pose scores 0.3-0.6 across a 70-110 degree turn of a 180-degree scanner); when no
        ICP pose meets them, ICP from the two motion priors is held to the bounds of the
        front end without odometry (``scan_min_fitness``, ``scan_min_score``), and its
        translation keeps the odometry's covariance (it fixes the heading, which the
        odometry misjudges most on a sharp turn). Twelve simulated office drives with
        odometry (150 scans 0.25 m apart, turns up to 65-137 degrees): worst position
        error 4.12 m -> 0.20 m; the shared logs unchanged (their consecutive keyframes
        never turn that much where the match fails); beyond pi (e.g. 4): off.

    Without odometry (the paper's setting;
    :func:`~scanclique.mapping.frontend.associate_by_scans`) the scans' own evidence places
    a scan, the constant-velocity prediction only weighs in where they leave a choice.
    Measured on the corrected Intel (910 scans, 1 m and up to 30 degrees between scans)
    and CSAIL (406, up to 78 degrees) logs, relation error mean, and on twelve simulated
    office drives (``office_world``, 150 scans 0.25 m apart, turns of up to 65-137 degrees
    between two scans before walls; the largest absolute error): before this front end
    Intel 7.48 m, CSAIL 3.31 m, 1 of 12 drives within 0.1 m (4-30 m on the others); with
    it, and the loops' use of its uncertainty (:class:`LoopConfig`), see the README's
    mapping section. Each default below against its neighbours, the others at their
    defaults (Intel / CSAIL m, drives within 0.1 m of 12, worst drive m; the defaults:
    0.0621 / 0.0777 m, 9 of 12, 0.39 m):

    jump_factor, jump_floor, jump_min_path :
        A scan lies at most ``jump_factor`` times the 90th percentile of the per-scan
        steps the scans measured so far, times the scans since the keyframe, plus
        ``jump_floor`` m from it (a robot turns as sharply as it likes, but does not
        jump: the look-alike placements of a rectangular room lie metres away); no bound
        before ``jump_min_path`` m were measured (the Intel robot turns in place for its
        first ten scans, then steps 1 m).
        No bound: 0.0621 / 0.0665 m, 5 of 12, 14.2 m (90-degree look-alikes of the
        drives' rooms, metres away, win); ``jump_factor`` 2: 8 of 12, 4.07 m;
        ``jump_floor`` 0.3: as the default. ``jump_min_path`` 0.5: Intel 1.22 m (its
        first 1 m step refused after the turns in place); 5: 8 of 12, 14.2 m.
    scan_min_score, scan_min_fitness, max_seeds, turn_seeds :
        When the validated feature match is missing, or turns where the prediction does
        not expect it: ICP of the raw scans from the first ``max_seeds`` distinct
        hypotheses of the match, the prediction, standing still and the prediction turned
        by every multiple of ``360 / turn_seeds`` degrees (a sharp turn may leave the
        matcher without a right hypothesis), kept when ICP paired ``scan_min_fitness`` of
        the points, and the hypotheses as they are; candidates scoring at least
        ``scan_min_score`` compete (a right pose scores 0.3-0.6 across a 70-110 degree
        turn of a 180-degree scanner, whose overlap is small); below inf, as
        ``icp_min_score``.
        No turned seeds (``turn_seeds`` 1): 0.0641 / 0.0772 m, 6 of 12, 29.0 m; 12:
        0.0616 / 0.0776 m, 9 of 12. ``scan_min_score`` 0.2: 0.0652 m (0.78 degrees) /
        0.0773 m; 0.4: CSAIL 2.50 m, 6 of 12, 25.6 m (sharp turns left to the
        prediction). ``scan_min_fitness`` 0.2, ``max_seeds`` 3: as the defaults.
    shift_cost, turn_cost :
        The competition's currency: a candidate's raw-scan score less ``shift_cost`` per
        standard deviation of translation and ``turn_cost`` per standard deviation of
        heading by which it departs from the prediction (``velocity_noise``): a robot's
        heading is much less predictable than its translation. Ties (within
        ``icp_score_tie``) at distinct headings are refused. With wheel odometry the
        same currency, against the odometry increment (``odometry_noise``), decides
        between a feature match and ICP from the odometry
        (:func:`~scanclique.mapping.frontend.contest_by_odometry`) and among the ICP
        fallback's poses: corrected Intel with odometry 0.1027 m -> 0.0377 m (a match
        slid along a corridor, an ICP pose near standstill), the raw logs unchanged.
        ``shift_cost`` 0.08: 0.0667 m, 9 of 12, 0.81 m; 0.16: 0.0621 m, 0.85 m.
        ``turn_cost`` 0.01: 0.0644 m (0.94 degrees: a 90-degree look-alike at one place
        wins); 0.025: 0.0634 / 0.0773 m.
    soft_constraint :
        Where the raw scans fix a step only loosely along one direction (the smallest
        eigenvalue of the paired normals' mean outer product below it: a corridor, 0 for
        two bare walls, 0.5 for a room), the step's covariance is as unsure along it as
        the step and the prediction disagree there (the raw-scan score of a corridor
        favours standing still; doors repeat), so that the loops can put it right.
        0 (never): 0.0650 / 0.134 m; 0.1: 0.0621 / 0.122 m; 0.3: 0.0636 / 0.0777 m. The
        disagreement, not the prediction's whole variance: with the latter the dense
        Intel log (13631 scans) without odometry fell from 0.0161 m to 0.0222 m (a wrong
        closure bent a softened corridor 2.8 m).
    guess_sigma_radians :
        Heading sigma of a step placed by the prediction (the scans could not place it):
        the 95th percentile of the prediction's heading errors measured so far, at most
        this, and this before ten were measured (a sharp turn the prediction missed: a
        CSAIL scan turned 65 degrees and 1.3 m from its predecessor, whose raw scans
        overlap too little, was 95 degrees off).
        30 and 90 degrees: as 60 here (the learnt 95th percentile decides); a fixed 60
        degrees bent a smooth simulated circle at its unplaced scans (a wrong closure
        with nothing to hold them).
    deskew :
        Take the motion's skew out of a scan whose beams carry their times
        (:attr:`~scanclique.scan.Scan.beam_times`: a rotating lidar read from a bag)
        before it is matched (:func:`~scanclique.scan.deskew`), at the velocity of its
        sweep: ``map_scans`` takes the odometry's to the next scan, or without odometry
        a first pass's (:func:`~scanclique.mapping.pipeline.sweep_velocities`, about 70 %
        more time); the online mapper the odometry's from the scan before, or the
        estimate's over ``deskew_window``. ``map_scans`` first checks how the driver gave
        the times (:func:`~scanclique.mapping.sweep.sweep_timing`: in the order of the
        ranges or against it, stamped at the sweep's start or end, or not to be trusted);
        the online mapper de-skews only from when the scans so far tell. Scans without
        beam times (CARMEN logs) are matched as they are whatever this says.
    fit_scanner :
        Fit the clustering to the log's scanner (:func:`~scanclique.features.for_scanner`;
        the online mapper decides on the first scan): one invalid beam between two
        returns the clustering rule joins read as a lost return, not open space, when the
        scanner loses returns inside surfaces (cheap 360-degree lidars), and the rule's
        range term widened to a range noise that grows with the range. Simulated RPLIDAR
        A1-class drives on a campus (seeds 0-2, ``benchmarks/mapping_sensors.py --world
        campus``): with odometry 0.234 -> 0.127 m, without 0.737 -> 0.170 m. The shared
        SICK logs are read as they are.
    odometry_fit, odometry_fit_min, odometry_fit_floor :
        With odometry, the ICP fallback gates and values its poses by the odometry as good
        as it has proved (:class:`~scanclique.mapping.frontend.OdometryFit`): the noise
        model's standard deviations scaled by the 95th percentiles of the odometry's
        residuals against the accepted feature matches (in the model's sigmas), once
        ``odometry_fit_min`` matches were measured (at least one), never below
        ``odometry_fit_floor`` times the model nor above it (a floor of 1: the model).
        ``odometry_noise`` is written for poor odometry; a robot whose wheels track well
        had its ICP steps turned by 6-9 degrees against odometry right to half a degree
        (a 3.5 m scanner outdoors, campus drives with odometry 6.24 -> 3.08 m of mean
        error; session 43). A scan the scans could not place at all is placed by the
        odometry as unsure as it has proved, unless its match was rejected for disagreeing
        with the odometry (a slip): 3.08 -> 1.23 m. The shared logs' odometry proves 0.2
        of the model in translation and 0.46-0.77 in heading: corrected Intel 0.0371 ->
        0.0368 m, CSAIL 0.0362 -> 0.0356 m, intel-raw 0.0147 -> 0.0146 m, fr079-raw 0.0313 ->
        0.0314 m (``benchmarks/mapping.py``).
    deskew_window :
        Seconds: without odometry, the velocity of the de-skew is the estimate's over
        the last scans spanning at least this before the scan (at most
        :data:`~scanclique.scan.MAX_SWEEP`). Over one step, a match's error comes back
        through the next scan's de-skew, and the steps alternate long and short (the
        simulated LDS-01 at 5 Hz: 0.06 m mean became 2-5 m).
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
    icp_min_constraint: float = 0.05
    icp_score_tie: float = 0.05
    sharp_turn: float = math.radians(45.0)
    jump_factor: float = 1.5
    jump_floor: float = 0.6
    jump_min_path: float = 2.0
    scan_min_score: float = 0.3
    scan_min_fitness: float = 0.3
    max_seeds: int = 6
    turn_seeds: int = 8
    shift_cost: float = 0.12
    turn_cost: float = 0.015
    soft_constraint: float = 0.2
    guess_sigma_radians: float = math.radians(60.0)
    deskew: bool = True
    deskew_window: float = 0.5
    fit_scanner: bool = True
    odometry_fit: bool = True
    odometry_fit_min: int = 20
    odometry_fit_floor: float = 0.1

    def __post_init__(self) -> None:
        _check_types(self)
        _positive(
            self, "keyframe_distance", "keyframe_angle", "sigma_floor_metres",
            "sigma_floor_radians", "jump_factor", "turn_seeds", "guess_sigma_radians",
            "sharp_turn", "refine_iterations", "refine_max_correspondence",
            "refine_min_correspondence", "icp_gate", "deskew_window",
        )  # fmt: skip
        _nonneg(
            self, "jump_floor", "jump_min_path", "scan_min_fitness", "max_seeds", "shift_cost",
            "turn_cost", "soft_constraint", "refine_max_shift", "refine_max_turn",
            "refine_min_fitness", "icp_min_fitness", "icp_min_constraint", "icp_score_tie",
            "odometry_fit_min",
        )  # fmt: skip
        _positive(self, "odometry_fit_floor")
        _radians(self, "keyframe_angle", "refine_max_turn")  # (sharp_turn beyond pi: off)
        _at_most(self, MAX_SIGMA_METRES, "sigma_floor_metres")
        _at_most(self, MAX_SIGMA_FLOOR_RADIANS, "sigma_floor_radians")
        _at_most(self, MAX_ITERATIONS, "refine_iterations")
        _below_inf(self, "icp_min_score", "scan_min_score")


@dataclass(frozen=True, slots=True)
class LoopConfig:
    """Loop-closure candidates and their verification (issue 12, part 2).

    A keyframe ``j`` is tried against earlier keyframes ``i`` whose estimated position
    lies within ``radius + growth * D`` of its own, where ``D`` is the path travelled
    since the last accepted closure or since ``i``, whichever is shorter (the drift the
    estimate may have accumulated), capped at ``max_radius``; and, where the front end's
    chain puts ``j`` more than ``radius`` from where the estimate puts it relative to
    ``i`` but within that drift radius, and no closure on the way has corrected the
    estimate there, within as much of the chain's position, verified as strictly as
    appearance candidates (local matches can pull the estimate off a right chain).

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
        Pairwise consistency maximisation runs over the closures of this many keyframes,
        and the estimate (iSAM2) takes the accepted ones then. The online mapper's
        default is 5 (:meth:`MapConfig.online`).
    pcm_gate : float
        Probability of the chi-square gate (3 dof) of pairwise consistency.
    pcm_anchor_batches : int
        Incremental PCM: the closures accepted over the last ``pcm_anchor_batches``
        batches (their newer keyframe that recent) anchor the new ones; a new closure
        must be pairwise consistent with each of them (0: each batch on its own).
    corroborate_batches : int
        The candidates' radius and their verification's prior widen to the front end's
        own uncertainty (its edges' covariances summed along the chain) where it exceeds
        the path's drift model above, with odometry or without: after a step placed by the
        prediction or the odometry, along a corridor, or over matches of few features, the
        estimate may be metres off (the heading
        widened to 40 degrees at most: a corridor seen the other way is a look-alike),
        and so does PCM's chain. An appearance closure that
        moves the estimate beyond the drift model's 99 % gate must then be corroborated
        by another one from an earlier place at least ``separation`` keyframes away, in
        the same PCM set, within ``corroborate_batches`` batches; else its verdict is
        ``"uncorroborated"`` (0: no such rule). Measured (Intel / CSAIL without odometry):
        0: 0.121 m (1.9 degrees: a 90-degree look-alike 7 m away corrects a step placed
        by the prediction) / 0.0777 m; 1: 0.0621 / 0.0787 m; 3 and 6: 0.0621 / 0.0777
        m. So must a closure by the estimate that moves it by more than ``max_radius``
        too (session 35: after a loop of hundreds of metres the front end's own
        uncertainty reaches a parallel corridor; every shared map the same).
    min_score : float
        A loop closure's match needs at least this raw-scan agreement
        (:func:`scanclique.match.pose_score`; the matcher's own floor is 0.1): a revisit
        seen from afar, or a look-alike place, often maps a few features at a pose the
        scans hardly support. Below inf (as ``RefineConfig.min_score``; -inf: no floor).
    appearance : bool
        Also propose candidates by appearance (``scanclique.places.signature``) when that
        module exists.
    max_turn : float
        A loop closure that turns the current estimate by more than this (rad) is refused
        (verdict ``"turned"``) unless the front end's own heading uncertainty between the
        two keyframes (its edges' variances summed, :meth:`front_std`) allows it at 3
        sigma. Rectilinear buildings repeat their corners and crossings a quarter or half
        turn round, and over a long loop the drift model's prior (up to 30 degrees) lets
        such a look-alike through: a simulated 60 x 40 m ring corridor driven twice with
        odometry (:func:`scanclique.sim.simulate_ring_drive`) mapped to 38-50 m of mean
        error on three seeds of four after closures 90 degrees off (0.04-0.18 m with the
        rule; chained matching alone 0.52 m). The right closures of the shared logs turn
        the estimate by at most 14 degrees (Intel), 3.7 (Freiburg 079).
    max_shift : float
        A loop closure that moves the current estimate by more than the drift model's
        candidate radius (``radius + growth * L``, capped) and by more than ``max_shift``
        times ``L``, the chain's path (m) between the two keyframes, is refused (verdict
        ``"shifted"``) unless the front end's own uncertainty between them allows it at 3
        sigma: a silent error of the front end is not taken to exceed that share of the
        path it was made over. Appearance candidates are verified by twice the drift
        model, and without odometry a look-alike place a door or two along a corridor
        passed that after 3-6 m of path (the ring corridor, seed 1: 2.8 m over 3 m of
        path while the local matches fixed that stretch to 3 cm; 3.56 -> 0.133 m of mean
        error). The right closures of the shared logs that move the estimate beyond the
        drift radius and the front end's 3 sigma do so by at most 0.105 times their path
        (corrected Intel with every second beam, 7.7 m over 73 m); the rule refuses only
        wrong ones there (CSAIL without odometry one 2.4 m off, corrected Intel with
        every second beam two, 4.3 and 22 m off). ``inf``: the rule off.
    max_conflict : float
        A loop closure that moves the current estimate beyond the front end's 3 sigma and
        the drift model's 99 % gate (not so far as to be refused as ``"shifted"``) is
        refused (verdict ``"conflicting"``) when the two keyframes' raw scans under it see through
        more than this fraction of each other's points
        (:func:`scanclique.match.conflict_fraction`): a twin room in a building of alike
        rooms lines its walls up with the other's, but its furniture stands where the
        other saw free floor. A simulated office drive of 600 poses (RPLIDAR class) took
        a room 3.6 m from the first for it after 23 m of path, its scans conflicting on
        8-17 %: 0.793 -> 0.013 m of mean error with odometry, 0.797 -> 0.013 m without.
        The right closures that move the estimate that far conflict on at most 0.6 %
        (simulated drives and the shared logs); the closures refused were all wrong
        (1.9-4.4 m in the simulator; 3.0-15.8 m on the real logs and their variants,
        where they had been outvoted: every shared map the same). ``1`` (all the
        points): the rule off.
    reach_edges : bool
        Verify loop closures (not the local matches between neighbouring keyframes) on
        features that include foreground edges where a wall only leaves the sensor's reach
        (``FeatureConfig.reach_edges``). Such an end moves with the robot along any wall at
        the same distance: between scans a step apart it supports a match, between places
        far apart in time it matches a wall of another place (as in place recognition,
        :func:`scanclique.features.leaves_reach`). ``map_scans`` and the online mapper
        turn it off for a log whose scanner meets its reach (``FrontEndConfig.fit_scanner``,
        :func:`scanclique.features.meets_reach`): the keyframes are then prepared a second
        time, without those edges, for the loops. Simulated 600-pose office drives of a
        3.5 m scanner (LDS-01 class), drives 0-3: 0.362 / 0.547 -> 0.360 / 0.533 m of
        mean error with / without odometry; 300-pose campus drives of a 10 m one, drives
        0-8: 0.233 / 0.225 -> 0.221 / 0.223 m (the local matches too without them: the
        600-pose drives 0.345 / 0.488 m, but 60-pose office drives 0.030 -> 0.037 m with
        odometry). A scanner that never meets its reach (the shared SICK logs) is the same
        either way.
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
    corroborate_batches: int = 3
    min_score: float = 0.3
    appearance: bool = True
    max_turn: float = math.radians(45.0)
    max_shift: float = 0.25
    max_conflict: float = 0.05
    reach_edges: bool = True
    max_sigma_metres: float = 0.20 / 3.255
    max_sigma_radians: float = math.radians(1.0) / 2.807

    def __post_init__(self) -> None:
        _check_types(self)
        _positive(
            self, "radius", "max_radius", "min_path", "pcm_batch", "every", "max_sigma_metres",
            "max_sigma_radians", "max_turn",
        )  # fmt: skip
        _nonneg(
            self, "corroborate_batches", "growth", "heading_growth", "local", "per_keyframe",
            "separation", "pcm_anchor_batches", "max_conflict",
        )  # fmt: skip
        _positive(self, "max_shift", infinite=True)  # inf: the rule off
        _probability(self, "pcm_gate")
        _radians(self, "max_turn")  # pi: the rule off
        _below_inf(self, "min_score")


@dataclass(frozen=True, slots=True)
class BackEndConfig:
    """SE(2) pose-graph optimisation with GTSAM (issue 12, part 3).

    ``robust``: the M-estimator on loop-closure edges (``"cauchy"``, ``"huber"``,
    ``"none"``) with scale ``robust_scale`` (in units of the edge's sigma), the second line
    of defence after PCM; without odometry, a closure across a stretch where the front end
    was less sure than the loops' drift model gets a scale that large
    (:meth:`scanclique.mapping.pipeline._Mapper.robust_scale`). ``max_iterations`` of
    Levenberg–Marquardt, at most :data:`~scanclique.config.MAX_ITERATIONS` (GTSAM counts
    them in 32 bits: 2**40 was a TypeError mid-run). ``covariances``: also give every
    scan's pose covariance, from the marginals of the optimised keyframe graph
    (:attr:`MapResult.covariances <scanclique.mapping.MapResult.covariances>`; off by
    default, it costs a factorisation and a marginal per keyframe).

    ``odometry_factors``: with odometry whose heading residuals against the accepted
    matches are at most ``odometry_max_fit`` of its noise model's
    (:attr:`MapResult.odometry_fit <scanclique.mapping.MapResult.odometry_fit>`, 95th
    percentiles), the batch back end also takes the odometry between consecutive
    keyframes as edges (kind ``"odometry_factor"``), with the steady heading drift the
    matches show taken out (:attr:`MapResult.odometry_drift
    <scanclique.mapping.MapResult.odometry_drift>`: a graph's edges are independent, so
    a drift within their noise on every edge bends a long corridor; the 200 x 120 m ring
    with 0.003 rad/m, seeds 0-3, 0.801 -> 0.484 m of mean error, session 44) and the
    model's covariance over the path scaled to the residuals left, judged so corrected
    against ``odometry_max_fit``. None when the matches steadily step further than the
    odometry (``OdometryFit.steps_off``: wheels measuring short, which the edges would
    carry into every corridor; the ring with 2 % short steps 0.845 -> 0.671 m),
    none for a chained-only map (``loops.enabled`` False), none across a scan whose
    match was rejected for disagreeing with the odometry (a slip) or was matched against
    it reversed. The shared logs' odometry proves 0.27-0.77 once corrected (intel-raw
    0.27, corrected Intel 0.31, fr079-raw 0.48, CSAIL 0.77) and takes none (their maps
    unchanged); odometry that tracks well is more exact per step than a short-reach
    scanner's matches: the simulated LDS-01 on the campus with odometry 1.23 -> 0.85 m,
    in offices (600 poses) 0.360 -> 0.344 m (session 43). Forced on the shared logs (a
    first form, without the slip rule), fr079-raw went 0.0314 -> 0.0319 m, CSAIL 0.0356
    -> 0.0345 m, intel-raw 0.0146 -> 0.0145 m. The online mapper's iSAM2 estimates do
    not take them;
    its finished map (the batch back end) does."""

    robust: str = "cauchy"
    robust_scale: float = 1.0
    max_iterations: int = 100
    covariances: bool = False
    odometry_factors: bool = True
    odometry_max_fit: float = 0.25

    def __post_init__(self) -> None:
        _check_types(self)
        _choice(self, "robust", ("cauchy", "huber", "none"))
        _positive(self, "robust_scale", "max_iterations", "odometry_max_fit")
        _at_most(self, MAX_ITERATIONS, "max_iterations")


MIN_RESOLUTION = 1e-4
"""Finest occupancy grid cell (m): a tenth of a millimetre, far below any laser's noise."""
MAX_OCCUPANCY_RANGE = 1e6
"""Longest beam cast into an occupancy grid (m)."""


@dataclass(frozen=True, slots=True)
class OccupancyConfig:
    """The occupancy grid (issue 12, part 4): ``resolution`` m per cell, log-odds added per
    hit and per pass, clamped to ``clamp``; beams longer than ``max_range`` are cut (and
    mark only free space); no-return beams (at or beyond the scan's ``range_max``, +inf
    included) are skipped unless ``free_on_no_return`` (then free up to ``max_range``: a
    window or an open door would paint free space beyond the walls); other invalid beams
    (NaN, -inf, at or below ``range_min``: too close, or an error) always are; every
    ``scan_stride``-th scan is cast. ``log_odds_miss`` is at most 0 (0: passes leave a
    cell alone) and at least -100, ``log_odds_hit`` and ``clamp`` at most 100 (float32
    cells), ``margin`` (m of unknown around the map) at least 0, ``resolution`` at
    least :data:`MIN_RESOLUTION` and ``max_range`` at most :data:`MAX_OCCUPANCY_RANGE`
    (cell indices stay exact integers; ``max_range=1e300`` with ``free_on_no_return``
    made the ray caster walk without end)."""

    resolution: float = 0.05
    log_odds_hit: float = 0.85
    log_odds_miss: float = -0.4
    clamp: float = 5.0
    max_range: float = 30.0
    scan_stride: int = 1
    margin: float = 1.0
    free_on_no_return: bool = False

    def __post_init__(self) -> None:
        _check_types(self)
        _positive(self, "resolution", "log_odds_hit", "clamp", "max_range", "scan_stride")
        _nonneg(self, "margin")
        # a log-odds of 100 is a probability within e^-100 of 1; 1e300 overflowed the
        # float32 cells
        _at_most(self, 100.0, "log_odds_hit", "clamp")
        if self.resolution < MIN_RESOLUTION:
            raise ConfigError(
                f"OccupancyConfig.resolution must be at least {MIN_RESOLUTION:g} m, "
                f"got {self.resolution!r}"
            )
        if self.max_range > MAX_OCCUPANCY_RANGE:
            raise ConfigError(
                f"OccupancyConfig.max_range must be at most {MAX_OCCUPANCY_RANGE:g} m, "
                f"got {self.max_range!r}"
            )
        if not (-100.0 <= self.log_odds_miss <= 0):
            raise ConfigError(
                "OccupancyConfig.log_odds_miss must be a number in [-100, 0] (a pass makes a "
                f"cell less likely occupied), got {self.log_odds_miss!r}"
            )


@dataclass(frozen=True, slots=True)
class MapConfig:
    """Everything :func:`scanclique.mapping.map_scans` uses."""

    match: MatchConfig = field(default_factory=MatchConfig)
    front_end: FrontEndConfig = field(default_factory=FrontEndConfig)
    loops: LoopConfig = field(default_factory=LoopConfig)
    back_end: BackEndConfig = field(default_factory=BackEndConfig)
    occupancy: OccupancyConfig = field(default_factory=OccupancyConfig)

    @classmethod
    def online(cls) -> MapConfig:
        """The defaults of the online mapper (:class:`~scanclique.mapping.OnlineMapper`,
        :func:`~scanclique.mapping.map_online`, ``scanclique map --online``): closures are
        decided every 5 keyframes instead of 10 (``loops.pcm_batch``; the anchors' and
        the corroboration's reach kept at 20 and 30 keyframes), so a robot's answers take
        a revisit's closures sooner. Measured (``benchmarks/mapping_online.py``, session
        22): the poses known when a scan comes are off by 0.0481 against 0.0545 m over
        relations longer than 10 s on fr079-raw and 0.0256 against 0.0356 m on
        intel-raw (with odometry). The finished map is within 0.2 mm of the batch
        defaults' on every log of the mapping benchmark, but not better on every one
        (intel-raw 0.0148 against 0.0147 m, and a millimetre worse with 3 cm of added
        range noise), so :func:`~scanclique.mapping.map_scans` keeps 10.

        >>> MapConfig.online().loops.pcm_batch, MapConfig().loops.pcm_batch
        (5, 10)
        """
        batch, n = LoopConfig(), 5
        reach = batch.pcm_batch // n  # batches of n per batch of the defaults
        loops = LoopConfig(
            pcm_batch=n,
            pcm_anchor_batches=batch.pcm_anchor_batches * reach,
            corroborate_batches=batch.corroborate_batches * reach,
        )
        return cls(loops=loops)

    def __post_init__(self) -> None:
        _check_types(self)  # each section a record of its class
