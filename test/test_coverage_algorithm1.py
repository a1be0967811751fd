"""The paper planner (coverage_pkg/algorithm1.py): Algorithm 1 of Acar, Choset and Lee driven by
sensed events alone; its pieces and a closed loop on a hand-made world."""
import math
from pathlib import Path

import numpy as np
import pytest

from coverage_pkg.algorithm1 import Branch, MorseCell, Node, PaperConfig, PaperPlanner, TracedPaths
from coverage_pkg.kinematic import run_kinematic
from coverage_pkg.sonar import SonarRing
from coverage_pkg.world import load_world, world_from_dict
from paramotion.errors import UserError

DOOR_ROOMS = Path(__file__).resolve().parents[1] / 'coverage_pkg' / 'worlds' / 'door_rooms.json'


def _planner(**kw):
    ring = SonarRing()
    return PaperPlanner(PaperConfig(**kw), ring.mount_angles(), ring.beam_width,
                        ring.min_range, ring.max_range)


def test_bad_without_is_refused_with_one_line():
    with pytest.raises(UserError, match='without "cusps" must be one of cusp, critical, meet'):
        _planner(without=('cusps',))


@pytest.mark.parametrize('echo, kind', [(4.0, 'vast'), (1.5, 'narrow')])
def test_create_node_takes_its_kind_from_the_ring_distance(echo, kind):
    """CreateNode(x, D(x)): vast where D > delta, narrow otherwise (Section IV-A)."""
    p = _planner()
    p.on_odometry(0.0, 0.0, 0.0, 0.0)
    for k in range(12):
        p.on_odometry(0.1 * k, 0.0, 0.0, 0.0)
        p.on_sweep(0.1 * k, np.full(16, echo))
        p.update(0.1 * k)
    assert [n.kind for n in p.nodes] == [kind]
    assert p.nodes[0].created_by is None         # the start: no event created it


def test_traced_paths_join_samples_only_inside_the_disk_the_ring_saw_free():
    paths = TracedPaths(clearance=0.35)
    for x in np.arange(0.0, 3.2, 0.32):          # along a wall: D = 0.6 m everywhere
        paths.add(float(x), 0.0, 0.6)
    route = paths.route(paths.nearest((0.0, 0.0)), paths.nearest((2.88, 0.0)))
    wide = TracedPaths(clearance=0.35)
    for x in np.arange(0.0, 3.2, 0.32):          # in the open: D = 3 m
        wide.add(float(x), 0.0, 3.0)
    hops = wide.route(0, len(wide.xy) - 1)
    steps = [math.dist(a, b) for a, b in zip(hops, hops[1:])]
    assert max(steps) > 1.0 and max(steps) <= wide.hop + 1e-9   # shortcuts, up to one hop
    steps = [math.dist(a, b) for a, b in zip(route, route[1:])]
    assert max(steps) <= 0.32 + 1e-9            # no shortcut: 0.64 m > D - clearance
    assert route[0] == (0.0, 0.0) and route[-1] == pytest.approx((2.88, 0.0))


def _traced(p, points, heading):
    """Points of a GVD edge as if traced (sweep 0) along ``heading``."""
    for x, y in points:
        p.gvd_trace.setdefault((int(x // 1.0), int(y // 1.0)), []).append(
            (x, y, 0, *heading, 0, None))


def test_a_branch_along_a_traced_gvd_edge_ends_traced_one_across_it_stays_open():
    """Each GVD edge is traced once: a branch whose edge the robot has traced (from its other
    end) ends 'traced' without a move, and its narrow node is covered by FindUncoveredNode;
    a branch that crosses the traced edge, or leaves it, stays open (``traced_way`` off: all
    three points out along the branch on the traced edge)."""
    p = _planner(traced_way=False)
    p.on_odometry(0.0, 0.0, 0.0, 0.0)
    _traced(p, [(x, 1.5) for x in np.arange(2.0, 8.0, 0.2)], (1.0, 0.0))
    n = Node(0, 'narrow', (1.6, 1.5))
    p.nodes.append(n)
    along = Branch((1.8, 1.6), (1.0, -0.05))            # the same edge, from its start
    across = Branch((5.0, 0.2), (0.0, 1.0))             # crosses it
    away = Branch((5.0, 1.5), (0.0, 1.0))               # leaves it at a junction
    n.branches += [along, across, away]
    assert p._open_branches(n) == [across, away]
    assert along.end == 'traced'
    assert p.events[-1][1] == 'branch_end'
    n.branches[:] = [along]
    assert p.find_uncovered_node() is None and n.covered


def test_a_branch_whose_traced_edge_ends_at_a_known_meet_point_ends_traced():
    """Each GVD edge is traced once, however short: a branch whose way out lies on a traced
    GVD edge up to a known meet point, where that edge turns away, ends 'traced'; without
    the meet point the same branch stays open (2.4 m out is not on the traced edge;
    ``traced_way`` off)."""
    for meet, end in (((3.3, 1.5, 0), 'traced'), (None, None)):
        p = _planner(traced_way=False)
        p.on_odometry(0.0, 0.0, 0.0, 0.0)
        _traced(p, [(x, 1.5) for x in np.arange(1.6, 3.3, 0.2)], (1.0, 0.0))
        _traced(p, [(3.3, y) for y in np.arange(1.7, 5.0, 0.2)], (0.0, 1.0))
        n = Node(0, 'narrow', (1.6, 1.5))
        p.nodes.append(n)
        if meet:
            n.meets.append(meet)
        b = Branch((1.8, 1.5), (1.0, 0.0))
        n.branches.append(b)
        assert p._open_branches(n) == ([] if meet else [b]) and b.end == end


def test_a_branch_whose_way_reaches_a_traced_edge_along_or_across_it_ends_traced():
    """``traced_way`` (ours, on): a branch whose way out comes within 0.4 m of a traced GVD
    edge, over 0.7 m from its start, ends 'traced' where that edge runs across the way (the
    branch's edge ends on it), where it runs along the way towards the branch's start (the
    branch's edge reached from its other end, curving off the straight way), or where it
    runs along the way from a trace that passed the branch's start. Open stay: a branch that
    leaves the traced edge at a junction, one beside a trace that left the same start in the
    same direction (a sibling edge), the same branches with no traced edge there, and all of
    them with ``traced_way`` off."""
    def trace(p, points, heading, start):
        for x, y in points:
            p.gvd_trace.setdefault((int(x // 1.0), int(y // 1.0)), []).append(
                (x, y, 0, *heading, 0, start))

    def branches():
        return {'across': Branch((5.0, 0.2), (0.0, 1.0)),          # 1.3 m to the edge
                'towards': Branch((1.6, 1.2), (math.cos(0.35), math.sin(0.35))),
                'junction': Branch((5.0, 1.5), (0.0, 1.0)),        # leaves the edge
                'sibling': Branch((10.0, 3.3), (math.cos(0.2), math.sin(0.2))),
                'through': Branch((10.0, 6.0), (math.cos(0.2), math.sin(0.2)))}
    for traced_way, edge, closed in ((True, True, {'across', 'towards', 'through'}),
                                     (True, False, set()), (False, True, set())):
        p = _planner(traced_way=traced_way)
        p.on_odometry(0.0, 0.0, 0.0, 0.0)
        if edge:
            # traced towards -x, from a meet point at (8, 1.5)
            trace(p, [(x, 1.5) for x in np.arange(8.0, 2.0, -0.2)], (-1.0, 0.0), (8.0, 1.5))
            # a sibling's trace leaving (10, 3.3) along +x
            trace(p, [(x, 3.3) for x in np.arange(10.0, 14.0, 0.2)], (1.0, 0.0), (10.0, 3.3))
            # a trace from (7, 6) along +x through (10, 6)
            trace(p, [(x, 6.0) for x in np.arange(7.0, 14.0, 0.2)], (1.0, 0.0), (7.0, 6.0))
        n = Node(0, 'narrow', (1.6, 1.5))
        p.nodes.append(n)
        b = branches()
        n.branches += list(b.values())
        open_ = p._open_branches(n)
        assert {k for k, v in b.items() if v.end == 'traced'} == closed, (traced_way, edge)
        assert [v for v in b.values() if v.end is None] == open_


def test_trace_joining_a_traced_edge_along_it_is_recognised_not_one_crossing_it():
    """The trace of a branch ends 'traced' where it runs along a GVD edge traced before it
    began (same direction or against it), not where it crosses one."""
    p = _planner()
    _traced(p, [(x, 1.5) for x in np.arange(2.0, 8.0, 0.2)], (1.0, 0.0))
    assert p._near_trace((4.0, 1.6), 0.35, before=5, along=(-1.0, 0.0))
    assert not p._near_trace((4.0, 1.6), 0.35, before=5, along=(0.0, 1.0))
    assert not p._near_trace((4.0, 1.6), 0.35, before=0, along=(1.0, 0.0))   # traced since


def test_a_circuit_that_encloses_no_area_senses_its_two_tips_as_cusps():
    """Walls about 2 delta apart: the vast cell is a sliver along the GVD and its circuit
    runs out and back; its tips (D = delta on the GVD) are cusps, each a narrow node beyond
    it. A circuit around a real cell senses none this way; without cusp, none."""
    out_and_back = [(x, 2.0) for x in np.arange(3.0, 8.01, 0.3)] + \
        [(x, 2.1) for x in np.arange(8.0, 2.99, -0.3)]
    square = [(x, 2.0) for x in np.arange(3.0, 8.0, 0.3)] + [(8.0, 2.0), (8.0, 5.0),
                                                              (3.0, 5.0)]
    for trace, without, tips in ((out_and_back, (), 2), (square, (), 0),
                                 (out_and_back, ('cusp',), 0)):
        p = _planner(without=without)
        p.on_odometry(0.0, 5.0, 2.0, 0.0)
        p.t_sweep = 1.0
        p.nodes.append(Node(0, 'vast', (5.0, 2.0)))
        p.current = 0
        assert p._sliver_tips(trace) == (trace is out_and_back)
        made = [n for n in p.nodes if n.kind == 'narrow']
        assert len(made) == tips
        if tips:
            assert sorted(round(n.anchor[0]) for n in made) == [3, 8]
            assert all(p.events[n.created_by][1] == 'cusp' for n in made)


@pytest.mark.slow
def test_a_door_branch_leaves_through_the_door_not_diagonally_past_a_jamb():
    """At a meet point in a corridor beside a door (the ring of gen_mixed_609 there), two
    cones two apart read far through the door and the one between them meets the room's
    obstacle beyond delta: one gap, whose GVD edge leaves between the two. Taking the first
    of them sent the branch diagonally past the jamb, back along the corridor, and the room
    behind the door stayed uncovered."""
    p = _planner()
    by_bearing = dict(zip(np.round(np.arange(16) * 22.5 + 6.6, 1),
                          [3.22, 1.20, 0.81, 0.69, 0.68, 0.73, 0.98, 1.85,
                           2.69, 1.07, 5.00, 3.56, 5.00, 0.68, 0.82, 1.54]))
    # the robot's yaw there, and the cones turned so that their order starts at 6.6 deg
    for angles in (p.mount - 3.0263706143591906, p.mount - p.mount[0] + math.radians(6.6)):
        p.angles = angles
        p.ranges = np.array([by_bearing[round(math.degrees(a % (2 * math.pi)), 1)]
                             for a in p.angles])
        back = math.radians(14.4)                # the corridor traced so far, behind
        bearings = p._openings(p.angles, p.ranges, [back], p.det)   # one sweep
        out = sorted(round(math.degrees(b), 1) for b in bearings)
        assert out == [186.6, 254.1]             # along the corridor; through the door


def test_rooms_and_corridor_are_covered_by_sensed_events_alone():
    """The start is vast (D > delta): its boundary circuit senses the room's corner cusps and
    the corridor's; every other node was created by one of those cusp events, and each edge
    carries the cusp that created it."""
    r = run_kinematic(load_world(DOOR_ROOMS), PaperConfig(), max_time=600)
    p = r['planner']
    assert r['state'] == 'done' and r['covered_fraction'] >= 0.99
    g = p.to_dict()
    start, *others = g['nodes']
    assert start['kind'] == 'vast' and start['created_by_event'] is None
    for n in others:
        ev = p.events[n['created_by_event']]
        assert ev[1] == 'cusp' and math.dist(ev[2:4], n['anchor']) < 1e-3
    assert sum(n['kind'] == 'vast' for n in g['nodes']) == 2     # the room beyond the corridor
    assert len(g['edges']) == len(others)
    for e in g['edges']:
        kinds = {g['nodes'][e['vast']]['kind'], g['nodes'][e['narrow']]['kind']}
        assert kinds == {'vast', 'narrow'}
    assert all(n['covered'] and n['closed_by_event'] is not None for n in g['nodes'])
    prim = p.primitive_lengths()
    assert set(prim) <= {'lap', 'boundary', 'gvd', 'transit'} and prim['gvd'] > 4.0


@pytest.mark.slow                         # a closed-loop run, 10-25 s
def test_obstacles_a_lap_runs_into_are_followed_and_their_slices_resumed_beyond():
    """A 15 x 15 m hall with four pillars 5 m apart: each pillar is met by a lap (a critical
    point: the slice splits), gets its own boundary circuit, and the slice is resumed on its
    far side, so the hall is covered."""
    pillars = [[[cx - 0.4, cy - 0.4], [cx + 0.4, cy - 0.4], [cx + 0.4, cy + 0.4],
                [cx - 0.4, cy + 0.4]] for cx in (5.0, 10.0) for cy in (5.0, 10.0)]
    world = world_from_dict({'name': 'pillars', 'boundary': [[0, 0], [15, 0], [15, 15], [0, 15]],
                             'obstacles': pillars, 'start': [2.5, 2.5]})
    r = run_kinematic(world, PaperConfig(), max_time=900)
    vast = r['planner'].nodes[0]
    assert r['state'] == 'done' and r['covered_fraction'] >= 0.99
    assert len(vast.circuits) == 5                    # the hall's boundary and each pillar's
    for circ in vast.circuits[1:]:
        ev = r['planner'].events[circ['opened_by']]
        assert ev[1] == 'critical' and 'split' in ev[4]
        assert min(math.dist(ev[2:4], (cx, cy)) for cx in (5, 10) for cy in (5, 10)) < 1.0


# gen_rooms_202's right room and its door, opening onto a 2 m stub
ROOM_DOOR = {'name': 'room_door', 'start': [11.696, 2.463],
             'boundary': [[7.647, 0.0], [14.71, 0.0], [14.71, 5.251], [7.647, 5.251],
                          [7.647, 3.522], [5.6, 3.522], [5.6, 2.146], [7.647, 2.146]]}


@pytest.mark.parametrize('before, cusps', [('boundary', 1), ('gvd', 0), ('lap', 0)])
def test_fig10_compares_the_closest_obstacle_between_sweeps_of_one_boundary_following(before,
                                                                                      cusps):
    """Fig. 10: following the boundary at D = delta, the closest obstacle jumps to another
    one: a cusp point. The jump is taken between two sweeps that both follow the boundary; the
    sweep before it driven by another primitive (a GVD edge, whose closest obstacle alternates
    between the two equidistant ones; a lap) gives no cusp when the boundary following begins."""
    p = _planner()
    p.on_odometry(0.0, 5.0, 5.0, 0.0)
    p.nodes.append(Node(0, 'vast', (5.0, 5.0)))
    p.current, p.t_first_sweep = 0, -5.0
    for k, (mode, near) in enumerate(((before, (0, 5)), ('boundary', (5, 0)))):
        ranges = np.full(16, 4.5)
        ranges[near[0]], ranges[near[1]] = 1.98, 2.03     # the closest echo jumps 112 deg
        p.mode = mode
        p.on_sweep(1.0 + 0.1 * k, ranges)
    assert sum(e[1] == 'cusp' for e in p.events) == cusps


def test_thin_is_a_circuit_that_turned_around_a_cell_within_delta_of_it():
    """``_thin`` (switch circuit_sweeps): every point a closed circuit encloses lies within
    delta - overlap of it. A 3 x 1.2 m loop is; a 6 x 6 m loop is not (its middle is 3 m
    from it); an open U (the circuit ended at its closest pass by the start) is not."""
    p = _planner()

    def loop(w, h):
        return [(x, 0.0) for x in np.arange(0.0, w, 0.3)] + \
            [(w, y) for y in np.arange(0.0, h, 0.3)] + \
            [(x, h) for x in np.arange(w, 0.0, -0.3)] + \
            [(0.0, y) for y in np.arange(h, 0.0, -0.3)]
    assert p._thin(loop(3.0, 1.2))
    assert not p._thin(loop(6.0, 6.0))
    u = [(7.48, 2.89), (7.45, 2.49), (7.43, 2.1), (7.72, 1.99), (8.12, 1.99), (8.06, 2.38),
         (8.03, 2.78), (8.05, 3.17)]                   # gen_mixed_100's first circuit
    assert not p._thin(u)


@pytest.mark.parametrize('circuit_sweeps', [False, True])
def test_a_cell_its_circuit_has_swept_gets_no_laps_with_circuit_sweeps(circuit_sweeps):
    """A 7 x 5.25 m room: its vast cell lies within 1 m of the boundary circuit, so the
    circuit has swept it. With circuit_sweeps (ours) the Morse cell closes when the circuit
    ends, without laps; in the paper's mode its laps are driven. Both cover the room."""
    r = run_kinematic(world_from_dict(ROOM_DOOR), PaperConfig(circuit_sweeps=circuit_sweeps),
                      max_time=300)
    cell = r['planner'].nodes[0].cells[0]
    assert r['state'] == 'done' and r['covered_fraction'] >= 0.99
    assert (not cell.laps) == circuit_sweeps
    closed = [e[4] for e in r['planner'].events if e[1] == 'cell_closed']
    assert any('swept by the circuit' in c for c in closed) == circuit_sweeps


@pytest.mark.parametrize('handover', [False, True])
def test_a_circuit_runs_on_past_its_start_in_the_handover_mode(handover):
    """Handed over at a cusp (Fig. 13's order), the vast node's circuit starts among the
    cell's cusps, so in that mode it runs on past its start by ``same_event`` (0.5 m) before
    it ends, for the Fig. 10 test to sense the cusps there; in Algorithm 1's mode it ends
    where it is back at its start."""
    r = run_kinematic(world_from_dict(ROOM_DOOR), PaperConfig(handover=handover), max_time=20)
    circ = r['planner'].nodes[0].circuits[0]
    assert circ['done'] and circ['back_at'] is not None
    run_on = circ['length'] - circ['back_at']
    assert (run_on >= 0.5) if handover else (run_on < 0.1)


@pytest.mark.parametrize('detour', [False, True])
def test_cusp_detour_traces_a_corner_before_the_circuit_ends_and_resumes_it(detour):
    """Switch ``cusp_detour`` (ours): in a room (one vast cell, a narrow node at each corner)
    the paper's order covers the vast node first and then each corner; with the switch the
    first corner's GVD edge is traced as soon as the circuit senses its cusp, the circuit is
    resumed where it was left, and the room is covered all the same."""
    room = world_from_dict({'name': 'room', 'boundary': [[0, 0], [9, 0], [9, 7], [0, 7]],
                            'obstacles': [], 'start': [4.5, 3.5]})
    r = run_kinematic(room, PaperConfig(cusp_detour=detour), max_time=600)
    p = r['planner']
    assert r['state'] == 'done' and r['covered_fraction'] >= 0.99
    kinds = [e[1] for e in p.events]
    first_end = kinds.index('branch_end')
    vast_done = next(i for i, e in enumerate(p.events)
                     if e[1] == 'node_covered' and e[4].startswith('vast'))
    assert (first_end < vast_done) == detour
    assert sum(n.kind == 'narrow' for n in p.nodes) == 4
    assert all(n.covered for n in p.nodes)


@pytest.mark.parametrize('circuit_y, split', [(2.0, False), (2.3, True), (4.5, True)])
def test_a_lap_ending_on_the_circuit_path_before_its_wall_is_no_obstacle_inside_the_cell(
        circuit_y, split):
    """A lap ends at D = delta, 2 m above a wall (its point p). Where it ends on the path of
    the cell's boundary circuit and p lies within delta + 0.15 m of that path, the circuit
    kept D = delta from p's wall: the wall is followed, no critical point, no second circuit,
    even though the circuit's recorded closest echoes miss p (gen_rooms_202's right room,
    where the cones' spacing left the wall below a corner of the circuit unrecorded). A
    circuit that passed 2.3 m from p (between two pillars, following the other one) or far
    away did not follow it: the lap meets an obstacle inside the cell, a split and a circuit
    around it."""
    p = _planner()
    p.pose, p.t_sweep = (12.7, 2.0, 0.0), 10.0
    p.angles = np.linspace(-math.pi, math.pi, 16, endpoint=False)
    p.ranges = np.full(16, 5.0)
    p.ranges[int(np.argmin(np.abs(p.angles + math.pi / 2)))] = 2.0   # the wall y = 0 below
    n = Node(0, 'vast', (11.7, 2.5))
    trace = [(x, circuit_y) for x in np.arange(9.6, 12.8, 0.3)]
    n.circuits.append({'start': trace[0], 'done': True, 'trace': trace,
                       'wall': [(x, -0.8) for x, _ in trace]})   # its echoes recorded elsewhere
    p.nodes.append(n)
    p.current = 0
    cell = MorseCell(0, (12.7, 3.2), +1)
    n.cells.append(cell)
    p._island(n, cell, -1)
    assert (len(n.circuits) == 2) == split
    assert bool(n.critical) == split
    if split:
        assert n.critical[0][2].startswith('split') and \
            math.dist(n.critical[0][:2], (12.7, 0.0)) < 0.1
