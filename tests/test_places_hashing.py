"""The triangle prefilter (geometric hashing of feature triangles) against what it
promises: invariance to the sensor's pose, robustness to partial overlap, one result
however the places were added, and the fused prefilter of PlaceDB."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import scanclique as sc
from scanclique.places import PlaceDB
from scanclique.places.hashing import QUANTUM, TriangleIndex, feature_triangles


def _place(rng, n=14, size=8.0):
    xy = rng.uniform(-size / 2, size / 2, (n, 2)) + [size / 2 + 1.0, 0.0]
    lab = rng.integers(0, 4, n).astype(np.int8)
    return xy, lab


def _moved(xy, pose):
    """Coordinates of ``xy`` in the frame of a sensor at ``pose`` (x, y, theta)."""
    x, y, th = pose
    c, s = np.cos(th), np.sin(th)
    d = xy - [x, y]
    return np.column_stack([c * d[:, 0] + s * d[:, 1], -s * d[:, 0] + c * d[:, 1]])


@settings(max_examples=40, deadline=None)
@given(st.integers(0, 2**31 - 1), st.floats(-np.pi, np.pi), st.floats(-5, 5), st.floats(-5, 5))
def test_keys_are_invariant_and_frames_give_the_pose(seed, th, x, y):
    rng = np.random.default_rng(seed)
    xy, lab = _place(rng)
    a = feature_triangles(xy, lab)
    b = feature_triangles(_moved(xy, (x, y, th)), lab)
    # the same triangles (sides equal to rounding; a side on a bin edge may fall either
    # way, so compare the sides, and the keys of the others)
    assert len(a.keys) == len(b.keys) > 0
    assert np.allclose(np.sort(a.sides, axis=0), np.sort(b.sides, axis=0), atol=1e-9)
    frac = a.sides / QUANTUM - np.floor(a.sides / QUANTUM)
    safe = np.all((frac > 1e-6) & (frac < 1 - 1e-6), axis=1)
    assert set(a.keys[safe]) <= set(b.keys)
    # a matched pair of frames gives the sensor's pose
    order_a, order_b = np.argsort(a.keys, kind="stable"), np.argsort(b.keys, kind="stable")
    ka, kb = a.keys[order_a], b.keys[order_b]
    unique = np.flatnonzero(np.r_[np.diff(ka) != 0, True] & np.r_[True, np.diff(ka) != 0])
    for i in unique[:5]:
        if not safe[order_a[i]]:
            continue
        j = np.searchsorted(kb, ka[i])
        fa, fb = a.frames[order_a[i]], b.frames[order_b[j]]
        dth = np.angle(np.exp(1j * (fa[2] - fb[2])))
        assert abs(np.angle(np.exp(1j * (dth - th)))) < 1e-6
        c, s = np.cos(dth), np.sin(dth)
        t = fa[:2] - [c * fb[0] - s * fb[1], s * fb[0] + c * fb[1]]
        assert np.allclose(t, [x, y], atol=1e-6)


def test_too_few_points_give_no_triangles():
    assert len(feature_triangles(np.zeros((2, 2)), np.zeros(2)).keys) == 0
    assert len(feature_triangles(np.zeros((0, 2)), np.zeros(0)).keys) == 0


def test_partial_view_with_clutter_finds_its_place():
    """A query that sees 60 % of a place's features, moved by noise of a few centimetres,
    with as many clutter points, ranks that place first among 60."""
    rng = np.random.default_rng(3)
    places = [_place(rng) for _ in range(60)]
    idx = TriangleIndex()
    idx.add(np.arange(1, 61), [feature_triangles(*p) for p in places])
    found = 0
    for t in range(10):
        xy, lab = places[t * 5]
        keep = rng.random(len(xy)) < 0.6
        seen = _moved(xy[keep], (1.0, -0.5, 1.7)) + rng.normal(0, 0.02, (keep.sum(), 2))
        clutter = rng.uniform(-4, 4, (keep.sum(), 2)) + [5.0, 0.0]
        q = feature_triangles(
            np.vstack([seen, clutter]), np.r_[lab[keep], rng.integers(0, 4, keep.sum())]
        )
        ids, votes = idx.search(q, 1)
        found += ids.tolist() == [t * 5 + 1]
    assert found >= 9


@settings(max_examples=15, deadline=None)
@given(st.integers(0, 2**31 - 1), st.lists(st.integers(1, 9), min_size=1, max_size=8))
def test_scores_do_not_depend_on_how_places_were_added(seed, batches):
    rng = np.random.default_rng(seed)
    tris = [feature_triangles(*_place(rng, n=8)) for _ in range(sum(batches))]
    ids = np.arange(10, 10 + len(tris))
    one = TriangleIndex()
    one.add(ids, tris)
    many = TriangleIndex()
    at = 0
    q = tris[rng.integers(len(tris))]
    for b in batches:  # searched between additions: the recent segment merges or not
        many.add(ids[at : at + b], tris[at : at + b])
        at += b
        many.scores(q)
    assert np.array_equal(one.scores(q), many.scores(q))
    ex = ids[::3].tolist()
    s = one.scores(q, exclude=ex)
    assert np.all(s[::3] == 0)
    assert np.array_equal(s, many.scores(q, exclude=ex))
    top, votes = one.search(q, 3)
    assert np.all(np.diff(votes) <= 0) and len(top) <= 3


def test_placedb_fuses_both_prefilters_and_reopens_alike(tmp_path):
    rng = np.random.default_rng(21)
    world = sc.sim.office_world(rng)
    traj = sc.sim.simulate_trajectory(rng, world, 8, step=0.3)
    path = tmp_path / "p.db"
    with PlaceDB(path) as db:
        for k in range(0, 8, 2):
            db.add(traj[k], name=f"s{k}")
        ids, dist = db.candidates(traj[3], n=3)
        hits = db.query(traj[3], k=3)
        assert len(db.triangles) == len(db) == 4
    assert len(ids) == len(set(ids.tolist())) == 3 and np.all(dist >= 0)
    assert hits and all(h.votes >= 0 for h in hits)
    with PlaceDB(path, readonly=True) as db:
        ids2, dist2 = db.candidates(traj[3], n=3)
        again = db.query(traj[3], k=3)
    assert ids2.tolist() == ids.tolist() and np.allclose(dist2, dist)
    assert [(h.place_id, h.verdict, h.votes, h.score) for h in again] == [
        (h.place_id, h.verdict, h.votes, h.score) for h in hits
    ]


@pytest.mark.parametrize("search", [False, True])
def test_search_option_reaches_the_matcher(tmp_path, search):
    with PlaceDB(tmp_path / "p.db", search=search) as db:
        assert db.verify_config.refine.search is search
        assert db.config.refine.search is True  # the stored configuration is unchanged


def test_votes_give_the_pose_of_the_best_bin():
    """A place seen from elsewhere: its best bin's mean pose is the pose that maps the
    query's points into the place's frame; places with no vote have none."""
    rng = np.random.default_rng(5)
    xy, lab = _place(rng, n=20)
    sensor = (1.5, -2.0, 0.7)  # the query's sensor pose in the place's frame
    idx = TriangleIndex()
    idx.add([3, 4], [feature_triangles(xy, lab), feature_triangles(xy[:0], lab[:0])])
    scores, poses = idx.votes(feature_triangles(_moved(xy, sensor), lab))
    assert scores[0] > 0 and scores[1] == 0
    assert np.allclose(poses[0], sensor, atol=1e-5)
    assert np.all(np.isnan(poses[1]))
    assert np.array_equal(scores, idx.scores(feature_triangles(_moved(xy, sensor), lab)))
    _, gone = idx.votes(feature_triangles(_moved(xy, sensor), lab), exclude=[3])
    assert np.all(np.isnan(gone[0]))


def test_compiled_votes_agree_with_the_numpy_reference():
    """Many places, some sharing triangles with the query at different poses: the
    compiled voting gives the reference's scores exactly and its poses up to rounding."""
    rng = np.random.default_rng(8)
    xy, lab = _place(rng, n=24)
    idx = TriangleIndex()
    ids, sets = [], []
    for k in range(60):  # places: parts of the query's view, moved, and unrelated ones
        if k % 3 == 0:
            sub = rng.choice(len(xy), size=12, replace=False)
            pose = (rng.uniform(-3, 3), rng.uniform(-3, 3), rng.uniform(-np.pi, np.pi))
            sets.append(feature_triangles(_moved(xy[sub], pose), lab[sub]))
        else:
            sets.append(feature_triangles(*_place(rng, n=16)))
        ids.append(100 + k)
    idx.add(ids[:40], sets[:40])
    idx.votes(feature_triangles(xy, lab))  # merges the first places into the main segment
    idx.add(ids[40:], sets[40:])  # and these stay in the recent one
    q = feature_triangles(xy, lab)
    for exclude in (None, [103, 150]):
        s, p = idx.votes(q, exclude)
        s_ref, p_ref = idx.votes_reference(q, exclude)
        assert np.array_equal(s, s_ref) and (s > 0).sum() > 20
        assert np.array_equal(np.isnan(p), np.isnan(p_ref))
        ok = ~np.isnan(p_ref[:, 0])
        d = p[ok] - p_ref[ok]
        d[:, 2] = (d[:, 2] + np.pi) % (2 * np.pi) - np.pi
        assert np.abs(d).max() < 1e-9
        # poses only of the places with at least min_pose votes: the same ones, exactly
        for min_pose in (2, 5):
            s2, p2 = idx.votes(q, exclude, min_pose=min_pose)
            keep = s >= min_pose
            assert np.array_equal(s2, s) and 0 < keep.sum() < (s > 0).sum()
            assert np.array_equal(p2[keep], p[keep]) and np.isnan(p2[~keep]).all()


@settings(max_examples=150, deadline=None)
@given(st.integers(0, 2**31 - 1), st.integers(0, 30), st.booleans())
def test_compiled_triangles_equal_the_numpy_reference(seed, n, grid):
    """The compiled triangles are the NumPy reference's exactly: same triangles in the
    same order, sides, kinds and frames bit for bit (points on a grid: many equal
    distances, which both must order alike; repeated points too)."""
    from scanclique.places.hashing import _feature_triangles_reference

    rng = np.random.default_rng(seed)
    if grid:
        xy = rng.integers(0, 8, (n, 2)) * rng.choice([0.5, 1.0, 1.3])
        if n > 3:
            xy[1] = xy[0]
    else:
        xy, _ = _place(rng, n=max(n, 1))
        xy = xy[:n]
    lab = rng.integers(-1, 5, len(xy)).astype(np.int8)
    a, b = feature_triangles(xy, lab), _feature_triangles_reference(xy, lab)
    for f in ("keys", "sides", "kinds", "frames"):
        x, y = getattr(a, f), getattr(b, f)
        assert x.dtype == y.dtype and np.array_equal(x, y), f
