"""Geometric hashing of feature triangles: the second prefilter of place recognition.

A global signature (:mod:`.signature`) summarises the whole scan, so a revisit that sees
only part of the place, or sees it from a very different heading, moves it far. The
clique matcher (paper §5) works because the *relations between features* (distances,
kinds) survive a change of viewpoint; this prefilter indexes those relations directly
(geometric hashing, Lamdan and Wolfson 1988):

1. **Triangles.** Every point feature (foreground point, edge, corner) forms triangles
   with pairs of its :data:`NEIGHBOURS` nearest point features (local triangles: a
   triangle whose corners are near each other is more likely to be wholly in view in
   another observation of the place). A triangle is kept when its sides are between
   :data:`MIN_SIDE` and :data:`MAX_SIDE`.
2. **Invariant key.** Its sides sorted ``a <= b <= c``, each quantised to
   :data:`QUANTUM` metres, and the kinds of the corners opposite them, in that order:
   invariant to a rotation and a translation of the sensor.
3. **Frame.** The triangle's centroid and the direction of its longest side (from the
   corner opposite ``a`` to the one opposite ``b``): a matched pair of triangles gives a
   pose hypothesis ``T_place_query`` by itself.
4. **Inverted index.** The keys of every place's triangles, sorted, with the place and
   the triangle's frame (:class:`TriangleIndex`).
5. **Voting.** A query's triangles look up their keys (each side in its own bin and in
   the neighbouring bin nearer its value, so that a side within half a quantum of the
   stored one always meets it: 8 keys per triangle); each stored triangle met votes for
   its place *and the pose it implies*, binned to :data:`VOTE_XY` metres and
   :data:`VOTE_THETA` radians. A place's score is the largest number of votes in one pose
   bin: triangles that agree on one pose, the constellation of common features that the
   matcher would find. Accidental equal triangles scatter their votes over many bins.

The score is robust to partial overlap (only the common triangles count) and to rotation
(by construction). It is a ranking, not a verdict: the candidates it ranks first are
verified by the matcher (:mod:`.verify`).

Examples
--------
>>> import numpy as np
>>> xy = np.array([[1.0, 0.0], [3.0, 0.5], [2.0, 2.0], [4.0, 3.0], [0.5, 3.5]])
>>> lab = np.array([3, 3, 1, 2, 3], dtype=np.int8)
>>> tri = feature_triangles(xy, lab)
>>> len(tri.keys) > 0
True
>>> c, s = np.cos(0.7), np.sin(0.7)
>>> moved = xy @ np.array([[c, s], [-s, c]]) + [5.0, -2.0]   # the same place, seen elsewhere
>>> idx = TriangleIndex()
>>> idx.add([7], [tri])
>>> ids, votes = idx.search(feature_triangles(moved, lab), 1)
>>> ids.tolist(), bool(votes[0] == len(tri.keys))
([7], True)
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .index import member_mask

__all__ = [
    "HASH_VERSION",
    "QUANTUM",
    "NEIGHBOURS",
    "MIN_SIDE",
    "MAX_SIDE",
    "VOTE_XY",
    "VOTE_THETA",
    "Triangles",
    "feature_triangles",
    "TriangleIndex",
]

#: bump when the keys or frames change
HASH_VERSION = 1
#: metres: side-length quantum, about twice the spread of a side between two observations
#: (point features are located to a few centimetres; the key tolerates half a quantum)
QUANTUM = 0.15
#: nearest point features each feature makes triangles with (pairs of them)
NEIGHBOURS = 6
#: metres: shorter sides are dropped (their direction, the frame's, is too uncertain)
MIN_SIDE = 0.5
#: metres: longer sides are dropped (less likely to be wholly in view again)
MAX_SIDE = 10.0
#: pose bins of the votes: metres and radians (a pose from one triangle is good to a few
#: decimetres and a few degrees)
VOTE_XY = 1.0
VOTE_THETA = 0.25

_NB = int(MAX_SIDE / QUANTUM) + 2  # side bins (the neighbouring bin of the last included)
_NXY = 4096  # translation bins each way (centred), +-2 km at 1 m
_NT = int(math.ceil(2 * math.pi / VOTE_THETA))
_LOOKUP_BITS = (np.arange(8)[:, None] >> np.arange(3)[None, :] & 1).astype(bool)  # (8, 3)


@dataclass(frozen=True, slots=True, eq=False)
class Triangles:
    """The triangles of one scan's point features.

    Attributes
    ----------
    keys : ndarray (T,) int64
        The invariant key of each triangle, its sides in their own bins.
    sides : ndarray (T, 3) float64
        The sorted side lengths (metres).
    kinds : ndarray (T, 3) int64
        Kinds of the corners opposite the sorted sides.
    frames : ndarray (T, 3) float64
        ``(x, y, theta)`` of each triangle's frame in the sensor frame: centroid and
        direction of the longest side.
    """

    keys: np.ndarray
    sides: np.ndarray
    kinds: np.ndarray
    frames: np.ndarray

    def query_keys(self) -> tuple[np.ndarray, np.ndarray]:
        """The 8 lookup keys of each triangle (each side in its bin or in the nearer
        neighbouring one) and the triangle each key belongs to."""
        u = self.sides / QUANTUM
        f0 = np.floor(u).astype(np.int64)
        nb = np.where(u - f0 >= 0.5, f0 + 1, f0 - 1)
        # lookup m takes side d from the neighbouring bin when bit d of m is set; the
        # keys of lookup 0 for every triangle first, then of lookup 1, ...
        q = np.where(_LOOKUP_BITS[:, None, :], nb[None], f0[None]).reshape(-1, 3)
        keys = _key(q, np.tile(self.kinds, (8, 1)))
        return keys, np.tile(np.arange(len(self.keys)), 8)


def _key(q: np.ndarray, kinds: np.ndarray) -> np.ndarray:
    q = np.clip(q, 0, _NB - 1)
    k = (q[:, 0] * _NB + q[:, 1]) * _NB + q[:, 2]
    return ((k * 4 + kinds[:, 0]) * 4 + kinds[:, 1]) * 4 + kinds[:, 2]


def _empty() -> Triangles:
    return Triangles(
        np.zeros(0, np.int64), np.zeros((0, 3)), np.zeros((0, 3), np.int64), np.zeros((0, 3))
    )


def feature_triangles(points_xy: np.ndarray, points_label: np.ndarray) -> Triangles:
    """The local triangles of a scan's point features (module docstring, steps 1–3).

    Parameters
    ----------
    points_xy : ndarray (P, 2)
        Point feature positions, sensor frame (metres).
    points_label : ndarray (P,)
        Their kinds, 0..3 (:data:`scanclique.features.FOREGROUND_POINT` ...
        :data:`~scanclique.features.CORNER`).

    Returns
    -------
    Triangles
    """
    xy = np.asarray(points_xy, dtype=float).reshape(-1, 2)
    lab = np.asarray(points_label, dtype=np.int64).reshape(-1)
    P = len(xy)
    if P < 3:
        return _empty()
    from ._kernels import triangle_corners

    D = np.hypot(xy[:, None, 0] - xy[None, :, 0], xy[:, None, 1] - xy[None, :, 1])
    # each triangle once (in the order of its sorted corner indices), its sides within
    # the limits, sorted (stable), and V[:, m] the corner opposite side m:
    # _feature_triangles_reference's steps, compiled
    V, s = triangle_corners(D, min(NEIGHBOURS, P - 1), MIN_SIDE, MAX_SIDE)
    if not len(V):
        return _empty()
    return _frames(xy, lab, V, s)


def _feature_triangles_reference(points_xy: np.ndarray, points_label: np.ndarray) -> Triangles:
    """:func:`feature_triangles` in NumPy: the reference the compiled loop
    (:func:`._kernels.triangle_corners`) must agree with exactly."""
    xy = np.asarray(points_xy, dtype=float).reshape(-1, 2)
    lab = np.asarray(points_label, dtype=np.int64).reshape(-1)
    P = len(xy)
    if P < 3:
        return _empty()
    D = np.hypot(xy[:, None, 0] - xy[None, :, 0], xy[:, None, 1] - xy[None, :, 1])
    K = min(NEIGHBOURS, P - 1)
    nn = np.argsort(D, axis=1, kind="stable")[:, 1 : K + 1]
    b, c = np.triu_indices(K, k=1)
    tri = np.stack(
        [np.repeat(np.arange(P), len(b)), nn[:, b].reshape(-1), nn[:, c].reshape(-1)], axis=1
    )
    tri.sort(axis=1)
    code = np.unique((tri[:, 0] * P + tri[:, 1]) * P + tri[:, 2])  # each triangle once
    i, j, k = code // (P * P), (code // P) % P, code % P
    tri = np.column_stack([i, j, k])
    s = np.stack([D[j, k], D[i, k], D[i, j]], axis=1)  # side opposite i, j, k
    ok = (s.max(axis=1) <= MAX_SIDE) & (s.min(axis=1) >= MIN_SIDE)
    V, s = tri[ok], s[ok]
    if not len(V):
        return _empty()
    o = np.argsort(s, axis=1, kind="stable")
    s = np.take_along_axis(s, o, axis=1)
    V = np.take_along_axis(V, o, axis=1)  # V[:, m]: the corner opposite side m
    return _frames(xy, lab, V, s)


def _frames(xy, lab, V, s) -> Triangles:
    """The triangles of corners ``V`` (opposite the sorted sides ``s``): kinds, frames,
    keys."""
    kinds = np.clip(lab[V], 0, 3)
    pa, pb = xy[V[:, 0]], xy[V[:, 1]]  # the longest side joins these two
    th = np.arctan2(pb[:, 1] - pa[:, 1], pb[:, 0] - pa[:, 0])
    cen = xy[V].mean(axis=1)
    keys = _key(np.floor(s / QUANTUM).astype(np.int64), kinds)
    return Triangles(keys, s, kinds, np.column_stack([cen, th]))


class TriangleIndex:
    """The inverted index of the places' triangles (module docstring, steps 4–5).

    Two sorted segments: the main one and a small one of recent additions, merged into
    the main one when it grows past an eighth of it (adding is amortised
    O(log N) per triangle; a search looks up both).
    """

    def __init__(self) -> None:
        self._ids = np.zeros(0, dtype=np.int64)  # place id of each row
        self._ascending = True  # ids strictly ascending in the order added
        self._segs = [self._seg([]), self._seg([])]
        self._pending: list[tuple] = []
        self._n_pending = 0

    @staticmethod
    def _seg(parts) -> dict:
        """A sorted segment from ``(keys, rows, frames)`` parts: keys, place rows, and per
        triangle ``(x, y, cos theta, sin theta)`` of its frame (float32, one gather)."""
        if not parts:
            return {
                "k": np.zeros(0, np.int64),
                "r": np.zeros(0, np.int32),
                "f": np.zeros((0, 4), np.float32),
            }
        k = np.concatenate([p[0] for p in parts])
        o = np.argsort(k, kind="stable")
        return {
            "k": k[o],
            "r": np.concatenate([p[1] for p in parts])[o],
            "f": np.concatenate([p[2] for p in parts])[o],
        }

    @staticmethod
    def _parts(seg) -> tuple:
        return (seg["k"], seg["r"], seg["f"])

    def __len__(self) -> int:
        return len(self._ids)

    @property
    def ids(self) -> np.ndarray:
        """Place ids in the order added (read-only view)."""
        v = self._ids.view()
        v.setflags(write=False)
        return v

    @property
    def size(self) -> int:
        """Stored triangles."""
        return sum(len(s["k"]) for s in self._segs) + self._n_pending

    def add(self, ids, triangles) -> None:
        """Append places ``ids`` with their :class:`Triangles`."""
        ids = np.atleast_1d(np.asarray(ids, dtype=np.int64))
        triangles = list(triangles)
        if len(ids) != len(triangles):
            raise ValueError(f"{len(ids)} ids but {len(triangles)} triangle sets")
        row0 = len(self._ids)
        if len(ids) and (np.any(ids[1:] <= ids[:-1]) or (row0 and ids[0] <= self._ids[-1])):
            self._ascending = False
        self._ids = np.concatenate([self._ids, ids])
        for r, t in enumerate(triangles):
            n = len(t.keys)
            if n:
                fr = t.frames
                f = np.column_stack([fr[:, 0], fr[:, 1], np.cos(fr[:, 2]), np.sin(fr[:, 2])])
                self._pending.append((t.keys, np.full(n, row0 + r, np.int32), f.astype(np.float32)))
                self._n_pending += n

    def _flush(self) -> None:
        if not self._pending:
            return
        main, recent = self._segs
        recent = self._seg([self._parts(recent), *self._pending])
        self._pending, self._n_pending = [], 0
        if len(recent["k"]) > max(4096, len(main["k"]) // 8):
            main, recent = self._seg([self._parts(main), self._parts(recent)]), self._seg([])
        self._segs = [main, recent]

    def scores(self, query: Triangles, exclude=None) -> np.ndarray:
        """The score of every place (rows in the order added): the most votes in one
        pose bin; places whose id is in ``exclude`` score 0."""
        return self.votes(query, exclude, min_pose=2**62)[0]

    def votes(
        self, query: Triangles, exclude=None, min_pose: int = 0
    ) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`scores`, and the pose hypothesis of each place's best bin (of the places
        whose best bin has at least ``min_pose`` votes: the others' poses are NaN, and
        cost nothing).

        Returns
        -------
        scores : ndarray (N,) int64
            Rows in the order added.
        poses : ndarray (N, 3)
            ``(x, y, theta)`` of ``T_place_query`` (maps the query's points into the
            place's frame): the mean of the votes in the place's best pose bin (the
            circular mean of their angles); NaN for places with no vote. Of the bins tied
            for the most votes, the first in the order of the bin keys.
        """
        out, poses, qk, qt, qf, qc, qs = self._begin(query)
        if qk is None:
            return out, poses
        from ._kernels import triangle_gather, triangle_reduce

        rs, vs = [], []
        for seg in self._segs:
            if len(seg["k"]):
                r, v = triangle_gather(seg["k"], seg["r"], seg["f"], qk, qt, qf, qc, qs)
                rs.append(r)
                vs.append(v)
        if rs:
            r = np.concatenate(rs) if len(rs) > 1 else rs[0]
            v = np.concatenate(vs) if len(vs) > 1 else vs[0]
            n = len(self._ids)
            triangle_reduce(r, v, n, VOTE_XY, VOTE_THETA, _NXY, _NT, out, poses, int(min_pose))
        self._exclude(out, poses, exclude)
        return out, poses

    def _begin(self, query: Triangles):
        """What both votings start from: the zeroed ``(scores, poses)``, then the query's
        lookup keys and their triangle rows, sorted by key (sorted needles: a faster
        lookup), its triangle frames and their cosines and sines (all None when nothing can
        vote: an empty query or index)."""
        self._flush()
        out = np.zeros(len(self._ids), dtype=np.int64)
        poses = np.full((len(self._ids), 3), np.nan)
        if not len(query.keys) or not len(self._ids):
            return out, poses, None, None, None, None, None
        qk, qt = query.query_keys()
        o = np.argsort(qk, kind="stable")
        qk, qt = np.ascontiguousarray(qk[o]), np.ascontiguousarray(qt[o])
        qf = np.ascontiguousarray(query.frames, dtype=np.float64)
        return out, poses, qk, qt, qf, np.cos(qf[:, 2]), np.sin(qf[:, 2])

    def _exclude(self, out: np.ndarray, poses: np.ndarray, exclude) -> None:
        """Zero the votes (and NaN the poses), in place, of the places ``exclude`` names."""
        if exclude is None:
            return
        ex = np.fromiter((int(i) for i in exclude), dtype=np.int64)
        if len(ex):
            gone = member_mask(self._ids, ex, self._ascending)
            out[gone] = 0
            poses[gone] = np.nan

    def votes_reference(self, query: Triangles, exclude=None) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`votes` in NumPy: the reference the compiled loops must agree with (up to
        the order of summation of the mean poses)."""
        out, poses, qk, qt, qf, qc, qs = self._begin(query)
        if qk is None:
            return out, poses
        rows, parts = [], []
        for seg in self._segs:
            if not len(seg["k"]):
                continue
            lo = np.searchsorted(seg["k"], qk, "left")
            cnt = np.searchsorted(seg["k"], qk, "right") - lo
            tot = int(cnt.sum())
            if not tot:
                continue
            ti = np.repeat(qt, cnt)
            pos = np.repeat(lo - np.cumsum(cnt) + cnt, cnt) + np.arange(tot)
            rows.append(seg["r"][pos])
            f = seg["f"][pos].astype(np.float64)
            # rotation: stored angle less the query's, as cos and sin of the difference
            c = f[:, 2] * qc[ti] + f[:, 3] * qs[ti]
            s = f[:, 3] * qc[ti] - f[:, 2] * qs[ti]
            qx, qy = qf[ti, 0], qf[ti, 1]
            parts.append(
                np.column_stack(
                    [np.arctan2(s, c), f[:, 0] - (c * qx - s * qy), f[:, 1] - (s * qx + c * qy)]
                )
            )
        if not rows:
            return out, poses
        r = np.concatenate(rows).astype(np.int64)
        v = np.concatenate(parts)
        # bins centred on the identity (a revisit from nearly the same pose, and a scan
        # queried against itself, must not split their votes over two bins)
        th = np.mod(v[:, 0] + 0.5 * VOTE_THETA, 2 * math.pi)
        bt = np.minimum((th / VOTE_THETA).astype(np.int64), _NT - 1)
        half = _NXY // 2
        b = np.floor(v[:, 1:] / VOTE_XY + 0.5).astype(np.int64) + half
        np.clip(b, 0, _NXY - 1, out=b)
        vk = ((r * _NXY + b[:, 0]) * _NXY + b[:, 1]) * _NT + bt
        o = np.argsort(vk, kind="stable")
        vk = vk[o]
        start = np.r_[0, np.flatnonzero(vk[1:] != vk[:-1]) + 1]
        counts = np.diff(np.r_[start, len(vk)])
        vr = vk[start] // (_NXY * _NXY * _NT)
        # vr is sorted: the largest count of each place's bins, and its first such bin
        first = np.r_[0, np.flatnonzero(vr[1:] != vr[:-1]) + 1]
        best = np.maximum.reduceat(counts, first)
        out[vr[first]] = best
        # the bin of each place's best count: the first bin of the group reaching it
        grp = np.repeat(np.arange(len(first)), np.diff(np.r_[first, len(vr)]))
        hit = np.flatnonzero(counts == best[grp])
        hit = hit[np.r_[True, grp[hit[1:]] != grp[hit[:-1]]]]
        # the mean pose of the votes in those bins (circular mean of the angle)
        vs = v[o]
        cs = np.vstack([np.zeros((1, 4)), np.cumsum(
            np.column_stack([np.cos(vs[:, 0]), np.sin(vs[:, 0]), vs[:, 1], vs[:, 2]]), axis=0
        )])  # fmt: skip
        lo, hi = start[hit], start[hit] + counts[hit]
        m = (cs[hi] - cs[lo]) / counts[hit][:, None]
        poses[vr[hit]] = np.column_stack([m[:, 2], m[:, 3], np.arctan2(m[:, 1], m[:, 0])])
        self._exclude(out, poses, exclude)
        return out, poses

    def search(self, query: Triangles, k: int, exclude=None) -> tuple[np.ndarray, np.ndarray]:
        """The ids of the (at most) ``k`` places of highest score, best first (ties to
        the smaller id), and their scores; places with no vote are not returned."""
        sc = self.scores(query, exclude)
        rows = np.flatnonzero(sc > 0)
        if not len(rows) or k <= 0:
            return np.zeros(0, np.int64), np.zeros(0, np.int64)
        order = np.lexsort((self._ids[rows], -sc[rows]))[: int(k)]
        return self._ids[rows[order]], sc[rows[order]]
