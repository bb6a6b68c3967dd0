"""One SLAM run on a data set, with its metrics and files: what ``scanclique slam`` does.

Examples
--------
>>> run = run_slam("victoria-park", association="clique", out="runs/vp")  # doctest: +SKIP
>>> run.metrics["landmarks"]  # doctest: +SKIP
"""

from __future__ import annotations

import dataclasses
import logging
import math
import os
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .._outdir import remove_earlier_output
from ..errors import ConfigError, DataNotFoundError, ParseError
from .ekf import SlamConfig, SlamResult, ekf_slam
from .metrics import (
    GpsError,
    TruthError,
    align_se2,
    duplicate_pairs,
    gps_error,
    gps_outliers,
    sensor_positions,
    truth_error,
)
from .models import Ackermann
from .reader import FILES as VP_FILES
from .reader import (
    LOG_FILES,
    LOG_HOLDS,
    LOG_ODOMETRY,
    LOG_OPTIONAL,
    Step,
    is_landmark_log,
    log_files,
    read_gps,
    read_landmark_log,
    read_victoria_park,
    resolve_victoria_park,
)

__all__ = [
    "MAX_CLUTTER",
    "SlamRun",
    "output_names",
    "run_slam",
    "inject_clutter",
    "victoria_park_model",
    "summarise_smoothed",
]

log = logging.getLogger(__name__)


def victoria_park_model() -> Ackermann:
    """The Victoria Park vehicle (data/README.md): L = 2.83, H = 0.76, laser a = 3.78,
    b = 0.5 m."""
    return Ackermann(wheelbase=2.83, encoder_offset=0.76, laser_a=3.78, laser_b=0.5)


def inject_clutter(
    steps,
    n: int,
    *,
    max_range: float,
    fov: float = math.pi,
    seed: int = 0,
    attribute_range=(0.05, 0.6),
) -> list[Step]:
    """The steps with ``n`` spurious detections added to every batch observation, uniform
    in the sensor's field of view (range uniform in [1 m, ``max_range``], bearing in
    [-fov/2, fov/2]), attributes uniform in ``attribute_range``; their order shuffled."""
    if n <= 0:
        return list(steps)
    rng = np.random.default_rng(seed)
    out = []
    for s in steps:
        if not s.n_observations:
            out.append(s)
            continue
        zc = np.column_stack([rng.uniform(1.0, max_range, n), rng.uniform(-fov / 2, fov / 2, n)])
        z = np.vstack([s.observations, zc])
        att = None
        if s.attributes is not None:
            att = np.r_[s.attributes, rng.uniform(*attribute_range, n)]
        order = rng.permutation(len(z))
        out.append(Step(s.time, s.control, z[order], None if att is None else att[order]))
    return out


@dataclass(frozen=True, slots=True, eq=False)
class SlamRun:
    """A run and what it measured.

    Attributes
    ----------
    result : SlamResult
    gps : GpsError or None
        Error of the laser's position at the GPS fixes (None without GPS).
    metrics : dict
        Name -> (value, units) of the run (the CLI's table).
    files : dict
        Name -> path of the files written.
    alignment : (Rm (2, 2), t (2,))
        Best SE(2) alignment of the estimate to the GPS frame (identity without GPS).
    removed : tuple of str
        Files of an earlier run in ``out`` that this one removed (a ``map.png`` of an
        earlier run, when this one draws none: it would show another map).
    truth : TruthError or None
        Error against the ground truth of a landmark log that has one
        (:func:`~scanclique.slam.read_landmark_log`'s ``truth.txt``).
    """

    result: SlamResult
    gps: GpsError | None
    metrics: dict
    files: dict = field(default_factory=dict)
    alignment: tuple = (np.eye(2), np.zeros(2))
    removed: tuple = ()
    truth: TruthError | None = None

    def to_dict(self) -> dict:
        """JSON-ready: method, metrics (value, units), GPS errors, ambiguous steps' times,
        files and the configuration."""
        from .outputs import _plain

        r = self.result
        return {
            "method": r.method,
            "metrics": {k: {"value": v, "units": u} for k, (v, u) in self.metrics.items()},
            "gps": None
            if self.gps is None
            else {
                "rmse_start": self.gps.rmse_start,
                "max_start": self.gps.max_start,
                "rmse_best": self.gps.rmse_best,
                "max_best": self.gps.max_best,
                "fixes": self.gps.fixes,
            },
            "truth": None if self.truth is None else dataclasses.asdict(self.truth),
            "ambiguous_times": r.observation_times[r.ambiguous].tolist(),
            "files": {k: str(v) for k, v in self.files.items()},
            "removed": list(self.removed),
            "config": _plain(r.config),
        }


def summarise(
    result: SlamResult,
    model,
    gps_fixes=None,
    clutter: int = 0,
    warn: bool = True,
    beyond: tuple[int, int] | None = None,
):
    """``(GpsError or None, metrics dict, alignment)`` of a run.

    The GPS error is None (and the metrics have no GPS rows) when there are no fixes, or
    no fix (outliers excepted) falls within the run's time span; the latter is logged
    (unless ``warn`` is false: :func:`summarise_smoothed`, whose filter run said it).
    ``beyond``: observations beyond ``SlamConfig.max_range`` (which the filter does not
    use) and all observations, shown as two rows (:attr:`SlamResult.beyond_max_range`).
    """
    pos = sensor_positions(result.poses, model.sensor_x, model.sensor_y)
    g = None
    align = (np.eye(2), np.zeros(2))
    ok = np.zeros((0, 3))
    if gps_fixes is not None and len(gps_fixes) and len(result.times):
        ok = gps_fixes[~gps_outliers(gps_fixes)]
        ok = ok[(ok[:, 0] >= result.times[0]) & (ok[:, 0] <= result.times[-1])]
        if not len(ok) and warn:
            log.warning(
                "none of the %d GPS fixes falls within the run's time span [%s, %s] s: "
                "no GPS error",
                len(gps_fixes),
                result.times[0],
                result.times[-1],
            )
    if len(ok):
        g = gps_error(result.times, pos, gps_fixes)
        est = np.column_stack(
            [
                np.interp(ok[:, 0], result.times, pos[:, 0]),
                np.interp(ok[:, 0], result.times, pos[:, 1]),
            ]
        )
        Rm, t, _ = align_se2(est, ok[:, 1:])
        align = (Rm, t)
    pairs, members = duplicate_pairs(result.landmarks, 1.0)
    n = len(result.landmarks)
    sec = result.association_seconds
    m = {}
    if g is not None:
        m["GPS RMSE (start alignment)"] = (g.rmse_start, "m")
        m["GPS max (start alignment)"] = (g.max_start, "m")
        m["GPS RMSE (best SE(2) alignment)"] = (g.rmse_best, "m")
        m["GPS max (best SE(2) alignment)"] = (g.max_best, "m")
        m["GPS fixes"] = (g.fixes, "")
    m["landmarks"] = (n, "")
    m["duplicate pairs (< 1 m)"] = (pairs, "")
    m["landmarks in duplicate pairs"] = (100.0 * members / max(n, 1), "%")
    m["association median"] = (1e3 * float(np.median(sec)) if len(sec) else 0.0, "ms/step")
    m["association p95"] = (1e3 * float(np.percentile(sec, 95)) if len(sec) else 0.0, "ms/step")
    m["ambiguous steps"] = (int(result.ambiguous.sum()), "")
    m["observation steps"] = (len(result.observation_times), "")
    if beyond is not None:
        m["observations"] = (beyond[1], "")
        m["observations beyond max_range (not used)"] = (beyond[0], "")
    m["clutter per scan"] = (clutter, "")
    if result.speed_scale is not None:  # the filter's estimate of the speed's scale error
        m["speed scale error"] = (100.0 * result.speed_scale[0], "%")
        m["speed scale error, 1 sigma"] = (100.0 * result.speed_scale[1], "%")
    if result.observation_noise is not None:  # the sensor noise the run ended with
        m["range sigma at the end"] = (result.observation_noise[0], "m")
        m["bearing sigma at the end"] = (math.degrees(result.observation_noise[1]), "deg")
        if not math.isnan(result.noise_raised):
            m["noise checks that raised it"] = (100.0 * result.noise_raised, "%")
    if not math.isnan(result.attribute_scale):  # the clique's attribute gate, as checked
        m["attribute gate widened by"] = (result.attribute_scale, "x")
    m["run time (CPU)"] = (result.cpu_seconds, "s")
    m["run time (wall)"] = (result.seconds, "s")
    return g, m, align


def summarise_smoothed(result: SlamResult, smoothed, model, gps_fixes=None, clutter: int = 0):
    """:func:`summarise` of the smoothed trajectory and map (a
    :class:`~scanclique.slam.smooth.SmoothResult` of ``result``): the same metrics, the GPS
    error over the observation steps' smoothed poses, the run times including the pass
    ("smoothing time" on its own)."""
    from dataclasses import replace

    r = replace(
        result,
        times=smoothed.times,
        poses=smoothed.poses,
        landmarks=smoothed.landmarks,
        cpu_seconds=result.cpu_seconds + smoothed.cpu_seconds,
        seconds=result.seconds + smoothed.seconds,
    )
    g, m, align = summarise(r, model, gps_fixes, clutter, warn=False)
    m["smoothing time"] = (smoothed.seconds, "s")
    return g, m, align


def _landmark_log_like(source) -> bool:
    """A landmark log, or a directory holding one of its files and none of Victoria
    Park's (read as a landmark log, whose reader then says what it lacks).

    Raises
    ------
    DataNotFoundError
        ``source`` is a directory holding no file of either (empty, or the wrong one),
        naming what each would hold.
    """
    if is_landmark_log(source):
        return True
    if not isinstance(source, (str, os.PathLike)) or os.fspath(source) == "victoria-park":
        return False
    d = Path(os.fspath(source)).expanduser()
    if not d.is_dir():
        return False  # Victoria Park's reader says so, with where it looked
    own = any((d / f).is_file() for f in (*LOG_FILES, LOG_ODOMETRY, *LOG_OPTIONAL))
    vp = any((d / f).is_file() for f in VP_FILES)
    if not own and not vp:
        raise DataNotFoundError(
            f"{d} holds neither a landmark log ({LOG_HOLDS}; see "
            f"scanclique.slam.read_landmark_log) nor the Victoria Park data "
            f"({', '.join(VP_FILES)})"
        )
    return own and not vp


def truth_rows(te: TruthError) -> dict:
    """The table rows (name -> (value, units)) of an error against ground truth."""
    m = {
        "pose RMSE (start alignment)": (te.rmse_start, "m"),
        "pose max (start alignment)": (te.max_start, "m"),
        "pose RMSE (best SE(2) alignment)": (te.rmse_best, "m"),
        "pose max (best SE(2) alignment)": (te.max_best, "m"),
        "heading RMSE": (math.degrees(te.heading_rmse), "deg"),
        "pose ANEES (3 dof; 3 if consistent)": (te.anees, ""),
        "poses compared with the truth": (te.poses, ""),
    }
    if te.landmarks_true:
        m["true landmarks mapped (within 1 m)"] = (te.landmarks_mapped, f"of {te.landmarks_true}")
        m["landmark RMSE (mapped)"] = (te.landmark_rmse, "m")
        m["landmarks not within 1 m of a true one"] = (te.landmarks_spurious, "")
    return m


MAX_CLUTTER = 100
"""Most spurious detections :func:`run_slam` injects per scan: Victoria Park's scans see
about 10 trees, the benchmarks add 5 or 10; 10**5 ran out of memory in the association
(a matrix of 65539 x 65539), 10**12 at once."""


def output_names(plot: bool = False, smooth: bool = False) -> tuple[str, ...]:
    """The names of the files :func:`run_slam` writes into its ``out`` directory (the
    ``slam`` command checks them before the run)."""
    return (
        ("trajectory.tum", "landmarks.csv")
        + (("trajectory-smoothed.tum",) if smooth else ())
        + (("map.png",) if plot else ())
        + ("report.json",)
    )


def run_slam(
    source: str | os.PathLike = "victoria-park",
    *,
    association: str = "clique",
    out: str | os.PathLike | None = None,
    clutter: int = 0,
    seed: int = 0,
    config: SlamConfig | None = None,
    progress=None,
    plot: bool = False,
    smooth: bool = False,
) -> SlamRun:
    """Run EKF-SLAM on the Victoria Park data (a name or a directory), or on a landmark
    log (a directory with ``controls.txt`` or ``odometry.txt``, and ``observations.txt``,
    :func:`~scanclique.slam.read_landmark_log`), and measure it.

    A landmark log is run with the motion model of its ``model.toml`` (a
    :class:`~scanclique.slam.Unicycle` without one) and, when its ``truth.txt`` covers the
    first step, from the true pose there (else from the origin); its metrics are then the
    error against the truth (:func:`~scanclique.slam.metrics.truth_error`) instead of
    the GPS's.

    Parameters
    ----------
    association : {"clique", "jcbb", "nn"}
    out : path, optional
        Directory for ``trajectory.tum``, ``landmarks.csv``, ``report.json`` (and
        ``map.png`` with ``plot``).
    clutter : int
        Spurious detections injected per scan (:func:`inject_clutter`), 0 to
        :data:`MAX_CLUTTER`.
    seed : int
        Seed of the clutter (>= 0).
    smooth : bool
        After the filter, also smooth the run (:func:`~scanclique.slam.smooth.smooth`): its
        metrics are added with the prefix "smoothed ", beside the filter's (which stay
        the filter's), and ``trajectory-smoothed.tum`` is written.

    Raises
    ------
    ParseError
        The data hold no step (``measurements.dat`` and ``inputs.dat`` have no rows),
        besides the errors of :func:`~scanclique.slam.read_victoria_park`.
    ConfigError
        ``clutter`` or ``seed`` out of range (checked before the data are read).
    """
    for name, v, hi in (("clutter", clutter, MAX_CLUTTER), ("seed", seed, None)):
        if isinstance(v, bool) or not isinstance(v, int) or v < 0 or (hi and v > hi):
            to = f"from 0 to {hi}" if hi else ">= 0"
            raise ConfigError(f"run_slam: {name} must be an integer {to}, got {v!r}")
    cfg = config or SlamConfig()
    own = read_landmark_log(source) if _landmark_log_like(source) else None
    pose0 = None
    if own is not None:
        steps, model, gps, name = own.steps, own.model, own.gps, own.directory.name
        where = own.directory
        files_ = f"{log_files(where)[0]} and observations.txt"
        pose0 = own.true_pose(steps[0].time) if steps else None
    else:
        steps, model, name = read_victoria_park(source), victoria_park_model(), "Victoria Park"
        where, files_ = resolve_victoria_park(source), "measurements.dat and inputs.dat"
        gps = read_gps(source)
    if not steps:
        raise ParseError(os.fspath(where), None, f"holds no steps: {files_} have no rows")
    if clutter:
        steps = inject_clutter(
            steps, clutter, max_range=cfg.max_range or 30.0, fov=cfg.sensor_fov, seed=seed
        )
    result = ekf_slam(
        steps,
        model,
        association=association,
        config=cfg,
        progress=progress,
        initial_pose=(0.0, 0.0, 0.0) if pose0 is None else pose0,
    )
    g, m, align = summarise(result, model, gps, clutter, beyond=result.beyond_max_range)
    te = None
    if own is not None and own.truth is not None:
        te = truth_error(
            result.times,
            result.poses,
            result.pose_covariances,
            own.truth,
            result.landmarks,
            own.landmarks,
        )
        if te is None:
            log.warning(
                "%s: no step falls within truth.txt's time span: no error against the truth",
                where,
            )
        else:
            m = {**truth_rows(te), **m}
    sm = None
    if smooth:
        from .smooth import smooth as _smooth

        sm = _smooth(steps, model, result, config=cfg)
        _g, ms, _a = summarise_smoothed(result, sm, model, gps, clutter)
        for k in (
            "GPS RMSE (start alignment)",
            "GPS max (start alignment)",
            "GPS RMSE (best SE(2) alignment)",
            "GPS max (best SE(2) alignment)",
            "landmarks in duplicate pairs",
        ):
            if k in ms:
                m["smoothed " + k] = ms[k]
        if te is not None:
            st = truth_error(sm.times, sm.poses, None, own.truth)
            if st is not None:
                m["smoothed pose RMSE (start alignment)"] = (st.rmse_start, "m")
                m["smoothed pose RMSE (best SE(2) alignment)"] = (st.rmse_best, "m")
        m["smoothing time"] = ms["smoothing time"]  # the pass's own: no prefix
    run = SlamRun(result, g, m, {}, align, truth=te)
    if out is not None:
        d = Path(out)
        d.mkdir(parents=True, exist_ok=True)
        from .outputs import plot_maps, write_landmarks, write_report, write_tum

        files = {
            "trajectory": write_tum(d / "trajectory.tum", result.times, result.poses),
            "landmarks": write_landmarks(
                d / "landmarks.csv",
                result.landmark_ids,
                result.landmarks,
                result.landmark_covariances,
                result.landmark_hits,
            ),
        }
        if sm is not None:
            files["trajectory (smoothed)"] = write_tum(
                d / "trajectory-smoothed.tum", sm.times, sm.poses
            )
        if plot:
            if te is not None:
                # the vehicle's positions in the truth's frame; the truth drawn when the
                # filter started from it (else the frames differ)
                pos, label, frame = result.poses[:, :2], "truth", (np.eye(2), np.zeros(2))
                ref = None if pose0 is None else own.truth[:, :3]
            else:
                pos = sensor_positions(result.poses, model.sensor_x, model.sensor_y)
                ref, label, frame = gps, "GPS", align
            files["map"] = plot_maps(
                d / "map.png",
                [(f"{association}", pos, result.landmarks, result.landmark_covariances, frame)],
                ref,
                title=f"EKF-SLAM ({association}) on {name}",
                reference_label=label,
                true_landmarks=None if te is None or ref is None else own.landmarks,
            )
        elif (gone := remove_earlier_output(d, "map.png")) is not None:
            run = dataclasses.replace(run, removed=(str(gone),))
        run.files.update(files)
        run.files["report"] = d / "report.json"
        write_report(d / "report.json", run.to_dict())
    return run
