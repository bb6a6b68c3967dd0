"""Mapping a whole log (the paper's first application, §2; issue 12).

>>> import scanclique as sc                                # doctest: +SKIP
>>> result = sc.mapping.map_scans(sc.read_scans("fr079.clf.bz2"))   # doctest: +SKIP

:func:`map_scans` (front end by matching, verified loop closures selected by PCM, GTSAM
pose-graph optimisation) returns a :class:`MapResult`; :func:`run_map` also writes the
outputs (trajectory.tum, graph.g2o, map.pgm/map.yaml, map.png, report.json).
:class:`OnlineMapper` is the same mapper fed one scan at a time, answering with each
scan's pose as soon as it comes.
"""

from .config import BackEndConfig, FrontEndConfig, LoopConfig, MapConfig, OccupancyConfig
from .loops import LoopClosure
from .online import OnlineMapper, OnlineRun, map_online
from .pipeline import Edge, MapResult, OdometryCheck, OdometryScale, map_scans
from .run import MapRun, run_map

__all__ = [
    "BackEndConfig",
    "Edge",
    "FrontEndConfig",
    "LoopClosure",
    "LoopConfig",
    "MapConfig",
    "MapResult",
    "MapRun",
    "OdometryCheck",
    "OdometryScale",
    "OnlineMapper",
    "OnlineRun",
    "OccupancyConfig",
    "map_online",
    "map_scans",
    "run_map",
]
