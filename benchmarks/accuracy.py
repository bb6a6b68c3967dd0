"""Accuracy of scan-to-scan matching on the real CARMEN logs with reference poses.

One command::

    python benchmarks/accuracy.py                 # default sample: <= 400 pairs per set per log
    python benchmarks/accuracy.py --cap 0         # every pair (slow on freiburg)
    python benchmarks/accuracy.py --paper         # the paper's exact configuration
    python benchmarks/accuracy.py --no-refine     # default, without the ICP refinement
    python benchmarks/accuracy.py --no-search     # default, without the raw-scan pose search
    python benchmarks/accuracy.py --logs intel csail --jobs 2

For each log (intel, csail, freiburg) and pair set (consecutive, skip3, revisit; see
``pairs.py``) it prints the success rate (within 0.20 m and 2 deg of the reference), the
median translation and rotation errors, the median and 95th-percentile time per pair and
the median time per stage, then the pooled rates against the targets of issue #2. Time
per pair counts both scans' feature extraction as if each pair were matched alone.
Results go to ``benchmarks/results/accuracy-<date>.json`` with the machine and config.
Data: ``$SCANCLIQUE_DATA`` (default ``../shared/data``).
"""

from __future__ import annotations

import argparse
import dataclasses
import datetime as _dt
import json
import math
import os
import sys
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("NUMBA_NUM_THREADS", "1")

import numpy as np  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent))
import pairs as P  # noqa: E402
from common import chunks, error_summary, machine, pool_map, results_path  # noqa: E402

import scanclique as sc  # noqa: E402
from scanclique.config import config_to_dict  # noqa: E402
from scanclique.datasets import DataNotFoundError, load_log  # noqa: E402
from scanclique.match import STAGES, match_prepared, prepare_scan  # noqa: E402

TARGETS = {"consecutive": 0.95, "skip3": 0.80, "revisit": 0.85}
LOGS = ("intel", "csail", "freiburg")

_cache: dict = {}


def make_config(paper: bool, refine: bool, search: bool = True) -> sc.MatchConfig:
    cfg = sc.paper_config() if paper else sc.MatchConfig()
    if not refine:
        cfg = dataclasses.replace(cfg, refine=dataclasses.replace(cfg.refine, enabled=False))
    if not search:
        cfg = dataclasses.replace(cfg, refine=dataclasses.replace(cfg.refine, search=False))
    return cfg


def _worker(args):
    """Match a chunk of pairs of one log; returns one record per pair."""
    log_name, pair_list, paper, refine, search = args
    cfg = make_config(paper, refine, search)
    if log_name not in _cache:
        _cache.clear()
        _cache[log_name] = (load_log(log_name), {})
    scans, prepared = _cache[log_name]
    out = []
    for i, j in pair_list:
        for k in (i, j):
            if k not in prepared:
                prepared[k] = prepare_scan(scans[k], cfg)
        t0 = time.perf_counter()
        m = match_prepared(prepared[i], prepared[j], cfg)
        elapsed = time.perf_counter() - t0
        total = elapsed + sum(prepared[i].seconds.values()) + sum(prepared[j].seconds.values())
        ref = P.reference_pose(scans, i, j)
        if m.pose is None:
            t_err = r_err = math.inf
        else:
            t_err, r_err = m.pose.distance_to(ref)
        out.append(
            {
                "i": i,
                "j": j,
                "t_err": t_err,
                "r_err": r_err,
                "success": P.is_success(t_err, r_err),
                "ms": 1e3 * total,
                "stages_ms": {k: 1e3 * v for k, v in m.seconds.items()},
                "clique": m.clique_size,
                "ambiguous": m.ambiguous,
                "score": m.score,
                "pose": None if m.pose is None else [m.pose.x, m.pose.y, m.pose.theta],
                "clique_nodes": m.clique_nodes,
                "stopped": m.stopped,
            }
        )
    return out


def summarise(records: list[dict]) -> dict:
    s = error_summary(records)
    if records:
        s["stages_median_ms"] = {
            k: float(np.median([r["stages_ms"][k] for r in records])) for k in STAGES
        }
    return s


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    ap.add_argument("--logs", nargs="+", default=list(LOGS))
    ap.add_argument("--cap", type=int, default=400, help="max pairs per set per log (0 = all)")
    ap.add_argument("--jobs", type=int, default=min(2, os.cpu_count() or 1))
    ap.add_argument("--paper", action="store_true", help="the paper's exact configuration")
    ap.add_argument("--no-refine", dest="refine", action="store_false", help="no ICP refinement")
    ap.add_argument(
        "--no-search", dest="search", action="store_false", help="no raw-scan pose search"
    )
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--out", default=None, help="JSON output path")
    args = ap.parse_args(argv)
    cap = None if args.cap <= 0 else args.cap

    results: dict = {}
    pooled: dict = {k: [] for k in TARGETS}
    t_start = time.perf_counter()
    with ProcessPoolExecutor(max_workers=args.jobs) as ex:
        for name in args.logs:
            try:
                scans = load_log(name)
            except DataNotFoundError as exc:
                print(f"skip {name}: {exc}")
                continue
            sets = P.pair_sets(scans, cap, args.seed)
            results[name] = {}
            for set_name, plist in sets.items():
                jobs = [
                    (name, c, args.paper, args.refine, args.search)
                    for c in chunks(plist, args.jobs)
                ]
                recs = pool_map(ex, _worker, jobs)
                recs.sort(key=lambda r: (r["i"], r["j"]))
                s = summarise(recs)
                results[name][set_name] = {"summary": s, "pairs": recs}
                pooled[set_name].extend(recs)
                if s["n"]:
                    st = " ".join(f"{k} {v:.1f}" for k, v in s["stages_median_ms"].items())
                    rate = 100 * s["success"]
                    print(
                        f"{name:9s} {set_name:12s} n={s['n']:4d} success {rate:5.1f}%  "
                        f"median err {s['median_t_err']:.3f} m {s['median_r_err_deg']:.2f} deg  "
                        f"time median {s['median_ms']:.1f} ms p95 {s['p95_ms']:.1f} ms  "
                        f"[stages ms: {st}]",
                        flush=True,
                    )
    print()
    ok = True
    summary_pooled = {}
    for set_name, target in TARGETS.items():
        s = summarise(pooled[set_name])
        summary_pooled[set_name] = s
        if not s["n"]:
            continue
        passed = s["success"] >= target
        ok &= passed
        print(
            f"ALL       {set_name:12s} n={s['n']:4d} success {100 * s['success']:5.1f}% "
            f"(target >= {100 * target:.0f}%: {'met' if passed else 'NOT met'})  "
            f"median err {s['median_t_err']:.3f} m {s['median_r_err_deg']:.2f} deg  "
            f"time median {s['median_ms']:.1f} ms p95 {s['p95_ms']:.1f} ms"
        )
    print(f"wall time {time.perf_counter() - t_start:.0f} s with {args.jobs} processes")

    out = results_path(
        args.out,
        f"accuracy-{'paper-' if args.paper else ''}{'' if args.refine else 'norefine-'}"
        f"{'' if args.search else 'nosearch-'}"
        f"{_dt.date.today().isoformat()}.json",
    )
    out.parent.mkdir(parents=True, exist_ok=True)
    cfg = make_config(args.paper, args.refine, args.search)
    doc = {
        "date": _dt.datetime.now().isoformat(timespec="seconds"),
        "machine": machine(),
        "scanclique": sc.__version__,
        "cap": cap,
        "config": config_to_dict(cfg),
        "pooled": summary_pooled,
        "logs": {n: {k: v["summary"] for k, v in d.items()} for n, d in results.items()},
    }
    out.write_text(json.dumps(doc, indent=1, default=float))
    print(f"wrote {out}")
    per_pair = Path(__file__).resolve().parent / "out" / out.name.replace(".json", "-pairs.json")
    per_pair.parent.mkdir(parents=True, exist_ok=True)
    per_pair.write_text(
        json.dumps(
            {n: {k: v["pairs"] for k, v in d.items()} for n, d in results.items()}, default=float
        )
    )
    print(f"wrote {per_pair} (per-pair records, not committed)")
    return 0 if ok else 1


if __name__ == "__main__":
    raise SystemExit(main())
