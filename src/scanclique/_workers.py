"""The one way scanclique runs work on local processes (issue 12 part 7, issue 14 part 4).

Two applications spread independent verifications over processes: the mapper's loop
candidates (:mod:`scanclique.mapping.parallel`) and the all-pairs revisit search
(:mod:`scanclique.places.loops`). Both follow one pattern, which lives here:

- a run is named by a random *token*; each process keeps the state of one run (the
  configuration, the scans, what it has prepared) in a :class:`RunState`, installed by the
  pool's initializer (or by the first task, on a Dask worker) and checked by every task, so a
  task never reads the state of another run;
- the pool forks when the platform can (the workers inherit the compiled kernels and start in
  milliseconds), else spawns;
- a serial run uses the same task functions in this process, through :class:`Done`, a
  finished task shaped like a future;
- results are consumed in submission order, so the answer does not depend on the number of
  workers.
"""

from __future__ import annotations

import logging
import os
import uuid
from collections.abc import Callable

__all__ = ["Done", "RunState", "check_workers", "local_pool", "max_workers", "new_token"]

log = logging.getLogger(__name__)


def max_workers() -> int:
    """The most local worker processes a run may ask for: 4 per core of this machine, and
    at least 64. The pool forks all of them at once; more only compete for the cores
    (the results are the same for every number), and a mistyped count (``--workers
    100000``) forked processes until the system refused."""
    return max(64, 4 * (os.cpu_count() or 1))


def check_workers(where: str, workers, lo: int = 1) -> None:
    """``workers`` is an integer from ``lo`` to :func:`max_workers`, else a
    :class:`~scanclique.errors.ConfigError` naming ``where`` (``"map_scans: workers"``)."""
    from .errors import ConfigError  # noqa: PLC0415

    top = max_workers()
    if isinstance(workers, bool) or not isinstance(workers, int) or not lo <= workers <= top:
        raise ConfigError(
            f"{where} must be an integer from {lo} to {top} (4 processes per core of this "
            f"machine's {os.cpu_count() or 1}, at least 64), got {workers!r}"
        )


def new_token() -> str:
    """A fresh token naming one parallel run."""
    return uuid.uuid4().hex


class RunState:
    """The state of one parallel run in this process, keyed by the run's token.

    Examples
    --------
    >>> s = RunState("demo")
    >>> s.install("t1", lambda: {"n": 3})["n"]
    3
    >>> s.install("t1", lambda: {"n": 4})["n"]    # same run: kept, the factory is not called
    3
    >>> s.require("t2")
    Traceback (most recent call last):
    ...
    RuntimeError: demo: worker state of another run
    >>> s.clear("t1"); s.token is None
    True
    """

    __slots__ = ("_name", "_values", "token")

    def __init__(self, name: str):
        self._name = name
        self.token: str | None = None
        self._values: dict = {}

    def install(self, token: str, build: Callable[[], dict]) -> dict:
        """The state of run ``token``, built by ``build()`` unless it is already installed."""
        if self.token != token:
            self._values = dict(build())
            self.token = token
        return self._values

    def require(self, token: str) -> dict:
        """The state of run ``token``; ``RuntimeError`` if this process holds another run."""
        if self.token != token:
            raise RuntimeError(f"{self._name}: worker state of another run")
        return self._values

    def clear(self, token: str | None = None) -> None:
        """Forget the run's state (only run ``token``'s, when given)."""
        if token is None or self.token == token:
            self.token = None
            self._values = {}


class Done:
    """A finished task, shaped like a future (``result()``)."""

    __slots__ = ("_value",)

    def __init__(self, value):
        self._value = value

    def result(self):
        return self._value


def local_pool(processes: int, initializer: Callable, initargs: tuple):
    """A ``concurrent.futures.ProcessPoolExecutor`` of ``processes`` local workers, forked
    when the platform can (else spawned), each running ``initializer(*initargs)`` once."""
    import concurrent.futures as cf  # noqa: PLC0415
    import multiprocessing as mp  # noqa: PLC0415

    method = "fork" if "fork" in mp.get_all_start_methods() else "spawn"
    log.debug("%d local %s worker processes", processes, method)
    return cf.ProcessPoolExecutor(
        max_workers=processes,
        mp_context=mp.get_context(method),
        initializer=initializer,
        initargs=initargs,
    )
