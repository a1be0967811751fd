"""Seeded generator of coverage worlds the planner has never seen.

Layouts (chosen by the seed): rooms joined by doors 1.2-1.6 m wide (a spanning tree of doors,
so some rooms are dead ends), a corridor maze (corridors 1.2-1.6 m wide on a coarse grid with
dead ends and a few open rooms), L and T halls, and a mix (rooms off a corridor). Rooms get
convex clutter. The free space is built as a union of rectangles (shapely); its outer ring
becomes the world ``boundary`` and its holes the ``obstacles``, in the world JSON format of
``/work/shared/worlds/README.md``. Every world is validated by
:func:`coverage_pkg.world.world_from_dict` before it is returned.
"""
from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
from shapely.geometry import Point, Polygon, box
from shapely.ops import unary_union

from coverage_pkg.world import world_from_dict
from paramotion.errors import UserError

KINDS = ('rooms', 'maze', 'halls', 'mixed')
WALL = 0.2                      # interior wall thickness (m)


def _door(rng):
    return float(rng.uniform(1.2, 1.6))


def _rooms(rng):
    """A grid of rooms; doors on a random spanning tree of the room adjacency."""
    nx, ny = int(rng.integers(2, 4)), int(rng.integers(1, 3))
    ws = rng.uniform(5.0, 8.0, nx)
    hs = rng.uniform(4.5, 7.0, ny)
    xs = np.r_[0.0, np.cumsum(ws + WALL)]
    ys = np.r_[0.0, np.cumsum(hs + WALL)]
    parts = [box(xs[i], ys[j], xs[i] + ws[i], ys[j] + hs[j])
             for i in range(nx) for j in range(ny)]
    for a, b in _spanning_tree(rng, nx, ny):
        (i, j), (k, m) = a, b
        d = _door(rng)
        if j == m:                                    # neighbours in x: door in a vertical wall
            y0 = rng.uniform(ys[j] + 0.3, ys[j] + hs[j] - d - 0.3)
            parts.append(box(xs[k] - WALL - 0.05, y0, xs[k] + 0.05, y0 + d))
        else:
            x0 = rng.uniform(xs[i] + 0.3, xs[i] + ws[i] - d - 0.3)
            parts.append(box(x0, ys[m] - WALL - 0.05, x0 + d, ys[m] + 0.05))
    rooms = [box(xs[i], ys[j], xs[i] + ws[i], ys[j] + hs[j])
             for i in range(nx) for j in range(ny)]
    return unary_union(parts), rooms


def _spanning_tree(rng, nx, ny):
    """Edges ((i, j), (k, m)) of a random spanning tree of the nx x ny grid, k >= i, m >= j."""
    seen = {(0, 0)}
    edges = []
    frontier = [((0, 0), n) for n in _nbrs((0, 0), nx, ny)]
    while frontier:
        a, b = frontier.pop(int(rng.integers(len(frontier))))
        if b in seen:
            continue
        seen.add(b)
        edges.append(tuple(sorted((a, b))))
        frontier += [(b, n) for n in _nbrs(b, nx, ny) if n not in seen]
    return edges


def _nbrs(c, nx, ny):
    i, j = c
    return [(i + di, j + dj) for di, dj in ((1, 0), (-1, 0), (0, 1), (0, -1))
            if 0 <= i + di < nx and 0 <= j + dj < ny]


def _maze(rng):
    """Corridors 1.2-1.6 m wide along a spanning tree of a coarse grid (dead ends at its
    leaves); one or two grid cells are open rooms."""
    nx, ny = int(rng.integers(3, 5)), int(rng.integers(2, 4))
    step = float(rng.uniform(3.5, 4.5))
    parts = []
    rooms = []
    for a, b in _spanning_tree(rng, nx, ny):
        w = _door(rng)
        (i, j), (k, m) = a, b
        x0, y0, x1, y1 = i * step, j * step, k * step, m * step
        parts.append(box(min(x0, x1) - w / 2, min(y0, y1) - w / 2,
                         max(x0, x1) + w / 2, max(y0, y1) + w / 2))
    for _ in range(int(rng.integers(1, 3))):
        i, j = int(rng.integers(nx)), int(rng.integers(ny))
        s = float(rng.uniform(4.0, 6.0))
        room = box(i * step - s / 2, j * step - s / 2, i * step + s / 2, j * step + s / 2)
        parts.append(room)
        rooms.append(room)
    return unary_union(parts), rooms


def _halls(rng):
    """An L or a T hall of 2.5-4.5 m wide arms."""
    w1, w2 = rng.uniform(2.5, 4.5, 2)
    l1, l2 = rng.uniform(9.0, 15.0), rng.uniform(6.0, 10.0)
    arm = box(0, 0, l1, w1)
    if rng.random() < 0.5:                                  # L
        leg = box(0, 0, w2, l2)
    else:                                                   # T
        x0 = rng.uniform(0.3, 0.7) * (l1 - w2)
        leg = box(x0, 0, x0 + w2, l2)
    return unary_union([arm, leg]), [arm, leg]


def _mixed(rng):
    """Two to four rooms opening (doors 1.2-1.6 m) onto a corridor, one of them a dead end."""
    n = int(rng.integers(2, 5))
    cw = _door(rng)
    ws = rng.uniform(4.5, 7.0, n)
    hs = rng.uniform(4.5, 6.5, n)
    xs = np.r_[0.0, np.cumsum(ws + WALL)]
    length = xs[-1] - WALL + float(rng.uniform(0.0, 3.0))   # may run on: a dead end
    corridor = box(0, 0, length, cw)
    parts, rooms = [corridor], []
    for i in range(n):
        up = rng.random() < 0.5
        y0 = cw + WALL if up else -WALL - hs[i]
        room = box(xs[i], y0, xs[i] + ws[i], y0 + hs[i])
        d = _door(rng)
        dx = rng.uniform(xs[i] + 0.3, xs[i] + ws[i] - d - 0.3)
        door = box(dx, cw - 0.05, dx + d, cw + WALL + 0.05) if up else \
            box(dx, -WALL - 0.05, dx + d, 0.05)
        parts += [room, door]
        rooms.append(room)
    return unary_union(parts), rooms


def _clutter(rng, free, rooms, radius):
    """Convex obstacles inside rooms, at least 1.2 m from walls and from each other."""
    obstacles = []
    for room in rooms:
        for _ in range(int(rng.integers(0, 3))):
            for _try in range(30):
                minx, miny, maxx, maxy = room.bounds
                c = rng.uniform([minx, miny], [maxx, maxy])
                k = int(rng.integers(3, 7))
                rad = float(rng.uniform(0.3, 0.9))
                ang = np.sort(rng.uniform(0, 2 * math.pi, k))
                if np.max(np.diff(np.r_[ang, ang[0] + 2 * math.pi])) > 2.5:
                    continue
                poly = Polygon(np.column_stack([c[0] + rad * np.cos(ang),
                                                c[1] + rad * np.sin(ang)]))
                if not poly.is_valid or poly.area < 0.15:
                    continue
                if not free.buffer(-1.2).contains(poly):
                    continue
                if any(poly.distance(o) < 1.2 for o in obstacles):
                    continue
                obstacles.append(poly)
                break
    return obstacles


def generate_world(seed: int, kind: str | None = None,
                   radius: float = 0.25) -> dict[str, object]:
    """One world dict (world JSON format) for ``seed``; ``kind`` in :data:`KINDS` or None (the
    seed chooses)."""
    rng = np.random.default_rng(seed)
    if kind is None:
        kind = KINDS[int(rng.integers(len(KINDS)))]
    if kind not in KINDS:
        raise UserError(f'world kind "{kind}": must be one of {", ".join(KINDS)}')
    # A layout whose outline comes out touching itself (a door flush with a room's corner,
    # or two vertices merged by the rounding to mm) is not a valid world: the seed's generator
    # draws the next layout of the same kind. A layout that is valid the first time is the
    # one earlier versions wrote for the seed.
    for attempt in range(20):
        try:
            return _layout(rng, seed, kind, radius)
        except UserError as err:
            if attempt == 19:
                raise UserError(f'generate_world({seed}): no valid {kind} layout in 20 draws '
                                f'({err})') from None
    raise AssertionError('unreachable')


def _layout(rng, seed, kind, radius):
    """One layout of ``kind`` drawn from ``rng``, checked by ``world_from_dict``."""
    free, rooms = {'rooms': _rooms, 'maze': _maze, 'halls': _halls, 'mixed': _mixed}[kind](rng)
    free = free.simplify(0.0)
    if free.geom_type != 'Polygon':
        free = max(free.geoms, key=lambda g: g.area)
    clutter = _clutter(rng, free, rooms, radius)
    holes = [Polygon(h) for h in free.interiors] + clutter
    ox, oy = free.bounds[0] - 0.0, free.bounds[1] - 0.0

    def ring(coords):
        pts = np.asarray(coords)[:-1] if np.allclose(coords[0], coords[-1]) else \
            np.asarray(coords)
        return np.round(pts - [ox, oy], 3).tolist()
    start = _start(rng, free, clutter, radius)
    data = {'name': f'gen_{kind}_{seed}', 'boundary': ring(free.exterior.coords),
            'obstacles': [ring(h.exterior.coords) for h in holes],
            'start': [round(start[0] - ox, 3), round(start[1] - oy, 3)]}
    world_from_dict(data, source=f'generate_world({seed})', radius=radius)
    return data


def _start(rng, free, clutter, radius):
    """A start with clearance of at least radius + 0.4 m."""
    space = free.difference(unary_union(clutter)) if clutter else free
    inner = space.buffer(-(radius + 0.4))
    minx, miny, maxx, maxy = inner.bounds
    for _ in range(1000):
        p = rng.uniform([minx, miny], [maxx, maxy])
        if inner.contains(Point(*p)):
            return float(p[0]), float(p[1])
    raise UserError('generated world has no start with enough clearance')


def write_worlds(out: str | Path, count: int, seed: int = 0,
                 kind: str | None = None) -> list[Path]:
    """Write ``count`` worlds ``<name>.json`` into directory ``out``; returns the paths."""
    if count < 1:
        raise UserError(f'--count {count}: must be at least 1')
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    paths = []
    for i in range(count):
        data = generate_world(seed + i, kind)
        p = out / f"{data['name']}.json"
        p.write_text(json.dumps(data, indent=1) + '\n')
        paths.append(p)
    return paths
