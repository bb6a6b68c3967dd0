"""Long loops in a rectilinear building: does the mapper close them on the right corner,
and on the right door along a corridor?

``scanclique.sim.simulate_ring_drive`` drives twice round a 60 x 40 m ring corridor
(``sim.ring_world``: every corner alike, closed doors at random), a scan every 0.25 m,
with odometry that drifts 0.003 rad/m. Each seed is mapped with and without odometry,
with the default configuration, with ``LoopConfig.max_turn`` at pi (no refusal of
closures that turn the estimate: the mapper before session 31) and with
``LoopConfig.max_shift`` at inf (no refusal of closures that move the estimate by more
than a share of the path between the two places: before session 32), with
``LoopConfig.max_conflict`` at 1 (no refusal of closures to a twin place whose raw scans
conflict: before session 41), side by side; and with chained matching alone (no
closures). ``--odometry yes`` (``no``) maps it only with (without) odometry. Figures:
mean and max position error (m) against the drive's true poses, both in the frame of the
first scan, and the closures refused as ``"turned"``, ``"shifted"`` and
``"conflicting"``.

    python benchmarks/mapping_ring.py
    python benchmarks/mapping_ring.py --seeds 0,1 --out /tmp/ring
    python benchmarks/mapping_ring.py --size 200x120 --step 0.05 --loops 1.25 --configs default
    python benchmarks/mapping_ring.py --size 200x120 --loops 1.25 --configs default \
        --modes batch,online --odometry yes --scale-error 0.02

The third is a long loop of a large building (640 m round, parallel corridors 117 m apart)
scanned densely (5 cm a scan: 10 Hz at 0.5 m/s), closed once: before session 35 a
parallel corridor was closed on after 470 m (``_Mapper.moves_far``). The fourth maps that
loop a scan every 25 cm with wheels 2 % long, in batch and online (session 46).

``--scale-error -0.02`` makes the odometry's steps 2 % short (wheels of a wrong radius), a
steady error the mapper reads from the matches and takes out (session 45,
``OdometryFit.scale``).

``--modes batch,online`` maps each drive with ``map_scans`` and, as a robot would live, with
``map_online`` (``MapConfig.online()``: closures decided every 5 keyframes; the rows'
configuration changes the same loop settings). The column "wrong" counts the accepted loop
closures more than 1 m or 5 degrees off the truth.

Writes benchmarks/results/mapping-ring-<date>.json and .md.
"""

from __future__ import annotations

import argparse
import dataclasses
import itertools
import math
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

import common  # noqa: E402

from scanclique import map_scans  # noqa: E402
from scanclique.mapping import MapConfig, map_online  # noqa: E402
from scanclique.sim import simulate_ring_drive  # noqa: E402

#: the configurations compared: name -> MapConfig
CONFIGS = {
    "default": MapConfig(),
    "max_turn=pi": dataclasses.replace(
        MapConfig(), loops=dataclasses.replace(MapConfig().loops, max_turn=math.pi)
    ),
    "max_shift=inf": dataclasses.replace(
        MapConfig(), loops=dataclasses.replace(MapConfig().loops, max_shift=math.inf)
    ),
    "max_conflict=1": dataclasses.replace(
        MapConfig(), loops=dataclasses.replace(MapConfig().loops, max_conflict=1.0)
    ),
    "chained only": dataclasses.replace(
        MapConfig(), loops=dataclasses.replace(MapConfig().loops, enabled=False)
    ),
}


#: the loop settings ``MapConfig.online()`` changes, taken into a row's configuration online
ONLINE_LOOPS = ("pcm_batch", "pcm_anchor_batches", "corroborate_batches")


def online_config(cfg: MapConfig) -> MapConfig:
    """``cfg`` with the online mapper's loop settings (:meth:`MapConfig.online`)."""
    on = MapConfig.online().loops
    return dataclasses.replace(
        cfg, loops=dataclasses.replace(cfg.loops, **{k: getattr(on, k) for k in ONLINE_LOOPS})
    )


def wrong_closures(result, truth, metres: float = 1.0, degrees: float = 5.0) -> int:
    """Accepted loop closures (not local matches) more than ``metres`` or ``degrees`` off
    the truth's relative pose of their two scans."""
    n = 0
    for c in result.loop_closures:
        if c.accepted and not c.local:
            t, r = c.pose.distance_to(truth[c.i].inverse() @ truth[c.j])
            n += t > metres or math.degrees(r) > degrees
    return n


def run(
    seed: int,
    loops: float,
    size: tuple[float, float] = (60.0, 40.0),
    step: float = 0.25,
    configs: tuple[str, ...] = tuple(CONFIGS),
    scale_error: float = 0.0,
    modes: tuple[str, ...] = ("batch",),
    odometries: tuple[bool, ...] = (True, False),
) -> list[dict]:
    """The configurations ``configs`` of :data:`CONFIGS`, with odometry and / or without
    (``odometries``), on one drive round a ring of ``size`` (length, width m), a scan
    every ``step`` m, the odometry's steps ``1 + scale_error`` times the true ones; mapped
    by ``map_scans`` (mode ``"batch"``) and / or ``map_online`` (``"online"``)."""
    scans = simulate_ring_drive(
        np.random.default_rng(seed), length=size[0], width=size[1], loops=loops, step=step,
        scale_error=scale_error,
    )  # fmt: skip
    truth = [scans[0].reference.inverse() @ s.reference for s in scans]
    odo = [scans[0].odometry.inverse() @ s.odometry for s in scans]
    odo_err = np.array([p.distance_to(t)[0] for p, t in zip(odo, truth, strict=True)])
    rows = []
    for mode, odometry, name in itertools.product(modes, odometries, configs):
        cfg = CONFIGS[name]
        t = time.perf_counter()
        if mode == "online":
            r = map_online(scans, use_odometry=odometry, config=online_config(cfg)).result
        else:
            r = map_scans(scans, use_odometry=odometry, config=cfg)
        e = np.array([p.distance_to(q)[0] for p, q in zip(r.poses, truth, strict=True)])
        rows.append(
            {
                "seed": seed,
                "size": list(size),
                "step": step,
                "scans": len(scans),
                "mode": mode,
                "odometry": odometry,
                "config": name,
                "mean": float(e.mean()),
                "max": float(e.max()),
                "odometry_mean": float(odo_err.mean()),
                "turned": sum(c.verdict == "turned" for c in r.loop_closures),
                "shifted": sum(c.verdict == "shifted" for c in r.loop_closures),
                "conflicting": sum(c.verdict == "conflicting" for c in r.loop_closures),
                "accepted": sum(c.accepted and not c.local for c in r.loop_closures),
                "wrong": wrong_closures(r, truth),
                "seconds": time.perf_counter() - t,
            }
        )
        print(
            f"seed {seed} {mode} {'odometry' if odometry else 'no odometry'} {name}: "
            f"{e.mean():.3f} / {e.max():.2f} m, {rows[-1]['wrong']} wrong closures",
            flush=True,
        )
    return rows


def table(rows: list[dict]) -> list[str]:
    out = [
        "| seed | mode | odometry | configuration | mean error (m) | max error (m) | closures "
        "accepted | wrong (> 1 m or 5 deg) | refused as turned | refused as shifted | "
        "refused as conflicting | odometry alone, mean (m) | seconds |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        out.append(
            f"| {r['seed']} | {r.get('mode', 'batch')} | {'yes' if r['odometry'] else 'no'} | "
            f"{r['config']} | {r['mean']:.3f} | {r['max']:.2f} | {r['accepted']} | "
            f"{r.get('wrong', '')} | {r['turned']} | "
            f"{r['shifted']} | {r.get('conflicting', 0)} | "
            f"{r['odometry_mean']:.2f} | {r['seconds']:.1f} |"
        )
    return out


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seeds", default="0,1,2,3")
    ap.add_argument("--loops", type=float, default=2.0, help="times round the ring")
    ap.add_argument("--size", default="60x40", help="the ring's length x width (m)")
    ap.add_argument("--step", type=float, default=0.25, help="metres between scans")
    ap.add_argument("--configs", default=",".join(CONFIGS), help=f"of {', '.join(CONFIGS)}")
    ap.add_argument(
        "--scale-error", type=float, default=0.0,
        help="the odometry's steps are 1 + this times the true ones (wheels of a wrong radius)",
    )  # fmt: skip
    ap.add_argument(
        "--modes", default="batch", help="batch (map_scans), online (map_online) or both"
    )
    ap.add_argument("--odometry", choices=("both", "yes", "no"), default="both")
    ap.add_argument("--out", default=None, help="path stem (default: benchmarks/results/...)")
    args = ap.parse_args(argv)
    t0 = time.perf_counter()
    rows = []
    try:
        size = tuple(float(v) for v in args.size.lower().split("x"))
    except ValueError:
        size = ()
    configs = tuple(c for c in args.configs.split(",") if c)
    unknown = sorted(set(configs) - set(CONFIGS))
    modes = tuple(m for m in args.modes.split(",") if m)
    if len(size) != 2 or unknown or not modes or set(modes) - {"batch", "online"}:
        ap.error(
            f"--size LENGTHxWIDTH, --configs of {', '.join(CONFIGS)} ({unknown}) and "
            f"--modes of batch, online ({args.modes!r})"
        )
    odometry = {"both": (True, False), "yes": (True,), "no": (False,)}[args.odometry]
    for seed in (int(s) for s in args.seeds.split(",")):
        rows += run(seed, args.loops, size, args.step, configs, args.scale_error, modes, odometry)
    lines = [
        f"Ring {size[0]:g} x {size[1]:g} m, driven {args.loops:g} times, a scan every "
        f"{args.step:g} m"
        + (
            f", the odometry's steps {1 + args.scale_error:g} times the true ones."
            if args.scale_error
            else "."
        ),
        "",
        *table(rows),
    ]
    common.publish(
        args.out,
        "mapping-ring",
        "Long loops in a ring corridor (benchmarks/mapping_ring.py)",
        lines,
        t0,
        rows,
    )


if __name__ == "__main__":
    main()
