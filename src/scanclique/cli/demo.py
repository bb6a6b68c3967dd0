"""The ``scanclique demo`` command: one scan pair, its table, error and figure."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from . import (
    ConfigOpt,
    PaperOpt,
    _check_plot_path,
    _console,
    _guard,
    _plot_module,
    _table,
)


def demo(
    plot: Annotated[Path, typer.Option("--plot", help="Where to write the figure.")] = Path(
        "match.png"
    ),
    config: ConfigOpt = None,
    paper: PaperOpt = False,
) -> None:
    """Match one scan pair, print the table and the error, and draw it.

    Intel scans 120 and 121 when the Intel log is found (SCANCLIQUE_DATA, default
    ../shared/data); else a simulated pair whose true pose is known.

    **Examples**

    ```
    scanclique demo
    scanclique demo --plot /tmp/match.png
    SCANCLIQUE_DATA=/nonexistent scanclique demo  # simulated
    ```
    """
    from .. import datasets
    from ..tools import DEMO_INDICES, DEMO_SEED, load_config, match_rows, run_demo

    _check_plot_path(plot)
    cfg = _guard(lambda: load_config(config, paper))
    con = _console()
    run = _guard(lambda: run_demo(cfg))
    real = run.names[0].startswith("intel")
    if real:
        where = datasets.dataset_path("intel")
        con.print(
            f"Intel Research Lab log, scans {DEMO_INDICES[0]} and {DEMO_INDICES[1]} ({where})",
            soft_wrap=True,
        )
    else:
        looked = ", ".join(map(str, datasets.data_dir_candidates()))
        con.print(
            f"no real data found in {looked} (set {datasets.ENV_VAR}): "
            f"simulated pair, simulate_pair(default_rng({DEMO_SEED}))",
            soft_wrap=True,
        )
    con.print(
        _table(
            match_rows(run),
            f"B = {run.names[1]} matched against A = {run.names[0]}",
            ("Metric", "Value", "Units"),
        )
    )
    p = _plot_module()
    _guard(
        lambda: p.plot_match(
            run.scan_a, run.scan_b, run.match, plot, reference=run.reference, names=run.names
        )
    )
    con.print(f"wrote {plot}")
    con.print(run.verdict("reference" if real else "known pose"), soft_wrap=True)
    if run.match.pose is None:
        raise typer.Exit(1)


def register(app: typer.Typer) -> None:
    """Add ``scanclique demo`` to ``app``."""
    app.command()(demo)
