"""The files a map run writes (issue 12, part 4), each in the format its tools expect.

* ``trajectory.tum`` — TUM RGB-D format (``timestamp x y z qx qy qz qw``, one pose per
  scan, z = 0, rotation about z), loads in ``evo``;
* ``graph.g2o`` — ``VERTEX_SE2 id x y theta`` and ``EDGE_SE2 i j dx dy dtheta`` with the
  upper triangle of the information matrix (tangent-space coordinates, as GTSAM's
  ``readG2o`` and g2o read it);
* ``map.pgm`` + ``map.yaml`` — ROS ``map_server`` convention: trinary image (0 occupied,
  254 free, 205 unknown), top row first; ``resolution``, ``origin`` (lower-left corner,
  metres), ``occupied_thresh: 0.65``, ``free_thresh: 0.196``, ``negate: 0``;
* ``map.png`` — the occupancy probabilities with the trajectory and the accepted loop
  closures drawn (matplotlib, imported lazily);
* ``report.json`` — the configuration used, counts, times, closures with their verdicts,
  and any metrics passed in;
* ``covariances.csv`` — when asked, each scan's pose covariance (``index timestamp`` and
  the upper triangle ``xx xy xt yy yt tt`` of the covariance of ``(x, y, theta)`` in the
  map frame's axes; m², m·rad, rad²), one row per scan with a pose.
"""

from __future__ import annotations

import json
import math
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from ..config import config_to_dict
from ..errors import ArgumentError
from ..geometry import Pose2
from ..io.tum import write_tum
from ..tools.jsonable import clean_json
from .backend import tangent_covariance
from .occupancy import OccupancyGrid, probabilities

__all__ = [
    "OCCUPIED_THRESH",
    "FREE_THRESH",
    "MAX_ELLIPSES",
    "write_tum",
    "write_covariances",
    "write_g2o",
    "write_map",
    "write_png",
    "write_report",
    "map_config_dict",
]

OCCUPIED_THRESH = 0.65
FREE_THRESH = 0.196


def _check_lengths(where: str, n: int, **values) -> None:
    """Each sequence has ``n`` items (one per pose), else :class:`ArgumentError`."""
    for name, v in values.items():
        if len(v) != n:
            raise ArgumentError(f"{where}: {len(v)} {name} for {n} poses (one per pose)")


def _check_grid(where: str, grid) -> None:
    """``grid`` is an :class:`OccupancyGrid` with a 2-D grid, a finite positive resolution
    and a finite origin, else :class:`ArgumentError`."""
    if not isinstance(grid, OccupancyGrid):
        raise ArgumentError(f"{where}: grid must be an OccupancyGrid, got {type(grid).__name__}")
    r, o = grid.resolution, np.asarray(grid.origin, dtype=float)
    if np.ndim(grid.log_odds) != 2 or not (math.isfinite(r) and r > 0):
        raise ArgumentError(
            f"{where}: grid must be 2-D with a finite positive resolution, got shape "
            f"{np.shape(grid.log_odds)}, resolution {r!r}"
        )
    if o.shape != (2,) or not np.all(np.isfinite(o)):
        raise ArgumentError(f"{where}: grid.origin must be two finite numbers, got {grid.origin!r}")


def write_covariances(
    path: str | Path, poses: Sequence[Pose2 | None], covariances, timestamps
) -> int:
    """Write each scan's pose covariance as CSV (see the module docstring); scans without
    a pose are left out. Returns the rows written. Timestamps default to the scan index
    when missing.

    Raises
    ------
    ArgumentError
        ``covariances`` or ``timestamps`` not one per pose.
    """
    _check_lengths("write_covariances", len(poses), covariances=covariances, timestamps=timestamps)
    lines = ["index,timestamp,xx,xy,xt,yy,yt,tt"]
    for k, (p, C) in enumerate(zip(poses, covariances, strict=True)):
        if p is None or C is None:
            continue
        t = timestamps[k] if timestamps[k] is not None else float(k)
        C = np.asarray(C, dtype=float)
        tri = (C[0, 0], C[0, 1], C[0, 2], C[1, 1], C[1, 2], C[2, 2])
        lines.append(f"{k},{t:.6f}," + ",".join(f"{v:.9e}" for v in tri))
    Path(path).write_text("\n".join(lines) + "\n")
    return len(lines) - 1


def write_g2o(path: str | Path, poses: Sequence[Pose2 | None], edges) -> tuple[int, int]:
    """Write the pose graph in g2o's 2D format (edges between placed scans only).
    Returns ``(vertices, edges)`` written."""
    out = []
    placed = set()
    for k, p in enumerate(poses):
        if p is None:
            continue
        placed.add(k)
        out.append(f"VERTEX_SE2 {k} {p.x:.9f} {p.y:.9f} {p.theta:.9f}")
    n_e = 0
    for e in edges:
        if e.i not in placed or e.j not in placed:
            continue
        info = np.linalg.inv(tangent_covariance(e.pose, e.covariance))
        info = 0.5 * (info + info.T)
        tri = [info[0, 0], info[0, 1], info[0, 2], info[1, 1], info[1, 2], info[2, 2]]
        z = e.pose
        out.append(
            f"EDGE_SE2 {e.i} {e.j} {z.x:.9f} {z.y:.9f} {z.theta:.9f} "
            + " ".join(f"{v:.9g}" for v in tri)
        )
        n_e += 1
    Path(path).write_text("\n".join(out) + "\n")
    return len(placed), n_e


def write_map(pgm: str | Path, yaml: str | Path, grid: OccupancyGrid) -> tuple[int, int]:
    """Write ``map.pgm`` (binary P5, trinary values, top row first) and ``map.yaml`` (ROS
    ``map_server``). Returns the image's ``(width, height)``.

    Raises
    ------
    ArgumentError
        ``grid`` is not a 2-D :class:`OccupancyGrid` with a finite resolution and origin.
    """
    _check_grid("write_map", grid)
    p = probabilities(grid.log_odds)
    img = np.full(p.shape, 205, dtype=np.uint8)
    img[p > OCCUPIED_THRESH] = 0
    img[p < FREE_THRESH] = 254
    img = img[::-1]  # row 0 of the grid is the lowest y; images start at the top
    h, w = img.shape
    with open(pgm, "wb") as f:
        f.write(f"P5\n# scanclique map\n{w} {h}\n255\n".encode("ascii"))
        f.write(img.tobytes())
    Path(yaml).write_text(
        f"image: {Path(pgm).name}\n"
        f"resolution: {grid.resolution:.6f}\n"
        f"origin: [{grid.origin[0]:.6f}, {grid.origin[1]:.6f}, 0.000000]\n"
        "negate: 0\n"
        f"occupied_thresh: {OCCUPIED_THRESH}\n"
        f"free_thresh: {FREE_THRESH}\n"
        "mode: trinary\n"
    )
    return w, h


#: at most this many pose covariance ellipses on ``map.png`` (evenly spaced along the log)
MAX_ELLIPSES = 60


def write_png(
    path: str | Path, grid: OccupancyGrid, poses, closures=(), title: str = "", covariances=None
) -> None:
    """``map.png``: occupancy probabilities (white free, black occupied, grey unknown),
    the trajectory (blue) and the accepted loop closures (red segments); with
    ``covariances`` (one (3, 3) per pose), the 3-sigma ellipses of the positions of at
    most :data:`MAX_ELLIPSES` poses evenly spaced along the log (green).

    Raises
    ------
    ArgumentError
        ``grid`` is not a 2-D :class:`OccupancyGrid` with a finite resolution and origin,
        a closure's scan index is not one of ``poses``, or ``covariances`` are not one
        per pose.
    """
    where = "write_png"
    _check_grid(where, grid)
    if covariances is not None:
        _check_lengths(where, len(poses), covariances=covariances)
    for c in closures:
        for k in (c.i, c.j):
            if not (isinstance(k, (int, np.integer)) and 0 <= k < len(poses)):
                raise ArgumentError(
                    f"{where}: closure {c.i} -> {c.j} names scan {k!r}, not one of the "
                    f"{len(poses)} poses"
                )
    import matplotlib  # noqa: PLC0415

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt  # noqa: PLC0415

    p = probabilities(grid.log_odds)
    h, w = p.shape
    r = grid.resolution
    x0, y0 = grid.origin
    extent = (x0, x0 + w * r, y0, y0 + h * r)
    size = 10.0
    fig, ax = plt.subplots(figsize=(size, size * h / max(w, 1) + 0.5), dpi=120)
    ax.imshow(1.0 - p, cmap="gray", origin="lower", extent=extent, vmin=0, vmax=1,
              interpolation="nearest")  # fmt: skip
    xy = np.array([[q.x, q.y] for q in poses if q is not None]).reshape(-1, 2)
    if len(xy):
        ax.plot(xy[:, 0], xy[:, 1], "-", color="tab:blue", lw=0.6, label="trajectory")
    segs = [
        (poses[c.i], poses[c.j])
        for c in closures
        if poses[c.i] is not None and poses[c.j] is not None
    ]
    for k, (a, b) in enumerate(segs):
        ax.plot([a.x, b.x], [a.y, b.y], "-", color="tab:red", lw=0.5, alpha=0.6,
                label="loop closures" if k == 0 else None)  # fmt: skip
    if covariances is not None and len(poses):
        from ..plot import ellipse_outline  # noqa: PLC0415

        step = max(1, -(-len(poses) // MAX_ELLIPSES))
        drawn = 0
        for q, c in zip(poses[::step], covariances[::step], strict=True):
            if q is None or c is None:
                continue
            e = ellipse_outline((q.x, q.y), np.asarray(c)[:2, :2], 3.0)
            ax.plot(e[:, 0], e[:, 1], "-", color="tab:green", lw=0.6,
                    label="position, 3 sigma" if drawn == 0 else None)  # fmt: skip
            drawn += 1
    ax.set_aspect("equal")
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    if title:
        ax.set_title(title)
    if len(xy) or segs:
        ax.legend(loc="upper right", fontsize=8)
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)


def map_config_dict(cfg) -> dict:
    """The :class:`~scanclique.mapping.config.MapConfig` as plain data (JSON-ready)."""
    import dataclasses  # noqa: PLC0415

    out = {}
    for f in dataclasses.fields(cfg):
        v = getattr(cfg, f.name)
        if f.name == "match":
            out[f.name] = config_to_dict(v)
        else:
            out[f.name] = clean_json(dataclasses.asdict(v))
    return out


def write_report(path: str | Path, report: dict) -> None:
    """Write ``report.json`` (non-finite numbers become null, NumPy arrays lists)."""
    Path(path).write_text(json.dumps(clean_json(report), indent=2, sort_keys=False) + "\n")
