"""Maximum clique: scanclique against igraph (cliquer), networkx and cliquematch, in one run.

One command::

    .venv/bin/python benchmarks/clique.py                  # everything (hours: peers time out)
    .venv/bin/python benchmarks/clique.py --graphs brock200_1 sanr200_0.9 --time-limit 20
    .venv/bin/python benchmarks/clique.py --no-dimacs --pairs 5 --large 4 --time-limit 10
    .venv/bin/python benchmarks/clique.py --compare before.json after.json   # two runs of ours

Graphs
    * the 27 DIMACS instances of ``$SCANCLIQUE_DATA/dimacs`` (default ``../shared/data``
      beside the repository); every solver's clique number is checked against
      ``omega.txt``;
    * correspondence graphs of real scan pairs of the shared logs (intel, csail, freiburg),
      built by the pipeline (``scanclique.match.prepare_scan``, then
      ``scanclique.correspondence.correspondence_graph``) on the pair sets of
      ``benchmarks/pairs.py`` (consecutive, skip3, revisit):

      - *pipeline*: the default ``MatchConfig``, ``--pairs`` pairs per log and set;
      - *large*: permissive feature extraction (more, smaller features) and tolerances
        ``--loose`` times the defaults, on pairs where both scans have at least 60 features,
        ``--large`` pairs spread over csail and freiburg (intel scans rarely have 60).

      These have no published clique number: the solvers that finish must agree.

Method. Each solver gets the graph in its own native form, built before the clock starts
(ours: the boolean adjacency matrix, which is what the pipeline hands over; igraph: an
``igraph.Graph``; networkx: an ``nx.Graph``; cliquematch: ``Graph.from_edgelist``). Every
(solver, graph) runs in a forked child process with a CPU-time limit (60 s; ``RLIMIT_CPU``
stops a solver that overruns it, ours stops itself), and a timeout counts as the limit.
The time is the CPU time of the solve call (all solvers are single-threaded; CPU time is
steadier than wall time on a shared machine); a solve shorter than 0.2 s is repeated back
to back for 0.2 s and the mean taken.
Our compiled kernels are loaded before the fork; their one-off cost (compilation into an
empty cache, and loading from the cache) is measured separately, in fresh processes. A
final check runs our solver with a time limit on a graph it cannot finish (1000 vertices,
density 0.9) and reports the overshoot, and then with node limits (the budget that decides
results): each run twice, the two results must be identical. Ratios are ours / peer:
below 1 we are faster.

Output: the report on stdout and in ``benchmarks/results/clique-<date>.md``, all numbers
with the machine, versions and load average in ``clique-<date>.json``.
"""

from __future__ import annotations

import argparse
import datetime as _dt
import json
import math
import multiprocessing as mp
import os
import resource
import signal
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO / "src"))
sys.path.insert(0, str(REPO / "benchmarks"))

from common import git_state, machine, versions  # noqa: E402

from scanclique.clique import all_maximum_cliques, max_clique, top_cliques  # noqa: E402
from scanclique.io.dimacs import read_dimacs  # noqa: E402

PEERS = ("igraph", "networkx", "cliquematch")
LOGS = ("intel", "csail", "freiburg")
LARGE_LOGS = ("csail", "freiburg")
MIN_FEATURES = 60  # per scan, for the large correspondence graphs
LARGE_CAP = 60  # pairs per log and pair set searched for large graphs
MIN_TIME = 0.2  # seconds of back-to-back repeats for a fast solve


def data_dir() -> Path:
    return Path(os.environ.get("SCANCLIQUE_DATA", REPO.parent / "shared" / "data"))


@dataclass
class Graph:
    name: str
    group: str  # "dimacs", "pipeline" or "large"
    adj: np.ndarray
    edges: np.ndarray  # (m, 2) 0-based, u < v
    omega: int | None  # published clique number, if any

    @property
    def n(self) -> int:
        return int(self.adj.shape[0])

    @property
    def density(self) -> float:
        n = self.n
        return 0.0 if n < 2 else 2.0 * len(self.edges) / (n * (n - 1))


def _graph(name: str, group: str, adj: np.ndarray, omega=None) -> Graph:
    iu, ju = np.nonzero(np.triu(adj, 1))
    return Graph(name, group, adj, np.stack([iu, ju], 1).astype(np.int64), omega)


# --------------------------------------------------------------------------------------
# Solvers: build (untimed) and solve (timed); each solve returns the clique number found
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
        return len(G.get_max_clique()), None  # defaults: exact (heuristic, then search)
    raise ValueError(solver)


_WARM = None


def _warm_graph() -> Graph:
    """A small graph each child solves once, untimed, before the measured solve (lazy
    imports and first-call set-up of every solver stay out of the clock)."""
    global _WARM
    if _WARM is None:
        rng = np.random.default_rng(1)
        a = np.triu(rng.random((40, 40)) < 0.5, 1)
        _WARM = _graph("warm", "warm", a | a.T)
    return _WARM


def _child(conn, solver: str, g: Graph, time_limit: float) -> None:
    try:
        w = _warm_graph()
        _solve(solver, _build(solver, w), time_limit)
        G = _build(solver, g)
        # the limit is on CPU time: past it the kernel stops this process (SIGXCPU)
        used = sum(resource.getrusage(resource.RUSAGE_SELF)[:2])
        soft = math.ceil(used + time_limit + 1.0)
        resource.setrlimit(resource.RLIMIT_CPU, (soft, soft + 5))
        reps = 0
        c0 = time.process_time()
        while True:
            omega, nodes = _solve(solver, G, time_limit)
            reps += 1
            spent = time.process_time() - c0
            if spent >= MIN_TIME or omega == -1:
                break
        conn.send(("ok", omega, spent / reps, nodes, reps))
    except Exception as e:  # reported in the table, never fatal
        conn.send(("error", f"{type(e).__name__}: {e}", None, None, 0))
    finally:
        conn.close()


def run_one(solver: str, g: Graph, time_limit: float) -> dict:
    """Solve in a forked child: ``{status: ok | timeout | error, omega, seconds, ...}``."""
    ctx = mp.get_context("fork")
    recv, send = ctx.Pipe(duplex=False)
    p = ctx.Process(target=_child, args=(send, solver, g, time_limit))
    p.start()
    send.close()
    # the child's CPU limit ends a long solve; this wall-clock guard is for a stuck child
    if not recv.poll(3.0 * time_limit + 30.0):
        p.kill()
        p.join()
        return {"status": "timeout", "seconds": time_limit}
    try:
        status, omega, sec, nodes, reps = recv.recv()
    except EOFError:  # the child died without a word: over its CPU limit, or crashed
        p.join()
        if p.exitcode in (-signal.SIGXCPU, -signal.SIGKILL):
            return {"status": "timeout", "seconds": time_limit}
        return {"status": "error", "message": f"exit code {p.exitcode}", "seconds": time_limit}
    p.join()
    if status == "error":
        return {"status": "error", "message": omega, "seconds": time_limit}
    if omega == -1 or sec > time_limit:  # ours stopped at its limit, or a peer overran it
        return {"status": "timeout", "seconds": time_limit, "nodes": nodes}
    return {"status": "ok", "omega": omega, "seconds": sec, "nodes": nodes, "reps": reps}


def available_peers(wanted) -> tuple[list[str], list[str]]:
    have, notes = [], []
    for peer in wanted:
        try:
            __import__(peer)
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
        out.append(Graph(name, "dimacs", dg.adjacency(), dg.edges.astype(np.int64), omega[name]))
    return out, None


def large_config(loose: float):
    """Permissive features (no crowd filter, single-beam clusters, shorter lines) and
    every correspondence tolerance times ``loose``."""
    from scanclique.config import CorrespondenceConfig, FeatureConfig, MatchConfig

    c = CorrespondenceConfig()
    return MatchConfig(
        features=FeatureConfig(
            crowd_radius=0.0, min_cluster_beams=1, line_min_length=0.2, line_min_points=4
        ),
        correspondence=CorrespondenceConfig(
            point_point=c.point_point * loose,
            point_line=c.point_line * loose,
            line_line=c.line_line * loose,
        ),
    )


def correspondence_graphs(
    pairs_per_set: int, n_large: int, loose: float
) -> tuple[list[Graph], list[str]]:
    """The pipeline and large correspondence graphs (see the module docstring)."""
    try:
        import pairs as pair_sets

        from scanclique.config import MatchConfig
        from scanclique.correspondence import correspondence_graph
        from scanclique.datasets import load_log
        from scanclique.match import prepare_scan
    except ImportError as e:
        return [], [f"correspondence graphs: pipeline not available ({e}); skipped"]
    out: list[Graph] = []
    notes: list[str] = []
    configs = []
    if pairs_per_set > 0:
        configs.append(("pipeline", MatchConfig(), LOGS, pairs_per_set))
    if n_large > 0:
        configs.append(("large", large_config(loose), LARGE_LOGS, LARGE_CAP))
    for group, cfg, logs, cap in configs:
        found: list[Graph] = []
        for log_name in logs:
            try:
                scans = load_log(log_name)
            except Exception as e:  # DataNotFoundError, ParseError
                notes.append(f"{group}: cannot load the {log_name} log ({e}); skipped")
                continue
            prepared: dict = {}

            def prep(k, scans=scans, prepared=prepared, cfg=cfg):
                if k not in prepared:
                    prepared[k] = prepare_scan(scans[k], cfg)
                return prepared[k]

            for set_name, pairs in pair_sets.pair_sets(scans, cap=cap).items():
                for i, j in pairs:
                    pa, pb = prep(i), prep(j)
                    if group == "large" and min(pa.graph.n_nodes, pb.graph.n_nodes) < MIN_FEATURES:
                        continue
                    cg = correspondence_graph(pa.graph, pb.graph, cfg.correspondence)
                    found.append(_graph(f"{log_name}:{set_name}:{i}-{j}", group, cg.adjacency))
        if group == "large":
            found = pair_sets.evenly(found, n_large)
        out += found
    return out, notes


# --------------------------------------------------------------------------------------
# First-call cost and the time-limit check
# --------------------------------------------------------------------------------------
_FIRST = """
import json, time
t = time.perf_counter()
import numpy as np
from scanclique.clique import all_maximum_cliques, max_clique, top_cliques
t_import = time.perf_counter() - t
a = np.zeros((70, 70), bool); a[0, 1] = a[1, 0] = True
t = time.perf_counter(); max_clique(a); t_first = time.perf_counter() - t
t = time.perf_counter()
all_maximum_cliques(a); max_clique(a, weights=np.ones(70)); top_cliques(a, 2)
t_rest = time.perf_counter() - t
print(json.dumps({"import": t_import, "max_clique": t_first, "other_entry_points": t_rest}))
"""


def first_call_cost(compile_too: bool) -> dict:
    """Seconds of a fresh process: importing the module, the first ``max_clique`` call and
    the first calls of the other entry points; with the kernels cached on disk (the normal
    case) and, when asked, with an empty cache (numba compiles them)."""
    env = dict(os.environ, PYTHONPATH=str(REPO / "src"))
    out = {}
    runs = [("cached", None)] + ([("empty_cache", "tmp")] if compile_too else [])
    for label, cache in runs:
        with tempfile.TemporaryDirectory() as tmp:
            if cache:
                env["NUMBA_CACHE_DIR"] = tmp
            r = subprocess.run(
                [sys.executable, "-c", _FIRST], env=env, capture_output=True, text=True
            )
        if r.returncode == 0:
            out[label] = json.loads(r.stdout.strip().splitlines()[-1])
        else:
            out[label] = {"error": r.stderr.strip().splitlines()[-1:]}
    return out


def random_graph(n: int, p: float, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    a = np.triu(rng.random((n, n)) < p, 1)
    return a | a.T


def time_limit_check(limits=(0.1, 1.0, 10.0), n: int = 1000, p: float = 0.9) -> list[dict]:
    """Our solver on a graph it cannot finish: wall time of the call against the limit,
    and whether the returned vertices form a clique."""
    out = []
    for k, limit in enumerate(limits):
        adj = random_graph(n, p, 100 + k)
        t = time.perf_counter()
        r = max_clique(adj, time_limit=limit)
        wall = time.perf_counter() - t
        v = r.vertices
        valid = bool((adj[np.ix_(v, v)] | np.eye(len(v), dtype=bool)).all())
        out.append(
            {
                "n": n,
                "density": p,
                "limit": limit,
                "wall": wall,
                "elapsed": r.elapsed,
                "overshoot": wall / limit - 1.0,
                "size": r.size,
                "optimal": r.optimal,
                "valid": valid,
                "nodes": r.nodes,
                "reason": r.reason,
            }
        )
    return out


def node_limit_check(limits=(10_000, 100_000), n: int = 1000, p: float = 0.9) -> list[dict]:
    """Our solver with a node limit on a graph it cannot finish, twice per limit: the
    clique, the node count and the reason must be the same both times (they do not depend
    on the machine's speed); the wall time is reported."""
    out = []
    for k, limit in enumerate(limits):
        adj = random_graph(n, p, 200 + k)
        runs, walls = [], []
        for _ in range(2):
            t = time.perf_counter()
            runs.append(max_clique(adj, node_limit=limit))
            walls.append(time.perf_counter() - t)
        a, b = runs
        v = a.vertices
        out.append(
            {
                "n": n,
                "density": p,
                "node_limit": limit,
                "walls": walls,
                "size": a.size,
                "nodes": a.nodes,
                "optimal": a.optimal,
                "reason": a.reason,
                "identical": bool(
                    np.array_equal(a.vertices, b.vertices)
                    and a.nodes == b.nodes
                    and a.reason == b.reason
                ),
                "valid": bool((adj[np.ix_(v, v)] | np.eye(len(v), dtype=bool)).all()),
            }
        )
    return out


# --------------------------------------------------------------------------------------
# Runs and summaries
# --------------------------------------------------------------------------------------
def _gmean(xs) -> float:
    xs = [x for x in xs if x > 0 and math.isfinite(x)]
    return math.exp(sum(math.log(x) for x in xs) / len(xs)) if xs else float("nan")


def run_graphs(graphs: list[Graph], peers: list[str], limit: float) -> list[dict]:
    rows = []
    for k, g in enumerate(graphs):
        res = {"ours": run_one("ours", g, limit)}
        for p in peers:
            res[p] = run_one(p, g, limit)
        row = {
            "graph": g.name,
            "group": g.group,
            "n": g.n,
            "m": len(g.edges),
            "density": g.density,
            "omega_known": g.omega,
            "results": res,
        }
        row["problems"] = _problems(g, res)
        rows.append(row)
        print(f"[{k + 1}/{len(graphs)}] " + _line(row, peers, limit), file=sys.stderr, flush=True)
    return rows


def _problems(g: Graph, res: dict) -> list[str]:
    found = {s: r["omega"] for s, r in res.items() if r["status"] == "ok"}
    out = [f"{s} failed: {r['message']}" for s, r in res.items() if r["status"] == "error"]
    ref = g.omega if g.omega is not None else found.get("ours")
    for s, w in found.items():
        if ref is not None and w != ref:
            what = "omega.txt" if g.omega is not None else "ours"
            out.append(f"{s} found {w}, {what} says {ref}")
    return out


def _line(row, peers, limit) -> str:
    r = row["results"]
    cells = [row["graph"], str(row["n"]), _fmt_t(r["ours"], limit)]
    cells += [f"{p} {_fmt_t(r[p], limit)}" for p in peers]
    return "  ".join(cells)


def summarise(rows: list[dict], peers: list[str]) -> dict:
    ratios = {p: [] for p in peers}
    best = []
    faster = {p: 0 for p in peers}
    solved_1 = solved_10 = solved = 0
    for row in rows:
        r = row["results"]
        t = r["ours"]["seconds"]
        ok = r["ours"]["status"] == "ok"
        solved += ok
        solved_1 += ok and t <= 1.0
        solved_10 += ok and t <= 10.0
        usable = [p for p in peers if r[p]["status"] != "error"]
        for p in usable:
            q = t / r[p]["seconds"]
            ratios[p].append(q)
            faster[p] += q < 1.0
        if usable:
            best.append(t / min(r[p]["seconds"] for p in usable))
        row["ours_over_best"] = best[-1] if usable else None
    return {
        "graphs": len(rows),
        "solved": solved,
        "solved_within_1s": solved_1,
        "solved_within_10s": solved_10,
        "gmean_ours_over_peer": {p: _gmean(ratios[p]) for p in peers},
        "gmean_ours_over_best": _gmean(best),
        "max_ours_over_best": max(best) if best else None,
        "faster_than": {p: [faster[p], len(ratios[p])] for p in peers},
        "problems": [f"{row['graph']}: {m}" for row in rows for m in row["problems"]],
    }


# --------------------------------------------------------------------------------------
# Report
# --------------------------------------------------------------------------------------
def _fmt_t(res, limit) -> str:
    if res["status"] == "timeout":
        return f">{limit:g}"
    if res["status"] == "error":
        return "error"
    s = res["seconds"]
    return f"{s:.2e}" if s < 0.01 else f"{s:.3f}"


def _fmt_q(q) -> str:
    return "-" if q is None or not math.isfinite(q) else f"{q:.3g}"


def table(rows: list[dict], peers: list[str], limit: float) -> str:
    head = ["graph", "n", "dens", "omega", "ours s", "nodes"]
    for p in peers:
        head += [f"{p} s", "ratio"]
    head.append("ours/best")
    body = []
    for row in rows:
        r = row["results"]
        o = r["ours"]
        om = o["omega"] if o["status"] == "ok" else "?"
        cells = [row["graph"], str(row["n"]), f"{row['density']:.2f}", str(om)]
        cells += [_fmt_t(o, limit), str(o.get("nodes", ""))]
        for p in peers:
            cells.append(_fmt_t(r[p], limit))
            q = o["seconds"] / r[p]["seconds"] if r[p]["status"] != "error" else None
            cells.append(_fmt_q(q))
        cells.append(_fmt_q(row.get("ours_over_best")))
        body.append(cells)
    return _markdown_table(head, body)


def _markdown_table(head, rows) -> str:
    widths = [max(len(str(r[i])) for r in [head] + rows) for i in range(len(head))]

    def line(cells):
        out = [
            str(c).ljust(w) if i == 0 else str(c).rjust(w)
            for i, (c, w) in enumerate(zip(cells, widths, strict=True))
        ]
        return "| " + " | ".join(out) + " |"

    sep = "|" + "|".join("-" * (w + 1) + (":" if i else "-") for i, w in enumerate(widths)) + "|"
    return "\n".join([line(head), sep] + [line(r) for r in rows])


def summary_lines(title: str, s: dict, peers: list[str]) -> list[str]:
    n = s["graphs"]
    lines = [
        f"{title}: ours solved {s['solved']}/{n} exactly, {s['solved_within_1s']}/{n} within "
        f"1 s, {s['solved_within_10s']}/{n} within 10 s",
        f"{title}: geometric mean ours/best peer {_fmt_q(s['gmean_ours_over_best'])} (worst "
        f"{_fmt_q(s['max_ours_over_best'])}); ours/peer "
        + ", ".join(f"{p} {_fmt_q(s['gmean_ours_over_peer'][p])}" for p in peers),
        f"{title}: faster than "
        + ", ".join(f"{p} on {a}/{b}" for p, (a, b) in s["faster_than"].items()),
    ]
    lines += [f"{title}: PROBLEM {m}" for m in s["problems"]]
    return lines


def _warm_ours() -> None:
    """Load every kernel specialisation the children will call (read-only and writable
    matrices), so that no child pays the cache load."""
    for n in (10, 70, 200):
        a = random_graph(n, 0.5, 0)
        max_clique(a)
        a.setflags(write=False)
        max_clique(a)
    all_maximum_cliques(a)
    top_cliques(a, 2)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--time-limit", type=float, default=60.0, help="seconds per solver and graph")
    ap.add_argument("--graphs", nargs="*", help="DIMACS names to run (default: all 27)")
    ap.add_argument("--peers", nargs="*", default=list(PEERS), choices=PEERS)
    ap.add_argument("--pairs", type=int, default=25, help="pipeline pairs per log and pair set")
    ap.add_argument("--large", type=int, default=30, help="large correspondence graphs")
    ap.add_argument("--loose", type=float, default=1.5, help="tolerance factor, large graphs")
    ap.add_argument("--no-dimacs", action="store_true")
    ap.add_argument("--no-correspondence", action="store_true")
    ap.add_argument("--no-compile-cost", action="store_true", help="skip the empty-cache run")
    ap.add_argument("--no-limit-check", action="store_true", help="skip the time-limit check")
    ap.add_argument("--out-dir", default=str(REPO / "benchmarks" / "results"))
    ap.add_argument("--no-save", action="store_true", help="print only")
    ap.add_argument(
        "--compare",
        nargs=2,
        metavar=("BEFORE", "AFTER"),
        help="compare our solver in two saved runs (.json): clique numbers and time ratios",
    )
    args = ap.parse_args(argv)
    if args.compare:
        print(compare_runs(*(json.loads(Path(p).read_text()) for p in args.compare)))
        return 0

    t_start = time.perf_counter()
    load_start = [round(x, 2) for x in os.getloadavg()]
    git_start = git_state()  # the code measured (others may commit while this runs)
    peers, notes = available_peers(args.peers)
    limit = args.time_limit
    first = first_call_cost(not args.no_compile_cost)
    _warm_ours()  # kernels loaded before the children fork

    # every graph is built before any solve (the pipeline's modules are read once)
    dimacs, corr = [], []
    if not args.no_dimacs:
        dimacs, note = dimacs_graphs(args.graphs)
        notes += [note] if note else []
    if not args.no_correspondence:
        corr, more = correspondence_graphs(args.pairs, args.large, args.loose)
        notes += more
    sections: dict[str, dict] = {}
    if dimacs:
        rows = run_graphs(dimacs, peers, limit)
        sections["dimacs"] = {"rows": rows, "summary": summarise(rows, peers)}
    if corr:
        rows = run_graphs(corr, peers, limit)
        for group in ("pipeline", "large"):
            part = [r for r in rows if r["group"] == group]
            if part:
                sections[group] = {"rows": part, "summary": summarise(part, peers)}
        if rows:
            sections["correspondence"] = {"rows": [], "summary": summarise(rows, peers)}
    checks = [] if args.no_limit_check else time_limit_check()
    node_checks = [] if args.no_limit_check else node_limit_check()

    date = _dt.date.today().isoformat()
    doc = {
        "date": _dt.datetime.now().isoformat(timespec="seconds"),
        "command": "python benchmarks/clique.py " + " ".join(argv or sys.argv[1:]),
        "machine": machine(detailed=True),
        "load_average_start": load_start,
        "versions": versions(("numpy", "numba", "python-igraph", "networkx", "cliquematch")),
        "git": git_start,
        "time_limit": limit,
        "peers": peers,
        "notes": notes,
        "first_call": first,
        "time_limit_check": checks,
        "node_limit_check": node_checks,
        "sections": sections,
        "wall_seconds": time.perf_counter() - t_start,
        "settings": {"pairs_per_set": args.pairs, "large": args.large, "loose": args.loose},
    }
    text = report(doc)
    print(text)
    if not args.no_save:
        out = Path(args.out_dir)
        out.mkdir(parents=True, exist_ok=True)
        (out / f"clique-{date}.md").write_text(text + "\n")
        (out / f"clique-{date}.json").write_text(json.dumps(doc, indent=1, default=float) + "\n")
        print(f"\nwrote {out / f'clique-{date}.md'} and .json", file=sys.stderr)
    return 0


def compare_runs(before: dict, after: dict) -> str:
    """Our solver in two saved runs (e.g. before and after a change): whether every graph
    has the same clique number and status, and the geometric mean of the CPU-time ratio
    after / before per section and by size (graphs both runs solved)."""

    def ours(doc):
        out = {}
        for key in ("dimacs", "pipeline", "large"):
            for r in doc["sections"].get(key, {}).get("rows", []):
                out[(key, r["graph"])] = (r["n"], r["results"]["ours"])
        return out

    a, b = ours(before), ours(after)
    common = sorted(set(a) & set(b))
    differ = [
        g
        for g in common
        if (a[g][1].get("omega"), a[g][1]["status"]) != (b[g][1].get("omega"), b[g][1]["status"])
    ]
    lines = [
        f"before: commit {str(before['git']['commit'])[:10]}, load {before['load_average_start']}"
        f"; after: commit {str(after['git']['commit'])[:10]}, load {after['load_average_start']}",
        f"graphs in both runs: {len(common)}; same clique number and status: "
        f"{len(common) - len(differ)}; different: {', '.join(map(':'.join, differ)) or 'none'}",
        "",
        "| graphs | solved by both | time after / before, geometric mean | median | min | max |",
        "|---|---:|---:|---:|---:|---:|",
    ]
    groups = [(k, lambda g, k=k: g[0] == k) for k in ("dimacs", "pipeline", "large")]
    groups += [
        ("correspondence, up to 64 vertices", lambda g: g[0] != "dimacs" and a[g][0] <= 64),
        ("correspondence, above 64 vertices", lambda g: g[0] != "dimacs" and a[g][0] > 64),
    ]
    for name, keep in groups:
        rs = sorted(
            b[g][1]["seconds"] / a[g][1]["seconds"]
            for g in common
            if keep(g) and a[g][1]["status"] == "ok" and b[g][1]["status"] == "ok"
        )
        if rs:
            lines.append(
                f"| {name} | {len(rs)} | {_gmean(rs):.3f} | {rs[len(rs) // 2]:.3f} | "
                f"{rs[0]:.3f} | {rs[-1]:.3f} |"
            )
    return "\n".join(lines)


TITLES = {
    "dimacs": "DIMACS (second challenge, 27 graphs)",
    "pipeline": "Correspondence graphs, pipeline configuration",
    "large": "Correspondence graphs, large (>= 60 features per scan, loose tolerances)",
    "correspondence": "Correspondence graphs, all",
}


def report(doc: dict) -> str:
    m, v = doc["machine"], doc["versions"]
    limit, peers = doc["time_limit"], doc["peers"]
    out = [
        f"# Maximum clique: scanclique against igraph, networkx and cliquematch — "
        f"{doc['date'][:10]}",
        "",
        f"Machine: {m['platform']}, {m['processor']}, {m['cpus']} CPUs; Python "
        f"{v['python']}, numpy {v['numpy']}, numba {v['numba']}, python-igraph "
        f"{v['python-igraph']}, networkx {v['networkx']}, cliquematch {v['cliquematch']}. "
        f"Load average (1, 5, 15 min) at the start {doc['load_average_start']}, at the end "
        f"{m['load_average']} (another job shared the machine: absolute times are "
        f"inflated, every solver ran on each graph in turn). Wall time "
        f"{doc['wall_seconds']:.0f} s. Code: commit {str(doc['git']['commit'])[:10]}"
        + (
            f" with uncommitted changes to {', '.join(doc['git']['modified'])}"
            if doc["git"]["modified"]
            else ""
        )
        + ".",
        "",
        f"Times: CPU seconds of one solve call (mean of back-to-back repeats for solves under "
        f"{MIN_TIME} s), each solver in its own forked process, graphs built beforehand in "
        f"each solver's native form; limit {limit:g} s per solver and graph, a timeout "
        f"counts as {limit:g} s. ratio = ours / peer (< 1: ours faster); ours/best = ours "
        f"over the fastest peer on that graph.",
    ]
    out += [f"- {n}" for n in doc["notes"]]
    fc = doc["first_call"]
    out += ["", "## First-call cost (fresh process)", ""]
    for label, what in (("cached", "kernels cached on disk"), ("empty_cache", "empty cache")):
        if label in fc and "error" not in fc[label]:
            d = fc[label]
            out.append(
                f"- {what}: import {d['import']:.2f} s, first max_clique "
                f"{d['max_clique']:.2f} s, first calls of the other entry points "
                f"{d['other_entry_points']:.2f} s"
            )
        elif label in fc:
            out.append(f"- {what}: failed: {fc[label]['error']}")
    for key in ("dimacs", "pipeline", "large"):
        if key in doc["sections"]:
            sec = doc["sections"][key]
            out += ["", f"## {TITLES[key]}", "", table(sec["rows"], peers, limit), ""]
            out += summary_lines(key, sec["summary"], peers)
    if "correspondence" in doc["sections"]:
        out += ["", f"## {TITLES['correspondence']}", ""]
        out += summary_lines("correspondence", doc["sections"]["correspondence"]["summary"], peers)
    if doc["time_limit_check"]:
        out += ["", "## Time limit on a graph that cannot be finished", ""]
        for c in doc["time_limit_check"]:
            out.append(
                f"- n={c['n']}, density {c['density']}, limit {c['limit']:g} s: call returned "
                f"after {c['wall']:.3f} s wall (overshoot {100 * c['overshoot']:+.1f} %), "
                f"clique of {c['size']} vertices, valid={c['valid']}, optimal={c['optimal']}, "
                f"{c['nodes']} nodes, reason {c.get('reason')}"
            )
    if doc.get("node_limit_check"):
        out += ["", "## Node limit on a graph that cannot be finished (twice each)", ""]
        for c in doc["node_limit_check"]:
            out.append(
                f"- n={c['n']}, density {c['density']}, node_limit {c['node_limit']}: clique "
                f"of {c['size']} vertices after {c['nodes']} nodes, reason {c['reason']}, "
                f"valid={c['valid']}, identical both runs={c['identical']}, wall "
                f"{c['walls'][0]:.3f} s and {c['walls'][1]:.3f} s"
            )
    return "\n".join(out)


if __name__ == "__main__":
    raise SystemExit(main())
