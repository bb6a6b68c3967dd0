"""A 2D indoor laser simulator: buildings, ray casting, scan pairs and short drives.

The unit tests and ``make demo`` use it to make scans whose relative pose is known.

Frames and units
----------------
Everything is in metres and radians. The *world frame* is the frame wall coordinates are
given in. The *sensor frame* has x forward (beam angle 0) and y to the left, and beam
angles grow counter-clockwise. ``pose_world_sensor`` (stored as :attr:`Scan.reference`)
maps sensor-frame points into the world frame::

    p_world = pose_world_sensor.transform(p_sensor)

A :class:`SimPair` carries ``pose_a_b = reference_a.inverse() @ reference_b``. It maps
points of scan b's sensor frame into scan a's sensor frame, which is the transform a
scan matcher should recover.

Randomness
----------
Every function that draws random numbers takes a ``numpy.random.Generator`` as ``rng``.
The same generator state and arguments always give the same output. Nothing reads the
global NumPy random state.

Worlds
------
A :class:`World` is made of wall segments (walls, box edges, clutter), circles (pillars)
and two lists that only the pose sampler uses: the rectangles of navigable floor and the
convex quadrilaterals that are solid (the inside of a box or table). Builders return
worlds at laser scale. Rooms are 3-10 m, corridors 1.5-3 m wide, doorways 0.8-1 m,
pillars 0.1-0.3 m in radius and clutter objects 0.2-1 m across.
"""

from __future__ import annotations

import math
from collections import Counter
from dataclasses import dataclass, field

import numpy as np

from ._records import readonly as _readonly
from .config import require_at_most, require_nonneg, require_positive
from .errors import ConfigError, ScanCliqueError
from .geometry import Pose2
from .scan import MAX_POSE_COORDINATE, Scan, beam_angles

__all__ = [
    "World",
    "SimPair",
    "room_world",
    "corridor_world",
    "office_world",
    "random_world",
    "ring_world",
    "campus_world",
    "cast_rays",
    "simulate_scan",
    "simulate_pair",
    "simulate_trajectory",
    "simulate_sensor_drive",
    "simulate_ring_drive",
    "MAX_BEAMS",
    "MAX_EXTENT",
    "MAX_OBJECTS",
    "MAX_PEOPLE",
    "MAX_SCANS",
    "MAX_SCAN_RATE",
]

# Building dimensions at laser scale, metres (low, high).
ROOM_SIZE = (3.0, 10.0)
CORRIDOR_WIDTH = (1.5, 3.0)
DOOR_WIDTH = (0.8, 1.0)
PILLAR_RADIUS = (0.1, 0.3)
CLUTTER_SIZE = (0.2, 1.0)
PERSON_RADIUS = (0.15, 0.25)

_PASSAGE = 0.7  # gap (m) kept between free-standing furniture so a robot can pass
_TRIES = 40  # rejection-sampling attempts per piece of furniture or person
_MIN_VALID_FRACTION = 0.5  # a usable view has returns on at least half of its beams...
_MIN_MEDIAN_RANGE = 0.8  # ...and does not stare into a wall (median return, metres)
_EPS = 1e-9

# Bounds on what one call may ask for: beyond them a call on a small world ran for minutes
# (``room_world(5, 5, pillars=10**6)``, ``ring_world(door_every=1e-6)``); each is a
# ConfigError naming the argument.
MAX_BEAMS = 100_000
"""Most beams of a simulated scan (the readers' default ``max_beams``)."""
MAX_EXTENT = 10_000.0
"""Largest size of a world, metres (a building or a campus, 10 km)."""
MIN_EXTENT = 1e-3
"""Smallest size of a room or a corridor, metres (a thinner one has no walls)."""
MAX_OBJECTS = 1_000
"""Most doorways, pillars or clutter objects asked of a world builder, and most
buildings, doors or trees a builder's sizes make."""
MAX_TREES = 10_000
"""Most trees the streets of :func:`campus_world` may line (at the densest spacing)."""
MAX_PEOPLE = 100
"""Most moving people in a :func:`simulate_pair`."""
MAX_SCANS = 100_000
"""Most scans (or drive steps) one simulated drive makes."""
MAX_SCAN_RATE = 1_000.0
"""Fastest scanner of :func:`simulate_sensor_drive`, Hz (laser scanners run at 5-50 Hz)."""


def _check_rng(rng, where: str) -> np.random.Generator:
    if not isinstance(rng, np.random.Generator):
        raise ConfigError(
            f"{where}: rng must be a numpy.random.Generator (e.g. numpy.random.default_rng(0)),"
            f" got {type(rng).__name__}"
        )
    return rng


def _check_positive(where: str, **values: float) -> None:
    require_positive(f"{where}: ", **values)


def _check_nonneg(where: str, **values: float) -> None:
    require_nonneg(f"{where}: ", **values)


def _check_count(where: str, **values: int) -> None:
    for name, v in values.items():
        if not (isinstance(v, (int, np.integer)) and not isinstance(v, bool) and v >= 0):
            raise ConfigError(f"{where}: {name} must be a non-negative integer, got {v!r}")


def _check_at_most(where: str, limit: float, **values: float) -> None:
    require_at_most(f"{where}: ", limit, **values)


def _check_beams(where: str, n_beams) -> None:
    _check_count(where, n_beams=n_beams)
    _check_positive(where, n_beams=n_beams)
    _check_at_most(where, MAX_BEAMS, n_beams=n_beams)


def _check_origin(where: str, origin) -> tuple[float, float]:
    """``origin`` as two finite numbers within MAX_POSE_COORDINATE of the frame's origin."""
    try:
        o = np.asarray(origin, dtype=float)
    except (TypeError, ValueError):
        o = None
    if o is None or o.shape != (2,) or not np.all(np.abs(o) <= MAX_POSE_COORDINATE):
        raise ConfigError(
            f"{where}: origin must be two finite numbers (x, y) within "
            f"{MAX_POSE_COORDINATE:g} m, got {origin!r}"
        )
    return float(o[0]), float(o[1])


# ------------------------------------------------------------------------------------
# World model
# ------------------------------------------------------------------------------------
@dataclass(frozen=True, slots=True, eq=False)
class World:
    """A 2D building: wall segments and circular obstacles, in the world frame (metres).

    Attributes
    ----------
    walls : ndarray, shape (K, 2, 2)
        Segments ``walls[k] = [[x0, y0], [x1, y1]]``: walls, the edges of boxes and tables,
        clutter. Segments have zero thickness, and a ray stops at the first one it meets.
    circle_centres : ndarray, shape (P, 2)
        Centres of circular obstacles such as pillars.
    circle_radii : ndarray, shape (P,)
        Their radii, all positive.
    free_regions : ndarray, shape (R, 4)
        Axis-aligned rectangles ``(xmin, ymin, xmax, ymax)`` of navigable floor (rooms,
        corridors). Poses are sampled from them. When none are given, this defaults to
        the bounding box of the walls (none if that box is flat).
    solids : ndarray, shape (B, 4, 2)
        Convex quadrilaterals (vertices in order) whose inside is solid, such as boxes and
        tables. Their edges must also appear in ``walls``. Only free-space tests use them.
    name : str
        A short description, e.g. ``"room 5.0 x 4.0 m"``.

    Examples
    --------
    >>> square = np.array([[[0, 0], [4, 0]], [[4, 0], [4, 4]], [[4, 4], [0, 4]], [[0, 4], [0, 0]]])
    >>> world = World(square, circle_centres=[[1.0, 1.0]], circle_radii=[0.2])
    >>> world.free_regions
    array([[0., 0., 4., 4.]])
    >>> world.is_free(np.array([[2.0, 2.0], [1.1, 1.0], [0.1, 2.0]]), clearance=0.3)
    array([ True, False, False])
    """

    walls: np.ndarray
    circle_centres: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))
    circle_radii: np.ndarray = field(default_factory=lambda: np.zeros(0))
    free_regions: np.ndarray = field(default_factory=lambda: np.zeros((0, 4)))
    solids: np.ndarray = field(default_factory=lambda: np.zeros((0, 4, 2)))
    name: str = ""

    def __post_init__(self) -> None:
        def arr(name: str, shape_tail: tuple[int, ...]) -> np.ndarray:
            try:
                a = np.array(getattr(self, name), dtype=np.float64, copy=True)
            except (TypeError, ValueError) as exc:
                raise ConfigError(f"World.{name} must be a numeric array ({exc})") from None
            if a.size == 0:
                a = a.reshape((0, *shape_tail))
            if a.ndim != 1 + len(shape_tail) or a.shape[1:] != shape_tail:
                want = ", ".join(["N", *map(str, shape_tail)])
                raise ConfigError(f"World.{name} must have shape ({want}), got {a.shape}")
            if not np.all(np.isfinite(a)):
                raise ConfigError(f"World.{name} must be finite")
            return a

        walls = arr("walls", (2, 2))
        centres = arr("circle_centres", (2,))
        radii = arr("circle_radii", ())
        regions = arr("free_regions", (4,))
        solids = arr("solids", (4, 2))
        if centres.shape[0] != radii.shape[0]:
            raise ConfigError(
                f"World: {centres.shape[0]} circle centres but {radii.shape[0]} radii"
            )
        if np.any(radii <= 0):
            raise ConfigError(f"World.circle_radii must be positive, got min {radii.min()}")
        if regions.shape[0] == 0 and walls.shape[0] > 0:
            pts = walls.reshape(-1, 2)
            box = np.concatenate((pts.min(axis=0), pts.max(axis=0)))
            if box[2] > box[0] and box[3] > box[1]:  # a single straight wall encloses nothing
                regions = box[None, :]
        if np.any(regions[:, 2] <= regions[:, 0]) or np.any(regions[:, 3] <= regions[:, 1]):
            raise ConfigError("World.free_regions rows must be (xmin, ymin, xmax, ymax), min < max")
        object.__setattr__(self, "walls", _readonly(walls))
        object.__setattr__(self, "circle_centres", _readonly(centres))
        object.__setattr__(self, "circle_radii", _readonly(radii))
        object.__setattr__(self, "free_regions", _readonly(regions))
        object.__setattr__(self, "solids", _readonly(solids))
        object.__setattr__(self, "name", str(self.name))

    @property
    def n_walls(self) -> int:
        """Number of wall segments K."""
        return int(self.walls.shape[0])

    @property
    def n_circles(self) -> int:
        """Number of circular obstacles P."""
        return int(self.circle_radii.shape[0])

    @property
    def bounds(self) -> tuple[float, float, float, float]:
        """``(xmin, ymin, xmax, ymax)`` of everything in the world (metres)."""
        pts = [self.walls.reshape(-1, 2), self.free_regions.reshape(-1, 2)]
        if self.n_circles:
            r = self.circle_radii[:, None]
            pts += [self.circle_centres - r, self.circle_centres + r]
        allp = np.concatenate(pts)
        if allp.size == 0:
            return (0.0, 0.0, 0.0, 0.0)
        lo, hi = allp.min(axis=0), allp.max(axis=0)
        return (float(lo[0]), float(lo[1]), float(hi[0]), float(hi[1]))

    def distance(self, points) -> np.ndarray:
        """Distance (metres) from world-frame points to the nearest wall or circle boundary.

        Parameters
        ----------
        points : array_like, shape (M, 2)
            Points in the world frame.

        Returns
        -------
        ndarray, shape (M,)
            Distance to the nearest surface. It is ``inf`` when the world is empty.
        """
        p = _as_points(points, "World.distance")
        d = np.full(p.shape[0], np.inf)
        if self.n_walls:
            d = np.minimum(d, _point_segment_distances(p, self.walls).min(axis=1))
        if self.n_circles:
            dc = np.linalg.norm(p[:, None, :] - self.circle_centres[None], axis=2)
            d = np.minimum(d, np.abs(dc - self.circle_radii[None]).min(axis=1))
        return d

    def is_free(self, points, clearance: float = 0.0) -> np.ndarray:
        """Which world-frame points a robot may stand on with this clearance.

        A point is free when it lies in a free region, outside every solid, at least
        ``clearance`` metres from every wall segment, and at least ``clearance`` metres
        outside every circle.

        Parameters
        ----------
        points : array_like, shape (M, 2)
            Points in the world frame (metres).
        clearance : float
            Required distance (metres) to the nearest obstacle.

        Returns
        -------
        ndarray of bool, shape (M,)
        """
        p = _as_points(points, "World.is_free")
        require_nonneg("World.is_free: ", clearance=clearance)
        reg = self.free_regions
        ok = (
            (p[:, None, 0] >= reg[None, :, 0])
            & (p[:, None, 0] <= reg[None, :, 2])
            & (p[:, None, 1] >= reg[None, :, 1])
            & (p[:, None, 1] <= reg[None, :, 3])
        ).any(axis=1)
        if self.solids.shape[0]:
            v = self.solids  # (B, 4, 2)
            edge = np.roll(v, -1, axis=1) - v  # (B, 4, 2)
            rel = p[:, None, None, :] - v[None]  # (M, B, 4, 2)
            cross = edge[None, ..., 0] * rel[..., 1] - edge[None, ..., 1] * rel[..., 0]
            inside = np.all(cross > 0, axis=2) | np.all(cross < 0, axis=2)  # (M, B)
            ok &= ~inside.any(axis=1)
        if self.n_walls:
            ok &= _point_segment_distances(p, self.walls).min(axis=1) >= clearance
        if self.n_circles:
            dc = np.linalg.norm(p[:, None, :] - self.circle_centres[None], axis=2)
            ok &= np.all(dc >= self.circle_radii[None] + clearance, axis=1)
        return np.asarray(ok, dtype=bool)

    def __repr__(self) -> str:
        return (
            f"World({self.name or 'unnamed'}, walls={self.n_walls}, circles={self.n_circles}, "
            f"regions={self.free_regions.shape[0]}, solids={self.solids.shape[0]})"
        )


def _as_points(points, where: str) -> np.ndarray:
    p = np.asarray(points, dtype=float)
    if p.ndim == 1 and p.shape == (2,):
        p = p[None, :]
    if p.ndim != 2 or p.shape[1] != 2:
        raise ConfigError(f"{where} expects (M, 2) points, got shape {p.shape}")
    return p


def _point_segment_distances(p: np.ndarray, segs: np.ndarray) -> np.ndarray:
    """Distances (M, K) from points (M, 2) to segments (K, 2, 2)."""
    a = segs[:, 0]
    ab = segs[:, 1] - a
    ab2 = np.maximum(np.einsum("kd,kd->k", ab, ab), _EPS * _EPS)
    ap = p[:, None, :] - a[None]
    t = np.clip(np.einsum("mkd,kd->mk", ap, ab) / ab2, 0.0, 1.0)
    closest = a[None] + t[..., None] * ab[None]
    return np.linalg.norm(p[:, None, :] - closest, axis=2)


# ------------------------------------------------------------------------------------
# World builders
# ------------------------------------------------------------------------------------
class _Builder:
    """Collects the parts of a building. Furniture placement stays out of doorways and
    leaves passages between pieces."""

    def __init__(self, rng: np.random.Generator):
        self.rng = rng
        self.walls: list[list[list[float]]] = []
        self.centres: list[list[float]] = []
        self.radii: list[float] = []
        self.solids: list[np.ndarray] = []
        self.regions: list[tuple[float, float, float, float]] = []
        self.keepouts: list[tuple[float, float, float]] = []  # (x, y, radius) no-go discs

    # -- structure ----------------------------------------------------------------
    def wall(self, p, q) -> None:
        self.walls.append([[float(p[0]), float(p[1])], [float(q[0]), float(q[1])]])

    def polyline(self, pts) -> None:
        for p, q in zip(pts[:-1], pts[1:], strict=True):
            self.wall(p, q)

    def wall_with_gaps(self, p, q, gaps) -> None:
        """Wall from p to q, minus gaps ``(centre distance from p, width)``. Each gap
        becomes a doorway that furniture keeps clear of."""
        p, q = np.asarray(p, float), np.asarray(q, float)
        length = float(np.linalg.norm(q - p))
        u = (q - p) / length
        s = 0.0
        for c, w in sorted(gaps):
            if c - w / 2 > s + _EPS:
                self.wall(p + s * u, p + (c - w / 2) * u)
            s = c + w / 2
            centre = p + c * u
            self.keepouts.append((float(centre[0]), float(centre[1]), w / 2 + 0.6))
        if length > s + _EPS:
            self.wall(p + s * u, q)

    def gaps(self, length: float, n: int, *, margin: float = 0.3, taken=()) -> list:
        """Up to ``n`` doorway gaps ``(centre, width)`` along a wall of this length. Each
        stays ``margin`` from the ends, from the ``taken`` intervals and from the other gaps."""
        out: list[tuple[float, float]] = []
        for _ in range(n):
            for _try in range(_TRIES):
                w = float(self.rng.uniform(*DOOR_WIDTH))
                lo, hi = margin + w / 2, length - margin - w / 2
                if hi <= lo:
                    break
                c = float(self.rng.uniform(lo, hi))
                a, b = c - w / 2 - margin, c + w / 2 + margin
                busy = [*taken, *((oc - ow / 2, oc + ow / 2) for oc, ow in out)]
                if all(b <= ta or a >= tb for ta, tb in busy):
                    out.append((c, w))
                    break
        return out

    def region(self, x0: float, y0: float, x1: float, y1: float) -> None:
        self.regions.append((float(x0), float(y0), float(x1), float(y1)))

    # -- furniture ----------------------------------------------------------------
    def furnish(self, rect, *, pillars: int, clutter: int) -> None:
        """Put pillars and clutter into the rectangle ``(x0, y0, x1, y1)``. Clutter is
        boxes against a wall, free-standing boxes or tables, and irregular debris. A piece
        that does not fit after a bounded number of tries is left out."""
        for _ in range(pillars):
            self._pillar(rect)
        place = (self._box_at_wall, self._free_box, self._debris)
        for _ in range(clutter):
            place[int(self.rng.choice(3, p=(0.4, 0.3, 0.3)))](rect)

    def _fits(self, c, r: float, margin: float) -> bool:
        return all(math.hypot(c[0] - x, c[1] - y) >= r + kr + margin for x, y, kr in self.keepouts)

    def _centre_in(self, rect, inset: float):
        x0, y0, x1, y1 = rect
        if x1 - x0 <= 2 * inset or y1 - y0 <= 2 * inset:
            return None
        return np.array(
            [self.rng.uniform(x0 + inset, x1 - inset), self.rng.uniform(y0 + inset, y1 - inset)]
        )

    def _pillar(self, rect) -> None:
        for _ in range(_TRIES):
            r = float(self.rng.uniform(*PILLAR_RADIUS))
            c = self._centre_in(rect, r + _PASSAGE)
            if c is not None and self._fits(c, r, _PASSAGE):
                self.centres.append([float(c[0]), float(c[1])])
                self.radii.append(r)
                self.keepouts.append((float(c[0]), float(c[1]), r))
                return

    def _add_box(self, corners: np.ndarray) -> None:
        self.polyline([*corners, corners[0]])
        self.solids.append(corners)
        c = corners.mean(axis=0)
        r = float(np.linalg.norm(corners - c, axis=1).max())
        self.keepouts.append((float(c[0]), float(c[1]), r))

    def _box_at_wall(self, rect) -> None:
        x0, y0, x1, y1 = rect
        # Each side as (start point, direction along the wall, inward normal, length).
        sides = (
            ((x0, y0), (1, 0), (0, 1), x1 - x0),
            ((x1, y0), (0, 1), (-1, 0), y1 - y0),
            ((x1, y1), (-1, 0), (0, -1), x1 - x0),
            ((x0, y1), (0, -1), (1, 0), y1 - y0),
        )
        for _ in range(_TRIES):
            a, b = self.rng.uniform(*CLUTTER_SIZE, size=2)  # along the wall, depth
            o, u, n, length = (np.asarray(v, float) for v in sides[int(self.rng.integers(4))])
            gap = self.rng.uniform(0.02, 0.1)
            if length < a + 0.2 or b + gap > 0.5 * min(x1 - x0, y1 - y0):
                continue
            s = self.rng.uniform(0.1, length - a - 0.1)
            corners = np.array(
                [
                    o + s * u + gap * n,
                    o + (s + a) * u + gap * n,
                    o + (s + a) * u + (gap + b) * n,
                    o + s * u + (gap + b) * n,
                ]
            )
            c = corners.mean(axis=0)
            if self._fits(c, 0.5 * math.hypot(a, b), 0.3):
                self._add_box(corners)
                return

    def _free_box(self, rect) -> None:
        for _ in range(_TRIES):
            a, b = self.rng.uniform(*CLUTTER_SIZE, size=2)
            phi = self.rng.uniform(-np.pi, np.pi)
            r = 0.5 * math.hypot(a, b)
            c = self._centre_in(rect, r + _PASSAGE)
            if c is None or not self._fits(c, r, _PASSAGE):
                continue
            local = np.array([[-a, -b], [a, -b], [a, b], [-a, b]]) / 2
            rot = np.array([[math.cos(phi), -math.sin(phi)], [math.sin(phi), math.cos(phi)]])
            self._add_box(local @ rot.T + c)
            return

    def _debris(self, rect) -> None:
        """An irregular open polyline of 1-3 short segments (a chair, a bin, a plant)."""
        for _ in range(_TRIES):
            k = int(self.rng.integers(1, 4))
            heading = self.rng.uniform(-np.pi, np.pi)
            pts = [np.zeros(2)]
            for _seg in range(k):
                heading += self.rng.uniform(-2.0, 2.0)
                step = self.rng.uniform(0.2, 0.5)
                pts.append(pts[-1] + step * np.array([math.cos(heading), math.sin(heading)]))
            P = np.array(pts)
            P -= 0.5 * (P.min(axis=0) + P.max(axis=0))
            r = float(np.linalg.norm(P, axis=1).max())
            if r > 0.5:  # keep the whole object within 1 m
                P *= 0.5 / r
                r = 0.5
            c = self._centre_in(rect, r + _PASSAGE)
            if c is None or not self._fits(c, r, _PASSAGE):
                continue
            self.polyline(P + c)
            self.keepouts.append((float(c[0]), float(c[1]), r))
            return

    def build(self, name: str) -> World:
        return World(
            walls=np.array(self.walls, dtype=float).reshape(-1, 2, 2),
            circle_centres=np.array(self.centres, dtype=float).reshape(-1, 2),
            circle_radii=np.array(self.radii, dtype=float),
            free_regions=np.array(self.regions, dtype=float).reshape(-1, 4),
            solids=np.array(self.solids, dtype=float).reshape(-1, 4, 2),
            name=name,
        )


def _check_extent(where: str, **values: float) -> None:
    """Each (positive) size is within [MIN_EXTENT, MAX_EXTENT] metres."""
    for name, v in values.items():
        if not MIN_EXTENT <= v <= MAX_EXTENT:
            raise ConfigError(
                f"{where}: {name} must be {MIN_EXTENT:g} to {MAX_EXTENT:g} m, got {v!r}"
            )


def room_world(
    width: float,
    height: float,
    *,
    rng: np.random.Generator,
    doorways: int = 1,
    pillars: int = 1,
    clutter: int = 4,
    origin: tuple[float, float] = (0.0, 0.0),
) -> World:
    """A single rectangular room with doorways, pillars and clutter.

    The room spans ``[x0, x0 + width] x [y0, y0 + height]`` in the world frame, with
    ``(x0, y0) = origin``. Each doorway opens onto the outside, where a backdrop wall
    1.5-3 m beyond it stands for the corridor a real door leads to. A piece of
    furniture that cannot be placed after a bounded number of tries is left out.

    Parameters
    ----------
    width, height : float
        Inner size of the room, metres (realistic rooms are 3-10 m).
    rng : numpy.random.Generator
        Source of all randomness.
    doorways, pillars, clutter : int
        Counts of doorways (0.8-1 m gaps in the walls), pillars (radius 0.1-0.3 m) and
        clutter objects (boxes, tables and debris, 0.2-1 m across).
    origin : (float, float)
        World coordinates of the room's lower-left corner, metres.

    Returns
    -------
    World

    Raises
    ------
    ConfigError
        A size outside :data:`MIN_EXTENT` to :data:`MAX_EXTENT`, a count that is not an
        integer of 0 to :data:`MAX_OBJECTS`, or an origin that is not two finite numbers
        within :data:`~scanclique.scan.MAX_POSE_COORDINATE`.

    Examples
    --------
    >>> w = room_world(4.0, 3.0, rng=np.random.default_rng(0), doorways=0, pillars=0, clutter=0)
    >>> w.n_walls, w.free_regions.tolist()
    (4, [[0.0, 0.0, 4.0, 3.0]])
    """
    where = "room_world"
    _check_rng(rng, where)
    _check_positive(where, width=width, height=height)
    _check_extent(where, width=width, height=height)
    _check_count(where, doorways=doorways, pillars=pillars, clutter=clutter)
    _check_at_most(where, MAX_OBJECTS, doorways=doorways, pillars=pillars, clutter=clutter)
    x0, y0 = _check_origin(where, origin)
    b = _Builder(rng)
    x1, y1 = x0 + float(width), y0 + float(height)
    corners = [(x0, y0), (x1, y0), (x1, y1), (x0, y1)]  # counter-clockwise
    lengths = np.array([width, height, width, height], dtype=float)
    door_side = rng.choice(4, size=doorways, p=lengths / lengths.sum())
    for i in range(4):
        p, q = np.array(corners[i]), np.array(corners[(i + 1) % 4])
        gaps = b.gaps(float(lengths[i]), int(np.sum(door_side == i)))
        b.wall_with_gaps(p, q, gaps)
        u = (q - p) / lengths[i]
        outward = np.array([u[1], -u[0]])  # right-hand normal of a counter-clockwise edge
        for c, _w in gaps:
            centre = p + c * u + rng.uniform(1.5, 3.0) * outward
            half = rng.uniform(1.5, 3.0)
            b.wall(centre - half * u, centre + half * u)
    b.region(x0, y0, x1, y1)
    b.furnish((x0, y0, x1, y1), pillars=pillars, clutter=clutter)
    return b.build(f"room {width:.1f} x {height:.1f} m")


def corridor_world(
    length: float,
    width: float,
    *,
    rng: np.random.Generator,
    side_rooms: int = 2,
    doorways: int = 2,
    clutter: int = 2,
) -> World:
    """A straight corridor along the x axis, with rooms and closed doors on its sides.

    The corridor spans ``[0, length] x [0, width]``. Side rooms (3-6 m wide and deep)
    alternate between the two sides and open into the corridor through one doorway each.
    ``doorways`` more are closed doors: 0.8-1 m gaps with a shallow recess (0.15-0.4 m)
    behind them.

    Parameters
    ----------
    length, width : float
        Corridor size, metres (realistic widths are 1.5-3 m).
    rng : numpy.random.Generator
        Source of all randomness.
    side_rooms : int
        Number of rooms off the corridor.
    doorways : int
        Number of closed doors (recesses) in the corridor walls. A door that does not
        fit is left out.
    clutter : int
        Clutter objects per side room.

    Returns
    -------
    World

    Raises
    ------
    ConfigError
        If the side rooms (at least 3 m each) or the doorways (at least 0.8 m each) do not
        fit along the corridor, a size is outside :data:`MIN_EXTENT` to
        :data:`MAX_EXTENT`, or a count is more than :data:`MAX_OBJECTS`.
    """
    where = "corridor_world"
    _check_rng(rng, where)
    _check_positive(where, length=length, width=width)
    _check_extent(where, length=length, width=width)
    _check_count(where, side_rooms=side_rooms, doorways=doorways, clutter=clutter)
    L, W = float(length), float(width)
    if doorways * DOOR_WIDTH[0] > 2.0 * L:
        raise ConfigError(
            f"{where}: {doorways} doorways of at least {DOOR_WIDTH[0]} m do not fit along the "
            f"two walls of a {L:.1f} m corridor"
        )
    _check_at_most(where, MAX_OBJECTS, side_rooms=side_rooms, doorways=doorways, clutter=clutter)
    b = _Builder(rng)
    # 1. Room spans along x, alternating between side 0 (below y=0) and side 1 (above y=W).
    first = int(rng.integers(2))
    per_side = [0, 0]
    for i in range(side_rooms):
        per_side[(first + i) % 2] += 1
    spans: list[list[tuple[float, float, float]]] = [[], []]  # (xa, xb, depth)
    for side in (0, 1):
        m = per_side[side]
        if m == 0:
            continue
        if m * 3.0 > L:
            raise ConfigError(
                f"{where}: {m} side rooms of at least 3 m do not fit along one side of a "
                f"{L:.1f} m corridor"
            )
        w = rng.uniform(3.0, 6.0, m)
        if w.sum() > L:
            w = 3.0 + (w - 3.0) * (L - 3.0 * m) / (w.sum() - 3.0 * m)
        slack = (L - w.sum()) * rng.dirichlet(np.ones(m + 1))
        x = slack[0]
        for i in range(m):
            spans[side].append((float(x), float(x + w[i]), float(rng.uniform(3.0, 6.0))))
            x += w[i] + slack[i + 1]
    # 2. Corridor walls with the room doors and the closed-door recesses.
    door_side = rng.integers(2, size=doorways)
    for side in (0, 1):
        y, out = (0.0, -1.0) if side == 0 else (W, 1.0)
        gaps = []
        for xa, xb, _d in spans[side]:
            gaps += [(xa + c, w) for c, w in b.gaps(xb - xa, 1)]
        taken = [(xa, xb) for xa, xb, _d in spans[side]]
        recesses = b.gaps(L, int(np.sum(door_side == side)), taken=taken)
        b.wall_with_gaps((0.0, y), (L, y), gaps + recesses)
        for c, w in recesses:
            e = out * rng.uniform(0.15, 0.4)
            b.polyline([(c - w / 2, y), (c - w / 2, y + e), (c + w / 2, y + e), (c + w / 2, y)])
        for xa, xb, d in spans[side]:
            b.polyline([(xa, y), (xa, y + out * d), (xb, y + out * d), (xb, y)])
            b.region(xa, min(y, y + out * d), xb, max(y, y + out * d))
    b.wall((0.0, 0.0), (0.0, W))
    b.wall((L, 0.0), (L, W))
    b.region(0.0, 0.0, L, W)
    # 3. Furniture in the side rooms only; the corridor stays clear.
    for rect in b.regions[:-1]:
        b.furnish(rect, pillars=0, clutter=clutter)
    return b.build(f"corridor {L:.1f} x {W:.1f} m, {side_rooms} side rooms")


def office_world(
    rng: np.random.Generator,
    *,
    length: float | None = None,
    corridor_width: float | None = None,
    room_depths: tuple[float, float] | None = None,
    pillars: int | None = None,
    clutter: int | None = None,
    connecting_doors: float = 0.3,
) -> World:
    """An office floor: a corridor along the x axis with a row of rooms on each side.

    The floor spans ``[0, length] x [-depth_below, corridor_width + depth_above]``.
    Every room (3-10 m) has a doorway into the corridor. With probability
    ``connecting_doors`` a partition wall also has a doorway into the next room.
    Pillars stand in randomly chosen rooms. Each room gets some clutter: boxes and
    tables against the walls or free-standing (small rectangles), and irregular debris
    segments.

    Parameters
    ----------
    rng : numpy.random.Generator
        Source of all randomness.
    length : float, optional
        Corridor length in metres. The default is uniform in 12-24 m.
    corridor_width : float, optional
        Metres. The default is uniform in 1.6-2.6 m.
    room_depths : (float, float), optional
        Depth of the rooms below and above the corridor, metres. The defaults are
        uniform in 3.5-6.5 m.
    pillars : int, optional
        Total number of pillars. The default is 2-4.
    clutter : int, optional
        Clutter objects per room. The default is 1-4, drawn for each room.
    connecting_doors : float
        Probability that a partition between neighbouring rooms has a doorway.

    Returns
    -------
    World

    Examples
    --------
    >>> w = office_world(np.random.default_rng(1))
    >>> w.free_regions.shape[0] >= 3  # a corridor and its rooms
    True
    """
    where = "office_world"
    _check_rng(rng, where)
    L = float(rng.uniform(12.0, 24.0)) if length is None else float(length)
    W = float(rng.uniform(1.6, 2.6)) if corridor_width is None else float(corridor_width)
    depths = rng.uniform(3.5, 6.5, 2) if room_depths is None else np.asarray(room_depths, float)
    _check_positive(where, length=L, corridor_width=W)
    _check_extent(where, length=L, corridor_width=W)
    if depths.shape != (2,) or not np.all((depths > 0) & (depths <= MAX_EXTENT)):
        raise ConfigError(
            f"{where}: room_depths must be two positive numbers of at most {MAX_EXTENT:g} m, "
            f"got {room_depths}"
        )
    if L < 3.0:
        raise ConfigError(f"{where}: length must be at least 3 m (one room), got {L}")
    if 2 * (L // 3.0) > MAX_OBJECTS:
        raise ConfigError(
            f"{where}: length {L:g} m makes up to {2 * (L // 3.0):.0f} rooms (two per 3 m), "
            f"more than {MAX_OBJECTS}"
        )
    if not 0.0 <= connecting_doors <= 1.0:
        raise ConfigError(f"{where}: connecting_doors must be in [0, 1], got {connecting_doors}")
    b = _Builder(rng)
    rooms: list[tuple[float, float, float, float]] = []
    y_out = (-float(depths[0]), W + float(depths[1]))
    # Outer shell.
    b.polyline([(0.0, y_out[0]), (L, y_out[0]), (L, y_out[1]), (0.0, y_out[1]), (0.0, y_out[0])])
    for side in (0, 1):
        y_wall = 0.0 if side == 0 else W
        # 1. Split this side into rooms at least 3 m wide.
        n = int(np.clip(round(L / rng.uniform(4.0, 6.0)), 1, int(L // 3.0)))
        widths = 3.0 + (L - 3.0 * n) * rng.dirichlet(np.full(n, 4.0))
        xs = np.concatenate(([0.0], np.cumsum(widths)))
        xs[-1] = L
        # 2. Corridor wall with one doorway per room.
        gaps = []
        for xa, xb in zip(xs[:-1], xs[1:], strict=True):
            gaps += [(xa + c, w) for c, w in b.gaps(xb - xa, 1)]
            rooms.append((xa, min(y_wall, y_out[side]), xb, max(y_wall, y_out[side])))
        b.wall_with_gaps((0.0, y_wall), (L, y_wall), gaps)
        # 3. Partitions, some with a doorway into the next room.
        for xk in xs[1:-1]:
            depth = abs(y_out[side] - y_wall)
            n_door = int(rng.random() < connecting_doors)
            b.wall_with_gaps((xk, y_wall), (xk, y_out[side]), b.gaps(depth, n_door))
    b.region(0.0, 0.0, L, W)
    for r in rooms:
        b.region(*r)
    # 4. Furniture.
    n_pillars = int(rng.integers(2, 5)) if pillars is None else pillars
    _check_count(where, pillars=n_pillars)
    _check_at_most(where, MAX_OBJECTS, pillars=n_pillars)
    per_room = rng.multinomial(n_pillars, np.full(len(rooms), 1.0 / len(rooms)))
    for rect, k in zip(rooms, per_room, strict=True):
        n_clutter = int(rng.integers(1, 5)) if clutter is None else clutter
        _check_count(where, clutter=n_clutter)
        _check_at_most(where, MAX_OBJECTS, clutter=n_clutter)
        b.furnish(rect, pillars=int(k), clutter=n_clutter)
    return b.build(f"office: {len(rooms)} rooms off a {L:.1f} x {W:.1f} m corridor")


def ring_world(
    rng: np.random.Generator,
    length: float = 60.0,
    width: float = 40.0,
    *,
    corridor: float = 2.5,
    door_every: float = 7.0,
) -> World:
    """A ring corridor round a solid block: a building's loop, the kind a mapper closes
    after a long drive (MIT's Killian Court, the ACES building).

    The outer walls span ``[0, length] x [0, width]``, the block ``[corridor, length -
    corridor] x [corridor, width - corridor]``. Each of the eight walls has closed doors
    (0.8-1 m gaps with a 0.15-0.5 m recess behind them) at random, about one every
    ``door_every`` metres. The four corners are alike: a quarter turn round, one looks
    like the next (the look-alike :class:`~scanclique.mapping.LoopConfig`'s ``max_turn``
    refuses).

    Raises
    ------
    ConfigError
        A size that is not positive or beyond :data:`MAX_EXTENT`, a corridor that leaves
        no block (``2 * corridor >= min(length, width)``), or more than
        :data:`MAX_OBJECTS` doors.
    """
    where = "ring_world"
    _check_rng(rng, where)
    _check_positive(where, length=length, width=width, corridor=corridor, door_every=door_every)
    _check_extent(where, length=length, width=width)
    L, W, c = float(length), float(width), float(corridor)
    if 2.0 * c >= min(L, W):
        raise ConfigError(f"{where}: a {c} m corridor leaves no block in {L} x {W} m")
    per_wall = [n / door_every for n in (L, W) * 2 + (L - 2.0 * c, W - 2.0 * c) * 2]
    if max(per_wall) > MAX_OBJECTS or sum(max(1, int(k)) for k in per_wall) > MAX_OBJECTS:
        raise ConfigError(
            f"{where}: door_every {door_every!r} m makes more than {MAX_OBJECTS} doors in a "
            f"{L:g} x {W:g} m ring"
        )
    b = _Builder(rng)
    # outer walls recess outwards, the block's inwards: away from the corridor
    for (x0, y0, x1, y1), sign in (((0.0, 0.0, L, W), -1.0), ((c, c, L - c, W - c), 1.0)):
        corners = [(x0, y0), (x1, y0), (x1, y1), (x0, y1), (x0, y0)]
        for p, q in zip(corners[:-1], corners[1:], strict=True):
            p, q = np.array(p), np.array(q)
            n = float(np.linalg.norm(q - p))
            u = (q - p) / n
            out = sign * np.array([-u[1], u[0]])  # left of a counter-clockwise wall: inside
            gaps = b.gaps(n, max(1, int(n / door_every)), margin=1.5)
            b.wall_with_gaps(p, q, gaps)
            for centre, w in gaps:
                e = float(rng.uniform(0.15, 0.5))
                a0, a1 = p + (centre - w / 2) * u, p + (centre + w / 2) * u
                b.polyline([a0, a0 + e * out, a1 + e * out, a1])
    for x0, y0, x1, y1 in ((0, 0, L, c), (0, W - c, L, W), (0, 0, c, W), (L - c, 0, L, W)):
        b.region(x0, y0, x1, y1)
    return b.build(f"ring {L:.1f} x {W:.1f} m, corridor {c:.1f} m")


def campus_world(
    rng: np.random.Generator,
    *,
    blocks: tuple[int, int] = (2, 2),
    street: float = 8.0,
    tree_spacing: float = 8.0,
) -> World:
    """Outdoors: a campus of buildings on a grid of streets, lined with trees, closed by
    the façades round it (the ground of an outdoor log: few long walls, many thin trunks,
    streets wider than a corridor and open far along their length).

    ``blocks`` = (columns, rows) buildings of 15-30 m a side, each with one recessed
    entrance (1.5-3 m wide, 0.5-1.5 m deep); streets ``street`` m wide between them and
    round them; the outer façades bound the outer streets. Trees (trunks of 0.1-0.4 m
    radius) stand along both edges of every street, 0.8-2 m from the kerb, about one every
    ``tree_spacing`` m (gaps of 0.5 to 1.5 times that); the middle of a street stays clear.
    The free regions are the streets.

    Raises
    ------
    ConfigError
        A size that is not positive, a street narrower than 5 m (trees leave no lane) or
        wider than :data:`MAX_EXTENT`, blocks that are not two integers of at least 1
        (:data:`MAX_OBJECTS` in all), or sizes that may plant more than
        :data:`MAX_TREES` trees.

    Examples
    --------
    >>> w = campus_world(np.random.default_rng(0))
    >>> w.n_circles > 40, len(w.free_regions)
    (True, 6)
    """
    where = "campus_world"
    _check_rng(rng, where)
    _check_positive(where, street=street, tree_spacing=tree_spacing)
    if not (
        isinstance(blocks, (tuple, list))
        and len(blocks) == 2
        and all(isinstance(n, (int, np.integer)) and not isinstance(n, bool) for n in blocks)
    ):
        raise ConfigError(f"{where}: blocks must be two integers (columns, rows), got {blocks!r}")
    nx, ny = (int(b) for b in blocks)
    if nx < 1 or ny < 1:
        raise ConfigError(f"{where}: blocks must be at least (1, 1), got {blocks}")
    _check_at_most(where, MAX_OBJECTS, **{"blocks (columns x rows)": nx * ny})
    if street < 5.0:
        raise ConfigError(f"{where}: a street of {street} m leaves no lane between its trees")
    _check_at_most(where, MAX_EXTENT, street=street)
    # at most one tree per half spacing along each edge of each street, the campus at its
    # largest (buildings of 30 m)
    w_max, h_max = nx * (30.0 + street) + street, ny * (30.0 + street) + street
    trees = 2.0 * ((ny + 1) * (w_max / (0.5 * tree_spacing) + 1) + (nx + 1) * (
        h_max / (0.5 * tree_spacing) + 1))  # fmt: skip
    if trees > MAX_TREES:
        raise ConfigError(
            f"{where}: blocks {blocks}, street {street!r} m and tree_spacing {tree_spacing!r} m "
            f"may plant up to {trees:.3g} trees, more than {MAX_TREES}"
        )
    b = _Builder(rng)
    S = float(street)
    xs, ys = [S], [S]  # the blocks' lower-left corners: a street before each
    widths = rng.uniform(15.0, 30.0, nx)
    depths = rng.uniform(15.0, 30.0, ny)
    for w in widths[:-1]:
        xs.append(xs[-1] + w + S)
    for d in depths[:-1]:
        ys.append(ys[-1] + d + S)
    W, H = xs[-1] + widths[-1] + S, ys[-1] + depths[-1] + S
    b.polyline([(0.0, 0.0), (W, 0.0), (W, H), (0.0, H), (0.0, 0.0)])  # the façades round
    for x0, w in zip(xs, widths, strict=True):
        for y0, d in zip(ys, depths, strict=True):
            corners = [(x0, y0), (x0 + w, y0), (x0 + w, y0 + d), (x0, y0 + d), (x0, y0)]
            side = int(rng.integers(4))  # the one with the entrance
            for k, (p, q) in enumerate(zip(corners[:-1], corners[1:], strict=True)):
                p, q = np.array(p), np.array(q)
                n = float(np.linalg.norm(q - p))
                if k != side:
                    b.wall(p, q)
                    continue
                u = (q - p) / n
                inward = np.array([-u[1], u[0]])  # corners run counter-clockwise
                gw, depth = float(rng.uniform(1.5, 3.0)), float(rng.uniform(0.5, 1.5))
                c = float(rng.uniform(2.0 + gw / 2, n - 2.0 - gw / 2))
                a0, a1 = p + (c - gw / 2) * u, p + (c + gw / 2) * u
                b.wall(p, a0)
                b.polyline([a0, a0 + depth * inward, a1 + depth * inward, a1])
                b.wall(a1, q)
    ends_y = [y0 + d for y0, d in zip(ys, depths, strict=True)]
    ends_x = [x0 + w for x0, w in zip(xs, widths, strict=True)]
    streets = [(0.0, y, W, y + S) for y in (0.0, *ends_y)]
    streets += [(x, 0.0, x + S, H) for x in (0.0, *ends_x)]
    for x0, y0, x1, y1 in streets:
        b.region(x0, y0, x1, y1)
        along_x = x1 - x0 > y1 - y0
        length = (x1 - x0) if along_x else (y1 - y0)
        for edge in (0, 1):
            t = float(rng.uniform(0.0, tree_spacing))
            while t < length:
                off = float(rng.uniform(0.8, 2.0))
                off = off if edge == 0 else S - off
                c = (x0 + t, y0 + off) if along_x else (x0 + off, y0 + t)
                r = float(rng.uniform(0.1, 0.4))
                if not _in_lane(c, streets) and all(
                    math.hypot(c[0] - cx, c[1] - cy) > 1.0 for cx, cy in b.centres
                ):
                    b.centres.append([float(c[0]), float(c[1])])
                    b.radii.append(r)
                t += float(rng.uniform(0.5, 1.5)) * tree_spacing
    return b.build(f"campus {W:.0f} x {H:.0f} m, {nx} x {ny} blocks, streets {S:.0f} m")


def _in_lane(c, streets, kerb: float = 2.0) -> bool:
    """Whether the point ``c`` lies in the middle of a street (more than ``kerb`` m from
    both its edges across it): at a crossing, the other street's lane."""
    for x0, y0, x1, y1 in streets:
        if not (x0 <= c[0] <= x1 and y0 <= c[1] <= y1):
            continue
        if x1 - x0 > y1 - y0:
            if y0 + kerb < c[1] < y1 - kerb:
                return True
        elif x0 + kerb < c[0] < x1 - kerb:
            return True
    return False


def random_world(rng: np.random.Generator) -> World:
    """A random building. Half are offices (:func:`office_world`), a quarter single rooms
    (:func:`room_world`, 4-10 m) and a quarter corridors (:func:`corridor_world`).

    Examples
    --------
    >>> a = random_world(np.random.default_rng(7))
    >>> b = random_world(np.random.default_rng(7))
    >>> bool(np.array_equal(a.walls, b.walls))
    True
    """
    _check_rng(rng, "random_world")
    kind = int(rng.choice(3, p=(0.5, 0.25, 0.25)))
    if kind == 0:
        return office_world(rng)
    if kind == 1:
        return room_world(
            float(rng.uniform(4.0, 10.0)),
            float(rng.uniform(4.0, 10.0)),
            rng=rng,
            doorways=int(rng.integers(1, 3)),
            pillars=int(rng.integers(0, 3)),
            clutter=int(rng.integers(2, 7)),
        )
    return corridor_world(
        float(rng.uniform(10.0, 25.0)),
        float(rng.uniform(*CORRIDOR_WIDTH)),
        rng=rng,
        side_rooms=int(rng.integers(1, 4)),
        doorways=int(rng.integers(1, 5)),
    )


# ------------------------------------------------------------------------------------
# Ray casting
# ------------------------------------------------------------------------------------
def _as_people(people) -> tuple[np.ndarray, np.ndarray]:
    if people is None:
        return np.zeros((0, 2)), np.zeros(0)
    try:
        centres, radii = people
    except (TypeError, ValueError):
        raise ConfigError("people must be a (centres (Q, 2), radii (Q,)) pair") from None
    c = np.asarray(centres, dtype=float).reshape(-1, 2)
    r = np.asarray(radii, dtype=float).reshape(-1)
    if c.shape[0] != r.shape[0] or np.any(r <= 0):
        raise ConfigError(
            f"people: need as many positive radii as centres, got {c.shape[0]} centres "
            f"and radii {r.tolist()}"
        )
    return c, r


def cast_rays(world: World, origin, angles, *, max_range: float = np.inf, people=None):
    """Distance from ``origin`` to the first surface along each ray.

    All rays are cast at once: (beams x segments) and (beams x circles) arrays.

    Parameters
    ----------
    world : World
        The building.
    origin : array_like, shape (2,) or (N, 2)
        Ray origin in the world frame, metres: one for all rays, or one per ray (a
        sensor moving during its sweep).
    angles : array_like, shape (N,)
        Ray directions in the world frame, radians, counter-clockwise from the x axis.
    max_range : float
        Hits at or beyond this distance (metres) count as no hit; positive, ``inf`` for
        no limit.
    people : (centres (Q, 2), radii (Q,)), optional
        Extra circles that exist only for this call.

    Returns
    -------
    ndarray, shape (N,)
        Distance in metres to the first wall, circle or person hit. It is ``inf`` where
        nothing is hit within ``max_range``.

    Raises
    ------
    ConfigError
        An origin of another shape, an origin or angle that is not finite, or a
        ``max_range`` that is not positive.

    Examples
    --------
    >>> world = room_world(4.0, 4.0, rng=np.random.default_rng(0), doorways=0, pillars=0, clutter=0)
    >>> cast_rays(world, (1.0, 2.0), np.array([0.0, np.pi / 2, np.pi]))
    array([3., 2., 1.])
    """
    where = "cast_rays"
    ang = np.asarray(angles, dtype=float).reshape(-1)
    o = np.asarray(origin, dtype=float)
    if o.size not in (2, 2 * ang.shape[0]):
        raise ConfigError(
            f"{where}: origin must be one point (2,) or one per ray ({ang.shape[0]}, 2), "
            f"got shape {o.shape}"
        )
    if not (np.all(np.isfinite(o)) and np.all(np.isfinite(ang))):
        raise ConfigError(f"{where}: origin and angles must be finite")
    if not max_range > 0:
        raise ConfigError(f"{where}: max_range must be positive (inf: no limit), got {max_range!r}")
    o = o.reshape(1, 2) if o.size == 2 else o.reshape(ang.shape[0], 2)  # (1 or N, 2)
    d = np.column_stack((np.cos(ang), np.sin(ang)))  # (N, 2) unit directions
    best = np.full(ang.shape[0], np.inf)
    if world.n_walls:
        # o + t d = p + s e  =>  t = (w x e) / (d x e),  s = (w x d) / (d x e),  w = p - o
        p = world.walls[:, 0]
        e = world.walls[:, 1] - p
        w = p[None, :, :] - o[:, None, :]  # (1 or N, K, 2)
        denom = d[:, None, 0] * e[None, :, 1] - d[:, None, 1] * e[None, :, 0]  # (N, K)
        t_num = w[..., 0] * e[None, :, 1] - w[..., 1] * e[None, :, 0]  # (1 or N, K)
        s_num = w[..., 0] * d[:, None, 1] - w[..., 1] * d[:, None, 0]  # (N, K)
        with np.errstate(divide="ignore", invalid="ignore"):
            t = t_num / denom
            s = s_num / denom
        hit = (np.abs(denom) > _EPS) & (t > _EPS) & (s >= -_EPS) & (s <= 1.0 + _EPS)
        best = np.minimum(best, np.where(hit, t, np.inf).min(axis=1))
    pc, pr = _as_people(people)
    centres = np.concatenate((world.circle_centres, pc))
    radii = np.concatenate((world.circle_radii, pr))
    if radii.size:
        # |o + t d - c|^2 = r^2  =>  t^2 + 2 b t + cc = 0,  b = d.(o - c),  cc = |o - c|^2 - r^2
        if len(o) == 1:
            oc = o[0][None, :] - centres  # (P, 2)
            bb = d @ oc.T  # (N, P)
            cc = (np.einsum("pd,pd->p", oc, oc) - radii**2)[None, :]  # (1, P)
        else:
            oc = o[:, None, :] - centres[None, :, :]  # (N, P, 2)
            bb = np.einsum("nd,npd->np", d, oc)  # (N, P)
            cc = np.einsum("npd,npd->np", oc, oc) - radii[None, :] ** 2  # (N, P)
        disc = bb**2 - cc
        sq = np.sqrt(np.maximum(disc, 0.0))
        t1, t2 = -bb - sq, -bb + sq
        t = np.where(t1 > _EPS, t1, np.where(t2 > _EPS, t2, np.inf))
        t = np.where(disc >= 0.0, t, np.inf)
        best = np.minimum(best, t.min(axis=1))
    return np.where(best < max_range, best, np.inf)


def _beam_angles(n_beams: int, fov: float, angle_min: float) -> np.ndarray:
    return beam_angles(n_beams, angle_min, fov / (n_beams - 1) if n_beams > 1 else 0.0)


def simulate_scan(
    world: World,
    pose_world_sensor: Pose2,
    *,
    n_beams: int = 361,
    fov: float = math.pi,
    angle_min: float = -math.pi / 2,
    max_range: float = 30.0,
    range_sigma: float = 0.01,
    dropout: float = 0.0,
    rng: np.random.Generator | None = None,
    timestamp: float | None = None,
    range_sigma_per_m: float = 0.0,
    odometry: Pose2 | None = None,
    people=None,
    source: str = "sim",
    sweep_poses: np.ndarray | None = None,
    beam_times: np.ndarray | None = None,
) -> Scan:
    """Simulate one laser scan taken at ``pose_world_sensor``.

    Beam ``i`` points along sensor-frame angle ``angle_min + i * fov / (n_beams - 1)``, the
    CARMEN convention also used by :meth:`Scan.from_ranges`. Its range is the distance to
    the first surface plus Gaussian noise, clipped to ``[0, max_range]``.

    Parameters
    ----------
    world : World
        The building.
    pose_world_sensor : Pose2
        Pose of the sensor in the world. It maps sensor-frame points into the world frame
        and becomes the scan's ``reference``.
    n_beams : int
        Number of beams, at most :data:`MAX_BEAMS`.
    fov, angle_min : float
        Field of view and first beam angle, radians, in the sensor frame.
    max_range : float
        Metres. A beam with no surface within it, or a dropped beam, returns exactly
        ``max_range``, a no-return that :class:`Scan` masks as invalid. It is also the
        scan's ``range_max``.
    range_sigma : float
        Standard deviation of the range noise, metres.
    dropout : float
        Probability that a beam returns nothing (``max_range``).
    rng : numpy.random.Generator, optional
        Needed when ``range_sigma > 0``, ``range_sigma_per_m > 0`` or ``dropout > 0``.
    timestamp : float, optional
        Seconds, copied to the scan.
    range_sigma_per_m : float
        Range noise growing with the range (m/m): the standard deviation of a return at
        range ``r`` is ``range_sigma + range_sigma_per_m * r`` (triangulation scanners such
        as the RPLIDAR A1: about 1-2 % of the range).
    odometry : Pose2, optional
        Odometry pose, copied to the scan.
    people : (centres (Q, 2), radii (Q,)), optional
        Circles in the world frame that exist only in this scan, such as moving people.
    source : str
        Label for messages.
    sweep_poses : array_like, shape (n_beams, 3), optional
        ``x y theta`` of the sensor in the world when it measured each beam (a rotating
        scanner on a moving robot); by default every beam from ``pose_world_sensor``.
    beam_times : array_like, shape (n_beams,), optional
        Copied to the scan (:attr:`Scan.beam_times`).

    Returns
    -------
    Scan
        ``range_min=0``, ``range_max=max_range``, ``reference=pose_world_sensor``.

    Examples
    --------
    >>> world = room_world(4.0, 4.0, rng=np.random.default_rng(0), doorways=0, pillars=0, clutter=0)
    >>> scan = simulate_scan(world, Pose2(2.0, 2.0, 0.0), n_beams=3, range_sigma=0.0)
    >>> scan.ranges  # right, forward, left
    array([2., 2., 2.])
    """
    where = "simulate_scan"
    if not isinstance(world, World):
        raise ConfigError(f"{where}: world must be a World, got {type(world).__name__}")
    if not isinstance(pose_world_sensor, Pose2):
        raise ConfigError(
            f"{where}: pose_world_sensor must be a Pose2, got {type(pose_world_sensor).__name__}"
        )
    _check_beams(where, n_beams)
    _check_positive(where, fov=fov, max_range=max_range)
    _check_nonneg(where, range_sigma=range_sigma, range_sigma_per_m=range_sigma_per_m)
    if not (math.isfinite(angle_min)):
        raise ConfigError(f"{where}: angle_min must be finite, got {angle_min}")
    if not 0.0 <= dropout <= 1.0:
        raise ConfigError(f"{where}: dropout must be in [0, 1], got {dropout}")
    if (range_sigma > 0 or range_sigma_per_m > 0 or dropout > 0) and rng is None:
        raise ConfigError(
            f"{where}: range_sigma={range_sigma}, range_sigma_per_m={range_sigma_per_m} and "
            f"dropout={dropout} need rng "
            "(a numpy.random.Generator)"
        )
    angles = _beam_angles(n_beams, fov, angle_min)
    if sweep_poses is None:
        origin, heading = pose_world_sensor.translation, pose_world_sensor.theta
    else:
        sp = np.asarray(sweep_poses, dtype=float)
        if sp.shape != (n_beams, 3) or not np.all(np.isfinite(sp)):
            raise ConfigError(f"{where}: sweep_poses must be finite, of shape ({n_beams}, 3)")
        origin, heading = sp[:, :2], sp[:, 2]
    true = cast_rays(world, origin, angles + heading, max_range=max_range, people=people)
    hit = np.isfinite(true)
    ranges = np.where(hit, true, max_range)
    if range_sigma > 0 or range_sigma_per_m > 0:
        sigma = range_sigma + range_sigma_per_m * np.where(hit, ranges, 0.0)
        noise = _check_rng(rng, where).normal(0.0, 1.0, n_beams) * sigma
        ranges = np.where(hit, np.clip(ranges + noise, 0.0, max_range), max_range)
    if dropout > 0:
        ranges = np.where(_check_rng(rng, where).random(n_beams) < dropout, max_range, ranges)
    return Scan(
        ranges,
        angles,
        range_min=0.0,
        range_max=max_range,
        timestamp=timestamp,
        odometry=odometry,
        reference=pose_world_sensor,
        source=source,
        beam_times=beam_times,
    )


# ------------------------------------------------------------------------------------
# Pose sampling
# ------------------------------------------------------------------------------------
def _random_pose(rng: np.random.Generator, world: World) -> Pose2:
    """A pose uniform over the free regions (area-weighted) with a uniform heading."""
    reg = world.free_regions
    if reg.shape[0] == 0:
        raise ScanCliqueError(f"{world.name or 'world'}: no free regions to place a sensor in")
    area = (reg[:, 2] - reg[:, 0]) * (reg[:, 3] - reg[:, 1])
    x0, y0, x1, y1 = reg[int(rng.choice(reg.shape[0], p=area / area.sum()))]
    return Pose2(rng.uniform(x0, x1), rng.uniform(y0, y1), rng.uniform(-np.pi, np.pi))


def _view_points(world, pose: Pose2, angles, max_range: float) -> np.ndarray | None:
    """World-frame hit points of a noise-free scan, or None when the view is poor
    (too few returns, or staring into a nearby wall)."""
    t = cast_rays(world, pose.translation, angles + pose.theta, max_range=max_range)
    hit = np.isfinite(t)
    if hit.mean() < _MIN_VALID_FRACTION or np.median(t[hit]) < _MIN_MEDIAN_RANGE:
        return None
    a = angles[hit] + pose.theta
    return pose.translation + t[hit, None] * np.column_stack((np.cos(a), np.sin(a)))


def _visible_fraction(world, pose: Pose2, points, *, angle_min, fov, max_range, tol=0.05):
    """Fraction of world points (M, 2) that a sensor at ``pose`` sees: inside its field
    of view, within range, and not hidden behind something nearer."""
    v = points - pose.translation
    dist = np.hypot(v[:, 0], v[:, 1])
    bearing = np.arctan2(v[:, 1], v[:, 0])
    in_fov = np.mod(bearing - pose.theta - angle_min, 2 * np.pi) <= fov + 1e-9
    free = cast_rays(world, pose.translation, bearing)
    return float(np.mean(in_fov & (dist < max_range) & (free >= dist - tol)))


def _person_fits(world, p, r, sensors, others, clearance) -> bool:
    if not world.is_free(p, clearance=r + 0.05)[0]:
        return False
    if any(math.hypot(*(p - s.translation)) < r + clearance for s in sensors):
        return False
    return all(math.hypot(*(p - c)) >= r + rc + 0.1 for c, rc in others)


def _place_people(rng, world, sensors, n, *, angle_min, fov, clearance):
    """``n`` people in front of the first sensor (0.8-4 m away). Each walks 0.3-1 m
    between the two scans. A person with no free spot is left out."""
    at_a: list[tuple[np.ndarray, float]] = []
    at_b: list[tuple[np.ndarray, float]] = []
    anchor = sensors[0]
    for _ in range(n):
        for _try in range(_TRIES):
            r = float(rng.uniform(*PERSON_RADIUS))
            bearing = anchor.theta + angle_min + rng.uniform(0.0, fov)
            pa = anchor.translation + rng.uniform(0.8, 4.0) * np.array(
                [math.cos(bearing), math.sin(bearing)]
            )
            heading = rng.uniform(-np.pi, np.pi)
            pb = pa + rng.uniform(0.3, 1.0) * np.array([math.cos(heading), math.sin(heading)])
            if _person_fits(world, pa, r, sensors, at_a, clearance) and _person_fits(
                world, pb, r, sensors, at_b, clearance
            ):
                at_a.append((pa, r))
                at_b.append((pb, r))
                break

    def pack(people):
        c = np.array([p for p, _ in people], dtype=float).reshape(-1, 2)
        r = np.array([r for _, r in people], dtype=float)
        return _readonly(c), _readonly(r)

    return pack(at_a), pack(at_b)


# ------------------------------------------------------------------------------------
# Scan pairs and drives
# ------------------------------------------------------------------------------------
@dataclass(frozen=True, slots=True, eq=False)
class SimPair:
    """Two simulated scans of one world with their true relative pose.

    Attributes
    ----------
    scan_a, scan_b : Scan
        The scans. Their ``reference`` is the true sensor pose in the world.
    world : World
        The building they were taken in.
    pose_a_b : Pose2
        ``scan_a.reference.inverse() @ scan_b.reference``. It maps points from scan b's
        sensor frame into scan a's sensor frame.
    people_a, people_b : (ndarray (Q, 2), ndarray (Q,))
        World-frame centres and radii of the moving people present in each scan.
    """

    scan_a: Scan
    scan_b: Scan
    world: World
    pose_a_b: Pose2
    people_a: tuple[np.ndarray, np.ndarray]
    people_b: tuple[np.ndarray, np.ndarray]


def simulate_pair(
    rng: np.random.Generator,
    *,
    world: World | None = None,
    max_translation: float = 1.0,
    max_rotation: float = 0.5,
    n_beams: int = 361,
    range_sigma: float = 0.01,
    dropout: float = 0.0,
    moving_people: int = 2,
    fov: float = math.pi,
    angle_min: float = -math.pi / 2,
    max_range: float = 30.0,
    clearance: float = 0.3,
    min_overlap: float = 0.5,
    max_attempts: int = 200,
    **scan_kw,
) -> SimPair:
    """Two scans of one world taken a short, known motion apart.

    Sensor a gets a pose uniform over the world's free regions. Sensor b is
    ``pose_a @ delta``, where ``delta`` has a translation uniform in a disc of radius
    ``max_translation`` and a rotation uniform in ``[-max_rotation, max_rotation]``,
    both in sensor a's frame. A candidate pair is rejected and drawn again when:

    * either pose is not free, that is outside the free regions, inside a box, or
      closer than ``clearance`` to a wall or pillar;
    * the straight path from a to b is blocked;
    * either view is poor: returns on fewer than half of the beams, or a median
      range under 0.8 m;
    * less than ``min_overlap`` of either scan's (noise-free) points is visible from
      the other pose.

    ``moving_people`` people (radius 0.15-0.25 m) stand 0.8-4 m in front of sensor a
    and each walks 0.3-1 m before scan b. They are present only in their own scan.

    Parameters
    ----------
    rng : numpy.random.Generator
        Source of all randomness (world, poses, people, noise).
    world : World, optional
        Default :func:`random_world`, drawn from ``rng``.
    max_translation : float
        Metres.
    max_rotation : float
        Radians.
    n_beams, range_sigma, dropout, fov, angle_min, max_range
        As in :func:`simulate_scan`.
    moving_people : int
        Number of people, at most :data:`MAX_PEOPLE`. A person with no free spot is left
        out.
    clearance : float
        Minimum distance (metres) from either sensor to any wall or pillar.
    min_overlap : float
        Minimum fraction of each scan's points that the other sensor also sees.
    max_attempts : int
        Candidate pairs to try before giving up.
    **scan_kw
        Passed on to :func:`simulate_scan` for both scans (e.g. ``timestamp``).

    Returns
    -------
    SimPair

    Raises
    ------
    ScanCliqueError
        If no acceptable pair is found in ``max_attempts`` tries. The message counts
        the rejections by reason.

    Examples
    --------
    >>> pair = simulate_pair(np.random.default_rng(3), moving_people=0)
    >>> d = pair.scan_a.reference.inverse() @ pair.scan_b.reference
    >>> bool(np.allclose(d.as_array(), pair.pose_a_b.as_array()))
    True
    """
    where = "simulate_pair"
    _check_rng(rng, where)
    _check_nonneg(where, max_translation=max_translation, max_rotation=max_rotation)
    _check_nonneg(where, clearance=clearance, min_overlap=min_overlap)
    _check_count(where, moving_people=moving_people, max_attempts=max_attempts)
    _check_at_most(where, MAX_PEOPLE, moving_people=moving_people)
    _check_beams(where, n_beams)
    _check_positive(where, fov=fov, max_range=max_range)
    if world is None:
        world = random_world(rng)
    elif not isinstance(world, World):
        raise ConfigError(f"{where}: world must be a World, got {type(world).__name__}")
    angles = _beam_angles(n_beams, fov, angle_min)
    view = {"angle_min": angle_min, "fov": fov, "max_range": max_range}
    rejected: Counter[str] = Counter()
    for _ in range(max_attempts):
        pose_a = _random_pose(rng, world)
        r = max_translation * math.sqrt(rng.random())
        phi = rng.uniform(-np.pi, np.pi)
        delta = Pose2(r * math.cos(phi), r * math.sin(phi), rng.uniform(-1, 1) * max_rotation)
        pose_b = pose_a @ delta
        xy = np.stack((pose_a.translation, pose_b.translation))
        if not np.all(world.is_free(xy, clearance=clearance)):
            rejected["not in free space"] += 1
            continue
        if r > _EPS:
            heading = math.atan2(*(xy[1] - xy[0])[::-1])
            if cast_rays(world, xy[0], [heading])[0] < r:
                rejected["path from a to b blocked"] += 1
                continue
        pts_a = _view_points(world, pose_a, angles, max_range)
        pts_b = _view_points(world, pose_b, angles, max_range)
        if pts_a is None or pts_b is None:
            rejected["seeing too little"] += 1
            continue
        overlap = min(
            _visible_fraction(world, pose_a, pts_b, **view),
            _visible_fraction(world, pose_b, pts_a, **view),
        )
        if overlap < min_overlap:
            rejected["overlap too small"] += 1
            continue
        break
    else:
        reasons = ", ".join(f"{k}: {v}" for k, v in rejected.most_common())
        raise ScanCliqueError(
            f"{where}: no acceptable pair of sensor poses in {max_attempts} attempts in "
            f"{world.name or 'the world'!s} (need {clearance} m clearance from walls and "
            f"pillars, returns on half the beams, {min_overlap:.0%} overlap; rejected: "
            f"{reasons})"
        )
    people_a, people_b = _place_people(
        rng,
        world,
        (pose_a, pose_b),
        moving_people,
        angle_min=angle_min,
        fov=fov,
        clearance=clearance,
    )
    scan_a, scan_b = (
        simulate_scan(
            world,
            pose,
            n_beams=n_beams,
            fov=fov,
            angle_min=angle_min,
            max_range=max_range,
            range_sigma=range_sigma,
            dropout=dropout,
            rng=rng,
            people=people,
            source=source,
            **scan_kw,
        )
        for pose, people, source in ((pose_a, people_a, "sim:a"), (pose_b, people_b, "sim:b"))
    )
    return SimPair(scan_a, scan_b, world, pose_a.inverse() @ pose_b, people_a, people_b)


def simulate_trajectory(
    rng: np.random.Generator,
    world: World,
    n_scans: int,
    step: float = 0.3,
    *,
    start: Pose2 | None = None,
    turn_sigma: float = 0.2,
    trans_noise_per_m: float = 0.05,
    rot_noise_per_m: float = 0.02,
    rot_noise_per_rad: float = 0.05,
    odometry_start: Pose2 | None = None,
    dt: float = 0.5,
    clearance: float = 0.3,
    lookahead: float = 2.0,
    n_beams: int = 361,
    range_sigma: float = 0.01,
    dropout: float = 0.0,
    max_attempts: int = 200,
    **scan_kw,
) -> list[Scan]:
    """A short drive through free space: scans with exact reference poses and drifting
    odometry.

    The robot moves ``step`` metres between scans. Before each step it picks a heading
    near a randomly perturbed version of its current one, preferring directions with
    open space within ``lookahead`` metres, so it turns before walls and goes through
    doorways now and then. It never comes closer than ``clearance`` to an obstacle.

    Odometry starts at ``odometry_start`` (default: the first reference pose). Each
    step's odometry increment is the true increment ``u = ref[i-1]^-1 @ ref[i]`` (in
    the previous sensor frame) plus zero-mean Gaussian noise. The translation noise has
    standard deviation ``trans_noise_per_m * |u|`` in x and y, and the rotation noise
    ``rot_noise_per_m * |u| + rot_noise_per_rad * |u.theta|``. The odometry therefore
    drifts as a random walk.

    Parameters
    ----------
    rng : numpy.random.Generator
        Source of all randomness.
    world : World
        The building.
    n_scans : int
        Number of scans (poses) in the drive, 1 to :data:`MAX_SCANS`.
    step : float
        Distance between consecutive poses, metres.
    start : Pose2, optional
        First sensor pose in the world. The default is a random free pose with a
        usable view.
    turn_sigma : float
        Standard deviation of the random heading change per step, radians.
    trans_noise_per_m, rot_noise_per_m, rot_noise_per_rad : float
        Odometry noise: metres per metre, radians per metre, radians per radian.
    odometry_start : Pose2, optional
        Odometry pose of the first scan.
    dt : float
        Seconds between scans. Timestamps are ``0, dt, 2 dt, ...``.
    clearance, lookahead : float
        Metres.
    n_beams, range_sigma, dropout
        As in :func:`simulate_scan`.
    max_attempts : int
        Attempts at drawing a start pose.
    **scan_kw
        Passed on to :func:`simulate_scan` (``fov``, ``angle_min``, ``max_range``).

    Returns
    -------
    list of Scan
        Each has ``reference`` (true pose), ``odometry`` (drifting), ``timestamp`` and
        ``source`` ``"sim:<index>"``.

    Raises
    ------
    ConfigError
        An argument out of range: ``n_scans`` below 1 or above :data:`MAX_SCANS`, more
        than :data:`MAX_BEAMS` beams, a step that is not positive...
    ScanCliqueError
        If no free start pose is found, or the robot is boxed in.
    """
    where = "simulate_trajectory"
    _check_rng(rng, where)
    if not isinstance(world, World):
        raise ConfigError(f"{where}: world must be a World, got {type(world).__name__}")
    _check_count(where, n_scans=n_scans, max_attempts=max_attempts)
    if n_scans < 1:
        raise ConfigError(f"{where}: n_scans must be >= 1 (the drive starts with a scan), got 0")
    _check_at_most(where, MAX_SCANS, n_scans=n_scans)
    _check_beams(where, n_beams)
    _check_positive(where, step=step, dt=dt, lookahead=lookahead)
    _check_nonneg(where, turn_sigma=turn_sigma, clearance=clearance)
    _check_nonneg(
        where,
        trans_noise_per_m=trans_noise_per_m,
        rot_noise_per_m=rot_noise_per_m,
        rot_noise_per_rad=rot_noise_per_rad,
    )
    view_angles = _beam_angles(
        n_beams, scan_kw.get("fov", math.pi), scan_kw.get("angle_min", -math.pi / 2)
    )
    max_range = scan_kw.get("max_range", 30.0)
    # 1. Start pose.
    if start is None:
        for _ in range(max_attempts):
            cand = _random_pose(rng, world)
            if world.is_free(cand.translation, clearance)[0] and (
                _view_points(world, cand, view_angles, max_range) is not None
            ):
                start = cand
                break
        else:
            raise ScanCliqueError(
                f"{where}: no free start pose with a usable view in {max_attempts} attempts "
                f"in {world.name or 'the world'} (clearance {clearance} m)"
            )
    elif not world.is_free(start.translation, clearance)[0]:
        raise ScanCliqueError(f"{where}: start {start} is not in free space ({clearance} m)")
    # 2. Drive: headings on a 5 degree fan around the desired one, best open space first.
    refs = [start]
    offsets = np.deg2rad(np.arange(-180.0, 180.0, 5.0))
    for i in range(1, n_scans):
        pose = refs[-1]
        desired = pose.theta + rng.normal(0.0, turn_sigma) if turn_sigma > 0 else pose.theta
        heads = desired + offsets
        free = cast_rays(world, pose.translation, heads)
        score = np.minimum(free, lookahead) - 0.3 * np.abs(offsets)
        for k in np.argsort(-score, kind="stable"):
            if free[k] < step + clearance:
                continue
            target = pose.translation + step * np.array([math.cos(heads[k]), math.sin(heads[k])])
            if world.is_free(target, clearance)[0]:
                refs.append(Pose2(target[0], target[1], heads[k]))
                break
        else:
            raise ScanCliqueError(f"{where}: robot boxed in at {pose} after {i} steps")
    # 3. Odometry: true increments plus noise proportional to distance and turn.
    odom = _drifting_odometry(
        rng, refs, refs[0] if odometry_start is None else odometry_start,
        trans_noise_per_m, rot_noise_per_m, rot_noise_per_rad,
    )  # fmt: skip
    # 4. Scans.
    return [
        simulate_scan(
            world,
            ref,
            n_beams=n_beams,
            range_sigma=range_sigma,
            dropout=dropout,
            rng=rng,
            timestamp=i * dt,
            odometry=od,
            source=f"sim:{i}",
            **scan_kw,
        )
        for i, (ref, od) in enumerate(zip(refs, odom, strict=True))
    ]


def _drifting_odometry(
    rng,
    refs: list[Pose2],
    start: Pose2,
    trans_per_m: float,
    rot_per_m: float,
    rot_per_rad: float,
    heading_bias_per_m: float = 0.0,
    scale_error: float = 0.0,
) -> list[Pose2]:
    """Odometry poses along the reference poses ``refs``, from ``start``: each step's true
    increment ``u = ref[i-1]^-1 @ ref[i]`` plus zero-mean Gaussian noise (``trans_per_m *
    |u|`` in x and y, ``rot_per_m * |u| + rot_per_rad * |u.theta|`` in the heading), a
    steady heading drift of ``heading_bias_per_m * |u|`` and its translation ``1 +
    scale_error`` times the true one (wheels of a wrong radius)."""
    odom = [start]
    for prev, cur in zip(refs[:-1], refs[1:], strict=True):
        u = prev.inverse() @ cur
        dist = math.hypot(u.x, u.y)
        s_t = trans_per_m * dist
        s_r = rot_per_m * dist + rot_per_rad * abs(u.theta)
        n = rng.normal(0.0, 1.0, 3) * np.array([s_t, s_t, s_r])
        th = u.theta + n[2] + heading_bias_per_m * dist
        k = 1.0 + scale_error
        odom.append(odom[-1] @ Pose2(k * u.x + n[0], k * u.y + n[1], th))
    return odom


def simulate_sensor_drive(
    rng: np.random.Generator,
    world: World,
    n_steps: int,
    step: float = 0.25,
    *,
    scan_rate: float = 10.0,
    speed: float = 1.0,
    turn_rate: float = math.radians(90.0),
    n_beams: int = 361,
    range_sigma: float = 0.01,
    range_sigma_per_m: float = 0.0,
    dropout: float = 0.0,
    sweep: float = 0.0,
    **scan_kw,
) -> list[Scan]:
    """The drive of :func:`simulate_trajectory` as a scanner running at ``scan_rate`` Hz
    sees it: the robot rides at ``speed`` m/s and turns at most ``turn_rate`` rad/s.

    The drive's ``n_steps`` poses ``step`` metres apart (and its drifting odometry) are
    joined by straight rides that turn evenly along the way; each lasts
    ``max(step / speed, |turn| / turn_rate)`` seconds and is scanned every
    ``1 / scan_rate`` s, so a 40 Hz scanner at 1 m/s sees steps of 2.5 cm and at most
    2.25 degrees at 90 degrees per second. Odometry is interpolated the same way between
    the drive's odometry poses (its noise is the drive's, whatever the rate).

    With ``sweep`` > 0 the scanner takes ``sweep`` seconds to measure its beams, one
    after the other in the order of their angles, beam ``i`` at ``i * sweep / n_beams``
    seconds after the scan's timestamp, from where the robot is by then (a rotating lidar
    sweeps once per scan: ``sweep = 1 / scan_rate``); the scans carry those
    :attr:`~scanclique.scan.Scan.beam_times`, and their ``reference`` is the pose at the
    timestamp (the first beam's, as ROS stamps a scan).

    Parameters
    ----------
    rng, world, n_steps, step
        As ``rng``, ``world``, ``n_scans`` and ``step`` of :func:`simulate_trajectory`.
    scan_rate, speed, turn_rate : float
        Hz (at most :data:`MAX_SCAN_RATE`), m/s, rad/s.
    sweep : float
        Seconds a scan's beams take, at most one scan period (0: all at once).
    n_beams, range_sigma, range_sigma_per_m, dropout, **scan_kw
        As in :func:`simulate_scan` (``fov``, ``angle_min``, ``max_range``).

    Returns
    -------
    list of Scan
        Timestamps ``k / scan_rate``, exact ``reference`` poses, drifting ``odometry``.

    Raises
    ------
    ConfigError
        As :func:`simulate_trajectory`, and a drive of more than :data:`MAX_SCANS` scans
        (a ``speed`` or ``turn_rate`` too low for the ``scan_rate``).

    Examples
    --------
    >>> rng = np.random.default_rng(0)
    >>> scans = simulate_sensor_drive(rng, office_world(rng), 5, scan_rate=40.0, n_beams=31)
    >>> len(scans) >= 4 * 10 + 1 and scans[1].timestamp == 0.025
    True
    """
    where = "simulate_sensor_drive"
    _check_count(where, n_steps=n_steps)
    if n_steps < 1:
        raise ConfigError(f"{where}: n_steps must be >= 1 (the drive starts with a scan), got 0")
    _check_positive(where, scan_rate=scan_rate, speed=speed, turn_rate=turn_rate)
    _check_at_most(where, MAX_SCAN_RATE, scan_rate=scan_rate)
    _check_nonneg(where, sweep=sweep)
    if sweep > 1.0 / scan_rate + 1e-12:
        raise ConfigError(f"{where}: sweep {sweep} s is longer than a scan period")
    view = {k: scan_kw[k] for k in ("fov", "angle_min", "max_range") if k in scan_kw}
    coarse = simulate_trajectory(
        rng, world, n_steps, step, n_beams=n_beams, range_sigma=0.0, **view
    )
    dt = 1.0 / scan_rate
    refs: list[Pose2] = [coarse[0].reference]
    odom: list[Pose2] = [coarse[0].odometry]
    # scan i is ride[i][0] @ _ride(ride[i][1], ride[i][3] / ride[i][2]), and the ride
    # ride[i + 1] carries it to scan i + 1 (for the sweep)
    ride: list[tuple[Pose2, Pose2, int, int]] = []
    legs = []  # (a, u, v, scans along the ride from a to b)
    for a, b in zip(coarse[:-1], coarse[1:], strict=True):
        u = a.reference.inverse() @ b.reference
        v = a.odometry.inverse() @ b.odometry
        seconds = max(math.hypot(u.x, u.y) / speed, abs(u.theta) / turn_rate)
        if not seconds / dt <= MAX_SCANS:  # inf too: ceil would overflow
            raise ConfigError(
                f"{where}: a ride of {seconds:.3g} s at scan_rate {scan_rate!r} Hz makes more "
                f"than {MAX_SCANS} scans (speed {speed!r} m/s, turn_rate {turn_rate!r} rad/s)"
            )
        legs.append((a, u, v, max(1, math.ceil(seconds / dt - 1e-9))))
    total = 1 + sum(leg[3] for leg in legs)
    if total > MAX_SCANS:
        raise ConfigError(
            f"{where}: the drive makes {total} scans at scan_rate {scan_rate!r} Hz, more than "
            f"{MAX_SCANS} (speed {speed!r} m/s, turn_rate {turn_rate!r} rad/s)"
        )
    for a, u, v, n in legs:
        if not ride:
            ride.append((a.reference, u, n, 0))
        for k in range(1, n + 1):
            f = k / n
            refs.append(a.reference @ _ride(u, f))
            odom.append(a.odometry @ _ride(v, f))
            ride.append((a.reference, u, n, k))
    ride = ride or [(refs[0], Pose2.identity(), 1, 0)]  # one pose: standing still
    times = np.arange(n_beams) * (sweep / n_beams) if sweep > 0 else None

    def swept(i: int):
        """The sensor's world poses while scan ``i``'s beams are measured: along the ride
        to scan ``i + 1`` (the last scan's on along its own)."""
        if times is None:
            return None
        if i + 1 < len(ride):
            start, u, n, k = ride[i + 1]
            f = (k - 1 + times / dt) / n
        else:
            start, u, n, k = ride[i]
            f = (k + times / dt) / n
        c, s_ = math.cos(start.theta), math.sin(start.theta)
        x, y = f * u.x, f * u.y
        return np.column_stack(
            (start.x + c * x - s_ * y, start.y + s_ * x + c * y, start.theta + f * u.theta)
        )

    return [
        simulate_scan(
            world,
            ref,
            n_beams=n_beams,
            range_sigma=range_sigma,
            range_sigma_per_m=range_sigma_per_m,
            dropout=dropout,
            rng=rng,
            timestamp=round(i * dt, 9),
            odometry=od,
            source=f"sim:{i}",
            sweep_poses=swept(i),
            beam_times=times,
            **scan_kw,
        )
        for i, (ref, od) in enumerate(zip(refs, odom, strict=True))
    ]


def _ride(u: Pose2, f: float) -> Pose2:
    """The fraction ``f`` of the straight ride ``u`` (its translation and its turn, each
    scaled by ``f``)."""
    return Pose2(f * u.x, f * u.y, f * u.theta)


def _ring_centreline(length: float, width: float, corridor: float, s: np.ndarray, r: float):
    """Poses (N, 3) at arc lengths ``s`` along the centre of :func:`ring_world`'s
    corridor, counter-clockwise from its lower left, the corners rounded with radius
    ``r``; ``s`` wraps round the loop."""
    h = corridor / 2.0
    straight = (length - 2.0 * h - 2.0 * r, width - 2.0 * h - 2.0 * r)
    arc = 0.5 * math.pi * r
    legs = [straight[0], arc, straight[1], arc] * 2
    starts = np.cumsum([0.0, *legs[:-1]])
    # where each straight starts, and its heading
    begins = [(h + r, h, 0.0), (length - h, h + r, 0.5 * math.pi),
              (length - h - r, width - h, math.pi), (h, width - h - r, -0.5 * math.pi)]  # fmt: skip
    out = np.zeros((len(s), 3))
    for n, x in enumerate(np.mod(s, sum(legs))):
        k = min(int(np.searchsorted(starts, x, side="right")) - 1, 7)
        d = x - starts[k]
        x0, y0, th = begins[k // 2]
        c, si = math.cos(th), math.sin(th)
        if k % 2 == 0:  # along a straight
            out[n] = (x0 + d * c, y0 + d * si, th)
        else:  # a quarter turn left about the corner's centre, after the straight
            end = straight[(k // 2) % 2]
            cx, cy = x0 + end * c - r * si, y0 + end * si + r * c
            phi = th + d / r
            out[n] = (cx + r * math.sin(phi), cy - r * math.cos(phi), phi)
    out[:, 2] = np.mod(out[:, 2] + math.pi, 2.0 * math.pi) - math.pi
    return out


def simulate_ring_drive(
    rng: np.random.Generator,
    *,
    length: float = 60.0,
    width: float = 40.0,
    corridor: float = 2.5,
    loops: float = 2.0,
    step: float = 0.25,
    trans_noise_per_m: float = 0.03,
    rot_noise_per_m: float = 0.005,
    rot_noise_per_rad: float = 0.02,
    heading_bias_per_m: float = 0.003,
    scale_error: float = 0.0,
    dt: float = 0.1,
    n_beams: int = 181,
    **scan_kw,
) -> list[Scan]:
    """Drive ``loops`` times round a :func:`ring_world` (drawn from ``rng``) along its
    corridor's centre, counter-clockwise, a scan every ``step`` metres: a long loop that
    a mapper must close, with every corner alike.

    The odometry is that of :func:`simulate_trajectory` (noise per metre and per radian
    of each step) with a steady heading drift of ``heading_bias_per_m`` rad per metre (a
    wheel a little larger than the other: 0.003 rad/m turns the odometry 33 degrees over
    a 190 m loop), its steps ``1 + scale_error`` times the true ones (wheels of a wrong
    radius; exact by default).

    Returns
    -------
    list of Scan
        With ``reference`` (true pose), ``odometry``, ``timestamp`` (``dt`` apart) and
        ``source`` ``"sim:<index>"``; the first reference pose is the loop's start.

    Raises
    ------
    ConfigError
        An argument out of range (as :func:`ring_world`'s), or ``loops`` and ``step``
        that make more than :data:`MAX_SCANS` scans.
    """
    where = "simulate_ring_drive"
    _check_positive(where, loops=loops, step=step, dt=dt)
    _check_beams(where, n_beams)
    _check_nonneg(
        where,
        trans_noise_per_m=trans_noise_per_m,
        rot_noise_per_m=rot_noise_per_m,
        rot_noise_per_rad=rot_noise_per_rad,
    )
    if not (math.isfinite(heading_bias_per_m) and math.isfinite(scale_error) and scale_error > -1):
        raise ConfigError(
            f"{where}: heading_bias_per_m {heading_bias_per_m} must be finite and "
            f"scale_error {scale_error} finite and above -1"
        )
    world = ring_world(rng, length, width, corridor=corridor)
    r = min(0.8, 0.45 * corridor)
    perimeter = 2.0 * (length + width - 4.0 * corridor / 2.0 - 4.0 * r) + 2.0 * math.pi * r
    if loops * perimeter / step > MAX_SCANS:
        raise ConfigError(
            f"{where}: {loops!r} loops of {perimeter:.1f} m, a scan every {step!r} m, make "
            f"more than {MAX_SCANS} scans"
        )
    s = np.arange(0.0, loops * perimeter, step)
    refs = [Pose2(*p) for p in _ring_centreline(length, width, corridor, s, r)]
    odom = _drifting_odometry(
        rng, refs, refs[0], trans_noise_per_m, rot_noise_per_m, rot_noise_per_rad,
        heading_bias_per_m, scale_error,
    )  # fmt: skip
    return [
        simulate_scan(world, ref, n_beams=n_beams, rng=rng, timestamp=i * dt, odometry=od,
                      source=f"sim:{i}", **scan_kw)
        for i, (ref, od) in enumerate(zip(refs, odom, strict=True))
    ]  # fmt: skip
