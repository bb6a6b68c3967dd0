"""The prefilter's index and the loop search's candidates against simple references."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from scanclique.errors import PlaceDatabaseError
from scanclique.places.index import SignatureIndex, brute_force_knn
from scanclique.places.loops import loop_candidates


@settings(max_examples=80, deadline=None)
@given(
    st.integers(1, 40),
    st.integers(1, 6),
    st.integers(0, 45),
    st.integers(0, 2**31 - 1),
    st.booleans(),
)
def test_index_agrees_with_brute_force(n, dim, k, seed, masked):
    rng = np.random.default_rng(seed)
    # coarse values: many exact ties, which both must break by position (ids increase)
    X = rng.integers(0, 3, (n, dim)).astype(np.float32)
    q = rng.integers(0, 3, dim).astype(np.float32)
    mask = rng.random(n) < 0.6 if masked else None
    idx = SignatureIndex(dim)
    ids = np.arange(100, 100 + n)
    for lo in range(0, n, 7):  # added in several pieces
        idx.add(ids[lo : lo + 7], X[lo : lo + 7])
    got_ids, got_d = idx.search(q, k, mask)
    rows, want_d = brute_force_knn(X, q, k, mask)
    assert got_ids.tolist() == ids[rows].tolist()
    np.testing.assert_allclose(got_d, want_d, atol=1e-5)


def test_index_rejects_bad_input():
    idx = SignatureIndex(3)
    with pytest.raises(PlaceDatabaseError):
        idx.add([1, 2], np.zeros((3, 3)))
    idx.add([1], np.zeros((1, 3)))
    with pytest.raises(PlaceDatabaseError):
        idx.search(np.zeros(3), 1, np.ones(2, bool))
    assert idx.search(np.zeros(3), 0)[0].size == 0


def _loop_candidates_reference(S, candidates, min_gap):
    out = []
    for i in range(len(S)):
        js = list(range(0, i - min_gap + 1))
        d = [float(np.sum((S[i] - S[j]) ** 2)) for j in js]
        order = sorted(range(len(js)), key=lambda t: (d[t], js[t]))[:candidates]
        out += [(i, js[t], r, d[t]) for r, t in enumerate(order)]
    return out


@settings(max_examples=60, deadline=None)
@given(st.integers(0, 30), st.integers(1, 5), st.integers(1, 8), st.integers(0, 2**31 - 1))
def test_loop_candidates_agree_with_reference(n, candidates, min_gap, seed):
    rng = np.random.default_rng(seed)
    S = rng.integers(0, 3, (n, 4)).astype(float)
    got = loop_candidates(S, candidates, min_gap, block=7)
    want = _loop_candidates_reference(S, candidates, min_gap)
    assert [g[:3] for g in got] == [w[:3] for w in want]
    np.testing.assert_allclose([g[3] for g in got], [w[3] for w in want], atol=1e-9)


def test_member_mask_is_isin():
    from scanclique.places.index import member_mask

    rng = np.random.default_rng(3)
    for n in (0, 1, 7, 300):
        ids = np.unique(rng.integers(1, 1000, n)).astype(np.int64)
        for ex in (np.zeros(0, np.int64), rng.integers(-5, 1010, 12), ids[::3], ids[-1:] + 1):
            ex = np.asarray(ex, dtype=np.int64)
            want = np.isin(ids, ex)
            assert np.array_equal(member_mask(ids, ex, True), want)
            shuffled = rng.permutation(ids)
            assert np.array_equal(member_mask(shuffled, ex, False), np.isin(shuffled, ex))


def test_index_contains_unsorted_ids():
    idx = SignatureIndex(2)
    idx.add([5, 9], np.ones((2, 2)))
    assert idx._ascending
    idx.add([3], np.ones((1, 2)))  # not ascending any more: np.isin
    assert not idx._ascending
    # a mask over the index's ids 5, 9, 3
    assert idx.contains([3, 9, 4]).tolist() == [False, True, True]
    assert idx.contains([5]).tolist() == [True, False, False]
