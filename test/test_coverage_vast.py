"""Vast cells of the paper planner (coverage_pkg/paper/morse_coverage.py, node_creation.py):
laps 2 delta apart, boundary following at D = delta, the Morse cells of a hall with pillars.

The hall is /work/shared/worlds/pillars.json (24 x 20 m, seven obstacles): the square pillar's
corner lies 4.045 m above the bottom wall, 2 delta + 0.045 m, so the curves D = delta of the
pillar and of the wall nearly touch (the case Section IV-A's assumption leaves out), and the
two pillars at the right lie within 2 delta of each other (a narrow cell between them)."""
import math

import numpy as np
import pytest

from coverage_pkg.algorithm1 import Branch, MorseCell, Node, PaperConfig, PaperPlanner
from coverage_pkg.kinematic import run_kinematic
from coverage_pkg.sonar import SonarRing
from coverage_pkg.world import world_from_dict

PILLARS = {'name': 'pillars', 'boundary': [[0, 0], [24, 0], [24, 20], [0, 20]], 'start': [1, 1],
           'obstacles': [
               [[7.2, 6.0], [6.6, 7.039], [5.4, 7.039], [4.8, 6.0], [5.4, 4.961], [6.6, 4.961]],
               [[13.955, 5.296], [12.704, 5.955], [12.045, 4.704], [13.296, 4.045]],
               [[15.6, 8.2], [14.909, 9.151], [13.791, 8.788], [13.791, 7.612],
                [14.909, 7.249]],
               [[18, 12], [21, 12], [21, 17], [18, 17]],
               [[3, 13], [9, 13], [9, 14.5], [3, 14.5]],
               [[12.5, 15.0], [12.061, 16.061], [11.0, 16.5], [9.939, 16.061], [9.5, 15.0],
                [9.939, 13.939], [11.0, 13.5], [12.061, 13.939]]]}


def _planner(**kw):
    ring = SonarRing()
    return PaperPlanner(PaperConfig(**kw), ring.mount_angles(), ring.beam_width,
                        ring.min_range, ring.max_range)


@pytest.fixture(scope='module')
def runs():
    """The hall covered with circuit_join (the default) and without it."""
    return {join: run_kinematic(world_from_dict(PILLARS), PaperConfig(circuit_join=join),
                                max_time=3000) for join in (True, False)}


@pytest.mark.slow                         # two closed-loop runs, 5-15 s
@pytest.mark.parametrize('join', [True, False])
def test_the_hall_is_covered_by_laps_with_or_without_circuit_join(runs, join):
    """The cell below the pillars runs on past the pinch under the square pillar (a lap there
    has no slice to read: no critical point) and laps the space right of the pillars: the
    triangle at x 18-19.8, y 4-8 is covered (a 'death' read from that lap left it unseen)."""
    r = runs[join]
    assert r['state'] == 'done' and r['covered_fraction'] >= 0.99
    laps = [lap for c in r['planner'].nodes[1].cells for lap in c.laps]
    assert any(16.0 < x < 22.0 and lo < 4.0 and hi > 8.0 for x, lo, hi in laps)


@pytest.mark.slow
@pytest.mark.parametrize('join', [True, False])
def test_no_slice_is_lapped_by_two_cells(runs, join):
    """The cell beyond the hexagonal pillar (opened by its critical point, resumed on its far
    side) ends where its slice joins the slice of its parent beyond the pillar (a merge of
    the Reeb graph, Fig. 3): no lap of one Morse cell runs on a lap of another."""
    cells = runs[join]['planner'].nodes[1].cells
    laps = [(c.id, lap) for c in cells for lap in c.laps]
    for i, (a, (xa, la, ha)) in enumerate(laps):
        for b, (xb, lb, hb) in laps[i + 1:]:
            if a != b and abs(xa - xb) < 0.75 * 2.0:
                assert min(ha, hb) - max(la, lb) < 1.0, (a, b, (xa, la, ha), (xb, lb, hb))


@pytest.mark.slow
def test_circuit_join_stops_circuits_on_boundary_followed_already(runs):
    """Switch ``circuit_join`` (ours): without it, the circuit round the two pillars at the
    right passes onto the hall's outer boundary where the curves D = delta nearly touch, and
    so does the circuit round the rectangle joined to the walls: each drives the hall's whole
    outer boundary again (about 100 m each). With it, a circuit ends where it reaches a
    boundary another circuit followed, and follows its start's other way round to a known
    boundary too; the path is a third shorter (the paper's boundary following traces each
    point of the boundary once, Section IV-B)."""
    on, off = (runs[j]['planner'] for j in (True, False))
    long_off = [c['length'] for c in off.nodes[1].circuits[1:] if c['length'] > 60.0]
    assert len(long_off) >= 2
    assert all(c['length'] < 30.0 for c in on.nodes[1].circuits[1:])
    assert any(c.get('joined') for c in on.nodes[1].circuits)
    assert not any(c.get('joined') for n in off.nodes for c in n.circuits)
    length = {j: runs[j]['path_length'] / runs[j]['lower_bound'] for j in runs}
    assert length[True] < 0.75 * length[False] and length[True] < 5.0


def test_a_circuit_joins_a_followed_boundary_only_on_its_path():
    """``_joins_known``: the robot following a boundary at D = delta is on a stretch another
    circuit followed when it lies within the equal-echo tolerance (0.15 m) of that circuit's
    path, between its samples too; a curve 0.3 m off (two obstacles 2 delta + 0.3 m apart) is
    another boundary. The circuit's own first half counts for its second half only beyond
    1.2 m of where both began."""
    p = _planner()
    done = {'start': (0.0, 2.0), 'done': True, 'trace': [(x, 2.0) for x in np.arange(0, 10, 0.3)]}
    own = {'start': (5.0, 6.0), 'done': False, 'trace': [(5.0, 6.0 - 0.3 * k) for k in range(9)]}
    p.nodes.append(Node(0, 'vast', (0.0, 2.0), circuits=[done, own]))
    for y, joins in ((2.05, True), (2.14, True), (2.3, False)):
        p.on_odometry(0.0, 5.05, y, 0.0)            # between two samples of the trace
        assert p._joins_known(own, {'circuit': own}) == joins
    own.update(reverse_from=(5.0, 6.0), first_len=9)
    for y, joins in ((5.4, False), (4.5, True), (3.6, True)):
        p.on_odometry(0.0, 5.0, y, 0.0)
        assert p._joins_known(own, {'circuit': own, 'side': -1}) == joins


@pytest.mark.parametrize('join', [True, False])
def test_a_cusp_on_a_followed_boundary_gives_that_vast_node_an_edge(join):
    """A cusp sensed while tracing a narrow node (Fig. 11) that lies on the path of a vast
    node's boundary circuit is a cusp of that vast cell: with ``circuit_join`` it gives the
    known node an edge and ends the branch, no node is created (one node per cell, Section
    IV-C); without it a new vast node is created beyond the cusp, as for an unknown cell."""
    p = _planner(circuit_join=join)
    p.on_odometry(0.0, 5.0, 2.1, 0.0)
    trace = [(x, 2.0) for x in np.arange(0.0, 10.0, 0.3)]
    vast = Node(0, 'vast', (0.0, 2.0), covered=True,
                circuits=[{'start': (0.0, 2.0), 'done': True, 'trace': trace}])
    branch = Branch((5.0, 0.5), (0.0, 1.0))
    p.nodes += [vast, Node(1, 'narrow', (5.0, 0.5), branches=[branch])]
    p.current, p.mode, p.t_sweep = 1, 'gvd', 1.0
    p.task = {'branch': branch, 'heading': (0.0, 1.0)}
    p._on_event(1.0, 'cusp', (5.0, 2.1), 'test')
    assert branch.end == 'cusp'
    if join:
        assert len(p.nodes) == 2 and p.edges == [(0, 1, (5.0, 2.1))]
    else:
        assert len(p.nodes) == 3 and p.nodes[2].kind == 'vast'
        assert p.edges == [(2, 1, (5.0, 2.1))] and math.dist(p.nodes[2].anchor, (5.0, 2.1)) < 1e-9


@pytest.mark.parametrize('join', [True, False])
def test_an_obstacle_another_vast_node_followed_is_no_obstacle_inside_the_cell(join):
    """A lap ends 2 m below a wall whose curve D = delta the circuit of another vast node
    followed (pillars exactly 2 delta apart join two vast cells at a point: report.pillar_hall
    (20.0)). With ``circuit_join`` that boundary is followed already: no critical point, no
    circuit round it again; without, only the node's own circuits count and the lap meets an
    obstacle inside the cell."""
    p = _planner(circuit_join=join)
    p.on_odometry(0.0, 5.0, 3.0, 0.0)
    p.angles, p.ranges = p.mount.copy(), np.full(16, 4.5)
    p.ranges[int(np.argmin(np.abs(np.remainder(p.angles - math.pi / 2 + math.pi,
                                               2 * math.pi) - math.pi)))] = 2.0
    xs = np.arange(0.0, 10.0, 0.3)
    other = Node(0, 'vast', (0.0, 3.0), covered=True, circuits=[
        {'start': (0.0, 3.0), 'done': True, 'trace': [(x, 3.0) for x in xs],
         'wall': [(x, 5.0) for x in xs]}])
    cell = MorseCell(0, (5.0, 3.0), 1, status='covering')
    here = Node(1, 'vast', (5.0, 3.0), cells=[cell])
    p.nodes += [other, here]
    p.current, p.t_sweep = 1, 1.0
    p._island(here, cell, 1)
    assert len(here.circuits) == (0 if join else 1)
    assert sum(e[1] == 'critical' for e in p.events) == (0 if join else 1)


def test_a_circuit_back_on_its_own_trace_the_same_way_has_gone_round():
    """A boundary circuit is done where it is back on a stretch of its own trace followed
    the same way (``_retraced``): up an arm of a bent sliver and back down it, then up again,
    the robot has gone round the curve D = delta once although it never passed its start
    (the corner of the bend, 1.5 m off the arm). Coming back down the arm (the other way) is
    not yet round."""
    pl = _planner()
    up = [(4.6, 2.0 + 0.3 * i) for i in range(10)]             # y 2.0 -> 4.7
    down = [(4.65, 4.7 - 0.3 * i) for i in range(1, 10)]       # y 4.4 -> 2.0
    circ, tk = {'trace': [], 'runs': []}, {'first': 0}
    run = 0.0
    for p in up + down:
        if circ['trace']:
            run += math.dist(circ['trace'][-1], p)
        circ['trace'].append(p)
        circ['runs'].append(run)
    tk['length'] = run
    pl.pose = np.array([4.62, 1.75, 0.0])               # on down the arm: the other way
    assert not pl._retraced(circ, tk)
    circ['trace'].append((4.6, 1.85))
    circ['runs'].append(run + 0.2)
    pl.pose = np.array([4.6, 2.2, 0.0])                  # up the arm again
    tk['length'] = run + 0.55
    assert pl._retraced(circ, tk)
