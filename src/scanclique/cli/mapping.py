"""The ``scanclique map`` command: map a whole log (issue 12).

The work is :func:`scanclique.mapping.run.run_map`; this module only parses arguments and
prints. Heavy imports happen inside the command.
"""

from __future__ import annotations

import sys
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


def register(app: typer.Typer) -> None:
    """Add ``scanclique map`` to ``app``."""
    app.command("map")(map_cmd)
