"""Tests of scanclique.clique: the branch and bound must agree with Bron–Kerbosch.

The property tests draw random graphs of up to 60 vertices at every density (2000 for the
maximum cliques). The reference is :func:`bron_kerbosch` with ``min_size`` set to the size
the solver claims: it then lists every maximal clique at least that large, which must be
exactly the solver's maximum cliques (a larger clique, or none of that size, would show).
Further property tests aim at each branch of the lean path of ``max_clique`` (one-word
search up to 64 vertices; above, the core of a greedy clique: empty, in one word, in
several words, or dense and handed to the full search).
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
    # max_clique(bool matrix) checks and packs in the kernel (solve_dense); an edge list is
    # packed in Python and goes to solve_bits: the same search, the same result
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
    from scanclique._kernels.clique_search import solve
    from scanclique._kernels.codes import NO_LIMIT, Mode

    A = bitsets_from_adjacency(adj)
    n = adj.shape[0]
    runs = [solve(A, n, 0, int(Mode.ALL_MAXIMUM), 10**6, np.inf, NO_LIMIT, o) for o in (0, 1, 3)]
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


# -- the lean path: small and sparse graphs ------------------------------------------------
def planted(n: int, p: float, k: int, seed: int) -> np.ndarray:
    """A random graph with a clique on ``k`` random vertices."""
    adj = random_graph(n, p, seed)
    c = np.random.default_rng(seed + 1).choice(n, size=min(k, n), replace=False)
    adj[np.ix_(c, c)] = True
    adj[c, c] = False
    return adj


def blocky(n: int, p: float, b: int, q: float, seed: int) -> np.ndarray:
    """A random graph of density ``p`` whose first ``b`` vertices have density ``q``."""
    adj = random_graph(n, p, seed)
    b = min(b, n)
    adj[:b, :b] = random_graph(b, q, seed + 7)
    return adj


def lean_path(adj: np.ndarray) -> str:
    """Which way ``max_clique(adj)`` goes (the steps of ``maximum_peeled``, replayed)."""
    from scanclique._kernels import clique_search, heuristics, ordering

    n = adj.shape[0]
    if n <= 64:
        return "word"
    A = bitsets_from_adjacency(adj)
    deg = adj.sum(1).astype(np.int64)
    top = np.argsort(-deg, kind="stable")[: clique_search.SPARSE_STARTS].astype(np.int64)
    scratch = (np.empty(n + 1, np.int64), np.empty(n, np.int64), np.empty(A.shape[1], np.uint64))
    k = heuristics.greedy_by_degree(A, deg, top, len(top), *scratch)
    alive = bitsets_from_adjacency(np.ones((1, n), bool))[0].copy()
    m = ordering.peel_core(A, n, deg, k, alive, np.empty(n, np.int64))
    core = np.flatnonzero(bitsets_to_bool(alive, n))
    if m == 0:
        return "empty core"
    if m <= 64:
        return "core in a word"
    if 4 * deg[core].sum() <= m * m:
        return "core in words"
    return "dense core" if m < n else "dense"


def full_search(adj: np.ndarray):
    """The full search (degeneracy order, local search, MaxSAT-style filter) in mode
    MAXIMUM, without the lean paths: ``(clique, nodes, status, found, status_all)``."""
    from scanclique._kernels.clique_search import OPT_DEFAULT, solve
    from scanclique._kernels.codes import NO_LIMIT, Mode

    A = bitsets_from_adjacency(adj)
    return solve(A, adj.shape[0], 0, int(Mode.MAXIMUM), 0, np.inf, NO_LIMIT, OPT_DEFAULT)


def bitsets_to_bool(bits: np.ndarray, n: int) -> np.ndarray:
    one = np.uint64(1)
    return ((bits[np.arange(n) >> 6] >> (np.arange(n) & 63).astype(np.uint64)) & one).astype(bool)


def check_max_clique(adj: np.ndarray, lower_bound: int | None, omega: int | None = None) -> int:
    """``max_clique`` against Bron–Kerbosch (or against ``omega`` when given), with and
    without ``lower_bound``, on the boolean matrix and on the edge list (which must
    agree exactly). Returns the clique number."""
    n = adj.shape[0]
    r = max_clique(adj)
    assert r.optimal and is_clique(adj, r.vertices)
    assert r.vertices.tolist() == sorted(set(r.vertices.tolist()))
    if omega is None:
        # every maximal clique of at least r.size vertices has r.size vertices
        ref = [c.tolist() for c in bron_kerbosch(adj, min_size=r.size)]
        assert all(len(c) == r.size for c in ref) and r.vertices.tolist() in ref
    else:
        assert r.size == omega
    omega = r.size
    if lower_bound is not None:
        r = max_clique(adj, lower_bound=lower_bound)
        assert is_clique(adj, r.vertices) and r.size <= omega
        assert r.optimal == (lower_bound <= omega)
        if r.optimal:
            assert r.size == omega
    e = max_clique((np.argwhere(np.triu(adj)), n), lower_bound=lower_bound)
    assert (e.vertices.tolist(), e.optimal, e.nodes) == (r.vertices.tolist(), r.optimal, r.nodes)
    return omega


LOWER_BOUNDS = st.none() | st.integers(1, 14)


@property_settings(EXAMPLES // 2)
@given(graphs_up_to(64, 40), LOWER_BOUNDS)
def test_property_one_word_path_vs_bron_kerbosch(adj, lower_bound):
    # up to 64 vertices: one-word branch and bound, without greedy clique or peeling
    if adj.shape[0]:
        check_max_clique(adj, lower_bound)


# more than 64 vertices: sparse graphs with a planted clique, most of them sparse enough
# for the core of the greedy clique to be empty or to fit in a word, the rest with a
# larger core searched in multi-word sets
peeled_graphs = st.one_of(
    st.tuples(st.integers(65, 160), st.floats(0.0, 0.1), st.integers(0, 8), SEEDS),
    st.tuples(st.integers(65, 160), st.floats(0.0, 0.25), st.integers(0, 16), SEEDS),
).map(lambda t: planted(*t))


@property_settings(EXAMPLES // 4)
@given(peeled_graphs, LOWER_BOUNDS)
def test_property_peeled_path_vs_bron_kerbosch(adj, lower_bound):
    check_max_clique(adj, lower_bound)


@property_settings(max(EXAMPLES // 40, 10))
@given(
    st.tuples(st.integers(65, 130), st.floats(0.0, 0.1), st.integers(65, 90), st.floats(0.3, 0.7))
    .flatmap(lambda t: st.tuples(*map(st.just, t), SEEDS))
    .map(lambda t: blocky(*t)),
    LOWER_BOUNDS,
)
def test_property_dense_core_vs_full_search(adj, lower_bound):
    # a dense core of more than 64 vertices goes to the full search, on the core alone:
    # the clique number must be the full search's on the whole graph
    best, _, status, _, _ = full_search(adj)
    assert status == 0
    check_max_clique(adj, lower_bound, omega=best.shape[0])


@pytest.mark.parametrize(
    ("adj", "path"),
    [
        (random_graph(50, 0.15, 1), "word"),
        (random_graph(64, 0.9, 1), "word"),  # dense: a node budget, then the full search
        (planted(150, 0.05, 15, 2), "empty core"),
        (planted(77, 0.085, 4, 11), "core in a word"),
        (planted(120, 0.08, 10, 3), "core in words"),
        (random_graph(300, 0.2, 11), "core in words"),
        (random_graph(400, 0.2, 11), "core in words"),  # more than 2000 nodes
        (blocky(150, 0.03, 80, 0.5, 6), "dense core"),
        (random_graph(100, 0.5, 7), "dense"),
    ],
)
def test_lean_paths(adj, path):
    assert lean_path(adj) == path
    best, _, _, _, _ = full_search(adj)
    omega = best.shape[0]
    for lower_bound in (None, omega - 1, omega, omega + 1):
        check_max_clique(adj, lower_bound, omega=omega)
    if path == "empty core":  # the peeling proves the greedy clique maximum
        assert max_clique(adj).nodes == 1


def test_lean_path_time_limit():
    # 618 nodes of the multi-word search, the clock read every 256
    adj = random_graph(300, 0.2, 11)
    assert lean_path(adj) == "core in words"
    max_clique(adj)
    r = max_clique(adj, time_limit=0.0)
    assert not r.optimal and is_clique(adj, r.vertices) and r.nodes < max_clique(adj).nodes


def test_one_word_search_time_limit():
    # the one-word search stops at its deadline (max_clique hands a dense graph like this
    # to the full search after a few hundred nodes, before the clock is read)
    from scanclique._kernels.clique_search import _bb_word
    from scanclique._kernels.codes import NO_LIMIT, Status

    adj = random_graph(64, 0.9, 59)  # 5945 nodes, the clock read every 4096
    S = bitsets_from_adjacency(adj)[:, 0].copy()
    found = np.empty(64, np.int64)
    size, nodes, status = _bb_word(S, 64, 0, 0.0, found, NO_LIMIT, np.empty(65, np.uint64))
    assert status == Status.TIME_LIMIT
    assert size == 0 or is_clique(adj, found[:size])
    size, nodes, status = _bb_word(S, 64, 0, np.inf, found, NO_LIMIT, np.empty(65, np.uint64))
    assert status == Status.FINISHED and size == max_clique(adj).size
    assert is_clique(adj, found[:size])


@pytest.mark.parametrize("n", [1, 2, 7, 8, 9, 11, 63, 64, 65, 100, 128, 130])
def test_packing(n):
    # 64 flags at a time where 64 bytes can be read, the last bytes eight or one at a time
    from scanclique._kernels.bitset import pack_checked

    adj = random_graph(n, 0.5, n)
    A, u, v = pack_checked(adj)
    assert (u, v) == (-1, -1) and np.array_equal(A, bitsets_from_adjacency(adj))
    for i, j in [(0, n - 1), (n - 1, 0), (n // 2, n - 1), (n - 1, n - 2)]:
        if i == j or min(i, j) < 0:
            continue
        bad = adj.copy()
        bad[i, j] = not bad[i, j]
        with pytest.raises(GraphError, match=rf"\({min(i, j)}, {max(i, j)}\)"):
            max_clique(bad)
        bad = adj.copy()
        bad[i, i] = True
        with pytest.raises(GraphError, match=f"self loop at vertex {i}"):
            max_clique(bad)


# -- one colouring and one set of search steps under every bound (issue 11, item 1) -------
def _colourings(adj):
    """The greedy colouring of all vertices read through the three bounds' kernels: the
    class of every vertex (kmin = 1), the classes as bitsets (kmin above the count), the
    class count, and the weighted bounds of unit weights."""
    from scanclique._kernels.colouring import colour_classes, colour_count, colour_weighted

    n = adj.shape[0]
    B = bitsets_from_adjacency(adj)
    W = B.shape[1]
    P = np.zeros(W, np.uint64)
    for v in range(n):
        P[v >> 6] |= np.uint64(1) << np.uint64(v & 63)
    U, Q = np.empty(W, np.uint64), np.empty(W, np.uint64)
    ord_v, ord_c, col = np.empty(n, np.int64), np.empty(n, np.int64), np.empty(n, np.int64)
    c = colour_classes(P, B, W, 1, U, Q, np.empty((1, W), np.uint64), ord_v, ord_c, 0, col)
    k = colour_count(P, B, W, U, Q)
    CL = np.empty((n + 1, W), np.uint64)
    c_rec = colour_classes(P, B, W, n + 2, U, Q, CL, np.empty(n, np.int64), ord_c.copy(), 0, col)
    wv, wb = np.empty(n, np.int64), np.empty(n)
    cw = colour_weighted(P, B, W, np.ones(n), -1.0, U, Q, wv, wb, 0)
    return (c, ord_v[:c], ord_c[:c]), k, (c_rec, CL[:k], col), (cw, wv[:cw], wb[:cw])


@pytest.mark.parametrize(("n", "p"), [(1, 0.5), (40, 0.3), (64, 0.5), (65, 0.2), (150, 0.6)])
def test_the_bounds_share_one_greedy_colouring(n, p):
    adj = random_graph(n, p, n)
    (c, verts, colours), k, (c_rec, CL, col), (cw, wverts, bounds) = _colourings(adj)
    # every vertex once, in non-decreasing colour; a class is independent, and a vertex of
    # class j > i has a neighbour in class i (classes are maximal, built in turn)
    assert c == n and sorted(verts.tolist()) == list(range(n))
    assert np.all(np.diff(colours) >= 0) and colours[-1] == k
    classes = [verts[colours == i + 1] for i in range(k)]
    for i, ci in enumerate(classes):
        assert not adj[np.ix_(ci, ci)].any()
        for cj in classes[i + 1 :]:
            assert adj[np.ix_(cj, ci)].any(axis=1).all()
        # in bit order within a class (the lowest uncoloured vertex first)
        assert np.all(np.diff(ci) > 0)
    # the same classes as bitsets (colour below kmin), with their index in `col`
    assert c_rec == 0
    for i, ci in enumerate(classes):
        bits = ((CL[i][:, None] >> np.arange(64, dtype=np.uint64)) & np.uint64(1)).astype(bool)
        assert np.flatnonzero(bits.reshape(-1)).tolist() == ci.tolist()
        assert np.all(col[ci] == i)
    # unit weights: the weighted bound of a vertex is its colour
    assert cw == n and wverts.tolist() == verts.tolist() and bounds.tolist() == colours.tolist()


@pytest.mark.parametrize("n", [63, 64, 65, 128, 129])
def test_weighted_and_top_at_word_boundaries(n):
    # the all-vertices set and the greedy starts of the weighted and top searches where
    # the last word is full, or holds one vertex
    adj = random_graph(n, 0.15, n)
    w = np.random.default_rng(n).random(n) * 10
    ref = list(bron_kerbosch(adj))
    r = max_clique(adj, weights=w)
    assert r.optimal and is_clique(adj, r.vertices)
    assert r.weight == pytest.approx(max(float(w[c].sum()) for c in ref), rel=1e-12)
    sizes = sorted((len(c) for c in ref), reverse=True)[:5]
    got = top_cliques(adj, 5)
    assert [len(c) for c in got] == sizes
    assert all(is_clique(adj, c) for c in got)


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


# -- node budgets: results that do not depend on the machine (issue 15, item 3) ------------
BUDGET_GRAPHS = [
    pytest.param(random_graph(40, 0.7, 2), id="word"),
    pytest.param(random_graph(64, 0.9, 59), id="word-dense-then-full"),
    pytest.param(random_graph(400, 0.2, 11), id="core-in-words"),
    pytest.param(blocky(150, 0.03, 80, 0.5, 6), id="dense-core"),
    pytest.param(random_graph(100, 0.5, 7), id="dense"),
]


@pytest.mark.parametrize("adj", BUDGET_GRAPHS)
def test_node_limit_gives_the_same_result_regardless_of_time(adj):
    full = max_clique(adj)
    assert full.optimal and full.reason is None and full.nodes > 3
    for limit in (1, full.nodes // 3, full.nodes - 1):
        runs = [max_clique(adj, node_limit=limit, time_limit=t) for t in (None, 1e6, None)]
        assert len({(tuple(r.vertices.tolist()), r.nodes, r.optimal) for r in runs}) == 1
        r = runs[0]
        assert is_clique(adj, r.vertices) and r.size <= full.size
        assert r.nodes <= limit + 2
        if not r.optimal:
            assert r.reason == "node_limit"
    # a limit the search does not reach changes nothing
    r = max_clique(adj, node_limit=full.nodes + 5)
    assert r.optimal and r.vertices.tolist() == full.vertices.tolist() and r.nodes == full.nodes


def test_node_limit_stops_a_search_that_cannot_finish():
    adj = random_graph(400, 0.9, 5)
    a, b = (max_clique(adj, node_limit=5000) for _ in range(2))
    assert not a.optimal and a.reason == "node_limit" and a.nodes <= 5002
    assert a.vertices.tolist() == b.vertices.tolist() and is_clique(adj, a.vertices)


@pytest.mark.parametrize("adj", BUDGET_GRAPHS[1:])
def test_node_limit_of_the_other_entry_points(adj):
    full = all_maximum_cliques(adj, limit=10**6)
    assert full.complete and full.reason is None and full.nodes > 0
    limit = max(full.nodes // 2, 1)
    a, b = (
        all_maximum_cliques(adj, limit=10**6, node_limit=limit, time_limit=t) for t in (None, 1e6)
    )
    assert [c.tolist() for c in a.cliques] == [c.tolist() for c in b.cliques]
    assert (a.omega, a.optimal, a.complete, a.nodes) == (b.omega, b.optimal, b.complete, b.nodes)
    assert not a.complete and a.reason == "node_limit" and a.nodes <= limit + 2
    assert all(is_clique(adj, c) for c in a.cliques)
    w = np.arange(adj.shape[0], dtype=float) % 7 + 1
    fw = max_clique(adj, weights=w)
    if fw.nodes > 2:
        ws = [max_clique(adj, weights=w, node_limit=fw.nodes // 2) for _ in range(2)]
        assert ws[0].vertices.tolist() == ws[1].vertices.tolist() and ws[0].weight == ws[1].weight
        assert not ws[0].optimal and ws[0].reason == "node_limit"
    t1, t2 = (top_cliques(adj, 4, node_limit=50) for _ in range(2))
    assert [c.tolist() for c in t1] == [c.tolist() for c in t2] and len(t1) >= 1


def test_reasons():
    adj = random_graph(50, 0.5, 4)
    omega = max_clique(adj).size
    assert max_clique(adj, lower_bound=omega + 1).reason == "lower_bound"
    assert max_clique(adj, lower_bound=omega).reason is None
    G = nx.turan_graph(12, 4)
    a = all_maximum_cliques(G, limit=10)
    assert a.optimal and not a.complete and a.reason == "clique_limit"
    r = max_clique(random_graph(400, 0.9, 5), time_limit=0.05)
    assert not r.optimal and r.reason == "time_limit"


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"time_limit": "1"}, "time_limit must be a number"),
        ({"time_limit": True}, "time_limit must be a number"),
        ({"time_limit": -1.0}, "non-negative"),
        ({"node_limit": 2.5}, "node_limit must be an int"),
        ({"node_limit": "10"}, "node_limit must be an int"),
        ({"node_limit": -1}, "node_limit must be non-negative"),
    ],
)
def test_budget_arguments_are_checked(kwargs, match):
    adj = random_graph(10, 0.5, 1)
    for f in (max_clique, all_maximum_cliques, lambda g, **kw: top_cliques(g, 2, **kw)):
        with pytest.raises(GraphError, match=match):
            f(adj, **kwargs)


# -- bounded memory: vertex counts checked before allocating (issue 15, item 2) ------------
def test_edge_list_naming_a_huge_vertex_is_refused():
    e = np.array([[0, 10**8]])
    for f in (max_clique, all_maximum_cliques, as_adjacency, lambda g: top_cliques(g, 2)):
        with pytest.raises(GraphError, match=r"edge list: 100000001 vertices would need 10\.0 PiB"):
            f(e)
    with pytest.raises(GraphError, match="limit is 32768 vertices"):
        as_adjacency((np.zeros((0, 2), np.int64), 10**6))
    with pytest.raises(GraphError, match="limit is 100 vertices"):
        as_adjacency((np.array([[0, 1]]), 101), max_vertices=100)
    assert as_adjacency((np.array([[0, 1]]), 100), max_vertices=100).shape == (100, 100)
    with pytest.raises(GraphError, match="networkx graph: 40000 vertices"):
        max_clique(nx.empty_graph(40000))
    with pytest.raises(GraphError, match="max_vertices must be a non-negative int"):
        as_adjacency(e, max_vertices=1.5)


def test_vertex_bound_from_the_environment(monkeypatch):
    monkeypatch.setenv("SCANCLIQUE_MAX_VERTICES", "10")
    with pytest.raises(GraphError, match="limit is 10 vertices"):
        max_clique(np.array([[0, 10]]))
    assert max_clique(np.array([[0, 9]])).size == 2
    monkeypatch.setenv("SCANCLIQUE_MAX_VERTICES", "lots")
    with pytest.raises(GraphError, match="SCANCLIQUE_MAX_VERTICES must be a whole number"):
        max_clique(np.array([[0, 9]]))


def test_huge_vertex_is_refused_under_a_memory_limit(tmp_path):
    # in a child limited to 1 GiB of address space: a GraphError, not numpy's MemoryError
    import subprocess
    import sys

    code = (
        "import resource, numpy as np\n"
        "resource.setrlimit(resource.RLIMIT_AS, (1 << 30, 1 << 30))\n"
        "from scanclique.clique import max_clique\n"
        "from scanclique.errors import GraphError\n"
        "try:\n"
        "    max_clique(np.array([[0, 10**8]]))\n"
        "except GraphError as e:\n"
        "    print('GraphError', e)\n"
    )
    env = {k: v for k, v in os.environ.items() if k != "SCANCLIQUE_MAX_VERTICES"}
    env["PYTHONPATH"] = str(Path(__file__).resolve().parents[1] / "src")
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env)
    assert r.returncode == 0, r.stderr[-2000:]
    assert r.stdout.startswith("GraphError edge list: 100000001 vertices would need")


# -- DIMACS files: weights used or refused, omega only when proven (issue 15, item 13) -----
def _weighted_file(tmp_path) -> Path:
    from scanclique.io.dimacs import write_dimacs

    # K4 on vertices 1..4 (weight 1 each), and the edge 5-6 (weight 10 each)
    edges = np.array([[0, 1], [0, 2], [0, 3], [1, 2], [1, 3], [2, 3], [4, 5]])
    path = tmp_path / "w.clq"
    write_dimacs(path, (edges, 6), weights=np.array([1, 1, 1, 1, 10, 10.0]))
    return path


def test_solve_file_uses_vertex_weights(tmp_path):
    path = _weighted_file(tmp_path)
    out = solve_file(path)
    json.dumps(out)
    assert out["weighted"] and out["clique"] == [5, 6] and out["weight"] == 20.0
    assert out["optimal"] and out["omega"] is None and out["size"] == 2
    out = solve_file(path, weights=False)
    assert not out["weighted"] and out["clique"] == [1, 2, 3, 4] and out["omega"] == 4
    assert out["weight"] is None
    with pytest.raises(GraphError, match="vertex weights.*by cardinality"):
        solve_file(path, all=True)
    assert solve_file(path, all=True, weights=False)["cliques"] == [[1, 2, 3, 4]]
    with pytest.raises(GraphError, match="no 'n v w' weight lines"):
        solve_file(_unweighted(tmp_path), weights=True)


def _unweighted(tmp_path) -> Path:
    from scanclique.io.dimacs import write_dimacs

    path = tmp_path / "u.clq"
    write_dimacs(path, random_graph(12, 0.5, 3))
    return path


def test_solve_file_reports_omega_only_when_proven(tmp_path):
    from scanclique.io.dimacs import write_dimacs

    path = tmp_path / "hard.clq"
    write_dimacs(path, random_graph(300, 0.9, 8))
    out = solve_file(path, node_limit=100)
    assert not out["optimal"] and out["reason"] == "node_limit" and out["omega"] is None
    assert out["size"] >= 20 and len(out["clique"]) == out["size"]
    with pytest.raises(GraphError, match="limit is 100 vertices"):
        solve_file(path, max_vertices=100)


# -- the kernel cache stamp (issue 11, item 5) ---------------------------------------------
def test_kernel_stamp_changes_with_any_kernel_source(tmp_path):
    import shutil

    import scanclique
    from scanclique._kernels import kernel_sources, kernel_stamp

    src = kernel_sources()
    names = {p.name for p in src}
    assert {"__init__.py", "clique_search.py", "bitset.py"} <= names
    assert any(p.name.endswith("_kernels.py") and p.parent.name == "scanclique" for p in src)
    root = Path(scanclique.__file__).resolve().parent
    pkg = tmp_path / "pkg"
    for p in src:
        dest = pkg / p.resolve().relative_to(root)
        dest.parent.mkdir(parents=True, exist_ok=True)
        shutil.copy(p, dest)
    copies = kernel_sources(pkg)
    assert len(copies) == len(src) and kernel_stamp(copies) == kernel_stamp()
    before = kernel_stamp(copies)
    callee = pkg / "_kernels" / "bitset.py"
    callee.write_text(callee.read_text().replace("ONE = np.uint64(1)", "ONE = np.uint64(1)  #"))
    assert kernel_stamp(kernel_sources(pkg)) != before
    (pkg / "_kernels" / "extra.py").write_text("")
    assert len({before, kernel_stamp(kernel_sources(pkg))}) == 2


def test_cache_dir_respects_the_users_numba_cache_dir(tmp_path, monkeypatch):
    from scanclique._kernels import _MARK, cache_dir_for

    monkeypatch.delenv(_MARK, raising=False)
    monkeypatch.setenv("NUMBA_CACHE_DIR", str(tmp_path))
    assert cache_dir_for("abc") == tmp_path / "scanclique-abc"
    # a child process inherits the stamped directory: it is not stamped again
    monkeypatch.setenv("NUMBA_CACHE_DIR", str(tmp_path / "scanclique-abc"))
    monkeypatch.setenv(_MARK, str(tmp_path / "scanclique-abc"))
    assert cache_dir_for("abc") == tmp_path / "scanclique-abc"
    assert cache_dir_for("def") == tmp_path / "scanclique-def"
    monkeypatch.delenv("NUMBA_CACHE_DIR")
    monkeypatch.delenv(_MARK)
    assert cache_dir_for("abc").name == "kernels-abc"


_CALLER = """
from ._kernels import callee
import numba

@numba.njit(cache=True)
def g(x):
    return 10 * callee.f(x)
"""
_CALLEE = """
import numba

@numba.njit(cache=True)
def f(x):
    return x + {k}
"""
_STAMPED = """
import os
from scanclique._kernels import ensure_cache

ensure_cache(package=os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
"""


def _run_caller(root: Path, k: int) -> int:
    """Write the callee with ``x + k``, then call the caller from a fresh process."""
    import subprocess
    import sys

    (root / "kpkg" / "_kernels" / "callee.py").write_text(_CALLEE.format(k=k))
    env = {
        key: v
        for key, v in os.environ.items()
        if key not in ("NUMBA_CACHE_DIR", "SCANCLIQUE_KERNEL_CACHE")
    }
    src = Path(__file__).resolve().parents[1] / "src"
    env["PYTHONPATH"] = os.pathsep.join([str(root), str(src)])
    code = "import kpkg._caller_kernels as m; print(m.g(1))"
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env)
    assert r.returncode == 0, r.stderr[-2000:]
    return int(r.stdout.split()[-1])


def _kernel_package(root: Path, stamped: bool) -> None:
    (root / "kpkg" / "_kernels").mkdir(parents=True)
    (root / "kpkg" / "__init__.py").write_text("")
    (root / "kpkg" / "_kernels" / "__init__.py").write_text(_STAMPED if stamped else "")
    (root / "kpkg" / "_caller_kernels.py").write_text(_CALLER)


def test_editing_a_callee_recompiles_its_callers(tmp_path):
    # the documented trap, gone: a cached kernel that calls a kernel of another module
    # sees the callee's edit in the next process
    _kernel_package(tmp_path, stamped=True)
    assert _run_caller(tmp_path, 1) == 20
    assert _run_caller(tmp_path, 1) == 20  # from the cache
    assert _run_caller(tmp_path, 2) == 30  # the callee changed: recompiled
    stamps = list((tmp_path / "kpkg" / "__pycache__").glob("kernels-*"))
    assert len(stamps) == 2


@pytest.mark.slow
@pytest.mark.skipif(not SLOW, reason="seconds; set SCANCLIQUE_SLOW_TESTS=1")
def test_without_the_stamp_the_trap_is_real(tmp_path):
    # the control: numba's own cache keeps the caller's stale code (why the stamp exists)
    _kernel_package(tmp_path, stamped=False)
    assert _run_caller(tmp_path, 1) == 20
    assert _run_caller(tmp_path, 2) == 20


@pytest.mark.slow
@pytest.mark.skipif(not SLOW, reason="compiles every kernel (a minute); SCANCLIQUE_SLOW_TESTS=1")
def test_compilation_does_not_count_against_the_time_limit(tmp_path):
    # an empty cache: the first call compiles for tens of seconds, yet a 1 s limit on a
    # graph that takes milliseconds ends in the same proven clique as in a warm process
    import subprocess
    import sys

    code = (
        "import numpy as np\n"
        "from scanclique.clique import max_clique\n"
        "rng = np.random.default_rng(7)\n"
        "a = np.triu(rng.random((100, 100)) < 0.5, 1)\n"
        "r = max_clique(a | a.T, time_limit=1.0)\n"
        "print(r.optimal, r.reason, ' '.join(map(str, r.vertices)))\n"
    )
    env = {k: v for k, v in os.environ.items() if k != "SCANCLIQUE_KERNEL_CACHE"}
    env["NUMBA_CACHE_DIR"] = str(tmp_path)
    env["PYTHONPATH"] = str(Path(__file__).resolve().parents[1] / "src")
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env)
    assert r.returncode == 0, r.stderr[-2000:]
    warm = max_clique(random_graph_like_child(), time_limit=1.0)
    assert r.stdout.split() == ["True", "None", *map(str, warm.vertices.tolist())]
    assert list(tmp_path.glob("scanclique-*")), "the cache went to the stamped directory"


def random_graph_like_child() -> np.ndarray:
    rng = np.random.default_rng(7)
    a = np.triu(rng.random((100, 100)) < 0.5, 1)
    return a | a.T


def test_stale_stamped_caches_are_pruned(tmp_path):
    # directories of other stamps beside the current one go once unwritten for a day
    from scanclique._kernels import _prune

    keep, old, recent, other = (tmp_path / n for n in ("kernels-a", "kernels-b", "kernels-c", "x"))
    for d in (keep, old, recent, other):
        (d / "sub").mkdir(parents=True)
        (d / "sub" / "f.nbi").write_text("")
    day_ago = time.time() - 2 * 86400
    for d in (old, other):
        for p in (d, d / "sub", d / "sub" / "f.nbi"):
            os.utime(p, (day_ago, day_ago))
    _prune(keep)
    assert keep.exists() and recent.exists() and other.exists() and not old.exists()
