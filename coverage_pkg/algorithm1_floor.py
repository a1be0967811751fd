"""The shortest path that drives what Algorithm 1 must drive (evaluation only).

Algorithm 1 covers narrow space by tracing its GVD edges and vast space by boundary circuits
at D = delta and laps. Whatever the order, the robot drives every GVD edge of the narrow
space (up to where all ahead lies within range, the rule that ends a branch at a dead end)
and every closed curve D = delta once at least. This module computes, **with the true map**,
a lower estimate of the path that does that - to say how much of the paper planner's path /
bound ratio is the method on the world and how much is the planner:

1. the grid of :class:`coverage_pkg.cvs.CoverableSet` (0.05 m) and its clearance D;
2. the narrow GVD: the medial axis of the free space (``skimage.morphology.medial_axis``)
   where r < D < delta; the curves D = delta: the boundary cells of {D >= delta};
3. dead ends trimmed: a leaf of the GVD is peeled back while every point it has shed lies
   within ``delta - view_margin`` of it (the planner's branch end, measured to the GVD and
   not to the wall beyond, so it trims at least as much as the planner does);
4. required length: the chains of what is left, each simplified to within one grid cell
   (the grid's staircase would overstate them by up to 8 %);
5. a lower bound of the shortest walk from the start that drives all of it (a rural
   postman problem): the walk reaches the required set at some cell p and drives all of it
   from there, so it is at least the way from the start to p, plus the required length,
   plus a minimum-weight perfect matching (``networkx.min_weight_matching``) of the
   odd-degree vertices (p's degree toggled) and one free end, on geodesic distances in
   FCS_r (``skimage.graph.MCP_Geometric``): the shortest set of extra ways that makes every
   degree even but the walk's ends'. The least over p is taken (cells p within 3 m of the
   nearest are tried every 0.2 m, less 0.4 m for the cells between; a farther one is bounded
   from below). The pieces are not required to be joined,
   so the bound holds where the required set falls apart.

:func:`nearest_first_walk` drives the same required set in an order an online robot could
follow: it learns an edge when it stands at one of its ends, and always drives to the nearest
edge it knows (ties between the edges of one vertex, whose lengths it cannot know, in a
random order). It is an estimate of what Algorithm 1 needs with FindUncoveredNode's
nearest-first choice, idealised: it senses every edge at once and drives the true shortest
way to it. With ``circuits_first`` it keeps Algorithm 1's order in a vast cell: a curve
D = delta, once reached, is driven round before the GVD edges that leave it.

:func:`driven_again` splits a path the planner drove into ground driven for the first time
and ground driven again, to set the first against the required length and the rest against
the walk's ways between edges.

Laps, the way between disconnected pieces and anything the sensors make the robot do are not
counted, so the planner's path can only be longer - except where the planner skips a stretch
the floor counts (the report says so where it happens). Unlike the full-knowledge route of
:mod:`coverage_pkg.oracle` this is not what any robot needs: it is what this method needs.
The planner never uses it.
"""
from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike

from coverage_pkg.cvs import CoverableSet
from coverage_pkg.oracle import geodesic

if TYPE_CHECKING:
    from coverage_pkg.world import World

_STEPS = [(-1, -1), (-1, 0), (-1, 1), (0, -1), (0, 1), (1, -1), (1, 0), (1, 1)]


def required_cells(cvs: CoverableSet, delta: float, radius: float, view_margin: float = 0.3,
                   rng: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """Boolean grids: the narrow GVD cells Algorithm 1 traces (dead ends trimmed) and the
    cells of the curves D = delta it circles. ``rng``: the medial axis's tie-breaking seed
    (fixed, so that the floor of a world is one number)."""
    from scipy import ndimage
    from skimage.morphology import medial_axis, skeletonize
    free = _reachable_free(cvs)
    d = cvs.clearance
    gvd = medial_axis(free, rng=rng) & (d > radius) & (d < delta)
    vast = free & (d >= delta)
    cross = ndimage.generate_binary_structure(2, 1)
    ring = vast & ~ndimage.binary_erosion(vast, structure=cross, border_value=0)
    thin = skeletonize(gvd | ring)
    # The grid's medial axis has small loops round no obstacle (a true GVD loop goes round
    # one, and a circle round vast space): filled and thinned again, each is one line.
    lab, _ = ndimage.label(~thin, structure=cross)
    kept = np.unique(lab[~free | vast])
    bubbles = (lab > 0) & ~np.isin(lab, kept)
    if bubbles.any():
        thin = skeletonize(thin | bubbles)
    ring &= thin
    gvd = thin & ~ring
    # A GVD cell next to a circle cell joins it: the cusp where the edge reaches D = delta.
    return _trim_dead_ends(gvd, ring, cvs.res, delta - view_margin), ring


def _reachable_free(cvs):
    """Free cells of the world in the component the robot starts in."""
    from scipy import ndimage
    lab, _ = ndimage.label(cvs.free)
    ids = np.unique(lab[cvs.fcs])
    return np.isin(lab, ids[ids > 0])


def _neighbours(mask, r, c):
    """Neighbours of a cell on a thin curve: the four sides, and a diagonal only where
    neither cell beside it is on the curve (no triangles, so degrees are a graph's)."""
    h, w = mask.shape

    def on(rr, cc):
        return 0 <= rr < h and 0 <= cc < w and mask[rr, cc]

    for dr, dc in _STEPS:
        if on(r + dr, c + dc) and (dr == 0 or dc == 0 or
                                   not (on(r + dr, c) or on(r, c + dc))):
            yield r + dr, c + dc


def _trim_dead_ends(gvd, ring, res, reach):
    """Peel leaves of the GVD while every cell they shed lies within ``reach`` m."""
    keep = gvd.copy()
    both = gvd | ring
    degree = {}
    for r, c in zip(*np.nonzero(gvd)):
        degree[(r, c)] = sum(1 for _ in _neighbours(both, r, c))
    shed = {k: [] for k in degree}
    stack = [k for k, v in degree.items() if v <= 1]
    while stack:
        cell = stack.pop()
        if not keep[cell]:
            continue
        ends = shed[cell] or [cell]
        if max(math.hypot(cell[0] - e[0], cell[1] - e[1]) for e in ends) * res > reach:
            continue
        keep[cell] = False
        both[cell] = False
        for n in _neighbours(both, *cell):
            if n in degree:
                shed[n].extend(ends)
                degree[n] -= 1
                if degree[n] <= 1:
                    stack.append(n)
    return keep


def _chains(mask, res, extra=(), middle=False):
    """Graph of the mask's cells: vertices where the degree is not 2 and the cells
    ``extra``, edges the chains between them with their simplified length. Returns (vertex
    cells, [(a, b, length)]; with ``middle``, [(a, b, length, the chain's middle cell)])."""
    cells = set(zip(*np.nonzero(mask)))
    nbrs = {k: list(_neighbours(mask, *k)) for k in cells}
    verts = {k for k, v in nbrs.items() if len(v) != 2} | (set(extra) & cells)
    edges, used = [], set()

    def walk(a, b):
        chain = [a, b]
        while chain[-1] not in verts:
            nxt = [n for n in nbrs[chain[-1]] if n != chain[-2]]
            if not nxt:
                break
            chain.append(nxt[0])
            if nxt[0] == chain[0]:
                break
        return chain

    for a in verts:
        for b in nbrs[a]:
            if (a, b) in used:
                continue
            chain = walk(a, b)
            for p, q in zip(chain[:-1], chain[1:]):
                used.add((p, q))
                used.add((q, p))
            edges.append((a, chain[-1], _length(chain, res)) +
                         ((chain[len(chain) // 2],) if middle else ()))
    for k in cells:                       # closed curves without a vertex: a loop each
        if k in verts or any((k, n) in used for n in nbrs[k]):
            continue
        verts.add(k)
        chain = walk(k, nbrs[k][0])
        if chain[-1] != k:
            chain.append(k)
        for p, q in zip(chain[:-1], chain[1:]):
            used.add((p, q))
            used.add((q, p))
        edges.append((k, k, _length(chain, res)) + ((chain[len(chain) // 2],) if middle else ()))
    return verts, edges


def _length(chain, res):
    """Length of a chain of cells, simplified to within one cell (no grid staircase)."""
    import shapely
    if len(chain) < 2:
        return 0.0
    pts = np.asarray(chain, dtype=float)[:, ::-1] * res
    return float(shapely.LineString(pts).simplify(res).length)


def algorithm1_floor(world: World, radius: float = 0.25, delta: float = 2.0,
                     view_margin: float = 0.3) -> dict[str, object]:
    """The floor of Algorithm 1's path on ``world`` (see the module doc). Returns the floor
    (m) and its parts: ``gvd`` and ``circles``, the required length on narrow GVD edges and
    on the curves D = delta; ``extra``, the least driving beside them (from the start to the
    required set and the matching; ``lead``, its first part, to the nearest required cell);
    ``odd``, the number of odd-degree vertices; the lower bound |CVS| / (2 delta) and the
    grids of the required cells."""
    import networkx as nx
    cvs = CoverableSet(world, radius, delta, 0.05)
    gvd, ring = required_cells(cvs, delta, radius, view_margin)
    verts, edges = _chains(gvd | ring, cvs.res)
    gvd_len = sum(length for a, b, length in edges if gvd[a] or gvd[b])
    total = sum(length for *_, length in edges)
    degree = {v: 0 for v in verts}
    for a, b, _ in edges:
        degree[a] += 1
        degree[b] += 1
    odd = sorted(v for v, k in degree.items() if k % 2)
    start = cvs.cell_of(world.start)
    passable = cvs.fcs.copy()
    passable[start] = True
    required = gvd | ring
    _, from_start = geodesic(passable, [start])
    from_start = np.where(required, from_start * cvs.res, np.inf)
    lead = float(from_start.min()) if np.isfinite(from_start).any() else 0.0
    pair = {}                                        # geodesic distances between odd vertices
    for i, a in enumerate(odd):
        _, cum = geodesic(passable, [a])
        for j in range(i + 1, len(odd)):
            if np.isfinite(cum[odd[j]]):
                pair[i, j] = float(cum[odd[j]] * cvs.res)

    def matching(entry=None, entry_dist=None, ends=1):
        """Minimum-weight perfect matching of the odd vertices (toggled by ``entry``, the
        cell where the walk enters the required set) and ``ends`` free ends."""
        g = nx.Graph()
        nodes = {i for i in range(len(odd)) if odd[i] != entry}
        g.add_edges_from((i, j, {'weight': w}) for (i, j), w in pair.items()
                         if i in nodes and j in nodes)
        for i in nodes:
            for e in range(ends):
                g.add_edge(i, ('end', e), weight=0.0)
        if entry is not None and entry not in odd:
            for i in nodes:
                if np.isfinite(entry_dist[odd[i]]):
                    g.add_edge('entry', i, weight=float(entry_dist[odd[i]] * cvs.res))
            for e in range(ends):
                g.add_edge('entry', ('end', e), weight=0.0)
        m = nx.min_weight_matching(g)
        return sum(g.edges[u, v]['weight'] for u, v in m)

    # The walk enters the required set at some cell p and covers it from there: at least
    # d(start, p) + L + matching(odd toggled at p, one free end). Cells p within ``window``
    # beyond the nearest are tried, every ``spacing`` at most; both terms change by at most
    # the distance between two cells, so the least found less twice the spacing bounds every
    # p of the window. Any farther p costs at least lead + window + the matching with two
    # free ends (which no p can undercut).
    window, spacing = 3.0, 0.2
    extra = lead + window + matching(ends=2)
    rows, cols = np.nonzero(from_start <= lead + window)
    tried, best = [], math.inf
    for k in np.argsort(from_start[rows, cols], kind='stable'):
        p = (int(rows[k]), int(cols[k]))
        if any(math.dist(p, q) * cvs.res < spacing for q in tried):
            continue
        tried.append(p)
        _, entry_dist = geodesic(passable, [p])
        best = min(best, from_start[p] + matching(p, entry_dist))
    extra = max(lead, min(extra, best - 2 * spacing))
    return {'floor': total + extra, 'gvd': gvd_len, 'circles': total - gvd_len,
            'lead': lead, 'extra': extra, 'odd': len(odd),
            'lower_bound': cvs.lower_bound_path(),
            'gvd_cells': gvd, 'circle_cells': ring, 'cvs': cvs}


def nearest_first_walk(world: World, radius: float = 0.25, delta: float = 2.0,
                       view_margin: float = 0.3, orders: int = 32,
                       circuits_first: bool = False) -> dict[str, object]:
    """The path of a nearest-first online order over the required set of
    :func:`algorithm1_floor` (see the module doc). The walk goes from the start to the
    nearest required cell p (a vertex); at each step it drives the geodesic way to the
    nearest end of an undriven edge that touches a vertex it has reached, and then the
    whole edge. Edges of one vertex tie; ``orders`` seeded random tie-breaks are walked.
    ``circuits_first``: Algorithm 1's order in a vast cell: a curve D = delta, once
    reached, is driven round whole before any other edge (the circuit before the corners'
    and doors' GVD edges that leave it). Returns the mean, least and largest walk (m), the
    required length and the bound."""
    walks = nearest_first_walks(world, radius, delta, view_margin, orders)
    key = 'circuits_first' if circuits_first else 'any_order'
    return {**walks[key], 'required': walks['required'], 'lower_bound': walks['lower_bound']}


def nearest_first_walks(world: World, radius: float = 0.25, delta: float = 2.0,
                        view_margin: float = 0.3, orders: int = 32) -> dict[str, object]:
    """Both orders of :func:`nearest_first_walk` on one graph (its geodesics are the cost):
    ``any_order`` and ``circuits_first``, each the mean, least and largest walk (m); the
    required length and the bound."""
    cvs = CoverableSet(world, radius, delta, 0.05)
    gvd, ring = required_cells(cvs, delta, radius, view_margin)
    required = gvd | ring
    start = cvs.cell_of(world.start)
    passable = cvs.fcs.copy()
    passable[start] = True
    _, from_start = geodesic(passable, [start])
    from_start = np.where(required, from_start * cvs.res, np.inf)
    if not np.isfinite(from_start).any():
        none = {'walk': 0.0, 'walk_min': 0.0, 'walk_max': 0.0}
        return {'any_order': none, 'circuits_first': none, 'required': 0.0,
                'lower_bound': cvs.lower_bound_path()}
    p = tuple(int(i) for i in np.unravel_index(np.argmin(from_start), from_start.shape))
    lead = float(from_start[p])
    verts, chains = _chains(required, cvs.res, extra=[p], middle=True)
    verts = sorted(verts)
    index = {v: i for i, v in enumerate(verts)}
    dist = np.empty((len(verts), len(verts)))
    for i, v in enumerate(verts):
        _, cum = geodesic(passable, [v])
        dist[i] = [cum[w] * cvs.res for w in verts]
    edges = [(index[a], index[b], length) for a, b, length, _ in chains]
    circuit = _circuits(edges, [bool(ring[m] and not gvd[m]) for *_, m in chains])
    out = {}
    for key, labels in (('any_order', [None] * len(edges)), ('circuits_first', circuit)):
        walks = [lead + _walk(edges, dist, labels, index[p], order) for order in range(orders)]
        out[key] = {'walk': float(np.mean(walks)), 'walk_min': float(min(walks)),
                    'walk_max': float(max(walks))}
    return {**out, 'required': sum(e[2] for e in edges), 'lower_bound': cvs.lower_bound_path()}


def _walk(edges, dist, circuit, start, order):
    """One nearest-first walk from vertex ``start`` (ties broken by the seed ``order``);
    ``circuit``: each edge's curve D = delta, driven round first once reached (None: a GVD
    edge, or no such order)."""
    import random
    rng = random.Random(order)
    tie = [rng.random() for _ in edges]
    todo, reached, here, walk = set(range(len(edges))), {start}, start, 0.0
    while todo:
        # the circuit of a curve D = delta the walk stands on goes first, if undriven
        going = {circuit[k] for k in todo if circuit[k] is not None and here in edges[k][:2]}
        pool = [k for k in todo if circuit[k] in going] or todo
        best = min(((dist[here, u], tie[k], k, u, w) for k in pool
                    for u, w in (edges[k][:2], edges[k][1::-1])
                    if u in reached and np.isfinite(dist[here, u])), default=None)
        if best is None:          # the rest lies beyond what the start can reach
            break
        way, _, k, _, w = best
        walk += way + edges[k][2]
        todo.discard(k)
        reached.add(w)
        here = w
    return walk


def _circuits(edges, on_curve):
    """The curve D = delta each edge lies on (an index per connected set of curve edges;
    None for a GVD edge)."""
    parent = {}

    def root(v):
        while parent.setdefault(v, v) != v:
            v = parent[v]
        return v

    for (a, b, _), c in zip(edges, on_curve):
        if c:
            parent[root(a)] = root(b)
    return [root(a) if c else None for (a, _, _), c in zip(edges, on_curve)]


def driven_again(path: ArrayLike, within: float = 0.3, lag: float = 1.0) -> float:
    """Length of ``path`` (an (n, 2) polyline) driven a second time: each step whose end
    lies within ``within`` of a point the path passed more than ``lag`` of path length
    before (so that a step is not counted against the stretch just driven). The rest of the
    length is ground driven for the first time: on the paper planner's path, the first
    tracing of GVD edges and boundary, to be set against the floor's required length; what
    is driven again (the way back out of dead ends, to open branches and nodes) against the
    walk's ways between edges."""
    from scipy.spatial import cKDTree
    p = np.asarray(path, dtype=float).reshape(-1, 2)
    if len(p) < 2:
        return 0.0
    step = np.hypot(*np.diff(p, axis=0).T)
    at = np.concatenate(([0.0], np.cumsum(step)))
    before = np.searchsorted(at, at - lag, side='right')    # indices of points lag behind
    near = cKDTree(p).query_ball_point(p, within)
    again = np.array([bool(b) and min(idx) < b for idx, b in zip(near, before)])
    return float(step[again[1:]].sum())
