"""The compiled matching kernels (``scanclique._match_kernels``) against plain references:
brute-force neighbour search, the NumPy pose estimates, a KD-tree for the normals and
Bron–Kerbosch for the small maximum clique."""

from __future__ import annotations

import itertools
import math
import time

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial import cKDTree

from scanclique import _match_kernels as K
from scanclique.clique import bron_kerbosch
from scanclique.config import MatchConfig
from scanclique.correspondence import correspondence_graph
from scanclique.geometry import Pose2
from scanclique.match import prepare_scan
from scanclique.pose import (
    closed_form_pose,
    closed_form_pose_pairs,
    estimate_pose_lsq,
    estimate_pose_lsq_pairs,
    mapped_features,
)
from scanclique.refine import agreement, nearest, reference_cloud
from scanclique.sim import simulate_pair


def _cloud(rng, n, full_turn):
    """Points around a sensor: some very near it (the window search's fallback), the
    bearings spanning the +-pi seam when ``full_turn``."""
    span = math.pi if full_turn else math.pi / 2
    phi = rng.uniform(-span, span, n)
    r = np.where(rng.random(n) < 0.1, rng.uniform(0.01, 0.3, n), rng.uniform(0.3, 8.0, n))
    return np.column_stack((r * np.cos(phi), r * np.sin(phi)))


@pytest.mark.parametrize("full_turn", [False, True])
@pytest.mark.parametrize("seed", range(4))
def test_window_search_equals_brute_force(seed, full_turn):
    rng = np.random.default_rng(seed)
    ref = reference_cloud(_cloud(rng, 400, full_turn))
    q = _cloud(rng, 300, full_turn)
    pose = Pose2(rng.normal(0, 0.3), rng.normal(0, 0.3), rng.uniform(-math.pi, math.pi))
    moved = pose.transform(q)
    d_all = np.linalg.norm(moved[:, None, :] - ref.points[None, :, :], axis=2)
    for dmax in (0.05, 0.15, 0.5):
        idx, d = nearest(ref, q, pose, dmax)
        best = d_all.min(axis=1)
        found = best < dmax
        assert np.array_equal(idx >= 0, found)
        np.testing.assert_allclose(d[found], best[found], atol=1e-12)
        assert agreement(ref, q, pose, dmax) == pytest.approx(found.mean())


def test_normals_equal_a_kd_tree_pca():
    p = simulate_pair(np.random.default_rng(2)).scan_a.points()
    ref = reference_cloud(p)
    pts = ref.points
    d, idx = cKDTree(pts).query(pts, k=5)
    w = (d <= 0.3).astype(float)
    cnt = w.sum(axis=1)
    nb = pts[idx]
    mean = np.einsum("mk,mkd->md", w, nb) / np.maximum(cnt, 1)[:, None]
    q = (nb - mean[:, None, :]) * w[:, :, None]
    normals = np.linalg.eigh(np.einsum("mki,mkj->mij", q, q))[1][:, :, 0]
    normals[cnt < 3] = 0.0
    same = np.abs(np.sum(normals * ref.normals, axis=1))
    zero = np.abs(normals).sum(axis=1) == 0
    agree = np.where(zero, np.abs(ref.normals).sum(axis=1) == 0, same > 1 - 1e-9)
    assert agree.mean() > 0.995  # the rest: exact ties for the 5th neighbour


@pytest.mark.parametrize("seed", range(6))
def test_compiled_poses_equal_the_numpy_estimates(seed):
    cfg = MatchConfig()
    p = simulate_pair(np.random.default_rng(seed))
    a, b = prepare_scan(p.scan_a, cfg), prepare_scan(p.scan_b, cfg)
    cg = correspondence_graph(a.graph, b.graph, cfg.correspondence)
    rng = np.random.default_rng(seed)
    for _ in range(20):
        k = int(rng.integers(2, min(8, cg.n_nodes) + 1))
        pairs = cg.pairs[np.sort(rng.choice(cg.n_nodes, k, replace=False))]
        m = mapped_features(a.features, b.features, pairs)
        ref, got = closed_form_pose(m), closed_form_pose_pairs(a.features, b.features, pairs)
        assert (ref is None) == (got is None)
        if ref is None:
            continue
        np.testing.assert_allclose(got.as_array(), ref.as_array(), atol=1e-9)
        e_ref = estimate_pose_lsq(m)
        e_got = estimate_pose_lsq_pairs(a.features, b.features, pairs)
        np.testing.assert_allclose(e_got.pose.as_array(), e_ref.pose.as_array(), atol=1e-9)
        np.testing.assert_allclose(e_got.residuals, e_ref.residuals, rtol=1e-6, atol=1e-9)
        assert np.array_equal(np.isinf(e_got.covariance), np.isinf(e_ref.covariance))
        fin = np.isfinite(e_ref.covariance)
        np.testing.assert_allclose(
            e_got.covariance[fin], e_ref.covariance[fin], rtol=1e-6, atol=1e-15
        )


@settings(max_examples=300, deadline=None)
@given(
    n=st.integers(1, 90),
    density=st.floats(0.0, 1.0),
    keep=st.floats(0.05, 1.0),
    seed=st.integers(0, 2**31),
)
def test_maximum_of_an_induced_subgraph(n, density, keep, seed):
    """The hypotheses' clique of a vertex subset (peeling, vertex-guided cliques): a
    maximum clique of the induced subgraph, as sorted positions in the subset."""
    from scanclique.clique import bitsets_from_adjacency

    rng = np.random.default_rng(seed)
    A = np.triu(rng.random((n, n)) < density, 1)
    A = A | A.T
    verts = np.flatnonzero(rng.random(n) < keep)
    if len(verts) == 0:
        verts = np.array([n - 1])
    sub = A[np.ix_(verts, verts)]
    r, nodes, status = K._maximum_of(
        bitsets_from_adjacency(A), verts, time.perf_counter() + 10.0, 10**9
    )
    assert status == 0 and nodes >= 0  # finished within the budgets
    assert np.all(np.diff(r) > 0) and r.min() >= 0 and r.max() < len(verts)
    assert all(sub[u, v] for u, v in itertools.combinations(r.tolist(), 2))
    omega = max(len(q) for q in bron_kerbosch(sub)) if len(verts) <= 40 else None
    if omega is not None:
        assert len(r) == omega


@pytest.mark.parametrize("seed", range(4))
def test_consistent_pairs_equal_the_numpy_test(seed):
    from scanclique.pose import pair_consistent

    cfg = MatchConfig()
    p = simulate_pair(np.random.default_rng(seed))
    a, b = prepare_scan(p.scan_a, cfg), prepare_scan(p.scan_b, cfg)
    cg = correspondence_graph(a.graph, b.graph, cfg.correspondence)
    pairs = np.ascontiguousarray(cg.pairs[np.argsort(cg.pairs[:, 0] >= a.features.n_points)])
    cc = cfg.correspondence
    fa, fb = a.features, b.features
    ref = pair_consistent(
        mapped_features(fa, fb, pairs), p.pose_a_b, cc.point_point, cc.line_line, cc.point_line
    )
    got = K.consistent(
        pairs, fa.n_points, fb.n_points, fa.points_xy, fb.points_xy, fa.lines_rho_alpha,
        fb.lines_rho_alpha, p.pose_a_b.as_array(), cc.point_point, cc.line_line, cc.point_line,
    )  # fmt: skip
    assert np.array_equal(got, ref) and ref.any()


# -- raw-scan search seeds ------------------------------------------------------------------------
def _rotated(v, th):
    c, s = np.cos(th), np.sin(th)
    return v @ np.array([[c, s], [-s, c]])


@pytest.mark.parametrize("th", [0.3, -2.0, 3.0])
def test_rotation_candidates_recover_the_rotation(th):
    """Normals of B are A's turned by -th (B's frame is A's turned by th): a candidate is
    th, up to one histogram bin."""
    rng = np.random.default_rng(1)
    ang = np.concatenate([np.full(50, 0.2), np.full(30, 1.0), rng.uniform(-np.pi, np.pi, 20)])
    na = np.stack([np.cos(ang), np.sin(ang)], 1)
    nb = _rotated(na, -th)
    out = np.empty(12)
    n = K.rotation_candidates(na, nb, 180, 6, out)
    assert n == 12
    err = np.abs((out[:n] - th + np.pi) % (2 * np.pi) - np.pi)
    assert err.min() < np.pi / 180 * 1.01


def test_rotation_candidates_skip_zero_normals():
    out = np.empty(4)
    assert K.rotation_candidates(np.zeros((5, 2)), np.zeros((5, 2)), 180, 2, out) == 0


@pytest.mark.parametrize("th", [0.0, 1.2])
def test_translation_votes_recover_the_translation(th):
    """B is A's points moved into B's frame by (t, th), plus clutter: the most voted cell
    is t, and its votes are at least the shared points."""
    rng = np.random.default_rng(2)
    A = rng.uniform(-8, 8, (80, 2))
    t = np.array([1.3, -0.7])
    B = _rotated(A - t, -th)  # R(th) B + t = A
    B = np.concatenate([B, rng.uniform(-8, 8, (20, 2))])
    out = np.empty((3, 3))
    n = K.translation_votes(A, B, th, 0.25, 3, out)
    assert n == 3
    assert np.hypot(*(out[0, :2] - t)) < 0.05
    assert out[0, 2] >= 80 and out[0, 2] > out[1, 2] >= out[2, 2]


def test_translation_votes_of_nothing():
    out = np.empty((2, 3))
    assert K.translation_votes(np.zeros((0, 2)), np.ones((3, 2)), 0.0, 0.25, 2, out) == 0
