"""The edge a robot came along to a meet point is read from its path (TraceGVD).

The world is gen_halls_1012's shape: a hall 14.16 m long and 4.06 m high (2 delta + 0.06 m,
delta = 2 m), a tower 3 m wide rising from its middle and an island right of the tower. The
robot starts right of the island and traces the GVD round the island's bottom; the meet
point left of the island (bottom wall, top wall and island about delta away) is sensed, and
the robot halts about 0.4 m past it facing north-east, off the edge it came along (from the
south-east, under the island). The hall's left half opens west of the meet point, 40-50
degrees from the reversed heading.

The runs switch ``cusp_meet`` off: with it on, the left half is entered the same way but
its sliver's tip is passed without a cusp, and the top-left corner is left unseen (98.66 %
of CVS, as in gen_halls_1012 itself; docs/coverage.md lists it).
"""
import math

import numpy as np
import pytest
from paper_rules import LATER_RULES_OFF

from coverage_pkg.algorithm1 import PaperConfig, PaperPlanner
from coverage_pkg.kinematic import run_kinematic
from coverage_pkg.world import world_from_dict

HALL = {'name': 'hall_tower_island', 'start': [11.11, 1.1],
        'boundary': [[14.162, 4.061], [14.162, 0.0], [0.0, 0.0], [0.0, 4.061], [5.94, 4.061],
                     [5.94, 7.975], [8.917, 7.975], [8.917, 4.061]],
        'obstacles': [[[9.29, 2.408], [9.092, 2.592], [8.619, 2.68], [8.177, 2.397],
                       [8.063, 2.097], [9.166, 1.481]]]}


def _left_reached(r):
    """The least x the robot reached (the hall's left half is x < 5)."""
    return float(np.asarray(r['path'])[:, 0].min())


@pytest.mark.slow                         # two closed-loop runs, about 3 s
def test_the_opening_beside_the_reversed_heading_is_a_branch(monkeypatch):
    """With the way come read from the path 1.5 m behind, the hall's left half is a branch of
    the meet point: the robot traces it and the world is covered. With the way come taken as
    the heading reversed, the left half's opening lies within 60 degrees of it and is taken
    for the way come: the robot never goes left of x 5 and a quarter of the hall stays
    uncovered."""
    cfg = PaperConfig(cusp_meet=False, **LATER_RULES_OFF)
    r = run_kinematic(world_from_dict(HALL), cfg, max_time=3000)
    assert r['state'] == 'done' and r['covered_fraction'] >= 0.99
    assert _left_reached(r) < 3.0

    monkeypatch.setattr(PaperPlanner, '_way_back',
                        lambda self, h, back=1.5, since=None, origin=None:
                        math.atan2(-h[1], -h[0]))
    off = run_kinematic(world_from_dict(HALL), cfg, max_time=3000)
    assert off['state'] == 'done' and off['covered_fraction'] < 0.9
    assert _left_reached(off) > 5.0
