"""A cusp where three closest obstacles are equidistant is also a meet point (CreateNode).

The world is gen_mixed_1075's shape: a room 5.15 m wide and 5.89 m high (a small vast cell
whose boundary circuit senses a cusp at each of its four corners) with a 1.37 m door in its
top wall, 1.19 m left of the north-east corner, onto a corridor 1.59 m high and 23.6 m long.
The door's GVD edge (between its jambs) and the north-east corner's edge (between the right
wall and the right jamb) leave the vast cell together, a quarter of a metre apart, where the
two jambs and the right wall are about delta from the robot. The cusp's own branch runs along
the bisector of its two closest obstacles, into the corner, where it ends; the three-echo test
takes no meet point there (its three obstacles lie within half a turn, a door's own meet
point). Read as a meet point at D = delta, the cusp gives the narrow node a second branch,
north through the door.
"""
import math

import numpy as np
import pytest
from paper_rules import LATER_RULES_OFF

from coverage_pkg.algorithm1 import PaperConfig
from coverage_pkg.kinematic import run_kinematic
from coverage_pkg.world import world_from_dict

CORNER_DOOR = {'name': 'corner_door', 'start': [6.194, 2.011], 'obstacles': [],
               'boundary': [[5.026, 0.135], [10.174, 0.135], [10.174, 6.028], [8.987, 6.028],
                            [8.987, 6.228], [23.617, 6.228], [23.617, 7.817], [0.0, 7.817],
                            [0.0, 6.228], [7.617, 6.228], [7.617, 6.028], [5.026, 6.028]]}


def _highest(r):
    """The highest y the robot reached (the corridor lies above y 6.23)."""
    return float(np.asarray(r['path'])[:, 1].max())


@pytest.mark.slow                         # two closed-loop runs, about 3 s
def test_the_door_beside_a_corners_cusp_is_a_branch_of_its_narrow_node():
    """With ``cusp_meet`` the cusp is read as a meet point: a meet event at the north-east
    cusp adds a branch northwards, the robot traces it through the door into the corridor
    and the world is covered. Without it, the cusp's one branch ends in the corner, the
    corridor is never entered and most of it stays uncovered."""
    r = run_kinematic(world_from_dict(CORNER_DOOR), PaperConfig(cusp_meet=True, **LATER_RULES_OFF),
                      max_time=3000)
    assert r['state'] == 'done' and r['covered_fraction'] >= 0.99
    assert _highest(r) > 6.5
    at_cusp = [e for e in r['planner'].events if e[1] == 'meet' and 'at the cusp' in e[4]]
    assert any(math.dist(e[2:4], (8.15, 4.2)) < 0.5 for e in at_cusp)
    n = next(k for k in r['planner'].nodes
             if k.kind == 'narrow' and math.dist(k.anchor, (8.15, 4.2)) < 0.5)
    assert any(b.heading[1] > 0.9 for b in n.branches)          # north, through the door

    off = run_kinematic(world_from_dict(CORNER_DOOR),
                        PaperConfig(cusp_meet=False, **LATER_RULES_OFF), max_time=3000)
    assert off['state'] == 'done' and off['covered_fraction'] < 0.9
    assert _highest(off) < 6.0
    assert not any('at the cusp' in e[4] for e in off['planner'].events)


#: gen_mixed_7023's start room: 5.77 m x 4.53 m, its 1.34 m door in the bottom wall 1.28 m
#: right of the bottom-left corner, onto a corridor 1.56 m high. The corner's cusp is sensed
#: where three obstacles are about equidistant (the left wall, the wall left of the door and
#: the wall right of it); the bisector of its two closest points at the wall between the
#: corner (gap at about 204 deg) and the door (about 260 deg).
DOOR_BY_CORNER = {'name': 'door_by_corner', 'start': [16.169, 8.429], 'obstacles': [],
                  'boundary': [[13.408, 6.796], [13.408, 11.328], [19.181, 11.328],
                               [19.181, 6.796], [16.027, 6.796], [16.027, 6.596],
                               [22.0, 6.596], [22.0, 5.035], [8.0, 5.035], [8.0, 6.596],
                               [14.686, 6.596], [14.686, 6.796]]}
CORNER = (13.9, 7.3)


def _first_in_corridor(r):
    """Time of the first event below the room's bottom wall (in the door or corridor)."""
    return min(e[0] for e in r['planner'].events if e[3] < 6.6)


def _corner_branch_heading(r):
    """Bearing (deg) of the branch the corner's cusp opened, off its own narrow node."""
    pl = r['planner']
    n = next(k for k in pl.nodes if k.kind == 'narrow' and math.dist(k.anchor, (15.4, 8.6)) < 0.4)
    b = next(b for b in n.branches if b.opened_by == n.created_by)
    return math.degrees(math.atan2(b.heading[1], b.heading[0])) % 360


@pytest.mark.slow                         # two closed-loop runs, about 3 s
def test_with_cusp_meet_gap_the_corners_own_branch_leaves_through_the_door():
    """With ``cusp_meet_gap`` the cusp's own branch takes the gap nearest its bisector, the
    door's, and the robot enters the corridor on the first trace from that cusp, before it
    reaches the corner. Without it, the branch keeps the bisector and is matched to the
    door's gap, so both traces run into the corner, and the door is found only as a gap
    beside the second one's dead end."""
    on = run_kinematic(world_from_dict(DOOR_BY_CORNER), PaperConfig(cusp_meet_gap=True),
                       max_time=3000)
    assert on['state'] == 'done' and on['covered_fraction'] >= 0.99
    assert abs(_corner_branch_heading(on) - 260) < 10
    ends = [e[0] for e in on['planner'].events if e[1] == 'branch_end' and
            math.dist(e[2:4], CORNER) < 0.8]
    assert ends and _first_in_corridor(on) < min(ends)
    assert not any('where the GVD edge ends' in e[4] for e in on['planner'].events)

    off = run_kinematic(world_from_dict(DOOR_BY_CORNER), PaperConfig(cusp_meet_gap=False),
                        max_time=3000)
    assert off['state'] == 'done' and off['covered_fraction'] >= 0.99
    assert abs(_corner_branch_heading(off) - 238) < 10
    gap = [e[0] for e in off['planner'].events if 'where the GVD edge ends' in e[4]]
    assert gap and _first_in_corridor(off) > min(gap)
