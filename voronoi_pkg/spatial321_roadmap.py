"""Retraction onto the simplified Voronoi diagram of the 3-2-1 platform and a roadmap whose
edges run along it (section 5 of Vaca, Aranda & Thomas, after Canny & Donald).

The diagram is the one of :mod:`voronoi_pkg.ties`, shared with the planar planner: poses
where the two smallest *contacts* tie, counting two contacts decided by the same signed
determinant as one feature. The contacts are the fused factors of
:class:`~voronoi_pkg.spatial321.Spatial321Model` (children of rho's root min node) followed
by the planning bounds and leg-length margins, which the 3-2-1 model adds as contacts (the
planar model has neither). The configuration space is 6-D, so the diagram (a 5-D set) is not
built slice by slice as in :mod:`voronoi_pkg.diagram`; it is reached and followed pointwise:

* :func:`tie_measure`: the two smallest distinct contacts, their gap and the distance to their
  tie set, first order: ``gap / |grad(f2 - f1)|`` in the metric ``(m, m, m, s rad, s rad,
  s rad)`` with ``s = angle_scale``. Determinants are affine in position at a fixed
  orientation, so the estimate is exact for moves in position.
* :func:`retract`: steepest ascent of rho. At each step the gradient of the smallest contact
  (forward differences of its deciding determinant), then a line search along it that stops
  where another contact becomes the smallest (doubling, then bisection onto the tie);
  repeated until the pose is within ``tie_tol`` of a tie. rho grows at every accepted step.
* :func:`project_to_tie`: Newton steps on ``f2 - f1 = 0`` (rho need not grow), with
  :func:`retract` for the poses that do not converge; used to trace edges.
* :class:`DiagramRoadmapPlanner`: deterministic (scrambled Halton) samples in the start's
  singularity cell are retracted onto the diagram together with start and goal; each node's
  ``k`` nearest nodes (scaled 6-D distance) are candidate edges. A lazy Dijkstra search takes
  the shortest candidate path and, for its edges not yet tested (plus up to ``batch_edges``
  untested edges at its nodes), *traces* them (:meth:`~DiagramRoadmapPlanner.trace`: probes
  every ``probe_step`` along the chord projected onto the tie set, midpoints of remaining gaps
  projected and inserted for up to three rounds; refused if a projection misses the tie set or
  a gap over ``max_gap`` remains) and checks the traced polylines densely (``check_step`` m,
  ``check_dangle`` rad: rho > 0, no singularity sign change, no leg passing through a leg);
  refused edges are dropped and the search repeats. An edge is dropped only after it fails,
  so "no path" is the answer of the fully traced roadmap: start and goal retractions lie in
  different connected components of it. The path found is shortened along the diagram
  (:meth:`~DiagramRoadmapPlanner._shortcut`: traced jumps to later path nodes that pass the
  dense check), assembled with the two retraction chains and checked densely again; its
  share within ``diagram_tol`` of a tie is reported
  (:meth:`~DiagramRoadmapPlanner.path_on_diagram`).

No ROS imports.
"""
from __future__ import annotations

import time
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import dijkstra
from scipy.spatial import cKDTree

from paramotion.errors import UserError
from voronoi_pkg.predicates import bracket4
from voronoi_pkg.spatial321 import (
    bad_samples,
    check_path6,
    densify6,
    validate_pose,
)
from voronoi_pkg.ties import two_smallest

if TYPE_CHECKING:
    from voronoi_pkg.spatial321 import Spatial321Model

__all__ = ['DiagramRoadmapPlanner', 'SpatialPlanResult', 'project_to_tie', 'retract',
           'tie_measure']


def _leaf_gradients(model, q, codes, h=1e-6):
    """Forward-difference gradients (scaled coordinates) of the signed leaves ``codes`` (M,)
    at poses ``q`` (M, 6): (M, 6). A contact's value equals its active leaf's near the pose,
    so this is the contact's gradient; only that one determinant (or margin) is evaluated at
    the six shifted poses. Determinants are polynomials in the pose: a step of 1e-6 is
    accurate to ~1e-6 relative."""
    q = np.asarray(q, dtype=float)
    m = len(q)
    shifts = np.vstack([np.zeros(6), np.eye(6) * (h / model.scale)[:, None]])
    qs = (q[None, :, :] + shifts[:, None, :]).reshape(-1, 6)      # (7 M, 6)
    n_det = len(model.program.keys)
    codes = np.asarray(codes)
    vals = np.zeros((7, m))
    det = codes < 2 * n_det
    if det.any():
        cols = np.flatnonzero(det)
        sub = qs.reshape(7, m, 6)[:, cols].reshape(-1, 6)
        P = model.point_array(sub)                                  # (L, 7 k, 3)
        key = np.tile(model.flat.key_idx[codes[cols] // 2], (7, 1))  # (7 k, 4)
        j = np.arange(len(sub))
        a, b, c, d = (P[key[:, i], j] for i in range(4))
        v = bracket4(a, b, c, d) * np.tile(np.where(codes[cols] % 2 == 1, 1.0, -1.0), 7)
        vals[:, cols] = v.reshape(7, len(cols))
    if (~det).any():
        cols = np.flatnonzero(~det)
        sub = qs.reshape(7, m, 6)[:, cols].reshape(-1, 6)
        ex = model.extra_values(sub)                                # (n_extra, 7 k)
        row = np.tile(codes[cols] - 2 * n_det, 7)
        vals[:, cols] = ex[row, np.arange(len(sub))].reshape(7, len(cols))
    return ((vals[1:] - vals[:1]) / h).T


def tie_measure(model: Spatial321Model, q: ArrayLike,
                grads: bool = False) -> dict[str, np.ndarray]:
    """Distance of poses ``q`` (M, 6) from the tie set of their two smallest contacts.

    Returns a dict: ``rho``, ``gap`` (f2 - f1), ``dist`` (gap / |grad(f2 - f1)|, scaled
    metric), ``first``/``second`` (contact indices), ``grad`` (scaled gradient of the
    smallest contact, (M, 6)).
    """
    q = np.atleast_2d(np.asarray(q, dtype=float))
    vals, leaves = model.contact_values(q)
    i1, f1, i2, f2 = two_smallest(vals, leaves)
    cols = np.arange(len(q))
    g = _leaf_gradients(model, np.vstack([q, q]), np.r_[leaves[i1, cols], leaves[i2, cols]])
    g = g.reshape(2, len(q), 6)
    gnorm = np.linalg.norm(g[1] - g[0], axis=1)
    gap = f2 - f1
    dist = np.where(gnorm > 0, gap / np.maximum(gnorm, 1e-300), np.inf)
    out = {'rho': f1, 'gap': gap, 'dist': dist, 'first': i1, 'second': i2, 'grad': g[0]}
    if grads:
        out['dgrad'] = g[1] - g[0]
    return out


def retract(model: Spatial321Model, q: ArrayLike, tie_tol: float = 1e-3, max_steps: int = 30,
            t_first: float = 1e-3, t_max: float = 0.4, bisections: int = 16,
            keep_chain: Iterable[int] = ()
            ) -> tuple[np.ndarray, np.ndarray, np.ndarray, dict[int, np.ndarray]]:
    """Steepest ascent of rho from poses ``q`` (M, 6) until two contacts tie.

    Returns ``(points, on_tie, steps, chains)``: the final poses, whether each is within
    ``tie_tol`` (scaled metric) of a tie, the number of ascent steps taken, and the list of
    visited poses for the indices in ``keep_chain`` (the retraction path, rho increasing).
    """
    q = np.array(np.atleast_2d(q), dtype=float)
    n = len(q)
    scale = model.scale
    active = np.ones(n, dtype=bool)
    on_tie = np.zeros(n, dtype=bool)
    steps = np.zeros(n, dtype=np.int64)
    chains = {i: [q[i].copy()] for i in keep_chain}
    for _ in range(max_steps + 1):
        idx = np.flatnonzero(active)
        if not idx.size:
            break
        meas = tie_measure(model, q[idx])
        hit = meas['dist'] <= tie_tol
        on_tie[idx[hit]] = True
        grad = meas['grad']
        gnorm = np.linalg.norm(grad, axis=1)
        stuck = ~hit & ~(gnorm > 0)
        active[idx[hit | stuck]] = False
        go = ~hit & ~stuck
        if _ >= max_steps or not go.any():
            active[idx] = False
            break
        idx, rho0 = idx[go], meas['rho'][go]
        first = meas['first'][go]
        direction = grad[go] / gnorm[go, None] / scale          # unit length, scaled metric
        base = q[idx]
        first_leaf = model.contact_values(base)[1][first, np.arange(len(idx))]

        def good(t, best):
            p = base + t[:, None] * direction
            vals, leaves = model.contact_values(p)
            cols = np.arange(len(p))
            amin = np.argmin(vals, axis=0)
            rho = vals[amin, cols]
            same = (amin == first) | (leaves[amin, cols] == first_leaf)
            return same & (rho > best) & model.in_bounds(p), rho

        lo = np.zeros(len(idx))
        best = rho0.copy()
        hi = np.full(len(idx), np.nan)
        t = np.full(len(idx), t_first)
        while True:                          # doubling until the smallest contact changes
            open_ = np.isnan(hi) & (t <= t_max)
            if not open_.any():
                break
            ok, rho = good(t, best)
            grow = open_ & ok
            lo = np.where(grow, t, lo)
            best = np.where(grow, rho, best)
            hi = np.where(open_ & ~ok, t, hi)
            t = np.where(grow, 2 * t, t)
        bracketed = ~np.isnan(hi)
        hi = np.where(bracketed, hi, lo)
        for _b in range(bisections):         # bisection onto the tie
            mid = 0.5 * (lo + hi)
            ok, rho = good(mid, best)
            ok &= bracketed
            lo = np.where(ok, mid, lo)
            best = np.where(ok, rho, best)
            hi = np.where(bracketed & ~ok, mid, hi)
        moved = lo > 0
        q[idx] = base + lo[:, None] * direction
        steps[idx[moved]] += 1
        active[idx[~moved]] = False
        for i in chains:
            if active[i] or i in idx[moved]:
                if not np.array_equal(chains[i][-1], q[i]):
                    chains[i].append(q[i].copy())
    # Final classification of the ones that stopped without a measurement.
    rest = np.flatnonzero(~on_tie)
    if rest.size:
        on_tie[rest] = tie_measure(model, q[rest])['dist'] <= tie_tol
    return q, on_tie, steps, {i: np.array(c) for i, c in chains.items()}


def project_to_tie(model: Spatial321Model, q: ArrayLike, tie_tol: float = 1e-3,
                   iterations: int = 6) -> tuple[np.ndarray, np.ndarray]:
    """Nearest point of the tie set, by Newton steps on ``f2 - f1 = 0`` (f1, f2: the two
    smallest distinct contacts, re-chosen at every step). Exact in one step for moves in
    position at a fixed orientation while the pair does not change. Poses that do not converge
    (about 1.5 %, cycling between pairs) are retracted by :func:`retract` instead. Returns
    ``(points, on_tie)``. Used to trace edges along the diagram (rho need not grow here)."""
    q = np.array(np.atleast_2d(q), dtype=float)
    on = np.zeros(len(q), dtype=bool)
    idx = np.arange(len(q))
    for _ in range(iterations + 1):
        if not idx.size:
            break
        meas = tie_measure(model, q[idx], grads=True)
        hit = meas['dist'] <= tie_tol
        on[idx[hit]] = True
        idx, gap, dg = idx[~hit], meas['gap'][~hit], meas['dgrad'][~hit]
        if _ == iterations:
            break
        norm2 = np.einsum('ij,ij->i', dg, dg)
        step = np.where(norm2[:, None] > 0, -gap[:, None] * dg / np.maximum(norm2, 1e-300)[
            :, None], 0.0)
        q[idx] += step / model.scale
    if idx.size:
        q[idx], on[idx], _, _ = retract(model, q[idx], tie_tol)
    return q, on


@dataclass
class SpatialPlanResult:
    status: str
    reason: str = ''
    path: np.ndarray = field(default_factory=lambda: np.zeros((0, 6)))
    waypoints: np.ndarray = field(default_factory=lambda: np.zeros((0, 6)))
    min_rho: float = float('nan')
    planning_time: float = 0.0
    stats: dict = field(default_factory=dict)

    @property
    def found(self) -> bool:
        return self.status == 'ok'


class DiagramRoadmapPlanner:
    """Roadmap on the simplified Voronoi diagram of a 3-2-1 model (see module docstring)."""

    def __init__(self, model: Spatial321Model, n_samples: int = 400, k: int = 8, seed: int = 0,
                 check_step: float = 0.005, check_dangle: float = 0.01,
                 tie_tol: float = 1e-3, diagram_tol: float = 2e-3, probe_step: float = 0.01,
                 max_gap: float = 0.03, batch_edges: int = 40, shortcut: bool = True) -> None:
        if n_samples < 10 or k < 2:
            raise UserError(f'samples {n_samples}, neighbours {k}: need at least 10 samples '
                            'and 2 neighbours')
        for name, v in (('check_step', check_step), ('check_dangle', check_dangle),
                        ('tie_tol', tie_tol), ('diagram_tol', diagram_tol),
                        ('probe_step', probe_step), ('max_gap', max_gap)):
            if not (v > 0 and np.isfinite(v)):
                raise UserError(f'{name} {v}: must be a positive number')
        self.model = model
        self.n_samples = int(n_samples)
        self.k = int(k)
        self.seed = int(seed)
        self.check_step = float(check_step)
        self.check_dangle = float(check_dangle)
        self.tie_tol = float(tie_tol)
        self.diagram_tol = float(diagram_tol)
        self.probe_step = float(probe_step)
        self.max_gap = float(max_gap)
        self.batch_edges = int(batch_edges)
        self.shortcut = bool(shortcut)

    # -- samples -------------------------------------------------------------------------------
    def samples(self) -> np.ndarray:
        """Scrambled Halton poses in the bounds (deterministic for a seed)."""
        from scipy.stats import qmc  # 0.8 s to import: only when sampling

        m = self.model
        u = qmc.Halton(d=6, scramble=True, seed=self.seed).random(self.n_samples)
        return m.lower() + u * (m.upper() - m.lower())

    # -- edges along the diagram -----------------------------------------------------------------
    def trace(self, starts: ArrayLike, ends: ArrayLike,
              rounds: int = 3) -> list[np.ndarray | None]:
        """Trace edges between diagram points along the diagram.

        Probes every ``probe_step`` (scaled metric) along the chord are projected onto the
        nearest tie (:func:`project_to_tie`); where two consecutive projected points are more
        than ``probe_step`` apart, the midpoint is projected and inserted (up to ``rounds``
        times). The edge is the polyline through the projected points. Refused (None) if a
        projection does not reach a tie or a gap of more than ``max_gap`` remains (the trace
        jumped between distant sheets of the diagram; the chord across such a gap is the part
        of the edge that may leave the diagram, measured by :meth:`path_on_diagram`).
        """
        m = self.model
        starts = np.atleast_2d(starts)
        ends = np.atleast_2d(ends)
        n = np.maximum(1, np.ceil(np.linalg.norm((ends - starts) * m.scale, axis=1)
                                  / self.probe_step)).astype(int)
        owner = np.repeat(np.arange(len(starts)), n - 1)
        k = np.arange(owner.size) - np.repeat(np.cumsum(n - 1) - (n - 1), n - 1) + 1
        probes = starts[owner] + (k / n[owner])[:, None] * (ends[owner] - starts[owner])
        proj, on = project_to_tie(m, probes, self.tie_tol) if probes.size else (probes, [])
        polys, bad = [], np.zeros(len(starts), dtype=bool)
        for i in range(len(starts)):
            sel = owner == i
            bad[i] = not np.all(np.asarray(on)[sel]) if sel.any() else False
            polys.append(np.vstack([starts[i], proj[sel], ends[i]]))
        for _ in range(rounds):
            gaps = [(i, j) for i in range(len(polys)) if not bad[i]
                    for j in np.flatnonzero(np.linalg.norm(np.diff(polys[i], axis=0) * m.scale,
                                                           axis=1) > self.probe_step)]
            if not gaps:
                break
            mids = np.array([0.5 * (polys[i][j] + polys[i][j + 1]) for i, j in gaps])
            mproj, mon = project_to_tie(m, mids, self.tie_tol)
            inserts = {}
            for (i, j), p, good in zip(gaps, mproj, mon):
                if not good:
                    bad[i] = True
                inserts.setdefault(i, []).append((j, p))
            for i, lst in inserts.items():
                if bad[i]:
                    continue
                for j, p in sorted(lst, key=lambda x: -x[0]):
                    polys[i] = np.insert(polys[i], j + 1, p, axis=0)
        out = []
        for i, poly in enumerate(polys):
            jump = np.linalg.norm(np.diff(poly, axis=0) * m.scale, axis=1)
            out.append(None if bad[i] or np.any(jump > self.max_gap) else poly)
        return out

    def _free_polylines(self, polys):
        """Dense check of many polylines at once: list of bool."""
        samples, owner = [], []
        for i, p in enumerate(polys):
            s, _ = densify6(p, self.check_step, self.check_dangle)
            samples.append(s)
            owner.append(np.full(len(s), i))
        if not samples:
            return []
        samples = np.concatenate(samples)
        owner = np.concatenate(owner)
        bad, _ = bad_samples(self.model, samples)
        same = owner[1:] == owner[:-1]
        refused = np.zeros(len(polys), dtype=bool)
        np.logical_or.at(refused, owner[:-1][same], bad[same])
        return list(~refused)

    # -- planning ------------------------------------------------------------------------------
    def plan(self, start: ArrayLike, goal: ArrayLike,
             progress: Callable[[str], object] | None = None) -> SpatialPlanResult:
        """Plan from ``start`` to ``goal`` (6-D poses). The steps: a singularity certificate,
        Halton samples retracted onto the diagram with start and goal (:meth:`_roadmap_nodes`),
        candidate edges between near nodes (:meth:`_candidate_edges`), a lazy shortest-path
        search that traces and checks only the edges it is about to use
        (:meth:`_lazy_search`), then the path assembled from the traced diagram pieces and
        checked densely (:meth:`_assemble`)."""
        t0 = time.perf_counter()
        c0 = time.process_time()
        tick = progress or (lambda s: None)
        m = self.model
        start = np.asarray(start, dtype=float)
        goal = np.asarray(goal, dtype=float)
        validate_pose(m, start, 'start')
        validate_pose(m, goal, 'goal')
        stats = {}

        def result(status, reason='', **kw):
            # CPU time too: on the shared machine wall time depends on the load.
            stats['cpu_time_s'] = time.process_time() - c0
            return SpatialPlanResult(status, reason, planning_time=time.perf_counter() - t0,
                                     stats=stats, **kw)

        s_sign, g_sign = m.singular_signs(start), m.singular_signs(goal)
        if np.any(s_sign != g_sign):
            i = int(np.flatnonzero(s_sign != g_sign)[0])
            det = '[' + ' '.join(f'p{k}' for k in m.singular_keys[i]) + ']'
            return result('no_path', f'start and goal are in different singularity cells: '
                          f'{det} changes sign, so every path crosses the singularity '
                          f'{det} = 0')
        pts, ends = self._roadmap_nodes(start, goal, s_sign, stats, tick)
        tick('search')
        t_e = time.perf_counter()
        a, b, weight, edge_of = self._candidate_edges(pts)
        seq, polys, alive = self._lazy_search(pts, a, b, weight, edge_of, stats)
        stats['edge_time_s'] = time.perf_counter() - t_e
        if seq is None:
            return result('no_path', 'start and goal retractions are in different connected '
                          f'components of the diagram roadmap ({len(pts)} diagram points from '
                          f'{self.n_samples} Halton samples, k = {self.k}; '
                          f'{int((~alive).sum())} of {len(a)} edges refused by tracing along '
                          f'the diagram every {self.probe_step:g} or by the dense check); '
                          'more samples may connect them')
        tick('verify')
        return result('ok', **self._assemble(pts, seq, polys, edge_of, ends, stats))

    def _roadmap_nodes(self, start, goal, s_sign, stats, tick):
        """Free Halton samples in the start's singularity cell, retracted with start and goal
        by rho ascent to the ties of two contact predicates. Returns the roadmap nodes (start,
        goal, then the samples that reached a tie) and the two end chains (a retraction chain
        when it checks densely, else the end itself)."""
        m = self.model
        tick('sample')
        q = self.samples()
        rho = m.rho(q)
        keep = (rho > m.free_tol) & np.all(m.singular_signs(q) == s_sign[:, None], axis=0)
        q = q[keep]
        tick('retract')
        t_r = time.perf_counter()
        raw = np.vstack([start, goal, q])
        nodes, on_tie, steps, chains = retract(m, raw, self.tie_tol, keep_chain=(0, 1))
        disp = np.linalg.norm((nodes - raw) * m.scale, axis=1)
        rho_raw, rho_nodes = m.rho(raw), m.rho(nodes)
        stats.update(samples=self.n_samples, free_samples=int(keep.sum()),
                     retracted_on_diagram=int(on_tie[2:].sum()),
                     retraction_displacement_median=float(np.median(disp[2:])) if len(q)
                     else float('nan'),
                     retraction_steps_median=float(np.median(steps[2:])) if len(q) else 0.0,
                     retraction_rho_gain_min=float(np.min(rho_nodes - rho_raw)),
                     retraction_time_s=time.perf_counter() - t_r)
        # Start and goal join through their retraction chains (checked densely).
        ends = []
        for i, q_in in ((0, start), (1, goal)):
            chain = chains[i]
            if len(chain) > 1 and check_path6(m, chain, self.check_step, self.check_dangle)[0]:
                ends.append(chain)
            else:
                ends.append(q_in[None])
                nodes[i] = q_in
        use = np.r_[0, 1, 2 + np.flatnonzero(on_tie[2:])]
        pts = nodes[use]
        stats['roadmap_nodes'] = len(pts)
        if len(q):
            # Distance to the tie set of the samples before and of the nodes after retraction.
            before = tie_measure(m, raw[2:])['dist']
            after = tie_measure(m, pts[2:])['dist'] if len(pts) > 2 else np.zeros(1)
            stats.update(sample_tie_distance_median=float(np.median(before)),
                         node_tie_distance_median=float(np.median(after)),
                         node_tie_distance_max=float(np.max(after)))
        return pts, ends

    def _candidate_edges(self, pts):
        """Each node's ``k`` nearest nodes (scaled 6-D distance) as undirected candidate
        edges ``(a, b)`` with ``a < b``, their straight length as the first weight, and the
        index of each edge by its end pair."""
        m = self.model
        tree = cKDTree(pts * m.scale)
        kk = min(self.k + 1, len(pts))
        _, nbr = tree.query(pts * m.scale, k=kk)
        a = np.repeat(np.arange(len(pts)), kk - 1)
        b = nbr[:, 1:].ravel()
        ok = (b < len(pts)) & (a != b)
        lo_, hi_ = np.minimum(a[ok], b[ok]), np.maximum(a[ok], b[ok])
        uniq = np.unique(lo_ * len(pts) + hi_)
        a, b = uniq // len(pts), uniq % len(pts)
        weight = np.linalg.norm((pts[a] - pts[b]) * m.scale, axis=1)
        edge_of = {(int(x), int(y)): i for i, (x, y) in enumerate(zip(a, b))}
        return a, b, weight, edge_of

    def _lazy_search(self, pts, a, b, weight, edge_of, stats):
        """Shortest path from node 0 to node 1 over edges not yet refused; trace along the
        diagram and check the edges it uses, drop refused ones, repeat. An edge is dropped
        only after it fails, so the answer (connected or not) is the one of the fully traced
        roadmap. Returns ``(node sequence or None, traced polylines by edge, alive mask)``."""
        m = self.model
        alive = np.ones(len(a), dtype=bool)
        polys = {}
        seq, it = None, 0
        while seq is None:
            it += 1
            e = np.flatnonzero(alive)
            graph = csr_matrix((np.r_[weight[e], weight[e]] + 1e-12,
                                (np.r_[a[e], b[e]], np.r_[b[e], a[e]])),
                               shape=(len(pts), len(pts)))
            _, pred = dijkstra(graph, directed=False, indices=0, return_predecessors=True)
            if pred[1] < 0:
                break
            cand = [1]
            while cand[-1] != 0:
                cand.append(int(pred[cand[-1]]))
            cand = cand[::-1]
            eids = [edge_of[(min(u, v), max(u, v))] for u, v in zip(cand[:-1], cand[1:])]
            todo = [i for i in eids if i not in polys]
            # Batch: also trace untested edges at the nodes of this path (numpy works per
            # batch, so they come almost free and spare later search iterations).
            on_path = np.zeros(len(pts), dtype=bool)
            on_path[cand] = True
            extra = np.flatnonzero(alive & (on_path[a] | on_path[b]))
            extra = [int(i) for i in extra if int(i) not in polys and int(i) not in todo]
            todo += extra[:self.batch_edges]
            traced = self.trace(pts[a[todo]], pts[b[todo]]) if todo else []
            good = [i for i, p in zip(todo, traced) if p is not None]
            free = self._free_polylines([traced[todo.index(i)] for i in good])
            failed = [i for i, p in zip(todo, traced) if p is None]
            for i, f in zip(good, free):
                if f:
                    polys[i] = traced[todo.index(i)]
                    weight[i] = np.sum(np.linalg.norm(np.diff(polys[i], axis=0) * m.scale,
                                                      axis=1))
                else:
                    failed.append(i)
            alive[failed] = False
            if all(i in polys for i in eids):
                seq = cand
        stats.update(candidate_edges=len(a), traced_edges=len(polys),
                     refused_edges=int((~alive).sum()), search_iterations=it)
        return seq, polys, alive

    def _assemble(self, pts, seq, polys, edge_of, ends, stats):
        """The start's chain, the traced diagram pieces (shortcut along the diagram when
        enabled), the goal's chain reversed; densely checked; its on-diagram share."""
        m = self.model
        pieces = []
        for u, v in zip(seq[:-1], seq[1:]):
            poly = polys[edge_of[(min(u, v), max(u, v))]]
            pieces.append(poly if u < v else poly[::-1])
        if self.shortcut:
            pieces = self._shortcut(pts[seq], pieces)
        stats['path_diagram_pieces'] = len(pieces)
        parts = [ends[0]] + [piece[1:] for piece in pieces] + [ends[1][::-1][1:]]
        way = np.vstack(parts)
        ok, min_rho, bad = check_path6(m, way, self.check_step, self.check_dangle)
        if not ok:
            raise RuntimeError(f'assembled path failed dense checking at {bad[:5]}')
        path, _ = densify6(way, self.check_step, self.check_dangle)
        n_chain = (len(ends[0]), len(ends[1]))
        stats.update(self.path_on_diagram(path, way, n_chain))
        return {'path': path, 'waypoints': way, 'min_rho': min_rho}

    def _shortcut(self, nodes, pieces, reach=6):
        """Shorten a roadmap path along the diagram: from each path node, trace edges to the
        next ``reach`` nodes beyond its neighbour (one batch) and jump to the farthest one whose
        traced edge passes the dense check and is shorter than the pieces it replaces."""
        m = self.model

        def length(poly):
            return float(np.sum(np.linalg.norm(np.diff(poly, axis=0) * m.scale, axis=1)))

        out, i = [], 0
        while i < len(pieces):
            cands = list(range(min(len(nodes) - 1, i + 1 + reach), i + 1, -1))
            jump = None
            if cands:
                traced = self.trace(np.repeat(nodes[i:i + 1], len(cands), axis=0),
                                    nodes[cands])
                ok = [(j, t) for j, t in zip(cands, traced) if t is not None
                      and length(t) < sum(length(pc) for pc in pieces[i:j])]
                free = self._free_polylines([t for _, t in ok])
                jump = next(((j, t) for (j, t), f in zip(ok, free) if f), None)
            if jump is None:
                out.append(pieces[i])
                i += 1
            else:
                out.append(jump[1])
                i = jump[0]
        return out

    def path_on_diagram(self, path: np.ndarray, way: np.ndarray,
                        n_chain: Sequence[int]) -> dict[str, float]:
        """Length share of the path within ``diagram_tol`` of a tie, overall and between the
        two retraction chains, and the distance distribution of the path samples."""
        m = self.model
        dist = tie_measure(m, path)['dist']
        seg = np.linalg.norm(np.diff(path, axis=0) * m.scale, axis=1)
        on = (dist[1:] <= self.diagram_tol) & (dist[:-1] <= self.diagram_tol)
        total = float(seg.sum())
        # Samples between the end of the start chain and the start of the goal chain.
        a = np.linalg.norm((path - way[n_chain[0] - 1]) * m.scale, axis=1).argmin()
        b = np.linalg.norm((path - way[len(way) - n_chain[1]]) * m.scale, axis=1).argmin()
        inner = slice(a, max(a, b))
        seg_in = seg[inner]
        return {
            'path_length_scaled': total,
            'on_diagram_fraction': float(seg[on].sum() / total) if total > 0 else 1.0,
            'on_diagram_fraction_between_retractions':
                float(seg_in[on[inner]].sum() / seg_in.sum()) if seg_in.sum() > 0 else 1.0,
            'tie_distance_median': float(np.median(dist)),
            'tie_distance_p90': float(np.percentile(dist, 90)),
            'tie_distance_max': float(np.max(dist)),
            'diagram_tol': self.diagram_tol,
        }
