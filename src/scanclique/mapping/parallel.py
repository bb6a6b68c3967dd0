"""Loop-candidate verification on local processes (issue 12, part 7: ``--workers N``).

The mapper (:mod:`.pipeline`) decides *which* pairs of keyframes to verify from the estimate
it holds between two PCM batches; no verification result of a batch changes that estimate
before the batch is flushed (the estimate is updated only then). So the verifications of a
batch are independent of one another: they are submitted as they are proposed, one task per
keyframe, and their results are consumed at the flush in the order they were proposed. The
map is therefore the same, pose for pose, whatever the number of workers; ``workers=1``
runs the same code in this process.

What a task carries: the two scans' *prepared* forms (features, feature graph, point cloud:
about 80 kB pickled for a 360-beam scan, a fraction of a millisecond to pickle and unpickle,
against about 5 ms to prepare the scan again), the two estimated poses and the prior's
standard deviations. The workers are forked with the configuration (and the compiled
kernels) of the run; they keep no scans of their own.

This follows the process pool of :func:`scanclique.places.loops.find_loops` (fork when the
platform has it, an initializer installing the run's state, results consumed in
submission order); its pool class is private to that module and verifies another kind of
pair, so only the approach is shared.
"""

from __future__ import annotations

import logging
import uuid
from collections.abc import Sequence

from ..errors import ConfigError
from . import loops as _loops

__all__ = ["Job", "Verifier"]

log = logging.getLogger(__name__)

#: a verification: ``(i, j, est_i, est_j, sigma, quick, strict)`` with scan indices
#: ``i < j``, the current estimates of both scans, the prior's ``(sigma_xy m, sigma_theta
#: rad)``, ``quick`` for a local neighbour and ``strict`` for an appearance candidate
Job = tuple

_STATE: dict = {"token": None}


def _install(token: str, match_cfg, front_end, floor) -> None:
    if _STATE.get("token") != token:
        _STATE.clear()
        _STATE.update(token=token, match=match_cfg, front_end=front_end, floor=floor)


def _verify_jobs(token: str, jobs: Sequence[Job], prepared: dict) -> list:
    """Verify ``jobs`` (see :data:`Job`); one ``(pose, covariance, verdict, score,
    reason)`` per job (:func:`scanclique.mapping.loops.verify`); ``prepared``: scan index
    -> PreparedScan of every scan the jobs name."""
    if _STATE.get("token") != token:  # pragma: no cover - a stale or foreign pool
        raise RuntimeError("mapping.parallel: worker state of another run")
    fe, cfg, floor = _STATE["front_end"], _STATE["match"], _STATE["floor"]
    return [
        _loops.verify(
            prepared[i],
            prepared[j],
            est_i,
            est_j,
            sigma,
            cfg,
            floor,
            fe,
            quick=quick,
            strict=strict,
        )  # fmt: skip
        for i, j, est_i, est_j, sigma, quick, strict in jobs
    ]


class _Done:
    """A finished serial task, shaped like a future."""

    __slots__ = ("_value",)

    def __init__(self, value):
        self._value = value

    def result(self):
        return self._value


class Verifier:
    """Verifies batches of loop candidates, in this process (``workers == 1``) or, with
    ``workers = N > 1``, on ``N - 1`` forked local processes while this one (the front end,
    PCM, iSAM2) goes on: ``N`` processes work, one per core (on a 2-core machine
    ``workers=2`` is one worker beside the main process). :meth:`submit` returns a handle
    whose ``result()`` is the list of verdicts of the batch, in job order.

    Parameters
    ----------
    match_cfg, front_end, floor :
        What :func:`scanclique.mapping.loops.verify` is called with.
    workers : int
        Processes working, this one included (>= 1).
    """

    def __init__(self, match_cfg, front_end, floor, workers: int = 1):
        if isinstance(workers, bool) or not isinstance(workers, int) or workers < 1:
            raise ConfigError(f"map_scans: workers must be an integer >= 1, got {workers!r}")
        self.workers = workers
        self.token = uuid.uuid4().hex
        self.pool = None
        args = (self.token, match_cfg, front_end, floor)
        if workers > 1:
            import concurrent.futures as cf  # noqa: PLC0415
            import multiprocessing as mp  # noqa: PLC0415

            method = "fork" if "fork" in mp.get_all_start_methods() else "spawn"
            self.pool = cf.ProcessPoolExecutor(
                max_workers=workers - 1,
                mp_context=mp.get_context(method),
                initializer=_install,
                initargs=args,
            )
            log.debug("loop verification on %d %s processes", workers - 1, method)
        else:
            _install(*args)

    def submit(self, jobs: Sequence[Job], prepared: dict):
        """Start verifying ``jobs``; ``prepared``: scan index -> PreparedScan of every scan
        they name."""
        jobs = [tuple(job) for job in jobs]
        if self.pool is None:
            return _Done(_verify_jobs(self.token, jobs, prepared))
        return self.pool.submit(_verify_jobs, self.token, jobs, prepared)

    def close(self) -> None:
        if self.pool is not None:
            self.pool.shutdown(wait=True, cancel_futures=True)
            self.pool = None
        elif _STATE.get("token") == self.token:
            _STATE.clear()
            _STATE["token"] = None
