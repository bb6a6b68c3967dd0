"""Mapping on other laser scanners (session 10): simulated drives with known truth.

One command::

    python benchmarks/mapping_sensors.py                      # every profile, 3 seeds
    python benchmarks/mapping_sensors.py --profiles hokuyo --seeds 0 --odometry no

``scanclique.map_scans`` is tuned on CARMEN logs of 180-degree SICK scanners (361 or 181
beams, 5-10 Hz, 1 cm noise). Each profile here is a scanner people use today, riding the
same kind of office drive (``office_world``; the drive of ``simulate_trajectory``, 0.25 m
steps, resampled at the scanner's rate by ``simulate_sensor_drive``: the robot rides at
``speed`` and turns at most 90 degrees per second):

* ``carmen``: 180 degrees, 361 beams, 30 m, sigma 1 cm, 5 Hz at 1.25 m/s (the control);
* ``hokuyo`` (UTM-30LX): 270 degrees, 1081 beams, 30 m, sigma 2 cm, 40 Hz at 1 m/s
  (2.5 cm and at most 2.25 degrees between scans);
* ``tim571`` (SICK TiM571): 270 degrees, 811 beams, 25 m, sigma 2 cm, 15 Hz at 1 m/s;
* ``rplidar`` (RPLIDAR A1 class): 360 degrees (``angle_min`` -pi, 360 beams 1
  degree apart), 10 m, sigma 1.5 % of the range, 7 % of the beams without a return, 7 Hz at
  0.5 m/s;
* ``lds`` (TurtleBot3's LDS-01, session 36): 360 degrees (360 beams from 0), 3.5 m, sigma
  1.5 % of the range, 5 % of the beams without a return, 5 Hz at 0.2 m/s: a short reach,
  so that walls recede out of it;
* ``rplidar-swept``, ``lds-swept`` (session 38): the two rotating lidars as they really
  measure, one beam after the other over the whole scan period (``sweep``, 1/7 and 1/5 s:
  turning at 90 degrees per second the LDS-01's last beam is 18 degrees behind its first),
  each scan with its ``beam_times``; ``hokuyo-swept``, ``tim571-swept``: the 270 degree
  scanners likewise (three quarters of a 1/40 and a 1/15 s period). ``map_scans`` takes the skew out
  (``FrontEndConfig.deskew``); ``--deskew both`` (the default) also maps them without
  (rows ``..., raw``). ``--times negated`` (``reversed``, ``shifted``) publishes their
  beam times as drivers that store or stamp the sweep otherwise do, which the mapper must
  read back (``scanclique.mapping.sweep``; rows ``(published ..., read ...)``).

Each with and without odometry (``use_odometry``), for a few seeds (one world and drive
per seed, the same for every profile). Columns: ATE (position error after expressing the
truth in the frame of scan 0; mean over scans, mean and max over seeds of the per-drive
max), the largest relative error of consecutive scans (m, degrees), how the scans were
placed, accepted loop closures, wall time of ``map_scans`` and scans per second,
seconds of mapping per second of data (``realtime``: below 1 keeps up with the scanner),
and where the time goes: the front end (preparing and matching every scan against its
keyframe) per scan, the loops (local matches, loop candidates, PCM, iSAM2, the final
optimisation) per keyframe.
Times include the numba kernels' warm-up only in the first run (a warm-up drive runs
first).

Results: ``benchmarks/results/mapping-sensors-2026-12-02-s10.{md,json}``.

**Outdoors** (session 39), one command::

    python benchmarks/mapping_sensors.py --world campus --steps 600 --profiles PROFILES

The same scanners riding ``scanclique.sim.campus_world`` instead of an office: a grid of
buildings with streets 8 m wide between them, trees along the streets, the façades round
the campus; 150 m drives. Session 39 ran ``--profiles carmen,hokuyo,rplidar,lds``. Results:
``benchmarks/results/mapping-sensors-campus-2026-12-07-s39.{md,json}`` (``-s39-before``:
before the front end's contest by odometry took ICP's overlap relative to the match's).

**Real logs with another scanner's limits** (session 14), one command::

    python benchmarks/mapping_sensors.py --real fr079-raw,intel-raw

The raw Kümmerle logs (180-degree SICK, 361 / 181 beams, wheel odometry), each scan
degraded to what a cheaper or different scanner gives, then mapped with the defaults and
scored by the benchmark's relation metric (mean translation and rotation error over the
log's relations, as in ``mapping.py``; the relations refer to the robot frame, the
laser's mounting taken into account). Variants (:data:`VARIANTS`):

* ``as-is``: the log as recorded (the control);
* ``range-5.6``: readings at 5.6 m or beyond become no-returns (a Hokuyo URG-04LX);
* ``half-beams``: every second beam (half the angular resolution: 1 or 2 degrees);
* ``noise-3cm``: Gaussian noise of 3 cm added to every return (seeded; three times the
  SICK's);
* ``every-2nd-scan``: every second scan dropped (twice the motion between scans); only the
  relations whose two scans are kept are scored (``missing`` counts the others).

Results: ``benchmarks/results/mapping-sensors-real-2026-12-04-s14.{md,json}``.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
import time
from pathlib import Path

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("OMP_NUM_THREADS", "1")

import numpy as np  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent))
from common import TODAY, provenance, results_path  # noqa: E402

PROFILES = {
    "carmen": dict(
        n_beams=361, fov=math.pi, angle_min=-math.pi / 2, max_range=30.0, range_sigma=0.01,
        scan_rate=5.0, speed=1.25,
    ),
    "hokuyo": dict(
        n_beams=1081, fov=math.radians(270.0), angle_min=math.radians(-135.0), max_range=30.0,
        range_sigma=0.02, scan_rate=40.0, speed=1.0,
    ),
    "tim571": dict(
        n_beams=811, fov=math.radians(270.0), angle_min=math.radians(-135.0), max_range=25.0,
        range_sigma=0.02, scan_rate=15.0, speed=1.0,
    ),
    "rplidar": dict(
        n_beams=360, fov=2 * math.pi * 359 / 360, angle_min=-math.pi, max_range=10.0,
        range_sigma=0.0, range_sigma_per_m=0.015, dropout=0.07, scan_rate=7.0, speed=0.5,
    ),
    "lds": dict(
        n_beams=360, fov=2 * math.pi * 359 / 360, angle_min=0.0, max_range=3.5,
        range_sigma=0.0, range_sigma_per_m=0.015, dropout=0.05, scan_rate=5.0, speed=0.2,
    ),
}  # fmt: skip
# every scanner sweeps its beams at the pace of one turn a scan period (module
# docstring): a full circle in the whole period, 270 degrees in three quarters of it
for _name in ("hokuyo", "tim571", "rplidar", "lds"):
    _p = PROFILES[_name]
    _turn = _p["fov"] * _p["n_beams"] / (_p["n_beams"] - 1) / (2 * math.pi)  # one beam each
    PROFILES[f"{_name}-swept"] = {**_p, "sweep": _turn / _p["scan_rate"]}


#: how the swept profiles' beam times may be published (``--times``): as measured (REP
#: 117), or as drivers that store or stamp a sweep otherwise give them, which
#: ``scanclique.mapping.sweep.sweep_timing`` must read back (``scan.TIMINGS``)
PUBLISHED = {
    "given": lambda t: t,
    "negated": lambda t: -t,  # stored against the order measured, stamped at the end
    "reversed": lambda t: t.max() - t,  # stored against the order measured
    "shifted": lambda t: t + t.max(),  # stamped at the end
}


#: the worlds the drives ride in (``--world``): indoors (the default) and outdoors
WORLDS = ("office", "campus")


def make_world(name: str, rng):
    """The world ``name`` (:data:`WORLDS`) drawn from ``rng``; ``places_sensors.py`` too."""
    from scanclique import sim  # noqa: PLC0415

    return {"office": sim.office_world, "campus": sim.campus_world}[name](rng)


def drive(profile: str, seed: int, n_steps: int, times: str = "given", world: str = "office"):
    """The scans of drive ``seed`` (``n_steps`` poses 0.25 m apart) seen by ``profile`` in
    ``world`` (:data:`WORLDS`), a swept profile's beam times published as ``times`` says
    (:data:`PUBLISHED`)."""
    import dataclasses  # noqa: PLC0415

    from scanclique import sim  # noqa: PLC0415

    rng = np.random.default_rng(seed)
    kw = dict(PROFILES[profile])
    scans = sim.simulate_sensor_drive(rng, make_world(world, rng), n_steps, 0.25, **kw)
    if times == "given" or "sweep" not in kw:
        return scans
    return [dataclasses.replace(s, beam_times=PUBLISHED[times](s.beam_times)) for s in scans]


def errors(result, scans) -> dict:
    """ATE after alignment in the frame of scan 0, and consecutive relative errors."""
    r0 = scans[0].reference.inverse()
    ate = np.array(
        [p.distance_to(r0 @ s.reference)[0] for p, s in zip(result.poses, scans, strict=True)]
    )
    t, r = [], []
    pairs = zip(result.poses[:-1], result.poses[1:], scans[:-1], scans[1:], strict=True)
    for a, b, sa, sb in pairs:
        dt, dr = (a.inverse() @ b).distance_to(sa.reference.inverse() @ sb.reference)
        t.append(dt)
        r.append(dr)
    return {
        "ate_mean": float(ate.mean()),
        "ate_max": float(ate.max()),
        "rel_max_m": float(max(t)),
        "rel_max_deg": float(math.degrees(max(r))),
    }


def run_one(
    profile: str,
    seed: int,
    odometry: bool,
    n_steps: int,
    deskew: bool = True,
    times="given",
    world: str = "office",
) -> dict:
    import dataclasses  # noqa: PLC0415

    from scanclique.mapping import MapConfig, map_scans  # noqa: PLC0415

    scans = drive(profile, seed, n_steps, times, world)
    cfg = MapConfig()
    cfg = dataclasses.replace(cfg, front_end=dataclasses.replace(cfg.front_end, deskew=deskew))
    t0 = time.perf_counter()
    res = map_scans(scans, use_odometry=odometry, config=cfg)
    wall = time.perf_counter() - t0
    c = res.counts()
    data_seconds = scans[-1].timestamp - scans[0].timestamp
    rec = {
        "profile": profile,
        "world": world,
        "seed": seed,
        "odometry": odometry,
        "deskew": deskew,
        "times": times,
        "sweep_timing": res.sweep_timing,
        "scans": len(scans),
        "data_seconds": data_seconds,
        "keyframes": c["keyframes"],
        "placed_by": {k: v for k, v in c["placed_by"].items() if v},
        "closures": c["loop_closures_accepted"],
        "wall": wall,
        "scans_per_s": len(scans) / wall,
        "realtime": wall / data_seconds,
        "stages": {k: round(v, 3) for k, v in res.seconds.items()},
        **errors(res, scans),
    }
    return rec


def _fmt_placed(recs) -> str:
    tot: dict[str, int] = {}
    for r in recs:
        for k, v in r["placed_by"].items():
            if k != "first":
                tot[k] = tot.get(k, 0) + v
    return " ".join(f"{k} {v}" for k, v in sorted(tot.items(), key=lambda kv: -kv[1]))


def table(records: list[dict]) -> list[str]:
    lines = [
        "| profile | odometry | scans | ATE mean (m) | ATE max mean / max (m) | rel max (m / deg) "
        "| placed by | closures | wall (s) | scans/s | s per s of data | front end ms/scan "
        "| loops ms/keyframe |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    keys = sorted(
        {(r["profile"], r.get("deskew", True), r["odometry"]) for r in records},
        key=lambda k: (list(PROFILES).index(k[0]), not k[1], not k[2]),
    )
    for prof, ds, odo in keys:
        rs = [
            r
            for r in records
            if (r["profile"], r.get("deskew", True), r["odometry"]) == (prof, ds, odo)
        ]
        scans = sum(r["scans"] for r in rs)
        wall = sum(r["wall"] for r in rs)
        front = sum(r["stages"]["prepare"] + r["stages"]["front_end"] for r in rs)
        back = sum(r["stages"][k] for r in rs for k in ("loops", "pcm", "isam", "optimize"))
        lines.append(
            f"| {prof}{'' if ds else ', raw'}{_published(rs)} | {'yes' if odo else 'no'} "
            f"| {scans} "
            f"| {np.mean([r['ate_mean'] for r in rs]):.3f} "
            f"| {np.mean([r['ate_max'] for r in rs]):.3f} / {max(r['ate_max'] for r in rs):.3f} "
            f"| {max(r['rel_max_m'] for r in rs):.3f} / {max(r['rel_max_deg'] for r in rs):.2f} "
            f"| {_fmt_placed(rs)} | {sum(r['closures'] for r in rs)} | {wall:.1f} "
            f"| {scans / wall:.0f} | {wall / sum(r['data_seconds'] for r in rs):.2f} "
            f"| {1000 * front / scans:.1f} | {1000 * back / sum(r['keyframes'] for r in rs):.1f} |"
        )
    return lines


def _published(recs) -> str:
    """``" (published negated, read negated)"``: how the drives' beam times were given
    and read, when not as measured."""
    times = recs[0].get("times", "given")
    if times == "given":
        return ""
    read = "/".join(sorted({r.get("sweep_timing") or "-" for r in recs}))
    return f" (published {times}, read {read})"


#: degradations of a real log's scans (module docstring)
VARIANTS = ("as-is", "range-5.6", "half-beams", "noise-3cm", "every-2nd-scan")


def degrade(scans: list, variant: str, seed: int = 0) -> list:
    """The scans of a real log as another scanner would give them (:data:`VARIANTS`)."""
    import dataclasses  # noqa: PLC0415

    if variant == "as-is":
        return list(scans)
    if variant == "every-2nd-scan":
        return list(scans[::2])
    rng = np.random.default_rng(seed)
    out = []
    for s in scans:
        if variant == "range-5.6":
            out.append(dataclasses.replace(s, range_max=min(s.range_max, 5.6)))
        elif variant == "half-beams":
            out.append(dataclasses.replace(s, ranges=s.ranges[::2], angles=s.angles[::2]))
        elif variant == "noise-3cm":
            r = np.where(s.valid, s.ranges + rng.normal(0.0, 0.03, s.ranges.shape), s.ranges)
            out.append(dataclasses.replace(s, ranges=r))
        else:
            raise ValueError(f"unknown variant {variant!r}; one of {', '.join(VARIANTS)}")
    return out


def run_real(name: str, scans0: list, rels, mounting, variant: str, odometry: bool) -> dict:
    """Map ``variant`` of the real log ``name`` and score it by its relations."""
    from scanclique.eval import relation_metrics  # noqa: PLC0415
    from scanclique.mapping import map_scans  # noqa: PLC0415

    scans = degrade(scans0, variant)
    t0 = time.perf_counter()
    res = map_scans(scans, use_odometry=None if odometry else False)
    wall = time.perf_counter() - t0
    m = relation_metrics(rels, list(res.poses), [s.timestamp for s in scans], mounting=mounting)
    c = res.counts()
    return {
        "log": name,
        "variant": variant,
        "odometry": odometry,
        "scans": len(scans),
        "metrics": m.to_dict(),
        "placed_by": {k: v for k, v in c["placed_by"].items() if v},
        "closures": c["loop_closures_accepted"],
        "wall": wall,
    }


def real_table(records: list[dict]) -> list[str]:
    lines = [
        "| log | variant | odometry | scans | relations (missing) | translation (m) "
        "| rotation (deg) | ≤10 s (m) | >10 s (m) | max (m) | placed by | closures | wall (s) |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in records:
        a, sh, lo = (r["metrics"][k] for k in ("all", "short", "long"))
        lines.append(
            f"| {r['log']} | {r['variant']} | {'yes' if r['odometry'] else 'no'} | {r['scans']} "
            f"| {a['n']} ({a['missing']}) "
            f"| {a['translation_mean']:.4f} ± {a['translation_std']:.4f} "
            f"| {a['rotation_mean']:.3f} ± {a['rotation_std']:.3f} | {sh['translation_mean']:.4f} "
            f"| {lo['translation_mean']:.4f} | {a['translation_max']:.3f} "
            f"| {_fmt_placed([r])} | {r['closures']} | {r['wall']:.1f} |"
        )
    return lines


def main_real(logs: list[str], variants: list[str], odos: list[bool], out_arg) -> None:
    from scanclique import datasets  # noqa: PLC0415
    from scanclique.eval import frame_mounting, read_relations  # noqa: PLC0415

    t0 = time.perf_counter()
    run_one("carmen", 100, True, 12)  # warm-up: numba kernels
    records = []
    for name in logs:
        scans0 = datasets.load_log(name)
        rels = read_relations(datasets.data_dir() / datasets.DATASETS[name].relations)
        mounting = frame_mounting(scans0)
        for variant in variants:
            for odo in odos:
                rec = run_real(name, scans0, rels, mounting, variant, odo)
                records.append(rec)
                print(real_table([rec])[-1], flush=True)
    lines = real_table(records)
    result = {"tag": TODAY, **provenance(t0), "records": records}
    about = (
        f"`map_scans` with its defaults on degraded scans of {', '.join(logs)}; the relation "
        "metric of `mapping.py` (robot frame, the laser's mounting taken into account). git "
        f"{(result['git']['commit'] or '?')[:7]}, {result['seconds']:.0f} s in all, load "
        f"{result['machine'].get('load_average')}."
    )
    title = "Mapping real logs with another scanner's limits (benchmarks/mapping_sensors.py --real)"
    write_results(out_arg, f"mapping-sensors-real-{TODAY}", result, title, about, lines, t0)


def write_results(out_arg, stem: str, result: dict, title: str, about: str, lines, t0) -> None:
    """``result`` as JSON and a Markdown page (``title``, ``about``, the table ``lines``)
    at ``--out`` or ``benchmarks/results/<stem>``."""
    out = results_path(out_arg, stem)
    if out.suffix in (".md", ".json"):
        out = out.with_suffix("")
    out.with_suffix(".json").write_text(json.dumps(result, indent=2) + "\n")
    md = [f"# {title}", "", about, "", *lines, ""]
    out.with_suffix(".md").write_text("\n".join(md) + "\n")
    print(f"wrote {out.with_suffix('.json')} and .md in {time.perf_counter() - t0:.0f} s")


def _progress(label: str, odo: bool, seed: int, rec: dict) -> None:
    print(
        f"{label:8s} odo={'yes' if odo else 'no ':3s} seed {seed}: {rec['scans']} scans"
        f" ATE mean {rec['ate_mean']:.3f} max {rec['ate_max']:.3f} m, rel max"
        f" {rec['rel_max_m']:.3f} m {rec['rel_max_deg']:.2f} deg,"
        f" {rec['placed_by']}, {rec['closures']} closures, {rec['wall']:.1f} s"
        f" ({rec['scans_per_s']:.0f} scans/s, {rec['realtime']:.2f} s/s)"
        + (f", beam times read {rec['sweep_timing']!r}" if rec.get("sweep_timing") else ""),
        flush=True,
    )


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--profiles", default=",".join(PROFILES))
    ap.add_argument("--seeds", default="0,1,2")
    ap.add_argument("--odometry", choices=("both", "yes", "no"), default="both")
    ap.add_argument("--steps", type=int, default=60, help="drive poses, 0.25 m apart")
    ap.add_argument(
        "--world",
        choices=WORLDS,
        default="office",
        help="indoors (sim.office_world) or outdoors (sim.campus_world)",
    )
    ap.add_argument("--out", default=None, help="path stem (default: benchmarks/results/...)")
    ap.add_argument("--real", default="", help="real logs to degrade instead (fr079-raw,...)")
    ap.add_argument("--variants", default=",".join(VARIANTS), help="with --real")
    ap.add_argument(
        "--deskew",
        choices=("both", "yes", "no"),
        default="both",
        help="the swept profiles mapped with the skew taken out, without, or both",
    )
    ap.add_argument(
        "--times",
        choices=tuple(PUBLISHED),
        default="given",
        help="the swept profiles' beam times published as measured or as other drivers do",
    )
    a = ap.parse_args(argv)
    odos = {"both": [True, False], "yes": [True], "no": [False]}[a.odometry]
    if a.real:
        variants = [v for v in a.variants.split(",") if v]
        for v in variants:
            if v not in VARIANTS:
                ap.error(f"unknown variant {v!r}; one of {', '.join(VARIANTS)}")
        main_real([x for x in a.real.split(",") if x], variants, odos, a.out)
        return
    profiles = [p for p in a.profiles.split(",") if p]
    seeds = [int(s) for s in a.seeds.split(",") if s]
    t0 = time.perf_counter()
    run_one("carmen", 100, True, 12)  # warm-up: numba kernels
    print(f"warm-up {time.perf_counter() - t0:.1f} s", flush=True)
    records = []
    deskews = {"both": [True, False], "yes": [True], "no": [False]}[a.deskew]
    for prof in profiles:
        for ds in deskews if "sweep" in PROFILES[prof] else [True]:
            for odo in odos:
                for seed in seeds:
                    rec = run_one(prof, seed, odo, a.steps, ds, a.times, a.world)
                    records.append(rec)
                    _progress(prof + ("" if ds else ", raw"), odo, seed, rec)
    lines = table(records)
    result = {
        "tag": TODAY,
        **provenance(t0),
        "profiles": PROFILES,
        "world": a.world,
        "steps": a.steps,
        "records": records,
    }
    about = (
        f"Simulated {a.world} drives ({a.steps} poses 0.25 m apart, seeds {a.seeds}), "
        "`map_scans` with and without odometry (the swept profiles also without de-skew: "
        "`, raw`). git "
        f"{(result['git']['commit'] or '?')[:7]}, {result['seconds']:.0f} s in all."
    )
    print("\n".join(lines))
    title = "Mapping on other laser scanners (benchmarks/mapping_sensors.py)"
    world = "" if a.world == "office" else f"{a.world}-"
    stem = f"mapping-sensors-{world}{TODAY}"
    write_results(a.out, stem, result, title, about, lines, t0)


if __name__ == "__main__":
    main()
