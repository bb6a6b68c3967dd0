"""SE(2) pose-graph optimisation with GTSAM (issue 12, part 3).

Nodes are scan poses ``x_i`` (the sensor frame of scan ``i`` in the map frame); an edge
``(i, j, Z, P)`` says ``x_i^-1 x_j = Z`` (``Z`` maps points of scan ``j`` into scan ``i``)
with the covariance ``P`` of ``Z``'s ``(x, y, theta)`` as the matcher gives it (in frame
``i``'s axes). GTSAM's ``BetweenFactorPose2`` measures the error in the tangent space at
``Z`` (right perturbation ``Z Exp(xi)``), so ``P`` is rotated into ``Z``'s own axes first
(:func:`tangent_covariance`). Scan 0 is held at the identity by a tight prior; the batch is
solved by Levenberg–Marquardt (Dellaert & Kaess, "Factor graphs for robot perception",
2017). GTSAM is imported lazily: ``import scanclique`` does not load it.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Sequence

import numpy as np

from ..errors import solving
from ..geometry import Pose2

__all__ = [
    "tangent_covariance",
    "tangent_covariances",
    "map_frame_covariances",
    "optimize",
    "PoseGraph",
]

log = logging.getLogger(__name__)

#: variance standing in for an infinite one (a direction a match does not fix)
BIG_VARIANCE = 1e4

#: what a map's :class:`~scanclique.errors.PoseGraphError` asks the user to check
ODOMETRY_HINT = (
    "Is the odometry in metres and radians (Scan.odometry)? use_odometry=False "
    "(--no-odometry) maps from the scans alone."
)


def levenberg_marquardt(gtsam, graph, values, max_iterations: int = 100):
    """GTSAM's Levenberg–Marquardt on the factor graph ``graph`` from ``values`` (the
    optimised ``Values``), at most ``max_iterations`` iterations, stopping when the error
    changes by less than 1e-6 (relative or absolute). Its ``RuntimeError`` passes through
    (callers wrap it in :func:`~scanclique.errors.solving`)."""
    params = gtsam.LevenbergMarquardtParams()
    params.setMaxIterations(int(max_iterations))
    params.setRelativeErrorTol(1e-6)
    params.setAbsoluteErrorTol(1e-6)
    return gtsam.LevenbergMarquardtOptimizer(graph, values, params).optimize()


def _gtsam():
    import gtsam  # noqa: PLC0415  (lazy: heavy, optional at import time)

    return gtsam


def tangent_covariance(Z: Pose2, P: np.ndarray) -> np.ndarray:
    """The covariance ``P`` of ``(x, y, theta)`` of ``Z`` (frame-``i`` axes) expressed in
    ``Z``'s tangent space (GTSAM's convention for Pose2 factors), made finite, symmetric and
    positive definite.

    ``Z Exp(xi) ~ (t + R(theta) xi_xy, theta + xi_theta)`` to first order, so
    ``xi = J (dx, dy, dtheta)`` with ``J = diag(R(theta)^T, 1)``.
    """
    P = np.array(P, dtype=float)
    bad = ~np.isfinite(P)
    if bad.any():
        d = np.diag(P).copy()
        P[bad] = 0.0
        np.fill_diagonal(P, np.where(np.isfinite(d), d, BIG_VARIANCE))
    c, s = math.cos(Z.theta), math.sin(Z.theta)
    J = np.array([[c, s, 0.0], [-s, c, 0.0], [0.0, 0.0, 1.0]])
    Q = J @ P @ J.T
    Q = 0.5 * (Q + Q.T)
    w, V = np.linalg.eigh(Q)
    w = np.clip(w, 1e-10, BIG_VARIANCE)
    return (V * w) @ V.T


def _tangent_jacobians(thetas: np.ndarray) -> np.ndarray:
    """``J = diag(R(theta)^T, 1)`` (m, 3, 3) for headings ``thetas`` (m,): the Jacobian
    from a pose's ``(x, y, theta)`` perturbation in the parent's axes to its tangent space."""
    c, s = np.cos(thetas), np.sin(thetas)
    J = np.zeros((len(thetas), 3, 3))
    J[:, 0, 0], J[:, 0, 1], J[:, 1, 0], J[:, 1, 1], J[:, 2, 2] = c, s, -s, c, 1.0
    return J


def tangent_covariances(thetas: np.ndarray, P: np.ndarray) -> np.ndarray:
    """:func:`tangent_covariance` of many edges at once: ``thetas`` (m,) the headings of
    the measurements ``Z``, ``P`` (m, 3, 3) their covariances; returns (m, 3, 3)."""
    P = np.array(P, dtype=float)
    bad = ~np.isfinite(P)
    if bad.any():
        diag = np.einsum("kii->ki", P).copy()
        P[bad] = 0.0
        idx = np.arange(3)
        P[:, idx, idx] = np.where(np.isfinite(diag), diag, BIG_VARIANCE)
    J = _tangent_jacobians(thetas)
    Q = J @ P @ J.transpose(0, 2, 1)
    Q = 0.5 * (Q + Q.transpose(0, 2, 1))
    w, V = np.linalg.eigh(Q)
    w = np.clip(w, 1e-10, BIG_VARIANCE)
    return (V * w[:, None, :]) @ V.transpose(0, 2, 1)


def map_frame_covariances(thetas: np.ndarray, Q: np.ndarray) -> np.ndarray:
    """The inverse of :func:`tangent_covariances`: covariances ``Q`` (m, 3, 3) in the
    tangent spaces of poses of headings ``thetas`` (m,) (GTSAM's convention for a Pose2's
    marginal, a right perturbation ``x Exp(xi)``) as covariances of the poses' ``(x, y,
    theta)`` in the parent (map) frame's axes: ``J^T Q J`` with ``J = diag(R(theta)^T, 1)``."""
    J = _tangent_jacobians(thetas)
    P = J.transpose(0, 2, 1) @ np.asarray(Q, dtype=float) @ J
    return 0.5 * (P + P.transpose(0, 2, 1))


class PoseGraph:
    """A growing pose graph: nodes with initial guesses, between edges, batch solve.

    Examples
    --------
    >>> g = PoseGraph()
    >>> for k in range(4):
    ...     g.add_node(k, Pose2(k * 1.1, 0.0, 0.0))
    >>> for k in range(3):
    ...     g.add_edge(k, k + 1, Pose2(1.0, 0.0, 0.0), np.diag([0.01, 0.01, 0.001]))
    >>> poses = g.optimize()
    >>> round(poses[3].x, 6)
    3.0
    """

    def __init__(self, anchor: bool = True) -> None:
        gtsam = _gtsam()
        self._g = gtsam
        self.graph = gtsam.NonlinearFactorGraph()
        self.values = gtsam.Values()
        self.n_edges = 0
        self._anchored = not anchor
        self.result = None

    def add_node(self, key: int, guess: Pose2) -> None:
        """Node ``key`` with initial guess ``guess``; the first node added is anchored
        (unless the graph was made with ``anchor=False``: its priors place it)."""
        gtsam = self._g
        self.values.insert(key, gtsam.Pose2(guess.x, guess.y, guess.theta))
        if not self._anchored:
            noise = gtsam.noiseModel.Diagonal.Sigmas(np.array([1e-6, 1e-6, 1e-8]))
            self.graph.add(
                gtsam.PriorFactorPose2(key, gtsam.Pose2(guess.x, guess.y, guess.theta), noise)
            )
            self._anchored = True

    def add_edge(
        self, i: int, j: int, Z: Pose2, covariance: np.ndarray, robust: str = "none",
        robust_scale: float = 1.0, tangent: np.ndarray | None = None,
    ) -> None:  # fmt: skip
        """Edge ``x_i^-1 x_j = Z`` with the covariance of ``Z`` (frame-``i`` axes), under
        an optional M-estimator (``"cauchy"``, ``"huber"``); ``tangent``: the covariance
        already in ``Z``'s tangent space (:func:`tangent_covariances`), when known."""
        gtsam = self._g
        if tangent is None:
            tangent = tangent_covariance(Z, covariance)
        noise = self._robust(gtsam.noiseModel.Gaussian.Covariance(tangent), robust, robust_scale)
        self.graph.add(gtsam.BetweenFactorPose2(i, j, gtsam.Pose2(Z.x, Z.y, Z.theta), noise))
        self.n_edges += 1

    def _robust(self, noise, robust: str, scale: float):
        """``noise`` under the M-estimator ``robust`` (``"cauchy"``, ``"huber"``, or
        ``"none"``: as it is) of scale ``scale``."""
        m = self._g.noiseModel
        if robust == "cauchy":
            return m.Robust.Create(m.mEstimator.Cauchy.Create(scale), noise)
        if robust == "huber":
            return m.Robust.Create(m.mEstimator.Huber.Create(scale), noise)
        return noise

    def add_prior(
        self, key: int, pose: Pose2, sigmas, robust: str = "none", robust_scale: float = 1.0
    ) -> None:
        """A prior on node ``key``: at ``pose`` with standard deviations ``sigmas`` ``(x,
        y, theta)`` (m, m, rad; tangent space), under an optional M-estimator as
        :meth:`add_edge`."""
        gtsam = self._g
        noise = gtsam.noiseModel.Diagonal.Sigmas(np.asarray(sigmas, dtype=float))
        noise = self._robust(noise, robust, robust_scale)
        self.graph.add(gtsam.PriorFactorPose2(key, gtsam.Pose2(pose.x, pose.y, pose.theta), noise))

    def optimize(self, max_iterations: int = 100) -> dict[int, Pose2]:
        """Levenberg–Marquardt from the initial guesses; the optimised pose of every node."""
        gtsam = self._g
        with solving("PoseGraph.optimize", ODOMETRY_HINT):
            result = levenberg_marquardt(gtsam, self.graph, self.values, max_iterations)
        self.result = result
        keys = list(gtsam.KeyVector(result.keys()))
        arr = gtsam.utilities.extractPose2(result)
        return {int(k): Pose2(a[0], a[1], a[2]) for k, a in zip(keys, arr, strict=True)}

    def covariances(self) -> dict[int, np.ndarray]:
        """Covariance ``(3, 3)`` of every node's ``(x, y, theta)`` (map-frame axes; m, rad)
        from the marginals of the graph linearised at the last :meth:`optimize` result
        (GTSAM ``Marginals``; robust edges with the weights they have there), relative
        to the anchored first node. A first-order (Laplace) estimate: as good as the edges'
        covariances."""
        gtsam = self._g
        result = self.result
        if result is None:
            raise RuntimeError("PoseGraph.covariances: optimize() first")
        with solving("PoseGraph.covariances", ODOMETRY_HINT):
            marginals = gtsam.Marginals(self.graph, result)
        keys = [int(k) for k in gtsam.KeyVector(result.keys())]
        arr = gtsam.utilities.extractPose2(result)
        Q = np.array([marginals.marginalCovariance(k) for k in keys])
        P = map_frame_covariances(np.asarray(arr)[:, 2], Q)
        return dict(zip(keys, P, strict=True))

    def error(self, poses: dict[int, Pose2] | None = None) -> float:
        """The graph's total error at ``poses`` (default: the initial guesses)."""
        gtsam = self._g
        if poses is None:
            return float(self.graph.error(self.values))
        v = gtsam.Values()
        for k, p in poses.items():
            v.insert(k, gtsam.Pose2(p.x, p.y, p.theta))
        return float(self.graph.error(v))


def optimize(
    guesses: Sequence[Pose2],
    edges: Sequence[tuple[int, int, Pose2, np.ndarray, bool]],
    *,
    robust: str = "cauchy",
    robust_scale: float = 1.0,
    max_iterations: int = 100,
) -> list[Pose2]:
    """Optimise a pose graph in batch.

    Parameters
    ----------
    guesses : sequence of Pose2
        Initial guess of every node ``0 .. n-1`` (node 0 is held fixed).
    edges : sequence of (i, j, Z, covariance, is_loop)
        ``x_i^-1 x_j = Z``; loop-closure edges (``is_loop``) get the robust kernel.

    Returns
    -------
    list of Pose2
        The optimised poses, node order.
    """
    g = PoseGraph()
    for k, p in enumerate(guesses):
        g.add_node(k, p)
    if not edges:
        return list(guesses)
    Q = tangent_covariances(
        np.array([e[2].theta for e in edges]), np.array([e[3] for e in edges], dtype=float)
    )
    for (i, j, Z, P, is_loop), q in zip(edges, Q, strict=True):
        g.add_edge(i, j, Z, P, robust if is_loop else "none", robust_scale, tangent=q)
    out = g.optimize(max_iterations)
    return [out[k] for k in range(len(guesses))]
