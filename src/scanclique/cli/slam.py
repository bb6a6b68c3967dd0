"""The ``scanclique slam`` command: EKF-SLAM with batch association on Victoria Park or
a landmark log in plain text."""

from __future__ import annotations

import sys
from typing import Annotated

import typer

from . import (
    AppConfigOpt,
    JsonOpt,
    SaveConfigOpt,
    _check_out_dir,
    _check_out_file,
    _console,
    _err_console,
    _fail,
    _guard,
    _invocation,
    _note,
    _print_json,
    _read_app_config,
    _save_config,
    _table,
)

METHODS = ("clique", "clique-jcbb", "jcbb", "nn")


def slam(
    data: Annotated[
        str,
        typer.Argument(
            help="'victoria-park' (in the shared data directory) or its directory, or a "
            "landmark log: a directory with controls.txt (time c1 c2; or odometry.txt, "
            "time x y theta, for a unicycle) and observations.txt (time range bearing "
            "[attribute]), optionally truth.txt "
            "(time x y theta), landmarks.txt (x y), gps.txt (time x y) and model.toml "
            "(kind = 'unicycle' or 'ackermann' and its parameters)."
        ),
    ] = "victoria-park",
    association: Annotated[
        str, typer.Option("--association", "-a", help="clique, clique-jcbb (hybrid), jcbb or nn.")
    ] = "clique",
    out: Annotated[
        str | None,  # not a Path: Path('') is '.', and an empty --out must be refused
        typer.Option(
            "--out", help="Directory for trajectory.tum, landmarks.csv, report.json, map.png."
        ),
    ] = None,
    clutter: Annotated[
        int,
        typer.Option(
            "--clutter",
            min=0,
            max=100,  # scanclique.slam.run.MAX_CLUTTER (not imported here: light CLI)
            help="Spurious detections added per scan (benchmark; at most 100).",
        ),
    ] = 0,
    seed: Annotated[int, typer.Option("--seed", min=0, help="Seed of the clutter.")] = 0,
    plot: Annotated[
        bool | None,
        typer.Option(
            "--plot/--no-plot",
            help="Write map.png (landmarks, trajectory, GPS) into --out: the default when "
            "--out is given.",
        ),
    ] = None,
    smooth: Annotated[
        bool,
        typer.Option(
            "--smooth",
            help="Also smooth the run (GTSAM pose graph with the filter's associations); "
            "its metrics are added as 'smoothed ...' beside the filter's.",
        ),
    ] = False,
    config: AppConfigOpt = None,
    save_config: SaveConfigOpt = None,
    json_out: JsonOpt = False,
) -> None:
    """EKF-SLAM of point landmarks (Victoria Park's trees, or one's own landmark log),
    each scan associated with the map as a whole.

    Association by the maximum clique of the correspondence graph between the scan's trees
    and the predicted map (paper section 2 and 5), or by JCBB or nearest neighbour. Ends
    with a Metric / Value / Units table (GPS error in both alignments, or the error
    against a landmark log's truth.txt; landmarks, duplicates, association time).

    **Examples**

    ```
    scanclique slam victoria-park --association clique --out runs/vp   # map.png too
    scanclique slam victoria-park -a jcbb --out runs/vp-jcbb --no-plot
    scanclique slam victoria-park --association jcbb --json
    scanclique slam /data/victoria-park -a nn --clutter 5
    scanclique slam victoria-park -a clique --smooth
    scanclique slam runs/my-robot --out runs/mine   # controls.txt, observations.txt, truth.txt
    scanclique config --for slam > slam.toml     # every key of SlamConfig, to edit
    scanclique slam victoria-park -c slam.toml --save-config used.toml
    ```
    """
    if association not in METHODS:
        raise _fail(f"--association must be one of {', '.join(METHODS)}, got {association!r}")
    if plot and out is None:
        raise _fail("--plot writes map.png into --out: give --out DIR")
    plot = out is not None if plot is None else plot
    from ..slam import SlamConfig
    from ..slam.run import output_names, run_slam

    if out is not None:
        _check_out_dir(out, output_names(plot, smooth))  # before the run, not after it
    if save_config is not None:
        _check_out_file(save_config, out_dir=out)  # may go into a new --out

    cfg = _read_app_config(config, SlamConfig())

    show = not json_out and sys.stderr.isatty()

    def work():
        kw = dict(
            association=association, out=out, clutter=clutter, seed=seed, plot=plot, config=cfg
        )
        if not show:
            return run_slam(data, smooth=smooth, **kw)
        from rich.progress import Progress

        with Progress(console=_err_console(), transient=True) as bar:
            task = bar.add_task(f"EKF-SLAM ({association})", total=1)

            def progress(done, total):
                bar.update(task, completed=done, total=total)

            return run_slam(data, smooth=smooth, progress=progress, **kw)

    run = _guard(work)
    for f in run.removed:
        _note(f"removed {f}: an earlier run's figure (this run drew none; --plot draws one)")
    if save_config is not None:
        _save_config(cfg, save_config, f"used by: {_invocation()}")
    if json_out:
        _print_json(run.to_dict())
        return
    rows = []
    for name, (value, units) in run.metrics.items():
        v = f"{value:.3f}" if isinstance(value, float) else str(value)
        rows.append((name, v, units))
    for name, path in run.files.items():
        rows.append((f"file: {name}", str(path), ""))
    _console().print(
        _table(rows, f"EKF-SLAM on {data} ({association})", ("Metric", "Value", "Units"))
    )


def register(app: typer.Typer) -> None:
    app.command("slam")(slam)
