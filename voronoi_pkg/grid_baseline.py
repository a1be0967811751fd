"""A clearance-weighted grid planner and the Euclidean clearance of a planar path: the
comparison for the planner on the simplified Voronoi diagram (ours; not in the paper).

:class:`ClearanceGridPlanner` searches the free vertices of the same (x, y, phi) grid the
diagram planner samples its diagram on (:func:`voronoi_pkg.diagram.grid_axes`, the same
slices): 8-neighbours within a slice and the same (x, y) in the next slice, both ends free and
in one singularity cell. An edge costs its length (phi weighted by ``phi_scale``) times
``1 + weight * rho_ref / rho``, where ``rho`` is the smaller rho of its two ends and
``rho_ref`` the median rho of the free vertices: short paths that keep away from the
obstacles in the paper's own measure. Start and goal join the nearest free vertex of their
slice that a densely checked straight motion reaches; the path is checked densely like the
diagram planner's (lazy: failing edges are dropped and the search repeats).

:func:`segment_clearance` is plain geometry (no determinants): the Euclidean distance between
the platform segment P3P4 and the nearest fixed scene segment (base, boundary and obstacle
edges). No ROS imports.
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import dijkstra

from voronoi_pkg.diagram import grid_axes, shifted_pairs, slice_fields
from voronoi_pkg.planner import check_path, unwrap_phi, validate_configuration

if TYPE_CHECKING:
    from voronoi_pkg.planar import PlanarModel

__all__ = ['ClearanceGridPlanner', 'GridPlanResult', 'segment_clearance']


def _point_segment(p, a, b):
    ab = b - a
    den = np.maximum(np.sum(ab * ab, axis=-1), 1e-300)
    t = np.clip(np.sum((p - a) * ab, axis=-1) / den, 0.0, 1.0)
    return np.hypot(*np.moveaxis(p - a - t[..., None] * ab, -1, 0))


def segment_clearance(model: PlanarModel, path: ArrayLike) -> np.ndarray:
    """Euclidean distance between the platform segment and the nearest fixed scene segment at
    every configuration of ``path`` (M, 3); 0 where they touch or cross."""
    path = np.atleast_2d(np.asarray(path, dtype=float))
    pts = model.points(path)
    moving = sorted(model.moving)
    p3, p4 = pts[moving[0]], pts[moving[-1]]
    out = np.full(len(path), np.inf)
    for a, b in model.segments.values():
        if a not in model.fixed or b not in model.fixed:
            continue
        a, b = model.fixed[a], model.fixed[b]
        A, B = np.broadcast_to(a, p3.shape), np.broadcast_to(b, p3.shape)
        d = np.minimum.reduce([_point_segment(p3, A, B), _point_segment(p4, A, B),
                               _point_segment(A, p3, p4), _point_segment(B, p3, p4)])
        r, s = p4 - p3, b - a
        den = r[:, 0] * s[1] - r[:, 1] * s[0]
        qp = a - p3
        with np.errstate(divide='ignore', invalid='ignore'):
            t = (qp[:, 0] * s[1] - qp[:, 1] * s[0]) / den
            u = (qp[:, 0] * r[:, 1] - qp[:, 1] * r[:, 0]) / den
        d[(den != 0) & (t >= 0) & (t <= 1) & (u >= 0) & (u <= 1)] = 0.0
        out = np.minimum(out, d)
    return out


@dataclass
class GridPlanResult:
    status: str
    reason: str = ''
    path: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    min_rho: float = float('nan')
    planning_time: float = 0.0
    stats: dict = field(default_factory=dict)

    @property
    def found(self) -> bool:
        return self.status == 'ok'


class ClearanceGridPlanner:
    """Dijkstra on the free grid with clearance-weighted edge costs (see the module docs)."""

    def __init__(self, model: PlanarModel, h: float = 1.0, dphi_deg: float = 2.5,
                 weight: float = 1.0, check_step: float = 0.05, check_dphi: float = 0.01,
                 phi_scale: float | None = None, max_iterations: int = 200) -> None:
        self.model = model
        self.h = float(h)
        self.weight = float(weight)
        self.check_step, self.check_dphi = float(check_step), float(check_dphi)
        self.max_iterations = int(max_iterations)
        lengths = [np.linalg.norm(p) for p in model.moving.values()]
        self.phi_scale = float(phi_scale if phi_scale is not None else max(lengths + [1.0]))
        dom = model.domain
        self.xs, self.ys = grid_axes(dom, self.h)
        if dom.periodic:
            n = max(4, int(round(2 * math.pi / math.radians(dphi_deg))))
            self.phis = dom.phi[0] + 2 * math.pi * np.arange(n) / n
        else:
            n = max(2, int(round((dom.phi[1] - dom.phi[0]) / math.radians(dphi_deg))) + 1)
            self.phis = np.linspace(dom.phi[0], dom.phi[1], n)

    def _graph(self, f):
        shape = f.rho.shape
        idx = np.arange(f.rho.size).reshape(shape)
        free = f.free
        rho_ref = float(np.median(f.rho[free]))
        us, vs, ls = [], [], []
        dphi = float(self.phis[1] - self.phis[0])
        steps = [((slice(None),) + a[1:], (slice(None),) + b[1:], self.h * math.hypot(dx, dy))
                 for dy, dx in ((0, 1), (1, 0), (1, 1), (1, -1))
                 for a, b in [shifted_pairs(shape, dy, dx)]]
        steps.append(((slice(0, -1),), (slice(1, None),), self.phi_scale * dphi))
        if self.model.domain.periodic:
            steps.append(((slice(-1, None),), (slice(0, 1),), self.phi_scale * dphi))
        for a, b, length in steps:
            ok = free[a] & free[b] & (f.cell[a] == f.cell[b])
            us.append(idx[a][ok])
            vs.append(idx[b][ok])
            ls.append(np.full(int(ok.sum()), length))
        u, v, length = np.concatenate(us), np.concatenate(vs), np.concatenate(ls)
        rho = np.minimum(f.rho.ravel()[u], f.rho.ravel()[v])
        cost = length * (1.0 + self.weight * rho_ref / rho)
        return u, v, cost

    def _vertex(self, k, j, i):
        return np.array([self.xs[i], self.ys[j], self.phis[k]])

    def _join(self, f, q):
        """Flat index of the nearest free grid vertex of q's nearest slice that a checked
        straight motion from q reaches, or None."""
        dom = self.model.domain
        dk = np.abs((self.phis - q[2] + math.pi) % (2 * math.pi) - math.pi) \
            if dom.periodic else np.abs(self.phis - q[2])
        k = int(np.argmin(dk))
        jj, ii = np.meshgrid(np.arange(len(self.ys)), np.arange(len(self.xs)), indexing='ij')
        d = np.hypot(self.xs[ii] - q[0], self.ys[jj] - q[1])
        for flat in np.argsort(d, axis=None)[:24]:
            j, i = np.unravel_index(flat, d.shape)
            if not f.free[k, j, i]:
                continue
            v = self._vertex(k, j, i)
            if check_path(self.model, unwrap_phi(np.stack([q, v])), self.check_step,
                          self.check_dphi)[0]:
                return int(np.ravel_multi_index((k, j, i), f.rho.shape))
        return None

    def plan(self, start: ArrayLike, goal: ArrayLike) -> GridPlanResult:
        """Shortest clearance-weighted path from ``start`` to ``goal`` on the free grid."""
        t0 = time.perf_counter()
        model = self.model
        start, goal = np.asarray(start, dtype=float), np.asarray(goal, dtype=float)
        validate_configuration(model, start, 'start')
        validate_configuration(model, goal, 'goal')
        f = slice_fields(model, self.phis, self.xs, self.ys)
        u, v, cost = self._graph(f)
        n = f.rho.size
        stats = {'grid_vertices': int(f.free.sum()), 'grid_edges': len(u)}

        def result(status, reason='', **kw):
            return GridPlanResult(status, reason, planning_time=time.perf_counter() - t0,
                                  stats=stats, **kw)

        s_id, g_id = self._join(f, start), self._join(f, goal)
        if s_id is None or g_id is None:
            return result('no_path', 'start or goal reaches no free grid vertex')
        alive = np.ones(len(u), dtype=bool)
        coords = np.stack(np.unravel_index(np.arange(n), f.rho.shape), axis=1)
        for _ in range(self.max_iterations):
            e = np.flatnonzero(alive)
            graph = csr_matrix((cost[e], (u[e], v[e])), shape=(n, n))
            _, pred = dijkstra(graph, directed=False, indices=s_id, return_predecessors=True)
            if s_id != g_id and pred[g_id] < 0:
                return result('no_path', 'start and goal are not connected on the free grid')
            seq = [g_id]
            while seq[-1] != s_id:
                seq.append(int(pred[seq[-1]]))
            seq = seq[::-1]
            nodes = np.array([self._vertex(*coords[s]) for s in seq])
            way = unwrap_phi(np.vstack([start, nodes, goal]))
            ok, min_rho, bad, samples, _ = check_path(model, way, self.check_step,
                                                      self.check_dphi)
            if ok:
                return result('ok', path=samples, min_rho=min_rho)
            # Drop the failing grid edges (segments 1..len(seq)-1 of the waypoints).
            lo_, hi_ = np.minimum(u, v), np.maximum(u, v)
            drop = []
            for b in bad:
                if 1 <= b < len(seq):
                    a_, b_ = sorted((seq[b - 1], seq[b]))
                    drop.append(np.flatnonzero((lo_ == a_) & (hi_ == b_)))
            if not drop:
                return result('no_path', 'the path to or from the grid fails dense checking')
            alive[np.concatenate(drop)] = False
        return result('no_path', 'lazy search did not converge')
