"""scanclique: graph-theoretic data association between batch observations.

Bailey, Nebot, Rosenblatt and Durrant-Whyte, "Data Association for Mobile Robot
Navigation: A Graph Theoretic Approach", ICRA 2000: features of two scans become typed
nodes of complete graphs whose edges carry invariants; the maximum clique of their
correspondence graph is the association, and the relative pose follows from it.

The public names load on first use (PEP 562): ``import scanclique`` reads no kernels and
imports neither numba nor the applications' dependencies (GTSAM, SQLite, dask).

* the pairwise core: :func:`read_scans`, :func:`match_scans`, :func:`prepare_scan`,
  :class:`Scan`, :class:`Pose2`, :class:`MatchConfig`, :func:`paper_config`;
* the applications (paper §2): :func:`map_scans` (:mod:`scanclique.mapping`),
  :mod:`scanclique.slam` (EKF-SLAM feature tracking), :mod:`scanclique.places` (a place
  database);
* :mod:`scanclique.sim`, the simulator of the tests and the demo.

>>> import scanclique as sc
>>> pair = sc.sim.simulate_pair(np.random.default_rng(0))
>>> m = sc.match_scans(pair.scan_a, pair.scan_b)
>>> m.pose is not None
True
"""

from __future__ import annotations

import importlib

import numpy as np  # noqa: F401  (doctest namespace)

__version__ = "0.1.0"

#: public name -> (module, attribute or None for the module itself)
_LAZY = {
    "FeaturePair": ("scanclique.match", "FeaturePair"),
    "Features": ("scanclique.features", "Features"),
    "MatchConfig": ("scanclique.config", "MatchConfig"),
    "Pose2": ("scanclique.geometry", "Pose2"),
    "Scan": ("scanclique.scan", "Scan"),
    "ScanCliqueError": ("scanclique.errors", "ScanCliqueError"),
    "ScanMatch": ("scanclique.match", "ScanMatch"),
    "extract_features": ("scanclique.features", "extract_features"),
    "match_scans": ("scanclique.match", "match_scans"),
    "map_scans": ("scanclique.mapping", "map_scans"),
    "MapResult": ("scanclique.mapping", "MapResult"),
    "paper_config": ("scanclique.config", "paper_config"),
    "prepare_scan": ("scanclique.match", "prepare_scan"),
    "read_scans": ("scanclique.io", "read_scans"),
    "sim": ("scanclique.sim", None),
    "kinds": ("scanclique.kinds", None),
    "FeatureKind": ("scanclique.kinds", "FeatureKind"),
    "register_kind": ("scanclique.kinds", "register_kind"),
    "mapping": ("scanclique.mapping", None),
    "places": ("scanclique.places", None),
    "slam": ("scanclique.slam", None),
}

__all__ = ["__version__", *sorted(_LAZY)]


def __getattr__(name: str):
    try:
        module, attr = _LAZY[name]
    except KeyError:
        raise AttributeError(f"module 'scanclique' has no attribute {name!r}") from None
    mod = importlib.import_module(module)
    value = mod if attr is None else getattr(mod, attr)
    globals()[name] = value  # the next access is a plain lookup
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(_LAZY))
