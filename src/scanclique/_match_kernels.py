"""Compiled kernels of the matching stages, gathered (private; see :mod:`scanclique.refine`,
:mod:`scanclique.pose` and :mod:`scanclique.match`).

Everything that runs once per hypothesis or once per point of a hypothesis is compiled, so
that a whole scan match costs a handful of calls from Python instead of thousands of
small NumPy operations. The kernels live in :mod:`scanclique._kernels`, one module per
concern; this module gathers the matcher's under one name:

==============  ======================================================================
``algebra``     angle wrapping, 3x3 solves, 2x2 eigenvectors
``neighbours``  nearest neighbours by bearing window, surface normals, scan arrays
``score``       the raw-scan score of poses (agreement, free-space conflicts), batches
``icp``         point-to-line ICP
``pose``        poses from mapped features (paper §6): closed form, consistency, GN
``hypotheses``  the clique hypotheses of a match under a node budget (paper §5.3)
``refine``      the best few hypotheses: estimate, score, ICP, score in one call
``search``      the raw-scan pose search (orientation histograms, Hough votes)
==============  ======================================================================

Nearest-neighbour search without a tree. A scan's points are sorted by bearing (the angle
of the point seen from the sensor, in ``(-pi, pi]``). A reference point within distance
``d`` of a query point at range ``r > d`` has a bearing within ``asin(d / r)`` of the
query's (the distance from the query to the ray at angle ``dphi`` is ``r sin(dphi)``), so
only that window of the sorted points is searched: exact, and a few points per query on a
laser scan. A query nearer than ``d`` to the sensor searches everything.

Poses are ``(x, y, theta)`` mapping B's frame into A's: ``p_a = R(theta) p_b + (x, y)``.
Feature arrays follow :class:`scanclique.features.Features`: points ``(Np, 2)`` with
covariances ``(Np, 2, 2)``, lines ``(Nl, 2)`` as ``(rho, alpha)`` with covariances; node
``k`` of a feature graph is point ``k`` when ``k < Np`` and line ``k - Np`` otherwise.

Caching: the kernels are compiled once and cached in the directory that
:func:`scanclique._kernels.ensure_cache` stamps with a hash of every kernel source, so an
edit of any kernel recompiles everything that may call it.
"""

# ruff: noqa: F401 (this module re-exports)
from __future__ import annotations

from ._kernels.algebra import (
    smallest_eigvec2,
    solve3,
    wrap,
)
from ._kernels.hypotheses import (
    _FINISHED,
    _NODE_LIMIT,
    _TIME_LIMIT,
    _append,
    _distinct_cliques,
    _maximum_of,
    hypothesis_cliques,
)
from ._kernels.icp import (
    ICP_HUBER,
    ICP_POINT_WEIGHT,
    ICP_STEP_R,
    ICP_STEP_T,
    icp,
)
from ._kernels.neighbours import (
    _evenly_idx,
    _half_window,
    _keep_nearest,
    _search,
    _window,
    agreement_count,
    cloud_arrays,
    cloud_normals,
    has_near,
    has_near_polar,
    lower,
    make_index,
    nearest_many,
    nearest_one,
    scan_arrays,
    upper,
)
from ._kernels.pose import (
    _blocks,
    _normal_equations,
    closed_form,
    closed_form_batch,
    consistent,
    covariance,
    lsq_pose,
)
from ._kernels.refine import (
    CloudArrays,
    FeatureArrays,
    RefineOut,
    RefineParams,
    ScoreParams,
    _points_first_into,
    refine_candidates,
)
from ._kernels.score import (
    _in_free_space,
    _one_way,
    _same_pose,
    conflict_count,
    pose_score,
    score_batch,
)
from ._kernels.search import (
    VOTE_GRID_MAX,
    VOTE_LEADERS,
    _orientation_histogram,
    rotation_candidates,
    search_seeds,
    translation_votes,
)
