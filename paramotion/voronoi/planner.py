"""Motion planning on the simplified Voronoi diagram (section 5 of Vaca, Aranda & Thomas):
"to find a path between two points in free space, it suffices to find a path for each point
onto the diagram, and to join these points with a path that lies wholly on the diagram."

:class:`VoronoiPlanner` (planar platform, configuration ``(x, y, phi)``):

1. refuses a start or goal that is outside the domain, singular or in collision, naming the
   failing predicate (:class:`paramotion.errors.UserError`);
2. answers "no path" at once when start and goal lie in different singularity cells: the
   pure-condition determinants have different signs, so every path would cross a singularity
   (e.g. P3 above and below the base line);
3. builds the sampled roadmap of :mod:`paramotion.voronoi.diagram` with the start's and goal's
   orientations as extra slices, retracts start and goal onto the diagram (steepest ascent of
   rho, so the retraction never approaches an obstacle), and searches the roadmap with
   Dijkstra (cost: length, phi weighted by ``phi_scale``);
4. verifies every roadmap edge it uses by dense checking (rho > 0 every ``check_step`` units
   and ``check_dphi`` rad, and no sign change of a pure-condition determinant) and replaces a
   refused edge by its next witness (lazy verification), repeating the search;
5. returns the densely sampled path, or ``status = 'no_path'`` when the roadmap holds no
   verified connection - a finite search, never a hang.

Resolution completeness: the roadmap connects two diagram vertices whenever the free sampled
grid connects them (every free grid edge maps to a roadmap edge), so "no path" means no path
through free vertices of the sampled grid whose edges pass dense checking.
"""
import math
import time
from dataclasses import dataclass, field

import numpy as np
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import breadth_first_order, dijkstra, minimum_spanning_tree

from paramotion.errors import UserError
from paramotion.voronoi.diagram import build_roadmap, grid_axes, slice_fields

__all__ = ['MAX_GRID_VERTICES', 'PlanResult', 'VoronoiPlanner', 'check_path', 'densify',
           'validate_configuration']

#: Largest sampled grid accepted (about 1.5 GB of roadmap arrays).
MAX_GRID_VERTICES = 12_000_000


@dataclass
class PlanResult:
    """Outcome of one query. ``path`` is dense: consecutive points differ by at most the check
    steps, so straight interpolation between them is what was verified."""

    status: str                       # 'ok' or 'no_path'
    reason: str = ''
    path: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    waypoints: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    min_rho: float = float('nan')
    max_rho_step: float = float('nan')
    planning_time: float = 0.0
    stats: dict = field(default_factory=dict)

    @property
    def found(self):
        return self.status == 'ok'


def _wrap(a):
    return (a + np.pi) % (2 * np.pi) - np.pi


def unwrap_phi(points):
    """Make phi continuous along a polyline (differences taken modulo 2 pi)."""
    out = np.array(points, dtype=float, copy=True)
    if len(out) > 1:
        out[1:, 2] = out[0, 2] + np.cumsum(_wrap(np.diff(out[:, 2])))
    return out


def densify(waypoints, step_xy=0.05, step_phi=0.01):
    """Samples along the polyline with |d(x, y)| <= step_xy and |d phi| <= step_phi.

    Returns ``(samples (M, 3), segment_of_sample (M,))``; phi is used as given (unwrapped).
    """
    w = np.asarray(waypoints, dtype=float)
    if len(w) == 1:
        return w.copy(), np.zeros(1, dtype=np.int64)
    d = np.diff(w, axis=0)
    n = np.maximum(1, np.ceil(np.maximum(np.hypot(d[:, 0], d[:, 1]) / step_xy,
                                         np.abs(d[:, 2]) / step_phi)).astype(np.int64))
    seg = np.repeat(np.arange(len(d)), n)
    offs = np.arange(seg.size) - np.repeat(np.cumsum(n) - n, n)
    t = (offs / n[seg])[:, None]
    samples = w[seg] + t * d[seg]
    samples = np.vstack([samples, w[-1:]])
    seg = np.r_[seg, len(d) - 1]
    return samples, seg


def check_path(model, waypoints, step_xy=0.05, step_phi=0.01):
    """Dense check of a polyline in configuration space.

    Returns ``(ok, min_rho, bad_segments, samples, rho)``: rho must stay positive at every
    sample and no pure-condition determinant may change sign (a singularity is a zero set, so
    sampling rho alone could step over it).
    """
    samples, seg = densify(waypoints, step_xy, step_phi)
    rho = model.rho(samples)
    signs = model.singular_signs(samples)
    bad = rho <= model.free_tol
    if signs.size:
        bad |= np.any(signs != signs[:, :1], axis=0) | np.any(signs == 0, axis=0)
    bad_segments = np.unique(seg[bad])
    return (not bad.any()), float(rho.min()), bad_segments, samples, rho


def validate_configuration(model, q, name):
    """Refuse a query configuration that is not finite, outside the domain, or not free."""
    q = np.asarray(q, dtype=float)
    if q.shape != (3,) or not np.all(np.isfinite(q)):
        raise UserError(f'{name}: expected three finite numbers (x, y, phi), got {q.tolist()}')
    if not model.domain.contains(q):
        d = model.domain
        raise UserError(
            f'{name} ({q[0]:g}, {q[1]:g}, {math.degrees(q[2]):g} deg) is outside the planning '
            f'domain x in [{d.x[0]:g}, {d.x[1]:g}], y in [{d.y[0]:g}, {d.y[1]:g}], phi in '
            f'[{math.degrees(d.phi[0]):g}, {math.degrees(d.phi[1]):g}] deg')
    failures = model.diagnose(q)
    if failures:
        what = '; '.join(f'{n} (rho = {v + 0.0:.4g})' for n, v in failures)
        raise UserError(f'{name} ({q[0]:g}, {q[1]:g}, {math.degrees(q[2]):g} deg) is not '
                        f'free: {what}')


class VoronoiPlanner:
    """Planner on the sampled simplified Voronoi diagram of a planar model.

    ``h``: grid spacing in x, y (units); ``dphi_deg``: slice spacing; ``check_step`` and
    ``check_dphi``: dense checking resolution; ``phi_scale``: length per radian in edge costs
    (default: the platform length). The uniform slices are computed once and reused by every
    query (a node serves many requests).
    """

    def __init__(self, model, h=1.0, dphi_deg=2.5, check_step=0.05, check_dphi=0.01,
                 phi_scale=None, clearance_fraction=0.5, max_iterations=500):
        if not (h > 0 and dphi_deg > 0 and check_step > 0 and check_dphi > 0):
            raise UserError('planner resolutions must be positive')
        self.model = model
        self.h = float(h)
        self.check_step = float(check_step)
        self.check_dphi = float(check_dphi)
        self.max_iterations = int(max_iterations)
        self.clearance_fraction = float(clearance_fraction)
        lengths = [np.linalg.norm(p) for p in model.moving.values()]
        self.phi_scale = float(phi_scale if phi_scale is not None else max(lengths + [1.0]))
        dom = model.domain
        self.xs, self.ys = grid_axes(dom, self.h)
        span = dom.phi[1] - dom.phi[0]
        if dom.periodic:
            n = max(4, int(round(2 * math.pi / math.radians(dphi_deg))))
            self.phis = dom.phi[0] + 2 * math.pi * np.arange(n) / n
        else:
            n = max(2, int(round(span / math.radians(dphi_deg))) + 1)
            self.phis = np.linspace(dom.phi[0], dom.phi[1], n)
        size = len(self.xs) * len(self.ys) * (len(self.phis) + 2)
        if size > MAX_GRID_VERTICES:
            raise UserError(f'grid of {size:,} vertices (spacing {self.h:g}, slices '
                            f'{dphi_deg:g} deg) exceeds {MAX_GRID_VERTICES:,}; use a coarser '
                            'grid or fewer slices')
        self._fields = None

    @property
    def base_fields(self):
        """Fields of the uniform slices (computed on first use)."""
        if self._fields is None:
            self._fields = slice_fields(self.model, self.phis, self.xs, self.ys)
        return self._fields

    def _slice_phi(self, phi):
        dom = self.model.domain
        if dom.periodic:
            return dom.phi[0] + (phi - dom.phi[0]) % (2 * math.pi)
        return phi

    def _fields_with(self, extra):
        """Uniform fields plus slices at the ``extra`` orientations, sorted by phi."""
        base = self.base_fields
        extra = sorted({float(self._slice_phi(p)) for p in extra})
        extra = [p for p in extra if np.min(np.abs(_wrap(base.phis - p))) > 1e-9]
        if not extra:
            return base
        more = slice_fields(self.model, np.array(extra), self.xs, self.ys)
        phis = np.r_[base.phis, more.phis]
        order = np.argsort(phis, kind='stable')
        cat = {name: np.concatenate([getattr(base, name), getattr(more, name)])[order]
               for name in ('rho', 'active', 'cell')}
        return type(base)(phis[order], self.xs, self.ys, cat['rho'], cat['active'],
                          cat['cell'], base.tol)

    def _connect(self, roadmap, q):
        """Retract ``q`` onto the diagram: a verified straight move to a nearby free grid
        vertex of its own slice, then that vertex's steepest-ascent chain. Returns
        ``(root, waypoints from q to the root)`` or ``(None, None)``."""
        for c in roadmap.nearest_vertices(q, k=9):
            chain = roadmap.chain(c)
            pts = unwrap_phi(np.vstack([q[None, :], roadmap.position(chain)]))
            ok = check_path(self.model, pts, self.check_step, self.check_dphi)[0]
            if ok:
                return chain[-1], pts
        return None, None

    def plan(self, start, goal, progress=None):
        """Plan from ``start`` to ``goal`` (each ``(x, y, phi_rad)``); see the module docs.

        ``progress``: optional callable ``(stage: str)`` for progress reporting.
        """
        t0 = time.perf_counter()
        tick = progress or (lambda stage: None)
        model = self.model
        start = np.asarray(start, dtype=float)
        goal = np.asarray(goal, dtype=float)
        validate_configuration(model, start, 'start')
        validate_configuration(model, goal, 'goal')
        stats = {}

        def result(status, reason='', **kw):
            return PlanResult(status, reason, planning_time=time.perf_counter() - t0,
                              stats=stats, **kw)

        s_sign = model.singular_signs(start)
        g_sign = model.singular_signs(goal)
        if np.any(s_sign != g_sign):
            i = int(np.flatnonzero(s_sign != g_sign)[0])
            key = model.singular_keys[i]
            det = '[' + ' '.join(f'p{k}' for k in key) + ']'
            return result('no_path', f'start and goal are in different singularity cells: '
                          f'{det} is {s_sign[i]:+.0f} at the start and {g_sign[i]:+.0f} at '
                          f'the goal, so every path crosses the singularity {det} = 0')

        tick('slices')
        fields = self._fields_with([start[2], goal[2]])
        tick('roadmap')
        rm = build_roadmap(fields, model.domain.periodic, self.phi_scale)
        n = rm.n_vertices
        stats.update(slices=int(len(fields.phis)), grid_vertices=n,
                     free_vertices=int(np.count_nonzero(fields.free)),
                     diagram_vertices=int(np.count_nonzero(rm.node_mask)),
                     roadmap_edges=int(len(rm.pair_lo)))
        tick('retract')
        s_root, s_pts = self._connect(rm, start)
        g_root, g_pts = self._connect(rm, goal)
        for name, root in (('start', s_root), ('goal', g_root)):
            if root is None:
                raise UserError(f'{name} is free but too close to an obstacle to reach the '
                                f'sampling grid (spacing {self.h:g}); use a finer grid')
        tick('search')
        nodes, inv = np.unique(np.r_[rm.pair_lo, rm.pair_hi, s_root, g_root],
                               return_inverse=True)
        m = len(rm.pair_lo)
        lo_id, hi_id = inv[:m], inv[m:2 * m]
        s_id, g_id = inv[2 * m], inv[2 * m + 1]
        edge_of = csr_matrix((np.r_[np.arange(m), np.arange(m)] + 1,
                              (np.r_[lo_id, hi_id], np.r_[hi_id, lo_id])),
                             shape=(len(nodes), len(nodes)))
        ptr = rm.pair_start[:-1].copy()
        alive = np.ones(m, dtype=bool)
        verified = np.zeros(m, dtype=bool)
        cost = np.maximum(rm.witness_cost(ptr), 1e-9)
        clear = rm.wit_clearance[ptr].copy()
        bottleneck = self._bottleneck(len(nodes), lo_id, hi_id, clear, s_id, g_id)
        stats['bottleneck_rho'] = bottleneck
        rejected, iterations = 0, 0
        middle = None
        if s_root == g_root:
            middle = []
        # First search among edges keeping at least clearance_fraction of the best achievable
        # clearance (the maximin value on the diagram); then, if lazy checking removed too
        # much, among all edges: the threshold never costs completeness.
        thresholds = [self.clearance_fraction * bottleneck, 0.0] if bottleneck > 0 else []
        for tau in thresholds:
            while middle is None and iterations < self.max_iterations:
                iterations += 1
                e = np.flatnonzero(alive & (clear >= tau))
                graph = csr_matrix((np.r_[cost[e], cost[e]],
                                    (np.r_[lo_id[e], hi_id[e]], np.r_[hi_id[e], lo_id[e]])),
                                   shape=(len(nodes), len(nodes)))
                _, pred = dijkstra(graph, directed=True, indices=s_id,
                                   return_predecessors=True)
                if pred[g_id] < 0:
                    break
                seq = [g_id]
                while seq[-1] != s_id:
                    seq.append(pred[seq[-1]])
                seq = seq[::-1]
                pieces, edges = [], []
                for a, b in zip(seq[:-1], seq[1:]):
                    ei = int(edge_of[a, b]) - 1
                    u, v = rm.wit_u[ptr[ei]], rm.wit_v[ptr[ei]]
                    if nodes[a] != rm.pair_lo[ei]:
                        u, v = v, u
                    verts = rm.chain(u)[::-1] + rm.chain(v)
                    pieces.append(unwrap_phi(rm.position(verts)))
                    edges.append(ei)
                todo = [i for i, ei in enumerate(edges) if not verified[ei]]
                failed = []
                if todo:
                    # Check all unverified edges at once, then map bad segments back.
                    bounds = np.cumsum([0] + [len(pieces[i]) - 1 for i in todo])
                    bad = self._bad_segments(np.vstack([pieces[i][:-1] for i in todo]),
                                             np.vstack([pieces[i][1:] for i in todo]))
                    owner = np.searchsorted(bounds, bad, side='right') - 1
                    failed = sorted({todo[o] for o in owner})
                    verified[[edges[i] for i in todo]] = True
                if not failed:
                    middle = pieces
                    break
                for i in failed:
                    ei = edges[i]
                    verified[ei] = False
                    rejected += 1
                    ptr[ei] += 1
                    if ptr[ei] >= rm.pair_start[ei + 1]:
                        alive[ei] = False
                    else:
                        cost[ei] = max(float(rm.witness_cost(ptr[ei])), 1e-9)
                        clear[ei] = rm.wit_clearance[ptr[ei]]
        stats.update(search_iterations=iterations, rejected_witnesses=rejected)
        if middle is None:
            if iterations >= self.max_iterations:
                raise RuntimeError('lazy search did not converge; raise max_iterations')
            return result('no_path', 'the start and goal retract to parts of the simplified '
                          'Voronoi diagram that no verified roadmap edge connects (grid '
                          f'{self.h:g} units, slices '
                          f'{math.degrees(2 * math.pi / len(self.phis)):g} deg)')
        tick('verify')
        way = [s_pts] + [p[1:] for p in middle] + [g_pts[::-1][1:]]
        way = unwrap_phi(np.vstack(way))
        keep = np.r_[True, np.any(np.abs(np.diff(way, axis=0)) > 1e-12, axis=1)]
        way = way[keep]
        ok, min_rho, bad, samples, rho = check_path(model, way, self.check_step, self.check_dphi)
        if not ok:  # every piece was verified; reaching this is a bug, not a no-path answer
            raise RuntimeError(f'assembled path failed dense checking at segments {bad[:5]}')
        return result('ok', path=samples, waypoints=way, min_rho=min_rho,
                      max_rho_step=float(np.max(np.abs(np.diff(rho)))) if len(rho) > 1 else 0.0)

    @staticmethod
    def _bottleneck(n_nodes, lo_id, hi_id, clear, s_id, g_id):
        """Largest clearance c such that edges of clearance >= c connect start and goal (the
        maximin path lies on a maximum spanning tree); 0 if they are not connected."""
        if s_id == g_id:
            return float('inf')
        if len(clear) == 0:
            return 0.0
        top = float(clear.max())
        weight = (top - clear) + 1.0   # positive: csgraph drops zero weights
        graph = csr_matrix((weight, (lo_id, hi_id)), shape=(n_nodes, n_nodes))
        tree = minimum_spanning_tree(graph)
        order, pred = breadth_first_order(tree, s_id, directed=False,
                                          return_predecessors=True)
        if g_id != s_id and pred[g_id] < 0:
            return 0.0
        sym = (tree + tree.T).tocsr()
        worst = float('inf')
        node = g_id
        while node != s_id:
            p = pred[node]
            worst = min(worst, top + 1.0 - sym[p, node])
            node = p
        return worst

    def _bad_segments(self, a, b):
        """Indices of the straight segments a[i] -> b[i] that fail dense checking."""
        d = b - a
        nseg = np.maximum(1, np.ceil(np.maximum(np.hypot(d[:, 0], d[:, 1]) / self.check_step,
                                                np.abs(d[:, 2]) / self.check_dphi))
                          ).astype(np.int64)
        seg = np.repeat(np.arange(len(d)), nseg + 1)
        offs = np.arange(seg.size) - np.repeat(np.cumsum(nseg + 1) - (nseg + 1), nseg + 1)
        q = a[seg] + (offs / nseg[seg])[:, None] * d[seg]
        bad = self.model.rho(q) <= self.model.free_tol
        signs = self.model.singular_signs(q)
        if signs.size:
            first = np.repeat(np.cumsum(nseg + 1) - (nseg + 1), nseg + 1)
            bad |= np.any(signs != signs[:, first], axis=0) | np.any(signs == 0, axis=0)
        return np.unique(seg[bad])
