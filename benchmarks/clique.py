"""Maximum clique: scanclique against igraph (cliquer), networkx and cliquematch, in one run.

One command::

    .venv/bin/python benchmarks/clique.py                      # everything, 60 s per solve
    .venv/bin/python benchmarks/clique.py --graphs brock200_1 sanr200_0.9 --time-limit 20
    .venv/bin/python benchmarks/clique.py --no-dimacs --pairs 40   # scan pairs only

Graphs: the 27 DIMACS instances of ``$SCANCLIQUE_DATA/dimacs`` (default ``../shared/data``
beside the repository; the clique number is checked against ``omega.txt``), and
correspondence graphs of real scan pairs built by the pipeline (when
``scanclique.correspondence`` is available).

Method. Each solver gets the graph in its own native form, built before the clock starts
(ours: the boolean adjacency matrix, which is what the pipeline hands over). Every solve
runs in a forked child process, so that a solver which overruns the limit can be stopped:
a timeout counts as the limit (60 s). The time is the CPU time of the solve call in the
child (the solvers are single-threaded; CPU time is steadier than wall time on a shared
machine); solves under 0.2 s are repeated and the median taken. Our compiled kernels are
loaded before the fork, and their one-off cost (cache load, compilation) is reported
separately. Ratios are ours / peer: below 1 we are faster.
"""

from __future__ import annotations

import argparse
import math
import multiprocessing as mp
import os
import statistics
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO / "src"))

from scanclique.clique import max_clique  # noqa: E402
from scanclique.io.dimacs import read_dimacs  # noqa: E402

PEERS = ("igraph", "networkx", "cliquematch")


def data_dir() -> Path:
    return Path(os.environ.get("SCANCLIQUE_DATA", REPO.parent / "shared" / "data"))


@dataclass
class Graph:
    name: str
    adj: np.ndarray
    edges: np.ndarray  # (m, 2) 0-based, u < v
    omega: int | None  # known clique number, if any

    @property
    def n(self) -> int:
        return int(self.adj.shape[0])

    @property
    def density(self) -> float:
        n = self.n
        return 0.0 if n < 2 else 2.0 * len(self.edges) / (n * (n - 1))


# --------------------------------------------------------------------------------------
# Solvers: build (untimed) and solve (timed); each returns the clique number found
# --------------------------------------------------------------------------------------
def _build(solver: str, g: Graph):
    if solver == "ours":
        return g.adj
    if solver == "igraph":
        import igraph

        return igraph.Graph(n=g.n, edges=g.edges.tolist())
    if solver == "networkx":
        import networkx as nx

        G = nx.Graph()
        G.add_nodes_from(range(g.n))
        G.add_edges_from(g.edges.tolist())
        return G
    if solver == "cliquematch":
        import cliquematch

        # cliquematch numbers vertices from 1 (0 is its sentinel)
        return cliquematch.Graph.from_edgelist((g.edges + 1).astype(np.uint64), g.n)
    raise ValueError(solver)


def _solve(solver: str, G, time_limit: float) -> tuple[int, int | None]:
    if solver == "ours":
        r = max_clique(G, time_limit=time_limit)
        return (r.size if r.optimal else -1), r.nodes
    if solver == "igraph":
        return G.clique_number(), None
    if solver == "networkx":
        import networkx as nx

        _, w = nx.max_weight_clique(G, weight=None)
        return int(w), None
    if solver == "cliquematch":
        G.reset_search()
        return len(G.get_max_clique()), None  # defaults: exact (heuristic, then DFS)
    raise ValueError(solver)


def _child(conn, solver: str, g: Graph, time_limit: float, min_time: float) -> None:
    try:
        G = _build(solver, g)
        times = []
        omega = nodes = None
        while True:
            c0 = time.process_time()
            omega, nodes = _solve(solver, G, time_limit)
            times.append(time.process_time() - c0)
            if sum(times) >= min_time or len(times) >= 200:
                break
        conn.send(("ok", omega, statistics.median(times), nodes, len(times)))
    except Exception as e:  # reported in the table, never fatal
        conn.send(("error", f"{type(e).__name__}: {e}", None, None, 0))
    finally:
        conn.close()


def run_one(solver: str, g: Graph, time_limit: float, min_time: float = 0.2):
    """Solve in a forked child; returns dict(status, omega, seconds, nodes)."""
    ctx = mp.get_context("fork")
    recv, send = ctx.Pipe(duplex=False)
    p = ctx.Process(target=_child, args=(send, solver, g, time_limit, min_time))
    p.start()
    send.close()
    # the child may repeat a fast solve; allow for its building time too
    if recv.poll(time_limit + 5.0):
        status, omega, sec, nodes, reps = recv.recv()
        p.join()
        if status == "error":
            return {"status": "error", "message": omega, "seconds": time_limit}
        if omega == -1:  # ours hit its own limit
            return {"status": "timeout", "seconds": time_limit, "nodes": nodes}
        return {"status": "ok", "omega": omega, "seconds": sec, "nodes": nodes, "reps": reps}
    p.kill()
    p.join()
    return {"status": "timeout", "seconds": time_limit}


def available_peers(wanted) -> tuple[list[str], list[str]]:
    have, notes = [], []
    for peer in wanted:
        mod = {"igraph": "igraph", "networkx": "networkx", "cliquematch": "cliquematch"}[peer]
        try:
            __import__(mod)
            have.append(peer)
        except ImportError:
            pip = {"igraph": "python-igraph"}.get(peer, peer)
            notes.append(f"{peer}: not installed, skipped (pip install {pip})")
    return have, notes


# --------------------------------------------------------------------------------------
# Graphs
# --------------------------------------------------------------------------------------
def dimacs_graphs(names=None) -> tuple[list[Graph], str | None]:
    d = data_dir() / "dimacs"
    table = d / "omega.txt"
    if not table.exists():
        return [], f"DIMACS graphs: {d} not found (set SCANCLIQUE_DATA); section skipped"
    omega = {}
    for ln in table.read_text().splitlines():
        if ln.strip() and not ln.startswith("#"):
            name, _, w = ln.split()[:3]
            omega[name] = int(w)
    out = []
    for name in omega:
        if names and name not in names:
            continue
        dg = read_dimacs(d / f"{name}.clq")
        out.append(Graph(name, dg.adjacency(), dg.edges, omega[name]))
    return out, None


# ---- HOOK: correspondence graphs of real scan pairs -----------------------------------
# Built by the pipeline itself (scanclique.correspondence.correspondence_graph over the
# feature graphs of two scans). Skipped with a message when that module, the log or the
# pipeline's helpers are missing.
def correspondence_graphs(n_pairs: int, log_name: str = "intel") -> tuple[list[Graph], str | None]:
    try:
        from scanclique.correspondence import correspondence_graph
        from scanclique.datasets import load_log
        from scanclique.match import prepare_scan
    except ImportError as e:
        return [], f"correspondence graphs: pipeline not available ({e}); section skipped"
    try:
        scans = load_log(log_name)
    except Exception as e:  # DataNotFoundError, ParseError
        return [], f"correspondence graphs: cannot load the {log_name} log ({e}); section skipped"
    rng = np.random.default_rng(0)
    out = []
    half = max(n_pairs // 2, 1)
    # consecutive pairs, spread over the log, and pairs five scans apart
    firsts = np.linspace(0, len(scans) - 6, half).astype(int)
    pairs = [(int(i), int(i) + 1) for i in firsts] + [(int(i), int(i) + 5) for i in firsts]
    rng.shuffle(pairs)
    prepared = {}
    for i, j in sorted(pairs[:n_pairs]):
        for k in (i, j):
            if k not in prepared:
                prepared[k] = prepare_scan(scans[k])
        cg = correspondence_graph(prepared[i].graph, prepared[j].graph)
        adj = np.ascontiguousarray(cg.adjacency)
        iu, ju = np.nonzero(np.triu(adj, 1))
        out.append(Graph(f"{log_name}:{i}-{j}", adj, np.stack([iu, ju], 1), None))
    return out, None


# --------------------------------------------------------------------------------------
# First-call cost
# --------------------------------------------------------------------------------------
_FIRST = (
    "import time; t = time.perf_counter();"
    "import numpy as np; from scanclique.clique import max_clique, top_cliques;"
    "max_clique(np.zeros((2, 2), bool)); max_clique(np.zeros((2, 2), bool), weights=[1, 1]);"
    "top_cliques(np.zeros((2, 2), bool), 1); print(time.perf_counter() - t)"
)


def first_call_cost(compile_too: bool) -> list[str]:
    env = dict(os.environ, PYTHONPATH=str(REPO / "src"))
    lines = []
    r = subprocess.run([sys.executable, "-c", _FIRST], env=env, capture_output=True, text=True)
    if r.returncode == 0:
        lines.append(f"first call, kernels cached: {float(r.stdout):.2f} s (import + cache load)")
    if compile_too:
        with tempfile.TemporaryDirectory() as tmp:
            env["NUMBA_CACHE_DIR"] = tmp
            r = subprocess.run(
                [sys.executable, "-c", _FIRST], env=env, capture_output=True, text=True
            )
        if r.returncode == 0:
            lines.append(f"first call, empty cache:    {float(r.stdout):.2f} s (numba compilation)")
    return lines


# --------------------------------------------------------------------------------------
# Table
# --------------------------------------------------------------------------------------
def _fmt_t(res, limit) -> str:
    if res["status"] == "timeout":
        return f">{limit:g}"
    if res["status"] == "error":
        return "error"
    s = res["seconds"]
    return f"{s:.2e}" if s < 0.01 else f"{s:.3f}"


def _gmean(xs) -> float:
    xs = [x for x in xs if x > 0 and math.isfinite(x)]
    return math.exp(sum(math.log(x) for x in xs) / len(xs)) if xs else float("nan")


def section(title: str, graphs: list[Graph], peers: list[str], limit: float) -> list[str]:
    rows, notes = [], []
    ratios = {p: [] for p in peers}
    best_ratios = []
    faster = {p: 0 for p in peers}
    ours_times = []
    for g in graphs:
        res = {"ours": run_one("ours", g, limit)}
        for p in peers:
            res[p] = run_one(p, g, limit)
        t_ours = res["ours"]["seconds"]
        ours_times.append(t_ours)
        flags = []
        for s, r in res.items():
            if r["status"] == "error":
                notes.append(f"{g.name}: {s} failed: {r['message']}")
            elif r["status"] == "ok" and g.omega is not None and r["omega"] != g.omega:
                flags.append(f"{s} found {r['omega']} != omega {g.omega}")
        ok_peers = [p for p in peers if res[p]["status"] != "error"]
        cells = [g.name, str(g.n), f"{g.density:.2f}"]
        om = res["ours"].get("omega", "?") if res["ours"]["status"] == "ok" else "?"
        cells += [str(om), _fmt_t(res["ours"], limit), str(res["ours"].get("nodes", ""))]
        for p in peers:
            cells.append(_fmt_t(res[p], limit))
            if p in ok_peers:
                q = t_ours / res[p]["seconds"]
                ratios[p].append(q)
                faster[p] += t_ours < res[p]["seconds"]
                cells.append(f"{q:.3g}")
            else:
                cells.append("-")
        if ok_peers:
            best = min(res[p]["seconds"] for p in ok_peers)
            best_ratios.append(t_ours / best)
            cells.append(f"{t_ours / best:.3g}")
        else:
            cells.append("-")
        if flags:
            notes.append(f"{g.name}: " + "; ".join(flags))
        rows.append(cells)
        print("  " + "  ".join(cells), file=sys.stderr, flush=True)
    head = ["graph", "n", "dens", "omega", "ours s", "nodes"]
    for p in peers:
        head += [f"{p} s", "ratio"]
    head.append("ours/best")
    summary = ["geo. mean"] + [""] * 5
    for p in peers:
        summary += ["", f"{_gmean(ratios[p]):.3g}"]
    summary.append(f"{_gmean(best_ratios):.3g}")
    rows.append(summary)
    out = [title, _table(head, rows)]
    out.append(
        f"ours: {sum(t <= 1 for t in ours_times)}/{len(graphs)} within 1 s, "
        f"{sum(t <= 10 for t in ours_times)}/{len(graphs)} within 10 s; "
        + ", ".join(f"faster than {p} on {faster[p]}/{len(ratios[p])}" for p in peers)
    )
    out += notes
    return out


def _table(head, rows) -> str:
    try:
        from rich.console import Console
        from rich.table import Table

        t = Table(show_lines=False)
        for h in head:
            t.add_column(h, justify="left" if h == "graph" else "right")
        for r in rows:
            t.add_row(*r)
        console = Console(width=250, record=True, force_terminal=False)
        with console.capture() as cap:
            console.print(t)
        return cap.get()
    except ImportError:
        widths = [max(len(str(r[i])) for r in [head] + rows) for i in range(len(head))]
        lines = [
            "  ".join(str(c).rjust(w) for c, w in zip(r, widths, strict=True))
            for r in [head] + rows
        ]
        return "\n".join(lines)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--time-limit", type=float, default=60.0, help="seconds per solver and graph")
    ap.add_argument("--graphs", nargs="*", help="DIMACS names to run (default: all 27)")
    ap.add_argument("--peers", nargs="*", default=list(PEERS), choices=PEERS)
    ap.add_argument("--pairs", type=int, default=20, help="scan pairs for correspondence graphs")
    ap.add_argument("--no-dimacs", action="store_true")
    ap.add_argument("--no-correspondence", action="store_true")
    ap.add_argument("--no-compile-cost", action="store_true", help="skip the empty-cache run")
    args = ap.parse_args(argv)

    peers, notes = available_peers(args.peers)
    max_clique(np.zeros((2, 2), dtype=bool))  # kernels loaded before the children fork
    report = [
        f"scanclique maximum clique benchmark — limit {args.time_limit:g} s per solve, "
        f"times are CPU seconds of the solve call (median of repeats under 0.2 s)",
        f"peers: {', '.join(peers) or 'none'}",
    ]
    report += notes
    report += first_call_cost(not args.no_compile_cost)
    if not args.no_dimacs:
        graphs, note = dimacs_graphs(args.graphs)
        if note:
            report.append(note)
        else:
            report += section("DIMACS (second challenge)", graphs, peers, args.time_limit)
    if not args.no_correspondence and args.pairs > 0:
        graphs, note = correspondence_graphs(args.pairs)
        if note:
            report.append(note)
        else:
            report += section(
                "Correspondence graphs of real scan pairs", graphs, peers, args.time_limit
            )
    print("\n".join(report))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
