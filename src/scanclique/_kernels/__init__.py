"""Compiled kernels (numba), one module per concern, and the cache they share.

Private. The public faces are :mod:`scanclique.clique` (the maximum clique engine) and the
pipeline stages. The clique engine's kernels:

========================  ===============================================================
``bitset``                word primitives (popcount, trailing zeros), the kernel clock,
                          small array helpers, packing a boolean matrix into bitset rows
``ordering``              degeneracy order and core numbers, k-cores, renumbering,
                          induced subgraphs
``heuristics``            initial cliques: greedy cliques, tabu local search
``colouring``             greedy colouring bounds (plain, k-min filter, weighted)
``maxsat``                MaxSAT-style filtering of branching vertices
``clique_search``         branch and bound, the lean paths and the entry points
``weighted``              maximum-weight clique
``top``                   the k largest maximal cliques (Bron–Kerbosch)
``codes``                 modes, statuses and options as ``IntEnum`` (no numba)
========================  ===============================================================

The matcher's (gathered in :mod:`scanclique._match_kernels`), and the correspondence graph's:

========================  ===============================================================
``algebra``               angle wrapping, 3x3 solves, 2x2 eigenvectors
``neighbours``            nearest neighbours by bearing window, normals, scan arrays
``score``                 the raw-scan score of poses (agreement, free-space conflicts)
``icp``                   point-to-line ICP
``pose``                  poses from mapped features (paper §6), consistency, covariance
``hypotheses``            a match's clique hypotheses under a node budget (paper §5.3)
``refine``                the best few hypotheses: estimate, score, ICP, score
``search``                the raw-scan pose search (orientation histograms, Hough votes)
``correspondence``        the edges of the correspondence graph (paper §5.2)
========================  ===============================================================

The feature kernels (paper §4, §5.1) are :mod:`scanclique._feature_kernels`.

The cache stamp
---------------
numba caches a compiled function beside its source file and checks only that file's
modification time: a kernel in one module that calls a kernel in another is *not*
recompiled when the callee changes, and silently runs the old callee. :func:`ensure_cache`
replaces the old remedy (deleting ``__pycache__`` by hand) by a mechanism: it hashes the
source of every kernel module (this package's ``*.py`` and every other ``_*kernels.py`` of
``scanclique``, see :func:`kernel_sources`) and points numba's cache at a directory named
after that hash, so any edit of any kernel source starts a fresh cache, in which
everything compiles against the current callees. Every kernel loader calls it before its
first ``numba.njit(cache=True)`` decoration runs (the locator of a cached function is
fixed when it is decorated); the modules of this package call it at import.

Where the cache goes: ``$NUMBA_CACHE_DIR/scanclique-<stamp>`` when the user set
``NUMBA_CACHE_DIR``; else ``scanclique/__pycache__/kernels-<stamp>`` when the package
directory is writable; else ``$XDG_CACHE_HOME/scanclique/kernels-<stamp>`` (default
``~/.cache``). Directories of other stamps beside it are removed once nothing has been
written to them for a day.

This module imports no numba: it must run before numba caches anything.
"""

from __future__ import annotations

import hashlib
import logging
import os
import shutil
import time
from collections.abc import Iterable
from pathlib import Path

__all__ = ["ensure_cache", "kernel_sources", "kernel_stamp", "cache_dir_for"]

log = logging.getLogger(__name__)

#: set by :func:`ensure_cache` in the environment, so that child processes (which inherit
#: ``NUMBA_CACHE_DIR``) recognise a stamped directory and do not stamp it again
_MARK = "SCANCLIQUE_KERNEL_CACHE"
#: stamped directories of other stamps, in the default locations, older than this
#: (seconds since last written) are removed
_STALE = 86400.0

_PACKAGE = Path(__file__).resolve().parent.parent  # src/scanclique
_cache_dir: str | None = None


def kernel_sources(package: str | os.PathLike | None = None) -> list[Path]:
    """The source files whose compiled code shares one cache, sorted.

    Parameters
    ----------
    package : path, optional
        The package directory (default: the installed ``scanclique``). Its
        ``_kernels/*.py`` and every ``_*kernels.py`` in it or its subpackages (e.g.
        ``_match_kernels.py``, ``slam/_kernels.py``); ``__pycache__`` is not searched.

    Returns
    -------
    list of Path
    """
    root = Path(package) if package is not None else _PACKAGE
    files = list((root / "_kernels").glob("*.py"))
    for d, dirs, names in os.walk(root):
        dirs[:] = [x for x in dirs if x != "__pycache__" and not x.startswith(".")]
        files += [Path(d) / f for f in names if f.startswith("_") and f.endswith("kernels.py")]
    return sorted({p for p in files if p.is_file()})


def kernel_stamp(sources: Iterable[str | os.PathLike] | None = None) -> str:
    """A short hash of the kernel sources: their names and bytes, in sorted order.

    Parameters
    ----------
    sources : iterable of paths, optional
        Default: :func:`kernel_sources`.

    Returns
    -------
    str
        16 hexadecimal digits; it changes when any source changes, is added, removed or
        renamed.

    Examples
    --------
    >>> len(kernel_stamp())
    16
    """
    h = hashlib.sha256()
    files = [Path(p).resolve() for p in (kernel_sources() if sources is None else sources)]
    # names relative to the package, so that a copy of the package has the same stamp
    root = _common_root(files)
    for p in sorted(files, key=lambda q: q.relative_to(root).as_posix()):
        h.update(p.relative_to(root).as_posix().encode() + b"\0")
        h.update(p.read_bytes())
        h.update(b"\0")
    return h.hexdigest()[:16]


def _common_root(files: list[Path]) -> Path:
    if not files:
        return Path(".")
    return Path(os.path.commonpath([str(p.resolve().parent) for p in files]))


def cache_dir_for(stamp: str, package: str | os.PathLike | None = None) -> Path:
    """The cache directory :func:`ensure_cache` chooses for ``stamp`` (see the module
    docstring), without creating it."""
    user = os.environ.get("NUMBA_CACHE_DIR", "")
    ours = os.environ.get(_MARK, "")
    if user and user != ours:
        return Path(user) / f"scanclique-{stamp}"
    if user and user == ours and Path(user).name.startswith("scanclique-"):
        return Path(user).parent / f"scanclique-{stamp}"  # a user's base, stamped by a parent
    return _default_base(package) / f"kernels-{stamp}"


def _default_base(package) -> Path:
    root = Path(package) if package is not None else _PACKAGE
    pyc = root / "__pycache__"
    try:
        pyc.mkdir(exist_ok=True)
        if os.access(pyc, os.W_OK):
            return pyc
    except OSError:
        pass
    xdg = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    return Path(xdg) / "scanclique"


def ensure_cache(
    sources: Iterable[str | os.PathLike] | None = None,
    package: str | os.PathLike | None = None,
) -> str:
    """Point numba's cache at the directory stamped with the kernel sources' hash.

    Call before any kernel module is imported (their ``@njit(cache=True)`` decorations
    choose the cache location); idempotent, cheap after the first call (which reads the
    kernel sources, about a millisecond).

    Parameters
    ----------
    sources, package : optional
        For tests: other kernel sources and package directory than the installed ones.

    Returns
    -------
    str
        The cache directory (created). It is set as ``numba.config.CACHE_DIR`` when numba
        is imported already, and as ``NUMBA_CACHE_DIR`` in the environment (numba reads it
        at import and on every config reload; child processes inherit it).
    """
    global _cache_dir
    if _cache_dir is not None and sources is None and package is None:
        return _cache_dir
    stamp = kernel_stamp(sources if sources is not None else kernel_sources(package))
    d = cache_dir_for(stamp, package)
    try:
        d.mkdir(parents=True, exist_ok=True)
    except OSError as e:  # numba then falls back to its own locations
        log.warning("cannot create the kernel cache %s (%s); numba chooses", d, e)
        return ""
    _prune(d)
    path = str(d)
    os.environ["NUMBA_CACHE_DIR"] = path
    os.environ[_MARK] = path
    import sys

    cfg = sys.modules.get("numba.core.config")
    if cfg is not None:
        cfg.CACHE_DIR = path
    if sources is None and package is None:
        _cache_dir = path
    log.debug("numba kernel cache: %s", path)
    return path


def _prune(keep: Path) -> None:
    """Remove the sibling stamped directories of ``keep`` that nobody wrote for a day."""
    prefix = keep.name.split("-")[0] + "-"
    now = time.time()
    try:
        siblings = list(keep.parent.iterdir())
    except OSError:
        return
    for p in siblings:
        if p == keep or not p.name.startswith(prefix) or not p.is_dir():
            continue
        try:
            newest = max([p.stat().st_mtime] + [q.stat().st_mtime for q in p.rglob("*")])
        except OSError:
            continue
        if now - newest > _STALE:
            shutil.rmtree(p, ignore_errors=True)
