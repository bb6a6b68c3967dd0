"""``run_map``: read a log, map it, write the outputs (the work of ``scanclique map``).

A plain function a script calls the same way as the command does.
"""

from __future__ import annotations

import logging
import math
import os
import time
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from .. import datasets
from .._outdir import remove_earlier_output
from ..config import ClusterConfig
from ..errors import ScanCliqueError
from ..scan import Scan
from ..uncertainty import constellation_std
from .config import MapConfig
from .loops import LOOK_ALIKES
from .pipeline import MapResult, choose_odometry, loop_match, map_scans

__all__ = [
    "MapRun",
    "load_map_log",
    "output_names",
    "pose_sigmas",
    "relation_summary",
    "sigmas_dict",
    "run_map",
    "is_bag",
]

log = logging.getLogger(__name__)

from ..io.rosbag import BAG_SUFFIXES, is_bag  # noqa: E402,F401 (re-exported)


def load_map_log(
    log_or_name: str | os.PathLike,
    topic: str | None = None,
    laser: str | None = None,
    *,
    odom_frame: str | None = None,
    base_frame: str | None = None,
) -> tuple[list[Scan], str]:
    """The scans of a CARMEN log, a registered data set name or a ROS bag, and a label.

    ``topic``: a bag's LaserScan topic (default: its only one); ``odom_frame``,
    ``base_frame``: its tf frames of the odometry and the robot (default ``odom``, and
    ``base_link`` or ``base_footprint``; :func:`scanclique.io.rosbag.read_bag`).
    ``laser``: a CARMEN log's laser message type (default ``"main"``: its front laser when
    it holds several, see :func:`scanclique.io.read_scans`), since a map is one sensor's;
    for a bag, a LaserScan topic like ``topic``."""
    s = str(log_or_name)
    if is_bag(s):
        from ..io.carmen import LASER_MESSAGES  # noqa: PLC0415

        if laser in LASER_MESSAGES:
            raise ScanCliqueError(f"--laser applies to CARMEN logs only; {s} is a bag (--topic)")
        if laser not in (None, "main"):  # a bag's laser is a LaserScan topic, as in read_scans
            if topic not in (None, laser):
                raise ScanCliqueError(f"--laser {laser} and --topic {topic} name two topics")
            topic = laser
        from ..io.rosbag import read_bag  # noqa: PLC0415

        frames = {"base_frame": base_frame}
        if odom_frame is not None:
            frames["odom_frame"] = odom_frame
        return read_bag(s, topic=topic, **frames), Path(s).name
    for option, value in (("--topic", topic), ("--odom-frame", odom_frame),
                          ("--base-frame", base_frame)):  # fmt: skip
        if value is not None:
            raise ScanCliqueError(f"{option} applies to ROS bags only; {s} is not a bag")
    return datasets.load_log(s, laser=laser or "main"), Path(s).name


def relation_summary(scans, relations, *pose_sets, mounting=None) -> tuple[dict | None, ...]:
    """The relation metric (:mod:`scanclique.eval.relations`) of each of ``pose_sets``
    (one pose per scan, or None) against ``(path, relations)``; None for each when
    ``relations`` is None."""
    if relations is None:
        return (None,) * len(pose_sets)
    from ..eval import relation_metrics  # noqa: PLC0415

    path, rels = relations
    ts = [s.timestamp for s in scans]
    return tuple(
        {"relations": str(path),
         **relation_metrics(rels, list(poses), ts, mounting=mounting).to_dict()}
        for poses in pose_sets
    )  # fmt: skip


@dataclass(frozen=True, slots=True, eq=False)
class MapRun:
    """What :func:`run_map` did: the result, the files written, the relation metric (when
    the log is a registered benchmark log) and wall times."""

    label: str
    result: MapResult
    files: dict
    metrics: dict | None
    seconds: dict = field(default_factory=dict)
    removed: tuple = ()
    """Files of an earlier run in ``out`` that this one removed (a ``map.png`` of an
    earlier ``plot=True`` run, when this one draws none: it would show another map)."""
    online: dict | None = None
    """With ``online=True``: the time per scan after the first (``add_ms``: median, p95,
    max), the first scan's (``first_ms``, which also loads the compiled kernels), the
    finish's (``finish_s``) and the relation metric of the live poses (``live_metrics``,
    when the log has relations); else None."""
    odometry_check: dict | None = None
    """With odometry: how far its steps point from the matched ones
    (:func:`~scanclique.mapping.pipeline.odometry_turned`: ``median_turn_deg`` over
    ``steps``; a laser mounted turned on the robot shows as minus its turn); else None."""
    odometry_scale: dict | None = None
    """With odometry, or when the mapper set the log's odometry aside: how far its steps
    move against the matched ones (:class:`~scanclique.mapping.pipeline.OdometryScale`:
    ``median_scale`` over ``steps``; about 1 for right odometry); else None."""

    def rows(self) -> list[tuple[str, str, str]]:
        """Metric / Value / Units rows for the command's table."""
        c = self.result.counts()
        s = self.seconds
        n = c["scans"]
        rows = [
            ("scans", str(n), ""),
            ("keyframes", str(c["keyframes"]), ""),
            ("placed by match", str(c["placed_by"].get("match", 0)), "scans"),
            ("placed by ICP fallback", str(c["placed_by"].get("icp", 0)), "scans"),
            ("placed by odometry", str(c["placed_by"].get("odometry", 0)), "scans"),
            (
                "placed by constant velocity",
                str(c["placed_by"].get("constant_velocity", 0)),
                "scans",
            ),
            ("loop candidates verified", str(c["loop_candidates"]), ""),
            ("loop closures accepted", str(c["loop_closures_accepted"]), ""),
        ]
        alike = {v: c["loop_verdicts"].get(v, 0) for v in LOOK_ALIKES}
        if any(alike.values()):  # a corner turned round, a door along, a twin room
            text = ", ".join(f"{n} {verdict}" for verdict, n in alike.items())
            rows.append(("loop closures refused as look-alikes", text, ""))
        rows.append(("odometry used", "yes" if self.result.used_odometry else "no", ""))
        if c["deskewed"]:
            rows.append(("de-skewed (a rotating lidar's sweep)", str(c["deskewed"]), "scans"))
            rows.append(("beam times read", c["sweep_timing"], ""))
        clu = self.result.config.match.clustering
        if clu.max_gap_beams:  # the scanner loses returns (features.for_scanner), or asked
            rows.append(("lost returns bridged inside a surface", f"up to {clu.max_gap_beams}",
                         "beams"))  # fmt: skip
        if clu.c2 != ClusterConfig().c2:  # widened to the scanner's range noise, or asked
            rows.append(("clustering's range term (c2)", f"{clu.c2:g}", "m/m"))
        if loop_match(self.result.config) is not None:  # the scanner meets its reach
            rows.append(("edges where a wall leaves the reach", "left out of loop closures", ""))
        if self.odometry_check and self.odometry_check["steps"]:
            rows.append(
                ("odometry's turn from the scans (median)",
                 f"{self.odometry_check['median_turn_deg']:.1f}", "deg")
            )  # fmt: skip
        if c["odometry_fit"] is not None:
            rows.append(
                ("odometry's error / its noise model",
                 "{:.2f} / {:.2f}".format(*c["odometry_fit"]), "translation / heading")
            )  # fmt: skip
        if c.get("odometry_drift") is not None:
            per_metre, per_radian = c["odometry_drift"]
            rows.append(
                ("odometry's steady heading drift",
                 f"{math.degrees(per_metre):.2f} / {100 * per_radian:.1f}", "deg/m / % of turn")
            )  # fmt: skip
        if c.get("odometry_steps"):
            rows.append(
                ("odometry's steady scale error (taken out)",
                 f"{100 * c['odometry_steps']:+.1f}", "% of its steps")
            )  # fmt: skip
        if self.odometry_scale and self.odometry_scale["steps"]:
            rows.append(
                ("odometry's step / the scans' (median)",
                 f"{self.odometry_scale['median_scale']:.3g}", "")
            )  # fmt: skip
        rows += [
            ("mapping time", f"{self.result.seconds.get('total', math.nan):.1f}", "s"),
            ("total time", f"{s.get('total', math.nan):.1f}", "s"),
            ("scans per second", f"{n / max(s.get('total', math.nan), 1e-9):.1f}", "1/s"),
        ]
        if self.metrics:
            from ..eval import relation_rows  # noqa: PLC0415

            rows += relation_rows(self.metrics)
        covs = self.result.covariances
        if covs is not None:
            sig = pose_sigmas(covs)
            if sig is not None:
                rows += [
                    ("largest position sigma", f"{sig[0]:.4f}", "m"),
                    ("largest heading sigma", f"{sig[1]:.3f}", "deg"),
                ]
        if self.online:
            a = self.online["add_ms"]
            rows += [
                ("time per scan online (median / p95 / max)",
                 f"{a['p50']:.1f} / {a['p95']:.1f} / {a['max']:.0f}", "ms"),
                ("first scan online (kernels load)",
                 f"{self.online['first_ms']:.0f}", "ms"),
            ]  # fmt: skip
            live = self.online.get("live_metrics")
            if live:
                rows.append(
                    ("relation error of the live poses",
                     f"{live['all']['translation_mean']:.4f}", "m")
                )  # fmt: skip
        for k, v in self.files.items():
            rows.append((k, str(v), "file"))
        return rows


def pose_sigmas(covariances) -> tuple[float, float] | None:
    """The largest position standard deviation (m; the larger axis of a scan's xy
    covariance) and heading standard deviation (deg) over the scans; None for none."""
    stds = [constellation_std(c) for c in covariances if c is not None]
    if not stds:
        return None
    return max(s for s, _ in stds), math.degrees(max(t for _, t in stds))


def output_names(
    plot: bool = True, covariances: bool = False, online: bool = False
) -> tuple[str, ...]:
    """The names of the files :func:`run_map` writes into its ``out`` directory (the
    ``map`` command checks them before the run: a directory in the way of one failed
    only when the results were written)."""
    return (
        ("trajectory.tum", "graph.g2o", "map.pgm", "map.yaml", "report.json")
        + (("map.png",) if plot else ())
        + (("covariances.csv",) if covariances else ())
        + (("trajectory_live.tum",) if online else ())
    )


def run_map(
    log_or_name: str | os.PathLike,
    out: str | os.PathLike,
    *,
    use_odometry: bool | None = None,
    topic: str | None = None,
    plot: bool = True,
    config: MapConfig | None = None,
    progress: Callable[[int, int, int], None] | None = None,
    workers: int = 1,
    online: bool = False,
    laser: str | None = None,
    odom_frame: str | None = None,
    base_frame: str | None = None,
    relations: str | os.PathLike | None = None,
) -> MapRun:
    """Map a log and write ``trajectory.tum``, ``graph.g2o``, ``map.pgm``, ``map.yaml``,
    ``report.json`` (``map.png`` when ``plot``; ``covariances.csv`` when the
    configuration asks for the covariances, ``config.back_end.covariances``) into
    ``out``. Loop verification runs
    on ``workers - 1`` forked local processes beside this one (1: in this process; the map
    is the same).

    ``online``: map the log as a robot would have live (:func:`.online.map_online`, one
    scan at a time, the odometry's reversing told as the scans come) and also write
    ``trajectory_live.tum``, each scan's pose as it was answered when the scan came. The
    other files are the finished map's: the batch map of the same configuration (default
    :meth:`MapConfig.online`), except where the batch reads the whole log to tell whether
    the odometry reports backing up.

    ``laser``: which laser of a CARMEN log that holds several; ``odom_frame``,
    ``base_frame``: a bag's tf frames of the odometry and the robot (:func:`load_map_log`).

    ``relations``: a relations file of the SLAM benchmark (Kümmerle et al. 2009) for this
    log, whose metric the run reports (:attr:`MapRun.metrics`); default: the registered
    log's own (:func:`scanclique.datasets.log_relations`), else none. Read before the
    mapping, so that a malformed file is a :class:`~scanclique.errors.ParseError` at once.
    """
    from . import outputs  # noqa: PLC0415
    from .occupancy import occupancy_grid  # noqa: PLC0415

    t0 = time.perf_counter()
    cfg = config or (MapConfig.online() if online else MapConfig())
    rel_file = datasets.log_relations(log_or_name) if relations is None else relations
    rels = None
    if rel_file is not None:
        from ..eval import read_relations  # noqa: PLC0415

        rels = (rel_file, read_relations(rel_file))
    scans, label = load_map_log(
        log_or_name, topic, laser, odom_frame=odom_frame, base_frame=base_frame
    )
    t_read = time.perf_counter() - t0
    if not scans:
        raise ScanCliqueError(f"{log_or_name}: the log holds no laser scans")
    live = None
    if online:
        from .online import map_online  # noqa: PLC0415

        # as map_scans decides it, from the whole log (a live robot could not sample it)
        use, aside = choose_odometry(scans, use_odometry, cfg)
        orun = map_online(scans, use_odometry=use, config=cfg, progress=progress, workers=workers)
        result, live = orun.result, orun
        if aside is not None:
            result = replace(result, odometry_scale=aside)
    else:
        result = map_scans(
            scans, use_odometry=use_odometry, config=cfg, progress=progress, workers=workers
        )
    outdir = Path(out)
    try:
        outdir.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise ScanCliqueError(f"cannot create output directory {outdir}: {exc}") from None
    t = time.perf_counter()
    files = {}
    ts = [s.timestamp for s in scans]
    outputs.write_tum(outdir / "trajectory.tum", result.poses, ts)
    files["trajectory"] = outdir / "trajectory.tum"
    outputs.write_g2o(outdir / "graph.g2o", result.poses, result.edges)
    files["graph"] = outdir / "graph.g2o"
    if live is not None:
        outputs.write_tum(outdir / "trajectory_live.tum", live.live, ts)
        files["trajectory_live"] = outdir / "trajectory_live.tum"
    if result.covariances is not None:
        outputs.write_covariances(outdir / "covariances.csv", result.poses, result.covariances, ts)
        files["covariances"] = outdir / "covariances.csv"
    grid = occupancy_grid(scans, result.poses, cfg.occupancy, timing=result.sweep_timing or None)
    outputs.write_map(outdir / "map.pgm", outdir / "map.yaml", grid)
    files["map"] = outdir / "map.pgm"
    files["map_yaml"] = outdir / "map.yaml"
    removed = ()
    if plot:
        outputs.write_png(
            outdir / "map.png", grid, result.poses, result.accepted_closures, label,
            covariances=result.covariances,
        )  # fmt: skip
        files["image"] = outdir / "map.png"
    elif (gone := remove_earlier_output(outdir, "map.png")) is not None:
        removed = (str(gone),)
    t_out = time.perf_counter() - t
    from ..eval import frame_mounting  # noqa: PLC0415

    # the relations refer to the robot frame where the log's laser lines say where the
    # laser sits on it (fr079: 0.04 m behind), as benchmarks/mapping.py computes them
    pose_sets = (result.poses,) if live is None else (result.poses, live.live)
    metrics, *live_metrics = relation_summary(
        scans, rels, *pose_sets, mounting=frame_mounting(scans)
    )
    online_summary = None
    if live is not None:
        # the first scan also loads the compiled kernels (about a second): apart
        rest = live.add_seconds[1:] if live.add_seconds.size > 1 else live.add_seconds
        online_summary = {
            "add_ms": {
                q: float(np.percentile(rest, p) * 1e3)
                for q, p in (("p50", 50), ("p95", 95), ("max", 100))
            },
            "first_ms": float(live.add_seconds[0] * 1e3),
            "finish_s": live.finish_seconds,
            "live_metrics": live_metrics[0],
        }
    check = None if result.odometry_check is None else result.odometry_check._asdict()
    scale = None if result.odometry_scale is None else result.odometry_scale._asdict()
    seconds = {"read": t_read, "map": result.seconds.get("total", 0.0), "outputs": t_out}
    seconds["total"] = time.perf_counter() - t0
    report = {
        "log": str(log_or_name),
        "config": outputs.map_config_dict(cfg),
        "used_odometry": result.used_odometry,
        "odometry_check": check,
        "odometry_scale": scale,
        "workers": workers,
        "online": online_summary,
        "counts": result.counts(),
        "pose_sigmas": sigmas_dict(result.covariances),
        "seconds": {**result.seconds, **seconds},
        "metrics": metrics,
        "unplaced_or_flagged": {str(k): v for k, v in result.reasons.items()},
        "loop_closures": [c.to_dict() for c in result.loop_closures if not c.local],
        "files": {k: str(v) for k, v in files.items()},
        "removed": list(removed),
    }
    outputs.write_report(outdir / "report.json", report)
    files["report"] = outdir / "report.json"
    return MapRun(
        label, result, {k: str(v) for k, v in files.items()}, metrics, seconds, removed,
        online_summary, check, scale,
    )  # fmt: skip


def sigmas_dict(covariances) -> dict | None:
    """:func:`pose_sigmas` as a dict for ``report.json`` and ``--json`` (None when not
    computed or no scan has one)."""
    sig = None if covariances is None else pose_sigmas(covariances)
    return None if sig is None else {"position_m": sig[0], "heading_deg": sig[1]}
