"""FindUncoveredNode(N) of Algorithm 1 and the path to x(n) along the robot's traced paths.

The uncovered node nearest along the traced paths is chosen; the way there runs along the
robot's own path (:class:`TracedPaths`: a sample joins another when the segment between them
lies in the free disk the ring measured there). Where that way runs back along a traced GVD
edge, the robot follows the edge by the GVD control law.
"""
from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from coverage_pkg.paper.graph_nodes import Node


class TracedPaths:
    """The robot's own path as a roadmap for transit (Algorithm 1: 'find a path ... in (N, E)').

    Samples every ``step`` m carry the distance ``D`` the ring measured there; two samples are
    joined when they are closer than ``min(D_i, D_j) - clearance`` (the segment then lies in a
    disk the ring saw free), and consecutive samples always. The joins are made when a sample
    is added (among the samples within ``hop``), so a transit plan is one shortest-path search
    over a fixed sparse graph.
    """

    def __init__(self, clearance: float, step: float = 0.3, bucket: float = 1.5,
                 hop: float = 1.5):
        self.clear, self.step, self.bucket, self.hop = clearance, step, bucket, hop
        self.xy, self.d, self.grid = [], [], {}
        self._i, self._j, self._w = [], [], []
        self._csr = None

    def add(self, x: float, y: float, d: float) -> None:
        if self.xy and math.dist(self.xy[-1], (x, y)) < self.step:
            return
        k = len(self.xy)
        for j in self._near_point((x, y), self.hop + self.clear):
            step = math.dist(self.xy[j], (x, y))
            if step <= min(d, self.d[j], self.hop + self.clear) - self.clear or \
                    (j == k - 1 and step <= self.hop):
                self._i.append(k)
                self._j.append(j)
                self._w.append(max(step, 1e-6))
        self.xy.append((x, y))
        self.d.append(d)
        key = (int(x // self.bucket), int(y // self.bucket))
        self.grid.setdefault(key, []).append(k)
        self._csr = None

    def nearest(self, xy: Sequence[float]) -> int | None:
        for reach in (1.0, 3.0, 10.0, 1e9):
            best = None
            for j in (self._near_point(xy, reach) if reach < 1e9 else range(len(self.xy))):
                dd = math.dist(self.xy[j], xy)
                if dd <= reach and (best is None or dd < best[0]):
                    best = (dd, j)
            if best:
                return best[1]
        return None

    def back_index(self, length: float) -> int | None:
        """Index of the latest sample at least ``length`` m back along the path from its
        last one (None when the path is shorter)."""
        run = 0.0
        for j in range(len(self.xy) - 1, 0, -1):
            run += math.dist(self.xy[j], self.xy[j - 1])
            if run >= length:
                return j - 1
        return None

    def passes(self, xy: Sequence[float], within: float, before: int | None = None) -> bool:
        """A sample (of the first ``before``, if given) lies within ``within`` of ``xy``."""
        end = len(self.xy) if before is None else before
        return any(j < end and math.dist(self.xy[j], xy) < within
                   for j in self._near_point(xy, within))

    def _near_point(self, xy, reach):
        k = int(math.ceil(reach / self.bucket))
        bx, by = int(xy[0] // self.bucket), int(xy[1] // self.bucket)
        for gx in range(bx - k, bx + k + 1):
            for gy in range(by - k, by + k + 1):
                yield from self.grid.get((gx, gy), ())

    def distances(self, src: int) -> dict:
        """Path length along the roadmap from sample ``src`` to every sample reached."""
        dist, _ = self._dijkstra(src)
        ok = np.flatnonzero(np.isfinite(dist))
        return dict(zip(ok.tolist(), dist[ok].tolist()))

    def route(self, src: int, dst: int) -> list:
        """Waypoints from sample ``src`` to sample ``dst`` (empty if not connected)."""
        dist, prev = self._dijkstra(src)
        if not np.isfinite(dist[dst]):
            return []
        out = [dst]
        while out[-1] != src:
            out.append(int(prev[out[-1]]))
        return [self.xy[i] for i in reversed(out)]

    def _dijkstra(self, src):
        from scipy.sparse import coo_matrix
        from scipy.sparse.csgraph import dijkstra
        n = len(self.xy)
        if self._csr is None:
            self._csr = coo_matrix((self._w, (self._i, self._j)), shape=(n, n)).tocsr()
        return dijkstra(self._csr, directed=False, indices=src, return_predecessors=True)


class FindUncoveredNode:
    """Mixin of :class:`coverage_pkg.algorithm1.PaperPlanner`: the next node and the way to it."""

    def find_uncovered_node(self) -> Node | None:
        """FindUncoveredNode(N): the uncovered node nearest along the traced paths. A narrow
        node all of whose open branches run along GVD edges already traced is covered."""
        for n in self.nodes:
            if not n.covered and n.kind == 'narrow' and n.branches and \
                    not self._open_branches(n):
                n.covered = True
                n.closed_by = self._record(self.t_sweep or 0.0, 'node_covered', n.anchor,
                                           f'narrow node {n.id}: its GVD edges are traced')
        cands = [n for n in self.nodes if not n.covered]
        if not cands:
            return None
        cost = self._path_costs([self._resume_point(n) for n in cands])
        return min(zip(cost, [n.id for n in cands], cands))[2]

    @staticmethod
    def _resume_point(n):
        """Where covering ``n`` goes on: x(n), or where its boundary circuit was suspended
        (switch ``cusp_detour``)."""
        held = next((c['suspended'][0] for c in n.circuits if 'suspended' in c), None)
        return n.anchor if held is None else held

    def _path_costs(self, points):
        """Length of the way to each of ``points`` along the traced paths (the roadmap's
        shortest path to the sample nearest each, plus the straight rest)."""
        src = self.paths.nearest(self.pose[:2])
        if src is None:
            return [math.dist(self.pose[:2], q) for q in points]
        dist = self.paths.distances(src)
        out = []
        for q in points:
            j = self.paths.nearest(q)
            out.append(dist.get(j, 1e6) + math.dist(self.paths.xy[j], q))
        return out

    def _go_to(self, xy, then):
        """Transit along the traced paths to ``xy``; ``then`` is the mode after arrival."""
        if math.dist(self.pose[:2], xy) < 0.3:
            self.mode = then
            return
        src, dst = self.paths.nearest(self.pose[:2]), self.paths.nearest(xy)
        route = self.paths.route(src, dst) if src is not None and dst is not None else []
        self.route = route + [tuple(xy)]
        self.mode, self.task['after'] = 'transit', then

    def _transit_step(self):
        """One step of the path to x(n) along the traced paths. Where the way runs along a
        GVD edge (narrow space, the two closest echoes equal, the edge's tangent along the
        way ahead), the robot follows that edge back by the GVD control law; elsewhere it
        drives straight to the next waypoint."""
        self._law = None
        if len(self.route) > 1:               # passed: the nearest of the next waypoints
            near = min(range(min(len(self.route), 8)),
                       key=lambda i: math.dist(self.pose[:2], self.route[i]))
            del self.route[:near]
        while self.route and math.dist(self.pose[:2], self.route[0]) < 0.2:
            self.route.pop(0)
        if not self.route:
            self.mode = self.task.pop('after', None)
            return None
        v = self._retrace_velocity()
        if v is not None:
            self._law = 'gvd'
            return v
        v = self._wall_velocity()
        if v is not None:
            self._law = 'boundary'
            return v
        return self._towards(self.route[0], self.cfg.max_speed)

    def _goal_ahead(self):
        """Unit vector to the route's point ~1 m ahead; None when that is within 0.5 m."""
        goal = next((q for q in self.route if math.dist(q, self.pose[:2]) > 1.0),
                    self.route[-1])
        w = np.array(goal) - np.array(self.pose[:2])
        return None if np.linalg.norm(w) < 0.5 else w / np.linalg.norm(w)

    def _wall_velocity(self):
        """Boundary following at D = delta towards the route's point ~1 m ahead, where the
        way runs along a single closest obstacle at D = delta (a boundary circuit driven
        back); None elsewhere."""
        if len(self.mins) < 1 or len(self.route) < 2 or abs(self.D - self.det) > 0.15:
            return None
        d, a = self.mins[0]
        if len(self.mins) > 1 and self.mins[1][0] - d < 2 * self.cfg.event_tolerance:
            return None                        # two closest obstacles: a corner, a cusp
        w = self._goal_ahead()
        if w is None:
            return None
        nrm = np.array([math.cos(a), math.sin(a)])
        tang = np.array([-nrm[1], nrm[0]])
        if tang @ w < 0:
            tang = -tang
        if tang @ w < math.cos(math.radians(self.cfg.retrace_angle)) or self._behind(tang):
            return None
        v = tang * self.cfg.max_speed + np.clip(2.0 * (d - self.det), -1.0, 1.0) * nrm
        return v if v @ w >= 0.7 * self.cfg.max_speed else None

    def _retrace_velocity(self):
        """GVD following towards the route's point ~1 m ahead; None off the GVD, or where
        the edge's tangent does not lead there (a junction, a turn of the way)."""
        if self.D > self.det or len(self.gvd_mins) < 2 or len(self.route) < 2:
            return None
        (d1, a1), (d2, a2) = self.gvd_mins[:2]
        if abs(d1 - d2) > self.cfg.event_tolerance * 2:
            return None
        n1 = np.array([math.cos(a1), math.sin(a1)])
        n2 = np.array([math.cos(a2), math.sin(a2)])
        diff = n1 - n2
        if np.linalg.norm(diff) < 1.0:         # the two obstacles not on either side
            return None
        tang = np.array([-diff[1], diff[0]]) / np.linalg.norm(diff)
        w = self._goal_ahead()
        if w is None:
            return None
        if tang @ w < 0:
            tang = -tang
        if tang @ w < math.cos(math.radians(self.cfg.retrace_angle)) or self._behind(tang):
            return None
        v = tang * self.cfg.max_speed + diff / np.linalg.norm(diff) * (d1 - d2) * 2.0
        return v if v @ w >= 0.7 * self.cfg.max_speed else None

    def _behind(self, tang):
        """The route's next waypoint lies behind the way ``tang`` leads (more than 0.2 m):
        driven by the law, the robot would never reach it, nor come nearer the ones after it
        (a tug of war between the law and the waypoint, next to a cusp); it is driven to
        straight."""
        return float((np.asarray(self.route[0]) - np.asarray(self.pose[:2])) @ tang) < -0.2

    def _towards(self, xy, speed):
        d = np.array(xy) - np.array(self.pose[:2])
        norm = float(np.hypot(*d))
        return d / norm * min(speed, 2.0 * norm + 0.2) if norm > 1e-9 else np.zeros(2)
