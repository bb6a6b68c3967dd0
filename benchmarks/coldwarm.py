"""Results do not depend on the kernel cache (issue 15 item 3): the same matches in a
process whose numba cache is cold (a fresh ``NUMBA_CACHE_DIR``: every kernel compiles
during the run) and in one whose cache is warm give identical results.

It also measures what a first run costs: the seconds numba spends compiling (its own
``numba:compile`` events, outermost only) and how many specialisations it compiles.

One command::

    python benchmarks/coldwarm.py            # 200 benchmark pairs + the README's examples
    python benchmarks/coldwarm.py --pairs 50
    python benchmarks/coldwarm.py --compare /tmp/old/src   # another checkout's src, side by side

Runs itself twice in subprocesses with the same fresh cache directory (first cold, then
warm), each writing every match's pose, clique size, number of hypotheses and whether a
budget stopped the clique search, then compares the two runs field by field. With
``--compare``, the other source tree runs the same way (its own fresh cache) before this
one, the first-run figures are printed side by side with their ratios, and the matches of
the two trees are compared as well.
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


def _matches(pairs_file: str) -> tuple[bool, list[dict]]:
    """Whether the kernel cache was cold, and a record of each match of ``pairs_file``."""
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
    return cold, rows


def _run(pairs_file: str, out_file: str) -> None:
    """The child: the matches, and numba's compilation while they ran (seconds of the
    outermost compile events, and every specialisation compiled)."""
    from numba.core import event

    with event.install_recorder("numba:compile") as compiled:
        cold, rows = _matches(pairs_file)
    depth, compile_s, n_spec, start = 0, 0.0, 0, 0.0
    for t, ev in compiled.buffer:
        if ev.is_start:
            n_spec += 1
            depth += 1
            start = t if depth == 1 else start
        else:
            depth -= 1
            compile_s += (t - start) if depth == 0 else 0.0
    Path(out_file).write_text(
        json.dumps({"cold": cold, "rows": rows, "compile_s": compile_s, "compiled": n_spec})
    )


def _cold_then_warm(src: str | None, pairs_file: Path, tmp: Path, tag: str) -> dict:
    """The two runs of one source tree (None: the installed scanclique) in a fresh cache."""
    env = dict(os.environ, NUMBA_CACHE_DIR=str(tmp / f"cache-{tag}"))
    env.pop("SCANCLIQUE_KERNEL_CACHE", None)
    if src is not None:
        env["PYTHONPATH"] = os.pathsep.join([src, env.get("PYTHONPATH", "")]).rstrip(os.pathsep)
    out = {}
    for run in ("cold", "warm"):
        t0 = time.perf_counter()
        subprocess.run(
            [sys.executable, __file__, "--child", str(pairs_file), str(tmp / f"{tag}-{run}.json")],
            env=env,
            check=True,
        )
        got = json.loads((tmp / f"{tag}-{run}.json").read_text())
        got["seconds"] = time.perf_counter() - t0
        out[run] = got
    return out


def _differences(a: list, b: list) -> list:
    return [
        (x["pair"], k, x[k], y[k]) for x, y in zip(a, b, strict=True) for k in x if x[k] != y[k]
    ]


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    ap.add_argument("--pairs", type=int, default=200)
    ap.add_argument(
        "--compare", metavar="SRC", help="another checkout's src directory, run side by side"
    )
    ap.add_argument("--child", nargs=2, help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.child:
        _run(*args.child)
        return 0
    tmp = Path(tempfile.mkdtemp(prefix="scanclique-coldwarm-"))
    pairs_file = tmp / "pairs.json"
    pairs_file.write_text(json.dumps(_pairs(args.pairs)))
    other = _cold_then_warm(args.compare, pairs_file, tmp, "other") if args.compare else None
    this = _cold_then_warm(None, pairs_file, tmp, "this")
    diff = _differences(this["cold"]["rows"], this["warm"]["rows"])
    n = len(this["cold"]["rows"])
    state = {r: "cold" if this[r]["cold"] else "warm" for r in ("cold", "warm")}
    print(
        f"coldwarm: {n} matches ({len(README_PAIRS)} README examples + {n - len(README_PAIRS)} "
        f"benchmark pairs); first run {this['cold']['seconds']:.0f} s (cache {state['cold']}), "
        f"second run {this['warm']['seconds']:.0f} s (cache {state['warm']}); fields that "
        f"differ: {len(diff)}"
    )
    for d in diff[:20]:
        print("  differs:", d)
    stopped = sum(1 for r in this["cold"]["rows"] if r["stopped"])
    print(f"coldwarm: clique searches stopped by a budget: {stopped} of {n}")
    print(
        f"coldwarm: first run compiled {this['cold']['compiled']} specialisations in "
        f"{this['cold']['compile_s']:.1f} s; the second compiled {this['warm']['compiled']}"
    )
    if other is not None:
        vs = _differences(other["cold"]["rows"], this["cold"]["rows"])
        print(f"\n| first run | {args.compare} | this checkout | ratio |\n|---|---|---|---|")
        for label, key in (
            ("wall, s", "seconds"),
            ("compiling, s", "compile_s"),
            ("specialisations", "compiled"),
        ):
            a, b = other["cold"][key], this["cold"][key]
            print(
                f"| {label} | {a:.1f} | {b:.1f} | {b / a:.2f} |"
                if a
                else f"| {label} | {a} | {b} | |"
            )
        a, b = other["warm"]["seconds"], this["warm"]["seconds"]
        print(f"| second run (warm), wall, s | {a:.1f} | {b:.1f} | {b / a:.2f} |")
        print(f"coldwarm: fields that differ between the two trees' matches: {len(vs)}")
        for d in vs[:20]:
            print("  differs:", d)
        diff = diff + vs
    return 0 if not diff else 1


if __name__ == "__main__":
    raise SystemExit(main())
