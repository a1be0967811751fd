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
