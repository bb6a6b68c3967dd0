"""The clique engine's compiled kernels, loaded on first use (importing numba takes a
moment, and ``import scanclique`` must not pay it)."""

from __future__ import annotations

from types import SimpleNamespace

_K: SimpleNamespace | None = None


def kernels() -> SimpleNamespace:
    """The kernel functions and codes, as one namespace (imported once per process).

    :func:`scanclique._kernels.ensure_cache` runs first, so the compiled code is cached
    in the directory stamped with the kernel sources' hash.
    """
    global _K
    if _K is None:
        from .._kernels import ensure_cache

        ensure_cache()
        from .._kernels import bitset, clique_search, codes, top, weighted

        _K = SimpleNamespace(
            pack_checked=bitset.pack_checked,
            solve=clique_search.solve,
            solve_packed=clique_search.solve_packed,
            solve_dense=clique_search.solve_dense,
            solve_weighted=weighted.solve_weighted,
            solve_top=top.solve_top,
            OPT_DEFAULT=clique_search.OPT_DEFAULT,
            Mode=codes.Mode,
            Status=codes.Status,
            NO_LIMIT=codes.NO_LIMIT,
        )
    return _K
