"""Localisation in a place database's map, scan by scan as a robot gets them (paper §2,
the second application; issue 14).

:class:`Localiser` takes a log's scans in order (:meth:`Localiser.add`) and says of each
one queried where it is in the map of a :class:`~scanclique.places.PlaceDB` whose places
have map poses (``scanclique places add DB LOG --map DIR``):

* **recognition**, with no prior: the scan is a query (:meth:`PlaceDB.query`) and is
  :data:`LOCATED` at its first accepted hit's :attr:`PlaceHit.map_pose` (hits that
  disagree on where the query is are not accepted); :data:`UNMAPPED` when only places
  without a map pose accept it, :data:`DOUBTFUL` when hits are only ambiguous,
  :data:`UNKNOWN` when there are none;
* **tracking** (``track=True``): every scan added also goes to an online map of the run
  (:class:`scanclique.mapping.OnlineMapper`); a queried scan recognition does not locate
  is predicted from the last scan placed by the run's own motion since, and matched
  against the places near the prediction with it as the prior
  (:func:`.track.fix_near`): :data:`TRACKED` when one passes. Where recognition locates
  a scan outside the prediction's gate (4 sigma, ``front_end.icp_gate``) the prediction
  is verified too: when a place near it passes, the track holds (a look-alike recognised
  with confidence, as a ring of identical corners has, is not followed; ``contested``);
  when none does, recognition decides (a robot carried elsewhere is found again).

:func:`scanclique.places.run.run_locate` runs a whole log through it (``scanclique places
locate``).
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass

from ..config import require_count, require_flag
from ..errors import ArgumentError, PlaceDatabaseError, ScanError
from ..geometry import Pose2
from ..scan import Scan
from .database import PlaceDB
from .track import TRACK_MAX_PATH, Fix, MapPoses, fix_near, predict
from .verify import ACCEPTED, AMBIGUOUS

__all__ = [
    "LOCATED", "TRACKED", "UNMAPPED", "DOUBTFUL", "UNKNOWN", "Located", "Localiser",
]  # fmt: skip

#: what :class:`Localiser` says of a scan: placed in the map by an accepted hit; only an
#: accepted hit of a place without a map pose; hits, none accepted (ambiguous); none
LOCATED, UNMAPPED, DOUBTFUL, UNKNOWN = "located", "unmapped", "ambiguous", "not recognised"
#: with tracking: not located, but placed by a place near where the run predicts it
TRACKED = "tracked"


@dataclass(frozen=True, slots=True)
class Located:
    """One scan queried by :meth:`Localiser.add`: its position among the scans added
    (``index``, from 0) and ``timestamp``, its ``status`` (:data:`LOCATED`,
    :data:`TRACKED`, :data:`UNMAPPED`, :data:`DOUBTFUL` or :data:`UNKNOWN`), its ``pose``
    in the database's map (maps the scan's points into the map frame; m, rad; None unless
    located or tracked), the place that gave it (``place_id``: the best hit's, whatever
    its verdict, or the place that tracked it; None without one) and the hit's
    ``confidence`` (0 without a hit; NaN when tracked: no hit), the time the query and
    the tracking took (ms; ``track_ms`` 0 when not tried), and whether recognition
    located the scan elsewhere than the track put it (``contested``: the track's
    prediction was verified and holds; see :class:`Localiser`)."""

    index: int
    timestamp: float | None
    status: str
    pose: Pose2 | None
    place_id: int | None
    confidence: float
    query_ms: float
    track_ms: float = 0.0
    contested: bool = False

    @property
    def placed(self) -> bool:
        """Whether the scan has a pose in the map (located or tracked)."""
        return self.pose is not None


class Localiser:
    """Locate scans in the map of an open place database as they come.

    Parameters
    ----------
    db : PlaceDB
        An open database (read-only is enough) with places that have map poses.
    k, candidates : int
        As for :meth:`PlaceDB.query`: hits per query and prefilter candidates verified.
    track : bool
        Also map the run as it goes and track the scans recognition leaves (module
        docstring). Use the localiser in a ``with`` block (or :meth:`close` it). Places
        another process adds while it runs are tracked against from the next query on.
    use_odometry : bool, optional
        The online mapper's (:class:`scanclique.mapping.OnlineMapper`): None uses the
        odometry when the first scan carries it.

    Raises
    ------
    PlaceDatabaseError
        No place of ``db`` has a map pose.
    ArgumentError
        ``db`` is not a :class:`PlaceDB`, or ``use_odometry`` is not a bool or None.
    ConfigError
        ``k`` or ``candidates`` is not an integer >= 0 (as :meth:`PlaceDB.query`).

    Examples
    --------
    >>> import os, tempfile, numpy as np, scanclique as sc
    >>> from scanclique.places.run import run_add
    >>> rng = np.random.default_rng(2)
    >>> scans = sc.sim.simulate_trajectory(rng, sc.sim.office_world(rng), 6, step=0.3)
    >>> path = os.path.join(tempfile.mkdtemp(), "p.db")
    >>> start = scans[0].reference.inverse()
    >>> _ = run_add(path, scans, every=2, poses=[start @ s.reference for s in scans])
    >>> with PlaceDB(path, readonly=True) as db, Localiser(db, track=True) as loc:
    ...     got = [loc.add(s) for s in scans]
    >>> got[3].status, round(got[3].pose.distance_to(start @ scans[3].reference)[0], 2)
    ('located', 0.0)
    """

    def __init__(
        self,
        db: PlaceDB,
        *,
        k: int = 5,
        candidates: int | None = None,
        track: bool = False,
        use_odometry: bool | None = None,
    ) -> None:
        from ..mapping import MapConfig, OnlineMapper

        if not isinstance(db, PlaceDB):
            raise ArgumentError(f"Localiser: db must be an open PlaceDB, got {type(db).__name__}")
        require_flag("Localiser: ", track=track, use_odometry=use_odometry)
        require_count("Localiser: ", k=k)
        if candidates is not None:
            require_count("Localiser: ", candidates=candidates)
        self.db, self.k, self.candidates = db, k, candidates
        self.map_poses = db.map_poses()
        if not self.map_poses:
            raise PlaceDatabaseError(
                f"{db.path}: none of its {len(db)} places has a map pose: add them with "
                "'scanclique places add DB LOG --map DIR' (the --out of 'scanclique map LOG')"
            )
        self._places, self._known = MapPoses.of(self.map_poses), len(db)
        self._cfg = MapConfig.online()
        self._mapper = OnlineMapper(use_odometry=use_odometry, config=self._cfg) if track else None
        self._n = 0  # scans added
        self._path = 0.0  # the run's path so far (m), in its own map
        self._last: Pose2 | None = None  # the last scan's pose in the run's own map
        self._fix: Fix | None = None  # the last scan placed in the database's map

    @property
    def tracking(self) -> bool:
        return self._mapper is not None

    @property
    def front_end(self):
        """The front-end configuration tracking matches with
        (:meth:`MapConfig.online() <scanclique.mapping.MapConfig.online>`'s)."""
        return self._cfg.front_end

    @property
    def places(self) -> MapPoses:
        """The map poses of the database's places, as tracking uses them."""
        return self._places

    def add(self, scan: Scan, *, query: bool = True) -> Located | None:
        """Take the next scan of the run; with ``query`` (default) locate it in the map
        and return what was found, else (a scan the caller does not need placed, only
        followed by the tracker) None.

        Raises
        ------
        ScanError
            ``scan`` is not a :class:`~scanclique.scan.Scan`.
        ArgumentError
            ``query`` is not True, False or None (a string such as ``"no"``).
        """
        if not isinstance(scan, Scan):
            raise ScanError(f"Localiser.add: scan must be a Scan, got {type(scan).__name__}")
        require_flag("Localiser.add: ", query=query)
        index = self._n
        if self._mapper is not None:
            now = self._mapper.add(scan)
            if index:  # the step as now estimated: a closure's correction is no motion
                self._path += now.distance_to(self._mapper.pose(index - 1))[0]
            self._last = now
        self._n += 1
        if not query:
            return None
        t = time.perf_counter()
        q = self.db.prepare(scan)
        hits = self.db.query(q, k=self.k, candidates=self.candidates)
        if len(self.db) != self._known:  # places added since (by any process)
            self.map_poses = self.db.map_poses()
            self._places, self._known = MapPoses.of(self.map_poses), len(self.db)
        best = hits[0] if hits else None
        if best is not None and best.verdict == ACCEPTED:
            first = next(
                (h for h in hits if h.verdict == ACCEPTED and h.map_pose is not None), None
            )
            best = first or best
            status = LOCATED if first else UNMAPPED
        else:
            status = DOUBTFUL if best and best.verdict == AMBIGUOUS else UNKNOWN
        pose = best.map_pose if status == LOCATED else None
        place = None if best is None else best.place_id
        conf = 0.0 if best is None else best.confidence
        query_ms = 1e3 * (time.perf_counter() - t)
        t = time.perf_counter()
        from ..mapping.frontend import within_gate

        fix, contested = self._fix, False
        if fix is not None and self._path - fix.path <= TRACK_MAX_PATH:
            own_fix = self._mapper.pose(fix.index)
            pred, sigma = predict(fix, own_fix, self._last, self._path)
            fe = self.front_end
            contested = status == LOCATED and not within_gate(
                pose, pred, (sigma[0], sigma[0], sigma[1]), fe.icp_gate
            )
            if status != LOCATED or contested:
                got = fix_near(self.db, q, pred, sigma, self._places, fe)
                if got is not None:
                    status, pose, place, conf = TRACKED, got.map_pose, got.place_id, math.nan
                contested = contested and got is not None
        if self._mapper is not None and pose is not None:
            self._fix = Fix(index, pose, self._path)
        track_ms = 1e3 * (time.perf_counter() - t) if self._mapper is not None else 0.0
        return Located(
            index, scan.timestamp, status, pose, place, conf, query_ms, track_ms, contested
        )

    def finish(self):
        """The run's own map of every scan added (tracking only: the online mapper's
        :meth:`~scanclique.mapping.OnlineMapper.finish`, a
        :class:`~scanclique.mapping.MapResult` in the frame of the first scan added);
        None without tracking."""
        return None if self._mapper is None else self._mapper.finish()

    def close(self) -> None:
        """End the online mapper (tracking); the database stays open (the caller's)."""
        if self._mapper is not None:
            self._mapper.close()

    def __enter__(self) -> Localiser:
        return self

    def __exit__(self, *exc) -> None:
        self.close()
