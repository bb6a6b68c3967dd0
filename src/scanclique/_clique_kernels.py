"""Compiled kernels of the maximum clique engine (private; see :mod:`scanclique.clique`).

Graphs arrive here as bitset adjacency rows: ``A[v, w]`` is a ``uint64`` word whose bit ``b``
says whether ``v`` is adjacent to ``64 * w + b``. Every kernel is ``numba.njit(cache=True)``:
the first call in a fresh environment compiles them (tens of seconds), later processes load
the cache from ``__pycache__`` (well under a second).

Inside the full search the graph is renumbered in degeneracy order (``B``), so that bit
order is the order of the greedy colouring (BBMC). Small and sparse graphs first take a
lean path (:func:`solve_bits`): one-word sets up to 64 vertices; above, a greedy clique and
the k-core it implies, whose vertices are often few enough for one word. Local names
follow the papers: ``P`` the candidate set, ``C`` the growing clique, ``bar`` the size to
beat, ``need = bar - |C|`` how many more vertices a child must add to beat it.

numba pitfall kept in mind throughout: mixing ``uint64`` with ``int64`` promotes to
``float64``, so every word operation uses ``uint64`` operands only (``_ONE``, ``_ZERO``).
"""

from __future__ import annotations

import time

import numba
import numpy as np
from llvmlite import ir
from numba import types
from numba.core import cgutils
from numba.extending import intrinsic

_ONE = np.uint64(1)
_ZERO = np.uint64(0)

#: option bits of :func:`solve` (``opts``)
OPT_MAXSAT = 1  # filter the branching vertices with MaxSAT-style reasoning
OPT_LOCAL_SEARCH = 2  # improve the greedy initial clique by tabu local search
OPT_DEFAULT = OPT_MAXSAT | OPT_LOCAL_SEARCH

#: greedy starts of :func:`maximum_peeled`
SPARSE_STARTS = 4
#: node budgets of its searches with the plain colouring bound, past which the full
#: search takes over: multi-word sets (sparse cores), one-word sets of a dense core
SPARSE_NODES = 2000
DENSE_WORD_NODES = 200


@intrinsic
def _cttz(typingctx, x):
    """Count trailing zeros of a non-zero ``uint64`` (one ``tzcnt`` instruction)."""
    sig = types.uint64(types.uint64)

    def codegen(context, builder, signature, args):
        return builder.cttz(args[0], ir.Constant(ir.IntType(1), 1))

    return sig, codegen


@intrinsic
def _ctpop(typingctx, x):
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


# The kernels compare against deadlines taken with time.perf_counter in Python. Where that
# is clock_gettime(CLOCK_MONOTONIC) (Linux) the kernels read the same clock directly; else
# through object mode, whose first call in a process costs a tenth of a second.
if time.get_clock_info("perf_counter").implementation == "clock_gettime(CLOCK_MONOTONIC)":

    @numba.njit(cache=True)
    def _now():
        """``time.perf_counter()``, from compiled code."""
        return _clock_monotonic()

else:  # pragma: no cover - not Linux

    @numba.njit(cache=True)
    def _now():
        """``time.perf_counter()``, from compiled code."""
        with numba.objmode(t="float64"):
            t = time.perf_counter()
        return t


@numba.njit(cache=True)
def _popcount(P, W):
    s = 0
    for w in range(W):
        s += int(_ctpop(P[w]))
    return s


@numba.njit(cache=True)
def _first(P, W):
    """Lowest set bit of ``P``, or -1."""
    for w in range(W):
        if P[w] != _ZERO:
            return w * 64 + int(_cttz(P[w]))
    return -1


@numba.njit(cache=True)
def _setbit(P, v):
    P[v >> 6] |= _ONE << np.uint64(v & 63)


@numba.njit(cache=True)
def _clearbit(P, v):
    P[v >> 6] &= ~(_ONE << np.uint64(v & 63))


@numba.njit(cache=True)
def _head(a, k):
    """A new array holding ``a[:k]`` (explicit loops: slicing costs seconds of compilation)."""
    out = np.empty(k, a.dtype)
    for i in range(k):
        out[i] = a[i]
    return out


@numba.njit(cache=True)
def _grow(a, k, cap):
    """A new array of length ``cap`` starting with ``a[:k]``."""
    out = np.empty(cap, a.dtype)
    for i in range(k):
        out[i] = a[i]
    return out


@numba.njit(cache=True)
def _mapped_sorted(a, k, order):
    """``sorted(order[a[i]] for i < k)``: back to the caller's labels."""
    out = np.empty(k, np.int64)
    _map_sorted_into(a, k, order, out)
    return out


@numba.njit(cache=True)
def _map_sorted_into(a, k, order, out):
    """``out[:k] = sorted(order[a[i]] for i < k)`` (insertion sort, cliques are short)."""
    for i in range(k):
        x = order[a[i]]
        j = i
        while j > 0 and out[j - 1] > x:
            out[j] = out[j - 1]
            j -= 1
        out[j] = x


@numba.njit(cache=True)
def check_mask(n, W):
    """Nodes between two looks at the clock, minus one: about 2e5 word operations apart."""
    work = n * W + 1
    mask = 0
    while mask < 4095 and (mask + 1) * work < 200_000:
        mask = mask * 2 + 1
    return mask


# --------------------------------------------------------------------------------------
# Input checks
# --------------------------------------------------------------------------------------
_GATHER = np.uint64(0x0102040810204080)
_SHIFT56 = np.uint64(56)


@numba.njit(cache=True)
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
                    x &= (_ONE << np.uint64(k)) - _ONE
                A[i, w] = x
                continue
            # the last bytes of the matrix: eight at a time, as described above
            x = _ZERO
            j = 0
            while j + 8 <= k:
                y = _ZERO
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
        bi = _ONE << np.uint64(i & 63)
        if A[i, wi] & bi:
            return A, i, i
        for w in range(W):
            x = A[i, w]
            total += int(_ctpop(x))
            if w < wi:
                continue
            if w == wi:
                x &= ~((bi << _ONE) - _ONE)  # columns j > i only
            while x:
                b = _cttz(x)
                x &= x - _ONE
                j = w * 64 + int(b)
                upper += 1
                if A[j, wi] & bi == _ZERO:
                    return A, i, j
    if total != 2 * upper:  # an edge below the diagonal without its mirror above
        for i in range(n):
            for w in range(W):
                x = A[i, w]
                while x:
                    b = _cttz(x)
                    x &= x - _ONE
                    j = w * 64 + int(b)
                    if (A[j, i >> 6] >> np.uint64(i & 63)) & _ONE == _ZERO:
                        return A, i, j
    return A, -1, -1


# --------------------------------------------------------------------------------------
# Initial order, renumbering, initial clique
# --------------------------------------------------------------------------------------
@numba.njit(cache=True)
def _swap(vert, pos, p, q):
    """Exchange the vertices at positions ``p`` and ``q`` of ``vert`` (``pos`` its inverse)."""
    x = vert[p]
    y = vert[q]
    vert[p] = y
    pos[y] = p
    vert[q] = x
    pos[x] = q


@numba.njit(cache=True)
def degeneracy_order(A, n):
    """Smallest-last order (densest core first) and each vertex's core number.

    Vertices are peeled one at a time, each time one of minimum degree in the graph that
    remains; ``order[n - 1]`` is the first peeled, ``order[0]`` the last, so that the
    search meets the densest core first (the initial order of MCQ/MCS), and the core
    number of a vertex is the largest minimum degree seen up to its removal. Dense graphs
    of up to 1024 vertices (density above 1/4, where the search is hard) break ties by
    the lowest label, in O(n^2); other graphs keep the vertices sorted by remaining degree
    in one array of buckets (Matula & Beck 1983, with the swaps of Batagelj & Zaversnik
    2003), O(n W + m).
    """
    W = A.shape[1]
    deg = np.empty(n, np.int64)
    dmax = 0
    m2 = 0
    for v in range(n):
        deg[v] = _popcount(A[v], W)
        dmax = max(dmax, deg[v])
        m2 += deg[v]
    if n <= 1024 and 4 * m2 > n * n:
        return _peel_exact(A, n, deg)
    # vert: vertices sorted by remaining degree, bucket e starting at start[e]; the
    # first i entries are peeled
    start = np.zeros(dmax + 2, np.int64)
    for v in range(n):
        start[deg[v] + 1] += 1
    for e in range(dmax + 1):
        start[e + 1] += start[e]
    vert = np.empty(n, np.int64)
    pos = np.empty(n, np.int64)
    fill = start.copy()
    for v in range(n):
        pos[v] = fill[deg[v]]
        vert[pos[v]] = v
        fill[deg[v]] += 1
    order = np.empty(n, np.int64)
    core = np.empty(n, np.int64)
    k = 0
    for i in range(n):
        # invariant: vert[i:] hold the remaining vertices in non-decreasing remaining
        # degree; bucket deg[vert[i]] begins at i, every higher bucket e at start[e]
        # (after the two assignments below: buckets d - 1 and d begin at i + 1)
        v = vert[i]
        d = deg[v]
        start[d] = i + 1
        if d > 0:
            start[d - 1] = i + 1  # empty: a vertex falling below d opens it
        k = max(k, d)
        core[v] = k
        order[n - 1 - i] = v
        for w in range(W):
            x = A[v, w]
            while x:
                b = _cttz(x)
                x &= x - _ONE
                u = w * 64 + int(b)
                pu = pos[u]
                if pu <= i:  # peeled already
                    continue
                # swap u to the front of bucket e and move the bucket's start past it:
                # u ends bucket e - 1; then swap it to the front of that bucket, so that
                # among equal degrees the vertex that lost a neighbour last is peeled first
                e = deg[u]
                pw = start[e]
                _swap(vert, pos, pu, pw)
                start[e] = pw + 1
                _swap(vert, pos, pw, start[e - 1])
                deg[u] = e - 1
    return order, core


@numba.njit(cache=True)
def _peel_exact(A, n, deg):
    """Smallest-last peeling by an argmin per step (see :func:`degeneracy_order`)."""
    W = A.shape[1]
    removed = np.zeros(n, np.bool_)
    order = np.empty(n, np.int64)
    core = np.empty(n, np.int64)
    k = 0
    for i in range(n):
        # invariant: deg[u] = |N(u) minus removed| for every remaining u
        best = -1
        bd = n + 1
        for v in range(n):
            if not removed[v] and deg[v] < bd:
                bd = deg[v]
                best = v
        k = max(k, bd)
        core[best] = k
        order[n - 1 - i] = best
        removed[best] = True
        for w in range(W):
            x = A[best, w]
            while x:
                b = _cttz(x)
                x &= x - _ONE
                u = w * 64 + int(b)
                if not removed[u]:
                    deg[u] -= 1
    return order, core


@numba.njit(cache=True)
def relabel(A, n, order):
    """Bitset rows of the graph renumbered so that new vertex ``i`` is old ``order[i]``."""
    W = A.shape[1]
    pos = np.empty(n, np.int64)
    for i in range(n):
        pos[order[i]] = i
    B = np.zeros((n, W), np.uint64)
    for i in range(n):
        v = order[i]
        for w in range(W):
            x = A[v, w]
            while x:
                b = _cttz(x)
                x &= x - _ONE
                _setbit(B[i], pos[w * 64 + int(b)])
    return B


@numba.njit(cache=True)
def greedy_clique(B, n, P, t0, time_limit, core):
    """Best of the greedy cliques grown from each vertex (while time lasts).

    From ``s``: candidates ``N(s)``, then repeatedly add the lowest-numbered candidate (in
    the degeneracy numbering: the one deepest in the core) and intersect. O(n w W).
    ``core[s]`` is the core number of ``s`` (non-increasing in the degeneracy numbering):
    a clique through ``s`` has at most ``core[s] + 1`` vertices, so the starts end once
    that cannot beat the best.
    """
    W = B.shape[1]
    best = np.empty(n, np.int64)
    bsize = 0
    cur = np.empty(n, np.int64)
    for s in range(n):
        if core[s] + 1 <= bsize:
            break
        if (s & 1023) == 1023 and _now() - t0 > time_limit:
            break
        for w in range(W):
            P[w] = B[s, w]
        cur[0] = s
        size = 1
        w0 = 0
        while True:
            # invariant: cur[:size] is a clique, P its common neighbourhood
            while w0 < W and P[w0] == _ZERO:
                w0 += 1
            if w0 == W:
                break
            u = w0 * 64 + int(_cttz(P[w0]))
            cur[size] = u
            size += 1
            for w in range(w0, W):
                P[w] &= B[u, w]
        if size > bsize:
            bsize = size
            for i in range(size):
                best[i] = cur[i]
    return _head(best, bsize)


@numba.njit(cache=True)
def _rand(state, k):
    """Uniform integer in ``[0, k)`` from a xorshift64 generator (Marsaglia 2003) kept in
    ``state[0]``: deterministic, and numba's global generator is left alone."""
    x = state[0]
    x ^= x << np.uint64(13)
    x ^= x >> np.uint64(7)
    x ^= x << np.uint64(17)
    state[0] = x
    return int(x % np.uint64(k))


@numba.njit(cache=True)
def _ls_add(B, n, W, v, miss, sign):
    # every vertex u != v not adjacent to v gains (loses) one missing clique neighbour
    for w in range(W):
        x = ~B[v, w]
        if w == W - 1 and (n & 63) != 0:
            x &= (_ONE << np.uint64(n & 63)) - _ONE
        while x:
            b = _cttz(x)
            x &= x - _ONE
            miss[w * 64 + int(b)] += sign
    miss[v] -= sign


@numba.njit(cache=True)
def local_search(B, n, init, max_iter, stall, t0, time_limit, seed):
    """Tabu plateau search from ``init``: add moves, (1,1)-swaps, and drops when stuck.

    ``miss[v]`` counts the clique vertices not adjacent to ``v``: ``v`` can be added when
    it is 0 and swapped in (for its one non-neighbour) when it is 1. A vertex swapped or
    dropped out is tabu for a few iterations. After ``stall`` iterations without a new
    best, the search restarts from a random vertex. After Grosso, Locatelli & Pullan (2008)
    and Wu & Hao (2012), much simplified.
    """
    W = B.shape[1]
    rng = np.full(1, np.uint64(seed) | _ONE, np.uint64)
    inC = np.zeros(n, np.bool_)
    C = np.empty(n + 1, np.int64)
    where = np.empty(n, np.int64)
    miss = np.zeros(n, np.int64)
    tabu = np.zeros(n, np.int64)
    cand_a = np.empty(n, np.int64)
    cand_s = np.empty(n, np.int64)
    size = 0
    for v in init:
        _ls_add(B, n, W, v, miss, 1)
        inC[v] = True
        where[v] = size
        C[size] = v
        size += 1
    best = _head(init, init.shape[0])
    last = 0
    for it in range(max_iter):
        # invariant: C[:size] is a clique; miss[v] = |C minus N(v) minus {v}|
        if (it & 255) == 255 and _now() - t0 > time_limit:
            break
        if it - last > stall:  # restart from a random vertex
            while size > 0:
                size -= 1
                _ls_add(B, n, W, C[size], miss, -1)
                inC[C[size]] = False
            v = _rand(rng, n)
            _ls_add(B, n, W, v, miss, 1)
            inC[v] = True
            where[v] = 0
            C[0] = v
            size = 1
            last = it
            continue
        na = 0
        ns = 0
        for v in range(n):
            if inC[v] or tabu[v] > it:
                continue
            if miss[v] == 0:
                cand_a[na] = v
                na += 1
            elif miss[v] == 1:
                cand_s[ns] = v
                ns += 1
        if na > 0:
            v = cand_a[_rand(rng, na)]
        elif ns > 0:
            v = cand_s[_rand(rng, ns)]
            # the one clique vertex not adjacent to v leaves
            u = -1
            for i in range(size):
                c = C[i]
                if (B[v, c >> 6] >> np.uint64(c & 63)) & _ONE == _ZERO:
                    u = c
                    break
            _ls_add(B, n, W, u, miss, -1)
            inC[u] = False
            i = where[u]
            size -= 1
            C[i] = C[size]
            where[C[i]] = i
            tabu[u] = it + 7 + _rand(rng, ns + 1)
        else:
            if size == 0:
                break
            u = C[_rand(rng, size)]
            _ls_add(B, n, W, u, miss, -1)
            inC[u] = False
            i = where[u]
            size -= 1
            C[i] = C[size]
            where[C[i]] = i
            tabu[u] = it + 7
            continue
        _ls_add(B, n, W, v, miss, 1)
        inC[v] = True
        where[v] = size
        C[size] = v
        size += 1
        if size > best.shape[0]:
            best = _head(C, size)
            last = it
    return best


# --------------------------------------------------------------------------------------
# Colouring bound and MaxSAT-style filtering
# --------------------------------------------------------------------------------------
@numba.njit(cache=True)
def colour_classes(P, B, W, kmin, U, Q, CL, ord_v, ord_c, base, col):
    """Greedy sequential colouring of ``P`` in bit order (BBMC, San Segundo et al. 2011).

    Classes are built one at a time, each a maximal independent set taken from the
    uncoloured vertices in increasing index. Classes ``1 .. kmin - 1`` are kept as bitsets
    in ``CL[0 .. kmin - 2]``; vertices of colour ``>= kmin`` go to ``ord_v[base:]`` with
    their colour in ``ord_c[base:]``, in non-decreasing colour (Tomita's k-min filter:
    only they can lead to a clique that beats the incumbent). Returns how many.
    """
    w0 = W
    for w in range(W):
        U[w] = P[w]
        if P[w] != _ZERO and w < w0:
            w0 = w
    k = 0
    cnt = 0
    while True:
        # invariant: U = vertices of P not yet coloured, and U[:w0] is empty
        while w0 < W and U[w0] == _ZERO:
            w0 += 1
        if w0 == W:
            break
        k += 1
        rec = k < kmin
        if rec:
            for w in range(W):
                CL[k - 1, w] = _ZERO
        for w in range(w0, W):
            Q[w] = U[w]
        wq = w0
        while True:
            # invariant: Q = uncoloured vertices not adjacent to any vertex of class k
            while wq < W and Q[wq] == _ZERO:
                wq += 1
            if wq == W:
                break
            b = _cttz(Q[wq])
            v = wq * 64 + int(b)
            one = _ONE << b
            Q[wq] &= ~one
            U[wq] &= ~one
            for w in range(wq, W):
                Q[w] &= ~B[v, w]
            if rec:
                CL[k - 1, wq] |= one
                col[v] = k - 1
            else:
                col[v] = -1
                ord_v[base + cnt] = v
                ord_c[base + cnt] = k
                cnt += 1
    return cnt


@numba.njit(cache=True)
def colour_count(P, B, W, U, Q):
    """Number of classes of the greedy colouring of ``P``: an upper bound on its clique."""
    for w in range(W):
        U[w] = P[w]
    k = 0
    w0 = 0
    while True:
        while w0 < W and U[w0] == _ZERO:
            w0 += 1
        if w0 == W:
            return k
        k += 1
        for w in range(w0, W):
            Q[w] = U[w]
        wq = w0
        while True:
            while wq < W and Q[wq] == _ZERO:
                wq += 1
            if wq == W:
                break
            b = _cttz(Q[wq])
            v = wq * 64 + int(b)
            one = _ONE << b
            Q[wq] &= ~one
            U[wq] &= ~one
            for w in range(wq, W):
                Q[w] &= ~B[v, w]


@numba.njit(cache=True)
def try_vertex(v, B, W, need, CL, P, S):
    """Can ``v`` join the ``need`` classes without raising their clique bound?

    Returns 1 when ``v`` was put into a class: directly (no neighbour there) or by
    Tomita's Re-NUMBER (its single neighbour ``u`` in class ``k`` moves to a class with no
    neighbour of ``u``; MCS, 2010). Returns 2 when unit propagation from ``v`` fails
    (MaxCLQ, Li & Quan 2010): classes are clauses "the clique takes one of these", ``v``
    is set true, every class keeps only the vertices adjacent to all true ones, a class
    left with one vertex makes it true, and a class left empty is a conflict. The classes
    that took part (traced back through the reasons ``RS``) are written to ``SX``:
    together with ``v`` they hold no clique with one vertex per class. Returns 0 otherwise.
    """
    RS, SX, SU, T, D, col, left, active, queued, fired, queue, uvert = S
    WC = (need + 63) >> 6
    nunits = 0
    for k in range(need):
        if not active[k]:
            continue
        c = 0
        for w in range(W):
            c += int(_ctpop(CL[k, w] & B[v, w]))
        if c == 0:
            _setbit(CL[k], v)
            col[v] = k
            return 1
        left[k] = c
        fired[k] = False
        queued[k] = c == 1
        for w in range(WC):
            RS[k, w] = _ZERO
        if c == 1:
            queue[nunits] = k
            for w in range(W):
                x = CL[k, w] & B[v, w]
                if x != _ZERO:
                    uvert[nunits] = w * 64 + int(_cttz(x))
                    break
            nunits += 1
    # Re-NUMBER: keeps every class, so it is tried before anything is consumed. The class
    # that takes u must not be in SU, the conflicts of this candidate colour not yet
    # retired: their proofs assumed the classes as they were, and u (unlike v, which is
    # not adjacent to the candidates of its colour) could complete a clique there
    for qi in range(nunits):
        k = queue[qi]
        u = uvert[qi]
        for l in range(need):
            if l == k or not active[l] or (SU[l >> 6] >> np.uint64(l & 63)) & _ONE:
                continue
            ok = True
            for w in range(W):
                if CL[l, w] & B[u, w]:
                    ok = False
                    break
            if ok:
                _clearbit(CL[k], u)
                _setbit(CL[k], v)
                _setbit(CL[l], u)
                col[v] = k
                col[u] = l
                return 1
    for w in range(W):
        T[w] = B[v, w] & P[w]
    qh = 0
    conflict = -1
    while qh < nunits and conflict < 0:
        # invariant: T = P ∩ N(v) ∩ N(every fired unit); left[l] = |CL[l] ∩ T| for the
        # live classes; RS[l] = the fired classes whose units shrank class l (closed
        # under their own reasons)
        k = queue[qh]
        u = uvert[qh]
        if u < 0:
            for w in range(W):
                x = CL[k, w] & T[w]
                if x != _ZERO:
                    u = w * 64 + int(_cttz(x))
                    break
        qh += 1
        fired[k] = True
        _setbit(RS[k], k)
        for w in range(W):
            t = T[w]
            D[w] = t & ~B[u, w]
            T[w] = t & B[u, w]
        for w in range(W):
            x = D[w]
            while x:
                b = _cttz(x)
                x &= x - _ONE
                l = col[w * 64 + int(b)]
                if l < 0 or not active[l] or fired[l]:
                    continue
                left[l] -= 1
                for w2 in range(WC):
                    RS[l, w2] |= RS[k, w2]
                if left[l] == 0:
                    conflict = l
                    break
                if left[l] == 1 and not queued[l]:
                    queued[l] = True
                    queue[nunits] = l
                    uvert[nunits] = -1
                    nunits += 1
            if conflict >= 0:
                break
    if conflict < 0:
        return 0
    for w in range(WC):
        SX[w] = RS[conflict, w]
    _setbit(SX, conflict)
    return 2


@numba.njit(cache=True)
def absorb(B, W, need, CL, P, ord_v, ord_c, base, cnt, S):
    """Drop from the branching list the vertices the MaxSAT-style reasoning absorbs.

    ``CL[:need]`` are the first ``need`` colour classes of the candidate set ``P``,
    ``ord_*[base:base + cnt]`` the branching candidates (colour > need) in non-decreasing
    colour. Candidates are taken a colour class at a time; each is tried by
    :func:`try_vertex`. The classes consumed by the failed-literal conflicts of one
    candidate class are retired together (a clause and the conflicts of each of its
    literals form one inconsistent subset, so they may overlap), and later candidates
    work with the classes left. Invariant: the retired subsets and the active classes,
    with the absorbed vertices, hold no clique larger than ``need``; so branching on the
    survivors alone is exact. Returns how many survive.
    """
    RS, SX, SU, T, D, col, left, active, queued, fired, queue, uvert = S
    WC = (need + 63) >> 6
    for k in range(need):
        active[k] = True
    out = 0
    i = 0
    while i < cnt:
        c = ord_c[base + i]
        j = i
        while j < cnt and ord_c[base + j] == c:
            j += 1
        for w in range(WC):
            SU[w] = _ZERO
        for t in range(i, j):
            v = ord_v[base + t]
            r = try_vertex(v, B, W, need, CL, P, S)
            if r == 0:
                ord_v[base + out] = v
                ord_c[base + out] = c
                out += 1
            elif r == 2:
                for w in range(WC):
                    SU[w] |= SX[w]
        for w in range(WC):
            x = SU[w]
            while x:
                b = _cttz(x)
                x &= x - _ONE
                active[w * 64 + int(b)] = False
        i = j
    return out


@numba.njit(cache=True)
def _scratch(n, W):
    return (
        np.empty((n + 1, W), np.uint64),  # RS: reasons, a bitset of classes per class
        np.empty(W, np.uint64),  # SX: the classes of one conflict
        np.empty(W, np.uint64),  # SU: the classes consumed by one candidate class
        np.empty(W, np.uint64),  # T: vertices still compatible with the true ones
        np.empty(W, np.uint64),  # D: vertices a new unit removes from T
        np.full(n + 1, -1, np.int64),  # col: class index of each vertex, -1 if none
        np.empty(n + 1, np.int64),  # left: |class ∩ T|
        np.empty(n + 1, np.bool_),  # active
        np.empty(n + 1, np.bool_),  # queued
        np.empty(n + 1, np.bool_),  # fired
        np.empty(n + 1, np.int64),  # queue of unit classes
        np.empty(n + 1, np.int64),  # their vertices (-1: not known yet)
    )


# --------------------------------------------------------------------------------------
# Branch and bound
# --------------------------------------------------------------------------------------
@numba.njit(cache=True)
def bb_search(B, n, P0, init, floor, mode, limit, time_limit, t0, mask, maxsat, node_limit):
    """Branch and bound for cliques larger than ``floor`` (mode 0) or of size ``floor + 1``.

    Parameters
    ----------
    B : (n, W) uint64, renumbered adjacency (bit order = colouring order).
    P0 : (W,) uint64, root candidate set.
    init : int64 array, an initial clique (the incumbent) in the new numbering.
    floor : cliques of size ``<= floor`` are of no interest.
    mode : 0 = maximum clique (the bar rises with each improvement); 1 = enumerate every
        clique of size ``floor + 1`` (the bar stays), at most ``limit`` of them.
    maxsat : filter branching vertices with :func:`absorb`.
    node_limit : stop (status 2) after this many nodes.

    Returns ``(best, nodes, status, found)``; status 0 = finished, 1 = out of time,
    2 = node limit reached, 3 = more than ``limit`` cliques.
    """
    W = B.shape[1]
    bar = floor
    if mode == 0 and init.shape[0] > bar:
        bar = init.shape[0]
    best = _head(init, init.shape[0])
    target = floor + 1
    found = np.empty((min(limit, 64) if mode == 1 else 0, target), np.int64)
    nfound = 0
    status = 0

    maxd = n + 2
    Pst = np.empty((maxd, W), np.uint64)
    pos = np.empty(maxd, np.int64)
    base = np.empty(maxd, np.int64)
    cnt = np.empty(maxd, np.int64)
    C = np.empty(maxd, np.int64)
    U = np.empty(W, np.uint64)
    Q = np.empty(W, np.uint64)
    CL = np.empty((n + 1, W), np.uint64)
    S = _scratch(n, W)
    cap = 4 * n + 64
    ord_v = np.empty(cap, np.int64)
    ord_c = np.empty(cap, np.int64)

    nodes = 1
    Pst[0, :] = P0
    base[0] = 0
    need = _popcount(P0, W)
    if need > cap:
        cap = 2 * need
        ord_v = np.empty(cap, np.int64)
        ord_c = np.empty(cap, np.int64)
    col = S[5]
    c = colour_classes(Pst[0], B, W, bar + 1, U, Q, CL, ord_v, ord_c, 0, col)
    if maxsat and c > 0 and bar > 0:
        c = absorb(B, W, bar, CL, Pst[0], ord_v, ord_c, 0, c, S)
    cnt[0] = c
    pos[0] = c - 1
    depth = 0
    while depth >= 0:
        # invariant: C[:depth] is a clique and Pst[depth] its common neighbours not yet
        # branched on; ord_*[base + 0 .. base + pos] are the branching candidates left,
        # and every clique in Pst[depth] avoiding them has at most bar - depth vertices
        p = pos[depth]
        if p < 0:
            depth -= 1
            continue
        b0 = base[depth]
        v = ord_v[b0 + p]
        if depth + ord_c[b0 + p] <= bar:
            pos[depth] = -1
            continue
        pos[depth] = p - 1
        size = 0
        for w in range(W):
            x = Pst[depth, w] & B[v, w]
            Pst[depth + 1, w] = x
            size += int(_ctpop(x))
        _clearbit(Pst[depth], v)
        C[depth] = v
        if size == 0:
            size = depth + 1
            if mode == 0:
                if size > bar:
                    bar = size
                    best = _head(C, size)
            elif size == target:
                if nfound < limit:
                    if nfound == found.shape[0]:
                        grown = np.empty((min(limit, 2 * nfound), target), np.int64)
                        for r in range(nfound):
                            for i in range(target):
                                grown[r, i] = found[r, i]
                        found = grown
                    for i in range(size):
                        found[nfound, i] = C[i]
                    nfound += 1
                else:
                    status = 3
                    break
            continue
        kneed = bar - depth - 1
        if size <= kneed:
            continue
        nodes += 1
        if nodes > node_limit:
            status = 2
            break
        if (nodes & mask) == 0:
            if _now() - t0 > time_limit:
                status = 1
                break
        nb = b0 + cnt[depth]
        if nb + size > cap:
            cap = 2 * (nb + size)
            ord_v = _grow(ord_v, nb, cap)
            ord_c = _grow(ord_c, nb, cap)
        c = colour_classes(Pst[depth + 1], B, W, kneed + 1, U, Q, CL, ord_v, ord_c, nb, col)
        if maxsat and c > 0 and kneed > 0:
            c = absorb(B, W, kneed, CL, Pst[depth + 1], ord_v, ord_c, nb, c, S)
        if c == 0:
            continue
        depth += 1
        base[depth] = nb
        cnt[depth] = c
        pos[depth] = c - 1
    out = np.empty((nfound, target), np.int64)
    for r in range(nfound):
        for i in range(target):
            out[r, i] = found[r, i]
    return best, nodes, status, out


@numba.njit(cache=True)
def solve(A, n, floor, mode, limit, time_limit, t0, opts):
    """Whole pipeline on bitset rows: order, renumber, initial clique, prune, search.

    Modes: 0 = a maximum clique (cliques larger than ``floor``); 1 = every clique of size
    ``floor + 1``, at most ``limit``; 2 = mode 0, then, if it finished, mode 1 with
    ``floor = omega - 1`` (every maximum clique), sharing the order and renumbering.

    In mode 0 the search first runs with a small node budget and the plain colouring
    bound: easy graphs end there. If it does not, tabu local search improves the
    incumbent and the search starts again with the higher bar and the MaxSAT-style
    filter (hard graphs repay the few milliseconds many times over).

    Returns ``(clique, nodes, status, found, status_all)`` in the caller's labels: status
    of the maximum clique search and of the enumeration (-1 when not run), as in
    :func:`bb_search`.
    """
    W = A.shape[1]
    order, core = degeneracy_order(A, n)
    B = relabel(A, n, order)
    U = np.empty(W, np.uint64)
    maxsat = (opts & OPT_MAXSAT) != 0
    mask = check_mask(n, W)
    nodes = 0
    status = 0
    best = np.empty(0, np.int64)
    if mode != 1:
        best, nodes, status = _maximum(
            B, n, order, core, floor, time_limit, t0, opts, maxsat, mask, U
        )
    status_all = -1
    found = np.empty((0, floor + 1), np.int64)
    if mode == 1 or (mode == 2 and status == 0 and best.shape[0] > 0):
        if mode == 2:
            floor = best.shape[0] - 1
        # k-core pruning: a clique of size floor + 1 lies inside the floor-core
        P0 = np.zeros(W, np.uint64)
        for i in range(n):
            if core[order[i]] >= floor:
                _setbit(P0, i)
        _, used, status_all, found = bb_search(
            B,
            n,
            P0,
            np.empty(0, np.int64),
            floor,
            1,
            limit,
            time_limit,
            t0,
            mask,
            maxsat,
            1 << 62,
        )
        nodes += used
    found_o = np.empty((found.shape[0], found.shape[1]), np.int64)
    for r in range(found.shape[0]):
        row = _mapped_sorted(found[r], found.shape[1], order)
        for i in range(found.shape[1]):
            found_o[r, i] = row[i]
    return _mapped_sorted(best, best.shape[0], order), nodes, status, found_o, status_all


# --------------------------------------------------------------------------------------
# Small and sparse graphs: greedy clique, k-core peel, one-word search
# --------------------------------------------------------------------------------------
@numba.njit(cache=True)
def _sorted_into(a, k, out):
    """``out[:k] = sorted(a[:k])`` (insertion sort, cliques are short)."""
    for i in range(k):
        x = a[i]
        j = i
        while j > 0 and out[j - 1] > x:
            out[j] = out[j - 1]
            j -= 1
        out[j] = x


@numba.njit(cache=True)
def _sort_by_degree(items, m, deg, dmax, out):
    """``out[:m]`` = ``items[:m]`` in non-increasing ``deg`` (ties in the given order):
    a counting sort, O(m + dmax)."""
    start = np.zeros(dmax + 2, np.int64)
    for i in range(m):
        start[dmax - deg[items[i]] + 1] += 1
    for e in range(dmax + 1):
        start[e + 1] += start[e]
    for i in range(m):
        v = items[i]
        e = dmax - deg[v]
        out[start[e]] = v
        start[e] += 1


@numba.njit(cache=True)
def _greedy_raw(A, deg, order, starts, best, cur, P):
    """Best of the greedy cliques grown from ``order[:starts]`` (highest degree first).

    From ``s``: candidates ``N(s)``; repeatedly add the candidate of highest degree and
    intersect, until no candidate is left or the clique cannot beat the best one. A
    clique through ``s`` has at most ``deg[s] + 1`` vertices, so the starts end once
    that cannot beat the best. Writes the clique to ``best``, returns its size (``cur``:
    scratch for a clique, ``P``: for a set).
    """
    W = A.shape[1]
    bsize = 0
    for t in range(starts):
        s = order[t]
        if deg[s] + 1 <= bsize:
            break
        for w in range(W):
            P[w] = A[s, w]
        cur[0] = s
        size = 1
        while True:
            # invariant: cur[:size] is a clique, P its common neighbourhood
            left = 0
            for w in range(W):
                left += int(_ctpop(P[w]))
            if size + left <= bsize:
                break  # cannot beat the best
            u = -1
            du = -1
            for w in range(W):
                x = P[w]
                while x:
                    b = _cttz(x)
                    x &= x - _ONE
                    j = w * 64 + int(b)
                    if deg[j] > du:
                        du = deg[j]
                        u = j
            if u < 0:
                break
            cur[size] = u
            size += 1
            for w in range(W):
                P[w] &= A[u, w]
        if size > bsize:
            bsize = size
            for i in range(size):
                best[i] = cur[i]
    return bsize


@numba.njit(cache=True)
def _peel(A, n, deg, k, alive, stack):
    """The ``k``-core: ``alive`` (all ``n`` bits set on entry) keeps the vertices with at
    least ``k`` neighbours among the kept ones; ``deg`` becomes their degree there.
    Returns how many. A clique of ``k + 1`` vertices lies in the ``k``-core. ``stack``:
    scratch for ``n`` vertices."""
    W = A.shape[1]
    top = 0
    for v in range(n):
        if deg[v] < k:
            _clearbit(alive, v)
            stack[top] = v
            top += 1
    left = n - top
    while top > 0:
        # invariant: the stacked vertices are out of `alive` but still counted in the
        # degrees of their kept neighbours
        top -= 1
        v = stack[top]
        for w in range(W):
            x = A[v, w] & alive[w]
            while x:
                b = _cttz(x)
                x &= x - _ONE
                u = w * 64 + int(b)
                deg[u] -= 1
                if deg[u] < k:
                    _clearbit(alive, u)
                    stack[top] = u
                    top += 1
                    left -= 1
    return left


@numba.njit(cache=True)
def _word_rows(A, verts, m, alive, pos, S):
    """``S[:m]``: one-word adjacency rows of the subgraph induced by ``verts[:m]``
    (``m <= 64``, ``alive`` their bitset), renumbered so that new vertex ``i`` is
    ``verts[i]`` (``pos``: scratch for the inverse, one entry per vertex of ``A``)."""
    W = A.shape[1]
    for i in range(m):
        pos[verts[i]] = i
    for i in range(m):
        v = verts[i]
        r = _ZERO
        for w in range(W):
            x = A[v, w] & alive[w]
            while x:
                b = _cttz(x)
                x &= x - _ONE
                r |= _ONE << np.uint64(pos[w * 64 + int(b)])
        S[i] = r
    return S


@numba.njit(cache=True)
def _colour_word(S, P, kmin, ord_v, ord_c, base):
    """:func:`colour_classes` for a one-word candidate set, without the class bitsets:
    the vertices of colour ``>= kmin`` go to ``ord_*[base:]``. Returns how many."""
    U = P
    k = 0
    cnt = 0
    while U != _ZERO:
        # invariant: U = vertices of P not yet coloured
        k += 1
        Q = U
        while Q != _ZERO:
            # invariant: Q = uncoloured vertices not adjacent to any vertex of class k
            b = _cttz(Q)
            one = _ONE << b
            U &= ~one
            Q &= ~(one | S[b])
            if k >= kmin:
                ord_v[base + cnt] = int(b)
                ord_c[base + cnt] = k
                cnt += 1
    return cnt


@numba.njit(cache=True)
def _bb_word(S, m, bar, deadline, best, node_limit, Pst):
    """:func:`bb_search` in mode 0 on at most 64 vertices (one-word sets, plain colouring
    bound, no MaxSAT filter): a clique larger than ``bar`` in ``S`` (all ``m`` vertices
    are candidates), written to ``best``. Returns ``(size, nodes, status)``, size 0 when
    there is none; status 0 = finished, 1 = out of time (``deadline`` passed), 2 = more
    than ``node_limit`` nodes needed. ``Pst``: scratch for ``m + 1`` words.

    The rest of the stack lives in one small array (int16: every entry is below
    ``64 * 65``): the branching lists of the nodes on the current path take at most
    ``m + (m - 1) + ... + 1`` entries (a child's candidates are its parent's minus at
    least the branching vertex), so nothing grows during the search.
    """
    mask = check_mask(m, 1)
    D = m + 1
    cap = D * m // 2
    st = np.empty(4 * D + 2 * cap, np.int16)
    pos = st[:D]
    base = st[D : 2 * D]
    cnt = st[2 * D : 3 * D]
    C = st[3 * D : 4 * D]
    ord_v = st[4 * D : 4 * D + cap]
    ord_c = st[4 * D + cap :]
    P0 = ~_ZERO >> np.uint64(64 - m)
    nodes = 1
    bsize = 0
    status = 0
    c = _colour_word(S, P0, bar + 1, ord_v, ord_c, 0)
    if c == 0:
        return 0, nodes, 0
    Pst[0] = P0
    base[0] = 0
    cnt[0] = c
    pos[0] = c - 1
    depth = 0
    while depth >= 0:
        # invariant: C[:depth] is a clique and Pst[depth] its common neighbours not yet
        # branched on; ord_*[base + 0 .. base + pos] are the branching candidates left,
        # and every clique in Pst[depth] avoiding them has at most bar - depth vertices
        p = int(pos[depth])
        b0 = int(base[depth])
        if p < 0 or depth + int(ord_c[b0 + p]) <= bar:
            depth -= 1
            continue
        pos[depth] = p - 1
        v = int(ord_v[b0 + p])
        x = Pst[depth] & S[v]
        Pst[depth] &= ~(_ONE << np.uint64(v))
        C[depth] = v
        if x == _ZERO:
            if depth + 1 > bar:
                bar = depth + 1
                bsize = bar
                for i in range(bsize):
                    best[i] = C[i]
            continue
        kneed = bar - depth - 1
        size = int(_ctpop(x))
        if size <= kneed:
            continue
        nodes += 1
        if nodes > node_limit:
            status = 2
            break
        if (nodes & mask) == 0 and _now() > deadline:
            status = 1
            break
        nb = b0 + int(cnt[depth])
        c = _colour_word(S, x, kneed + 1, ord_v, ord_c, nb)
        if c == 0:
            continue
        depth += 1
        Pst[depth] = x
        base[depth] = nb
        cnt[depth] = c
        pos[depth] = c - 1
    return bsize, nodes, status


@numba.njit(cache=True)
def _bb_words(B, P0, m, depth_max, bar, deadline, best, node_limit):
    """:func:`_bb_word` on multi-word sets: ``B`` the rows, ``P0`` the ``m`` candidates,
    and no clique among them has more than ``depth_max`` vertices. Status 2 when more
    than ``node_limit`` nodes would be needed."""
    W = B.shape[1]
    mask = check_mask(B.shape[0], W)
    cap = 4 * m + 64
    ord_v = np.empty(cap, np.int64)
    ord_c = np.empty(cap, np.int64)
    D = depth_max + 1
    Pst = np.empty((D, W), np.uint64)
    pos = np.empty(D, np.int64)
    base = np.empty(D, np.int64)
    cnt = np.empty(D, np.int64)
    C = np.empty(D, np.int64)
    U = np.empty(W, np.uint64)
    Q = np.empty(W, np.uint64)
    # colour_classes' class bitsets and colours, written but not read here (no MaxSAT
    # filter follows); classes below the bar number fewer than max(bar, depth_max)
    CL = np.empty((max(bar, depth_max) + 1, W), np.uint64)
    col = np.empty(B.shape[0], np.int64)
    for w in range(W):
        Pst[0, w] = P0[w]
    nodes = 1
    bsize = 0
    status = 0
    c = colour_classes(Pst[0], B, W, bar + 1, U, Q, CL, ord_v, ord_c, 0, col)
    if c == 0:
        return 0, nodes, 0
    base[0] = 0
    cnt[0] = c
    pos[0] = c - 1
    depth = 0
    while depth >= 0:
        # invariant: as in _bb_word
        p = pos[depth]
        b0 = base[depth]
        if p < 0 or depth + ord_c[b0 + p] <= bar:
            depth -= 1
            continue
        pos[depth] = p - 1
        v = ord_v[b0 + p]
        size = 0
        for w in range(W):
            x = Pst[depth, w] & B[v, w]
            Pst[depth + 1, w] = x
            size += int(_ctpop(x))
        _clearbit(Pst[depth], v)
        C[depth] = v
        if size == 0:
            if depth + 1 > bar:
                bar = depth + 1
                bsize = bar
                for i in range(bsize):
                    best[i] = C[i]
            continue
        kneed = bar - depth - 1
        if size <= kneed:
            continue
        nodes += 1
        if nodes > node_limit:
            status = 2
            break
        if (nodes & mask) == 0 and _now() > deadline:
            status = 1
            break
        nb = b0 + cnt[depth]
        if nb + size > cap:
            cap = 2 * (nb + size)
            ord_v = _grow(ord_v, nb, cap)
            ord_c = _grow(ord_c, nb, cap)
        c = colour_classes(Pst[depth + 1], B, W, kneed + 1, U, Q, CL, ord_v, ord_c, nb, col)
        if c == 0:
            continue
        depth += 1
        base[depth] = nb
        cnt[depth] = c
        pos[depth] = c - 1
    return bsize, nodes, status


@numba.njit(cache=True)
def _induced_rows(A, verts, m, alive):
    """Multi-word rows of the subgraph induced by ``verts[:m]`` (``alive`` their
    bitset), renumbered so that new vertex ``i`` is ``verts[i]``."""
    W = A.shape[1]
    pos = np.empty(A.shape[0], np.int64)
    for i in range(m):
        pos[verts[i]] = i
    B = np.zeros((m, (m + 63) >> 6), np.uint64)
    for i in range(m):
        v = verts[i]
        for w in range(W):
            x = A[v, w] & alive[w]
            while x:
                b = _cttz(x)
                x &= x - _ONE
                _setbit(B[i], pos[w * 64 + int(b)])
    return B


@numba.njit(cache=True)
def maximum_word(A, n, floor, deadline, out, dense_limit):
    """Mode 0 of :func:`solve` for at most 64 vertices: :func:`_bb_word` on the graph as
    it is (labels as given, no initial clique: on the pipeline's graphs the search finds
    one as fast as a greedy would). A graph of density above 1/4 gets at most
    ``dense_limit`` nodes, then the full search of :func:`solve`. When no clique is larger
    than ``floor``, a greedy clique is returned. Returns ``(size, nodes, status)`` with
    the clique in ``out[:size]``, sorted."""
    SP = np.empty(2 * n + 1, np.uint64)
    S = SP[:n]
    found = np.empty(n, np.int64)
    d2 = 0
    for v in range(n):
        S[v] = A[v, 0]
        d2 += int(_ctpop(S[v]))
    limit = 1 << 62 if 4 * d2 <= n * n else dense_limit
    size, nodes, status = _bb_word(S, n, floor, deadline, found, limit, SP[n:])
    if status == 2:
        best, used, status = _full_maximum(A, n, floor, deadline)
        nodes += used
        size = best.shape[0]
        for i in range(size):
            found[i] = best[i]
    if size == 0:  # from the vertex of highest degree
        deg = np.empty(n, np.int64)
        top = np.zeros(1, np.int64)
        for v in range(n):
            deg[v] = int(_ctpop(S[v]))
            if deg[v] > deg[top[0]]:
                top[0] = v
        greedy = np.empty(n + 1, np.int64)
        size = _greedy_raw(A, deg, top, 1, greedy, found, SP[n:])
        _sorted_into(greedy, size, out)
    else:
        _sorted_into(found, size, out)
    return size, nodes, status


@numba.njit(cache=True)
def maximum_peeled(A, n, floor, deadline, out, starts, node_limit, dense_limit):
    """Mode 0 of :func:`solve` with elimination first, for the small sparse graphs of the
    pipeline (the full search's set-up costs more than their search).

    1. a greedy clique of size ``k`` (:func:`_greedy_raw`); the bar is ``max(floor, k)``;
    2. the ``bar``-core (:func:`_peel`): any larger clique lies in it. Empty: done;
    3. a core smaller than the graph is renumbered by non-increasing degree in the core
       (the colouring order; the whole graph keeps its labels), then searched with the
       plain colouring bound: in one-word sets (:func:`_bb_word`) when it has at most 64
       vertices (at most ``dense_limit`` nodes if its density is above 1/4); else, if its
       density is at most 1/4, in multi-word sets (:func:`_bb_words`) for at most
       ``node_limit`` nodes;
    4. a dense core, or one that needs more nodes: the full search of :func:`solve`
       (degeneracy order, local search, MaxSAT-style filter) on the core, with ``bar`` as
       the floor; on the whole graph with ``floor`` when nothing was peeled, exactly as
       :func:`solve` would.

    Returns ``(size, nodes, status)`` with the clique in ``out[:size]`` (sorted, the
    caller's labels), as :func:`solve_dense`; ``nodes`` counts the search nodes of steps 3
    and 4 (1 when step 2 ends the search).
    """
    W = A.shape[1]
    # scratch, in two allocations: per vertex a degree, a clique entry or two, a stack
    # entry, an inverse index; words for two sets and for the rows of a core
    iw = np.empty(5 * n + starts + 1, np.int64)
    deg = iw[:n]
    greedy = iw[n : 2 * n + 1]
    cur = iw[2 * n + 1 : 3 * n + 1]  # also the peeling stack, then the inverse index
    found = iw[3 * n + 1 : 4 * n + 1]
    verts = iw[4 * n + 1 : 5 * n + 1]  # found vertex i is verts[i] (or i where `same`)
    top = iw[5 * n + 1 :]  # the vertices of highest degree, highest first
    uw = np.empty(2 * W + 129, np.uint64)
    alive = uw[:W]
    P = uw[W : 2 * W]
    S = uw[2 * W : 2 * W + 64]
    Pst = uw[2 * W + 64 :]
    ntop = 0
    for v in range(n):
        d = int(_ctpop(A[v, 0]))
        for w in range(1, W):
            d += int(_ctpop(A[v, w]))
        deg[v] = d
        if ntop < starts or d > deg[top[ntop - 1]]:
            i = min(ntop, starts - 1)
            while i > 0 and deg[top[i - 1]] < d:
                top[i] = top[i - 1]
                i -= 1
            top[i] = v
            ntop = min(ntop + 1, starts)
    k = _greedy_raw(A, deg, top, ntop, greedy, cur, P)
    bar = max(floor, k)
    for w in range(W):
        alive[w] = ~_ZERO
    if n & 63:
        alive[W - 1] = (_ONE << np.uint64(n & 63)) - _ONE
    m = _peel(A, n, deg, bar, alive, cur)
    if m == 0:
        _sorted_into(greedy, k, out)
        return k, 1, 0
    d2 = 0  # twice the edges of the core
    dcore = 0  # its largest degree
    i = 0
    for w in range(W):
        x = alive[w]
        while x:
            b = _cttz(x)
            x &= x - _ONE
            v = w * 64 + int(b)
            out[i] = v  # the core, in label order
            i += 1
            d2 += deg[v]
            dcore = max(dcore, deg[v])
    sparse = 4 * d2 <= m * m
    same = False
    nodes = 0
    status = 2
    if m <= 64:
        _sort_by_degree(out, m, deg, dcore, verts)
        _word_rows(A, verts, m, alive, cur, S)
        limit = 1 << 62 if sparse else dense_limit
        size, nodes, status = _bb_word(S, m, bar, deadline, found, limit, Pst)
    else:
        same = True
        if sparse:
            size, nodes, status = _bb_words(
                A, alive, m, dcore + 1, bar, deadline, found, node_limit
            )
    if status == 2:  # step 4
        if m == n:
            best, used, status = _full_maximum(A, n, floor, deadline)
            same = True
        else:
            for i in range(m):
                verts[i] = out[i]
            B = _induced_rows(A, verts, m, alive)
            best, used, status = _full_maximum(B, m, bar, deadline)
            same = False
        nodes += used
        size = best.shape[0]
        for i in range(size):
            found[i] = best[i]
    if size < k:  # (a search that finds nothing larger than bar returns 0)
        size = k
        _sorted_into(greedy, k, out)
    elif same:
        _sorted_into(found, size, out)
    else:
        _map_sorted_into(found, size, verts, out)
    return size, nodes, status


@numba.njit(cache=True)
def _full_maximum(A, n, floor, deadline):
    """:func:`solve` in mode 0 with the default options: ``(clique, nodes, status)``, the
    clique in ``A``'s labels (not sorted)."""
    W = A.shape[1]
    order, core = degeneracy_order(A, n)
    B = relabel(A, n, order)
    U = np.empty(W, np.uint64)
    maxsat = (OPT_DEFAULT & OPT_MAXSAT) != 0
    best, nodes, status = _maximum(
        B, n, order, core, floor, deadline, 0.0, OPT_DEFAULT, maxsat, check_mask(n, W), U
    )
    for i in range(best.shape[0]):
        best[i] = order[best[i]]
    return best, nodes, status


@numba.njit(cache=True)
def solve_bits(A, n, floor, deadline, out):
    """A maximum clique of the graph with bitset rows ``A`` (``n >= 1`` vertices), the
    path of ``max_clique`` without weights: :func:`maximum_word` for at most 64 vertices,
    else :func:`maximum_peeled`. Cliques of at most ``floor`` vertices are of no interest;
    ``deadline`` is a ``time.perf_counter()`` reading (``inf``: none). Returns ``(size,
    nodes, status)`` with the clique in ``out[:size]``, sorted; status 0 = finished, 1 =
    out of time."""
    if n <= 64:
        return maximum_word(A, n, floor, deadline, out, DENSE_WORD_NODES)
    return maximum_peeled(A, n, floor, deadline, out, SPARSE_STARTS, SPARSE_NODES, DENSE_WORD_NODES)


@numba.njit(cache=True)
def solve_dense(adj, floor, deadline, out):
    """:func:`pack_checked` then :func:`solve_bits`, in one call: the lean path of
    ``max_clique`` for boolean matrices. Few arguments and no array crosses back into
    Python (the clique is written to ``out[:size]``): on the pipeline's graphs the fixed
    costs are a good part of the call. Returns ``(size, nodes, status, u, v)``;
    ``status`` is -1 and ``(u, v)`` the defect when the matrix is not a valid
    adjacency."""
    n = adj.shape[0]
    A, u, v = pack_checked(adj)
    if u >= 0:
        return 0, 0, -1, u, v
    size, nodes, status = solve_bits(A, n, floor, deadline, out)
    return size, nodes, status, -1, -1


@numba.njit(cache=True)
def _maximum(B, n, order, core, floor, time_limit, t0, opts, maxsat, mask, U):
    """Mode 0 of :func:`solve`: ``(clique, nodes, status)`` in the renumbered labels."""
    core_new = np.empty(n, np.int64)  # core numbers in the degeneracy numbering
    kmax = 0
    for i in range(n):
        core_new[i] = core[order[i]]
        kmax = max(kmax, core[i])
    init = greedy_clique(B, n, U, t0, time_limit, core_new)
    if init.shape[0] > kmax and init.shape[0] > floor:
        # a clique of size k + 1 needs a k-core: the degeneracy bound is met already
        return init, 1, 0
    W = B.shape[1]
    nodes = 0
    budget = 1 << 62
    reason = maxsat
    if (opts & OPT_LOCAL_SEARCH) != 0:
        # a first, cheap try: plain colouring bound, a thousand nodes
        budget = 1000
        reason = False
    while True:
        bar = max(floor, init.shape[0])
        # k-core pruning: a clique of size bar + 1 lies inside the bar-core
        P0 = np.zeros(W, np.uint64)
        for i in range(n):
            if core[order[i]] >= bar:
                _setbit(P0, i)
        best, used, status, _ = bb_search(
            B, n, P0, init, floor, 0, 0, time_limit, t0, mask, reason, budget
        )
        nodes += used
        if status != 2:
            return best, nodes, status
        iters = min(20 * n, 20_000_000 // (n + 1))
        init = local_search(B, n, best, iters, max(500, 2 * n), t0, time_limit, 12345)
        budget = 1 << 62
        reason = maxsat


# --------------------------------------------------------------------------------------
# Maximum-weight clique
# --------------------------------------------------------------------------------------
@numba.njit(cache=True)
def colour_weighted(P, B, W, wt, need, U, Q, ord_v, ord_b, base):
    """Weighted colouring bound (Kumlander 2004): classes built as in BBMC; the bound of
    the ``i``-th vertex is the heaviest vertex of each earlier class plus the heaviest of
    its own class up to ``i``. Only entries with a bound above ``need`` are written."""
    w0 = W
    for w in range(W):
        U[w] = P[w]
        if P[w] != _ZERO and w < w0:
            w0 = w
    acc = 0.0
    cnt = 0
    while True:
        while w0 < W and U[w0] == _ZERO:
            w0 += 1
        if w0 == W:
            break
        for w in range(w0, W):
            Q[w] = U[w]
        wq = w0
        cmax = 0.0
        while True:
            while wq < W and Q[wq] == _ZERO:
                wq += 1
            if wq == W:
                break
            b = _cttz(Q[wq])
            v = wq * 64 + int(b)
            one = _ONE << b
            Q[wq] &= ~one
            U[wq] &= ~one
            for w in range(wq, W):
                Q[w] &= ~B[v, w]
            if wt[v] > cmax:
                cmax = wt[v]
            if acc + cmax > need:
                ord_v[base + cnt] = v
                ord_b[base + cnt] = acc + cmax
                cnt += 1
        acc += cmax
    return cnt


@numba.njit(cache=True)
def solve_weighted(A, n, weights, time_limit, t0):
    """Maximum-weight clique by branch and bound with the weighted colouring bound.

    Returns ``(clique, weight, nodes, timed_out)`` in the caller's labels.
    """
    W = A.shape[1]
    order, core = degeneracy_order(A, n)
    B = relabel(A, n, order)
    wt = np.empty(n)
    for i in range(n):
        wt[i] = weights[order[i]]
    # initial clique: from each of the first 128 vertices (densest core), add the
    # heaviest candidate until none is left
    U = np.empty(W, np.uint64)
    Q = np.empty(W, np.uint64)
    best = np.empty(0, np.int64)
    best_w = -1.0
    cur = np.empty(n, np.int64)
    for s in range(min(n, 128)):
        if (s & 15) == 15 and _now() - t0 > time_limit:
            break
        for w in range(W):
            U[w] = B[s, w]
        cur[0] = s
        size = 1
        tot = wt[s]
        while True:
            u = -1
            bw = -1.0
            for w in range(W):
                x = U[w]
                while x:
                    b = _cttz(x)
                    x &= x - _ONE
                    j = w * 64 + int(b)
                    if wt[j] > bw:
                        bw = wt[j]
                        u = j
            if u < 0:
                break
            cur[size] = u
            size += 1
            tot += wt[u]
            for w in range(W):
                U[w] &= B[u, w]
        if tot > best_w:
            best_w = tot
            best = _head(cur, size)

    maxd = n + 2
    Pst = np.empty((maxd, W), np.uint64)
    pos = np.empty(maxd, np.int64)
    base = np.empty(maxd, np.int64)
    cnt = np.empty(maxd, np.int64)
    C = np.empty(maxd, np.int64)
    Cw = np.zeros(maxd)
    cap = 4 * n + 64
    ord_v = np.empty(cap, np.int64)
    ord_b = np.empty(cap)
    mask = check_mask(n, W)
    nodes = 1
    timed_out = False
    Pst[0, :] = _ZERO
    for i in range(n):
        _setbit(Pst[0], i)
    if n > cap:
        cap = 2 * n
        ord_v = np.empty(cap, np.int64)
        ord_b = np.empty(cap)
    base[0] = 0
    c = colour_weighted(Pst[0], B, W, wt, best_w, U, Q, ord_v, ord_b, 0)
    cnt[0] = c
    pos[0] = c - 1
    depth = 0
    while depth >= 0:
        # invariant: C[:depth] is a clique of weight Cw[depth]; the branching candidates
        # left are ord_*[base + 0 .. base + pos], each with a bound on the weight it can add
        p = pos[depth]
        if p < 0:
            depth -= 1
            continue
        b0 = base[depth]
        v = ord_v[b0 + p]
        if Cw[depth] + ord_b[b0 + p] <= best_w:
            pos[depth] = -1
            continue
        pos[depth] = p - 1
        size = 0
        for w in range(W):
            x = Pst[depth, w] & B[v, w]
            Pst[depth + 1, w] = x
            size += int(_ctpop(x))
        _clearbit(Pst[depth], v)
        C[depth] = v
        Cw[depth + 1] = Cw[depth] + wt[v]
        if size == 0:
            if Cw[depth + 1] > best_w:
                best_w = Cw[depth + 1]
                best = _head(C, depth + 1)
            continue
        nodes += 1
        if (nodes & mask) == 0:
            if _now() - t0 > time_limit:
                timed_out = True
                break
        nb = b0 + cnt[depth]
        if nb + size > cap:
            cap = 2 * (nb + size)
            ord_v = _grow(ord_v, nb, cap)
            ord_b = _grow(ord_b, nb, cap)
        c = colour_weighted(
            Pst[depth + 1], B, W, wt, best_w - Cw[depth + 1], U, Q, ord_v, ord_b, nb
        )
        if c == 0:
            continue
        depth += 1
        base[depth] = nb
        cnt[depth] = c
        pos[depth] = c - 1
    return _mapped_sorted(best, best.shape[0], order), best_w, nodes, timed_out


# --------------------------------------------------------------------------------------
# The k largest maximal cliques
# --------------------------------------------------------------------------------------
@numba.njit(cache=True)
def solve_top(A, n, k, time_limit, t0):
    """Bron–Kerbosch with Tomita's pivot, pruned by the colouring bound once ``k``
    maximal cliques are held: a branch whose clique plus colour count cannot exceed the
    smallest one kept is cut. Returns ``(tops, sizes, count, timed_out)``."""
    W = A.shape[1]
    order, core = degeneracy_order(A, n)
    B = relabel(A, n, order)
    tops = np.zeros((k, n), np.int64)
    tsize = np.zeros(k, np.int64)
    count = 0
    maxd = n + 2
    Pst = np.zeros((maxd, W), np.uint64)
    Xst = np.zeros((maxd, W), np.uint64)
    pos = np.empty(maxd, np.int64)
    base = np.empty(maxd, np.int64)
    cnt = np.empty(maxd, np.int64)
    R = np.empty(maxd, np.int64)
    U = np.empty(W, np.uint64)
    Q = np.empty(W, np.uint64)
    cap = 4 * n + 64
    lst = np.empty(cap, np.int64)
    mask = check_mask(n, W)
    nodes = 0
    timed_out = False
    for i in range(n):
        _setbit(Pst[0], i)
    depth = 0
    base[0] = 0
    fresh = True  # the node at `depth` has not been expanded yet
    while depth >= 0:
        if fresh:
            fresh = False
            nodes += 1
            if (nodes & mask) == 0 and _now() - t0 > time_limit:
                timed_out = True
                break
            np_ = _popcount(Pst[depth], W)
            nx_ = _popcount(Xst[depth], W)
            if np_ == 0:
                if nx_ == 0:  # R[:depth] is a maximal clique
                    j = count
                    if count == k:  # replace the smallest kept, if this one is larger
                        j = 0
                        for r in range(1, k):
                            if tsize[r] < tsize[j]:
                                j = r
                        if depth <= tsize[j]:
                            j = -1
                    else:
                        count += 1
                    if j >= 0:
                        for i in range(depth):
                            tops[j, i] = R[i]
                        tsize[j] = depth
                depth -= 1
                continue
            if count == k:
                smallest = n
                for r in range(k):
                    smallest = min(smallest, tsize[r])
                if depth + colour_count(Pst[depth], B, W, U, Q) <= smallest:
                    depth -= 1
                    continue
            # pivot u in P ∪ X maximising |P ∩ N(u)|; branch on P minus N(u)
            bu = -1
            bc = -1
            for src in range(2):
                for w in range(W):
                    x = Pst[depth, w] if src == 0 else Xst[depth, w]
                    while x:
                        b = _cttz(x)
                        x &= x - _ONE
                        u = w * 64 + int(b)
                        c = 0
                        for w2 in range(W):
                            c += int(_ctpop(Pst[depth, w2] & B[u, w2]))
                        if c > bc:
                            bc = c
                            bu = u
            nb = base[depth]
            if nb + np_ > cap:
                cap = 2 * (nb + np_)
                lst = _grow(lst, nb, cap)
            c = 0
            for w in range(W):
                x = Pst[depth, w] & ~B[bu, w]
                while x:
                    b = _cttz(x)
                    x &= x - _ONE
                    lst[nb + c] = w * 64 + int(b)
                    c += 1
            cnt[depth] = c
            pos[depth] = 0
        # invariant: the vertices lst[base + pos[depth] ..] of this node are still to branch
        if pos[depth] >= cnt[depth]:
            depth -= 1
            continue
        v = lst[base[depth] + pos[depth]]
        pos[depth] += 1
        for w in range(W):
            Pst[depth + 1, w] = Pst[depth, w] & B[v, w]
            Xst[depth + 1, w] = Xst[depth, w] & B[v, w]
        _clearbit(Pst[depth], v)
        _setbit(Xst[depth], v)
        R[depth] = v
        base[depth + 1] = base[depth] + cnt[depth]
        depth += 1
        fresh = True
    out = np.zeros((count, n), np.int64)
    for r in range(count):
        row = _mapped_sorted(tops[r], tsize[r], order)
        for i in range(tsize[r]):
            out[r, i] = row[i]
    return out, _head(tsize, count), count, timed_out
