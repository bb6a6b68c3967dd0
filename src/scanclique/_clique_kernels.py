"""Compatibility module: the clique kernels moved to :mod:`scanclique._kernels` (private).

Kept until :mod:`scanclique._match_kernels` and :mod:`scanclique.match` import from the
new places. The old names and signatures keep working here, without node limits:

=============================  ===========================================================
old name                       new home
=============================  ===========================================================
``solve(A, n, floor, mode,     ``clique_search.search_until(A, n, floor, mode, limit,
limit, time_limit, t0, opts)`` deadline, node_limit, opts)`` (``deadline = t0 +
                               time_limit``; entry point with a relative limit:
                               ``clique_search.solve``)
``solve_bits(A, n, floor,      ``clique_search.maximum_until(A, n, floor, deadline,
deadline, out)``               node_limit, out)``
``_induced_rows``              ``ordering.induced_rows``
``_setbit``, ``_now``,         ``bitset.setbit``, ``bitset.now``, ``bitset.ctpop``
``_ctpop``
``OPT_DEFAULT``                ``clique_search.OPT_DEFAULT`` (``codes.Option.DEFAULT``)
=============================  ===========================================================
"""

# ruff: noqa: E402 (ensure_cache() runs before numba is imported)
from __future__ import annotations

from ._kernels import ensure_cache

ensure_cache()  # before any njit(cache=True) below picks its cache location

import numba

from ._kernels.bitset import ctpop as _ctpop
from ._kernels.bitset import now as _now
from ._kernels.bitset import setbit as _setbit
from ._kernels.clique_search import OPT_DEFAULT, maximum_until, search_until
from ._kernels.codes import NO_LIMIT
from ._kernels.ordering import induced_rows as _induced_rows

__all__ = ["solve", "solve_bits", "OPT_DEFAULT", "_induced_rows", "_setbit", "_now", "_ctpop"]


@numba.njit(cache=True)
def solve(A, n, floor, mode, limit, time_limit, t0, opts):
    """Old signature of :func:`scanclique._kernels.clique_search.search_until` (no node
    limit; the deadline is ``t0 + time_limit``)."""
    return search_until(A, n, floor, mode, limit, t0 + time_limit, NO_LIMIT, opts)


@numba.njit(cache=True)
def solve_bits(A, n, floor, deadline, out):
    """Old signature of :func:`scanclique._kernels.clique_search.maximum_until` (no node
    limit)."""
    return maximum_until(A, n, floor, deadline, NO_LIMIT, out)
