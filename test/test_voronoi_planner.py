"""Planar planner on the simplified Voronoi diagram: the paper's query, "no path" answers,
bad input and the CLI (completeness: test_voronoi_completeness.py; detours:
test_voronoi_detours.py).

Paths are checked by an independent checker (direct geometry, not the planner's rho): every
0.01 rad / 0.05 units along straight interpolation, P3 stays on one side of the base line,
P2-P3-P4 never become collinear, and the platform crosses neither the base nor the boundary.
"""
import json
import math

import numpy as np
import pytest

from paramotion.cli import main as cli_main
from paramotion.errors import UserError
from voronoi_pkg.diagram import grid_axes, slice_fields
from voronoi_pkg.grid_baseline import ClearanceGridPlanner
from voronoi_pkg.measures import on_diagram_share
from voronoi_pkg.planar import (
    PAPER_GOAL,
    PAPER_START,
    Domain,
    load_scene,
    paper_model,
    planar_model,
)
from voronoi_pkg.planner import ATTACH, RETRACTION, SLICE_LINK, SLICE_PIECE, VoronoiPlanner

SQUARE = np.array([[-25, 40], [-25, -40], [55, -40], [55, 40]], dtype=float)


def _cross2(a, b):
    return a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0]


def _segments_intersect(p, r, q, s):
    """Closed segments p->p+r and q->q+s intersect (including touching): vectorised, by the
    parametric method (independent of the determinant predicates)."""
    rxs = _cross2(r, s)
    qp = q - p
    parallel = np.abs(rxs) < 1e-12
    with np.errstate(divide='ignore', invalid='ignore'):
        t = _cross2(qp, s) / rxs
        u = _cross2(qp, r) / rxs
    hit = ~parallel & (t >= 0) & (t <= 1) & (u >= 0) & (u <= 1)
    # Collinear overlap.
    col = parallel & (np.abs(_cross2(qp, r)) < 1e-12)
    rr = np.maximum(np.sum(r * r, axis=-1), 1e-300)
    t0 = np.sum(qp * r, axis=-1) / rr
    t1 = t0 + np.sum(s * r, axis=-1) / rr
    hit |= col & (np.maximum(t0, t1) >= 0) & (np.minimum(t0, t1) <= 1)
    return hit


def _bad_samples(q, base, length, boundary, obstacles):
    """Per-sample failure flags and the reasons, by direct geometry (see independent_check).
    Singularity sides are returned as sign arrays for the caller to compare."""
    p1, p2 = np.asarray(base[0], dtype=float), np.asarray(base[1], dtype=float)
    p3 = q[:, :2]
    dirv = length * np.stack([np.cos(q[:, 2]), np.sin(q[:, 2])], axis=1)
    p4 = p3 + dirv
    side = np.sign(_cross2(p2 - p1, p3 - p1))
    coll = np.sign(_cross2(p3 - p2, p4 - p2))
    edges = [(p1, p2)]
    if boundary is not None and len(boundary):
        edges += [(boundary[i], boundary[(i + 1) % len(boundary)])
                  for i in range(len(boundary))]
    for poly in obstacles:
        poly = np.asarray(poly, dtype=float)
        edges += [(poly[i], poly[(i + 1) % len(poly)]) for i in range(len(poly))]
    hit = np.zeros(len(q), dtype=bool)
    lo, hi = np.minimum(p3, p4), np.maximum(p3, p4)
    for a, b in edges:
        a = np.asarray(a, dtype=float)
        b = np.asarray(b, dtype=float)
        # Bounding boxes first (cheap), the exact test only where they overlap.
        near = np.all((lo <= np.maximum(a, b) + 1e-9) & (hi >= np.minimum(a, b) - 1e-9),
                      axis=1)
        i = np.flatnonzero(near)
        hit[i] |= _segments_intersect(np.broadcast_to(a, (len(i), 2)),
                                      np.broadcast_to(b - a, (len(i), 2)), p3[i], dirv[i])
    return hit, side, coll


def _resample(a, b, step_xy, step_phi):
    """Samples on the straight segments a[i] -> b[i] (both ends included) and their owner."""
    d = b - a
    n = np.maximum(1, np.ceil(np.maximum(np.hypot(d[:, 0], d[:, 1]) / step_xy,
                                         np.abs(d[:, 2]) / step_phi)).astype(int))
    owner = np.repeat(np.arange(len(d)), n + 1)
    k = np.arange(owner.size) - np.repeat(np.cumsum(n + 1) - (n + 1), n + 1)
    t = k / n[owner]
    return a[owner] + t[:, None] * d[owner], owner


def _swept(q0, q1, base, length, boundary, obstacles):
    """Per step q0[i] -> q1[i]: the quadrilateral swept by the platform meets a scene segment
    (a wall crossed while parallel to it lies between two samples)."""
    def ends(q):
        return q[:, :2], q[:, :2] + length * np.stack([np.cos(q[:, 2]), np.sin(q[:, 2])], 1)
    (a3, a4), (b3, b4) = ends(q0), ends(q1)
    quad = [a3, a4, b4, b3]
    edges = [(np.asarray(base[0], float), np.asarray(base[1], float))]
    if boundary is not None and len(boundary):
        edges += [(boundary[i], boundary[(i + 1) % len(boundary)]) for i in range(len(boundary))]
    for poly in obstacles:
        poly = np.asarray(poly, dtype=float)
        edges += [(poly[i], poly[(i + 1) % len(poly)]) for i in range(len(poly))]
    hit = np.zeros(len(q0), dtype=bool)
    lo, hi = np.minimum.reduce(quad), np.maximum.reduce(quad)
    for s, e in edges:
        s, e = np.asarray(s, dtype=float), np.asarray(e, dtype=float)
        # Bounding boxes first (cheap), the exact tests only where they overlap.
        k = np.flatnonzero(np.all((lo <= np.maximum(s, e) + 1e-9)
                                  & (hi >= np.minimum(s, e) - 1e-9), axis=1))
        sub = [c[k] for c in quad]
        for i in range(4):
            r = sub[(i + 1) % 4] - sub[i]
            real = np.hypot(r[:, 0], r[:, 1]) > 1e-12         # a point does not move: no edge
            hit[k] |= real & _segments_intersect(sub[i], r, np.broadcast_to(s, r.shape),
                                                 np.broadcast_to(e - s, r.shape))
        side = np.stack([_cross2(sub[(i + 1) % 4] - sub[i], s - sub[i]) for i in range(4)])
        flat = np.stack([np.hypot(*(sub[(i + 1) % 4] - sub[i]).T) <= 1e-12 for i in range(4)])
        hit[k] |= np.all((side > 0) | flat, axis=0) | np.all((side < 0) | flat, axis=0)
    return hit


def bad_segments(a, b, base=((0.0, 0.0), (15.0, 0.0)), length=10.0, boundary=SQUARE,
                 obstacles=(), step_xy=0.05, step_phi=0.01):
    """Which straight segments a[i] -> b[i] in configuration space are not free: checked
    every step_xy / step_phi by direct geometry (closed-segment intersection, sides of the
    singular lines), independently of the determinant predicates."""
    q, owner = _resample(np.asarray(a, dtype=float), np.asarray(b, dtype=float),
                         step_xy, step_phi)
    hit, side, coll = _bad_samples(q, base, length, boundary, obstacles)
    first = np.r_[0, np.flatnonzero(np.diff(owner)) + 1]
    first_of = first[owner]
    bad = hit | (side == 0) | (coll == 0) | (side != side[first_of]) | (coll != coll[first_of])
    bad[1:] |= (owner[1:] == owner[:-1]) & _swept(q[:-1], q[1:], base, length, boundary,
                                                   obstacles)
    out = np.zeros(len(a), dtype=bool)
    out[owner[bad]] = True
    return out


def independent_check(path, base=((0.0, 0.0), (15.0, 0.0)), length=10.0, boundary=SQUARE,
                      obstacles=(), step_xy=0.05, step_phi=0.01):
    """Densely re-sample ``path`` and check it by direct geometry; returns a failure text or
    None."""
    path = np.asarray(path, dtype=float)
    q, _ = _resample(path[:-1], path[1:], step_xy, step_phi)
    hit, side, coll = _bad_samples(q, base, length, boundary, obstacles)
    if np.any(side == 0) or np.any(side != side[0]):
        return 'P3 reaches or crosses the base line'
    if np.any(coll == 0) or np.any(coll != coll[0]):
        return 'P2, P3, P4 become collinear'
    if hit.any():
        return f'platform meets an obstacle segment at {q[hit][0].tolist()}'
    swept = _swept(q[:-1], q[1:], base, length, boundary, obstacles)
    if swept.any():
        return f'platform sweeps across an obstacle segment after {q[:-1][swept][0].tolist()}'
    return None


@pytest.fixture(scope='module')
def paper_planner():
    return VoronoiPlanner(paper_model())


def test_paper_query_is_solved_and_verified_independently(paper_planner):
    res = paper_planner.plan(PAPER_START, PAPER_GOAL)
    assert res.found, res.reason
    path = res.path
    np.testing.assert_allclose(path[0], PAPER_START)
    assert np.allclose(path[-1, :2], PAPER_GOAL[:2])
    assert math.isclose(math.remainder(path[-1, 2] - PAPER_GOAL[2], 2 * math.pi), 0,
                        abs_tol=1e-9)
    steps = np.abs(np.diff(path, axis=0))
    assert np.all(np.hypot(steps[:, 0], steps[:, 1]) <= 0.05 + 1e-9)
    assert np.all(steps[:, 2] <= 0.01 + 1e-9)
    assert independent_check(path) is None
    # The path keeps clear of the obstacles: rho is far above its change per step.
    assert res.min_rho > 10 * res.max_rho_step
    # Only the two retraction climbs are off the diagram; everything between them is
    # diagram pieces and links, and the path really runs where the active leaf changes.
    assert res.stats['retraction_on_diagram'] == [True, True]
    kinds = res.segment_kinds
    middle = kinds[np.flatnonzero(kinds != RETRACTION)[0]:np.flatnonzero(kinds != RETRACTION)[-1]]
    assert np.all(np.isin(middle, [SLICE_PIECE, SLICE_LINK, ATTACH]))
    assert 0.5 < res.on_diagram_fraction <= 1.0
    # Measured on rho: at least 85 % of the length between the two climbs lies within 0.05
    # units (the dense-check step) of a tie of the two smallest contacts.
    share, climbs = on_diagram_share(paper_planner.model, path, 0.05)
    assert share >= 0.85, share
    assert climbs <= 1.01 * res.stats['length_by_kind']['retraction']
    # Clearance profile: rho at every dense sample along the arc length.
    assert res.clearance.shape == (len(path), 2)
    assert np.all(np.diff(res.clearance[:, 0]) >= 0) and res.clearance[:, 1].min() == res.min_rho


def test_independent_checker_detects_a_bad_path():
    # Straight line from start to goal in configuration space passes through the base.
    bad = np.array([PAPER_START, (10.0, -5.0, 1.2), PAPER_GOAL])
    assert independent_check(bad) is not None
    assert 'base line' in independent_check(np.array([PAPER_START, (35, 20, 1.5)]))


def test_query_across_the_base_line_singularity_answers_no_path_at_once(paper_planner):
    res = paper_planner.plan(PAPER_START, (-10.0, 15.0, -math.pi / 2))
    assert res.status == 'no_path'
    assert '[p1 p2 p3]' in res.reason
    assert res.stats['decided_by'] == 'singularity certificate'
    assert 'slices' not in res.stats          # decided before any roadmap was built


@pytest.mark.slow            # a diagram search over every slice
def test_query_into_a_disconnected_region_answers_no_path(paper_planner):
    # Goal outside the boundary square (free for P2, as in the paper) in the same singularity
    # cell: only the roadmap search can tell that the boundary separates them.
    goal = (-28.0, -20.0, -math.pi / 2)
    assert paper_planner.model.rho(np.array(goal)) > 0
    res = paper_planner.plan(PAPER_START, goal)
    assert res.status == 'no_path', res.reason
    assert res.stats['decided_by'] == 'diagram search' and 'slices' in res.stats


@pytest.mark.parametrize('q, words', [
    ((52.0, 0.5, 0.0), 'boundary edge P7P8'),          # platform through the right wall
    ((20.0, 0.0, 1.0), 'Delta(1,2,3)'),                # P3 on the base line
    ((25.0, 10.0, math.pi / 4), 'Delta(2,3,4)'),       # P2, P3, P4 collinear
    ((5.0, -3.0, math.pi / 2), 'crosses base P1P2'),   # platform through the base
    ((70.0, 0.0, 0.0), 'outside the planning domain'),
    ((float('nan'), 0.0, 0.0), 'finite'),
])
def test_bad_start_or_goal_names_the_failing_predicate(paper_planner, q, words):
    with pytest.raises(UserError, match='start') as err:
        paper_planner.plan(q, PAPER_GOAL)
    assert words in str(err.value)
    with pytest.raises(UserError, match='goal') as err:
        paper_planner.plan(PAPER_START, q)
    assert words in str(err.value)


def test_scene_file_errors_are_one_line(tmp_path):
    bad = tmp_path / 'bad.json'
    bad.write_text('{"obstacles": [[[0, 0], [4, 0], [4, 4], [2, 1], [0, 4]]]}')
    with pytest.raises(UserError, match='convex'):
        load_scene(bad)
    bad.write_text('{"platform_length": -1}')
    with pytest.raises(UserError, match='platform_length'):
        load_scene(bad)
    bad.write_text('{"base": [[0, 0]]')
    with pytest.raises(UserError, match='not valid JSON'):
        load_scene(bad)
    with pytest.raises(UserError, match='cannot read'):
        load_scene(tmp_path / 'missing.json')


@pytest.mark.slow
def test_cli_plan_writes_result_and_figures(tmp_path, capsys):
    scene = tmp_path / 'scene.json'
    scene.write_text(json.dumps({'obstacles': [[[30, 10], [40, 10], [40, 20], [30, 20]]]}))
    out = tmp_path / 'out'
    code = cli_main(['voronoi', 'plan', '--start', '35', '-20', '90', '--goal', '-10', '-15',
                     '-90', '--scene', str(scene), '--out', str(out), '--grid', '2',
                     '--slice-deg', '5'])
    assert code == 0
    doc = json.loads((out / 'result.json').read_text())
    assert doc['status'] == 'ok' and doc['min_rho'] > 0 and doc['planning_time_s'] > 0
    assert 0.5 < doc['on_diagram_fraction'] <= 1.0
    profile = doc['clearance_profile']
    assert len(profile['arc_length']) == len(profile['rho']) > 10
    assert min(profile['rho']) == pytest.approx(doc['min_rho'], abs=1e-6)
    assert independent_check(np.array(doc['path']),
                             obstacles=[[[30, 10], [40, 10], [40, 20], [30, 20]]]) is None
    for name in ('figure2.png', 'figure3.png'):
        assert (out / name).read_bytes()[:8] == b'\x89PNG\r\n\x1a\n'


def test_cli_plan_refuses_bad_input_without_writing(tmp_path, capsys):
    out = tmp_path / 'never'
    code = cli_main(['voronoi', 'plan', '--start', '20', '0', '10', '--goal', '-10', '-15',
                     '-90', '--out', str(out)])
    assert code == 2
    err = capsys.readouterr().err
    assert 'Delta(1,2,3)' in err and len(err.strip().splitlines()) == 1
    assert not out.exists()


def test_fields_match_pointwise_rho():
    model = paper_model()
    xs, ys = grid_axes(model.domain, 5.0)
    f = slice_fields(model, np.array([0.3, 2.0]), xs, ys)
    X, Y = np.meshgrid(xs, ys)
    q = np.stack([X, Y, np.full_like(X, 2.0)], axis=-1)
    # The slices use the exact affine form of each determinant (A + B x + C y): equal up to
    # rounding, far below the free tolerance.
    np.testing.assert_allclose(f.rho[1], model.rho(q), rtol=1e-9, atol=1e-3 * model.free_tol)


@pytest.mark.slow            # the paper query again, with a planner of its own
def test_paper_query_in_the_exact_fig3_domain(tmp_path):
    """Fig. 3's region, phi in [-pi/2, pi/2] (not periodic): the path stays inside it."""
    scene = tmp_path / 'fig3.json'
    scene.write_text(json.dumps({'domain': {'x': [-30, 60], 'y': [-45, 45],
                                            'phi_deg': [-90, 90]}}))
    model = load_scene(scene)
    assert not model.domain.periodic
    res = VoronoiPlanner(model).plan(PAPER_START, PAPER_GOAL)
    assert res.found, res.reason
    assert res.path[:, 2].min() >= -math.pi / 2 - 1e-9
    assert res.path[:, 2].max() <= math.pi / 2 + 1e-9
    np.testing.assert_allclose(res.path[-1], PAPER_GOAL, atol=1e-9)
    assert independent_check(res.path) is None


def test_no_path_that_only_the_diagram_search_can_give():
    """A wall across the boundary square separates start and goal, which lie on the same side
    of every singularity (the certificate has nothing to say): the diagram search over every
    slice answers "no path". Without the wall the same query has a path (causal), and the
    clearance-weighted grid planner agrees that the wall separates them."""
    wall = [(-30.0, -22.0), (60.0, -22.0), (60.0, -18.0), (-30.0, -18.0)]
    start, goal = (20.0, -10.0, 0.0), (20.0, -30.0, 0.0)
    walled = planar_model(((0.0, 0.0), (15.0, 0.0)), 10.0, [tuple(p) for p in SQUARE], [wall],
                          Domain())
    planner = VoronoiPlanner(walled, h=1.5, dphi_deg=5.0)
    assert np.array_equal(walled.singular_signs(np.array(start)),
                          walled.singular_signs(np.array(goal)))
    assert planner._singularity_certificate(np.array(start), np.array(goal)) == ''
    res = planner.plan(start, goal)
    assert res.status == 'no_path'
    assert res.stats['decided_by'] == 'diagram search'
    assert res.stats['slices'] == len(planner.phis) and res.stats['diagram_nodes'] > 1000
    assert 'Voronoi diagram' in res.reason
    assert not ClearanceGridPlanner(walled, h=1.5, dphi_deg=5.0).plan(start, goal).found
    open_ = planar_model(((0.0, 0.0), (15.0, 0.0)), 10.0, [tuple(p) for p in SQUARE], [],
                         Domain())
    res = VoronoiPlanner(open_, h=1.5, dphi_deg=5.0).plan(start, goal)
    assert res.found, res.reason
    assert independent_check(res.path) is None
