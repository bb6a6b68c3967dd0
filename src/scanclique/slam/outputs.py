"""Files of a SLAM run: ``trajectory.tum``, ``landmarks.csv``, ``report.json``, ``map.png``.

* ``trajectory.tum``: ``time x y z qx qy qz qw`` per step (TUM RGB-D format; z = 0, the
  quaternion of the heading about z): the vehicle's reference point in the filter's frame.
* ``landmarks.csv``: ``id,x,y,var_x,cov_xy,var_y,hits`` of the final map.
* ``report.json``: the run's metrics and configuration (see :func:`report_dict`).
* ``map.png``: landmarks with 3-sigma covariance ellipses, the trajectory and the GPS
  fixes (matplotlib, imported only here).
"""

from __future__ import annotations

import json
import math
from dataclasses import asdict, is_dataclass
from pathlib import Path

import numpy as np

from ..io.tum import write_tum as _write_tum

__all__ = ["write_tum", "write_landmarks", "write_report", "plot_maps", "write_landmark_log"]


def write_tum(path, times, poses) -> Path:
    """Write poses (N, 3) at ``times`` (N,) in TUM format (:func:`scanclique.io.write_tum`,
    which refuses poses or times that are not finite, or not one time per pose, with an
    :class:`~scanclique.errors.ArgumentError`); returns the path."""
    p = Path(path)
    _write_tum(p, np.asarray(poses, float), list(times))
    return p


def write_landmarks(path, ids, landmarks, covariances, hits) -> Path:
    """Write ``landmarks.csv``: one row per landmark, its integer id, position ``(x, y)``,
    the upper triangle of its (2, 2) covariance and its hits; returns the path.

    Raises
    ------
    ArgumentError
        The four are not one per landmark, an id or a hit count is not an integer, or a
        position or covariance is not finite (of shape (2,) and (2, 2)); nothing is
        written.
    """
    from ..errors import ArgumentError  # noqa: PLC0415

    where = "write_landmarks"
    n = len(ids)
    for name, v in (("landmarks", landmarks), ("covariances", covariances), ("hits", hits)):
        if len(v) != n:
            raise ArgumentError(f"{where}: {len(v)} {name} for {n} ids (one per landmark)")
    try:
        m_all = np.asarray(landmarks, dtype=float).reshape(n, 2)
        c_all = np.asarray(covariances, dtype=float).reshape(n, 2, 2)
        counts = np.asarray([ids, hits], dtype=float).reshape(2, n)
    except (TypeError, ValueError):
        raise ArgumentError(
            f"{where}: landmarks must be (N, 2), covariances (N, 2, 2), ids and hits N numbers"
        ) from None
    if not (np.all(np.isfinite(m_all)) and np.all(np.isfinite(c_all))):
        raise ArgumentError(f"{where}: landmarks and covariances must be finite")
    if not np.all(np.isfinite(counts) & (counts == np.round(counts))):
        raise ArgumentError(f"{where}: ids and hits must be integers, got {ids!r}, {hits!r}")
    p = Path(path)
    with open(p, "w") as fh:
        fh.write("id,x,y,var_x,cov_xy,var_y,hits\n")
        for i, m, c, h in zip(ids, landmarks, covariances, hits, strict=True):
            cov = f"{c[0, 0]:.6g},{c[0, 1]:.6g},{c[1, 1]:.6g}"
            fh.write(f"{int(i)},{m[0]:.4f},{m[1]:.4f},{cov},{int(h)}\n")
    return p


def write_landmark_log(directory, steps, *, model=None, truth=None, landmarks=None) -> Path:
    """Write ``steps`` as a landmark log in plain text, the format
    :func:`~scanclique.slam.read_landmark_log` reads (``controls.txt``,
    ``observations.txt``; ``truth.txt`` from ``truth`` ``(T, 4)`` rows ``time x y theta``,
    ``landmarks.txt`` from ``landmarks`` ``(L, 2)``, ``model.toml`` from ``model``, when
    given), numbers to 17 significant digits so that reading gives the same steps back.
    Returns the directory (created when absent).

    Steps with the same time as another are merged by the reader (a control and a batch
    at one time are one step), and a step with neither a control nor an observation has
    no row (the filter uses neither).

    Raises
    ------
    ArgumentError
        Some steps' observations have attributes and others' not: the file holds them
        for every observation or for none, and dropping them would lose them. A step
        that is not a :class:`~scanclique.slam.Step`, or a model other than a
        :class:`~scanclique.slam.Unicycle` or an :class:`~scanclique.slam.Ackermann`
        (a subclass's own parameters would not read back).
    """
    from dataclasses import fields

    from ..errors import ArgumentError  # noqa: PLC0415
    from .models import Ackermann, Unicycle  # noqa: PLC0415
    from .reader import Step  # noqa: PLC0415

    steps = list(steps)
    for k, s in enumerate(steps):
        if not isinstance(s, Step):
            raise ArgumentError(
                f"write_landmark_log: steps[{k}] is a {type(s).__name__}, not a Step"
            )
    if model is not None and type(model) not in (Ackermann, Unicycle):
        raise ArgumentError(
            "write_landmark_log: model.toml describes a slam.Unicycle or a slam.Ackermann, "
            f"got {type(model).__name__}"
        )
    seen = [s for s in steps if s.n_observations]
    with_att = [s.attributes is not None for s in seen]
    if any(with_att) and not all(with_att):
        k = with_att.index(False)
        raise ArgumentError(
            f"write_landmark_log: the observations at t={seen[k].time} have no attributes "
            "while others have: observations.txt holds an attribute for every observation "
            "or for none"
        )
    with_att = all(with_att)
    d = Path(directory)
    d.mkdir(parents=True, exist_ok=True)
    with open(d / "controls.txt", "w") as fh:
        fh.write("# time c1 c2\n")
        for s in steps:
            if s.control is not None:
                c0, c1 = s.control.tolist()
                fh.write(f"{float(s.time)!r} {c0!r} {c1!r}\n")
    with open(d / "observations.txt", "w") as fh:
        fh.write("# time range bearing" + (" attribute" if with_att else "") + "\n")
        for s in steps:
            for i, (r, b) in enumerate(s.observations.tolist()):
                att = f" {float(s.attributes[i])!r}" if with_att else ""
                fh.write(f"{float(s.time)!r} {r!r} {b!r}{att}\n")
    if truth is not None:
        rows = np.asarray(truth, float).reshape(-1, 4).tolist()
        (d / "truth.txt").write_text(
            "# time x y theta\n" + "".join(" ".join(repr(v) for v in r) + "\n" for r in rows)
        )
    if landmarks is not None:
        rows = np.asarray(landmarks, float).reshape(-1, 2).tolist()
        (d / "landmarks.txt").write_text("# x y\n" + "".join(f"{x!r} {y!r}\n" for x, y in rows))
    if model is not None:
        kind = "ackermann" if isinstance(model, Ackermann) else "unicycle"
        alias = getattr(model, "_ALIASES", {})
        lines = [f'kind = "{kind}"']
        lines += [
            f"{alias.get(f.name, f.name)} = {float(getattr(model, f.name))!r}"
            for f in fields(model)
        ]
        (d / "model.toml").write_text("\n".join(lines) + "\n")
    return d


def _plain(obj):
    if is_dataclass(obj) and not isinstance(obj, type):
        return {k: _plain(v) for k, v in asdict(obj).items()}
    if isinstance(obj, dict):
        return {str(k): _plain(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_plain(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return _plain(obj.tolist())
    if isinstance(obj, np.generic):
        obj = obj.item()
    if isinstance(obj, float) and not math.isfinite(obj):
        return None
    return obj


def write_report(path, report: dict) -> Path:
    p = Path(path)
    p.write_text(json.dumps(_plain(report), indent=2, allow_nan=False) + "\n")
    return p


def _ellipse(ax, m, c, color, nsig=3.0):
    from ..plot import ellipse_outline  # noqa: PLC0415

    pts = ellipse_outline(m, c, nsig)
    ax.plot(pts[:, 0], pts[:, 1], color=color, lw=0.5)


def plot_maps(
    path,
    runs,
    gps=None,
    title="EKF-SLAM on Victoria Park",
    errors=None,
    reference_label="GPS",
    true_landmarks=None,
):
    """One panel per run: GPS fixes, trajectory and landmarks (3-sigma ellipses), all
    in the GPS frame; with ``errors``, a panel below of each run's error at every fix.
    ``reference_label`` names the ``gps`` track in the legend ("truth" for a landmark
    log's true poses); ``true_landmarks`` ``(L, 2)``, when given, are drawn too.

    Parameters
    ----------
    runs : list of (label, positions (N, 2), landmarks (n, 2), covariances (n, 2, 2),
        (Rm, t) alignment estimate -> GPS)
    gps : (G, 3) array, optional
    errors : list of (label, fix times (F,) s, errors (F,) m), optional
        Plotted against the time since the first fix; ``jumps`` (fix times, s) may follow
        as a fourth item, marked below the curves (the GPS's own steps, see
        :func:`scanclique.slam.metrics.gps_jumps`).
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    n = len(runs)
    if errors:
        fig = plt.figure(figsize=(6 * n, 9))
        grid = fig.add_gridspec(2, n, height_ratios=(2, 1))
        axes = [fig.add_subplot(grid[0, i]) for i in range(n)]
        eax = fig.add_subplot(grid[1, :])
    else:
        fig, ax2 = plt.subplots(1, n, figsize=(6 * n, 6), squeeze=False)
        axes, eax = list(ax2[0]), None
    for ax, (label, pos, lms, covs, (Rm, t)) in zip(axes, runs, strict=False):
        if gps is not None:
            ax.plot(gps[:, 1], gps[:, 2], ".", color="0.6", ms=1.5, label=reference_label)
        if true_landmarks is not None and len(true_landmarks):
            tl = np.asarray(true_landmarks, float)
            ax.plot(tl[:, 0], tl[:, 1], "o", mfc="none", color="0.3", ms=5, label="true landmarks")
        p = pos @ Rm.T + t
        ax.plot(p[:, 0], p[:, 1], "-", color="tab:blue", lw=0.7, label="estimate")
        lm = lms @ Rm.T + t
        ax.plot(lm[:, 0], lm[:, 1], "+", color="tab:green", ms=4, label=f"{len(lm)} landmarks")
        for m, c in zip(lm, covs, strict=False):
            _ellipse(ax, m, Rm @ c @ Rm.T, "tab:green")
        ax.set_title(label)
        ax.set_aspect("equal")
        ax.set_xlabel("x [m]")
        ax.set_ylabel("y [m]")
        ax.legend(loc="upper left", fontsize=7)
    if eax is not None:
        t0 = min(float(e[1][0]) for e in errors if len(e[1]))
        for item in errors:
            label, te, ee = item[:3]
            eax.plot(np.asarray(te) - t0, ee, lw=0.6, label=label)
            if len(item) > 3 and len(item[3]):
                j = np.asarray(item[3]) - t0
                eax.plot(j, np.full(len(j), -0.5), "|", color="k", ms=6)
        eax.set_xlabel("time since the first fix [s]")
        eax.set_ylabel("error at the GPS fix [m] (SE(2) alignment)")
        eax.set_title("error at every GPS fix; black ticks: the GPS's jumps (see gps_jumps)")
        eax.legend(loc="upper left", fontsize=7)
    fig.suptitle(title)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return Path(path)
