"""Planar coverage worlds: load, validate, rasterise and ray-cast.

A world (format in ``shared/worlds/README.md``) is an outer boundary polygon, disjoint obstacle
polygons inside it and a start position. This module is the single reader of world files: the
simulator, the simulated sonar and the evaluation monitor use it; the planner never does (it
only knows what its sensors tell it, Section V of Acar, Choset and Lee).

Bad input raises :class:`paramotion.errors.UserError` with one line naming the file and the
problem, so that a scenario never starts half-way on a broken world.
"""
from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Protocol

import numpy as np
from numpy.typing import ArrayLike
from shapely.geometry import Point, Polygon
from shapely.validation import explain_validity

from paramotion.errors import UserError
from paramotion.jsonfile import load_json_object


class _NamedNode(Protocol):
    """What :func:`load_world_param` reads of a node: its name (for the error line)."""

    def get_name(self) -> str: ...


@dataclass
class World:
    """A validated planar world; coordinates in metres in the ``map`` frame."""

    name: str
    boundary: np.ndarray                 # (n, 2) outer wall, counter-clockwise
    obstacles: list                      # list of (m, 2) arrays
    start: np.ndarray                    # (2,) robot centre at start
    source: str = '<memory>'
    free: Polygon = field(init=False, repr=False)
    segments: np.ndarray = field(init=False, repr=False)

    def __post_init__(self):
        holes = [list(map(tuple, o)) for o in self.obstacles]
        self.free = Polygon(list(map(tuple, self.boundary)), holes)
        segs = []
        for ring in [self.boundary] + list(self.obstacles):
            ring = np.asarray(ring, dtype=float)
            segs.append(np.hstack([ring, np.roll(ring, -1, axis=0)]))
        self.segments = np.vstack(segs)

    @property
    def bounds(self) -> tuple[float, float, float, float]:
        """(xmin, ymin, xmax, ymax) of the boundary."""
        return self.free.bounds

    def clearance(self, xy: ArrayLike) -> float:
        """Distance D(x) from a point to the nearest wall or obstacle (0 outside free space)."""
        p = Point(float(xy[0]), float(xy[1]))
        if not self.free.contains(p):
            return 0.0
        return float(self.free.boundary.distance(p))

    def contains(self, xy: ArrayLike) -> bool:
        """True if the point lies in the free workspace FWS."""
        return bool(self.free.contains(Point(float(xy[0]), float(xy[1]))))

    def raycast(self, origin: ArrayLike, angles: ArrayLike, max_range: float) -> np.ndarray:
        """Distance along each ray from ``origin`` to the first wall, capped at ``max_range``.

        Exact ray/segment intersection, vectorised over rays and segments.
        """
        return raycast_segments(self.segments, origin, angles, max_range)

    def to_json(self) -> dict[str, object]:
        """The world as the JSON-compatible dict it was loaded from."""
        return {'name': self.name, 'boundary': self.boundary.tolist(),
                'obstacles': [o.tolist() for o in self.obstacles],
                'start': self.start.tolist()}


def raycast_segments(segments: np.ndarray, origin: ArrayLike, angles: ArrayLike,
                     max_range: float) -> np.ndarray:
    """Distance from ``origin`` along each direction in ``angles`` to the nearest segment.

    ``segments`` is (k, 4) rows ``x1, y1, x2, y2``. Returns an array shaped like ``angles``;
    rays that hit nothing within ``max_range`` return ``max_range``.
    """
    angles = np.asarray(angles, dtype=float)
    d = np.stack([np.cos(angles.ravel()), np.sin(angles.ravel())], axis=1)    # (n, 2)
    p = np.asarray(origin, dtype=float)[:2]
    a = segments[:, :2] - p                                                   # (k, 2)
    e = segments[:, 2:] - segments[:, :2]                                     # (k, 2)
    # Solve p + t d = s1 + u e  ->  t = cross(a, e) / cross(d, e), u = cross(a, d) / cross(d, e)
    den = d[:, None, 0] * e[None, :, 1] - d[:, None, 1] * e[None, :, 0]       # (n, k)
    num_t = a[None, :, 0] * e[None, :, 1] - a[None, :, 1] * e[None, :, 0]
    num_u = a[None, :, 0] * d[:, None, 1] - a[None, :, 1] * d[:, None, 0]
    with np.errstate(divide='ignore', invalid='ignore'):
        t = num_t / den
        u = num_u / den
    ok = (np.abs(den) > 1e-12) & (t >= 0.0) & (u >= -1e-9) & (u <= 1.0 + 1e-9)
    t = np.where(ok, t, np.inf)
    out = np.minimum(t.min(axis=1), max_range)
    return out.reshape(angles.shape)


def _polygon(points, what, source):
    """Validate one polygon given as a list of [x, y] pairs; return an (n, 2) array."""
    if not isinstance(points, list) or len(points) < 3:
        raise UserError(f'{source}: {what} must be a list of at least 3 [x, y] vertices')
    try:
        arr = np.array(points, dtype=float)
    except (TypeError, ValueError):
        raise UserError(f'{source}: {what} has a vertex that is not an [x, y] number pair')
    if arr.ndim != 2 or arr.shape[1] != 2:
        raise UserError(f'{source}: {what} has a vertex that is not an [x, y] number pair')
    if not np.all(np.isfinite(arr)):
        raise UserError(f'{source}: {what} has a non-finite coordinate')
    if np.allclose(arr[0], arr[-1]):
        arr = arr[:-1]                                    # tolerate an explicitly closed ring
    poly = Polygon(arr)
    if not poly.is_valid:
        raise UserError(f'{source}: {what} is not a simple polygon '
                        f'({explain_validity(poly)})')
    if poly.area <= 0.0:
        raise UserError(f'{source}: {what} has zero area')
    if poly.exterior.is_ccw is False:
        arr = arr[::-1].copy()                            # orientation is not an error
    return arr


def world_from_dict(data: Mapping[str, object], source: str = '<memory>',
                    radius: float | None = None) -> World:
    """Validate a world dict (see module docstring); ``radius`` checks start clearance."""
    if not isinstance(data, dict):
        raise UserError(f'{source}: top level must be a JSON object')
    for key in ('boundary', 'start'):
        if key not in data:
            raise UserError(f'{source}: missing key "{key}"')
    boundary = _polygon(data['boundary'], 'boundary', source)
    obstacles_raw = data.get('obstacles', [])
    if not isinstance(obstacles_raw, list):
        raise UserError(f'{source}: "obstacles" must be a list of polygons')
    obstacles = [_polygon(o, f'obstacle {i}', source) for i, o in enumerate(obstacles_raw)]
    outer = Polygon(boundary)
    polys = [Polygon(o) for o in obstacles]
    for i, p in enumerate(polys):
        if not outer.contains(p):
            raise UserError(f'{source}: obstacle {i} is not strictly inside the boundary')
        for j in range(i):
            if p.intersects(polys[j]):
                raise UserError(f'{source}: obstacles {j} and {i} overlap or touch')
    start = data['start']
    try:
        start = np.array(start, dtype=float)
    except (TypeError, ValueError):
        raise UserError(f'{source}: "start" must be an [x, y] number pair')
    if start.shape != (2,) or not np.all(np.isfinite(start)):
        raise UserError(f'{source}: "start" must be a finite [x, y] number pair')
    world = World(name=str(data.get('name', 'world')), boundary=boundary, obstacles=obstacles,
                  start=start, source=source)
    if not outer.contains(Point(*start)):
        raise UserError(f'{source}: start {start.tolist()} is outside the boundary')
    for i, p in enumerate(polys):
        if p.covers(Point(*start)):
            raise UserError(f'{source}: start {start.tolist()} is inside obstacle {i}')
    if radius is not None:
        c = world.clearance(start)
        if not c > radius:
            raise UserError(f'{source}: start {start.tolist()} has clearance {c:.3f} m, '
                            f'not more than the robot radius {radius:g} m')
    return world


def load_world(path: str | Path, radius: float | None = None) -> World:
    """Load and validate a world JSON file; raise UserError with one line if it is bad."""
    data = load_json_object(path, 'world file')
    return world_from_dict(data, source=str(path), radius=radius)


def load_world_param(node: _NamedNode, path: str | Path,
                     radius: float | None = None) -> World:
    """Load the world named by a node's ``world`` parameter; a bad file is a bad parameter.

    Raises :class:`paramotion.errors.ParameterError` (one line, naming node and parameter), so
    that ``run_node`` reports it like any other refused parameter.
    """
    from paramotion.errors import ParameterError
    if not path:
        raise ParameterError(f"{node.get_name()}: parameter 'world' is empty: give the world "
                             'JSON file')
    try:
        return load_world(path, radius=radius)
    except UserError as exc:
        raise ParameterError(f"{node.get_name()}: parameter 'world': {exc}") from None


def rasterize(world: World, resolution: float,
              margin: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """Rasterise the free workspace on a grid of square cells.

    Returns ``(free_mask, origin)`` where ``free_mask[i, j]`` is True if the centre of cell
    (row i = y index, column j = x index) lies in FWS, and ``origin`` is the (x, y) of the
    lower-left corner of cell (0, 0).
    """
    from matplotlib.path import Path
    xmin, ymin, xmax, ymax = world.bounds
    xmin -= margin
    ymin -= margin
    nx = int(math.ceil((xmax + margin - xmin) / resolution))
    ny = int(math.ceil((ymax + margin - ymin) / resolution))
    xs = xmin + (np.arange(nx) + 0.5) * resolution
    ys = ymin + (np.arange(ny) + 0.5) * resolution
    gx, gy = np.meshgrid(xs, ys)
    pts = np.column_stack([gx.ravel(), gy.ravel()])
    mask = Path(world.boundary).contains_points(pts)
    for o in world.obstacles:
        mask &= ~Path(o).contains_points(pts)
    return mask.reshape(ny, nx), np.array([xmin, ymin])


def random_world(seed: int, size: tuple[float, float] = (16.0, 12.0), n_obstacles: int = 4,
                 radius: float = 0.25) -> World:
    """A random, valid world (rectangular room with a notch and convex obstacles).

    Used by the tests to check the planner on worlds it has never seen.
    """
    rng = np.random.default_rng(seed)
    w, h = size
    # Boundary: a rectangle with a rectangular notch cut into one side, making a non-convex room.
    nw, nh = rng.uniform(0.2, 0.4) * w, rng.uniform(0.2, 0.4) * h
    nx0 = rng.uniform(0.25, 0.75) * (w - nw)
    boundary = [[0, 0], [w, 0], [w, h], [nx0 + nw, h], [nx0 + nw, h - nh], [nx0, h - nh],
                [nx0, h], [0, h]]
    outer = Polygon(boundary)
    obstacles = []
    tries = 0
    while len(obstacles) < n_obstacles and tries < 500:
        tries += 1
        c = rng.uniform([1.5, 1.5], [w - 1.5, h - 1.5])
        k = int(rng.integers(3, 7))
        rad = rng.uniform(0.4, 1.6)
        ang = np.sort(rng.uniform(0, 2 * math.pi, k))
        if np.max(np.diff(np.r_[ang, ang[0] + 2 * math.pi])) > 2.5:
            continue
        pts = np.column_stack([c[0] + rad * np.cos(ang), c[1] + rad * np.sin(ang)])
        poly = Polygon(pts)
        if not poly.is_valid or poly.area < 0.2:
            continue
        if not outer.buffer(-1.0).contains(poly):
            continue
        if any(poly.distance(Polygon(o)) < 1.0 for o in obstacles):
            continue
        obstacles.append(np.round(pts, 3).tolist())
    data = {'name': f'random_{seed}', 'boundary': boundary, 'obstacles': obstacles,
            'start': [1.0, 1.0]}
    return world_from_dict(data, source=f'random_world({seed})', radius=radius)
