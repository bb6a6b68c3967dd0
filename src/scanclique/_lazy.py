"""One rule for the compiled kernels: they load on first use, never at ``import scanclique``.

Importing numba and loading (or, on a first run, compiling) the kernels takes from a second
to a few minutes; ``scanclique --version``, ``--help`` and scripts that only read logs pay
none of it. Every module that calls compiled code names its kernel module through
:func:`kernel_module`, which returns a stand-in that imports the real module on the first
attribute access and then caches each attribute it hands out (a later call costs a plain
attribute lookup).

The time each kernel module took to import is kept in :data:`LOAD_SECONDS`, so that a
caller can report kernel loading apart from the work it timed. Compilation itself happens
on each kernel's first call (numba compiles lazily); :func:`scanclique.match.warm_up` runs a
tiny match once so that later timings, and the budgets that decide results, never include it.

>>> from scanclique._lazy import kernel_module
>>> K = kernel_module("scanclique.geometry")   # any module works; kernels are the use
>>> bool(K.wrap_angle(4.0) < 0)
True
"""

from __future__ import annotations

import importlib
import logging
import sys
import time
from types import ModuleType

__all__ = ["LOAD_SECONDS", "KernelModule", "cache_is_cold", "kernel_module", "load"]

log = logging.getLogger(__name__)

#: seconds each lazily loaded module took to import, by module name
LOAD_SECONDS: dict[str, float] = {}


def _prepare_cache() -> None:
    """Point numba's cache at a directory stamped with the kernel sources, when the
    kernels package offers it (``scanclique._kernels.ensure_cache``)."""
    try:
        from ._kernels import ensure_cache  # type: ignore[attr-defined]
    except ImportError:
        return
    ensure_cache()


def cache_is_cold() -> bool:
    """True when nothing has been compiled into the current kernel cache yet (the first
    run after installing, or after any kernel source changed: the cache is stamped with
    their hash): the next match compiles the kernels, which takes minutes. A caller that
    talks to a person says so before it starts (``scanclique`` does, on stderr)."""
    try:
        from ._kernels import ensure_cache
    except ImportError:  # pragma: no cover - the package is always there
        return False
    from pathlib import Path

    root = Path(ensure_cache())
    return next(root.rglob("*.nbi"), None) is None


_announced = False


def _announce(name: str) -> None:
    """One warning per process, before the first kernel module loads into a cold cache
    (``scanclique`` shows warnings on stderr): a first run compiles for minutes, and
    should say so rather than look hung."""
    global _announced
    if _announced or "_kernels" not in name:
        return
    _announced = True
    if cache_is_cold():
        log.warning(
            "compiling the numba kernels: first run only, about 1-3 minutes on an idle "
            "2-core machine (longer when it is busy); later runs load them in about a second"
        )


def load(name: str) -> ModuleType:
    """Import module ``name`` (fully qualified), timing the first import."""
    mod = sys.modules.get(name)
    if mod is not None:
        return mod
    t0 = time.perf_counter()
    _prepare_cache()
    _announce(name)
    mod = importlib.import_module(name)
    LOAD_SECONDS[name] = time.perf_counter() - t0
    log.debug("loaded %s in %.2f s", name, LOAD_SECONDS[name])
    return mod


class KernelModule:
    """Stand-in for a module that is imported on first attribute access (see module doc)."""

    def __init__(self, name: str) -> None:
        object.__setattr__(self, "_name", name)

    def __getattr__(self, attr: str):
        if attr.startswith("__"):
            raise AttributeError(attr)
        value = getattr(load(object.__getattribute__(self, "_name")), attr)
        object.__setattr__(self, attr, value)  # the next access skips __getattr__
        return value

    def __repr__(self) -> str:
        name = object.__getattribute__(self, "_name")
        state = "loaded" if name in sys.modules else "not loaded"
        return f"<kernel module {name} ({state})>"


def kernel_module(name: str) -> KernelModule:
    """A :class:`KernelModule` for the fully qualified module ``name``."""
    return KernelModule(name)
