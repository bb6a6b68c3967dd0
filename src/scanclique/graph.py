"""Feature graphs (paper §5.1; pipeline stage 4).

Each feature is a typed node; every pair of nodes carries invariant edge labels, values
that a rigid motion of the sensor does not change. The paper's relations:

==============  =====================================  ==================================
node types      paper (unsigned)                       default (signed, not mirror-blind)
==============  =====================================  ==================================
point–point     distance                               distance
point–line      perpendicular distance                 signed distance, the line's normal
                                                       pointing from the sensor to the line
line–line       acute angle magnitude                  signed angle between the oriented
                                                       normals, in [-pi, pi)
line–line (‖)   —                                      signed offset between (anti)parallel
                                                       lines (``parallel_offset``)
==============  =====================================  ==================================

A graph is stored as *layers*: ``invariants[k, i, j]`` is the value of relation k
between nodes i and j (NaN where relation k does not apply to that type pair),
``tolerances[k, i, j]`` its matching tolerance, and ``circular[k]`` says whether layer k
is an angle compared modulo 2π (:data:`LAYERS` names them).

Which relations a pair of nodes has follows from the *geometries* of their kinds
(:mod:`scanclique.kinds`: ``Geometry.relations``), not from the kinds themselves, so a
kind registered there (a point with a diameter, as a tree trunk is) gets its invariants
with every other kind without a change here. Node attributes (the diameter) are not
pairwise: they travel in ``FeatureGraph.attributes`` and the correspondence stage
compares them when it pairs nodes. The correspondence stage only reads these arrays;
a new geometry (3D points and planes) adds its relations and layers here.
"""

from __future__ import annotations

from collections.abc import Iterator, Mapping
from dataclasses import dataclass

import numpy as np

from . import kinds as _registry
from ._records import readonly
from .config import CorrespondenceConfig, FeatureConfig
from .errors import GraphError
from .features import (
    Features,
    _kernels,  # the compiled kernels (_feature_kernels), imported lazily
)
from .kinds import LINE

__all__ = [
    "LINE",
    "LAYERS",
    "NODE_KIND_NAMES",
    "PARALLEL_MAX_ANGLE",
    "FeatureGraph",
    "feature_graph",
    "point_distance_invariants",
]

#: the invariant layers of an SE(2) feature graph, and the geometry pairs that fill them
LAYERS = ("distance", "angle", "offset")


class _KindNames(Mapping):
    """``{label: name}`` of the registered feature kinds, read from the registry on each
    access (so a kind registered later is found)."""

    def __getitem__(self, label: int) -> str:
        return _registry.kind(int(label)).name

    def __iter__(self) -> Iterator[int]:
        return iter(_registry.kind_names())

    def __len__(self) -> int:
        return len(_registry.kind_names())


#: node label -> kind name, for every registered kind (:mod:`scanclique.kinds`)
NODE_KIND_NAMES: Mapping[int, str] = _KindNames()
# Lines within ~3 degrees of (anti)parallel also get an offset invariant: rho_j - rho_i
# drifts by |t| sin(dalpha) under a motion t, about 0.25 m after 5 m, within tolerance.
PARALLEL_MAX_ANGLE = 0.05  #: radians; lines this close to (anti)parallel get an offset
_PARALLEL_SIN = np.sin(PARALLEL_MAX_ANGLE)


_DEFAULT_CORRESPONDENCE_FIELD = CorrespondenceConfig()


@dataclass(frozen=True, slots=True, eq=False)
class FeatureGraph:
    """A complete graph over the features of one scan, with invariant edge labels.

    Nodes are ordered points first (the ``P`` point features), then the ``L`` lines.

    Attributes
    ----------
    labels : ndarray, shape (N,), int64
        Node labels; only same-label nodes may correspond.
    kinds : ndarray, shape (N,), int64
        The feature kind of each node (a key of :data:`NODE_KIND_NAMES`), kept even when
        ``labels`` lumps kinds together (the paper's untyped points).
    invariants : ndarray, shape (K, N, N)
        Layered relation values, symmetric in (i, j) up to sign for angles; NaN = n/a.
    tolerances : ndarray, shape (K, N, N)
        Matching tolerance of each relation.
    circular : ndarray, shape (K,), bool
        Layers that are angles compared modulo 2π.
    n_points : int
        Number of point nodes (the first ``n_points`` nodes).
    attributes : ndarray, shape (N, A)
        Node attributes (column k: attribute k of the node's kind, NaN where it has
        none); (N, 0) when no kind present has attributes.
    attribute_tolerances : ndarray, shape (N, A)
        The matching tolerance of each node's attribute (``inf`` where none).
    config : CorrespondenceConfig
        The tolerances and invariant choices the graph was built with; the
        correspondence stage refuses to pair graphs built with different ones.
    typed_edges : bool
        Whether point kinds got distinct labels (``FeatureConfig.typed_edges``).
    """

    labels: np.ndarray
    kinds: np.ndarray
    invariants: np.ndarray
    tolerances: np.ndarray
    circular: np.ndarray
    n_points: int
    config: CorrespondenceConfig = _DEFAULT_CORRESPONDENCE_FIELD
    typed_edges: bool = True
    attributes: np.ndarray | None = None
    attribute_tolerances: np.ndarray | None = None

    def __post_init__(self) -> None:
        n = int(np.size(self.labels))
        if self.attributes is None:
            object.__setattr__(self, "attributes", np.zeros((n, 0)))
        if self.attribute_tolerances is None:
            object.__setattr__(
                self, "attribute_tolerances", np.full(np.shape(self.attributes), np.inf)
            )
        if not (
            np.shape(self.attributes) == np.shape(self.attribute_tolerances)
            and np.ndim(self.attributes) == 2
            and np.shape(self.attributes)[0] == n
        ):
            raise GraphError(
                f"FeatureGraph: attributes {np.shape(self.attributes)} and attribute "
                f"tolerances {np.shape(self.attribute_tolerances)} must both be ({n}, A)"
            )
        for name in (
            "labels",
            "kinds",
            "invariants",
            "tolerances",
            "circular",
            "attributes",
            "attribute_tolerances",
        ):
            object.__setattr__(self, name, readonly(getattr(self, name)))

    @property
    def n_nodes(self) -> int:
        return int(self.labels.size)


_DEFAULT_CORRESPONDENCE = CorrespondenceConfig()
_DEFAULT_FEATURES = FeatureConfig()


def _line_normals(alpha: np.ndarray) -> np.ndarray:
    return np.column_stack((np.cos(alpha), np.sin(alpha)))


def feature_graph(
    features: Features,
    config: CorrespondenceConfig | None = None,
    feature_config: FeatureConfig | None = None,
) -> FeatureGraph:
    """Build the invariant-labelled complete graph of one scan's features (paper §5.1).

    Parameters
    ----------
    features : Features
        The scan's features.
    config : CorrespondenceConfig, optional
        Tolerances, and ``signed`` / ``parallel_offset`` choices of invariants.
    feature_config : FeatureConfig, optional
        ``typed_edges=False`` lumps all point kinds into one label, as in the paper.

    Returns
    -------
    FeatureGraph
        Three layers: 0 distances (point–point, point–line), 1 line–line angle,
        2 line–line parallel offset.

    Examples
    --------
    >>> from scanclique.features import Features
    >>> f = Features(np.array([[0.0, 1.0], [3.0, 5.0]]), np.array([0, 0], np.int8),
    ...              np.zeros((2, 2, 2)), np.array([0, 1]), np.zeros((0, 2)),
    ...              np.zeros((0, 2, 2)), np.zeros((0, 2, 2)), np.zeros((0, 2), int),
    ...              np.zeros(0, int), np.zeros((0, 2), int))
    >>> float(feature_graph(f).invariants[0, 0, 1])
    5.0

    Notes
    -----
    The arrays come from one compiled kernel (:func:`scanclique._feature_kernels.graph_layers`,
    numba); :func:`_feature_graph_reference` computes the same with NumPy and is what the
    tests hold it to.
    """
    cfg = config or _DEFAULT_CORRESPONDENCE
    typed = (feature_config or _DEFAULT_FEATURES).typed_edges
    P, L = features.n_points, features.n_lines
    N = P + L
    if N > cfg.max_features:  # refused before the (3, N, N) layers are allocated
        raise GraphError(
            f"feature graph of {N} features ({P} points, {L} lines) would take "
            f"{48 * N * N / 2**20:.0f} MiB, more than correspondence.max_features="
            f"{cfg.max_features} allows; raise the limit or extract fewer features"
        )
    xy = np.asarray(features.points_xy, dtype=np.float64)
    label = np.asarray(features.points_label, dtype=np.int8)
    cov = np.asarray(features.points_cov, dtype=np.float64)
    rho_alpha = np.asarray(features.lines_rho_alpha, dtype=np.float64)
    # the kernel does not check bounds: refuse arrays that disagree with the counts
    if (
        xy.shape != (P, 2)
        or label.shape != (P,)
        or cov.shape != (P, 2, 2)
        or rho_alpha.shape != (L, 2)
    ):
        raise GraphError(
            f"features: expected points_xy (P, 2), points_label (P,), points_cov (P, 2, 2) and "
            f"lines_rho_alpha (L, 2); got {xy.shape}, {label.shape}, {cov.shape}, "
            f"{rho_alpha.shape}"
        )
    labels, kinds, inv, tol = _kernels().graph_layers(
        xy,
        label,
        cov,
        rho_alpha,
        bool(typed),
        float(cfg.point_point),
        float(cfg.point_line),
        float(cfg.line_line),
        bool(cfg.signed),
        bool(cfg.parallel_offset),
        float(cfg.adaptive),
        float(_PARALLEL_SIN),
    )
    attrs, attr_tol = _node_attributes(features, kinds)
    return FeatureGraph(
        labels=labels,
        kinds=kinds,
        invariants=inv,
        tolerances=tol,
        circular=np.array([False, cfg.signed, False]),
        n_points=P,
        config=cfg,
        typed_edges=bool(typed),
        attributes=attrs,
        attribute_tolerances=attr_tol,
    )


def point_distance_invariants(points, cov) -> tuple[np.ndarray, np.ndarray]:
    """Point–point distances and their first-order variances: the invariant of a pair of
    ``point`` geometry nodes (paper §5.1), for callers that hold a *joint* covariance.

    :func:`feature_graph` computes the same distances for one scan's features (with a
    tolerance from each point's own covariance); this form serves graphs whose points are
    correlated, such as the predicted landmarks of an EKF map (:mod:`scanclique.slam`).

    Parameters
    ----------
    points : array_like, shape (n, 2)
        Metres.
    cov : array_like, shape (2n, 2n) or (n, 2, 2)
        Joint covariance of the stacked points (m²), or independent per-point blocks.

    Returns
    -------
    D : ndarray, shape (n, n)
        ``|p_a - p_b|`` (metres).
    V : ndarray, shape (n, n)
        First-order variance of ``D`` (m²), ``u^T (S_a + S_b - C_ab - C_ba) u`` with ``u``
        the unit vector from b to a (zero on the diagonal), never negative.

    Examples
    --------
    >>> D, V = point_distance_invariants([[0.0, 0.0], [3.0, 4.0]], np.tile(np.eye(2), (2, 1, 1)))
    >>> float(D[0, 1]), float(V[0, 1])
    (5.0, 2.0)
    """
    p = np.asarray(points, float).reshape(-1, 2)
    n = len(p)
    d = p[:, None, :] - p[None, :, :]
    D = np.sqrt((d * d).sum(-1))
    with np.errstate(invalid="ignore", divide="ignore"):
        u = d / D[..., None]
    u[~np.isfinite(u)] = 0.0
    cov = np.asarray(cov, float)
    if cov.ndim == 3:
        B = cov
        C = None
    else:
        B = cov.reshape(n, 2, n, 2)[np.arange(n), :, np.arange(n), :]
        C = cov.reshape(n, 2, n, 2).transpose(0, 2, 1, 3)  # (n, n, 2, 2) blocks
    Sab = B[:, None] + B[None, :]
    if C is not None:
        Sab = Sab - C - C.transpose(0, 1, 3, 2)
    V = np.einsum("abi,abij,abj->ab", u, Sab, u)
    return D, np.maximum(V, 0.0)


def _node_attributes(features: Features, node_kinds: np.ndarray):
    """The graph's node attributes (points then lines, NaN-padded to one width) and their
    tolerances from each node's kind; (N, 0) arrays when there are none."""
    pa = np.asarray(features.points_attributes, dtype=np.float64)
    la = np.asarray(features.lines_attributes, dtype=np.float64)
    A = max(pa.shape[1], la.shape[1])
    N = pa.shape[0] + la.shape[0]
    if A == 0:
        return np.zeros((N, 0)), np.zeros((N, 0))
    attrs = np.full((N, A), np.nan)
    attrs[: pa.shape[0], : pa.shape[1]] = pa
    attrs[pa.shape[0] :, : la.shape[1]] = la
    tol, At = _registry.attribute_tolerances(node_kinds)
    tol = np.pad(tol, ((0, 0), (0, A - At)), constant_values=np.inf) if At < A else tol[:, :A]
    return attrs, tol


def _feature_graph_reference(
    features: Features,
    config: CorrespondenceConfig | None = None,
    feature_config: FeatureConfig | None = None,
) -> FeatureGraph:
    """:func:`feature_graph` in NumPy: the reference of the compiled kernel."""
    cfg = config or CorrespondenceConfig()
    fcfg = feature_config or FeatureConfig()
    P, L = features.n_points, features.n_lines
    N = P + L
    kinds = np.concatenate((features.points_label.astype(np.int64), np.full(L, LINE, np.int64)))
    labels = kinds.copy() if fcfg.typed_edges else np.where(kinds == LINE, LINE, 0)

    inv = np.full((3, N, N), np.nan)
    tol = np.zeros((3, N, N))
    xy = features.points_xy
    rho = features.lines_rho_alpha[:, 0]
    alpha = features.lines_rho_alpha[:, 1]
    nrm = _line_normals(alpha)

    # layer 0: point–point distance
    if P:
        d = np.linalg.norm(xy[:, None, :] - xy[None, :, :], axis=2)
        inv[0, :P, :P] = d
        tol[0, :P, :P] = cfg.point_point
        if cfg.adaptive > 0:
            # largest positional variance of each point; the distance between two points
            # varies with both (and the other scan's pair adds as much again)
            lam = np.linalg.eigvalsh(features.points_cov)[:, -1]
            sd = np.sqrt(2.0 * (lam[:, None] + lam[None, :]))
            tol[0, :P, :P] = np.maximum(cfg.point_point, cfg.adaptive * sd)
    # layer 0: point–line (signed) perpendicular distance, normal from sensor to line
    if P and L:
        s = xy @ nrm.T - rho[None, :]  # (P, L); negative: the point is on the sensor's side
        if not cfg.signed:
            s = np.abs(s)
        inv[0, :P, P:] = s
        inv[0, P:, :P] = s.T
        tol[0, :P, P:] = cfg.point_line
        tol[0, P:, :P] = cfg.point_line
    if L:
        da = alpha[None, :] - alpha[:, None]  # angle from line i's normal to line j's
        if cfg.signed:
            ang = (da + np.pi) % (2 * np.pi) - np.pi
        else:
            a = np.abs(da) % np.pi
            ang = np.minimum(a, np.pi - a)  # acute angle magnitude in [0, pi/2]
        inv[1, P:, P:] = ang
        tol[1, P:, P:] = cfg.line_line
        if cfg.parallel_offset:
            cosd = np.cos(da)
            par = np.abs(np.sin(da)) < _PARALLEL_SIN
            # parallel: rho_j - rho_i is invariant; antiparallel: rho_j + rho_i
            off = np.where(cosd > 0, rho[None, :] - rho[:, None], rho[None, :] + rho[:, None])
            if not cfg.signed:
                off = np.abs(off)
            off = np.where(par, off, np.nan)
            inv[2, P:, P:] = off
            tol[2, P:, P:] = cfg.point_line
        idx = np.arange(P, N)
        inv[:, idx, idx] = np.nan
    attrs, attr_tol = _node_attributes(features, kinds)
    return FeatureGraph(
        labels=labels,
        kinds=kinds,
        invariants=inv,
        tolerances=tol,
        circular=np.array([False, cfg.signed, False]),
        n_points=P,
        config=cfg,
        typed_edges=bool(fcfg.typed_edges),
        attributes=attrs,
        attribute_tolerances=attr_tol,
    )
