"""The registry of feature kinds (paper §4–§6: typed nodes, their invariants, their poses).

The paper's graph is *typed*: every node carries a label and only same-label nodes may
correspond (§5.2). Which labels exist, what geometry a node of each label has, which
invariants join it to every other node, which residual it adds to the pose estimate and
which node attributes it carries is declared here, once, and the graph (§5.1),
correspondence (§5.2) and pose (§6) stages read it instead of hard-wiring five kinds.

Two layers of declaration:

* a :class:`Geometry` is a geometric primitive in the sensor frame: its parameters, the
  group of :class:`~scanclique.features.Features` arrays that hold it, the relations it
  has with every other geometry (the invariant layers of :mod:`scanclique.graph`) and the
  residual it contributes to the pose (:mod:`scanclique.pose`). SE(2) has two: ``point``
  ``(x, y)`` and ``line`` ``(rho, alpha)``. A 3D issue adds its own (points and planes in
  SE(3)) with their relations; nothing here assumes two dimensions except the two
  geometries registered below.
* a :class:`FeatureKind` is a typed node: a name, a node label, a geometry, optional
  *node attributes* (scalars a rigid motion leaves unchanged, e.g. a tree trunk's
  diameter) each with a matching tolerance, and optionally an extractor that finds
  features of the kind in a scan.

A kind with an existing geometry gets, from the geometry, its invariants with every other
kind (a new point kind is at a distance from every point and at a signed distance from
every line) and its pose residual (point to point); its attributes are compared when two
nodes of the kind are paired (:func:`scanclique.correspondence.candidate_pairs`). So a new
kind needs no change of the matcher: register it and match.

>>> from scanclique import kinds
>>> [k.name for k in kinds.registered_kinds()]
['foreground_point', 'edge_cw', 'edge_ccw', 'corner', 'line']
>>> trunk = kinds.FeatureKind("trunk", label=4, geometry="point",
...                           attributes=("diameter",), attribute_tolerances=(0.05,))
>>> with kinds.registered(trunk):
...     kinds.kind("trunk").label, kinds.kind(4).attributes
(4, ('diameter',))
>>> "trunk" in kinds.kind_names().values()
False

The registry is process-wide state, like a codec registry: register a kind before
preparing the scans that should carry it, in every process that prepares scans.
"""

from __future__ import annotations

import contextlib
import math
import threading
from collections.abc import Callable, Iterator
from dataclasses import dataclass

import numpy as np

from ._records import readonly
from .errors import ConfigError

__all__ = [
    "Geometry",
    "FeatureKind",
    "KindFeatures",
    "GEOMETRIES",
    "FOREGROUND_POINT",
    "EDGE_CW",
    "EDGE_CCW",
    "CORNER",
    "LINE",
    "MAX_LABEL",
    "register_kind",
    "unregister_kind",
    "registered",
    "registered_kinds",
    "extractor_kinds",
    "kind",
    "kind_name",
    "kind_names",
    "attribute_tolerances",
]


@dataclass(frozen=True, slots=True)
class Geometry:
    """A geometric primitive that feature kinds share.

    Attributes
    ----------
    name : str
        ``"point"`` or ``"line"`` in SE(2).
    group : str
        Which arrays of :class:`~scanclique.features.Features` hold the features
        (``"points"``: ``points_xy``, ``points_cov``, ...; ``"lines"``: ``lines_rho_alpha``,
        ...). The feature graph orders its nodes by group, in the order of
        :data:`GEOMETRIES` (points first, then lines).
    parameters : tuple of str
        The parameters, with units: ``("x [m]", "y [m]")``, ``("rho [m]", "alpha [rad]")``.
    relations : dict
        For each geometry (by name), the invariant layers of :mod:`scanclique.graph` that
        a pair of this geometry and that one fills.
    residual : str
        What a paired feature of this geometry adds to the pose estimate (paper §6).
    """

    name: str
    group: str
    parameters: tuple[str, ...]
    relations: dict
    residual: str


#: the SE(2) geometries, in node order (the graph's layers: 0 distance, 1 angle, 2 offset)
GEOMETRIES: dict[str, Geometry] = {
    "point": Geometry(
        name="point",
        group="points",
        parameters=("x [m]", "y [m]"),
        relations={"point": ("distance",), "line": ("signed distance to the line",)},
        residual="point to point: R p_b + t - p_a, weighted by both covariances",
    ),
    "line": Geometry(
        name="line",
        group="lines",
        parameters=("rho [m]", "alpha [rad]"),
        relations={
            "point": ("signed distance to the line",),
            "line": ("signed angle between normals", "offset of (anti)parallel lines"),
        },
        residual="line to line: (rho, alpha) of B's line moved into A's frame minus A's",
    ),
}


@dataclass(frozen=True, slots=True, eq=False)
class KindFeatures:
    """Features of one registered kind found by its extractor, in the sensor frame.

    Attributes
    ----------
    xy : ndarray, shape (n, 2)
        Positions (metres); for a ``point`` geometry.
    cov : ndarray, shape (n, 2, 2)
        Position covariances (m²).
    beam : ndarray, shape (n,), int64
        The beam each feature came from (e.g. its middle beam).
    attributes : ndarray, shape (n, A)
        The kind's node attributes, in the order of :attr:`FeatureKind.attributes`.
    """

    xy: np.ndarray
    cov: np.ndarray
    beam: np.ndarray
    attributes: np.ndarray

    def __post_init__(self) -> None:
        # copies: freezing the arrays must never freeze the extractor's own
        xy = readonly(self.xy, dtype=np.float64, copy=True)
        n = xy.shape[0] if xy.ndim == 2 else -1
        arrays = {
            "xy": (xy, (n, 2)),
            "cov": (readonly(self.cov, dtype=np.float64, copy=True), (n, 2, 2)),
            "beam": (readonly(self.beam, dtype=np.int64, copy=True), (n,)),
        }
        attrs = readonly(self.attributes, dtype=np.float64, copy=True)
        for name, (a, shape) in arrays.items():
            if a.shape != shape:
                raise ConfigError(
                    f"KindFeatures.{name}: expected shape {shape} for {n} features, got {a.shape}"
                )
        if attrs.ndim != 2 or attrs.shape[0] != n:
            raise ConfigError(
                f"KindFeatures.attributes: expected shape ({n}, A), got {attrs.shape}"
            )
        if not (np.all(np.isfinite(xy)) and np.all(np.isfinite(arrays["cov"][0]))):
            raise ConfigError("KindFeatures: positions and covariances must be finite")
        for name, (a, _shape) in arrays.items():
            object.__setattr__(self, name, a)
        object.__setattr__(self, "attributes", attrs)


#: an extractor: ``(scan, features) -> KindFeatures``, given the scan and the built-in
#: features already extracted from it (its clusters, lines, points), in the sensor frame
Extractor = Callable[..., KindFeatures]

#: node labels are small non-negative integers (the typed graph compares them)
MAX_LABEL = 63


@dataclass(frozen=True, slots=True)
class FeatureKind:
    """A typed node of the feature graph.

    Attributes
    ----------
    name : str
        Unique; the name a match reports its pairs under (``FeaturePair.kind``).
    label : int
        Unique node label in ``[0, MAX_LABEL]``; only same-label nodes correspond.
    geometry : str
        A key of :data:`GEOMETRIES`: which invariants and pose residual the kind has.
    attributes : tuple of str
        Names of node attributes (invariant scalars, e.g. ``"diameter"``, with units in
        the documentation of the kind).
    attribute_tolerances : tuple of float
        For each attribute, the largest difference at which two nodes of the kind may
        still correspond (same units as the attribute). Positive.
    extract : callable, optional
        ``extract(scan, features) -> KindFeatures``: finds the kind's features in a scan,
        given the built-in features. Built-in kinds have none (one compiled kernel
        extracts them all, :func:`scanclique.features.extract_features`). Extractors
        are supported for ``point`` geometry kinds.
    description : str
        One line for listings.
    """

    name: str
    label: int
    geometry: str
    attributes: tuple[str, ...] = ()
    attribute_tolerances: tuple[float, ...] = ()
    extract: Extractor | None = None
    description: str = ""

    def __post_init__(self) -> None:
        if not (isinstance(self.name, str) and self.name.isidentifier()):
            raise ConfigError(f"FeatureKind.name must be an identifier, got {self.name!r}")
        if isinstance(self.label, bool) or not isinstance(self.label, (int, np.integer)):
            raise ConfigError(f"FeatureKind({self.name}).label must be an int, got {self.label!r}")
        if not 0 <= int(self.label) <= MAX_LABEL:
            raise ConfigError(
                f"FeatureKind({self.name}).label must be in [0, {MAX_LABEL}], got {self.label}"
            )
        object.__setattr__(self, "label", int(self.label))
        if self.geometry not in GEOMETRIES:
            raise ConfigError(
                f"FeatureKind({self.name}).geometry must be one of {sorted(GEOMETRIES)}, "
                f"got {self.geometry!r}"
            )
        attrs = tuple(self.attributes)
        tols = tuple(float(t) for t in self.attribute_tolerances)
        if len(attrs) != len(tols):
            raise ConfigError(
                f"FeatureKind({self.name}): {len(attrs)} attributes {attrs} but {len(tols)} "
                "attribute tolerances; give one tolerance per attribute"
            )
        for a, t in zip(attrs, tols, strict=True):
            if not (isinstance(a, str) and a):
                raise ConfigError(f"FeatureKind({self.name}): attribute names must be strings")
            if not (math.isfinite(t) and t > 0):
                raise ConfigError(
                    f"FeatureKind({self.name}): tolerance of {a!r} must be finite and > 0, got {t}"
                )
        object.__setattr__(self, "attributes", attrs)
        object.__setattr__(self, "attribute_tolerances", tols)
        if self.extract is not None:
            if not callable(self.extract):
                raise ConfigError(f"FeatureKind({self.name}).extract must be callable")
            if self.geometry != "point":
                raise ConfigError(
                    f"FeatureKind({self.name}): extractors are supported for point kinds, "
                    f"not {self.geometry!r}"
                )


#: today's kinds (paper §4, plus corners); labels kept from before the registry
FOREGROUND_POINT = 0
EDGE_CW = 1
EDGE_CCW = 2
CORNER = 3
LINE = 8

_BUILTIN = (
    FeatureKind(
        "foreground_point",
        FOREGROUND_POINT,
        "point",
        description="small cluster nearer than both neighbours (poles, legs)",
    ),
    FeatureKind(
        "edge_cw",
        EDGE_CW,
        "point",
        description="foreground edge, background clockwise (at a smaller angle)",
    ),
    FeatureKind(
        "edge_ccw", EDGE_CCW, "point", description="foreground edge, background counter-clockwise"
    ),
    FeatureKind(
        "corner",
        CORNER,
        "point",
        description="intersection of two lines of one cluster at a large angle",
    ),
    FeatureKind("line", LINE, "line", description="total-least-squares wall segment"),
)
_BUILTIN_NAMES = frozenset(k.name for k in _BUILTIN)

_lock = threading.Lock()
_kinds: dict[int, FeatureKind] = {k.label: k for k in _BUILTIN}


def register_kind(new: FeatureKind) -> FeatureKind:
    """Add a feature kind to the registry; returns it.

    Raises
    ------
    ConfigError
        When its name or label is taken, or for a new kind of line geometry (every line
        feature is of the built-in kind ``line`` today).
    """
    if not isinstance(new, FeatureKind):
        raise ConfigError(f"register_kind: expected a FeatureKind, got {type(new).__name__}")
    if new.geometry == "line":
        # the line group of Features has no label array: its nodes are all of kind "line"
        raise ConfigError(
            f"register_kind: {new.name!r}: new kinds of line geometry are not supported yet "
            "(every line feature is of the built-in kind 'line'); register a point kind"
        )
    with _lock:
        for k in _kinds.values():
            if k.name == new.name or k.label == new.label:
                raise ConfigError(
                    f"register_kind: {new.name!r} (label {new.label}) clashes with the "
                    f"registered kind {k.name!r} (label {k.label})"
                )
        _kinds[new.label] = new
    return new


def unregister_kind(name: str) -> None:
    """Remove a kind added by :func:`register_kind`; built-in kinds stay.

    Raises
    ------
    ConfigError
        For a built-in or unknown kind.
    """
    if name in _BUILTIN_NAMES:
        raise ConfigError(f"unregister_kind: {name!r} is a built-in kind and cannot be removed")
    with _lock:
        for label, k in list(_kinds.items()):
            if k.name == name:
                del _kinds[label]
                return
    raise ConfigError(f"unregister_kind: no kind named {name!r} is registered")


@contextlib.contextmanager
def registered(*new: FeatureKind) -> Iterator[tuple[FeatureKind, ...]]:
    """Register kinds for the duration of a ``with`` block (tests, scripts)."""
    done = []
    try:
        for k in new:
            done.append(register_kind(k))
        yield tuple(done)
    finally:
        for k in reversed(done):
            unregister_kind(k.name)


def registered_kinds() -> tuple[FeatureKind, ...]:
    """Every registered kind, in label order."""
    with _lock:
        return tuple(_kinds[label] for label in sorted(_kinds))


def extractor_kinds() -> tuple[FeatureKind, ...]:
    """The registered kinds that bring an extractor, in label order."""
    return tuple(k for k in registered_kinds() if k.extract is not None)


def kind(key: int | str) -> FeatureKind:
    """The registered kind with this label (int) or name (str).

    Raises
    ------
    ConfigError
        When no such kind is registered.
    """
    with _lock:
        if isinstance(key, str):
            for k in _kinds.values():
                if k.name == key:
                    return k
        elif int(key) in _kinds:
            return _kinds[int(key)]
    raise ConfigError(
        f"no feature kind {key!r} is registered (known: "
        f"{', '.join(f'{k.name}={k.label}' for k in registered_kinds())})"
    )


def kind_name(label: int) -> str:
    """The name of the registered kind with this label, ``"label_<n>"`` when none is."""
    with _lock:
        k = _kinds.get(int(label))
    return k.name if k is not None else f"label_{int(label)}"


def kind_names(geometry: str | None = None) -> dict[int, str]:
    """``{label: name}`` of the built-in kinds and those registered, optionally of one
    geometry, in label order.

    A kind registered inside a ``with registered(...)`` block is listed only inside it.
    """
    return {k.label: k.name for k in registered_kinds() if geometry in (None, k.geometry)}


def attribute_tolerances(kind_labels: np.ndarray) -> tuple[np.ndarray, int]:
    """Per-node attribute tolerances for nodes of the given kinds.

    Parameters
    ----------
    kind_labels : ndarray, shape (N,)
        The kind label of each node.

    Returns
    -------
    tolerances : ndarray, shape (N, A)
        Tolerance of each node's attribute k (``inf`` where its kind has fewer than k+1
        attributes); ``A`` is the largest attribute count among the kinds present.
    A : int
    """
    labels = np.asarray(kind_labels, dtype=np.int64).ravel()
    present = {int(v): kind(int(v)) for v in np.unique(labels)}
    A = max((len(k.attributes) for k in present.values()), default=0)
    tol = np.full((labels.size, A), np.inf)
    for v, k in present.items():
        if k.attributes:
            tol[labels == v, : len(k.attributes)] = k.attribute_tolerances
    return tol, A
