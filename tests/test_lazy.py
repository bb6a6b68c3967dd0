"""Kernels load on first use (scanclique._lazy): the stand-in, the load times, and the one
warning a first (cold-cache) run gives before it compiles; and they compile once per
argument type (scanclique._kernels.jit): compiling is most of what a first run costs."""

from __future__ import annotations

import subprocess
import sys

import numpy as np


def test_kernel_module_loads_on_first_attribute_and_caches_it():
    from scanclique._lazy import LOAD_SECONDS, kernel_module

    K = kernel_module("scanclique.eval.success")
    assert "not loaded" in repr(K) or "loaded" in repr(K)
    assert K.is_success(0.1, 0.01) is True
    assert "is_success" in vars(K)  # cached on the stand-in: no second lookup
    assert "loaded" in repr(K)
    assert all(v >= 0 for v in LOAD_SECONDS.values())


def test_a_cold_cache_is_announced_once_before_compiling(tmp_path):
    code = (
        "import logging, scanclique._lazy as L\n"
        "logging.basicConfig(level=logging.WARNING, format='%(message)s')\n"
        "print(L.cache_is_cold())\n"
        "L._announce('scanclique._match_kernels')\n"
        "L._announce('scanclique._feature_kernels')\n"
    )
    env = {"NUMBA_CACHE_DIR": str(tmp_path), "PATH": "/usr/bin:/bin"}
    out = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, env=env, timeout=120
    )
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == "True"
    assert out.stderr.count("compiling the numba kernels: first run only") == 1


def test_a_kernel_called_with_a_constant_compiles_for_its_type_not_its_value():
    """scanclique._kernels.jit.njit: a call from one kernel to another with a constant
    argument compiles the callee for int64, once, where numba.njit compiles a
    Literal[int] specialisation for every constant as well."""
    import numba
    from numba.core import types

    from scanclique._kernels.jit import njit

    def build(decorate):
        @decorate
        def inner(a, k):
            return a[k] + k

        @decorate
        def outer(a, k):
            return inner(a, 0) + inner(a, 1) + inner(a, k)

        return inner, outer

    a = np.arange(4.0)
    for decorate, literal in ((numba.njit, True), (njit, False)):
        inner, outer = build(decorate)
        assert outer(a, 2) == (0.0 + 0) + (1.0 + 1) + (2.0 + 2)
        kinds = [isinstance(t, types.Literal) for sig in inner.signatures for t in sig]
        assert any(kinds) is literal
        assert len(inner.signatures) == (3 if literal else 1)
    assert njit(lambda x: x + 1)(1) == 2  # the bare form


def test_every_kernel_is_decorated_through_scanclique_njit():
    """Every compiled function of the package comes from scanclique._kernels.jit.njit, so
    none compiles a Literal specialisation per constant (the test above). A kernel
    decorated with numba.njit directly would compile its callees' constants again on every
    first run; this is checked on the sources, since a warm cache loads the callers whole
    and never shows the callees' signatures."""
    import re
    from pathlib import Path

    import scanclique

    root = Path(scanclique.__file__).parent
    direct = re.compile(r"numba\.n?jit\(|^\s*@numba\.n?jit\b|from numba import .*\bn?jit\b", re.M)
    offenders = [
        f"{p.relative_to(root)}:{s[: m.start()].count(chr(10)) + 1}"
        for p in sorted(root.rglob("*.py"))
        if p.name != "jit.py"
        for s in [p.read_text()]
        for m in direct.finditer(s)
        for line in [s[: m.start()].rsplit("\n", 1)[-1]]
        if not (line.lstrip().startswith("#") or line.endswith("``"))  # comments, docs
    ]
    assert offenders == []
