"""A branch whose way out reaches a traced GVD edge is not driven (``traced_way``, ours, off).

The world is gen_halls_1014: an L-shaped hall 3.67 m high (under 2 delta, delta = 2 m) with a
4.3 m wide arm going up at its left end and an island right of the start. The robot starts
above the island's left end; its GVD edge leaves the start both ways, and one more gap of the
ring beyond delta, down to the right under the island, is a branch of the start too. The
robot first traces the edge round the island's right side and back along its lower side to
the meet point left of the island: that gap's way now runs onto the traced lower side.
"""
import math

import pytest

from coverage_pkg.algorithm1 import PaperConfig
from coverage_pkg.kinematic import run_kinematic
from coverage_pkg.world import load_world, world_from_dict
from coverage_pkg.worldgen import write_worlds

L_HALL = {'name': 'l_hall_island', 'start': [8.267, 2.111],
          'boundary': [[14.955, 3.671], [14.955, 0.0], [0.0, 0.0], [0.0, 8.046],
                       [4.296, 8.046], [4.296, 3.671]],
          'obstacles': [[[9.006, 1.983], [8.976, 1.301], [9.044, 1.278], [9.372, 1.361],
                         [9.487, 1.561]]]}


def _gap_branch(r):
    """The start's branch down the gap under the island (heading down and to the right)."""
    start = r['planner'].nodes[0]
    return next(b for b in start.branches if b.opened_by is None and b.heading is not None
                and b.heading[0] > 0.3 and b.heading[1] < -0.5)


@pytest.mark.slow                         # two closed-loop runs, about 3 s
def test_the_gap_onto_the_islands_traced_side_is_not_driven():
    """With ``traced_way`` the gap's branch ends 'traced' where it starts, without a move,
    and the run ends at the top of the arm. Off, only a branch whose first 2.4 m all lie on
    a traced edge counts: the gap's way curves off the island's lower side, so at the end of
    the run the robot drives back from the arm's top to the start (about 12 m) and 1.7 m
    down the gap before its trace joins the lower side. Both cover the hall."""
    on = run_kinematic(world_from_dict(L_HALL), PaperConfig(traced_way=True), max_time=3000)
    off = run_kinematic(world_from_dict(L_HALL), PaperConfig(), max_time=3000)
    for r in (on, off):
        assert r['state'] == 'done' and r['covered_fraction'] >= 0.99
    b_on, b_off = _gap_branch(on), _gap_branch(off)
    assert b_on.end == 'traced' and math.dist(b_on.start, b_on.end_xy) < 1e-6
    assert b_off.end == 'traced' and math.dist(b_off.start, b_off.end_xy) > 1.0
    assert on['path'][-1][1] > 4.0 > off['path'][-1][1]      # ends up the arm / by the island
    assert on['path_length'] < 0.85 * off['path_length']


@pytest.mark.slow                         # two closed-loop runs, about 5 s
def test_in_algorithm1_order_a_meet_point_missed_once_is_sensed_on_the_second_trace(tmp_path):
    """Why ``traced_way`` is off: it takes away the second trace of an edge, which is where a
    meet point the first trace missed is sensed. In gen_rooms_702 (four rooms, Algorithm 1's
    pseudocode order, ``handover=false``) the edge round the bottom-left room's island is
    traced from its right end, past the meet point where the top-left room's door edge leaves
    it, without sensing that meet point. Off, the branch at the island's left end is traced
    along that edge from the other end, the meet point is sensed there and the top-left room
    is covered; with ``traced_way`` the branch is closed as reached from its other end, and
    the top-left room (about a fifth of CVS) is never entered."""
    world = load_world(write_worlds(str(tmp_path), 1, seed=702)[0])
    off = run_kinematic(world, PaperConfig(handover=False), max_time=3000)
    on = run_kinematic(world, PaperConfig(handover=False, traced_way=True), max_time=3000)
    assert off['state'] == on['state'] == 'done'
    assert off['covered_fraction'] >= 0.99 > 0.9 > on['covered_fraction']
    top_left = [p for p in off['path'] if p[0] < 6.5 and p[1] > 6.2]
    assert top_left and not [p for p in on['path'] if p[0] < 6.5 and p[1] > 6.2]
