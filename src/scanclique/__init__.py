"""scanclique: graph-theoretic data association between batch observations.

Bailey, Nebot, Rosenblatt and Durrant-Whyte, "Data Association for Mobile Robot
Navigation: A Graph Theoretic Approach", ICRA 2000: features of two scans become typed
nodes of complete graphs whose edges carry invariants; the maximum clique of their
correspondence graph is the association, and the relative pose follows from it.

>>> import scanclique as sc
>>> pair = sc.sim.simulate_pair(np.random.default_rng(0))
>>> m = sc.match_scans(pair.scan_a, pair.scan_b)
>>> m.pose is not None
True
"""

import numpy as np  # noqa: F401  (doctest namespace)

from . import sim
from .config import MatchConfig, paper_config
from .errors import ScanCliqueError
from .features import Features, extract_features
from .geometry import Pose2
from .io import read_scans
from .match import FeaturePair, ScanMatch, match_scans, prepare_scan
from .scan import Scan

__version__ = "0.1.0"
__all__ = [
    "FeaturePair",
    "Features",
    "MatchConfig",
    "Pose2",
    "Scan",
    "ScanCliqueError",
    "ScanMatch",
    "__version__",
    "extract_features",
    "match_scans",
    "paper_config",
    "prepare_scan",
    "read_scans",
    "sim",
]
