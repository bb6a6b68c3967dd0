"""Pose covariances of a map (``BackEndConfig.covariances``): what they cost and whether
they are right, on the real logs.

The mapper's covariances come from the marginals of its optimised keyframe graph (GTSAM
``Marginals``), a scan between keyframes adding its match to its keyframe. They are only
as right as the edges' covariances, so this measures them against the data:

* on the raw benchmark logs (fr079-raw, intel-raw; with odometry), each relation of
  Kümmerle et al. whose two scans belong to different keyframes: the error of the map's
  relative pose against the relation (in the laser frame) normalised by the relative
  pose's covariance (the two keyframes' *joint* marginal, the scans' matches to them
  composed on either side): ``d2 = e^T P^-1 e``, chi-square with 3 degrees of freedom if
  the covariances are right (mean 3; 95 % of the relations below 7.81, 99 % below 11.34).
  The relations are themselves noisy (their own redundancy gives about 0.010 m and 0.25
  deg on Intel, 0.015 m and 0.34 deg on fr079, ``benchmarks/mapping.py``'s relation
  sigma), so ``d2`` is also given with that noise added to ``P``;
* on the corrected logs (intel, csail; their reference pose per scan is the corrected
  trajectory): each scan's absolute error (relative to scan 0) normalised by its own
  covariance (the NEES);
* the marginals' time against the optimisation's.

    python benchmarks/mapping_covariances.py
    python benchmarks/mapping_covariances.py --logs intel,csail --out /tmp/cov

Writes benchmarks/results/mapping-covariances-<date>.json and .md.
"""

from __future__ import annotations

import argparse
import dataclasses
import datetime
import math
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

import common  # noqa: E402
from mapping import relations_trajectory  # noqa: E402

from scanclique import datasets  # noqa: E402
from scanclique.eval import frame_mounting, read_relations  # noqa: E402
from scanclique.eval.relations import join_relations  # noqa: E402
from scanclique.geometry import Pose2  # noqa: E402
from scanclique.mapping import MapConfig, map_scans  # noqa: E402
from scanclique.mapping import backend as _backend  # noqa: E402
from scanclique.slam.metrics import nees  # noqa: E402
from scanclique.uncertainty import compose_covariance, inverse_covariance  # noqa: E402

RAW = ("fr079-raw", "intel-raw")
CORRECTED = ("intel", "csail")
CHI2_3 = (7.815, 11.345)  # 95 % and 99 % points of chi-square with 3 degrees of freedom


def _map_keeping_graph(scans, cfg):
    """``map_scans`` with the covariances, and the optimised keyframe graph it built (kept
    by wrapping ``PoseGraph.covariances``, which the mapper calls once, on that graph)."""
    kept = {}
    original = _backend.PoseGraph.covariances

    def keep(self):
        kept["graph"] = self
        return original(self)

    _backend.PoseGraph.covariances = keep
    try:
        result = map_scans(scans, config=cfg)
    finally:
        _backend.PoseGraph.covariances = original
    return result, kept["graph"]


def _relative_covariance(marginals, ki, kj, pi: Pose2, pj: Pose2) -> np.ndarray:
    """Covariance of ``(x, y, theta)`` of ``pi^-1 pj`` (frame-``i`` axes) from the joint
    marginal of nodes ``ki``, ``kj`` (tangent spaces, right perturbations)."""
    import gtsam  # noqa: PLC0415

    J = marginals.jointMarginalCovariance(gtsam.KeyVector([ki, kj])).fullMatrix()
    rel = pi.inverse() @ pj
    inv = rel.inverse()
    c, s = math.cos(inv.theta), math.sin(inv.theta)
    adjoint = np.array([[c, -s, inv.y], [s, c, -inv.x], [0.0, 0.0, 1.0]])  # Ad(rel^-1)
    A = np.hstack([-adjoint, np.eye(3)])
    Q = A @ J @ A.T  # in the tangent space of rel
    return _backend.map_frame_covariances(np.array([rel.theta]), Q[None])[0]


def raw_log(name: str, cfg: MapConfig) -> dict:
    import gtsam  # noqa: PLC0415

    scans = datasets.load_log(name)
    rels = read_relations(datasets.data_dir() / datasets.DATASETS[name].relations)
    mounting = frame_mounting(scans) or Pose2.identity()
    t0 = time.perf_counter()
    res, graph = _map_keeping_graph(scans, cfg)
    wall = time.perf_counter() - t0
    marginals = gtsam.Marginals(graph.graph, graph.result)
    kf_index = {k: n for n, k in enumerate(res.keyframes)}
    kf_sorted = np.array(res.keyframes)
    to_kf = {(e.i, e.j): e for e in res.edges if e.kind in ("match", "icp")}
    sigma = relations_trajectory(scans, rels, mounting)[2].relation_sigma
    R = np.diag([sigma[0] ** 2, sigma[0] ** 2, sigma[1] ** 2])

    def offset(j):  # the scan's pose and covariance relative to its keyframe
        k = int(kf_sorted[np.searchsorted(kf_sorted, j, side="right") - 1])
        if k == j:
            return k, Pose2.identity(), np.zeros((3, 3))
        e = to_kf[(k, j)]
        return k, e.pose, np.asarray(e.covariance)

    ij, _ = join_relations(rels, [s.timestamp for s in scans])
    d2, d2_ref, terr, span = [], [], [], []
    for r, (a, b) in zip(rels, ij.tolist(), strict=True):
        if a < 0 or b < 0:
            continue
        ka, oa, ca = offset(a)
        kb, ob, cb = offset(b)
        if ka == kb:
            continue
        P = _relative_covariance(
            marginals, kf_index[ka], kf_index[kb], res.poses[ka], res.poses[kb]
        )
        rel_kf = res.poses[ka].inverse() @ res.poses[kb]
        # offset_a^-1 (rel_kf offset_b), to first order, the three independent
        inner = compose_covariance(rel_kf, P, ob, cb)
        oa_inv = oa.inverse()
        P = compose_covariance(oa_inv, inverse_covariance(oa, ca), rel_kf @ ob, inner)
        est = res.poses[a].inverse() @ res.poses[b]
        ref = mounting @ r.delta @ mounting.inverse()  # the relation in the laser frame
        E = est @ ref.inverse()
        e = np.array([E.x, E.y, E.theta])
        d2.append(float(e @ np.linalg.solve(P, e)))
        d2_ref.append(float(e @ np.linalg.solve(P + R, e)))
        span.append(r.span)
        terr.append(math.hypot(E.x, E.y))
    d2, d2_ref, short = np.array(d2), np.array(d2_ref), np.array(span) <= 10.0
    return {
        **_row(name, "relations", scans, res, wall, len(d2)),
        "relation_sigma": [sigma[0], math.degrees(sigma[1])],
        "d2": _summary(d2),
        "d2_with_reference_noise": _summary(d2_ref),
        # the relations spanning at most 10 s (mostly within a keyframe or two) and longer
        "d2_with_reference_noise_short": _summary(d2_ref[short]),
        "d2_with_reference_noise_long": _summary(d2_ref[~short]),
        "translation_error_mean_m": float(np.mean(terr)),
    }


def corrected_log(name: str, cfg: MapConfig) -> dict:
    scans = datasets.load_log(name)
    t0 = time.perf_counter()
    res = map_scans(scans, config=cfg)
    wall = time.perf_counter() - t0
    r0 = scans[0].reference.inverse()
    E = []
    for p, s in zip(res.poses[1:], scans[1:], strict=True):
        t = r0 @ s.reference
        E.append((p.x - t.x, p.y - t.y, math.remainder(p.theta - t.theta, 2 * math.pi)))
    d2 = nees(np.array(E), np.array(res.covariances[1:]))
    C = np.array(res.covariances)
    return {
        **_row(name, "reference poses", scans, res, wall, len(d2)),
        "d2": _summary(d2),
        "largest_position_sigma_m": float(np.sqrt(np.linalg.eigvalsh(C[:, :2, :2])[:, -1].max())),
    }


def _row(name, kind, scans, res, wall, pairs) -> dict:
    """The columns every log's row has: what was mapped, how long it took."""
    return {
        "log": name,
        "kind": kind,
        "scans": len(scans),
        "keyframes": len(res.keyframes),
        "wall_s": wall,
        "optimize_s": res.seconds["optimize"],
        "covariances_s": res.seconds["covariances"],
        "pairs": pairs,
    }


def _summary(d2: np.ndarray) -> dict:
    return {
        "mean": float(d2.mean()),
        "median": float(np.median(d2)),
        "within_95": float(np.mean(d2 < CHI2_3[0])),
        "within_99": float(np.mean(d2 < CHI2_3[1])),
    }


def table(rows: list[dict]) -> list[str]:
    lines = [
        "| log | judged by | scans | keyframes | pairs | d2 mean | median | within 95 % | "
        "within 99 % | with the reference's noise: d2 mean | within 95 % | within 99 % | "
        "optimise s | marginals s |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        d, q = r["d2"], r.get("d2_with_reference_noise")
        ref = (
            f"{q['mean']:.2f} | {100 * q['within_95']:.1f} % | {100 * q['within_99']:.1f} %"
            if q
            else " |  | "
        )
        lines.append(
            f"| {r['log']} | {r['kind']} | {r['scans']} | {r['keyframes']} | {r['pairs']} | "
            f"{d['mean']:.2f} | {d['median']:.2f} | {100 * d['within_95']:.1f} % | "
            f"{100 * d['within_99']:.1f} % | {ref} | {r['optimize_s']:.2f} | "
            f"{r['covariances_s']:.2f} |"
        )
    return lines


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--logs", default=",".join(RAW + CORRECTED))
    ap.add_argument("--out", help="results path without suffix")
    args = ap.parse_args(argv)
    t0 = time.perf_counter()
    cfg = MapConfig()
    cfg = dataclasses.replace(cfg, back_end=dataclasses.replace(cfg.back_end, covariances=True))
    rows = []
    for name in args.logs.split(","):
        # freiburg's odometry fields are its corrected poses: mapping with them would be
        # judged against themselves
        if not common.log_available(name, RAW + CORRECTED):
            continue
        row = raw_log(name, cfg) if name in RAW else corrected_log(name, cfg)
        rows.append(row)
        d = row["d2"]
        print(f"{name}: {row['pairs']} {row['kind']}, d2 mean {d['mean']:.2f}, "
              f"within 95 % {100 * d['within_95']:.1f} %; marginals "
              f"{row['covariances_s']:.2f} s / optimisation {row['optimize_s']:.2f} s",
              flush=True)  # fmt: skip
    date = datetime.date.today().isoformat()
    base = common.results_path(args.out, f"mapping-covariances-{date}")
    head = [
        "# Pose covariances of the map (benchmarks/mapping_covariances.py)",
        "",
        "d2: error normalised by the covariance; chi-square with 3 degrees of freedom when "
        "the covariances are right (mean 3, 95 % below 7.81, 99 % below 11.34).",
        "",
    ]
    ratios = [
        f"- {r['log']}: marginals / optimisation time = "
        f"{r['covariances_s'] / max(r['optimize_s'], 1e-9):.2f}"
        for r in rows
    ] + [
        f"- {r['log']}: d2 with the reference's noise, relations over <= 10 s "
        f"{r['d2_with_reference_noise_short']['mean']:.2f} "
        f"({100 * r['d2_with_reference_noise_short']['within_95']:.1f} % within 95 %), "
        f"over > 10 s {r['d2_with_reference_noise_long']['mean']:.2f} "
        f"({100 * r['d2_with_reference_noise_long']['within_95']:.1f} %)"
        for r in rows
        if "d2_with_reference_noise_short" in r
    ]
    text = "\n".join(head + table(rows) + [""] + ratios) + "\n"
    print(text)
    if rows:  # a run that found no log leaves earlier results alone
        common.write_results(base, text, t0, rows)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
