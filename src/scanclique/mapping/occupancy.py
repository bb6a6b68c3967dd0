"""Occupancy grid by log-odds ray casting (issue 12, part 4).

Every beam of every cast scan walks the cells from the sensor to its end point (Bresenham's
line, Bresenham 1965): the cells it passes are evidence of free space (``log_odds_miss``
added), the end cell of a valid return evidence of an obstacle (``log_odds_hit``); the sum
is clamped to ``[-clamp, clamp]`` (Thrun, Burgard and Fox, *Probabilistic Robotics*, §9.2,
the inverse sensor model in log-odds form). A return beyond ``max_range`` marks free
space only, up to ``max_range``; a beam with no return is skipped (or, with
``free_on_no_return``, marks free space up to ``max_range``: a *no return* is a reading at or
beyond the scan's ``range_max``, +inf included, as ROS drivers mark "nothing within reach"
(REP 117); NaN, -inf and readings at or below ``range_min`` say nothing of the space ahead
and are always skipped).

The kernel is compiled with numba on first use (``@njit(cache=True)``), never at import.
The grid's cell ``(row, col)`` covers ``x in [x0 + col r, x0 + (col + 1) r)`` and
``y in [y0 + row r, ...)``: row 0 is the *lowest* y (the images are flipped when written,
as ROS ``map_server`` expects the top row first).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from ..config import require_config
from ..errors import ArgumentError, ConfigError
from ..geometry import Pose2
from ..scan import Scan, deskew_along
from .config import OccupancyConfig

__all__ = ["MAX_GRID_CELLS", "OccupancyGrid", "occupancy_grid", "probabilities"]

MAX_GRID_CELLS = 2**30
"""Most cells of an occupancy grid (4 GiB of float32): a finer one is a
:class:`~scanclique.errors.ConfigError` naming the resolution (``resolution=1e-7`` asked
numpy for 32.9 PiB, a MemoryError traceback after the whole mapping run). A 250 x 200 m
building at the default 0.05 m is 2 10^7 cells."""

_KERNEL = None


def _kernel():
    """The compiled ray-casting kernel (loaded lazily: numba compiles or loads it on first
    use)."""
    global _KERNEL
    if _KERNEL is None:
        from .._kernels.jit import njit  # noqa: PLC0415

        @njit(cache=True)
        def cast(grid, ox, oy, ex, ey, hit, l_hit, l_miss, clamp):  # pragma: no cover
            rows, cols = grid.shape
            for b in range(ox.shape[0]):
                x0, y0, x1, y1 = ox[b], oy[b], ex[b], ey[b]
                dx = abs(x1 - x0)
                dy = -abs(y1 - y0)
                sx = 1 if x0 < x1 else -1
                sy = 1 if y0 < y1 else -1
                err = dx + dy
                x, y = x0, y0
                while True:
                    if x == x1 and y == y1:
                        break
                    if 0 <= x < cols and 0 <= y < rows:
                        v = grid[y, x] + l_miss
                        grid[y, x] = v if v > -clamp else -clamp
                    e2 = 2 * err
                    if e2 >= dy:
                        err += dy
                        x += sx
                    if e2 <= dx:
                        err += dx
                        y += sy
                    # off the grid and moving away (x and y never pass x1, y1): no cell
                    # of the rest, the end included, is on it; a long free-only beam
                    # (max_range) walked all of its cells
                    if (x < 0 and sx < 0) or (x >= cols and sx > 0):
                        break
                    if (y < 0 and sy < 0) or (y >= rows and sy > 0):
                        break
                if 0 <= x1 < cols and 0 <= y1 < rows:
                    if hit[b]:
                        v = grid[y1, x1] + l_hit
                        grid[y1, x1] = v if v < clamp else clamp
                    else:
                        v = grid[y1, x1] + l_miss
                        grid[y1, x1] = v if v > -clamp else -clamp
            return grid

        _KERNEL = cast
    return _KERNEL


@dataclass(frozen=True, slots=True, eq=False)
class OccupancyGrid:
    """A log-odds occupancy grid.

    ``log_odds`` ``(rows, cols)`` float32 (0: unknown), row 0 at the lowest y;
    ``resolution`` metres per cell; ``origin`` ``(x, y)`` of the lower-left corner of cell
    ``(0, 0)`` in the map frame (metres)."""

    log_odds: np.ndarray
    resolution: float
    origin: tuple[float, float]

    def __post_init__(self) -> None:
        self.log_odds.setflags(write=False)

    @property
    def shape(self) -> tuple[int, int]:
        return self.log_odds.shape


def probabilities(log_odds: np.ndarray) -> np.ndarray:
    """Occupancy probability of each cell, ``1 - 1 / (1 + exp(l))``."""
    return 1.0 - 1.0 / (1.0 + np.exp(log_odds.astype(float)))


def occupancy_grid(
    scans: Sequence[Scan],
    poses: Sequence[Pose2 | None],
    config: OccupancyConfig | None = None,
    *,
    timing: str | None = "given",
) -> OccupancyGrid:
    """Cast every ``config.scan_stride``-th placed scan into a log-odds grid.

    A scan whose beams carry their times (:attr:`~scanclique.scan.Scan.beam_times`, a
    rotating lidar) is cast de-skewed along ``poses`` (the velocity to the next placed
    scan), its times read as ``timing`` says (:func:`scanclique.scan.retime`; the map's
    ``MapResult.sweep_timing``), as the mapper matched it; ``timing=None``: as it is.

    Parameters
    ----------
    scans : sequence of Scan
    poses : sequence of Pose2 or None
        Pose of each scan's sensor in the map frame (maps sensor points into the map);
        scans with None are skipped.
    config : OccupancyConfig, optional

    Returns
    -------
    OccupancyGrid
        All unknown (zeros) when no scan is placed or no placed scan has a beam to cast.

    Raises
    ------
    ArgumentError
        ``poses`` is not one per scan, a pose is not a :class:`~scanclique.geometry.Pose2`
        or None, or a scan not a :class:`~scanclique.scan.Scan`.
    ConfigError
        ``config`` is not an :class:`OccupancyConfig`, or the grid would have more than
        :data:`MAX_GRID_CELLS` cells (poses or returns far apart).
    """
    if len(poses) != len(scans):
        raise ArgumentError(
            f"occupancy_grid: {len(poses)} poses for {len(scans)} scans (one per scan, None "
            "for a scan that is not placed)"
        )
    for k, (s, p) in enumerate(zip(scans, poses, strict=True)):
        if not isinstance(s, Scan):
            raise ArgumentError(f"occupancy_grid: scans[{k}] is a {type(s).__name__}, not a Scan")
        if p is not None and not isinstance(p, Pose2):
            raise ArgumentError(
                f"occupancy_grid: poses[{k}] is a {type(p).__name__}, not a Pose2 or None"
            )
    require_config("occupancy_grid: ", config, OccupancyConfig)
    cfg = config or OccupancyConfig()
    r = cfg.resolution
    idx = [k for k in range(0, len(scans), cfg.scan_stride) if poses[k] is not None]
    if not idx:
        return OccupancyGrid(np.zeros((1, 1), np.float32), r, (0.0, 0.0))
    # beam end points in the map frame, first to size the grid
    starts, ends, hits = [], [], []
    for k in idx:
        s = scans[k] if timing is None else deskew_along(scans, k, poses.__getitem__, timing)
        p = poses[k]
        keep = s.valid | s.no_return if cfg.free_on_no_return else s.valid
        rng = np.where(s.valid, s.ranges, cfg.max_range)[keep]
        hit = s.valid[keep] & (rng <= cfg.max_range)
        rng = np.minimum(rng, cfg.max_range)
        ang = s.angles[keep]
        pts = np.column_stack((rng * np.cos(ang), rng * np.sin(ang)))
        ends.append(p.transform(pts))
        starts.append(np.repeat([[p.x, p.y]], len(pts), axis=0))
        hits.append(hit)
    E = np.vstack(ends)
    S = np.vstack(starts)
    H = np.concatenate(hits)
    # size the grid on the hits and the sensor positions (free-only beams are clipped)
    if H.any():
        pts = np.vstack([E[H], S[:1]])
    elif len(S):
        pts = S
    else:  # no placed scan kept a beam (all NaN, or no beams): an empty grid at the poses
        pts = np.array([[poses[k].x, poses[k].y] for k in idx])
    lo = pts.min(axis=0) - cfg.margin
    hi = pts.max(axis=0) + cfg.margin
    with np.errstate(over="ignore", invalid="ignore"):
        extent = hi - lo  # inf for poses 1e308 apart: ceil would overflow
    size = extent / r
    far = not np.all(size <= MAX_GRID_CELLS)
    cols = int(math.ceil(size[0])) + 1 if not far else math.inf
    rows = int(math.ceil(size[1])) + 1 if not far else math.inf
    if far or rows * cols > MAX_GRID_CELLS:
        raise ConfigError(
            f"occupancy grid of {cols} x {rows} cells ({extent[0]:.6g} x "
            f"{extent[1]:.6g} m at OccupancyConfig.resolution={r:g} m, margin "
            f"{cfg.margin:g} m): more than {MAX_GRID_CELLS} cells; use a coarser resolution"
        )
    grid = np.zeros((rows, cols), dtype=np.float32)

    def cell(P):
        return np.floor((P - lo) / r).astype(np.int64)

    cs, ce = cell(S), cell(E)
    _kernel()(
        grid, cs[:, 0].copy(), cs[:, 1].copy(), ce[:, 0].copy(), ce[:, 1].copy(), H,
        np.float32(cfg.log_odds_hit), np.float32(cfg.log_odds_miss), np.float32(cfg.clamp),
    )  # fmt: skip
    return OccupancyGrid(grid, r, (float(lo[0]), float(lo[1])))
