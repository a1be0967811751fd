"""Detours on the simplified Voronoi diagram: queries whose straight interpolation collides.

Three scenes in the paper's setting (base P1P2, platform of length 10, boundary square), with
convex obstacles: a block across the straight line, a slot narrower than the platform that it
only passes turned along the slot, and a U-shaped trap around the start. Each path is checked by
the independent direct-geometry checker of ``test_voronoi_planner`` every 0.05 units / 0.01 rad;
its share on the diagram is measured from rho (not the planner's labels), and its length, min
rho and Euclidean clearance (distance between the platform segment P3P4 and every obstacle,
base and boundary segment) are printed beside those of the clearance-weighted grid planner
(voronoi_pkg.grid_baseline) on the same grid.
"""
import math

import numpy as np
import pytest
from test_voronoi_planner import SQUARE, independent_check

from voronoi_pkg.grid_baseline import ClearanceGridPlanner, segment_clearance
from voronoi_pkg.measures import on_diagram_share, path_length
from voronoi_pkg.planar import Domain, planar_model
from voronoi_pkg.planner import RETRACTION, VoronoiPlanner


def rect(x0, x1, y0, y1):
    return [(x0, y0), (x1, y0), (x1, y1), (x0, y1)]


SCENES = {
    # A block across the straight line from start to goal.
    'block': ([rect(10, 20, -35, -15)], (-10.0, -25.0, 0.0), (40.0, -25.0, 0.0)),
    # A wall with a slot 4 wide (platform 10 long): only a platform turned along the slot
    # passes; start and goal are across the wall, turned across it.
    'slot': ([rect(18, 22, -40, -24), rect(18, 22, -20, 40)], (5.0, -22.0, math.pi / 2),
             (35.0, -22.0, math.radians(150))),
    # A U open to the left around the start; the goal is behind the U's closed side.
    'u_trap': ([rect(10, 34, -9, -6), rect(10, 34, -36, -33), rect(31, 34, -33, -9)],
               (22.0, -21.0, math.pi), (48.0, -21.0, math.pi)),
}


def clearance(path, obstacles):
    """Euclidean distance between the platform segment and the nearest scene segment at
    every configuration of ``path`` (0 when they touch or cross): the package's plain
    geometry (no determinants), checked against brute-force sampling below."""
    model = planar_model(((0.0, 0.0), (15.0, 0.0)), 10.0, [tuple(p) for p in SQUARE],
                         obstacles, Domain())
    return segment_clearance(model, path)


def _sampled_clearance(q, obstacles, n=201):
    """Brute force: smallest distance between n points on the platform and n points on every
    scene segment (an over-estimate by at most half a sample spacing on each)."""
    segs = [((0.0, 0.0), (15.0, 0.0))] + [(SQUARE[i], SQUARE[(i + 1) % 4]) for i in range(4)]
    for poly in obstacles:
        segs += [(poly[i], poly[(i + 1) % len(poly)]) for i in range(len(poly))]
    s = np.linspace(0.0, 1.0, n)[:, None]
    p3 = q[:2]
    robot = p3 + s * 10.0 * np.array([np.cos(q[2]), np.sin(q[2])])
    best = np.inf
    for a, b in segs:
        a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
        pts = a + s * (b - a)
        best = min(best, float(np.min(np.hypot(*(robot[:, None] - pts[None]).T))))
    return best


def test_clearance_geometry_matches_brute_force_sampling():
    obstacles = SCENES['slot'][0]
    rng = np.random.default_rng(4)
    q = rng.uniform([-20, -38, -math.pi], [50, -2, math.pi], (30, 3))
    got = clearance(q, obstacles)
    for qi, g in zip(q, got):
        ref = _sampled_clearance(qi, obstacles)
        # Sampling over-estimates by at most half the sample spacings (10/200 and 80/200).
        assert g - 1e-9 <= ref <= g + 0.2 + 0.025 or (g == 0 and ref <= 0.2 + 0.025)


@pytest.mark.slow
@pytest.mark.parametrize('name', sorted(SCENES))
def test_detour_on_the_diagram_is_free_and_keeps_clear(name):
    obstacles, start, goal = SCENES[name]
    model = planar_model(((0.0, 0.0), (15.0, 0.0)), 10.0, [tuple(p) for p in SQUARE],
                         obstacles, Domain())
    # The straight interpolation collides: the planner must detour.
    line = np.linspace(start, goal, 2)
    assert independent_check(line, obstacles=obstacles) is not None
    planner = VoronoiPlanner(model)
    res = planner.plan(start, goal)
    assert res.found, res.reason
    np.testing.assert_allclose(res.path[0], start, atol=1e-12)
    np.testing.assert_allclose(res.path[-1, :2], goal[:2], atol=1e-9)
    assert independent_check(res.path, obstacles=obstacles) is None
    # Only the two retraction climbs are off the diagram.
    kinds = res.segment_kinds
    inner = np.flatnonzero(kinds != RETRACTION)
    assert np.all(kinds[inner[0]:inner[-1] + 1] != RETRACTION)
    # Measured on rho itself, not on the planner's labels: at least 85 % of the length
    # between the two retraction climbs runs within 0.05 units of a tie of two contacts.
    share, _ = on_diagram_share(model, res.path, 0.05)
    assert share >= 0.85, share
    # In rho, the measure the diagram is built on: the path keeps at least a quarter of
    # what the scene allows (the diagram's bottleneck between the retraction ends, and rho at
    # the start and goal themselves).
    allowed = min(res.stats['bottleneck_rho'], float(model.rho(np.asarray(start))),
                  float(model.rho(np.asarray(goal))))
    assert res.min_rho >= 0.25 * allowed
    print(f'{name}: length {path_length(res.path):.1f}, min rho {res.min_rho:.3g}, min '
          f'clearance {clearance(res.path, obstacles).min():.2f}, on the diagram {share:.3f}, '
          f'{res.planning_time:.2f} s')


@pytest.mark.slow
def test_comparison_with_the_clearance_weighted_grid_planner():
    """The clearance-weighted grid planner (ours, voronoi_pkg.grid_baseline) on the same grid
    and slices, on the block scene: both paths pass the independent check; the figures are
    printed side by side (docs/results/voronoi.md has them for every scene). The diagram's
    gain is the size of what is searched, not clearance: its graph has a small fraction of
    the free grid's vertices."""
    obstacles, start, goal = SCENES['block']
    model = planar_model(((0.0, 0.0), (15.0, 0.0)), 10.0, [tuple(p) for p in SQUARE],
                         obstacles, Domain())
    res = VoronoiPlanner(model).plan(start, goal)
    grid = ClearanceGridPlanner(model).plan(start, goal)
    assert res.found and grid.found, (res.reason, grid.reason)
    assert independent_check(res.path, obstacles=obstacles) is None
    assert independent_check(grid.path, obstacles=obstacles) is None
    mine, theirs = clearance(res.path, obstacles), clearance(grid.path, obstacles)
    print(f'diagram: length {path_length(res.path):.1f}, min rho {res.min_rho:.3g}, min '
          f'clearance {mine.min():.2f}, {res.planning_time:.2f} s, '
          f'{res.stats["diagram_nodes"]} nodes; grid: {path_length(grid.path):.1f}, '
          f'{grid.min_rho:.3g}, {theirs.min():.2f}, {grid.planning_time:.2f} s, '
          f'{grid.stats["grid_vertices"]} free vertices')
    assert res.stats['diagram_nodes'] < 0.1 * grid.stats['grid_vertices']
