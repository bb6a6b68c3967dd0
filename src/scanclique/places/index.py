"""Exact nearest-signature search: the prefilter's vector index.

Brute force in NumPy: the squared Euclidean distances from a query signature to every
stored one by one matrix-vector product (``|x|² - 2 x·q + |q|²``, by a single-threaded
``einsum``), then a partial sort (``np.partition``) of the ``k`` smallest. Signatures
are kept in ``float32``; distances are exact up to that rounding (about 1e-7 relative),
and ties are broken by place id so that every run ranks alike. At 50 000 places of
:data:`~.signature.SIGNATURE_SIZE` values the matrix is 42 MB and one search costs a few
milliseconds, so an approximate index (faiss, HNSW) would not pay here;
``benchmarks/places.py`` measures it.

Examples
--------
>>> idx = SignatureIndex(3)
>>> idx.add([10, 11, 12], np.array([[1.0, 0, 0], [0, 1.0, 0], [0.9, 0.1, 0]]))
>>> ids, d = idx.search(np.array([1.0, 0, 0]), k=2)
>>> ids.tolist(), np.round(d, 3).tolist()
([10, 12], [0.0, 0.02])
"""

from __future__ import annotations

import numpy as np

from ..errors import PlaceDatabaseError

__all__ = ["SignatureIndex", "brute_force_knn", "member_mask"]


def member_mask(ids: np.ndarray, ex: np.ndarray, ascending: bool) -> np.ndarray:
    """``np.isin(ids, ex)``: which of ``ids`` are among ``ex`` (int64). When ``ids`` is
    strictly ascending (``ascending``, as a place database's are), by a binary search of
    each of ``ex`` in ``ids``: O(len(ex) log len(ids)) instead of a pass over all ids.

    >>> member_mask(np.array([2, 4, 6]), np.array([6, 5, 2, 2]), True).tolist()
    [True, False, True]
    """
    if not ascending:
        return np.isin(ids, ex)
    mask = np.zeros(len(ids), dtype=bool)
    if len(ids) and len(ex):
        pos = np.searchsorted(ids, ex)
        ok = pos < len(ids)
        pos = pos[ok]
        mask[pos[ids[pos] == ex[ok]]] = True
    return mask


def brute_force_knn(
    X: np.ndarray, q: np.ndarray, k: int, allowed: np.ndarray | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """Row indices of the ``k`` rows of ``X`` nearest ``q`` (squared Euclidean), nearest
    first, and their distances; only rows where ``allowed`` is True when given.

    The slow, simple reference of :meth:`SignatureIndex.search` (a full sort of exact
    float64 distances; ties broken by row index)."""
    d = np.sum((np.asarray(X, dtype=float) - np.asarray(q, dtype=float)) ** 2, axis=1)
    rows = np.arange(len(d))
    if allowed is not None:
        rows = rows[np.asarray(allowed, dtype=bool)]
    order = np.lexsort((rows, d[rows]))[:k]
    return rows[order], d[rows[order]]


class SignatureIndex:
    """Signatures of places in memory, searched exactly by brute force.

    Parameters
    ----------
    dim : int
        Length of a signature.

    Notes
    -----
    Adding is amortised O(1) (capacity doubles); a search is O(N D) for N places of D
    values.
    """

    def __init__(self, dim: int) -> None:
        self.dim = int(dim)
        self._X = np.zeros((0, self.dim), dtype=np.float32)
        self._sq = np.zeros(0, dtype=np.float32)
        self._ids = np.zeros(0, dtype=np.int64)
        self._n = 0
        self._ascending = True  # ids strictly ascending in the order added

    def __len__(self) -> int:
        return self._n

    @property
    def ids(self) -> np.ndarray:
        """Place ids in the order they were added (read-only view)."""
        v = self._ids[: self._n]
        v.setflags(write=False)
        return v

    @property
    def signatures(self) -> np.ndarray:
        """``(N, dim)`` float32 signatures in id order of :attr:`ids` (read-only view)."""
        v = self._X[: self._n]
        v.setflags(write=False)
        return v

    def add(self, ids, signatures) -> None:
        """Append places ``ids`` (int) with their ``(n, dim)`` signatures."""
        ids = np.atleast_1d(np.asarray(ids, dtype=np.int64))
        S = np.asarray(signatures, dtype=np.float32).reshape(-1, self.dim)
        if len(ids) != len(S):
            raise PlaceDatabaseError(f"{len(ids)} ids but {len(S)} signatures")
        if len(ids) and (
            np.any(ids[1:] <= ids[:-1]) or (self._n and ids[0] <= self._ids[self._n - 1])
        ):
            self._ascending = False
        need = self._n + len(ids)
        if need > len(self._X):
            cap = max(need, 2 * len(self._X), 64)
            X = np.zeros((cap, self.dim), dtype=np.float32)
            X[: self._n] = self._X[: self._n]
            sq = np.zeros(cap, dtype=np.float32)
            sq[: self._n] = self._sq[: self._n]
            i = np.zeros(cap, dtype=np.int64)
            i[: self._n] = self._ids[: self._n]
            self._X, self._sq, self._ids = X, sq, i
        self._X[self._n : need] = S
        self._sq[self._n : need] = np.einsum("ij,ij->i", S, S)
        self._ids[self._n : need] = ids
        self._n = need

    def contains(self, ids) -> np.ndarray:
        """Boolean mask over :attr:`ids`: which are among ``ids`` (``np.isin``)."""
        ex = np.atleast_1d(np.asarray(ids, dtype=np.int64))
        return member_mask(self._ids[: self._n], ex, self._ascending)

    def distances(self, q: np.ndarray) -> np.ndarray:
        """Squared Euclidean distance from ``q`` to every stored signature, ``(N,)``
        float32 (clipped at 0 against rounding)."""
        q = np.asarray(q, dtype=np.float32).reshape(self.dim)
        X = self._X[: self._n]
        # einsum, not BLAS: a multithreaded BLAS matrix-vector product costs ~5x more on
        # a busy machine (its threads wake for a 1 MFLOP product), measured at 5k places
        xq = np.einsum("ij,j->i", X, q)
        d = self._sq[: self._n] - 2.0 * xq + float(np.einsum("i,i->", q, q))
        return np.maximum(d, 0.0)

    def search(
        self, q: np.ndarray, k: int, allowed: np.ndarray | None = None
    ) -> tuple[np.ndarray, np.ndarray]:
        """The ids of the ``k`` places whose signatures are nearest ``q``, nearest first,
        and their distances (float64); restricted to the rows where ``allowed`` (a
        boolean mask over :attr:`ids`) is True when given. Ties go to the smaller id."""
        d = self.distances(q).astype(np.float64)
        rows = np.arange(self._n)
        if allowed is not None:
            allowed = np.asarray(allowed, dtype=bool)
            if allowed.shape != (self._n,):
                raise PlaceDatabaseError(
                    f"allowed mask has shape {allowed.shape}, expected ({self._n},)"
                )
            rows = rows[allowed]
        k = max(0, min(int(k), len(rows)))
        if k == 0:
            return np.zeros(0, dtype=np.int64), np.zeros(0)
        dr = d[rows]
        if k < len(rows):
            # the k smallest, plus every row tied with the k-th (ties go by id below)
            kth = np.partition(dr, k - 1)[k - 1]
            keep = dr <= kth
            rows, dr = rows[keep], dr[keep]
        ids = self._ids[rows]
        order = np.lexsort((ids, dr))[:k]
        return ids[order], dr[order]
