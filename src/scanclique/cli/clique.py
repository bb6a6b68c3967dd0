"""The ``scanclique clique`` command: maximum clique of a DIMACS graph (paper §5.3)."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from . import (
    JsonOpt,
    _console,
    _guard,
    _print_json,
    _table,
)


def clique(
    file: Annotated[Path, typer.Argument(help="A DIMACS .clq graph (p edge N M; e u v).")],
    all_: Annotated[
        bool, typer.Option("--all", help="Also enumerate every maximum clique (up to 1000).")
    ] = False,
    time_limit: Annotated[
        float | None,
        typer.Option(
            "--time-limit", min=0.0, help="Seconds; past it the best clique so far (optimal: no)."
        ),
    ] = None,
    json_out: JsonOpt = False,
) -> None:
    """Maximum clique of a DIMACS graph with the library's exact solver (paper §5.3).

    **Examples**

    ```
    scanclique clique brock200_2.clq
    scanclique clique MANN_a27.clq --time-limit 5
    scanclique clique graph.clq --all --json
    ```
    """
    from ..clique import solve_file

    res = _guard(lambda: solve_file(file, all=all_, time_limit=time_limit))
    if json_out:
        _print_json(res)
        return
    rows = [
        ("graph", f"{res['n']} vertices, {res['m']} edges", ""),
        ("ω (clique number)", str(res["omega"]), "vertices"),
        ("optimal", "yes" if res["optimal"] else "no (time limit)", ""),
        ("clique", " ".join(map(str, res["clique"])), "1-based"),
        ("search nodes", str(res["nodes"]), ""),
        ("search time", f"{1e3 * res['elapsed']:.1f}", "ms"),
        ("compiled kernels loaded in", f"{1e3 * res['load']:.0f}", "ms"),
    ]
    if all_:
        rows.insert(
            3,
            (
                "maximum cliques",
                str(len(res["cliques"])) + ("" if res["complete"] else " (incomplete)"),
                "",
            ),
        )
    _console().print(_table(rows, f"maximum clique of {file}", ("Metric", "Value", "Units")))


def register(app: typer.Typer) -> None:
    """Add ``scanclique clique`` to ``app``."""
    app.command()(clique)
