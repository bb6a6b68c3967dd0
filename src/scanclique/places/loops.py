"""Every revisit of a log: the all-pairs loop search, serially, over local processes or
over a Dask cluster, with identical results.

The search, for a log of ``N`` scans (paper §2: place recognition used for loop closing):

1. the signature of every scan (:func:`.signature.scan_signature`);
2. the prefilter: for each scan ``i``, ``candidates`` earlier scans ``j <= i -
   min_gap``, the two rankings of :class:`.database.PlaceDB` taken in turn: the most
   triangle votes on one pose (:mod:`.hashing`, at least :data:`.database.MIN_VOTES`;
   ties to the nearer signature, then the smaller ``j``) and the nearest signatures
   (exact brute force in blocks of rows; ties go to the smaller ``j``);
3. every candidate pair verified (:func:`.verify.verify_pair`): the clique matcher on
   scan ``j`` (the place) and scan ``i`` (the query), then validation without odometry.

Steps 1 and 3 are embarrassingly parallel. They run in this process (``workers=1``),
over ``workers`` local processes (:mod:`concurrent.futures`), or, given a scheduler
address, over an existing Dask cluster (:mod:`dask.distributed`; the scans are
scattered to every worker once). Step 2 runs here. Work is cut into chunks of scans
and of pairs, each worker keeps the scans it prepared, and the results are put back in
pair order, so every backend returns exactly the serial result.

Examples
--------
>>> import numpy as np, scanclique as sc
>>> rng = np.random.default_rng(5)
>>> world = sc.sim.office_world(rng)
>>> scans = sc.sim.simulate_trajectory(rng, world, 8, step=0.2)
>>> res = find_loops(scans, candidates=2, min_gap=3)
>>> len(res.loops), res.backend
(9, 'serial')
"""

from __future__ import annotations

import logging
import math
import os
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np

from .. import __version__
from .._workers import RunState, check_workers, local_pool, new_token
from ..config import (
    MatchConfig,
    config_from_dict,
    config_to_dict,
    require_callable,
    require_config,
    require_count,
)
from ..errors import ArgumentError, ScanCliqueError
from ..features import for_scanner
from ..geometry import Pose2
from ..match import prepare_scan
from ..scan import Scan
from .hashing import TriangleIndex, Triangles, feature_triangles
from .signature import SIGNATURE_SIZE, scan_signature
from .verify import (
    ACCEPT_MIN_CONFIDENCE,
    ACCEPT_MIN_FEATURES,
    ACCEPT_MIN_SCORE,
    ACCEPTED,
    verify_pair,
)

__all__ = ["Loop", "LoopSearch", "find_loops", "fused_loop_candidates", "loop_candidates"]

log = logging.getLogger(__name__)


@dataclass(frozen=True, slots=True, eq=False)
class Loop:
    """One verified candidate pair of the loop search.

    ``i`` is the later scan (the query), ``j`` the earlier one (the place); ``pose`` the
    pose of scan ``i``'s sensor frame in scan ``j``'s (maps ``i``'s points into ``j``'s
    frame), None when rejected; ``rank`` and ``distance`` from the prefilter."""

    i: int
    j: int
    rank: int
    distance: float
    verdict: str
    pose: Pose2 | None
    score: float
    n_features: int

    def key(self) -> tuple:
        """Everything, as plain numbers (for comparing runs exactly)."""
        p = None if self.pose is None else (self.pose.x, self.pose.y, self.pose.theta)
        return (
            self.i,
            self.j,
            self.rank,
            self.distance,
            self.verdict,
            p,
            self.score,
            self.n_features,
        )

    def to_dict(self) -> dict:
        p = self.pose
        return {
            "i": self.i,
            "j": self.j,
            "rank": self.rank,
            "distance": self.distance,
            "verdict": self.verdict,
            "pose": None if p is None else {"x": p.x, "y": p.y, "theta": p.theta},
            "score": self.score,
            "n_features": self.n_features,
        }


@dataclass(frozen=True, slots=True, eq=False)
class LoopSearch:
    """The result of :func:`find_loops`: every verified pair, sorted by ``(i, j)``.

    ``seconds`` has the wall time of ``signatures``, ``prefilter``, ``verify`` and
    ``total``; ``backend`` is ``"serial"``, ``"processes"`` or ``"dask"``; ``config`` the
    matcher's configuration the scans were prepared and verified with."""

    loops: tuple
    n_scans: int
    candidates: int
    min_gap: int
    backend: str
    workers: int
    seconds: dict
    config: MatchConfig = field(default_factory=MatchConfig)

    @property
    def accepted(self) -> tuple:
        return tuple(lp for lp in self.loops if lp.verdict == ACCEPTED)

    def keys(self) -> list[tuple]:
        return [lp.key() for lp in self.loops]

    def to_dict(self) -> dict:
        return {
            "n_scans": self.n_scans,
            "candidates": self.candidates,
            "min_gap": self.min_gap,
            "backend": self.backend,
            "workers": self.workers,
            "n_pairs": len(self.loops),
            "n_accepted": len(self.accepted),
            "seconds": dict(self.seconds),
            "config": config_to_dict(self.config),
            "loops": [lp.to_dict() for lp in self.loops],
        }


# ---------------------------------------------------------------------------------------
# Worker side: the scans of the run and the scans prepared so far, per process
# ---------------------------------------------------------------------------------------
_STATE = RunState("places.loops")


def _install(token: str, scans, config_dict: dict, limits: tuple) -> dict:
    return _STATE.install(
        token,
        lambda: {
            "scans": list(scans),
            "config": config_from_dict(config_dict),
            "limits": (float(limits[0]), int(limits[1]), float(limits[2])),
            "prepared": {},
        },
    )


def _state(token, scans, config_dict, limits) -> dict:
    """The run's state; a Dask task carries the run's inputs and installs them itself."""
    if scans is not None:
        return _install(token, scans, config_dict, limits)
    return _STATE.require(token)


def _prepared(state: dict, i: int):
    cache = state["prepared"]
    p = cache.get(i)
    if p is None:
        p = cache[i] = prepare_scan(state["scans"][i], state["config"])
    return p


def _signature_task(token, indices, scans=None, config_dict=None, limits=(0.0, 0, 0.0)):
    """Signatures of the scans ``indices`` (``(n, SIGNATURE_SIZE)``) and their feature
    triangles (:func:`.hashing.feature_triangles`, as tuples of arrays)."""
    state = _state(token, scans, config_dict, limits)
    sigs, tris = [], []
    for i in indices:
        p = _prepared(state, int(i))
        sigs.append(scan_signature(p))
        t = feature_triangles(p.features.points_xy, p.features.points_label)
        tris.append((t.keys, t.sides, t.kinds, t.frames))
    return np.array(sigs).reshape(-1, SIGNATURE_SIZE), tris


def _verify_task(token, pairs, scans=None, config_dict=None, limits=(0.0, 0, 0.0)):
    """Verification of the pairs ``(i, j)``: tuples ``(verdict, x, y, theta, score,
    n_features)`` (pose None when rejected)."""
    state = _state(token, scans, config_dict, limits)
    out = []
    cfg, (ms, mf, mc) = state["config"], state["limits"]
    for i, j in pairs:
        v = verify_pair(
            _prepared(state, int(j)),
            _prepared(state, int(i)),
            cfg,
            min_score=ms,
            min_features=mf,
            min_confidence=mc,
        )
        p = None if v.pose is None else (v.pose.x, v.pose.y, v.pose.theta)
        out.append((v.verdict, p, v.score, v.n_features))
    return out


# ---------------------------------------------------------------------------------------
# The prefilter (here)
# ---------------------------------------------------------------------------------------
def loop_candidates(
    signatures: np.ndarray, candidates: int, min_gap: int, block: int = 512
) -> list[tuple[int, int, int, float]]:
    """For each scan ``i``, the ``candidates`` scans ``j <= i - min_gap`` whose
    signatures are nearest (squared Euclidean in float64): ``(i, j, rank, distance)``
    sorted by ``(i, rank)``; ties go to the smaller ``j``."""
    S = np.asarray(signatures, dtype=np.float64)
    n = len(S)
    sq = np.einsum("ij,ij->i", S, S)
    out = []
    for b0 in range(0, n, block):
        rows = np.arange(b0, min(n, b0 + block))
        D = sq[rows, None] + sq[None, :] - 2.0 * (S[rows] @ S.T)
        np.maximum(D, 0.0, out=D)
        for r, i in enumerate(rows.tolist()):
            last = i - min_gap  # j in [0, last]
            if last < 0:
                continue
            d = D[r, : last + 1]
            k = min(candidates, last + 1)
            if k < len(d):
                kth = np.partition(d, k - 1)[k - 1]
                js = np.flatnonzero(d <= kth)
            else:
                js = np.arange(len(d))
            order = np.lexsort((js, d[js]))[:k]
            for rank, jj in enumerate(js[order].tolist()):
                out.append((i, int(jj), rank, float(d[jj])))
    return out


def fused_loop_candidates(
    signatures: np.ndarray, triangles: Sequence[Triangles], candidates: int, min_gap: int
) -> list[tuple[int, int, int, float]]:
    """:func:`loop_candidates` fused with the triangle ranking, as a place query fuses
    them (:meth:`.database.PlaceDB.query`): for each scan ``i``, the scans ``j <= i -
    min_gap`` of most triangle votes on one pose (at least
    :data:`.database.MIN_VOTES`; ties to the nearer signature, then the smaller ``j``)
    and of nearest signature, taken in turn, each once, until ``candidates``:
    ``(i, j, rank, signature distance)`` sorted by ``(i, rank)``."""
    from .database import MIN_VOTES

    S = np.asarray(signatures, dtype=np.float64)
    n = len(S)
    by_sig: dict[int, list[int]] = {}
    for i, j, _, _ in loop_candidates(S, candidates, min_gap):
        by_sig.setdefault(i, []).append(j)
    index = TriangleIndex()
    out = []
    for i in range(n):
        last = i - min_gap
        if last < 0:
            continue
        # the index holds exactly the scans 0 .. last
        while len(index) <= last:
            index.add([len(index)], [triangles[len(index)]])
        votes = index.scores(triangles[i])
        rows = np.flatnonzero(votes >= MIN_VOTES)
        d_all = np.sum((S[: last + 1] - S[i]) ** 2, axis=1)
        if len(rows):
            order = np.lexsort((rows, d_all[rows], -votes[rows]))[:candidates]
            t_js = rows[order].tolist()
        else:
            t_js = []
        got: list[int] = []
        seen: set[int] = set()
        s_js = by_sig.get(i, [])
        for k in range(max(len(t_js), len(s_js))):
            for js in (t_js, s_js):
                if k < len(js) and js[k] not in seen and len(got) < candidates:
                    seen.add(js[k])
                    got.append(js[k])
        for rank, j in enumerate(got):
            out.append((i, int(j), rank, float(d_all[j])))
    return out


# ---------------------------------------------------------------------------------------
# The search
# ---------------------------------------------------------------------------------------
def _chunks(items: list, n_chunks: int) -> list[list]:
    if not items:
        return []
    size = max(1, math.ceil(len(items) / max(1, n_chunks)))
    return [items[k : k + size] for k in range(0, len(items), size)]


class _Runner:
    """Runs the two parallel steps on one backend."""

    def __init__(self, scans, cfg, limits, workers, scheduler):
        self.token = new_token()
        self.args = (config_to_dict(cfg), (float(limits[0]), int(limits[1]), float(limits[2])))
        self.scans = scans
        self.workers = workers
        self.pool = self.client = self.scans_future = None
        if scheduler is not None:
            self.backend = "dask"
            try:
                from distributed import Client
            except ImportError as exc:  # pragma: no cover - optional dependency
                raise ScanCliqueError(
                    f"--scheduler needs dask.distributed ({exc}): pip install 'scanclique[scale]'"
                ) from None
            try:
                self.client = (
                    scheduler if hasattr(scheduler, "submit") else Client(scheduler, timeout="10s")
                )
            except (OSError, TimeoutError) as exc:
                raise ScanCliqueError(
                    f"cannot reach the Dask scheduler {scheduler}: {exc}"
                ) from None
            self._own_client = not hasattr(scheduler, "submit")
            try:
                self.workers = max(1, len(self.client.scheduler_info().get("workers", {})))
                # waits for a worker up to the client's connection timeout
                self.scans_future = self.client.scatter([list(scans)], broadcast=True)[0]
            except (OSError, TimeoutError) as exc:
                address = scheduler if isinstance(scheduler, str) else "<scheduler address>"
                self.close()
                raise ScanCliqueError(
                    f"the Dask scheduler {scheduler} has no worker to take the scans "
                    f"({type(exc).__name__}: {exc}); start workers with "
                    f"'dask worker {address}'"
                ) from None
        elif workers > 1:
            self.backend = "processes"
            self.pool = local_pool(workers, _install, (self.token, list(scans), *self.args))
        else:
            self.backend = "serial"
            self.workers = 1
            _install(self.token, scans, *self.args)

    def map(self, fn, chunks: list, progress: Callable[[int], None] | None = None) -> list:
        """``fn(token, chunk)`` for each chunk, results in chunk order."""
        if self.backend == "serial":
            out = []
            for c in chunks:
                out.append(fn(self.token, c))
                if progress:
                    progress(len(c))
            return out
        if self.backend == "processes":
            futs = [self.pool.submit(fn, self.token, c) for c in chunks]
        else:
            futs = [
                self.client.submit(fn, self.token, c, self.scans_future, *self.args, pure=False)
                for c in chunks
            ]
        index = {f: k for k, f in enumerate(futs)}
        results = [None] * len(futs)
        if self.backend == "processes":
            import concurrent.futures as cf

            done_iter = cf.as_completed(futs)
        else:
            from distributed import as_completed

            done_iter = as_completed(futs)
        for f in done_iter:
            k = index[f]
            try:
                results[k] = f.result()
            except Exception as exc:
                if self.backend != "dask":
                    raise
                # a worker's own failure (most often a worker without scanclique, or
                # with another version) comes back here, with the worker's message
                raise ScanCliqueError(
                    f"a Dask worker failed on {fn.__name__} of chunk {k} "
                    f"({type(exc).__name__}: {exc}); each worker needs scanclique "
                    f"{__version__} installed"
                ) from exc
            if progress:
                progress(len(chunks[k]))
        return results

    def close(self) -> None:
        if self.pool is not None:
            self.pool.shutdown()
        if self.client is not None and self._own_client:
            self.client.close()
        if self.backend == "serial":
            _STATE.clear(self.token)


def find_loops(
    scans: Sequence[Scan],
    config: MatchConfig | None = None,
    *,
    candidates: int = 5,
    min_gap: int = 50,
    workers: int = 1,
    scheduler=None,
    min_score: float = ACCEPT_MIN_SCORE,
    min_features: int = ACCEPT_MIN_FEATURES,
    min_confidence: float = ACCEPT_MIN_CONFIDENCE,
    progress: Callable[[str, int, int], None] | None = None,
) -> LoopSearch:
    """The all-pairs revisit search of a log (module docstring).

    Parameters
    ----------
    scans : sequence of Scan
        The log, in order.
    config : MatchConfig, optional
        None: the defaults, one lost return bridged for a scanner that loses them and no
        edges where a wall only leaves the reach (:func:`scanclique.features.for_scanner`,
        not widened, no reach edges).
    candidates : int
        Prefilter candidates verified per scan.
    min_gap : int
        Only pairs at least this many scans apart (``j <= i - min_gap``).
    workers : int
        Local worker processes (1: this process; 0: one per CPU).
    scheduler : str or distributed.Client, optional
        A Dask scheduler address (``tcp://host:8786``) or client: run there instead.
    min_score, min_features, min_confidence : float, int, float
        As for :func:`.verify.verify_pair` (a pair accepted below ``min_confidence`` is
        ``ambiguous``).
    progress : callable, optional
        ``progress(stage, done, total)`` as work completes (``"signatures"``,
        ``"verify"``).

    Returns
    -------
    LoopSearch
        Identical for every backend and number of workers.

    Raises
    ------
    ConfigError
        ``candidates < 1``, ``min_gap < 1``, ``workers < 0`` or above
        :func:`scanclique._workers.max_workers` (4 per core, at least 64), or ``config``
        is not a :class:`~scanclique.config.MatchConfig`.
    ArgumentError
        ``scans`` is not a sequence (None, a path, a generator).
    ScanCliqueError
        The scheduler cannot be reached, has no worker (within the client's 10 s
        connection timeout), or a worker fails (a worker without scanclique, or with
        another version: the message says which task and why).
    """
    require_count("find_loops: ", 1, candidates=candidates, min_gap=min_gap)
    require_callable("find_loops: ", progress=progress)
    check_workers("find_loops: workers", workers, 0)
    if isinstance(scans, (str, bytes)) or not isinstance(scans, Sequence):
        raise ArgumentError(
            f"find_loops: scans must be a sequence of Scan (read a file with read_scans "
            f"first), got {type(scans).__name__}"
        )
    require_config("find_loops: ", config, MatchConfig)
    cfg = config or for_scanner(None, scans, widen=False, reach_edges=False)
    if workers == 0:
        workers = os.cpu_count() or 1
    t0 = time.perf_counter()
    seconds = {}
    n = len(scans)
    runner = _Runner(scans, cfg, (min_score, min_features, min_confidence), workers, scheduler)
    try:
        nchunk = 1 if runner.backend == "serial" else 4 * runner.workers

        def tick(stage, total):
            done = [0]

            def f(k):
                done[0] += k
                if progress:
                    progress(stage, done[0], total)

            return f

        # 1. signatures
        t = time.perf_counter()
        chunks = _chunks(list(range(n)), nchunk if runner.backend != "serial" else max(1, n // 64))
        parts = runner.map(_signature_task, chunks, tick("signatures", n))
        sigs = np.concatenate([p[0] for p in parts]) if parts else np.zeros((0, SIGNATURE_SIZE))
        tris = [Triangles(*t) for p in parts for t in p[1]]
        seconds["signatures"] = time.perf_counter() - t
        # 2. prefilter
        t = time.perf_counter()
        cand = fused_loop_candidates(sigs, tris, candidates, min_gap)
        seconds["prefilter"] = time.perf_counter() - t
        # 3. verification
        t = time.perf_counter()
        pairs = [(i, j) for i, j, _, _ in cand]
        pchunks = _chunks(
            pairs, 8 * runner.workers if runner.backend != "serial" else max(1, len(pairs) // 64)
        )
        results = [
            r
            for part in runner.map(_verify_task, pchunks, tick("verify", len(pairs)))
            for r in part
        ]
        seconds["verify"] = time.perf_counter() - t
        backend, used = runner.backend, runner.workers
    finally:
        runner.close()
    loops = []
    for (i, j, rank, d), (verdict, p, score, nf) in zip(cand, results, strict=True):
        loops.append(Loop(i, j, rank, d, verdict, None if p is None else Pose2(*p), score, nf))
    loops.sort(key=lambda lp: (lp.i, lp.j))
    seconds["total"] = time.perf_counter() - t0
    return LoopSearch(tuple(loops), n, candidates, min_gap, backend, used, seconds, cfg)
