"""Error of an estimated trajectory against GPS fixes or ground truth, and map statistics.

The estimated position compared with a fix is the sensor's (the laser's) position,
interpolated linearly to the fix's time: in the Victoria Park vehicle model of Guivant and
Nebot the tracked point is the laser's, and the GPS fixes are compared with it.

Two alignments of the estimate's frame to the GPS frame (the filter starts at the
origin, heading along x):

* **start**: the least-squares rigid alignment of the start of the run only: the fixes
  until the GPS track has gone ``start_distance`` metres (50 m) from its first fix; the
  error is then measured at every fix (the drift of the whole run from its start);
* **best**: the least-squares rigid (SE(2)) alignment over all fixes (Kabsch / Umeyama
  without scale).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..geometry import align_se2

__all__ = [
    "gps_outliers",
    "GpsError",
    "gps_error",
    "gps_fix_errors",
    "gps_jumps",
    "align_se2",
    "duplicate_pairs",
    "sensor_positions",
    "nees",
    "TruthScore",
    "score_against_truth",
    "TruthError",
    "truth_error",
]


@dataclass(frozen=True, slots=True)
class GpsError:
    """RMS and max position error (m) at the GPS fixes, for each alignment."""

    rmse_start: float
    max_start: float
    rmse_best: float
    max_best: float
    fixes: int
    rotation_best: float  # rad, rotation of the best alignment (estimate -> GPS)
    translation_best: tuple[float, float]


def sensor_positions(poses, sensor_x: float, sensor_y: float) -> np.ndarray:
    """World positions (N, 2) of the sensor for vehicle poses (N, 3)."""
    p = np.asarray(poses, float)
    c, s = np.cos(p[:, 2]), np.sin(p[:, 2])
    return np.column_stack(
        [p[:, 0] + c * sensor_x - s * sensor_y, p[:, 1] + s * sensor_x + c * sensor_y]
    )


def gps_outliers(gps, max_speed: float = 15.0) -> np.ndarray:
    """Fixes (bool (G,)) that imply a speed above ``max_speed`` (m/s) both from the
    previous and to the next fix: isolated jumps of the receiver (Victoria Park's GPS
    holds one of 141 m), not motion of a car in a park."""
    g = np.asarray(gps, float)
    if len(g) < 3:
        return np.zeros(len(g), bool)
    dt = np.maximum(np.diff(g[:, 0]), 1e-6)
    v = np.hypot(*np.diff(g[:, 1:], axis=0).T) / dt
    out = np.zeros(len(g), bool)
    out[1:-1] = (v[:-1] > max_speed) & (v[1:] > max_speed)
    return out


def gps_fix_errors(times, positions, gps, *, start_distance: float = 50.0):
    """Position error of a trajectory at each GPS fix, for both alignments.

    Parameters
    ----------
    times : (N,) array
        Times of the estimated positions (s), increasing.
    positions : (N, 2) array
        Estimated positions (m) in the estimate's frame.
    gps : (G, 3) array
        ``time x y`` fixes; those outside ``[times[0], times[-1]]`` are ignored, and so
        are the outliers of :func:`gps_outliers`.

    Returns
    -------
    fixes : (F, 3) ndarray
        The fixes used (``time x y``).
    e_start, e_best : (F,) ndarrays
        Error (m) at each fix after the start alignment and after the best SE(2)
        alignment.
    estimate_best : (F, 2) ndarray
        The estimate at the fixes' times, in the GPS frame by the best alignment.
    best : (Rm (2, 2), t (2,), angle)
        The best alignment (estimate -> GPS).
    """
    times = np.asarray(times, float)
    positions = np.asarray(positions, float)
    g = np.asarray(gps, float)
    g = g[~gps_outliers(g)]
    g = g[(g[:, 0] >= times[0]) & (g[:, 0] <= times[-1])]
    est = np.column_stack(
        [np.interp(g[:, 0], times, positions[:, 0]), np.interp(g[:, 0], times, positions[:, 1])]
    )
    ref = g[:, 1:]
    # start alignment
    far = np.flatnonzero(np.hypot(*(ref - ref[0]).T) >= start_distance)
    k = int(far[0]) if len(far) else len(ref) - 1
    Rs, ts, _ = align_se2(est[: k + 1], ref[: k + 1])
    a = est @ Rs.T + ts
    e_start = np.hypot(*(a - ref).T)
    Rb, tb, angb = align_se2(est, ref)
    est_best = est @ Rb.T + tb
    e_best = np.hypot(*(est_best - ref).T)
    return g, e_start, e_best, est_best, (Rb, tb, angb)


def gps_error(times, positions, gps, *, start_distance: float = 50.0) -> GpsError:
    """RMS and max position error of a trajectory at the GPS fixes (see
    :func:`gps_fix_errors`, which takes the same arguments)."""
    g, e_start, e_best, _est, (_Rb, tb, angb) = gps_fix_errors(
        times, positions, gps, start_distance=start_distance
    )
    return GpsError(
        float(np.sqrt(np.mean(e_start**2))),
        float(e_start.max()),
        float(np.sqrt(np.mean(e_best**2))),
        float(e_best.max()),
        len(g),
        float(angb),
        (float(tb[0]), float(tb[1])),
    )


def gps_jumps(fixes, estimate, *, tolerance: float = 1.5, max_dt: float = 1.0) -> np.ndarray:
    """Fixes (bool (F,)) where the GPS jumps: its step from the previous fix (less than
    ``max_dt`` s before) differs from the estimate's step over the same interval by more
    than ``tolerance`` (m). A smooth estimate cannot move that far from one fix to the
    next (0.2 s on Victoria Park), so such a step is the receiver's (a change of
    satellites or multipath) and the fixes that follow carry its offset until the next.

    Parameters
    ----------
    fixes : (F, 3) array
        ``time x y``.
    estimate : (F, 2) array
        The estimate at the fixes' times, in the GPS frame.
    """
    f = np.asarray(fixes, float)
    e = np.asarray(estimate, float)
    out = np.zeros(len(f), bool)
    if len(f) < 2:
        return out
    step = np.hypot(*(np.diff(f[:, 1:], axis=0) - np.diff(e, axis=0)).T)
    out[1:] = (step > tolerance) & (np.diff(f[:, 0]) < max_dt)
    return out


def duplicate_pairs(landmarks, distance: float = 1.0) -> tuple[int, int]:
    """``(pairs, landmarks in a pair)`` of landmarks closer than ``distance`` (m)."""
    lm = np.asarray(landmarks, float).reshape(-1, 2)
    if len(lm) < 2:
        return 0, 0
    d = np.hypot(*(lm[:, None, :] - lm[None, :, :]).transpose(2, 0, 1))
    iu = np.triu_indices(len(lm), 1)
    close = d[iu] < distance
    members = np.unique(np.r_[iu[0][close], iu[1][close]])
    return int(close.sum()), int(len(members))


def nees(errors, covariances) -> np.ndarray:
    """Normalised estimation error squared ``e^T P^-1 e`` of each (N, d) error."""
    e = np.asarray(errors, float)
    P = np.asarray(covariances, float)
    return np.einsum("ni,ni->n", e, np.linalg.solve(P, e[..., None])[..., 0])


@dataclass(frozen=True, slots=True)
class TruthScore:
    """A run's associations and map against a simulator's truth (:func:`score_against_truth`).

    Each landmark of the run is identified with the true landmark that most of its paired
    observations see (clutter, -1, if most are clutter).

    Attributes
    ----------
    pairs : int
        Observations paired with a landmark, over the run.
    wrong : int
        Pairs whose observation is clutter or of another true landmark than its
        landmark's identity.
    landmarks : int
        Landmarks in the final map.
    distinct : int
        Distinct true landmarks among the final map's identities.
    spurious : int
        Final landmarks identified with clutter (or never paired).
    seen : int
        True landmarks observed at least once.
    """

    pairs: int
    wrong: int
    landmarks: int
    distinct: int
    spurious: int
    seen: int

    @property
    def wrong_rate(self) -> float:
        """``wrong / pairs`` (0 without pairs)."""
        return self.wrong / self.pairs if self.pairs else 0.0

    @property
    def duplicates(self) -> int:
        """Final landmarks beyond the first of each true landmark."""
        return self.landmarks - self.spurious - self.distinct


def score_against_truth(landmark_ids, associations, truth) -> TruthScore:
    """Score a run's associations against the truth of a simulated log.

    Parameters
    ----------
    landmark_ids : (n,) int array
        The final map's landmark ids (:attr:`SlamResult.landmark_ids`).
    associations : sequence of (k,) int arrays
        Per observation step, the landmark id of each observation or a negative code
        (:attr:`SlamResult.associations`).
    truth : sequence of (k,) int arrays
        Per observation step, the true landmark of each observation, -1 for clutter
        (:attr:`scanclique.slam.sim.SimRun.truth`).

    Examples
    --------
    >>> a = [np.array([-1, -1]), np.array([7, 8]), np.array([7, 8]), np.array([7, 8])]
    >>> t = [np.array([0, 1]), np.array([0, 1]), np.array([0, 1]), np.array([-1, 1])]
    >>> s = score_against_truth([7, 8], a, t)
    >>> s.pairs, s.wrong, s.distinct, s.spurious
    (6, 1, 2, 0)
    """
    votes: dict[int, dict[int, int]] = {}
    for a, tr in zip(associations, truth, strict=True):
        for lid, t in zip(np.asarray(a).tolist(), np.asarray(tr).tolist(), strict=True):
            if lid >= 0:
                v = votes.setdefault(lid, {})
                v[t] = v.get(t, 0) + 1
    # a landmark's identity: the true landmark its pairs see most (ties: the lowest index)
    ident = {lid: max(sorted(v), key=lambda t: v[t]) for lid, v in votes.items()}
    pairs = sum(sum(v.values()) for v in votes.values())
    right = sum(v[ident[lid]] for lid, v in votes.items() if ident[lid] >= 0)
    final = [ident.get(int(lid), -1) for lid in np.asarray(landmark_ids).tolist()]
    seen = {t for tr in truth for t in np.asarray(tr).tolist() if t >= 0}
    return TruthScore(
        pairs=pairs,
        wrong=pairs - right,
        landmarks=len(final),
        distinct=len({t for t in final if t >= 0}),
        spurious=sum(t < 0 for t in final),
        seen=len(seen),
    )


@dataclass(frozen=True, slots=True)
class TruthError:
    """A run's vehicle poses and map against ground truth (:func:`truth_error`).

    Attributes
    ----------
    rmse_start, max_start : float
        Position error (m) in the start alignment: the estimate's frame moved so that its
        pose at the first true pose's time is that true pose (nothing moves when the filter
        started at the true pose); the drift of the whole run.
    rmse_best, max_best : float
        Position error (m) after the least-squares SE(2) alignment of all positions.
    heading_rmse : float
        Heading error (rad), start alignment.
    anees : float
        Mean pose NEES (3 degrees of freedom; 3 for a consistent filter), start alignment.
    poses : int
        Estimated poses compared (those within the truth's time span).
    landmarks_true, landmarks_mapped : int
        True landmarks, and those with an estimated landmark within 1 m, each other's
        nearest (start alignment); 0 without true landmarks.
    landmark_rmse : float
        Position error (m) of the mapped ones (NaN when none).
    landmarks_spurious : int
        Estimated landmarks with no true one within 1 m (0 without true landmarks).
    """

    rmse_start: float
    max_start: float
    rmse_best: float
    max_best: float
    heading_rmse: float
    anees: float
    poses: int
    landmarks_true: int = 0
    landmarks_mapped: int = 0
    landmark_rmse: float = math.nan
    landmarks_spurious: int = 0


def truth_error(times, poses, covariances, truth, landmarks=None, true_landmarks=None):
    """The :class:`TruthError` of estimated vehicle poses ``(N, 3)`` at ``times`` (s),
    with their covariances ``(N, 3, 3)`` (None: no ANEES, NaN), against true poses
    ``(T, 4)`` rows ``time x y theta`` (interpolated to ``times``; estimates outside the
    truth's span are left out),
    and of the estimated ``landmarks`` ``(n, 2)`` against ``true_landmarks`` ``(L, 2)``.

    Returns None when no estimate falls within the truth's time span.
    """
    from .models import wrap
    from .reader import interpolate_poses

    times = np.asarray(times, float)
    truth = np.asarray(truth, float)
    if not len(truth) or not len(times):
        return None
    inside = (times >= truth[0, 0]) & (times <= truth[-1, 0])
    if not inside.any():
        return None
    est = np.asarray(poses, float)[inside]
    ref = interpolate_poses(truth, times[inside])
    # start alignment: est[0] onto ref[0]
    dth = float(wrap(ref[0, 2] - est[0, 2]))
    c, s = math.cos(dth), math.sin(dth)
    Rs = np.array([[c, -s], [s, c]])
    ts = ref[0, :2] - Rs @ est[0, :2]
    e_xy = est[:, :2] @ Rs.T + ts - ref[:, :2]
    e_th = wrap(est[:, 2] + dth - ref[:, 2])
    d_start = np.hypot(e_xy[:, 0], e_xy[:, 1])
    Rb, tb, _ = align_se2(est[:, :2], ref[:, :2])
    e_b = est[:, :2] @ Rb.T + tb - ref[:, :2]
    d_best = np.hypot(e_b[:, 0], e_b[:, 1])
    an = np.full(len(est), math.nan)
    if covariances is not None:  # the covariances turn with the estimate's frame
        R3 = np.eye(3)
        R3[:2, :2] = Rs
        cov = np.asarray(covariances, float)[inside]
        with np.errstate(all="ignore"):
            an = nees(np.column_stack([e_xy, e_th]), R3 @ cov @ R3.T)
    out = dict(
        rmse_start=float(np.sqrt(np.mean(d_start**2))),
        max_start=float(d_start.max()),
        rmse_best=float(np.sqrt(np.mean(d_best**2))),
        max_best=float(d_best.max()),
        heading_rmse=float(np.sqrt(np.mean(e_th**2))),
        anees=float(np.mean(an[np.isfinite(an)])) if np.isfinite(an).any() else math.nan,
        poses=int(inside.sum()),
    )
    if true_landmarks is not None and len(true_landmarks):
        tl = np.asarray(true_landmarks, float).reshape(-1, 2)
        lm = np.asarray(landmarks, float).reshape(-1, 2) @ Rs.T + ts
        mapped, err = 0, []
        near_true = np.zeros(len(lm), bool)
        if len(lm):
            D = np.hypot(*(tl[:, None, :] - lm[None, :, :]).transpose(2, 0, 1))
            near_true = (D <= 1.0).any(axis=0)
            j = D.argmin(axis=1)  # each true landmark's nearest estimate
            for i in range(len(tl)):
                if D[i, j[i]] <= 1.0 and D[:, j[i]].argmin() == i:
                    mapped += 1
                    err.append(D[i, j[i]])
        out.update(
            landmarks_true=len(tl),
            landmarks_mapped=mapped,
            landmark_rmse=float(np.sqrt(np.mean(np.square(err)))) if err else math.nan,
            landmarks_spurious=int((~near_true).sum()),
        )
    return TruthError(**out)
