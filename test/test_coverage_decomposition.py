"""The grid planner's decomposition (`coverage_pkg.planner`, ours) on hand-made worlds.

Constructed worlds whose hierarchical decomposition (Section IV-A: vast cells = components of
VR = {D > delta}, narrow cells = components of NR = FCS_r minus VR) is known by hand; delta = 2 m,
r = 0.25 m. Each world is covered once (ROS-free loop, ground-truth path) and the run is checked
against the hand-made answer: the cells and their adjacency, the lap spacing, where the cusp
points were sensed (on the GVD where D = delta) and where the critical points were sensed.
A planner that does not build this decomposition, or laps at another spacing, fails here.
"""
import math

import numpy as np
import pytest

from coverage_pkg.kinematic import run_kinematic
from coverage_pkg.planner import CoveragePlanner, PlannerConfig
from coverage_pkg.sonar import SonarRing
from coverage_pkg.world import world_from_dict

pytestmark = pytest.mark.slow  # whole coverage runs of hand-made worlds

DELTA = 2.0
# 16 x 12 room, one 4 x 2 obstacle in the middle: VR is a ring around the obstacle (one vast
# cell); NR is the band along the walls and the band around the obstacle (two narrow cells,
# separated by VR).
RECT_OBS = {'name': 'rect_obs', 'boundary': [[0, 0], [16, 0], [16, 12], [0, 12]],
            'obstacles': [[[6, 5], [10, 5], [10, 7], [6, 7]]], 'start': [1.0, 1.0]}
# Two 8 x 8 rooms joined by a 4 m corridor 1.5 m wide: two vast cells (one per room), one
# narrow cell (the wall band, connected through the corridor).
TWO_ROOMS = {'name': 'two_rooms_corridor',
             'boundary': [[0, 0], [8, 0], [8, 3.25], [12, 3.25], [12, 0], [20, 0], [20, 8],
                          [12, 8], [12, 4.75], [8, 4.75], [8, 8], [0, 8]],
             'obstacles': [], 'start': [1.0, 1.0]}
# T-hall: a 20 x 6 crossbar on a 3 m wide, 8 m long stem: one vast cell (the middle of the
# crossbar), one narrow cell (the stem and the band along the crossbar's walls).
T_HALL = {'name': 't_hall',
          'boundary': [[8.5, 0], [11.5, 0], [11.5, 8], [20, 8], [20, 14], [0, 14], [0, 8],
                       [8.5, 8]],
          'obstacles': [], 'start': [10.0, 1.0]}
# An empty 18 x 10 room: laps x = 1 + 4k cross VR (2 < x < 16) at x = 5, 9, 13.
PLAIN = {'name': 'plain', 'boundary': [[0, 0], [18, 0], [18, 10], [0, 10]], 'obstacles': [],
         'start': [1.0, 1.0]}

WORLDS = {'rect_obs': RECT_OBS, 'two_rooms': TWO_ROOMS, 't_hall': T_HALL, 'plain': PLAIN}
# Hand count: (vast cells, narrow cells, vast-narrow edges).
CELLS = {'rect_obs': (1, 2, 2), 'two_rooms': (2, 1, 2), 't_hall': (1, 1, 1),
         'plain': (1, 1, 1)}
# Cusp points (GVD points with D = delta), worked out by hand: the bisector of each concave
# corner at delta from both walls; the centre line of a door/stem where the distance to its
# two corners reaches delta (corridor half-width 0.75: 8 - sqrt(4 - 0.75^2) = 6.146;
# stem half-width 1.5: 8 + sqrt(4 - 1.5^2) = 9.323).
CUSPS = {
    'rect_obs': [(2, 2), (14, 2), (2, 10), (14, 10)],
    'two_rooms': [(2, 2), (6, 2), (2, 6), (6, 6), (14, 2), (18, 2), (14, 6), (18, 6),
                  (8 - math.sqrt(4 - 0.75 ** 2), 4), (12 + math.sqrt(4 - 0.75 ** 2), 4)],
    't_hall': [(2, 10), (18, 10), (2, 12), (18, 12), (10, 8 + math.sqrt(4 - 1.5 ** 2))],
    'plain': [(2, 2), (16, 2), (2, 8), (16, 8)],
}


class _Runs(dict):
    """Each world covered once, when a test first asks for it (10-25 s wall each, unloaded)."""

    def __missing__(self, name):
        self[name] = run_kinematic(world_from_dict(WORLDS[name]), PlannerConfig(delta=DELTA),
                                   max_time=600)
        return self[name]


@pytest.fixture(scope='module')
def runs():
    return _Runs()


@pytest.mark.parametrize('name', sorted(WORLDS))
def test_cells_and_adjacency_are_the_hand_made_decomposition(runs, name):
    r = runs[name]
    p = r['planner']
    assert r['state'] == 'done', p.events[-3:]
    assert r['covered_fraction'] >= 0.99
    vast, narrow = p.graph.alive('vast'), p.graph.alive('narrow')
    n_vast, n_narrow, n_edges = CELLS[name]
    assert (len(vast), len(narrow)) == (n_vast, n_narrow)
    edges = set(p.graph.edges)
    assert len(edges) == n_edges
    ids = {n.id for n in vast}, {n.id for n in narrow}
    assert all(v in ids[0] and n in ids[1] for v, n in edges)   # only vast-narrow edges
    assert {v for v, _ in edges} == ids[0] and {n for _, n in edges} == ids[1]
    assert all(n.covered for n in vast + narrow) and not p.given_up
    # No sliver cells: every vast cell is bigger than a detector disk's quarter.
    assert all(n.area > 0.25 * math.pi * DELTA ** 2 for n in vast)


@pytest.mark.parametrize('name', sorted(WORLDS))
def test_cusp_points_are_sensed_where_the_gvd_has_d_equal_delta(runs, name):
    p = runs[name]['planner']
    sensed = [(x, y) for x, y, _, _ in p.sensed['cusp']]
    assert len(sensed) >= 4
    truth = np.array(CUSPS[name], dtype=float)
    for x, y in sensed:
        assert np.min(np.hypot(truth[:, 0] - x, truth[:, 1] - y)) <= 0.15, (x, y)
    # and every cusp point of the world is sensed (Theorem 1 needs the robot to find them all)
    got = np.array(sensed)
    for x, y in truth:
        assert np.min(np.hypot(got[:, 0] - x, got[:, 1] - y)) <= 0.15, ('missed', x, y)
    kinds = {e[1] for e in p.events}
    assert {'cusp', 'node_created', 'start', 'done'} <= kinds


def test_every_critical_point_is_sensed_within_0_3_m(runs):
    """rect_obs: the slice h = x changes connectivity at the obstacle's delta-offset (left side
    x = 4, right side x = 12, both for 5 <= y <= 7) and at the walls' (x = 2, x = 14). The
    sides are flat (degenerate critical points); each must be sensed, with the obstacle on the
    correct side (+x: the slice closes a cell; -x: it opens one)."""
    p = runs['rect_obs']['planner']
    crit = p.sensed['critical']
    world_critical = [(4.0, 5.0, 7.0, +1), (12.0, 5.0, 7.0, -1), (2.0, 2.0, 10.0, -1),
                      (14.0, 2.0, 10.0, +1)]
    for x0, y0, y1, side in world_critical:
        assert any(abs(x - x0) <= 0.3 and y0 - 0.3 <= y <= y1 + 0.3 and s == side
                   for x, y, _, s in crit), (x0, side, crit)
    # and nothing sensed elsewhere
    for x, y, _, s in crit:
        assert any(abs(x - x0) <= 0.3 and y0 - 0.3 <= y <= y1 + 0.3 and s == side
                   for x0, y0, y1, side in world_critical), (x, y, s)
    assert any(e[1] == 'cell_closed' for e in p.events)


def test_morse_cells_of_the_vast_node_are_bounded_by_its_sensed_critical_points(runs):
    """rect_obs: the vast cell is a ring around the obstacle. Its Morse cells (h = x, Fig. 3)
    are four: left of the obstacle (from the left wall's slice x = 2 to the split at x = 4),
    below and above it (split to merge at x = 12) and right of it (merge to the right wall's
    slice x = 14). Each cell boundary is a critical point the ring sensed: the Reeb graph
    names, for each cell, the sensed point that opened it and the one that closed it."""
    p = runs['rect_obs']['planner']
    (vast,) = p.graph.alive('vast')
    pts, edges = vast.reeb_points, vast.reeb_edges
    assert len(edges) == 4 and all(a >= 0 and b >= 0 for a, b in edges), edges

    def x_of(i):
        return pts[i][0]                   # the ROS-free loop's odometry is the world frame
    spans = sorted((round(x_of(a)), round(x_of(b))) for a, b in edges)
    assert spans == [(2, 4), (4, 12), (4, 12), (12, 14)], spans
    assert all(pts[a][2] == 'opens' or round(x_of(a)) == 4 for a, _ in edges)
    assert all(pts[b][2] == 'closes' or round(x_of(b)) == 12 for _, b in edges)
    closed = [e for e in p.events if e[1] == 'cell_closed']
    assert len(closed) >= 4 and all('sensed at t =' in e[4] for e in closed)


# A T of corridors 1.5 m wide: the crossbar y in [0, 1.5], x in [0, 14]; the stem x in
# [6.25, 7.75] up to y = 8. One narrow cell (D <= 0.94 m everywhere), no vast cell.
T_CORRIDOR = {'name': 't_corridor',
              'boundary': [[0, 0], [14, 0], [14, 1.5], [7.75, 1.5], [7.75, 8], [6.25, 8],
                           [6.25, 1.5], [0, 1.5]],
              'obstacles': [], 'start': [1.0, 0.75]}


def test_the_meet_point_of_a_corridor_junction_is_sensed_where_three_walls_are_equidistant():
    """The GVD of the T has a meet point at the junction, equidistant to the bottom wall and
    the stem's two corners: (7, y) with y = sqrt(0.75^2 + (1.5 - y)^2), y = 0.9375 (D there).
    A robot on the crossbar's centre line (y = 0.75) passes 0.19 m from it, where the third
    obstacle is 0.31 m farther than the other two. The ring's three closest echoes place it.
    The other meet points of this GVD are the ends of the corridors (0.75, 0.75),
    (13.25, 0.75), (7, 7.25); nothing else may be reported as one."""
    r = run_kinematic(world_from_dict(T_CORRIDOR), PlannerConfig(delta=DELTA), max_time=600)
    p = r['planner']
    assert r['state'] == 'done' and r['covered_fraction'] >= 0.99
    (narrow,) = p.graph.alive('narrow')
    assert not p.graph.alive('vast')
    meets = [(x, y) for x, y, _, _ in p.sensed['meet']]
    junction = (7.0, 0.9375)
    assert any(math.hypot(x - junction[0], y - junction[1]) <= 0.15 for x, y in meets), meets
    truth = np.array([junction, (0.75, 0.75), (13.25, 0.75), (7.0, 7.25)])
    for x, y in meets:
        assert np.min(np.hypot(truth[:, 0] - x, truth[:, 1] - y)) <= 0.3, (x, y)
    assert narrow.meet_points and any(e[1] == 'meet' for e in p.events)


def test_laps_are_two_delta_apart_on_the_ground_truth_path(runs):
    """Laps are straight runs along the slice direction (|dx| < 5 cm) that cross the vast cell:
    at least 2 delta of y (VR is 6 m tall here), mostly inside VR (true clearance > delta +
    0.5 m, so boundary following is not counted). A shorter straight piece is not a lap: a
    transit to a wall strip can run 3-4 m straight down a column. The laps' x values, grouped,
    are 2 delta apart within 0.1 m."""
    r = runs['plain']
    world = world_from_dict(PLAIN)
    path = np.asarray(r['path'])
    xs = []
    i = 0
    while i < len(path) - 1:
        j = i
        while j + 1 < len(path) and abs(path[j + 1, 0] - path[i, 0]) < 0.05:
            j += 1
        run = path[i:j + 1]
        if np.ptp(run[:, 1]) >= 2 * DELTA:
            inside = [world.clearance(q) > DELTA + 0.5 for q in run]
            if np.mean(inside) > 0.5:
                xs.append(float(np.median(run[:, 0])))
        i = j + 1
    laps = []
    for x in sorted(xs):
        if not laps or x - laps[-1][-1] > 0.3:
            laps.append([x])
        else:
            laps[-1].append(x)
    centres = [float(np.mean(g)) for g in laps]
    assert len(centres) >= 3, centres
    gaps = np.diff(centres)
    assert np.all(np.abs(gaps - 2 * DELTA) <= 0.1), centres


def test_a_given_up_node_means_incomplete_never_done():
    ring = SonarRing()
    p = CoveragePlanner(PlannerConfig(), ring.mount_angles(), ring.beam_width, ring.min_range,
                        ring.max_range)
    p.on_odometry(0.0, 0.0, 0.0, 0.0)
    node = p.graph.create_node('narrow', (0.0, 0.0))
    p.given_up.append(node.id)
    p._finish(1.0)
    assert p.state == 'incomplete'
    assert p.events[-1][1] == 'incomplete' and str(node.id) in p.events[-1][4]


# An L-hall 4.3 m wide: D on its centre line is 2.15 m > delta, but the VR sliver there is too
# thin to be a vast cell, so the hall is one narrow cell traced on its GVD, 2.15 m from both
# walls: the pass leaves the strips along the walls out of range.
L_HALL = {'name': 'l_hall_4_3',
          'boundary': [[11.3, 4.3], [11.3, 0], [0, 0], [0, 8.6], [3.35, 8.6], [3.35, 4.3]],
          'obstacles': [], 'start': [2.5, 4.85]}


def test_pockets_a_finished_pass_left_unseen_are_approached_once():
    """The left-pocket pass is what covers the hall's wall strips when the hall's pieces are
    taken nearest first: with it >= 99 % of CVS, without it `done` below 99 % (98.8 % when this
    test was written). The default tour order happens to pass close enough to the walls of this
    hall without it (99.7 %), so the pass is shown load-bearing with
    ``piece_order='nearest'``; the default run must still reach 99 %."""
    from unittest import mock
    r = run_kinematic(world_from_dict(L_HALL), PlannerConfig(delta=DELTA), max_time=600)
    assert r['state'] == 'done' and r['covered_fraction'] >= 0.99
    nearest = PlannerConfig(delta=DELTA, piece_order='nearest')
    r1 = run_kinematic(world_from_dict(L_HALL), nearest, max_time=600)
    assert r1['state'] == 'done' and r1['covered_fraction'] >= 0.99
    no_band = mock.patch.object(CoveragePlanner, '_approach_left_pockets',
                                lambda self, d, *args: np.zeros_like(d['reach']))
    with no_band:
        r0 = run_kinematic(world_from_dict(L_HALL), nearest, max_time=600)
    assert r0['state'] == 'done' and r0['covered_fraction'] < 0.99


def _first_x_over(path, x):
    return int(np.flatnonzero(path[:, 0] > x)[0])


def test_a_room_is_finished_before_the_robot_moves_on(runs):
    """Two rooms and one narrow cell (the wall band of both, through the corridor). Once the
    band of the start room is done, the next narrow work is across the corridor: the start
    room's vast cell is covered then (``leave_far``), not on a trip back at the end. Once in
    the second room (x > 12), the robot never comes back into the first (x < 8). Without the
    rule (``leave_far = 0``) it does: it goes back for the first room's laps (to x = 1.95 when
    this test was written), and back again for the band of the second."""
    r = runs['two_rooms']
    path = np.asarray(r['path'])
    assert path[_first_x_over(path, 12.0):, 0].min() > 8.0
    assert any('leaves it behind' in e[4] for e in r['planner'].events)
    r0 = run_kinematic(world_from_dict(TWO_ROOMS), PlannerConfig(delta=DELTA, leave_far=0.0),
                       max_time=600)
    assert r0['state'] == 'done' and r0['covered_fraction'] >= 0.99
    p0 = np.asarray(r0['path'])
    assert p0[_first_x_over(p0, 12.0):, 0].min() < 8.0
    assert r['path_length'] < r0['path_length']


def test_a_hall_is_lapped_after_its_band_is_done(runs):
    """The empty 18 x 10 room: one narrow cell (the band along the walls) and one vast cell
    (the hall). The hall's laps reach farther than the rest of the band, so the narrow node
    does not hand over (``_vast_left_behind``): the band is finished, then the hall is lapped.
    A hand-over without that condition takes the robot into the laps at 47.5 s with
    the top band half traced; it comes back for the band piece by piece (path 3.64 times the
    lower bound, against 2.78 with the condition)."""
    ev = runs['plain']['planner'].events
    assert not any('leaves it behind' in e[4] for e in ev)
    to_vast = [e[0] for e in ev if e[1] == 'next_node' and 'vast node' in e[4]]
    band_done = [e[0] for e in ev if e[1] == 'node_covered' and 'narrow node' in e[4]]
    assert to_vast and band_done and band_done[0] <= to_vast[0]
