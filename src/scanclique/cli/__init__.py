"""The ``scanclique`` command: a thin shell over the library layer :mod:`scanclique.tools`.

This module holds the typer ``app``, its options and the printing helpers; each command
lives in a module of this package (``match``, ``features``, ``clique``, ``demo``,
``validate``, ``config`` and the applications' modules listed in :data:`COMMAND_MODULES`)
that defines ``register(app)``. The work of a command is a plain function of
:mod:`scanclique.tools` (or of an application package) that scripts call without typer
or rich; the old names (``scanclique.cli.run_match`` and the rest) still resolve here,
loaded on first use. Errors a user can cause (a missing file, a scan index out of range,
a malformed configuration) end the command with one ``error:`` line on stderr and exit
code 2, never a traceback.

At module level this package and every command module import only typer, rich, the
standard library and ``scanclique.errors``, so that ``scanclique --help`` and
``--version`` load no NumPy kernels and no numba.
"""

from __future__ import annotations

import importlib
import json
import logging
import os
import sys
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Annotated, Any

import typer
from rich.console import Console
from rich.table import Table

from .. import __version__
from ..errors import ScanCliqueError, ScanIndexError

log = logging.getLogger(__name__)

#: Names of the library layer kept importable from here for old scripts
#: (``from scanclique.cli import run_match``); they live in :mod:`scanclique.tools`.
_TOOLS = frozenset(
    {
        "MatchRun",
        "ValidateRun",
        "load_scan",
        "load_scan_pair",
        "load_config",
        "run_match",
        "run_demo",
        "run_validate",
        "odometry_path",
        "validation_rows",
        "confusion_rows",
        "match_rows",
        "feature_rows",
        "features_to_dict",
        "KINDS",
        "SUCCESS_TRANSLATION",
        "SUCCESS_ROTATION_DEG",
        "DEMO_INDICES",
        "DEMO_SEED",
    }
)

__all__ = ["ScanIndexError", *sorted(_TOOLS), "app", "main", "COMMAND_MODULES"]


def __getattr__(name: str) -> Any:
    if name in _TOOLS:
        from .. import tools

        return getattr(tools, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


# ---------------------------------------------------------------------------------------
# Printing
# ---------------------------------------------------------------------------------------
def _console() -> Console:
    """stdout, plain text: no markup, so ``[m]`` and file names print as they are."""
    return Console(highlight=False, markup=False)


def _err_console() -> Console:
    return Console(stderr=True, highlight=False)


def _print_json(obj: Any) -> None:
    from ..tools.jsonable import clean_json

    typer.echo(json.dumps(clean_json(obj), indent=2, allow_nan=False))


def _table(rows: Sequence[Sequence[str]], title: str, columns: Sequence[str]) -> Table:
    """A rich table, for the plain-text console of :func:`_console`."""
    t = Table(title=title, title_justify="left")
    for i, c in enumerate(columns):
        t.add_column(c, justify="right" if i == 1 and len(columns) == 3 else "left")
    for r in rows:
        t.add_row(*(str(c) for c in r))
    return t


def _note(msg: str) -> None:
    _err_console().print(f"[yellow]note:[/yellow] {_escape(msg)}", soft_wrap=True)


def _fail(msg: str, code: int = 2) -> typer.Exit:
    _err_console().print(f"[bold red]error:[/bold red] {msg}", soft_wrap=True, markup=True)
    return typer.Exit(code)


def _guard(fn: Callable[[], Any]) -> Any:
    """Run ``fn``; errors a user can cause become one line on stderr and exit code 2."""
    try:
        return fn()
    except (ScanCliqueError, IndexError) as exc:
        raise _fail(_escape(str(exc))) from None
    except OSError as exc:
        where = f"{exc.filename}: " if getattr(exc, "filename", None) else ""
        raise _fail(_escape(f"{where}{exc.strerror or exc}")) from None


def _escape(s: str) -> str:
    from rich.markup import escape

    return escape(s)


def _plot_module():
    try:
        from .. import plot
    except ImportError as exc:  # pragma: no cover - matplotlib missing
        raise _fail(f"plotting needs matplotlib ({exc}): pip install 'scanclique[plot]'") from None
    try:
        import matplotlib  # noqa: F401
    except ImportError as exc:  # pragma: no cover
        raise _fail(f"plotting needs matplotlib ({exc}): pip install 'scanclique[plot]'") from None
    return plot


def _check_plot_path(path: Path | None) -> None:
    """Refuse a ``--plot`` path before any work (see
    :func:`scanclique.plot.check_figure_path`): one ``error:`` line, exit code 2."""
    if path is None:
        return
    from ..plot import check_figure_path

    _guard(lambda: check_figure_path(path))


def _check_out_dir(path: str | os.PathLike, files: Sequence[str] = ()) -> None:
    """Refuse an output directory (``--out``) before any work: one ``error:`` line, exit
    code 2. It may exist (the command's files in it are replaced, with a ``note:`` when it
    is not empty) or not yet (it is created with its parents when the results are written).
    It may not be empty text (which named the current directory), nor hold anything but a
    regular file under one of the names ``files`` the command writes (a directory there
    failed only when the results were written, after the whole run)."""
    if os.fspath(path) == "":
        raise _fail("--out is empty: give the output directory ('.' for this one)")
    p = Path(path)
    try:
        _check_existing_out_dir(p, files)
    except OSError as exc:  # a name too long, a loop of links, ...
        raise _fail(_escape(f"{p}: {exc.strerror or exc}")) from None


def _check_existing_out_dir(p: Path, files: Sequence[str]) -> None:
    """:func:`_check_out_dir`'s checks of a path that may exist."""
    if p.exists():
        if not p.is_dir():
            raise _fail(_escape(f"{p}: exists and is not a directory (--out names a directory)"))
        if not os.access(p, os.W_OK | os.X_OK):
            raise _fail(_escape(f"{p}: the directory is not writable"))
        for name in files:
            f = p / name
            if (f.exists() or f.is_symlink()) and not f.is_file():
                what = "a directory" if f.is_dir() else "not a regular file"
                raise _fail(_escape(f"{f}: is {what}: this command writes its {name} there"))
        if any(p.iterdir()):
            _note(f"{p} is not empty: the files this command writes there are replaced")
        return
    ancestor = p.absolute().parent
    while not ancestor.exists() and ancestor != ancestor.parent:
        ancestor = ancestor.parent
    if not ancestor.is_dir():
        raise _fail(_escape(f"{p}: cannot be created: {ancestor} is not a directory"))
    if not os.access(ancestor, os.W_OK | os.X_OK):
        raise _fail(_escape(f"{p}: cannot be created: {ancestor} is not writable"))


def _check_out_file(
    path: str | os.PathLike,
    out_dir: str | os.PathLike | None = None,
    log: str | os.PathLike | None = None,
) -> None:
    """Refuse an output file (``loops --out``, a new place database, ``--save-config``)
    before any work: one ``error:`` line, exit code 2. Its directory must exist (it is not
    created), unless it is ``out_dir``, the command's ``--out`` (checked by
    :func:`_check_out_dir` and created by the run before the file is written). It must not
    be the input ``log`` (a path or a registered name), which writing would destroy."""
    p = Path(path)
    if p.is_dir():
        raise _fail(_escape(f"{p}: is a directory, not a file"))
    if log is not None and p.exists():
        from ..datasets import resolve_log
        from ..errors import ScanCliqueError

        try:
            source = resolve_log(log)
            same = source.exists() and os.path.samefile(source, p)
        except (ScanCliqueError, OSError):
            same = False  # a log that cannot be found is said so by the reader
        if same:
            raise _fail(_escape(f"{p}: is the input log {log}; it would be overwritten"))
    parent = p.absolute().parent
    if out_dir is not None and os.path.abspath(parent) == os.path.abspath(out_dir):
        return
    if not parent.is_dir():
        raise _fail(_escape(f"{p}: directory {p.parent} does not exist (it is not created)"))


def _save_config(cfg: Any, path: Path, comment: str) -> None:
    from ..io.config import write_config

    _guard(lambda: write_config(path, cfg, comment=comment))
    _note(f"configuration written to {path}")


def _read_app_config(path: Path | None, default: Any) -> Any:
    """The configuration of a ``map`` / ``slam`` run: ``default`` (a ``MapConfig()`` or
    ``SlamConfig()``) with the keys of the TOML file ``path`` on top; ``default`` itself
    without a file. A bad file is one ``error:`` line naming it and the key."""
    if path is None:
        return default
    from ..io.config import read_config

    return _guard(lambda: read_config(path, base=default))


AppConfigOpt = Annotated[
    Path | None,
    typer.Option(
        "--config",
        "-c",
        help="TOML configuration: its keys override the defaults ('scanclique config --for "
        "map' or '--for slam' prints every key).",
        dir_okay=False,
    ),
]
SaveConfigOpt = Annotated[
    Path | None,
    typer.Option("--save-config", help="Write the configuration used (TOML).", dir_okay=False),
]


def _invocation() -> str:
    return "scanclique " + " ".join(sys.argv[1:]) if sys.argv else "scanclique"


# ---------------------------------------------------------------------------------------
# The typer app
# ---------------------------------------------------------------------------------------
def _usage_hint(exc) -> str:
    """What to add to a usage error: a negative index is parsed as an option by click."""
    msg = exc.format_message()
    opt = getattr(exc, "option_name", "") or ""
    ctx = getattr(exc, "ctx", None)
    where = ctx.command_path if ctx is not None else "scanclique"
    if type(exc).__name__ == "NoSuchOption" and opt.lstrip("-").isdigit():
        msg = f"{opt} is not an option: scan indices start at 0 (a negative index?)"
    elif type(exc).__name__ == "NoSuchOption" and (opt == "--verbose" or opt in ("-v", "-vv")):
        # -v, -vv, --verbose belong to scanclique itself, not to a command
        sub = where.split(" ", 1)[1] if " " in where else "COMMAND"
        msg = f"{opt} goes before the command: scanclique {opt} {sub} ..."
    return f"{msg} (see '{where} -h')"


def _flag_type_hidden() -> None:
    """Plain flags show no ``<bool>`` in --help (typer prints a type for every option)."""
    from typer.core import TyperOption

    orig = TyperOption.display_type_rich
    if getattr(orig, "_scanclique", False):
        return

    def display_type_rich(self, ctx):
        if getattr(self, "is_flag", False) or getattr(self, "count", False):
            return None
        return orig(self, ctx)

    display_type_rich._scanclique = True  # type: ignore[attr-defined]
    TyperOption.display_type_rich = display_type_rich  # type: ignore[method-assign]


class _Group(typer.core.TyperGroup):
    """The ``scanclique`` group: usage errors (an unknown option, a bad value, a negative
    index) end with one ``error:`` line and exit code 2 instead of typer's box."""

    def main(self, *args, **kwargs):
        import typer.core

        click = getattr(typer.core, "_click", None)  # typer >= 0.2x vendors click
        if click is None:  # pragma: no cover - older typer on click
            import click
        abort = getattr(typer.core, "Abort", None) or click.exceptions.Abort
        _flag_type_hidden()
        kwargs["standalone_mode"] = False
        try:
            rv = super().main(*args, **kwargs)
        except abort:
            _err_console().print("error: aborted", markup=False)
            sys.exit(1)
        except click.exceptions.ClickException as exc:
            if type(exc).__name__ == "NoArgsIsHelpError":
                exc.show()  # the help text, as with --help
            else:
                msg = f"error: {_usage_hint(exc)}"
                _err_console().print(msg, soft_wrap=True, markup=False)
            sys.exit(exc.exit_code)
        sys.exit(rv if isinstance(rv, int) else 0)


app = typer.Typer(
    name="scanclique",
    cls=_Group,
    no_args_is_help=True,
    add_completion=False,
    rich_markup_mode="markdown",
    pretty_exceptions_show_locals=False,
    context_settings={"help_option_names": ["-h", "--help"]},
)


def _version(value: bool) -> None:
    if value:
        typer.echo(f"scanclique {__version__}")
        raise typer.Exit()


@app.callback()
def _main(
    verbose: Annotated[
        int,
        typer.Option("--verbose", "-v", count=True, help="Log more: -v info, -vv debug (stderr)."),
    ] = 0,
    version: Annotated[
        bool,
        typer.Option(
            "--version", callback=_version, is_eager=True, help="Print the version and exit."
        ),
    ] = False,
) -> None:
    """Graph-theoretic data association between 2D laser scans (Bailey et al., ICRA 2000):
    maximum-clique feature mapping and the relative pose, without a prior pose.

    **Examples**

    ```
    scanclique demo
    scanclique match intel 120 125
    scanclique -v match a.txt b.txt --json
    ```
    """
    level = logging.WARNING if verbose == 0 else logging.INFO if verbose == 1 else logging.DEBUG
    root = logging.getLogger("scanclique")
    root.setLevel(level)
    if not any(getattr(h, "_scanclique", False) for h in root.handlers):
        h = logging.StreamHandler(sys.stderr)
        h.setFormatter(logging.Formatter("%(levelname)s %(name)s: %(message)s"))
        # records the commands print themselves as a "note:" line (read_scans' no-return)
        h.addFilter(lambda r: not getattr(r, "user_note", False))
        h._scanclique = True  # type: ignore[attr-defined]
        root.addHandler(h)


ConfigOpt = Annotated[
    Path | None,
    typer.Option(
        "--config",
        "-c",
        help="TOML configuration (keys override the defaults / --paper).",
        dir_okay=False,
    ),
]
PaperOpt = Annotated[
    bool,
    typer.Option("--paper", help="Start from the paper's exact configuration (paper_config())."),
]
JsonOpt = Annotated[bool, typer.Option("--json", help="Print JSON only (for machines).")]
OdometryOpt = Annotated[
    bool | None,
    typer.Option(
        "--odometry/--no-odometry",
        help="--no-odometry maps from the scans alone; --odometry uses the log's "
        "odometry as it is. Default: use it when 95 % of the scans have it and a sample of "
        "matched pairs says it moves as the scans do (zeros, frozen or millimetres are "
        "set aside, with a warning).",
        show_default=False,
    ),
]
PerMetreOpt = Annotated[
    float | None,
    typer.Option(
        "--odom-per-metre",
        min=0.0,
        show_default=False,
        help="Odometry translation error per metre travelled (1 sigma, m/m; default: "
        "OdometryNoise().per_metre).",
    ),
]
PerRadianOpt = Annotated[
    float | None,
    typer.Option(
        "--odom-per-radian",
        min=0.0,
        show_default=False,
        help="Odometry heading error per radian turned (1 sigma, rad/rad; default: "
        "OdometryNoise().per_radian).",
    ),
]


MaxRangeOpt = Annotated[
    float | None,
    typer.Option(
        "--max-range",
        show_default=False,
        help="Readings at or beyond this range (m) are no return (CARMEN FLASER/RLASER; "
        "default 80, or the no-return value the log is found to use).",
    ),
]
MaxBeamsOpt = Annotated[
    int | None,
    typer.Option(
        "--max-beams",
        show_default=False,
        help="Largest beam count accepted in one message (default 100000; guards corrupt counts).",
    ),
]


def _noise(per_metre: float | None, per_radian: float | None):
    """The :class:`~scanclique.validation.OdometryNoise` of the ``--odom-*`` options
    (None: the library's default for that field)."""
    from ..validation import OdometryNoise

    kw = {}
    if per_metre is not None:
        kw["per_metre"] = per_metre
    if per_radian is not None:
        kw["per_radian"] = per_radian
    return _guard(lambda: OdometryNoise(**kw))


# ---------------------------------------------------------------------------------------
# Commands: one module of this package each, registered here
# ---------------------------------------------------------------------------------------
#: The core's commands, in the order ``--help`` lists them.
_CORE_COMMANDS: tuple[str, ...] = ("match", "features", "clique", "demo", "validate", "config")

#: Modules of ``scanclique.cli`` that add commands. Each defines ``register(app)``, which
#: adds its typer command(s) to ``app``. A command module imports only typer, rich and the
#: standard library at module level (heavy imports go inside the command), so that
#: ``scanclique --help`` and ``--version`` stay light.
COMMAND_MODULES: tuple[str, ...] = ("slam", "mapping", "places")


def _register_commands() -> None:
    for name in (*_CORE_COMMANDS, *COMMAND_MODULES):
        importlib.import_module(f"{__name__}.{name}").register(app)


_register_commands()


def main() -> None:
    """Console-script entry point (``scanclique``)."""
    app(prog_name="scanclique")
