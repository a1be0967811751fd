"""A meet point whose three closest obstacles lie within a half-plane (EventSensing,
``PaperConfig.meet_surround`` off).

The world is gen_rooms_1101's shape: three rooms of a row of rooms, the robot starting in
the top-right one (a vast cell). A door 1.23 m high joins it to the top-left room; a door
1.47 m wide in its bottom wall, 0.53 m from the corner below the first door, joins it to the
bottom room. Where the robot traces the GVD edge west through the first door, the first
door's two jambs and the second door's far jamb are equidistant from a point north-east of
the corner: the triangle of their closest points is obtuse, so the point lies outside it
and all three bearings lie within a half-plane. The GVD edge between the lower jamb and the
far jamb leaves that meet point south-east, through the second door into the bottom room.
"""
import numpy as np
import pytest

from coverage_pkg.algorithm1 import PaperConfig
from coverage_pkg.kinematic import run_kinematic
from coverage_pkg.world import world_from_dict

ROOMS = {'name': 'doors_share_a_corner', 'start': [13.3, 8.1],
         'boundary': [[0.0, 6.084], [0.0, 12.339], [7.445, 12.339], [7.445, 8.123],
                      [7.645, 8.123], [7.645, 12.339], [15.332, 12.339], [15.332, 6.084],
                      [9.647, 6.084], [9.647, 5.884], [15.332, 5.884], [15.332, 0.0],
                      [7.645, 0.0], [7.645, 5.884], [8.179, 5.884], [8.179, 6.084],
                      [7.645, 6.084], [7.645, 6.889], [7.445, 6.889], [7.445, 6.084]],
         'obstacles': []}


def _lowest(r):
    """The least y the robot reached (the bottom room is y < 5.9)."""
    return float(np.asarray(r['path'])[:, 1].min())


@pytest.mark.slow                         # two closed-loop runs, about 3 s
def test_a_meet_point_outside_its_obstacles_triangle_adds_the_door_beside_it():
    """Sensed wherever the three closest obstacles solve to one distance, the meet point by
    the corner makes the second door's edge a branch: the robot enters the bottom room and
    the world is covered. Sensed only where the three bearings surround the point (the
    widest gap between them under 190 degrees), it is missed: the robot passes the corner
    into the top-left room and the bottom room, a third of the world, stays unentered."""
    r = run_kinematic(world_from_dict(ROOMS), PaperConfig(meet_surround=False), max_time=3000)
    assert r['state'] == 'done' and r['covered_fraction'] >= 0.99
    assert _lowest(r) < 3.0

    off = run_kinematic(world_from_dict(ROOMS), PaperConfig(meet_surround=True), max_time=3000)
    assert off['state'] == 'done' and off['covered_fraction'] < 0.8
    assert _lowest(off) > 5.9
