"""scanclique side by side with what a user would pick instead (issue #4).

One command (needs the ``bench`` extra: ``pip install -e '.[bench]'``)::

    python benchmarks/peers.py                       # <= 200 pairs per set per log, all methods
    python benchmarks/peers.py --cap 50 --logs intel --methods scanclique fpfh-ransac
    python benchmarks/peers.py --tune                # the peers' tuning run (on csail only)

Pairs: the pair sets of ``accuracy.py`` (``pairs.py``: consecutive, skip3, revisit) on every
shared CARMEN log, plus on intel the Kümmerle et al. 2009 relations whose two scans are in
the log (``relations/intel.relations``: ``t1 t2 x y z roll pitch yaw``, the pose at t2 in
the frame of t1; timestamps matched to ``Scan.timestamp`` within 1 ms). No method gets an
initial guess. A pair *succeeds* within 0.20 m and 2 degrees of the reference.

Methods (``--methods``; a peer whose package is missing is skipped with a message):

* ``scanclique``        the default configuration (``MatchConfig()``);
* ``scanclique-paper``  the paper's exact configuration (``scanclique.paper_config()``);
* ``cliquematch``       our features and correspondence graph, one maximum clique found by
  cliquematch instead of our solver, then our pose step on that clique (weighted least
  squares with one round of outlier rejection) and our point-to-line ICP refinement, kept
  when it raises the raw-scan score: the same pose and refinement as ours, but with a single
  clique and no hypothesis ranking;
* ``oneclique``         exactly the same as ``cliquematch`` with our solver
  (``scanclique.clique.max_clique``): the pair of rows separates the solver from the rest;
* ``o3d-icp``           Open3D point-to-point ICP from the identity;
* ``small-gicp``        small_gicp GICP from the identity;
* ``fpfh-ransac``       Open3D global registration: FPFH features, RANSAC on feature matches
  (mutual filter, edge-length and distance checkers), point-to-plane ICP refinement.

Lifting 2D scans to 3D. Point-to-point ICP only needs positions: z = 0. GICP and FPFH need
surface normals (local covariances), and a planar cloud has none: the neighbourhood of a
point on a wall is a line, so the plane fitted to it can turn freely about that line and the
"normal" is arbitrary. Both peers therefore get each 2D point extruded into a short vertical
column, z in {-h, 0, h}: walls become vertical planes whose normals are horizontal, i.e. the
2D normals, and the ICP of the 3D peers stays a 2D problem in effect. h is tied to each
peer's voxel size so that downsampling keeps the three layers. FPFH normals are oriented
towards the sensor (the origin of each scan). Poses are brought back to SE(2) as x, y and
the yaw of the 3D rotation.

Timing: every method single-threaded (``OMP_NUM_THREADS=1`` and friends set before any
import; small_gicp ``num_threads=1``; Open3D verbosity set to errors only), each worker
warmed up before timing, the pool's processes one per core. A pair's time counts everything
from the two scans to the pose: for scanclique both scans' feature extraction and feature
graphs (as ``accuracy.py``), for the peers lifting, downsampling, normals and features.

Peer settings: one setting per peer for all logs, tuned on the csail log only
(``--tune``: a small grid, <= 60 pairs per set, best pooled success rate, ties to the
faster); the grids and the chosen values are in ``TUNING_GRID`` and ``PEER_SETTINGS`` and
are written with the results.

Output: ``benchmarks/results/peers-<date>.md`` (a table per log and pair set),
``peers-<date>.json`` (the same, with the machine, versions and settings) and
``peers-<date>.png`` (success rate against the reference translation and rotation).
Data: ``$SCANCLIQUE_DATA`` (default ``../shared/data``).
"""

from __future__ import annotations

import os

# single-threaded timing: before numpy, numba, open3d or small_gicp are imported
for _var in ("OMP_NUM_THREADS", "NUMBA_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[_var] = "1"

import argparse  # noqa: E402
import contextlib  # noqa: E402
import datetime as _dt  # noqa: E402
import importlib  # noqa: E402
import itertools  # noqa: E402
import json  # noqa: E402
import math  # noqa: E402
import multiprocessing  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from concurrent.futures import ProcessPoolExecutor  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent))
import pairs as P  # noqa: E402
from common import chunks, error_summary, git_state, machine, pool_map, versions  # noqa: E402

import scanclique as sc  # noqa: E402
from scanclique import clique as _clique  # noqa: E402
from scanclique.correspondence import correspondence_graph  # noqa: E402
from scanclique.datasets import DataNotFoundError, load_log, relations_path  # noqa: E402
from scanclique.geometry import Pose2  # noqa: E402
from scanclique.match import (  # noqa: E402
    estimate_clique_pose,
    match_prepared,
    pose_score,
    prepare_scan,
)
from scanclique.refine import icp_point_to_line  # noqa: E402

LOGS = ("intel", "csail", "freiburg")
SETS = ("consecutive", "skip3", "revisit", "relations")
TUNING_LOG = "csail"
TUNING_CAP = 60
RELATION_TOLERANCE = 1e-3  # seconds
REFERENCE = "scanclique"  # the "ours" of the time ratios

METHODS = {
    # key: (label, Python modules it needs)
    "scanclique": ("scanclique (default)", ()),
    "scanclique-paper": ("scanclique (paper config)", ()),
    "cliquematch": ("our graph + cliquematch, 1 clique", ("cliquematch",)),
    "oneclique": ("our graph + our solver, 1 clique", ()),
    "o3d-icp": ("Open3D ICP point-to-point", ("open3d",)),
    "small-gicp": ("small_gicp GICP", ("small_gicp",)),
    "fpfh-ransac": ("Open3D FPFH + RANSAC + ICP", ("open3d",)),
}
PACKAGES = {"open3d": "open3d", "small_gicp": "small_gicp", "cliquematch": "cliquematch"}

# One setting per peer for all logs, chosen by ``--tune`` on csail (see TUNING_GRID and
# benchmarks/results/peers-tuning-*.md). Distances in metres.
PEER_SETTINGS: dict[str, dict] = {
    "o3d-icp": {"max_correspondence": 2.0, "max_iterations": 300},
    "small-gicp": {
        "downsampling": 0.1,
        "column": 0.2,
        "num_neighbors": 20,
        "max_correspondence": 2.0,
        "max_iterations": 50,
    },
    "fpfh-ransac": {
        "voxel": 0.2,
        "normal_radius": 2.0,  # x voxel
        "feature_radius": 10.0,  # x voxel
        "ransac_distance": 1.5,  # x voxel
        "edge_length": 0.9,
        "ransac_iterations": 10000,
        "confidence": 0.999,
        "refine_distance": 1.0,  # x voxel
    },
}
# The grids searched by --tune (each entry overrides PEER_SETTINGS).
TUNING_GRID: dict[str, list[dict]] = {
    "o3d-icp": [
        {"max_correspondence": d, "max_iterations": n}
        for d, n in itertools.product((0.25, 0.5, 1.0, 2.0, 5.0), (30, 100, 300))
    ],
    # column 0 is the plain z = 0 lift (three coincident layers merge when downsampled)
    "small-gicp": [
        {"downsampling": ds, "column": h, "max_correspondence": d}
        for ds, d in itertools.product((0.05, 0.1, 0.25), (0.5, 1.0, 2.0, 5.0))
        for h in (0.0, max(0.1, 2 * ds))
    ],
    "fpfh-ransac": [
        {"voxel": v, "feature_radius": f, "ransac_iterations": n}
        for v, f, n in itertools.product((0.1, 0.2, 0.3, 0.4), (5.0, 10.0, 15.0), (10000, 100000))
    ],
}


# --------------------------------------------------------------------------------------
# Peers: availability, lifting to 3D, and one function per method
# --------------------------------------------------------------------------------------
def peer_status(methods) -> dict[str, str | None]:
    """For each method, None when it can run here, else why not (a missing package)."""
    status: dict[str, str | None] = {}
    for m in methods:
        reason = None
        for mod in METHODS[m][1]:
            try:
                importlib.import_module(mod)
            except Exception as exc:  # ImportError, or OSError for a missing shared library
                reason = (
                    f"cannot import {mod} ({type(exc).__name__}: {exc}); install the bench "
                    f"extra (pip install -e '.[bench]') or pip install {PACKAGES[mod]}"
                )
                break
        status[m] = reason
    return status


def lift_plane(points_xy: np.ndarray) -> np.ndarray:
    """(N, 2) -> (N, 3) with z = 0."""
    return np.column_stack((points_xy, np.zeros(len(points_xy))))


def lift_column(points_xy: np.ndarray, h: float) -> np.ndarray:
    """(N, 2) -> (3N, 3): each point extruded into a vertical column z in {-h, 0, h}, so
    that walls become vertical planes with horizontal (2D) normals."""
    n = len(points_xy)
    xy = np.tile(points_xy, (3, 1))
    z = np.repeat(np.array([-h, 0.0, h]), n)
    return np.column_stack((xy, z))


def se2_of(T: np.ndarray) -> Pose2:
    """The planar part of a 4x4 rigid transform: x, y and the yaw of its rotation."""
    T = np.asarray(T)
    return Pose2.from_xytheta(float(T[0, 3]), float(T[1, 3]), math.atan2(T[1, 0], T[0, 0]))


class Runner:
    """Per-process state: the log's scans, prepared scans per configuration, settings."""

    def __init__(self, settings: dict, seed: int) -> None:
        self.settings = settings
        self.seed = seed
        self.log_name: str | None = None
        self.scans: list = []
        self.prepared: dict = {}
        self.configs = {"default": sc.MatchConfig(), "paper": sc.paper_config()}
        self.stages: dict = {}  # ms per stage of the last scanclique match
        self._o3d = None

    def load(self, log_name: str) -> None:
        if log_name != self.log_name:
            self.scans = load_log(log_name)
            self.log_name = log_name
            self.prepared = {}

    def _prep(self, key: str, k: int):
        cache = self.prepared.setdefault(key, {})
        if k not in cache:
            cache[k] = prepare_scan(self.scans[k], self.configs[key])
        p = cache[k]
        return p, sum(p.seconds.values())

    # -- scanclique -------------------------------------------------------------------
    def scanclique(self, i: int, j: int, key: str = "default"):
        """Our matcher; prepared scans are cached, their preparation time is added."""
        pa, sa = self._prep(key, i)
        pb, sb = self._prep(key, j)
        t0 = time.perf_counter()
        m = match_prepared(pa, pb, self.configs[key])
        self.stages = {k: 1e3 * v for k, v in m.seconds.items()}
        return m.pose, time.perf_counter() - t0 + sa + sb

    def one_clique(self, i: int, j: int, solver: str):
        """Our features and correspondence graph, one maximum clique from ``solver``
        (``"cliquematch"`` or ``"ours"``), our pose from it, our ICP refinement."""
        cfg = self.configs["default"]
        pa, sa = self._prep("default", i)
        pb, sb = self._prep("default", j)
        t0 = time.perf_counter()
        pose = None
        cg = correspondence_graph(pa.graph, pb.graph, cfg.correspondence)
        if cg.n_nodes >= cfg.pose.min_pairs:
            if solver == "cliquematch":
                import cliquematch

                with _quiet_fd(2):  # it reports its buffer sizing on std::cerr now and then
                    G = cliquematch.Graph.from_matrix(cg.adjacency)
                    c = np.asarray(G.get_max_clique(time_limit=cfg.clique.time_limit), int)
                c = c - 1  # cliquematch numbers vertices from 1
            else:
                c = np.asarray(_clique.max_clique(cg.adjacency, time_limit=2.0).vertices)
            if len(c) >= cfg.pose.min_pairs:
                est = estimate_clique_pose(pa.features, pb.features, cg.pairs[np.sort(c)], cfg)
                if est is not None:
                    pose = est.pose
                    if cfg.refine.enabled:
                        rc = cfg.refine
                        icp = icp_point_to_line(
                            pa.cloud,
                            pb.sample,
                            pose,
                            iterations=rc.iterations,
                            max_correspondence=rc.max_correspondence,
                            min_correspondence=rc.inlier_distance,
                        )
                        if pose_score(pa, pb, icp.pose, cfg) >= pose_score(pa, pb, pose, cfg):
                            pose = icp.pose
        return pose, time.perf_counter() - t0 + sa + sb

    # -- Open3D and small_gicp ----------------------------------------------------------
    def _open3d(self):
        if self._o3d is None:
            import open3d as o3d

            o3d.utility.set_verbosity_level(o3d.utility.VerbosityLevel.Error)
            o3d.utility.random.seed(self.seed)
            self._o3d = o3d
        return self._o3d

    def o3d_icp(self, i: int, j: int, s: dict):
        """Point-to-point ICP from the identity, z = 0; B is the source, A the target."""
        o3d = self._open3d()
        reg = o3d.pipelines.registration
        t0 = time.perf_counter()
        ca = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(lift_plane(self.scans[i].points())))
        cb = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(lift_plane(self.scans[j].points())))
        r = reg.registration_icp(
            cb,
            ca,
            s["max_correspondence"],
            np.eye(4),
            reg.TransformationEstimationPointToPoint(),
            reg.ICPConvergenceCriteria(max_iteration=s["max_iterations"]),
        )
        return se2_of(r.transformation), time.perf_counter() - t0

    def small_gicp(self, i: int, j: int, s: dict):
        """GICP from the identity on column-extruded scans."""
        import small_gicp

        t0 = time.perf_counter()
        pa = lift_column(self.scans[i].points(), s["column"])
        pb = lift_column(self.scans[j].points(), s["column"])
        ta, tree_a = small_gicp.preprocess_points(
            pa, s["downsampling"], num_neighbors=s["num_neighbors"], num_threads=1
        )
        tb, _ = small_gicp.preprocess_points(
            pb, s["downsampling"], num_neighbors=s["num_neighbors"], num_threads=1
        )
        r = small_gicp.align(
            ta,
            tb,
            tree_a,
            registration_type="GICP",
            max_correspondence_distance=s["max_correspondence"],
            num_threads=1,
            max_iterations=s["max_iterations"],
        )
        return se2_of(r.T_target_source), time.perf_counter() - t0

    def fpfh_ransac(self, i: int, j: int, s: dict):
        """Open3D global registration (FPFH + RANSAC) refined by point-to-plane ICP."""
        o3d = self._open3d()
        reg = o3d.pipelines.registration
        v = s["voxel"]
        t0 = time.perf_counter()

        def features(points_xy):
            pc = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(lift_column(points_xy, v)))
            pc = pc.voxel_down_sample(v)
            pc.estimate_normals(o3d.geometry.KDTreeSearchParamHybrid(s["normal_radius"] * v, 30))
            pc.orient_normals_towards_camera_location(np.zeros(3))
            f = reg.compute_fpfh_feature(
                pc, o3d.geometry.KDTreeSearchParamHybrid(s["feature_radius"] * v, 100)
            )
            return pc, f

        ca, fa = features(self.scans[i].points())
        cb, fb = features(self.scans[j].points())
        d = s["ransac_distance"] * v
        r = reg.registration_ransac_based_on_feature_matching(
            cb,
            ca,
            fb,
            fa,
            True,
            d,
            reg.TransformationEstimationPointToPoint(False),
            3,
            [
                reg.CorrespondenceCheckerBasedOnEdgeLength(s["edge_length"]),
                reg.CorrespondenceCheckerBasedOnDistance(d),
            ],
            reg.RANSACConvergenceCriteria(s["ransac_iterations"], s["confidence"]),
        )
        r = reg.registration_icp(
            cb,
            ca,
            s["refine_distance"] * v,
            r.transformation,
            reg.TransformationEstimationPointToPlane(),
        )
        return se2_of(r.transformation), time.perf_counter() - t0

    # -- dispatch -----------------------------------------------------------------------
    def run(self, method: str, i: int, j: int, settings: dict | None = None):
        s = settings if settings is not None else self.settings.get(method, {})
        if method == "scanclique":
            return self.scanclique(i, j, "default")
        if method == "scanclique-paper":
            return self.scanclique(i, j, "paper")
        if method == "cliquematch":
            return self.one_clique(i, j, "cliquematch")
        if method == "oneclique":
            return self.one_clique(i, j, "ours")
        if method == "o3d-icp":
            return self.o3d_icp(i, j, s)
        if method == "small-gicp":
            return self.small_gicp(i, j, s)
        if method == "fpfh-ransac":
            return self.fpfh_ransac(i, j, s)
        raise ValueError(f"unknown method {method!r}")


@contextlib.contextmanager
def _quiet_fd(fd: int):
    """Silence writes to file descriptor ``fd`` (C++ code writing past ``sys.stderr``)."""
    saved = os.dup(fd)
    devnull = os.open(os.devnull, os.O_WRONLY)
    try:
        os.dup2(devnull, fd)
        yield
    finally:
        os.dup2(saved, fd)
        os.close(saved)
        os.close(devnull)


_runner: Runner | None = None


def _init(settings: dict, seed: int) -> None:
    global _runner
    _runner = Runner(settings, seed)


def _worker(args):
    """Run ``variants`` (``(name, method, settings)``) on a chunk of pairs of one log.

    Each variant is warmed up on the chunk's first pair (JIT-compiled kernels loaded,
    libraries initialised) before anything is timed; prepared scans of the warm-up are
    dropped so that their time is measured again."""
    log_name, plist, variants = args
    assert _runner is not None
    _runner.load(log_name)
    i0, j0 = plist[0][:2]
    for _name, method, s in variants:
        _runner.run(method, i0, j0, s)
    _runner.prepared = {}
    out = []
    for i, j, ref_xyt in plist:
        ref = Pose2.from_array(ref_xyt)
        for name, method, s in variants:
            _runner.stages = {}
            pose, seconds = _runner.run(method, i, j, s)
            if pose is None:
                t_err = r_err = math.inf
            else:
                t_err, r_err = pose.distance_to(ref)
            out.append(
                {
                    "stages_ms": _runner.stages,
                    "method": name,
                    "i": int(i),
                    "j": int(j),
                    "t_err": t_err,
                    "r_err": r_err,
                    "success": P.is_success(t_err, r_err),
                    "ms": 1e3 * seconds,
                    "ref_t": float(np.hypot(ref.x, ref.y)),
                    "ref_r": abs(ref.theta),
                }
            )
    return out


# --------------------------------------------------------------------------------------
# Pairs and summaries
# --------------------------------------------------------------------------------------
def relation_pairs(scans) -> list[tuple[int, int, tuple]]:
    """Kümmerle et al. relations of the Intel log whose two scans are in ``scans``:
    ``(i, j, (x, y, yaw))``, the pose of scan j in scan i's frame."""
    ts = np.array([s.timestamp for s in scans], dtype=float)
    order = np.argsort(ts)
    rel = np.loadtxt(relations_path(), ndmin=2)

    def index(t):
        k = np.searchsorted(ts[order], t)
        for c in (k - 1, k):
            if 0 <= c < len(ts) and abs(ts[order[c]] - t) <= RELATION_TOLERANCE:
                return int(order[c])
        return None

    out = []
    for t1, t2, x, y, _z, _roll, _pitch, yaw in rel:
        i, j = index(t1), index(t2)
        if i is not None and j is not None and i != j:
            out.append((i, j, (float(x), float(y), float(yaw))))
    return out


def log_pairs(name: str, scans, cap, seed) -> dict[str, list]:
    sets = {
        k: [(i, j, tuple(P.reference_pose(scans, i, j).as_array())) for i, j in v]
        for k, v in P.pair_sets(scans, cap, seed).items()
    }
    if name == "intel":
        try:
            sets["relations"] = P.evenly(relation_pairs(scans), cap)
        except DataNotFoundError as exc:
            print(f"skip intel relations: {exc}")
    return sets


def summarise(records: list[dict]) -> dict:
    s = error_summary(records)
    if not records:
        return s
    t = np.array([r["t_err"] for r in records])
    a = np.array([r["r_err"] for r in records])
    ok = np.isfinite(t)
    s["no_pose"] = int((~ok).sum())
    if all(r.get("stages_ms") for r in records):
        s["stages_median_ms"] = {
            k: float(np.median([r["stages_ms"][k] for r in records]))
            for k in records[0]["stages_ms"]
        }
    # Kümmerle et al. 2009 report mean +- std of the absolute errors: over every pair with
    # a pose (one wild pose dominates them), and over the method's successful pairs
    good = np.array([r["success"] for r in records])
    for suffix, sel in (("", ok), ("_success", good)):
        if sel.any():
            s[f"mean_t_err{suffix}"] = float(t[sel].mean())
            s[f"std_t_err{suffix}"] = float(t[sel].std())
            s[f"mean_r_err_deg{suffix}"] = float(np.degrees(a[sel]).mean())
            s[f"std_r_err_deg{suffix}"] = float(np.degrees(a[sel]).std())
    return s


def run_pairs(ex, jobs, name, plist, variants) -> dict[str, list[dict]]:
    """All variants on all pairs of one set, spread over the pool."""
    recs: dict[str, list[dict]] = {v[0]: [] for v in variants}
    for r in pool_map(ex, _worker, [(name, c, variants) for c in chunks(plist, jobs)]):
        recs[r["method"]].append(r)
    for v in recs.values():
        v.sort(key=lambda r: (r["i"], r["j"]))
    return recs


def _versions() -> dict:
    packages = ("numpy", "numba", "open3d", "small_gicp", "cliquematch", "matplotlib")
    return versions(packages, scanclique=sc.__version__)


def _machine() -> dict:
    return machine(detailed=True)


# --------------------------------------------------------------------------------------
# Reports
# --------------------------------------------------------------------------------------
def _f(x, fmt):
    return "—" if x is None or (isinstance(x, float) and not math.isfinite(x)) else fmt.format(x)


def markdown_table(summaries: dict[str, dict], relations: bool = False) -> str:
    ours = summaries.get(REFERENCE, {}).get("median_ms")
    head = (
        "| method | n | success | median t err (m) | median r err (°) | median ms | p95 ms "
        "| ours/peer time |"
    )
    sep = "|---|---:|---:|---:|---:|---:|---:|---:|"
    if relations:
        head += (
            " mean ± std t err (m), all | mean ± std r err (°), all "
            "| mean ± std t err (m), successes | mean ± std r err (°), successes | no pose |"
        )
        sep += "---:|---:|---:|---:|---:|"
    rows = [head, sep]
    for m, s in summaries.items():
        if not s.get("n"):
            continue
        ratio = ours / s["median_ms"] if ours and s["median_ms"] > 0 else None
        row = (
            f"| {METHODS[m][0]} | {s['n']} | {100 * s['success']:.1f}% "
            f"| {_f(s['median_t_err'], '{:.3f}')} | {_f(s['median_r_err_deg'], '{:.2f}')} "
            f"| {s['median_ms']:.1f} | {s['p95_ms']:.1f} | {_f(ratio, '{:.2f}')} |"
        )
        if relations:
            for x in ("", "_success"):
                row += (
                    f" {_f(s.get('mean_t_err' + x), '{:.3f}')} ± "
                    f"{_f(s.get('std_t_err' + x), '{:.3f}')} "
                    f"| {_f(s.get('mean_r_err_deg' + x), '{:.2f}')} ± "
                    f"{_f(s.get('std_r_err_deg' + x), '{:.2f}')} |"
                )
            row += f" {s['no_pose']} |"
        rows.append(row)
    return "\n".join(rows)


def figure(records: dict[str, list[dict]], path: Path, title: str) -> bool:
    """Success rate against the reference translation and rotation, one curve per method,
    all logs and pair sets pooled."""
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        print("no matplotlib: no figure")
        return False
    t_edges = [0, 0.1, 0.2, 0.3, 0.5, 0.75, 1.0, 1.5, 2.0, 3.0, 5.0, math.inf]  # metres
    r_edges = [0, 1, 2, 5, 10, 20, 45, 90, 180]  # degrees
    fig, axes = plt.subplots(1, 2, figsize=(12, 4.8))
    for ax, key, edges, what, scale in (
        (axes[0], "ref_t", t_edges, "translation (m)", 1.0),
        (axes[1], "ref_r", r_edges, "rotation (°)", math.degrees(1)),
    ):
        counts = None
        for m, recs in records.items():
            if not recs:
                continue
            x = scale * np.array([r[key] for r in recs])
            ok = np.array([r["success"] for r in recs], dtype=float)
            b = np.clip(np.digitize(x, edges) - 1, 0, len(edges) - 2)
            counts = np.bincount(b, minlength=len(edges) - 1)
            xs = [k for k in range(len(edges) - 1) if counts[k] >= 5]
            ys = [100 * ok[b == k].mean() for k in xs]
            style = "-" if m.startswith("scanclique") else "--"
            ax.plot(xs, ys, style, marker="o", ms=4, label=METHODS[m][0])
        labels = [
            (f"{lo:g}–{hi:g}" if math.isfinite(hi) else f">{lo:g}")
            + ("" if counts is None else f"\nn={counts[k]}")
            for k, (lo, hi) in enumerate(zip(edges[:-1], edges[1:], strict=True))
        ]
        ax.set_xticks(range(len(labels)))
        ax.set_xticklabels(labels, fontsize=7)
        ax.set_xlabel(f"reference {what} between the two scans (bins; n = pairs per method)")
        ax.set_ylabel("success rate (%)")
        ax.set_ylim(-3, 103)
        ax.grid(alpha=0.3)
    axes[1].legend(fontsize=8, loc="lower left")
    fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return True


# --------------------------------------------------------------------------------------
# Commands
# --------------------------------------------------------------------------------------
def tune(args, status) -> int:
    """Grid search of each available peer on TUNING_LOG; writes peers-tuning-<date>.*"""
    scans = load_log(TUNING_LOG)
    sets = P.pair_sets(scans, args.tune_cap, args.seed)
    plist = [
        (i, j, tuple(P.reference_pose(scans, i, j).as_array())) for v in sets.values() for i, j in v
    ]
    peers = [m for m in TUNING_GRID if m in args.methods and status[m] is None]
    results = {}
    load_start = [round(x, 2) for x in os.getloadavg()]
    t_start = time.perf_counter()
    ctx = multiprocessing.get_context("spawn")
    with ProcessPoolExecutor(args.jobs, ctx, _init, (PEER_SETTINGS, args.seed)) as ex:
        for m in peers:
            variants = [
                (f"{m}#{k}", m, {**PEER_SETTINGS[m], **g}) for k, g in enumerate(TUNING_GRID[m])
            ]
            recs = run_pairs(ex, args.jobs, TUNING_LOG, plist, variants)
            rows = []
            for (name, _m, s), g in zip(variants, TUNING_GRID[m], strict=True):
                sm = summarise(recs[name])
                rows.append({"grid": g, "settings": s, **sm})
                print(
                    f"{m:12s} {json.dumps(g):70s} success {100 * sm['success']:5.1f}% "
                    f"median {sm['median_ms']:7.1f} ms",
                    flush=True,
                )
            best = max(rows, key=lambda r: (round(r["success"], 6), -r["median_ms"]))
            results[m] = {"rows": rows, "best": best["settings"]}
            print(f"{m:12s} best: {json.dumps(best['settings'])}")
    date = _dt.date.today().isoformat()
    out = Path(args.out_dir) / f"peers-tuning-{date}"
    doc = {
        "date": _dt.datetime.now().isoformat(timespec="seconds"),
        "machine": _machine(),
        "versions": _versions(),
        "log": TUNING_LOG,
        "cap_per_set": args.tune_cap,
        "n_pairs": len(plist),
        "peers": results,
    }
    out.with_suffix(".json").write_text(json.dumps(doc, indent=1, default=float))
    md = [
        f"# Peer tuning — {date}",
        "",
        f"Log: **{TUNING_LOG}** only, {len(plist)} pairs (<= {args.tune_cap} per set: "
        f"{', '.join(f'{k} {len(v)}' for k, v in sets.items())}). Criterion: pooled success "
        "rate (0.20 m, 2°), ties to the lower median time. Machine: "
        f"{_machine()['platform']}, {_machine()['cpus']} CPUs, single-threaded methods. "
        f"Command: `python benchmarks/peers.py --tune`. Wall time "
        f"{time.perf_counter() - t_start:.0f} s; load average at the start {load_start}, "
        f"at the end {_machine()['load_average']} (other jobs shared the machine).",
        "",
    ]
    for m, r in results.items():
        md += [f"## {METHODS[m][0]}", "", "| setting | success | median ms |", "|---|---:|---:|"]
        for row in r["rows"]:
            mark = " **(chosen)**" if row["settings"] == r["best"] else ""
            md.append(
                f"| `{json.dumps(row['grid'])}`{mark} | {100 * row['success']:.1f}% "
                f"| {row['median_ms']:.1f} |"
            )
        md += ["", f"Full setting chosen: `{json.dumps(r['best'])}`", ""]
    out.with_suffix(".md").write_text("\n".join(md))
    print(f"wrote {out}.md and .json")
    return 0


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    ap.add_argument("--logs", nargs="+", default=list(LOGS), choices=LOGS)
    ap.add_argument("--methods", nargs="+", default=list(METHODS), choices=list(METHODS))
    ap.add_argument("--cap", type=int, default=200, help="max pairs per set per log (0 = all)")
    ap.add_argument("--jobs", type=int, default=min(2, os.cpu_count() or 1))
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--tune", action="store_true", help=f"tune the peers on {TUNING_LOG}")
    ap.add_argument("--tune-cap", type=int, default=TUNING_CAP)
    ap.add_argument(
        "--out-dir", default=str(Path(__file__).resolve().parent / "results"), help="output dir"
    )
    args = ap.parse_args(argv)
    cap = None if args.cap <= 0 else args.cap
    Path(args.out_dir).mkdir(parents=True, exist_ok=True)

    status = peer_status(args.methods)
    skipped = {m: why for m, why in status.items() if why is not None}
    for m, why in skipped.items():
        print(f"skip {m}: {why}")
    if args.tune:
        return tune(args, status)
    methods = [m for m in args.methods if m not in skipped]
    variants = [(m, m, PEER_SETTINGS.get(m, {})) for m in methods]

    results: dict = {}
    all_recs: dict[str, list[dict]] = {m: [] for m in methods}
    load_start = [round(x, 2) for x in os.getloadavg()]
    t_start = time.perf_counter()
    ctx = multiprocessing.get_context("spawn")
    with ProcessPoolExecutor(args.jobs, ctx, _init, (PEER_SETTINGS, args.seed)) as ex:
        for name in args.logs:
            try:
                scans = load_log(name)
            except DataNotFoundError as exc:
                print(f"skip {name}: {exc}")
                continue
            results[name] = {}
            for set_name, plist in log_pairs(name, scans, cap, args.seed).items():
                if not plist:
                    continue
                recs = run_pairs(ex, args.jobs, name, plist, variants)
                summ = {m: summarise(recs[m]) for m in methods}
                results[name][set_name] = {"summary": summ, "pairs": recs}
                for m in methods:
                    all_recs[m].extend(recs[m])
                    s = summ[m]
                    print(
                        f"{name:9s} {set_name:12s} {m:17s} n={s['n']:4d} "
                        f"success {100 * s['success']:5.1f}%  median err "
                        f"{s['median_t_err']:.3f} m {s['median_r_err_deg']:.2f} deg  time median "
                        f"{s['median_ms']:.1f} ms p95 {s['p95_ms']:.1f} ms",
                        flush=True,
                    )
    wall = time.perf_counter() - t_start
    print(f"wall time {wall:.0f} s with {args.jobs} processes")

    date = _dt.date.today().isoformat()
    out = Path(args.out_dir) / f"peers-{date}"
    machine, versions = _machine(), _versions()
    command = "python benchmarks/peers.py" + (" " + " ".join(argv) if argv else "")
    if argv is None and len(sys.argv) > 1:
        command = "python benchmarks/peers.py " + " ".join(sys.argv[1:])
    doc = {
        "date": _dt.datetime.now().isoformat(timespec="seconds"),
        "command": command,
        "machine": machine,
        "load_average_start": load_start,
        "versions": versions,
        "git": git_state(),
        "jobs": args.jobs,
        "wall_seconds": wall,
        "cap": cap,
        "single_threaded": "OMP_NUM_THREADS=NUMBA_NUM_THREADS=OPENBLAS_NUM_THREADS=1 before "
        "import; small_gicp num_threads=1; Open3D verbosity Error",
        "lifting": {
            "o3d-icp": "z = 0",
            "small-gicp": "vertical column z in {-h, 0, h}, h = settings.column",
            "fpfh-ransac": "vertical column z in {-v, 0, v}, v = voxel; normals oriented "
            "towards the sensor",
        },
        "methods": {m: METHODS[m][0] for m in methods},
        "skipped": skipped,
        "settings": {m: PEER_SETTINGS[m] for m in methods if m in PEER_SETTINGS},
        "tuning": {"log": TUNING_LOG, "grid": TUNING_GRID},
        "logs": {n: {k: v["summary"] for k, v in d.items()} for n, d in results.items()},
        "pooled": {m: summarise(all_recs[m]) for m in methods},
    }
    out.with_suffix(".json").write_text(json.dumps(doc, indent=1, default=float))
    has_fig = figure(
        all_recs,
        out.with_suffix(".png"),
        f"Success (0.20 m, 2°) vs reference motion — all logs and pair sets pooled "
        f"({date}, {machine['cpus']} CPUs)",
    )
    out.with_suffix(".md").write_text(markdown_report(doc, results, has_fig, out.name))
    default_dir = Path(args.out_dir).resolve() == (Path(__file__).resolve().parent / "results")
    per_pair = (
        Path(__file__).resolve().parent / "out" if default_dir else Path(args.out_dir)
    ) / f"{out.name}-pairs.json"
    per_pair.parent.mkdir(parents=True, exist_ok=True)
    per_pair.write_text(
        json.dumps({n: {k: v["pairs"] for k, v in d.items()} for n, d in results.items()})
    )
    print(f"wrote {out}.md, .json{', .png' if has_fig else ''}; per-pair records {per_pair}")
    return 0


def markdown_report(doc: dict, results: dict, has_fig: bool, stem: str) -> str:
    m = doc["machine"]
    v = doc["versions"]
    lines = [
        f"# scanclique against peers — {doc['date'][:10]}",
        "",
        f"Machine: {m['platform']}, {m['processor']}, {m['cpus']} CPUs; Python {v['python']}, "
        f"numpy {v['numpy']}, numba {v['numba']}, open3d {v['open3d']}, small_gicp "
        f"{v['small_gicp']}, cliquematch {v['cliquematch']}. Command: `{doc['command']}` "
        f"({doc['jobs']} worker processes, wall time {doc['wall_seconds']:.0f} s). Load "
        f"average (1, 5, 15 min) at the start {doc['load_average_start']}, at the end "
        f"{m['load_average']}: other jobs shared the machine, so absolute times are "
        "inflated; every method was run on each pair in turn, so the ratios are fair. "
        f"Code: commit {str(doc['git']['commit'])[:10]}"
        + (
            f" with uncommitted changes to {', '.join(doc['git']['modified'])}."
            if doc["git"]["modified"]
            else "."
        ),
        "",
        "Every method runs **single-threaded** (OMP_NUM_THREADS=1 etc. set before any import, "
        "small_gicp num_threads=1, Open3D verbosity Error), warmed up before timing, with no "
        "initial guess. A pair's time covers everything from the two scans to the pose "
        "(for scanclique: both scans' features and feature graphs). *Success*: within "
        "0.20 m and 2° of the reference. *ours/peer time*: median time of scanclique "
        "(default) over the peer's median time on the same pairs (< 1: scanclique is "
        "faster). Absolute times are indicative only; ratios are measured in one run.",
        "",
        "Pair sets (`benchmarks/pairs.py`): consecutive `(i, i+1)`, skip3 `(i, i+3)`, "
        "revisit (>= 50 scans apart, < 2 m, >= 50% overlap), at most "
        f"{doc['cap']} per set, evenly spread; on intel also the Kümmerle et al. 2009 "
        "relations whose two scans are in the log (timestamps within 1 ms), where the "
        "reference is the relation and the last columns give mean ± std of the absolute "
        "errors as that paper reports them, over every pair with a pose (a single wild "
        "pose dominates these) and over the method's successful pairs.",
        "",
        "Methods:",
        "",
        "- **scanclique (default)**: `MatchConfig()`; **(paper config)**: "
        "`scanclique.paper_config()`.",
        "- **our graph + cliquematch, 1 clique**: our features and correspondence graph, one "
        "maximum clique from cliquematch (`Graph.from_matrix(...).get_max_clique`, 2 s "
        "limit), then our pose step on that clique (weighted least squares, one round of "
        "outlier rejection) and our point-to-line ICP refinement kept when it raises the "
        "raw-scan score. **our graph + our solver, 1 clique**: the same with "
        "`scanclique.clique.max_clique`. These two rows against each other isolate the "
        "solver; against scanclique (default) they show what the hypotheses (all maximum "
        "cliques, peeled and vertex-guided cliques, ranked on the raw scans) add.",
        "- **Open3D ICP**: point-to-point ICP from the identity, points lifted with z = 0.",
        "- **small_gicp GICP** from the identity; **Open3D FPFH + RANSAC + ICP**: voxel "
        "downsampling, normals, FPFH, RANSAC on mutual feature matches with edge-length and "
        "distance checkers, point-to-plane ICP refinement. Both need normals, which a planar "
        "cloud does not define (a wall's neighbourhood is a line: any plane through it fits), "
        "so each 2D point is extruded into a vertical column z in {-h, 0, h} (h = the "
        "column/voxel size below, so downsampling keeps the layers): walls become vertical "
        "planes whose normals are the 2D normals. FPFH normals are oriented towards the "
        "sensor. 3D results are reduced to x, y and yaw.",
        "",
        f"Peer settings: one per peer for all logs, tuned on **{doc['tuning']['log']}** only "
        "(`python benchmarks/peers.py --tune`, grid and scores in `peers-tuning-*.md`):",
        "",
    ]
    for k, s in doc["settings"].items():
        lines.append(f"- {METHODS[k][0]}: `{json.dumps(s)}`")
    if doc["skipped"]:
        lines += ["", "Skipped here:"] + [f"- {k}: {w}" for k, w in doc["skipped"].items()]
    for name, sets in results.items():
        for set_name, d in sets.items():
            lines += ["", f"## {name} — {set_name}", ""]
            lines.append(markdown_table(d["summary"], relations=set_name == "relations"))
    lines += ["", "## All logs and pair sets pooled", ""]
    lines.append(markdown_table(doc["pooled"]))
    for k in ("scanclique", "scanclique-paper"):
        st = doc["pooled"].get(k, {}).get("stages_median_ms")
        if st:
            lines += [
                "",
                f"{METHODS[k][0]}, median ms per stage over all pairs (features and graph: "
                "both scans): " + ", ".join(f"{n} {v:.1f}" for n, v in st.items()) + ".",
            ]
    if has_fig:
        lines += ["", f"![success against reference motion]({stem}.png)"]
    return "\n".join(lines) + "\n"


if __name__ == "__main__":
    raise SystemExit(main())
