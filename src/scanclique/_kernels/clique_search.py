"""Branch and bound for maximum cliques, the lean paths and the entry points (private;
see :mod:`scanclique.clique`, whose :func:`~scanclique.clique.max_clique` docstring
describes the algorithm and its references).

Inside the full search the graph is renumbered in degeneracy order (``B``), so that bit
order is the order of the greedy colouring (BBMC). Small and sparse graphs first take a
lean path (:func:`maximum_until`): one-word sets up to 64 vertices; above, a greedy clique
and the k-core it implies, whose vertices are often few enough for one word. Local names
follow the papers: ``P`` the candidate set, ``C`` the growing clique, ``bar`` the size to
beat, ``need = bar - |C|`` how many more vertices a child must add to beat it.

Budgets. ``node_limit`` counts search nodes (the work unit that decides results: the same
input gives the same answer on every machine and every run); ``deadline`` is a reading of
the kernel clock (:func:`~scanclique._kernels.bitset.now`, the ``time.perf_counter``
clock) past which a search stops: a guard, reported as ``Status.TIME_LIMIT``. The entry
points (:func:`solve`, :func:`solve_packed`, :func:`solve_dense`) take ``time_limit``
seconds and read the clock when their body starts, after numba has compiled or loaded
them, so compilation never counts against it; the ``*_until`` functions take a deadline,
for compiled callers that share one between several searches.

Statuses are :class:`~scanclique._kernels.codes.Status` values; ``PHASE_BUDGET`` is
internal (a cheap first phase ran out of its node budget and the next phase takes over).
"""

# ruff: noqa: E402 (ensure_cache() runs before numba is imported)
from __future__ import annotations

from . import ensure_cache

ensure_cache()  # before any njit(cache=True) below picks its cache location

import numpy as np

from .bitset import (
    ONE,
    ZERO,
    check_mask,
    child_set,
    ctpop,
    cttz,
    fill,
    grow_pair,
    head,
    map_sorted_into,
    mapped_sorted,
    now,
    pack_checked,
    popcount,
    setbit,
    sorted_into,
    spent,
)
from .codes import ALL_MAXIMUM as _ALL
from .codes import CLIQUE_LIMIT as _CLIQUES
from .codes import ENUMERATE as _ENUMERATE
from .codes import FINISHED as _FINISHED
from .codes import INVALID as _INVALID
from .codes import MAXIMUM as _MAXIMUM
from .codes import NO_LIMIT, Option
from .codes import NODE_LIMIT as _NODES
from .codes import NOT_RUN as _NOT_RUN
from .codes import OPT_LOCAL_SEARCH as _OPT_LOCAL_SEARCH
from .codes import OPT_MAXSAT as _OPT_MAXSAT
from .codes import PHASE_BUDGET as _PHASE
from .colouring import colour_classes, colour_word
from .heuristics import greedy_by_degree, greedy_clique, local_search
from .jit import njit
from .maxsat import absorb, maxsat_scratch
from .ordering import (
    degeneracy_order,
    induced_rows,
    peel_core,
    relabel,
    sort_by_degree,
    word_rows,
)

#: the default option bits of the full search
OPT_DEFAULT = int(Option.DEFAULT)

#: greedy starts of :func:`maximum_peeled`
SPARSE_STARTS = 4
#: node budgets of its searches with the plain colouring bound, past which the full
#: search takes over: multi-word sets (sparse cores), one-word sets of a dense core
SPARSE_NODES = 2000
DENSE_WORD_NODES = 200
#: node budget of the full search's first, cheap try (plain colouring bound), before
#: the local search and the MaxSAT-style filter
FIRST_TRY_NODES = 1000


@njit(cache=True)
def _phase(budget, node_limit, used):
    """The node budget of a phase: its own ``budget``, or what is left of the caller's
    ``node_limit`` after ``used`` nodes when that is smaller. Returns ``(limit,
    binding)``; ``binding`` says that running out of it means running out of the caller's
    limit (``Status.NODE_LIMIT``), not moving on to the next phase."""
    left = node_limit - used
    if left <= budget:
        return left, True
    return budget, False


@njit(cache=True)
def bb_search(B, n, P0, init, floor, mode, limit, deadline, mask, maxsat, node_limit, depth_max):
    """Branch and bound for cliques larger than ``floor`` (mode MAXIMUM) or of size
    ``floor + 1`` (mode ENUMERATE).

    Parameters
    ----------
    B : (n, W) uint64, adjacency rows (in the full search renumbered: bit order =
        colouring order).
    P0 : (W,) uint64, root candidate set.
    init : int64 array, an initial clique (the incumbent), in ``B``'s labels.
    floor : cliques of size ``<= floor`` are of no interest.
    mode : MAXIMUM (the bar rises with each improvement) or ENUMERATE (every clique of
        size ``floor + 1``, the bar stays; at most ``limit`` of them).
    deadline : kernel clock reading (seconds) past which the search stops.
    mask : look at the clock every ``mask + 1`` nodes (:func:`check_mask`).
    maxsat : filter branching vertices with :func:`absorb`.
    node_limit : stop (``PHASE_BUDGET``) when more than this many nodes are needed.
    depth_max : no clique within ``P0`` has more than this many vertices (sizes the
        stacks; ``n + 1`` always does).

    Returns ``(best, nodes, status, found)``: ``best`` the incumbent at the end (``init``
    when nothing larger was found); status ``FINISHED``, ``TIME_LIMIT``, ``PHASE_BUDGET``
    or ``CLIQUE_LIMIT``; ``found`` the enumerated cliques (mode ENUMERATE).
    """
    W = B.shape[1]
    bar = floor
    if mode == _MAXIMUM and init.shape[0] > bar:
        bar = init.shape[0]
    best = head(init, init.shape[0])
    target = floor + 1
    found = np.empty((min(limit, 64) if mode == _ENUMERATE else 0, target), np.int64)
    nfound = 0
    status = _FINISHED

    # few allocations (the pipeline's graphs are searched in microseconds): the stacks
    # as rows of one block, the two scratch sets as rows of another
    maxd = depth_max + 1
    Pst = np.empty((maxd, W), np.uint64)
    stack = np.empty((4, maxd), np.int64)
    pos = stack[0]
    base = stack[1]
    cnt = stack[2]
    C = stack[3]
    UQ = np.empty((2, W), np.uint64)
    U = UQ[0]
    Q = UQ[1]
    # colour classes below the bar (the bar never exceeds depth_max)
    CL = np.empty((max(bar, depth_max) + 1, W), np.uint64)
    S = maxsat_scratch(n, W)
    col = S[5]
    need = popcount(P0, W)
    cap = 4 * need + 64
    ord_v = np.empty(cap, np.int64)
    ord_c = np.empty(cap, np.int64)

    nodes = 1
    for w in range(W):
        Pst[0, w] = P0[w]
    base[0] = 0
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
        b0 = base[depth]
        if p < 0 or depth + ord_c[b0 + p] <= bar:
            depth -= 1
            continue
        pos[depth] = p - 1
        v = ord_v[b0 + p]
        size = child_set(Pst, depth, B, v, W)
        C[depth] = v
        if size == 0:
            size = depth + 1
            if mode == _MAXIMUM:
                if size > bar:
                    bar = size
                    best = head(C, size)
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
                    status = _CLIQUES
                    break
            continue
        kneed = bar - depth - 1
        if size <= kneed:
            continue
        nodes += 1
        status = spent(nodes, node_limit, mask, deadline, _PHASE)
        if status != _FINISHED:
            break
        nb = b0 + cnt[depth]
        if nb + size > cap:
            cap = 2 * (nb + size)
            ord_v, ord_c = grow_pair(ord_v, ord_c, nb, cap)
        c = colour_classes(Pst[depth + 1], B, W, kneed + 1, U, Q, CL, ord_v, ord_c, nb, col)
        if maxsat and c > 0 and kneed > 0:
            c = absorb(B, W, kneed, CL, Pst[depth + 1], ord_v, ord_c, nb, c, S)
        if c == 0:
            continue
        depth += 1
        base[depth] = nb
        cnt[depth] = c
        pos[depth] = c - 1
    if nfound == found.shape[0]:
        return best, nodes, status, found
    out = np.empty((nfound, target), np.int64)
    for r in range(nfound):
        for i in range(target):
            out[r, i] = found[r, i]
    return best, nodes, status, out


@njit(cache=True)
def _bb_word(S, m, bar, deadline, best, node_limit, Pst):
    """:func:`bb_search` in mode 0 on at most 64 vertices (one-word sets, plain colouring
    bound, no MaxSAT filter): a clique larger than ``bar`` in ``S`` (all ``m`` vertices
    are candidates), written to ``best``. Returns ``(size, nodes, status)``, size 0 when
    there is none; status ``FINISHED``, ``TIME_LIMIT`` (``deadline`` passed) or
    ``PHASE_BUDGET`` (more than ``node_limit`` nodes needed). ``Pst``: scratch for ``m + 1`` words.

    The rest of the stack lives in one small array (int16: every entry is below
    ``64 * 65``): the branching lists of the nodes on the current path take at most
    ``m + (m - 1) + ... + 1`` entries (a child's candidates are its parent's minus at
    least the branching vertex), so nothing grows during the search.

    A specialisation of :func:`bb_search` kept on purpose (the same search: the same
    cliques and node counts on every graph tried): sets are single words held in
    registers, colouring is :func:`~.colouring.colour_word`, and nothing is allocated
    per call but one small stack. Running :func:`bb_search` on one-word rows instead
    (plain bound) took 4.07 times as long (geometric mean over the 32 pipeline graphs of
    up to 64 vertices of the clique benchmark's ``--pairs 10`` set, three rounds; 2.6 to
    7.7 times), on graphs that are searched in microseconds.
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
    P0 = ~ZERO >> np.uint64(64 - m)
    nodes = 1
    bsize = 0
    status = _FINISHED
    c = colour_word(S, P0, bar + 1, ord_v, ord_c, 0)
    if c == 0:
        return 0, nodes, _FINISHED
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
        Pst[depth] &= ~(ONE << np.uint64(v))
        C[depth] = v
        if x == ZERO:
            if depth + 1 > bar:
                bar = depth + 1
                bsize = bar
                for i in range(bsize):
                    best[i] = C[i]
            continue
        kneed = bar - depth - 1
        size = int(ctpop(x))
        if size <= kneed:
            continue
        nodes += 1
        status = spent(nodes, node_limit, mask, deadline, _PHASE)
        if status != _FINISHED:
            break
        nb = b0 + int(cnt[depth])
        c = colour_word(S, x, kneed + 1, ord_v, ord_c, nb)
        if c == 0:
            continue
        depth += 1
        Pst[depth] = x
        base[depth] = nb
        cnt[depth] = c
        pos[depth] = c - 1
    return bsize, nodes, status


@njit(cache=True)
def search_until(A, n, floor, mode, limit, deadline, node_limit, opts):
    """The full search on bitset rows: order, renumber, initial clique, prune, search.

    Modes (:class:`~.codes.Mode`): MAXIMUM = a maximum clique (cliques larger than
    ``floor``); ENUMERATE = every clique of size ``floor + 1``, at most ``limit``;
    ALL_MAXIMUM = MAXIMUM, then, if it finished, ENUMERATE with ``floor = omega - 1``
    (every maximum clique), sharing the order and renumbering.

    In mode MAXIMUM the search first runs with a small node budget and the plain
    colouring bound: easy graphs end there. If it does not, tabu local search improves the
    incumbent and the search starts again with the higher bar and the MaxSAT-style filter
    (hard graphs repay the few milliseconds many times over). ``node_limit`` bounds the
    nodes of all phases together; ``deadline`` is a kernel clock reading.

    Returns ``(clique, nodes, status, found, status_all)`` in the caller's labels: status
    of the maximum clique search and of the enumeration (``NOT_RUN`` when not run).
    """
    W = A.shape[1]
    order, core = degeneracy_order(A, n)
    B = relabel(A, n, order)
    U = np.empty(W, np.uint64)
    maxsat = (opts & _OPT_MAXSAT) != 0
    mask = check_mask(n, W)
    nodes = 0
    status = _FINISHED
    best = np.empty(0, np.int64)
    if mode != _ENUMERATE:
        best, nodes, status = _maximum(
            B, n, order, core, floor, deadline, opts, maxsat, mask, U, node_limit
        )
    status_all = _NOT_RUN
    found = np.empty((0, floor + 1), np.int64)
    if mode == _ENUMERATE or (mode == _ALL and status == _FINISHED and best.shape[0] > 0):
        if mode == _ALL:
            floor = best.shape[0] - 1
        # k-core pruning: a clique of size floor + 1 lies inside the floor-core
        P0 = np.zeros(W, np.uint64)
        for i in range(n):
            if core[order[i]] >= floor:
                setbit(P0, i)
        # no initial clique: a fresh array (numba types a global array as read-only, and
        # would compile bb_search a second time for it)
        no_init = np.empty(0, np.int64)
        _, used, status_all, found = bb_search(
            B, n, P0, no_init, floor, _ENUMERATE, limit, deadline, mask, maxsat,
            node_limit - nodes, n + 1,
        )  # fmt: skip
        if status_all == _PHASE:
            status_all = _NODES
        nodes += used
    found_o = np.empty((found.shape[0], found.shape[1]), np.int64)
    for r in range(found.shape[0]):
        row = mapped_sorted(found[r], found.shape[1], order)
        for i in range(found.shape[1]):
            found_o[r, i] = row[i]
    return mapped_sorted(best, best.shape[0], order), nodes, status, found_o, status_all


@njit(cache=True)
def _maximum(B, n, order, core, floor, deadline, opts, maxsat, mask, U, node_limit):
    """Mode MAXIMUM of :func:`search_until`: ``(clique, nodes, status)`` in the
    renumbered labels."""
    core_new = np.empty(n, np.int64)  # core numbers in the degeneracy numbering
    kmax = 0
    for i in range(n):
        core_new[i] = core[order[i]]
        kmax = max(kmax, core[i])
    init = greedy_clique(B, n, U, deadline, core_new)
    if init.shape[0] > kmax and init.shape[0] > floor:
        # a clique of size k + 1 needs a k-core: the degeneracy bound is met already
        return init, 1, _FINISHED
    W = B.shape[1]
    nodes = 0
    budget = NO_LIMIT
    reason = maxsat
    if (opts & _OPT_LOCAL_SEARCH) != 0:
        # a first, cheap try: plain colouring bound, a thousand nodes
        budget = FIRST_TRY_NODES
        reason = False
    while True:
        bar = max(floor, init.shape[0])
        # k-core pruning: a clique of size bar + 1 lies inside the bar-core
        P0 = np.zeros(W, np.uint64)
        for i in range(n):
            if core[order[i]] >= bar:
                setbit(P0, i)
        lim, binding = _phase(budget, node_limit, nodes)
        if binding and lim <= 0:  # the caller's nodes are spent: the incumbent stands
            return init, nodes, _NODES
        best, used, status, _ = bb_search(
            B, n, P0, init, floor, _MAXIMUM, 0, deadline, mask, reason, lim, n + 1
        )
        nodes += used
        if status == _PHASE and binding:
            return best, nodes, _NODES
        if status != _PHASE:
            return best, nodes, status
        iters = min(20 * n, 20_000_000 // (n + 1))
        init = local_search(B, n, best, iters, max(500, 2 * n), deadline, 12345)
        budget = NO_LIMIT
        reason = maxsat


@njit(cache=True)
def _full_maximum(A, n, floor, deadline, node_limit):
    """:func:`search_until` in mode MAXIMUM with the default options: ``(clique, nodes,
    status)``, the clique in ``A``'s labels (not sorted)."""
    W = A.shape[1]
    order, core = degeneracy_order(A, n)
    B = relabel(A, n, order)
    U = np.empty(W, np.uint64)
    maxsat = (OPT_DEFAULT & _OPT_MAXSAT) != 0
    best, nodes, status = _maximum(
        B, n, order, core, floor, deadline, OPT_DEFAULT, maxsat, check_mask(n, W), U, node_limit
    )
    for i in range(best.shape[0]):
        best[i] = order[best[i]]
    return best, nodes, status


@njit(inline="always")
def _degrees(A, n, starts, deg, top):
    """``deg[v]``, the degree of every vertex, and ``top[:ntop]``, the ``starts`` vertices
    of highest degree, highest first (the lower label first among equals). Returns
    ``ntop = min(n, starts)``."""
    W = A.shape[1]
    ntop = 0
    for v in range(n):
        d = popcount(A[v], W)
        deg[v] = d
        if ntop < starts or d > deg[top[ntop - 1]]:
            i = min(ntop, starts - 1)
            while i > 0 and deg[top[i - 1]] < d:
                top[i] = top[i - 1]
                i -= 1
            top[i] = v
            ntop = min(ntop + 1, starts)
    return ntop


@njit(cache=True)
def maximum_word(A, n, floor, deadline, node_limit, out, dense_limit):
    """Mode MAXIMUM for at most 64 vertices: :func:`_bb_word` on the graph as it is
    (labels as given, no initial clique: on the pipeline's graphs the search finds one as
    fast as a greedy would). A graph of density above 1/4 gets at most ``dense_limit``
    nodes, then the full search (:func:`search_until`). When no clique is larger than
    ``floor``, a greedy clique is returned. At most ``node_limit`` nodes in all. Returns
    ``(size, nodes, status)`` with the clique in ``out[:size]``, sorted."""
    SP = np.empty(2 * n + 1, np.uint64)
    S = SP[:n]
    found = np.empty(n, np.int64)
    d2 = 0
    for v in range(n):
        S[v] = A[v, 0]
        d2 += int(ctpop(S[v]))
    lim, binding = _phase(NO_LIMIT if 4 * d2 <= n * n else dense_limit, node_limit, 0)
    size, nodes, status = _bb_word(S, n, floor, deadline, found, lim, SP[n:])
    if status == _PHASE and binding:
        status = _NODES
    elif status == _PHASE:
        best, used, status = _full_maximum(A, n, floor, deadline, node_limit - nodes)
        nodes += used
        size = best.shape[0]
        for i in range(size):
            found[i] = best[i]
    if size == 0:  # from the vertex of highest degree
        deg = np.empty(n, np.int64)
        top = np.empty(1, np.int64)
        _degrees(A, n, 1, deg, top)
        greedy = np.empty(n + 1, np.int64)
        size = greedy_by_degree(A, deg, top, 1, greedy, found, SP[n:])
        sorted_into(greedy, size, out)
    else:
        sorted_into(found, size, out)
    return size, nodes, status


@njit(cache=True)
def maximum_peeled(A, n, floor, deadline, node_limit, out, starts, sparse_nodes, dense_limit):
    """Mode 0 of :func:`solve` with elimination first, for the small sparse graphs of the
    pipeline (the full search's set-up costs more than their search).

    1. a greedy clique of size ``k`` (:func:`greedy_by_degree`); the bar is ``max(floor, k)``;
    2. the ``bar``-core (:func:`peel_core`): any larger clique lies in it. Empty: done;
    3. a core smaller than the graph is renumbered by non-increasing degree in the core
       (the colouring order; the whole graph keeps its labels), then searched with the
       plain colouring bound: in one-word sets (:func:`_bb_word`) when it has at most 64
       vertices (at most ``dense_limit`` nodes if its density is above 1/4); else, if its
       density is at most 1/4, in multi-word sets (:func:`bb_search`, plain bound) for at
       most ``sparse_nodes`` nodes;
    4. a dense core, or one that needs more nodes: the full search of :func:`solve`
       (degeneracy order, local search, MaxSAT-style filter) on the core, with ``bar`` as
       the floor; on the whole graph with ``floor`` when nothing was peeled, exactly as
       :func:`solve` would.

    At most ``node_limit`` nodes in all (steps 3 and 4). Returns ``(size, nodes,
    status)`` with the clique in ``out[:size]`` (sorted, the caller's labels), as
    :func:`solve_dense`; ``nodes`` counts the search nodes of steps 3 and 4 (1 when step 2
    ends the search).
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
    ntop = _degrees(A, n, starts, deg, top)
    k = greedy_by_degree(A, deg, top, ntop, greedy, cur, P)
    bar = max(floor, k)
    fill(alive, n)
    m = peel_core(A, n, deg, bar, alive, cur)
    if m == 0:
        sorted_into(greedy, k, out)
        return k, 1, _FINISHED
    d2 = 0  # twice the edges of the core
    dcore = 0  # its largest degree
    i = 0
    for w in range(W):
        x = alive[w]
        while x:
            b = cttz(x)
            x &= x - ONE
            v = w * 64 + int(b)
            out[i] = v  # the core, in label order
            i += 1
            d2 += deg[v]
            dcore = max(dcore, deg[v])
    sparse = 4 * d2 <= m * m
    same = False
    nodes = 0
    status = _PHASE
    binding = False
    size = 0
    if m <= 64:
        sort_by_degree(out, m, deg, dcore, verts)
        word_rows(A, verts, m, alive, cur, S)
        lim, binding = _phase(NO_LIMIT if sparse else dense_limit, node_limit, 0)
        size, nodes, status = _bb_word(S, m, bar, deadline, found, lim, Pst)
    else:
        same = True
        if sparse:
            lim, binding = _phase(sparse_nodes, node_limit, 0)
            no_init = np.empty(0, np.int64)  # a fresh array, as in search_until
            best, nodes, status, _ = bb_search(
                A, A.shape[0], alive, no_init, bar, _MAXIMUM, 0, deadline, check_mask(n, W),
                False, lim, dcore + 1,
            )  # fmt: skip
            size = best.shape[0]
            for i in range(size):
                found[i] = best[i]
    if status == _PHASE and binding:
        status = _NODES
    elif status == _PHASE:  # step 4
        if m == n:
            best, used, status = _full_maximum(A, n, floor, deadline, node_limit - nodes)
            same = True
        else:
            for i in range(m):
                verts[i] = out[i]
            B = induced_rows(A, verts, m, alive)
            best, used, status = _full_maximum(B, m, bar, deadline, node_limit - nodes)
            same = False
        nodes += used
        size = best.shape[0]
        for i in range(size):
            found[i] = best[i]
    if size < k:  # (a search that finds nothing larger than bar returns 0)
        size = k
        sorted_into(greedy, k, out)
    elif same:
        sorted_into(found, size, out)
    else:
        map_sorted_into(found, size, verts, out)
    return size, nodes, status


@njit(cache=True)
def maximum_until(A, n, floor, deadline, node_limit, out):
    """A maximum clique of the graph with bitset rows ``A`` (``n >= 1`` vertices), the
    path of ``max_clique`` without weights: :func:`maximum_word` for at most 64 vertices,
    else :func:`maximum_peeled`. Cliques of at most ``floor`` vertices are of no interest;
    ``deadline`` is a kernel clock reading (``inf``: none), ``node_limit`` a number of
    search nodes. Returns ``(size, nodes, status)`` with the clique in ``out[:size]``,
    sorted; status ``FINISHED``, ``TIME_LIMIT`` or ``NODE_LIMIT``."""
    if n <= 64:
        return maximum_word(A, n, floor, deadline, node_limit, out, DENSE_WORD_NODES)
    return maximum_peeled(
        A, n, floor, deadline, node_limit, out, SPARSE_STARTS, SPARSE_NODES, DENSE_WORD_NODES
    )


# --------------------------------------------------------------------------------------
# Entry points from Python: time limits count from the start of the compiled body
# --------------------------------------------------------------------------------------
@njit(cache=True)
def solve(A, n, floor, mode, limit, time_limit, node_limit, opts):
    """:func:`search_until` with a deadline ``time_limit`` seconds from now."""
    return search_until(A, n, floor, mode, limit, now() + time_limit, node_limit, opts)


@njit(cache=True)
def solve_packed(A, n, floor, time_limit, node_limit, out):
    """:func:`maximum_until` with a deadline ``time_limit`` seconds from now."""
    return maximum_until(A, n, floor, now() + time_limit, node_limit, out)


@njit(cache=True)
def solve_dense(adj, floor, time_limit, node_limit, out):
    """:func:`pack_checked` then :func:`maximum_until`, in one call: the lean path of
    ``max_clique`` for boolean matrices. Few arguments and no array crosses back into
    Python (the clique is written to ``out[:size]``): on the pipeline's graphs the fixed
    costs are a good part of the call. Returns ``(size, nodes, status, u, v)``;
    ``status`` is ``INVALID`` and ``(u, v)`` the defect when the matrix is not a valid
    adjacency."""
    deadline = now() + time_limit
    n = adj.shape[0]
    A, u, v = pack_checked(adj)
    if u >= 0:
        return 0, 0, _INVALID, u, v
    size, nodes, status = maximum_until(A, n, floor, deadline, node_limit, out)
    return size, nodes, status, -1, -1
