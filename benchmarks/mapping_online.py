"""Online mapping (``OnlineMapper``): how soon and how well each scan is placed as it
comes, on the raw logs of Kümmerle et al. 2009, beside the batch map of the same scans.

One command::

    python benchmarks/mapping_online.py
    python benchmarks/mapping_online.py --logs fr079-raw --modes odometry --out /tmp/online

Per log (``fr079-raw``, ``intel-raw``) and mode (``odometry``: with the wheel odometry;
``scans``: without it, the paper's point), in one run:

* ``batch``: :func:`~scanclique.mapping.map_scans` over the whole log with the online
  mapper's configuration, :meth:`MapConfig.online` (the reference);
* ``online``: :class:`~scanclique.mapping.OnlineMapper` fed the scans in recording order,
  as a driver would (:func:`~scanclique.mapping.map_online`), with its defaults (the
  odometry's reversing told as the scans come);
  ``online-2-workers``: the same with the loop verification on a second process.

Columns:

* ``identical``: the finished online map is the batch map, pose for pose;
* ``add ms``: the time :meth:`OnlineMapper.add` took per scan (median, 95th and 99th
  percentile, max); ``in period``: the fraction of scans answered within the log's median
  time between scans;
* ``lag s``: the log replayed at its recorded rate (scan ``j`` arrives at its timestamp;
  the mapper takes it once done with the previous one): the time from a scan's arrival
  to its answer, median and max, and at the last scan (whether it keeps up);
* relation errors (the benchmark's metric: mean |translation| m and |angle| deg over all
  relations, and the translation mean over those spanning <= 10 s and > 10 s) of:
  ``known then``, each relation's later scan as ``add`` answered it, against the earlier
  scan's pose *in the same estimate* (where the robot, when it took the later scan, put
  itself relative to a place it had seen: what a robot navigating by its map uses);
  ``live``, each scan's pose as ``add`` answered it, the two ends of a relation taken
  from the estimates of their own times (a long relation then mixes two estimates of the
  map, before and after the closures between them moved it); ``finished``, the map after
  :meth:`OnlineMapper.finish` (the batch map); ``chained``, the front end alone (no
  closures).

Writes benchmarks/results/mapping-online-<date>.json and .md.
"""

from __future__ import annotations

import argparse
import datetime
import math
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

import common  # noqa: E402
from mapping import _fmt  # noqa: E402 (the mapping benchmark's cell format)

from scanclique import datasets  # noqa: E402
from scanclique.eval import frame_mounting, read_relations, relation_metrics  # noqa: E402
from scanclique.eval.relations import (  # noqa: E402
    SplitErrors,
    join_relations,
    relation_errors,
)
from scanclique.mapping import MapConfig, map_online, map_scans  # noqa: E402

LOGS = ("fr079-raw", "intel-raw")
MODES = {"odometry": True, "scans": False}
RUNS = (("online", 1), ("online-2-workers", 2))


def _poses(poses) -> np.ndarray:
    return np.array([[math.nan] * 3 if p is None else p.as_array() for p in poses])


def _errors(rels, poses, ts, mounting) -> dict:
    return _means(relation_metrics(rels, list(poses), ts, mounting=mounting))


def _means(m: SplitErrors) -> dict:
    return {
        "all_m": m.all.translation_mean,
        "all_deg": m.all.rotation_mean,
        "short_m": m.short.translation_mean,
        "long_m": m.long.translation_mean,
    }


def lag(timestamps: np.ndarray, seconds: np.ndarray) -> np.ndarray:
    """Per scan, the time (s) from its arrival to its answer when the log is replayed at
    its recorded rate: scan ``j`` arrives at ``timestamps[j]``, is taken when it has
    arrived and the previous one is answered, and takes ``seconds[j]``.

    >>> lag(np.array([0.0, 0.1, 0.2]), np.array([0.05, 0.2, 0.05])).round(3).tolist()
    [0.05, 0.2, 0.15]
    """
    done, out = -math.inf, np.empty(len(seconds))
    for j, (t, s) in enumerate(zip(timestamps, seconds, strict=True)):
        done = max(done, t) + s
        out[j] = done - t
    return out


def known_then(rels, ts, mounting):
    """A ``watch`` for :func:`map_online` that keeps, for each relation, both of its scans'
    poses in the estimate of the moment its later scan was added, and the function that
    gives their errors (:func:`_errors`' keys) once the run is done."""
    ij, _ = join_relations(rels, ts)
    later: dict[int, list] = {}
    for k, (a, b) in enumerate(ij.tolist()):
        if a >= 0 and b >= 0:
            later.setdefault(max(a, b), []).append((k, min(a, b)))
    kept: dict[int, tuple] = {}

    def watch(mapper, j: int) -> None:
        for k, a in later.get(j, ()):
            kept[k] = (a, mapper.pose(a), j, mapper.pose(j))

    def errors() -> dict:
        per = [
            relation_errors([rels[k]], {ts[a]: pa, ts[b]: pb}, mounting=mounting)
            for k, (a, pa, b, pb) in kept.items()
        ]
        t, r, span = (np.array([e[i][0] for e in per]) for i in range(3))
        return _means(SplitErrors.of(t, r, span))

    return watch, errors


def run_log(name: str, modes: list[str], limit: int | None = None) -> list[dict]:
    scans = datasets.load_log(name)[:limit]
    rels = read_relations(datasets.data_dir() / datasets.DATASETS[name].relations)
    mounting = frame_mounting(scans)
    ts = np.array([s.timestamp for s in scans])
    period = float(np.median(np.diff(ts)))
    rows = []
    for mode in modes:
        use = MODES[mode]
        t = time.perf_counter()
        # the online mapper's defaults (MapConfig.online()), so that "identical" compares
        # like with like; the batch defaults' map is benchmarks/mapping.py's
        batch = map_scans(scans, use_odometry=use, config=MapConfig.online())
        wall = time.perf_counter() - t
        ref = _poses(batch.poses)
        base = {"log": name, "mode": mode, "scans": len(scans), "period_s": period,
                "limit": limit}  # fmt: skip
        rows.append(
            {**base, "run": "batch", "seconds": wall, "closures": len(batch.accepted_closures),
             "finished": _errors(rels, batch.poses, ts, mounting),
             "chained": _errors(rels, batch.chained, ts, mounting)}
        )  # fmt: skip
        print(f"{name} {mode} batch: {wall:.1f} s", flush=True)
        for run, workers in RUNS:
            watch, then_errors = known_then(rels, ts, mounting)
            run_ = map_online(scans, use_odometry=use, workers=workers, watch=watch)
            result, live, took, finish = (
                run_.result,
                run_.live,
                run_.add_seconds,
                run_.finish_seconds,
            )
            lags = lag(ts - ts[0], took)
            row = {
                **base,
                "run": run,
                "seconds": float(took.sum() + finish),
                "finish_s": finish,
                "identical": bool(np.array_equal(_poses(result.poses), ref, equal_nan=True)),
                "closures": len(result.accepted_closures),
                "add_ms": {
                    q: float(np.percentile(took, p) * 1e3)
                    for q, p in (("p50", 50), ("p95", 95), ("p99", 99), ("max", 100))
                },
                "in_period": float(np.mean(took <= period)),
                "lag_s": {
                    "p50": float(np.median(lags)),
                    "max": float(lags.max()),
                    "end": float(lags[-1]),
                },  # fmt: skip
                "known_then": then_errors(),
                "live": _errors(rels, live, ts, mounting),
                "finished": _errors(rels, result.poses, ts, mounting),
            }
            rows.append(row)
            a = row["add_ms"]
            print(f"{name} {mode} {run}: {row['seconds']:.1f} s, identical {row['identical']}, "
                  f"add ms {a['p50']:.1f} / {a['p95']:.1f} / {a['max']:.0f}, known then "
                  f"{row['known_then']['all_m']:.4f} m, live {row['live']['all_m']:.4f} m",
                  flush=True)  # fmt: skip
    return rows


def table(rows: list[dict]) -> list[str]:
    out = [
        "| log | mode | run | wall s | x batch | identical | add ms p50 / p95 / p99 / max "
        "| in period | lag s p50 / max / end | closures |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    batch = {(r["log"], r["mode"]): r["seconds"] for r in rows if r["run"] == "batch"}
    for r in rows:
        x = r["seconds"] / batch[(r["log"], r["mode"])]
        if r["run"] == "batch":
            out.append(f"| {r['log']} | {r['mode']} | batch | {r['seconds']:.1f} | 1.00 | | | "
                       f"| | {r['closures']} |")  # fmt: skip
            continue
        a, g = r["add_ms"], r["lag_s"]
        out.append(
            f"| {r['log']} | {r['mode']} | {r['run']} | {r['seconds']:.1f} | {x:.2f} | "
            f"{r['identical']} | {a['p50']:.1f} / {a['p95']:.1f} / {a['p99']:.1f} / "
            f"{a['max']:.0f} | {100 * r['in_period']:.1f} % | {g['p50']:.3f} / "
            f"{g['max']:.2f} / {g['end']:.3f} | {r['closures']} |"
        )
    out += [
        "",
        "Relation errors (mean; m and deg over all relations, m over <= 10 s and > 10 s):",
        "",
        "| log | mode | trajectory | all m | all deg | <= 10 s m | > 10 s m |",
        "|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        if r["run"] == "batch":
            kinds = ("finished", "chained")
        else:  # the finished online map too when it is not the batch map
            kinds = ("known_then", "live") + (() if r["identical"] else ("finished",))
        for k in kinds:
            e = r[k]
            label = k.replace("_", " ")
            label = label if r["run"] == "batch" else f"{label} ({r['run']})"
            out.append(
                f"| {r['log']} | {r['mode']} | {label} | {_fmt(e['all_m'])} | "
                f"{_fmt(e['all_deg'], '.3f')} | {_fmt(e['short_m'])} | {_fmt(e['long_m'])} |"
            )
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--logs", default=",".join(LOGS))
    ap.add_argument("--modes", default=",".join(MODES), help="odometry, scans or both")
    ap.add_argument("--limit", type=int, default=None, help="first N scans only (a quick look)")
    ap.add_argument("--out", help="results path without suffix")
    args = ap.parse_args(argv)
    modes = [m for m in args.modes.split(",") if m]
    for m in modes:
        if m not in MODES:
            ap.error(f"--modes: unknown mode {m!r} (known: {', '.join(MODES)})")
    t0 = time.perf_counter()
    rows = []
    for name in filter(None, args.logs.split(",")):
        if not common.log_available(name, LOGS, ": the logs with the benchmark's relations"):
            continue
        rows += run_log(name, modes, args.limit)
    date = datetime.date.today().isoformat()
    base = common.results_path(args.out, f"mapping-online-{date}")
    head = [
        "# Online mapping (benchmarks/mapping_online.py)",
        "",
        "OnlineMapper fed each log's scans in order beside map_scans over the whole log. "
        "Lag: the log replayed at its recorded rate.",
        "",
    ]
    text = "\n".join(head + table(rows)) + "\n" if rows else "no log found\n"
    print(text)
    if rows:
        common.write_results(base, text, t0, rows)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
