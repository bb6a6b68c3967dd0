"""Is the front end's own uncertainty honest? Its chain against the reference, by path length.

The mapper's loop rules (``LoopConfig.max_turn``, ``max_shift``, the corroboration of a
closure that moves the estimate beyond ``max_radius``) weigh a closure against the front
end's own uncertainty between two keyframes (``_Mapper.front_std``): the variances of its
chain edges summed, a heading variance acting on a third of the path's square as its lever
arm. Each edge's heading sigma is at least ``FrontEndConfig.sigma_floor_radians``
(0.25 degrees), so over hundreds of metres the summed sigma grows with the number of
keyframes. Session 35 saw it grow ten times past the chain's real error on a simulated
building; this benchmark asks whether real logs agree.

For each log with a reference pose per scan (``intel``, ``csail`` with and without
odometry, ``freiburg`` without: its odometry fields are the reference) and one drive round
the simulated ring (``sim.simulate_ring_drive``, seed 0, a scan every 0.25 m), the log is
mapped with chained matching alone (``LoopConfig.enabled`` False). Then, for up to 3000
keyframes ``a`` drawn at random and the keyframe ``b`` a path ``L`` further on, the chain's
relative heading error against the reference's, divided by the summed heading sigma
(``z``), and its translation error divided by the translation sigma (``front_std``'s
form, ``pipeline._chain_sigma_xy``). Columns: pairs, median |heading error| (deg), median
heading sigma (deg), the rms of ``z`` (1 for an honest sigma; below 1 too cautious, above
it overconfident), the share of |z| > 3, the median translation error / sigma.

    python benchmarks/mapping_calibration.py
    python benchmarks/mapping_calibration.py --logs intel --lengths 10,100

Writes benchmarks/results/mapping-calibration-<date>.json and .md.
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

import common  # noqa: E402

from scanclique import map_scans  # noqa: E402
from scanclique.mapping import MapConfig  # noqa: E402
from scanclique.mapping.pipeline import _chain_sigma_xy  # noqa: E402

#: log -> the ``use_odometry`` values mapped (freiburg's odometry is its reference)
LOGS = {"intel": (None, False), "csail": (None, False), "freiburg": (False,), "ring": (None, False)}


def load(name: str) -> list:
    """The scans of a registered log, or of the simulated ring's drive (``"ring"``)."""
    if name == "ring":
        from scanclique.sim import simulate_ring_drive  # noqa: PLC0415

        return simulate_ring_drive(np.random.default_rng(0), loops=1.0, step=0.25)
    from scanclique.datasets import load_log  # noqa: PLC0415

    return load_log(name)


def chain_sigmas(result) -> tuple[list[int], np.ndarray, np.ndarray, np.ndarray]:
    """Keyframes, and along them the cumulative heading variance (rad²), largest-axis
    translation variance (m²) and path (m) of the chain edges between consecutive ones."""
    kf = list(result.keyframes)
    at = {k: n for n, k in enumerate(kf)}
    v_th, v_xy, step = (np.zeros(len(kf)) for _ in range(3))
    for e in result.edges:
        if e.i in at and e.j in at and at[e.j] == at[e.i] + 1:
            n = at[e.j]
            v_th[n] = e.covariance[2, 2]
            v_xy[n] = np.linalg.eigvalsh(e.covariance[:2, :2])[-1]
            step[n] = math.hypot(e.pose.x, e.pose.y)
    return kf, np.cumsum(v_th), np.cumsum(v_xy), np.cumsum(step)


def calibrate(scans, result, lengths, pairs: int = 3000, seed: int = 1) -> list[dict]:
    """Per path length ``L`` (m): the chain's errors against the reference, in sigmas."""
    kf, c_th, c_xy, path = chain_sigmas(result)
    ref = [scans[k].reference for k in kf]
    chain = [result.chained[k] for k in kf]
    starts = np.random.default_rng(seed).integers(0, len(kf), pairs)
    out = []
    for L in lengths:
        z, err, sig, zxy = [], [], [], []
        for a in starts:
            b = int(np.searchsorted(path, path[a] + L))
            if b >= len(kf):
                continue
            truth = ref[a].inverse() @ ref[b]
            est = chain[a].inverse() @ chain[b]
            e_th = math.remainder(est.theta - truth.theta, 2 * math.pi)
            s_th = math.sqrt(c_th[b] - c_th[a])
            if s_th <= 0.0:  # no chain edge between them claims anything
                continue
            s_xy = float(_chain_sigma_xy(c_xy[b] - c_xy[a], c_th[b] - c_th[a], L))
            z.append(e_th / s_th)
            err.append(abs(e_th))
            sig.append(s_th)
            zxy.append(math.hypot(est.x - truth.x, est.y - truth.y) / s_xy)
        if len(z) < 20:
            continue
        z = np.array(z)
        out.append({
            "length": L, "pairs": len(z),
            "heading_error_deg": math.degrees(float(np.median(err))),
            "heading_sigma_deg": math.degrees(float(np.median(sig))),
            "z_rms": float(np.sqrt(np.mean(z**2))), "beyond_3": float(np.mean(np.abs(z) > 3)),
            "xy_error_per_sigma": float(np.median(zxy)),
        })  # fmt: skip
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--logs", default=",".join(LOGS), help="of " + ", ".join(LOGS))
    ap.add_argument("--lengths", default="5,10,20,50,100,200", help="path lengths L (m)")
    ap.add_argument("--out", default=None, help="path stem (default: benchmarks/results/...)")
    args = ap.parse_args(argv)
    t0 = time.perf_counter()
    try:
        lengths = [float(x) for x in args.lengths.split(",") if x.strip()]
    except ValueError:
        ap.error(f"--lengths: metres separated by commas, got {args.lengths!r}")
    if not all(0.0 < x < math.inf for x in lengths):
        ap.error(f"--lengths: each a positive number of metres, got {args.lengths!r}")
    names = [n.strip() for n in args.logs.split(",") if n.strip()]
    if unknown := [n for n in names if n not in LOGS]:
        ap.error(f"--logs: unknown {', '.join(unknown)}; of {', '.join(LOGS)}")
    chained = dataclasses.replace(
        MapConfig(), loops=dataclasses.replace(MapConfig().loops, enabled=False)
    )
    lines = [
        "| log | odometry | keyframes | L (m) | pairs | heading error (deg, median) "
        "| heading sigma (deg, median) | z rms | share abs(z) > 3 | xy error / sigma (median) |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    rows = []
    for name in names:
        if name != "ring" and not common.log_available(name, tuple(LOGS)):
            continue
        scans = load(name)
        for odometry in LOGS[name]:
            res = map_scans(scans, use_odometry=odometry, config=chained)
            odo = "no" if odometry is False else "yes"
            for r in calibrate(scans, res, lengths):
                rows.append({"log": name, "odometry": odo, "keyframes": len(res.keyframes), **r})
                lines.append(
                    f"| {name} | {odo} | {len(res.keyframes)} | {r['length']:g} | {r['pairs']} "
                    f"| {r['heading_error_deg']:.2f} | {r['heading_sigma_deg']:.2f} "
                    f"| {r['z_rms']:.2f} | {r['beyond_3']:.3f} | {r['xy_error_per_sigma']:.2f} |"
                )
            print(f"{name} odometry={odo}: {len(scans)} scans mapped", flush=True)
    title = "The front end's uncertainty against the reference (benchmarks/mapping_calibration.py)"
    common.publish(args.out, "mapping-calibration", title, lines, t0, rows)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
