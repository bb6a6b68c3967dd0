"""``njit`` for the kernels: one compiled specialisation per argument *type*, not per constant.

A kernel that calls another with a constant argument (``head(stack, 0)``,
``bb_search(..., 0, 1, ...)``) makes numba compile the callee for ``Literal[int](0)``, a
type of its own, beside the ``int64`` specialisation that the other call sites need; the
callee's own callees then follow. For ``scanclique demo``'s scan match that was 107
specialisations of 75 kernels, and 26 % of its first run (116 s against 81 s on a cold
cache, measured with numba's compile events). Numba prefers non-literal types for calls
from Python and for ``@overload`` templates, but a call from one jitted function to
another compiles whatever types the caller holds
(``numba.core.dispatcher.Dispatcher.get_call_template``).

:func:`njit` is ``numba.njit`` whose dispatcher widens the argument types of such calls
to their non-literal types first (``numba.types.unliteral``: ``Literal[int](0)`` becomes
``int64``, ``Literal[bool](True)`` ``boolean``), so each kernel compiles once per real
signature. The code compiled is the same code for the same values: nothing in the
kernels dispatches on a literal (no ``numba.literally``, no ``@overload`` on values).
What a constant argument no longer gives is constant folding inside the callee, which
LLVM recovers where it inlines. Measured in session 28 (``benchmarks/results/
coldwarm-2026-12-06-s28.md``): the same matches, SLAM runs, maps and place hits to the bit,
and warm run times the same within noise (DIMACS graphs 0.93-1.01 of before).

The widening goes through that one method of numba's dispatcher (numba 0.68 here). A
numba without it keeps its own behaviour: more compilation, the same results.
"""

# ruff: noqa: E402 (ensure_cache() runs before numba caches anything)
from __future__ import annotations

import types as _pytypes

from . import ensure_cache

ensure_cache()

import numba
from numba.core import types

__all__ = ["njit"]


def _get_call_template(self, args, kws):
    """``Dispatcher.get_call_template`` with the argument types made non-literal."""
    args = tuple(types.unliteral(a) for a in args)
    kws = {k: types.unliteral(v) for k, v in kws.items()}
    return type(self).get_call_template(self, args, kws)


def _plain(dispatcher):
    """Make ``dispatcher`` compile calls from other kernels for non-literal types."""
    if hasattr(type(dispatcher), "get_call_template"):
        dispatcher.get_call_template = _pytypes.MethodType(_get_call_template, dispatcher)
    return dispatcher


def njit(*args, **options):
    """``numba.njit(*args, **options)`` whose dispatcher compiles calls from other kernels
    for the arguments' non-literal types (see the module docstring). Used as
    ``@njit(cache=True)``, as ``@njit`` or as ``njit(f, cache=True)``."""
    if args and callable(args[0]):
        return _plain(numba.njit(**options)(args[0]))
    decorate = numba.njit(*args, **options)
    return lambda f: _plain(decorate(f))
