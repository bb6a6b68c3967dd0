"""The ``scanclique validate`` command: the confusion table of a log's pair sets (paper §7)."""

from __future__ import annotations

import math
import sys
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
    _console,
    _err_console,
    _guard,
    _noise,
    _note,
    _print_json,
    _table,
)


def validate(
    source: Annotated[
        str, typer.Argument(help="A log with reference poses (CARMEN, .npz, text) or intel.")
    ],
    cap: Annotated[
        int, typer.Option("--cap", min=0, help="At most this many pairs per set (0: all).")
    ] = 50,
    sets: Annotated[
        list[str] | None,
        typer.Option("--set", help="consecutive, skip3 or revisit (repeat; default all)."),
    ] = None,
    odometry: Annotated[
        bool,
        typer.Option("--odometry/--no-odometry", help="Use the log's odometry (default yes)."),
    ] = True,
    odom_per_metre: PerMetreOpt = None,
    odom_per_radian: PerRadianOpt = None,
    config: ConfigOpt = None,
    paper: PaperOpt = False,
    max_range: MaxRangeOpt = None,
    max_beams: MaxBeamsOpt = None,
    json_out: JsonOpt = False,
) -> None:
    """Match and validate the pair sets of a log; print the confusion table.

    The pair sets are consecutive scans, scans three apart and revisits (scans at least
    50 apart that see the same place). A verdict's pose is right when within 0.2 m and
    2 deg of the reference; the table counts right and wrong poses by verdict, with the
    precision (right accepted / accepted) and recall (right accepted / right) of
    accepted.

    **Examples**

    ```
    scanclique validate intel                 # 50 pairs per set, with odometry
    scanclique validate csail --cap 0 --set consecutive
    scanclique validate intel --no-odometry --json
    ```
    """
    from ..tools import confusion_rows, load_config, run_validate

    cfg = _guard(lambda: load_config(config, paper))
    noise = _noise(odom_per_metre, odom_per_radian)
    from rich.progress import Progress

    # no bar when stderr is not a terminal: it would leave an empty line there
    quiet = json_out or not sys.stderr.isatty()
    with Progress(console=_err_console(), transient=True, disable=quiet) as bar:
        task = bar.add_task("matching", total=None)

        def tick(done: int, total: int) -> None:
            bar.update(task, completed=done, total=total)

        run = _guard(
            lambda: run_validate(
                source,
                cap=None if cap == 0 else cap,
                sets=sets or None,
                odometry=odometry,
                noise=noise,
                config=cfg,
                progress=tick,
                max_range=max_range,
                max_beams=max_beams,
            )
        )
    if json_out:
        _print_json(run.to_dict())
        return
    for n in run.notes:
        _note(n)
    con = _console()
    columns = ("Pose", "accepted", "rejected", "odometry", "ambiguous", "too few")
    what = "with odometry" if odometry else "without odometry"
    for set_name in sorted({r["set"] for r in run.records}):
        c = run.counts(set_name)
        con.print(_table(confusion_rows(run, set_name), f"{run.name} {set_name} ({what})", columns))
        con.print(_summary(c), soft_wrap=True)
    c = run.counts()
    con.print(_table(confusion_rows(run), f"{run.name}: all pairs ({what})", columns))
    con.print(_summary(c), soft_wrap=True)
    con.print(
        "right: the verdict's pose is within 0.2 m and 2 deg of the reference; rejected = "
        "rejected_odometry (odometry) + ambiguous + too_few_features (too few)",
        soft_wrap=True,
    )


def _summary(c: dict) -> str:
    return (
        f"{c['n']} pairs: precision of accepted {_pct(c['precision'])}, recall "
        f"{_pct(c['recall'])}; odometry turned {c['ambiguous_to_right']} of "
        f"{c['ambiguous']} ambiguous matches into a right accepted pose"
    )


def _pct(v: float) -> str:
    return "n/a" if not math.isfinite(v) else f"{100 * v:.1f} %"


def register(app: typer.Typer) -> None:
    """Add ``scanclique validate`` to ``app``."""
    app.command()(validate)
