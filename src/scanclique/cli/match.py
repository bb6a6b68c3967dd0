"""The ``scanclique match`` command: match scan B against scan A (paper §5-§7)."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from . import (
    ConfigOpt,
    JsonOpt,
    MaxBeamsOpt,
    MaxRangeOpt,
    PaperOpt,
    PerMetreOpt,
    PerRadianOpt,
    _check_out_file,
    _check_plot_path,
    _console,
    _guard,
    _invocation,
    _noise,
    _note,
    _plot_module,
    _print_json,
    _save_config,
    _table,
)


def match(
    source: Annotated[
        str,
        typer.Argument(
            help="A log (CARMEN, .npz, scan text) or data set name (intel); or scan file A."
        ),
    ],
    a: Annotated[
        str | None,
        typer.Argument(help="Index of scan A in the log; or scan file B.", show_default=False),
    ] = None,
    b: Annotated[
        str | None, typer.Argument(help="Index of scan B in the log.", show_default=False)
    ] = None,
    config: ConfigOpt = None,
    paper: PaperOpt = False,
    plot: Annotated[
        Path | None,
        typer.Option("--plot", help="Write the figure (paper Fig. 8-10) here (.png/.pdf/.svg)."),
    ] = None,
    save_config: Annotated[
        Path | None, typer.Option("--save-config", help="Write the configuration used (TOML).")
    ] = None,
    odometry: Annotated[
        bool,
        typer.Option(
            "--odometry",
            help="Validate the pose against the scans' odometry (paper §7): Mahalanobis gate.",
        ),
    ] = False,
    odom_per_metre: PerMetreOpt = None,
    odom_per_radian: PerRadianOpt = None,
    max_range: MaxRangeOpt = None,
    max_beams: MaxBeamsOpt = None,
    json_out: JsonOpt = False,
) -> None:
    """Match scan B against scan A: feature mapping (maximum clique), pose and verdict.

    The pose maps points of B into A's frame: p_a = R(theta) p_b + (x, y). When both scans
    carry reference poses the table adds the reference relative pose and the errors. The
    verdict (accepted, rejected_odometry, ambiguous, too_few_features) judges the match on
    its features alone, or with --odometry also against the odometry of the log (the
    distance travelled summed over the scans in between).

    **Examples**

    ```
    scanclique match intel 120 125          # data set name, 2 indices
    scanclique match path/to/intel-odometry.log.gz 120 121
    scanclique match a.txt b.txt            # one scan per file
    scanclique match intel 120 125 --plot match.png
    scanclique match intel 120 125 --paper --json
    scanclique match intel 0 5 -c my.toml --save-config used.toml
    scanclique match intel 120 125 --odometry
    scanclique match csail 10 11 --odometry --odom-per-radian 0.3
    ```
    """
    from ..tools import load_config, match_rows, run_match

    _check_plot_path(plot)
    if save_config is not None:
        _check_out_file(save_config)  # before the match, not after it
    cfg = _guard(lambda: load_config(config, paper))
    noise = _noise(odom_per_metre, odom_per_radian)
    run = _guard(
        lambda: run_match(
            source,
            a,
            b,
            cfg,
            odometry=odometry,
            noise=noise,
            max_range=max_range,
            max_beams=max_beams,
        )
    )
    for n in run.notes:
        _note(n)
    if save_config is not None:
        _save_config(cfg, save_config, f"used by: {_invocation()}")
    if json_out:
        _print_json(run.to_dict())
    else:
        _console().print(
            _table(
                match_rows(run),
                f"B = {run.names[1]} matched against A = {run.names[0]}",
                ("Metric", "Value", "Units"),
            )
        )
    if plot is not None:
        p = _plot_module()
        _guard(
            lambda: p.plot_match(
                run.scan_a, run.scan_b, run.match, plot, reference=run.reference, names=run.names
            )
        )
        if not json_out:
            _console().print(f"wrote {plot}")


def register(app: typer.Typer) -> None:
    """Add ``scanclique match`` to ``app``."""
    app.command()(match)
