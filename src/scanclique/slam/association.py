"""Data association of a batch of range-bearing observations with a feature map.

Three methods behind one interface (:func:`associate`, and
:func:`associate_predicted` inside the filter):

``"nn"``
    Nearest neighbour with individual-compatibility gates: each observation's Mahalanobis
    distance to each predicted landmark, gated by the chi-square bound of 2 degrees of
    freedom; pairs taken greedily by increasing distance, one-to-one.
``"jcbb"``
    Joint compatibility branch and bound (J. Neira and J. D. Tardos, "Data association in
    stochastic mapping using the joint compatibility test", IEEE Trans. Robotics and
    Automation 17(6), 2001): the largest set of pairs whose joint innovation passes the
    chi-square gate of 2n degrees of freedom with the full covariance (ties: the least
    joint distance). Exact, over the individually compatible pairs.
``"clique"``
    Batch graph association (Bailey et al., ICRA 2000, section 5; the paper's feature
    tracking argument of section 2): the observed features and the predicted map features
    each form a complete graph whose edges carry the point-point distance, an invariant of
    the vehicle pose; the correspondence graph joins two pairs whose distances agree within
    a tolerance from both covariances (:func:`point_distance_invariants`); its maximum
    clique is the association, checked by a joint compatibility gate with the full
    covariance (pairs outside the individual gate NN and JCBB use are dropped, then the
    pair with the worst individual distance until it passes). Candidate pairs are gated
    individually with a much looser bound, so that the graph finds the clique under pose
    error, and on the tree diameter (node attribute, :class:`AssociationConfig`).
    Maximum cliques that pass the joint gate with nearly as small a joint distance (a
    likelihood ratio under 10) and pair nothing differently are one hypothesis, each
    missing members (a true edge outside the tolerance): their union is taken when it
    passes the joint gate too. A rival that pairs an observation or a landmark differently,
    or that the union's joint gate refuses, makes the step *ambiguous*: only the pairs
    they all agree on are kept (``AssociationConfig.ambiguity``).
``"clique-jcbb"``
    Hybrid: the maximum cliques propose, joint compatibility verifies: JCBB restricted to
    the pairs of the maximum cliques (the largest jointly compatible set of geometrically
    consistent pairs). Several distinct maximum cliques mark the step ambiguous; the
    observations they disagree on start no landmark.

For every method, a loop closure needs support (``AssociationConfig.closure_crowding``):
a pair whose gate the vehicle's drift has opened wide enough to hold a neighbouring tree
(:func:`gate_crowding`) is kept only when another such pair of the same scan is jointly
compatible with it.

Observations left unpaired become a new landmark when they are far from every landmark
(beyond the chi-square bound at ``new_probability``), else they are rejected.
"""

from __future__ import annotations

import functools
import math
import time
from dataclasses import dataclass

import numpy as np

from ..config import check_choice, check_positive, check_probability, check_types
from ..errors import ConfigError, StepError
from ..graph import point_distance_invariants  # the point-point invariant, in the core
from .models import inverse_observe, observe, wrap
from .reader import as_numbers, as_observations

__all__ = [
    "NEW",
    "REJECTED",
    "METHODS",
    "AssociationConfig",
    "Association",
    "Predicted",
    "associate",
    "associate_predicted",
    "point_distance_invariants",
    "joint_distance",
    "gate_crowding",
    "chi2_bound",
]

#: Association codes of an observation that is paired with no landmark.
NEW = -1
REJECTED = -2
METHODS = ("nn", "jcbb", "clique", "clique-jcbb")


@functools.lru_cache(maxsize=4096)
def chi2_bound(dof: int, probability: float) -> float:
    """The chi-square quantile of ``dof`` degrees of freedom at ``probability``."""
    from scipy.stats import chi2

    return float(chi2.ppf(probability, dof))


@dataclass(frozen=True, slots=True)
class AssociationConfig:
    """Parameters of the association (all methods).

    Attributes
    ----------
    gate_probability : float
        Chi-square probability of the individual (NN, JCBB candidates) and joint (JCBB,
        clique) gates.
    new_probability : float
        An unpaired observation whose least Mahalanobis distance to any landmark exceeds
        the chi-square bound at this probability starts a new landmark; otherwise it is
        rejected (too close to a landmark to be another, too far to be it).
    clique_probability : float
        The looser individual gate of the clique method's candidate pairs.
    invariant_sigmas : float
        Correspondence-graph tolerance: two pairs are consistent when their point-point
        distances differ by at most this many standard deviations of the difference.
        2 (was 3): each spurious vertex the graph admits can join a clique, and with
        clutter the maximum clique of a 3-sigma graph admits clutter pairs and ties with
        distinct cliques (ambiguous steps, their pairs dropped); a clique of several
        pairs loses little when one true edge in twenty falls outside 2 sigma. On
        Victoria Park with 10 clutter detections per scan (clique, with
        ``attribute_gate`` 2): GPS RMSE 3.13 m (start) / 2.31 m (SE(2)), 167 landmarks,
        against 35.3 / 13.95 m, 366 landmarks with both at 3; on 3 simulated parks
        ANEES 3.08 (3.55 at 3), position RMSE 1.30 m (1.55).
    attribute_tolerance : float or None
        When set, and attributes are given, a candidate pair's attributes (tree diameters,
        m) must agree within this (the node attribute of the correspondence graph).
    attribute_sigma : (2,) float or None
        Standard deviation of an observed attribute about its landmark's, growing with
        the range: ``a + b * range`` (m, m per m). When set, and attributes are given, a
        candidate pair of the clique methods must agree within ``attribute_gate`` of these
        (the correspondence graph's node attribute). The default is the spread of the
        Victoria Park detector's trunk diameters about each tree's median over the
        associated pairs of a run (robust standard deviation 0.06 m within 10 m, 0.07 at
        10-20 m, 0.11 at 20-30 m, 0.15 at 30-40 m).
    attribute_gate : float
        The attribute gate in standard deviations: 2 (was 3), for the reason of
        ``invariant_sigmas``. Alone (``invariant_sigmas`` 3) it takes Victoria Park at
        10 clutter detections per scan from 35.3 / 13.95 m to 3.09 / 1.83 m (start /
        SE(2)); 2.5 gives 11.9 / 8.7 m: a steep dependence, on clutter whose diameters
        the benchmark draws uniform in 0.05-0.6 m (:func:`~scanclique.slam.run.inject_clutter`),
        so a detector whose false trunks look like trees gains less.
    ambiguity_probability : float
        Two distinct hypotheses of the same size (clique method) are ambiguous unless the
        likelier one's joint distance is smaller by more than the chi-square bound of 2
        degrees of freedom at this probability (0.9: a likelihood ratio of 10); an
        ambiguous scan keeps only the pairs the hypotheses share, otherwise the likelier
        hypothesis is taken.
    ambiguity : {"merge", "distinct", "conflict"}
        Which hypotheses of the clique method are rivals (an ambiguous step needs a rival
        as likely as the best). Cliques {a, b, c} and {a, b, d} can differ only because
        the 2-sigma edge test missed the true edge c-d (one true edge in twenty: a clique
        of 15 pairs has 105 edges, so with many landmarks in view most scans hold several
        maximum cliques). ``"merge"`` (the default): the equally likely cliques are merged
        into the best while their union stays one-to-one and passes the joint gate; the
        others are its rivals. ``"distinct"`` (the default until session 27): any other
        maximum clique is a rival, and an ambiguous step keeps only {a, b} and starts no
        landmark from c or d. ``"conflict"``: only a clique that pairs an observation or
        a landmark differently from the best is a rival, and the likelier clique is
        taken. The hybrid ``clique-jcbb`` reads ``"merge"`` as ``"distinct"``.
        Measured in session 27, ``"merge"`` against ``"distinct"`` (clique): on 40
        simulated parks ANEES 3.93 -> 3.76 (the 40-run band [2.29, 3.81]), steps inside
        42.4 -> 53.6 %, pose RMSE 1.26 -> 1.24 m, runs above ANEES 10 1 -> 0; on
        simulated parks with 19 trees in view per scan (600 trees 1.5 m apart, 2 laps, 6
        seeds) pose RMSE 0.670 / 0.816 / 1.034 / 2.028 / 1.286 / 2.032 m -> 0.862 / 0.697 /
        0.480 / 0.530 / 1.334 / 0.671 (mean 1.31 -> 0.85; NN 0.62 / 0.73 / 0.68 / 0.89 /
        1.37 / 5.76), the two runs with over 500 wrong pairs gone; on the 5 rooms with
        0.5 and 1 spurious detections per frame 0.325 / 0.228 -> 0.308 / 0.200 m, the
        others within 0.002 m; on Victoria Park 3.533 / 1.523, 3.375 / 1.507, 3.003 /
        2.206 m -> 3.543 / 1.525, 3.356 / 1.516, 3.069 / 2.025 m at 0, 5, 10 clutter
        detections per scan (start / SE(2); ambiguous scans 1 / 247 / 700 -> 0 / 202 /
        485); on the benchmark's 5 parks ANEES 3.58 -> 3.71 and pose RMSE 1.29 -> 1.35 m.
        Earlier, ``"conflict"`` against ``"distinct"``: Victoria Park 3.46 / 1.57 m
        unchanged without clutter, 3.53 / 1.62 m (was 3.51 / 1.61) at 5, 3.04 / 2.23 m
        (3.13 / 2.31) at 10; on 5 simulated parks ANEES 2.99 -> 3.37 and pose RMSE 1.11
        -> 1.23 m; on the dense parks above 0.864 / 0.648 / 0.705 / 0.624 / 1.008 / 4.316
        m (session 27).
    clique_individual_gate : bool
        The clique method's verification drops the clique's pairs outside the individual
        gate at ``gate_probability`` (the one NN and JCBB use) before the joint test: the
        loose candidate gate lets the graph find the clique under pose error, but a joint
        test of many pairs alone would pass one spurious pair among good ones.
    jcbb_node_limit : int
        Node budget of the branch and bound (the best hypothesis so far is kept).
    clique_limit : int
        At most this many maximum cliques are examined (ambiguity shows as several).
    node_limit : int
        Search nodes the clique search may spend per scan (the budget that decides the
        result, the same on every machine; Victoria Park's graphs need a few hundred).
    closure_crowding : float or None
        A pair whose gate the drift opens to more than this many unrelated features
        (:func:`gate_crowding`: the area of the vehicle's and the map's uncertainty about an
        established landmark, times the map's density) is a *closure* pair: the
        re-observation of a landmark the vehicle has drifted from. It is kept only when at
        least ``closure_support`` closure pairs of the same batch are jointly compatible:
        the relative geometry of several old landmarks tells a revisit from a neighbouring
        tree, one landmark alone does not (the paper's argument for batch association,
        section 2). Unsupported closure pairs are unpaired and start no landmark. All
        methods; None turns it off. The failing simulated parks session 23 traced (ANEES far
        above the band; park 1 with NN, park 3 with the clique) close the loop on a
        neighbouring tree 4.8-7.3 m from the right one, a single old landmark paired beside
        landmarks seen moments before. With 0.1, on 40 simulated parks (the default
        :class:`~scanclique.slam.SlamConfig`, truth and filter): runs ending above ANEES 10
        fall from 6 to 1 (clique) and from 6 to 2 (NN), pairs against the truth 0.40 -> 0.00
        % wrong (clique), duplicate pairs per run 10.4 -> 0, position RMSE 1.76 -> 1.26 m
        (clique) and 1.72 -> 1.45 m (NN); 0.05 gives as much (NN 1 run of 40), 0.2 less
        (clique 2, NN 4), 0.5 nothing. Victoria Park is identical to the last millimetre at
        0, 5 (three clutter draws) and 10 clutter detections per scan for the clique (3.533
        / 1.523 m start / SE(2) without clutter): its closures come with several trees. On
        the simulated rooms nothing changes without clutter; with one spurious detection per
        frame the pose RMSE falls 0.245 -> 0.228 m (clique) and 0.251 -> 0.236 m (NN); a
        filter not told the room's sensor (``SlamConfig()``) does better with the clique
        (0.352 -> 0.334 m) and worse with NN (0.292 -> 0.411 m; with 0.05 both 0.43 m, hence
        0.1). Counting the sensor's noise in the gate instead marks the first
        re-observations of landmarks started at long range: on Victoria Park with 5 clutter
        detections per scan it cost the clique 0.1-0.4 m (start-aligned).
    closure_support : int
        The closure pairs a batch needs, jointly compatible, for any of them to be kept.

    The probabilities lie strictly between 0 and 1, the sigmas, gates and limits are
    positive, ``ambiguity`` is one of its choices: anything else (NaN, a wrong type) is
    a :class:`~scanclique.errors.ConfigError` naming the field when the record is built.
    """

    gate_probability: float = 0.99
    new_probability: float = 0.9999
    clique_probability: float = 0.999999
    invariant_sigmas: float = 2.0
    attribute_tolerance: float | None = None
    attribute_sigma: tuple[float, float] | None = (0.03, 0.004)
    attribute_gate: float = 2.0
    ambiguity_probability: float = 0.9
    clique_individual_gate: bool = True
    ambiguity: str = "merge"
    jcbb_node_limit: int = 200_000
    clique_limit: int = 4
    node_limit: int = 1_000_000
    closure_crowding: float | None = 0.1
    closure_support: int = 2

    def __post_init__(self) -> None:
        check_types(self)
        check_probability(
            self, "gate_probability", "new_probability", "clique_probability",
            "ambiguity_probability",
        )  # fmt: skip
        check_positive(
            self, "invariant_sigmas", "attribute_tolerance", "attribute_gate", "jcbb_node_limit",
            "clique_limit", "node_limit", "closure_crowding", "closure_support",
        )  # fmt: skip
        if self.attribute_sigma is not None:
            a, b = self.attribute_sigma
            if not (math.isfinite(a) and math.isfinite(b) and a >= 0 and b >= 0 and a + b > 0):
                raise ConfigError(
                    "AssociationConfig.attribute_sigma must be two numbers >= 0, not both 0 "
                    f"(a + b * range), or None, got {self.attribute_sigma!r}"
                )
        check_choice(self, "ambiguity", ("merge", "distinct", "conflict"))


@dataclass(frozen=True, slots=True, eq=False)
class Association:
    """The association of one batch observation.

    Attributes
    ----------
    landmarks : (k,) int64 ndarray, read-only
        Per observation: the index of its landmark (into the map given to
        :func:`associate`), :data:`NEW` or :data:`REJECTED`.
    joint_d2 : float
        Joint Mahalanobis distance (squared) of the pairs with the full covariance
        (paper section 7's validation); 0 with no pair.
    dof : int
        Its degrees of freedom (2 per pair).
    ambiguous : bool
        A distinct hypothesis (clique) as large also passed the joint gate; only the
        pairs all of them share were kept.
    method : str
    candidates : int
        Candidate pairs considered (correspondence-graph vertices for the clique).
    clique_size : int
        Size of the maximum clique (clique method), else the number of pairs.
    seconds : float
        CPU time of the association (the thread's, so that other processes on a shared
        machine do not count).
    """

    landmarks: np.ndarray
    joint_d2: float
    dof: int
    ambiguous: bool
    method: str
    candidates: int = 0
    clique_size: int = 0
    seconds: float = 0.0

    def __post_init__(self) -> None:
        a = np.asarray(self.landmarks, np.int64).copy()
        a.setflags(write=False)
        object.__setattr__(self, "landmarks", a)

    @property
    def pairs(self) -> np.ndarray:
        """``(n, 2)`` int64: (observation, landmark) of each pair."""
        i = np.flatnonzero(self.landmarks >= 0)
        return np.column_stack([i, self.landmarks[i]]).astype(np.int64)

    @property
    def n_pairs(self) -> int:
        return int((self.landmarks >= 0).sum())


@dataclass(frozen=True, slots=True, eq=False)
class Predicted:
    """The map as the sensor should see it: predicted measurements and their covariance.

    Attributes
    ----------
    z : (n, 2) ndarray
        Predicted range and bearing of each landmark.
    Sz : (2n, 2n) ndarray
        Their joint covariance ``H P H^T`` (vehicle and map uncertainty, without the
        sensor noise).
    positions : (n, 2) ndarray
        World positions of the landmarks (for the invariants).
    Pm : (2n, 2n) ndarray
        Joint covariance of the positions.
    attributes : (n,) ndarray or None
        A scalar attribute per landmark (tree diameter).
    established : (n,) bool ndarray or None
        The landmarks past their tentative stage (the filter's permanent ones; None: all).
        Only an established landmark's pair can be a loop closure
        (``AssociationConfig.closure_crowding``), and only established landmarks give
        the map's density: a tentative one was started moments ago, often by a spurious
        detection.
    """

    z: np.ndarray
    Sz: np.ndarray
    positions: np.ndarray
    Pm: np.ndarray
    attributes: np.ndarray | None = None
    established: np.ndarray | None = None

    @property
    def n(self) -> int:
        return len(self.z)


def predict_map(state, P, model) -> Predicted:
    """:class:`Predicted` from a joint state ``[x, y, theta, m1x, m1y, ...]`` and its
    covariance ``P`` (dimension ``3 + 2n``), with ``model``'s sensor offset."""
    n = (len(state) - 3) // 2
    lm = np.asarray(state[3:], float).reshape(n, 2)
    z, Hx, Hm = observe(state[:3], lm, model.sensor_x, model.sensor_y)
    # H (2n, 3+2n): [Hx_j, 0.., Hm_j, ..]; H P H^T without forming H
    Hx2 = Hx.reshape(2 * n, 3)
    Pvv = P[:3, :3]
    Pvm = P[:3, 3:]
    Pmm = P[3:, 3:]
    # block-diagonal Hm as (2n, 2n)
    HmB = np.zeros((2 * n, 2 * n))
    idx = np.arange(n)
    for a in range(2):
        for b in range(2):
            HmB[2 * idx + a, 2 * idx + b] = Hm[:, a, b]
    A = Hx2 @ Pvm @ HmB.T
    Sz = Hx2 @ Pvv @ Hx2.T + A + A.T + HmB @ Pmm @ HmB.T
    return Predicted(z, Sz, lm, Pmm)


def _innovations(z, zhat):
    """``nu[i, j] = z_i - zhat_j`` (k, n, 2) with the bearing wrapped."""
    nu = z[:, None, :] - zhat[None, :, :]
    nu[..., 1] = wrap(nu[..., 1])
    return nu


def _individual_d2(nu, Sz, R):
    """Mahalanobis distances (k, n) of each observation to each predicted landmark."""
    n = nu.shape[1]
    idx = np.arange(n)
    s00 = Sz[2 * idx, 2 * idx][None, :] + R[:, 0, 0][:, None]
    s01 = Sz[2 * idx, 2 * idx + 1][None, :] + R[:, 0, 1][:, None]
    s11 = Sz[2 * idx + 1, 2 * idx + 1][None, :] + R[:, 1, 1][:, None]
    det = s00 * s11 - s01 * s01
    a, b = nu[..., 0], nu[..., 1]
    return (s11 * a * a - 2 * s01 * a * b + s00 * b * b) / det


def _pair_cov(pairs, Sz, R):
    """Innovation covariance (2m, 2m) and its row indices for pairs (obs, lm)."""
    obs = pairs[:, 0]
    rows = (2 * pairs[:, 1][:, None] + np.arange(2)).reshape(-1)
    S = Sz[np.ix_(rows, rows)]
    m = len(pairs)
    ii, jj = np.nonzero(obs[:, None] == obs[None, :])
    S4 = S.reshape(m, 2, m, 2)
    S4[ii, :, jj, :] += R[obs[ii]]
    return S


def joint_distance(pairs, nu, Sz, R) -> float:
    """Joint Mahalanobis distance (squared) of ``pairs`` ((m, 2) obs, landmark) with the
    full covariance; ``nu`` (k, n, 2) innovations."""
    pairs = np.asarray(pairs, np.int64).reshape(-1, 2)
    if len(pairs) == 0:
        return 0.0
    S = _pair_cov(pairs, Sz, R)
    v = nu[pairs[:, 0], pairs[:, 1]].reshape(-1)
    try:
        c = np.linalg.cholesky(S)
    except np.linalg.LinAlgError:
        return math.inf
    w = np.linalg.solve(c, v)
    return float(w @ w)


def _observation_points(z, R):
    """Cartesian points (k, 2) in the sensor frame and their covariances (k, 2, 2)."""
    r, b = z[:, 0], z[:, 1]
    c, s = np.cos(b), np.sin(b)
    pts = np.column_stack([r * c, r * s])
    J = np.empty((len(z), 2, 2))
    J[:, 0, 0] = c
    J[:, 0, 1] = -r * s
    J[:, 1, 0] = s
    J[:, 1, 1] = r * c
    return pts, J @ R @ J.transpose(0, 2, 1)


def _new_or_rejected(out, d2, cfg, blocked=()):
    """Unpaired observations -> NEW when far from all landmarks, else REJECTED."""
    bound = chi2_bound(2, cfg.new_probability)
    for i in np.flatnonzero(out < 0):
        far = d2.shape[1] == 0 or float(d2[i].min()) > bound
        out[i] = NEW if far and i not in blocked else REJECTED


def _nn(d2, cfg):
    k, n = d2.shape
    out = np.full(k, REJECTED, np.int64)
    gate = chi2_bound(2, cfg.gate_probability)
    if n:
        oi, lj = np.nonzero(d2 <= gate)
        order = np.argsort(d2[oi, lj], kind="stable")
        used_o = np.zeros(k, bool)
        used_l = np.zeros(n, bool)
        for q in order:
            i, j = oi[q], lj[q]
            if not used_o[i] and not used_l[j]:
                out[i] = j
                used_o[i] = used_l[j] = True
    return out


def _gate_table(kmax, probability):
    return np.array([0.0] + [chi2_bound(2 * m, probability) for m in range(1, kmax + 1)])


def _jcbb(d2, nu, Sz, R, cfg, allowed=None):
    """JCBB over the individually compatible pairs (restricted to ``allowed`` (k, n)
    bool when given). Returns (out, nodes)."""
    from ._kernels import jcbb_search

    k, n = d2.shape
    out = np.full(k, REJECTED, np.int64)
    if n == 0 or k == 0:
        return out, 0
    ok = d2 <= chi2_bound(2, cfg.gate_probability)
    if allowed is not None:
        ok &= allowed
    oi, lj = np.nonzero(ok)
    if len(oi) == 0:
        return out, 0
    # candidates of each observation, most likely first
    order = np.lexsort((d2[oi, lj], oi))
    oi, lj = oi[order], lj[order]
    pairs = np.column_stack([oi, lj])
    S = _pair_cov(pairs, Sz, R)
    v = nu[oi, lj].reshape(-1)
    cand_start = np.searchsorted(oi, np.arange(k + 1)).astype(np.int64)
    cand = np.arange(len(oi), dtype=np.int64)
    gate = _gate_table(k, cfg.gate_probability)
    best, _d2, nodes = jcbb_search(
        S, v, cand_start, cand, lj.astype(np.int64), n, gate, cfg.jcbb_node_limit
    )
    out[oi[best]] = lj[best]
    return out, nodes


def correspondence_graph(z, R, d2, pred: Predicted, cfg, attributes=None, _slow_graph=False):
    """The correspondence graph of the observation and the predicted map (paper 5.2).

    Vertices: the pairs (observation i, landmark j) within the loose individual gate
    ``clique_probability`` (and, with attributes, within ``attribute_tolerance`` and
    ``attribute_gate`` standard deviations ``attribute_sigma`` of the landmark's).
    Edges: pairs ``(i, j)``, ``(k, l)`` with ``i != k``, ``j != l`` whose
    point-point distances agree, ``(|p_i - p_k| - |m_j - m_l|)^2 <= s^2 (var_o + var_m)``
    with ``s = invariant_sigmas`` and the variances from :func:`point_distance_invariants`
    (observation noise ``R``; the map's joint covariance).

    Returns
    -------
    (oi, lj, A)
        Observation and landmark of each vertex, and the boolean adjacency matrix.
    """
    ok = d2 <= chi2_bound(2, cfg.clique_probability)
    if attributes is not None and pred.attributes is not None:
        gap = np.abs(attributes[:, None] - pred.attributes[None, :])
        if cfg.attribute_tolerance is not None:
            ok &= gap <= cfg.attribute_tolerance
        if cfg.attribute_sigma is not None:
            a, b = cfg.attribute_sigma
            ok &= gap <= cfg.attribute_gate * (a + b * np.asarray(z)[:, 0])[:, None]
    oi, lj = np.nonzero(ok)
    if _slow_graph:
        # the NumPy reference (point_distance_invariants over all pairs)
        pts, pcov = _observation_points(z, R)
        Do, Vo = point_distance_invariants(pts, pcov)
        Dm, Vm = point_distance_invariants(pred.positions, pred.Pm)
        diff = Do[np.ix_(oi, oi)] - Dm[np.ix_(lj, lj)]
        var = Vo[np.ix_(oi, oi)] + Vm[np.ix_(lj, lj)]
        A = diff * diff <= cfg.invariant_sigmas**2 * var
        A &= oi[:, None] != oi[None, :]
        A &= lj[:, None] != lj[None, :]
        return oi, lj, A
    from ._kernels import correspondence_adjacency

    A = correspondence_adjacency(
        np.ascontiguousarray(z, dtype=float),
        np.ascontiguousarray(R, dtype=float),
        np.ascontiguousarray(pred.positions, dtype=float),
        np.ascontiguousarray(pred.Pm),
        oi.astype(np.int64),
        lj.astype(np.int64),
        float(cfg.invariant_sigmas**2),
    )
    return oi, lj, A


def _clique(z, R, d2, nu, pred: Predicted, cfg, attributes=None, verify="peel"):
    """Maximum cliques of the correspondence graph, then the joint gate.

    ``verify="peel"`` (method ``clique``): each maximum clique's pairs are tested jointly
    with the full covariance, and the pair of largest individual distance is dropped until
    the test passes. ``verify="jcbb"`` (hybrid ``clique-jcbb``): JCBB restricted to the
    pairs of the maximum cliques finds their largest jointly compatible subset.

    Returns (out, candidates, clique size, ambiguous, blocked observations).
    """
    from ..clique import all_maximum_cliques

    k, n = d2.shape
    out = np.full(k, REJECTED, np.int64)
    if n == 0 or k == 0:
        return out, 0, 0, False, ()
    oi, lj, A = correspondence_graph(z, R, d2, pred, cfg, attributes)
    C = len(oi)
    if C == 0:
        return out, 0, 0, False, ()
    res = all_maximum_cliques(A, limit=cfg.clique_limit, node_limit=cfg.node_limit)
    gate = _gate_table(k, cfg.gate_probability)
    if verify == "jcbb":
        allowed = np.zeros((k, n), bool)
        for cl in res.cliques:
            allowed[oi[cl], lj[cl]] = True
        out, _nodes = _jcbb(d2, nu, pred.Sz, R, cfg, allowed)
        blocked = ()
        amb = False
        if len(res.cliques) > 1:
            shared = _shared_pairs([_pair_set(oi[cl], lj[cl]) for cl in res.cliques], cfg)
            if shared is not None:
                amb, blocked = True, shared[1]
        return out, C, int(res.omega), amb, blocked
    passing = []
    single = chi2_bound(2, cfg.gate_probability) if cfg.clique_individual_gate else math.inf
    for cl in res.cliques:
        sel = np.asarray(cl, np.int64)
        sel = sel[d2[oi[sel], lj[sel]] <= single]
        D2 = 0.0
        while len(sel):
            pairs = np.column_stack([oi[sel], lj[sel]])
            D2 = joint_distance(pairs, nu, pred.Sz, R)
            if D2 <= gate[len(sel)]:
                break
            sel = np.delete(sel, int(np.argmax(d2[oi[sel], lj[sel]])))
        passing.append((len(sel), D2 if len(sel) else 0.0, sel))
    size = max(p[0] for p in passing)
    best = [p for p in passing if p[0] == size]
    best.sort(key=lambda p: p[1])
    sel = best[0][2]
    margin = chi2_bound(2, cfg.ambiguity_probability)
    best = [p for p in best if p[1] - best[0][1] <= margin]  # as likely as the best
    if len(best) > 1 and size > 0 and cfg.ambiguity == "merge":
        hyp, rivals = _merged([_pair_set(oi[p[2]], lj[p[2]]) for p in best], nu, pred.Sz, R, gate)
        blocked = ()
        if rivals:  # ambiguous: keep only the pairs the merged hypothesis and its rivals share
            common = set.intersection(hyp, *rivals)
            blocked = tuple({i for i, _ in set.union(hyp, *rivals) - common})
            hyp = common
        for i, j in sorted(hyp):
            out[i] = j
        return out, C, int(res.omega), bool(rivals), blocked
    if len(best) > 1 and size > 0:
        shared = _shared_pairs([_pair_set(oi[p[2]], lj[p[2]]) for p in best], cfg)
        if shared is not None:
            # ambiguous: keep only the pairs every equally good hypothesis shares
            common, blocked = shared
            for i, j in sorted(common):
                out[i] = j
            return out, C, int(res.omega), True, blocked
    out[oi[sel]] = lj[sel]
    return out, C, int(res.omega), False, ()


def _merged(sets: list[set], nu, Sz, R, gate) -> tuple[set, list[set]]:
    """Equally likely hypotheses (sets of (observation, landmark); the best first) merged
    into the best while their union stays one-to-one and passes the joint gate (``gate``
    indexed by the number of pairs): the merged hypothesis and the rivals left out."""
    hyp, rivals = sets[0], []
    for h in sets[1:]:
        u = hyp | h
        one_to_one = len({i for i, _ in u}) == len(u) == len({j for _, j in u})
        if one_to_one and joint_distance(sorted(u), nu, Sz, R) <= gate[len(u)]:
            hyp = u
        else:
            rivals.append(h)
    return hyp, rivals


def _pair_set(o, l) -> set:
    return set(zip(np.asarray(o).tolist(), np.asarray(l).tolist(), strict=True))


def _shared_pairs(sets: list[set], cfg) -> tuple[set, tuple] | None:
    """For hypotheses ``sets`` (the best first): None when no other is its rival
    (:func:`_rivals`); else the pairs the best and its rivals share and the observations
    paired in one of them but not in all (an ambiguous step: those start no landmark)."""
    rivals = [x for x in sets[1:] if _rivals(sets[0], x, cfg)]
    if not rivals:
        return None
    common = set.intersection(sets[0], *rivals)
    return common, tuple({i for i, _ in set.union(sets[0], *rivals) - common})


def _rivals(h1: set, h2: set, cfg) -> bool:
    """Whether two distinct hypotheses (sets of (observation, landmark)) are rivals:
    any two, under ``ambiguity="distinct"``; only when they pair an observation or a
    landmark differently (their union is not one-to-one), under ``"conflict"``."""
    if h1 == h2:
        return False
    if cfg.ambiguity in ("distinct", "merge"):  # the hybrid reads "merge" as "distinct"
        return True
    o1 = dict(h1)
    l1 = {j: i for i, j in h1}
    return any(o1.get(i, j) != j or l1.get(j, i) != i for i, j in h2)


def gate_crowding(z, pred: Predicted, pairs, probability: float) -> np.ndarray:
    """How many unrelated features the drift opens each pair's gate to (m,).

    For a pair ``(i, j)`` (observation, predicted landmark) the landmark's predicted
    measurement has the covariance ``S_j`` of the vehicle's and the map's uncertainty
    (the sensor's noise left out: it opens every gate alike, and a landmark seen moments
    ago is no closure). Its chi-square ellipse at ``probability``, in metres about the
    sensor (range, and bearing times the observed range ``z[i]``), has the area ``pi *
    chi2 * sqrt(det)``. The map's density is estimated from the established landmarks'
    median nearest-neighbour distance ``d`` (:attr:`Predicted.established`; all landmarks
    when None) as that of a Poisson field, ``ln 2 / (pi d^2)``. Their product is how
    many features, mapped or not, the gate is expected to hold besides the landmark:
    near 0 when the landmark is known relative to the vehicle to well within the
    landmarks' spacing; of order 0.1-1 when the vehicle comes back to a place after a
    long drift, where one landmark alone may be its neighbour. 0 when fewer than 2
    established landmarks are given: no spacing to judge by.

    Parameters
    ----------
    z : (k, 2) array
        The observations (range, bearing).
    pred : Predicted
    pairs : (m, 2) int array
        (observation, landmark) indices.
    probability : float
        The gate's chi-square probability (2 degrees of freedom).
    """
    pairs = np.asarray(pairs, np.int64).reshape(-1, 2)
    m = len(pairs)
    P = pred.positions if pred.established is None else pred.positions[pred.established]
    if m == 0:
        return np.zeros(0)
    if len(P) < 2:
        return np.zeros(m)
    D = np.hypot(*(P[:, None, :] - P[None, :, :]).transpose(2, 0, 1))
    np.fill_diagonal(D, math.inf)
    d = float(np.median(D.min(axis=1)))
    density = math.log(2.0) / (math.pi * d * d) if d > 0 else math.inf
    i, j = pairs[:, 0], pairs[:, 1]
    s_rr, s_rb, s_bb = (
        pred.Sz[2 * j, 2 * j],
        pred.Sz[2 * j, 2 * j + 1],
        pred.Sz[2 * j + 1, 2 * j + 1],
    )
    r = np.maximum(np.asarray(z)[i, 0], 1e-9)
    det_m = (s_rr * s_bb - s_rb**2) * r * r  # in metres: diag(1, r) S diag(1, r)
    area = math.pi * chi2_bound(2, probability) * np.sqrt(np.maximum(det_m, 0.0))
    return density * area


def _unsupported_closures(out, z, R, nu, pred: Predicted, cfg) -> tuple:
    """Unpair the pairs whose gate is crowded (:func:`gate_crowding` above
    ``closure_crowding``: a loop closure's re-observation of a landmark the vehicle has
    drifted from) unless at least ``closure_support`` such pairs are jointly compatible
    in the same batch: the relative geometry of several old landmarks tells a revisit
    from a neighbouring feature, one alone does not. Returns the observations unpaired
    (they start no landmark)."""
    paired = np.flatnonzero(out >= 0)
    if len(paired) == 0:
        return ()
    pairs = np.column_stack([paired, out[paired]])
    if pred.established is not None:
        pairs = pairs[pred.established[pairs[:, 1]]]
    crowd = gate_crowding(z, pred, pairs, cfg.gate_probability)
    weak = pairs[crowd > cfg.closure_crowding]
    if len(weak) == 0:
        return ()
    if len(weak) >= cfg.closure_support:
        D2 = joint_distance(weak, nu, pred.Sz, R)
        if D2 <= chi2_bound(2 * len(weak), cfg.gate_probability):
            return ()
    out[weak[:, 0]] = REJECTED
    return tuple(weak[:, 0].tolist())


def associate_predicted(
    z,
    R,
    pred: Predicted,
    method: str = "clique",
    config: AssociationConfig | None = None,
    attributes=None,
) -> Association:
    """Associate observations ``z`` (k, 2) with noise ``R`` ((2, 2) or (k, 2, 2)) to the
    predicted map ``pred`` (see :func:`associate` for the methods)."""
    t0 = time.thread_time()
    cfg = config or AssociationConfig()
    z = np.asarray(z, float).reshape(-1, 2)
    k = len(z)
    R = np.asarray(R, float)
    if R.ndim == 2:
        R = np.broadcast_to(R, (k, 2, 2))
    nu = _innovations(z, pred.z)
    d2 = _individual_d2(nu, pred.Sz, R)
    amb = False
    blocked: tuple = ()
    cands = int((d2 <= chi2_bound(2, cfg.gate_probability)).sum())
    csize = 0
    if method == "nn":
        out = _nn(d2, cfg)
    elif method == "jcbb":
        out, _nodes = _jcbb(d2, nu, pred.Sz, R, cfg)
    elif method == "clique":
        out, cands, csize, amb, blocked = _clique(z, R, d2, nu, pred, cfg, attributes)
    elif method == "clique-jcbb":
        out, cands, csize, amb, blocked = _clique(z, R, d2, nu, pred, cfg, attributes, "jcbb")
    else:
        raise ConfigError(f"association method must be one of {', '.join(METHODS)}, got {method!r}")
    if cfg.closure_crowding is not None:
        blocked = tuple(blocked) + _unsupported_closures(out, z, R, nu, pred, cfg)
    pairs = np.column_stack([np.flatnonzero(out >= 0), out[out >= 0]])
    D2 = joint_distance(pairs, nu, pred.Sz, R) if len(pairs) else 0.0
    _new_or_rejected(out, d2, cfg, blocked)
    np_ = len(pairs)
    return Association(
        out,
        D2,
        2 * np_,
        amb,
        method,
        cands,
        csize if method == "clique" else np_,
        time.thread_time() - t0,
    )


def associate(
    z,
    R,
    map_mean,
    map_cov,
    pose,
    pose_cov,
    method: str = "clique",
    *,
    cross_cov=None,
    sensor=(0.0, 0.0),
    config: AssociationConfig | None = None,
    attributes=None,
    map_attributes=None,
) -> Association:
    """Associate one batch of range-bearing observations with a map of point landmarks.

    Usable on its own, outside the filter.

    Parameters
    ----------
    z : (k, 2) array
        Range (m) and bearing (rad, counter-clockwise from the vehicle's heading) of each
        observation, from the sensor.
    R : (2, 2) or (k, 2, 2) array
        Observation noise covariance.
    map_mean : (n, 2) array
        World positions of the landmarks.
    map_cov : (2n, 2n) or (n, 2, 2) array
        Their covariance (joint, or independent per landmark).
    pose : (3,) array
        Vehicle pose ``(x, y, theta)`` in the world.
    pose_cov : (3, 3) array
    method : {"clique", "clique-jcbb", "jcbb", "nn"}
    cross_cov : (3, 2n) array, optional
        Covariance between pose and map (zero when omitted).
    sensor : (2,) float
        Sensor position in the vehicle frame.
    attributes, map_attributes : (k,), (n,) arrays, optional
        Per-feature scalar attributes (tree diameters), used with
        ``config.attribute_tolerance``.

    Returns
    -------
    Association
        ``landmarks[i]`` = index into ``map_mean``, :data:`NEW` or :data:`REJECTED`.

    Raises
    ------
    StepError
        An array that is not finite numbers or not of its shape above, ``z`` not pairs,
        a range not above 0, or a bearing beyond two turns (degrees given for radians).

    Examples
    --------
    >>> lm = np.array([[10.0, 0.0], [10.0, 5.0], [15.0, -3.0]])
    >>> z, _, _ = observe(np.zeros(3), lm[[2, 0]])
    >>> a = associate(z, np.diag([0.1, 0.01]) ** 2, lm, np.tile(np.eye(2) * 0.01, (3, 1, 1)),
    ...               np.zeros(3), np.eye(3) * 1e-4, method="jcbb")
    >>> a.landmarks.tolist()
    [2, 0]
    """
    z = np.array(as_observations(z, "associate", "z"))
    k = len(z)
    R = _finite_array(R, "R", (2, 2), (k, 2, 2))
    pose_cov = _finite_array(pose_cov, "pose_cov", (3, 3))
    pose = _finite_array(pose, "pose", (3,), flat=True)
    sensor = _finite_array(sensor, "sensor", (2,), flat=True)
    mean = _finite_array(map_mean, "map_mean")
    if mean.size % 2:
        raise StepError(f"associate: map_mean must be (n, 2) positions, got shape {mean.shape}")
    mean = mean.reshape(-1, 2)
    n = len(mean)
    cov = _finite_array(map_cov, "map_cov", (n, 2, 2), (2 * n, 2 * n))
    if cross_cov is not None:
        cross_cov = _finite_array(cross_cov, "cross_cov", (3, 2 * n))
    if attributes is not None:
        attributes = _finite_array(attributes, "attributes", (k,))
    if map_attributes is not None:
        map_attributes = _finite_array(map_attributes, "map_attributes", (n,))
    if cov.ndim == 3:
        full = np.zeros((2 * n, 2 * n))
        for j in range(n):
            full[2 * j : 2 * j + 2, 2 * j : 2 * j + 2] = cov[j]
        cov = full
    P = np.zeros((3 + 2 * n, 3 + 2 * n))
    P[:3, :3] = pose_cov
    P[3:, 3:] = cov
    if cross_cov is not None:
        P[:3, 3:] = cross_cov
        P[3:, :3] = np.asarray(cross_cov).T
    state = np.concatenate([np.asarray(pose, float), mean.reshape(-1)])

    class _S:  # sensor offset holder
        sensor_x, sensor_y = float(sensor[0]), float(sensor[1])

    pred = predict_map(state, P, _S)
    if map_attributes is not None:
        pred = Predicted(
            pred.z, pred.Sz, pred.positions, pred.Pm, np.asarray(map_attributes, float)
        )
    att = None if attributes is None else np.asarray(attributes, float)
    return associate_predicted(z, R, pred, method, config, att)


def _finite_array(values, name: str, *shapes, flat: bool = False) -> np.ndarray:
    """``values`` as a float array (a copy; flattened when ``flat``), or a
    :class:`StepError` naming ``name`` when it is not finite numbers or, when ``shapes``
    are given, not of one of them."""
    a = np.array(as_numbers(values, "associate", name))
    if flat:
        a = a.reshape(-1)
    if not np.isfinite(a).all():
        raise StepError(f"associate: {name} is not finite")
    if shapes and a.shape not in shapes:
        want = " or ".join(str(s) for s in shapes)
        raise StepError(f"associate: {name} must be of shape {want}, got {a.shape}")
    return a


__all__ += ["predict_map", "inverse_observe"]
