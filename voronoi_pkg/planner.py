"""Motion planning on the simplified Voronoi diagram (section 5 of Vaca, Aranda & Thomas):
"to find a path between two points in free space, it suffices to find a path for each point
onto the diagram, and to join these points with a path that lies wholly on the diagram."

:class:`VoronoiPlanner` (planar platform, configuration ``(x, y, phi)``):

1. refuses a start or goal that is outside the domain, singular or in collision, naming the
   failing predicate (:class:`paramotion.errors.UserError`);
2. answers "no path" at once when start and goal lie in different singularity cells: the
   pure-condition determinants have different signs, so every path would cross a singularity
   (e.g. P3 above and below the base line);
3. retracts start and goal onto the diagram (:mod:`voronoi_pkg.ties`: the two smallest
   contacts tie) by rho ascent within the slice (:meth:`VoronoiPlanner.retract`);
4. searches only along diagram edges (:mod:`voronoi_pkg.diagram`): the exact straight
   pieces within each phi slice and links between diagram vertices of consecutive slices,
   with Dijkstra (length, phi weighted by ``phi_scale``) among edges keeping at least half the
   best achievable bottleneck clearance, then all; slices are computed lazily in widening
   phi windows around the start-goal arc and cached;
5. verifies every edge it uses by dense checking (rho > 0 every ``check_step`` units and
   ``check_dphi`` rad, no sign change of a pure-condition determinant), drops refused edges
   and repeats (lazy verification);
6. returns the densely sampled path (climb, diagram pieces, climb back), its
   ``on_diagram_fraction`` and clearance profile, or ``status = 'no_path'`` when the verified
   diagram graph does not connect the two retraction ends - a finite search, never a hang.

Resolution completeness: "no path" means no connection on the diagram as sampled (tie points
on an ``h`` grid, slices ``dphi`` apart, links within ``link_radius``); passages narrower than
about a grid spacing can be missed. Different singularity cells are an exact "no path".
"""
from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import breadth_first_order, dijkstra, minimum_spanning_tree

from paramotion.errors import UserError
from voronoi_pkg.diagram import (
    SliceFields,
    contact_evaluator,
    diagram_slices,
    grid_axes,
    link_slices,
    slice_fields,
)
from voronoi_pkg.ties import on_diagram

if TYPE_CHECKING:
    from voronoi_pkg.planar import PlanarModel

__all__ = ['KIND_NAMES', 'MAX_GRID_VERTICES', 'PlanResult', 'VoronoiPlanner', 'check_path',
           'densify', 'diagram_segments', 'near_diagram_fraction', 'validate_configuration']

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
    #: Length share of the path on diagram edges (phi weighted by the planner's phi_scale).
    on_diagram_fraction: float = float('nan')
    #: Kind of each waypoint segment (see ``KIND_NAMES``).
    segment_kinds: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=int))
    #: Clearance profile: ``(M, 2)`` of (arc length, rho) at every dense path sample.
    clearance: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))

    @property
    def found(self) -> bool:
        return self.status == 'ok'


def _wrap(a):
    return (a + np.pi) % (2 * np.pi) - np.pi


def unwrap_phi(points: ArrayLike) -> np.ndarray:
    """Make phi continuous along a polyline (differences taken modulo 2 pi)."""
    out = np.array(points, dtype=float, copy=True)
    if len(out) > 1:
        out[1:, 2] = out[0, 2] + np.cumsum(_wrap(np.diff(out[:, 2])))
    return out


def densify(waypoints: ArrayLike, step_xy: float = 0.05,
            step_phi: float = 0.01) -> tuple[np.ndarray, np.ndarray]:
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


def check_path(model: PlanarModel, waypoints: ArrayLike, step_xy: float = 0.05,
               step_phi: float = 0.01
               ) -> tuple[bool, float, np.ndarray, np.ndarray, np.ndarray]:
    """Dense check of a polyline in configuration space.

    Returns ``(ok, min_rho, bad_segments, samples, rho)``: rho must stay positive at every
    sample, no pure-condition determinant may change sign (a singularity is a zero set, so
    sampling rho alone could step over it) and no step may sweep the platform across a scene
    segment (:meth:`~voronoi_pkg.planar.PlanarModel.swept_hits`).
    """
    samples, seg = densify(waypoints, step_xy, step_phi)
    rho = model.rho(samples)
    signs = model.singular_signs(samples)
    bad = rho <= model.free_tol
    if signs.size:
        bad |= np.any(signs != signs[:, :1], axis=0) | np.any(signs == 0, axis=0)
    bad[1:] |= model.swept_hits(samples[:-1], samples[1:])
    bad_segments = np.unique(seg[bad])
    return (not bad.any()), float(rho.min()), bad_segments, samples, rho


def validate_configuration(model: PlanarModel, q: ArrayLike, name: str) -> None:
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


# Kinds of path pieces, for on_diagram_fraction.
RETRACTION, SLICE_PIECE, SLICE_LINK, ATTACH, OFF_ATTACH = 0, 1, 2, 3, 4
_ON_DIAGRAM = (SLICE_PIECE, SLICE_LINK, ATTACH)
KIND_NAMES = {RETRACTION: 'retraction', SLICE_PIECE: 'diagram piece (in slice)',
              SLICE_LINK: 'diagram link (between slices)', ATTACH: 'diagram piece (attach)',
              OFF_ATTACH: 'off-diagram attach'}


def _bottleneck(n_nodes, u, v, clear, s_id, g_id):
    """Largest clearance c such that edges of clearance >= c connect start and goal (the
    maximin path lies on a maximum spanning tree); 0 if they are not connected."""
    if s_id == g_id:
        return float('inf')
    if len(clear) == 0:
        return 0.0
    top = float(clear.max())
    weight = (top - clear) + 1.0   # positive: csgraph drops zero weights
    tree = minimum_spanning_tree(csr_matrix((weight, (u, v)), shape=(n_nodes, n_nodes)))
    _, pred = breadth_first_order(tree, s_id, directed=False, return_predecessors=True)
    if pred[g_id] < 0:
        return 0.0
    sym = (tree + tree.T).tocsr()
    worst = float('inf')
    node = g_id
    while node != s_id:
        p = pred[node]
        worst = min(worst, top + 1.0 - sym[p, node])
        node = p
    return worst


def near_diagram_fraction(model: PlanarModel, path: ArrayLike, delta: float,
                          phi_scale: float) -> float:
    """Length share of a dense ``path`` (phi weighted by ``phi_scale``) whose samples lie
    within ``delta`` in x or y of the diagram: a probe there has another smallest contact,
    decided by another determinant (:mod:`voronoi_pkg.ties`)."""
    path = np.asarray(path, dtype=float)
    if len(path) < 2:
        return 1.0
    probes = [model.fields(path + np.array([dx, dy, 0.0]))
              for dx, dy in ((0, 0), (delta, 0), (-delta, 0), (0, delta), (0, -delta))]
    contact = np.array([f[1] for f in probes])
    code = np.array([f[2] for f in probes])
    near = np.any((contact != contact[:1]) & (code != code[:1]), axis=0)
    d = np.diff(path, axis=0)
    length = np.sqrt(d[:, 0] ** 2 + d[:, 1] ** 2 + (phi_scale * d[:, 2]) ** 2)
    total = float(length.sum())
    return float(length[near[:-1] & near[1:]].sum() / total) if total > 0 else 1.0


def diagram_segments(result: PlanResult) -> np.ndarray:
    """The diagram edges a found path used, ``(m, 2, 3)`` pairs of configurations."""
    if not result.found:
        return np.zeros((0, 2, 3))
    w = result.waypoints
    on = np.isin(result.segment_kinds, _ON_DIAGRAM)
    return np.stack([w[:-1][on], w[1:][on]], axis=1)


class VoronoiPlanner:
    """Planner on the simplified Voronoi diagram of a planar model (see the module docs).

    ``h``: grid spacing in x, y (units) on which the diagram's tie points are found;
    ``dphi_deg``: slice spacing; ``check_step`` and ``check_dphi``: dense checking resolution;
    ``phi_scale``: length per radian in edge costs (default: the platform length);
    ``link_radius``: largest (x, y) distance of a link between diagram vertices of
    consecutive slices (default 2 h). Diagram slices are computed lazily, only where the
    search needs them, and cached for later queries (a node serves many requests).
    """

    def __init__(self, model: PlanarModel, h: float = 1.0, dphi_deg: float = 2.5,
                 check_step: float = 0.05, check_dphi: float = 0.01,
                 phi_scale: float | None = None, link_radius: float | None = None,
                 clearance_fraction: float = 0.5, max_iterations: int = 500) -> None:
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
        self.link_radius = float(link_radius if link_radius is not None else 2.0 * self.h)
        dom = model.domain
        self.xs, self.ys = grid_axes(dom, self.h)
        span = dom.phi[1] - dom.phi[0]
        if dom.periodic:
            n = max(4, int(round(2 * math.pi / math.radians(dphi_deg))))
            self.phis = dom.phi[0] + 2 * math.pi * np.arange(n) / n
        else:
            n = max(2, int(round(span / math.radians(dphi_deg))) + 1)
            self.phis = np.linspace(dom.phi[0], dom.phi[1], n)
        self.dphi = float(self.phis[1] - self.phis[0])
        size = len(self.xs) * len(self.ys) * (len(self.phis) + 2)
        if size > MAX_GRID_VERTICES:
            raise UserError(f'grid of {size:,} vertices (spacing {self.h:g}, slices '
                            f'{dphi_deg:g} deg) exceeds {MAX_GRID_VERTICES:,}; use a coarser '
                            'grid or fewer slices')
        self._fields = None
        self._slices = {}
        self._links = {}

    @property
    def base_fields(self) -> SliceFields:
        """rho, smallest contact and cell on the uniform slices' grid (computed on first
        use)."""
        if self._fields is None:
            self._fields = slice_fields(self.model, self.phis, self.xs, self.ys)
        return self._fields

    def prepare(self) -> None:
        """Compute and cache the diagram of every uniform slice and the links between
        consecutive ones (e.g. at node start-up)."""
        slices = self._uniform(range(len(self.phis)))
        pairs = list(zip(slices, slices[1:]))
        if self.model.domain.periodic:
            pairs.append((slices[-1], slices[0]))
        for a, b in pairs:
            if (id(a), id(b)) not in self._links:
                self._links[(id(a), id(b))] = link_slices(a, b, self.link_radius)

    def _uniform(self, ks):
        ks = list(ks)
        missing = [k for k in ks if k not in self._slices]
        for part in range(0, len(missing), 24):
            chunk = missing[part:part + 24]
            f = slice_fields(self.model, self.phis[chunk], self.xs, self.ys)
            for k, sl in zip(chunk, diagram_slices(self.model, f)):
                self._slices[k] = sl
        return [self._slices[k] for k in ks]

    def _cached(self):
        return {id(s) for s in self._slices.values()}

    def _slice_at(self, phi):
        """Diagram slice at orientation ``phi``: a cached uniform one if it coincides."""
        d = np.abs(_wrap(self.phis - phi)) if self.model.domain.periodic \
            else np.abs(self.phis - phi)
        k = int(np.argmin(d))
        if d[k] < 1e-9:
            return k, self._uniform([k])[0]
        f = slice_fields(self.model, np.array([phi]), self.xs, self.ys)
        return None, diagram_slices(self.model, f)[0]

    def _window(self, phi_s, phi_g, margin):
        """Uniform slice indices searched, in order along phi, and the ordering key."""
        dom = self.model.domain
        n = len(self.phis)
        full = margin is None or (dom.periodic and 2 * margin + abs(float(_wrap(phi_g - phi_s)))
                                  >= 2 * math.pi - self.dphi)
        if not dom.periodic:
            if full:
                return list(range(n)), (lambda p: p)
            lo, hi = min(phi_s, phi_g) - margin, max(phi_s, phi_g) + margin
            return [k for k in range(n) if lo <= self.phis[k] <= hi], (lambda p: p)
        if full:
            return list(range(n)), (lambda p: (p - dom.phi[0]) % (2 * math.pi))
        d = float(_wrap(phi_g - phi_s))
        lo = (phi_s if d >= 0 else phi_g) - margin
        span = abs(d) + 2 * margin

        def key(p):
            return (p - lo) % (2 * math.pi)

        ks = [k for k in range(n) if key(self.phis[k]) <= span]
        return sorted(ks, key=lambda k: key(self.phis[k])), key

    # -- retraction ----------------------------------------------------------------------------
    def retract(self, q: ArrayLike) -> tuple[np.ndarray, bool]:
        """Climb rho from ``q`` within its slice onto the diagram (:mod:`voronoi_pkg.ties`).

        In a slice every contact is piecewise affine, so rho increases fastest along the
        gradient of the determinant deciding the smallest contact. The straight climb runs
        until that changes (found by bisection): where another contact, decided by another
        determinant, becomes the smallest, the point is on the diagram and the climb ends.
        A change inside the smallest contact is not the diagram: at a valley crease (the new
        determinant still increases along the climb) the climb goes on along the new
        gradient; at a ridge inside the contact it follows the ridge while both determinants
        increase. At the domain's edge the climb slides along it. Returns ``(chain (m, 3)
        from q, on_diagram)``; rho increases along the chain.
        """
        model = self.model
        evaluate, (A, B, C) = contact_evaluator(model, q[2])
        dom = model.domain
        lo = np.array([dom.x[0], dom.y[0]])
        hi = np.array([dom.x[1], dom.y[1]])
        eps = 1e-9 * float(np.max(hi - lo))
        tol = model.free_tol
        p = np.array(q[:2], dtype=float)
        chain = [np.array(q, dtype=float)]

        def state(pts):
            vals, codes = evaluate(pts)
            i1 = np.argmin(vals, axis=0)
            return i1, codes[i1, np.arange(len(i1))], vals, codes

        def grad(code):
            key, sign = code // 2, (1.0 if code % 2 else -1.0)
            return sign * np.array([B[key], C[key]])

        def clip(g):
            g = g.copy()
            for ax in range(2):
                if (p[ax] <= lo[ax] + eps and g[ax] < 0) or (p[ax] >= hi[ax] - eps and g[ax] > 0):
                    g[ax] = 0.0
            return g

        ridge = None            # (codes of the two determinants, direction) on a ridge
        for _ in range(64):
            i1, c1, vals, codes = state(p)
            if on_diagram(vals, codes, tol)[0]:
                return np.array(chain), True
            i1, c1 = int(i1[0]), int(c1[0])
            allowed = {c1} if ridge is None else set(ridge[0])
            g = clip(grad(c1) if ridge is None else ridge[1])
            norm = float(np.hypot(*g))
            if norm <= 1e-12 * (float(np.max(np.abs(grad(c1)))) + 1.0):
                return np.array(chain), False
            d = g / norm
            with np.errstate(divide='ignore', invalid='ignore'):
                lim = np.where(d > 0, (hi - p) / d, np.where(d < 0, (lo - p) / d, np.inf))
            tmax = float(max(0.0, np.min(lim)))
            if tmax <= eps:
                return np.array(chain), False

            def changed(ts):
                j, c, _, _ = state(p + ts[:, None] * d)
                return (j != i1) | ~np.isin(c, list(allowed))

            ts = np.linspace(0.0, tmax, max(2, int(math.ceil(tmax / (self.h / 4)))) + 1)[1:]
            other = np.flatnonzero(changed(ts))
            if not len(other):
                p = np.clip(p + tmax * d, lo, hi)
                chain.append(np.r_[p, q[2]])
                continue
            t_lo = ts[other[0] - 1] if other[0] > 0 else 0.0
            t_hi = ts[other[0]]
            for _ in range(4):      # bracket shrinks 256-fold per vectorised pass
                ts = np.linspace(t_lo, t_hi, 257)[1:-1]
                change = np.flatnonzero(changed(ts))
                if len(change):
                    t_hi = ts[change[0]]
                    t_lo = ts[change[0] - 1] if change[0] > 0 else t_lo
                else:
                    t_lo = ts[-1]
            j, c2, vals, codes = state((p + t_hi * d)[None])
            j, c2 = int(j[0]), int(c2[0])
            p = p + t_lo * d
            chain.append(np.r_[p, q[2]])
            if j != i1 and c2 not in allowed:
                # Another contact became the smallest: the tie of two contacts, the diagram.
                return np.array(chain), bool(on_diagram(*evaluate(p), tol)[0])
            g2 = grad(c2)
            if g2 @ d > 0:
                ridge = None        # valley crease inside the contact: climb on
                p = p + (t_hi - t_lo) * d
                continue
            # Ridge inside the contact: follow it while both determinants increase.
            g1 = grad(c1)
            e = np.array([-(g1 - g2)[1], (g1 - g2)[0]])
            e = e if g1 @ e > 0 else -e
            if not g1 @ e > 1e-12 * float(np.hypot(*g1)) * float(np.hypot(*e)):
                return np.array(chain), False      # a peak of the contact, off the diagram
            ridge = ((c1, c2), e)
        return np.array(chain), False

    # -- search --------------------------------------------------------------------------------
    def _graph(self, slices, periodic_ring, ends):
        """Global node positions, rho and deduplicated edges (u, v, kind) of the diagram
        graph over ``slices`` (ordered along phi) plus the two retraction ends."""
        offs = np.cumsum([0] + [len(s.xyz) for s in slices])
        xyz = np.vstack([s.xyz for s in slices] + [np.zeros((0, 3))])
        node_rho = np.concatenate([s.rho for s in slices] + [np.zeros(0)])
        us, vs, kinds = [], [], []
        for i, s in enumerate(slices):
            us.append(s.edges[:, 0] + offs[i])
            vs.append(s.edges[:, 1] + offs[i])
            kinds.append(np.full(len(s.edges), SLICE_PIECE))
        pairs = list(zip(range(len(slices) - 1), range(1, len(slices))))
        if periodic_ring and len(slices) > 2:
            pairs.append((len(slices) - 1, 0))
        cached = self._cached()
        for a, b in pairs:
            cache = (id(slices[a]), id(slices[b]))
            lk = self._links.get(cache)
            if lk is None:
                lk = link_slices(slices[a], slices[b], self.link_radius)
                if cache[0] in cached and cache[1] in cached:
                    self._links[cache] = lk
            us.append(lk[:, 0] + offs[a])
            vs.append(lk[:, 1] + offs[b])
            kinds.append(np.full(len(lk), SLICE_LINK))
        end_ids = []
        for slice_index, p, on in ends:
            nid = len(xyz)
            xyz = np.vstack([xyz, p[None, :]])
            node_rho = np.r_[node_rho, self.model.rho(p)]
            end_ids.append(nid)
            s = slices[slice_index]
            near = []
            for r in (1.5 * self.h, 3 * self.h, 6 * self.h):
                near = s.tree.query_ball_point(p[:2], r)
                if near:
                    break
            near = np.asarray(near, dtype=np.int64)
            us.append(np.full(len(near), nid))
            vs.append(near + offs[slice_index])
            kinds.append(np.full(len(near), ATTACH if on else OFF_ATTACH))
        u, v, kind = np.concatenate(us), np.concatenate(vs), np.concatenate(kinds)
        n = len(xyz)
        lo_, hi_ = np.minimum(u, v), np.maximum(u, v)
        code, first = np.unique(lo_ * n + hi_, return_index=True)
        keep = lo_[first] != hi_[first]
        u, v, kind = lo_[first][keep], hi_[first][keep], kind[first][keep]
        d = xyz[v] - xyz[u]
        d[:, 2] = _wrap(d[:, 2]) * self.phi_scale
        cost = np.maximum(np.sqrt(np.sum(d * d, axis=1)), 1e-9)
        clear = np.minimum(node_rho[u], node_rho[v])
        return xyz, u, v, kind, cost, clear, end_ids

    def _search(self, xyz, u, v, kind, cost, clear, s_id, g_id, stats):
        """Lazy Dijkstra on the diagram graph: the shortest path among edges whose clearance
        is at least ``clearance_fraction`` of the best achievable bottleneck (maximin, from a
        maximum spanning tree), then, if lazy checking removed too much, among all edges
        (the threshold never costs completeness). Every edge used passes dense checking.
        Returns (node sequence, edge kinds) or None."""
        n = len(xyz)
        best = _bottleneck(n, u, v, clear, s_id, g_id)
        stats['bottleneck_rho'] = best
        for tau in ([self.clearance_fraction * best, 0.0] if best > 0 else [0.0]):
            found = self._lazy(xyz, u, v, kind, cost, clear >= tau, tau, s_id, g_id, stats)
            if found is not None:
                return found
        return None

    def _lazy(self, xyz, u, v, kind, cost, usable, floor, s_id, g_id, stats):
        """Dijkstra among ``usable`` edges; each edge of a candidate path is checked densely
        and dropped if it is not free or if rho dips below ``floor`` along it."""
        n = len(xyz)
        alive = usable.copy()
        verified = np.zeros(len(u), dtype=bool)
        # One symmetric matrix for all iterations: a dropped edge gets an infinite weight.
        eid = np.r_[np.arange(len(u)), np.arange(len(u))]
        graph = csr_matrix((eid + 1.0, (np.r_[u, v], np.r_[v, u])), shape=(n, n))
        graph.sort_indices()
        pos_eid = graph.data.astype(np.int64) - 1
        graph.data = np.where(alive[pos_eid], cost[pos_eid], np.inf)
        for _ in range(self.max_iterations):
            stats['search_iterations'] = stats.get('search_iterations', 0) + 1
            _, pred = dijkstra(graph, directed=True, indices=s_id, return_predecessors=True)
            if s_id != g_id and pred[g_id] < 0:
                return None
            seq = [g_id]
            while seq[-1] != s_id:
                seq.append(int(pred[seq[-1]]))
            seq = seq[::-1]
            edges = []
            for a, b in zip(seq[:-1], seq[1:]):
                lo_, hi_ = graph.indptr[a], graph.indptr[a + 1]
                edges.append(pos_eid[lo_ + np.searchsorted(graph.indices[lo_:hi_], b)])
            edges = np.array(edges, dtype=np.int64)
            todo = edges[~verified[edges]]
            if len(todo):
                a = xyz[u[todo]]
                b = xyz[v[todo]].copy()
                b[:, 2] = a[:, 2] + _wrap(b[:, 2] - a[:, 2])
                bad = self._bad_segments(a, b, floor)
                verified[todo] = True
                if len(bad):
                    alive[todo[bad]] = False
                    graph.data[np.isin(pos_eid, todo[bad])] = np.inf
                    stats['rejected_edges'] = stats.get('rejected_edges', 0) + len(bad)
                    continue
            return seq, kind[edges]
        raise RuntimeError('lazy search did not converge; raise max_iterations')

    def plan(self, start: ArrayLike, goal: ArrayLike,
             progress: Callable[[str], object] | None = None) -> PlanResult:
        """Plan from ``start`` to ``goal`` (each ``(x, y, phi_rad)``); see the module docs.

        The steps: a singularity certificate (no search when start and goal lie in different
        cells of the base-line singularities), retraction of both ends onto the diagram,
        search along diagram edges in widening orientation windows, assembly and dense
        verification of the path. ``progress``: optional callable ``(stage: str)``.
        """
        t0 = time.perf_counter()
        tick = progress or (lambda stage: None)
        start = np.asarray(start, dtype=float)
        goal = np.asarray(goal, dtype=float)
        validate_configuration(self.model, start, 'start')
        validate_configuration(self.model, goal, 'goal')
        stats = {}

        def result(status, reason='', **kw):
            return PlanResult(status, reason, planning_time=time.perf_counter() - t0,
                              stats=stats, **kw)

        reason = self._singularity_certificate(start, goal)
        if reason:
            stats['decided_by'] = 'singularity certificate'
            return result('no_path', reason)
        stats['decided_by'] = 'diagram search'
        tick('retract')
        chains = self._retract_ends(start, goal, stats)
        tick('slices')
        found, xyz = self._search_windows(start, goal, chains, stats, tick)
        if found is None:
            return result('no_path', 'start and goal retract onto parts of the simplified '
                          'Voronoi diagram that no verified diagram edge connects (diagram '
                          f'sampled on a {self.h:g}-unit grid in slices '
                          f'{math.degrees(self.dphi):g} deg apart)')
        tick('verify')
        return result('ok', **self._assemble(found, xyz, chains, stats))

    def _singularity_certificate(self, start, goal):
        """Why no path exists when start and goal lie on opposite sides of a base-line
        singularity (a 3x3 determinant of the base points changes sign), else ``''``."""
        model = self.model
        s_sign = model.singular_signs(start)
        g_sign = model.singular_signs(goal)
        if not np.any(s_sign != g_sign):
            return ''
        i = int(np.flatnonzero(s_sign != g_sign)[0])
        det = '[' + ' '.join(f'p{k}' for k in model.singular_keys[i]) + ']'
        return (f'start and goal are in different singularity cells: {det} is '
                f'{s_sign[i]:+.0f} at the start and {g_sign[i]:+.0f} at the goal, so every '
                f'path crosses the singularity {det} = 0')

    def _retract_ends(self, start, goal, stats):
        """The two retraction chains (rho ascent onto the diagram), each densely checked:
        ``[(start chain, on diagram), (goal chain, on diagram)]``."""
        chains = []
        for name, q in (('start', start), ('goal', goal)):
            chain, on = self.retract(q)
            ok = check_path(self.model, unwrap_phi(chain), self.check_step,
                            self.check_dphi)[0]
            if not ok:  # rho increases along the climb; failing here is a bug
                raise RuntimeError(f'{name} retraction failed dense checking')
            chains.append((chain, on))
        stats['retraction_on_diagram'] = [bool(chains[0][1]), bool(chains[1][1])]
        return chains

    def _window_slices(self, start, goal, margin, s_slice, g_slice, s_k, g_k):
        """The diagram slices of one orientation window in order along it (the start's and
        goal's own slices included), and whether the window is every slice."""
        ks, key = self._window(start[2], goal[2], margin)
        full = len(ks) == len(self.phis)
        entries = [(key(self.phis[k]), k, sl) for k, sl in zip(ks, self._uniform(ks))]
        for k, sl in ((s_k, s_slice), (g_k, g_slice)):
            if k is None or k not in ks:
                entries.append((key(sl.phi), None, sl))
        entries.sort(key=lambda e: e[0])
        slices, index = [], {}
        for e in entries:
            if id(e[2]) not in index:
                index[id(e[2])] = len(slices)
                slices.append(e[2])
        return slices, index, full

    def _search_windows(self, start, goal, chains, stats, tick):
        """Search along diagram edges in widening windows (the start-goal arc +- 2 slices,
        +- 45 deg, then every slice); returns ``(found, node positions)``."""
        model = self.model
        s_k, s_slice = self._slice_at(start[2])
        g_k, g_slice = self._slice_at(goal[2])
        found, xyz = None, None
        margins = (2 * self.dphi, max(2 * self.dphi, math.radians(45)), None)
        for stage, margin in enumerate(margins):
            slices, index, full = self._window_slices(start, goal, margin, s_slice, g_slice,
                                                      s_k, g_k)
            ring = full and model.domain.periodic
            ends = [(index[id(s_slice)], chains[0][0][-1], chains[0][1]),
                    (index[id(g_slice)], chains[1][0][-1], chains[1][1])]
            tick('search')
            xyz, u, v, kind, cost, clear, (s_id, g_id) = self._graph(slices, ring, ends)
            stats.update(stage=stage + 1, slices=len(slices), diagram_nodes=len(xyz) - 2,
                         diagram_edges=int(np.count_nonzero(kind != OFF_ATTACH)))
            found = self._search(xyz, u, v, kind, cost, clear, s_id, g_id, stats)
            # The window between the start's and goal's orientations is enough when its
            # bottleneck is not what limits the clearance: at least clearance_fraction of
            # the clearance at the two retraction ends. Otherwise (e.g. the platform must
            # turn away to pass) search all slices.
            cap = min(float(model.rho(chains[0][0][-1])), float(model.rho(chains[1][0][-1])))
            if found is not None and (full or stats['bottleneck_rho']
                                      >= self.clearance_fraction * cap):
                break
        return found, xyz

    def _assemble(self, found, xyz, chains, stats):
        """The path: the start's climb, the diagram pieces and links, the goal's climb
        reversed; densely verified; its on-diagram share and clearance profile."""
        model = self.model
        seq, kinds = found
        s_chain, g_chain = chains[0][0], chains[1][0][::-1]
        way = np.vstack([s_chain, xyz[seq[1:-1]], g_chain])
        seg_kind = np.r_[np.full(len(s_chain) - 1, RETRACTION), kinds,
                         np.full(len(g_chain) - 1, RETRACTION)]
        way = unwrap_phi(way)
        ok, min_rho, bad, samples, rho = check_path(model, way, self.check_step,
                                                    self.check_dphi)
        if not ok:  # every piece was verified; reaching this is a bug, not a no-path answer
            raise RuntimeError(f'assembled path failed dense checking at segments {bad[:5]}')
        d = np.diff(way, axis=0)
        seg_len = np.sqrt(d[:, 0] ** 2 + d[:, 1] ** 2 + (self.phi_scale * d[:, 2]) ** 2)
        total = float(seg_len.sum())
        on = float(seg_len[np.isin(seg_kind, _ON_DIAGRAM)].sum())
        stats['length_by_kind'] = {KIND_NAMES[k]: float(seg_len[seg_kind == k].sum())
                                   for k in KIND_NAMES if np.any(seg_kind == k)}
        # The same share measured on rho itself: within 0.05 units, and within one grid
        # spacing (the resolution at which the diagram is sampled), of a tie of two contacts.
        stats['on_diagram_measured'] = {
            f'within {d:g}': near_diagram_fraction(model, samples, d, self.phi_scale)
            for d in (0.05, self.h)}
        ds = np.diff(samples, axis=0)
        arc = np.r_[0.0, np.cumsum(np.sqrt(ds[:, 0] ** 2 + ds[:, 1] ** 2
                                           + (self.phi_scale * ds[:, 2]) ** 2))]
        return {'path': samples, 'waypoints': way, 'min_rho': min_rho,
                'max_rho_step': float(np.max(np.abs(np.diff(rho)))) if len(rho) > 1 else 0.0,
                'on_diagram_fraction': on / total if total > 0 else 1.0,
                'segment_kinds': seg_kind, 'clearance': np.c_[arc, rho]}

    def _bad_segments(self, a, b, floor=0.0):
        """Indices of the straight segments a[i] -> b[i] that fail dense checking (rho at or
        below ``floor`` or the free tolerance, or a pure-condition sign change)."""
        d = b - a
        nseg = np.maximum(1, np.ceil(np.maximum(np.hypot(d[:, 0], d[:, 1]) / self.check_step,
                                                np.abs(d[:, 2]) / self.check_dphi))
                          ).astype(np.int64)
        seg = np.repeat(np.arange(len(d)), nseg + 1)
        offs = np.arange(seg.size) - np.repeat(np.cumsum(nseg + 1) - (nseg + 1), nseg + 1)
        q = a[seg] + (offs / nseg[seg])[:, None] * d[seg]
        bad = self.model.rho(q) <= max(self.model.free_tol, floor)
        signs = self.model.singular_signs(q)
        if signs.size:
            first = np.repeat(np.cumsum(nseg + 1) - (nseg + 1), nseg + 1)
            bad |= np.any(signs != signs[:, first], axis=0) | np.any(signs == 0, axis=0)
        same = seg[1:] == seg[:-1]
        bad[1:] |= same & self.model.swept_hits(q[:-1], q[1:])
        return np.unique(seg[bad])
