"""The ``scanclique features`` command: the features of one scan (paper §4)."""

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
    _check_plot_path,
    _console,
    _guard,
    _note,
    _plot_module,
    _print_json,
    _table,
)


def features(
    source: Annotated[str, typer.Argument(help="A log or scan file, or a data set name (intel).")],
    index: Annotated[
        int | None, typer.Argument(help="Scan index (default: the first scan).", show_default=False)
    ] = None,
    config: ConfigOpt = None,
    paper: PaperOpt = False,
    plot: Annotated[
        Path | None, typer.Option("--plot", help="Write the features figure (paper Fig. 8) here.")
    ] = None,
    max_range: MaxRangeOpt = None,
    max_beams: MaxBeamsOpt = None,
    json_out: JsonOpt = False,
) -> None:
    """Extract the features of one scan (paper §4): counts per kind and a table.

    Point features (foreground points, foreground edges cw/ccw, corners) are listed by
    position (sensor frame, metres); lines in Hesse normal form
    x cos(alpha) + y sin(alpha) = rho.

    **Examples**

    ```
    scanclique features intel 120
    scanclique features intel 120 --plot features.png
    scanclique features scan.txt --json
    ```
    """
    from ..features import extract_features
    from ..tools import feature_rows, features_to_dict, load_config, load_scan
    from ..tools.loading import read_options

    _check_plot_path(plot)
    cfg = _guard(lambda: load_config(config, paper))
    opts = read_options(max_range, max_beams)
    scan, name, notes = _guard(lambda: load_scan(source, index, **opts))
    for n in notes:
        _note(n)
    feats = extract_features(scan, cfg.features, cfg.clustering)
    if json_out:
        _print_json(
            {
                "scan": name,
                "source": scan.source,
                "range_max": scan.range_max,
                "notes": notes,
                **features_to_dict(feats),
            }
        )
    else:
        con = _console()
        counts = [(k.replace("_", " "), str(v)) for k, v in feats.counts().items()]
        counts.append(("total", str(len(feats))))
        counts.append(("valid beams", f"{scan.n_valid}/{scan.n_beams}"))
        counts.append(("no return at or beyond", f"{scan.range_max:g} m"))
        con.print(_table(counts, f"features of {name}", ("Kind", "Count")))
        if len(feats):
            con.print(
                _table(
                    feature_rows(feats),
                    "features (sensor frame)",
                    ("#", "Kind", "x / rho [m]", "y [m] / alpha", "Length [m]", "Beams"),
                )
            )
    if plot is not None:
        p = _plot_module()

        def draw():
            ax = p.plot_features(scan, feats, title=f"{name}: {len(feats)} features")
            p.save_figure(ax.figure, plot)
            p._pyplot().close(ax.figure)

        _guard(draw)
        if not json_out:
            _console().print(f"wrote {plot}")


def register(app: typer.Typer) -> None:
    """Add ``scanclique features`` to ``app``."""
    app.command()(features)
