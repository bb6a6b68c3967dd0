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

The pool, the per-process run state and the serial stand-in for a future are the ones
:func:`scanclique.places.loops.find_loops` uses too (:mod:`scanclique._workers`).
"""

from __future__ import annotations

from collections.abc import Sequence

from .._workers import Done, RunState, check_workers, local_pool, new_token
from . import loops as _loops

__all__ = ["Job", "Verifier"]

#: a verification: ``(i, j, est_i, est_j, sigma, quick, strict)`` with scan indices
#: ``i < j``, the current estimates of both scans, the prior's ``(sigma_xy m, sigma_theta
#: rad)``, ``quick`` for a local neighbour and ``strict`` for an appearance candidate
Job = tuple

_STATE = RunState("mapping.parallel")


def _install(token: str, match_cfg, front_end, floor, loop_cfg=None) -> None:
    _STATE.install(
        token,
        lambda: {
            "match": match_cfg, "loop_match": loop_cfg or match_cfg, "front_end": front_end,
            "floor": floor,
        },
    )  # fmt: skip


def _verify_jobs(
    token: str, jobs: Sequence[Job], prepared: dict, loop_prepared: dict | None = None
) -> list:
    """Verify ``jobs`` (see :data:`Job`); one ``(pose, covariance, verdict, score,
    reason)`` per job (:func:`scanclique.mapping.loops.verify`); ``prepared``: scan index
    -> PreparedScan of every scan the jobs name; ``loop_prepared``, when given, the same
    prepared under the loops' configuration for the jobs that are not local
    (``LoopConfig.reach_edges``)."""
    state = _STATE.require(token)
    fe, floor = state["front_end"], state["floor"]
    out = []
    for i, j, est_i, est_j, sigma, quick, strict in jobs:
        loop = not quick and loop_prepared is not None
        p, cfg = (loop_prepared, state["loop_match"]) if loop else (prepared, state["match"])
        out.append(
            _loops.verify(
                p[i], p[j], est_i, est_j, sigma, cfg, floor, fe, quick=quick, strict=strict
            )
        )
    return out


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
    loop_cfg : MatchConfig, optional
        The configuration of the jobs that are not local, when it differs
        (``LoopConfig.reach_edges``; their scans then come in ``submit``'s
        ``loop_prepared``).
    workers : int
        Processes working, this one included (>= 1).
    """

    def __init__(self, match_cfg, front_end, floor, workers: int = 1, loop_cfg=None):
        check_workers("map_scans: workers", workers)
        self.workers = workers
        self.token = new_token()
        self.pool = None
        args = (self.token, match_cfg, front_end, floor, loop_cfg)
        if workers > 1:
            self.pool = local_pool(workers - 1, _install, args)
        else:
            _install(*args)

    def submit(self, jobs: Sequence[Job], prepared: dict, loop_prepared: dict | None = None):
        """Start verifying ``jobs``; ``prepared``: scan index -> PreparedScan of every scan
        they name; ``loop_prepared``: the same under the loops' configuration, for the
        jobs that are not local (when the Verifier has one)."""
        jobs = [tuple(job) for job in jobs]
        if self.pool is None:
            return Done(_verify_jobs(self.token, jobs, prepared, loop_prepared))
        return self.pool.submit(_verify_jobs, self.token, jobs, prepared, loop_prepared)

    def close(self) -> None:
        if self.pool is not None:
            self.pool.shutdown(wait=True, cancel_futures=True)
            self.pool = None
        else:
            _STATE.clear(self.token)
