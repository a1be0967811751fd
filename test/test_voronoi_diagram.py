"""The simplified Voronoi diagram's construction, tested directly (voronoi_pkg.ties and
voronoi_pkg.diagram): every diagram node is a tie of the two smallest contacts with no third
smaller, and on hand-made scenes the diagram's vertices and edges are the hand-computed ones.

Hand-made scene: the platform (length 10) alone in the square [-40, 40]^2 (no base, so no
singularity), planned inside the square (domain [-39.5, 39.5]^2). At phi = 0 the four wall
contacts are, by hand from the determinants of section 6 (P3 = (x, y), P4 = P3 + (10, 0)):
left 80 (x + 40), right 80 (30 - x), bottom 80 (y + 40), top 80 (40 - y). Free space in the
slice is the rectangle (-40, 30) x (-40, 40); the diagram is its straight skeleton: a
vertical edge x = -5 between the vertices (-5, -5) and (-5, 5), where three walls tie, and
four diagonals from those vertices to the corners. At phi = 90 deg the platform is vertical
and the skeleton turns over: vertices (-5, -5) and (5, -5).
"""
import math

import numpy as np
import pytest

from voronoi_pkg.diagram import diagram_slices, grid_axes, slice_fields, tie_segments
from voronoi_pkg.planar import Domain, NamedPredicate, PlanarModel, paper_model
from voronoi_pkg.planner import VoronoiPlanner
from voronoi_pkg.predicates import Not, segments_cross
from voronoi_pkg.spatial321 import demo_model
from voronoi_pkg.spatial321_roadmap import tie_measure
from voronoi_pkg.ties import on_diagram, tie_gap, tie_tolerance, two_smallest

# Spacing chosen so that no hand-computed vertex falls on a grid line.
H = 79.0 / 111


def box_model():
    fixed = {5: (-40.0, 40.0), 6: (-40.0, -40.0), 7: (40.0, -40.0), 8: (40.0, 40.0)}
    ring = [(5, 6), (6, 7), (7, 8), (8, 5)]
    preds = [NamedPredicate(f'wall P{a}P{b}', 'collision', Not(segments_cross(a, b, 3, 4)))
             for a, b in ring]
    return PlanarModel(fixed, {3: (0.0, 0.0), 4: (10.0, 0.0)}, preds,
                       Domain((-39.5, 39.5), (-39.5, 39.5), (-math.pi, math.pi)))


def one_slice(model, phi, h=H, program='total'):
    xs, ys = grid_axes(model.domain, h)
    return diagram_slices(model, slice_fields(model, np.array([phi]), xs, ys, program),
                          program)[0]


def chains(sl):
    """The diagram graph with its degree-2 nodes contracted: (vertices of degree != 2 with
    their degrees, list of chains as node-id lists between them)."""
    n = len(sl.xyz)
    adj = [[] for _ in range(n)]
    for a, b in sl.edges:
        adj[a].append(b)
        adj[b].append(a)
    deg = np.array([len(a) for a in adj])
    ends = set(np.flatnonzero(deg != 2).tolist())
    seen, out = set(), []
    for v in ends:
        for w in adj[v]:
            if (v, w) in seen:
                continue
            path = [v, w]
            while path[-1] not in ends:
                nxt = [u for u in adj[path[-1]] if u != path[-2]]
                path.append(nxt[0])
            seen.add((path[-1], path[-2]))
            seen.add((v, w))
            out.append(path)
    return {v: int(deg[v]) for v in ends}, out


def hand_walls(q):
    """The four wall contacts of the box scene by hand (valid inside the box)."""
    x, y, phi = q[:, 0], q[:, 1], q[:, 2]
    dx, dy = 10 * np.cos(phi), 10 * np.sin(phi)
    return np.stack([80 * (x + np.minimum(0, dx) + 40), 80 * (40 - x - np.maximum(0, dx)),
                     80 * (y + np.minimum(0, dy) + 40), 80 * (40 - y - np.maximum(0, dy))])


@pytest.mark.parametrize('phi, vertices, corners', [
    (0.0, [(-5.0, -5.0), (-5.0, 5.0)], [(-40, -40), (-40, 40), (30, -40), (30, 40)]),
    (math.pi / 2, [(-5.0, -5.0), (5.0, -5.0)], [(-40, -40), (40, -40), (-40, 30), (40, 30)]),
])
def test_box_scene_diagram_is_the_hand_computed_skeleton(phi, vertices, corners):
    model = box_model()
    sl = one_slice(model, phi)
    # Every node is a tie of the two smallest walls, computed by hand, not by rho.
    walls = np.sort(hand_walls(sl.xyz), axis=0)
    np.testing.assert_allclose(walls[0], walls[1], atol=1e-9 * 80 * 80)
    # Vertices: the two junctions, exactly where three walls tie.
    junction = sl.xyz[sl.pair == -1, :2]
    assert len(junction) == 2
    np.testing.assert_allclose(sorted(map(tuple, junction)), sorted(vertices), atol=1e-9)
    # Topology: two vertices of degree 3, four ends; five edges (one between the vertices,
    # four diagonals to the corners).
    degree, edges = chains(sl)
    assert sorted(degree.values()) == [1, 1, 1, 1, 3, 3]
    assert len(edges) == 5
    ends = np.array([sl.xyz[v, :2] for v, d in degree.items() if d == 1])
    for c in corners:
        assert np.min(np.hypot(*(ends - c).T)) < 2 * H + 0.75
    lengths = sorted(float(np.sum(np.hypot(*np.diff(sl.xyz[e, :2], axis=0).T))) for e in edges)
    assert lengths[0] == pytest.approx(10.0, abs=1e-9)
    np.testing.assert_allclose(lengths[1:], 35 * math.sqrt(2), atol=2 * H + 0.75)
    # The drawing shows the same pieces.
    xs, ys = grid_axes(model.domain, H)
    assert len(tie_segments(model, phi, xs, ys)) == len(sl.edges)


def test_singularity_diagram_of_the_paper_robot_by_hand():
    """P1 alone (section 6): contacts |[p1 p2 p3]| = 15 |y| and |[p2 p3 p4]|. At phi = 0 the
    latter is 10 |y|, never equal to 15 |y| off the singularity: no diagram. At phi = 90 deg
    it is 10 |x - 15|: the diagram is the four rays y = +-2/3 (x - 15) from P2, each in its
    own singularity cell, without a vertex (they would meet at P2, which is singular)."""
    model = paper_model()
    assert len(one_slice(model, 0.0, program='singularity').xyz) == 0
    sl = one_slice(model, math.pi / 2, program='singularity')
    x, y = sl.xyz[:, 0], sl.xyz[:, 1]
    np.testing.assert_allclose(np.abs(y), 2 / 3 * np.abs(x - 15), atol=1e-9)
    assert not np.any(sl.pair == -1)
    degree, edges = chains(sl)
    assert len(edges) == 4 and sorted(set(degree.values())) == [1]
    quadrants = {(bool(np.sign(sl.xyz[e[1], 0] - 15) > 0), bool(sl.xyz[e[1], 1] > 0))
                 for e in edges}
    assert len(quadrants) == 4


def test_every_paper_diagram_node_is_a_tie_of_the_two_smallest_contacts():
    """All slices of the paper scene (5 deg apart, 1-unit grid): at every node the two
    contacts named by its pair are the smallest (no third contact, decided by another
    determinant, is smaller) and tie within the tolerance; junctions tie three contacts.
    Edge midpoints: straight pieces of one tie line are exact; chords across a bend that
    the construction could not place in the cell stay within half a grid spacing."""
    model = paper_model()
    xs, ys = grid_axes(model.domain, 1.0)
    phis = np.radians(np.arange(-180, 180, 5.0))
    slices = diagram_slices(model, slice_fields(model, phis, xs, ys))
    n_c = model.programs['total'].n_contacts
    q = np.vstack([s.xyz for s in slices])
    pair = np.concatenate([s.pair for s in slices])
    assert len(q) > 10000
    vals, codes = model.contact_values(q)
    assert on_diagram(vals, codes, model.free_tol).all()
    cols = np.flatnonzero(pair >= 0)
    a, b = pair[cols] // n_c, pair[cols] % n_c
    fa, fb = vals[a, cols], vals[b, cols]
    rho = vals[:, cols].min(axis=0)
    tol = tie_tolerance(fa, fb, model.free_tol)
    assert np.all(np.abs(fa - fb) <= tol) and np.all(np.minimum(fa, fb) <= rho + tol)
    assert np.all(codes[a, cols] != codes[b, cols])
    others = vals[:, cols].copy()
    others[a, np.arange(len(cols))] = np.inf
    others[b, np.arange(len(cols))] = np.inf
    distinct = (codes[:, cols] != codes[a, cols]) & (codes[:, cols] != codes[b, cols])
    assert np.all(np.where(distinct, others, np.inf) >= np.maximum(fa, fb) - tol)
    # Junctions: three contacts with distinct determinants tie.
    j = np.flatnonzero(pair == -1)
    assert len(j) > 100
    _, f1, _, f2 = two_smallest(vals[:, j], codes[:, j])
    assert np.all(f2 - f1 <= tie_tolerance(f1, f2, model.free_tol))
    # Edges.
    mids = np.vstack([s.xyz[s.edges].mean(axis=1) for s in slices if len(s.edges)])
    vals, codes = model.contact_values(mids)
    exact = on_diagram(vals, codes, model.free_tol)
    assert exact.mean() >= 0.999, exact.mean()
    gap = tie_gap(vals, codes)
    eps = 1e-4
    grad = [(tie_gap(*model.contact_values(mids[~exact] + d))
             - tie_gap(*model.contact_values(mids[~exact] - d))) / (2 * eps)
            for d in (np.array([eps, 0, 0]), np.array([0, eps, 0]))]
    dist = gap[~exact] / np.maximum(np.hypot(*grad), 1e-300)
    assert np.all(dist <= 0.5), dist.max()


def test_valley_creases_inside_a_contact_are_not_the_diagram():
    """The box scene's bottom wall at phi = 0 is decided by two determinants that are equal
    everywhere ([p6 p7 p3] = [p6 p7 p4], P3 and P4 at one height): a change of the deciding
    determinant inside one contact, which is no tie of two contacts. The diagram there is
    still the hand-computed skeleton (the test above); counted the other way, every change of
    the deciding determinant would add those creases."""
    model = box_model()
    q = np.array([[-5.0, -30.0, 0.0]])
    vals, codes = model.contact_values(q)
    prog = model.programs['total']
    # The bottom wall (contact 1) is the smallest, and two of its determinants are equal.
    assert int(np.argmin(vals[:, 0])) == 1
    keys = [prog.keys.index(k) for k in prog.keys if set(k) in ({3, 6, 7}, {4, 6, 7})]
    dets = model.determinants(q)
    assert len(keys) == 2 and dets[keys[0], 0] == pytest.approx(dets[keys[1], 0])
    assert not on_diagram(vals, codes, model.free_tol)[0]


def test_planar_retraction_ends_on_the_diagram():
    model = paper_model()
    planner = VoronoiPlanner(model)
    rng = np.random.default_rng(1)
    q = rng.uniform([-30, -45, -math.pi], [60, 45, math.pi], (400, 3))
    q = q[model.rho(q) > model.free_tol][:40]
    ends = []
    for p in q:
        chain, on = planner.retract(p)
        assert np.all(np.diff(model.rho(chain)) >= -model.free_tol)
        if on:
            ends.append(chain[-1])
    assert len(ends) >= 0.9 * len(q), (len(ends), len(q))
    vals, codes = model.contact_values(np.array(ends))
    assert on_diagram(vals, codes, model.free_tol).all()


def test_the_321_planner_measures_ties_with_the_same_definition():
    """tie_measure's gap is ties.tie_gap of the model's contacts: one definition."""
    model = demo_model()
    rng = np.random.default_rng(2)
    q = model.sample(rng, 300)
    meas = tie_measure(model, q)
    vals, codes = model.contact_values(q)
    np.testing.assert_array_equal(meas['gap'], tie_gap(vals, codes))
