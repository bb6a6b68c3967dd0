"""Place recognition on scanners other than the shared logs' (issue 14, the general case).

One command::

    python benchmarks/places_sensors.py                  # every profile, 6 drives each
    python benchmarks/places_sensors.py --profiles sick180 --seeds 6

The shared logs all come from 180-degree SICK scanners. The project is judged on logs we
do not have, so this measures :class:`scanclique.places.PlaceDB`, with its defaults (and,
since session 40, one lost return bridged for a scanner that loses them, as ``scanclique
places add`` decides from a log: :func:`scanclique.features.for_scanner`), on
drives of our own simulator (``scanclique.sim.office_world``: rooms off corridors, many
of them alike, with exact reference poses) for the scanners people use today:

* ``carmen``: 180 deg, 361 beams, 30 m, sigma 1 cm (the shared logs' kind; the control);
* ``hokuyo``: 270 deg, 1081 beams, 30 m, sigma 2 cm (Hokuyo UTM-30LX class);
* ``tim571``: 270 deg, 811 beams, 25 m, sigma 2 cm (SICK TiM571 class);
* ``rplidar``: 360 deg, 360 beams, 10 m, sigma 1.5 % of the range, 7 % of beams without
  return (RPLIDAR A1 class);
* ``lds``: 360 deg, 360 beams, 3.5 m, sigma 1.5 % of the range, 5 % of beams without return
  (TurtleBot3's LDS-01; session 36: precision 0.965, rooms of one shape alike within reach).

These are ``benchmarks/mapping_sensors.py``'s scanners (its ``PROFILES``, one definition).

Each drive is 300 scans 0.3 m apart. Every scan is added; every second scan is queried
(``k=5``) against the places at least 50 scans away, the protocol of
``benchmarks/places.py``: a hit is right within 0.5 m and 0.2 rad of the reference; a query
has a true place when a scan at least 50 scans away lies within 2 m with at least 50 %
overlap (``scanclique.pairsets``' revisit rule). Precision is over the default answers
(the best hit when it is ``accepted``), recall over the queries with a true place. The
wrong answers are listed with their evidence (mapped features, clique surprise, the rival
pose's score over the hit's, free-space conflicts).

Results: ``benchmarks/results/places-sensors-2026-12-02-s10.{md,json}``; ``lds`` and
``rplidar`` again in ``places-sensors-2026-12-07-s36.{md,json}``. ``--world campus``
(session 39) rides ``scanclique.sim.campus_world`` instead, outdoors:
``places-sensors-campus-2026-12-07.{md,json}``; with the look-alike rule (session 40,
``scanclique.places.verify.look_alike``) ``places-sensors-campus-2026-12-07-s40.{md,json}``,
and a lost return bridged too (``scanclique.features.for_scanner``, not widened)
``places-sensors-campus-2026-12-07-s40b.{md,json}``, indoors
``places-sensors-2026-12-07-s40.{md,json}``.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from common import TODAY, git_state, machine, results_path, versions  # noqa: E402
from mapping_sensors import PROFILES as SCANNERS  # noqa: E402
from mapping_sensors import WORLDS, make_world  # noqa: E402
from places import RIGHT_R, RIGHT_T, true_places  # noqa: E402

#: the scanners of ``benchmarks/mapping_sensors.py`` (one definition), as one scan sees
#: them: its rate and the robot's speed do not matter to a place database (nor the swept
#: profiles, whose scans are skewed by a motion a place query does not know)
PROFILES = {
    name: {k: v for k, v in p.items() if k not in ("scan_rate", "speed")}
    for name, p in SCANNERS.items()
    if "sweep" not in p
}
N_SCANS = 300
STEP = 0.3
QUERY_EVERY = 2


def drive(profile: str, seed: int, tmp: Path, world: str = "office") -> dict:
    """Add one simulated drive's scans to a new database and query every second one; the
    drive rides ``world`` (``office`` or ``campus``, as in ``mapping_sensors.py``)."""
    from scanclique import sim
    from scanclique.features import for_scanner
    from scanclique.pairsets import REVISIT_MIN_GAP
    from scanclique.places import ACCEPTED, PlaceDB
    from scanclique.places.verify import rival_ratio

    rng = np.random.default_rng(100 + seed)
    place_world = make_world(world, rng)
    scans = sim.simulate_trajectory(rng, place_world, N_SCANS, step=STEP, **PROFILES[profile])
    n = len(scans)
    out = {"profile": profile, "seed": seed, "queries": 0, "with_true": 0, "accepted": 0}
    out.update(right=0, right_true=0, wrong=[], query_ms=[], add_ms=[])
    # the database as ``scanclique places add`` makes it from a log: the defaults, a lost
    # return bridged for a scanner that loses them (session 40), no edges where a wall
    # leaves the reach (session 42)
    config = for_scanner(None, scans, widen=False, reach_edges=False)
    with PlaceDB(tmp / f"{profile}-{seed}.db", config) as db:
        for s in scans:
            t = time.perf_counter()
            db.add(s)
            out["add_ms"].append(1e3 * (time.perf_counter() - t))
        queries = list(range(0, n, QUERY_EVERY))
        truth = true_places(scans, queries)
        for i in queries:
            exclude = range(max(1, i + 2 - REVISIT_MIN_GAP), min(n, i + REVISIT_MIN_GAP) + 1)
            t = time.perf_counter()
            hits = db.query(scans[i], k=5, exclude=exclude)
            out["query_ms"].append(1e3 * (time.perf_counter() - t))
            out["queries"] += 1
            out["with_true"] += bool(truth[i])
            if not hits or hits[0].verdict != ACCEPTED:
                continue
            h = hits[0]
            place = scans[h.place_id - 1]
            t_err, r_err = (place.reference @ h.pose).distance_to(scans[i].reference)
            ok = t_err <= RIGHT_T and r_err <= RIGHT_R
            out["accepted"] += 1
            out["right"] += ok
            out["right_true"] += ok and bool(truth[i])
            if not ok:
                out["wrong"].append(
                    {
                        "query": i,
                        "place": h.place_id - 1,
                        "error_m": round(t_err, 3),
                        "error_deg": round(math.degrees(r_err), 1),
                        "confidence": round(h.confidence, 4),
                        "score": round(h.score, 3),
                        "n_features": h.n_features,
                        "surprise": round(h.surprise, 2),
                        "rival_ratio": round(rival_ratio(h.score, h.rival_score), 2),
                        "conflict": round(h.conflict, 4),
                    }
                )
    return out


def summary(runs: list[dict]) -> dict:
    """Per-profile totals over its drives."""
    tot = {k: sum(r[k] for r in runs) for k in ("queries", "with_true", "accepted", "right")}
    tot["right_true"] = sum(r["right_true"] for r in runs)
    q = np.concatenate([r["query_ms"] for r in runs])
    a = np.concatenate([r["add_ms"] for r in runs])
    tot.update(
        profile=runs[0]["profile"],
        drives=len(runs),
        precision=tot["right"] / tot["accepted"] if tot["accepted"] else None,
        recall=tot["right_true"] / tot["with_true"] if tot["with_true"] else None,
        query_ms_median=float(np.median(q)),
        query_ms_p95=float(np.percentile(q, 95)),
        add_ms_median=float(np.median(a)),
        wrong=[dict(w, seed=r["seed"]) for r in runs for w in r["wrong"]],
    )
    return tot


def _f(v, fmt=".3f"):
    return "" if v is None else format(v, fmt)


def report(res: dict) -> str:
    lines = [
        f"# places on other scanners {res['date']}",
        "",
        f"`python benchmarks/places_sensors.py` at {res['git'].get('commit', '?')}, "
        f"{res['machine'].get('cpus', '?')} CPUs, {res['seconds']:.0f} s. Simulated "
        f"{res['args'].get('world', 'office')} "
        f"drives ({N_SCANS} scans, {STEP} m apart), every {QUERY_EVERY}nd scan queried "
        "against the places >= 50 scans away; PlaceDB defaults (a lost return bridged for a "
        "scanner that loses them, as `places add` decides).",
        "",
        "| scanner | drives | queries | with true place | accepted | precision | recall | "
        "query ms median | p95 | add ms median |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    for s in res["profiles"]:
        lines.append(
            f"| {s['profile']} | {s['drives']} | {s['queries']} | {s['with_true']} | "
            f"{s['accepted']} | {_f(s['precision'])} | {_f(s['recall'])} | "
            f"{s['query_ms_median']:.1f} | {s['query_ms_p95']:.1f} | {s['add_ms_median']:.2f} |"
        )
    wrong = [(s["profile"], w) for s in res["profiles"] for w in s["wrong"]]
    if wrong:
        lines += [
            "",
            "Wrong accepted answers:",
            "",
            "| scanner | seed | query | place | error m | error deg | confidence | score | "
            "features | surprise | rival ratio | conflict |",
            "|---|---|---|---|---|---|---|---|---|---|---|---|",
        ]
        for p, w in wrong:
            lines.append(
                f"| {p} | {w['seed']} | {w['query']} | {w['place']} | {w['error_m']} | "
                f"{w['error_deg']} | {w['confidence']} | {w['score']} | {w['n_features']} | "
                f"{w['surprise']} | {w['rival_ratio']} | {w['conflict']} |"
            )
    return "\n".join(lines) + "\n"


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--profiles", default=",".join(PROFILES))
    ap.add_argument("--seeds", type=int, default=6, help="drives per scanner")
    ap.add_argument("--out", default=None, help="results JSON (default benchmarks/results/)")
    ap.add_argument("--world", choices=WORLDS, default="office", help="indoors or outdoors")
    a = ap.parse_args(argv)
    profiles = a.profiles.split(",")
    unknown = [p for p in profiles if p not in PROFILES]
    if unknown:
        ap.error(f"unknown profile(s) {unknown}; known: {', '.join(PROFILES)}")
    stem = "places-sensors" if a.world == "office" else f"places-sensors-{a.world}"
    out_json = results_path(a.out, f"{stem}-{TODAY}.json")
    res = {
        "date": TODAY,
        "args": vars(a),
        "machine": machine(),
        "versions": versions(("numpy", "scipy", "numba")),
        "git": git_state(),
    }
    t0 = time.perf_counter()
    res["profiles"] = []
    with tempfile.TemporaryDirectory() as tmpd:
        for p in profiles:
            runs = []
            for seed in range(a.seeds):
                runs.append(drive(p, seed, Path(tmpd), a.world))
                el = time.perf_counter() - t0
                print(f"  {p} drive {seed}: done, {el:.0f} s", file=sys.stderr)
            res["profiles"].append(summary(runs))
    res["seconds"] = time.perf_counter() - t0
    out_json.parent.mkdir(parents=True, exist_ok=True)
    out_json.write_text(json.dumps(res, indent=1))
    md = report(res)
    out_json.with_suffix(".md").write_text(md)
    print(md)


if __name__ == "__main__":
    main()
