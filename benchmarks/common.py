"""What the benchmarks share besides the pair sets (``pairs.py``): the process-pool
chunking, the error and time summary of a list of per-pair records, and the machine,
version and git metadata written with the results."""

from __future__ import annotations

import datetime
import importlib.metadata
import json
import os
import platform
import subprocess
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
RESULTS = Path(__file__).resolve().parent / "results"


def chunks(items: list, jobs: int) -> list[list]:
    """``items`` dealt round-robin into four chunks per process, empty chunks dropped."""
    n = jobs * 4
    return [c for c in (items[k::n] for k in range(n)) if c]


def pool_map(ex, worker, args: list) -> list:
    """``worker`` over ``args`` in the pool ``ex``; the records of every call, in order."""
    return [r for part in ex.map(worker, args) for r in part]


def error_summary(records: list[dict]) -> dict:
    """Success rate, median errors and time percentiles of per-pair records (keys
    ``t_err`` in metres, ``r_err`` in radians, ``success``, ``ms``)."""
    if not records:
        return {"n": 0}
    t = np.array([r["t_err"] for r in records])
    a = np.array([r["r_err"] for r in records])
    ms = np.array([r["ms"] for r in records])
    return {
        "n": len(records),
        "success": float(np.mean([r["success"] for r in records])),
        "median_t_err": float(np.median(t)),
        "median_r_err_deg": float(np.degrees(np.median(a))),
        "median_ms": float(np.median(ms)),
        "p95_ms": float(np.percentile(ms, 95)),
    }


def machine(detailed: bool = False) -> dict:
    """Platform, processor and CPU count; ``detailed``: the processor falls back to the
    architecture and the load average is added."""
    out = {
        "platform": platform.platform(),
        "processor": platform.processor(),
        "cpus": os.cpu_count(),
    }
    if detailed:
        out["processor"] = out["processor"] or platform.machine()
        out["load_average"] = [round(x, 2) for x in os.getloadavg()]
    return out


def versions(packages: tuple[str, ...], **known: str) -> dict:
    """Python's version, then ``known``, then each installed package's (None if missing)."""
    out = {"python": platform.python_version(), **known}
    for pkg in packages:
        try:
            out[pkg] = importlib.metadata.version(pkg)
        except importlib.metadata.PackageNotFoundError:
            out[pkg] = None
    return out


def git_state() -> dict:
    """The commit of the checkout and the files that differ from it (results are of the
    working tree)."""

    def git(*a):
        r = subprocess.run(["git", *a], cwd=REPO, capture_output=True, text=True, check=False)
        return r.stdout.rstrip("\n") if r.returncode == 0 else None

    status = git("status", "--porcelain", "--untracked-files=no")
    return {
        "commit": git("rev-parse", "HEAD"),
        "modified": [] if not status else [ln[3:] for ln in status.splitlines()],
    }


#: the day the benchmark runs (ISO date): recorded with its results (:func:`provenance`)
#: and the default name of its results files
TODAY = datetime.date.today().isoformat()


def provenance(t0: float) -> dict:
    """What a results file says of its run: the day it ran, the checkout
    (:func:`git_state`), the machine with its load (:func:`machine`) and the seconds since
    ``t0`` (``time.perf_counter()`` at the start)."""
    return {
        "date": TODAY,
        "git": git_state(),
        "machine": machine(detailed=True),
        "seconds": time.perf_counter() - t0,
    }


def results_path(out: str | None, name: str) -> Path:
    """``out`` if given, else ``benchmarks/results/<name>``."""
    return Path(out) if out else RESULTS / name


def log_available(name: str, known: tuple[str, ...], why: str = "") -> bool:
    """Whether the registered log ``name`` is one of the ``known`` ones a benchmark runs
    and its data are present; else say why it is skipped (``why``: the reason it runs only
    those)."""
    from scanclique import datasets  # noqa: PLC0415
    from scanclique.errors import DataNotFoundError  # noqa: PLC0415

    if name not in known:
        print(f"{name}: skipped (this benchmark runs {', '.join(known)}{why})", flush=True)
        return False
    try:
        datasets.dataset_path(name)
    except DataNotFoundError as exc:
        print(f"{name}: skipped ({exc})", flush=True)
        return False
    return True


def publish(out: str | None, stem: str, title: str, lines: list[str], t0: float, rows: list):
    """Print the table ``lines``, then write them under the heading ``title`` with
    :func:`write_results` to ``out``, else ``benchmarks/results/<stem>-<date>``; say where."""
    print("\n".join(lines))
    base = results_path(out, f"{stem}-{TODAY}")
    write_results(base, f"# {title}\n\n" + "\n".join(lines) + "\n", t0, rows)
    print(f"written: {base}.md, {base}.json")


def write_results(base: Path | str, text: str, t0: float, rows: list) -> None:
    """``base``.md holding ``text`` and ``base``.json holding the run's
    :func:`provenance` and ``rows``."""
    base = Path(base)
    base.parent.mkdir(parents=True, exist_ok=True)
    Path(f"{base}.md").write_text(text)
    Path(f"{base}.json").write_text(json.dumps({**provenance(t0), "rows": rows}, indent=1) + "\n")
