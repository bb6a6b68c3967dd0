"""Results do not depend on the kernel cache (issue 15 item 3): the same matches in a
process whose numba cache is cold (a fresh ``NUMBA_CACHE_DIR``: every kernel compiles
during the run) and in one whose cache is warm give identical results.

One command::

    python benchmarks/coldwarm.py            # 200 benchmark pairs + the README's examples
    python benchmarks/coldwarm.py --pairs 50

Runs itself twice in subprocesses with the same fresh cache directory (first cold, then
warm), each writing every match's pose, clique size, number of hypotheses and whether a
budget stopped the clique search, then compares the two runs field by field.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

README_PAIRS = [("intel", 120, 121), ("intel", 120, 125), ("intel", 11, 12), ("intel", 0, 5)]


def _pairs(n: int) -> list[tuple[str, int, int]]:
    import pairs as P

    from scanclique.datasets import load_log

    out = list(README_PAIRS)
    for log in ("intel", "csail", "freiburg"):
        sets = P.pair_sets(load_log(log), cap=max(1, n // 9), seed=0)
        for plist in sets.values():
            out += [(log, i, j) for i, j in plist]
    return out[: len(README_PAIRS) + n]


def _run(pairs_file: str, out_file: str) -> None:
    from scanclique._lazy import cache_is_cold
    from scanclique.datasets import load_log
    from scanclique.match import match_scans

    todo = json.loads(Path(pairs_file).read_text())
    cold = cache_is_cold()
    logs: dict = {}
    rows = []
    for log, i, j in todo:
        scans = logs.setdefault(log, load_log(log))
        m = match_scans(scans[i], scans[j])
        rows.append(
            {
                "pair": [log, i, j],
                "pose": None if m.pose is None else [m.pose.x, m.pose.y, m.pose.theta],
                "clique": m.clique_size,
                "omega": m.omega,
                "optimal": m.optimal,
                "hypotheses": len(m.hypotheses),
                "stopped": m.stopped,
                "nodes": m.clique_nodes,
            }
        )
    Path(out_file).write_text(json.dumps({"cold": cold, "rows": rows}))


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    ap.add_argument("--pairs", type=int, default=200)
    ap.add_argument("--child", nargs=2, help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.child:
        _run(*args.child)
        return 0
    tmp = Path(tempfile.mkdtemp(prefix="scanclique-coldwarm-"))
    pairs_file = tmp / "pairs.json"
    pairs_file.write_text(json.dumps(_pairs(args.pairs)))
    env = dict(os.environ, NUMBA_CACHE_DIR=str(tmp / "cache"))
    env.pop("SCANCLIQUE_KERNEL_CACHE", None)
    results, seconds, state = {}, {}, {}
    for run in ("cold", "warm"):
        t0 = time.perf_counter()
        subprocess.run(
            [sys.executable, __file__, "--child", str(pairs_file), str(tmp / f"{run}.json")],
            env=env,
            check=True,
        )
        seconds[run] = time.perf_counter() - t0
        got = json.loads((tmp / f"{run}.json").read_text())
        results[run], state[run] = got["rows"], "cold" if got["cold"] else "warm"
    diff = [
        (c["pair"], k, c[k], w[k])
        for c, w in zip(results["cold"], results["warm"], strict=True)
        for k in c
        if c[k] != w[k]
    ]
    n = len(results["cold"])
    print(
        f"coldwarm: {n} matches ({len(README_PAIRS)} README examples + {n - len(README_PAIRS)} "
        f"benchmark pairs); first run {seconds['cold']:.0f} s (cache {state['cold']}), second "
        f"run {seconds['warm']:.0f} s (cache {state['warm']}); fields that differ: {len(diff)}"
    )
    for d in diff[:20]:
        print("  differs:", d)
    stopped = sum(1 for r in results["cold"] if r["stopped"])
    print(f"coldwarm: clique searches stopped by a budget: {stopped} of {n}")
    return 0 if not diff else 1


if __name__ == "__main__":
    raise SystemExit(main())
