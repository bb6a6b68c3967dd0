"""Mapping a log while it is recorded: :class:`OnlineMapper` (issue 12, part 3, "iSAM2
incrementally if you offer an online mode").

A robot's driver hands the scans over one at a time; :meth:`OnlineMapper.add` places each
at once and answers with its pose in the map frame (the frame of the first scan) as the
mapper estimates it *now*: its keyframe's estimate by the incremental optimiser (iSAM2,
which takes the accepted closures every ``loops.pcm_batch`` keyframes), composed with the
scan's match to that keyframe. No scan that has not come yet is used. This is the same
mapper as :func:`~scanclique.mapping.map_scans` (:class:`~.pipeline._Mapper`), fed one scan
at a time: :meth:`OnlineMapper.finish` ends the log and runs the batch back end, and its
:class:`~.pipeline.MapResult` is the one ``map_scans`` gives for the same scans and
configuration, pose for pose, when the two take the odometry alike. The online default
configuration is :meth:`MapConfig.online() <scanclique.mapping.MapConfig.online>`
(closures decided every 5 keyframes instead of 10, so answers take them sooner).

What ``map_scans`` reads from the whole log, the online mapper reads from the scans so far:

* ``use_odometry=None``: the odometry is used from the first of the first
  :data:`ODOMETRY_FIRST_SCANS` scans that carries it (a bag's first laser message can
  come before its first odometry message; ``map_scans``: when 95 % of the scans do). A
  later scan without odometry is placed by the constant-velocity prior, as in
  ``map_scans(..., use_odometry=True)``.
* ``odometry_reverses=None``: whether the wheel odometry reports backing up
  (:func:`~.frontend.odometry_sees_reversing`, which ``map_scans`` asks of the whole log)
  is told from the scans so far (:class:`~.frontend.ReversingWatch`): until 50 moving
  steps have come, and as soon as one goes backwards, it is taken to report it. A robot's
  odometry either reports backing up or does not: give it when known.
* A rotating lidar's sweep (scans with :attr:`~scanclique.scan.Scan.beam_times`) is
  de-skewed (``FrontEndConfig.deskew``) at the velocity of the motion before the scan,
  not of the sweep itself, which ``map_scans`` has from the whole log: with odometry
  from the scan before, not to the next (on the simulated LDS-01 at 5 Hz, eight drives,
  0.146 m mean against the batch's 0.068 m; 0.185 m without de-skew); without, the
  estimate's over ``FrontEndConfig.deskew_window``, not a first pass's
  (:func:`~scanclique.mapping.pipeline.sweep_velocities`; the same drives 0.396 m online
  against the batch's 0.236 m; 1.437 m without de-skew). How the driver gave the times
  (:func:`~scanclique.mapping.sweep.sweep_timing`, which ``map_scans`` asks of the whole
  log first) is tried on the scans so far at the 25th, 50th, 100th, ... scan, and the
  scans are de-skewed only from when one direction of the times clearly leads (before,
  as they are: times read the wrong way round would double the skew). Such scans map
  differently online and in batch.
* The clustering is fitted to the scanner (``FrontEndConfig.fit_scanner``,
  :func:`~scanclique.features.for_scanner`, which ``map_scans`` asks of up to 200 scans
  of the log) on the first scan: its range noise is read less surely from one scan
  (simulated RPLIDAR drives: 1.3-1.8 % against 1.5 %), and a first scan with too few
  surfaces beyond 2 m (the 3.5 m LDS-01 always) leaves the range term as it is.
"""

from __future__ import annotations

import operator
import time
from bisect import bisect_left
from collections.abc import Callable, Iterable
from dataclasses import dataclass

import numpy as np

from .._records import readonly
from .._workers import check_workers
from ..config import require_callable, require_config, require_flag
from ..errors import ArgumentError, ScanError
from ..geometry import Pose2
from ..scan import Scan
from .config import MapConfig
from .frontend import ReversingWatch
from .pipeline import (
    MapResult,
    _Mapper,
    check_iterable_of_scans,
    check_odometry,
    fit_scanner,
    map_scans,
    warn_time_order,
    warn_unmatched,
)

__all__ = ["ODOMETRY_FIRST_SCANS", "OnlineMapper", "OnlineRun", "map_online"]

#: ``use_odometry=None``: the odometry is used from the first scan that carries it among
#: this many first scans (a bag's first laser messages can precede its odometry)
ODOMETRY_FIRST_SCANS = 10


class OnlineMapper:
    """Map scans as they come: :meth:`add` each in recording order, :meth:`finish` at the
    end (paper §2, the first application, run online).

    Parameters
    ----------
    use_odometry : bool, optional
        None (default): use the odometry when the first scan carries it. False: from the
        scans alone (constant-velocity prior). True: use it where present.
    odometry_reverses : bool, optional
        Whether the wheel odometry reports the robot backing up. None (default): told from
        the scans so far (module docstring).
    config : MapConfig, optional
        Default: :meth:`MapConfig.online() <scanclique.mapping.MapConfig.online>`.
    workers : int
        As for :func:`~scanclique.mapping.map_scans`: N > 1 verifies the loop candidates on
        N - 1 forked local processes. Use the mapper in a ``with`` block (or call
        :meth:`close`) so that they end with it.

    Raises
    ------
    ConfigError
        If ``config`` is not a :class:`MapConfig` or ``workers`` is out of range.
    ArgumentError
        If ``use_odometry`` or ``odometry_reverses`` is not a bool or None.

    Examples
    --------
    >>> import numpy as np
    >>> from scanclique.sim import simulate_pair
    >>> pair = simulate_pair(np.random.default_rng(0))
    >>> with OnlineMapper(use_odometry=False) as mapper:
    ...     first = mapper.add(pair.scan_a)
    ...     now = mapper.add(pair.scan_b)        # scan b's pose in scan a's frame, now
    ...     result = mapper.finish()             # map_scans([a, b], config=MapConfig.online())
    >>> first, len(result.poses)
    (Pose2(x=0.0000, y=0.0000, theta=0.0000), 2)
    """

    def __init__(
        self,
        *,
        use_odometry: bool | None = None,
        odometry_reverses: bool | None = None,
        config: MapConfig | None = None,
        workers: int = 1,
    ) -> None:
        require_config("OnlineMapper: ", config, MapConfig)
        check_workers("OnlineMapper: workers", workers)
        require_flag(
            "OnlineMapper: ", use_odometry=use_odometry, odometry_reverses=odometry_reverses
        )
        self._use = use_odometry
        self._reverses = odometry_reverses
        self._cfg = config or MapConfig.online()
        self._workers = workers
        self._watch = ReversingWatch()
        self._mapper: _Mapper | None = None  # made at the first scan
        self._result: MapResult | None = None
        self._busy = 0.0  # seconds spent in add and finish
        self._closed = False  # close() before finish(): no result

    # -- taking scans -------------------------------------------------------------------
    def add(self, scan: Scan) -> Pose2:
        """Map the next scan; return its pose in the map frame as now estimated (maps the
        scan's points into the frame of the first scan; m, rad).

        The pose of an earlier scan may move as closures come (:meth:`pose`,
        :meth:`poses`); the one returned here is what the mapper knew when the scan came.

        Raises
        ------
        ScanError
            If ``scan`` is not a :class:`~scanclique.scan.Scan`.
        ArgumentError
            After :meth:`finish` or :meth:`close`.
        """
        if not isinstance(scan, Scan):
            raise ScanError(f"OnlineMapper.add: scan must be a Scan, got {type(scan).__name__}")
        if self._result is not None or self._closed:
            raise ArgumentError(
                "OnlineMapper.add: the log is finished (finish() or close() was called); "
                "start a new OnlineMapper"
            )
        t = time.perf_counter()
        if self._mapper is None:
            use = scan.odometry is not None if self._use is None else self._use
            blind = self._reverses is False
            self._cfg = fit_scanner([scan], self._cfg)  # the scanner, from its first scan
            self._mapper = _Mapper(use, blind, self._cfg, self._workers)
        m = self._mapper
        if self._use is None and not m.odo and scan.odometry is not None:
            if len(m.scans) < ODOMETRY_FIRST_SCANS:  # the odometry came after the laser
                m.odo = True
        if self._reverses is None:
            self._watch.see(scan.odometry)
            m.blind_to_reversing = m.odo and not self._watch.sees_reversing
        m.add_scan(scan)
        pose = self.pose(len(m.scans) - 1)
        self._busy += time.perf_counter() - t
        return pose

    # -- what is known now --------------------------------------------------------------
    def __len__(self) -> int:
        """The number of scans taken so far."""
        return 0 if self._mapper is None else len(self._mapper.scans)

    def pose(self, index: int) -> Pose2:
        """Scan ``index``'s pose in the map frame under the current estimate (its
        keyframe's, composed with its match to it).

        Raises
        ------
        ArgumentError
            If ``index`` is not an integer naming a scan taken so far (negative counts
            from the newest).
        """
        n = len(self)
        try:
            if isinstance(index, bool):
                raise TypeError
            index = operator.index(index)
        except TypeError:
            raise ArgumentError(
                f"OnlineMapper.pose: index must be an integer, got {index!r}"
            ) from None
        if not -n <= index < n:
            raise ArgumentError(f"OnlineMapper.pose: no scan {index} ({n} taken so far)")
        m = self._mapper
        j = index % n
        base = m.kf_of[j]
        return m.estimate_of(bisect_left(m.kf, base)) @ m.rel_to_kf[j]

    def poses(self) -> tuple[Pose2, ...]:
        """Every scan's pose so far under the current estimate (:meth:`pose`)."""
        return tuple(self.pose(j) for j in range(len(self)))

    @property
    def keyframes(self) -> tuple[int, ...]:
        """Scan indices of the keyframes so far."""
        return () if self._mapper is None else tuple(self._mapper.kf)

    @property
    def loop_closures(self) -> tuple:
        """The loop candidates decided so far, with their verdicts (accepted or not; see
        :class:`~scanclique.mapping.loops.LoopClosure`). The candidates of the newest
        ``loops.pcm_batch`` keyframes are decided at the next batch or at :meth:`finish`."""
        return () if self._mapper is None else tuple(self._mapper.closures)

    # -- the end ------------------------------------------------------------------------
    def finish(self) -> MapResult:
        """End the log: the last scan becomes a keyframe, the pending closures are decided
        and the batch back end (Levenberg–Marquardt) runs. The result is what
        :func:`~scanclique.mapping.map_scans` gives for the same scans and configuration
        when the odometry is taken alike (module docstring); ``seconds["total"]`` is the
        time spent in :meth:`add` and here. Calling it again returns the same result.

        Raises
        ------
        ArgumentError
            After :meth:`close` without a result.
        """
        if self._result is not None:
            return self._result
        if self._closed:
            raise ArgumentError("OnlineMapper.finish: the mapper was closed without a result")
        t = time.perf_counter()
        m = self._mapper
        if m is None:
            self._result = map_scans([], config=self._cfg)
            return self._result
        try:
            m.close_log()
        finally:
            m.verifier.close()
        self._result = m.result(t - self._busy)
        warn_unmatched(self._result)
        warn_time_order(m.scans)
        if m.odo:
            self._result = check_odometry(m.scans, self._result)
        return self._result

    def close(self) -> None:
        """End the worker processes (if any) without a result; the mapper takes no more
        scans. :meth:`finish` closes them too."""
        if self._result is None and not self._closed:
            if self._mapper is not None:
                self._mapper.verifier.close()
            self._closed = True

    def __enter__(self) -> OnlineMapper:
        return self

    def __exit__(self, *exc) -> None:
        self.close()


@dataclass(frozen=True, slots=True, eq=False)
class OnlineRun:
    """A recorded log mapped online (:func:`map_online`).

    Attributes
    ----------
    result : MapResult
        The finished map (:meth:`OnlineMapper.finish`).
    live : tuple of Pose2
        Per scan, its pose as :meth:`OnlineMapper.add` answered it when the scan came (what
        the robot knew then), in the map frame.
    add_seconds : (N,) ndarray
        Per scan, the time :meth:`OnlineMapper.add` took (s); ``finish_seconds`` is that of
        :meth:`OnlineMapper.finish`.
    finish_seconds : float
    """

    result: MapResult
    live: tuple
    add_seconds: np.ndarray
    finish_seconds: float

    def __post_init__(self) -> None:
        object.__setattr__(self, "add_seconds", readonly(self.add_seconds, dtype=float))


def map_online(
    scans: Iterable[Scan],
    *,
    use_odometry: bool | None = None,
    odometry_reverses: bool | None = None,
    config: MapConfig | None = None,
    progress: Callable[[int, int, int], None] | None = None,
    workers: int = 1,
    watch: Callable[[OnlineMapper, int], None] | None = None,
) -> OnlineRun:
    """Map a recorded log as a robot would have live: an :class:`OnlineMapper` fed its
    scans in order, every answer and its time kept. The arguments are the mapper's;
    ``progress(done, total, closures)`` is called every 50 scans (``total`` 0 when
    ``scans`` has no length); ``watch(mapper, index)`` after each scan is added, to read
    what is known then (:meth:`OnlineMapper.pose` of earlier scans; not timed).

    Raises
    ------
    ArgumentError
        If ``scans`` is not an iterable of scans (None, a number, a path), or as
        :class:`OnlineMapper` does.
    ConfigError
        As :class:`OnlineMapper` does.
    ScanError
        If one of the scans is not a :class:`~scanclique.scan.Scan` (naming its index).
    """
    check_iterable_of_scans("map_online", scans)
    require_callable("map_online: ", progress=progress, watch=watch)
    total = len(scans) if hasattr(scans, "__len__") else 0
    live, took = [], []
    with OnlineMapper(
        use_odometry=use_odometry, odometry_reverses=odometry_reverses, config=config,
        workers=workers,
    ) as mapper:  # fmt: skip
        for j, scan in enumerate(scans):
            if not isinstance(scan, Scan):
                raise ScanError(f"map_online: scans[{j}] is a {type(scan).__name__}, not a Scan")
            t = time.perf_counter()
            live.append(mapper.add(scan))
            took.append(time.perf_counter() - t)
            if watch is not None:
                watch(mapper, j)
            if progress is not None and j > 0 and (j % 50 == 0 or j == total - 1):
                progress(j + 1, total, mapper._mapper.closures_accepted())
        t = time.perf_counter()
        result = mapper.finish()
        finish = time.perf_counter() - t
    return OnlineRun(result, tuple(live), np.array(took, dtype=float), finish)
