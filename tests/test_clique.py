"""Tests of scanclique.clique: the branch and bound must agree with Bron–Kerbosch.

The property tests draw random graphs of up to 60 vertices at every density (2000 for the
maximum cliques). The reference is :func:`bron_kerbosch` with ``min_size`` set to the size
the solver claims: it then lists every maximal clique at least that large, which must be
exactly the solver's maximum cliques (a larger clique, or none of that size, would show).
``SCANCLIQUE_HYPOTHESIS_EXAMPLES`` changes the number of examples. The DIMACS graphs whose
search takes seconds run with ``SCANCLIQUE_SLOW_TESTS=1`` (``benchmarks/clique.py``
checks the clique number of all 27 on every run).
"""

from __future__ import annotations

import json
import os
import time
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from scanclique.clique import (
    AllCliquesResult,
    CliqueResult,
    all_maximum_cliques,
    as_adjacency,
    bitsets_from_adjacency,
    bron_kerbosch,
    max_clique,
    solve_file,
    top_cliques,
)
from scanclique.errors import GraphError, ScanCliqueError

nx = pytest.importorskip("networkx")

EXAMPLES = int(os.environ.get("SCANCLIQUE_HYPOTHESIS_EXAMPLES", "2000"))
SLOW = os.environ.get("SCANCLIQUE_SLOW_TESTS", "") not in ("", "0")


def property_settings(examples: int):
    return settings(
        max_examples=examples, deadline=None, suppress_health_check=[HealthCheck.too_slow]
    )


def random_graph(n: int, p: float, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    a = np.triu(rng.random((n, n)) < p, 1)
    return a | a.T


def is_clique(adj: np.ndarray, verts) -> bool:
    v = np.asarray(verts)
    sub = adj[np.ix_(v, v)]
    return bool((sub | np.eye(len(v), dtype=bool)).all())


def maximum_cliques_reference(adj):
    cl = [c.tolist() for c in bron_kerbosch(adj)]
    omega = max((len(c) for c in cl), default=0)
    return omega, sorted(c for c in cl if len(c) == omega)


SEEDS = st.integers(0, 2**32 - 1)


def graphs_up_to(n_max: int, n_max_dense: int):
    """Random graphs at every density; above density 0.8 at most ``n_max_dense`` vertices
    (there the pure-Python reference takes a tenth of a second per graph at 60)."""
    return (
        st.floats(0.0, 1.0)
        .flatmap(
            lambda p: st.tuples(
                st.integers(0, n_max if p <= 0.8 else n_max_dense), st.just(p), SEEDS
            )
        )
        .map(lambda t: random_graph(*t))
    )


graphs = graphs_up_to(60, 40)


# -- known graphs --------------------------------------------------------------------------
@pytest.mark.parametrize(
    ("G", "omega", "count"),
    [
        (nx.petersen_graph(), 2, 15),
        (nx.complete_graph(7), 7, 1),
        (nx.empty_graph(5), 1, 5),
        (nx.cycle_graph(5), 2, 5),
        (nx.disjoint_union(nx.complete_graph(3), nx.complete_graph(3)), 3, 2),
        (nx.complete_multipartite_graph(2, 2, 2), 3, 8),
        (nx.turan_graph(12, 4), 4, 81),
    ],
)
def test_known_graphs(G, omega, count):
    r = max_clique(G)
    assert (r.size, r.optimal) == (omega, True)
    a = all_maximum_cliques(G)
    assert (a.omega, len(a.cliques), a.complete, a.optimal) == (omega, count, True, True)
    ref = sorted(sorted(c) for c in nx.find_cliques(G) if len(c) == omega)
    assert [c.tolist() for c in a.cliques] == ref


@pytest.mark.parametrize("n", [0, 1])
def test_trivial_graphs(n):
    adj = np.zeros((n, n), dtype=bool)
    r = max_clique(adj)
    assert r.vertices.tolist() == list(range(n)) and r.optimal and r.size == n
    a = all_maximum_cliques(adj)
    assert a.omega == n and a.complete and len(a.cliques) == n
    assert len(list(bron_kerbosch(adj))) == n
    assert len(top_cliques(adj, 3)) == n


def test_result_is_frozen():
    r = max_clique(nx.complete_graph(3))
    assert isinstance(r, CliqueResult) and r.vertices.dtype == np.int64
    with pytest.raises(ValueError):
        r.vertices[0] = 5
    with pytest.raises(AttributeError):
        r.optimal = False  # type: ignore[misc]
    a = all_maximum_cliques(nx.complete_graph(3))
    assert isinstance(a, AllCliquesResult)
    with pytest.raises(ValueError):
        a.cliques[0][0] = 5


def test_dense_result_is_frozen():
    # a boolean matrix takes the lean path, which builds the record without __init__
    r = max_clique(random_graph(11, 0.5, 0))
    assert type(r) is CliqueResult and r.weight is None and isinstance(r.nodes, int)
    assert r.vertices.dtype == np.int64 and not r.vertices.flags.writeable
    with pytest.raises(AttributeError):
        r.optimal = False  # type: ignore[misc]
    assert repr(r).startswith("CliqueResult(vertices=array([")


@pytest.mark.parametrize("lower_bound", [None, 1, 4, 9])
@pytest.mark.parametrize(("n", "p"), [(1, 0.0), (11, 0.15), (60, 0.15), (70, 0.5), (130, 0.3)])
def test_dense_path_agrees_with_bitset_path(n, p, lower_bound):
    # max_clique(bool matrix) has its own kernel entry; an edge list goes through solve()
    adj = random_graph(n, p, n)
    ref = max_clique((np.argwhere(np.triu(adj)), n), lower_bound=lower_bound)
    views = [adj, np.asfortranarray(adj), np.kron(adj, np.ones((2, 2), bool))[::2, ::2]]
    views.append(adj.copy())
    views[-1].setflags(write=False)
    for a in views:
        r = max_clique(a, lower_bound=lower_bound, time_limit=60)
        assert (r.vertices.tolist(), r.optimal, r.nodes) == (
            ref.vertices.tolist(),
            ref.optimal,
            ref.nodes,
        )


# -- inputs --------------------------------------------------------------------------------
def test_input_forms_agree(tmp_path):
    from scanclique.io.dimacs import write_dimacs

    adj = random_graph(30, 0.5, 1)
    edges = np.argwhere(np.triu(adj))
    path = tmp_path / "g.clq"
    write_dimacs(path, adj)
    G = nx.Graph()
    G.add_nodes_from(range(30))
    G.add_edges_from(edges.tolist())
    for g in (adj, (edges, 30), G, str(path), path):
        assert np.array_equal(as_adjacency(g), adj)
    assert max_clique(str(path)).size == max_clique(adj).size


def test_networkx_labels_are_positions():
    G = nx.Graph([("a", "b"), ("b", "c"), ("c", "a"), ("c", "d")])
    r = max_clique(G)
    assert [list(G)[i] for i in r.vertices] == ["a", "b", "c"]


@pytest.mark.parametrize(
    ("graph", "match"),
    [
        (np.zeros((2, 3), dtype=bool), "square"),
        (np.array([[False, True], [False, False]]), "symmetric"),
        (np.eye(2, dtype=bool), "self loop"),
        (np.zeros((3, 3), dtype=float), "bool"),
        ((np.array([[0, 3]]), 3), "outside"),
        ((np.array([[1, 1]]), 3), "self loop"),
        (nx.DiGraph([(0, 1)]), "directed"),
        (nx.Graph([(0, 0)]), "self loop"),
        ([[0, 1]], "cannot read"),
    ],
)
def test_malformed_graphs(graph, match):
    with pytest.raises(GraphError, match=match):
        max_clique(graph)


def test_bad_arguments():
    adj = random_graph(5, 0.5, 0)
    with pytest.raises(ScanCliqueError):
        max_clique(adj, time_limit=-1)
    with pytest.raises(GraphError, match="weights"):
        max_clique(adj, weights=[1, 2])
    with pytest.raises(GraphError, match="weights"):
        max_clique(adj, weights=[1, 2, 3, 4, -5])


def test_bitsets_from_adjacency():
    adj = random_graph(130, 0.3, 2)
    bits = bitsets_from_adjacency(adj)
    assert bits.shape == (130, 3) and bits.dtype == np.uint64
    back = ((bits[:, :, None] >> np.arange(64, dtype=np.uint64)) & np.uint64(1)).astype(bool)
    assert np.array_equal(back.reshape(130, -1)[:, :130], adj)


# -- agreement with the reference ----------------------------------------------------------
@property_settings(EXAMPLES)
@given(graphs)
def test_property_max_clique_vs_bron_kerbosch(adj):
    r = max_clique(adj)
    assert r.optimal and is_clique(adj, r.vertices)
    a = all_maximum_cliques(adj, limit=10**6)
    assert (a.omega, a.complete, a.optimal) == (r.size, True, True)
    # every maximal clique of at least r.size vertices: all of size r.size (so omega is not
    # larger) and at least one (so it is not smaller); they are the maximum cliques
    ref = sorted(c.tolist() for c in bron_kerbosch(adj, min_size=r.size))
    assert all(len(c) == r.size for c in ref) and len(ref) >= min(adj.shape[0], 1)
    assert [c.tolist() for c in a.cliques] == ref


@property_settings(max(EXAMPLES // 4, 20))
@given(graphs, st.integers(1, 6))
def test_property_top_cliques_vs_maximal_cliques(adj, k):
    got = [c.tolist() for c in top_cliques(adj, k)]
    assert len({tuple(c) for c in got}) == len(got) <= k
    assert [len(c) for c in got] == sorted((len(c) for c in got), reverse=True)
    # all maximal cliques at least as large as the smallest returned (all of them when
    # fewer than k came back): the k largest of these must match in size
    smallest = len(got[-1]) if len(got) == k else 0
    ref = sorted(
        (c.tolist() for c in bron_kerbosch(adj, min_size=smallest)), key=lambda c: (-len(c), c)
    )
    maximal = {tuple(c) for c in ref}
    assert all(tuple(c) in maximal for c in got)
    assert [len(c) for c in got] == [len(c) for c in ref[:k]]


@property_settings(max(EXAMPLES // 10, 20))
@given(graphs_up_to(40, 30), SEEDS, st.booleans())
def test_property_weighted_vs_networkx(adj, seed, integer):
    n = adj.shape[0]
    rng = np.random.default_rng(seed)
    w = rng.integers(0, 20, n) if integer else rng.random(n) * 10
    if integer:  # networkx takes integer weights only
        G = nx.from_numpy_array(adj.astype(np.int8))
        nx.set_node_attributes(G, {i: int(w[i]) for i in range(n)}, "w")
        _, ref = nx.max_weight_clique(G, weight="w")
    else:  # with non-negative weights some maximal clique is heaviest
        ref = max((float(w[c].sum()) for c in bron_kerbosch(adj)), default=0.0)
    r = max_clique(adj, weights=w)
    assert r.optimal and is_clique(adj, r.vertices)
    assert r.weight == pytest.approx(ref, rel=1e-9, abs=1e-9)
    assert r.weight == pytest.approx(float(np.sum(w[r.vertices])))


@property_settings(max(EXAMPLES // 8, 20))
@given(st.tuples(st.integers(40, 100), st.floats(0.6, 0.97), SEEDS).map(lambda t: random_graph(*t)))
def test_property_maxsat_filter_is_exact(adj):
    # dense graphs beyond the reference's reach: the search with the MaxSAT-style filter
    # (from the first node, or after local search as by default) must find the clique
    # number and every maximum clique that the plain colouring bound finds
    from scanclique import _clique_kernels as K

    A = bitsets_from_adjacency(adj)
    n = adj.shape[0]
    runs = [K.solve(A, n, 0, 2, 10**6, np.inf, time.perf_counter(), opts) for opts in (0, 1, 3)]
    omegas = {r[0].shape[0] for r in runs}
    assert len(omegas) == 1 and all(r[2] == 0 and r[4] == 0 for r in runs)
    found = [sorted(map(tuple, r[3].tolist())) for r in runs]
    assert found[0] == found[1] == found[2] and len(found[0]) >= 1
    assert all(is_clique(adj, c) for c in found[0])


def test_weights_all_equal_is_max_clique():
    adj = random_graph(40, 0.6, 3)
    assert max_clique(adj, weights=np.ones(40)).size == max_clique(adj).size


def test_lower_bound():
    adj = random_graph(50, 0.5, 4)
    omega = max_clique(adj).size
    r = max_clique(adj, lower_bound=omega)
    assert r.size == omega and r.optimal
    r = max_clique(adj, lower_bound=omega + 1)
    assert not r.optimal and r.size <= omega and is_clique(adj, r.vertices)


def test_all_maximum_cliques_limit():
    G = nx.turan_graph(12, 4)  # 3^4 = 81 maximum cliques
    a = all_maximum_cliques(G, limit=10)
    assert len(a.cliques) == 10 and not a.complete and a.optimal and a.omega == 4


# -- time limit ----------------------------------------------------------------------------
def test_time_limit_is_honoured():
    adj = random_graph(400, 0.9, 5)
    max_clique(random_graph(70, 0.5, 0))  # kernels loaded (or compiled) outside the clock
    t = time.perf_counter()
    r = max_clique(adj, time_limit=0.2)
    wall = time.perf_counter() - t
    assert not r.optimal and is_clique(adj, r.vertices) and r.size >= 30
    assert wall < 0.2 * 1.1 + 0.05
    a = all_maximum_cliques(adj, time_limit=0.1)
    assert not a.complete and not a.optimal and all(is_clique(adj, c) for c in a.cliques)
    assert len(top_cliques(adj, 3, time_limit=0.1)) == 3


def test_time_limit_on_a_graph_that_cannot_be_finished():
    adj = random_graph(1000, 0.9, 6)  # the case: far beyond any exact search
    max_clique(random_graph(70, 0.5, 0))  # kernels loaded (or compiled) outside the clock
    t = time.perf_counter()
    r = max_clique(adj, time_limit=1.0)
    wall = time.perf_counter() - t
    assert not r.optimal and is_clique(adj, r.vertices) and r.size >= 50
    assert 1.0 <= r.elapsed <= wall <= 1.1  # within 10 %, result assembly included


# -- CLI helper ----------------------------------------------------------------------------
def test_solve_file(tmp_path):
    from scanclique.io.dimacs import write_dimacs

    path = tmp_path / "k4.clq"
    write_dimacs(path, (np.array([[0, 1], [0, 2], [1, 2], [0, 3], [1, 3], [2, 3], [3, 4]]), 6))
    out = solve_file(path, all=True)
    json.dumps(out)
    assert out["omega"] == 4 and out["optimal"] and out["clique"] == [1, 2, 3, 4]
    assert out["cliques"] == [[1, 2, 3, 4]] and out["complete"]


# -- command line --------------------------------------------------------------------------
def test_cli_clique(tmp_path):
    from typer.testing import CliRunner

    from scanclique import cli
    from scanclique.io.dimacs import write_dimacs

    path = tmp_path / "g.clq"
    write_dimacs(path, nx.to_numpy_array(nx.turan_graph(9, 3), dtype=bool))
    runner = CliRunner()
    res = runner.invoke(cli.app, ["clique", str(path), "--all", "--json"])
    assert res.exit_code == 0, res.output
    out = json.loads(res.output)
    assert (out["omega"], out["optimal"], len(out["cliques"]), out["complete"]) == (
        3,
        True,
        27,
        True,
    )
    res = runner.invoke(cli.app, ["clique", str(path), "--time-limit", "5"])
    assert res.exit_code == 0 and "optimal" in res.output
    res = runner.invoke(cli.app, ["clique", str(tmp_path / "missing.clq")])
    assert res.exit_code != 0


# -- real data -----------------------------------------------------------------------------
def _dimacs_dir() -> Path:
    root = Path(__file__).resolve().parents[1]
    return Path(os.environ.get("SCANCLIQUE_DATA", root.parent / "shared" / "data")) / "dimacs"


def _omega_table() -> dict[str, int]:
    table = _dimacs_dir() / "omega.txt"
    if not table.exists():
        return {}
    return {
        ln.split()[0]: int(ln.split()[2])
        for ln in table.read_text().splitlines()
        if ln.strip() and not ln.startswith("#")
    }


OMEGA = _omega_table()
SLOW_DIMACS = {"sanr200_0.9"}  # about 3 s; every other graph well under 0.5 s


@pytest.mark.realdata
@pytest.mark.parametrize(
    "name",
    [
        pytest.param(
            name,
            marks=[
                pytest.mark.slow,
                pytest.mark.skipif(not SLOW, reason="seconds; set SCANCLIQUE_SLOW_TESTS=1"),
            ],
        )
        if name in SLOW_DIMACS
        else name
        for name in sorted(OMEGA)
    ]
    or ["no-data"],
)
def test_dimacs_omega(name):
    if not OMEGA:
        pytest.skip(f"DIMACS data not found: {_dimacs_dir()}/omega.txt (set SCANCLIQUE_DATA)")
    r = max_clique(_dimacs_dir() / f"{name}.clq")
    assert r.optimal and r.size == OMEGA[name] and r.vertices.shape[0] == OMEGA[name]
    adj = as_adjacency(_dimacs_dir() / f"{name}.clq")
    assert is_clique(adj, r.vertices)


def test_dimacs_table_has_all_27():
    if not OMEGA:
        pytest.skip(f"DIMACS data not found: {_dimacs_dir()}/omega.txt (set SCANCLIQUE_DATA)")
    assert len(OMEGA) == 27
