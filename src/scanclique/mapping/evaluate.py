"""The run behind ``scanclique evaluate``: a trajectory scored by the relation metric of the
SLAM benchmark (Kümmerle et al. 2009), as a plain function (no typer, no rich).

Any system's trajectory in the TUM format (``scanclique map``'s ``trajectory.tum``, or one
exported from Cartographer, GMapping, slam_toolbox, ...) against a relations file of the
benchmark (``t1 t2 x y z roll pitch yaw`` per line, the robot's pose at ``t2`` in its frame
at ``t1``), so that a map of a benchmark log made here or elsewhere is scored the same way
(:func:`scanclique.eval.trajectory_relation_metrics`).

The relations refer to the robot's frame. ``scanclique map`` writes the laser's poses, so
for a log whose laser sits off the robot's centre (the raw fr079 log: 0.04 m behind) the
mounting is needed: given, or read from the log's laser lines
(:func:`scanclique.eval.frame_mounting`), by default from the registered log whose
relations are used.

>>> import tempfile, pathlib
>>> d = pathlib.Path(tempfile.mkdtemp())
>>> _ = (d / "t.tum").write_text("0 0 0 0 0 0 0 1\\n1 1.1 0 0 0 0 0 1\\n")
>>> _ = (d / "r.relations").write_text("0 1 1 0 0 0 0 0\\n")
>>> run = run_evaluate(d / "t.tum", d / "r.relations")
>>> round(run.metrics["all"]["translation_mean"], 6), run.metrics["all"]["n"]
(0.1, 1)
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass
from pathlib import Path

from .. import datasets
from ..config import require_positive
from ..errors import ArgumentError, DataNotFoundError
from ..geometry import Pose2

__all__ = ["EvaluateRun", "run_evaluate"]


@dataclass(frozen=True, slots=True, eq=False)
class EvaluateRun:
    """What :func:`run_evaluate` measured.

    Attributes
    ----------
    trajectory, relations : str
        The files read.
    rows : int
        Poses in the trajectory.
    mounting : Pose2 or None
        The pose of the relations' frame (the robot's) in the trajectory's (None: the same).
    mounting_source : str
        Where the mounting came from (``"given"``, ``"<log>'s laser lines"``, ``"none"``).
    metrics : dict
        :meth:`scanclique.eval.SplitErrors.to_dict`.
    """

    trajectory: str
    relations: str
    rows: int
    mounting: Pose2 | None
    mounting_source: str
    metrics: dict

    def table_rows(self) -> list[tuple[str, str, str]]:
        """Metric / Value / Units rows for the command's table."""
        from ..eval import relation_rows  # noqa: PLC0415

        m = self.mounting
        frame = (
            "the trajectory's"
            if m is None
            else f"x {m.x:+.3f} m, y {m.y:+.3f} m, theta {math.degrees(m.theta):+.2f} deg"
        )
        return [
            ("trajectory", self.trajectory, "file"),
            ("poses", str(self.rows), ""),
            ("relations file", self.relations, "file"),
            ("relations' frame (robot)", f"{frame} ({self.mounting_source})", ""),
            *relation_rows(self.metrics),
        ]

    def to_dict(self) -> dict:
        m = self.mounting
        return {
            "trajectory": self.trajectory,
            "relations": self.relations,
            "rows": self.rows,
            "mounting": None if m is None else [m.x, m.y, m.theta],
            "mounting_source": self.mounting_source,
            "metrics": self.metrics,
        }


def run_evaluate(
    trajectory: str | os.PathLike,
    relations: str | os.PathLike,
    *,
    log: str | os.PathLike | None = None,
    mounting: Pose2 | None = None,
    short_seconds: float | None = None,
) -> EvaluateRun:
    """Score a TUM trajectory against a relations file.

    Parameters
    ----------
    trajectory : path
        TUM rows ``timestamp x y z qx qy qz qw`` (:func:`scanclique.io.read_tum`), any rate.
    relations : path or str
        A relations file, or a registered log with relations (``intel``, ``fr079``).
    log : path or str, optional
        The log the trajectory is of: its laser lines give the mounting. Default: the
        registered log named by ``relations``, if that is one.
    mounting : Pose2, optional
        The relations' frame in the trajectory's, given (``Pose2(0, 0, 0)``: the same
        frame); overrides ``log``.
    short_seconds : float, optional
        Relations spanning at most this are "short" (default
        :data:`scanclique.eval.relations.SHORT_SECONDS`, 10 s).

    Raises
    ------
    DataNotFoundError
        ``relations`` is neither a file nor a registered log with relations at hand.
    ParseError
        A malformed trajectory or relations file (file, line and field named).
    ArgumentError
        No relation's time lies within the trajectory; ``trajectory`` or ``relations``
        not a path (or name), ``mounting`` not a :class:`~scanclique.geometry.Pose2`.
    ConfigError
        ``short_seconds`` not a positive number.
    """
    from ..eval.relations import (  # noqa: PLC0415
        SHORT_SECONDS,
        frame_mounting,
        read_relations,
        trajectory_relation_metrics,
    )
    from ..io import read_tum  # noqa: PLC0415
    from ..io.text import check_path  # noqa: PLC0415

    check_path(trajectory, "run_evaluate: trajectory")
    relations = check_path(relations, "run_evaluate: relations")
    if mounting is not None and not isinstance(mounting, Pose2):
        raise ArgumentError(f"run_evaluate: mounting must be a Pose2, got {mounting!r}")
    if short_seconds is not None:
        require_positive("run_evaluate: ", short_seconds=short_seconds)
    rel_file = Path(relations).expanduser()
    if not rel_file.is_file():
        found = datasets.log_relations(relations) if isinstance(relations, str) else None
        if found is None:
            raise DataNotFoundError(
                f"{os.fspath(relations)!r} is neither a relations file nor a registered log "
                f"with relations at hand ("
                f"{', '.join(k for k, d in datasets.DATASETS.items() if d.relations)})"
            )
        rel_file = found
        if log is None:
            log = relations
    rels = read_relations(rel_file)
    rows = read_tum(trajectory)
    source = "given"
    if mounting is None:
        source = "none"
        if log is not None:
            mounting = frame_mounting(datasets.load_log(log, laser="main"))
            source = f"{os.fspath(log)}'s laser lines"
    if mounting is not None and mounting == Pose2(0.0, 0.0, 0.0):
        mounting = None
    metrics = trajectory_relation_metrics(
        rows,
        rels,
        mounting=mounting,
        short_seconds=SHORT_SECONDS if short_seconds is None else short_seconds,
    )
    return EvaluateRun(
        os.fspath(trajectory), os.fspath(rel_file), len(rows), mounting, source, metrics.to_dict()
    )
