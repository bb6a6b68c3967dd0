"""EKF-SLAM on Victoria Park: nearest neighbour vs JCBB vs clique association, one run.

For each method and each clutter level (spurious detections injected per scan): GPS error
of the laser's position at every fix (RMS and max; aligned by the start of the run and by
the best SE(2) alignment), landmarks in the final map, landmarks in pairs closer than 1 m
(duplicates), median and 95th-percentile association time per step (CPU), whole-run time
(CPU and wall). A figure of the three maps over the GPS track. Then the filter's NEES of
the vehicle pose on simulated tree parks (known truth, the same noise as the filter's), and
on simulated rooms (``scanclique.slam.sim.simulate_room``: a wheeled robot with odometry
at 67 Hz, 15 landmarks without attributes in a 15 x 8 m room, a 5 m sensor with a 60 deg
field of view, frames asynchronous to the odometry; also with a 180 deg field of view and
with clutter): pose RMSE, ANEES and its 95 % band, landmarks against the truth, and the
share of wrong associations.

    python benchmarks/slam.py                 # full: clutter 0, 5, 10; 5 simulated parks; rooms
    python benchmarks/slam.py --clutter 0 --sims 2 --jobs 2
    python benchmarks/slam.py --sections room --out /tmp/slam-room   # the rooms only
    python benchmarks/slam.py --sections logs --logs DIR1,DIR2 [--log-config slam.toml]

``--logs``: landmark logs of one's own (``scanclique.slam.read_landmark_log``: controls,
observations, truth): every method on each, side by side against the truth (pose error in
both alignments, heading, ANEES, true landmarks mapped), with the clique methods' ratios to
the better of NN and JCBB; ``--log-config`` the SlamConfig (TOML) for them (default
``SlamConfig()``).

Each filter run is followed by the optional smoothing pass (scanclique.slam.smooth: a GTSAM
pose graph with the filter's associations), reported on its own rows ("nn + smoothing", ...;
run times include the filter's); ``--no-smooth`` leaves them out.

Writes benchmarks/results/slam-2026-12-02-s9.json, .md and .png (the maps, and below them each
clutter-0 run's error at every GPS fix with the GPS's own jumps marked; the -s8, -s7, -s6 files are
earlier sessions' runs, the files without a suffix the first).
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")  # one core per run
os.environ.setdefault("OMP_NUM_THREADS", "1")

import numpy as np  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent))
from common import RESULTS, TODAY, provenance  # noqa: E402

METHODS = ("nn", "jcbb", "clique", "clique-jcbb")


def _warm_up(method):
    """Compile (or load) the numba kernels before anything is timed."""
    from scanclique.slam import Ackermann, SlamConfig, ekf_slam
    from scanclique.slam.sim import simulate_park

    run = simulate_park(0, laps=1, length=20.0, width=10.0, n_trees=20)
    ekf_slam(run.steps[:800], Ackermann(), association=method, config=SlamConfig())


def _with_closure(cfg, crowding):
    """``cfg`` with ``AssociationConfig.closure_crowding`` set (``--closure-crowding``:
    None keeps the library's default, "off" turns the closure rule off)."""
    if crowding is None:
        return cfg
    from dataclasses import replace

    value = None if crowding == "off" else float(crowding)
    return replace(cfg, association=replace(cfg.association, closure_crowding=value))


def _vp_worker(args):
    method, clutter, seed, smooth, crowding = args
    _warm_up(method)
    from scanclique.slam import read_gps, read_victoria_park
    from scanclique.slam.ekf import SlamConfig, ekf_slam
    from scanclique.slam.metrics import gps_fix_errors, gps_jumps, sensor_positions
    from scanclique.slam.run import inject_clutter, summarise, victoria_park_model

    cfg = _with_closure(SlamConfig(), crowding)
    steps = read_victoria_park("victoria-park")
    gps = read_gps("victoria-park")
    if clutter:
        steps = inject_clutter(steps, clutter, max_range=cfg.max_range or 30.0, seed=seed)
    model = victoria_park_model()
    r = ekf_slam(steps, model, association=method, config=cfg)
    g, m, (Rm, t) = summarise(r, model, gps, clutter)
    pos = sensor_positions(r.poses, model.sensor_x, model.sensor_y)
    fixes, _e_start, e_best, est_best, _best = gps_fix_errors(r.times, pos, gps)
    jumps = gps_jumps(fixes, est_best)
    gap = np.r_[False, np.diff(fixes[:, 0]) > 2.0]
    top = np.argsort(-e_best)[: max(1, len(e_best) // 20)]
    diag = {
        "median": float(np.median(e_best)),
        "p90": float(np.percentile(e_best, 90)),
        "share_top5": float(np.sum(e_best[top] ** 2) / np.sum(e_best**2)),
        "jumps": int(jumps.sum()),
        "top10_after_jump_or_gap": int(
            sum(
                bool(
                    np.any(
                        (jumps | gap)
                        & (fixes[:, 0] <= fixes[i, 0])
                        & (fixes[:, 0] > fixes[i, 0] - 1.0)
                    )
                )
                for i in np.argsort(-e_best)[:10]
            )
        ),
    }
    keep = slice(None, None, 10)
    extra = []
    if smooth:
        from scanclique.slam.run import summarise_smoothed
        from scanclique.slam.smooth import smooth as smooth_run

        sm = smooth_run(steps, model, r, config=cfg)
        _g, ms, _a = summarise_smoothed(r, sm, model, gps, clutter)
        extra.append(
            {
                "method": f"{method} + smoothing",
                "clutter": clutter,
                "metrics": {k: v for k, (v, _u) in ms.items()},
                "units": {k: u for k, (_v, u) in ms.items()},
            }
        )
    return [
        {
            "method": method,
            "clutter": clutter,
            "metrics": {k: v for k, (v, _u) in m.items()},
            "units": {k: u for k, (_v, u) in m.items()},
            "gps_diagnosis": diag,
            "_plot": (
                pos[keep].tolist(),
                r.landmarks.tolist(),
                r.landmark_covariances.tolist(),
                Rm.tolist(),
                t.tolist(),
                fixes[:, 0].tolist(),
                e_best.tolist(),
                fixes[jumps, 0].tolist(),
            ),
        }
    ] + extra


LOG_COLUMNS = (
    ("pose RMSE (start alignment)", "pose RMSE start [m]"),
    ("pose RMSE (best SE(2) alignment)", "pose RMSE SE(2) [m]"),
    ("pose max (start alignment)", "pose max start [m]"),
    ("heading RMSE", "heading RMSE [deg]"),
    ("pose ANEES (3 dof; 3 if consistent)", "ANEES"),
    ("true landmarks mapped (within 1 m)", "true landmarks mapped"),
    ("landmark RMSE (mapped)", "landmark RMSE [m]"),
    ("landmarks", "landmarks"),
    ("duplicate pairs (< 1 m)", "duplicate pairs"),
    ("association median", "assoc. median [ms]"),
    ("run time (CPU)", "CPU [s]"),
)


def _log_worker(args):
    """One method on one landmark log: its metrics against the log's truth."""
    log_dir, method, config_path = args
    _warm_up(method)
    from scanclique.io.config import read_config
    from scanclique.slam import SlamConfig
    from scanclique.slam.run import run_slam

    cfg = read_config(config_path, cls=SlamConfig) if config_path else SlamConfig()
    run = run_slam(log_dir, association=method, config=cfg)
    return {
        "log": str(log_dir),
        "method": method,
        "metrics": {k: v for k, (v, _u) in run.metrics.items()},
        "units": {k: u for k, (_v, u) in run.metrics.items()},
    }


def _metric_table(first: str, records, columns, label) -> list[str]:
    """Markdown table of ``records``' metrics: a row per record, ``label(record)`` in
    the first column (headed ``first``), its method, then ``columns`` ((key, heading))."""
    lines = [f"| {first} | method | " + " | ".join(c[1] for c in columns) + " |"]
    lines.append("|" + "---|" * (len(columns) + 2))
    for r in records:
        cells = " | ".join(_fmt(r["metrics"].get(k, "")) for k, _ in columns)
        lines.append(f"| {label(r)} | {r['method']} | {cells} |")
    return lines


def log_table(records) -> tuple[list[str], list[str]]:
    """Markdown rows of the landmark logs' runs (one per log and method) and the clique
    methods' ratios to the better of NN and JCBB on the pose errors."""
    lines = _metric_table("log", records, LOG_COLUMNS, lambda r: Path(r["log"]).name)
    ratios = []
    for log in dict.fromkeys(r["log"] for r in records):
        rs = {r["method"]: r["metrics"] for r in records if r["log"] == log}
        classic = [m for m in ("nn", "jcbb") if m in rs]
        for cm in ("clique", "clique-jcbb"):
            keys = ("pose RMSE (best SE(2) alignment)", "pose RMSE (start alignment)")
            if cm in rs and classic and all(k in rs[m] for m in (cm, *classic) for k in keys):
                parts = [
                    f"{k} {cm} / best of {', '.join(classic)} = "
                    f"{rs[cm][k] / max(min(rs[m][k] for m in classic), 1e-12):.3f}"
                    for k in keys
                ]
                ratios.append(f"{Path(log).name}: " + "; ".join(parts))
    return lines, ratios


def _truth_record(run, r, steps_mask):
    """NEES at the steps ``steps_mask``, pose RMSE and the associations against the truth."""
    from scanclique.slam import wrap
    from scanclique.slam.metrics import nees, score_against_truth

    e = r.poses - run.poses
    e[:, 2] = wrap(e[:, 2])
    n = nees(e, r.pose_covariances)
    sc = score_against_truth(r.landmark_ids, r.associations, run.truth)
    return {
        "nees_obs_steps": n[np.flatnonzero(steps_mask)].tolist(),
        "pos_rmse": float(np.sqrt(np.mean(np.sum(e[:, :2] ** 2, 1)))),
        "landmarks": len(r.landmarks),
        "trees": len(run.landmarks),
        "pair_consistency": 1.0 - sc.wrong_rate,
        "seen": sc.seen,
        "distinct": sc.distinct,
        "spurious": sc.spurious,
        "duplicates": sc.duplicates,
        "wrong_rate": sc.wrong_rate,
        "ambiguous": int(r.ambiguous.sum()),
    }


def _nees_worker(args):
    method, seed, crowding = args
    from scanclique.slam import Ackermann, SlamConfig, ekf_slam
    from scanclique.slam.sim import simulate_park

    cfg = _with_closure(SlamConfig(), crowding)
    run = simulate_park(seed, config=cfg, max_range=cfg.max_range or 20.0)
    r = ekf_slam(run.steps, Ackermann(), association=method, config=cfg)
    mask = np.array([s.n_observations > 0 for s in run.steps])
    return {"method": method, "seed": seed, **_truth_record(run, r, mask)}


#: The simulated rooms: (changes of ``room_config``, keyword arguments of ``simulate_room``,
#: and optionally the filter's configuration when it is not the room's: "default" is
#: ``SlamConfig()``, Victoria Park's, as a caller who gives no configuration gets;
#: "sensor" is ``SlamConfig.for_sensor`` with the room's sensor and the default slip, as a
#: caller who gives the sensor but not the robot's slip gets).
ROOM_SETTINGS = {
    "narrow": ({}, {}),
    "wide": ({"sensor_fov": math.pi}, {}),
    "narrow, clutter 0.5": ({}, {"clutter": 0.5}),
    "narrow, clutter 1": ({}, {"clutter": 1.0}),
    "narrow, clutter 1, tentative_update=landmark": (
        {"tentative_update": "landmark"},
        {"clutter": 1.0},
    ),
    "narrow, SlamConfig()": ({}, {}, "default"),
    "narrow, for_sensor (default slip)": ({}, {}, "sensor"),
    "wide, SlamConfig()": ({"sensor_fov": math.pi}, {}, "default"),
}


def _room_worker(args):
    setting, method, seed, crowding = args
    from scanclique.slam import SlamConfig, Unicycle, ekf_slam
    from scanclique.slam.sim import room_config, simulate_room

    cfg_kw, sim_kw, *filt = ROOM_SETTINGS[setting]
    cfg = room_config(**cfg_kw)
    run = simulate_room(seed, config=cfg, **sim_kw)
    if filt == ["default"]:
        cfg = SlamConfig()  # the filter does not know the sensor
    elif filt == ["sensor"]:  # the filter knows the sensor, not the slip
        cfg = SlamConfig.for_sensor(
            cfg.sigma_range, cfg.sigma_bearing, cfg.max_range, cfg.sensor_fov,
            attribute_sigma=cfg.association.attribute_sigma,
        )  # fmt: skip
    cfg = _with_closure(cfg, crowding)
    r = ekf_slam(run.steps, Unicycle(), association=method, config=cfg, initial_pose=run.poses[0])
    # NEES at every frame (the steps without a control): the same count in every run
    mask = np.array([s.control is None for s in run.steps])
    return {"setting": setting, "method": method, "seed": seed, **_truth_record(run, r, mask)}


def _nees_summary(records, M):
    from scipy.stats import chi2

    # (M, T): scan by scan across the runs; a simulated scan that sees nothing is no step,
    # so a run may have a scan fewer (its later scans then pair with the others' one
    # scan, 0.2 s, later): the runs are cut to the shortest
    T = min(len(r["nees_obs_steps"]) for r in records)
    a = np.array([r["nees_obs_steps"][:T] for r in records])
    mean_t = a.mean(0)
    per_run = a.mean(1)  # each run's own ANEES: one run that diverges dominates mean_t
    lo, hi = chi2.ppf(0.025, 3 * M) / M, chi2.ppf(0.975, 3 * M) / M
    inside = float(np.mean((mean_t >= lo) & (mean_t <= hi)))
    return {
        "runs": M,
        "steps_compared": T,
        "band": [lo, hi],
        "anees": float(mean_t.mean()),
        "fraction_inside": inside,
        "run_anees_median": float(np.median(per_run)),
        "run_anees_max": float(per_run.max()),
        "runs_above_10": int((per_run > 10).sum()),
        "pos_rmse": float(np.mean([r["pos_rmse"] for r in records])),
        "pair_consistency": float(np.mean([r["pair_consistency"] for r in records])),
        "landmarks": float(np.mean([r["landmarks"] for r in records])),
        **{
            k: float(np.mean([r[k] for r in records]))
            for k in ("seen", "distinct", "spurious", "duplicates", "wrong_rate", "ambiguous")
        },
    }


def _fmt(v):
    return f"{v:.2f}" if isinstance(v, float) else str(v)


COLUMNS = [
    ("GPS RMSE (start alignment)", "RMSE start [m]"),
    ("GPS max (start alignment)", "max start [m]"),
    ("GPS RMSE (best SE(2) alignment)", "RMSE SE(2) [m]"),
    ("GPS max (best SE(2) alignment)", "max SE(2) [m]"),
    ("landmarks", "landmarks"),
    ("landmarks in duplicate pairs", "dup [%]"),
    ("association median", "assoc med [ms]"),
    ("association p95", "assoc p95 [ms]"),
    ("ambiguous steps", "ambiguous"),
    ("run time (CPU)", "run CPU [s]"),
    ("run time (wall)", "run wall [s]"),
]


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--clutter", default="0,5,10", help="clutter levels, comma-separated")
    ap.add_argument("--methods", default=",".join(METHODS))
    ap.add_argument("--sims", type=int, default=5, help="simulated parks for the NEES")
    ap.add_argument("--jobs", type=int, default=1)
    ap.add_argument("--no-smooth", action="store_true", help="leave out the smoothing rows")
    ap.add_argument(
        "--sections",
        default="vp,park,room",
        help="parts to run: vp (Victoria Park), park (simulated parks), room (simulated rooms)",
    )
    ap.add_argument("--room-seeds", type=int, default=5, help="simulated rooms per setting")
    ap.add_argument(
        "--closure-crowding",
        default=None,
        help="AssociationConfig.closure_crowding for every run: a number, or 'off' "
        "(default: the library's)",
    )
    ap.add_argument(
        "--logs",
        default="",
        help="landmark log directories, comma-separated (section 'logs', added when given)",
    )
    ap.add_argument("--log-config", default=None, help="SlamConfig TOML for --logs")
    ap.add_argument("--out", default=str(RESULTS / f"slam-{TODAY}"))
    args = ap.parse_args(argv)
    sections = set(args.sections.split(","))
    logs = [d for d in args.logs.split(",") if d]
    if logs:
        sections.add("logs")
    elif "logs" in sections:
        ap.error("--sections logs needs --logs DIR[,DIR...]")
    clutters = [int(c) for c in args.clutter.split(",") if c != ""] if "vp" in sections else []
    methods = [m for m in args.methods.split(",") if m]
    t0 = time.perf_counter()
    cc = args.closure_crowding
    tasks = [(m, c, 0, not args.no_smooth, cc) for c in clutters for m in methods]
    nees_tasks = [(m, s, cc) for m in methods for s in range(args.sims)] * ("park" in sections)
    room_tasks = [
        (st, m, s, cc) for st in ROOM_SETTINGS for m in methods for s in range(args.room_seeds)
    ] * ("room" in sections)
    log_tasks = [(d, m, args.log_config) for d in logs for m in methods]
    with ProcessPoolExecutor(args.jobs) as ex:
        log_runs = list(ex.map(_log_worker, log_tasks)) if log_tasks else []
        vp = [row for rows in ex.map(_vp_worker, tasks) for row in rows]
        sims = list(ex.map(_nees_worker, nees_tasks)) if nees_tasks else []
        rooms = list(ex.map(_room_worker, room_tasks)) if room_tasks else []
    lines = _metric_table("clutter", vp, COLUMNS, lambda r: r["clutter"])
    # ratios: each clique method against the better of NN and JCBB, per clutter level
    ratio_lines = []
    keys = ("GPS RMSE (best SE(2) alignment)", "GPS RMSE (start alignment)", "landmarks")
    for c in clutters:
        rs = {r["method"]: r["metrics"] for r in vp if r["clutter"] == c}
        for suffix in ("", " + smoothing"):
            classic = [m + suffix for m in ("nn", "jcbb") if m + suffix in rs]
            for cm in ("clique" + suffix, "clique-jcbb" + suffix):
                if cm in rs and classic:
                    parts = []
                    for key in keys[:2]:
                        best = min(rs[m][key] for m in classic)
                        parts.append(
                            f"{key} {cm} / best of nn, jcbb{suffix} = {rs[cm][key] / best:.3f}"
                        )
                    ratio_lines.append(f"clutter {c}: " + "; ".join(parts))
    diag_lines = [
        "| clutter | method | median [m] | p90 [m] | share of squared error in the worst 5 % "
        "of fixes | GPS jumps | of the 10 worst fixes, within 1 s after a GPS jump or a > 2 s "
        "gap |",
        "|---|---|---|---|---|---|---|",
    ]
    for r in vp:
        g = r.get("gps_diagnosis")
        if g:
            diag_lines.append(
                f"| {r['clutter']} | {r['method']} | {g['median']:.2f} | {g['p90']:.2f} | "
                f"{100 * g['share_top5']:.0f} % | {g['jumps']} | {g['top10_after_jump_or_gap']} |"
            )
    nees = {}
    for m in methods:
        recs = [s for s in sims if s["method"] == m]
        if recs:
            nees[m] = _nees_summary(recs, len(recs))
    nees_lines = [
        "| method | runs | ANEES | 95 % band | fraction of steps inside | pos RMSE [m] "
        "| pair consistency | landmarks | ANEES of a run: median | max | runs above 10 |",
        "|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for m, s in nees.items():
        nees_lines.append(
            f"| {m} | {s['runs']} | {s['anees']:.2f} | [{s['band'][0]:.2f}, {s['band'][1]:.2f}] | "
            f"{100 * s['fraction_inside']:.1f} % | {s['pos_rmse']:.2f} | "
            f"{100 * s['pair_consistency']:.2f} % | {s['landmarks']:.0f} | "
            f"{s['run_anees_median']:.2f} | {s['run_anees_max']:.2f} | {s['runs_above_10']} |"
        )
    room = {}
    for st in ROOM_SETTINGS:
        for m in methods:
            recs = [s for s in rooms if s["setting"] == st and s["method"] == m]
            if recs:
                room[f"{st} | {m}"] = _nees_summary(recs, len(recs))
    room_lines = [
        "| setting | method | runs | pose RMSE [m] | ANEES | 95 % band | steps inside "
        "| landmarks / seen | duplicates | spurious | wrong associations | ambiguous steps |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for key, s in room.items():
        st, m = key.split(" | ")
        room_lines.append(
            f"| {st} | {m} | {s['runs']} | {s['pos_rmse']:.3f} | {s['anees']:.2f} | "
            f"[{s['band'][0]:.2f}, {s['band'][1]:.2f}] | {100 * s['fraction_inside']:.1f} % | "
            f"{s['landmarks']:.1f} / {s['seen']:.1f} | {s['duplicates']:.1f} | "
            f"{s['spurious']:.1f} | {100 * s['wrong_rate']:.2f} % | {s['ambiguous']:.0f} |"
        )
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    # the figure: the maps at the lowest clutter level
    try:
        from scanclique.slam import read_gps
        from scanclique.slam.outputs import plot_maps

        c0 = min(clutters, default=None)
        runs, errors = [], []
        for r in vp:
            if r["clutter"] == c0 and "_plot" in r:
                pos, lm, lc, Rm, t, te, ee, tj = r["_plot"]
                errors.append((r["method"], np.array(te), np.array(ee), np.array(tj)))
                runs.append(
                    (
                        f"{r['method']} (clutter {c0})",
                        np.array(pos),
                        np.array(lm).reshape(-1, 2),
                        np.array(lc).reshape(-1, 2, 2),
                        (np.array(Rm), np.array(t)),
                    )
                )
        if runs:
            plot_maps(
                out.with_suffix(".png"),
                runs,
                np.asarray(read_gps("victoria-park")),
                title="EKF-SLAM on Victoria Park: NN, JCBB, clique association",
                errors=errors,
            )
    except Exception as exc:  # pragma: no cover - plotting optional
        print(f"figure not written: {exc}", file=sys.stderr)
    for r in vp:
        r.pop("_plot", None)
    result = {
        "command": " ".join(["python", "benchmarks/slam.py", *(argv or sys.argv[1:])]),
        "closure_crowding": args.closure_crowding,
        **provenance(t0),
        "victoria_park": vp,
        "nees": nees,
        "nees_runs": [{k: v for k, v in s.items() if k != "nees_obs_steps"} for s in sims],
        "room": room,
        "room_runs": [{k: v for k, v in s.items() if k != "nees_obs_steps"} for s in rooms],
        "landmark_logs": log_runs,
    }
    log_lines, log_ratios = log_table(log_runs)
    out.with_suffix(".json").write_text(json.dumps(result, indent=2) + "\n")
    md = [
        "# EKF-SLAM on Victoria Park (benchmarks/slam.py)",
        "",
        f"`{result['command']}`",
        "",
        *lines,
        "",
        *ratio_lines,
        "",
        "## Where the GPS error lies (best SE(2) alignment, per fix; the figure's lower panel)",
        "",
        *diag_lines,
        "",
        "## NEES of the vehicle pose on simulated tree parks",
        "",
        *nees_lines,
        "",
        "## Simulated rooms (simulate_room: unicycle robot, point landmarks without attributes)",
        "",
        *room_lines,
        "",
        "## Landmark logs (--logs: against each log's truth)",
        "",
        *(log_lines if log_runs else ["(none given)"]),
        "",
        *log_ratios,
        "",
    ]
    out.with_suffix(".md").write_text("\n".join(md) + "\n")
    print("\n".join(lines))
    print()
    print("\n".join(ratio_lines))
    print()
    print("\n".join(diag_lines))
    print()
    print("\n".join(nees_lines))
    print()
    print("\n".join(room_lines))
    if log_runs:
        print()
        print("\n".join(log_lines))
        print()
        print("\n".join(log_ratios))
    print(f"\nwrote {out.with_suffix('.json')}, .md, .png in {time.perf_counter() - t0:.0f} s")


if __name__ == "__main__":
    main()
