"""At a meet point, the way come is read from the branch's own trace (TraceGVD._way_back).

The world is gen_maze_1179's shape: a room 4.38 m square (about 2 delta, delta = 2 m) with a
door in its floor, left of the middle, onto corridors that loop east and back. The robot
starts in the room, traces the corridors and then the GVD edge towards the room's top-right
corner to a dead end, and transits back down to the narrow node's start. From there it leaves
along the branch towards the top-left corner and senses a meet point within half a metre. The
robot's path 1.5 m behind lies on the transit it came down along from the top right, not on
the edge it came along: read from there, the way come points up to the right, and both top
corners' openings lie within 60 degrees of it, so the meet point gets no branch towards the
top-left corner and that corner stays unseen. Read from the branch's start, the way come
points back down to the node, and the top-left corner's opening is a branch.
"""
import numpy as np
import pytest

from coverage_pkg.algorithm1 import PaperConfig, PaperPlanner
from coverage_pkg.kinematic import run_kinematic
from coverage_pkg.world import world_from_dict

ROOM = {'name': 'room_2delta_door_loop', 'start': [2.707, 3.014], 'obstacles': [],
        'boundary': [[1.5, 1.435], [1.505, 1.435], [1.505, 2.191], [0.0, 2.191],
                     [0.0, 6.568], [4.377, 6.568], [4.377, 2.191], [2.872, 2.191],
                     [2.872, 1.435], [5.077, 1.435], [5.077, 1.491], [5.17, 1.491],
                     [5.17, 3.596], [5.039, 3.596], [5.039, 5.163], [10.24, 5.163],
                     [10.24, 3.596], [6.475, 3.596], [6.475, 1.491], [10.202, 1.491],
                     [10.202, 0.0], [5.077, 0.0], [5.077, 0.057], [1.5, 0.057]]}
CORNER = (0.0, 6.568)                    # the room's top-left corner


def _corner_approach(r):
    """The robot's least distance to the top-left corner."""
    p = np.asarray(r['path'])
    return float(np.hypot(p[:, 0] - CORNER[0], p[:, 1] - CORNER[1]).min())


@pytest.mark.slow                         # two closed-loop runs, about 2 s
def test_the_way_come_at_a_meet_point_is_read_from_the_branch(monkeypatch):
    """Read from the branch's own trace, the way come at the meet point near the branch's
    start points back to the node, the top-left corner's edge is a branch, and the room is
    covered. Read from the path 1.5 m behind (across the transit before the branch), the
    corner's opening is taken for the way come: the robot stays over 2.5 m from that corner
    and part of the room stays unseen."""
    r = run_kinematic(world_from_dict(ROOM), PaperConfig(), max_time=3000)
    assert r['state'] == 'done' and r['covered_fraction'] >= 0.99
    assert _corner_approach(r) < 2.5

    old = PaperPlanner._way_back

    def path_behind(self, heading, back=1.5, since=None, origin=None):
        return old(self, heading, back)              # the rule before: the path 1.5 m behind

    monkeypatch.setattr(PaperPlanner, '_way_back', path_behind)
    r = run_kinematic(world_from_dict(ROOM), PaperConfig(), max_time=3000)
    assert r['covered_fraction'] < 0.99
    assert _corner_approach(r) > 2.5
