"""A door whose view is split by an obstacle beyond it is one branch along its bisector.

The world is gen_mixed_1093's shape: a corridor 1.42 m high (narrow, delta = 2 m) from x 8 to
x 22, and a room 5.37 m x 6.33 m above it entered by a door 1.35 m wide (x 13.96 to 15.31)
in a wall 0.2 m thick. A small obstacle in the room, about 2.4 m beyond the door and right
of its middle, meets the cones through the door's middle-right: seen from the meet point
below the door, the range over bearing has two peaks through the door, one past each side
of the obstacle (about 50 and 95 degrees). Both look through the one opening (no echo
between them lies within delta) and are one GVD edge. The middle of the left-hand peak
alone points at the door's right jamb: a branch along it is carried by the GVD law back
into the corridor, where it ends on the traced corridor edge and the room stays unentered.
The middle of the span covering both peaks points between the jambs.
"""
import numpy as np
import pytest

from coverage_pkg.algorithm1 import PaperConfig, PaperPlanner
from coverage_pkg.kinematic import run_kinematic
from coverage_pkg.world import world_from_dict

CORRIDOR_DOOR_ROOM = {
    'name': 'corridor_door_room', 'start': [9.0, 5.5],
    'boundary': [[8.0, 4.799], [8.0, 6.215], [13.962, 6.215], [13.962, 6.415],
                 [12.813, 6.415], [12.813, 12.747], [18.184, 12.747], [18.184, 6.415],
                 [15.313, 6.415], [15.313, 6.215], [22.0, 6.215], [22.0, 4.799]],
    'obstacles': [[[16.278, 8.177], [15.382, 8.504], [15.336, 8.44], [15.392, 7.837],
                   [16.277, 8.136]]]}


def _room_reached(r):
    """The highest y the robot reached (the room spans y 6.42 to 12.75)."""
    return float(np.asarray(r['path'])[:, 1].max())


@pytest.mark.slow                         # two closed-loop runs, about 4 s
def test_a_door_seen_past_both_sides_of_an_obstacle_is_entered_along_its_bisector(
        monkeypatch):
    """With the merged peaks' edge along the middle of their joint span, the branch through
    the door enters the room and the world is covered. With the edge along the first peak's
    middle (the old rule), the branch heads for the right jamb, ends on the traced corridor
    edge, and the room is never entered: more than half of the world stays uncovered."""
    r = run_kinematic(world_from_dict(CORRIDOR_DOOR_ROOM), PaperConfig(), max_time=3000)
    assert r['state'] == 'done' and r['covered_fraction'] >= 0.99
    assert _room_reached(r) > 10.0

    monkeypatch.setattr(PaperPlanner, '_join_opening', staticmethod(lambda q, lo, hi: None))
    off = run_kinematic(world_from_dict(CORRIDOR_DOOR_ROOM), PaperConfig(), max_time=3000)
    assert off['state'] == 'done' and off['covered_fraction'] < 0.6
    assert _room_reached(off) < 6.5
