"""Evaluation of estimated trajectories against independent references.

:mod:`scanclique.eval.relations` implements the relation metric of Kümmerle et al. 2009
(the SLAM benchmark of the Freiburg raw logs), as Cartographer's
``compute_relations_metrics`` computes it.
"""

from .relations import (
    Relation,
    RelationErrors,
    SplitErrors,
    frame_mounting,
    join_relations,
    read_relations,
    relation_errors,
    relation_metrics,
    relation_rows,
    trajectory_relation_metrics,
)

__all__ = [
    "Relation",
    "RelationErrors",
    "SplitErrors",
    "frame_mounting",
    "join_relations",
    "read_relations",
    "relation_errors",
    "relation_metrics",
    "relation_rows",
    "trajectory_relation_metrics",
]
