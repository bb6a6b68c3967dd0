"""Place recognition benchmark (issue 14): recognition, scale and scale-out of
``scanclique.places``.

One command::

    python benchmarks/places.py                      # the default run (~10 min here)
    python benchmarks/places.py --full               # every scan a query, full freiburg loops
    python benchmarks/places.py --stages recognition --logs intel --query-every 1

1. **Recognition**, the FLIRT / GFLIP protocol, per log (intel, csail, freiburg): every
   scan of the log is a place (:class:`scanclique.places.PlaceDB`, built by ``add``); a
   query (every ``--query-every``-th scan; all with ``--full``) is asked against all
   places at least 50 scans away (``exclude``), ``--candidates`` prefilter candidates
   verified (and ``--escalate`` more when none is accepted with confidence 0.99). Its
   answer is its best hit when that is ``accepted``; the answer is right when the
   place's reference pose composed with the hit's pose is within 0.5 m and 0.2 rad of
   the query's reference pose. A query *has a true place* when some scan at
   least 50 scans away is within 2 m with at least 50 % overlap under the reference
   (the revisit rule of :mod:`scanclique.pairsets`). Recall = right answers of queries
   with a true place / queries with a true place; precision = right answers / answers
   (all queries). Thresholding the answers by their confidence
   (:func:`scanclique.places.verify.confidence`; the query's hits ranked by it) gives the
   precision-recall curve (figure); reported: recall at 99 % and at 100 % precision (also
   with the answers thresholded by raw-scan score), precision and recall of every
   accepted answer and of those the defaults accept (score 0.3, confidence 0.99), the
   prefilter's recall at 10 and 50 candidates (a true place among them) for the fused
   prefilter the query uses and for each of its two rankings alone (signature distance;
   triangle votes, :mod:`scanclique.places.hashing`), and time per query.
   ``--calibrate`` fits the confidence's weights on the logs run and, leaving each log
   out, reports the curve on it under the others' fit. ``--search`` verifies with the
   matcher's raw-scan pose search
   (``PlaceDB(search=True)``; off by default). ``--degrade range-5.6`` (or
   ``half-beams``, ``noise-3cm``) runs it on every scan degraded to another scanner's
   limits (``benchmarks/mapping_sensors.py``'s variants: a 5.6 m range, every second
   beam, 3 cm more range noise), the protocol unchanged.
2. **Scale**: one database grown to 1k, 5k and 50k places (the logs' scans added again
   and again with distinct names): add time per place (features, signature and
   transaction), query time (``k=5``, five candidates verified, five more for a query
   with no confident answer among them; the query scan's own
   copies excluded; wall time, and the CPU time of the querying process, which a
   machine shared with other work inflates less) and the prefilter alone, median and
   p95, and the file size.
3. **Scale-out**: the all-pairs revisit search of freiburg 079
   (:func:`scanclique.places.loops.find_loops`, every ``--loops-every``-th scan; all with
   ``--full``) serially, over 2 local worker processes, and over a local Dask cluster of
   2 worker processes: wall time, speedup, and whether the results are identical.

Not in the default run (``--stages locate,ring``):

* **Localisation in a map** (``locate``, :func:`locate`): each log's first half mapped
  and stored as places with their mapped poses, every ``--query-every``-th scan of the
  second half located (``places locate``: recognition, then tracking), and the whole
  second half carried into the map (``--trajectory``).
* **Every corner alike** (``ring``, :func:`locate_ring`): the simulated ring corridor,
  located with tracking, 4 seeds with and without odometry.

Results: ``benchmarks/results/places-2026-12-04-s14.json`` / ``.md`` / ``.png``;
localisation ``places-2026-12-06-s34-locate.*`` (earlier
sessions: ``places-2026-12-04-s13.*``, ``places-2026-12-02-s9.*``, ``-s8.*``,
``places-2026-12-01*``); degraded scanners: ``places-degraded-2026-12-04-s14-<variant>.*``
(``-range-5.6-alias-rival.*``: after :data:`scanclique.places.verify.ALIAS_SURPRISE`).
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

LOGS = ("intel", "csail", "freiburg")
RIGHT_T = 0.5  # metres
RIGHT_R = 0.2  # radians


# ---------------------------------------------------------------------------------------
# 1. Recognition
# ---------------------------------------------------------------------------------------
def true_places(scans, queries) -> dict[int, set]:
    """For each query, the scans that are true places for it (the revisit rule)."""
    from scipy.spatial import cKDTree

    from scanclique.pairsets import (
        REVISIT_MAX_DISTANCE,
        REVISIT_MIN_GAP,
        REVISIT_MIN_OVERLAP,
        overlap,
        reference_pose,
    )

    pos = np.array([[s.reference.x, s.reference.y] for s in scans])
    tree = cKDTree(pos)
    out = {}
    for i in queries:
        near = [
            j
            for j in tree.query_ball_point(pos[i], REVISIT_MAX_DISTANCE)
            if abs(j - i) >= REVISIT_MIN_GAP
        ]
        out[i] = {
            j
            for j in sorted(near)
            if overlap(scans[j], scans[i], reference_pose(scans, j, i)) >= REVISIT_MIN_OVERLAP
        }
    return out


def pr_curve(answers: list[dict], n_true: int, key: str = "confidence") -> dict:
    """Precision and recall of the answers thresholded by ``key`` (``"confidence"``, the
    hits' :func:`scanclique.places.verify.confidence`, or ``"score"``, raw-scan score;
    best first)."""
    a = sorted(answers, key=lambda r: -r[key])
    right = np.array([r["right"] for r in a], dtype=float)
    counted = np.array([r["right"] and r["has_true"] for r in a], dtype=float)
    if not len(a):
        return {"precision": [], "recall": [], "threshold": [], "r99": 0.0, "r100": 0.0}
    prec = np.cumsum(right) / np.arange(1, len(a) + 1)
    rec = np.cumsum(counted) / max(1, n_true)
    # a threshold can only sit between distinct values
    last = np.r_[np.diff([r[key] for r in a]) != 0, True]
    prec, rec = prec[last], rec[last]
    thr = np.array([r[key] for r in a])[last]

    def at(p):
        ok = prec >= p - 1e-12
        return float(rec[ok].max()) if ok.any() else 0.0

    return {
        "precision": prec.tolist(),
        "recall": rec.tolist(),
        "threshold": thr.tolist(),
        "r99": at(0.99),
        "r100": at(1.0),
    }


#: the outcome of a query with a true place, in the order they are tested
OUTCOMES = (
    "right",
    "no true place verified",
    "true place: wrong pose accepted",
    "true place outranked by a wrong answer",
    "true place ambiguous",
    "true place: no pose",
    "true place: too few features",
    "true place: pose not fixed",
    "true place: rejected, other",
)


def miss_category(hits, true_rows: set, rec: dict, scans, q) -> str:
    """Why a query with a true place got (or missed) its right answer: the verified
    candidates' verdicts on its true places (the best verdict among them)."""
    if rec["right"]:
        return "right"
    mine = [h for h in hits if h.place_id - 1 in true_rows]
    if not mine:
        return "no true place verified"
    acc = [h for h in mine if h.verdict == "accepted"]
    if acc:
        for h in acc:
            t, r = (scans[h.place_id - 1].reference @ h.pose).distance_to(q.reference)
            if t <= RIGHT_T and r <= RIGHT_R:
                return "true place outranked by a wrong answer"
        return "true place: wrong pose accepted"
    if any(h.verdict == "ambiguous" for h in mine):
        return "true place ambiguous"
    reasons = " ".join(h.reason for h in mine)
    if "no pose" in reasons and all("no pose" in h.reason for h in mine):
        return "true place: no pose"
    if "fewer than" in reasons:
        return "true place: too few features"
    if "fix the pose" in reasons:
        return "true place: pose not fixed"
    return "true place: rejected, other"


def recognition(
    name: str,
    every: int,
    candidates: int,
    tmp: Path,
    progress=True,
    search=False,
    seeded=None,
    aliases=False,
    min_features=None,
    escalate=None,
    degrade=None,
    ceiling=False,
    mapped=False,
) -> dict:
    from scanclique.datasets import load_log
    from scanclique.features import for_scanner
    from scanclique.pairsets import REVISIT_MIN_GAP
    from scanclique.places import ACCEPTED, PlaceDB
    from scanclique.places.hashing import feature_triangles
    from scanclique.places.signature import scan_signature
    from scanclique.places.verify import (
        ACCEPT_MIN_CONFIDENCE,
        ACCEPT_MIN_FEATURES,
        ACCEPT_MIN_SCORE,
    )

    scans = load_log(name)
    if degrade:  # another scanner's limits (mapping_sensors.degrade); the protocol unchanged
        from mapping_sensors import degrade as degraded  # noqa: PLC0415

        scans = degraded(scans, degrade)
    n = len(scans)
    # every answer accepted (validation and min_features), thresholded by confidence (and
    # by score) below (the default min_score and min_confidence are one point of that)
    from scanclique.places.database import ESCALATE, SEEDED

    # the configuration ``scanclique places add`` gives a new database of the log (the
    # shared logs as recorded: the defaults; a degraded one may meet its reach)
    db = PlaceDB(
        tmp / f"{name}{'-mapped' if mapped else ''}.db",
        for_scanner(None, scans, widen=False, reach_edges=False),
        min_score=0.0,
        min_confidence=0.0,
        search=search,
        seeded=SEEDED if seeded is None else seeded,
        aliases=aliases,
        min_features=ACCEPT_MIN_FEATURES if min_features is None else min_features,
        escalate=ESCALATE if escalate is None else escalate,
    )
    map_poses, map_s = [None] * n, 0.0
    if mapped:  # --map: each place with its pose in the log's map (map_scans, as a robot has)
        from scanclique.io import odometry_is_reference
        from scanclique.mapping import map_scans

        t = time.perf_counter()
        map_poses = map_scans(
            scans, use_odometry=False if odometry_is_reference(scans) else None
        ).poses
        map_s = time.perf_counter() - t
    t = time.perf_counter()
    add_ms = []
    for k, s in enumerate(scans):
        t1 = time.perf_counter()
        pid = db.add(s, name=f"{name}:{k}", pose=map_poses[k])
        add_ms.append(1e3 * (time.perf_counter() - t1))
        assert pid == k + 1
    build_s = time.perf_counter() - t
    queries = list(range(0, n, every))
    truth = true_places(scans, queries)
    records, pre10, pre50, n_true = [], 0, 0, 0
    # each prefilter alone: the signature's nearest, the triangles' most votes
    alone = {"signature": [0, 0], "triangles": [0, 0]}
    ceil = dict.fromkeys(CEILING_KEYS, 0)  # --ceiling: the true places verified directly
    q_ms = []
    t0 = time.perf_counter()
    for qn, i in enumerate(queries):
        q = scans[i]
        exclude = range(max(1, i + 2 - REVISIT_MIN_GAP), min(n, i + REVISIT_MIN_GAP) + 1)
        p = db.prepare(q)
        ids, _ = db.candidates(p, n=50, exclude=exclude)
        rows = [int(x) - 1 for x in ids]
        has_true = bool(truth[i])
        if has_true:
            n_true += 1
            pre10 += bool(truth[i].intersection(rows[:10]))
            pre50 += bool(truth[i].intersection(rows[:50]))
            allowed = ~np.isin(db.index.ids, np.arange(exclude.start, exclude.stop))
            s_ids, _ = db.index.search(scan_signature(p), 50, allowed)
            tri = feature_triangles(p.features.points_xy, p.features.points_label)
            t_ids, _ = db.triangles.search(tri, 50, exclude)
            for key, got in (("signature", s_ids), ("triangles", t_ids)):
                r = [int(x) - 1 for x in got]
                alone[key][0] += bool(truth[i].intersection(r[:10]))
                alone[key][1] += bool(truth[i].intersection(r[:50]))
            if ceiling:
                for key, v in verifier_ceiling(db, scans, i, truth[i], p).items():
                    ceil[key] += v
        t1 = time.perf_counter()
        hits = db.query(p, k=candidates, candidates=candidates, exclude=exclude)
        q_ms.append(1e3 * (time.perf_counter() - t1))
        best = hits[0] if hits and hits[0].verdict == ACCEPTED else None
        rec = {
            "i": i,
            "has_true": has_true,
            "answered": best is not None,
            "right": False,
            "score": 0.0,
            "confidence": 0.0,
            "verdicts": [h.verdict for h in hits],
        }
        if best is not None:
            place = scans[best.place_id - 1]
            t_err, r_err = (place.reference @ best.pose).distance_to(q.reference)
            rec.update(
                place=best.place_id - 1,
                score=best.score,
                t_err=t_err,
                r_err=r_err,
                right=bool(t_err <= RIGHT_T and r_err <= RIGHT_R),
                rank=best.rank,
                n_features=best.n_features,
                votes=best.votes,
                source=best.source,
                confidence=best.confidence,
                surprise=best.surprise,
                rival_score=best.rival_score,
            )
        # every accepted hit's evidence and rightness, for --calibrate
        rec["accepted"] = [
            [h.score, h.surprise, h.rival_score, h.conflict, _is_right(scans[h.place_id - 1], h, q)]
            for h in hits
            if h.verdict == ACCEPTED
        ]
        if has_true:
            rec["outcome"] = miss_category(hits, truth[i], rec, scans, q)
        records.append(rec)
        if progress and (qn + 1) % 50 == 0:
            el = time.perf_counter() - t0
            print(f"  {name}: {qn + 1}/{len(queries)} queries, {el:.0f} s", file=sys.stderr)
    db.close()
    answers = [r for r in records if r["answered"]]
    curve = pr_curve(answers, n_true)
    by_score = pr_curve(answers, n_true, key="score")
    n_right = sum(r["right"] for r in answers)
    n_right_true = sum(r["right"] and r["has_true"] for r in answers)
    dflt = [
        r
        for r in answers
        if r["score"] >= ACCEPT_MIN_SCORE and r["confidence"] >= ACCEPT_MIN_CONFIDENCE
    ]
    d_right = sum(r["right"] for r in dflt)
    d_right_true = sum(r["right"] and r["has_true"] for r in dflt)
    return {
        "log": name + (" (mapped)" if mapped else ""),
        "mapped": mapped,
        "mapping_s": map_s,
        "scans": n,
        "queries": len(queries),
        "with_true_place": n_true,
        "candidates": candidates,
        "answered": len(answers),
        "right": n_right,
        "precision": n_right / len(answers) if answers else float("nan"),
        "recall": n_right_true / n_true if n_true else float("nan"),
        "default_min_score": ACCEPT_MIN_SCORE,
        "default_min_confidence": ACCEPT_MIN_CONFIDENCE,
        "default_answered": len(dflt),
        "default_precision": d_right / len(dflt) if dflt else float("nan"),
        "default_recall": d_right_true / n_true if n_true else float("nan"),
        "recall_at_99": curve["r99"],
        "recall_at_100": curve["r100"],
        "recall_at_99_by_score": by_score["r99"],
        "recall_at_100_by_score": by_score["r100"],
        "prefilter_recall_10": pre10 / n_true if n_true else float("nan"),
        "prefilter_recall_50": pre50 / n_true if n_true else float("nan"),
        **{
            f"{key}_recall_{at}": v[m] / n_true if n_true else float("nan")
            for key, v in alone.items()
            for m, at in enumerate((10, 50))
        },
        **(
            {f"ceiling_{k}": v / n_true if n_true else float("nan") for k, v in ceil.items()}
            if ceiling
            else {}
        ),
        "outcomes": {k: sum(r.get("outcome") == k for r in records) for k in OUTCOMES},
        "query_ms_median": float(np.median(q_ms)),
        "query_ms_p95": float(np.percentile(q_ms, 95)),
        "add_ms_median": float(np.median(add_ms)),
        "build_s": build_s,
        "wrong": [r for r in answers if not r["right"]],
        "answers": [
            {
                k: r.get(k)
                for k in (
                    "i",
                    "place",
                    "has_true",
                    "right",
                    "score",
                    "confidence",
                    "surprise",
                    "rival_score",
                    "n_features",
                    "rank",
                    "votes",
                    "source",
                    "t_err",
                    "r_err",
                )
            }
            for r in answers
        ],
        "accepted_hits": [[r["has_true"], r["accepted"]] for r in records if r["accepted"]],
        "curve": {k: curve[k] for k in ("precision", "recall", "threshold")},
    }


# ---------------------------------------------------------------------------------------
# 1b. Localisation in a map (places locate)
# ---------------------------------------------------------------------------------------
def locate(
    name: str, every: int, candidates: int, tmp: Path, progress=True, figure: Path | None = None
) -> dict:
    """Relocalisation in a known map: the first half of the log mapped (``map_scans``) and
    every scan of it stored as a place with its mapped pose; every ``every``-th scan of
    the second half localised by :func:`scanclique.places.run.run_locate` (each on its
    own, no prior). A located scan is right when its map pose, carried into the
    reference frame by the rigid motion that best maps the places' mapped positions onto
    their reference positions (``geometry.align_se2``), is within 0.5 m and 0.2 rad of
    its reference pose. Recall over the queries with a true place among the first half
    (the revisit rule); precision over all located queries."""
    from scanclique.datasets import load_log
    from scanclique.geometry import Pose2, align_se2
    from scanclique.io import odometry_is_reference
    from scanclique.mapping import map_scans
    from scanclique.places.run import LOCATED, TRACKED, run_add, run_locate

    scans = load_log(name)
    n, half = len(scans), len(scans) // 2
    first = scans[:half]
    t = time.perf_counter()
    # a log whose odometry fields repeat the reference is mapped from the scans alone
    odometry = False if odometry_is_reference(scans) else None
    mapped = map_scans(first, use_odometry=odometry).poses
    map_s = time.perf_counter() - t
    path = tmp / f"{name}-locate.db"
    run_add(path, first, poses=list(mapped))
    ok = [k for k in range(half) if mapped[k] is not None]
    src = np.array([[mapped[k].x, mapped[k].y] for k in ok])
    dst = np.array([[scans[k].reference.x, scans[k].reference.y] for k in ok])
    Rm, tr, ang = align_se2(src, dst)
    to_ref = Pose2(float(tr[0]), float(tr[1]), ang)
    fit = np.hypot(*(src @ Rm.T + tr - dst).T)
    queries = list(range(half, n, every))
    truth = {i: {j for j in js if j < half} for i, js in true_places(scans, queries).items()}
    t = time.perf_counter()
    run = run_locate(
        path, scans, start=half, every=every, candidates=candidates, whole=True, track=True,
        use_odometry=odometry,
    )  # fmt: skip
    seconds = time.perf_counter() - t
    # the whole second half, carried into the map by its located scans, in the reference
    # frame; and its own map's shape error (the best rigid alignment to the reference)
    whole = [(i, q) for i, q in zip(run.trajectory_indices, run.trajectory, strict=True) if q]
    ate = np.array([(to_ref @ q).distance_to(scans[i].reference)[0] for i, q in whole])
    if len(whole) >= 2:
        own = np.array([[q.x, q.y] for _, q in whole])
        ref = np.array([[scans[i].reference.x, scans[i].reference.y] for i, _ in whole])
        R2, t2, _ = align_se2(own, ref)
        shape = np.hypot(*(own @ R2.T + t2 - ref).T)
    else:
        shape = np.full(1, np.nan)
    count = {s: [0, 0, 0] for s in (LOCATED, TRACKED)}  # placed, right, right with a true place
    errors = {LOCATED: [], TRACKED: []}
    for i, status, pose, pid in zip(run.indices, run.status, run.poses, run.places, strict=True):
        if status not in count:
            continue
        k = pid - 1  # the place: scan k of the first half (added in order)
        rel = mapped[k].inverse() @ pose  # the hit's pose: the query in the place's frame
        ok_i = _right_pose(scans[k], rel, scans[i])
        c = count[status]
        c[0], c[1], c[2] = c[0] + 1, c[1] + ok_i, c[2] + (ok_i and bool(truth[i]))
        if ok_i:  # where the map puts it: the map's own error included
            errors[status].append((to_ref @ pose).distance_to(scans[i].reference))
    located, right, right_true = count[LOCATED]
    tracked, t_right, t_right_true = count[TRACKED]
    n_true = sum(bool(v) for v in truth.values())
    e = np.array(errors[LOCATED]) if errors[LOCATED] else np.full((1, 2), np.nan)
    e2 = np.array(errors[TRACKED]) if errors[TRACKED] else np.full((1, 2), np.nan)
    if figure is not None:  # in the reference frame: the first half's map carried there
        from scanclique.plot import plot_located

        plot_located(
            figure,
            [to_ref @ p for p in run.place_poses],
            [None if p is None else to_ref @ p for p in run.poses],
            [None if p is None else to_ref @ p for p in run.trajectory],
            f"{name}: the second half located in the first half's map",
            tracked=[s == TRACKED for s in run.status],
        )
    if progress:
        print(
            f"  {name}: located {located}, tracked {tracked} ({tracked - t_right} wrong) "
            f"of {len(queries)}",
            file=sys.stderr,
        )
    return {
        "log": name,
        "places": half,
        "queries": len(queries),
        "with_true_place": n_true,
        "located": located,
        "right": right,
        "wrong": located - right,
        "precision": right / located if located else float("nan"),
        "recall": right_true / n_true if n_true else float("nan"),
        "doubtful": run.count("ambiguous"),
        "tracked": tracked,
        "tracked_right": t_right,
        "tracked_wrong": tracked - t_right,
        "tracked_precision": t_right / tracked if tracked else float("nan"),
        "recall_tracking": (right_true + t_right_true) / n_true if n_true else float("nan"),
        "placed_fraction": (located + tracked) / len(queries),
        "tracked_error_median_m": float(np.median(e2[:, 0])),
        "tracked_error_median_deg": float(np.degrees(np.median(e2[:, 1]))),
        "track_ms_mean": float(np.mean(run.track_ms)),
        "error_median_m": float(np.median(e[:, 0])),
        "error_median_deg": float(np.degrees(np.median(e[:, 1]))),
        "map_fit_rms_m": float(np.sqrt(np.mean(fit**2))),
        "anchor_inliers": run.anchor_inliers if run.anchor is not None else 0,
        "bent": run.bent,
        "whole_placed": len(whole),
        "whole_ate_rms_m": float(np.sqrt(np.mean(ate**2))) if len(ate) else float("nan"),
        "whole_ate_max_m": float(ate.max()) if len(ate) else float("nan"),
        "whole_shape_rms_m": float(np.sqrt(np.mean(shape**2))),
        "mapping_s": map_s,
        "query_ms_median": float(np.median(run.query_ms)),
        "query_ms_p95": float(np.percentile(run.query_ms, 95)),
        "seconds": seconds,
    }


def locate_ring(seed: int, odometry: bool, every: int, tmp: Path) -> dict:
    """Localisation where every corner looks alike (``sim.simulate_ring_drive``: a 60 x
    40 m ring corridor driven twice): the first lap's every 4th scan stored as a place at
    its true pose, every ``every``-th scan of the second lap located with tracking
    (``run_locate(track=True)``, the run's own map with or without its odometry). Right
    within 0.5 m and 0.2 rad of the true pose."""
    from scanclique.places.run import LOCATED, TRACKED, run_add, run_locate
    from scanclique.sim import simulate_ring_drive

    scans = simulate_ring_drive(np.random.default_rng(seed), loops=2.0)
    half = len(scans) // 2
    start = scans[0].reference.inverse()
    truth = [start @ s.reference for s in scans]
    path = tmp / f"ring-{seed}-{odometry}.db"
    first = list(range(0, half, 4))
    run_add(path, [scans[k] for k in first], poses=[truth[k] for k in first])
    run = run_locate(
        path, scans, start=half, every=every, track=True, use_odometry=None if odometry else False
    )
    out = {"seed": seed, "odometry": odometry, "queries": len(run.indices)}
    for status in (LOCATED, TRACKED):
        got = [(i, p) for i, s, p in zip(run.indices, run.status, run.poses, strict=True)
               if s == status]  # fmt: skip
        right = sum(
            p.distance_to(truth[i])[0] <= RIGHT_T and p.distance_to(truth[i])[1] <= RIGHT_R
            for i, p in got
        )
        out[status] = {"placed": len(got), "right": right, "wrong": len(got) - right}
    out["contested"] = int(sum(run.contested))
    return out


#: ``--ceiling``: a query's true places verified directly (bypassing the prefilter), the
#: most overlapping first
CEILING_PLACES = 3
CEILING_KEYS = ("verify_1", "verify_3", "verify_3_sure", "search_1", "either_1")


def verifier_ceiling(db, scans, i: int, true_rows: set, p) -> dict[str, bool]:
    """What the verification can recognise for query ``i`` when the prefilter is
    bypassed: its :data:`CEILING_PLACES` true places of largest overlap under the
    reference, each verified by :meth:`scanclique.places.PlaceDB.verify` (the clique
    matcher and the validation, as a query verifies a candidate). ``verify_1`` /
    ``verify_3``: the most overlapping one / any of them accepted with a right pose;
    ``verify_3_sure``: also with confidence >= 0.99; ``search_1``: the matcher's raw-scan
    pose search (:func:`scanclique.match.search_pose`, no features, no decision) finds the
    right pose of the most overlapping one; ``either_1``: ``verify_1`` or ``search_1``.
    Recall can reach ``verify_3`` with a perfect prefilter and the verification as it is;
    the gap to ``search_1`` is revisits whose pose the raw scans give but nothing decides
    without a prior."""
    from scanclique.match import search_pose
    from scanclique.pairsets import overlap, reference_pose
    from scanclique.places import ACCEPTED
    from scanclique.places.verify import ACCEPT_MIN_CONFIDENCE

    q = scans[i]
    best = sorted(true_rows, key=lambda j: (-overlap(scans[j], q, reference_pose(scans, j, i)), j))
    right, sure = [], []
    for j in best[:CEILING_PLACES]:
        v = db.verify(j + 1, p)
        ok = v.verdict == ACCEPTED and _right_pose(scans[j], v.pose, q)
        right.append(ok)
        sure.append(ok and v.confidence >= ACCEPT_MIN_CONFIDENCE)
    found = search_pose(db.prepared(best[0] + 1), p, db.config)
    searched = found is not None and _right_pose(scans[best[0]], found[0], q)
    return {
        "verify_1": right[0],
        "verify_3": any(right),
        "verify_3_sure": any(sure),
        "search_1": searched,
        "either_1": right[0] or searched,
    }


def _right_pose(place, pose, q) -> bool:
    """Whether ``pose`` (maps the query into the place's frame) puts the query within
    the protocol's tolerance of its reference pose."""
    t_err, r_err = (place.reference @ pose).distance_to(q.reference)
    return bool(t_err <= RIGHT_T and r_err <= RIGHT_R)


def _is_right(place, hit, q) -> bool:
    return _right_pose(place, hit.pose, q)


# ---------------------------------------------------------------------------------------
# Calibration of the hit confidence (places.verify.CONFIDENCE_WEIGHTS)
# ---------------------------------------------------------------------------------------
#: the last column of an accepted hit's evidence row: whether its pose is right
RIGHT = -1


def _evidence(rows) -> np.ndarray:
    """``(score, surprise, rival ratio, conflict)`` rows of accepted hits ``[score,
    surprise, rival_score, conflict, right]``, as
    :func:`scanclique.places.verify.confidence` reads them."""
    from scanclique.places.verify import rival_ratio

    return np.array(
        [(float(r[0]), float(r[1]), rival_ratio(r[0], r[2]), float(r[3])) for r in rows],
        dtype=float,
    ).reshape(-1, 4)


def fit_logistic(X: np.ndarray, y: np.ndarray, lam: float = 1e-2) -> np.ndarray:
    """L2-regularised logistic regression by Newton's method on standardised columns:
    ``(w0, w1, ...)`` with log-odds ``w0 + X @ w[1:]`` (the intercept not penalised)."""
    mu, sd = X.mean(axis=0), X.std(axis=0) + 1e-9
    Z = np.c_[np.ones(len(X)), (X - mu) / sd]
    w = np.zeros(Z.shape[1])
    pen = lam * np.r_[0.0, np.ones(Z.shape[1] - 1)]
    for _ in range(100):
        p = 1.0 / (1.0 + np.exp(-Z @ w))
        step = np.linalg.solve(
            (Z * (p * (1 - p))[:, None]).T @ Z + np.diag(pen), Z.T @ (p - y) + pen * w
        )
        w -= step
        if np.abs(step).max() < 1e-10:
            break
    return np.r_[w[0] - (w[1:] * mu / sd).sum(), w[1:] / sd]


def calibrate(rec: list[dict]) -> dict:
    """The confidence model fitted on all logs' accepted hits, and leave one log out: for
    each log, the model fitted on the others, its answers (per query the accepted hit of
    highest confidence) thresholded by that model on the log left out."""
    from scanclique.places.verify import ACCEPT_MIN_CONFIDENCE

    def data(logs):
        rows = [h for r in rec if r["log"] in logs for _, hs in r["accepted_hits"] for h in hs]
        return _evidence(rows), np.array([h[RIGHT] for h in rows], dtype=float)

    logs = [r["log"] for r in rec]
    X, y = data(logs)
    out = {"all": {"weights": fit_logistic(X, y).tolist(), "hits": len(y), "right": int(y.sum())}}
    for r in rec:
        w = fit_logistic(*data([x for x in logs if x != r["log"]]))
        answers = []
        for has_true, hs in r["accepted_hits"]:
            z = w[0] + _evidence(hs) @ w[1:]
            k = int(np.argmax(z))
            conf = 1.0 / (1.0 + np.exp(-z[k]))
            answers.append({"confidence": conf, "right": hs[k][RIGHT], "has_true": has_true})
        c = pr_curve(answers, r["with_true_place"])
        d = [a for a in answers if a["confidence"] >= ACCEPT_MIN_CONFIDENCE]
        out[r["log"]] = {
            "weights": w.tolist(),
            "recall_at_99": c["r99"],
            "recall_at_100": c["r100"],
            "default_answered": len(d),
            "default_precision": sum(a["right"] for a in d) / len(d) if d else float("nan"),
            "default_recall": sum(a["right"] and a["has_true"] for a in d)
            / max(1, r["with_true_place"]),
        }
    return out


# ---------------------------------------------------------------------------------------
# 2. Scale
# ---------------------------------------------------------------------------------------
def scale(sizes: list[int], n_queries: int, tmp: Path, progress=True) -> list[dict]:
    from scanclique.datasets import load_log
    from scanclique.places import PlaceDB

    pool = [
        (name, k, s)
        for name in ("freiburg", "intel", "csail")
        for k, s in enumerate(load_log(name))
    ]
    rng = np.random.default_rng(0)
    qidx = rng.choice(len(pool), size=n_queries, replace=False)
    path = tmp / "scale.db"
    db = PlaceDB(path)
    out, added = [], 0
    for size in sizes:
        add_ms = []
        t0 = time.perf_counter()
        while added < size:
            name, k, s = pool[added % len(pool)]
            t = time.perf_counter()
            db.add(s, name=f"{name}:{k}#{added // len(pool)}")
            add_ms.append(1e3 * (time.perf_counter() - t))
            added += 1
            if progress and added % 5000 == 0:
                print(f"  scale: {added} places, {time.perf_counter() - t0:.0f} s", file=sys.stderr)
        # queries from a second connection, as a reader would
        reader = PlaceDB(path, readonly=True)
        q_ms, pre_ms, q_cpu = [], [], []
        for qi in qidx:
            s = pool[int(qi)][2]
            # the query's own copies (place ids qi + 1 + m * len(pool)) are left out: a
            # query is a new observation, not one of the stored ones
            own = range(int(qi) + 1, added + 1, len(pool))
            t, c = time.perf_counter(), time.process_time()
            reader.query(s, k=5, exclude=own)
            q_ms.append(1e3 * (time.perf_counter() - t))
            q_cpu.append(1e3 * (time.process_time() - c))
            p = reader.prepare(s)
            t = time.perf_counter()
            reader.candidates(p, n=5, exclude=own)
            pre_ms.append(1e3 * (time.perf_counter() - t))
        reader.close()
        st = db.store.stats()
        out.append(
            {
                "places": size,
                "add_ms_median": float(np.median(add_ms)),
                "add_ms_p95": float(np.percentile(add_ms, 95)),
                "query_ms_median": float(np.median(q_ms)),
                "query_ms_p95": float(np.percentile(q_ms, 95)),
                "query_cpu_ms_median": float(np.median(q_cpu)),
                "query_cpu_ms_p95": float(np.percentile(q_cpu, 95)),
                "prefilter_ms_median": float(np.median(pre_ms)),
                "prefilter_ms_p95": float(np.percentile(pre_ms, 95)),
                "file_mb": (st["file_bytes"] + st["wal_bytes"]) / 1e6,
                "bytes_per_place": (st["file_bytes"] + st["wal_bytes"]) / size,
            }
        )
        if progress:
            print(f"  scale: {out[-1]}", file=sys.stderr)
    db.close()
    return out


# ---------------------------------------------------------------------------------------
# 3. Scale-out
# ---------------------------------------------------------------------------------------
def scale_out(every: int, candidates: int, workers: int) -> dict:
    from distributed import LocalCluster

    from scanclique.datasets import load_log
    from scanclique.places.loops import find_loops

    scans = load_log("freiburg")[::every]
    min_gap = max(1, math.ceil(50 / every))
    # warm up the compiled kernels and caches in this process
    find_loops(scans[: min_gap + 5], candidates=1, min_gap=min_gap)
    runs = {}
    t = time.perf_counter()
    runs["serial"] = find_loops(scans, candidates=candidates, min_gap=min_gap)
    runs["serial"].seconds["wall"] = time.perf_counter() - t
    t = time.perf_counter()
    runs["processes"] = find_loops(scans, candidates=candidates, min_gap=min_gap, workers=workers)
    runs["processes"].seconds["wall"] = time.perf_counter() - t
    with LocalCluster(
        n_workers=workers, threads_per_worker=1, processes=True, dashboard_address=":0"
    ) as cluster:
        t = time.perf_counter()
        runs["dask"] = find_loops(
            scans, candidates=candidates, min_gap=min_gap, scheduler=cluster.scheduler_address
        )
        runs["dask"].seconds["wall"] = time.perf_counter() - t
    ref = runs["serial"].keys()
    base = runs["serial"].seconds["wall"]
    return {
        "scans": len(scans),
        "every": every,
        "min_gap": min_gap,
        "candidates": candidates,
        "pairs": len(ref),
        "accepted": len(runs["serial"].accepted),
        "workers": workers,
        "runs": {
            k: {
                "backend": r.backend,
                "workers": r.workers,
                "wall_s": r.seconds["wall"],
                "seconds": r.seconds,
                "speedup": base / r.seconds["wall"],
                "identical": r.keys() == ref,
            }
            for k, r in runs.items()
        },
    }


# ---------------------------------------------------------------------------------------
# Report
# ---------------------------------------------------------------------------------------
def _f(v, fmt=".3f"):
    return "n/a" if v is None or (isinstance(v, float) and not math.isfinite(v)) else format(v, fmt)


def report(res: dict) -> str:
    from scanclique.places.verify import ACCEPT_MIN_SCORE

    lines = []
    if "recognition" in res:
        lines += [
            "## Recognition (FLIRT/GFLIP protocol: all places >= 50 scans away; "
            "right: 0.5 m, 0.2 rad)",
            "",
            "| log | queries | with true place | accepted (any score) | precision | recall | "
            f"default (score >= {ACCEPT_MIN_SCORE:g}, confidence >= 0.99): precision | recall | "
            "recall@99%P | "
            "recall@100%P | by score: recall@99%P | @100%P | "
            "prefilter recall@10 | @50 | signature alone @10 | @50 | triangles alone @10 | "
            "@50 | query ms median | p95 |",
            "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|",
        ]
        for r in res["recognition"]:
            lines.append(
                f"| {r['log']} | {r['queries']} | {r['with_true_place']} | {r['answered']} | "
                f"{_f(r['precision'])} | {_f(r['recall'])} | {_f(r['default_precision'])} | "
                f"{_f(r['default_recall'])} | {_f(r['recall_at_99'])} | "
                f"{_f(r['recall_at_100'])} | {_f(r.get('recall_at_99_by_score'))} | "
                f"{_f(r.get('recall_at_100_by_score'))} | {_f(r['prefilter_recall_10'])} | "
                f"{_f(r['prefilter_recall_50'])} | {_f(r.get('signature_recall_10'))} | "
                f"{_f(r.get('signature_recall_50'))} | {_f(r.get('triangles_recall_10'))} | "
                f"{_f(r.get('triangles_recall_50'))} | {_f(r['query_ms_median'], '.1f')} | "
                f"{_f(r['query_ms_p95'], '.1f')} |"
            )
        lines.append("")
        if all("outcomes" in r for r in res["recognition"]):
            lines += [
                "Queries with a true place, by outcome (the verified candidates' verdicts on "
                "the query's true places):",
                "",
                "| outcome | " + " | ".join(r["log"] for r in res["recognition"]) + " |",
                "|---|" + "---|" * len(res["recognition"]),
            ]
            for k in OUTCOMES:
                lines.append(
                    f"| {k} | "
                    + " | ".join(str(r["outcomes"].get(k, 0)) for r in res["recognition"])
                    + " |"
                )
            lines.append("")
        if all("ceiling_verify_3" in r for r in res["recognition"]):
            lines += [
                f"The prefilter bypassed (`--ceiling`): each query with a true place verified "
                f"against its {CEILING_PLACES} true places of largest overlap directly, as a "
                "query verifies a candidate (fraction of the queries with a true place; "
                "recall could reach `any of 3` with a perfect prefilter):",
                "",
                "| log | most overlapping accepted, right | any of 3 | any of 3 with "
                "confidence >= 0.99 | raw-scan search right (no decision) | either |",
                "|---|---|---|---|---|---|",
            ]
            for r in res["recognition"]:
                lines.append(
                    f"| {r['log']} | "
                    + " | ".join(_f(r["ceiling_" + k]) for k in CEILING_KEYS)
                    + " |"
                )
            lines.append("")
    if "locate" in res:
        lines += [
            "## Localisation in a map (`places locate`: the first half mapped and stored as "
            "places with their mapped poses; the second half's queries each on its own; "
            "right: the pose relative to the place within 0.5 m, 0.2 rad; the error in the "
            "reference frame includes the map's)",
            "",
            "| log | places | queries | with true place | located | right | wrong | "
            "precision | recall | ambiguous, not tracked | "
            "right: median error in the reference frame m | deg | map fit RMS m | "
            "query ms median | p95 |",
            "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|",
        ]
        tail = [
            "",
            "The whole second half mapped on its own (`map_scans`) and carried into the "
            "database's map by the rigid motion its located and tracked scans agree on "
            "(`run_locate(whole=True)`, `--trajectory`); its error in the reference frame, "
            "and the least any rigid motion leaves of it (its own map's shape):",
            "",
            "| log | scans placed | located or tracked scans agreeing | bent onto all | "
            "error RMS m | max m | best rigid alignment RMS m |",
            "|---|---|---|---|---|---|---|",
        ]
        track = [
            "",
            "Tracking (`run_locate(track=True)`, `--track`): a queried scan recognition does "
            "not locate, predicted from the last scan placed by the run's own online map and "
            "matched against the places near the prediction with it as the prior:",
            "",
            "| log | queries | located | tracked | right | wrong | precision | "
            "recall, located or tracked | placed | right: median error m | deg | "
            "tracking ms per scan, mean |",
            "|---|---|---|---|---|---|---|---|---|---|---|---|",
        ]
        for r in res["locate"]:
            if "tracked" not in r:
                continue
            track.append(
                f"| {r['log']} | {r['queries']} | {r['located']} | {r['tracked']} | "
                f"{r['tracked_right']} | {r['tracked_wrong']} | {_f(r['tracked_precision'])} | "
                f"{_f(r['recall_tracking'])} | {_f(r['placed_fraction'])} | "
                f"{_f(r['tracked_error_median_m'])} | "
                f"{_f(r['tracked_error_median_deg'], '.2f')} | "
                f"{_f(r['track_ms_mean'], '.1f')} |"
            )
        for r in res["locate"]:
            tail.append(
                f"| {r['log']} | {r['whole_placed']} | {r['anchor_inliers']} | "
                f"{({True: 'yes', False: 'no'}).get(r.get('bent'), '')} | "
                f"{_f(r['whole_ate_rms_m'])} | {_f(r['whole_ate_max_m'])} | "
                f"{_f(r['whole_shape_rms_m'])} |"
            )
        tail += track
        for r in res["locate"]:
            lines.append(
                f"| {r['log']} | {r['places']} | {r['queries']} | {r['with_true_place']} | "
                f"{r['located']} | {r['right']} | {r['wrong']} | {_f(r['precision'])} | "
                f"{_f(r['recall'])} | {r['doubtful']} | {_f(r['error_median_m'])} | "
                f"{_f(r['error_median_deg'], '.2f')} | {_f(r['map_fit_rms_m'])} | "
                f"{_f(r['query_ms_median'], '.1f')} | {_f(r['query_ms_p95'], '.1f')} |"
            )
        lines += tail + [""]
    if "ring" in res:
        lines += [
            "## Localisation where every corner looks alike (`--stages ring`: "
            "`sim.simulate_ring_drive`, the first lap's every 4th scan a place at its true "
            "pose, the second lap located with tracking; right within 0.5 m, 0.2 rad)",
            "",
            "| seed | odometry | queries | located | right | wrong | tracked | right | wrong | "
            "tracked, though recognised elsewhere |",
            "|---|---|---|---|---|---|---|---|---|---|",
        ]
        for r in res["ring"]:
            lo, tr = r["located"], r["tracked"]
            lines.append(
                f"| {r['seed']} | {'yes' if r['odometry'] else 'no'} | {r['queries']} | "
                f"{lo['placed']} | {lo['right']} | {lo['wrong']} | {tr['placed']} | "
                f"{tr['right']} | {tr['wrong']} | {r['contested']} |"
            )
        lines.append("")
    if "scale" in res:
        lines += [
            "## Scale (one database grown; queries k=5 from a second connection)",
            "",
            "| places | add ms median | add ms p95 | query ms median | query ms p95 | "
            "query CPU ms median | p95 | prefilter ms median | prefilter ms p95 | file MB | "
            "bytes/place |",
            "|---|---|---|---|---|---|---|---|---|---|---|",
        ]
        for r in res["scale"]:
            lines.append(
                f"| {r['places']} | {_f(r['add_ms_median'], '.2f')} | "
                f"{_f(r['add_ms_p95'], '.2f')} | "
                f"{_f(r['query_ms_median'], '.1f')} | {_f(r['query_ms_p95'], '.1f')} | "
                f"{_f(r.get('query_cpu_ms_median'), '.1f')} | "
                f"{_f(r.get('query_cpu_ms_p95'), '.1f')} | "
                f"{_f(r['prefilter_ms_median'], '.2f')} | {_f(r['prefilter_ms_p95'], '.2f')} | "
                f"{_f(r['file_mb'], '.1f')} | {_f(r['bytes_per_place'], '.0f')} |"
            )
        lines.append("")
    if "scale_out" in res:
        s = res["scale_out"]
        lines += [
            f"## Scale-out: freiburg all-pairs revisit search ({s['scans']} scans, every "
            f"{s['every']}, min gap {s['min_gap']}, {s['candidates']} candidates: {s['pairs']} "
            f"pairs, {s['accepted']} accepted)",
            "",
            "| backend | workers | wall s | speedup | identical to serial |",
            "|---|---|---|---|---|",
        ]
        for k, r in s["runs"].items():
            lines.append(
                f"| {k} | {r['workers']} | {_f(r['wall_s'], '.1f')} | {_f(r['speedup'], '.2f')} | "
                f"{r['identical']} |"
            )
        lines.append("")
    return "\n".join(lines)


def figure(rec: list[dict], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(5.5, 4.2))
    for r in rec:
        c = r["curve"]
        ax.plot(
            c["recall"],
            c["precision"],
            marker=".",
            ms=3,
            label=f"{r['log']} (r@99% {r['recall_at_99']:.2f})",
        )
    ax.set_xlabel("recall (queries with a true place)")
    ax.set_ylabel("precision (accepted answers)")
    ax.set_xlim(0, 1)
    ax.set_ylim(0.8, 1.005)
    ax.axhline(0.99, color="grey", lw=0.5, ls="--")
    ax.grid(alpha=0.3)
    ax.legend(loc="lower left")
    ax.set_title("scanclique places: answers thresholded by confidence")
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument(
        "--stages",
        default="recognition,scale,scale_out",
        help="of recognition, locate, ring, scale, scale_out",
    )
    ap.add_argument("--logs", default=",".join(LOGS))
    ap.add_argument("--query-every", type=int, default=3, help="every n-th scan is a query")
    ap.add_argument("--candidates", type=int, default=5, help="candidates verified per query")
    ap.add_argument("--sizes", default="1000,5000,50000")
    ap.add_argument("--scale-queries", type=int, default=60)
    ap.add_argument("--loops-every", type=int, default=3)
    ap.add_argument("--loops-candidates", type=int, default=3)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument(
        "--search",
        action="store_true",
        help="recognition: let the matcher search the pose on raw scans (PlaceDB search=True)",
    )
    ap.add_argument(
        "--seeded",
        type=int,
        default=None,
        help="recognition: places checked by their triangle pose alone beyond the "
        "candidates (PlaceDB seeded=; default SEEDED)",
    )
    ap.add_argument(
        "--aliases",
        action="store_true",
        help="recognition: refuse clique hits with a quarter/half-turn alias "
        "(PlaceDB aliases=True)",
    )
    ap.add_argument(
        "--escalate",
        type=int,
        default=None,
        help="recognition: candidates verified beyond --candidates when none was accepted "
        "with confidence 0.99 (PlaceDB escalate=; default ESCALATE)",
    )
    ap.add_argument(
        "--min-features",
        type=int,
        default=None,
        help="recognition: mapped features an accepted hit needs (PlaceDB min_features=; "
        "default ACCEPT_MIN_FEATURES)",
    )
    ap.add_argument(
        "--calibrate",
        action="store_true",
        help="recognition: fit the hit confidence's weights on the logs run, and leave "
        "one log out (needs two logs or more)",
    )
    ap.add_argument(
        "--full",
        action="store_true",
        help="every scan a query, all freiburg scans in the loop search",
    )
    ap.add_argument(
        "--degrade",
        choices=("range-5.6", "half-beams", "noise-3cm"),
        default=None,
        help="recognition: every scan degraded to another scanner's limits "
        "(benchmarks/mapping_sensors.py's VARIANTS)",
    )
    ap.add_argument(
        "--ceiling",
        action="store_true",
        help="recognition: also verify each query's true places directly, bypassing the "
        "prefilter (what the verification can recognise; slower)",
    )
    ap.add_argument(
        "--map",
        action="store_true",
        help="recognition: each log also run with its places stored with their poses in "
        "the log's map (map_scans first; PlaceDB.add pose=), the hits that disagree on "
        "where the query is then not accepted",
    )
    ap.add_argument("--out", default=None, help="results JSON (default benchmarks/results/)")
    a = ap.parse_args(argv)
    if a.full:
        a.query_every, a.loops_every = 1, 1
    stages = set(a.stages.split(","))
    out_json = results_path(a.out, f"places-{TODAY}.json")
    res = {
        "date": TODAY,
        "args": vars(a),
        "machine": machine(detailed=True),
        "versions": versions(("numpy", "scipy", "numba", "distributed")),
        "git": git_state(),
    }
    from scanclique import __version__

    res["versions"]["scanclique"] = __version__
    t0 = time.perf_counter()
    with tempfile.TemporaryDirectory() as tmpd:
        tmp = Path(tmpd)
        if "recognition" in stages:
            res["recognition"] = [
                recognition(
                    n,
                    a.query_every,
                    a.candidates,
                    tmp,
                    search=a.search,
                    seeded=a.seeded,
                    aliases=a.aliases,
                    min_features=a.min_features,
                    escalate=a.escalate,
                    degrade=a.degrade,
                    ceiling=a.ceiling,
                    mapped=m,
                )
                for n in a.logs.split(",")
                for m in ((False, True) if a.map else (False,))
            ]
            for r in res["recognition"]:
                print(
                    f"{r['log']:9s} queries {r['queries']:5d} true {r['with_true_place']:5d} "
                    f"answered {r['answered']:5d} precision {_f(r['precision'])} recall "
                    f"{_f(r['recall'])} default P {_f(r['default_precision'])} R "
                    f"{_f(r['default_recall'])} r@99 {_f(r['recall_at_99'])} r@100 "
                    f"{_f(r['recall_at_100'])} (by score {_f(r['recall_at_99_by_score'])} / "
                    f"{_f(r['recall_at_100_by_score'])}) "
                    f"prefilter@10 {_f(r['prefilter_recall_10'])} "
                    f"@50 {_f(r['prefilter_recall_50'])} (signature "
                    f"{_f(r['signature_recall_10'])} / {_f(r['signature_recall_50'])}, "
                    f"triangles {_f(r['triangles_recall_10'])} / "
                    f"{_f(r['triangles_recall_50'])}) query ms {r['query_ms_median']:.1f} "
                    f"(p95 {r['query_ms_p95']:.1f})",
                    flush=True,
                )
                print(
                    f"{'':9s} true queries by outcome: "
                    + ", ".join(f"{k} {v}" for k, v in r["outcomes"].items()),
                    flush=True,
                )
                if "ceiling_verify_3" in r:
                    print(
                        f"{'':9s} prefilter bypassed: "
                        + ", ".join(f"{k} {_f(r['ceiling_' + k])}" for k in CEILING_KEYS),
                        flush=True,
                    )
            if a.calibrate and len(res["recognition"]) > 1:
                res["calibration"] = calibrate(res["recognition"])
                for k, v in res["calibration"].items():
                    print(
                        f"calibration {k:9s} weights "
                        + " ".join(f"{x:.3f}" for x in v["weights"])
                        + (
                            ""
                            if k == "all"
                            else f" left out: r@99 {_f(v['recall_at_99'])} r@100 "
                            f"{_f(v['recall_at_100'])} default n {v['default_answered']} P "
                            f"{_f(v['default_precision'])} R {_f(v['default_recall'])}"
                        ),
                        flush=True,
                    )
        if "locate" in stages:
            res["locate"] = [
                locate(n, a.query_every, a.candidates, tmp,
                       figure=out_json.with_name(f"{out_json.stem}-{n}.png"))
                for n in a.logs.split(",")
            ]  # fmt: skip
        if "ring" in stages:
            res["ring"] = [
                locate_ring(seed, odometry, a.query_every, tmp)
                for odometry in (True, False)
                for seed in range(4)
            ]
        if "scale" in stages:
            res["scale"] = scale([int(x) for x in a.sizes.split(",")], a.scale_queries, tmp)
        if "scale_out" in stages:
            res["scale_out"] = scale_out(a.loops_every, a.loops_candidates, a.workers)
    res["seconds"] = time.perf_counter() - t0
    # stages not run this time are kept from the previous results file, with their commit
    if out_json.exists():
        old = json.loads(out_json.read_text())
        ran = set(res)
        for stage in ("recognition", "calibration", "locate", "ring", "scale", "scale_out"):
            # the calibration goes with the recognition it was fitted on
            if (
                stage not in ran
                and stage in old
                and (stage != "calibration" or "recognition" not in ran)
            ):
                res[stage] = old[stage]
                res.setdefault("carried_over", {})[stage] = old.get("carried_over", {}).get(
                    stage, old.get("git", {}).get("commit")
                )
    out_json.parent.mkdir(parents=True, exist_ok=True)
    out_json.write_text(json.dumps(res, indent=1, default=float))
    md = report(res)
    out_json.with_suffix(".md").write_text(
        f"# places benchmark {TODAY}\n\n"
        f"`python benchmarks/places.py {' '.join(argv or sys.argv[1:])}`"
        f" at {res['git']['commit']}, {res['machine']['cpus']} CPUs, load "
        f"{res['machine']['load_average']}, {res['seconds']:.0f} s"
        + "".join(
            f"; {k} carried over from the run at {v}"
            for k, v in res.get("carried_over", {}).items()
        )
        + "\n\n"
        + md
    )
    if "recognition" in res:
        figure(res["recognition"], out_json.with_suffix(".png"))
    print(md)
    print(f"results: {out_json}")


if __name__ == "__main__":
    main()
