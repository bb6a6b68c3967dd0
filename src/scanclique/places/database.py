"""The place database: add observations as places, query a scan for the places it sees.

>>> import tempfile, os, numpy as np, scanclique as sc
>>> pair = sc.sim.simulate_pair(np.random.default_rng(24))
>>> path = os.path.join(tempfile.mkdtemp(), "places.db")
>>> with PlaceDB(path) as db:
...     pid = db.add(pair.scan_a, name="room")
...     hits = db.query(pair.scan_b, k=1)
>>> hits[0].name, hits[0].verdict, bool(hits[0].confidence >= 0.99)
('room', 'accepted', True)
>>> t_err, r_err = hits[0].pose.distance_to(pair.pose_a_b)
>>> bool(t_err < 0.1 and r_err < 0.02)
True

A query is, in order:

1. the query scan prepared (features, feature graph, raw-point cloud), its signature
   (:func:`.signature.scan_signature`) and its feature triangles
   (:func:`.hashing.feature_triangles`);
2. the prefilter, two rankings taken in turn until ``candidates`` places: the places
   whose triangles agree most on one pose with the query's (geometric hashing,
   :class:`.hashing.TriangleIndex`: robust to partial overlap and any change of
   heading) and the places of nearest signature (exact brute force,
   :class:`.index.SignatureIndex`: a similar view of the whole scan);
3. each candidate verified (:func:`.verify.verify_pair`): the clique matcher against
   the stored place (without its raw-scan pose search, see ``search``), then validation
   without odometry; when none is accepted with a confidence of at least
   :data:`.verify.ACCEPT_MIN_CONFIDENCE`, the next ``escalate`` candidates too;
4. the second path (``PlaceHit.source == "triangles"``), when the matcher accepted no
   candidate: the candidates it rejected, and up to ``seeded`` more places down the
   triangle ranking, whose triangles
   agree on one pose bin with at least :data:`SEED_MIN_VOTES` votes, verified from that
   pose on the raw scans (:func:`.verify.verify_seeded`: ICP, score, conditioning,
   agreement with the triangles' pose, no quarter- or half-turn alias);
5. each hit's confidence (:func:`.verify.confidence`: the probability that its pose is
   right, from its raw-scan score, how unlikely its clique is between unrelated places,
   how nearly a distinct pose explains the same scans, and how much of either scan lies
   in the other's observed free space); an accepted hit below ``min_confidence`` becomes
   ``ambiguous``;
6. the hits ranked: accepted first, then ambiguous, then rejected; by confidence within
   each (to :data:`CONFIDENCE_DIGITS` decimals, then raw-scan score).

Places are stored in SQLite (:class:`.store.PlaceStore`); the signatures are loaded and
the triangles computed from the stored point features when a database is opened (about
0.4 ms per place) and kept in memory; the stored scan is prepared
again when a place is verified (a quarter of a millisecond, less than reading and checking
its features' blobs) and kept in a cache of recently used places. A database opened by
several processes sees the places another process added at its next query.
"""

from __future__ import annotations

import dataclasses
import json
import logging
import math
import os
import sqlite3
import urllib.parse
from collections import OrderedDict
from collections.abc import Iterable
from dataclasses import dataclass
from itertools import zip_longest
from pathlib import Path

import numpy as np

from .. import __version__
from ..config import MatchConfig, config_from_dict, config_to_dict, require_config, require_count
from ..errors import ArgumentError, ConfigError, PlaceDatabaseError, ScanError
from ..geometry import Pose2
from ..match import PreparedScan, prepare_scan
from ..scan import Scan
from .hashing import TriangleIndex, feature_triangles
from .index import SignatureIndex
from .signature import SIGNATURE_SIZE, SIGNATURE_VERSION, scan_signature
from .store import MAP_POSE, PlaceRecord, PlaceStore
from .verify import (
    ACCEPT_MIN_CONFIDENCE,
    ACCEPT_MIN_FEATURES,
    ACCEPT_MIN_SCORE,
    ACCEPTED,
    AMBIGUOUS,
    REJECTED,
    VERDICT_RANK,
    Verification,
    alias_score,
    below_confidence,
    verify_pair,
    verify_seeded,
)

__all__ = [
    "PlaceDB",
    "PlaceHit",
    "PREPARE_KEYS",
    "MIN_VOTES",
    "SEEDED",
    "SEED_MIN_VOTES",
    "MAP_POSE",
    "AGREE_METRES",
    "AGREE_RADIANS",
    "RIVAL_CONFIDENCE",
    "RIVAL_RATIO",
    "feature_arrays",
]

log = logging.getLogger(__name__)

#: the configuration values that decide a place's stored features and signature: a
#: database refuses to be used with a configuration that differs in any of them
PREPARE_KEYS = ("clustering", "features", "refine.sample_points")

#: a place enters the candidates by the triangle ranking only with at least this many
#: votes in one pose bin: one triangle alone implies a pose with any place that has an
#: equal triangle, two that agree on it are evidence
MIN_VOTES = 2
#: places beyond the verified candidates that a query checks by their triangle pose alone
#: (:func:`.verify.verify_seeded`, an ICP from the pose bin the triangles agree on),
#: taken down the triangle ranking, when the clique matcher accepted no candidate. 0 by
#: default since session 9: with :data:`ESCALATE` more candidates verified by the
#: matcher, these places gave no further right answer on the three shared logs (recall
#: at 99 % precision 0.826 / 0.474 / 0.736 with 10 or with 0; ``benchmarks/places.py
#: --seeded``) and cost most of the time of the queries that have no true place (the
#: rejected candidates are still checked from their triangle pose)
SEEDED = 0
#: candidates of the fused prefilter verified by the clique matcher beyond a query's own
#: ``candidates`` when none of those was accepted with a confidence of at least
#: :data:`.verify.ACCEPT_MIN_CONFIDENCE`: the hard queries (a revisit from another
#: heading, whose true place the prefilter ranks lower) get twice the verification, the
#: easy ones (most) none more
ESCALATE = 5
#: a place's triangle pose is verified on the raw scans (:func:`.verify.verify_seeded`)
#: only when at least this many of its triangles agree on it: the pose has no mapped
#: features for the validation to weigh, and the agreeing triangles stand in for them
#: (5, what a clique match had to map until session 9; kept when
#: :data:`.verify.ACCEPT_MIN_FEATURES` became 3, since a triangle vote is weaker evidence
#: than a mapped feature whose pose the validation checked)
SEED_MIN_VOTES = 5
#: hits are ranked by their confidence rounded to this many decimals, then by raw-scan
#: score: near certainty the logistic's last digits rank by evidence of no use then
CONFIDENCE_DIGITS = 4
_TRIANGLE_FIELDS = ("features.points_xy", "features.points_label")
_SURE = ACCEPT_MIN_CONFIDENCE


def _triangles_of(arrays: dict):
    return feature_triangles(
        arrays.get("features.points_xy", np.zeros((0, 2))),
        arrays.get("features.points_label", np.zeros(0, dtype=np.int8)),
    )


_FEATURE_FIELDS = (
    "points_xy",
    "points_label",
    "points_cov",
    "points_beam",
    "lines_rho_alpha",
    "lines_ends",
    "lines_cov",
    "lines_beams",
    "lines_n_points",
    "clusters",
)


#: two hits agree on where the query is when the map poses they give it lie within this
#: (m, rad) of each other; hits of other places with a confidence of at least
#: :data:`RIVAL_CONFIDENCE` (accepted or ambiguous) that contradict an accepted hit make it
#: ambiguous unless :data:`RIVAL_RATIO` says otherwise (:meth:`PlaceDB.query`)
AGREE_METRES = 1.0
AGREE_RADIANS = 0.2
RIVAL_CONFIDENCE = 0.9
#: an accepted hit stays accepted against hits that put the query elsewhere in the map
#: when those, with the hits agreeing with them, are at least this many times as likely
#: all wrong as it is with the hits agreeing with it (:meth:`PlaceDB.query`)
RIVAL_RATIO = 1000.0


def _map_pose(a: np.ndarray, path, pid: int) -> Pose2:
    """A stored :data:`MAP_POSE` array as a Pose2; a corrupted one is a
    :class:`~scanclique.errors.PlaceDatabaseError`."""
    a = np.asarray(a, dtype=float).ravel()
    if a.shape != (3,) or not np.all(np.isfinite(a)):
        raise PlaceDatabaseError(f"{os.fspath(path)}: place {pid}: corrupted map pose {a!r}")
    return Pose2(float(a[0]), float(a[1]), float(a[2]))


def feature_arrays(prepared: PreparedScan) -> dict[str, np.ndarray]:
    """The array fields of a prepared scan's features, keyed ``"features.<field>"``."""
    f = prepared.features
    return {f"features.{k}": np.asarray(getattr(f, k)) for k in _FEATURE_FIELDS}


@dataclass(frozen=True, slots=True, eq=False)
class PlaceHit:
    """One place a query scan may see, and what verification said.

    Attributes
    ----------
    place_id : int
    name : str or None
    pose : Pose2 or None
        Pose of the query scan's sensor frame in the place's frame (maps the query's
        points into the place's frame); None when the verdict is ``rejected``.
    score : float
        Raw-scan agreement of the match (at most 1; 0 without a pose).
    verdict : str
        ``"accepted"``, ``"ambiguous"`` or ``"rejected"`` (:mod:`.verify`).
    distance : float
        Signature distance of the prefilter (:func:`.signature.signature_distance`).
    rank : int
        Rank of the place in the fused prefilter (0: first).
    n_features : int
        Mapped features agreeing with the pose.
    covariance : ndarray (3, 3) or None
        Covariance of ``pose``.
    reason : str
        The validation's reason, in words.
    votes : int
        The place's score in the triangle prefilter (:mod:`.hashing`): triangles of the
        query agreeing on one pose with the place's.
    source : str
        What found the pose: ``"clique"`` (the clique matcher and validation,
        :func:`.verify.verify_pair`) or ``"triangles"`` (the triangle prefilter's pose
        refined on the raw scans, :func:`.verify.verify_seeded`, for a place the matcher
        rejected or that only the triangle ranking proposed).
    confidence : float
        Probability that ``pose`` is right (:func:`.verify.confidence`); 0 without a pose.
        Hits are ranked by it within a verdict; an accepted hit has at least the
        database's ``min_confidence``.
    surprise : float
        How unlikely the clique of mapped features is between unrelated places
        (:func:`.verify.clique_surprise`, decades; 0 without mapped features).
    rival_score : float
        Raw-scan score of the best distinct pose of the same place
        (:attr:`.verify.Verification.rival_score`).
    conflict : float
        The larger fraction of either scan's points in the other's observed free space
        at ``pose`` (:func:`.verify.conflict_fraction`; 0 without a pose).
    map_pose : Pose2 or None
        Pose of the query scan's sensor frame in the map: the place's map pose
        (:meth:`PlaceDB.add`'s ``pose``, :meth:`PlaceDB.map_pose`) composed with
        ``pose``; None when the place was added without one or the hit has no pose.
    """

    place_id: int
    name: str | None
    pose: Pose2 | None
    score: float
    verdict: str
    distance: float
    rank: int
    n_features: int
    covariance: np.ndarray | None
    reason: str
    votes: int = 0
    source: str = "clique"
    confidence: float = 0.0
    surprise: float = 0.0
    rival_score: float = 0.0
    conflict: float = 0.0
    map_pose: Pose2 | None = None

    def to_dict(self) -> dict:
        p, m = self.pose, self.map_pose
        return {
            "place_id": self.place_id,
            "name": self.name,
            "pose": None if p is None else {"x": p.x, "y": p.y, "theta": p.theta},
            "score": self.score,
            "verdict": self.verdict,
            "distance": self.distance,
            "rank": self.rank,
            "n_features": self.n_features,
            "reason": self.reason,
            "votes": self.votes,
            "source": self.source,
            "confidence": self.confidence,
            "surprise": self.surprise,
            "rival_score": self.rival_score,
            "conflict": self.conflict,
            "map_pose": None if m is None else {"x": m.x, "y": m.y, "theta": m.theta},
        }


def _get(d: dict, dotted: str):
    for part in dotted.split("."):
        d = d.get(part, {}) if isinstance(d, dict) else {}
    return d


def _flat(d, prefix=""):
    if not isinstance(d, dict):
        return {prefix: d}
    out = {}
    for k, v in d.items():
        out.update(_flat(v, f"{prefix}.{k}" if prefix else k))
    return out


def config_differences(stored: dict, given: dict, keys=PREPARE_KEYS) -> list[str]:
    """``"section.key: stored X, given Y"`` for each value under ``keys`` that differs."""
    out = []
    for key in keys:
        a, b = _flat(_get(stored, key), key), _flat(_get(given, key), key)
        for k in sorted(set(a) | set(b)):
            if a.get(k) != b.get(k):
                out.append(f"{k}: database {a.get(k)!r}, given {b.get(k)!r}")
    return out


def _whole(name: str, v, lo: int) -> int:
    """``v`` as an int of at least ``lo``; a :class:`ConfigError` naming the argument
    otherwise (:func:`scanclique.config.require_count`)."""
    require_count("PlaceDB: ", lo, **{name: v})
    return int(v)


def _real(name: str, v, lo: float, hi: float) -> float:
    """``v`` as a float in ``[lo, hi]``; a :class:`ConfigError` naming the argument
    otherwise (NaN and a string included)."""
    if isinstance(v, bool) or not isinstance(v, (int, float, np.integer, np.floating)):
        raise ConfigError(f"PlaceDB: {name} must be a number, got {v!r}")
    if not lo <= float(v) <= hi:  # NaN fails both
        raise ConfigError(f"PlaceDB: {name} must be in [{lo}, {hi}], got {v!r}")
    return float(v)


def _place_id(v) -> int:
    """A place id given by the caller, as an int; an :class:`ArgumentError` otherwise."""
    if isinstance(v, bool) or not isinstance(v, (int, np.integer)):
        raise ArgumentError(f"PlaceDB: a place id is an integer, got {v!r}")
    return int(v)


def _exclude_ids(exclude) -> np.ndarray | None:
    """The place ids of a query's ``exclude`` (any iterable of integers, e.g. a range) as
    an int64 array; None for None. A string, or an item that is not an integer, is an
    :class:`ArgumentError` (``"12"`` would otherwise exclude places 1 and 2)."""
    if exclude is None:
        return None
    if isinstance(exclude, (str, bytes)) or not isinstance(exclude, Iterable):
        raise ArgumentError(
            f"PlaceDB: exclude must be an iterable of place ids, got {type(exclude).__name__}"
        )
    if isinstance(exclude, range):
        return np.arange(exclude.start, exclude.stop, exclude.step, dtype=np.int64)
    return np.array([_place_id(i) for i in exclude], dtype=np.int64)


def _wal_files(path) -> tuple[Path, Path] | None:
    """The ``-wal`` and ``-shm`` files SQLite keeps beside the database ``path`` in WAL
    mode (beside the file a symbolic link points to, as :class:`.PlaceStore` opens it);
    None for a ``path`` that is not one."""
    if not isinstance(path, (str, os.PathLike)):
        return None
    where = os.fspath(Path(path).resolve())
    return Path(f"{where}-wal"), Path(f"{where}-shm")


def _release_wal(path) -> None:
    """Let SQLite remove the ``-wal`` and ``-shm`` files of the database ``path`` if no
    connection has it open any more: open it read-write (refusing writes), read, close.

    This is SQLite's own way (https://sqlite.org/wal.html: the last connection to close
    checkpoints the WAL, which writes into the database only what another process
    committed since, and deletes both files; the only safe way to remove a WAL file is
    to open the database and close it). While another connection has the database open
    nothing happens; a file without write permission stays as it is (SQLite then opens
    it read-only). Deleting the files directly could lose a writer's commits, so it is
    never done."""
    where = urllib.parse.quote(os.fspath(Path(path).resolve()), safe="/")  # as PlaceStore
    try:
        conn = sqlite3.connect(f"file:{where}?mode=rw", uri=True, isolation_level=None)
    except sqlite3.Error:
        return
    try:
        conn.execute("PRAGMA query_only = ON")
        conn.execute("SELECT count(*) FROM sqlite_master").fetchone()
    except sqlite3.Error:
        pass
    finally:
        conn.close()


class PlaceDB:
    """A persistent database of places (paper §2: topological localisation).

    Parameters
    ----------
    path : str or PathLike
        The SQLite file; created when absent.
    config : MatchConfig, optional
        The configuration to prepare and match scans with. A new database stores it; an
        existing one refuses a configuration whose :data:`PREPARE_KEYS` values differ
        from its own (its places were prepared with those; a value the stored one lacks,
        written before it existed, counts as its default). None: the stored one (the
        defaults for a new database). For a new database of a log's scans,
        ``features.for_scanner(None, scans, widen=False, reach_edges=False)`` is what
        ``scanclique places add`` takes: lost returns bridged for a scanner that loses
        them, no edges where a wall only leaves a short reach.
    readonly : bool
        Open an existing database for queries only. A reader of a WAL database needs
        SQLite's ``-wal`` and ``-shm`` files beside it and creates them when they are
        absent, and a read-only connection never removes them: when they were absent at
        the open, :meth:`close` has SQLite remove them (:func:`_release_wal`), so the
        directory is left as it was found, unless another connection still has the
        database open then (the files are in use; the last to close removes them, if it
        may write). Read-only queries never write the database; that release writes into
        it only what another process committed to the WAL meanwhile, as any last
        connection closing does.
    durable : bool
        Commit with ``synchronous=FULL`` (survive power loss, slower adds).
    min_score : float
        Accepted matches below this raw-scan score are rejected (:func:`.verify_pair`;
        default :data:`.verify.ACCEPT_MIN_SCORE`).
    min_features : int
        Accepted matches mapping fewer features are rejected (default
        :data:`.verify.ACCEPT_MIN_FEATURES`).
    cache : int
        Prepared places kept in memory (most recently used).
    search : bool
        Let the matcher search the pose on the raw scans when no clique of features
        explains them (``refine.search``) while verifying a candidate. Off by default: a
        place is recognised by the features it shares with the query (the prefilter ranks
        places by shared feature triangles), and on the shared logs the search changed no
        recognition while costing most of the verification time of the candidates that
        are not the place (``benchmarks/places.py``). It does not change the stored
        features, so a database may be queried either way.
    escalate : int
        Prefilter candidates verified by the clique matcher beyond a query's
        ``candidates`` when none of those was accepted with a confidence of at least
        :data:`.verify.ACCEPT_MIN_CONFIDENCE` (:data:`ESCALATE`; 0: none), whatever
        ``min_confidence`` is.
    seeded : int
        Places beyond the verified candidates checked by their triangle pose alone
        (:data:`SEEDED`; 0: none). That second path runs only when the matcher accepted
        no candidate; it checks the candidates it rejected too (any ``seeded``).
    aliases : bool
        Refuse an accepted clique match whose pose turned by a quarter or a half turn
        explains the raw scans nearly as well (:func:`.verify.alias_score`, the matcher's
        ambiguity rule): the hit is ``ambiguous``. Off by default: the wrong
        recognitions are mostly *other* look-alike places, which this test of the
        place's own aliases does not see (``benchmarks/places.py --aliases``).
    min_confidence : float
        An accepted hit whose confidence (:func:`.verify.confidence`) is below this is
        ``ambiguous`` (default :data:`.verify.ACCEPT_MIN_CONFIDENCE`; 0: the validation
        and ``min_score`` / ``min_features`` alone decide).

    Raises
    ------
    PlaceDatabaseError
        The file is not a place database, is newer, corrupted, or was built with an
        incompatible configuration or a newer signature. Signatures of an older
        version (:data:`.signature.SIGNATURE_VERSION`) are recomputed from the stored
        scans when the database is opened for writing, and refused read-only.
    ConfigError
        A count that is not an integer >= 0 (``cache``, ``seeded``, ``escalate``,
        ``min_features``), a ``min_score`` that is not a number, a ``min_confidence``
        outside ``[0, 1]``, or a ``config`` that is not a MatchConfig; checked before
        the file is opened or created.
    """

    def __init__(
        self,
        path: str | os.PathLike,
        config: MatchConfig | None = None,
        *,
        readonly: bool = False,
        durable: bool = False,
        min_score: float = ACCEPT_MIN_SCORE,
        min_features: int = ACCEPT_MIN_FEATURES,
        cache: int = 4096,
        search: bool = False,
        seeded: int = SEEDED,
        aliases: bool = False,
        min_confidence: float = ACCEPT_MIN_CONFIDENCE,
        escalate: int = ESCALATE,
    ) -> None:
        # the arguments first: a refused one creates no file
        cache = _whole("cache", cache, 0)
        seeded = _whole("seeded", seeded, 0)
        escalate = _whole("escalate", escalate, 0)
        min_features = _whole("min_features", min_features, 0)
        min_score = _real("min_score", min_score, -math.inf, math.inf)
        min_confidence = _real("min_confidence", min_confidence, 0.0, 1.0)
        require_config("PlaceDB: ", config, MatchConfig)
        given = None if config is None else config_to_dict(config)
        meta = {
            "config": json.dumps(given if given is not None else config_to_dict(MatchConfig())),
            "signature_version": str(SIGNATURE_VERSION),
            "signature_size": str(SIGNATURE_SIZE),
            "scanclique_version": __version__,
        }
        # a reader creates the WAL's two files when they are absent: close() removes them
        wal = _wal_files(path)
        self._release = bool(readonly and wal and not (wal[0].exists() or wal[1].exists()))
        try:
            self.store = PlaceStore(path, meta, readonly=readonly, durable=durable)
        except BaseException:
            if self._release:
                _release_wal(path)
            raise
        self.path = self.store.path
        try:
            self.config = self._check_meta(given, config)
            self._upgrade_signatures()
        except BaseException:
            self.close()
            raise
        self.search = bool(search)
        self.seeded = int(seeded)
        self.escalate = escalate
        self.aliases = bool(aliases)
        self.verify_config = dataclasses.replace(
            self.config, refine=dataclasses.replace(self.config.refine, search=self.search)
        )
        self.min_score = float(min_score)
        self.min_features = int(min_features)
        self.min_confidence = float(min_confidence)
        self.index = SignatureIndex(SIGNATURE_SIZE)
        self.triangles = TriangleIndex()
        self._last = 0
        # places' poses in a map (None: added without), read when first asked for
        self._map_poses: dict[int, Pose2 | None] = {}
        self._cache: OrderedDict[int, PreparedScan] = OrderedDict()
        self._cache_size = int(cache)
        self._names: dict[int, str | None] = {}
        self.refresh()

    def _check_meta(self, given: dict | None, config: MatchConfig | None) -> MatchConfig:
        where = os.fspath(self.path)
        m = self.store.meta
        try:
            stored = json.loads(m.get("config", ""))
            stored_cfg = config_from_dict(stored)
        except (ValueError, ConfigError) as exc:
            raise PlaceDatabaseError(
                f"{where}: meta.config is not a valid configuration ({exc})"
            ) from None
        if given is None:
            return stored_cfg
        # a value the stored configuration lacks (written before it existed) is its default
        diff = config_differences(config_to_dict(stored_cfg), given)
        if diff:
            raise PlaceDatabaseError(
                f"{where}: the configuration differs from the one its places were prepared "
                f"with: {'; '.join(diff)}"
            )
        return config

    def _upgrade_signatures(self) -> None:
        """Recompute the stored signatures when they are of an older version than
        :data:`.signature.SIGNATURE_VERSION` (from each place's stored scan, prepared
        with the stored configuration; one transaction, :meth:`.PlaceStore.rewrite_signatures`).

        Raises
        ------
        PlaceDatabaseError
            The signatures are of a newer (or unknown) version, or of an older one and
            the database is open read-only.
        """
        m = self.store.meta
        sv, size = m.get("signature_version"), m.get("signature_size")
        if sv == str(SIGNATURE_VERSION) and size == str(SIGNATURE_SIZE):
            return
        where = os.fspath(self.path)
        found = (
            f"{where}: signatures of version {sv} ({size} values); this scanclique computes "
            f"version {SIGNATURE_VERSION} ({SIGNATURE_SIZE})"
        )
        if not (sv or "").isdigit() or int(sv) >= SIGNATURE_VERSION:
            raise PlaceDatabaseError(f"{found}: upgrade scanclique, or rebuild the database")
        if self.store.readonly:
            raise PlaceDatabaseError(
                f"{found}: open it once for writing to recompute them (read-only here)"
            )
        n = self.store.rewrite_signatures(
            lambda scan: scan_signature(self.prepare(scan)),
            {"signature_version": str(SIGNATURE_VERSION), "signature_size": str(SIGNATURE_SIZE)},
        )
        log.info("%s: signatures of version %s recomputed for %d places", where, sv, n)

    # -- writing -----------------------------------------------------------------------
    def prepare(self, scan: Scan) -> PreparedScan:
        """The scan prepared with the database's configuration."""
        return prepare_scan(scan, self.config)

    def _prepared(self, where: str, scan: Scan | PreparedScan) -> PreparedScan:
        """``scan`` prepared with the database's configuration; a :class:`PreparedScan`
        as it is, when it was prepared with a configuration that prepares scans alike.

        Raises a :class:`ScanError` for anything else, and a :class:`ConfigError` for a
        scan prepared otherwise (its features and signature would not be comparable with
        the stored places'), each naming the method ``where`` the user called."""
        if isinstance(scan, PreparedScan):
            differ = (
                ()
                if scan.config is self.config
                else scan.config.preparation_differences(self.config)
            )
            if differ:
                raise ConfigError(
                    f"PlaceDB.{where}: the scan was prepared with another configuration than "
                    f"the database's ({', '.join(differ)} differ); give the Scan, or prepare "
                    "it with PlaceDB.prepare"
                )
            return scan
        if not isinstance(scan, Scan):
            raise ScanError(
                f"PlaceDB.{where}: scan must be a Scan or a PreparedScan (from "
                f"PlaceDB.prepare), got {type(scan).__name__}"
            )
        return self.prepare(scan)

    def add(self, scan: Scan, name: str | None = None, *, pose: Pose2 | None = None) -> int:
        """Store ``scan`` as a new place, with its features and signature, in one
        transaction; returns the place id.

        ``pose``, optional: where the place is in a map (the pose of the scan's sensor
        frame, e.g. from :func:`~scanclique.mapping.map_scans`), stored with it. A query's
        hits of such places give the query's pose in that map (:attr:`PlaceHit.map_pose`),
        and a hit that others put more than :data:`AGREE_METRES` / :data:`AGREE_RADIANS`
        elsewhere about as believably is not accepted (:meth:`query`,
        :data:`RIVAL_RATIO`): a building of places that look alike (corners a quarter
        turn round, doors along a corridor) otherwise gets a look-alike accepted with high
        confidence.

        Raises
        ------
        PlaceDatabaseError
            ``name`` is already used (names are unique; None is allowed any number of
            times).
        ArgumentError
            ``name`` is neither a str nor None (SQLite would keep a number as a number, and
            the place's name would come back as one), or ``pose`` is neither a
            :class:`~scanclique.geometry.Pose2` nor None.
        """
        if not isinstance(scan, Scan):
            raise ScanError(f"PlaceDB.add: scan must be a Scan, got {type(scan).__name__}")
        if name is not None and not isinstance(name, str):
            raise ArgumentError(f"PlaceDB.add: name must be a str or None, got {name!r}")
        if pose is not None and not isinstance(pose, Pose2):  # a Pose2 is finite
            raise ArgumentError(f"PlaceDB.add: pose must be a Pose2 or None, got {pose!r}")
        p = self.prepare(scan)
        sig = scan_signature(p)
        arrays = feature_arrays(p)
        if pose is not None:
            arrays[MAP_POSE] = pose.as_array().astype(float)
        pid = self.store.add(scan, arrays, sig, name=name, n_features=len(p.features))
        if pid == self._last + 1:  # nobody else added since: index it without reading back
            self.index.add([pid], sig[None, :])
            self.triangles.add([pid], [_triangles_of(arrays)])
            self._map_poses[pid] = pose
            self._last = pid
        else:
            self.refresh()
        self._remember(pid, p)
        return pid

    # -- reading -----------------------------------------------------------------------
    def refresh(self) -> int:
        """Load the signatures, and compute the triangles, of places added since the last
        call (by any process); returns how many."""
        ids, sigs = self.store.signatures_after(self._last)
        if len(ids):
            # no further than the signatures read: another process may be adding
            tids, arrays = self.store.arrays_after(self._last, _TRIANGLE_FIELDS, upto=int(ids[-1]))
            self.triangles.add(tids, [_triangles_of(a) for a in arrays])
            self.index.add(ids, sigs)
            self._last = int(ids[-1])
        return len(ids)

    def __len__(self) -> int:
        return len(self.index)

    def map_pose(self, place_id: int) -> Pose2 | None:
        """Where place ``place_id`` is in a map, when :meth:`add` was given it (else None).

        Raises
        ------
        PlaceDatabaseError
            No such place.
        """
        pid = _place_id(place_id)
        pose = self._map_poses_of([pid])[pid]
        if pose is None and not self.store.names([pid]):
            self._map_poses.pop(pid, None)
            raise PlaceDatabaseError(f"{os.fspath(self.path)}: no place with id {pid}")
        return pose

    def set_map_pose(self, place_id: int, pose: Pose2) -> None:
        """Give the stored place ``place_id`` its pose in a map (as :meth:`add`'s
        ``pose``), replacing any it had, in one transaction. Another process that already
        read this place's map pose sees the new one once it reopens the database.

        Raises
        ------
        PlaceDatabaseError
            No such place.
        ArgumentError
            ``pose`` is not a :class:`~scanclique.geometry.Pose2`.
        """
        if not isinstance(pose, Pose2):
            raise ArgumentError(f"PlaceDB.set_map_pose: pose must be a Pose2, got {pose!r}")
        pid = _place_id(place_id)
        self.store.set_array(pid, MAP_POSE, pose.as_array().astype(float))
        self._map_poses[pid] = pose

    def map_poses(self) -> dict[int, Pose2]:
        """Place id -> map pose of every place that has one (:meth:`map_pose`), in id
        order; read from the store once per place."""
        self.refresh()
        got = self._map_poses_of([int(i) for i in self.ids])
        return {i: p for i, p in got.items() if p is not None}

    def _map_poses_of(self, ids: list[int]) -> dict[int, Pose2 | None]:
        """:meth:`map_pose` of each of ``ids``, read from the store once per place."""
        new = [i for i in ids if i not in self._map_poses]
        if new:
            got = self.store.array_of(new, MAP_POSE)
            for i in new:
                self._map_poses[i] = _map_pose(got[i], self.path, i) if i in got else None
        return {i: self._map_poses[i] for i in ids}

    @property
    def ids(self) -> np.ndarray:
        return self.index.ids

    def get(self, place_id: int) -> PlaceRecord:
        """The stored place (scan, features' arrays)."""
        return self.store.get(_place_id(place_id))

    def _remember(self, pid: int, p: PreparedScan) -> None:
        self._cache[pid] = p
        self._cache.move_to_end(pid)
        while len(self._cache) > self._cache_size:
            self._cache.popitem(last=False)

    def prepared(self, place_id: int) -> PreparedScan:
        """The stored place's scan, prepared (cached)."""
        pid = _place_id(place_id)
        p = self._cache.get(pid)
        if p is None:
            p = self.prepare(self.store.get(pid, arrays=False).scan)
        self._remember(pid, p)
        return p

    def candidates(
        self, scan: Scan | PreparedScan, n: int = 10, exclude: Iterable[int] | None = None
    ) -> tuple[np.ndarray, np.ndarray]:
        """The prefilter alone: ids of the ``n`` places of nearest signature and their
        distances, nearest first (places in ``exclude`` left out)."""
        n = _whole("n", n, 0)
        exclude = _exclude_ids(exclude)
        self.refresh()
        p = self._prepared("candidates", scan)
        ids, dist, _, _ = self._candidates(p, n, exclude)
        return ids, dist

    def _candidates(self, p: PreparedScan, n: int, exclude, extra: int = 0):
        """The fused prefilter: ``(ids, signature distances, triangle votes, triangle
        poses)``, poses ``(x, y, theta)`` rows of ``T_place_query`` (NaN for a place with
        fewer than :data:`SEED_MIN_VOTES` votes).

        The two rankings, by triangle votes (:mod:`.hashing`, places with at least
        :data:`MIN_VOTES`) and by signature distance (:mod:`.signature`), taken in turn
        (the triangles' first, then the signature's first, ...), each place once, until
        ``n`` places; then up to ``extra`` more places down the triangle ranking that have
        at least :data:`SEED_MIN_VOTES` votes. The two
        fail on different revisits: the triangles need common point features, the
        signature a similar view of the whole scan."""
        n = int(n)
        extra = max(0, int(extra))
        ex = None
        if exclude is not None:
            ex = np.fromiter((int(i) for i in exclude), dtype=np.int64)
        allowed = ~self.index.contains(ex) if ex is not None and len(ex) else None
        sig = scan_signature(p)
        s_ids, _ = self.index.search(sig, n, allowed)
        tri = feature_triangles(p.features.points_xy, p.features.points_label)
        # poses only where they are used: places with SEED_MIN_VOTES (pz below)
        votes, poses = self.triangles.votes(tri, ex, min_pose=SEED_MIN_VOTES)
        t_ids_all = self.triangles.ids
        rows = np.flatnonzero(votes >= MIN_VOTES)
        m = n + extra
        if len(rows) > m > 0:  # the m best, and every place tied with the m-th
            kth = np.partition(-votes[rows], m - 1)[m - 1]
            rows = rows[-votes[rows] <= kth]
        t_ids = t_ids_all[rows]
        # ties of votes (neighbouring places see the same triangles) go to the nearer
        # signature, then to the smaller id
        order = np.lexsort((t_ids, self._signature_distances(sig, t_ids), -votes[rows]))[:m]
        t_ids, t_votes = t_ids[order], votes[rows[order]]
        out: list[int] = []
        seen: set[int] = set()
        for a, b in zip_longest(t_ids[:n].tolist(), s_ids.tolist()):
            for c in (a, b):
                if c is not None and c not in seen and len(out) < n:
                    seen.add(c)
                    out.append(c)
        for c, nv in zip(t_ids.tolist(), t_votes.tolist(), strict=True):
            if len(out) >= n + extra or nv < SEED_MIN_VOTES:
                break
            if c not in seen:
                seen.add(c)
                out.append(c)
        ids = np.array(out, dtype=np.int64)
        dist = self._signature_distances(sig, ids)
        trows = np.searchsorted(t_ids_all, ids)
        v = np.zeros(len(ids), dtype=np.int64)
        pz = np.full((len(ids), 3), np.nan)
        okr = trows < len(t_ids_all)
        okr[okr] = t_ids_all[trows[okr]] == ids[okr]
        v[okr] = votes[trows[okr]]
        pz[okr] = poses[trows[okr]]
        pz[v < SEED_MIN_VOTES] = np.nan
        return ids, dist, v, pz

    def _signature_distances(self, sig: np.ndarray, ids: np.ndarray) -> np.ndarray:
        """Signature distances from ``sig`` to the places ``ids`` (all in the index)."""
        X = self.index.signatures
        rows = np.searchsorted(self.index.ids, ids)
        return np.sum((X[rows].astype(np.float64) - sig) ** 2, axis=1)

    def query(
        self,
        scan: Scan | PreparedScan,
        k: int = 5,
        *,
        candidates: int | None = None,
        exclude: Iterable[int] | None = None,
    ) -> list[PlaceHit]:
        """The places ``scan`` may see, verified, best first.

        Parameters
        ----------
        scan : Scan or PreparedScan
            The query (prepared with the database's configuration when a Scan).
        k : int
            Return at most this many hits.
        candidates : int, optional
            Verify this many prefilter candidates (default ``k``); the best ``k`` of them
            are returned.
        exclude : iterable of int, optional
            Place ids not to consider (e.g. the scans just before the query in a log).

        Returns
        -------
        list of PlaceHit
            Accepted first, then ambiguous, then rejected; by confidence within each
            (to :data:`CONFIDENCE_DIGITS` decimals, then raw-scan score). ``hit.pose``
            maps the query's points into the place's frame.

        Raises
        ------
        ConfigError
            ``k`` or ``candidates`` is not an integer >= 0, or ``scan`` is a
            :class:`PreparedScan` prepared with a configuration that prepares scans
            otherwise than the database's.
        ScanError
            ``scan`` is neither a :class:`Scan` nor a :class:`PreparedScan`.
        ArgumentError
            ``exclude`` is not an iterable of integers (a string, say).
        """
        k = _whole("k", k, 0)
        candidates = 0 if candidates is None else _whole("candidates", candidates, 0)
        exclude = _exclude_ids(exclude)
        self.refresh()
        p = self._prepared("query", scan)
        n = max(k, candidates)
        ids, dist, votes, poses = self._candidates(p, n + self.escalate, exclude, self.seeded)
        missing = [int(i) for i in ids if int(i) not in self._names]
        if missing:
            self._names.update(self.store.names(missing))
        rows = list(enumerate(zip(ids.tolist(), dist.tolist(), votes.tolist(), strict=True)))
        found: list[tuple[Verification, str] | None] = [None] * len(rows)
        for rank, (pid, _, _) in rows[:n]:
            found[rank] = (self._verify_clique(pid, p), "clique")
        if not any(
            f is not None and f[0].verdict == ACCEPTED and f[0].confidence >= _SURE for f in found
        ):  # a hard query: the next candidates of the fused ranking too
            for rank, (pid, _, _) in rows[n : n + self.escalate]:
                found[rank] = (self._verify_clique(pid, p), "clique")
        if not any(f is not None and f[0].verdict == ACCEPTED for f in found):
            # the second path, for the revisits the clique matcher misses: the rejected
            # candidates and the places only the triangles propose, from their pose
            for rank, (pid, _, _) in rows:
                if (found[rank] is None or found[rank][0].verdict == REJECTED) and np.all(
                    np.isfinite(poses[rank])
                ):
                    w = verify_seeded(
                        self.prepared(pid),
                        p,
                        Pose2.from_array(poses[rank]),
                        self.config,
                        min_score=self.min_score,
                        min_confidence=0.0,
                    )
                    if found[rank] is None or w.verdict != REJECTED:
                        found[rank] = (w, "triangles")
        hits = []
        for rank, (pid, d, nv) in rows:
            if found[rank] is None:
                continue
            v, source = found[rank]
            # below the confidence only now: the second path above runs when the
            # validation accepted no candidate, whatever their confidence
            v = below_confidence(v, self.min_confidence)
            hits.append(
                PlaceHit(
                    pid,
                    self._names.get(pid),
                    v.pose,
                    v.score,
                    v.verdict,
                    float(d),
                    rank,
                    v.n_features,
                    v.covariance,
                    v.reason,
                    int(nv),
                    source,
                    v.confidence,
                    v.surprise,
                    v.rival_score,
                    v.conflict,
                )
            )
        hits = self._disagreeing(hits)
        # confidences within 1e-4 of each other are a tie (two neighbouring places both
        # all but certain), broken by the raw-scan score
        hits.sort(
            key=lambda h: (
                VERDICT_RANK[h.verdict],
                -round(h.confidence, CONFIDENCE_DIGITS),
                -h.score,
                h.rank,
            )
        )
        return hits[: int(k)]

    def _disagreeing(self, hits: list[PlaceHit]) -> list[PlaceHit]:
        """``hits`` with their :attr:`PlaceHit.map_pose` (the query's pose in the map, for
        the hits of places with a map pose), each accepted one made ambiguous when hits
        of other places put the query elsewhere in the map about as believably.

        The *rivals* are the hits with a map pose and a confidence of at least
        :data:`RIVAL_CONFIDENCE` (accepted or ambiguous). Two hits agree when the map
        poses they give the query lie within :data:`AGREE_METRES` and
        :data:`AGREE_RADIANS`. An accepted hit's *support* is the rivals agreeing with it
        (itself among them), a disagreeing rival's the rivals agreeing with that one; a
        support is as likely wrong as the product of its hits' ``1 - confidence`` (as if
        independent). The accepted hit stays accepted only if every disagreeing rival's
        support is at least :data:`RIVAL_RATIO` times as likely wrong as its own. Hits of
        places without a map pose are left as they are.

        The ring corridor of :func:`scanclique.sim.simulate_ring_drive` (every corner
        alike; the first lap's every 4th scan added with its true pose, the second lap's
        every 10th queried, seeds 0-3): the first accepted hit right for 177 queries and
        wrong for 21 without poses (each at confidence >= 0.99); with them 129 and 1
        (with any disagreeing rival enough, as in session 32: 116 and 1). The shared logs
        (``benchmarks/places.py --map``) lose no right answer (with any rival enough,
        one on intel and three on freiburg)."""
        posed = [h.place_id for h in hits if h.pose is not None]
        maps = self._map_poses_of(posed) if posed else {}
        if not any(m is not None for m in maps.values()):
            return hits
        hits = [
            h if maps.get(h.place_id) is None or h.pose is None
            else dataclasses.replace(h, map_pose=maps[h.place_id] @ h.pose)
            for h in hits
        ]  # fmt: skip
        rivals = [
            h for h in hits
            if h.map_pose is not None and h.verdict != REJECTED
            and h.confidence >= RIVAL_CONFIDENCE
        ]  # fmt: skip

        def apart(a: PlaceHit, b: PlaceHit) -> tuple[float, float] | None:
            dt, dr = a.map_pose.distance_to(b.map_pose)
            return (dt, dr) if dt > AGREE_METRES or dr > AGREE_RADIANS else None

        def wrong(h: PlaceHit) -> float:  # the chance that h and all agreeing rivals are wrong
            support = [h] + [o for o in rivals if o is not h and apart(h, o) is None]
            return math.prod(1.0 - o.confidence for o in support)

        out = []
        for h in hits:
            against = [o for o in rivals if o is not h and h.verdict == ACCEPTED
                       and h.map_pose is not None and apart(h, o) is not None]  # fmt: skip
            if against:
                mine = wrong(h)
                o = min(against, key=wrong)
                if wrong(o) <= RIVAL_RATIO * mine:
                    dt, dr = apart(h, o)
                    why = (
                        f"place {o.place_id} ({o.verdict}, confidence {o.confidence:.3f}) puts "
                        f"the query {dt:.2f} m / {math.degrees(dr):.1f} deg away in the map"
                    )
                    h = dataclasses.replace(
                        h, verdict=AMBIGUOUS, reason="; ".join(filter(None, (h.reason, why)))
                    )
            out.append(h)
        return out

    def verify(self, place_id: int, scan: Scan | PreparedScan) -> Verification:
        """The verdict on one stored place for ``scan``, as :meth:`query` gives it to a
        candidate of the prefilter: the clique matcher and the validation
        (:func:`.verify.verify_pair` with the database's ``min_score``, ``min_features``,
        ``search`` and ``aliases``), an accepted match below ``min_confidence``
        ``ambiguous``; without the prefilter and without the second path from the
        triangles' pose. ``pose`` maps the query's points into the place's frame.

        For checking a known hypothesis ("is this the place I think it is?"), and for
        measuring what the verification can recognise when the prefilter is bypassed
        (``benchmarks/places.py --ceiling``).

        Raises
        ------
        PlaceDatabaseError
            No place has that id.
        ScanError, ConfigError
            As for :meth:`query`.
        """
        p = self._prepared("verify", scan)
        return below_confidence(self._verify_clique(_place_id(place_id), p), self.min_confidence)

    def _verify_clique(self, pid: int, p: PreparedScan) -> Verification:
        """The clique matcher's verdict on one candidate, its accepted pose checked
        against its aliases when ``aliases``."""
        place = self.prepared(pid)
        v = verify_pair(
            place,
            p,
            self.verify_config,
            min_score=self.min_score,
            min_features=self.min_features,
            min_confidence=0.0,
        )
        if v.verdict == ACCEPTED and self.aliases:
            alias, _ = alias_score(place, p, v.pose, self.config)
            if alias >= self.config.refine.ambiguous_score * v.score:
                v = dataclasses.replace(
                    v,
                    verdict=AMBIGUOUS,
                    reason=f"the pose turned by a quarter or half turn scores {alias:.3f} "
                    f"(of {v.score:.3f}); {v.reason}",
                )
        return v

    def best(self, scan: Scan | PreparedScan, **kw) -> PlaceHit | None:
        """The best hit if it is not rejected, else None (``kw`` as for :meth:`query`)."""
        hits = self.query(scan, **kw)
        return hits[0] if hits and hits[0].verdict != REJECTED else None

    def info(self, check: bool = False) -> dict:
        """Counts, sizes, versions and the stored configuration; ``check`` also runs
        SQLite's integrity check (reads the whole file)."""
        out = {"path": os.fspath(self.path), **self.store.stats()}
        m = self.store.meta
        out.update(
            {
                "schema_version": int(m.get("schema_version", 0)),
                "signature_version": int(m.get("signature_version", 0)),
                "signature_size": int(m.get("signature_size", 0)),
                "scanclique_version": m.get("scanclique_version"),
                "created": float(m["created"]) if "created" in m else None,
                "config": json.loads(m.get("config", "{}")),
            }
        )
        if check:
            out["integrity"] = self.store.integrity_check() or ["ok"]
        return out

    def close(self) -> None:
        """Close the file; a read-only database also has SQLite remove the ``-wal`` and
        ``-shm`` files its open created (see ``readonly``)."""
        self.store.close()
        if self._release:
            self._release = False
            _release_wal(self.path)

    def __enter__(self) -> PlaceDB:
        return self

    def __exit__(self, *exc) -> None:
        self.close()
