"""Correspondence graph (paper §5.2): the compiled kernel against a slow reference written
from the definition, over features directly (so it checks the feature graph's layers too)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from scanclique.config import CorrespondenceConfig, FeatureConfig
from scanclique.correspondence import candidate_pairs, correspondence_graph
from scanclique.errors import GraphError
from scanclique.features import CORNER, EDGE_CCW, EDGE_CW, FOREGROUND_POINT, Features
from scanclique.geometry import Pose2
from scanclique.graph import LINE, PARALLEL_MAX_ANGLE, FeatureGraph, feature_graph


def make_features(points=(), labels=None, lines=()) -> Features:
    p = np.asarray(points, dtype=float).reshape(-1, 2)
    ln = np.asarray(lines, dtype=float).reshape(-1, 2)
    P, L = len(p), len(ln)
    lab = np.zeros(P, np.int8) if labels is None else np.asarray(labels, np.int8)
    return Features(
        points_xy=p,
        points_label=lab,
        points_cov=np.tile(np.eye(2) * 1e-4, (P, 1, 1)),
        points_beam=np.arange(P),
        lines_rho_alpha=ln,
        lines_ends=np.zeros((L, 2, 2)),
        lines_cov=np.tile(np.diag([1e-4, 1e-6]), (L, 1, 1)),
        lines_beams=np.zeros((L, 2), np.int64),
        lines_n_points=np.full(L, 10),
        clusters=np.zeros((0, 2), np.int64),
    )


def build(fa, fb, cfg=None, fcfg=None):
    cfg = cfg or CorrespondenceConfig()
    return correspondence_graph(feature_graph(fa, cfg, fcfg), feature_graph(fb, cfg, fcfg), cfg)


# -- the slow reference: paper §5.1 invariants and §5.2 edges, one pair of pairs at a time ------
def _wrap(a):
    return (a + math.pi) % (2 * math.pi) - math.pi


def node_list(f: Features, typed: bool):
    """(label, kind, payload) per node: points first, then lines."""
    out = []
    for (x, y), lab in zip(f.points_xy, f.points_label, strict=True):
        out.append((int(lab) if typed else 0, "p", (float(x), float(y))))
    for rho, alpha in f.lines_rho_alpha:
        out.append((LINE, "l", (float(rho), float(alpha))))
    return out


def relation(n1, n2, cfg: CorrespondenceConfig) -> dict:
    """The invariants of one node pair: {name: (value, tolerance, circular)}."""
    k1, v1 = n1[1], n1[2]
    k2, v2 = n2[1], n2[2]
    if k1 == "p" and k2 == "p":
        return {"dist": (math.hypot(v1[0] - v2[0], v1[1] - v2[1]), cfg.point_point, False)}
    if k1 != k2:
        (x, y), (rho, alpha) = (v1, v2) if k1 == "p" else (v2, v1)
        s = x * math.cos(alpha) + y * math.sin(alpha) - rho
        return {"dist": (s if cfg.signed else abs(s), cfg.point_line, False)}
    da = v2[1] - v1[1]
    if cfg.signed:
        out = {"angle": (_wrap(da), cfg.line_line, True)}
    else:
        a = abs(da) % math.pi
        out = {"angle": (min(a, math.pi - a), cfg.line_line, False)}
    if cfg.parallel_offset and abs(math.sin(da)) < math.sin(PARALLEL_MAX_ANGLE):
        off = v2[0] - v1[0] if math.cos(da) > 0 else v2[0] + v1[0]
        out["offset"] = (off if cfg.signed else abs(off), cfg.point_line, False)
    return out


def reference_graph(fa, fb, cfg: CorrespondenceConfig, typed: bool = True):
    na, nb = node_list(fa, typed), node_list(fb, typed)
    pairs = [(i, j) for i in range(len(na)) for j in range(len(nb)) if na[i][0] == nb[j][0]]
    n = len(pairs)
    adj = np.zeros((n, n), bool)
    for u in range(n):
        for v in range(n):
            (a1, b1), (a2, b2) = pairs[u], pairs[v]
            if a1 == a2 or b1 == b2:
                continue
            ra, rb = relation(na[a1], na[a2], cfg), relation(nb[b1], nb[b2], cfg)
            ok = True
            for key in ra.keys() & rb.keys():
                (x, tol, circ), (y, _, _) = ra[key], rb[key]
                d = abs(x - y)
                if circ:
                    d = min(d % (2 * math.pi), 2 * math.pi - d % (2 * math.pi))
                ok &= d <= tol
            adj[u, v] = ok
    return np.array(pairs, dtype=np.int64).reshape(-1, 2), adj


def random_pair(rng: np.random.Generator, n_common: int, n_extra: int, noise: float):
    """Features of A, and of B = a rigid motion of some of A's features, noise and clutter."""
    labels = [FOREGROUND_POINT, EDGE_CW, EDGE_CCW, CORNER]
    n_pts = rng.integers(0, n_common + 1)
    n_lines = n_common - n_pts
    pts = rng.uniform(-6, 6, (n_pts, 2))
    lab = rng.choice(labels, n_pts)
    alpha = rng.uniform(-math.pi, math.pi, n_lines)
    if n_lines > 1:  # some exact (anti)parallels: corridors
        k = rng.integers(0, n_lines, n_lines // 2)
        alpha[: n_lines // 2] = alpha[k] + rng.choice([0.0, math.pi], n_lines // 2)
    lines = np.column_stack((rng.uniform(2.0, 8.0, n_lines), alpha))
    fa = make_features(pts, lab, lines)
    T = Pose2(rng.uniform(-1, 1), rng.uniform(-1, 1), rng.uniform(-math.pi, math.pi))
    inv = T.inverse()
    pb = inv.transform(pts) + rng.normal(0, noise, pts.shape) if n_pts else pts
    lb = []
    for rho, a in lines:
        ab = a - T.theta
        n = np.array([math.cos(ab), math.sin(ab)])
        lb.append((rho + n @ inv.translation + rng.normal(0, noise), ab + rng.normal(0, noise / 5)))
    keep = rng.random(n_pts) < 0.8
    pb, labb = pb[keep], lab[keep]
    extra = rng.uniform(-6, 6, (n_extra, 2))
    pb = np.vstack((pb, extra))
    labb = np.concatenate((labb, rng.choice(labels, n_extra)))
    lb += [(rng.uniform(2, 8), rng.uniform(-math.pi, math.pi)) for _ in range(rng.integers(0, 2))]
    order = rng.permutation(len(pb))
    return fa, make_features(pb[order], labb[order], lb)


@settings(max_examples=60, deadline=None)
@given(
    seed=st.integers(0, 2**32 - 1),
    n_common=st.integers(0, 9),
    n_extra=st.integers(0, 4),
    noise=st.sampled_from([0.0, 0.05, 0.3]),
    signed=st.booleans(),
    parallel=st.booleans(),
    typed=st.booleans(),
)
def test_kernel_matches_reference(seed, n_common, n_extra, noise, signed, parallel, typed):
    fa, fb = random_pair(np.random.default_rng(seed), n_common, n_extra, noise)
    cfg = CorrespondenceConfig(signed=signed, parallel_offset=parallel)
    cg = build(fa, fb, cfg, FeatureConfig(typed_edges=typed))
    pairs, adj = reference_graph(fa, fb, cfg, typed)
    np.testing.assert_array_equal(cg.pairs, pairs)
    np.testing.assert_array_equal(cg.adjacency, adj)


def test_kernel_matches_reference_on_a_bigger_case():
    rng = np.random.default_rng(123)
    fa, fb = random_pair(rng, 16, 5, 0.05)
    cg = build(fa, fb)
    pairs, adj = reference_graph(fa, fb, CorrespondenceConfig())
    assert cg.n_edges > 20  # not a vacuous comparison
    np.testing.assert_array_equal(cg.pairs, pairs)
    np.testing.assert_array_equal(cg.adjacency, adj)


def test_true_association_is_a_clique():
    rng = np.random.default_rng(5)
    pts = rng.uniform(-5, 5, (6, 2))
    T = Pose2(0.4, -0.3, 1.2)
    fa = make_features(pts)
    fb = make_features(T.inverse().transform(pts)[::-1])  # reversed order in B
    cg = build(fa, fb)
    truth = [
        int(np.flatnonzero((cg.pairs[:, 0] == i) & (cg.pairs[:, 1] == 5 - i))[0]) for i in range(6)
    ]
    sub = cg.adjacency[np.ix_(truth, truth)]
    assert np.all(sub | np.eye(6, dtype=bool))


# -- known answers -----------------------------------------------------------------------------
@pytest.mark.parametrize(
    ("d_b", "edges"), [(3.2, [(0, 3), (1, 2)]), (3.29, [(0, 3), (1, 2)]), (3.31, [])]
)
def test_two_points_known_answer(d_b, edges):
    fa = make_features([[0.0, 0.0], [3.0, 0.0]])
    fb = make_features([[5.0, 5.0], [5.0, 5.0 + d_b]])
    cg = build(fa, fb)
    assert cg.pairs.tolist() == [[0, 0], [0, 1], [1, 0], [1, 1]]
    expected = np.zeros((4, 4), bool)
    for u, v in edges:
        expected[u, v] = expected[v, u] = True
    np.testing.assert_array_equal(cg.adjacency, expected)
    assert cg.n_edges == len(edges)


def test_signed_angle_compared_across_the_cut():
    # angle from line 0 to line 1: 3.1 in A, -3.1 in B: 0.083 rad apart modulo 2 pi
    fa = make_features(lines=[[2.0, 0.0], [3.0, 3.1]])
    fb = make_features(lines=[[2.0, 0.0], [3.0, -3.1]])
    cg = build(fa, fb, CorrespondenceConfig(parallel_offset=False))
    u = cg.pairs.tolist().index([0, 0])
    v = cg.pairs.tolist().index([1, 1])
    assert cg.adjacency[u, v]


def test_mirror_image_rejected_by_signed_invariants():
    # B is A's mirror image: same distances and acute angles, opposite signed ones
    fa = make_features([[1.0, 0.5]], lines=[[3.0, 0.2], [2.5, 1.4]])
    fb = make_features([[1.0, -0.5]], lines=[[3.0, -0.2], [2.5, -1.4]])
    truth = [[0, 0], [1, 1], [2, 2]]

    def is_clique(cg):
        idx = [cg.pairs.tolist().index(p) for p in truth]
        return bool(np.all(cg.adjacency[np.ix_(idx, idx)] | np.eye(3, dtype=bool)))

    assert is_clique(build(fa, fb, CorrespondenceConfig(signed=False)))
    assert not is_clique(build(fa, fb, CorrespondenceConfig(signed=True)))


def test_same_label_pairing_only():
    fa = make_features([[0, 0], [1, 0], [0, 2]], [EDGE_CW, EDGE_CCW, CORNER], lines=[[2.0, 0.0]])
    fb = make_features([[0, 0], [1, 1]], [EDGE_CW, EDGE_CW], lines=[[2.0, 0.0], [3.0, 1.0]])
    cg = build(fa, fb)
    # EDGE_CW of A with both EDGE_CW of B; A's line with both lines of B (node 3 = line 0)
    assert cg.pairs.tolist() == [[0, 0], [0, 1], [3, 2], [3, 3]]
    ga, gb = feature_graph(fa), feature_graph(fb)
    assert np.all(ga.labels[cg.pairs[:, 0]] == gb.labels[cg.pairs[:, 1]])
    # the paper's untyped points pair any point with any point, never with a line
    cg_u = build(fa, fb, fcfg=FeatureConfig(typed_edges=False))
    assert len(cg_u.pairs) == 3 * 2 + 1 * 2


def test_candidate_pairs_order():
    got = candidate_pairs(np.array([1, 0, 1]), np.array([0, 1, 1]))
    assert got.tolist() == [[0, 1], [0, 2], [1, 0], [2, 1], [2, 2]]
    assert candidate_pairs(np.zeros(0, int), np.array([1])).shape == (0, 2)


def test_no_edge_shares_a_node():
    rng = np.random.default_rng(9)
    fa, fb = random_pair(rng, 10, 3, 0.0)
    cg = build(fa, fb)
    u, v = np.nonzero(cg.adjacency)
    assert len(u) > 0
    assert np.all(cg.pairs[u, 0] != cg.pairs[v, 0])
    assert np.all(cg.pairs[u, 1] != cg.pairs[v, 1])
    np.testing.assert_array_equal(cg.adjacency, cg.adjacency.T)
    assert not np.any(np.diag(cg.adjacency))
    n = cg.n_nodes
    assert cg.density == pytest.approx(2 * cg.n_edges / (n * (n - 1)))


def test_empty_inputs():
    cg = build(make_features(), make_features([[0, 0]]))
    assert cg.n_nodes == 0 and cg.n_edges == 0 and cg.density == 0.0
    cg1 = build(make_features([[0, 0]]), make_features([[1, 1]]))
    assert cg1.n_nodes == 1 and cg1.n_edges == 0


def test_max_nodes():
    fa = make_features(np.arange(20.0).reshape(10, 2))
    fb = make_features(np.arange(20.0).reshape(10, 2))
    with pytest.raises(GraphError, match="100 nodes"):
        build(fa, fb, CorrespondenceConfig(max_nodes=99))
    assert build(fa, fb, CorrespondenceConfig(max_nodes=100)).n_nodes == 100


def test_layer_mismatch():
    ga = feature_graph(make_features([[0, 0], [1, 0]]))
    gb = FeatureGraph(
        labels=ga.labels,
        kinds=ga.kinds,
        invariants=ga.invariants[:2],
        tolerances=ga.tolerances[:2],
        circular=ga.circular[:2],
        n_points=ga.n_points,
    )
    with pytest.raises(GraphError, match="layers"):
        correspondence_graph(ga, gb)


def test_adjacency_read_only():
    cg = build(make_features([[0, 0], [3, 0]]), make_features([[0, 0], [3, 0]]))
    with pytest.raises(ValueError):
        cg.adjacency[0, 0] = True


def test_graphs_of_other_tolerances_are_refused():
    from scanclique.config import CorrespondenceConfig
    from scanclique.errors import ConfigError
    from scanclique.features import extract_features
    from scanclique.graph import feature_graph
    from scanclique.sim import simulate_pair

    pair = simulate_pair(np.random.default_rng(0))
    fa, fb = extract_features(pair.scan_a), extract_features(pair.scan_b)
    loose = CorrespondenceConfig(point_point=0.6)
    ga, gb = feature_graph(fa), feature_graph(fb, loose)
    with pytest.raises(ConfigError, match="graph_b was built with other tolerances"):
        correspondence_graph(ga, gb)
    with pytest.raises(ConfigError, match="graph_a"):
        correspondence_graph(ga, feature_graph(fb), loose)
    # max_nodes is no tolerance: a graph built under another limit still pairs
    cg = correspondence_graph(ga, feature_graph(fb), CorrespondenceConfig(max_nodes=10**6))
    assert cg.n_nodes > 0


def test_too_many_pairings_are_refused_before_allocating():
    from scanclique.config import CorrespondenceConfig
    from scanclique.correspondence import count_pairs
    from scanclique.errors import GraphError

    la = np.array([0, 0, 1, 8, 8, 8])
    lb = np.array([0, 1, 1, 8, 2])
    assert count_pairs(la, lb) == len(candidate_pairs(la, lb)) == 2 * 1 + 1 * 2 + 3 * 1
    assert count_pairs(la[:0], lb) == 0
    # 3000 nodes of one label each side: 9e6 pairings, refused from the counts alone
    big = np.zeros(3000, dtype=np.int64)
    assert count_pairs(big, big) == 9_000_000
    from scanclique.graph import FeatureGraph

    def labels_only(labels):  # the count check reads only the labels and the config
        z = np.zeros((3, 1, 1))
        return FeatureGraph(labels, labels, z, z, np.zeros(3, bool), len(labels))

    with pytest.raises(GraphError, match="9000000 nodes.*max_nodes=20000"):
        correspondence_graph(labels_only(big), labels_only(big), CorrespondenceConfig())


def test_a_scan_with_too_many_features_is_refused_before_its_graph_is_built():
    from scanclique.config import CorrespondenceConfig
    from scanclique.errors import GraphError as _GraphError
    from scanclique.features import Features
    from scanclique.graph import feature_graph

    n = 50
    f = Features(
        np.column_stack((np.arange(n, dtype=float), np.ones(n))), np.zeros(n, np.int8),
        np.tile(np.eye(2) * 1e-4, (n, 1, 1)), np.arange(n), np.zeros((0, 2)),
        np.zeros((0, 2, 2)), np.zeros((0, 2, 2)), np.zeros((0, 2), int),
        np.zeros(0, int), np.zeros((0, 2), int),
    )  # fmt: skip
    assert feature_graph(f).n_nodes == n
    with pytest.raises(_GraphError, match="feature graph of 50 features.*max_features=49"):
        feature_graph(f, CorrespondenceConfig(max_features=49))


def test_a_raised_max_nodes_beyond_memory_is_a_graph_error_not_a_crash():
    """Issue 15 item 5: ``max_nodes = 10**9`` with thousands of features must end in a
    GraphError naming the memory, whatever the machine holds (run under an address-space
    limit, so that the allocation fails here as it would on a small machine)."""
    import subprocess
    import sys

    code = (
        "import resource, numpy as np\n"
        "resource.setrlimit(resource.RLIMIT_AS, (2 * 2**30, 2 * 2**30))\n"
        "from scanclique.config import CorrespondenceConfig\n"
        "from scanclique.correspondence import correspondence_graph\n"
        "from scanclique.errors import GraphError\n"
        "from scanclique.graph import FeatureGraph\n"
        "z = np.zeros((3, 1, 1)); lab = np.zeros(200_000, np.int64)\n"
        "g = FeatureGraph(lab, lab, z, z, np.zeros(3, bool), len(lab))\n"
        "try:\n"
        "    correspondence_graph(g, g, CorrespondenceConfig(max_nodes=10**12))\n"
        "except GraphError as e:\n"
        "    print('GraphError', e)\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr[-2000:]
    assert out.stdout.startswith("GraphError") and "GiB" in out.stdout, out.stdout
