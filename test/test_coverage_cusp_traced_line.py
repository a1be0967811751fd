"""A cusp a step from where a traced branch ended is that branch's only if it lies on the
line the branch was traced along (CreateNode._on_traced_line).

The world is gen_mixed_5088's shape: a room 5.54 m by 6.34 m whose bottom wall has a door
1.21 m wide 2.04 m from the bottom-left corner, onto a hall 1.41 m high below. The robot
starts in the corner's narrow cell and traces the corner's GVD edge up to its cusp at about
(2.02, 9.52), where the vast room begins; the branch ends at (2.15, 9.59) heading 44
degrees. The room's boundary circuit then senses the door's cusp at about (2.59, 9.40),
0.48 m from where the branch ended (same_event is 0.5 m), its GVD edge leading down between
the jambs 43 degrees from the branch's reversed heading (the bearing test allows 45). Taken
for the branch's end, the door's cusp joins the corner's node, whose edges are traced, and the
hall stays unentered. The cusp lies 0.44 m across the corner edge's line, outside the strip
the robot swept along it: it is another edge's.
"""
import math

import numpy as np
import pytest

from coverage_pkg.algorithm1 import Branch, PaperConfig
from coverage_pkg.kinematic import run_kinematic
from coverage_pkg.paper.node_creation import CreateNode
from coverage_pkg.world import world_from_dict

ROOM = {'name': 'room_door_beside_corner', 'start': [1.4, 8.2],
        'boundary': [[8.0, 5.92], [0.0, 5.92], [0.0, 7.33], [2.04, 7.33], [2.04, 7.53],
                     [0.0, 7.53], [0.0, 13.87], [5.54, 13.87], [5.54, 7.53], [3.25, 7.53],
                     [3.25, 7.33], [8.0, 7.33]],
        'obstacles': []}


def _lowest(r):
    """The least y the robot reached (the hall below the door is y < 7.33)."""
    return float(np.asarray(r['path'])[:, 1].min())


def _corner_branch():
    b = Branch((1.38, 8.70), (0.76, 0.65), None)
    b.end, b.end_xy = 'cusp', (2.15, 9.59)
    b.end_heading = (math.cos(math.radians(44.4)), math.sin(math.radians(44.4)))
    return b


def test_a_cusp_across_the_traced_line_is_not_where_the_branch_ended():
    """The door's cusp passes the distance and bearing tests but lies 0.44 m across the
    corner edge's line; the corner's own cusp, 0.15 m behind the branch's end along it, and
    a cusp sensed a little ahead along the line are the branch's end."""
    b, radius = _corner_branch(), PaperConfig().radius
    door, into = (2.59, 9.40), math.radians(-92.5)
    assert CreateNode._arrived(b, door, 0.5, into)
    assert not CreateNode._arrived(b, door, 0.5, into, radius)
    corner = math.radians(-135.6)
    assert CreateNode._arrived(b, (2.02, 9.52), 0.5, corner, radius)
    assert CreateNode._arrived(b, (2.40, 9.80), 0.5, corner, radius)


@pytest.mark.slow                         # two closed-loop runs, about 3 s
def test_the_door_beside_the_corner_is_a_narrow_node_of_its_own(monkeypatch):
    """With the traced line compared, the door's cusp creates a narrow node: the robot
    traces it through the door into the hall and the world is covered. Without, the cusp
    joins the corner's node: the robot never passes the door and the hall stays unseen."""
    r = run_kinematic(world_from_dict(ROOM), PaperConfig(), max_time=3000)
    assert r['state'] == 'done' and r['covered_fraction'] >= 0.99
    assert _lowest(r) < 7.0

    monkeypatch.setattr(CreateNode, '_on_traced_line', staticmethod(lambda b, xy, w: True))
    off = run_kinematic(world_from_dict(ROOM), PaperConfig(), max_time=3000)
    assert off['state'] == 'done' and off['covered_fraction'] < 0.9
    assert _lowest(off) > 7.53
