"""Scan-to-scan matching: the whole pipeline of the paper on two scans (stages 1–9).

>>> import scanclique as sc
>>> pair = sc.sim.simulate_pair(np.random.default_rng(3))
>>> m = sc.match_scans(pair.scan_a, pair.scan_b)
>>> t_err, r_err = m.pose.distance_to(pair.pose_a_b)
>>> bool(t_err < 0.1 and r_err < 0.02)
True
"""

from __future__ import annotations

import logging
import time
from dataclasses import dataclass, field, replace
from typing import NamedTuple

import numpy as np

from . import clique as _clique
from ._kernels.codes import Option
from ._lazy import kernel_module
from .config import MatchConfig, a_or_an, require_config
from .correspondence import CorrespondenceGraph, correspondence_graph
from .errors import ConfigError, ScanError
from .features import Features, extract_features
from .geometry import Pose2
from .graph import NODE_KIND_NAMES, FeatureGraph, feature_graph
from .pose import (
    PoseEstimate,
    covariance_from_information,
    estimate_pose_lsq_pairs,
    estimate_pose_median,
    mapped_features,
    pair_consistent_pairs,
    points_first,
)
from .refine import ReferenceCloud, free_space_conflicts, icp_point_to_line, reference_cloud
from .scan import Scan

_K = kernel_module("scanclique._match_kernels")

__all__ = [
    "FeaturePair",
    "Hypothesis",
    "PreparedScan",
    "ScanMatch",
    "prepare_scan",
    "prepared_again",
    "pose_score",
    "conflict_fraction",
    "estimate_clique_pose",
    "search_pose",
    "match_prepared",
    "match_scans",
    "distinct_poses",
    "near_rival",
    "warm_up",
    "warm_up_seconds",
]

log = logging.getLogger(__name__)

_DEFAULT = MatchConfig()

#: the stages timed in ``ScanMatch.seconds``: ``pose`` is the quick pose and score of every
#: clique, ``refine`` the full estimate of the best few, their ICP and rescoring
#: ``search`` the raw-scan pose search of weak matches (``refine.search``)
STAGES = ("features", "graph", "correspondence", "clique", "pose", "refine", "search")


class FeaturePair(NamedTuple):
    """One mapped feature: ``kind`` (``"line"``, ``"corner"``, ``"edge_cw"``, ...), and the
    feature's index in scan A's and scan B's group of that geometry (``Features.points_*``
    for point kinds, ``Features.lines_*`` for lines)."""

    kind: str
    a: int
    b: int


@dataclass(frozen=True, slots=True, eq=False)
class Hypothesis:
    """One association hypothesis: a clique of the correspondence graph and its pose.

    ``node_pairs`` are (node of A, node of B) in feature-graph order (points, then lines);
    ``score`` is the raw-scan agreement of ``pose`` (:func:`pose_score`; for hypotheses
    ranked below the best ``refine.quick_exact * refine.candidates`` it is measured on every
    third sample point only). ``estimate`` is the
    full weighted estimate with covariance, computed for the best few hypotheses only (the
    others carry the closed-form pose used to rank them); ``refined`` says whether ``pose``
    was refined by ICP on the raw points. ``origin`` is ``"clique"`` for the hypotheses of
    the clique search (paper §5.3) and ``"search"`` for the one found by
    :func:`search_pose`, whose ``node_pairs`` are the largest set of mapped features that
    agree with its pose.
    """

    node_pairs: np.ndarray
    clique_size: int
    pose: Pose2
    score: float
    estimate: PoseEstimate | None = None
    refined: bool = False
    origin: str = "clique"


@dataclass(frozen=True, slots=True, eq=False)
class PreparedScan:
    """What the pipeline derives from one scan, reusable across many matches.

    ``points`` are the scan's valid points (sensor frame); ``cloud`` at most
    ``CLOUD_MAX_POINTS`` of them, evenly spaced in beam order; ``sample`` at most
    ``refine.sample_points`` of them, evenly spaced in beam order, for scoring and ICP;
    ``free`` the free range along each beam (:func:`scanclique.refine.free_ranges`);
    ``angle_index`` the search index of the beam angles
    (:func:`scanclique.refine.search_index`); ``config`` the configuration it was
    prepared with (:func:`match_prepared` refuses to match two prepared scans, or a
    configuration, whose :meth:`~scanclique.config.MatchConfig.preparation` differ)."""

    scan: Scan
    features: Features
    graph: FeatureGraph
    cloud: ReferenceCloud
    points: np.ndarray
    sample: np.ndarray
    free: np.ndarray
    angle_index: tuple
    seconds: dict = field(default_factory=dict)
    config: MatchConfig = field(default_factory=MatchConfig)


@dataclass(frozen=True, slots=True, eq=False)
class ScanMatch:
    """The result of matching scan B against scan A.

    Attributes
    ----------
    pose : Pose2 or None
        ``T_a_b``, the pose of B's sensor frame in A's frame: maps points of B into A
        (``R(theta) p_b + (x, y)``). None when no pose could be determined; ``reason``
        says why.
    covariance : ndarray (3, 3) or None
        Covariance of ``(x, y, theta)`` of the feature-based estimate (paper §7's
        precision of the constellation of mapped features).
    pairs : tuple of FeaturePair
        The mapping: the pairs of the chosen clique that agree with ``pose`` (within the
        correspondence tolerances), with feature kinds.
    clique_size : int
        Size of the chosen clique (0 when there was none). Usually ``omega``; smaller when
        the raw scans preferred another hypothesis to every maximum clique.
    omega : int
        Size of the maximum clique of the correspondence graph (proven when ``optimal``).
    optimal : bool
        True when the clique search proved the clique maximum within its time limit.
    ambiguous : bool
        True when a distinct hypothesis (another maximum or near-maximum clique giving a
        different pose) agrees with the raw scans almost as well as the chosen one.
    hypotheses : tuple of Hypothesis
        All hypotheses, best first; ``hypotheses[1]`` is the runner-up.
    score : float
        Raw-scan agreement of ``pose`` (:func:`pose_score`: the fraction of B's points near
        A's points, less the points that fall in the other scan's free space).
    refined : bool
        Whether ``pose`` was refined by ICP on the raw points.
    reason : str or None
        Why there is no pose (or a note on a weak one).
    features_a, features_b : Features
    n_correspondence_nodes, n_correspondence_edges : int
    seconds : dict
        Time per stage (``features``, ``graph``, ``correspondence``, ``clique``, ``pose``,
        ``refine``, ``search``) in seconds.
    config : MatchConfig
        The configuration the match was made with (validation reads its tolerances and
        thresholds from it).
    stopped : str or None
        ``"node_limit"`` when the clique search spent ``clique.node_limit`` search nodes
        before it had found every hypothesis (the same on every machine), ``"time_limit"``
        when the outer guard ``clique.time_limit`` stopped it (then the result may depend
        on the machine's speed); None when it ran to its end.
    clique_nodes : int
        Search nodes the clique stage used.
    """

    pose: Pose2 | None
    covariance: np.ndarray | None
    pairs: tuple
    clique_size: int
    omega: int
    optimal: bool
    ambiguous: bool
    hypotheses: tuple
    score: float
    refined: bool
    reason: str | None
    features_a: Features
    features_b: Features
    n_correspondence_nodes: int
    n_correspondence_edges: int
    seconds: dict
    config: MatchConfig = field(default_factory=MatchConfig)
    stopped: str | None = None
    clique_nodes: int = 0

    @property
    def success(self) -> bool:
        """True when a pose was determined."""
        return self.pose is not None

    @property
    def runner_up(self) -> Hypothesis | None:
        return self.hypotheses[1] if len(self.hypotheses) > 1 else None

    def to_dict(self) -> dict:
        """A JSON-ready summary."""
        return {
            "pose": None
            if self.pose is None
            else {"x": self.pose.x, "y": self.pose.y, "theta": self.pose.theta},
            "covariance": None
            if self.covariance is None
            else np.where(np.isfinite(self.covariance), self.covariance, None).tolist(),
            "pairs": [{"kind": p.kind, "a": p.a, "b": p.b} for p in self.pairs],
            "clique_size": self.clique_size,
            "omega": self.omega,
            "optimal": self.optimal,
            "ambiguous": self.ambiguous,
            "score": self.score,
            "refined": self.refined,
            "reason": self.reason,
            "stopped": self.stopped,
            "clique_nodes": self.clique_nodes,
            "n_features_a": len(self.features_a),
            "n_features_b": len(self.features_b),
            "n_correspondence_nodes": self.n_correspondence_nodes,
            "n_correspondence_edges": self.n_correspondence_edges,
            "hypotheses": [
                {
                    "x": h.pose.x,
                    "y": h.pose.y,
                    "theta": h.pose.theta,
                    "score": h.score,
                    "clique_size": h.clique_size,
                    "origin": h.origin,
                }
                for h in self.hypotheses
            ],
            "seconds": dict(self.seconds),
        }


def prepare_scan(scan: Scan, config: MatchConfig | None = None) -> PreparedScan:
    """Features (paper §4), feature graph (§5.1) and the raw-point cloud of one scan,
    recorded with the configuration that made them (``PreparedScan.config``)."""
    _check_args("prepare_scan", config, scan=scan)
    cfg = config or _DEFAULT
    warm_up()  # kernel loading never counts in PreparedScan.seconds
    feats, graph, seconds = _features_and_graph(scan, cfg)
    t = time.perf_counter()
    # the raw-point cloud for scoring and ICP: at most CLOUD_MAX_POINTS, evenly spaced in
    # beam order (a million-beam scan keeps points millimetres apart; the score and the
    # ICP need no more, and their cost stays bounded)
    pts, cloud_pts, sample, free, angle_index = _K.scan_arrays(
        scan.ranges, scan.angles, scan.valid, CLOUD_MAX_POINTS, cfg.refine.sample_points
    )
    cloud = reference_cloud(cloud_pts)
    seconds["graph"] += time.perf_counter() - t
    return PreparedScan(scan, feats, graph, cloud, pts, sample, free, angle_index, seconds, cfg)


def _features_and_graph(scan: Scan, cfg: MatchConfig):
    """The features (paper §4) and feature graph (§5.1) of ``scan`` under ``cfg``, with
    the seconds each took (``{"features": ..., "graph": ...}``)."""
    t0 = time.perf_counter()
    feats = extract_features(scan, cfg.features, cfg.clustering)
    t1 = time.perf_counter()
    graph = feature_graph(feats, cfg.correspondence, cfg.features)
    return feats, graph, {"features": t1 - t0, "graph": time.perf_counter() - t1}


def prepared_again(p: PreparedScan, config: MatchConfig | None) -> PreparedScan:
    """``p`` with its features (paper §4) and feature graph (§5.1) made again under
    ``config``, its raw-point arrays (cloud, sample, free ranges) kept: the same as
    :func:`prepare_scan` of ``p.scan`` under ``config`` (None: the defaults) at the cost of
    the features alone. ``config`` must sample the raw points as ``p``'s did
    (``refine.sample_points``); a :class:`~scanclique.errors.ConfigError` otherwise."""
    _check_args("prepared_again", config, p=p, cls=PreparedScan)
    config = config or _DEFAULT
    if config.refine.sample_points != p.config.refine.sample_points:
        raise ConfigError(
            f"prepared_again: config samples {config.refine.sample_points} raw points, the "
            f"prepared scan {p.config.refine.sample_points}; prepare the scan again instead"
        )
    feats, graph, seconds = _features_and_graph(p.scan, config)
    return replace(p, features=feats, graph=graph, seconds=seconds, config=config)


#: the raw-point cloud of a prepared scan keeps at most this many points (evenly spaced in
#: beam order), so that its bearing windows stay small and scoring and ICP stay bounded
CLOUD_MAX_POINTS = 4096


def pose_score(
    pa: PreparedScan, pb: PreparedScan, pose: Pose2, config: MatchConfig | None = None
) -> float:
    """How well the raw scans agree under ``pose`` (maps B into A), symmetrically: the mean
    of the fraction of B's sampled points within ``refine.inlier_distance`` of A's points
    and the same for A's points against B's, minus ``refine.conflict_weight`` times the
    mean fraction of points lying in the other scan's observed free space."""
    cfg = config or _DEFAULT
    return _score(pa, pb, pose.x, pose.y, pose.theta, cfg)


def conflict_fraction(
    place: PreparedScan, query: PreparedScan, pose: Pose2, config: MatchConfig | None = None
) -> float:
    """How much of either scan lies where the other saw through, under ``pose`` (maps the
    query into the place's frame): the larger of the fraction of the query's points in the
    place's observed free space and of the place's points in the query's
    (:func:`scanclique.refine.free_space_conflicts`, with ``refine.conflict_margin`` and
    ``refine.conflict_ratio``), in ``[0, 1]``.

    A look-alike place (a twin room, a corridor seen from its other end) lines its walls
    up with the query's, but a cupboard, a door or a pillar of one stands where the other
    saw free floor; the same place conflicts only where people or doors moved. The raw-scan
    score (:func:`scanclique.match.pose_score`) averages the two directions and weighs
    conflicts against agreement; the larger one, read on its own, separates revisits from
    twins better (``benchmarks/places.py --calibrate``).
    """
    r = (config or _DEFAULT).refine
    m, k = r.conflict_margin, r.conflict_ratio
    c_query = free_space_conflicts(place.scan, query.points, m, k, pose=pose)
    c_place = free_space_conflicts(query.scan, place.points, m, k, pose=pose.inverse())
    return float(max(c_query, c_place))


def _feature_arrays(f: Features):
    return _K.FeatureArrays(
        int(f.n_points), f.points_xy, f.points_cov, f.lines_rho_alpha, f.lines_cov
    )


def _cloud_arrays(p: PreparedScan):
    c = p.cloud
    return _K.CloudArrays(c.index, c.points, c.normals, p.angle_index, p.free, p.sample)


def _scan_args(p: PreparedScan) -> tuple:
    return (p.cloud.index, p.cloud.points, p.angle_index, p.free, p.sample)


def _score(pa: PreparedScan, pb: PreparedScan, x: float, y: float, th: float, cfg) -> float:
    """:func:`pose_score` of the pose ``(x, y, th)``, compiled."""
    r = cfg.refine
    return float(
        _K.pose_score(
            *_scan_args(pa),
            *_scan_args(pb),
            float(x),
            float(y),
            float(th),
            r.inlier_distance,
            r.conflict_weight,
            r.conflict_margin,
            r.conflict_ratio,
        )
    )


def _scores(pa, pb, poses, ok, sizes, exact_best, cfg) -> np.ndarray:
    """:func:`pose_score` of each of ``poses`` (n, 3) with ``ok`` set (``-inf`` for the
    others), compiled in one batch: coarse (every third sample point) except for the
    ``exact_best`` best by rank, score plus ``refine.size_weight`` per clique vertex
    (``sizes``); see :func:`scanclique._match_kernels.score_batch`."""
    n = len(poses)
    r = cfg.refine
    scores = np.empty(n)
    exact = np.empty(n, dtype=bool)
    _K.score_batch(
        poses, ok, np.asarray(sizes, dtype=float), r.size_weight, exact_best,
        *_scan_args(pa), *_scan_args(pb), r.inlier_distance,
        r.conflict_weight, r.conflict_margin, r.conflict_ratio, scores, exact,
    )  # fmt: skip
    return scores


def _node_pairs_to_feature_pairs(
    node_pairs: np.ndarray, ga: FeatureGraph, gb: FeatureGraph
) -> tuple:
    out = []
    for a, b in node_pairs:
        kind = NODE_KIND_NAMES[int(ga.kinds[a])]
        if a >= ga.n_points:
            out.append(FeaturePair(kind, int(a - ga.n_points), int(b - gb.n_points)))
        else:
            out.append(FeaturePair(kind, int(a), int(b)))
    return tuple(out)


def estimate_clique_pose(
    fa: Features, fb: Features, node_pairs: np.ndarray, cfg: MatchConfig
) -> PoseEstimate | None:
    """Pose of one clique of the correspondence graph (paper §6): ``node_pairs`` (K, 2) of
    (node of A, node of B) in feature-graph order; the paper's median method or weighted
    least squares with one round of outlier rejection (pairs whose Mahalanobis residual
    exceeds ``pose.outlier_mahalanobis`` are dropped). The pose maps B's frame into A's;
    None when the pairs cannot fix one."""
    if cfg.pose.method == "median":
        return estimate_pose_median(mapped_features(fa, fb, node_pairs))
    est = estimate_pose_lsq_pairs(fa, fb, node_pairs)
    if est is None:
        return None
    bad = est.residuals > cfg.pose.outlier_mahalanobis
    if bad.any() and (~bad).sum() >= cfg.pose.min_pairs:
        ordered = points_first(node_pairs, fa.n_points)
        return estimate_pose_lsq_pairs(fa, fb, ordered[~bad], initial=est.pose)
    return est


_STOPPED = {1: "time_limit", 4: "node_limit"}  # codes.Status of the hypothesis search


def _hypothesis_cliques(cg: CorrespondenceGraph, cfg: MatchConfig, t0: float):
    """The cliques that become hypotheses (see :func:`match_prepared`, step 2), one
    compiled call: ``(data, indptr, omega, optimal, stopped, nodes)``, clique ``i`` being
    the correspondence nodes ``data[indptr[i]:indptr[i + 1]]`` (distinct, at least
    ``pose.min_pairs``); ``stopped`` is ``"node_limit"`` or ``"time_limit"`` when a budget
    cut the search short, else None. ``clique.node_limit`` decides the result;
    ``clique.time_limit`` (seconds from ``t0``) is an outer guard."""
    cc = cfg.clique
    bits = _clique.bitsets_from_adjacency(cg.adjacency)
    data, indptr, _, omega, optimal, _, stop, nodes = _K.hypothesis_cliques(
        bits,
        cg.n_nodes,
        cc.max_hypotheses,
        cc.peel,
        cc.per_vertex,
        cfg.pose.min_pairs,
        int(cc.node_limit),
        float(t0) + float(cc.time_limit),
        int(Option.DEFAULT),
    )
    return data, indptr, int(omega), bool(optimal), _STOPPED.get(int(stop)), int(nodes)


def _rank(h: Hypothesis, size_weight: float) -> float:
    """Ranking key of a hypothesis: raw-scan score plus ``size_weight`` per mapped feature
    (the clique's size is evidence too: between two poses that explain the scans about
    equally well, the one more features agree on wins)."""
    return h.score + size_weight * h.clique_size


def distinct_poses(p: Pose2, q: Pose2, config: MatchConfig | None = None) -> bool:
    """Whether two hypotheses are distinct poses: more than ``refine.distinct_metres``
    apart in translation or ``refine.distinct_radians`` in rotation (the one rule the
    matcher's ranking, its ambiguity flag and validation's rivals share)."""
    r = (config or _DEFAULT).refine
    t, a = p.distance_to(q)
    return t > r.distinct_metres or a > r.distinct_radians


def near_rival(h: Hypothesis, best: Hypothesis, config: MatchConfig | None = None) -> bool:
    """The ambiguity rule (:func:`match_prepared`, step 7): ``h`` explains the raw scans
    nearly as well as ``best`` (a score at least ``refine.ambiguous_score`` of it) with a
    clique at most one smaller. A match is ambiguous when a distinct hypothesis
    (:func:`distinct_poses`) is a near rival of its best."""
    r = (config or _DEFAULT).refine
    return h.score >= r.ambiguous_score * best.score and h.clique_size >= best.clique_size - 1


def _why_none(scan: Scan) -> str:
    """What a scan without features lacks, for the match's reason: beams, or valid
    returns (and whether they all lie at or beyond ``range_max``, as ranges in
    millimetres do); empty when it has valid returns (a featureless view)."""
    if scan.n_beams == 0:
        return ": it has no beams"
    if scan.n_valid:
        return ""
    n, far = scan.n_beams, int(scan.no_return.sum())
    if far == n:
        return (
            f": none of its {n} beams returns below range_max ({scan.range_max:g} m); "
            "are its ranges in metres?"
        )
    return f": none of its {n} beams is a valid return ({far} at or beyond range_max)"


def _empty(
    pa: PreparedScan,
    pb: PreparedScan,
    cfg: MatchConfig,
    reason: str,
    seconds: dict,
    n_nodes=0,
    n_edges=0,
    optimal=True,
    omega=0,
    hypotheses=(),
    stopped=None,
    clique_nodes=0,
) -> ScanMatch:
    return ScanMatch(
        pose=None,
        covariance=None,
        pairs=(),
        clique_size=0,
        omega=omega,
        optimal=optimal,
        ambiguous=False,
        hypotheses=tuple(hypotheses),
        score=hypotheses[0].score if hypotheses else 0.0,
        refined=False,
        reason=reason,
        features_a=pa.features,
        features_b=pb.features,
        n_correspondence_nodes=n_nodes,
        n_correspondence_edges=n_edges,
        seconds=seconds,
        config=cfg,
        stopped=stopped,
        clique_nodes=clique_nodes,
    )


def _quick_hypotheses(
    pa: PreparedScan, pb: PreparedScan, flat: np.ndarray, indptr: np.ndarray, cfg: MatchConfig
) -> list[Hypothesis]:
    """A pose per clique and its raw-scan score, best-ranked first: the closed-form pose
    (or the paper's median estimate with ``pose.method="median"``), scored by
    :func:`pose_score`, in compiled batches where the clouds allow. Clique ``i`` is the
    node pairs ``flat[indptr[i]:indptr[i + 1]]``."""
    fa, fb = pa.features, pb.features
    n = len(indptr) - 1
    if n <= 0:
        return []
    flat = np.ascontiguousarray(flat)
    sizes = np.diff(indptr)
    node_pairs = [flat[indptr[i] : indptr[i + 1]] for i in range(n)]
    if cfg.pose.method == "median":
        ests = [estimate_clique_pose(fa, fb, npairs, cfg) for npairs in node_pairs]
        ok = np.array([e is not None for e in ests])
        poses = np.array([e.pose.as_array() if e is not None else np.zeros(3) for e in ests])
    else:
        ests = [None] * n
        poses = np.empty((n, 3))
        ok = np.empty(n, dtype=bool)
        _K.closed_form_batch(
            flat,
            indptr,
            fa.n_points,
            fb.n_points,
            fa.points_xy,
            fb.points_xy,
            fa.lines_rho_alpha,
            fb.lines_rho_alpha,
            poses,
            ok,
        )
    scores = _scores(pa, pb, poses, ok, sizes, cfg.refine.quick_exact * cfg.refine.candidates, cfg)
    rank = scores + cfg.refine.size_weight * sizes
    out = []
    pl, sl, zl = poses.tolist(), scores.tolist(), sizes.tolist()
    for i in np.argsort(-rank, kind="stable").tolist():
        if ok[i]:
            out.append(Hypothesis(node_pairs[i], zl[i], Pose2(*pl[i]), sl[i], ests[i]))
    return out


def _refine_candidates(
    pa: PreparedScan, pb: PreparedScan, distinct: list[Hypothesis], cfg: MatchConfig
) -> list[Hypothesis]:
    """Step 4 of :func:`match_prepared` in one compiled call: for each candidate, the
    weighted least-squares estimate with covariance (:func:`estimate_clique_pose`), its
    score, and (``refine.enabled``) the ICP from it, kept when it scores at least as
    well."""
    fa, fb, r = pa.features, pb.features, cfg.refine
    if not distinct:
        return []
    sizes = [len(h.node_pairs) for h in distinct]
    flat = np.ascontiguousarray(np.concatenate([h.node_pairs for h in distinct]))
    indptr = np.concatenate(([0], np.cumsum(sizes))).astype(np.int64)
    n = len(distinct)
    ok = np.empty(n, dtype=bool)
    x_est, x_icp = np.empty((n, 3)), np.empty((n, 3))
    info = np.empty((n, 3, 3))
    ssr, score_est, score_icp = np.empty(n), np.empty(n), np.empty(n)
    used = np.empty(n, dtype=np.int64)
    maha = np.empty(len(flat))
    _K.refine_candidates(
        flat,
        indptr,
        _feature_arrays(fa),
        _feature_arrays(fb),
        _cloud_arrays(pa),
        _cloud_arrays(pb),
        _K.ScoreParams(
            float(r.inlier_distance),
            float(r.conflict_weight),
            float(r.conflict_margin),
            float(r.conflict_ratio),
        ),
        # the ICP's correspondence distance shrinks to the score's inlier distance
        _K.RefineParams(
            int(cfg.pose.min_pairs),
            float(cfg.pose.outlier_mahalanobis),
            bool(r.enabled),
            int(r.iterations),
            float(r.max_correspondence),
            float(r.inlier_distance),
        ),
        _K.RefineOut(ok, x_est, info, ssr, used, maha, score_est, x_icp, score_icp),
    )
    out = []
    for i, h in enumerate(distinct):
        if not ok[i]:
            continue
        cov, rms, degenerate = covariance_from_information(info[i], ssr[i], int(used[i]))
        res = maha[indptr[i] : indptr[i] + used[i]].copy()
        est = PoseEstimate(Pose2.from_array(x_est[i]), cov, rms, res, degenerate)
        if score_icp[i] >= score_est[i]:
            pose, score, refined = Pose2.from_array(x_icp[i]), float(score_icp[i]), True
        else:
            pose, score, refined = est.pose, float(score_est[i]), False
        out.append(Hypothesis(h.node_pairs, h.clique_size, pose, score, est, refined))
    return out


def _refine_median_candidates(
    pa: PreparedScan, pb: PreparedScan, distinct: list[Hypothesis], cfg: MatchConfig
) -> list[Hypothesis]:
    """Step 4 of :func:`match_prepared` for the paper's median method
    (``pose.method="median"``, :func:`scanclique.pose.estimate_pose_median`): the same
    score and ICP as :func:`_refine_candidates`, one candidate at a time (the compiled
    step computes weighted least-squares estimates only)."""
    full = []
    for h in distinct:
        est = h.estimate
        if est is None:
            est = estimate_clique_pose(pa.features, pb.features, h.node_pairs, cfg)
        if est is None:
            continue
        full.append(
            Hypothesis(
                h.node_pairs, h.clique_size, est.pose, pose_score(pa, pb, est.pose, cfg), est
            )
        )
    if cfg.refine.enabled and len(pb.sample) >= 3:
        for k, h in enumerate(full):
            icp = icp_point_to_line(
                pa.cloud,
                pb.sample,
                h.pose,
                iterations=cfg.refine.iterations,
                max_correspondence=cfg.refine.max_correspondence,
                min_correspondence=cfg.refine.inlier_distance,
            )
            score = pose_score(pa, pb, icp.pose, cfg)
            if score >= h.score:
                full[k] = Hypothesis(
                    h.node_pairs, h.clique_size, icp.pose, score, h.estimate, refined=True
                )
    return full


def search_pose(
    pa: PreparedScan, pb: PreparedScan, config: MatchConfig | None = None
) -> tuple[Pose2, float] | None:
    """The pose of B in A found on the raw scans alone, without features, and its
    :func:`pose_score`; None when the scans give no seed (no surface normals).

    Beyond the paper; used by :func:`match_prepared` when the features explain the raw
    scans poorly (``refine.search_below``). The steps:

    1. rotation seeds: the peaks of the circular cross-correlation of the two scans'
       histograms of surface orientation (the normal angle modulo pi, as in angle-histogram
       matching), each also turned by pi;
    2. translation seeds per rotation: every pair of sample points (every other one of
       A, one of B) votes for the translation that would bring them together, in square
       cells (a Hough transform); the best few cells, each the mean of its votes and its
       neighbours';
    3. every seed is scored, and the best ``refine.search_icp`` are refined by
       point-to-line ICP and scored again; the best-scoring pose is returned.

    The search's sizes are ``refine.search_*`` (:class:`~scanclique.config.RefineConfig`).

    Costs one to two milliseconds on laser scans (``6 x 2`` rotations, ``60 x 120``
    votes each, 36 seeds scored, 4 ICP runs).
    """
    cfg = config or _DEFAULT
    r = cfg.refine
    seeds = _K.search_seeds(
        pa.cloud.normals, pb.cloud.normals,
        np.ascontiguousarray(pa.sample[:: r.search_stride]), pb.sample,
        r.search_bins, r.search_peaks, r.search_cell, r.search_top,
    )  # fmt: skip
    if len(seeds) == 0 or len(pb.sample) < 3:
        return None
    n = len(seeds)
    scores = _scores(pa, pb, seeds, np.ones(n, dtype=bool), np.zeros(n), 0, cfg)
    best = None
    for i in np.argsort(-scores, kind="stable")[: r.search_icp].tolist():
        icp = icp_point_to_line(
            pa.cloud,
            pb.sample,
            Pose2.from_array(seeds[i]),
            iterations=r.iterations,
            max_correspondence=r.max_correspondence,
            min_correspondence=r.inlier_distance,
        )
        score = pose_score(pa, pb, icp.pose, cfg)
        if best is None or score > best[1]:
            best = (icp.pose, score)
    return best


def _searched_hypothesis(
    pa: PreparedScan, pb: PreparedScan, cg: CorrespondenceGraph, cfg: MatchConfig, beat: float
) -> Hypothesis | None:
    """The hypothesis of :func:`search_pose` when it scores at least ``refine.search_margin``
    above ``beat`` (and ``refine.min_score``) and the largest set of mapped features that
    agree with its pose (a clique of the correspondence graph among the nodes consistent
    with it) has at least ``pose.min_pairs`` features; else None. Its ``estimate`` is the
    weighted least-squares estimate of those features, linearised at the searched pose:
    the covariance says what the features alone fix (a corridor's walls leave the
    along-corridor direction free, infinite variance)."""
    found = search_pose(pa, pb, cfg)
    if found is None:
        return None
    pose, score = found
    if score < beat + cfg.refine.search_margin or score < cfg.refine.min_score:
        return None
    fa, fb, cc = pa.features, pb.features, cfg.correspondence
    agree = pair_consistent_pairs(
        fa, fb, cg.pairs, pose, cc.point_point, cc.line_line, cc.point_line
    )
    nodes = np.flatnonzero(agree)
    if len(nodes) < cfg.pose.min_pairs:
        return None
    sub = np.ascontiguousarray(cg.adjacency[np.ix_(nodes, nodes)])
    support = _clique.max_clique(
        sub, time_limit=cfg.clique.time_limit, node_limit=cfg.clique.node_limit
    )
    node_pairs = points_first(cg.pairs[nodes[support.vertices]], fa.n_points)
    if len(node_pairs) < cfg.pose.min_pairs:
        return None
    est = estimate_pose_lsq_pairs(fa, fb, node_pairs, initial=pose, iterations=0)
    if est is None:
        return None
    return Hypothesis(node_pairs, len(node_pairs), pose, score, est, True, "search")


def _check_args(where: str, config, cls=Scan, **records) -> None:
    """Refuse arguments of the wrong type at a public entry point, naming them."""
    for name, r in records.items():
        if not isinstance(r, cls):
            hint = " (from prepare_scan)" if cls is PreparedScan else ""
            raise ScanError(
                f"{where}: {name} must be {a_or_an(cls.__name__)}{hint}, got {type(r).__name__}"
            )
    require_config(f"{where}: ", config, MatchConfig)


def _check_prepared(pa, pb, config) -> MatchConfig:
    _check_args("match_prepared", config, PreparedScan, pa=pa, pb=pb)
    cfg = config if config is not None else pa.config
    for name, p in (("pa", pa), ("pb", pb)):
        differ = () if p.config is cfg else p.config.preparation_differences(cfg)
        if differ:
            raise ConfigError(
                f"match_prepared: {name} was prepared with another configuration "
                f"({', '.join(differ)} differ); prepare both scans with the "
                "configuration you match with"
            )
    return cfg


def match_prepared(
    pa: PreparedScan, pb: PreparedScan, config: MatchConfig | None = None
) -> ScanMatch:
    """Match two prepared scans: the pose of B in A's frame and the feature mapping.

    The recipe (paper §5–§6, with the ranking and refinement this library adds):

    1. correspondence graph of the two feature graphs (§5.2);
    2. maximum cliques (§5.3): every maximum clique up to ``clique.max_hypotheses``, then
       ``clique.peel`` disjoint alternatives (maximum cliques of what the earlier ones leave);
    3. a pose per clique (§6: weighted least squares or the paper's median);
    4. rank the hypotheses by raw-scan agreement, refine the best few by point-to-line ICP
       on the raw points (``refine.enabled``) and rank again;
    5. when even the best scores below ``refine.search_below``, search the pose on the raw
       scans (:func:`search_pose`); a clearly better pose that at least ``pose.min_pairs``
       mapped features agree with becomes the best hypothesis (``origin="search"``);
    6. no pose when even the best hypothesis has no raw-scan support
       (score below ``refine.min_score``);
    7. flag ambiguity when a distinct runner-up scores nearly as well.

    ``config`` defaults to the one ``pa`` was prepared with. Raises
    :class:`~scanclique.errors.ConfigError` when ``pa``, ``pb`` and ``config`` disagree on
    what shaped the prepared scans (:meth:`~scanclique.config.MatchConfig.preparation`):
    features and tolerances of one configuration cannot be matched under another's.
    """
    cfg = _check_prepared(pa, pb, config)
    warm_up()  # kernel loading never counts against the clocks below
    seconds = {k: 0.0 for k in STAGES}
    seconds["features"] = pa.seconds.get("features", 0.0) + pb.seconds.get("features", 0.0)
    seconds["graph"] = pa.seconds.get("graph", 0.0) + pb.seconds.get("graph", 0.0)
    fa, fb = pa.features, pb.features
    min_pairs = cfg.pose.min_pairs
    if len(fa) == 0 or len(fb) == 0:
        which, s = ("A", pa.scan) if len(fa) == 0 else ("B", pb.scan)
        return _empty(pa, pb, cfg, f"scan {which} has no features{_why_none(s)}", seconds)

    # 1. correspondence graph (paper §5.2)
    t = time.perf_counter()
    cg: CorrespondenceGraph = correspondence_graph(pa.graph, pb.graph, cfg.correspondence)
    seconds["correspondence"] = time.perf_counter() - t
    n_nodes, n_edges = cg.n_nodes, cg.n_edges
    if n_nodes == 0:
        return _empty(pa, pb, cfg, "no feature of A has a feature of the same type in B", seconds)

    # 2. maximum cliques (paper §5.3), disjoint alternatives by peeling, vertex-guided
    t = time.perf_counter()
    data, indptr, omega, optimal, stopped, nodes = _hypothesis_cliques(cg, cfg, t)
    if stopped is not None:
        log.info("clique search stopped by clique.%s after %d nodes", stopped, nodes)
    seconds["clique"] = time.perf_counter() - t
    if omega < min_pairs:
        return _empty(
            pa,
            pb,
            cfg,
            f"largest consistent mapping has {omega} features, fewer than min_pairs={min_pairs}",
            seconds,
            n_nodes,
            n_edges,
            optimal,
            omega,
            stopped=stopped,
            clique_nodes=nodes,
        )

    # 3. a quick pose per clique (paper §6), scored against the raw scans
    t = time.perf_counter()
    hyps = _quick_hypotheses(pa, pb, cg.pairs[data], indptr, cfg)
    if not hyps:
        seconds["pose"] = time.perf_counter() - t
        return _empty(
            pa,
            pb,
            cfg,
            "no clique fixes a pose (too few or degenerate features)",
            seconds,
            n_nodes,
            n_edges,
            optimal,
            omega,
            stopped=stopped,
            clique_nodes=nodes,
        )

    # 4. the best few distinct hypotheses: full weighted estimate with covariance, then
    #    ICP on the raw points (refine.enabled), and rank again
    distinct: list[Hypothesis] = []
    for h in hyps:
        if all(distinct_poses(h.pose, d.pose, cfg) for d in distinct):
            distinct.append(h)
        if len(distinct) >= cfg.refine.candidates:
            break
    seconds["pose"] = time.perf_counter() - t
    t = time.perf_counter()
    if cfg.pose.method == "lsq":
        full = _refine_candidates(pa, pb, distinct, cfg)
    else:
        full = _refine_median_candidates(pa, pb, distinct, cfg)
    seconds["refine"] = time.perf_counter() - t
    if not full:
        return _empty(
            pa,
            pb,
            cfg,
            "no clique fixes a pose (degenerate features)",
            seconds,
            n_nodes,
            n_edges,
            optimal,
            omega,
            stopped=stopped,
            clique_nodes=nodes,
        )
    full.sort(key=lambda h: -_rank(h, cfg.refine.size_weight))
    hyps = full + [h for h in hyps if all(h is not d for d in distinct)]

    # 5. a weak best (beyond the paper): search the pose on the raw scans; a clearly
    #    better pose that enough mapped features agree with goes first
    if cfg.refine.search and hyps[0].score < cfg.refine.search_below:
        t = time.perf_counter()
        found = _searched_hypothesis(pa, pb, cg, cfg, hyps[0].score)
        if found is not None:
            hyps.insert(0, found)
        seconds["search"] = time.perf_counter() - t

    # 6. no raw-scan evidence for the best hypothesis: no pose (the hypotheses stay)
    best = hyps[0]
    if best.score < cfg.refine.min_score:
        return _empty(
            pa,
            pb,
            cfg,
            f"no hypothesis explains the raw scans (best score {best.score:.3f} < "
            f"refine.min_score={cfg.refine.min_score})",
            seconds,
            n_nodes,
            n_edges,
            optimal,
            omega,
            hyps,
            stopped=stopped,
            clique_nodes=nodes,
        )

    # 7. ambiguity: a distinct runner-up that explains the raw scans nearly as well
    ambiguous = any(
        near_rival(h, best, cfg) and distinct_poses(h.pose, best.pose, cfg) for h in hyps[1:]
    )
    # the mapping reported: the chosen clique's pairs that agree with the final pose
    ordered = points_first(best.node_pairs, fa.n_points)
    cc = cfg.correspondence
    keep = pair_consistent_pairs(
        fa, fb, ordered, best.pose, cc.point_point, cc.line_line, cc.point_line
    )
    return ScanMatch(
        pose=best.pose,
        covariance=best.estimate.covariance,
        pairs=_node_pairs_to_feature_pairs(ordered[keep], pa.graph, pb.graph),
        clique_size=best.clique_size,
        omega=omega,
        optimal=optimal,
        ambiguous=ambiguous,
        hypotheses=tuple(hyps),
        score=best.score,
        refined=best.refined,
        reason=None,
        features_a=fa,
        features_b=fb,
        n_correspondence_nodes=n_nodes,
        n_correspondence_edges=n_edges,
        seconds=seconds,
        config=cfg,
        stopped=stopped,
        clique_nodes=nodes,
    )


_warm_seconds: float | None = None


def warm_up() -> float:
    """Load every compiled kernel the matcher uses (on a first run: compile them), once
    per process, by matching a tiny simulated pair with the default and the paper's
    configurations and running the raw-scan search.

    :func:`match_prepared` calls it before it starts its clocks, so that neither the
    times it reports (``ScanMatch.seconds``) nor its time guards ever count kernel loading
    or compilation. Returns the seconds it took the first time (0.0 on later calls);
    :func:`scanclique._lazy.cache_is_cold` says beforehand whether it will compile.
    """
    global _warm_seconds
    if _warm_seconds is not None:
        return 0.0
    _warm_seconds = 0.0  # match_prepared below must not warm up again
    t0 = time.perf_counter()
    from .config import paper_config
    from .sim import simulate_pair

    pair = simulate_pair(np.random.default_rng(0), n_beams=181)
    for cfg in (_DEFAULT, paper_config()):
        pa, pb = prepare_scan(pair.scan_a, cfg), prepare_scan(pair.scan_b, cfg)
        match_prepared(pa, pb, cfg)
        search_pose(pa, pb, cfg)
    _warm_seconds = time.perf_counter() - t0
    log.info("kernels loaded in %.1f s", _warm_seconds)
    return _warm_seconds


def warm_up_seconds() -> float | None:
    """Seconds :func:`warm_up` took in this process (loading, on a first run compiling,
    the kernels), None before it ran; reported apart from the stages' times."""
    return _warm_seconds


def match_scans(a: Scan, b: Scan, config: MatchConfig | None = None) -> ScanMatch:
    """Find the mapping of the features common to scans ``a`` and ``b`` and the pose of
    ``b``'s sensor frame in ``a``'s (paper §4–§6), with no prior pose.

    Parameters
    ----------
    a, b : Scan
        The two observations.
    config : MatchConfig, optional
        Defaults: the paper's parameters plus this library's additions; see
        :func:`scanclique.config.paper_config` for the paper's exact behaviour.

    Returns
    -------
    ScanMatch
        ``.pose`` maps points of ``b`` into ``a``'s frame (``R(theta) p_b + (x, y)``), or is
        None with ``.reason`` when no pose can be determined (e.g. a scan with no features:
        an empty mapping, not an exception).
    """
    _check_args("match_scans", config, a=a, b=b)
    cfg = config or _DEFAULT
    return match_prepared(prepare_scan(a, cfg), prepare_scan(b, cfg), cfg)
