"""A gap beside the end of a traced GVD edge is a branch (TraceGVD, a meet event).

The world is gen_halls_1006's shape: a hall 10.4 m long and 3.70 m high (narrower than
2 delta, delta = 2 m) with a room 3.10 m wide rising from its left end to y 9.2 m. The robot
starts near the hall's right end and traces the hall's GVD leftwards. The meet point where
the bottom wall, the left wall and the room's corner (3.10, 3.70) are equidistant (about
(1.97, 1.97)) is not sensed, and the trace curves onto the edge into the bottom-left corner,
where it ends: all ahead is in view. There the range over bearing has two peaks beyond delta,
the hall behind (east) and the room (north); the edge's last heading reversed points between
them, within 60 degrees of both, and the bearing to the path 1.5 m behind lies in the east
peak. Only that peak is the way back; the room's is a branch.
"""
import math

import numpy as np
import pytest
from paper_rules import LATER_RULES_OFF

from coverage_pkg.algorithm1 import PaperConfig, PaperPlanner
from coverage_pkg.kinematic import run_kinematic
from coverage_pkg.world import world_from_dict

L_HALL = {'name': 'l_hall', 'start': [8.9, 1.9], 'obstacles': [],
          'boundary': [[10.425, 3.702], [10.425, 0.0], [0.0, 0.0], [0.0, 9.199],
                       [3.096, 9.199], [3.096, 3.702]]}


def _room_reached(r):
    """The highest y the robot reached (the room rises from y 3.70 to 9.20)."""
    return float(np.asarray(r['path'])[:, 1].max())


@pytest.mark.slow                         # two closed-loop runs, about 3 s
def test_the_room_beside_the_end_of_the_hall_is_a_branch(monkeypatch):
    """With the way back read from the path, a meet event at the trace's end adds a branch
    northwards, the robot traces it into the room and the world is covered. With the way
    back taken as the last heading reversed, both peaks read as the way come, no branch is
    added, the room is never entered and most of it stays uncovered. The meet point the
    trace passes just beyond delta (TraceGVD._passed_meet_branches) leads into the room as
    well; it is switched off in both runs, so that the gap at the end is the only way."""
    monkeypatch.setattr(PaperPlanner, '_passed_meet_branches', lambda self, n: None)
    r = run_kinematic(world_from_dict(L_HALL), PaperConfig(**LATER_RULES_OFF), max_time=3000)
    assert r['state'] == 'done' and r['covered_fraction'] >= 0.99
    assert _room_reached(r) > 5.5
    pl = r['planner']
    gaps = [e for e in pl.events if e[1] == 'meet' and 'where the GVD edge ends' in e[4]]
    assert any(e[2] < 3.1 and e[3] < 3.7 for e in gaps)

    monkeypatch.setattr(PaperPlanner, '_way_back',
                        lambda self, h, back=1.5, since=None, origin=None:
                        math.atan2(-h[1], -h[0]))
    off = run_kinematic(world_from_dict(L_HALL), PaperConfig(**LATER_RULES_OFF), max_time=3000)
    assert off['state'] == 'done' and off['covered_fraction'] < 0.9
    assert _room_reached(off) < 3.7
