"""Signatures of the place prefilter (scanclique.places.signature)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import scanclique as sc
from scanclique.match import prepare_scan
from scanclique.places import SIGNATURE_SIZE, scan_signature, signature_distance
from scanclique.places.signature import _soft_hist
from scanclique.scan import Scan


@pytest.fixture(scope="module")
def pair():
    return sc.sim.simulate_pair(np.random.default_rng(0))


def _turned(scan: Scan, dtheta: float) -> Scan:
    """The same ranges with every beam angle turned by ``dtheta``: the sensor rotated in
    place in a world that turned with it (the points rotate, nothing else changes)."""
    return Scan(scan.ranges, scan.angles + dtheta, scan.range_min, scan.range_max)


def test_shape_and_norm(pair):
    s = scan_signature(prepare_scan(pair.scan_a))
    assert s.shape == (SIGNATURE_SIZE,) and s.dtype == np.float64
    assert np.all(s >= 0)
    assert math.isclose(float(np.sum(s**2)), 1.0, rel_tol=1e-9)  # every block has values


@pytest.mark.parametrize("dtheta", [0.3, -1.2, 2.5])
def test_rotation_invariant(pair, dtheta):
    a = scan_signature(prepare_scan(pair.scan_a))
    b = scan_signature(prepare_scan(_turned(pair.scan_a, dtheta)))
    assert signature_distance(a, b) < 1e-6


def test_same_place_nearer_than_other_places():
    # scans of one world taken near one pose are nearer than scans of other worlds
    rng = np.random.default_rng(4)
    sigs, world_of = [], []
    for w in range(4):
        world = sc.sim.office_world(rng)
        traj = sc.sim.simulate_trajectory(rng, world, 3, step=0.2)
        for s in traj:
            sigs.append(scan_signature(prepare_scan(s)))
            world_of.append(w)
    X = np.array(sigs)
    world_of = np.array(world_of)
    for i in range(len(X)):
        d = signature_distance(X[i], X)
        d[i] = np.inf
        assert world_of[int(np.argmin(d))] == world_of[i]


def test_empty_scan_has_zero_signature():
    s = Scan.from_ranges(np.full(181, np.nan))
    sig = scan_signature(prepare_scan(s))
    assert sig.shape == (SIGNATURE_SIZE,) and not sig.any()


def test_distance_broadcasts_and_bounds(pair):
    a = scan_signature(prepare_scan(pair.scan_a))
    b = scan_signature(prepare_scan(pair.scan_b))
    d = signature_distance(a, np.stack([a, b, np.zeros_like(a)]))
    assert d.shape == (3,) and d[0] == 0.0 and 0 < d[1] < 2.0
    assert math.isclose(float(d[2]), 1.0)  # an empty signature is 1 from a full one


@settings(max_examples=60, deadline=None)
@given(st.lists(st.floats(0, 12, allow_nan=False), max_size=40), st.integers(2, 20))
def test_soft_hist_keeps_mass_and_mean(values, n):
    u = np.array(values, dtype=float)
    h = _soft_hist(u, n)
    assert h.shape == (n,) and np.all(h >= 0)
    assert math.isclose(h.sum(), len(u), abs_tol=1e-9)
    clipped = np.clip(u, 0, n - 1)
    # linear splitting keeps the mean of the (clipped) values exactly
    if len(u):
        assert math.isclose(float(h @ np.arange(n)) / len(u), float(clipped.mean()), abs_tol=1e-9)


def test_compiled_blocks_agree_with_reference():
    from scanclique.places.signature import _blocks, _blocks_reference

    rng = np.random.default_rng(8)
    scans = [sc.sim.simulate_pair(rng).scan_a for _ in range(3)]
    scans.append(Scan.from_ranges(np.full(181, np.nan)))
    scans.append(Scan.from_ranges(np.r_[np.full(90, np.nan), 2.0, 2.1, np.full(89, np.nan)]))
    for s in scans:
        p = prepare_scan(s)
        for fast, ref in zip(_blocks(p), _blocks_reference(p), strict=True):
            np.testing.assert_allclose(fast, ref, rtol=1e-9, atol=1e-9)


def _local_block(sig: np.ndarray) -> np.ndarray:
    from scanclique.places.signature import SIGNATURE_BLOCKS

    start = sum(n for name, n, _ in SIGNATURE_BLOCKS if name != "local")
    assert SIGNATURE_BLOCKS[-1][0] == "local"
    return sig[start:]


@pytest.mark.parametrize("dtheta", [0.4, -2.0, math.pi])
def test_local_block_unchanged_by_a_turn_of_the_sensor(pair, dtheta):
    from scanclique.places.signature import _local_hist

    a = _local_hist(prepare_scan(pair.scan_a))
    b = _local_hist(prepare_scan(_turned(pair.scan_a, dtheta)))
    assert a.sum() > 0
    # the same thinned points and pairs; a pair exactly at a bin edge may move by one
    # rounding error, so compare the counts, not their bins' exact floats
    assert np.abs(a - b).sum() <= 0.01 * a.sum()


def test_local_block_of_a_straight_wall():
    from scanclique.places.signature import _PAIR_ANGLE_BINS as na
    from scanclique.places.signature import _PAIR_DIST_BINS as nd
    from scanclique.places.signature import _local_hist

    n = 181
    ang = np.linspace(-math.pi / 2, math.pi / 2, n)
    r = np.where(np.abs(ang) < 0.6, 3.0 / np.cos(ang), np.nan)  # a wall 3 m ahead
    s = Scan(r, ang)
    h = _local_hist(prepare_scan(s))
    assert h.sum() > 0
    # pairs along one wall: both normals perpendicular to the segment joining them, so
    # every count is in the (|cos| lo, |cos| hi) = (0, 0) cell of some distance bin; the
    # wall is about 4 m long, so its pairs fill the distance bins up to LOCAL_RADIUS
    cells = h.reshape(nd, na, na)
    assert cells[:, 0, 0].sum() >= 0.9 * h.sum()
    assert (cells[:, 0, 0] > 0).sum() >= nd - 1


def test_local_block_of_bad_scans_is_defined():
    from scanclique.places.signature import _local_hist, _thinned

    for s in (
        Scan.from_ranges(np.full(181, np.nan)),  # every beam invalid
        Scan.from_ranges(np.r_[np.full(90, np.nan), 2.0, np.full(90, np.nan)]),  # one point
        Scan(np.zeros(0), np.zeros(0)),  # no beams
    ):
        h = _local_hist(prepare_scan(s))
        assert h.shape == (128,) and not h.any()
        sig = scan_signature(prepare_scan(s))
        assert np.all(np.isfinite(sig)) and not _local_block(sig).any()
    assert _thinned(np.zeros((0, 2)), 0.25).shape == (0,)
    assert _thinned(np.zeros((5, 2)), 0.25).tolist() == [0]  # all at one spot: one kept


def test_local_block_identical_scans_distance_zero(pair):
    a = scan_signature(prepare_scan(pair.scan_a))
    b = scan_signature(prepare_scan(pair.scan_a))
    assert signature_distance(_local_block(a), _local_block(b)) == 0.0
    assert _local_block(a).any()
