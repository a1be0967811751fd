"""The spatial 3-2-1 platform of Fig. 1 (left) of Vaca, Aranda & Thomas among polyhedral
obstacles: singularity and collision predicates as signs of 4x4 determinants, rho in 6-D, and
a sampled roadmap on the simplified Voronoi diagram.

Robot (labels as in the paper's pure condition): base attachments P1..P6 fixed on the ground,
platform triangle P7 P8 P9. Three legs meet at P7 (from P1, P2, P3), two at P8 (from P5, P6) and
one at P9 (from P4). The platform is singular iff a tetrahedron of the factorised pure
condition ``[p1 p2 p3 p7][p5 p6 p7 p8][p4 p7 p8 p9] = 0`` degenerates (section 2, eq. 2).

Collisions (section 3): every leg segment and every platform edge against every triangle of
every obstacle box, and every box edge against the platform triangle, each the segment-triangle
basic contact :func:`~paramotion.voronoi.predicates.segment_pierces_triangle`; a box is hit iff
one of them holds (leg-leg contacts and leg length limits are not modelled).

Configuration ``q = (x, y, z, roll, pitch, yaw)``: position of P7 (m) and ZYX Euler angles
(rad) of the platform. rho (section 4) is evaluated for many poses at once.

:class:`SampledVoronoiPlanner`: random free poses are retracted onto the diagram (moving along
the gradient of rho - of the active determinant - until the active determinant changes, so rho
grows on the way); diagram points are joined to their nearest neighbours; a lazy Dijkstra search
checks the edges it uses densely (every ``check_step`` m and ``check_dangle`` rad: rho > 0 and no
sign change of a pure-condition determinant), drops refused edges and searches again, until a
verified path or an exhausted roadmap ("no path" for this sample set). No ROS imports.
"""
import json
import math
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import dijkstra
from scipy.spatial import cKDTree

from paramotion.errors import UserError
from paramotion.jsonfile import load_json_object
from paramotion.voronoi.distance import compile_rho
from paramotion.voronoi.planar import NamedPredicate
from paramotion.voronoi.planner import VoronoiPlanner
from paramotion.voronoi.predicates import (
    Not,
    Or,
    evaluate_determinants,
    fuse,
    pure_condition_free,
    segment_pierces_triangle,
)

__all__ = ['PURE_CONDITION', 'Spatial321Model', 'SampledVoronoiPlanner', 'box_mesh',
           'demo_model', 'load_scene', 'rpy_matrix', 'DEMO_START', 'DEMO_GOAL']

#: Factors of the 3-2-1 pure condition [p1p2p3p7][p5p6p7p8][p4p7p8p9].
PURE_CONDITION = ((1, 2, 3, 7), (5, 6, 7, 8), (4, 7, 8, 9))
LEGS = ((1, 7), (2, 7), (3, 7), (5, 8), (6, 8), (4, 9))

DEMO_BASE = {1: (-0.40, -0.30, 0.0), 2: (0.10, -0.50, 0.0), 3: (-0.40, 0.30, 0.0),
             4: (0.40, 0.60, 0.0), 5: (0.70, -0.30, 0.0), 6: (0.70, 0.30, 0.0)}
DEMO_PLATFORM = {7: (0.0, 0.0, 0.0), 8: (0.40, 0.0, 0.0), 9: (0.20, 0.30, 0.0)}
# A block hanging at platform height between start and goal: the platform must pass beside
# or under it (its legs stay below the platform).
DEMO_BOXES = ({'center': (0.25, 0.15, 0.90), 'size': (0.15, 0.15, 0.20)},)
DEMO_START = (-0.2, -0.2, 0.85, math.radians(4), math.radians(-3), math.radians(-6))
DEMO_GOAL = (0.3, 0.3, 0.85, math.radians(-3), math.radians(4), math.radians(8))
DEMO_BOUNDS = {'position_min': (-0.25, -0.3, 0.45), 'position_max': (0.4, 0.4, 1.1),
               'angle_max_deg': 30.0}

_CHUNK = 1 << 13


def rpy_matrix(rpy):
    """Rotation matrices ``(..., 3, 3)`` of ZYX Euler angles ``(..., 3)`` = roll, pitch, yaw."""
    rpy = np.asarray(rpy, dtype=float)
    cr, sr = np.cos(rpy[..., 0]), np.sin(rpy[..., 0])
    cp, sp = np.cos(rpy[..., 1]), np.sin(rpy[..., 1])
    cy, sy = np.cos(rpy[..., 2]), np.sin(rpy[..., 2])
    return np.stack([
        np.stack([cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr], axis=-1),
        np.stack([sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr], axis=-1),
        np.stack([-sp, cp * sr, cp * cr], axis=-1)], axis=-2)


def box_mesh(center, size):
    """Vertices (8, 3), triangles (12, 3) with outward counter-clockwise order, edges (12, 2)."""
    c = np.asarray(center, dtype=float)
    h = 0.5 * np.asarray(size, dtype=float)
    corners = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)])
    verts = c + corners * h
    quads = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4),
             (1, 5, 7, 3)]
    tris = []
    for a, b, cc, d in quads:
        tris += [(a, b, cc), (a, cc, d)]
    edges = sorted({tuple(sorted(e)) for a, b, cc, d in quads
                    for e in ((a, b), (b, cc), (cc, d), (d, a))})
    return verts, np.array(tris), np.array(edges)


@dataclass
class Spatial321Model:
    """3-2-1 platform, obstacle boxes and the fused predicate (singularities AND collisions)."""

    base: dict
    platform: dict
    boxes: tuple
    position_min: tuple
    position_max: tuple
    angle_max: float
    predicates: list = field(default_factory=list)

    def __post_init__(self):
        self.fixed = {k: np.asarray(v, dtype=float) for k, v in self.base.items()}
        self.moving = {k: np.asarray(v, dtype=float) for k, v in self.platform.items()}
        self.predicates = [NamedPredicate(
            f'singularity: [p{a} p{b} p{c} p{d}] = 0 (tetrahedron P{a}P{b}P{c}P{d} flat)',
            'singularity', pure_condition_free([(a, b, c, d)]))
            for a, b, c, d in PURE_CONDITION]
        self.meshes = []
        label = 10
        for n, box in enumerate(self.boxes):
            verts, tris, edges = box_mesh(box['center'], box['size'])
            labels = list(range(label, label + 8))
            label += 8
            for lab, v in zip(labels, verts):
                self.fixed[lab] = v
            self.meshes.append((verts, tris, edges))
            tri_l = [tuple(labels[i] for i in t) for t in tris]
            edge_l = [tuple(labels[i] for i in e) for e in edges]
            for a, b in LEGS:
                hits = [segment_pierces_triangle(a, b, *t) for t in tri_l]
                self.predicates.append(NamedPredicate(
                    f'collision: leg P{a}P{b} hits box {n}', 'collision', Not(Or(*hits))))
            hits = [segment_pierces_triangle(a, b, *t)
                    for a, b in ((7, 8), (8, 9), (9, 7)) for t in tri_l]
            hits += [segment_pierces_triangle(a, b, 7, 8, 9) for a, b in edge_l]
            self.predicates.append(NamedPredicate(
                f'collision: platform P7P8P9 hits box {n}', 'collision', Not(Or(*hits))))
        self.tree = fuse(*[p.tree for p in self.predicates])
        self.program = compile_rho(self.tree)
        self.factor_programs = [compile_rho(p.tree) for p in self.predicates]
        self.singular_keys = [tuple(sorted(f)) for f in PURE_CONDITION]
        span = float(np.linalg.norm(np.subtract(self.position_max, self.position_min)))
        self.free_tol = 1e-9 * span ** 3     # 4x4 brackets are volumes

    # -- geometry ------------------------------------------------------------------------------
    def points(self, q):
        q = np.asarray(q, dtype=float)
        rot = rpy_matrix(q[..., 3:6])
        out = {k: np.broadcast_to(v, q.shape[:-1] + (3,)) for k, v in self.fixed.items()}
        for k, v in self.moving.items():
            out[k] = q[..., :3] + rot @ v
        return out

    def _chunked(self, q, fn, dtypes):
        q = np.asarray(q, dtype=float)
        flat = q.reshape(-1, 6)
        outs = [np.empty(len(flat), dtype=dt) for dt in dtypes]
        for s in range(0, len(flat), _CHUNK):
            part = fn(flat[s:s + _CHUNK])
            part = part if isinstance(part, tuple) else (part,)
            for o, p in zip(outs, part):
                o[s:s + _CHUNK] = p
        outs = [o.reshape(q.shape[:-1]) for o in outs]
        return outs[0] if len(outs) == 1 else tuple(outs)

    def rho(self, q):
        """rho of the fused predicate at poses ``q`` (..., 6)."""
        prog = self.program
        return self._chunked(
            q, lambda c: prog.rho(evaluate_determinants(prog.keys, self.points(c), False)),
            [float])

    def evaluate(self, q):
        """``(rho, active leaf)`` at poses ``q`` (..., 6)."""
        prog = self.program
        return self._chunked(
            q, lambda c: prog.evaluate(evaluate_determinants(prog.keys, self.points(c), False)),
            [float, np.int32])

    def singular_signs(self, q):
        return np.sign(evaluate_determinants(self.singular_keys, self.points(q)))

    def diagnose(self, q):
        q = np.asarray(q, dtype=float).reshape(6)
        out = []
        for pred, prog in zip(self.predicates, self.factor_programs):
            v = float(prog.rho(evaluate_determinants(prog.keys, self.points(q))))
            if not v > self.free_tol:
                out.append((pred.name, v))
        return out

    def in_bounds(self, q):
        q = np.asarray(q, dtype=float)
        return (np.all(q[..., :3] >= self.position_min, axis=-1)
                & np.all(q[..., :3] <= self.position_max, axis=-1)
                & np.all(np.abs(q[..., 3:]) <= self.angle_max, axis=-1))

    def sample(self, rng, n):
        lo = np.r_[self.position_min, [-self.angle_max] * 3]
        hi = np.r_[self.position_max, [self.angle_max] * 3]
        return rng.uniform(lo, hi, (n, 6))

    def world_points(self, q):
        """Platform and base points for drawing one pose ``q``."""
        return {k: np.asarray(v) for k, v in self.points(np.asarray(q, dtype=float)).items()}


def demo_model(boxes=DEMO_BOXES):
    return Spatial321Model(DEMO_BASE, DEMO_PLATFORM, tuple(boxes), DEMO_BOUNDS['position_min'],
                           DEMO_BOUNDS['position_max'], math.radians(DEMO_BOUNDS['angle_max_deg']))


def load_scene(path):
    """Spatial scene JSON: ``boxes`` [{"center": [x, y, z], "size": [sx, sy, sz]}, ...],
    optional ``base`` {"1": [x, y, z], ... "6": ...}, ``platform`` {"7": ..., "8": ...,
    "9": ...} (platform frame, P7 at the origin), ``bounds`` {"position_min", "position_max",
    "angle_max_deg"}; missing keys take the demo values."""
    path = Path(path)
    data = load_json_object(path, 'scene file')

    def vec(v, what):
        try:
            a = np.asarray(v, dtype=float)
        except (TypeError, ValueError):
            a = None
        if a is None or a.shape != (3,) or not np.all(np.isfinite(a)):
            raise UserError(f'scene file {path}: {what} must be three finite numbers')
        return tuple(a)

    boxes = []
    for i, b in enumerate(data.get('boxes', [])):
        if not isinstance(b, dict) or set(b) != {'center', 'size'}:
            raise UserError(f'scene file {path}: box {i} needs exactly "center" and "size"')
        size = vec(b['size'], f'box {i} size')
        if min(size) <= 0:
            raise UserError(f'scene file {path}: box {i} size must be positive')
        boxes.append({'center': vec(b['center'], f'box {i} center'), 'size': size})
    base = {k: vec(data.get('base', {}).get(str(k), v), f'base point {k}')
            for k, v in DEMO_BASE.items()}
    plat = {k: vec(data.get('platform', {}).get(str(k), v), f'platform point {k}')
            for k, v in DEMO_PLATFORM.items()}
    bounds = dict(DEMO_BOUNDS, **data.get('bounds', {}))
    pmin = vec(bounds['position_min'], 'bounds position_min')
    pmax = vec(bounds['position_max'], 'bounds position_max')
    if not np.all(np.less(pmin, pmax)):
        raise UserError(f'scene file {path}: bounds position_min must be below position_max')
    amax = bounds['angle_max_deg']
    if not isinstance(amax, (int, float)) or not 0 < amax <= 90:
        raise UserError(f'scene file {path}: bounds angle_max_deg must be in (0, 90]')
    return Spatial321Model(base, plat, tuple(boxes), pmin, pmax, math.radians(amax))


# ---------------------------------------------------------------------------------------------
# Sampled roadmap on the simplified Voronoi diagram
# ---------------------------------------------------------------------------------------------

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
    def found(self):
        return self.status == 'ok'


def densify6(waypoints, step, dangle):
    """Samples along a 6-D polyline: |d position| <= step, every |d angle| <= dangle."""
    w = np.asarray(waypoints, dtype=float)
    if len(w) < 2:
        return w.copy(), np.zeros(len(w), dtype=np.int64)
    d = np.diff(w, axis=0)
    n = np.maximum(1, np.ceil(np.maximum(np.linalg.norm(d[:, :3], axis=1) / step,
                                         np.max(np.abs(d[:, 3:]), axis=1) / dangle))
                   ).astype(np.int64)
    seg = np.repeat(np.arange(len(d)), n)
    k = np.arange(seg.size) - np.repeat(np.cumsum(n) - n, n)
    samples = np.vstack([w[seg] + (k / n[seg])[:, None] * d[seg], w[-1:]])
    return samples, np.r_[seg, len(d) - 1]


def check_path6(model, waypoints, step=0.005, dangle=0.01):
    """Dense check of a 6-D polyline: ``(ok, min_rho, bad segment indices)``."""
    samples, seg = densify6(waypoints, step, dangle)
    rho = model.rho(samples)
    signs = model.singular_signs(samples)
    bad = (rho <= model.free_tol) | np.any(signs != signs[:, :1], axis=0) \
        | np.any(signs == 0, axis=0)
    return (not bad.any()), float(rho.min()), np.unique(seg[bad])


def validate_pose(model, q, name):
    q = np.asarray(q, dtype=float)
    if q.shape != (6,) or not np.all(np.isfinite(q)):
        raise UserError(f'{name}: expected six finite numbers (x, y, z, roll, pitch, yaw)')
    if not model.in_bounds(q):
        raise UserError(f'{name} {np.round(q, 4).tolist()} is outside the planning bounds '
                        f'(position {model.position_min}..{model.position_max} m, angles '
                        f'within +-{math.degrees(model.angle_max):g} deg)')
    failures = model.diagnose(q)
    if failures:
        raise UserError(f'{name} is not free: ' + '; '.join(
            f'{n} (rho = {v + 0.0:.3g})' for n, v in failures))


class SampledVoronoiPlanner:
    """Sampled roadmap on the simplified Voronoi diagram of a :class:`Spatial321Model`."""

    def __init__(self, model, n_samples=3000, k=10, seed=0, check_step=0.005,
                 check_dangle=0.01, angle_scale=0.5, max_iterations=2000):
        if n_samples < 10 or k < 2:
            raise UserError('need at least 10 samples and 2 neighbours')
        self.model = model
        self.n_samples = int(n_samples)
        self.k = int(k)
        self.rng = np.random.default_rng(seed)
        self.check_step = float(check_step)
        self.check_dangle = float(check_dangle)
        self.scale = np.r_[1.0, 1.0, 1.0, [angle_scale] * 3]
        self.max_iterations = int(max_iterations)

    def retract(self, q, max_len=0.5, steps=8):
        """Move each pose along the gradient of rho until the active determinant changes.

        Returns the diagram points ``(M, 6)``. A pose already at a tie stays put; a pose whose
        ray leaves the bounds first stops at the last in-bounds point before that.
        """
        m = self.model
        q = np.asarray(q, dtype=float)
        rho0, act0 = m.evaluate(q)
        eps = 1e-5
        grads = np.empty_like(q)
        for i in range(6):
            dq = np.zeros(6)
            dq[i] = eps / self.scale[i]
            grads[:, i] = (m.rho(q + dq) - m.rho(q - dq)) / (2 * eps)
        norm = np.linalg.norm(grads, axis=1)
        d = np.where(norm[:, None] > 0, grads / np.maximum(norm, 1e-300)[:, None], 0.0)
        d = d / self.scale            # direction in pose coordinates (unit scaled length)

        def same(t):
            p = q + t[:, None] * d
            rho, act = m.evaluate(p)
            return (act == act0) & (rho >= rho0) & m.in_bounds(p)

        lo = np.zeros(len(q))
        hi = np.full(len(q), np.nan)
        t = np.full(len(q), max_len / 2 ** steps)
        for _ in range(steps + 1):       # expand until the active leaf changes
            open_ = np.isnan(hi)
            if not open_.any():
                break
            ok = same(t)
            lo = np.where(open_ & ok, t, lo)
            hi = np.where(open_ & ~ok, t, hi)
            t = np.where(open_ & ok, 2 * t, t)
        found = ~np.isnan(hi)
        hi = np.where(found, hi, lo)
        for _ in range(10):              # bisection onto the tie
            mid = 0.5 * (lo + hi)
            ok = same(mid)
            lo = np.where(found & ok, mid, lo)
            hi = np.where(found & ~ok, mid, hi)
        return q + lo[:, None] * d

    def plan(self, start, goal, progress=None):
        t0 = time.perf_counter()
        tick = progress or (lambda s: None)
        m = self.model
        start = np.asarray(start, dtype=float)
        goal = np.asarray(goal, dtype=float)
        validate_pose(m, start, 'start')
        validate_pose(m, goal, 'goal')
        stats = {}

        def result(status, reason='', **kw):
            return SpatialPlanResult(status, reason, planning_time=time.perf_counter() - t0,
                                     stats=stats, **kw)

        s_sign, g_sign = m.singular_signs(start), m.singular_signs(goal)
        if np.any(s_sign != g_sign):
            i = int(np.flatnonzero(s_sign != g_sign)[0])
            det = '[' + ' '.join(f'p{k}' for k in m.singular_keys[i]) + ']'
            return result('no_path', f'start and goal are in different singularity cells: '
                          f'{det} changes sign, so every path crosses the singularity '
                          f'{det} = 0')
        tick('sample')
        q = m.sample(self.rng, self.n_samples)
        rho = m.rho(q)
        cell = m.singular_signs(q)
        keep = (rho > m.free_tol) & np.all(cell == s_sign[:, None], axis=0)
        q = q[keep]
        tick('retract')
        nodes = self.retract(np.vstack([start, goal, q]))
        # Start and goal join the roadmap through their retraction segments.
        s_node, g_node = 0, 1
        stats.update(samples=self.n_samples, free_samples=int(keep.sum()),
                     roadmap_nodes=len(nodes))
        tick('roadmap')
        pts = nodes * self.scale
        tree = cKDTree(pts)
        dist, nbr = tree.query(pts, k=min(self.k + 1, len(pts)))
        a = np.repeat(np.arange(len(pts)), nbr.shape[1] - 1)
        b = nbr[:, 1:].ravel()
        w = dist[:, 1:].ravel()
        ok = np.isfinite(w) & (a != b)
        a, b, w = a[ok], b[ok], np.maximum(w[ok], 1e-12)
        lo, hi = np.minimum(a, b), np.maximum(a, b)
        key = np.unique(lo * len(pts) + hi, return_index=True)[1]
        a, b, w = lo[key], hi[key], w[key]
        stats['roadmap_edges'] = len(a)
        # Retraction segments of start and goal must be free too.
        ends = []
        for q_in, node in ((start, s_node), (goal, g_node)):
            seg = np.vstack([q_in, nodes[node]])
            ends.append(seg if check_path6(m, seg, self.check_step, self.check_dangle)[0]
                        else seg[:1])
        if len(ends[0]) == 1:
            nodes[s_node] = start
        if len(ends[1]) == 1:
            nodes[g_node] = goal
        tick('search')
        # Edge clearance: rho at both ends and the midpoint. Search first among edges keeping
        # half the best achievable bottleneck clearance, then among all (as in the planar
        # planner): paths stay near the diagram's high-clearance part.
        node_rho = m.rho(nodes)
        clear = np.minimum(np.minimum(node_rho[a], node_rho[b]),
                           m.rho(0.5 * (nodes[a] + nodes[b])))
        bottleneck = VoronoiPlanner._bottleneck(len(pts), a, b, np.maximum(clear, 0.0),
                                                s_node, g_node)
        stats['bottleneck_rho'] = float(bottleneck)
        alive = clear > m.free_tol
        verified = np.zeros(len(a), dtype=bool)
        rejected, it = 0, 0
        seq = None
        for tau in ([0.5 * bottleneck, 0.0] if bottleneck > 0 else []):
            while seq is None and it < self.max_iterations:
                it += 1
                e = np.flatnonzero(alive & (clear >= tau))
                graph = csr_matrix((np.r_[w[e], w[e]], (np.r_[a[e], b[e]], np.r_[b[e], a[e]])),
                                   shape=(len(pts), len(pts)))
                _, pred = dijkstra(graph, directed=True, indices=s_node,
                                   return_predecessors=True)
                if pred[g_node] < 0:
                    break
                cand = [g_node]
                while cand[-1] != s_node:
                    cand.append(int(pred[cand[-1]]))
                cand = cand[::-1]
                eids = [int(np.flatnonzero((a == min(u, v)) & (b == max(u, v)))[0])
                        for u, v in zip(cand[:-1], cand[1:])]
                failed = []
                for i, ei in enumerate(eids):
                    if verified[ei]:
                        continue
                    seg = nodes[[cand[i], cand[i + 1]]]
                    if check_path6(m, seg, self.check_step, self.check_dangle)[0]:
                        verified[ei] = True
                    else:
                        failed.append(ei)
                if not failed:
                    seq = cand
                    break
                alive[failed] = False
                rejected += len(failed)
        if seq is None:
            if it >= self.max_iterations:
                raise RuntimeError('lazy search did not converge')
            stats.update(search_iterations=it, rejected_edges=rejected)
            return result('no_path', 'no verified roadmap connection between the start '
                          f'and goal retractions ({self.n_samples} samples, k = {self.k}); '
                          'more samples may find one')
        stats.update(search_iterations=it, rejected_edges=rejected)
        tick('verify')
        way = np.vstack([ends[0][:-1] if len(ends[0]) > 1 else np.zeros((0, 6)),
                         nodes[seq],
                         ends[1][::-1][1:] if len(ends[1]) > 1 else np.zeros((0, 6))])
        ok, min_rho, bad = check_path6(m, way, self.check_step, self.check_dangle)
        if not ok:
            raise RuntimeError(f'assembled path failed dense checking at {bad[:5]}')
        path, _ = densify6(way, self.check_step, self.check_dangle)
        return result('ok', path=path, waypoints=way, min_rho=min_rho)


# ---------------------------------------------------------------------------------------------
# CLI body (paramotion voronoi plan321)
# ---------------------------------------------------------------------------------------------

def _pose_arg(values, default):
    if values is None:
        return np.asarray(default, dtype=float)
    v = np.asarray(values, dtype=float)
    return np.r_[v[:3], np.radians(v[3:])]


def run_cli(args, out):
    """Plan between two poses and write ``out/result.json`` and ``out/figure321.png``."""
    from tqdm import tqdm

    model = load_scene(args.scene) if args.scene else demo_model()
    start = _pose_arg(args.start, DEMO_START)
    goal = _pose_arg(args.goal, DEMO_GOAL)
    validate_pose(model, start, 'start')
    validate_pose(model, goal, 'goal')
    if args.samples < 10:
        raise UserError(f'--samples {args.samples}: need at least 10')
    planner = SampledVoronoiPlanner(model, n_samples=args.samples, seed=args.seed)
    stages = ('sample', 'retract', 'roadmap', 'search', 'verify')
    bar = tqdm(total=len(stages), desc='voronoi plan321', unit='stage', leave=False)

    def progress(stage):
        bar.set_postfix_str(stage)
        bar.update(1)

    res = planner.plan(start, goal, progress)
    bar.close()
    straight_ok = check_path6(model, np.vstack([start, goal]))[0]
    out.mkdir(parents=True, exist_ok=True)
    doc = {
        'status': res.status, 'reason': res.reason,
        'start': start.tolist(), 'goal': goal.tolist(),
        'pose_note': '[x, y, z] of P7 in m, [roll, pitch, yaw] ZYX in rad',
        'straight_line_free': bool(straight_ok),
        'min_rho': None if math.isnan(res.min_rho) else res.min_rho,
        'planning_time_s': res.planning_time,
        'stats': {k: int(v) if isinstance(v, (int, np.integer)) else v
                  for k, v in res.stats.items()},
        'waypoints': np.round(res.waypoints, 9).tolist(),
        'path': np.round(res.path, 9).tolist(),
    }
    (out / 'result.json').write_text(json.dumps(doc) + '\n')
    figure321(model, out / 'figure321.png', res.path if res.found else None, start, goal)
    if res.found:
        print(f'path found: {len(res.path)} poses, min rho {res.min_rho:.4g}, planning time '
              f'{res.planning_time:.2f} s (straight line free: {straight_ok}) -> {out}')
        return 0
    print(f'no path: {res.reason} -> {out}')
    return 1


def figure321(model, path_file, path, start, goal):
    """3-D view of the platform at start, along the path and at the goal, and the boxes."""
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt
    from mpl_toolkits.mplot3d.art3d import Poly3DCollection

    fig = plt.figure(figsize=(9, 8))
    ax = fig.add_subplot(projection='3d')
    for verts, tris, _ in model.meshes:
        ax.add_collection3d(Poly3DCollection(verts[tris], facecolor='tab:gray', alpha=0.35,
                                             edgecolor='k', linewidth=0.3))

    def draw(q, color, alpha, lw):
        p = model.world_points(q)
        for a, b in LEGS:
            ax.plot(*np.stack([p[a], p[b]]).T, color=color, alpha=alpha, linewidth=lw)
        tri = np.stack([p[7], p[8], p[9], p[7]])
        ax.plot(*tri.T, color=color, alpha=alpha, linewidth=lw + 1)

    poses = [start, goal]
    if path is not None and len(path):
        idx = np.linspace(0, len(path) - 1, 8).astype(int)[1:-1]
        for q in path[idx]:
            draw(q, 'tab:orange', 0.35, 0.8)
        ax.plot(*path[:, :3].T, color='red', linewidth=2, label='P7 path')
    draw(poses[0], 'black', 1.0, 1.5)
    draw(poses[1], 'tab:blue', 1.0, 1.5)
    base = np.array([model.fixed[k] for k in range(1, 7)])
    ax.scatter(*base.T, color='k', s=15)
    ax.set_xlabel('x (m)')
    ax.set_ylabel('y (m)')
    ax.set_zlabel('z (m)')
    ax.set_title('3-2-1 platform: start (black), goal (blue), intermediate poses (orange)')
    ax.set_box_aspect((1, 1, 0.9))
    if path is not None and len(path):
        ax.legend()
    fig.savefig(path_file, dpi=90)
    plt.close(fig)
