"""A gap at a dead end is a known branch only if both lead to one place (TraceGVD).

The world is gen_rooms_5086's shape: a room 7.67 m x 6.27 m with two small obstacles and a
door 1.44 m wide in its right wall just above the bottom-right corner, onto a second room of
the same size; a stub on the left, beside which the robot starts. The robot senses a meet point
about 1.3 m from that corner, leaves it towards the door, and the GVD law takes it along the
edge between the floor and the door's lower jamb into the corner, a dead end. From there the
door is a gap beyond delta at about 46 degrees; the meet point, 0.9 m away, has a branch at
86 degrees, up between the obstacle and the right wall. Compared as bearings read from
their two places, 40 degrees apart, the gap is taken for that branch's edge and dropped, and
the second room stays unentered. Compared from one place, delta out along the gap lies about
64 degrees off the branch's bearing from the meet point: the door is a branch and the robot
covers the room beyond.
"""
import math

import numpy as np
import pytest

from coverage_pkg.algorithm1 import PaperConfig, PaperPlanner
from coverage_pkg.kinematic import run_kinematic
from coverage_pkg.world import world_from_dict

ROOMS = {'name': 'room_door_by_corner', 'start': [7.2, 2.3],
         'boundary': [[6.713, 0.0], [6.713, 1.437], [5.5, 1.437], [5.5, 2.659],
                      [6.713, 2.659], [6.713, 6.273], [14.383, 6.273], [14.383, 2.318],
                      [14.583, 2.318], [14.583, 6.273], [21.866, 6.273], [21.866, 0.0],
                      [14.583, 0.0], [14.583, 0.879], [14.383, 0.879], [14.383, 0.0]],
         'obstacles': [[[11.376, 2.135], [10.864, 1.799], [10.939, 1.35], [11.694, 1.316],
                        [11.772, 1.431]],
                       [[11.589, 4.067], [11.109, 4.014], [11.307, 3.384], [11.351, 3.378],
                        [11.526, 3.406]]]}


def _farthest_east(r):
    """The greatest x the robot reached (the second room is x 14.58-21.87)."""
    return float(np.asarray(r['path'])[:, 0].max())


@pytest.mark.slow                         # two closed-loop runs, about 3 s
def test_the_door_beside_a_dead_end_is_no_branch_read_from_elsewhere(monkeypatch):
    """Compared from one place, the door's gap at the corner's dead end is a branch: the
    robot passes the door and covers both rooms. Compared as bearings read from the dead
    end and from the meet point, the gap is the meet point's upward branch, the robot never
    passes the door and about half the world stays unseen. Both runs have ``meet_side_pair``
    off (past the meet point it leads the robot through the door with the rule before too)
    and ``way_come_held`` off (the switches as this rule was made)."""
    cfg = PaperConfig(meet_side_pair=False, way_come_held=False)
    r = run_kinematic(world_from_dict(ROOMS), cfg, max_time=3000)
    assert r['state'] == 'done' and r['covered_fraction'] >= 0.99
    assert _farthest_east(r) > 16.0

    def bearings_here(self, q, b):              # the rule before: the two bearings alone
        a = math.atan2(q.heading[1], q.heading[0])
        return abs(math.remainder(a - b, 2 * math.pi)) < math.radians(45)

    monkeypatch.setattr(PaperPlanner, '_known_branch', bearings_here)
    off = run_kinematic(world_from_dict(ROOMS), cfg, max_time=3000)
    assert off['state'] == 'done' and off['covered_fraction'] < 0.9
    assert _farthest_east(off) < 14.6
