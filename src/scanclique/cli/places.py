"""The ``scanclique places`` commands (``add``, ``query``, ``locate``, ``info``) and
``scanclique loops``: the place database of :mod:`scanclique.places` (issue 14).

The work is :mod:`scanclique.places.run`; this module only parses arguments and prints.
Heavy imports happen inside the commands.
"""

from __future__ import annotations

import sys
from pathlib import Path
from typing import Annotated

import typer

from . import (
    ConfigOpt,
    JsonOpt,
    OdometryOpt,
    PaperOpt,
    _check_out_file,
    _console,
    _err_console,
    _escape,
    _fail,
    _guard,
    _note,
    _print_json,
    _table,
)

places_app = typer.Typer(
    name="places",
    no_args_is_help=True,
    add_completion=False,
    rich_markup_mode="markdown",
    help="A place database (topological localisation): add scans as places, query a scan "
    "for the places it sees and its pose relative to each, locate a log's scans in the "
    "map of places added with --map.\n\n"
    "**Examples**\n\n"
    "```\n"
    "scanclique places add places.db freiburg --every 5\n"
    "scanclique places query places.db freiburg 1002 --top 5\n"
    "scanclique places info places.db --check\n"
    "scanclique places add mapped.db intel --every 5 --map runs/intel\n"
    "scanclique places locate mapped.db my-run.clf --out my-run.tum\n"
    "```",
)

DbArg = Annotated[Path, typer.Argument(help="The place database (SQLite file; created by add).")]
SourceArg = Annotated[
    str,
    typer.Argument(help="A log (CARMEN, .npz, scan text, ROS bag) or a data set name (freiburg)."),
]
LaserOpt = Annotated[
    str,
    typer.Option(
        "--laser",
        "--topic",
        help="Which laser of the log: a CARMEN message type (FLASER, RLASER, ROBOTLASER1..2, "
        "RAWLASER1..4, LASER3..4) or a ROS bag's LaserScan topic (/front/scan; --topic as "
        "for scanclique map); default: the main one.",
    ),
]


def _config(config, paper):
    """None when neither is given: the database's stored configuration is used."""
    if config is None and not paper:
        return None
    from ..tools import load_config

    return _guard(lambda: load_config(config, paper))


CandidatesOpt = Annotated[
    int | None,
    typer.Option("--candidates", min=1, help="Prefilter candidates to verify (default --top)."),
]
StartOpt = Annotated[int, typer.Option("--start", min=0, help="First scan index.")]
StopOpt = Annotated[int | None, typer.Option("--stop", min=0, help="Stop before this scan index.")]


def _check_range(source: str, start: int, stop: int | None, laser: str = "main") -> None:
    """Refuse a ``--stop`` not beyond ``--start``, and a ``--start`` beyond the log
    (:func:`_check_start`)."""
    if stop is not None and stop <= start:
        raise _fail(f"--stop {stop} must be beyond --start {start}: no scan lies between them")
    if start > 0:
        _check_start(source, start, laser)


def _check_start(source: str, start: int, laser: str = "main") -> None:
    """Refuse a ``--start`` at or beyond the end of the log before the database is opened
    (or created): one ``error:`` line, exit code 2, instead of "added 0 places". The log
    read here stays in :func:`scanclique.datasets.load_log`'s cache, where ``run_add``
    finds it (an empty log is left to ``run_add``, which says so)."""
    from .. import datasets

    n = len(_guard(lambda: datasets.load_log(source, laser=laser)))
    if 0 < n <= start:
        raise _fail(
            _escape(f"--start {start} is beyond the log: {source} has {n} scans (0..{n - 1})")
        )


def _quiet(json_out: bool) -> bool:
    return json_out or not sys.stderr.isatty()


@places_app.command("add")
def add(
    db: DbArg,
    source: SourceArg,
    every: Annotated[int, typer.Option("--every", min=1, help="One place per n-th scan.")] = 1,
    start: StartOpt = 0,
    stop: StopOpt = None,
    laser: LaserOpt = "main",
    map_poses: Annotated[
        Path | None,
        typer.Option(
            "--map",
            help="Store each place's pose in a map: a TUM trajectory of the same log, or the "
            "--out directory of 'scanclique map' on it (its trajectory.tum); poses go to scans "
            "by timestamp. A query then gives its pose in that map, and does not accept hits "
            "that others confidently contradict there.",
        ),
    ] = None,
    config: ConfigOpt = None,
    paper: PaperOpt = False,
    json_out: JsonOpt = False,
) -> None:
    """Add scans of a log as places (named LOG:INDEX; names already present are skipped).

    **Examples**

    ```
    scanclique places add places.db freiburg --every 5
    scanclique places add places.db intel --start 100 --stop 200
    scanclique map intel --out runs/intel && scanclique places add places.db intel --map runs/intel
    ```
    """
    from rich.progress import Progress

    if not db.exists():
        _check_out_file(db)  # a new database: its directory must exist
    from ..places.run import run_add

    cfg = _config(config, paper)
    _check_range(source, start, stop, laser)
    with Progress(console=_err_console(), transient=True, disable=_quiet(json_out)) as bar:
        task = bar.add_task("adding places", total=None)
        run = _guard(
            lambda: run_add(
                db, source, every=every, start=start, stop=stop, config=cfg, laser=laser,
                poses=map_poses, progress=lambda d, t: bar.update(task, completed=d, total=t),
            )
        )  # fmt: skip
    if json_out:
        _print_json(run.to_dict())
        return
    _console().print(f"added {run.added} places to {db} ({run.total} in the database)")
    _console().print(
        _table(run.rows(), f"scanclique places add {run.label}", ("Metric", "Value", "Units"))
    )


@places_app.command("query")
def query(
    db: DbArg,
    source: SourceArg,
    index: Annotated[int, typer.Argument(help="Index of the query scan in the log.")],
    top: Annotated[int, typer.Option("--top", "-k", min=1, help="Hits to show.")] = 5,
    candidates: CandidatesOpt = None,
    min_score: Annotated[
        float | None,
        typer.Option(
            "--min-score", help="Accept only matches scoring at least this (default 0.3)."
        ),
    ] = None,
    min_features: Annotated[
        int | None,
        typer.Option(
            "--min-features", min=2, help="Accept only matches mapping this many features (3)."
        ),
    ] = None,
    laser: LaserOpt = "main",
    config: ConfigOpt = None,
    paper: PaperOpt = False,
    json_out: JsonOpt = False,
) -> None:
    """Query the database with one scan: the best places, their verified relative poses
    (the query's frame in the place's) and verdicts.

    **Examples**

    ```
    scanclique places query places.db intel 120 --top 5
    scanclique places query places.db freiburg 3000 --candidates 10 --json
    ```
    """
    from ..places.run import run_query
    from ..places.verify import ACCEPT_MIN_FEATURES, ACCEPT_MIN_SCORE

    cfg = _config(config, paper)
    ms = ACCEPT_MIN_SCORE if min_score is None else min_score
    mf = ACCEPT_MIN_FEATURES if min_features is None else min_features
    run = _guard(lambda: run_query(db, source, index, k=top, candidates=candidates, config=cfg,
                                   min_score=ms, min_features=mf, laser=laser))  # fmt: skip
    if json_out:
        _print_json(run.to_dict())
        return
    con = _console()
    cols = (
        "Rank", "Place", "Verdict", "Score", "Conf.", "Feat.", "x y [m] th [deg]", "err [m, deg]",
        *(["in the map: x y [m] th [deg]"] if run.mapped else []),
    )  # fmt: skip
    con.print(_table(run.hit_rows(), f"{run.label}:{index} in {db}", cols))
    con.print(_table(run.rows(), "query", ("Metric", "Value", "Units")))
    con.print(
        "pose: the query scan's frame in the place's frame (maps the query's points into the "
        "place's); err: against the reference poses, when both scans have one; rank: in the "
        "prefilter; conf.: the probability that the pose is right (an accepted hit below "
        "min_confidence 0.99 is ambiguous); the best of the candidates verified: --candidates, "
        "and 5 more when none of them is accepted with confidence 0.99; a verdict marked "
        "(triangles): the triangle prefilter's pose verified on the raw scans (the clique "
        "matcher accepted no candidate)"
        + (
            "; in the map: the query's pose in the map of the places added with --map (an "
            "accepted hit that other confident hits put more than 1 m or 0.2 rad elsewhere "
            "there is ambiguous, unless the hits agreeing with it outweigh theirs a "
            "thousandfold)"
            if run.mapped
            else ""
        ),
        soft_wrap=True,
    )


#: ``places locate --trajectory`` notes a run more than this many times wider than the
#: located scans that carry it
SPREAD_RATIO = 3.0


@places_app.command("locate")
def locate(
    db: DbArg,
    source: SourceArg,
    every: Annotated[int, typer.Option("--every", min=1, help="Query every n-th scan.")] = 1,
    start: StartOpt = 0,
    stop: StopOpt = None,
    top: Annotated[int, typer.Option("--top", "-k", min=1, help="Hits per query.")] = 5,
    candidates: CandidatesOpt = None,
    out: Annotated[
        Path | None,
        typer.Option(
            "--out", "-o", help="Write the located (and tracked) scans' poses as a TUM trajectory."
        ),
    ] = None,
    trajectory: Annotated[
        Path | None,
        typer.Option(
            "--trajectory",
            help="Also map the log itself and carry its whole trajectory into the database's "
            "map by the motion its located (and tracked) scans agree on; write it here (TUM).",
        ),
    ] = None,
    plot: Annotated[
        Path | None,
        typer.Option(
            "--plot",
            help="Write a figure: the places, the located scans and the carried run (PNG).",
        ),
    ] = None,
    track: Annotated[
        bool,
        typer.Option(
            "--track",
            help="Also map the run as it goes and place a scan that is not recognised by "
            "the places near where the run predicts it from the last scan placed (and, "
            "afterwards, from the next one: the log is whole).",
        ),
    ] = False,
    odometry: OdometryOpt = None,
    laser: LaserOpt = "main",
    config: ConfigOpt = None,
    paper: PaperOpt = False,
    json_out: JsonOpt = False,
) -> None:
    """Localise the scans of a log in the map of a place database (places added with
    --map): each scan on its own, by recognition, with no prior pose; a scan is located
    when a hit is accepted, at the pose that hit gives it in the map. With --track, a scan
    not recognised is matched against the places near where the run's own motion puts it
    since the last scan placed, or back from the next one (tracked).

    **Examples**

    ```
    scanclique map intel --out runs/intel
    scanclique places add intel.db intel --every 5 --map runs/intel
    scanclique places locate intel.db my-run.clf --out my-run-in-intel.tum
    scanclique places locate intel.db my-run.clf --track --out my-run-tracked.tum
    ```
    """
    from rich.progress import Progress

    from ..places.run import TRACKED, run_locate

    for f in (out, trajectory):
        if f is not None:
            _check_out_file(f, log=source)
    if plot is not None:
        from ..plot import check_figure_path

        _guard(lambda: check_figure_path(plot))
    cfg = _config(config, paper)
    _check_range(source, start, stop, laser)
    with Progress(console=_err_console(), transient=True, disable=_quiet(json_out)) as bar:
        task = bar.add_task("locating scans", total=None)
        run = _guard(
            lambda: run_locate(
                db, source, every=every, start=start, stop=stop, k=top, candidates=candidates,
                config=cfg, laser=laser, whole=trajectory is not None, track=track,
                use_odometry=odometry,
                progress=lambda d, t: bar.update(task, completed=d, total=t),
            )
        )  # fmt: skip
    from ..io import write_tum

    if out is not None:
        n = _guard(lambda: write_tum(out, run.poses, run.timestamps))
        _note(f"{n} {'located or tracked' if track else 'located'} scans written to {out}")
    if trajectory is not None and run.anchor is None:
        _note(f"{trajectory} not written: the located scans agree on no one motion")
    elif trajectory is not None:
        n = _guard(lambda: write_tum(trajectory, run.trajectory, run.trajectory_times))
        _note(f"the whole run, {n} scans, written to {trajectory}")
        if run.bent:
            _note(
                "some placed scans disagree with one rigid carry: the run was bent onto all "
                "of them (its own map bends, or one of them is wrong: check the figure, --plot)"
            )
        elif run.run_extent > SPREAD_RATIO * run.anchor_spread:
            _note(
                f"the located scans that carry the run lie within {run.anchor_spread:.1f} m of "
                f"each other, in a run {run.run_extent:.1f} m across: far from them a small "
                "turn of the carry moves the run a lot (check the figure, --plot)"
            )
    if plot is not None:
        from ..plot import plot_located

        title = f"{run.label} located in {db.name}"
        tracked = [s == TRACKED for s in run.status]
        _guard(
            lambda: plot_located(
                plot, run.place_poses, run.poses, run.trajectory, title, tracked=tracked
            )
        )
        _note(f"wrote {plot}")
    if json_out:
        _print_json(run.to_dict())
        return
    _console().print(
        _table(
            run.rows(),
            f"scanclique places locate {run.label} in {db}",
            ("Metric", "Value", "Units"),
        )
    )


@places_app.command("info")
def info(
    db: DbArg,
    check: Annotated[
        bool, typer.Option("--check", help="Also run SQLite's integrity check (reads the file).")
    ] = False,
    json_out: JsonOpt = False,
) -> None:
    """Counts, sizes, versions and the stored configuration of a place database.

    **Examples**

    ```
    scanclique places info places.db
    scanclique places info places.db --check --json
    ```
    """
    from ..places.run import run_info

    d = _guard(lambda: run_info(db, check=check))
    if json_out:
        _print_json(d)
        return
    rows = [
        ("places", str(d["places"]), ""),
        ("of them with a map pose", str(d["places_with_map_pose"]), ""),
        ("file size", f"{(d['file_bytes'] + d['wal_bytes']) / 1e6:.2f}", "MB"),
        ("array data", f"{d['array_bytes'] / 1e6:.2f}", "MB"),
        ("schema version", str(d["schema_version"]), ""),
        ("signature version", f"{d['signature_version']} ({d['signature_size']} values)", ""),
        ("written by scanclique", str(d["scanclique_version"]), ""),
    ]
    if "integrity" in d:
        rows.append(("integrity", "; ".join(d["integrity"]), ""))
    _console().print(_table(rows, f"scanclique places info {db}", ("Metric", "Value", "Units")))


def loops(
    source: SourceArg,
    workers: Annotated[
        int,
        typer.Option(
            "--workers", "-j", "-w", min=0, help="Local worker processes (0: one per CPU)."
        ),
    ] = 1,
    scheduler: Annotated[
        str | None,
        typer.Option("--scheduler", help="Run on this Dask scheduler (tcp://host:8786) instead."),
    ] = None,
    candidates: Annotated[
        int, typer.Option("--candidates", min=1, help="Prefilter candidates verified per scan.")
    ] = 5,
    min_gap: Annotated[
        int, typer.Option("--min-gap", min=1, help="Only pairs at least this many scans apart.")
    ] = 50,
    every: Annotated[int, typer.Option("--every", min=1, help="Search every n-th scan.")] = 1,
    out: Annotated[
        Path | None,
        typer.Option(
            "--out", "-o", help="Write every verified pair as JSON here (a file there is replaced)."
        ),
    ] = None,
    laser: LaserOpt = "main",
    config: ConfigOpt = None,
    paper: PaperOpt = False,
    json_out: JsonOpt = False,
) -> None:
    """Every revisit in a log: all scans through the signature prefilter, the candidates
    verified by the clique matcher, in parallel; identical results on every backend.

    **Examples**

    ```
    scanclique loops freiburg --workers 2 --out loops.json
    scanclique loops freiburg --scheduler tcp://host:8786
    scanclique loops intel --candidates 10 --json
    ```
    """
    from rich.progress import Progress

    from .._workers import check_workers

    _guard(lambda: check_workers("--workers", workers, 0))  # before reading the log
    if out is not None:
        _check_out_file(out, log=source)  # before the search, not after it
        if out.exists():  # replaced, and said so, as map and slam do with their --out
            _note(f"{out} exists: the pairs written there replace it")
    from ..places.run import run_loops

    cfg = _config(config, paper)
    with Progress(console=_err_console(), transient=True, disable=_quiet(json_out)) as bar:
        tasks = {}

        def tick(stage: str, done: int, total: int) -> None:
            if stage not in tasks:
                tasks[stage] = bar.add_task(stage, total=total)
            bar.update(tasks[stage], completed=done, total=total)

        run = _guard(
            lambda: run_loops(
                source, every=every, candidates=candidates, min_gap=min_gap, workers=workers,
                scheduler=scheduler, config=cfg, out=out, progress=tick, laser=laser,
            )
        )  # fmt: skip
    if json_out:
        _print_json(run.to_dict())
        return
    _console().print(
        _table(run.rows(), f"scanclique loops {run.label}", ("Metric", "Value", "Units"))
    )
    if out is not None:
        _console().print(f"pairs written to {out}")


def register(app: typer.Typer) -> None:
    """Add ``scanclique places {add,query,info}`` and ``scanclique loops`` to ``app``."""
    app.add_typer(places_app, name="places")
    app.command("loops")(loops)
