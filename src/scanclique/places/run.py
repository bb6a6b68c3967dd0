"""The work of the ``scanclique places`` and ``scanclique loops`` commands, as plain
functions a script calls the same way (no typer, no rich).

>>> import tempfile, os, numpy as np, scanclique as sc
>>> d = tempfile.mkdtemp()
>>> scans = sc.sim.simulate_trajectory(np.random.default_rng(2), sc.sim.office_world(
...     np.random.default_rng(2)), 6, step=0.3)
>>> run = run_add(os.path.join(d, "p.db"), scans, every=2)
>>> run.added, run.total
(3, 3)
>>> q = run_query(os.path.join(d, "p.db"), scans, 3, k=2)
>>> q.hits[0].verdict
'accepted'
"""

from __future__ import annotations

import math
import os
import time
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from ..config import MatchConfig, require_flag
from ..errors import ScanCliqueError
from ..features import for_scanner
from ..geometry import Pose2, align_poses, wrap_angle
from ..match import warm_up
from ..scan import Scan
from .database import PlaceDB
from .locate import DOUBTFUL, LOCATED, TRACKED, UNKNOWN, UNMAPPED, Localiser, Located
from .loops import LoopSearch, find_loops
from .verify import ACCEPT_MIN_FEATURES, ACCEPT_MIN_SCORE, ACCEPTED, AMBIGUOUS, REJECTED

__all__ = [
    "AddRun", "QueryRun", "LocateRun", "LoopsRun",
    "run_add", "run_query", "run_locate", "run_info", "run_loops", "consensus_motion",
]  # fmt: skip

#: a recognised pose is right when this close to the reference (the benchmark's rule)
RIGHT_TRANSLATION = 0.5  # metres
RIGHT_ROTATION = 0.2  # radians


def _scans(source, laser: str = "main") -> tuple[list[Scan], str]:
    """The scans of a log (path or registered name; ``laser``: which laser, a CARMEN
    message type or a ROS bag's LaserScan topic, default its main one), or a given
    sequence of scans."""
    if isinstance(source, (str, os.PathLike)):
        from .. import datasets

        s = os.fspath(source)
        scans = list(datasets.load_log(source, laser=laser))  # a log's one trajectory
        if not scans:
            raise ScanCliqueError(f"{s}: the log holds no laser scans")
        # a registered log is one log whether it is named or given by its path
        label = datasets.registered_name(source) or (os.path.basename(s) if os.sep in s else s)
        return scans, label
    return list(source), "scans"


@dataclass(frozen=True, slots=True, eq=False)
class AddRun:
    """What :func:`run_add` did: ``added`` places (ids ``ids``), ``total`` in the database
    afterwards, ``skipped`` scans already in it (by name), and the time per add."""

    path: str
    label: str
    added: int
    skipped: int
    total: int
    ids: tuple
    add_ms: tuple
    seconds: float
    loading_seconds: float = 0.0
    #: of the places added, how many with a map pose (:func:`run_add`'s ``poses``)
    posed: int = 0
    #: where the map poses came from (a TUM file), "" without
    poses_source: str = ""
    #: places already present, added before without a map pose, given theirs now
    posed_present: int = 0
    #: lost returns bridged in the database's clustering (``max_gap_beams``: 1 for a log
    #: whose scanner loses returns, :func:`scanclique.features.for_scanner`)
    bridged: int = 0
    #: whether the database's features claim edges where a wall only leaves the sensor's
    #: reach (``FeatureConfig.reach_edges``: off for a new database of a log whose scanner
    #: meets its reach, :func:`scanclique.features.for_scanner`)
    reach_edges: bool = True

    def rows(self) -> list[tuple[str, str, str]]:
        ms = np.array(self.add_ms) if self.add_ms else np.zeros(1)
        return [
            ("places added", str(self.added), ""),
            *(
                [("of them with a map pose", f"{self.posed} of {self.added}", "")]
                if self.poses_source
                else []
            ),
            ("already present (same name)", str(self.skipped), ""),
            *(
                [("of them given a map pose (they had none)", str(self.posed_present), "")]
                if self.poses_source
                else []
            ),
            ("places in the database", str(self.total), ""),
            *(
                [("lost returns bridged inside a surface", f"up to {self.bridged}", "beams")]
                if self.bridged
                else []
            ),
            *(
                [("edges where a wall leaves the reach", "left out", "")]
                if not self.reach_edges
                else []
            ),
            ("add time, median", f"{np.median(ms):.2f}", "ms"),
            ("add time, p95", f"{np.percentile(ms, 95):.2f}", "ms"),
            ("kernel loading (before the adds)", f"{self.loading_seconds:.1f}", "s"),
            ("wall time", f"{self.seconds:.1f}", "s"),
        ]

    def to_dict(self) -> dict:
        ms = np.array(self.add_ms) if self.add_ms else np.zeros(1)
        return {
            "path": self.path,
            "source": self.label,
            "added": self.added,
            "skipped": self.skipped,
            "total": self.total,
            "ids": list(self.ids),
            "add_ms_median": float(np.median(ms)),
            "posed": self.posed,
            "posed_present": self.posed_present,
            "poses": self.poses_source or None,
            "bridged": self.bridged,
            "reach_edges": self.reach_edges,
            "seconds": self.seconds,
            "loading_seconds": self.loading_seconds,
        }


def run_add(
    path: str | os.PathLike,
    source,
    *,
    every: int = 1,
    start: int = 0,
    stop: int | None = None,
    config: MatchConfig | None = None,
    progress: Callable[[int, int], None] | None = None,
    laser: str = "main",
    poses=None,
) -> AddRun:
    """Add every ``every``-th scan of ``source`` (``start`` to ``stop``) to the database
    at ``path`` as places named ``"<log>:<index>"`` (``<log>`` the registered name of a
    registered log, given by name or by path, else the file's name); scans whose name is
    already there are skipped (so a run can be repeated or resumed), except that one
    added without a map pose is given the one ``poses`` has for it (one that has a map
    pose keeps it). ``laser``: which laser of the log
    (:func:`scanclique.io.read_scans`). ``config`` None: a new database takes the
    defaults, one lost return bridged when the log's scanner loses them and no edges where
    a wall only leaves its reach (:func:`scanclique.features.for_scanner`, not widened, no
    reach edges); an existing one keeps its own.

    ``poses``, optional: where the places are in a map (:meth:`PlaceDB.add`'s ``pose``),
    as a TUM trajectory file, a directory holding ``trajectory.tum`` (the ``--out`` of
    ``scanclique map`` on the same log), rows ``time x y theta``, or one Pose2 or None per
    scan of the log. A file's or the rows' poses are given to the scans by their
    timestamps (:func:`scanclique.io.poses_at`: one row per scan in the log's order, as
    ``scanclique map`` writes it, or any trajectory in time order, interpolated); a scan
    without one is added without a pose (counted in :attr:`AddRun.posed`)."""
    scans, label = _scans(source, laser)
    if config is None and not os.path.exists(path):
        # a new database: a lost return bridged for a scanner that loses them, no edges
        # where a wall only leaves the reach
        config = for_scanner(None, scans, widen=False, reach_edges=False)
    idx = list(_span(len(scans), start, stop)[:: max(1, every)])
    place_poses, poses_source = _place_poses(poses, scans)
    t0 = time.perf_counter()
    loading = warm_up()  # loading the kernels is reported apart from the adds' times
    ids, ms, skipped, posed = [], [], 0, 0
    given = 0
    with PlaceDB(path, config) as db:
        have = {v: k for k, v in db.store.names(db.ids).items()} if len(db) else {}
        for n, i in enumerate(idx):
            name = f"{label}:{i}"
            if name in have:
                skipped += 1
                pid = have[name]
                if place_poses[i] is not None and db.map_pose(pid) is None:
                    db.set_map_pose(pid, place_poses[i])  # added before without one
                    given += 1
            else:
                t = time.perf_counter()
                ids.append(db.add(scans[i], name=name, pose=place_poses[i]))
                ms.append(1e3 * (time.perf_counter() - t))
                posed += place_poses[i] is not None
            if progress:
                progress(n + 1, len(idx))
        total = len(db)
        bridged = db.config.clustering.max_gap_beams
        reach_edges = db.config.features.reach_edges
    return AddRun(
        os.fspath(path), label, len(ids), skipped, total, tuple(ids), tuple(ms),
        time.perf_counter() - t0, loading, posed, poses_source, given, bridged, reach_edges,
    )  # fmt: skip


def _span(n: int, start: int, stop: int | None) -> range:
    """The indices ``start`` to ``stop`` (None: the end) of a log of ``n`` scans."""
    return range(start, n if stop is None else min(stop, n))


#: the trajectory file in a ``scanclique map`` output directory
TRAJECTORY_FILE = "trajectory.tum"


def _place_poses(poses, scans: list[Scan]) -> tuple[list, str]:
    """One map pose (Pose2 or None) per scan from :func:`run_add`'s ``poses``, and where
    they came from ("" for none)."""
    from ..errors import ArgumentError, DataNotFoundError
    from ..io import poses_at, read_tum

    if poses is None:
        return [None] * len(scans), ""
    if isinstance(poses, (str, os.PathLike)):
        p = os.fspath(poses)
        if os.path.isdir(p):
            f = os.path.join(p, TRAJECTORY_FILE)
            if not os.path.isfile(f):
                raise DataNotFoundError(
                    f"{p}: a directory without {TRAJECTORY_FILE} (the --out of scanclique map)"
                )
            p = f
        rows, source = read_tum(p), p
    elif isinstance(poses, np.ndarray) and poses.ndim == 2:  # rows time x y theta
        rows, source = poses, "rows"
    else:
        got = list(poses)
        if len(got) != len(scans) or not all(q is None or isinstance(q, Pose2) for q in got):
            raise ArgumentError(
                f"poses must be a TUM file, a scanclique map directory, rows time x y theta "
                f"or one Pose2 or None per scan ({len(scans)}), got {len(got)} items"
            )
        return got, "poses"
    try:
        return list(poses_at(rows, [s.timestamp for s in scans])), source
    except ArgumentError as exc:
        raise ArgumentError(f"{source}: {exc}") from None


@dataclass(frozen=True, slots=True, eq=False)
class QueryRun:
    """The hits of one query (:meth:`PlaceDB.query`), with the query's reference error of
    each hit when both the query and the place have reference poses
    (``errors[k] = (metres, radians)`` or None)."""

    path: str
    label: str
    index: int
    hits: tuple
    errors: tuple
    places: int
    seconds: float
    loading_seconds: float = 0.0

    @property
    def mapped(self) -> bool:
        """Whether a hit gives the query's pose in a map (:attr:`PlaceHit.map_pose`): the
        rows of :meth:`hit_rows` then end with it."""
        return any(h.map_pose is not None for h in self.hits)

    def hit_rows(self) -> list[tuple[str, ...]]:
        out, mapped = [], self.mapped
        for h, e in zip(self.hits, self.errors, strict=True):
            p, m = h.pose, h.map_pose
            out.append(
                (
                    str(h.rank),
                    f"{h.place_id} {h.name}" if h.name else str(h.place_id),
                    h.verdict if h.source == "clique" else f"{h.verdict} ({h.source})",
                    f"{h.score:.2f}",
                    f"{h.confidence:.3f}",
                    str(h.n_features),
                    "-" if p is None else f"{p.x:.2f} {p.y:.2f} {math.degrees(p.theta):.1f}",
                    "-" if e is None else f"{e[0]:.2f} {math.degrees(e[1]):.1f}",
                    *(
                        ["-" if m is None else f"{m.x:.2f} {m.y:.2f} {math.degrees(m.theta):.1f}"]
                        if mapped
                        else []
                    ),
                )
            )
        return out

    def rows(self) -> list[tuple[str, str, str]]:
        n = {v: sum(h.verdict == v for h in self.hits) for v in (ACCEPTED, AMBIGUOUS, REJECTED)}
        return [
            ("places in the database", str(self.places), ""),
            ("hits shown", str(len(self.hits)), ""),
            (
                "accepted / ambiguous / rejected",
                f"{n[ACCEPTED]} / {n[AMBIGUOUS]} / {n[REJECTED]}",
                "",
            ),
            ("query time", f"{1e3 * self.seconds:.1f}", "ms"),
            ("kernel loading (before the query)", f"{self.loading_seconds:.1f}", "s"),
        ]

    def to_dict(self) -> dict:
        return {
            "path": self.path,
            "query": f"{self.label}:{self.index}",
            "places": self.places,
            "seconds": self.seconds,
            "loading_seconds": self.loading_seconds,
            "hits": [
                {**h.to_dict(), "reference_error": None if e is None else list(e)}
                for h, e in zip(self.hits, self.errors, strict=True)
            ],
        }


def run_query(
    path: str | os.PathLike,
    source,
    index: int,
    *,
    k: int = 5,
    candidates: int | None = None,
    config: MatchConfig | None = None,
    min_score: float = ACCEPT_MIN_SCORE,
    min_features: int = ACCEPT_MIN_FEATURES,
    laser: str = "main",
) -> QueryRun:
    """Query the database at ``path`` with scan ``index`` of ``source`` (of its laser
    ``laser``, :func:`scanclique.io.read_scans`)."""
    from ..errors import ScanIndexError

    scans, label = _scans(source, laser)
    if not 0 <= index < len(scans):
        raise ScanIndexError(
            f"{label}: scan index {index} out of range: the log has {len(scans)} scans "
            f"(0..{len(scans) - 1})"
        )
    q = scans[index]
    loading = warm_up()  # loading the kernels is reported apart from the query's time
    with PlaceDB(path, config, readonly=True, min_score=min_score, min_features=min_features) as db:
        t = time.perf_counter()
        hits = db.query(q, k=k, candidates=candidates)
        seconds = time.perf_counter() - t
        errors = []
        for h in hits:
            ref = db.get(h.place_id).scan.reference if h.pose is not None else None
            if ref is None or q.reference is None:
                errors.append(None)
            else:
                errors.append((ref @ h.pose).distance_to(q.reference))
        n = len(db)
    return QueryRun(os.fspath(path), label, index, tuple(hits), tuple(errors), n, seconds, loading)


@dataclass(frozen=True, slots=True, eq=False)
class LocateRun:
    """What :func:`run_locate` found: for each scan queried (``indices``, with their
    ``timestamps``), its ``status`` (:data:`LOCATED`, :data:`TRACKED`, :data:`UNMAPPED`,
    :data:`DOUBTFUL` or :data:`UNKNOWN`), its pose in the database's map (``poses``:
    Pose2, None unless located or tracked), the place that gave it and that hit's
    confidence (``places``, ``confidences``: the best hit's, whatever its verdict; None
    and 0 without one; a tracked scan's place is the one that fixed it, its confidence
    NaN: no hit), and the query times (ms)."""

    path: str
    label: str
    indices: tuple
    timestamps: tuple
    status: tuple
    poses: tuple
    places: tuple
    confidences: tuple
    query_ms: tuple
    mapped_places: int
    total_places: int
    seconds: float
    loading_seconds: float = 0.0
    #: with ``whole=True``: the motion carrying the log's own map (``map_scans``) into the
    #: database's (None when its located, or tracked, scans agree on none), how many of
    #: them agree on it and their residual RMS (m), and every scan's pose in the database's
    #: map (``trajectory``, one per scan from ``start`` to ``stop``; None unplaced)
    anchor: Pose2 | None = None
    anchor_inliers: int = 0
    anchor_rms: float = math.nan
    trajectory: tuple = ()
    trajectory_indices: tuple = ()
    trajectory_times: tuple = ()
    #: the map poses of the database's places that have one (for a figure)
    place_poses: tuple = ()
    #: with ``whole=True``: how far apart the agreeing located scans lie, and the run
    #: (the diagonals of their bounding boxes, m): a run carried by scans at one end of it
    #: may be off by the rotation's lever arm at the other
    anchor_spread: float = math.nan
    run_extent: float = math.nan
    #: whether the carried run was bent onto its placed scans (:func:`bend_onto`: some
    #: of them disagree with the rigid carry)
    bent: bool = False
    #: whether the scans not located were tracked (``track=True``), the time that took
    #: for each scan queried (ms, after its query; 0 when not tried), and whether each
    #: tracked scan was one recognition located elsewhere (:attr:`Located.contested`)
    tracked: bool = False
    track_ms: tuple = ()
    contested: tuple = ()

    def count(self, status: str) -> int:
        return sum(s == status for s in self.status)

    def rows(self) -> list[tuple[str, str, str]]:
        n = max(len(self.indices), 1)
        ms = np.array(self.query_ms) if self.query_ms else np.zeros(1)
        return [
            ("scans queried", str(len(self.indices)), ""),
            *(
                (what, f"{self.count(s)} ({100.0 * self.count(s) / n:.1f} %)", "")
                for what, s in (
                    ("located in the map (an accepted hit)", LOCATED),
                    *(
                        [("tracked (a place near where the run predicts it)", TRACKED)]
                        if self.tracked
                        else []
                    ),
                    ("accepted, by places without a map pose only", UNMAPPED),
                    ("recognised, none accepted (ambiguous)", DOUBTFUL),
                    ("not recognised", UNKNOWN),
                )
            ),
            *(
                [("tracked, though recognised elsewhere", str(sum(self.contested)), "")]
                if self.tracked
                else []
            ),
            ("places with a map pose", f"{self.mapped_places} of {self.total_places}", ""),
            *(
                [
                    (
                        "whole run carried into the map by",
                        f"{self.anchor_inliers} of {self.count(LOCATED) + self.count(TRACKED)} "
                        "located or tracked scans"
                        if self.anchor is not None
                        else "none (the located scans agree on no one motion)",
                        "",
                    ),
                    ("their residual, RMS", f"{self.anchor_rms:.3f}", "m"),
                    (
                        "then bent onto every placed scan",
                        "yes (some disagree with the rigid carry)" if self.bent else "no",
                        "",
                    ),
                    (
                        "they lie within / the run spans",
                        f"{self.anchor_spread:.1f} / {self.run_extent:.1f}",
                        "m",
                    ),
                ]
                if self.trajectory
                else []
            ),
            ("query time, median", f"{np.median(ms):.1f}", "ms"),
            ("query time, p95", f"{np.percentile(ms, 95):.1f}", "ms"),
            *(
                [("tracking time per scan, mean", f"{np.mean(self.track_ms):.1f}", "ms")]
                if self.track_ms
                else []
            ),
            ("kernel loading (before the queries)", f"{self.loading_seconds:.1f}", "s"),
            ("wall time", f"{self.seconds:.1f}", "s"),
        ]

    def to_dict(self) -> dict:
        return {
            "path": self.path,
            "source": self.label,
            "queried": len(self.indices),
            **{s: self.count(s) for s in (LOCATED, TRACKED, UNMAPPED, DOUBTFUL, UNKNOWN)},
            "mapped_places": self.mapped_places,
            "places": self.total_places,
            "seconds": self.seconds,
            "loading_seconds": self.loading_seconds,
            "tracking": self.tracked,
            "track_ms_mean": float(np.mean(self.track_ms)) if self.track_ms else None,
            "contested": int(sum(self.contested)),
            "anchor": None
            if self.anchor is None
            else {"x": self.anchor.x, "y": self.anchor.y, "theta": self.anchor.theta},
            "anchor_inliers": self.anchor_inliers,
            "anchor_rms": None if math.isnan(self.anchor_rms) else self.anchor_rms,
            "anchor_spread": None if math.isnan(self.anchor_spread) else self.anchor_spread,
            "run_extent": None if math.isnan(self.run_extent) else self.run_extent,
            "bent": self.bent,
            "scans": [
                {
                    "index": i,
                    "timestamp": t,
                    "status": s,
                    "pose": None if p is None else {"x": p.x, "y": p.y, "theta": p.theta},
                    "place_id": pid,
                    "confidence": None if math.isnan(c) else c,
                    "query_ms": ms,
                    "contested": bool(con),
                }
                for i, t, s, p, pid, c, ms, con in zip(
                    self.indices,
                    self.timestamps,
                    self.status,
                    self.poses,
                    self.places,
                    self.confidences,
                    self.query_ms,
                    self.contested or (False,) * len(self.indices),
                    strict=True,
                )  # fmt: skip
            ],
        }


def run_locate(
    path: str | os.PathLike,
    source,
    *,
    every: int = 1,
    start: int = 0,
    stop: int | None = None,
    k: int = 5,
    candidates: int | None = None,
    config: MatchConfig | None = None,
    laser: str = "main",
    progress: Callable[[int, int], None] | None = None,
    whole: bool = False,
    track: bool = False,
    use_odometry: bool | None = None,
) -> LocateRun:
    """Localise the scans of a log in the map of a place database: topological
    localisation by recognition, scan by scan, with no prior pose (paper §2).

    Every ``every``-th scan of ``source`` (``start`` to ``stop``; ``laser`` as in
    :func:`scanclique.io.read_scans`) is a query (:meth:`PlaceDB.query`, ``k`` hits of
    ``candidates`` verified); its pose in the map is the first accepted hit's
    :attr:`PlaceHit.map_pose` (the place's map pose composed with the hit's pose; hits
    that disagree on where the query is are not accepted). Without ``track`` scans are
    queried independently: nothing is carried from one to the next.

    ``track=True`` also maps the run as it goes (:class:`scanclique.mapping.OnlineMapper`,
    every scan from ``start`` on): a queried scan that recognition does not locate is
    predicted from the last scan placed, by the run's own motion since, and matched
    against the places near the prediction with it as the prior
    (:func:`scanclique.places.track.fix_near`): status :data:`TRACKED` when one accepts.
    A scan recognition locates outside the prediction's gate stays with the track when
    the prediction is verified too (:attr:`Located.contested`), else recognition decides
    (a robot carried elsewhere is found again): :class:`scanclique.places.Localiser`.
    Then, the log being whole, the scans still unplaced are tracked backwards from the
    next scan placed after them, along the run's finished own map (:data:`TRACK_BACK`).

    ``whole=True`` also maps the log itself (:func:`scanclique.mapping.map_scans`, every
    scan from ``start`` to ``stop``; with ``track``, the tracker's online map of them,
    finished) and carries that map into the database's by the
    rigid motion its located (and tracked) scans agree on (:func:`consensus_motion`):
    every scan's pose in the database's map (:attr:`LocateRun.trajectory`), when at least
    :data:`ANCHOR_MIN_INLIERS` of them agree.

    ``use_odometry`` is the mappers' (:func:`scanclique.mapping.map_scans`): None uses
    the scans' odometry when they all carry it and it moves as the scans do.

    Raises
    ------
    PlaceDatabaseError
        No place of the database has a map pose (add them with
        ``scanclique places add DB LOG --map DIR``), or no such database.
    ArgumentError
        ``use_odometry`` not True, False or None.
    """
    from ..mapping import MapConfig, map_scans
    from ..mapping.pipeline import choose_odometry

    require_flag("run_locate: ", track=track, use_odometry=use_odometry)
    scans, label = _scans(source, laser)
    span = _span(len(scans), start, stop)
    idx = list(span[:: max(1, every)])
    t0 = time.perf_counter()
    loading = warm_up()
    found: list[Located] = []
    online = use_odometry
    if track:  # as map_scans decides it, from the whole log (a live robot could not)
        online, _ = choose_odometry([scans[i] for i in span], use_odometry, MapConfig.online())
    with (
        PlaceDB(path, config, readonly=True) as db,
        Localiser(db, k=k, candidates=candidates, track=track, use_odometry=online) as loc,
    ):
        want = set(idx)
        # with track and whole the tracker's own map of the whole span is the run's map
        last = span[-1] if track and whole and len(span) else (idx[-1] if idx else start - 1)
        for i in range(start, last + 1):
            r = loc.add(scans[i], query=i in want)
            if r is not None:
                found.append(r)
                if progress:
                    progress(len(found), len(idx))
        total, place_poses = len(db), tuple(loc.map_poses.values())
        tracked_map = loc.finish() if track else None
        if track and TRACK_BACK:
            found = _track_back(db, loc, found, scans, start, tracked_map.poses)
    if not whole:
        tracked_map = None
    status = [r.status for r in found]
    poses = [r.pose for r in found]
    whole_run = {}
    if whole:
        own = (
            tracked_map
            or map_scans(
                [scans[i] for i in span],
                use_odometry=use_odometry,
                progress=None
                if progress is None
                else lambda d, n, _c: progress(len(idx) + d, len(idx) + n),
            )
        ).poses
        # the scans placed in the map (located, and tracked with track=True)
        placed = [
            p if s in (LOCATED, TRACKED) else None for s, p in zip(status, poses, strict=True)
        ]
        pairs = [(own[i - start], p) for i, p in zip(idx, placed, strict=True)
                 if p is not None and own[i - start] is not None]  # fmt: skip
        motion, inliers, rms = consensus_motion(pairs)
        anchored = motion is not None and len(inliers) >= ANCHOR_MIN_INLIERS
        run_xy = np.array([[q.x, q.y] for q in own if q is not None]).reshape(-1, 2)
        carried = [None if q is None or not anchored else motion @ q for q in own]
        bent = anchored and len(inliers) < len(pairs)
        if bent:  # placed scans the rigid carry leaves out: the run's own map is bent
            fixes = [(i - start, p) for i, p in zip(idx, placed, strict=True)
                     if p is not None and own[i - start] is not None]  # fmt: skip
            carried = bend_onto(own, carried, fixes)
        whole_run = dict(
            anchor=motion if anchored else None, anchor_inliers=len(inliers), anchor_rms=rms,
            anchor_spread=_extent(np.array([[pairs[i][0].x, pairs[i][0].y] for i in inliers])),
            run_extent=_extent(run_xy), trajectory=tuple(carried), bent=bent,
            trajectory_indices=tuple(span),
            trajectory_times=tuple(scans[i].timestamp for i in span),
        )  # fmt: skip
    return LocateRun(
        os.fspath(path), label, tuple(idx), tuple(scans[i].timestamp for i in idx),
        tuple(status), tuple(poses), tuple(r.place_id for r in found),
        tuple(r.confidence for r in found), tuple(r.query_ms for r in found),
        len(place_poses), total, time.perf_counter() - t0, loading, **whole_run,
        place_poses=place_poses, tracked=track,
        track_ms=tuple(r.track_ms for r in found) if track else (),
        contested=tuple(r.contested for r in found) if track else (),
    )  # fmt: skip


#: ``run_locate(track=True)`` also tracks backwards, from each scan placed to the
#: queried scans before it that are not (offline: the run's finished own map)
TRACK_BACK = True


def _track_back(db, loc, found: list, scans, start: int, own) -> list:
    """``found`` (:class:`Located` per queried scan, in order) with the scans left
    unplaced tracked from the next placed scan after them, backwards along the run's own
    map ``own`` (Pose2 or None per scan added, the first at ``start``): the same
    prediction, prior and matching as forward (:mod:`scanclique.places.track`), not
    past :data:`~scanclique.places.track.TRACK_MAX_PATH` of path."""
    from dataclasses import replace

    from .track import TRACK_MAX_PATH, Fix, fix_near, predict

    xy = np.array([[q.x, q.y] if q is not None else [np.nan, np.nan] for q in own])
    steps = np.hypot(*np.diff(xy, axis=0).T) if len(xy) > 1 else np.zeros(0)
    path = np.concatenate([[0.0], np.cumsum(np.nan_to_num(steps))])
    out, nxt = list(found), None  # nxt: the next scan placed, as a Fix
    for k in range(len(out) - 1, -1, -1):
        r = out[k]
        j = r.index
        if r.pose is not None:
            nxt = Fix(j, r.pose, float(path[j]))
            continue
        if nxt is None or own[j] is None or own[nxt.index] is None:
            continue
        if nxt.path - path[j] > TRACK_MAX_PATH:
            continue
        t = time.perf_counter()
        pred, sigma = predict(nxt, own[nxt.index], own[j], float(path[j]))
        got = fix_near(db, db.prepare(scans[start + j]), pred, sigma, loc.places, loc.front_end)
        ms = r.track_ms + 1e3 * (time.perf_counter() - t)
        if got is not None:
            out[k] = replace(r, status=TRACKED, pose=got.map_pose, place_id=got.place_id,
                             confidence=math.nan, track_ms=ms)  # fmt: skip
            nxt = Fix(j, got.map_pose, float(path[j]))
        else:
            out[k] = replace(r, track_ms=ms)
    return out


#: the run's own map as a random walk between consecutive scans (``bend_onto``): standard
#: deviation per square root of metre travelled (m, rad), the rates of the mapper's own
#: chain model (``mapping.pipeline``: 0.02 m and 0.3 deg per metre), and of heading per
#: radian turned
BEND_WALK = (0.02, math.radians(0.3))
BEND_TURN = 0.01
#: the M-estimator of the fixes' priors in :func:`bend_onto`, and its scale (in sigmas):
#: a wrong fix is outweighed, while a run bent by metres (ten sigmas and more from the
#: rigid carry) still pulls (scale 1 left a simulated 8 deg bend 1.75 m off; CSAIL the same)
BEND_KERNEL = ("cauchy", 3.0)


def bend_onto(own, carried, fixes) -> list:
    """The run's own map ``own`` (Pose2 or None per scan), carried rigidly into the
    database's map (``carried``), bent onto its placed scans ``fixes`` (``(index in own,
    map pose)``): a pose graph (GTSAM, :class:`scanclique.mapping.backend.PoseGraph`) of
    the own map's steps between consecutive scans as a random walk
    (:data:`BEND_WALK` per square root of metre, :data:`BEND_TURN` of each turn) and a
    prior at each fix (:data:`ANCHOR_SIGMA`, under :data:`BEND_KERNEL`: a wrong fix is
    outweighed), solved from the rigid carry. Returns the poses, None where ``own`` has
    none.

    A run that closes no loop bends as it goes (CSAIL's second half: its own map's best
    rigid alignment leaves 0.30 m); the rigid carry then leaves out the fixes at its far
    end, and this brings them back."""
    from ..mapping.backend import PoseGraph

    valid = [j for j, q in enumerate(own) if q is not None]
    g = PoseGraph(anchor=False)
    for j in valid:
        g.add_node(j, carried[j])
    for a, b in zip(valid, valid[1:], strict=False):
        rel = own[a].inverse() @ own[b]
        d = math.hypot(rel.x, rel.y)
        s_xy = math.sqrt(1e-6 + BEND_WALK[0] ** 2 * d)
        s_th = math.sqrt(1e-8 + BEND_WALK[1] ** 2 * d + (BEND_TURN * rel.theta) ** 2)
        g.add_edge(a, b, rel, np.diag([s_xy**2, s_xy**2, s_th**2]))
    sigmas = (ANCHOR_SIGMA[0], ANCHOR_SIGMA[0], ANCHOR_SIGMA[1])
    for j, p in fixes:
        g.add_prior(j, p, sigmas, robust=BEND_KERNEL[0], robust_scale=BEND_KERNEL[1])
    got = g.optimize()
    return [got.get(j) for j in range(len(own))]


def _extent(xy: np.ndarray) -> float:
    """The diagonal of the bounding box of points ``(N, 2)`` (0 for fewer than two)."""
    xy = np.asarray(xy, dtype=float).reshape(-1, 2)
    return float(np.hypot(*np.ptp(xy, axis=0))) if len(xy) >= 2 else 0.0


#: a log's own map is carried into a database's only when this many located scans agree
#: on the motion (:func:`run_locate`'s ``whole``)
ANCHOR_MIN_INLIERS = 3
#: how far a located scan's map pose may be from where the carried run puts it (m, rad),
#: weighing positions against headings in :func:`consensus_motion`'s refit: located
#: scans bunched within a few metres fix the rotation by their headings (CSAIL's second
#: half, 7 of them within 13.6 m of a 53 m run: carried run 1.027 -> 0.939 m RMS)
ANCHOR_SIGMA = (0.1, math.radians(1.0))


def consensus_motion(
    pairs, metres: float = 1.0, radians: float = 0.2
) -> tuple[Pose2 | None, int, float]:
    """The rigid motion ``T`` that carries most poses ``a`` onto their ``b``: each pair
    ``(a, b)`` proposes ``T = b a^-1``; the proposal with the most pairs it carries
    within ``metres`` and ``radians`` wins (ties: the smaller summed distance), refitted
    to its agreeing pairs' positions and headings (:func:`scanclique.geometry.align_poses`
    with :data:`ANCHOR_SIGMA`; with one pair its own proposal). Returns ``(T, the
    indices of the agreeing pairs, their residual RMS in metres)``; ``(None, (), nan)``
    without pairs. Vectorised, :data:`CONSENSUS_CHUNK` proposals at a time (memory
    linear in the pairs)."""
    if not pairs:
        return None, (), math.nan
    a = np.array([p.as_array() for p, _ in pairs], dtype=float)
    b = np.array([q.as_array() for _, q in pairs], dtype=float)
    th = b[:, 2] - a[:, 2]  # each proposal's rotation, then its translation
    c, s = np.cos(th), np.sin(th)
    tx = b[:, 0] - (c * a[:, 0] - s * a[:, 1])
    ty = b[:, 1] - (s * a[:, 0] + c * a[:, 1])
    best_key, best = (-1, 0.0), None
    for k0 in range(0, len(pairs), CONSENSUS_CHUNK):
        k = slice(k0, k0 + CONSENSUS_CHUNK)
        x = c[k, None] * a[None, :, 0] - s[k, None] * a[None, :, 1] + tx[k, None]
        y = s[k, None] * a[None, :, 0] + c[k, None] * a[None, :, 1] + ty[k, None]
        dt = np.hypot(x - b[None, :, 0], y - b[None, :, 1])
        dr = np.abs(wrap_angle(a[None, :, 2] + th[k, None] - b[None, :, 2]))
        ok = (dt <= metres) & (dr <= radians)
        n, d = ok.sum(axis=1), np.where(ok, dt, 0.0).sum(axis=1)
        for r in np.lexsort((d, -n))[:1]:  # the most agreeing, then the closest
            if (int(n[r]), -float(d[r])) > best_key:
                best_key, best = (int(n[r]), -float(d[r])), np.flatnonzero(ok[r])
    if len(best) >= 2:
        T = Pose2(*align_poses(a[best], b[best], *ANCHOR_SIGMA))
    else:
        p, q = pairs[int(best[0])]
        T = q @ p.inverse()
    res = [(T @ pairs[i][0]).distance_to(pairs[i][1])[0] for i in best]
    return T, tuple(int(i) for i in best), float(np.sqrt(np.mean(np.square(res))))


#: proposals :func:`consensus_motion` weighs at once
CONSENSUS_CHUNK = 256


def run_info(path: str | os.PathLike, check: bool = False) -> dict:
    """:meth:`PlaceDB.info` of an existing database (opened read-only)."""
    with PlaceDB(path, readonly=True) as db:
        return db.info(check=check)


@dataclass(frozen=True, slots=True, eq=False)
class LoopsRun:
    """:func:`run_loops`' result: the search, and when the log has reference poses the
    number of accepted loops whose pose is right (0.5 m, 0.2 rad)."""

    label: str
    search: LoopSearch
    every: int
    right: int | None
    out: str | None = None
    notes: tuple = field(default=())

    def rows(self) -> list[tuple[str, str, str]]:
        s = self.search
        n = {v: sum(lp.verdict == v for lp in s.loops) for v in (ACCEPTED, AMBIGUOUS, REJECTED)}
        rows = [
            ("scans searched", str(s.n_scans), ""),
            ("candidates per scan", str(s.candidates), ""),
            ("minimum gap", str(s.min_gap), "scans"),
            ("pairs verified", str(len(s.loops)), ""),
            ("accepted", str(n[ACCEPTED]), ""),
            ("ambiguous", str(n[AMBIGUOUS]), ""),
            ("rejected", str(n[REJECTED]), ""),
        ]
        if self.right is not None:
            rows.append(("accepted with a right pose (0.5 m, 0.2 rad)", str(self.right), ""))
        rows += [
            ("backend", f"{s.backend} ({s.workers} worker{'s' if s.workers != 1 else ''})", ""),
            ("signatures", f"{s.seconds['signatures']:.1f}", "s"),
            ("prefilter", f"{s.seconds['prefilter']:.2f}", "s"),
            ("verification", f"{s.seconds['verify']:.1f}", "s"),
            ("total", f"{s.seconds['total']:.1f}", "s"),
        ]
        return rows

    def to_dict(self) -> dict:
        return {"source": self.label, "every": self.every, "right": self.right,
                **self.search.to_dict()}  # fmt: skip


def run_loops(
    source,
    *,
    every: int = 1,
    candidates: int = 5,
    min_gap: int = 50,
    workers: int = 1,
    scheduler=None,
    config: MatchConfig | None = None,
    min_score: float = ACCEPT_MIN_SCORE,
    out: str | os.PathLike | None = None,
    progress: Callable[[str, int, int], None] | None = None,
    laser: str = "main",
) -> LoopsRun:
    """Every revisit of a log (:func:`.loops.find_loops`) on every ``every``-th scan
    (``min_gap`` counts scans of the full log); indices in the result are of the full
    log (of its laser ``laser``, :func:`scanclique.io.read_scans`). Writes the result as
    JSON to ``out`` when given."""
    import json

    scans, label = _scans(source, laser)
    sel = scans[:: max(1, every)]
    gap = max(1, math.ceil(min_gap / max(1, every)))
    res = find_loops(
        sel, config, candidates=candidates, min_gap=gap, workers=workers,
        scheduler=scheduler, min_score=min_score, progress=progress,
    )  # fmt: skip
    if every > 1:
        from .loops import Loop

        loops = tuple(
            Loop(lp.i * every, lp.j * every, lp.rank, lp.distance, lp.verdict, lp.pose,
                 lp.score, lp.n_features)
            for lp in res.loops
        )  # fmt: skip
        res = LoopSearch(loops, len(sel), res.candidates, gap * every, res.backend,
                         res.workers, res.seconds)  # fmt: skip
    right = None
    if all(s.reference is not None for s in scans):
        right = 0
        for lp in res.accepted:
            t, r = (scans[lp.j].reference @ lp.pose).distance_to(scans[lp.i].reference)
            right += bool(t <= RIGHT_TRANSLATION and r <= RIGHT_ROTATION)
    run = LoopsRun(label, res, every, right, None if out is None else os.fspath(out))
    if out is not None:
        with open(out, "w") as fh:
            json.dump(run.to_dict(), fh, indent=1)
    return run
