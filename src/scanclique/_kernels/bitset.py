"""Bitset primitives, the kernel clock and small array helpers (private).

Graphs arrive in the clique kernels as bitset adjacency rows: ``A[v, w]`` is a ``uint64``
word whose bit ``b`` says whether ``v`` is adjacent to ``64 * w + b``; a vertex set is a
row of such words. :func:`pack_checked` builds the rows from a boolean matrix.

The steps every search shares live here, inlined where they are called: the node budget
and clock check (:func:`spent`), the child set of a branching step (:func:`child_set`).
An ``inline="always"`` helper must not call another one: nested inlining made the
colouring 2 to 6 times slower (measured, see :mod:`.colouring`). Two idioms are written
out where they are used rather than wrapped: the visit of the set bits of a word,
``while x: b = cttz(x); x &= x - ONE``, and the scan to the first non-empty word,
``while w < W and P[w] == ZERO: w += 1``.

numba pitfall kept in mind throughout the clique kernels: mixing ``uint64`` with
``int64`` promotes to ``float64``, so every word operation uses ``uint64`` operands only
(:data:`ONE`, :data:`ZERO`).
"""

# ruff: noqa: E402 (ensure_cache() runs before numba is imported)
from __future__ import annotations

from . import ensure_cache

ensure_cache()  # before any njit(cache=True) below picks its cache location

import time

import numba
import numpy as np
from llvmlite import ir
from numba import types
from numba.core import cgutils
from numba.extending import intrinsic

from .codes import FINISHED as _FINISHED
from .codes import TIME_LIMIT as _TIME_LIMIT
from .jit import njit

ONE = np.uint64(1)
ZERO = np.uint64(0)
_GATHER = np.uint64(0x0102040810204080)
_SHIFT56 = np.uint64(56)


@intrinsic
def cttz(typingctx, x):
    """Count trailing zeros of a non-zero ``uint64`` (one ``tzcnt`` instruction)."""
    sig = types.uint64(types.uint64)

    def codegen(context, builder, signature, args):
        return builder.cttz(args[0], ir.Constant(ir.IntType(1), 1))

    return sig, codegen


@intrinsic
def ctpop(typingctx, x):
    """Population count of a ``uint64`` (one ``popcnt`` instruction)."""
    sig = types.uint64(types.uint64)

    def codegen(context, builder, signature, args):
        return builder.ctpop(args[0])

    return sig, codegen


@intrinsic
def _mask64(typingctx, a, i):
    """Bit ``k`` set where byte ``a[i + k]`` is not zero, ``k < 64``, for a ``uint8`` array
    with at least ``i + 64`` bytes: one unaligned vector load, a compare and a movemask
    (``vpcmpb``/``vpmovmskb`` on x86)."""
    sig = types.uint64(a, i)

    def codegen(context, builder, signature, args):
        arr = context.make_array(signature.args[0])(context, builder, args[0])
        vt = ir.VectorType(ir.IntType(8), 64)
        ptr = builder.bitcast(builder.gep(arr.data, [args[1]]), vt.as_pointer())
        nz = builder.icmp_unsigned("!=", builder.load(ptr, align=1), ir.Constant(vt, None))
        return builder.bitcast(nz, ir.IntType(64))

    return sig, codegen


@intrinsic
def _clock_monotonic(typingctx):
    """``clock_gettime(CLOCK_MONOTONIC)`` in seconds, a direct libc call."""
    sig = types.float64()

    def codegen(context, builder, signature, args):
        i32, i64, f64 = ir.IntType(32), ir.IntType(64), ir.DoubleType()
        timespec = ir.LiteralStructType([i64, i64])
        fn = cgutils.get_or_insert_function(
            builder.module, ir.FunctionType(i32, [i32, timespec.as_pointer()]), "clock_gettime"
        )
        ts = cgutils.alloca_once(builder, timespec)
        builder.call(fn, [ir.Constant(i32, time.CLOCK_MONOTONIC), ts])
        zero = ir.Constant(i32, 0)
        sec = builder.load(builder.gep(ts, [zero, zero]))
        nsec = builder.load(builder.gep(ts, [zero, ir.Constant(i32, 1)]))
        frac = builder.fmul(builder.sitofp(nsec, f64), ir.Constant(f64, 1e-9))
        return builder.fadd(builder.sitofp(sec, f64), frac)

    return sig, codegen


if time.get_clock_info("perf_counter").implementation == "clock_gettime(CLOCK_MONOTONIC)":

    @njit(cache=True)
    def now():
        """``time.perf_counter()``, from compiled code."""
        return _clock_monotonic()

else:  # pragma: no cover - not Linux

    @njit(cache=True)
    def now():
        """``time.perf_counter()``, from compiled code."""
        with numba.objmode(t="float64"):
            t = time.perf_counter()
        return t


@njit(cache=True)
def popcount(P, W):
    s = 0
    for w in range(W):
        s += int(ctpop(P[w]))
    return s


@njit(cache=True)
def setbit(P, v):
    P[v >> 6] |= ONE << np.uint64(v & 63)


@njit(cache=True)
def clearbit(P, v):
    P[v >> 6] &= ~(ONE << np.uint64(v & 63))


@njit(cache=True)
def grow(a, k, cap):
    """A new array of length ``cap`` starting with ``a[:k]`` (explicit loops: slicing
    costs seconds of compilation)."""
    out = np.empty(cap, a.dtype)
    for i in range(k):
        out[i] = a[i]
    return out


@njit(cache=True)
def head(a, k):
    """A new array holding ``a[:k]``."""
    return grow(a, k, k)


@njit(inline="always")
def grow_pair(a, b, k, cap):
    """:func:`grow` of the two arrays of a branching list (vertices and their bounds)."""
    return grow(a, k, cap), grow(b, k, cap)


@njit(inline="always")
def fill(P, n):
    """``P`` (``(n + 63) // 64`` words) becomes the set of all ``n`` vertices."""
    W = P.shape[0]
    for w in range(W):
        P[w] = ~ZERO
    if n & 63:
        P[W - 1] = (ONE << np.uint64(n & 63)) - ONE


@njit(cache=True)
def mapped_sorted(a, k, order):
    """``sorted(order[a[i]] for i < k)``: back to the caller's labels."""
    out = np.empty(k, np.int64)
    map_sorted_into(a, k, order, out)
    return out


@njit(inline="always")
def _insert(out, i, x):
    """Insert ``x`` into the sorted ``out[:i]`` (one step of an insertion sort)."""
    j = i
    while j > 0 and out[j - 1] > x:
        out[j] = out[j - 1]
        j -= 1
    out[j] = x


@njit(cache=True)
def map_sorted_into(a, k, order, out):
    """``out[:k] = sorted(order[a[i]] for i < k)`` (insertion sort, cliques are short)."""
    for i in range(k):
        _insert(out, i, order[a[i]])


@njit(cache=True)
def sorted_into(a, k, out):
    """``out[:k] = sorted(a[:k])`` (insertion sort, cliques are short)."""
    for i in range(k):
        _insert(out, i, a[i])


@njit(inline="always")
def child_set(Pst, depth, B, v, W):
    """Branch on ``v`` at ``depth`` of a search stack: ``Pst[depth + 1] = Pst[depth] & N(v)``
    and ``v`` leaves ``Pst[depth]``. Returns ``|Pst[depth + 1]|``."""
    size = 0
    for w in range(W):
        x = Pst[depth, w] & B[v, w]
        Pst[depth + 1, w] = x
        size += int(ctpop(x))
    clearbit(Pst[depth], v)
    return size


@njit(inline="always")
def spent(nodes, node_limit, mask, deadline, over):
    """Whether a search must stop at node number ``nodes``: ``over`` (its status for an
    exhausted node budget) past ``node_limit``, ``Status.TIME_LIMIT`` when the kernel clock,
    read every ``mask + 1`` nodes (:func:`check_mask`), has passed ``deadline``, else
    ``Status.FINISHED`` (go on)."""
    if nodes > node_limit:
        return over
    if (nodes & mask) == 0 and now() > deadline:
        return _TIME_LIMIT
    return _FINISHED


@njit(cache=True)
def check_mask(n, W):
    """Nodes between two looks at the clock, minus one: about 2e5 word operations apart."""
    work = n * W + 1
    mask = 0
    while mask < 4095 and (mask + 1) * work < 200_000:
        mask = mask * 2 + 1
    return mask


@njit(cache=True)
def pack_checked(adj):
    """Bitset rows of a boolean adjacency matrix, and its first defect.

    Returns ``(A, u, v)``: ``A[i, w]`` bit ``b`` is ``adj[i, 64 w + b]``; ``(u, v)`` is
    ``(-1, -1)`` for a symmetric matrix with a False diagonal, ``(i, i)`` for a self loop,
    else a pair with ``adj[u, v] != adj[v, u]``.

    Sixty-four flags at a time where 64 bytes can be read (:func:`_mask64`); the last
    bytes of the matrix eight at a time: a NumPy bool is one byte, 0 or 1, so eight read as one
    little-endian word ``y`` have their flags at bits 0, 8, ..., 56. In ``y * M`` with
    ``M = sum_j 2^(56 - 7 j)`` (``0x0102040810204080``) flag ``k`` times term ``j`` lands on
    bit ``56 + 8 k - 7 j``: on ``56 + k`` for ``j = k``, below 56 or beyond 63 otherwise,
    and no two products share a bit (so nothing carries). The top byte is the eight flags.
    Symmetry is then checked on the bits: every edge ``i < j`` must have its mirror, and
    the rows must hold twice as many bits as the upper triangle (O(m) in all).
    """
    n = adj.shape[0]
    W = (n + 63) >> 6
    A = np.empty((n, W), np.uint64)
    flat = adj.reshape(-1).view(np.uint8)
    end = n * n
    for i in range(n):
        for w in range(W):
            p = i * n + w * 64
            k = min(n - w * 64, 64)  # columns in this word
            if p + 64 <= end:
                # 64 flags at once; those past the row (k < 64) are masked off
                x = _mask64(flat, p)
                if k < 64:
                    x &= (ONE << np.uint64(k)) - ONE
                A[i, w] = x
                continue
            # the last bytes of the matrix: eight at a time, as described above
            x = ZERO
            j = 0
            while j + 8 <= k:
                y = ZERO
                for b in range(8):
                    y |= np.uint64(flat[p + j + b]) << np.uint64(8 * b)
                x |= ((y * _GATHER) >> _SHIFT56) << np.uint64(j)
                j += 8
            while j < k:
                x |= np.uint64(flat[p + j]) << np.uint64(j)
                j += 1
            A[i, w] = x
    upper = 0
    total = 0
    for i in range(n):
        wi = i >> 6
        bi = ONE << np.uint64(i & 63)
        if A[i, wi] & bi:
            return A, i, i
        for w in range(W):
            x = A[i, w]
            total += int(ctpop(x))
            if w < wi:
                continue
            if w == wi:
                x &= ~((bi << ONE) - ONE)  # columns j > i only
            while x:
                b = cttz(x)
                x &= x - ONE
                j = w * 64 + int(b)
                upper += 1
                if A[j, wi] & bi == ZERO:
                    return A, i, j
    if total != 2 * upper:  # an edge below the diagonal without its mirror above
        for i in range(n):
            for w in range(W):
                x = A[i, w]
                while x:
                    b = cttz(x)
                    x &= x - ONE
                    j = w * 64 + int(b)
                    if (A[j, i >> 6] >> np.uint64(i & 63)) & ONE == ZERO:
                        return A, i, j
    return A, -1, -1
