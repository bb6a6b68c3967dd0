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
    file: Annotated[
        Path,
        typer.Argument(
            help="A DIMACS .clq graph (p edge N M; e u v); a bare name not found here is "
            "looked up among the shared data's DIMACS graphs."
        ),
    ],
    all_: Annotated[
        bool, typer.Option("--all", help="Also enumerate every maximum clique (up to 1000).")
    ] = False,
    time_limit: Annotated[
        float | None,
        typer.Option(
            "--time-limit", min=0.0, help="Seconds; past it the best clique so far (optimal: no)."
        ),
    ] = None,
    node_limit: Annotated[
        int | None,
        typer.Option(
            "--node-limit",
            min=1,
            help="Search nodes; past it the best clique so far (optimal: no). The same on "
            "every machine, unlike --time-limit.",
        ),
    ] = None,
    weights: Annotated[
        bool | None,
        typer.Option(
            "--weights/--no-weights",
            show_default=False,
            help="Use the file's vertex weights ('n v w' lines: maximum-weight clique) or "
            "ignore them (default: use them when the file has any).",
        ),
    ] = None,
    json_out: JsonOpt = False,
) -> None:
    """Maximum clique of a DIMACS graph with the library's exact solver (paper §5.3).

    With vertex weights in the file the clique of largest total weight is found (unless
    --no-weights).

    **Examples**

    ```
    scanclique clique brock200_2.clq
    scanclique clique MANN_a27.clq --time-limit 5
    scanclique clique graph.clq --all --json
    ```
    """
    from ..clique import solve_file
    from ..errors import GraphError

    file = _shared_graph(file)

    def solve():
        try:
            return solve_file(
                file, all=all_, time_limit=time_limit, node_limit=node_limit, weights=weights
            )
        except GraphError as exc:  # max_vertices= is the library's; the command has the variable
            msg = str(exc).replace("pass max_vertices= or set ", "set ")
            raise GraphError(msg) from None

    res = _guard(solve)
    if json_out:
        _print_json(res)
        return
    optimal = res["optimal"]
    why = {"node_limit": "node limit", "time_limit": "time limit"}.get(res.get("reason"), "")
    rows = [("graph", f"{res['n']} vertices, {res['m']} edges", "")]
    if res.get("weighted"):
        what = "maximum-weight clique" if optimal else "heaviest clique found"
        rows.append((what, f"{res['size']} vertices, weight {res['weight']:g}", ""))
    elif optimal:
        rows.append(("ω (clique number)", str(res["omega"]), "vertices"))
    else:
        rows.append(("largest clique found", str(res["size"]), "vertices"))
    rows += [
        ("optimal", "yes" if optimal else f"no ({why or 'search cut short'})", ""),
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


def _shared_graph(file: Path) -> Path:
    """``file``, or the shared data's DIMACS graph of that name when ``file`` is a bare
    name that does not exist here (``scanclique clique brock200_2.clq`` from anywhere)."""
    if file.exists() or file.parent != Path("."):
        return file
    from ..datasets import dimacs_dir
    from ..errors import DataNotFoundError

    try:
        shared = dimacs_dir() / file.name
    except DataNotFoundError:
        return file
    return shared if shared.is_file() else file


def register(app: typer.Typer) -> None:
    """Add ``scanclique clique`` to ``app``."""
    app.command()(clique)
