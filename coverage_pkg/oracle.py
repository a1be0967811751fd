"""A full-knowledge coverage route: how short a path that sees CVS can be (evaluation only).

The lower bound |CVS| / (2 delta) of Section VI assumes that every metre of path sweeps a
fresh strip 2 delta wide. In rooms, halls and 1.2-1.6 m corridors no path does that: a
dead-end corridor must be driven in and out, and a room's corners must be approached. To say
how much of the online planner's path / bound ratio is the planner and how much is the world,
this module plans offline, **with the true map**, a short route whose detector footprint
covers (nearly) all of CVS - an approximate watchman route:

1. viewpoints: configurations of FCS_r on a lattice (``view_step``), each with the cells of
   CVS it sees (within delta, line of sight; the same visibility as the evaluation);
2. greedy set cover of CVS by viewpoints;
3. an open tour from the start through the chosen viewpoints (geodesic distances in FCS_r,
   nearest neighbour then 2-opt and or-opt);
4. pruning: a viewpoint is dropped when what the route sees without it, along the whole path
   and not only at the viewpoints, still reaches the target fraction; then the tour is
   improved again;
5. the path is string-pulled (straight where the line stays in FCS_r) and its footprint is
   measured with a fresh :class:`CoverageAccumulator`, exactly as the planner's runs are.

Greedy set cover and local tour search give an *upper* bound on the shortest such route, not
the optimum (the watchman route problem with limited range is NP-hard). The oracle reads the
world; the planner never uses it.
"""
from __future__ import annotations

import heapq
import math
from typing import TYPE_CHECKING

import numpy as np

from coverage_pkg.cvs import CoverableSet, CoverageAccumulator

if TYPE_CHECKING:
    from coverage_pkg.world import World


def geodesic(passable: np.ndarray, sources: list) -> tuple[object, np.ndarray]:
    """MCP_Geometric on the passable cells from the ``sources`` cells; returns the engine and
    the cost-to-go array (in cells; inf where not reached)."""
    from skimage.graph import MCP_Geometric
    cost = np.where(passable, 1.0, np.inf)
    m = MCP_Geometric(cost)
    cum, _ = m.find_costs(sources)
    return m, cum


def _segment_free(passable, a, b, step=0.5):
    """True if the straight segment between cells ``a`` and ``b`` stays on passable cells."""
    n = int(math.ceil(math.hypot(b[0] - a[0], b[1] - a[1]) / step)) + 1
    rr = np.rint(np.linspace(a[0], b[0], n + 1)).astype(int)
    cc = np.rint(np.linspace(a[1], b[1], n + 1)).astype(int)
    return bool(passable[rr, cc].all())


def _string_pull(passable, cells):
    """Shortcut a grid path where the straight line stays passable (greedy, farthest first)."""
    if len(cells) <= 2:
        return list(cells)
    out = [cells[0]]
    i, last = 0, len(cells) - 1
    while i < last:
        # Farthest cell with a free straight line: gallop, then bisect up to the first failed
        # jump. Visibility along a path is not monotone, so every jump taken is checked.
        j, step = i + 1, 1
        while i + step <= last and _segment_free(passable, cells[i], cells[i + step]):
            j = i + step
            step *= 2
        lo, hi = j, min(i + step, last)
        while lo < hi:
            mid = (lo + hi + 1) // 2
            if _segment_free(passable, cells[i], cells[mid]):
                lo = mid
            else:
                hi = mid - 1
        out.append(cells[lo])
        i = lo
    return out


def _improve_tour(order, dist):
    """2-opt and or-opt on an open tour that starts at order[0] (kept fixed)."""
    order = list(order)
    improved = True
    while improved:
        improved = False
        n = len(order)
        for i in range(1, n - 1):
            for j in range(i + 1, n):
                a, b = order[i - 1], order[i]
                c = order[j]
                d = order[j + 1] if j + 1 < n else None
                old = dist[a, b] + (dist[c, d] if d is not None else 0.0)
                new = dist[a, c] + (dist[b, d] if d is not None else 0.0)
                if new < old - 1e-9:
                    order[i:j + 1] = order[i:j + 1][::-1]
                    improved = True
        n = len(order)
        for i in range(1, n):
            node = order[i]
            prev = order[i - 1]
            nxt = order[i + 1] if i + 1 < n else None
            gain = dist[prev, node] + (dist[node, nxt] - dist[prev, nxt] if nxt is not None
                                       else 0.0)
            rest = order[:i] + order[i + 1:]
            best, best_k = 0.0, None
            for k in range(1, len(rest) + 1):
                p = rest[k - 1]
                q = rest[k] if k < len(rest) else None
                add = dist[p, node] + (dist[node, q] - dist[p, q] if q is not None else 0.0)
                if gain - add > best + 1e-9:
                    best, best_k = gain - add, k
            if best_k is not None:
                order = rest[:best_k] + [node] + rest[best_k:]
                improved = True
                break
    return order


class OracleRoute:
    """Offline route through the true world that sees ``target`` of CVS (see module doc)."""

    def __init__(self, world: World, radius: float, delta: float, target: float = 0.998,
                 clearance_margin: float = 0.05, pose_step: float = 0.2) -> None:
        self.world = world
        self.cvs = CoverableSet(world, radius, delta, 0.05)
        self.acc = CoverageAccumulator(self.cvs)
        self.target = float(target)
        self.pose_step = float(pose_step)
        cvs = self.cvs
        self.passable = cvs.fcs & (cvs.clearance > radius + clearance_margin)
        self.passable[cvs.cell_of(world.start)] = True     # the start is valid by input check
        self._idx = -np.ones(cvs.mask.shape, dtype=np.int64)
        self._idx[cvs.mask] = np.arange(int(cvs.mask.sum()))
        self.n_targets = int(cvs.mask.sum())
        self._seg_cache = {}

    # ---------------------------------------------------------------- visibility

    def _sees(self, cell):
        """Indices of the CVS cells seen from the centre of grid cell ``cell``."""
        x, y = self.cvs.centers(cell[0], cell[1])
        rows, cols = self.acc.visible(float(x), float(y))
        ids = self._idx[rows, cols]
        return ids[ids >= 0]

    def _viewpoints(self, view_step):
        k = max(1, int(round(view_step / self.cvs.res)))
        lattice = np.zeros_like(self.passable)
        lattice[::k, ::k] = True
        rr, cc = np.nonzero(self.passable & lattice)
        return list(zip(rr.tolist(), cc.tolist()))

    def _set_cover(self, sets, need):
        """Lazy greedy set cover until ``need`` targets are covered."""
        covered = np.zeros(self.n_targets, dtype=bool)
        heap = [(-len(s), i) for i, s in enumerate(sets)]
        heapq.heapify(heap)
        chosen = []
        count = 0
        while heap and count < need:
            neg, i = heapq.heappop(heap)
            gain = int(np.count_nonzero(~covered[sets[i]]))
            if gain == 0:
                continue
            if heap and gain < -heap[0][0]:
                heapq.heappush(heap, (-gain, i))
                continue
            covered[sets[i]] = True
            count += gain
            chosen.append(i)
        return chosen

    # ---------------------------------------------------------------- route

    def _leg(self, a, b):
        """Seen set (target indices) and string-pulled cells of the geodesic leg a -> b."""
        key = (a, b)
        if key not in self._seg_cache:
            cells = self._engines[a].traceback(self._cells[b])
            cells = _string_pull(self.passable, cells)
            pts = self._densify(cells, self.pose_step)
            seen = np.unique(np.concatenate([self._sees(c) for c in pts] + [np.zeros(0, int)]))
            self._seg_cache[key] = (seen, cells)
        return self._seg_cache[key]

    def _densify(self, cells, step):
        """Cells every ``step`` metres along the polyline through ``cells``."""
        out = [cells[0]]
        res = self.cvs.res
        for a, b in zip(cells[:-1], cells[1:]):
            n = int(math.ceil(math.hypot(b[0] - a[0], b[1] - a[1]) * res / step))
            for t in np.linspace(0, 1, n + 1)[1:]:
                out.append((int(round(a[0] + t * (b[0] - a[0]))),
                            int(round(a[1] + t * (b[1] - a[1])))))
        return out

    def _route_seen(self, order):
        covered = np.zeros(self.n_targets, dtype=bool)
        covered[self._sees(self._cells[order[0]])] = True
        for a, b in zip(order[:-1], order[1:]):
            covered[self._leg(a, b)[0]] = True
        return int(covered.sum())

    def plan(self, view_step: float = 0.25) -> dict[str, object]:
        """Plan the route; returns a dict with the path (map frame), its length, the covered
        fraction of CVS measured along it and the viewpoints kept."""
        cvs = self.cvs
        start = cvs.cell_of(self.world.start)
        cand = self._viewpoints(view_step)
        sets = [self._sees(c) for c in cand]
        need = int(math.ceil(self.target * self.n_targets))
        chosen = self._set_cover(sets, need)
        self._cells = [start] + [cand[i] for i in chosen]
        n = len(self._cells)
        self._engines = []
        dist = np.zeros((n, n))
        for i, c in enumerate(self._cells):
            m, cum = geodesic(self.passable, [c])
            self._engines.append(m)
            for j, d in enumerate(self._cells):
                dist[i, j] = cum[d] * cvs.res
        if not np.isfinite(dist[0]).all():
            keep = [i for i in range(n) if np.isfinite(dist[0, i])]
            dist = dist[np.ix_(keep, keep)]
            self._cells = [self._cells[i] for i in keep]
            self._engines = [self._engines[i] for i in keep]
            n = len(keep)
        order = [0]
        left = set(range(1, n))
        while left:
            nxt = min(left, key=lambda j: dist[order[-1], j])
            order.append(nxt)
            left.remove(nxt)
        order = _improve_tour(order, dist)
        # Prune viewpoints the rest of the route already sees (farthest detours first).
        changed = True
        while changed:
            changed = False
            detour = []
            for k in range(1, len(order)):
                prev, node = order[k - 1], order[k]
                nxt = order[k + 1] if k + 1 < len(order) else None
                save = dist[prev, node] + (dist[node, nxt] - dist[prev, nxt] if nxt is not None
                                           else 0.0)
                detour.append((save, k))
            for save, k in sorted(detour, reverse=True):
                trial = order[:k] + order[k + 1:]
                if self._route_seen(trial) >= need:
                    # A shorter order sees other things on the way: kept only if enough.
                    better = _improve_tour(trial, dist)
                    order = better if self._route_seen(better) >= need else trial
                    changed = True
                    break
        cells = [self._cells[order[0]]]
        for a, b in zip(order[:-1], order[1:]):
            cells += self._leg(a, b)[1][1:]      # each leg string-pulled, viewpoints kept
        path = [tuple(map(float, cvs.centers(r, c))) for r, c in cells]
        length = float(sum(math.hypot(b[0] - a[0], b[1] - a[1])
                           for a, b in zip(path[:-1], path[1:])))
        check = CoverageAccumulator(cvs)
        for a, b in zip(path[:-1], path[1:]):
            m = max(1, int(math.ceil(math.hypot(b[0] - a[0], b[1] - a[1]) / 0.05)))
            for t in np.linspace(0.0, 1.0, m + 1):
                check.add_pose(a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1]))
        if len(path) == 1:
            check.add_pose(*path[0])
        return {'path': path, 'path_length': length, 'covered_fraction': check.fraction(),
                'lower_bound': cvs.lower_bound_path(), 'cvs_area': cvs.area,
                'viewpoints': [tuple(map(float, cvs.centers(*self._cells[i])))
                               for i in order[1:]]}


def oracle_route(world: World, radius: float = 0.25, delta: float = 2.0, target: float = 0.998,
                 view_step: float = 0.25) -> dict[str, object]:
    """Plan the full-knowledge route of ``world`` (see :class:`OracleRoute`)."""
    return OracleRoute(world, radius, delta, target=target).plan(view_step=view_step)
