"""Spatial 3-2-1 platform: the pure condition against the leg Plucker matrix, box contacts and
containment against slab / separating-axis tests, leg-leg contacts against closest-point
geometry, leg-length limits, the retraction onto the simplified Voronoi diagram (two tied
contacts, rho higher) and the diagram roadmap on detour and walled-off scenes, every path
checked by those independent methods at a finer resolution than the planner's; the ablations
(``without``): each construct switched off, the path found crosses what it forbade."""
import json
import math

import numpy as np
import pytest

from paramotion.cli import main as cli_main
from paramotion.errors import UserError
from voronoi_pkg.predicates import bracket4
from voronoi_pkg.spatial321 import (
    DEMO_BASE,
    DEMO_GOAL,
    DEMO_START,
    LEGS,
    PLATFORM_EDGES,
    PURE_CONDITION,
    Spatial321Model,
    check_path6,
    demo_model,
    densify6,
    load_scene,
    robot_segment_pairs,
)
from voronoi_pkg.spatial321_roadmap import DiagramRoadmapPlanner, retract, tie_measure

RNG = np.random.default_rng(321)
# Independent checks run at half the planner's resolution (0.005 m, 0.01 rad).
FINE_STEP, FINE_DANGLE = 0.0025, 0.005


def pluecker_det(p):
    """det of the 6x6 matrix of the legs' Plucker coordinates (direction, moment): zero iff
    the legs' lines are linearly dependent, i.e. the platform is singular (independent of
    the determinant factorisation)."""
    rows = [np.concatenate([p[b] - p[a], np.cross(p[a], p[b])], axis=-1) for a, b in LEGS]
    return np.linalg.det(np.stack(rows, axis=-2))


def segment_hits_box(a, b, lo, hi):
    """Slab (Liang-Barsky) test: does segment ab meet the closed box [lo, hi]?"""
    d = b - a
    t0, t1 = np.zeros(len(a)), np.ones(len(a))
    for k in range(3):
        with np.errstate(divide='ignore', invalid='ignore'):
            ta = (lo[k] - a[:, k]) / d[:, k]
            tb = (hi[k] - a[:, k]) / d[:, k]
        par = np.abs(d[:, k]) < 1e-15
        outside = par & ((a[:, k] < lo[k]) | (a[:, k] > hi[k]))
        t0 = np.where(par, t0, np.maximum(t0, np.minimum(ta, tb)))
        t1 = np.where(par, t1, np.minimum(t1, np.maximum(ta, tb)))
        t1 = np.where(outside, -1.0, t1)
    return t0 <= t1


def triangle_hits_box(v0, v1, v2, lo, hi):
    """Separating axis theorem for triangle vs axis-aligned box (13 axes); a triangle inside
    the box overlaps it too."""
    c, h = 0.5 * (lo + hi), 0.5 * (hi - lo)
    v = [v0 - c, v1 - c, v2 - c]
    e = [v[1] - v[0], v[2] - v[1], v[0] - v[2]]
    axes = [np.tile(np.eye(3)[k], (len(v0), 1)) for k in range(3)]
    axes.append(np.cross(e[0], e[1]))
    axes += [np.cross(np.tile(np.eye(3)[k], (len(v0), 1)), ei) for k in range(3) for ei in e]
    hit = np.ones(len(v0), dtype=bool)
    for ax in axes:
        proj = np.stack([np.einsum('ij,ij->i', vi, ax) for vi in v])
        r = np.abs(ax) @ h
        hit &= ~((proj.min(axis=0) > r) | (proj.max(axis=0) < -r))
    return hit


def independent_free(model, q):
    """Free by direct geometry: no leg or platform overlap with a box (containment
    included), non-singular, legs within their length limits, inside the bounds."""
    p = model.points(q)
    free = np.abs(pluecker_det(p)) > 0
    for box in model.boxes:
        c, s = np.asarray(box['center']), np.asarray(box['size'])
        lo, hi = c - s / 2, c + s / 2
        for a, b in LEGS:
            free &= ~segment_hits_box(p[a], p[b], lo, hi)
        free &= ~triangle_hits_box(p[7], p[8], p[9], lo, hi)
    if model.leg_limits is not None:
        for a, b in LEGS:
            length = np.linalg.norm(p[b] - p[a], axis=-1)
            free &= (length > model.leg_limits[0]) & (length < model.leg_limits[1])
    return free & model.in_bounds(q)


def closest_params(a, b, c, d):
    """Parameters (s, t) of the closest points of the lines ab and cd (vectorised)."""
    u, v, w = b - a, d - c, a - c
    uu, uv, vv = (u * u).sum(-1), (u * v).sum(-1), (v * v).sum(-1)
    uw, vw = (u * w).sum(-1), (v * w).sum(-1)
    den = uu * vv - uv ** 2
    with np.errstate(divide='ignore', invalid='ignore'):
        s = (uv * vw - vv * uw) / den
        t = (uu * vw - uv * uw) / den
    return s, t


def legs_pass_through(model, samples):
    """Between consecutive samples, do two robot segments (legs, platform edges, sharing no
    point) pass through each other? Side of one line relative to the other (triple product)
    changes while the closest points lie inside both segments."""
    p = model.points(samples)
    out = np.zeros(len(samples) - 1, dtype=bool)
    for (a, b), (c, d) in robot_segment_pairs():
        side = np.sign(np.einsum('ij,ij->i', np.cross(p[b] - p[a], p[d] - p[c]), p[c] - p[a]))
        s, t = closest_params(p[a], p[b], p[c], p[d])
        inside = (s >= 0) & (s <= 1) & (t >= 0) & (t <= 1)
        out |= (side[1:] != side[:-1]) & (inside[1:] | inside[:-1])
    return out


def assert_path_independently_free(model, path):
    dense, _ = densify6(path, FINE_STEP, FINE_DANGLE)
    assert independent_free(model, dense).all()
    assert not legs_pass_through(model, dense).any()
    sign = np.sign(pluecker_det(model.points(dense)))
    assert np.all(sign == sign[0]) and sign[0] != 0


def test_pure_condition_equals_the_leg_pluecker_determinant():
    model = demo_model()
    q = model.sample(RNG, 300)
    q[:, 3:] = RNG.uniform(-1.2, 1.2, (300, 3))      # wide orientations too
    p = model.points(q)
    product = np.prod([bracket4(*(p[i] for i in f)) for f in PURE_CONDITION], axis=0)
    np.testing.assert_allclose(pluecker_det(p), -product, rtol=1e-8, atol=1e-14)
    # A flat tetrahedron (P7 on the base plane z = 0) is singular and is named.
    failures = model.diagnose(np.array([0.0, 0.0, 0.0, 0.0, 0.0, 0.0]))
    assert any('[p1 p2 p3 p7]' in name for name, _ in failures)


def test_box_contacts_and_containment_match_slab_and_separating_axis_tests():
    """Every sampled pose, platform inside the box included, is classified as the direct
    geometry classifies it (legs of any length here)."""
    model = Spatial321Model(demo_model().base, demo_model().platform,
                            ({'center': (0.1, 0.1, 0.6), 'size': (0.55, 0.5, 0.3)},),
                            (-0.3, -0.3, 0.3), (0.5, 0.5, 1.0), math.radians(40))
    q = model.sample(RNG, 4000)
    rho = model.rho(q)
    p = model.points(q)
    box = model.boxes[0]
    c, s = np.asarray(box['center']), np.asarray(box['size'])
    lo, hi = c - s / 2, c + s / 2
    inside = np.all([np.all((p[k] > lo) & (p[k] < hi), axis=1) for k in (7, 8, 9)], axis=0)
    assert inside.sum() >= 20                 # the comparison covers containment
    ok = np.abs(rho) > 1e-7
    expected = independent_free(model, q)
    assert 0.1 < expected[ok].mean() < 0.9     # a mix of free and colliding poses
    assert np.array_equal((rho > 0)[ok], expected[ok])


def test_platform_inside_an_obstacle_is_a_collision():
    """A platform fully inside a box touches no face: every segment-face contact says free,
    only the containment contact forbids it."""
    box = {'center': (0.2, 0.1, 0.8), 'size': (0.7, 0.6, 0.3)}
    model = Spatial321Model(DEMO_BASE, demo_model().platform, (box,), (-0.25, -0.3, 0.45),
                            (0.4, 0.4, 1.1), math.radians(30))
    q = np.array([0.05, -0.05, 0.8, 0.0, 0.0, 0.0])
    p = model.points(q)
    lo = np.subtract(box['center'], np.divide(box['size'], 2))
    hi = np.add(box['center'], np.divide(box['size'], 2))
    assert all(np.all((p[k] > lo) & (p[k] < hi)) for k in (7, 8, 9))
    failures = model.diagnose(q)
    names = [n for n, _ in failures]
    assert names and all(n.startswith('containment') or n.startswith('collision: leg')
                         for n in names)
    assert sum(n.startswith('containment') for n in names) == 3
    assert not any('platform' in n for n in names if n.startswith('collision'))
    assert model.rho(q) < 0 and not independent_free(model, q[None])[0]
    with pytest.raises(UserError, match='containment: platform vertex P7 inside box 0'):
        DiagramRoadmapPlanner(model, n_samples=20).plan(q, DEMO_GOAL)


def _crossing_pair(model, rng):
    """Two nearby free poses between which two legs pass through each other (independent
    closest-point geometry), found by a seeded random search."""
    for _ in range(200):
        a = model.sample(rng, 4000)
        b = a + rng.normal(0, 0.03, a.shape) * model.scale ** -1
        ok = model.in_bounds(b) & (model.rho(a) > 1e-6) & (model.rho(b) > 1e-6)
        idx = np.flatnonzero(ok)
        for i in idx:
            seg, _ = densify6(np.vstack([a[i], b[i]]), FINE_STEP, FINE_DANGLE)
            if legs_pass_through(model, seg).any():
                return a[i], b[i]
    raise AssertionError('no crossing found')


def test_legs_passing_through_each_other_are_refused():
    model = Spatial321Model(DEMO_BASE, demo_model().platform, (), (-0.4, -0.4, 0.3),
                            (0.6, 0.6, 1.1), math.radians(60))
    assert len(robot_segment_pairs()) == 17
    qa, qb = _crossing_pair(model, np.random.default_rng(5))
    # Both poses are free, yet the straight motion between them makes two legs cross.
    assert model.rho(qa) > 0 and model.rho(qb) > 0
    assert not check_path6(model, np.vstack([qa, qb]))[0]
    # At the crossing itself (bisection on the side of the two lines) rho is ~0: the contact
    # is a hypersurface of configuration space.
    signs, cross = model.thin_state(np.vstack([qa, qb]))
    k = int(np.flatnonzero((signs[:, 0] != signs[:, 1]) & (cross[:, 0] | cross[:, 1]))[0])
    lo, hi = 0.0, 1.0
    for _ in range(50):
        mid = 0.5 * (lo + hi)
        s, _ = model.thin_state(qa + mid * (qb - qa))
        lo, hi = (mid, hi) if s[k] == signs[k, 0] else (lo, mid)
    q_touch = qa + lo * (qb - qa)
    assert model.rho(q_touch) < 1e-9 * float(model.rho(qa))
    name = [n for n, _ in model.diagnose(q_touch) if n.startswith('leg-leg')]
    (a, b), (c, d) = robot_segment_pairs()[k]
    assert name == [f'leg-leg: P{a}P{b} passes through P{c}P{d}']
    assert ((a, b) in LEGS or (a, b) in PLATFORM_EDGES)


def test_leg_length_limits_are_parameters_and_refuse_out_of_range_poses():
    free_model = demo_model(leg_limits=None)
    limited = demo_model(leg_limits=(0.55, 1.2))
    q = free_model.sample(RNG, 3000)
    lengths = free_model.leg_lengths(q)
    in_range = np.all((lengths > 0.55) & (lengths < 1.2), axis=1)
    rho_free, rho_lim = free_model.rho(q), limited.rho(q)
    assert (~in_range).sum() > 100 and in_range.sum() > 100
    # Out of range is never free; in range, the limits change nothing about freedom.
    assert not np.any(rho_lim[~in_range] > 0)
    np.testing.assert_array_equal(rho_lim[in_range] > 0, rho_free[in_range] > 0)
    long_pose = q[np.flatnonzero((rho_free > 1e-6) & (lengths.max(axis=1) > 1.25))[0]]
    with pytest.raises(UserError, match=r'leg length: \|P\dP\d\| <= 1.2 m'):
        DiagramRoadmapPlanner(limited, n_samples=20).plan(long_pose, DEMO_GOAL)
    with pytest.raises(UserError, match='need 0 <= min < max'):
        demo_model(leg_limits=(1.0, 0.5))


def test_retraction_climbs_rho_until_two_contacts_tie():
    model = demo_model()
    q = model.sample(np.random.default_rng(7), 400)
    q = q[model.rho(q) > model.free_tol]
    before = tie_measure(model, q)
    moved_from = before['dist'] > 0.01           # clearly off the diagram at the start
    assert moved_from.sum() > 50
    pts, on_tie, steps, _ = retract(model, q[moved_from])
    assert on_tie.mean() > 0.95
    after = tie_measure(model, pts[on_tie])
    vals, _ = model.contact_values(pts[on_tie])
    # Two distinct contacts share the minimum: gap tiny against rho, and the pose is within
    # 1e-3 (scaled metric) of their tie set.
    assert np.all(after['first'] != after['second'])
    assert np.all(after['gap'] <= 1e-3 * np.maximum(after['rho'], 1e-12) + 1e-9)
    assert np.all(after['dist'] <= 1e-3)
    np.testing.assert_allclose(vals.min(axis=0), after['rho'])
    # rho grew (ascent), and the retraction really moved the pose.
    assert np.all(model.rho(pts[on_tie]) > model.rho(q[moved_from][on_tie]))
    disp = np.linalg.norm((pts - q[moved_from]) * model.scale, axis=1)
    assert np.median(disp) > 0.01


@pytest.fixture(scope='module')
def demo_result():
    model = demo_model()
    planner = DiagramRoadmapPlanner(model, n_samples=200, seed=0)
    return model, planner, planner.plan(DEMO_START, DEMO_GOAL)


@pytest.mark.slow
def test_demo_detour_is_found_on_the_diagram_and_verified_independently(demo_result):
    model, planner, res = demo_result
    assert res.found, res.reason
    np.testing.assert_allclose(res.path[0], DEMO_START)
    np.testing.assert_allclose(res.path[-1], DEMO_GOAL)
    # The straight 6-D line is blocked, so the planner had to go around.
    line, _ = densify6(np.vstack([DEMO_START, DEMO_GOAL]), FINE_STEP, FINE_DANGLE)
    assert not independent_free(model, line).all()
    assert_path_independently_free(model, res.path)
    assert res.min_rho > 0
    # Most of the path runs on the diagram, far more than random free poses would.
    rand = model.sample(np.random.default_rng(3), 1500)
    rand = rand[model.rho(rand) > model.free_tol]
    random_share = np.mean(tie_measure(model, rand)['dist'] <= planner.diagram_tol)
    assert res.stats['on_diagram_fraction'] >= 0.8
    assert res.stats['on_diagram_fraction'] > 3 * random_share


def _window_model(window):
    """A wall across x = 0 (pillars in y); with ``window`` a gap y in (-0.15, 0.25) lets
    P7 through. P7 stays at z in [0.6, 0.7], so without the gap P7 itself would have to
    enter the wall."""
    plat = {7: (0.0, 0.0, 0.0), 8: (-0.2, 0.12, 0.0), 9: (-0.2, -0.12, 0.0)}
    if window:
        boxes = ({'center': (0.0, -0.45, 0.95), 'size': (0.06, 0.6, 0.8)},
                 {'center': (0.0, 0.55, 0.95), 'size': (0.06, 0.6, 0.8)})
    else:
        boxes = ({'center': (0.0, 0.05, 0.95), 'size': (0.06, 1.6, 0.8)},)
    return Spatial321Model(DEMO_BASE, plat, boxes, (-0.25, -0.3, 0.6), (0.4, 0.4, 0.7),
                           math.radians(20), (0.3, 1.6))


WALL_START = (-0.2, 0.3, 0.65, 0.0, 0.0, 0.0)
WALL_GOAL = (0.3, 0.3, 0.65, 0.0, 0.0, 0.0)


@pytest.mark.slow
def test_window_detour_found_and_walled_off_answered_no_path():
    window = _window_model(True)
    planner = DiagramRoadmapPlanner(window, n_samples=200, seed=0)
    res = planner.plan(WALL_START, WALL_GOAL)
    line, _ = densify6(np.vstack([WALL_START, WALL_GOAL]), FINE_STEP, FINE_DANGLE)
    assert not independent_free(window, line).all()       # straight through the pillar
    assert res.found, res.reason
    assert_path_independently_free(window, res.path)
    gate = np.abs(res.path[:, 0]) < 0.03
    assert np.all((res.path[gate, 1] > -0.15) & (res.path[gate, 1] < 0.25))
    # Same scene without the window, same sampling: no path.
    wall = _window_model(False)
    wall_planner = DiagramRoadmapPlanner(wall, n_samples=200, seed=0)
    res = wall_planner.plan(WALL_START, WALL_GOAL)
    assert res.status == 'no_path' and 'different connected components' in res.reason
    # Not for want of samples: the same sampling has free poses on both sides of the wall.
    q = wall_planner.samples()
    q = q[wall.rho(q) > wall.free_tol]
    assert (q[:, 0] < -0.03).sum() > 20 and (q[:, 0] > 0.03).sum() > 20
    # Independent check: x of P7 is continuous from -0.2 to 0.3, so any path has a pose with
    # P7 at x in (-0.03, 0.03); every such pose in the bounds collides (direct geometry).
    q = wall.sample(np.random.default_rng(11), 20000)
    q[:, 0] = np.random.default_rng(12).uniform(-0.0299, 0.0299, len(q))
    assert not independent_free(wall, q).any()
    assert not np.any(wall.rho(q) > 0)


def test_singularity_cell_certificate_and_bad_poses():
    model = Spatial321Model(demo_model().base, demo_model().platform, (),
                            (-0.3, -0.3, 0.3), (0.5, 0.5, 1.0), math.radians(89))
    planner = DiagramRoadmapPlanner(model, n_samples=200)
    q = model.sample(RNG, 5000)
    signs = model.singular_signs(q)
    start = np.array(DEMO_START)
    s0 = model.singular_signs(start)
    other = np.flatnonzero(np.any(signs != s0[:, None], axis=0) & (model.rho(q) > 1e-6))
    res = planner.plan(start, q[other[0]])
    assert res.status == 'no_path' and 'singularity' in res.reason
    assert 'samples' not in res.stats          # answered before sampling
    demo = DiagramRoadmapPlanner(demo_model(), n_samples=100)
    inside = (0.2, 0.0, 0.9, 0.0, 0.0, 0.0)      # platform through the hanging block
    with pytest.raises(UserError, match='platform edge P\\dP\\d crosses face'):
        demo.plan(inside, DEMO_GOAL)
    with pytest.raises(UserError, match='outside the planning bounds'):
        demo.plan(DEMO_START, (0.0, 0.0, 3.0, 0.0, 0.0, 0.0))


@pytest.mark.slow
def test_cli_plan321_writes_result_and_figure(tmp_path):
    out = tmp_path / 'out'
    window = tmp_path / 'window.json'
    window.write_text(json.dumps({
        'platform': {'7': [0, 0, 0], '8': [-0.2, 0.12, 0], '9': [-0.2, -0.12, 0]},
        'boxes': [{'center': [0.0, -0.45, 0.95], 'size': [0.06, 0.6, 0.8]},
                  {'center': [0.0, 0.55, 0.95], 'size': [0.06, 0.6, 0.8]}],
        'bounds': {'position_min': [-0.25, -0.3, 0.6], 'position_max': [0.4, 0.4, 0.7],
                   'angle_max_deg': 20},
        'leg_length': {'min': 0.2, 'max': 2.0}}))
    pose = ['--start', '-0.2', '0.3', '0.65', '0', '0', '0',
            '--goal', '0.3', '0.3', '0.65', '0', '0', '0']
    assert cli_main(['voronoi', 'plan321', '--out', str(out), '--scene', str(window),
                     '--samples', '200', '--leg-min', '0.3', '--leg-max', '1.6'] + pose) == 0
    doc = json.loads((out / 'result.json').read_text())
    assert doc['status'] == 'ok' and doc['straight_line_free'] is False
    assert doc['leg_length_limits_m'] == [0.3, 1.6]
    assert doc['resolution']['samples'] == 200
    assert 0 < doc['stats']['on_diagram_fraction'] <= 1
    assert doc['stats']['retracted_on_diagram'] <= doc['stats']['free_samples']
    assert (out / 'figure321.png').read_bytes()[:4] == b'\x89PNG'
    scene = tmp_path / 'bad.json'
    scene.write_text('{"boxes": [{"center": [0, 0, 1], "size": [0, 1, 1]}]}')
    with pytest.raises(UserError, match='size must be positive'):
        load_scene(scene)
    scene.write_text('{"boxes": [{"center": [-0.4, -0.3, 0.05], "size": [0.2, 0.2, 0.2]}]}')
    with pytest.raises(UserError, match='contains or touches base point P1'):
        load_scene(scene)
    assert cli_main(['voronoi', 'plan321', '--out', str(tmp_path / 'o2'),
                     '--leg-min', '0.3']) == 2
    assert not (tmp_path / 'o2').exists()


@pytest.mark.slow
def test_unseen_random_scene_queries_are_verified():
    """Random box and random free start/goal: every path found passes the independent
    check, and every 'no path' names the roadmap resolution."""
    rng = np.random.default_rng(99)
    base = demo_model()
    box = {'center': tuple(rng.uniform([0.0, 0.0, 0.8], [0.3, 0.3, 0.9])),
           'size': tuple(rng.uniform(0.08, 0.15, 3))}
    model = Spatial321Model(base.base, base.platform, (box,), (-0.25, -0.3, 0.45),
                            (0.4, 0.4, 1.1), math.radians(30), (0.3, 1.6))
    q = model.sample(rng, 3000)
    s0 = model.singular_signs(np.array(DEMO_START))
    ok = (model.rho(q) > 1e-5) & np.all(model.singular_signs(q) == s0[:, None], axis=0)
    q = q[ok]
    planner = DiagramRoadmapPlanner(model, n_samples=200, seed=1)
    found = 0
    for i in range(2):
        res = planner.plan(q[2 * i], q[2 * i + 1])
        if res.found:
            found += 1
            assert_path_independently_free(model, res.path)
        else:
            assert 'Halton samples' in res.reason
    assert found >= 1


# -- ablations (--without NAME): the constructs are load-bearing ------------------------------

#: A free pose of the demo scene on the other side of the singularity [p4 p7 p8 p9] = 0 from
#: DEMO_START (P4 crosses the platform's plane); found by sampling the demo bounds.
ACROSS_SINGULARITY = (-0.154, -0.143, 0.518, math.radians(-25.21), math.radians(19.77),
                      math.radians(-14.44))


def _wall(without=()):
    w = _window_model(False)
    return Spatial321Model(w.base, w.platform, w.boxes, w.position_min, w.position_max,
                           w.angle_max, w.leg_limits, without=without)


def test_without_singularity_the_path_crosses_a_singular_configuration():
    """Start and goal in different cells of [p4 p7 p8 p9]: the full planner answers no path by
    the certificate; without the singularity factors it returns a path along which the leg
    Plucker determinant (independent of the factorisation) changes sign."""
    res = DiagramRoadmapPlanner(demo_model(), n_samples=100).plan(DEMO_START,
                                                                  ACROSS_SINGULARITY)
    assert res.status == 'no_path' and '[p4 p7 p8 p9] changes sign' in res.reason
    ablated = demo_model(without=['singularity'])
    assert not ablated.singular_keys and len(ablated.contacts) == len(demo_model().contacts) - 3
    res = DiagramRoadmapPlanner(ablated, n_samples=100).plan(DEMO_START, ACROSS_SINGULARITY)
    assert res.found, res.reason
    dense, _ = densify6(res.path, FINE_STEP, FINE_DANGLE)
    sign = np.sign(pluecker_det(demo_model().points(dense)))
    assert np.any(sign != sign[0])
    assert not check_path6(demo_model(), res.path)[0]


def test_without_collision_the_path_goes_through_the_wall():
    """A wall across the bounds between start and goal (same singularity cell): with the
    robot-obstacle contacts the diagram search answers no path; without them the planner
    returns a path that direct geometry (slab and separating-axis tests) finds in the wall."""
    res = DiagramRoadmapPlanner(_wall(), n_samples=100).plan(WALL_START, WALL_GOAL)
    assert res.status == 'no_path' and 'different connected components' in res.reason
    res = DiagramRoadmapPlanner(_wall(['collision']), n_samples=100).plan(WALL_START,
                                                                         WALL_GOAL)
    assert res.found, res.reason
    dense, _ = densify6(res.path, FINE_STEP, FINE_DANGLE)
    assert not independent_free(_wall(), dense).all()
    # Only the obstacle contacts are gone: the path still avoids singularities.
    sign = np.sign(pluecker_det(_wall().points(dense)))
    assert np.all(sign == sign[0])


@pytest.mark.parametrize('without, words', [
    (['bogus'], "unknown construct 'bogus'"),
    (['singularity', 'collision'], 'no predicate'),
])
def test_bad_spatial_ablations_are_refused(without, words):
    with pytest.raises(UserError, match=words):
        demo_model(without=without)


def test_cli_plan321_bad_without_gives_one_line(tmp_path, capsys):
    code = cli_main(['voronoi', 'plan321', '--without', 'walls', '--out',
                     str(tmp_path / 'never')])
    assert code == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and 'walls' in err[0]
    assert not (tmp_path / 'never').exists()


def test_cli_plan321_without_is_recorded(tmp_path):
    out = tmp_path / 'o'
    goal = [str(v) for v in ACROSS_SINGULARITY[:3]] + [
        str(math.degrees(v)) for v in ACROSS_SINGULARITY[3:]]
    code = cli_main(['voronoi', 'plan321', '--goal', *goal, '--samples', '30',
                     '--without', 'singularity', '--out', str(out)])
    assert code == 0
    doc = json.loads((out / 'result.json').read_text())
    assert doc['without'] == ['singularity'] and doc['status'] == 'ok'
