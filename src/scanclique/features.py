"""Clustering and feature extraction from one laser scan (paper §4; pipeline stages 2–3).

Three feature kinds of the paper, plus corners:

* **foreground edges** — a cluster end point nearer than the adjacent cluster's end
  point. The far end point next to a nearer object is occluded and is *not* a feature.
  With typed labels an edge remembers on which side its background lies
  (:data:`EDGE_CW`: the farther neighbour is clockwise, at a smaller beam angle;
  :data:`EDGE_CCW`: counter-clockwise).
* **foreground points** — a small cluster nearer than both neighbours (poles, legs).
* **lines** — recursive split of each cluster at the point farthest from its chord, then a
  total-least-squares fit of each piece, in Hesse normal form ``x cos(alpha) + y sin(alpha)
  = rho`` with ``rho >= 0`` (the normal points from the sensor towards the line), with end
  points and the fit's covariance; collinear lines are merged (the paper notes that unmerged
  collinear segments make the mapping ill-defined).
* **corners** (beyond the paper) — the intersection of two lines fitted to adjacent pieces
  of one cluster that meet at a large angle: a point feature as stable as the walls.

These five kinds are declared in the registry of feature kinds (:mod:`scanclique.kinds`),
with their labels, geometries and pose residuals. A kind registered there with an
extractor (e.g. tree trunks with their diameter) is added to every scan's features by
:func:`extract_features`, after the built-in ones.

The clustering rule's constants suit a SICK (a centimetre of noise, few lost returns);
:func:`for_scanner` fits them to a log's scanner (lost returns bridged,
:func:`drops_returns`; the range term widened to its range noise, :func:`range_noise`).

All coordinates are in the sensor frame, metres and radians.

:func:`extract_features` runs as one compiled kernel (:mod:`scanclique._feature_kernels`,
about 0.05 ms for a 361-beam scan); the stage functions here, composed in
:func:`_extract_features_reference`, are the readable algorithm it must agree with.
"""

from __future__ import annotations

import dataclasses
import functools
import logging
import math
from collections.abc import Iterable
from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from . import kinds
from ._lazy import kernel_module
from ._records import readonly
from .config import ClusterConfig, FeatureConfig, MatchConfig, require_config
from .errors import ArgumentError, ConfigError, GraphError, ScanError
from .kinds import CORNER, EDGE_CCW, EDGE_CW, FOREGROUND_POINT
from .scan import Scan

__all__ = [
    "FOREGROUND_POINT",
    "EDGE_CW",
    "EDGE_CCW",
    "CORNER",
    "POINT_LABEL_NAMES",
    "Features",
    "cluster_scan",
    "DROPOUT_BRIDGE",
    "dropout_fraction",
    "drops_returns",
    "NOISE_SIGMAS",
    "range_noise",
    "for_scanner",
    "leaves_reach",
    "meets_reach",
    "extract_features",
    "fit_line_tls",
    "split_and_merge",
]

log = logging.getLogger(__name__)

#: the built-in point kinds' labels and names; every kind, built in or registered, is
#: declared in :mod:`scanclique.kinds` (the registry), which these come from
POINT_LABEL_NAMES = kinds.kind_names("point")


@dataclass(frozen=True, slots=True, eq=False)
class Features:
    """The features of one scan, in the sensor frame.

    Point features (foreground points, edges, corners) and line features are kept in two
    groups of parallel arrays.

    Attributes
    ----------
    points_xy : ndarray, shape (P, 2)
        Point feature positions (metres).
    points_label : ndarray, shape (P,), int8
        One of :data:`FOREGROUND_POINT`, :data:`EDGE_CW`, :data:`EDGE_CCW`, :data:`CORNER`.
    points_cov : ndarray, shape (P, 2, 2)
        Position covariance (m²).
    points_beam : ndarray, shape (P,), int64
        Index of the beam the point came from (for a foreground point, its middle beam).
    lines_rho_alpha : ndarray, shape (L, 2)
        Hesse normal form ``(rho, alpha)``: ``x cos(alpha) + y sin(alpha) = rho``, rho >= 0.
    lines_ends : ndarray, shape (L, 2, 2)
        Segment end points (the extreme projections of the fitted points on the line).
    lines_cov : ndarray, shape (L, 2, 2)
        Covariance of ``(rho, alpha)`` (m², m·rad, rad²).
    lines_beams : ndarray, shape (L, 2), int64
        First and last beam index of the points the line was fitted to.
    lines_n_points : ndarray, shape (L,), int64
        Number of scan points behind each line.
    clusters : ndarray, shape (C, 2), int64
        Beam index ranges ``[start, stop)`` of the clusters (valid beams only).
    points_attributes : ndarray, shape (P, A), optional
        Node attributes of the point features, column k holding attribute k of each
        point's kind (:attr:`scanclique.kinds.FeatureKind.attributes`), NaN where its
        kind has fewer. Built-in kinds have none: (P, 0), the default.
    lines_attributes : ndarray, shape (L, A'), optional
        The same for the line features; (L, 0) by default.

    The label of a feature says its kind (:mod:`scanclique.kinds`); the kind's geometry
    says which group it is in (point kinds in ``points_*``, line kinds in ``lines_*``).
    """

    points_xy: np.ndarray
    points_label: np.ndarray
    points_cov: np.ndarray
    points_beam: np.ndarray
    lines_rho_alpha: np.ndarray
    lines_ends: np.ndarray
    lines_cov: np.ndarray
    lines_beams: np.ndarray
    lines_n_points: np.ndarray
    clusters: np.ndarray
    points_attributes: np.ndarray | None = None
    lines_attributes: np.ndarray | None = None

    def __post_init__(self) -> None:
        for name, group in (
            ("points_attributes", "points_xy"),
            ("lines_attributes", "lines_rho_alpha"),
        ):
            n = np.shape(getattr(self, group))[0]
            a = getattr(self, name)
            a = np.zeros((n, 0)) if a is None else np.asarray(a, dtype=np.float64)
            if a.ndim != 2 or a.shape[0] != n:
                raise GraphError(f"Features.{name}: expected shape ({n}, A), got {a.shape}")
            object.__setattr__(self, name, a)
        for name in self.__dataclass_fields__:
            object.__setattr__(self, name, readonly(getattr(self, name)))

    @property
    def n_points(self) -> int:
        return int(self.points_xy.shape[0])

    @property
    def n_lines(self) -> int:
        return int(self.lines_rho_alpha.shape[0])

    def __len__(self) -> int:
        return self.n_points + self.n_lines

    def counts(self) -> dict[str, int]:
        """Number of features of each registered kind (:mod:`scanclique.kinds`), in label
        order; a point label no registered kind has is counted as ``"label_<n>"``."""
        labels = np.asarray(self.points_label, dtype=np.int64)
        out = {}
        for k in kinds.registered_kinds():
            out[k.name] = self.n_lines if k.geometry == "line" else int(np.sum(labels == k.label))
        point_labels = kinds.kind_names("point")
        for v in np.unique(labels):
            if int(v) not in point_labels:
                out[kinds.kind_name(int(v))] = int(np.sum(labels == v))
        return out

    def __repr__(self) -> str:
        kinds = ", ".join(f"{k}={v}" for k, v in self.counts().items())
        return f"Features({kinds})"


# --------------------------------------------------------------------------------------
# Stage 2: clustering (paper §4)
# --------------------------------------------------------------------------------------
def cluster_scan(scan: Scan, config: ClusterConfig | None = None) -> np.ndarray:
    """Split a scan's valid beams into clusters (paper §4).

    Consecutive valid ranges ``R_i, R_{i+1}`` join one cluster when
    ``|R_i - R_{i+1}| < c1 + c2 * min(R_i, R_{i+1})``. Invalid returns (NaN, inf,
    out of limits, max range) break clusters; with ``config.max_gap_beams = k > 0``, up to
    ``k`` invalid beams between two valid ones are bridged when the rule holds across them.

    Returns
    -------
    ndarray, shape (C, 2), int64
        ``[start, stop)`` beam indices of each cluster, in beam order. Invalid beams inside
        a bridged gap lie inside a range but never become points.

    Examples
    --------
    >>> s = Scan.from_ranges([1.0, 1.01, 1.02, 3.0, 3.02, np.nan, 2.0])
    >>> cluster_scan(s).tolist()
    [[0, 3], [3, 5], [6, 7]]
    """
    cfg = config or ClusterConfig()
    idx = np.flatnonzero(scan.valid)
    if idx.size == 0:
        return np.zeros((0, 2), dtype=np.int64)
    r = scan.ranges[idx]
    dr = np.abs(np.diff(r))
    limit = _join_limit(cfg, r[:-1], r[1:])
    join = (dr < limit) & (np.diff(idx) <= 1 + cfg.max_gap_beams)
    breaks = np.flatnonzero(~join) + 1
    starts = np.concatenate(([0], breaks))
    stops = np.concatenate((breaks, [idx.size]))
    return np.column_stack((idx[starts], idx[stops - 1] + 1)).astype(np.int64)


#: a scanner *drops returns* (:func:`drops_returns`) when the median of its scans'
#: :func:`dropout_fraction` is at least this. Cheap 360-degree lidars (RPLIDAR A1 class,
#: the LDS-01) lose a return on dark or shiny spots of a wall: each such beam reads as
#: nothing within reach, and with the paper's clustering (any invalid return breaks a
#: cluster) it makes two foreground edges where there is no occlusion, features that move
#: with every scan. The simulated ones (5-7 % of beams lost) have a median of 4-6 % per
#: scan; the shared SICK logs 0 (means 0.1-0.2 %: glass, the odd specular spot). Bridging
#: one beam (``ClusterConfig.max_gap_beams = 1``) left 0.44 of the features of one
#: simulated RPLIDAR scan within 0.2 m of the same kind in the scan 4 later on a campus
#: (0.29 without), and the SICK logs' maps a little worse (intel-raw 0.0147 -> 0.0150 m),
#: so it is the scanner's dropout rate that decides (:func:`for_scanner`).
DROPOUT_BRIDGE = 0.01


def dropout_fraction(scan: Scan, config: ClusterConfig | None = None) -> float:
    """The fraction of a scan's beams that are a lost return inside a surface: one
    invalid beam between two valid ones whose ranges the clustering rule
    (:func:`cluster_scan`: ``|R_a - R_b| < c1 + c2 * min(R_a, R_b)``) joins across it.
    0 for a scan of fewer than three beams.

    >>> dropout_fraction(Scan.from_ranges([2.0, 2.01, np.inf, 2.02, 2.03, np.inf, np.inf, 5.0]))
    0.125
    """
    if not isinstance(scan, Scan):
        raise ScanError(f"dropout_fraction: scan must be a Scan, got {type(scan).__name__}")
    cfg = config or ClusterConfig()
    v, r = scan.valid, scan.ranges
    if len(r) < 3:
        return 0.0
    i = np.flatnonzero(~v[1:-1]) + 1
    i = i[v[i - 1] & v[i + 1]]
    a, b = r[i - 1], r[i + 1]
    joined = np.abs(a - b) < _join_limit(cfg, a, b)
    return float(np.count_nonzero(joined)) / len(r)


def drops_returns(scans, config: ClusterConfig | None = None, sample: int = 200) -> bool:
    """Whether the scanner of ``scans`` loses returns inside surfaces: the median
    :func:`dropout_fraction` of up to ``sample`` scans spread over the log is at least
    :data:`DROPOUT_BRIDGE`. Then one invalid beam between two returns the clustering rule
    joins is a lost return, not open space (``ClusterConfig.max_gap_beams = 1``,
    :func:`for_scanner`). False for no scans; what is not a Scan is left to the caller's
    checks."""
    spread = _spread(scans, sample)
    if not spread:
        return False
    return bool(np.median([dropout_fraction(s, config) for s in spread]) >= DROPOUT_BRIDGE)


def meets_reach(scans, config: ClusterConfig | None = None, sample: int = 200) -> bool:
    """Whether the scanner of ``scans`` sees surfaces leave its reach: some scan of up to
    ``sample`` spread over the log has a valid return within one clustering step
    (``c1 + c2 * r``) of its ``range_max``, where a cluster's end may be the reach's
    rather than the surface's (:func:`leaves_reach`). False for no scans, and for the
    shared SICK logs (80 m; nothing valid beyond 37 m); True for a 3.5 m or 10 m 360°
    lidar wherever a wall runs on past its reach."""
    c = config or ClusterConfig()
    for s in _spread(scans, sample):
        r = s.ranges[s.valid]
        if len(r) and bool(np.any(r + c.c1 + c.c2 * r >= s.range_max)):
            return True
    return False


def _spread(scans, sample: int) -> list[Scan]:
    """Up to ``sample`` of ``scans`` spread evenly over the log, first and last among
    them; what is not a Scan left out (to the caller's own checks). An ArgumentError
    when ``scans`` is no sequence (None, a number, a path)."""
    if isinstance(scans, (str, bytes)) or not isinstance(scans, Iterable):
        raise ArgumentError(
            f"scans must be a sequence of Scan (read a file with read_scans first), "
            f"got {type(scans).__name__}"
        )
    scans = [s for s in scans if isinstance(s, Scan)]
    if not scans:
        return []
    pick = np.unique(np.linspace(0, len(scans) - 1, min(sample, len(scans))).astype(int))
    return [scans[k] for k in pick]


#: :func:`for_scanner` widens the clustering rule's range term ``c2`` to this many
#: standard deviations of the difference of two neighbouring ranges (``sqrt(2)`` times
#: :func:`range_noise`) when that is more than ``c2``: the paper's 0.04 m/m suits a SICK's
#: centimetre at any range, but a scanner whose noise grows with the range (1.5 % for the
#: simulated RPLIDAR and LDS-01: 0.066 m/m) then breaks every far wall into pieces whose
#: ends are foreground edges that are not there in the next scan. Repeatable point features
#: of the simulated RPLIDAR on a campus (within 0.2 m of one of the same kind four scans
#: later), lost returns bridged: far edges 0.32-0.39 at 0.04, 0.47-0.49 at 0.08.
NOISE_SIGMAS = 3.0


def range_noise(scans, config: ClusterConfig | None = None, sample: int = 200) -> float:
    """The scanner's range noise relative to the range (sigma / range, dimensionless),
    from its scans: over up to ``sample`` scans spread over the log, every three
    consecutive valid beams at 2 m or more whose neighbouring ranges the clustering rule,
    three times as loose, joins (one surface), the second difference ``r0 - 2 r1 + r2``
    (6 sigma² for independent noise on a plane seen at the beams' spacing), robustly:
    ``1.4826 * median(|r0 - 2 r1 + r2| / r1) / sqrt(6)``. NaN with fewer than 100 such
    triples (nothing to tell by).

    The shared SICK logs read 0.26-0.64 % (a centimetre at a few metres); the simulated
    RPLIDAR and LDS-01 (1.5 % of the range) 1.50-1.55 %, their 270-degree scanners (2 cm)
    0.25-0.58 %."""
    cfg = config or ClusterConfig()
    found = []
    for scan in _spread(scans, sample):
        v, r = scan.valid, scan.ranges
        if len(r) < 3:
            continue
        a, b, c = r[:-2], r[1:-1], r[2:]
        loose = 3.0 * _join_limit(cfg, np.minimum(a, b), c)
        with np.errstate(invalid="ignore"):
            ok = v[:-2] & v[1:-1] & v[2:] & (b >= 2.0)
            ok &= (np.abs(a - b) < loose) & (np.abs(c - b) < loose)
        a, b, c = a[ok], b[ok], c[ok]  # (no-returns read +inf: left out before any sum)
        found.append(np.abs(a - 2.0 * b + c) / b)
    d = np.concatenate(found) if found else np.zeros(0)
    if len(d) < 100:
        return math.nan
    return float(1.4826 * np.median(d) / math.sqrt(6.0))


def for_scanner(
    config: MatchConfig | None, scans, *, widen: bool = True, reach_edges: bool = True
) -> MatchConfig:
    """``config`` (None: the defaults) with its clustering fitted to the scanner of
    ``scans``: one lost return bridged in every cluster (``max_gap_beams = 1``) when it
    bridges none and the scanner loses returns inside surfaces (:func:`drops_returns`),
    and, with ``widen``, the range term ``c2`` widened to :data:`NOISE_SIGMAS` standard
    deviations of a difference of neighbouring ranges (:func:`range_noise`) when that is
    more; without ``reach_edges``, no foreground edge where a surface may only leave the
    sensor's reach (``FeatureConfig.reach_edges`` off) when the log meets its reach
    (:func:`meets_reach`); else ``config`` as it is (the shared SICK logs: none of the
    three). How a whole log's scans are prepared: by ``map_scans``
    (``FrontEndConfig.fit_scanner``), and, without widening and without reach edges, by
    ``places.find_loops`` and for a new database of ``scanclique places add``: place
    recognition puts precision first, and the widened rule's features made the simulated
    RPLIDAR's recognition on a campus less precise (0.913 against 0.946) and the LDS-01's
    in offices (0.959 against 0.970), while they made both map better; the reach's edges
    made places recognised wrongly (campus LDS-01 precision 0.320 with them, 0.519
    without; office LDS-01 0.970, 0.989), while mapping without them was worse (office
    LDS-01 600-pose drives 0.362 / 0.547 m, 0.508 / 0.795 m with / without odometry)
    (``benchmarks/mapping_sensors.py``, ``benchmarks/places_sensors.py``; README,
    "Fitting the clustering to the scanner", "A wall leaving a short reach")."""
    require_config("for_scanner: ", config, MatchConfig)
    cfg = config or MatchConfig()
    clu = cfg.clustering
    fit = clu
    if clu.max_gap_beams == 0 and drops_returns(scans, clu):
        fit = dataclasses.replace(fit, max_gap_beams=1)
    wide = NOISE_SIGMAS * math.sqrt(2.0) * range_noise(scans, clu) if widen else math.nan
    if wide > clu.c2:  # (False for NaN)
        fit = dataclasses.replace(fit, c2=round(wide, 3))
    feat = cfg.features
    if not reach_edges and feat.reach_edges and meets_reach(scans, fit):
        feat = dataclasses.replace(feat, reach_edges=False)
    if fit == clu and feat == cfg.features:
        return cfg
    log.info(
        "the clustering fitted to the scanner: %d lost beam(s) bridged, c2 %.3f m/m%s",
        fit.max_gap_beams, fit.c2, "" if feat.reach_edges else ", no edges at the reach",
    )  # fmt: skip
    return dataclasses.replace(cfg, clustering=fit, features=feat)


def _join_limit(cfg: ClusterConfig, a, b):
    """The clustering rule's bound on ``|R_a - R_b|`` for two ranges to join one cluster
    (paper §4): ``c1 + c2 * min(R_a, R_b)``, elementwise."""
    return cfg.c1 + cfg.c2 * np.minimum(a, b)


# --------------------------------------------------------------------------------------
# Lines: total least squares and recursive split (paper §4)
# --------------------------------------------------------------------------------------
def fit_line_tls(points: np.ndarray, sigma: float = 0.02):
    """Total-least-squares line through ``(N, 2)`` points, in Hesse normal form.

    Returns ``(rho, alpha, cov, rms, ends)``: ``x cos(alpha) + y sin(alpha) = rho`` with
    ``rho >= 0``; ``cov`` the 2x2 covariance of ``(rho, alpha)`` for isotropic point noise
    ``sigma`` (metres); ``rms`` the RMS orthogonal residual; ``ends`` (2, 2) the extreme
    projections of the points on the line, in point order.

    The normal is the eigenvector of the scatter matrix with the smallest eigenvalue.
    Writing ``u_i`` for the along-line coordinate of point i about the centroid and ``m``
    for the centroid's along-line coordinate from the foot of the normal,
    ``var(alpha) = sigma² / sum(u²)``, ``var(rho) = sigma²/N + m² var(alpha)``,
    ``cov(rho, alpha) = m var(alpha)``.

    Examples
    --------
    >>> pts = np.column_stack((np.full(5, 2.0), np.linspace(-1, 1, 5)))
    >>> rho, alpha, cov, rms, ends = fit_line_tls(pts)
    >>> round(rho, 6), round(alpha, 6), round(rms, 6)
    (2.0, 0.0, 0.0)
    """
    p = np.asarray(points, dtype=float)
    c = p.mean(axis=0)
    q = p - c
    s = q.T @ q
    # smallest-eigenvalue eigenvector of the 2x2 scatter: the normal
    w, v = np.linalg.eigh(s)
    n = v[:, 0]
    rho = float(n @ c)
    if rho < 0:
        n, rho = -n, -rho
    alpha = math.atan2(n[1], n[0])
    t = np.array([-n[1], n[0]])
    u = q @ t
    resid = q @ n
    rms = float(np.sqrt(np.mean(resid**2)))
    suu = float(u @ u)
    var_alpha = sigma**2 / max(suu, 1e-12)
    m = float(c @ t)
    cov = np.array(
        [[sigma**2 / len(p) + m * m * var_alpha, m * var_alpha], [m * var_alpha, var_alpha]]
    )
    foot = rho * n
    ends = np.array([foot + (m + u[0]) * t, foot + (m + u[-1]) * t])
    return rho, alpha, cov, rms, ends


def split_and_merge(
    points: np.ndarray, ranges: np.ndarray, cfg: FeatureConfig
) -> list[tuple[int, int]]:
    """Recursive split of one cluster's ordered points (paper §4).

    The chord joins the first and last point; the cluster is split at the point farthest
    from it while that distance exceeds ``cfg.split_distance + cfg.split_ratio * range``.

    Returns the ``[start, stop)`` index ranges of the pieces, in order (adjacent pieces
    share their split point).
    """
    out: list[tuple[int, int]] = []
    stack = [(0, len(points))]
    while stack:
        a, b = stack.pop()
        if b - a < 3:
            out.append((a, b))
            continue
        p0, p1 = points[a], points[b - 1]
        d = p1 - p0
        norm = math.hypot(d[0], d[1])
        seg = points[a:b] - p0
        if norm < 1e-9:
            dist = np.hypot(seg[:, 0], seg[:, 1])
        else:
            dist = np.abs(seg[:, 0] * d[1] - seg[:, 1] * d[0]) / norm
        k = int(np.argmax(dist))
        if dist[k] > cfg.split_distance + cfg.split_ratio * ranges[a + k] and 0 < k < b - a - 1:
            # the split point belongs to both halves; push right first so left pops first
            stack.append((a + k, b))
            stack.append((a, a + k + 1))
        else:
            out.append((a, b))
    out.sort()
    return out


def _line_record(pts: np.ndarray, beams: np.ndarray, cfg: FeatureConfig):
    rho, alpha, cov, rms, ends = fit_line_tls(pts, cfg.range_sigma)
    return {
        "rho": rho,
        "alpha": alpha,
        "cov": cov,
        "rms": rms,
        "ends": ends,
        "pts": pts,
        "beams": beams,
    }


def _accept_line(rec, cfg: FeatureConfig) -> bool:
    length = float(np.linalg.norm(rec["ends"][1] - rec["ends"][0]))
    return (
        len(rec["pts"]) >= cfg.line_min_points
        and length >= cfg.line_min_length
        and rec["rms"] <= cfg.line_max_rms
    )


def _merge_collinear(lines: list[dict], cfg: FeatureConfig) -> list[dict]:
    """Merge lines whose normals agree within ``merge_angle`` and whose offsets agree within
    ``merge_distance``, refitting on the union of their points (greedy, repeated until no
    pair merges). The merged fit must still pass the RMS test."""
    lines = list(lines)
    merged = True
    while merged and len(lines) > 1:
        merged = False
        for i in range(len(lines)):
            for j in range(i + 1, len(lines)):
                a, b = lines[i], lines[j]
                dalpha = abs((a["alpha"] - b["alpha"] + math.pi) % (2 * math.pi) - math.pi)
                if dalpha > cfg.merge_angle:
                    continue
                # offsets of each segment's points from the other line
                na = np.array([math.cos(a["alpha"]), math.sin(a["alpha"])])
                nb = np.array([math.cos(b["alpha"]), math.sin(b["alpha"])])
                da = np.abs(b["ends"] @ na - a["rho"]).max()
                db = np.abs(a["ends"] @ nb - b["rho"]).max()
                if max(da, db) > cfg.merge_distance:
                    continue
                order = np.argsort(np.concatenate((a["beams"], b["beams"])), kind="stable")
                pts = np.concatenate((a["pts"], b["pts"]))[order]
                beams = np.concatenate((a["beams"], b["beams"]))[order]
                rec = _line_record(pts, beams, cfg)
                if rec["rms"] > cfg.line_max_rms:
                    continue
                lines[i] = rec
                del lines[j]
                merged = True
                break
            if merged:
                break
    return lines


def _corners(lines: list[dict], scan: Scan, cfg: FeatureConfig):
    """Corners: intersections of two lines that meet at ``corner_min_angle`` or more and
    whose segments both end within ``corner_reach`` of the intersection. The point is the
    intersection of the two fitted (infinite) lines, so it stays put when the corner
    itself is hidden; its covariance propagates both lines' (rho, alpha) covariances."""
    out = []
    for i in range(len(lines)):
        for j in range(i + 1, len(lines)):
            r1, r2 = lines[i], lines[j]
            d = abs((r1["alpha"] - r2["alpha"] + math.pi) % (2 * math.pi) - math.pi)
            if min(d, math.pi - d) < cfg.corner_min_angle:
                continue
            n1 = np.array([math.cos(r1["alpha"]), math.sin(r1["alpha"])])
            n2 = np.array([math.cos(r2["alpha"]), math.sin(r2["alpha"])])
            m = np.vstack((n1, n2))
            corner = np.linalg.solve(m, np.array([r1["rho"], r2["rho"]]))
            reach1 = np.linalg.norm(r1["ends"] - corner, axis=1).min()
            reach2 = np.linalg.norm(r2["ends"] - corner, axis=1).min()
            if max(reach1, reach2) > cfg.corner_reach:
                continue
            # corner = M^-1 rho; d corner / d alpha_k = -M^-1 (e_k t_k . corner)
            minv = np.linalg.inv(m)
            t1 = np.array([-n1[1], n1[0]])
            t2 = np.array([-n2[1], n2[0]])
            jac = np.zeros((2, 4))
            jac[:, 0] = minv[:, 0]
            jac[:, 2] = minv[:, 1]
            jac[:, 1] = -minv[:, 0] * (t1 @ corner)
            jac[:, 3] = -minv[:, 1] * (t2 @ corner)
            big = np.zeros((4, 4))
            big[:2, :2], big[2:, 2:] = r1["cov"], r2["cov"]
            cov = jac @ big @ jac.T  # the lines' own precision (NEES-checked, no floor)
            phi = math.atan2(corner[1], corner[0])
            beam = int(np.argmin(np.abs(scan.angles - phi)))
            out.append((corner, beam, cov))
    return out


def _chains(scan: Scan, xy: np.ndarray, cfg: FeatureConfig) -> list[np.ndarray]:
    """Runs of consecutive valid beams whose points are closer than
    ``cfg.line_max_gap + cfg.line_gap_ratio * range`` to their predecessor."""
    idx = np.flatnonzero(scan.valid)
    if idx.size == 0:
        return []
    p = xy[idx]
    gap = np.hypot(*(np.diff(p, axis=0).T))
    r = scan.ranges[idx]
    join = gap < cfg.line_max_gap + cfg.line_gap_ratio * np.minimum(r[:-1], r[1:])
    return np.split(idx, np.flatnonzero(~join) + 1)


# --------------------------------------------------------------------------------------
# Stage 3: features (paper §4)
# --------------------------------------------------------------------------------------
_K = kernel_module("scanclique._feature_kernels")


def _kernels():
    """The compiled kernels (:mod:`scanclique._feature_kernels`), loaded on first use."""
    return _K


@functools.lru_cache(maxsize=64)
def _kernel_params(config: FeatureConfig | None, cluster_config: ClusterConfig | None):
    """The kernel's flat settings for a pair of (frozen, hashable) configurations."""
    return _kernels().params(config or FeatureConfig(), cluster_config or ClusterConfig())


def _point_cov(r: float, a: float, cfg: FeatureConfig, beam_width: float) -> np.ndarray:
    """Covariance of a point at range r, bearing a: range noise along the beam, half a beam
    width of bearing uncertainty across it (an edge is only known to the beam)."""
    u = np.array([math.cos(a), math.sin(a)])
    v = np.array([-u[1], u[0]])
    s_across = max(r * beam_width / 2.0, cfg.range_sigma)
    return cfg.range_sigma**2 * np.outer(u, u) + s_across**2 * np.outer(v, v)


def leaves_reach(
    r_end: float, far: float | None, range_max: float, config: ClusterConfig | None = None
) -> bool:
    """True when a cluster's end at range ``r_end`` (m) may be where its surface leaves the
    sensor's reach rather than where it ends: beyond the end is a no-return (``far`` is
    inf) and ``r_end`` is within one step the clustering rule joins, ``c1 + c2 * r_end``,
    of ``range_max``. Had the surface gone on a beam further, its next range could have
    been beyond the reach, so the end says nothing about the world: with
    ``FeatureConfig.reach_edges`` off it is no foreground edge.

    A scanner that reaches far (the shared SICK logs: 80 m, nothing valid beyond 37 m)
    never meets it indoors; a 3.5 m reach meets it on every wall it sees leave its circle,
    and those ends, taken for edges, matched a wall of any other place outdoors (simulated
    LDS-01 on a campus, ``benchmarks/places_sensors.py --world campus``).

    >>> leaves_reach(3.4, float("inf"), 3.5), leaves_reach(3.4, 5.0, 3.5)
    (True, False)
    >>> leaves_reach(2.0, float("inf"), 3.5), leaves_reach(3.4, None, 3.5)
    (False, False)
    """
    c = config or ClusterConfig()
    if far is None or not math.isinf(far):
        return False
    return r_end + c.c1 + c.c2 * r_end >= range_max


def _continues(points_xy: np.ndarray, start: int, stop: int, at_end: bool, far: np.ndarray) -> bool:
    """True when ``far`` lies on the continuation of the cluster's surface near one end:
    the gap is a wall seen at grazing incidence, not an occlusion."""
    k = min(5, stop - start)
    if k < 2:
        return False
    seg = points_xy[stop - k : stop] if at_end else points_xy[start : start + k]
    d = seg[-1] - seg[0]
    norm = math.hypot(d[0], d[1])
    if norm < 1e-6:
        return False
    end = seg[-1] if at_end else seg[0]
    w = far - end
    dist = math.hypot(w[0], w[1])
    perp = abs(w[0] * d[1] - w[1] * d[0]) / norm
    return perp < 0.05 + 0.1 * dist


def extract_features(
    scan: Scan,
    config: FeatureConfig | None = None,
    cluster_config: ClusterConfig | None = None,
) -> Features:
    """Extract foreground edges, foreground points, lines and corners from a scan (paper §4).

    Parameters
    ----------
    scan : Scan
        The observation; only its valid beams are used. An invalid beam at or beyond
        ``scan.range_max`` (a CARMEN max-range reading, or ROS's ``+inf``, REP 117) is a
        *no-return*: nothing within reach, so a cluster beside it has open space behind
        it and its end is a foreground edge. NaN, ``-inf`` and readings at or below
        ``range_min`` are unknown: no edge is claimed beside them.
    config, cluster_config : FeatureConfig, ClusterConfig, optional
        Defaults are the paper's where it gives one.

    Returns
    -------
    Features
        Possibly empty (a scan with no valid returns has no features; that is not an error).

    Examples
    --------
    A wall 2 m ahead with a pole in front of it:

    >>> ang = np.radians(np.arange(-90, 91, 1.0))
    >>> r = 2.0 / np.cos(np.clip(ang, -1.2, 1.2))
    >>> r[88:92] = 1.0
    >>> f = extract_features(Scan(r, ang))
    >>> f.counts()["foreground_point"], f.n_lines >= 1
    (1, True)

    Notes
    -----
    The work is one call of a compiled kernel (:func:`scanclique._feature_kernels.extract`,
    numba). :func:`_extract_features_reference` below is the same algorithm written out in
    NumPy with the stage functions of this module; it is the readable specification, and
    the tests require the two to agree to round-off.
    """
    p = _kernel_params(config, cluster_config)
    out = _kernels().extract(scan.ranges, scan.angles, scan.valid, scan.range_max, p)
    features = Features(*out)
    extra = kinds.extractor_kinds()
    return _with_kinds(scan, features, extra) if extra else features


def _with_kinds(scan: Scan, features: Features, extra) -> Features:
    """``features`` plus the features each registered extractor finds in ``scan``.

    The extractors' point features follow the built-in ones, kind by kind in label
    order, with their attributes in ``points_attributes`` (NaN-padded to the widest
    kind's attribute count).
    """
    found = [(k, k.extract(scan, features)) for k in extra]
    for k, f in found:
        if not isinstance(f, kinds.KindFeatures):
            raise ArgumentError(
                f"the extractor of feature kind {k.name!r} returned {type(f).__name__}, "
                "not a scanclique.kinds.KindFeatures"
            )
        if f.attributes.shape[1] != len(k.attributes):
            raise ConfigError(
                f"the extractor of feature kind {k.name!r} gave {f.attributes.shape[1]} "
                f"attributes per feature; the kind declares {len(k.attributes)} {k.attributes}"
            )
    A = max([features.points_attributes.shape[1]] + [f.attributes.shape[1] for _, f in found])

    def pad(a):
        return np.pad(a, ((0, 0), (0, A - a.shape[1])), constant_values=np.nan)

    return dataclasses.replace(
        features,
        points_xy=np.concatenate([features.points_xy] + [f.xy for _, f in found]),
        points_label=np.concatenate(
            [features.points_label] + [np.full(len(f.xy), k.label, np.int8) for k, f in found]
        ).astype(np.int8),
        points_cov=np.concatenate([features.points_cov] + [f.cov for _, f in found]),
        points_beam=np.concatenate([features.points_beam] + [f.beam for _, f in found]),
        points_attributes=np.concatenate(
            [pad(features.points_attributes)] + [pad(f.attributes) for _, f in found]
        ),
    )


def _extract_features_reference(
    scan: Scan,
    config: FeatureConfig | None = None,
    cluster_config: ClusterConfig | None = None,
) -> Features:
    """:func:`extract_features` in NumPy, step by step: the reference of the compiled kernel."""
    cfg = config or FeatureConfig()
    clusters = cluster_scan(scan, cluster_config)
    xy = scan.xy()
    r_all = scan.ranges
    valid = scan.valid
    n_beams = scan.n_beams
    beam_width = float(np.median(np.diff(scan.angles))) if n_beams > 1 else 0.0
    no_return = scan.no_return

    pts, labels, covs, pbeams = [], [], [], []

    def add_point(p, label, beam, cov):
        pts.append(np.asarray(p, dtype=float))
        labels.append(label)
        pbeams.append(int(beam))
        covs.append(cov)

    # -- lines (paper §4), fitted on chains looser than the clusters ---------------------
    # A wall seen at grazing incidence breaks into single points under the clustering
    # rule; lines only need collinearity, which the split and the fit test, so they are
    # fitted on chains of consecutive valid points closer than line_max_gap + ratio * r.
    lines: list[dict] = []
    interior = np.zeros(n_beams, dtype=bool)  # beams strictly inside a fitted piece
    if cfg.lines or cfg.corners:
        for beams in _chains(scan, xy, cfg):
            if beams.size < cfg.line_min_points:
                continue
            cpts = xy[beams]
            for a, b in split_and_merge(cpts, r_all[beams], cfg):
                # too few points, or a chord too short, for the line tests: skip the fit
                if b - a < max(2, cfg.line_min_points):
                    continue
                if math.dist(cpts[a], cpts[b - 1]) < 0.9 * cfg.line_min_length:
                    continue
                rec = _line_record(cpts[a:b], beams[a:b], cfg)
                if _accept_line(rec, cfg):
                    lines.append(rec)
                    interior[beams[a + 1 : b - 1]] = True
        lines = _merge_collinear(lines, cfg)

    # -- foreground edges and points --------------------------------------------------
    def neighbour_range(beam: int, step: int) -> float | None:
        """Range on the far side of a cluster end: the next valid beam (or a run of
        no-returns, which counts as infinitely far). None when unknown (scan border, or
        an invalid return that is not a no-return)."""
        j = beam + step
        while 0 <= j < n_beams:
            if valid[j]:
                return float(r_all[j])
            if not no_return[j]:
                return None
            # a no-return: the background is beyond the sensor's reach
            return math.inf
        return None

    for start, stop in clusters:
        if int(np.count_nonzero(valid[start:stop])) < cfg.min_cluster_beams:
            continue
        first, last = int(start), int(stop) - 1
        r_first, r_last = float(r_all[first]), float(r_all[last])
        left = neighbour_range(first, -1)  # clockwise neighbour (smaller angle)
        right = neighbour_range(last, +1)  # counter-clockwise neighbour
        near_cw = left is not None and left - r_first >= cfg.min_edge_jump
        near_ccw = right is not None and right - r_last >= cfg.min_edge_jump
        # grazing-incidence walls break into clusters whose "edges" are not occlusions:
        # the far neighbour continues the surface, or the end lies inside a fitted line
        near_cw = near_cw and not interior[first]
        near_ccw = near_ccw and not interior[last]
        if near_cw and math.isfinite(left) and _continues(xy, first, stop, False, xy[first - 1]):
            near_cw = False
        if near_ccw and math.isfinite(right) and _continues(xy, first, stop, True, xy[last + 1]):
            near_ccw = False
        extent = float(np.linalg.norm(xy[last] - xy[first]))
        if near_cw and near_ccw and extent <= cfg.point_max_extent:
            if cfg.foreground_points:
                mid = (first + last) // 2
                centre = np.nanmean(xy[first : last + 1], axis=0)
                rng = float(np.hypot(*centre))
                cov = _point_cov(rng, math.atan2(centre[1], centre[0]), cfg, beam_width)
                add_point(centre, FOREGROUND_POINT, mid, cov + np.eye(2) * (extent / 4) ** 2)
            continue
        if cfg.foreground_edges and stop - start >= 2:
            # an end where the surface may leave the sensor's reach, unless asked for
            if not cfg.reach_edges:
                rm = scan.range_max
                near_cw = near_cw and not leaves_reach(r_first, left, rm, cluster_config)
                near_ccw = near_ccw and not leaves_reach(r_last, right, rm, cluster_config)
            if near_cw:
                a = scan.angles[first]
                add_point(xy[first], EDGE_CW, first, _point_cov(r_first, a, cfg, beam_width))
            if near_ccw:
                a = scan.angles[last]
                add_point(xy[last], EDGE_CCW, last, _point_cov(r_last, a, cfg, beam_width))

    if cfg.crowd_radius > 0 and pts:
        is_fp = np.array(labels) == FOREGROUND_POINT
        if is_fp.sum() > 1:
            fp = np.array(pts)[is_fp]
            # nearest other foreground point (k=2: the first hit is the point itself);
            # a KD-tree keeps memory linear in the number of points
            d, _ = cKDTree(fp).query(fp, k=2)
            crowded = np.zeros(len(pts), dtype=bool)
            crowded[np.flatnonzero(is_fp)] = d[:, 1] < cfg.crowd_radius
            keep = np.flatnonzero(~crowded)
            pts = [pts[i] for i in keep]
            labels = [labels[i] for i in keep]
            covs = [covs[i] for i in keep]
            pbeams = [pbeams[i] for i in keep]

    # -- corners (beyond the paper) ------------------------------------------------------
    if cfg.corners:
        for corner, beam, cov in _corners(lines, scan, cfg):
            add_point(corner, CORNER, beam, cov)
    if not cfg.lines:
        lines = []

    P = len(pts)
    L = len(lines)
    return Features(
        points_xy=np.array(pts, dtype=float).reshape(P, 2),
        points_label=np.array(labels, dtype=np.int8).reshape(P),
        points_cov=np.array(covs, dtype=float).reshape(P, 2, 2),
        points_beam=np.array(pbeams, dtype=np.int64).reshape(P),
        lines_rho_alpha=np.array([[ln["rho"], ln["alpha"]] for ln in lines], dtype=float).reshape(
            L, 2
        ),
        lines_ends=np.array([ln["ends"] for ln in lines], dtype=float).reshape(L, 2, 2),
        lines_cov=np.array([ln["cov"] for ln in lines], dtype=float).reshape(L, 2, 2),
        lines_beams=np.array(
            [[ln["beams"].min(), ln["beams"].max()] for ln in lines], dtype=np.int64
        ).reshape(L, 2),
        lines_n_points=np.array([len(ln["pts"]) for ln in lines], dtype=np.int64).reshape(L),
        clusters=clusters,
    )
