"""The ``scanclique config`` command: print a configuration as TOML."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from . import (
    _save_config,
)


def config_cmd(
    paper: Annotated[
        bool,
        typer.Option(
            "--paper/--default", help="The paper's configuration, or this library's defaults."
        ),
    ] = False,
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
    ```
    """
    from ..config import MatchConfig, paper_config
    from ..io.config import dumps_config

    cfg = paper_config() if paper else MatchConfig()
    comment = "the paper's configuration (paper_config())" if paper else "defaults (MatchConfig())"
    if output is not None:
        _save_config(cfg, output, comment)
    else:
        typer.echo(dumps_config(cfg, comment), nl=False)


def register(app: typer.Typer) -> None:
    """Add ``scanclique config`` to ``app``."""
    app.command("config")(config_cmd)
