"""Completeness of the planar planner on the simplified Voronoi diagram, against an
independent flood fill of free configurations at a finer resolution than the planner's.

On random scenes (three random convex quadrilaterals in the paper's scene) the planner
(diagram sampled on a 3-unit grid in 15 deg slices) must find a path exactly when start and
goal are connected in free space, for queries whose platform is at least half a grid spacing
from every obstacle. Its "no path" is resolution-limited: where it answers "no path" for a
connected query, the planner at the flood fill's resolution (1.5 units, 7.5 deg) must find
the path, and this may happen at most once per scene (seed 8 has one: a query in the 5-unit
strip between the boundary square and the domain's edge). The reference does not use rho, the
diagram or the planner's grid: free configurations on a 1.5-unit grid in 7.5 deg slices,
decided by direct geometry (segment intersection, point in polygon, sides of the singular
lines), joined when the straight motion between grid neighbours passes a dense
direct-geometry check (samples and swept steps); start and goal join the component of a
nearby vertex they reach by a checked straight motion. P3 cannot cross the base line (a
singularity), so queries keep P3 below it and the fill covers y < 0.
"""
import math

import numpy as np
import pytest
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components
from test_voronoi_detours import clearance
from test_voronoi_planner import SQUARE, _bad_samples, bad_segments, independent_check

from voronoi_pkg.planar import Domain, planar_model
from voronoi_pkg.planner import VoronoiPlanner

FILL_H, FILL_DPHI = 1.5, math.radians(7.5)
PLANNER_H, PLANNER_DPHI_DEG = 3.0, 15.0
#: Queries keep the platform at least this far (Euclidean) from every obstacle: the planner's
#: "no path" is resolution-limited, a start or goal wedged closer than half its grid spacing
#: may retract onto a diagram piece the sampled diagram does not connect.
QUERY_CLEARANCE = PLANNER_H / 2


def _inside_any(p, obstacles):
    """P3 strictly inside one of the convex (counter-clockwise) obstacles."""
    out = np.zeros(len(p), dtype=bool)
    for poly in obstacles:
        poly = np.asarray(poly, dtype=float)
        e = np.roll(poly, -1, axis=0) - poly
        cross = (e[None, :, 0] * (p[:, None, 1] - poly[None, :, 1])
                 - e[None, :, 1] * (p[:, None, 0] - poly[None, :, 0]))
        out |= np.all(cross > 0, axis=1)
    return out


def _free(q, obstacles):
    hit, side, coll = _bad_samples(q, ((0.0, 0.0), (15.0, 0.0)), 10.0, SQUARE, obstacles)
    return ~hit & (side < 0) & (coll != 0) & ~_inside_any(q[:, :2], obstacles)


def flood_fill(obstacles):
    """Labels of the fine reference grid (x, y < 0, phi periodic), -1 where not free."""
    xs = np.arange(-30.0, 60.0 + 1e-9, FILL_H)
    ys = np.arange(-45.0, -FILL_H / 2, FILL_H)
    phis = -math.pi + FILL_DPHI * np.arange(int(round(2 * math.pi / FILL_DPHI)))
    P, Y, X = np.meshgrid(phis, ys, xs, indexing='ij')
    q = np.stack([X, Y, P], axis=-1)
    shape = X.shape
    free = _free(q.reshape(-1, 3), obstacles).reshape(shape)
    idx = np.arange(free.size).reshape(shape)
    us, vs = [], []
    steps = [((slice(None), ya, xa), (slice(None), yb, xb), 0.0)
             for dy, dx in ((0, 1), (1, 0), (1, 1), (1, -1))
             for ya, yb, xa, xb in [(slice(max(0, -dy), shape[1] - max(0, dy)),
                                     slice(max(0, dy), shape[1] - max(0, -dy)),
                                     slice(max(0, -dx), shape[2] - max(0, dx)),
                                     slice(max(0, dx), shape[2] - max(0, -dx)))]]
    steps += [((slice(0, -1),), (slice(1, None),), 0.0),
              ((slice(-1, None),), (slice(0, 1),), 2 * math.pi)]
    for sa, sb, wrap in steps:
        ok = free[sa] & free[sb]
        u, v = idx[sa][ok], idx[sb][ok]
        a = q.reshape(-1, 3)[u]
        b = q.reshape(-1, 3)[v].copy()
        b[:, 2] += wrap
        good = ~bad_segments(a, b, obstacles=obstacles, step_xy=0.1, step_phi=0.02)
        us.append(u[good])
        vs.append(v[good])
    u, v = np.concatenate(us), np.concatenate(vs)
    _, labels = connected_components(coo_matrix((np.ones(len(u)), (u, v)),
                                                shape=(free.size, free.size)), directed=False)
    labels = np.where(free.ravel(), labels, -1)
    return q.reshape(-1, 3), labels


def component_of(q, grid, labels, obstacles):
    """Component of the nearest free fill vertices reachable from ``q`` by a checked straight
    motion (None if none of the 12 nearest is)."""
    d = np.hypot(grid[:, 0] - q[0], grid[:, 1] - q[1]) \
        + 10.0 * np.abs(np.remainder(grid[:, 2] - q[2] + math.pi, 2 * math.pi) - math.pi)
    for i in np.argsort(d)[:12]:
        if labels[i] < 0:
            continue
        b = grid[i].copy()
        b[2] = q[2] + np.remainder(b[2] - q[2] + math.pi, 2 * math.pi) - math.pi
        if not bad_segments(q[None], b[None], obstacles=obstacles)[0]:
            return labels[i]
    return None


@pytest.mark.slow
@pytest.mark.parametrize('seed', [3, 8])
def test_path_found_iff_connected_in_free_space(seed):
    rng = np.random.default_rng(seed)
    obstacles = []
    for _ in range(3):
        c = rng.uniform([-15, -32], [45, -10])
        ang = np.sort(rng.uniform(0, 2 * np.pi, 4))
        obstacles.append([tuple(c + rng.uniform(4, 8) * np.array([np.cos(a), np.sin(a)]))
                          for a in ang])
    model = planar_model(((0.0, 0.0), (15.0, 0.0)), 10.0, [tuple(p) for p in SQUARE],
                         obstacles, Domain())
    grid, labels = flood_fill(obstacles)
    planner = VoronoiPlanner(model, h=PLANNER_H, dphi_deg=PLANNER_DPHI_DEG)
    fine = VoronoiPlanner(model, h=FILL_H, dphi_deg=math.degrees(FILL_DPHI))
    refined = 0
    answers = {'path': 0, 'no path': 0}
    comps = {}
    tries = 0
    while sum(answers.values()) < 14 and tries < 400:
        tries += 1
        q = rng.uniform([-30, -45, -math.pi], [60, -0.5, math.pi])
        if not _free(q[None], obstacles)[0] or model.rho(q) <= model.free_tol:
            continue
        if clearance(q[None], obstacles)[0] < QUERY_CLEARANCE:
            continue
        comp = component_of(q, grid, labels, obstacles)
        if comp is None:
            continue
        comps.setdefault(comp, []).append(q)
        # Pair with an earlier query: of the same component or, alternately, another one.
        same = comps[comp][:-1]
        other = [p for c, ps in comps.items() if c != comp for p in ps]
        pool = same if (len(comps[comp]) % 2 == 0 and same) or not other else other
        if not pool:
            continue
        p = pool[rng.integers(len(pool))]
        connected = component_of(p, grid, labels, obstacles) == comp
        res = planner.plan(p, q)
        if connected and not res.found:
            # Resolution-limited "no path": the planner at the flood fill's resolution
            # must find it (resolution completeness), and this may happen once per scene.
            refined += 1
            res = fine.plan(p, q)
            assert res.found, (p.tolist(), q.tolist(), res.reason)
        assert res.found == connected, (p.tolist(), q.tolist(), res.reason)
        answers['path' if res.found else 'no path'] += 1
        if res.found:
            assert independent_check(res.path, obstacles=obstacles) is None
    # Both answers occur: the scenes have several free components (inside and outside the
    # boundary square, and the two sides of the P2-P3-P4 singularity).
    assert answers['path'] >= 3 and answers['no path'] >= 3, answers
    assert refined <= 1, refined
