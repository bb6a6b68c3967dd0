"""Configuration: one frozen dataclass per stage, composed into :class:`MatchConfig`.

Defaults are the paper's (Bailey et al. 2000, §4 and §6) where the paper gives one; the
rest were chosen on simulated scans and checked on the real logs by
``benchmarks/accuracy.py``. :func:`paper_config` returns the paper's behaviour exactly
(unsigned invariants, untyped points, median pose, no refinement).

Reading from / writing to TOML lives at the edge (:mod:`scanclique.io.config`); this
module only defines values and checks them.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field, fields

import numpy as np

from .errors import ArgumentError, ConfigError

__all__ = [
    "ClusterConfig",
    "FeatureConfig",
    "CorrespondenceConfig",
    "CliqueConfig",
    "PoseConfig",
    "RefineConfig",
    "ValidationConfig",
    "MatchConfig",
    "MAX_ITERATIONS",
    "MAX_QUICK_EXACT",
    "MAX_REFINE_CANDIDATES",
    "MAX_SEARCH_BINS",
    "MAX_SEARCH_SEEDS",
    "MAX_SIGMA_METRES",
    "check_at_most",
    "check_below_inf",
    "check_nonneg",
    "check_positive",
    "check_types",
    "check_probability",
    "check_choice",
    "require_at_most",
    "require_count",
    "require_callable",
    "require_config",
    "require_flag",
    "require_nonneg",
    "require_positive",
    "paper_config",
    "config_to_dict",
    "config_from_dict",
]


_TYPES = {"bool": (bool,), "int": (int,), "float": (int, float), "str": (str,)}
_INT64_MAX = 2**63 - 1
_SECTIONS: dict[tuple[type, str], type | None] = {}

#: the most iterations of an iterative solver a configuration may ask for (ICP, the back
#: end's Levenberg-Marquardt): the defaults take 10 to 100, and a count such as 2**62
#: ran without end (or overflowed the solver's 32-bit count)
MAX_ITERATIONS = 10_000

#: the largest standard deviation in metres a configuration may give (a range noise, a
#: covariance floor): a kilometre is no sensor's noise, and its square (1e6 m², scaled by
#: the arithmetic downstream) stays far from overflow, where 1e200 overflowed
MAX_SIGMA_METRES = 1e3


def _section_type(cls, f) -> type | None:
    """The configuration record a field holds (its default's class), None for a scalar."""
    key = (cls, f.name)
    if key not in _SECTIONS:
        default = f.default_factory() if f.default_factory is not dataclasses.MISSING else None
        _SECTIONS[key] = type(default) if dataclasses.is_dataclass(default) else None
    return _SECTIONS[key]


def _check_types(obj) -> None:
    """Every field holds a value of its annotated type (bools are not ints here, ints
    are accepted for floats and stored as floats: a Python int's square does not overflow,
    it becomes an object array in NumPy), integers fit in 64 bits (the compiled kernels
    take them) and no number is NaN; sections are checked by their own classes.

    Annotations understood (written as strings, ``from __future__ import annotations``):
    ``bool``, ``int``, ``float``, ``str``, any of them ``| None`` (None allowed),
    ``tuple[float, ...]`` (a tuple of that many numbers, none NaN; ``| None`` too), and a
    section (a field whose default is a configuration record: a record of that class)."""
    cls = type(obj)
    for f in fields(obj):
        name = f.type if isinstance(f.type, str) else getattr(f.type, "__name__", "")
        v = getattr(obj, f.name)
        where = f"{cls.__name__}.{f.name}"
        optional = name.endswith(" | None")
        if optional:
            if v is None:
                continue
            name = name[: -len(" | None")]
        if name.startswith("tuple["):
            n = len(name[len("tuple[") : -1].split(","))
            if not (isinstance(v, tuple) and len(v) == n and all(_is_number(x) for x in v)):
                raise ConfigError(f"{where} must be a tuple of {n} numbers, got {v!r}")
            if any(math.isnan(x) for x in v):
                raise ConfigError(f"{where} must be a tuple of {n} numbers, got {v!r} (nan)")
            continue
        expected = _TYPES.get(name)
        if expected is None:
            section = _section_type(cls, f)
            if section is not None and not isinstance(v, section):
                raise ConfigError(
                    f"{where} must be {a_or_an(section.__name__)}, got {type(v).__name__}"
                )
            continue
        wrong = not isinstance(v, expected) or (bool not in expected and isinstance(v, bool))
        if wrong:
            raise ConfigError(f"{where} must be {f.type}, got {v!r} ({type(v).__name__})")
        if isinstance(v, int) and not isinstance(v, bool) and abs(v) > _INT64_MAX:
            raise ConfigError(f"{where} must fit in 64 bits (|value| <= 2**63 - 1), got {v}")
        if name == "float" and isinstance(v, int):
            object.__setattr__(obj, f.name, float(v))
        if isinstance(v, float) and math.isnan(v):
            raise ConfigError(f"{where} must be a number, got nan")


check_types = _check_types


def a_or_an(name: str) -> str:
    """``name`` after its indefinite article, for messages: ``"an AssociationConfig"``,
    ``"a MatchConfig"`` (``an`` before a vowel letter but U, which the class names here
    read as "you": ``"a Unicycle"``)."""
    return f"{'an' if name[:1] in 'AEIOaeio' else 'a'} {name}"


def _is_number(v) -> bool:
    return isinstance(v, (int, float, np.number)) and not isinstance(v, (bool, np.bool_))


def require_positive(where: str, **values) -> None:
    """Each value is a finite number > 0, else :class:`ConfigError` naming ``where`` (a
    prefix such as ``"room_world: "`` or ``"ClusterConfig."``), the name and the value.
    The one argument checker of configs and of the simulator's parameters."""
    for name, v in values.items():
        if not (_is_number(v) and math.isfinite(v) and v > 0):
            raise ConfigError(f"{where}{name} must be a positive number, got {v!r}")


def require_count(where: str, lo: int = 0, **values) -> None:
    """Each value is an integer (not a bool, a float or NaN) of at least ``lo``, else
    :class:`ConfigError` (see :func:`require_positive`): the checker of counts given as
    arguments (candidates, a cache size)."""
    for name, v in values.items():
        if isinstance(v, (bool, np.bool_)) or not isinstance(v, (int, np.integer)) or v < lo:
            raise ConfigError(f"{where}{name} must be an integer >= {lo}, got {v!r}")


def require_config(where: str, config, cls: type) -> None:
    """``config`` is None or a ``cls``, else :class:`ConfigError` "``where``config must be
    a ``cls`` or None": the one check of an entry point's configuration argument."""
    if config is not None and not isinstance(config, cls):
        raise ConfigError(
            f"{where}config must be {a_or_an(cls.__name__)} or None, got {type(config).__name__}"
        )


def require_flag(where: str, **values) -> None:
    """Each value is True, False or None, else :class:`ArgumentError` (a string such as
    ``"no"`` would otherwise count as True): the checker of tri-state arguments."""
    for name, v in values.items():
        if v is not None and not isinstance(v, (bool, np.bool_)):
            raise ArgumentError(f"{where}{name} must be True, False or None, got {v!r}")


def require_callable(where: str, **values) -> None:
    """Each value is None or callable, else :class:`ArgumentError`, before a run starts
    (a ``progress`` that is not a function failed at its first call, mid-run)."""
    for name, v in values.items():
        if v is not None and not callable(v):
            raise ArgumentError(f"{where}{name} must be a function or None, got {v!r}")


def require_nonneg(where: str, **values) -> None:
    """Each value is a finite number >= 0, else :class:`ConfigError` (see
    :func:`require_positive`)."""
    for name, v in values.items():
        if not (_is_number(v) and math.isfinite(v) and v >= 0):
            raise ConfigError(f"{where}{name} must be a number >= 0, got {v!r}")


def _set(obj, names, infinite: bool) -> dict:
    """The named fields of ``obj`` to check: not an optional field's None (which means
    "off"; a field is optional when annotated ``... | None``), nor +inf when ``infinite``
    (which stands for "no limit")."""
    optional = {f.name for f in fields(obj) if str(f.type).endswith("| None")}
    values = {n: getattr(obj, n) for n in names}
    return {
        n: v
        for n, v in values.items()
        if not (v is None and n in optional) and not (infinite and v == math.inf)
    }


def check_positive(obj, *names: str, infinite: bool = False) -> None:
    """Each named field of ``obj`` is a finite number > 0 (:func:`require_positive`), or
    None (an optional field), or +inf when ``infinite`` (no limit)."""
    require_positive(f"{type(obj).__name__}.", **_set(obj, names, infinite))


def check_nonneg(obj, *names: str, infinite: bool = False) -> None:
    """Each named field of ``obj`` is a finite number >= 0 (:func:`require_nonneg`), or
    None (an optional field), or +inf when ``infinite`` (no limit)."""
    require_nonneg(f"{type(obj).__name__}.", **_set(obj, names, infinite))


def require_at_most(where: str, limit: float, **values) -> None:
    """Each value (a number, checked so first; None skipped) is at most ``limit``, the
    documented bound beyond which the value means nothing more and breaks the arithmetic
    (an array of that size, a count past a solver's integers, a square past float), else
    :class:`ConfigError` (see :func:`require_positive`)."""
    for name, v in values.items():
        if v is not None and v > limit:
            raise ConfigError(f"{where}{name} must be at most {limit:g}, got {v!r}")


def check_at_most(obj, limit: float, *names: str) -> None:
    """Each named field of ``obj`` is at most ``limit`` (:func:`require_at_most`)."""
    require_at_most(f"{type(obj).__name__}.", limit, **{n: getattr(obj, n) for n in names})


def check_below_inf(obj, *names: str) -> None:
    """Each named field of ``obj``, a floor on a raw-scan score (checked a number first),
    is below +inf: -inf is "no floor", +inf would refuse every pose."""
    for n in names:
        v = getattr(obj, n)
        if v == math.inf:
            raise ConfigError(f"{type(obj).__name__}.{n} must be below inf, got inf")


def check_probability(obj, *names: str) -> None:
    """Each named field of ``obj`` is a probability strictly between 0 and 1 (a gate at
    0 or 1 admits nothing or everything)."""
    for n in names:
        v = getattr(obj, n)
        if not (_is_number(v) and 0.0 < v < 1.0):
            raise ConfigError(
                f"{type(obj).__name__}.{n} must be a probability in (0, 1), got {v!r}"
            )


def check_radians(obj, *names: str) -> None:
    """Each named field of ``obj`` (an angle bound, checked a number first) is at most pi:
    no turn or direction difference is larger, and a value in degrees (10 for 10 degrees)
    would silently change what it bounds. None (an optional field) passes. Not for the
    standard deviations (a scaled noise may exceed pi) nor a bound whose documented
    "off" lies beyond pi."""
    for n in names:
        v = getattr(obj, n)
        if v is not None and v > math.pi:
            raise ConfigError(
                f"{type(obj).__name__}.{n} must be at most pi radians, got {v!r}: degrees? "
                f"({v} deg is {math.radians(v):.6g} rad)"
            )


def check_choice(obj, name: str, choices: tuple[str, ...]) -> None:
    """The named field of ``obj`` is one of ``choices`` (exactly: no case folding)."""
    v = getattr(obj, name)
    if v not in choices:
        listed = ", ".join(repr(c) for c in choices)
        raise ConfigError(f"{type(obj).__name__}.{name} must be one of {listed}, got {v!r}")


_positive = check_positive
_nonneg = check_nonneg


@dataclass(frozen=True, slots=True)
class ClusterConfig:
    """Paper §4: consecutive ranges join a cluster when |Ri - Ri+1| < c1 + c2 * min(Ri, Ri+1).

    ``max_gap_beams`` is how many consecutive invalid beams may be bridged inside a cluster
    (0, the paper's rule: any invalid return breaks the cluster).
    """

    c1: float = 0.07  # metres
    c2: float = 0.04  # metres per metre
    max_gap_beams: int = 0

    def __post_init__(self) -> None:
        _check_types(self)
        _nonneg(self, "c1", "c2", "max_gap_beams")


@dataclass(frozen=True, slots=True)
class FeatureConfig:
    """Paper §4 feature extraction.

    Attributes
    ----------
    foreground_edges, foreground_points, lines, corners : bool
        Which feature kinds to extract. Corners (the split point between two fitted lines
        meeting at a large angle) go beyond the paper.
    point_max_extent : float
        A cluster no longer than this (metres, end to end) that is nearer than both
        neighbours is a foreground point (a pole, a leg).
    split_distance : float
        Recursive split: a cluster is split at the point farthest from its chord when that
        distance exceeds ``split_distance + split_ratio * range`` (metres).
    line_min_points, line_min_length : int, float
        A fitted piece becomes a line feature when it has this many points and this length.
    line_max_gap, line_gap_ratio : float
        Lines are fitted on chains of consecutive valid points closer than
        ``line_max_gap + line_gap_ratio * range`` (metres): looser than the clusters, so a
        wall seen at grazing incidence still yields its line.
    line_max_rms : float
        ...and its total-least-squares residual RMS is below this (metres).
    merge_angle, merge_distance : float
        Collinear neighbours (normal angle within ``merge_angle`` rad, offset within
        ``merge_distance`` m) of the same or adjacent clusters are merged.
    corner_min_angle : float
        Two lines meeting at an angle (between directions) of at least this many radians
        form a corner point at their intersection...
    corner_reach : float
        ...when both segments end within this distance (metres) of the intersection.
    range_sigma : float
        Range noise standard deviation (metres) used for feature covariances; at most
        :data:`MAX_SIGMA_METRES` (1e200 overflowed the covariances).
    typed_edges : bool
        Label foreground edges as left / right (which side the occluded background is on);
        ``False`` lumps every point feature into one label, as in the paper.
    min_edge_jump : float
        A foreground edge needs its neighbour at least this much farther (metres).
    crowd_radius : float
        Foreground points with another foreground point nearer than this (metres) are
        dropped: points closer than the matching tolerance cannot be told apart by the
        invariants, and rows of them (railings, balusters) match themselves under any
        shift. 0 keeps them all.
    min_cluster_beams : int
        Clusters with fewer valid beams yield no feature: a lone return between two
        farther ones is as likely a mixed pixel or a gap in a railing as an object.
    reach_edges : bool
        Claim a foreground edge also where a surface may only leave the sensor's reach: a
        cluster end beside a no-return within one clustering step of ``range_max``
        (:func:`scanclique.features.leaves_reach`). Such an end is no feature of the world;
        between scans a step apart it still helps a match (a 3.5 m scanner in offices maps
        worse without it), but between places it matches any wall at the same distance,
        so place recognition leaves it out for a scanner whose reach its log meets
        (:func:`scanclique.features.for_scanner` with ``reach_edges=False``). A scanner
        that never meets its reach (the shared SICK logs) is the same either way.
    """

    foreground_edges: bool = True
    foreground_points: bool = True
    lines: bool = True
    corners: bool = True
    point_max_extent: float = 0.3
    split_distance: float = 0.05
    split_ratio: float = 0.01
    line_min_points: int = 6
    line_min_length: float = 0.4
    line_max_gap: float = 0.3
    line_gap_ratio: float = 0.1
    line_max_rms: float = 0.05
    merge_angle: float = 0.08
    merge_distance: float = 0.10
    corner_min_angle: float = math.radians(35)
    corner_reach: float = 1.0
    range_sigma: float = 0.02
    typed_edges: bool = True
    min_edge_jump: float = 0.15
    min_cluster_beams: int = 2
    crowd_radius: float = 0.3
    reach_edges: bool = True

    def __post_init__(self) -> None:
        _check_types(self)
        _positive(
            self,
            "min_cluster_beams",
            "point_max_extent",
            "split_distance",
            "line_min_length",
            "line_max_rms",
        )
        _positive(self, "merge_angle", "merge_distance", "corner_min_angle", "range_sigma")
        check_radians(self, "merge_angle", "corner_min_angle")
        check_at_most(self, MAX_SIGMA_METRES, "range_sigma")
        _nonneg(self, "corner_reach")
        _nonneg(
            self, "split_ratio", "min_edge_jump", "crowd_radius", "line_max_gap", "line_gap_ratio"
        )
        if not (isinstance(self.line_min_points, int) and self.line_min_points >= 2):
            raise ConfigError(
                f"FeatureConfig.line_min_points must be an int >= 2, got {self.line_min_points!r}"
            )


@dataclass(frozen=True, slots=True)
class CorrespondenceConfig:
    """Paper §5.2 and §6: tolerances on the edge invariants of the correspondence graph.

    Attributes
    ----------
    point_point : float
        |d_a - d_b| tolerance on point–point distances (metres; paper ±0.30).
    point_line : float
        Tolerance on point–line perpendicular distances (metres; paper ±0.40).
    line_line : float
        Tolerance on line–line angles (radians; paper ±0.1).
    signed : bool
        Use invariants that are not blind to mirror images: signed point–line distance with
        the line's normal pointing towards the sensor, and the signed angle between oriented
        lines. ``False`` gives the paper's unsigned invariants.
    parallel_offset : bool
        For two (nearly) parallel lines also compare the signed distance between them.
    adaptive : float
        Beyond the paper: a point–point tolerance grows to ``adaptive`` standard deviations
        of the two features' position uncertainty when that exceeds ``point_point`` (far
        edges are only known to a beam width). 0 keeps the paper's fixed tolerance.
    max_nodes : int
        Refuse to build a correspondence graph with more nodes than this
        (a :class:`~scanclique.errors.GraphError` names the sizes).
    max_features : int
        Refuse to build the feature graph of a scan with more features than this: its
        invariant and tolerance layers take ``48 N²`` bytes (190 MB at 2000). Laser scans
        give tens of features; a pathological one that gives thousands is refused before
        anything of that size is allocated.
    """

    point_point: float = 0.30
    point_line: float = 0.40
    line_line: float = 0.10
    signed: bool = True
    parallel_offset: bool = True
    adaptive: float = 0.0
    max_nodes: int = 20000
    max_features: int = 2000

    def tolerances(self) -> tuple:
        """What shapes a feature graph's invariants and tolerances (all but the limits
        ``max_nodes`` and ``max_features``): graphs built under equal tuples pair."""
        return (
            self.point_point,
            self.point_line,
            self.line_line,
            self.signed,
            self.parallel_offset,
            self.adaptive,
        )

    def __post_init__(self) -> None:
        _check_types(self)
        _positive(self, "point_point", "point_line", "line_line", "max_nodes", "max_features")
        _nonneg(self, "adaptive")


@dataclass(frozen=True, slots=True)
class CliqueConfig:
    """Paper §5.3: the maximum clique search.

    ``node_limit`` (search nodes, for all of a match's clique searches together) is the
    budget that decides results: the same scans give the same hypotheses on every machine
    and every run, compiled kernels warm or cold. Past it the best cliques found are used
    (``ScanMatch.stopped == "node_limit"``; ``optimal=False`` when omega was not proven).
    ``time_limit`` (seconds) is an outer guard only, for machines far slower than
    expected: when it bites, ``ScanMatch.stopped == "time_limit"`` says so (kernel
    loading never counts against it). ``max_hypotheses`` bounds how many maximum
    cliques are turned into pose hypotheses (several maximum cliques are the paper's §7
    symmetry). ``peel`` more hypotheses come from removing the vertices of the cliques
    found so far and taking the maximum clique of what remains: disjoint associations,
    which the raw scans then judge (0: the maximum clique alone, as in the paper).
    ``per_vertex``: for this many vertices of highest degree, the maximum clique containing
    the vertex is a hypothesis too (vertex-guided search: the true association is found
    when the maximum clique of the whole graph is a symmetric alias).
    """

    time_limit: float = 2.0
    node_limit: int = 2_000_000
    max_hypotheses: int = 8
    peel: int = 3
    per_vertex: int = 40

    def __post_init__(self) -> None:
        _check_types(self)
        _positive(self, "time_limit", "node_limit", "max_hypotheses")
        _nonneg(self, "peel", "per_vertex")


@dataclass(frozen=True, slots=True)
class PoseConfig:
    """Paper §6: pose from the mapped features.

    ``method`` is ``"lsq"`` (weighted least squares: Arun et al. 1987 for points, lines add
    normal and offset constraints; with covariance) or ``"median"`` (the paper's median
    rotation then median translation). ``min_pairs`` is the smallest clique that yields a
    pose hypothesis (two point or line pairs fix a planar pose; the raw scans then judge
    it).
    """

    method: str = "lsq"
    min_pairs: int = 2
    #: a clique's pairs whose Mahalanobis residual exceeds this are dropped from its
    #: weighted least-squares estimate (one round of outlier rejection)
    outlier_mahalanobis: float = 3.5

    def __post_init__(self) -> None:
        _check_types(self)
        _positive(self, "outlier_mahalanobis")
        if self.method not in ("lsq", "median"):
            raise ConfigError(f"PoseConfig.method must be 'lsq' or 'median', got {self.method!r}")
        if not (isinstance(self.min_pairs, int) and self.min_pairs >= 2):
            raise ConfigError(f"PoseConfig.min_pairs must be an int >= 2, got {self.min_pairs!r}")


#: bounds of :class:`RefineConfig` (its docstring): hypotheses refined, the multiple of
#: them scored on the full sample, orientation bins over pi, peaks or cells per rotation
MAX_REFINE_CANDIDATES = 10_000
MAX_QUICK_EXACT = 1_000
MAX_SEARCH_BINS = 3_600
MAX_SEARCH_SEEDS = 100


@dataclass(frozen=True, slots=True)
class RefineConfig:
    """Optional refinement on the raw points (point-to-line ICP) seeded by the clique's pose,
    and the raw-scan agreement score used to rank hypotheses.

    ``inlier_distance`` (metres): a point of B counts as agreeing with A when its nearest
    neighbour in A (under the pose) is closer than this. ``conflict_weight``: the score of a
    pose is the agreement minus this weight times the fraction of points that fall in the
    other scan's observed free space (see :func:`scanclique.refine.free_space_conflicts`).
    ``candidates``: how many distinct best-scoring hypotheses get the full weighted
    estimate and the ICP refinement before the final ranking. ``sample_points``: scoring
    and ICP use at most this many of each scan's points, evenly spaced in beam order.
    ``size_weight``: hypotheses are ranked by score plus this much per mapped feature.
    ``min_score``: when even the best hypothesis scores below this, the match has no pose
    (on the real logs every right match scored at least 0.2, while wrong ones went down
    to below 0).

    ``search``, ``search_below``: beyond the paper, when the best hypothesis scores below
    ``search_below``, the pose is also searched on the raw scans (rotations that align
    the two scans' surface orientations, translations voted by all pairs of sample points,
    ICP; see
    :func:`scanclique.match.search_pose`). Its pose replaces the clique's when it scores
    at least ``search_margin`` better and at least ``pose.min_pairs`` mapped features
    agree with it. It catches what a maximum clique misses: the true association is small
    (a corridor seen from its other end shares two walls and a door frame) while a larger
    clique of look-alike features wins. ``search=False`` disables it.

    The remaining fields tune those steps; their defaults were chosen once on simulated
    scans and are rarely worth changing:

    ``conflict_margin``, ``conflict_ratio``: a point conflicts with the other scan's free
    space when nearer than the beams' ranges by more than
    ``conflict_margin + conflict_ratio * range`` metres. ``quick_exact``: every clique's
    pose is first scored on every third sample point; this many times ``candidates`` of
    the best are scored again on the full sample. ``distinct_metres``,
    ``distinct_radians``: two hypotheses are the same pose unless this far apart (the one
    rule of :func:`scanclique.match.distinct_poses`). ``ambiguous_score``: a distinct
    runner-up scoring at least this fraction of the best, with a clique at most one
    smaller, makes a match ambiguous (:func:`scanclique.match.near_rival`). The raw-scan
    search (:func:`scanclique.match.search_pose`): orientation histograms of
    ``search_bins`` bins over pi, ``search_peaks`` peaks of their correlation (each also
    turned by pi), ``search_top`` translation peaks per rotation voted in cells of
    ``search_cell`` metres by every ``search_stride``-th sample point of A against every
    sample point of B, and ICP from the ``search_icp`` best-scoring seeds.

    Bounds, far above the defaults (beyond them a :class:`ConfigError`: 2**62 asked for
    arrays of that size, overflowed the kernels' 64-bit counts or ran without end):
    ``iterations`` at most :data:`MAX_ITERATIONS`; ``candidates`` at most
    :data:`MAX_REFINE_CANDIDATES`; ``quick_exact`` at most :data:`MAX_QUICK_EXACT` (the
    product of the two fits a 64-bit count); ``search_bins`` at most
    :data:`MAX_SEARCH_BINS` (a twentieth of a degree; the correlation costs ``bins**2``
    per match); ``search_peaks`` and ``search_top`` at most :data:`MAX_SEARCH_SEEDS`
    each (``2 * peaks * top`` seeds are scored); ``min_score`` below inf (-inf: no
    floor).
    """

    enabled: bool = True
    candidates: int = 2
    sample_points: int = 120
    size_weight: float = 0.01
    min_score: float = 0.1
    iterations: int = 10
    max_correspondence: float = 0.5
    inlier_distance: float = 0.15
    conflict_weight: float = 2.0
    search: bool = True
    search_below: float = 0.4
    search_margin: float = 0.1
    conflict_margin: float = 0.2
    conflict_ratio: float = 0.02
    quick_exact: int = 1
    distinct_metres: float = 0.3
    distinct_radians: float = math.radians(5.0)
    ambiguous_score: float = 0.9
    search_bins: int = 180
    search_peaks: int = 6
    search_top: int = 3
    search_cell: float = 0.25
    search_icp: int = 4
    search_stride: int = 2

    def __post_init__(self) -> None:
        _check_types(self)
        _positive(self, "max_correspondence", "inlier_distance", "sample_points")
        _nonneg(self, "conflict_weight", "size_weight", "search_margin")
        _nonneg(self, "conflict_margin", "conflict_ratio", "quick_exact")
        _nonneg(self, "distinct_metres", "distinct_radians", "ambiguous_score")
        check_radians(self, "distinct_radians")
        _positive(self, "search_bins", "search_peaks", "search_top", "search_cell")
        _positive(self, "search_icp", "search_stride")
        check_below_inf(self, "min_score")
        check_at_most(self, MAX_SEARCH_BINS, "search_bins")
        check_at_most(self, MAX_SEARCH_SEEDS, "search_peaks", "search_top")
        check_at_most(self, MAX_QUICK_EXACT, "quick_exact")
        check_at_most(self, MAX_REFINE_CANDIDATES, "candidates")
        if not (isinstance(self.search_below, (int, float)) and math.isfinite(self.search_below)):
            raise ConfigError(
                f"RefineConfig.search_below must be a finite number, got {self.search_below!r}"
            )
        if not (isinstance(self.candidates, int) and self.candidates >= 1):
            raise ConfigError(
                f"RefineConfig.candidates must be an int >= 1, got {self.candidates!r}"
            )
        _nonneg(self, "iterations")
        check_at_most(self, MAX_ITERATIONS, "iterations")


@dataclass(frozen=True, slots=True)
class ValidationConfig:
    """Paper §7: thresholds of :func:`scanclique.validation.validate_match`.

    Attributes
    ----------
    min_features : int
        A match needs at least this many mapped features (pairs of the chosen clique that
        agree with its pose within the correspondence tolerances), else
        ``too_few_features``. Two fix a planar pose, but the geometry of two features
        repeats almost anywhere; the chance of a symmetric alias falls fast with the
        number mapped (paper §7).
    max_std_metres, max_std_radians : float
        The precision the constellation allows
        (:func:`scanclique.uncertainty.constellation_std`): when the largest translation
        standard deviation or the heading standard deviation of the feature estimate
        exceeds these, the features do not fix the pose (``too_few_features``; a corridor
        seen along its walls).
    feature_gate : float
        Probability of the per-pair chi-square gate (2 dof) that decides which of the
        clique's pairs agree with the final pose in
        :func:`scanclique.validation.feature_estimate`.
    contender_score : float
        Hypotheses whose raw-scan score is at least this fraction of the best one's (and
        whose clique has ``min_features``) are the ones odometry may choose among.
    decisive : float
        When odometry has to choose (an ambiguous match, or the match's own pose outside
        the gate), the chosen hypothesis needs at least this posterior probability among
        the contenders (Gaussian likelihoods of their Mahalanobis distances, equal
        priors): with one rival, its squared distance must exceed the chosen one's by
        ``2 ln(p / (1 - p))``, 9.2 at 0.99. Being inside the gate only says a pose is
        *possible*; choosing needs the others to be improbable.
    rival_min_score : float
        A hypothesis that maps more features than the chosen one is its rival only when
        its raw-scan score is at least this. The default, 0.1, is the matcher's default
        ``refine.min_score``, below which it says that no pose explains the raw scans: a
        larger clique the raw scans refute is no evidence for another pose. (Change the
        two together.) Below inf, as ``refine.min_score`` (-inf: every hypothesis).
    """

    min_features: int = 3
    max_std_metres: float = 0.10
    max_std_radians: float = math.radians(1.0)
    feature_gate: float = 0.999
    contender_score: float = 0.5
    decisive: float = 0.99
    rival_min_score: float = 0.1

    def __post_init__(self) -> None:
        _check_types(self)
        if not self.min_features >= 2:
            raise ConfigError(
                f"ValidationConfig.min_features must be an int >= 2, got {self.min_features!r}"
            )
        _nonneg(self, "max_std_metres", "max_std_radians", "contender_score")
        check_below_inf(self, "rival_min_score")
        for name in ("feature_gate", "decisive"):
            v = getattr(self, name)
            if not 0.0 < v < 1.0:
                raise ConfigError(
                    f"ValidationConfig.{name} must be a probability in (0, 1), got {v!r}"
                )


@dataclass(frozen=True, slots=True)
class MatchConfig:
    """The whole pipeline's configuration: one section per stage (``validation`` is
    stage 8, used by :func:`scanclique.validation.validate_match`). Records the pipeline
    makes carry the configuration that made them (``PreparedScan.config``,
    ``ScanMatch.config``)."""

    clustering: ClusterConfig = field(default_factory=ClusterConfig)
    features: FeatureConfig = field(default_factory=FeatureConfig)
    correspondence: CorrespondenceConfig = field(default_factory=CorrespondenceConfig)
    clique: CliqueConfig = field(default_factory=CliqueConfig)
    pose: PoseConfig = field(default_factory=PoseConfig)
    refine: RefineConfig = field(default_factory=RefineConfig)
    validation: ValidationConfig = field(default_factory=ValidationConfig)

    def __post_init__(self) -> None:
        expected = {f.name: f.default_factory for f in fields(self)}
        for name, cls in expected.items():
            v = getattr(self, name)
            if not isinstance(v, cls):  # type: ignore[arg-type]
                raise ConfigError(
                    f"MatchConfig.{name} must be {a_or_an(cls.__name__)}, "  # type: ignore[union-attr]
                    f"got {type(v).__name__}"
                )

    def preparation(self) -> tuple:
        """What shapes a prepared scan (the features, the feature graph's invariants and
        tolerances, the raw-point sample): two prepared scans can be matched together,
        and under a configuration, only when these agree (the limits ``max_nodes`` and
        ``max_features`` may differ)."""
        return (
            self.clustering,
            self.features,
            self.correspondence.tolerances(),
            self.refine.sample_points,
        )

    def preparation_differences(self, other: MatchConfig) -> tuple[str, ...]:
        """Names of the parts of :meth:`preparation` in which ``other`` differs (empty:
        scans prepared under either can be matched under the other)."""
        names = ("clustering", "features", "correspondence", "refine.sample_points")
        pairs = zip(names, self.preparation(), other.preparation(), strict=True)
        return tuple(n for n, x, y in pairs if x != y)


def paper_config() -> MatchConfig:
    """The paper's exact behaviour: §4 features (no corners, untyped points), §6 tolerances,
    unsigned invariants, maximum clique only, median pose, no refinement, no raw-scan
    search."""
    return MatchConfig(
        features=FeatureConfig(corners=False, typed_edges=False),
        correspondence=CorrespondenceConfig(signed=False, parallel_offset=False),
        clique=CliqueConfig(peel=0, per_vertex=0),
        pose=PoseConfig(method="median"),
        refine=RefineConfig(enabled=False, min_score=-math.inf, search=False),
    )


def config_to_dict(cfg) -> dict:
    """A nested plain dict of a config (for TOML/JSON)."""
    return dataclasses.asdict(cfg)


def config_from_dict(data: dict, cls=MatchConfig):
    """Build a config from a nested dict; unknown keys raise :class:`ConfigError`."""
    if not isinstance(data, dict):
        raise ConfigError(f"{cls.__name__}: expected a table, got {type(data).__name__}")
    known = {f.name: f for f in fields(cls)}
    kwargs = {}
    for key, value in data.items():
        if key not in known:
            raise ConfigError(f"{cls.__name__}: unknown key {key!r} (known: {', '.join(known)})")
        f = known[key]
        default = f.default_factory() if f.default_factory is not dataclasses.MISSING else None
        if dataclasses.is_dataclass(default):  # a nested record (its factory may be a lambda)
            kwargs[key] = config_from_dict(value, type(default))
        else:
            kwargs[key] = value
    try:
        return cls(**kwargs)
    except TypeError as exc:
        raise ConfigError(f"{cls.__name__}: {exc}") from None
