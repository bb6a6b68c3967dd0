"""Kernels load on first use (scanclique._lazy): the stand-in, the load times, and the one
warning a first (cold-cache) run gives before it compiles."""

from __future__ import annotations

import subprocess
import sys


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
