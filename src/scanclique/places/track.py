"""Tracking in a place database's map: a scan placed by a place near where the run
predicts it (issue 14, localisation after recognition).

Recognition (:meth:`PlaceDB.query <scanclique.places.PlaceDB.query>`) places a scan with
no prior, and is sure only where a place is distinctive. A robot that was located a
moment ago knows roughly where it is: its own motion since then (an online map of the
run, :class:`scanclique.mapping.OnlineMapper`) carries the last fix to a prediction, and
the places stored near the prediction are matched against the scan with that prior,
exactly as a loop-closure candidate of the mapper is
(:func:`scanclique.mapping.loops.verify`: the matcher's best hypothesis, validated
(paper §7) against the prediction, refined, and refused where the raw scans do not fix
the pose in every direction). The prediction's uncertainty grows with the path since
the fix (:func:`track_std`); past :data:`TRACK_MAX_PATH` metres with no fix the track is
dropped.

The places are those within :data:`TRACK_RADIUS` of the prediction, where a revisit still
overlaps: partly, so the raw-scan check of a place with too few features to map asks ICP
to pair :data:`TRACK_MIN_FITNESS` of the scan's points rather than the front end's 0.6
(consecutive scans overlap almost wholly).

Functions here are pure but for :func:`fix_near`, which reads places from the database.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from ..config import require_count
from ..errors import ArgumentError
from ..geometry import Pose2
from ..match import PreparedScan
from .verify import ACCEPT_MIN_SCORE

__all__ = [
    "TRACK_RADIUS",
    "TRACK_MAX_PATH",
    "TRACK_PLACES",
    "TRACK_MIN_FITNESS",
    "track_std",
    "MapPoses",
    "Fix",
    "TrackFix",
    "predict",
    "near_places",
    "fix_near",
]

#: places whose map position lies within this distance of the prediction, plus three of
#: its standard deviations, are matched (m): the revisit rule's 2 m, beyond which two
#: scans of a building overlap too little to be matched reliably
TRACK_RADIUS = 2.0
#: the track is dropped after this much path (m) with no fix (:func:`track_std` is then
#: 1.15 m and 11.5 deg)
TRACK_MAX_PATH = 20.0
#: at most this many places near the prediction are matched, nearest first
TRACK_PLACES = 10
#: the fraction of the scan's points ICP must pair with a place's, for a place with too
#: few features to map (:func:`scanclique.mapping.loops.verify_by_icp`)
TRACK_MIN_FITNESS = 0.3
#: the prediction's standard deviations at the fix (m, rad: the fix's own error, a place's
#: map pose and its match) and their growth per metre of path (the run's own drift)
TRACK_SIGMA = (0.15, math.radians(1.5))
TRACK_GROWTH = (0.05, math.radians(0.5))


@dataclass(frozen=True, slots=True, eq=False)
class MapPoses:
    """The map poses of a database's places, as arrays for :func:`near_places`: place
    ``ids`` ``(N,)`` and their ``(x, y, theta)`` rows ``xyt`` ``(N, 3)`` (m, rad).

    >>> m = MapPoses.of({4: Pose2(1.0, 2.0, 0.5)})
    >>> m.ids.tolist(), m.pose(4)
    ([4], Pose2(x=1.0000, y=2.0000, theta=0.5000))
    """

    ids: np.ndarray
    xyt: np.ndarray

    @classmethod
    def of(cls, poses: dict[int, Pose2]) -> MapPoses:
        """From place id -> map pose (:meth:`PlaceDB.map_poses`); ArgumentError for a
        pose that is not a :class:`~scanclique.geometry.Pose2`."""
        for pid, p in poses.items():
            if not isinstance(p, Pose2):
                raise ArgumentError(
                    f"MapPoses.of: the pose of place {pid!r} must be a Pose2, got {p!r}"
                )
        ids = np.fromiter(poses, dtype=np.int64, count=len(poses))
        xyt = np.array([p.as_array() for p in poses.values()], dtype=float).reshape(-1, 3)
        return cls(ids, xyt)

    def pose(self, place_id: int) -> Pose2:
        """The map pose of place ``place_id`` (KeyError when it has none)."""
        at = np.flatnonzero(self.ids == place_id)
        if not len(at):
            raise KeyError(place_id)
        return Pose2.from_array(self.xyt[at[0]])

    def __len__(self) -> int:
        return len(self.ids)


@dataclass(frozen=True, slots=True)
class Fix:
    """The last scan placed in the database's map: its index in the log, its map
    ``pose``, and the run's path length when it was taken (m)."""

    index: int
    pose: Pose2
    path: float


@dataclass(frozen=True, slots=True)
class TrackFix:
    """A scan placed by tracking: the place that fixed it, the scan's pose in the map
    (the place's map pose composed with the match's pose), the match's pose (maps the
    scan's points into the place's frame), its raw-scan score, and how many places were
    tried."""

    place_id: int
    map_pose: Pose2
    pose: Pose2
    score: float
    tried: int


def _finite(where: str, **values) -> None:
    """Each value is a finite number, else :class:`ArgumentError` naming it (NaN gave the
    floor sigma, as at the fix)."""
    for name, v in values.items():
        if isinstance(v, (bool, np.bool_)) or not (
            isinstance(v, (int, float, np.number)) and math.isfinite(v)
        ):
            raise ArgumentError(f"{where}: {name} must be a finite number, got {v!r}")


def track_std(path: float) -> tuple[float, float]:
    """The prediction's standard deviations ``(m, rad)`` after ``path`` metres from the
    fix: :data:`TRACK_SIGMA` growing by :data:`TRACK_GROWTH` per metre (ArgumentError
    for a ``path`` that is not a finite number).

    >>> [round(v, 4) for v in track_std(2.0)]
    [0.25, 0.0436]
    """
    _finite("track_std", path=path)
    d = max(0.0, float(path))
    return TRACK_SIGMA[0] + TRACK_GROWTH[0] * d, TRACK_SIGMA[1] + TRACK_GROWTH[1] * d


def predict(
    fix: Fix, own_fix: Pose2, own_now: Pose2, path_now: float
) -> tuple[Pose2, tuple[float, float]]:
    """Where the scan is in the database's map, and how uncertain that is.

    ``own_fix`` and ``own_now`` are the fix's scan and this scan in the run's own map
    (one frame, the online mapper's current estimate); their relative motion carried
    from the fix's map pose is the prediction; its standard deviations ``(m, rad)`` are
    :func:`track_std` of the path between the two (``path_now`` is the run's path at
    this scan: after the fix when tracking forwards, before it when backwards).

    >>> f = Fix(0, Pose2(10.0, 0.0, math.pi / 2), 0.0)
    >>> p, s = predict(f, Pose2(0, 0, 0), Pose2(1.0, 0, 0), 1.0)
    >>> round(p.x, 6), round(p.y, 6), [round(v, 3) for v in s]
    (10.0, 1.0, [0.2, 0.035])
    """
    _finite("predict", path_now=path_now)
    pred = fix.pose @ (own_fix.inverse() @ own_now)
    return pred, track_std(abs(path_now - fix.path))


def near_places(places: MapPoses, pred: Pose2, radius: float, n: int) -> list[int]:
    """The ids of at most ``n`` places whose map position lies within ``radius`` (m) of
    ``pred``, nearest first (ties: the smaller heading difference, then the smaller id).

    >>> near_places(MapPoses.of({1: Pose2(0, 0, 0), 2: Pose2(1, 0, 0), 3: Pose2(5, 0, 0)}),
    ...             Pose2(0.9, 0, 0), 2.0, 5)
    [2, 1]
    """
    require_count("near_places: ", n=n)
    if not len(places) or n <= 0:
        return []
    ids, a = places.ids, places.xyt
    d = np.hypot(a[:, 0] - pred.x, a[:, 1] - pred.y)
    turn = np.abs(np.angle(np.exp(1j * (a[:, 2] - pred.theta))))
    ok = np.flatnonzero(d <= radius)
    order = ok[np.lexsort((ids[ok], turn[ok], d[ok]))]
    return [int(i) for i in ids[order[:n]]]


def fix_near(
    db,
    query: PreparedScan,
    pred: Pose2,
    sigma: tuple[float, float],
    places: MapPoses,
    front_end,
    n: int = TRACK_PLACES,
    min_score: float = ACCEPT_MIN_SCORE,
) -> TrackFix | None:
    """Match ``query`` against the places near the prediction ``pred`` (at most ``n``,
    :func:`near_places` within :data:`TRACK_RADIUS` + 3 ``sigma[0]``), each with the
    prediction as the prior (:func:`scanclique.mapping.loops.verify`, standard
    deviations ``sigma`` in m and rad, ``front_end`` a
    :class:`scanclique.mapping.FrontEndConfig`, its ICP fitness lowered to
    :data:`TRACK_MIN_FITNESS`), whose raw-scan score at the refined pose is at least
    ``min_score`` (a recognised hit's floor, :data:`.verify.ACCEPT_MIN_SCORE`: a
    look-alike a metre along a corridor passes a prior broadened by a long path, with
    its raw scans barely agreeing); the first place that passes fixes the scan. None
    when none does."""
    from ..mapping.loops import verify

    fe = replace(front_end, icp_min_fitness=min(front_end.icp_min_fitness, TRACK_MIN_FITNESS))
    floor = (fe.sigma_floor_metres, fe.sigma_floor_radians)
    tried = near_places(places, pred, TRACK_RADIUS + 3.0 * sigma[0], n)
    for k, pid in enumerate(tried):
        at = places.pose(pid)
        pose, _, verdict, score, _ = verify(
            db.prepared(pid), query, at, pred, sigma, db.config, floor, fe
        )
        if verdict == "accepted" and pose is not None and score >= min_score:
            return TrackFix(pid, at @ pose, pose, float(score), k + 1)
    return None
