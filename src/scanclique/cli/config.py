"""The ``scanclique config`` command: print a configuration as TOML."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from . import _fail, _save_config

FOR = ("match", "map", "slam")


def config_cmd(
    paper: Annotated[
        bool, typer.Option("--paper", help="The paper's configuration (match only).")
    ] = False,
    default: Annotated[
        bool, typer.Option("--default", help="This library's defaults (the default).")
    ] = False,
    for_: Annotated[
        str,
        typer.Option(
            "--for",
            help="Whose configuration: match (MatchConfig), map (MapConfig, the mapper's: "
            "its [match] table is the matcher's) or slam (SlamConfig).",
        ),
    ] = "match",
    output: Annotated[
        Path | None, typer.Option("--output", "-o", help="Write to this file instead of stdout.")
    ] = None,
) -> None:
    """Print a configuration as TOML, to edit and pass back with --config.

    **Examples**

    ```
    scanclique config --default > my.toml
    scanclique config --paper > paper.toml
    scanclique match intel 120 125 --config my.toml
    scanclique config --for map > map.toml
    scanclique map intel --out runs/intel --config map.toml
    scanclique config --for slam -o slam.toml
    ```
    """
    if paper and default:
        raise _fail("--paper and --default exclude each other: give one")
    if for_ not in FOR:
        raise _fail(f"--for must be one of {', '.join(FOR)}, got {for_!r}")
    if paper and for_ != "match":
        raise _fail(f"--paper is the matcher's configuration: use it without --for {for_}")
    from ..io.config import dumps_config

    if for_ == "map":
        from ..mapping import MapConfig

        cfg, comment = MapConfig(), "defaults (MapConfig())"
    elif for_ == "slam":
        from ..slam import SlamConfig

        cfg, comment = SlamConfig(), "defaults (SlamConfig(): Victoria Park's)"
    else:
        from ..config import MatchConfig, paper_config

        cfg = paper_config() if paper else MatchConfig()
        comment = (
            "the paper's configuration (paper_config())" if paper else "defaults (MatchConfig())"
        )
    if output is not None:
        _save_config(cfg, output, comment)
    else:
        typer.echo(dumps_config(cfg, comment), nl=False)


def register(app: typer.Typer) -> None:
    """Add ``scanclique config`` to ``app``."""
    app.command("config")(config_cmd)
