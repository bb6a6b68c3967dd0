"""Mapping a whole log: :func:`map_scans` and its result record :class:`MapResult`.

The recipe (issue 12; the paper's first application, §2):

1. prepare each scan once (features §4, feature graph §5.1, raw-point cloud);
2. front end: match it against the current keyframe, validate against odometry or a
   constant-velocity prior (§7); else place it by the prior, flagged
   (:mod:`.frontend`);
3. on each new keyframe: match it against ``local`` recent keyframes (ties the local chain)
   and verify loop candidates by estimate and appearance (:mod:`.loops`);
4. every ``pcm_batch`` keyframes: keep the largest pairwise-consistent set of the new
   closures (PCM, a maximum clique; :mod:`.pcm`), add the edges to the incremental
   optimiser (iSAM2) and update the estimate the next candidates are searched with;
5. at the end: Levenberg–Marquardt over the keyframe graph with a robust kernel on the
   closures (:mod:`.backend`); every other scan follows its keyframe by its one edge.
"""

from __future__ import annotations

import logging
import math
import os
import time
from collections import Counter
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass, field, replace
from typing import NamedTuple

import numpy as np

from .._lazy import kernel_module
from .._records import readonly
from .._workers import check_workers
from ..config import MatchConfig, require_callable, require_config, require_flag
from ..errors import ArgumentError, ScanError, solving
from ..features import for_scanner, meets_reach
from ..geometry import Pose2, rotation_matrix
from ..match import conflict_fraction, prepare_scan, prepared_again
from ..scan import Scan, deskew, measured_before, retime, sweep_velocity, sweep_velocity_of
from ..uncertainty import constellation_std, travel
from ..validation import (
    GATE_99,
    compose_covariance,
    mahalanobis_sq,
    odometry_prior,
)
from . import loops as _loops
from .backend import (
    ODOMETRY_HINT,
    PoseGraph,
    _gtsam,
    levenberg_marquardt,
    tangent_covariance,
    tangent_covariances,
)
from .config import MapConfig
from .frontend import (
    CONSTANT_VELOCITY,
    ICP,
    MATCH,
    ODOMETRY,
    OdometryFit,
    Step,
    VelocityModel,
    associate,
    associate_by_scans,
    constant_velocity,
    contest_by_odometry,
    icp_fallback,
    odometry_sees_reversing,
    prior_step,
    reversed_increment,
    sample_odometry_scale,
    step_scale,
)
from .loops import LoopClosure, closure_doubt
from .parallel import Verifier
from .pcm import pcm_select

_K = kernel_module("scanclique.mapping._kernels")

__all__ = ["Edge", "MapResult", "OdometryCheck", "map_scans"]

log = logging.getLogger(__name__)

Progress = Callable[[int, int, int], None]


def _ro(a) -> np.ndarray:
    return readonly(a, dtype=float, copy=True)


@dataclass(frozen=True, slots=True, eq=False)
class Edge:
    """One edge of the pose graph: ``x_i^-1 x_j = pose`` (maps points of scan ``j`` into
    scan ``i``) with the covariance of its ``(x, y, theta)``; ``kind`` is ``"match"``,
    ``"odometry"``, ``"constant_velocity"`` (front end), ``"local"``, ``"loop"`` or
    ``"odometry_factor"`` (the batch back end's odometry between keyframes,
    :attr:`BackEndConfig.odometry_factors
    <scanclique.mapping.config.BackEndConfig.odometry_factors>`)."""

    i: int
    j: int
    pose: Pose2
    covariance: np.ndarray
    kind: str

    def __post_init__(self) -> None:
        object.__setattr__(self, "covariance", _ro(self.covariance))


class OdometryScale(NamedTuple):
    """How far a log's odometry moves against its scans
    (:func:`~scanclique.mapping.frontend.step_scale`).

    ``median_scale`` is the median ratio of the odometry's step length to the matched
    one, over ``steps`` consecutive pairs of matched scans whose match moved (NaN and 0
    when none did): about 1 for right odometry (the shared logs 0.92-1.06), 0 for one
    that does not move (all zeros, or frozen), 1000 for millimetres.
    """

    median_scale: float
    steps: int

    @property
    def scaled(self) -> bool:
        """True when the odometry's steps are shorter than half or longer than twice the
        scans' (:data:`ODOMETRY_SCALE_RANGE`), over at least :data:`ODOMETRY_CHECK_STEPS`
        steps: :func:`map_scans` sets such odometry aside before it maps, or warns after."""
        lo, hi = ODOMETRY_SCALE_RANGE
        return self.steps >= ODOMETRY_CHECK_STEPS and not lo <= self.median_scale <= hi


class OdometryCheck(NamedTuple):
    """How far a map's odometry points from its scans (:func:`odometry_turned`).

    ``median_turn_deg`` is the median angle (degrees, counter-clockwise) from each
    odometry step's translation to the matched one, over ``steps`` consecutive pairs of
    matched scans that both moved; 0 and 0 when none did. A laser mounted turned by
    ``phi`` on a robot whose odometry is given as the laser's reads about ``-phi``.
    """

    median_turn_deg: float
    steps: int

    @property
    def turned(self) -> bool:
        """True when the odometry points more than :data:`ODOMETRY_CHECK_DEGREES` away,
        over at least :data:`ODOMETRY_CHECK_STEPS` steps: the mapper warns."""
        return self.steps >= ODOMETRY_CHECK_STEPS and abs(self.median_turn_deg) > (
            ODOMETRY_CHECK_DEGREES
        )


@dataclass(frozen=True, slots=True, eq=False)
class MapResult:
    """The map of a log.

    Attributes
    ----------
    poses : tuple of Pose2 or None
        One per input scan: the pose of its sensor frame in the frame of scan 0 (maps
        points of the scan into the map). None only for a scan that could not be placed
        (see ``reasons``).
    placed_by : tuple of str
        Per scan: ``"match"`` (matched to its keyframe and validated), ``"icp"`` (the
        match failed; ICP from the prior agreed with the raw scans), ``"odometry"`` or
        ``"constant_velocity"`` (the match failed: placed by the prior, flagged), or
        ``"first"`` for scan 0.
    reasons : dict int -> str
        For every scan not placed by a match: why.
    keyframes : tuple of int
        Scan indices of the keyframes (the nodes of the optimised graph).
    edges : tuple of Edge
        Every edge of the pose graph (front end, local and accepted loop edges).
    loop_closures : tuple of LoopClosure
        Every verified loop candidate with its verdict (accepted or not).
    chained : tuple of Pose2
        The front end's poses alone (chained matches, before any closure).
    used_odometry : bool
    seconds : dict
        Wall time per stage (``prepare``, ``front_end``, ``loops``, ``pcm``, ``isam``,
        ``optimize``, ``covariances`` when asked, ``sweeps`` for the scans' beam times
        when they have any (their timing checked, and without odometry a first pass for
        the sweeps' velocities, :func:`sweep_velocities`), ``total``).
    config : MapConfig
    covariances : tuple of (3, 3) ndarray, or None
        When asked (:attr:`BackEndConfig.covariances
        <scanclique.mapping.config.BackEndConfig.covariances>`), one per scan: the
        covariance of its pose's ``(x, y, theta)`` (m, rad; map-frame axes) relative to
        scan 0, whose own is about zero (the anchor's prior, sigma 1e-6 m). A keyframe's
        is its marginal in the optimised graph; a scan between keyframes adds its match
        to its keyframe, to first order
        (:func:`~scanclique.uncertainty.compose_covariance`, taking the two as
        independent). None when not asked.
    odometry_check : OdometryCheck or None
        When the map used odometry: how far its steps point from the matched ones (the
        mapper warns when :attr:`OdometryCheck.turned`); None otherwise.
    odometry_scale : OdometryScale or None
        When the map used odometry: how far its steps move against the matched ones (the
        mapper warns when :attr:`OdometryScale.scaled`); when :func:`map_scans` set the
        scans' odometry aside before mapping (``used_odometry`` False), the sample that
        made it do so; None otherwise.
    deskewed : int
        Scans matched with their sweep's skew taken out (``FrontEndConfig.deskew``: scans
        with beam times whose velocity was known); 0 for a log without beam times.
    sweep_timing : str
        How the beam times were read (:data:`scanclique.scan.TIMINGS`, as
        :func:`~scanclique.mapping.sweep.sweep_timing` found the log to agree best; not
        ``"given"`` is warned); ``""`` when no scan has beam times or ``deskew`` is off.
    odometry_fit : (float, float) or None
        When the map used odometry: the factors of the odometry noise model's standard
        deviations (translation, heading) the odometry proved against the accepted
        feature matches (:class:`~scanclique.mapping.frontend.OdometryFit`; the ICP
        fallback's gate when ``FrontEndConfig.odometry_fit``); None otherwise or before
        ``odometry_fit_min`` matches.
    odometry_drift : (float, float) or None
        When the map used odometry: its steady heading error the accepted feature
        matches show (:meth:`~scanclique.mapping.frontend.OdometryFit.drift`), per metre
        travelled (rad/m) and per radian turned (rad/rad), signed so that the scans turn
        by the odometry's turn plus it; a term the matches do not show is 0. Taken out of
        the batch back end's odometry edges (``BackEndConfig.odometry_factors``). None
        otherwise or before ``odometry_fit_min`` matches.
    odometry_steps : float or None
        When the map used odometry: its distance's steady relative error the accepted
        feature matches, each weighed by its own sigma along the step, show
        (:meth:`~scanclique.mapping.frontend.OdometryFit.scale`; the scans' steps are the
        odometry's times ``1 +`` it; 0 when not shown), as read at the end of the log.
        Taken out, as read at each scan, of the odometry the front end contests its
        matches with and seeds the ICP fallback by, and of the batch back end's odometry
        edges. None otherwise.
    """

    poses: tuple
    placed_by: tuple
    reasons: dict
    keyframes: tuple
    edges: tuple
    loop_closures: tuple
    chained: tuple
    used_odometry: bool
    seconds: dict
    config: MapConfig = field(repr=False, default_factory=MapConfig)
    covariances: tuple | None = field(repr=False, default=None)
    odometry_check: OdometryCheck | None = field(repr=False, default=None)
    odometry_scale: OdometryScale | None = field(repr=False, default=None)
    deskewed: int = 0
    sweep_timing: str = ""
    odometry_fit: tuple | None = None
    odometry_drift: tuple | None = None
    odometry_steps: float | None = None

    @property
    def accepted_closures(self) -> tuple:
        """The accepted loop closures (not local matches)."""
        return tuple(c for c in self.loop_closures if c.accepted and not c.local)

    def counts(self) -> dict:
        """Counts for reports: scans, keyframes, how scans were placed, closures."""
        kinds = {k: 0 for k in ("first", MATCH, ICP, ODOMETRY, CONSTANT_VELOCITY)}
        for k in self.placed_by:
            kinds[k] = kinds.get(k, 0) + 1
        loops = [c for c in self.loop_closures if not c.local]
        return {
            "scans": len(self.poses),
            "keyframes": len(self.keyframes),
            "placed_by": kinds,
            "loop_candidates": len(loops),
            "loop_closures_accepted": sum(c.accepted for c in loops),
            "loop_verdicts": _tally(c.verdict for c in loops),
            "local_matches": sum(1 for c in self.loop_closures if c.local),
            "local_accepted": sum(1 for c in self.loop_closures if c.local and c.accepted),
            "edges": len(self.edges),
            "deskewed": self.deskewed,
            "sweep_timing": self.sweep_timing,
            "odometry_fit": None if self.odometry_fit is None else list(self.odometry_fit),
            "odometry_drift": None if self.odometry_drift is None else list(self.odometry_drift),
            "odometry_steps": self.odometry_steps,
        }


def _chain_sigma_xy(var_xy, var_theta, path):
    """Translation sigma (m) of a stretch of the front end's chain from its summed
    translation and heading variances and its path length (m), scalars or arrays: a
    heading error acts on a third of the path's square as its lever arm."""
    return np.sqrt(np.maximum(var_xy + var_theta * path * path / 3.0, 0.0))


class _Rows:
    """A growing array of rows (``width`` values each, or scalars when None): amortised
    O(1) appends, the capacity doubling; :attr:`array` is the rows so far (a view). For
    the keyframes' values that every loop search reads whole, which a list would have
    to convert to an array each time (quadratic over a log: 2.3 s of fr079's 46 s)."""

    def __init__(self, width: int | None = None, dtype=float, capacity: int = 1024) -> None:
        self.n = 0
        self._a = np.zeros((capacity,) if width is None else (capacity, width), dtype)

    def append(self, row) -> None:
        if self.n == len(self._a):
            self._a = np.concatenate([self._a, np.zeros_like(self._a)])
        self._a[self.n] = row
        self.n += 1

    def __len__(self) -> int:
        return self.n

    @property
    def array(self) -> np.ndarray:
        return self._a[: self.n]

    def __getitem__(self, k):
        return self.array[k]


class _GraphEdges:
    """The keyframe graph's edges as growing arrays: both ends, the translation variance
    (largest eigenvalue of the covariance's x-y block, m²), the heading variance (rad²)
    and the translation's length (m) of each; ``m`` edges."""

    def __init__(self) -> None:
        self.a, self.b = _Rows(dtype=np.int64), _Rows(dtype=np.int64)
        self.var_xy, self.var_theta, self.length = _Rows(), _Rows(), _Rows()

    @property
    def m(self) -> int:
        return len(self.a)

    def add(self, a: int, b: int, Z: Pose2, P: np.ndarray) -> None:
        """Edge ``a - b`` of relative pose ``Z`` and covariance ``P`` (3, 3)."""
        self.a.append(a)
        self.b.append(b)
        self.var_xy.append(max(float(np.linalg.eigvalsh(P[:2, :2])[-1]), 0.0))
        self.var_theta.append(max(float(P[2, 2]), 0.0))
        self.length.append(math.hypot(Z.x, Z.y))


def _tally(items) -> dict:
    out: dict[str, int] = {}
    for x in items:
        out[x] = out.get(x, 0) + 1
    return out


#: what a pose graph GTSAM cannot solve asks of a user mapping from the scans alone
SCANS_HINT = (
    "Mapped from the scans alone: steps the front end could not match are placed by its "
    "prediction with a loose covariance (MapResult.placed_by says which); with odometry "
    "(use_odometry=True) they have a better prior."
)

#: a scan's placed step backwards (m) beyond which the robot counts as backing up, for
#: odometry that never reports it (:func:`~scanclique.mapping.frontend.odometry_sees_reversing`)
REVERSING_STEP = 0.01


def _cov_xy_rot(s_xy: float, s_th: float) -> np.ndarray:
    return np.diag([s_xy**2, s_xy**2, s_th**2])


class _Mapper:
    """The state carried across scans (keyframes, estimate, graph) by :func:`map_scans` and
    by :class:`~scanclique.mapping.online.OnlineMapper`, which feed it one scan at a time."""

    def __init__(
        self, use_odometry: bool, blind_to_reversing: bool, cfg: MapConfig, workers: int = 1
    ):
        self.scans: list[Scan] = []  # the scans so far, in recording order (add_scan)
        self.odo = use_odometry
        # odometry that never reports backing up (the speed's magnitude only): a reversing
        # robot is logged as driving forwards, so while the scans say it is backing up, a
        # match the odometry rejects is also validated against the odometry driven
        # backwards (frontend.odometry_sees_reversing; map_scans tells it from the whole
        # log, the online mapper as it goes)
        self.blind_to_reversing = bool(use_odometry) and blind_to_reversing
        self.cfg = cfg
        self.fe = cfg.front_end
        self.lc = cfg.loops
        self.floor = (self.fe.sigma_floor_metres, self.fe.sigma_floor_radians)
        # per scan, appended as each comes (add_scan)
        self.chain: list[Pose2 | None] = []  # front-end poses (dead reckoning)
        self.odo_fit = OdometryFit(self.fe)  # with odometry: how good it has proved
        # scans whose match the odometry rejected (a slip) or that were matched against it
        # reversed: the batch back end takes no odometry edge across them
        self.odometry_doubted: set[int] = set()
        self.odo_edges: list = []  # the batch back end's odometry edges (optimize)
        self.motion = VelocityModel(self.fe)  # without odometry: the learnt motion model
        self.placed_by: list[str] = []
        self.reasons: dict[int, str] = {}
        self.edges: list[Edge] = []
        self.closures: list[LoopClosure] = []
        # keyframes: scan index, prepared scan, cumulative path (chain), estimate
        self.kf: list[int] = []
        self.kf_prep: list = []
        self.kf_path = _Rows()
        self.kf_chain = _Rows(3)  # the keyframes' chain poses (x, y m, theta rad)
        self.kf_sig: _Rows | None = None  # (keyframes, signature size) when signatures exist
        self.kf_of: list[int] = []  # the keyframe each scan's edge hangs from
        self.rel_to_kf: list[Pose2] = []
        # the chain poses of the two scans before the next, for the motion's prediction
        self.world_prev2: Pose2 | None = None
        self.world_prev = Pose2.identity()
        # the newest scan when it is not a keyframe: (prepared, pose and covariance
        # relative to its keyframe), for close_log to make it one
        self.newest: tuple | None = None
        self.ahead: Sequence[Scan] | None = None  # the whole log, when given at once (run)
        # without odometry, each scan's sweep velocity from a first pass (map_scans)
        self.velocities: list | None = None
        self.deskewed = 0  # scans prepared de-skewed
        # how the beam times are read (scan.TIMINGS); None: not yet known (online, where
        # the scans are not de-skewed until decide_timing has seen enough turning ones)
        self.timing: str | None = None
        self.swept = False  # some scan had beam times to read
        self.est_xy = np.zeros((0, 3))  # current estimate of keyframes (x, y, theta)
        self.kf_edges: list[tuple[int, int, Pose2, np.ndarray, str]] = []  # keyframe graph
        self.pending: list[tuple[int, int, Pose2, np.ndarray, str, float, str]] = []
        self.last_closure_path = -math.inf
        self.loop_scale: dict[tuple[int, int], float] = {}  # robust kernel scale per closure
        self.deferred: list = []  # (pending closure, batches waited) awaiting corroboration
        # summed variances of the keyframe chain's edges (largest of x-y, theta), so that the
        # loops know where the front end was unsure (an ICP step along a corridor, a step
        # placed by the prediction or the odometry, matches of few features), with odometry
        # as without it. Odometry runs used to leave them at 0 (da018b4: then seeds 2 and 3
        # of 12 simulated drives went wrong through look-alikes; no longer, measured at
        # 55fd58a+: the 12 drives identical); with them at 0 the drift model alone bounds
        # the gates, and a front end that drifts faster (Intel with every second beam)
        # loses its closures for good: 2.615 -> 0.0255 m (131 -> 762 closures); Intel as
        # recorded 0.0149 -> 0.0147 m (1565 -> 1814, self precision 99.4 -> 99.8 %),
        # fr079 0.0312 -> 0.0313 m, corrected Intel 0.0377 -> 0.0371 m, CSAIL 0.0364 ->
        # 0.0362 m
        self.kf_var = _Rows(2)
        # the keyframe graph as it grows (chain steps, local matches, accepted closures),
        # for the front end's uncertainty between two keyframes along its most certain
        # path (front_std); the paths from the last keyframe asked for, while unchanged
        self.graph = _GraphEdges()
        self._paths: tuple[tuple[int, int, int], np.ndarray] | None = None
        self.seconds = {k: 0.0 for k in ("prepare", "front_end", "loops", "pcm", "isam")}
        gtsam = _gtsam()
        self.gtsam = gtsam
        self.isam = gtsam.ISAM2(gtsam.ISAM2Params())
        self.all_factors = gtsam.NonlinearFactorGraph()  # every factor given to iSAM2
        self.new_factors = gtsam.NonlinearFactorGraph()
        self.new_values = gtsam.Values()
        self.sig_mod = _loops.signature_module() if self.lc.appearance else None
        # verifications proposed since the last flush: (keyframe, [(i, local, source)],
        # handle of their verdicts)
        self.batch: list = []
        self.anchors: list = []  # accepted closures of the recent batches (PCM anchors)
        # the loops' own matcher configuration: the keyframes prepared again without the
        # edges where a wall only leaves the reach (LoopConfig.reach_edges); None: the
        # front end's
        self.loop_match = loop_match(cfg)
        self.kf_loop_prep: list = []
        self.verifier = Verifier(cfg.match, self.fe, self.floor, workers, self.loop_match)

    # -- helpers ----------------------------------------------------------------------
    def prepare(self, j: int):
        """Scan ``j`` prepared for matching, its sweep's skew taken out
        (``FrontEndConfig.deskew``) at the velocity of :meth:`sweep_velocity`; none known
        (the log's start, a gap): as it is."""
        t = time.perf_counter()
        scan = self.scans[j]
        if scan.beam_times is not None and self.fe.deskew:
            if self.timing is None:
                self.decide_timing(j)
            scan, self.swept = retime(scan, self.timing or "none"), True
            v = None if scan.beam_times is None else self.sweep_velocity(j, measured_before(scan))
            if v is not None:
                scan = deskew(scan, v)
                self.deskewed += 1
        p = prepare_scan(scan, self.cfg.match)
        self.seconds["prepare"] += time.perf_counter() - t
        return p

    def decide_timing(self, j: int) -> None:
        """Online, how the beam times are read (:func:`~.sweep.sweep_timing` on the scans
        placed so far, along the odometry or the chain), tried when scan ``j`` is the
        25th, 50th, 100th, ... (doubling: the log's length is not known); until the scans
        tell (enough of them turned, and one reading leads), they are not de-skewed."""
        q, r = divmod(j, 25)
        if r or q < 1 or q & (q - 1):  # j = 25 * 2^m only
            return
        from .sweep import sweep_timing

        done = self.scans[:j]
        pose = (lambda i: done[i].odometry) if self.odo else self.chain.__getitem__
        timing, scores, pairs = sweep_timing(done, pose, self.cfg.match)
        if timing is not None:
            self.timing = timing
            _log_timing(timing, scores, pairs)

    def sweep_velocity(self, j: int, before: bool) -> tuple[float, float, float] | None:
        """The velocity :meth:`prepare` de-skews scan ``j`` at (:func:`sweep_velocity`): the
        odometry's over the step its sweep lies in (to the next scan, or from the one
        before for beams ``before`` the stamp) when the whole log is given (:meth:`run`),
        else from the scan before; without odometry a first pass's
        (:func:`sweep_velocities`, ``map_scans``), else the chain's over the last
        ``FrontEndConfig.deskew_window`` seconds before scan ``j - 1``."""
        scans, s = self.scans, self.scans[j]
        if self.velocities is not None and not self.odo:
            return self.velocities[j]
        if self.odo and s.odometry is not None:
            log_ = self.ahead if self.ahead is not None else scans  # online: none ahead
            return sweep_velocity_of(log_, j, lambda i: log_[i].odometry, before)
        if j < 2 or scans[j - 1].timestamp is None:
            return None
        prev = scans[j - 1]
        # the chain's own steps are the matches': over one step their errors come back
        # through the de-skew (one step long, the next short, and so on)
        i = j - 2
        while i >= 0 and _ts(scans, i) is not None:
            if prev.timestamp - scans[i].timestamp >= self.fe.deskew_window:
                break
            i -= 1
        if i < 0 or self.chain[i] is None:
            return None
        return sweep_velocity(self.chain[i], self.chain[j - 1], scans[i].timestamp, prev.timestamp)

    def add_edge(self, a: int, b: int, Z: Pose2, P: np.ndarray, kind: str) -> None:
        """Edge ``a - b`` (``"chain"``, ``"local"`` or ``"loop"``) of the keyframe graph, as
        the batch back end takes it (``kf_edges``) and as the loops' paths do (``graph``)."""
        self.kf_edges.append((a, b, Z, P, kind))
        self.graph.add(a, b, Z, P)

    def estimate_of(self, kf_index: int) -> Pose2:
        return Pose2.from_array(self.est_xy[kf_index])

    def estimate_between(self, i: int, j: int) -> Pose2:
        """The current estimate's pose of keyframe ``j`` in keyframe ``i``."""
        return self.estimate_of(i).inverse() @ self.estimate_of(j)

    def drift_sigma(self, i: int, j: int) -> tuple[float, float]:
        """``(sigma_xy m, sigma_theta rad)`` the estimate of keyframe ``j`` may have drifted
        from keyframe ``i < j`` by the loops' drift model
        (:func:`~scanclique.mapping.loops.drift_std`) over :meth:`drift_path`."""
        return _loops.drift_std(float(self.drift_path(j, i)), self.lc)

    def drift_path(self, j: int, i: int | None = None):
        """The path (m) over which the estimate of keyframe ``j`` may have drifted from
        keyframe ``i`` (a float), or from each keyframe ``i <= j`` when ``i`` is None
        (``(j + 1,)``): the chain's path between them or, when shorter,
        with odometry the path since the last accepted closure, and without it the length
        of the most certain path of the keyframe graph (:meth:`paths_from`, closures
        counting their own short length).

        Without odometry, only the closures on the way between the two keyframes shorten
        it: after a short loop closed past a stretch the front end could not fix, the
        places before the stretch are as far as the chain says (Intel with every second
        beam: 0.1121 -> 0.0286 m; the rows without odometry of both raw logs and the
        corrected logs as good or better). With odometry the same rule let through more
        look-alike closures (Intel as recorded 0.0147 -> 0.0148 m, with a 5.6 m range
        0.0205 -> 0.0227 m, twice as many closures off by more than 0.2 m or 1 degree), so
        there the last closure restarts the path, as before session 17."""
        which = slice(0, j + 1) if i is None else i
        to = self.kf_path[j]
        chain = to - (self.kf_path[: j + 1] if i is None else self.kf_path[i])
        if self.odo:
            return np.minimum(chain, to - self.last_closure_path)
        return np.minimum(chain, self.paths_from(j)[which, 2])

    def beyond_drift(self, i: int, j: int, Z: Pose2, P: np.ndarray) -> bool:
        """Whether closure ``i``-``j`` (pose ``Z``, covariance ``P``) lies outside the 99 %
        gate of the current estimate with the path's drift model alone
        (:func:`~scanclique.mapping.loops.drift_std`)."""
        s_xy, s_th = self.drift_sigma(i, j)
        est = self.estimate_between(i, j)
        return mahalanobis_sq(Z, P, est, _cov_xy_rot(s_xy, s_th)) > GATE_99

    def moves_far(self, i: int, j: int, Z: Pose2) -> bool:
        """Whether closure ``i``-``j`` (pose ``Z``) moves the current estimate by more than
        the drift model's cap (``loops.max_radius``): a loop candidate by the estimate
        reaches that far only where the front end's own uncertainty (:meth:`front_std`)
        widened its radius, and is then corroborated as an appearance closure is.

        A 200 x 120 m ring corridor driven with odometry, a scan every 5 cm
        (``benchmarks/mapping_ring.py --size 200x120 --step 0.05``): without a closure
        the front end's sigma was 28 m after 400 m, and after 470 m a parallel corridor
        117 m away, seen the other way, was closed on: 54 m of mean error, 0.48 m with the
        rule."""
        return self.estimate_shift(i, j, Z) > self.lc.max_radius

    def estimate_shift(self, i: int, j: int, Z: Pose2) -> float:
        """How far (m) closure ``i``-``j`` (pose ``Z``) moves keyframe ``j`` from where the
        current estimate has it relative to ``i``."""
        est = self.estimate_between(i, j)
        return math.hypot(Z.x - est.x, Z.y - est.y)

    def turned(self, i: int, j: int, Z: Pose2) -> str:
        """Why closure ``i``-``j`` (pose ``Z``) is refused as a turned look-alike, or "":
        it turns the current estimate by more than ``loops.max_turn`` and by more than 3
        sigma of the front end's own heading uncertainty between the two keyframes
        (:meth:`front_std`)."""
        est = self.estimate_between(i, j)
        turn = abs(math.atan2(math.sin(Z.theta - est.theta), math.cos(Z.theta - est.theta)))
        if turn <= self.lc.max_turn:
            return ""
        s_th = self.front_std(i, j)[1]
        if turn <= 3.0 * s_th:
            return ""
        return (
            f"turns the estimate by {math.degrees(turn):.0f} deg > loops.max_turn="
            f"{math.degrees(self.lc.max_turn):.0f} deg and 3 sigma of the front end's own "
            f"heading uncertainty ({math.degrees(3.0 * s_th):.1f} deg): a look-alike a "
            "quarter or half turn round"
        )

    def robust_scale(self, i: int, j: int, P: np.ndarray) -> float:
        """Scale of the robust kernel of closure ``i``-``j`` (covariance ``P``), in units of
        its own sigma: at least ``back_end.robust_scale``, and as large as the front end's
        own uncertainty between the two keyframes (:meth:`front_std`) in excess of the
        path's drift model (:func:`~scanclique.mapping.loops.drift_std`, which the kernel
        at ``back_end.robust_scale`` was tuned with) in units of the closure's tightest
        sigma: a closure that corrects an error the front end knows it may have made (a
        step placed by the prediction, a corridor) is not taken for an outlier (PCM has
        vetted it). With odometry as without it. Measured
        on the corrected logs without odometry (relation error mean): Intel 0.0621 m
        (0.0966 m with the kernel at 1), CSAIL 0.0777 m (0.0639 m); the whole front-end
        uncertainty instead of its excess: 0.0621 / 0.0772 m."""
        f_xy, f_th = self.front_std(i, j, chain=True)
        d_xy, d_th = _loops.drift_std(abs(self.kf_path[j] - self.kf_path[i]), self.lc)
        f_xy = math.sqrt(max(f_xy**2 - d_xy**2, 0.0))
        f_th = math.sqrt(max(f_th**2 - d_th**2, 0.0))
        s_xy = math.sqrt(max(float(np.linalg.eigvalsh(P[:2, :2])[0]), 1e-12))
        s_th = math.sqrt(max(float(P[2, 2]), 1e-12))
        return max(self.cfg.back_end.robust_scale, f_xy / s_xy, f_th / s_th)

    def _add_isam_edge(
        self, a: int, b: int, Z: Pose2, P: np.ndarray, robust: bool, scale: float | None = None
    ) -> None:
        gtsam = self.gtsam
        noise = gtsam.noiseModel.Gaussian.Covariance(tangent_covariance(Z, P))
        if robust and self.cfg.back_end.robust != "none":
            scale = self.cfg.back_end.robust_scale if scale is None else scale
            est = (
                gtsam.noiseModel.mEstimator.Cauchy.Create(scale)
                if self.cfg.back_end.robust == "cauchy"
                else gtsam.noiseModel.mEstimator.Huber.Create(scale)
            )
            noise = gtsam.noiseModel.Robust.Create(est, noise)
        self.new_factors.add(gtsam.BetweenFactorPose2(a, b, gtsam.Pose2(Z.x, Z.y, Z.theta), noise))

    # -- step 2: a new keyframe -------------------------------------------------------
    def add_keyframe(self, j: int, prep, rel_prev: Pose2 | None, cov_prev: np.ndarray | None):
        gtsam = self.gtsam
        kidx = len(self.kf)
        if kidx == 0:
            guess = Pose2.identity()
            path = 0.0
            self.kf_var.append((0.0, 0.0))
            noise = gtsam.noiseModel.Diagonal.Sigmas(np.array([1e-6, 1e-6, 1e-8]))
            self.new_factors.add(gtsam.PriorFactorPose2(0, gtsam.Pose2(0, 0, 0), noise))
        else:
            guess = self.estimate_of(kidx - 1) @ rel_prev
            path = self.kf_path[-1] + math.hypot(rel_prev.x, rel_prev.y)
            vxy = float(np.linalg.eigvalsh(cov_prev[:2, :2])[-1])
            vth = float(cov_prev[2, 2])
            self.kf_var.append((self.kf_var[-1][0] + vxy, self.kf_var[-1][1] + vth))
            self.add_edge(kidx - 1, kidx, rel_prev, cov_prev, "chain")
            self._add_isam_edge(kidx - 1, kidx, rel_prev, cov_prev, False)
        self.new_values.insert(kidx, gtsam.Pose2(guess.x, guess.y, guess.theta))
        self.kf.append(j)
        self.kf_prep.append(prep)
        if self.loop_match is not None:
            t = time.perf_counter()
            self.kf_loop_prep.append(prepared_again(prep, self.loop_match))
            self.seconds["prepare"] += time.perf_counter() - t
        self.kf_path.append(path)
        self.kf_chain.append(self.chain[j].as_array())
        self.est_xy = np.vstack([self.est_xy, guess.as_array()[None]])
        if self.sig_mod is not None:
            sig = np.asarray(self.sig_mod.scan_signature(prep), dtype=float)
            if self.kf_sig is None:
                self.kf_sig = _Rows(len(sig))
            self.kf_sig.append(sig)
        if kidx > 0 and self.lc.enabled:
            self.search(kidx)
        if (kidx + 1) % self.lc.pcm_batch == 0:
            self.flush()

    # -- step 3: local matches and loop candidates -------------------------------------
    def search(self, kidx: int) -> None:
        t = time.perf_counter()
        lc = self.lc
        cum = self.kf_path.array
        est_j = self.estimate_of(kidx)
        tried: set[int] = {kidx - 1}
        jobs: list[tuple[int, bool, str]] = []
        # local neighbours: recent keyframes within min_path, still overlapping
        for back in range(2, 2 + lc.local):
            i = kidx - back
            if i < 0 or cum[kidx] - cum[i] >= lc.min_path:
                break
            jobs.append((i, True, "estimate"))
            tried.add(i)
        if kidx % lc.every == 0:
            since = self.drift_path(kidx)
            front = self.front_std_to(kidx)
            for i in _loops.candidates(kidx, self.est_xy[:, :2], cum, since, lc, tried, front):
                jobs.append((i, False, "estimate"))
                tried.add(i)
            # where the front end's chain puts this keyframe relative to each earlier one,
            # when that is further than the candidate radius from where the estimate puts
            # it, yet within the drift model's reach of it, and no closure on the way has
            # corrected the estimate there: the places nearest the chain's claim are
            # candidates too (source "chain"), verified as strictly as appearance ones.
            # Local matches can pull the estimate off a chain that is right (a 200 x 120 m
            # ring with 2 % long wheels, online: where the loop closes the estimate 3.1 m
            # off, the chain 0.58 m; the places nearest the estimate were a door along, and
            # that look-alike closed the loop: 3.750 -> 0.679 m). A chain further off than
            # the drift model allows (the LDS-01 outdoors, 25 m: a block along) is not
            # searched, and a loose one's look-alikes must match without the prior
            chain = self.kf_chain.array
            off = np.hypot(*(_relative(chain, kidx) - _relative(self.est_xy, kidx)).T)
            along = cum[kidx] - cum[: kidx + 1]
            reach = np.minimum(lc.radius + lc.growth * np.minimum(along, since), lc.max_radius)
            uncorrected = self.paths_from(kidx)[:, 2] >= 0.5 * along
            apart = (off >= lc.radius) & (off <= reach) & uncorrected
            for i in _loops.candidates(kidx, chain[:, :2], cum, since, lc, tried, front, apart):
                jobs.append((i, False, "chain"))
                tried.add(i)
            if self.kf_sig:
                for i in _loops.appearance_candidates(kidx, self.kf_sig.array, cum, lc):
                    if i not in tried:
                        jobs.append((i, False, "appearance"))
                        tried.add(i)
        tasks, meta = [], []
        for i, local, source in jobs:
            est_i = self.estimate_of(i)
            sigma = self.prior_sigma(i, kidx, local, source)
            tasks.append(
                (self.kf[i], self.kf[kidx], est_i, est_j, sigma, local, source != "estimate")
            )
            meta.append((i, local, source))
        if tasks:
            # the scans the jobs name, the loops' own when they have them (LoopConfig.reach_edges)
            own = self.loop_match is not None
            prepared = {self.kf[i]: self.kf_prep[i] for i, lo, _ in meta if lo or not own}
            prepared[self.kf[kidx]] = self.kf_prep[kidx]
            loop_prepared = None
            if own:
                loop_prepared = {self.kf[i]: self.kf_loop_prep[i] for i, lo, _ in meta if not lo}
                loop_prepared[self.kf[kidx]] = self.kf_loop_prep[kidx]
            handle = self.verifier.submit(tasks, prepared, loop_prepared)
            self.batch.append((kidx, meta, handle))
        self.seconds["loops"] += time.perf_counter() - t

    def prior_sigma(self, i: int, kidx: int, local: bool, source: str) -> tuple[float, float]:
        """``(sigma_xy m, sigma_theta rad)`` of the prior with which keyframe ``kidx`` is
        verified against the earlier keyframe ``i``: a local neighbour (``local``) by the
        well-known chain; a loop candidate (``source`` ``"estimate"``, ``"chain"`` or
        ``"appearance"``) by the drift the estimate may have accumulated since the last
        closure, widened to the front end's own uncertainty there (:meth:`front_std`); an
        appearance candidate by twice both."""
        if local:
            drift = self.kf_path[kidx] - self.kf_path[i]
            return (0.05 + 0.02 * drift, math.radians(1.0) + math.radians(0.5) * drift)
        sigma = self.drift_sigma(i, kidx)
        if source == "appearance":
            # beyond the estimate's radius, but not anywhere: twice the drift the
            # estimate may have accumulated (a 6-sigma bound), so that a look-alike
            # place of a symmetric building (a corridor seen the other way, a twin
            # room metres away) is refused when the estimate is known to be good
            sigma = (2.0 * sigma[0], min(2.0 * sigma[1], math.radians(40.0)))
        # where the front end itself was unsure (its edges' covariances: a step
        # placed by the prediction, a corridor), the estimate may be off by as much;
        # twice that for appearance, the look-alike guard on the heading kept
        k = 2.0 if source == "appearance" else 1.0
        f = self.front_std(i, kidx)
        f = (k * f[0], min(k * f[1], math.radians(40.0)))
        return max(sigma[0], f[0]), max(sigma[1], f[1])

    def paths_from(self, b: int) -> np.ndarray:
        """Summed ``(var_xy m², var_theta rad², length m)`` of the front end's most certain
        path in the keyframe graph (chain steps, local matches and accepted closures, each
        edge with its covariance and its translation's length) from keyframe ``b`` to every
        keyframe, ``(len(kf), 3)`` (:func:`~scanclique.mapping._kernels.most_certain_paths`).
        Computed again only when the graph has grown."""
        key = (b, len(self.kf), self.graph.m)
        if self._paths is None or self._paths[0] != key:
            g = self.graph
            paths = _K.most_certain_paths(
                len(self.kf),
                g.a.array,
                g.b.array,
                g.var_xy.array,
                g.var_theta.array,
                g.length.array,
                g.m,
                b,
            )
            self._paths = (key, paths)
        return self._paths[1]

    def front_std_to(self, b: int) -> np.ndarray:
        """:meth:`front_std`'s ``sigma_xy`` of every keyframe ``a <= b`` to ``b``, at once."""
        p = self.paths_from(b)[: b + 1]
        var = self.kf_var[: b + 1]
        path = self.kf_path[: b + 1]
        chain = _chain_sigma_xy(var[b, 0] - var[:, 0], var[b, 1] - var[:, 1], path[b] - path)
        return np.minimum(_chain_sigma_xy(p[:, 0], p[:, 1], p[:, 2]), chain)

    def front_std(self, a: int, b: int, chain: bool = False) -> tuple[float, float]:
        """``(sigma_xy m, sigma_theta rad)`` of the front end's relative pose of keyframes
        ``a`` and ``b`` from its own edges' covariances (the variances summed along a path,
        a heading error acting on a third of the path's square as its lever arm): along the
        most certain path of the keyframe graph (:meth:`paths_from`), through local matches
        and accepted closures, or the chain between them when that is more certain; or
        along the chain alone (``chain``).

        A closure shortens the paths it bypasses, and only those: after a short loop
        closed at the end of a corridor the front end slid along, the path from there to
        the places before the corridor still crosses the slide (Intel with every second
        beam, no odometry: the estimate's prior of those places, counted from the last
        closure instead, was 0.12 m where the estimate was 1.7 m off, and refused the
        closures that would have corrected it)."""
        lo, hi = min(a, b), max(a, b)
        var_xy = self.kf_var[hi][0] - self.kf_var[lo][0]
        var_th = self.kf_var[hi][1] - self.kf_var[lo][1]
        s_xy = float(_chain_sigma_xy(var_xy, var_th, self.kf_path[hi] - self.kf_path[lo]))
        if not chain:
            # the chain is one of the paths; the search's cost is not a sum over edges, so
            # its path may be less certain than the chain's (rarely)
            g_xy, g_th, g_len = self.paths_from(b)[a]
            g_sigma = float(_chain_sigma_xy(g_xy, g_th, g_len))
            if g_sigma < s_xy:
                s_xy, var_th = g_sigma, g_th
        return s_xy, math.sqrt(max(var_th, 0.0))

    def chain_rel(self, a: int, b: int) -> tuple[Pose2, np.ndarray]:
        """Front-end relative pose of keyframe ``b`` in keyframe ``a`` and a covariance
        growing with the path between them (PCM's chain)."""
        pa, pb = self.chain[self.kf[a]], self.chain[self.kf[b]]
        D = abs(self.kf_path[b] - self.kf_path[a])
        f_xy, f_th = self.front_std(a, b, chain=True)
        s_xy = max(0.02 + 0.02 * D, f_xy)
        s_th = max(math.radians(0.5) + math.radians(0.3) * D, f_th)
        return pa.inverse() @ pb, _cov_xy_rot(s_xy, s_th)

    # -- step 4: PCM over the batch, then iSAM2 ----------------------------------------
    def consume(self) -> None:
        """The verdicts of the batch's candidates, in the order they were proposed (the
        same whether they were verified here or on worker processes)."""
        lc = self.lc
        loops = []  # the loop candidates that passed, once the batch's local matches are in
        for kidx, meta, handle in self.batch:
            for (i, local, source), out in zip(meta, handle.result(), strict=True):
                pose, cov, verdict, score, reason = out
                doubt = None if pose is None or local else closure_doubt(cov, score, lc)
                if doubt is not None:
                    pose, (verdict, reason) = None, doubt
                if pose is not None and not local:
                    why = self.turned(i, kidx, pose)
                    if why:
                        pose, verdict, reason = None, "turned", why
                if pose is None:
                    self.closures.append(
                        LoopClosure(self.kf[i], self.kf[kidx], None, None, verdict, False,
                                    local, source, score, reason)
                    )  # fmt: skip
                    continue
                if local:
                    self.closures.append(
                        LoopClosure(self.kf[i], self.kf[kidx], pose, cov, verdict, True, True,
                                    source, score, reason)
                    )  # fmt: skip
                    self.add_edge(i, kidx, pose, cov, "local")
                    self._add_isam_edge(i, kidx, pose, cov, False)
                else:
                    loops.append((i, kidx, pose, cov, source, score, reason))
        self.batch = []
        for i, j, pose, cov, source, score, reason in loops:
            refused = self.look_alike(i, j, pose, cov)
            if refused is not None:
                verdict, why = refused
                self.closures.append(
                    LoopClosure(self.kf[i], self.kf[j], None, None, verdict, False, False,
                                source, score, why)
                )  # fmt: skip
            else:
                self.pending.append((i, j, pose, cov, source, score, reason))

    def look_alike(self, i: int, j: int, Z: Pose2, P: np.ndarray) -> tuple[str, str] | None:
        """``(verdict, reason)`` when closure ``i``-``j`` (pose ``Z``, covariance ``P``) is
        refused as a look-alike, else None. Either way it moves the current estimate by
        more than 3 sigma of the front end's own uncertainty between the two keyframes
        (:meth:`front_std`, through the local matches of the batch: a candidate is verified
        when its keyframe is made, by the prior of that moment, and the local matches that
        fix a stretch the chain was unsure of come after it); then

        * ``"shifted"``: by more than the drift model's candidate radius over the chain's
          path ``L`` between the two keyframes (:func:`~scanclique.mapping.loops.drift_std`,
          3 sigma) and by more than ``loops.max_shift`` times ``L``: a look-alike along the
          way (a door or two along a corridor);
        * ``"conflicting"``: outside the drift model's 99 % gate (:meth:`beyond_drift`, as
          a closure that must be corroborated), and the two keyframes' raw scans, under
          ``Z``, see through more than ``loops.max_conflict`` of each other's points
          (:func:`scanclique.match.conflict_fraction`): a twin room, its walls lined up
          with the other's while its furniture stands where the other saw free floor.
        """
        shift = self.estimate_shift(i, j, Z)
        s_xy = self.front_std(i, j)[0]
        if shift <= 3.0 * s_xy:
            return None
        path = float(self.kf_path[j] - self.kf_path[i])
        beyond = (
            f"moves the estimate by {shift:.2f} m over a path of {path:.1f} m: more than 3 "
            f"sigma of the front end's own uncertainty ({3.0 * s_xy:.2f} m)"
        )
        if shift > max(3.0 * _loops.drift_std(path, self.lc)[0], self.lc.max_shift * path):
            return "shifted", (
                f"{beyond}, the drift model's radius and loops.max_shift="
                f"{self.lc.max_shift:g} of the path: a look-alike along the way (a door or "
                "two along a corridor)"
            )
        if not self.beyond_drift(i, j, Z, P):
            return None
        conflict = conflict_fraction(self.kf_prep[i], self.kf_prep[j], Z, self.cfg.match)
        if conflict > self.lc.max_conflict:
            return "conflicting", (
                f"{beyond} and the drift model's 99 % gate, and {conflict:.1%} of the raw "
                "scans' points lie where the other saw through (loops.max_conflict="
                f"{self.lc.max_conflict:g}): a twin place"
            )
        return None

    def flush(self, final: bool = False) -> None:
        t = time.perf_counter()
        self.consume()
        self.seconds["loops"] += time.perf_counter() - t
        t = time.perf_counter()
        # closures deferred from the previous batches (waiting for a second one) come back
        self.pending = [p for p, _ in self.deferred] + self.pending
        age = {id(p): a for p, a in self.deferred}
        self.deferred = []
        if self.pending:
            cl = [(i, j, Z, P) for i, j, Z, P, *_ in self.pending]
            # incremental PCM: the closures accepted over the previous batches anchor the
            # new ones (a closure alone in its batch is checked against them too)
            newest = max(j for _, j, *_ in self.pending)
            span = self.lc.pcm_anchor_batches * self.lc.pcm_batch
            self.anchors = [a for a in self.anchors if newest - a[1] <= span]
            keep = set(
                pcm_select(cl, self.chain_rel, self.lc.pcm_gate, anchors=self.anchors).tolist()
            )
            # a closure that moves the estimate further than the path's drift allows (the
            # front end said it may have: a step placed by the prediction, a corridor)
            # needs a second one across the same stretch that agrees with it: a look-alike
            # place is rarely seen twice alike. So does one by the estimate that moves it
            # beyond the drift model's cap (found only because the front end's own
            # uncertainty, summed over a long loop, widened the search that far)
            big = [
                k for k in keep
                if self.lc.corroborate_batches > 0
                and self.beyond_drift(*cl[k])
                and (self.pending[k][4] == "appearance" or self.moves_far(*cl[k][:3]))
            ]  # fmt: skip
            # corroborated: another one from an earlier place at least ``separation``
            # keyframes away (consecutive keyframes seeing one look-alike are one witness)
            lone = {
                k for k in big
                if all(abs(cl[k][0] - cl[o][0]) < self.lc.separation for o in big)
            }  # fmt: skip
            for k, item in enumerate(self.pending):
                i, j, Z, P, source, score, reason = item
                a = age.get(id(item), 0)
                if k in lone and a + 1 < self.lc.corroborate_batches and not final:
                    self.deferred.append((item, a + 1))  # wait for a second closure
                    continue
                ok = k in keep and k not in lone
                verdict = "accepted" if ok else ("uncorroborated" if k in lone else "pcm_rejected")
                self.closures.append(
                    LoopClosure(self.kf[i], self.kf[j], Z, P, verdict, ok, False, source, score,
                                reason)
                )  # fmt: skip
                if ok:
                    self.anchors.append((i, j, Z, P))
                    self.add_edge(i, j, Z, P, "loop")
                    self.loop_scale[(i, j)] = self.robust_scale(i, j, P)
                    self._add_isam_edge(i, j, Z, P, True, self.loop_scale[(i, j)])
                    self.last_closure_path = max(self.last_closure_path, self.kf_path[j])
            self.pending = []
        self.seconds["pcm"] += time.perf_counter() - t
        t = time.perf_counter()
        if self.new_factors.size() or self.new_values.size():
            self.all_factors.push_back(self.new_factors)
            try:
                self.isam.update(self.new_factors, self.new_values)
            except RuntimeError as e:
                self.restart_isam(e)
            self.new_factors = self.gtsam.NonlinearFactorGraph()
            self.new_values = self.gtsam.Values()
            est = self.isam.calculateEstimate()
            self.est_xy = np.asarray(self.gtsam.utilities.extractPose2(est), dtype=float)
        self.seconds["isam"] += time.perf_counter() - t

    def restart_isam(self, error: RuntimeError) -> None:
        """iSAM2 from scratch, when its incremental update failed (``error``: an
        indeterminate linear system): Levenberg–Marquardt over every factor so far from the
        current estimate, and a new iSAM2 started from that solution. GTSAM's incremental
        elimination can find a system indeterminate that the batch solves (corrected CSAIL
        with every second scan, without odometry: near keyframe 119, after a 109-degree
        step and among steps placed by the prediction with 1 rad of sigma; the run ended
        there before). Raises
        :class:`~scanclique.errors.PoseGraphError` when the batch fails too."""
        gtsam = self.gtsam
        says = next((ln.strip() for ln in str(error).splitlines() if ln.strip()), "")
        log.info(
            "map_scans: iSAM2 could not take keyframes up to %d (%s); solved in batch and "
            "restarted", len(self.kf) - 1, says,
        )  # fmt: skip
        values = gtsam.Values()
        for k, (x, y, th) in enumerate(self.est_xy):
            values.insert(k, gtsam.Pose2(float(x), float(y), float(th)))
        hint = ODOMETRY_HINT if self.odo else SCANS_HINT
        with solving("map_scans (iSAM2, solved in batch after it failed)", hint):
            solved = levenberg_marquardt(
                gtsam, self.all_factors, values, self.cfg.back_end.max_iterations
            )
            self.isam = gtsam.ISAM2(gtsam.ISAM2Params())
            self.isam.update(self.all_factors, solved)

    # -- step 2: the front end, one scan at a time --------------------------------------
    def add_scan(self, scan: Scan) -> None:
        """Take the log's next scan: place it by the front end (matched to the current
        keyframe, else by the prior, flagged); a new keyframe is searched for loops, and
        every ``pcm_batch`` keyframes the closures are selected and the estimate updated."""
        t = time.perf_counter()
        busy = self.loop_seconds()
        j = len(self.scans)
        self.scans.append(scan)
        self.chain.append(None)
        self.placed_by.append("")
        self.kf_of.append(j)
        self.rel_to_kf.append(Pose2.identity())
        if j == 0:
            self.chain[0] = Pose2.identity()
            self.placed_by[0] = "first"
            self.add_keyframe(0, self.prepare(0), None, None)
        else:
            self.place(j)
        # the front end's own time: the loops' searches and flushes are timed apart
        self.seconds["front_end"] += time.perf_counter() - t - (self.loop_seconds() - busy)

    def closures_accepted(self) -> int:
        """Loop closures accepted so far (local matches not counted), for progress."""
        return sum(1 for c in self.closures if c.accepted and not c.local)

    def loop_seconds(self) -> float:
        return self.seconds["loops"] + self.seconds["pcm"] + self.seconds["isam"]

    def promote(self, j: int, prep, rel: Pose2, cov: np.ndarray) -> None:
        """Make scan ``j`` (``rel``, ``cov`` from the current keyframe) a keyframe."""
        self.add_keyframe(j, prep, rel, cov)
        self.kf_of[j] = j
        self.rel_to_kf[j] = Pose2.identity()

    def close_log(self) -> None:
        """The log has ended: its last scan becomes a keyframe (when it is not one) and the
        closures still pending are decided."""
        t = time.perf_counter()
        busy = self.loop_seconds()
        if self.newest is not None:
            self.promote(len(self.scans) - 1, *self.newest)
            self.newest = None
        self.seconds["front_end"] += time.perf_counter() - t - (self.loop_seconds() - busy)
        self.flush(final=True)

    def run(self, scans: Sequence[Scan], progress: Progress | None = None) -> None:
        """Map the whole of ``scans``: :meth:`add_scan` for each, then :meth:`close_log`."""
        n = len(scans)
        self.ahead = scans
        for j, scan in enumerate(scans):
            self.add_scan(scan)
            if progress is not None and j > 0 and (j % 50 == 0 or j == n - 1):
                progress(j + 1, n, self.closures_accepted())
        self.close_log()

    def place(self, j: int) -> None:
        """The front end on scan ``j >= 1``: its pose relative to the current keyframe."""
        scans, fe = self.scans, self.fe
        prev2, prev = self.world_prev2, self.world_prev  # chain poses of scans j - 2, j - 1
        k = self.kf[-1]
        pk = self.kf_prep[-1]
        pj = self.prepare(j)
        sj, sk = scans[j], scans[k]
        times = (_ts(scans, j - 2), _ts(scans, j - 1), sj.timestamp)
        chain_k = self.chain[k]
        # the prior of scan j relative to keyframe k
        if self.odo and sj.odometry is not None and sk.odometry is not None:
            prior_a, prior_b = sk.odometry, sj.odometry
            noise = fe.odometry_noise
            path = [s.odometry for s in scans[k : j + 1] if s.odometry is not None]
            kind = ODOMETRY
        else:
            pred = self.motion.predict(prev2, prev, times)
            prior_a, prior_b = chain_k, pred
            noise = fe.velocity_noise
            path = None
            kind = CONSTANT_VELOCITY
        carried_w = None
        if kind == CONSTANT_VELOCITY:
            # the previous scan's own looseness counts when it lies relative to k too
            carried_w = self.motion.carried(self.kf_of[j - 1] == k and j - 1 != k)
        reversed_prior = False  # the match was taken against the odometry reversed
        if kind == CONSTANT_VELOCITY and fe.icp_fallback:
            rel_pred, pred_cov = odometry_prior(prior_a, prior_b, noise)
            step = associate_by_scans(
                pk, pj, rel_pred, None if prev2 is None else pred_cov,
                self.cfg.match, fe, self.floor, self.motion.max_translation(j - k),
                _rotated(carried_w, -chain_k.theta),
                chain_k.inverse() @ prev,
            )  # fmt: skip
            if step.kind == ICP:
                self.reasons[j] = step.reason or ""
        else:
            step = None
            if (
                kind == ODOMETRY
                and self.blind_to_reversing
                and prev2 is not None
                and (prev2.inverse() @ prev).x < -REVERSING_STEP
            ):
                # the robot was backing up (the scans say so) while its odometry drove
                # forwards: it most likely still is, so the odometry reversed is the
                # prior first (the odometry as logged next, when that rejects the
                # match). The other way round, a wrong match that happens to agree with
                # the forward odometry was taken: fr079 with every second scan, 14 deg
                # off at scan 1408 (relation error 0.888 -> 0.148 m at most)
                back_b = prior_a @ reversed_increment(prior_a.inverse() @ prior_b)
                back_path = [prior_a @ reversed_increment(prior_a.inverse() @ q) for q in path]
                back = associate(
                    pk, pj, prior_a, back_b, noise, self.cfg.match, path=back_path,
                    sigma_floor=self.floor, front_end=fe,
                )  # fmt: skip
                # in a corridor the reversed match takes its position along it from
                # the reversed odometry (along_corridor): the scans do not say the
                # robot is still backing up, and the odometry as logged decides (a
                # 3.5 m scanner: a slid match read as backing up, then every step of the
                # corridor reversed, 0.27 m each)
                if back.kind == MATCH and not back.along_prior:
                    self.reasons[j] = (
                        "the scans say the robot is backing up: matched against the "
                        "odometry reversed (it never reports backing up)"
                    )
                    step, prior_b, path = back, back_b, back_path
                    reversed_prior = True
                    self.odometry_doubted.add(j)
            if step is None:
                step = associate(
                    pk, pj, prior_a, prior_b, noise, self.cfg.match, path=path,
                    sigma_floor=self.floor, front_end=fe,
                    weak_prior=kind == CONSTANT_VELOCITY,
                )  # fmt: skip
        # the odometry increment and its covariance (the first prior of the fallback)
        odo = odometry_prior(prior_a, prior_b, noise, path=path) if kind == ODOMETRY else None
        measured = odo  # the odometry as logged: what OdometryFit reads its errors from
        scale = self.odo_fit.scale() if odo is not None else 0.0
        if scale != 0.0:
            # its steady scale error taken out where the odometry alone may place the scan
            # along a corridor: the contest of the match and the ICP fallback's seed
            odo = (OdometryFit.scaled(odo[0], scale), odo[1])
        # a match taken against the odometry reversed is not contested from there: ICP from
        # the reversed odometry would confirm the reversal by the prior alone (simulated
        # campus drive 1, never backing up: a forward match 2.3 sigma from the reversed
        # odometry lost to ICP slid back along a street, and each step placed backwards
        # made the next one's prior reversed too, 0.4-0.6 m a step for 60 scans)
        if step.kind == MATCH and odo is not None and not reversed_prior:
            step = contest_by_odometry(pk, pj, step, odo[0], fe, self.cfg.match, odo[1])
            if step.kind == ICP:
                self.reasons[j] = f"{step.verdict}: {step.reason}; placed by ICP"
        if odo is not None and self.odo_fit.doubts(step.verdict):
            self.odometry_doubted.add(j)
        if step.kind != MATCH and fe.icp_fallback and odo is not None:
            # the chain's own constant-velocity prediction: a seed of ICP always, and a
            # prior ICP's pose may agree with instead of the odometry only when the scan
            # before was placed by a feature match. After a step ICP placed, the chain's
            # velocity carries that step's own error and would confirm the next one's (a
            # 3.5 m scanner outdoors: steps turned 20-31 degrees against odometry right to
            # 0.5, each agreeing with the one before; campus drives 2 and 3 with odometry
            # 23.5 / 6.9 -> 4.2 / 3.0 m)
            pred = constant_velocity(prev2, prev, *times)
            cv = odometry_prior(chain_k, pred, fe.velocity_noise)
            seeds = [odo[0], cv[0]]
            # the odometry as good as it has proved against the accepted matches
            fit = self.odo_fit.fitted(odo) if fe.odometry_fit else odo
            priors = [fit, cv] if self.placed_by[j - 1] in (MATCH, "first") else [fit]
            if step.pose is not None:
                seeds.append(step.pose)
            alt = icp_fallback(pk, pj, seeds, priors, fe, self.cfg.match)
            if alt is not None:
                self.reasons[j] = f"{step.verdict}: {step.reason}; placed by ICP"
                step = alt
        if step.kind == MATCH and odo is not None and not reversed_prior:
            self.odo_fit.observe(step.pose, *measured, step.covariance)
        if step.kind in (MATCH, ICP):
            rel, cov, base = step.pose, step.covariance, k
            self.placed_by[j] = step.kind
        else:
            # placed by the prior from the previous scan (j - 1), flagged
            if kind == ODOMETRY and scans[j - 1].odometry is not None:
                a, b = scans[j - 1].odometry, sj.odometry
            else:
                kind = CONSTANT_VELOCITY
                a, b = prev, self.motion.predict(prev2, prev, times)
                noise = fe.velocity_noise
            fb = prior_step(a, b, noise, kind, step.reason or "", step.verdict, step.score)
            if kind == ODOMETRY and fe.odometry_fit:
                fb = self.odo_fit.placing(fb)  # as unsure as it has proved, where trusted
            if kind == CONSTANT_VELOCITY and carried_w is not None:
                # placed by the prediction alone: it is as unsure as the prediction,
                # inherited looseness included, and all of its translation is the motion's
                c = fb.covariance.copy()
                c[:2, :2] += _rotated(carried_w, -a.theta)
                fb = Step(fb.pose, c, fb.kind, fb.verdict, fb.score, fb.reason, c[:2, :2])
            s_th = self.motion.heading_sigma()
            if not self.odo and fb.covariance[2, 2] < s_th**2:
                # without odometry, a scan the raw scans could not place may have turned
                # as the prediction has proved to miss (a sharp turn before a wall)
                c = fb.covariance.copy()
                c[2, 2] = s_th**2
                fb = Step(fb.pose, c, fb.kind, fb.verdict, fb.score, fb.reason, fb.loose)
            # edge from j-1; expressed from keyframe k for the keyframe chain
            rel_prev = self.rel_to_kf[j - 1] if self.kf_of[j - 1] == k else Pose2.identity()
            cov_prev = np.zeros((3, 3))
            rel = rel_prev @ fb.pose
            cov = compose_covariance(rel_prev, cov_prev, fb.pose, fb.covariance)
            base = k
            self.placed_by[j] = kind
            self.reasons[j] = f"{step.verdict}: {step.reason}"
            self.edges.append(Edge(j - 1, j, fb.pose, fb.covariance, kind))
        self.chain[j] = chain_k @ rel
        self.kf_of[j] = base
        self.rel_to_kf[j] = rel
        if step.kind in (MATCH, ICP):
            self.edges.append(Edge(k, j, rel, cov, step.kind))
            if not self.odo:
                self.motion.observe(prev2, prev, times, self.chain[j], rel, j - k)
        moved = math.hypot(rel.x, rel.y) >= fe.keyframe_distance or abs(rel.theta) >= (
            fe.keyframe_angle
        )
        if (
            kind == CONSTANT_VELOCITY
            and step.kind in (MATCH, ICP)
            and constellation_std(cov)[0] >= fe.keyframe_distance
        ):
            # without odometry, a scan the raw scans place only to within more than a
            # keyframe's spacing (a corridor, look-alike poses) is a keyframe of its own:
            # a scan kept relative to a keyframe is where the front end put it for good,
            # a keyframe is where the back end and the loops put it
            moved = True
        self.newest = None
        if moved or step.kind not in (MATCH, ICP):
            self.promote(j, pj, rel, cov)
        else:  # the last scan of a log becomes a keyframe when the log ends (close_log)
            self.newest = (pj, rel, cov)
        self.world_prev2, self.world_prev = self.world_prev, self.chain[j]
        # what the motion model, not the scans, gave this scan, for the next prediction
        loose = step.loose if step.kind in (MATCH, ICP) else fb.loose
        frame = self.chain[j - 1] if step.kind not in (MATCH, ICP) else chain_k
        self.motion.placed(_rotated(loose, frame.theta))

    # -- step 5: the batch back end -----------------------------------------------------
    def odometry_factors(self) -> list[tuple[int, int, Pose2, np.ndarray]]:
        """``(i, j, Z, P)`` odometry edges of consecutive keyframes ``i``, ``j`` for the
        batch back end (:attr:`BackEndConfig.odometry_factors`): the odometry increment
        over the scans between them with its steady heading drift taken out and the
        model's covariance over that path scaled to the residuals left
        (:meth:`OdometryFit.calibration`, :meth:`OdometryFit.corrected`: edges of a graph
        are independent, so a drift within their noise on every edge would bend a long
        corridor; 0.003 rad/m bent a 200 x 120 m ring by metres), and its steady scale
        error too when the matches, each weighed by its own sigma along the step, show one
        (:meth:`OdometryFit.scale`); none unless the odometry
        proved, so corrected, at least ``odometry_max_fit`` times better than its model in
        heading, none when no scale error is shown but the matches steadily step further
        than the odometry (:meth:`OdometryFit.steps_off` above 0: wheels measuring short,
        whose edges would shorten every corridor: a 200 x 120 m ring whose odometry steps
        2 % short maps 0.845 m with the edges, 0.671 m without, 0.541 m with its scale
        taken out of the edges). Matches stepping short of the odometry are no such sign:
        along a street or corridor they stay partly where their seed put them and read steps short
        themselves (the simulated campus LDS-01, whose odometry is exact, 2.9 % on drive
        0; without the edges that drive's online map went 0.11 -> 0.33 m), none
        for a chained-only map (``loops.enabled`` False), and none across a scan whose
        match was rejected for disagreeing with it (a slip) or matched against it
        reversed."""
        be = self.cfg.back_end
        on = self.odo and be.odometry_factors and self.cfg.loops.enabled  # not chained only
        cal = self.odo_fit.calibration() if on else None
        if cal is None or cal[1][1] > be.odometry_max_fit:  # (drift, (xy, heading) scales)
            return []
        scale = self.odo_fit.scale()
        if scale == 0.0 and self.odo_fit.steps_off() > 0.0:  # the wheels are short
            return []
        out = []
        for k in range(1, len(self.kf)):
            a, b = self.kf[k - 1], self.kf[k]
            path = [s.odometry for s in self.scans[a : b + 1]]
            doubted = any(m in self.odometry_doubted for m in range(a + 1, b + 1))
            if doubted or any(p is None for p in path):
                continue
            if scale != 0.0:  # the steady scale error the matches read taken out
                start, back = path[0], path[0].inverse()
                path = [start @ OdometryFit.scaled(back @ q, scale) for q in path]
            Z, P = self.odo_fit.corrected(
                odometry_prior(path[0], path[-1], self.fe.odometry_noise, path=path),
                travel(path)[0],
                cal,
            )
            out.append((k - 1, k, Z, P))
        return out

    def optimize(self) -> tuple[list[Pose2], list[np.ndarray] | None]:
        """The batch back end: every scan's pose, and with
        :attr:`BackEndConfig.covariances` every scan's covariance (else None)."""
        be = self.cfg.back_end
        g = PoseGraph()
        for kidx in range(len(self.kf)):
            g.add_node(kidx, self.estimate_of(kidx))
        Q = (
            tangent_covariances(
                np.array([e[2].theta for e in self.kf_edges]),
                np.array([e[3] for e in self.kf_edges], dtype=float),
            )
            if self.kf_edges
            else []
        )
        for (i, j, Z, P, kind), q in zip(self.kf_edges, Q, strict=True):
            robust = be.robust if kind == "loop" else "none"
            scale = self.loop_scale.get((i, j), be.robust_scale)
            g.add_edge(i, j, Z, P, robust, scale, tangent=q)
        self.odo_edges = self.odometry_factors()
        for i, j, Z, P in self.odo_edges:
            g.add_edge(i, j, Z, P)
        out = g.optimize(be.max_iterations)
        kf_pose = {self.kf[k]: out[k] for k in range(len(self.kf))}
        t = time.perf_counter()
        kf_cov = None
        if be.covariances:
            marg = g.covariances()
            kf_cov = {self.kf[k]: marg[k] for k in range(len(self.kf))}
            # a scan kept between keyframes hangs from its keyframe by its front-end edge
            to_kf = {(e.i, e.j): e.covariance for e in self.edges if e.kind in (MATCH, ICP)}
        poses, covs = [], None if kf_cov is None else []
        for j in range(len(self.scans)):
            base = self.kf_of[j]
            if j in kf_pose:
                poses.append(kf_pose[j])
            else:
                poses.append(kf_pose[base] @ self.rel_to_kf[j])
            if covs is not None:  # a scan between keyframes: its match to its keyframe added
                covs.append(
                    kf_cov[j]
                    if j in kf_cov
                    else compose_covariance(
                        kf_pose[base], kf_cov[base], self.rel_to_kf[j], to_kf[(base, j)]
                    )
                )
        if covs is not None:
            self.seconds["covariances"] = time.perf_counter() - t
        return poses, covs

    # -- the result ---------------------------------------------------------------------
    def result(self, t0: float) -> MapResult:
        """The batch back end over the keyframe graph so far, and the map's record
        (``t0``: the ``perf_counter`` the run started at, for ``seconds["total"]``)."""
        t = time.perf_counter()
        poses, covs = self.optimize()
        seconds = dict(self.seconds)
        seconds["optimize"] = time.perf_counter() - t - seconds.get("covariances", 0.0)
        # every edge of the keyframe graph, in scan indices, for the outputs
        kf_edges = [
            Edge(self.kf[i], self.kf[j], Z, P, kind if kind != "chain" else "keyframe")
            for i, j, Z, P, kind in self.kf_edges
            if kind != "chain"
        ] + [Edge(self.kf[i], self.kf[j], Z, P, "odometry_factor") for i, j, Z, P in self.odo_edges]
        seconds["total"] = time.perf_counter() - t0
        return MapResult(
            poses=tuple(poses),
            placed_by=tuple(self.placed_by),
            reasons=dict(self.reasons),
            keyframes=tuple(self.kf),
            edges=tuple(self.edges) + tuple(kf_edges),
            loop_closures=tuple(self.closures),
            chained=tuple(self.chain),
            used_odometry=bool(self.odo),
            seconds=seconds,
            config=self.cfg,
            covariances=None if covs is None else tuple(_ro(c) for c in covs),
            deskewed=self.deskewed,
            sweep_timing=(self.timing or "none") if self.swept else "",
            odometry_fit=self.odo_fit.scales() if self.odo else None,
            odometry_drift=self.odo_fit.drift() if self.odo else None,
            odometry_steps=self.odo_fit.scale() if self.odo else None,
        )


def check_iterable_of_scans(where: str, scans):
    """``scans`` itself, or an :class:`ArgumentError` naming ``where`` when it cannot be a
    sequence of scans (None, a number, a path: iterating would fail with a bare TypeError,
    or split the path into characters)."""
    if isinstance(scans, (str, bytes, os.PathLike)) or not isinstance(scans, Iterable):
        raise ArgumentError(
            f"{where}: scans must be a sequence of Scan (read a file with read_scans "
            f"first), got {type(scans).__name__}"
        )
    return scans


def _relative(poses: np.ndarray, j: int) -> np.ndarray:
    """Position (m) of pose ``j`` in the frame of each of ``poses[: j + 1]`` (rows ``x, y,
    theta``), ``(j + 1, 2)``."""
    a = poses[: j + 1]
    d = poses[j, :2] - a[:, :2]
    c, s = np.cos(a[:, 2]), np.sin(a[:, 2])
    return np.stack([c * d[:, 0] + s * d[:, 1], c * d[:, 1] - s * d[:, 0]], axis=1)


def _rotated(cov: np.ndarray | None, theta: float) -> np.ndarray | None:
    """A ``(2, 2)`` covariance expressed in a frame turned by ``-theta`` (``R cov R^T``,
    ``R`` the rotation by ``theta``): from a scan's frame to the world's with that scan's
    heading, back with its negative."""
    if cov is None:
        return None
    R = rotation_matrix(theta)
    return R @ cov @ R.T


def _ts(scans: Sequence[Scan], j: int) -> float | None:
    return scans[j].timestamp if j >= 0 else None


def map_scans(
    scans: Sequence[Scan],
    *,
    use_odometry: bool | None = None,
    config: MapConfig | None = None,
    progress: Progress | None = None,
    workers: int = 1,
) -> MapResult:
    """Map a whole log: the pose of every scan in the frame of scan 0.

    Parameters
    ----------
    scans : sequence of Scan
        One sensor's, in recording order (of a CARMEN log with a front and a rear laser,
        ``read_scans(path, laser="main")`` reads the front one's).
    use_odometry : bool, optional
        None (default): use the odometry when at least 95 % of the scans carry it
        (:func:`choose_odometry`). False: from the scans alone (constant-velocity prior),
        the paper's point. True: use it where present.
    config : MapConfig, optional
    progress : callable (done, total, closures), optional
        Called every 50 scans.
    workers : int
        Processes at work: 1 (default) verifies the loop candidates (and local matches) in
        this process; N > 1 verifies them on N - 1 forked local processes while this one
        goes on with the front end (:mod:`scanclique.mapping.parallel`; one per core). The
        result is the same, pose for pose, for every value.

    Returns
    -------
    MapResult
        No scans give an empty result (no poses).

    Raises
    ------
    ArgumentError
        If ``scans`` is not an iterable of scans (None, a number, a path),
        ``use_odometry`` not True, False or None, or ``progress`` not a function.
    ConfigError
        If ``config`` is not a :class:`MapConfig` (a ``MatchConfig`` goes in its
        ``match`` field), or ``workers`` is not an integer from 1 to
        :func:`scanclique._workers.max_workers` (4 per core, at least 64).
    ScanError
        If one of them is not a :class:`~scanclique.scan.Scan`.

    Examples
    --------
    >>> import numpy as np
    >>> from scanclique.sim import simulate_pair
    >>> pair = simulate_pair(np.random.default_rng(0))
    >>> r = map_scans([pair.scan_a, pair.scan_b], use_odometry=False)
    >>> len(r.poses), r.placed_by[0]
    (2, 'first')
    """
    require_config("map_scans: ", config, MapConfig)
    cfg = config or MapConfig()
    check_workers("map_scans: workers", workers)
    require_flag("map_scans: ", use_odometry=use_odometry)
    require_callable("map_scans: ", progress=progress)
    scans = list(check_iterable_of_scans("map_scans", scans))
    for k, s in enumerate(scans):
        if not isinstance(s, Scan):
            raise ScanError(f"map_scans: scans[{k}] is a {type(s).__name__}, not a Scan")
    t0 = time.perf_counter()
    if not scans:
        covs = () if cfg.back_end.covariances else None
        return MapResult((), (), {}, (), (), (), (), False, {"total": 0.0}, cfg, covs)
    use_odometry, aside = choose_odometry(scans, use_odometry, cfg)
    cfg = fit_scanner(scans, cfg)
    blind = bool(use_odometry) and not odometry_sees_reversing(scans)
    if blind:
        log.info("the odometry never moves backwards: a match it rejects is tried reversed")
    timing, velocities, t = "given", None, time.perf_counter()
    swept = cfg.front_end.deskew and any(s.beam_times is not None for s in scans)
    if swept:  # (before the mapper: one at a time)
        timing, velocities = _sweeps(scans, cfg, bool(use_odometry))
    t = time.perf_counter() - t
    m = _Mapper(bool(use_odometry), blind, cfg, workers)
    m.timing, m.velocities = timing, velocities
    if swept:
        m.seconds["sweeps"] = t
    try:
        m.run(scans, progress)
    finally:
        m.verifier.close()
    result = m.result(t0)
    warn_unmatched(result)
    warn_time_order(scans)
    if aside is not None:
        return replace(result, odometry_scale=aside)
    return check_odometry(scans, result) if use_odometry else result


def fit_scanner(scans: Sequence[Scan], cfg: MapConfig) -> MapConfig:
    """``cfg`` with its matcher's clustering fitted to the scanner of ``scans``
    (:func:`~scanclique.features.for_scanner`: lost returns bridged, the range term
    widened to the range noise), and its loop closures verified without the edges where
    a wall only leaves the reach when the scanner meets it (``LoopConfig.reach_edges``
    off, :func:`~scanclique.features.meets_reach`), when ``front_end.fit_scanner`` is set;
    else ``cfg``."""
    if not cfg.front_end.fit_scanner:
        return cfg
    match = for_scanner(cfg.match, scans)
    out = cfg if match is cfg.match else replace(cfg, match=match)
    if (
        cfg.loops.reach_edges
        and match.features.reach_edges
        and meets_reach(scans, match.clustering)
    ):
        out = replace(out, loops=replace(cfg.loops, reach_edges=False))
    return out


def loop_match(cfg: MapConfig) -> MatchConfig | None:
    """The matcher configuration loop closures are verified with when it is not the
    front end's: ``cfg.match`` without the edges where a wall only leaves the reach
    (``LoopConfig.reach_edges`` off while the features have them); else None."""
    f = cfg.match.features
    if cfg.loops.reach_edges or not f.reach_edges:
        return None
    return replace(cfg.match, features=replace(f, reach_edges=False))


def _sweeps(scans: Sequence[Scan], cfg: MapConfig, use_odometry: bool):
    """The timing of the scans' beam times (:func:`~.sweep.sweep_timing`, on the
    odometry or a first pass of the front end) and, without odometry, each sweep's
    velocity (:func:`sweep_velocities`, again under that timing when it is not
    ``"given"``): ``(timing, velocities or None)``. A log that does not tell is read as
    REP 117 gives its times."""
    from .sweep import sweep_timing

    chain = None if use_odometry else _first_pass(scans, cfg, "given")
    if chain is None:
        timing, scores, pairs = sweep_timing(scans, lambda i: scans[i].odometry, cfg.match)
    else:
        log.info("the sweeps' velocities: a first pass of the front end (no odometry)")
        timing, scores, pairs = sweep_timing(scans, chain.__getitem__, cfg.match)
    _log_timing(timing, scores, pairs)
    timing = timing or "given"
    if chain is None:
        return timing, None
    if timing not in ("given", "none"):
        chain = _first_pass(scans, cfg, timing)
    return timing, _along(scans, chain, timing)


def _log_timing(timing: str | None, scores: dict, pairs: int) -> None:
    """Say how the beam times are read: warned when not as REP 117 gives them."""
    about = ", ".join(f"{k} {v:.3f} / {d:.2f} deg" for k, (v, d) in scores.items())
    if timing is None:
        log.info(
            "the scans do not tell how their beam times run (%d turning scans: %s): read as "
            "REP 117 gives them", pairs, about,
        )  # fmt: skip
    elif timing != "given":
        log.warning(
            "the scans' beam times agree with the motion best read %r, not as REP 117 gives "
            "them (over %d turning scans, mean raw-scan score / turn from the motion: %s): "
            "the driver stored or stamped its sweep otherwise; read so",
            timing, pairs, about,
        )  # fmt: skip
    else:
        log.info("the scans' beam times read as given (%d turning scans: %s)", pairs, about)


def _first_pass(scans: Sequence[Scan], config: MapConfig, timing: str) -> list:
    """The chain poses of a first pass of the front end alone (loops off), the beam times
    read as ``timing`` and de-skewed at the estimate's velocity over
    ``FrontEndConfig.deskew_window``."""
    first = replace(config, loops=replace(config.loops, enabled=False))
    m = _Mapper(False, False, first, 1)
    m.timing = timing
    try:
        for s in scans:
            m.add_scan(s)
    finally:
        m.verifier.close()
    return list(m.chain)


def sweep_velocities(scans: Sequence[Scan], config: MapConfig, timing: str = "given") -> list:
    """Without odometry, the velocity of each scan's sweep (:func:`~scanclique.scan.deskew`)
    from a first pass of the front end alone (loops off, the skew taken out at the
    estimate's velocity over ``FrontEndConfig.deskew_window``): its chain's step to the
    next scan, the sweep's own motion (from the scan before for the last; None where
    neither is known). The second pass, :func:`map_scans` itself, de-skews with these: on
    the simulated 360 degree lidars without odometry (``benchmarks/mapping_sensors.py``,
    ``rplidar-swept`` and ``lds-swept``, seeds 0-3) the window's lagging velocity gave
    0.327 and 0.724 m, the true velocities 0.025 and 0.284 m. ``timing``: how the beam
    times are read (:func:`scanclique.scan.retime`)."""
    return _along(scans, _first_pass(scans, config, timing), timing)


def _along(scans: Sequence[Scan], chain: list, timing: str) -> list:
    """Each scan's sweep velocity along ``chain`` (its beam times read as ``timing``)."""
    return [
        sweep_velocity_of(scans, j, chain.__getitem__, measured_before(retime(s, timing)))
        for j, s in enumerate(scans)
    ]


#: :func:`map_scans` warns when more than this fraction of a log's scans (10 or more) were
#: placed by their prior (odometry or constant velocity), not by matching
UNMATCHED_WARNING = 0.5


def warn_unmatched(result: MapResult) -> None:
    """Warn when most scans of ``result`` (more than :data:`UNMATCHED_WARNING` of 10 or
    more) were placed by their prior, not matched, with the commonest reason: a map of
    dead reckoning is not a map of the scans (ranges in millimetres all lie beyond
    ``range_max``: every scan has no features, and the map was the odometry, silently)."""
    n = len(result.placed_by)
    prior = [k for k, p in enumerate(result.placed_by) if p in (ODOMETRY, CONSTANT_VELOCITY)]
    if n < 10 or len(prior) <= UNMATCHED_WARNING * n:
        return
    why, count = Counter(result.reasons.get(k, "") for k in prior).most_common(1)[0]
    log.warning(
        "%d of %d scans were placed by their prior (odometry or constant velocity), not by "
        "matching; the commonest reason (%d scans): %s",
        len(prior), n, count, why,
    )  # fmt: skip


def warn_time_order(scans: Sequence[Scan]) -> int:
    """Warn when a scan's timestamp is earlier than that of the scan before it, and return
    how many are. The scans are mapped in the order given (a log's order, the sensor's),
    and ``trajectory.tum`` keeps that order: a tool that pairs its poses by time (with a
    reference, or with another sensor) expects increasing times. Equal timestamps and
    scans without one are not counted."""
    t = np.array([np.nan if s.timestamp is None else s.timestamp for s in scans], float)
    step = np.diff(t)
    back = np.flatnonzero(step < 0)  # a NaN on either side compares False
    if len(back):
        k = int(back[0]) + 1
        log.warning(
            "%d scans have a timestamp earlier than the scan before them, by up to %.3g s "
            "(the first: scan %d at %.6f s, after %.6f s); they are mapped in the order "
            "given, and trajectory.tum keeps it (evo_traj --full_check calls that 'not "
            "ascending')",
            len(back), -step[back].min(), k, t[k], t[k - 1],
        )  # fmt: skip
    return len(back)


#: :func:`map_scans` warns when the odometry's steps point more than this many degrees away
#: from the scans' (median over at least :data:`ODOMETRY_CHECK_STEPS` steps)
ODOMETRY_CHECK_DEGREES = 10.0
ODOMETRY_CHECK_STEPS = 20
#: ... or when their median length is outside this range of the scans' (as a ratio);
#: with ``use_odometry=None`` it samples that before mapping and sets such odometry aside
ODOMETRY_SCALE_RANGE = (0.5, 2.0)


#: ``use_odometry=None`` maps with the odometry when at least this share of the scans
#: carry it: a bag's first or last scans can lie a few milliseconds outside its odometry's
#: time span (they are placed as ``use_odometry=True`` places them, by the motion model)
ODOMETRY_MIN_SHARE = 0.95


def choose_odometry(
    scans: Sequence[Scan], use_odometry: bool | None, cfg: MapConfig
) -> tuple[bool, OdometryScale | None]:
    """Whether to map ``scans`` with their odometry, as :func:`map_scans` decides it:
    ``(use, aside)``. ``use_odometry`` True or False is kept (``aside`` None); None uses
    the odometry when at least :data:`ODOMETRY_MIN_SHARE` of the scans carry it (the
    others warned) and a sample of matched consecutive pairs says it moves as the scans
    do; else ``aside`` is that sample's :class:`OdometryScale` (logged as a warning) and
    the map is made from the scans alone."""
    if use_odometry is not None:
        return bool(use_odometry), None
    have = sum(s.odometry is not None for s in scans)
    if have < len(scans):
        first = next(k for k, s in enumerate(scans) if s.odometry is None)
        enough = have >= ODOMETRY_MIN_SHARE * len(scans)
        if have:
            log.warning(
                "%d of %d scans carry no odometry (the first: scan %d, %s): %s",
                len(scans) - have, len(scans), first, scans[first].source or "unnamed",
                "they are placed by the motion model" if enough else "mapping from the "
                "scans alone (use_odometry=True uses it where there is any)",
            )  # fmt: skip
        if not enough:
            return False, None
    aside = _odometry_aside(scans, cfg) if len(scans) > 1 else None
    return aside is None, aside


def _odometry_aside(scans, cfg: MapConfig) -> OdometryScale | None:
    """Before mapping with the scans' odometry (``use_odometry=None``): the
    :class:`OdometryScale` of a sample of matched consecutive pairs
    (:func:`~scanclique.mapping.frontend.sample_odometry_scale`) when it says the odometry
    does not move as the scans do (logged: the map is then made from the scans alone),
    else None. A log converted with zeros for its odometry, or whose odometry froze, was
    otherwise mapped with it: the first 600 scans of intel-raw 0.0845 m of error over 10 scans
    against 0.0285 m from the scans alone; one in millimetres stopped GTSAM."""
    scale, n = sample_odometry_scale(scans, cfg.match)
    check = OdometryScale(scale, n)
    if not check.scaled:
        return None
    log.warning(
        "the scans' odometry moves %.3g times as far as the scans do (median of %d "
        "sampled consecutive pairs; right odometry gives about 1): is it all zeros, "
        "frozen, or not in metres? Mapping from the scans alone (use_odometry=True, "
        "--odometry, uses it anyway).",
        scale, n,
    )  # fmt: skip
    return check


def check_odometry(scans, result: MapResult) -> MapResult:
    """``result`` with its :attr:`~MapResult.odometry_check` (:func:`odometry_turned` of
    ``scans`` against its poses) and :attr:`~MapResult.odometry_scale`, warning when the
    odometry's steps point more than :data:`ODOMETRY_CHECK_DEGREES` away from the scans',
    or move less than half or more than twice as far: what a map made with odometry
    says of it."""
    steps = matched_steps(scans, result.poses, result.placed_by)
    scale = OdometryScale(*step_scale(steps))
    if scale.scaled:
        log.warning(
            "the odometry moves %.3g times as far as the scans (median of %d steps; right "
            "odometry gives about 1): is it frozen, or not in metres? use_odometry=False "
            "(--no-odometry) maps from the scans alone",
            scale.median_scale, scale.steps,
        )  # fmt: skip
    check = OdometryCheck(*step_turn(steps))
    if check.turned:
        log.warning(
            "the odometry's steps point %.0f deg away from the scans' (median of %d steps): "
            "is the laser mounted turned on the robot? Scan.odometry must be the laser's "
            "pose (read_bag applies a bag's static transforms); use_odometry=False "
            "(--no-odometry) maps from the scans alone",
            check.median_turn_deg, check.steps,
        )  # fmt: skip
    return replace(result, odometry_check=check, odometry_scale=scale)


def matched_steps(scans, poses, placed_by) -> list[tuple[Pose2, Pose2]]:
    """``(mapped step, odometry step)`` increments of each scan placed by matching
    (``placed_by`` ``"match"`` or ``"icp"``) from the scan before, both with poses and
    odometry."""
    out = []
    for k in range(1, len(scans)):
        a, b, o0, o1 = poses[k - 1], poses[k], scans[k - 1].odometry, scans[k].odometry
        if placed_by[k] in (MATCH, ICP) and None not in (a, b, o0, o1):
            out.append((a.inverse() @ b, o0.inverse() @ o1))
    return out


def odometry_turned(scans, poses, placed_by, min_step: float = 0.05) -> tuple[float, int]:
    """How far the odometry's steps point from the scans': the median (degrees) of the
    angle from each odometry step's translation to the mapped one, over consecutive scans
    placed by matching (``placed_by`` ``"match"`` or ``"icp"``) that both move at least
    ``min_step`` m, and how many such steps there were (0 and 0 when none).

    A laser mounted turned by ``phi`` on a robot whose odometry is given as the laser's
    shows here as about ``-phi``; right odometry as about 0 (its own noise aside).

    >>> from scanclique.geometry import Pose2
    >>> from scanclique.scan import Scan
    >>> odo = [Pose2(0.1 * k, 0.0, 0.0) for k in range(4)]
    >>> scans = [Scan([1.0], [0.0], odometry=p) for p in odo]
    >>> back = [Pose2(-0.1 * k, 0.0, 0.0) for k in range(4)]   # the scans saw it go back
    >>> odometry_turned(scans, back, ["first", "match", "match", "icp"])
    (180.0, 3)
    """
    return step_turn(matched_steps(scans, poses, placed_by), min_step)


def step_turn(steps, min_step: float = 0.05) -> tuple[float, int]:
    """:func:`odometry_turned` of ``steps``, :func:`matched_steps`' pairs."""
    d = [
        math.atan2(s.y, s.x) - math.atan2(o.y, o.x)
        for s, o in steps
        if math.hypot(s.x, s.y) >= min_step and math.hypot(o.x, o.y) >= min_step
    ]
    if not d:
        return 0.0, 0
    c = np.exp(1j * np.asarray(d))
    mean = np.angle(np.mean(c))  # the median about the circular mean
    turn = mean + float(np.median(np.angle(c * np.exp(-1j * mean))))
    deg = math.degrees(math.atan2(math.sin(turn), math.cos(turn)))
    return round(deg, 6) + 0.0, len(d)
