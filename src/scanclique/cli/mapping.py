"""The ``scanclique map`` command: map a whole log (issue 12); and ``scanclique evaluate``,
which scores a trajectory (this one's or another system's) by the benchmark's relations.

The work is :func:`scanclique.mapping.run.run_map` and
:func:`scanclique.mapping.evaluate.run_evaluate`; this module only parses arguments and
prints. Heavy imports happen inside the commands.
"""

from __future__ import annotations

import sys
from pathlib import Path
from typing import Annotated

import typer

from . import (
    AppConfigOpt,
    JsonOpt,
    OdometryOpt,
    SaveConfigOpt,
    _check_out_dir,
    _check_out_file,
    _console,
    _err_console,
    _guard,
    _invocation,
    _note,
    _print_json,
    _read_app_config,
    _save_config,
    _table,
)


def map_cmd(
    log: Annotated[
        str,
        typer.Argument(
            help="A CARMEN log (.log, .clf, .gz, .bz2), a registered data set name "
            "(intel, fr079, ...) or a ROS 1/ROS 2 bag."
        ),
    ],
    out: Annotated[str, typer.Option("--out", "-o", help="Output directory.")],
    odometry: OdometryOpt = None,
    topic: Annotated[
        str | None,
        typer.Option("--topic", help="LaserScan topic of a ROS bag (default: the only one)."),
    ] = None,
    odom_frame: Annotated[
        str | None,
        typer.Option(
            "--odom-frame",
            help="A ROS bag's tf frame of the odometry, when it has no nav_msgs/Odometry "
            "topic (default: odom).",
        ),
    ] = None,
    base_frame: Annotated[
        str | None,
        typer.Option(
            "--base-frame",
            help="A ROS bag's tf frame of the robot (default: base_link, else base_footprint).",
        ),
    ] = None,
    laser: Annotated[
        str | None,
        typer.Option(
            "--laser",
            help="Which laser of a CARMEN log that holds several (FLASER, RLASER, "
            "ROBOTLASER1..2, RAWLASER1..4, LASER3..4; default: the main one, FLASER first, "
            "said on stderr); for a ROS bag, its LaserScan topic (as --topic).",
        ),
    ] = None,
    plot: Annotated[
        bool, typer.Option("--plot", help="Also write map.png with the trajectory and closures.")
    ] = False,
    workers: Annotated[
        int,
        typer.Option(
            "--workers",
            "-w",
            "-j",
            min=1,
            help="N processes at work, one per core: loop candidates are verified on N-1 "
            "forked processes beside this one (the map is the same as with 1).",
        ),
    ] = 1,
    online: Annotated[
        bool,
        typer.Option(
            "--online",
            help="Map the log as a robot would live, one scan at a time, and also write "
            "trajectory_live.tum: each scan's pose as it was known when the scan came. The "
            "table adds the time per scan.",
        ),
    ] = False,
    covariances: Annotated[
        bool,
        typer.Option(
            "--covariances",
            help="Also write covariances.csv: every scan's pose covariance, from the "
            "marginals of the optimised graph (the same as back_end.covariances = true).",
        ),
    ] = False,
    relations: Annotated[
        Path | None,
        typer.Option(
            "--relations",
            help="A relations file of the SLAM benchmark (Kuemmerle et al.) for this log: "
            "the table adds its relation error (default: a registered log's own).",
            dir_okay=False,
        ),
    ] = None,
    config: AppConfigOpt = None,
    save_config: SaveConfigOpt = None,
    json_out: JsonOpt = False,
) -> None:
    """Map a log: trajectory.tum, graph.g2o, map.pgm + map.yaml (ROS map_server),
    report.json (map.png with --plot, covariances.csv with --covariances,
    trajectory_live.tum with --online) in OUT.

    **Examples**

    ```
    scanclique map ../shared/data/carmen/fr079.clf.bz2 --out runs/fr079
    scanclique map intel-raw --out runs/intel --no-odometry
    scanclique map my.bag --topic /scan --out runs/mine --plot
    scanclique map fr079-raw --out runs/fr079 --workers 2
    scanclique map intel --out runs/intel --covariances
    scanclique map fr079-raw --out runs/fr079 --online   # + trajectory_live.tum
    scanclique map aces.clf --out runs/aces --relations aces.relations
    scanclique config --for map > map.toml      # every key of MapConfig, to edit
    scanclique map intel --out runs/intel -c map.toml --save-config runs/used.toml
    ```
    """
    from .._workers import check_workers
    from ..mapping import MapConfig

    _guard(lambda: check_workers("--workers", workers))  # before reading the log
    from ..mapping.run import output_names

    if save_config is not None:
        _check_out_file(save_config, out_dir=out)  # may go into a new --out
    cfg = _read_app_config(config, MapConfig.online() if online else MapConfig())
    if covariances and not cfg.back_end.covariances:
        import dataclasses

        cfg = dataclasses.replace(cfg, back_end=dataclasses.replace(cfg.back_end, covariances=True))
    _check_out_dir(out, output_names(plot, cfg.back_end.covariances, online))  # before the run
    from rich.progress import BarColumn, Progress, TextColumn, TimeRemainingColumn

    from ..mapping.run import run_map, sigmas_dict

    quiet = json_out or not sys.stderr.isatty()
    with Progress(
        TextColumn("mapping"),
        BarColumn(),
        TextColumn("{task.completed}/{task.total} scans"),
        TextColumn("{task.fields[rate]:.0f} scans/s"),
        TextColumn("{task.fields[closures]} closures"),
        TimeRemainingColumn(),
        console=_err_console(),
        transient=True,
        disable=quiet,
    ) as bar:
        task = bar.add_task("map", total=None, rate=0.0, closures=0)
        import time

        t0 = time.perf_counter()

        def tick(done: int, total: int, closures: int) -> None:
            rate = done / max(time.perf_counter() - t0, 1e-9)
            bar.update(task, completed=done, total=total, rate=rate, closures=closures)

        run = _guard(
            lambda: run_map(
                log,
                out,
                use_odometry=odometry,
                topic=topic,
                laser=laser,
                odom_frame=odom_frame,
                base_frame=base_frame,
                plot=plot,
                progress=tick,
                workers=workers,
                config=cfg,
                online=online,
                relations=relations,
            )
        )
    for f in run.removed:
        _note(f"removed {f}: an earlier run's figure (this run drew none; --plot draws one)")
    if save_config is not None:
        _save_config(cfg, save_config, f"used by: {_invocation()}")
    if json_out:
        _print_json(
            {
                "log": log,
                "counts": run.result.counts(),
                "seconds": {**run.result.seconds, **run.seconds},
                "metrics": run.metrics,
                "pose_sigmas": sigmas_dict(run.result.covariances),
                "online": run.online,
                "files": run.files,
                "removed": list(run.removed),
            }
        )
        return
    _console().print(
        _table(run.rows(), f"scanclique map {run.label}", ("Metric", "Value", "Units"))
    )


def evaluate_cmd(
    trajectory: Annotated[
        Path,
        typer.Argument(
            help="A TUM trajectory (timestamp x y z qx qy qz qw): scanclique map's "
            "trajectory.tum, or another system's.",
            dir_okay=False,
        ),
    ],
    relations: Annotated[
        str,
        typer.Argument(
            help="A relations file of the SLAM benchmark (t1 t2 x y z roll pitch yaw), or "
            "a registered log with relations (intel, fr079)."
        ),
    ],
    log: Annotated[
        str | None,
        typer.Option(
            "--log",
            help="The log the trajectory is of: its laser lines say where the laser sits on "
            "the robot, whose frame the relations refer to (default: the registered log "
            "named by RELATIONS).",
        ),
    ] = None,
    mounting: Annotated[
        str | None,
        typer.Option(
            "--mounting",
            help="The robot's frame in the trajectory's, 'x,y,theta' (m, m, rad); '0,0,0' "
            "for a trajectory of the robot's own poses. Overrides --log.",
        ),
    ] = None,
    short: Annotated[
        float,
        typer.Option("--short", min=0.0, help="Relations spanning at most this are short (s)."),
    ] = 10.0,
    json_out: JsonOpt = False,
) -> None:
    """Score a trajectory by the relation metric of the SLAM benchmark (Kuemmerle et al.
    2009): the error of every relation, mean and standard deviation, absolute and squared,
    and split into short and long relations.

    Each relation's poses are the trajectory's at its two times: the row at that time, or
    interpolated between rows at most 1 s apart; a relation with a time outside the
    trajectory is counted as missing.

    **Examples**

    ```
    scanclique map fr079 --out runs/fr079 && scanclique evaluate runs/fr079/trajectory.tum fr079
    scanclique evaluate runs/aces/trajectory.tum aces.relations --log aces.clf
    scanclique evaluate cartographer.tum intel.relations --mounting 0,0,0 --json
    ```
    """
    from ..mapping.evaluate import run_evaluate

    pose = None
    if mounting is not None:
        pose = _guard(lambda: _parse_mounting(mounting))
    run = _guard(
        lambda: run_evaluate(trajectory, relations, log=log, mounting=pose, short_seconds=short)
    )
    if json_out:
        _print_json(run.to_dict())
        return
    _console().print(
        _table(
            run.table_rows(), f"scanclique evaluate {trajectory.name}", ("Metric", "Value", "Units")
        )
    )


def _parse_mounting(text: str):
    """``'x,y,theta'`` (m, m, rad) as a Pose2; an ArgumentError naming the option else."""
    import math

    from ..errors import ArgumentError
    from ..geometry import Pose2
    from ..io.text import plain_float

    parts = text.replace(" ", "").split(",")
    try:  # plain ASCII numbers, as every number field of the readers
        values = [plain_float(p) for p in parts]
    except ValueError:
        values = []
    if len(values) != 3 or not all(math.isfinite(v) for v in values):
        raise ArgumentError(f"--mounting expects three finite numbers x,y,theta, got {text!r}")
    return Pose2(*values)


def register(app: typer.Typer) -> None:
    """Add ``scanclique map`` and ``scanclique evaluate`` to ``app``."""
    app.command("map")(map_cmd)
    app.command("evaluate")(evaluate_cmd)
