"""Going on past a meet point, the robot follows the edge between an obstacle on either side of
its heading (TraceGVD._side_pair, ``PaperConfig.meet_side_pair``).

The world is gen_rooms_5024's top-right room: 7.46 m x 5.84 m, a small pillar right of its
middle near the top and a larger one left of its middle lower down. The robot starts right of
the small pillar, traces the top wall's edge west and senses the meet point of the left wall,
the top wall and the small pillar. It goes on along the opening down the left wall, between
the left wall and the lower pillar. Off the meet point the two closest obstacles are both
pillars, on the left of that bearing: their GVD edge leads down and right, between the
pillars, to the edge the robot has traced already. Following the left wall and the lower
pillar, one on either side, the robot traces the room's left part under the lower pillar;
following the two closest, it never enters it.
"""
import numpy as np
import pytest

from coverage_pkg.algorithm1 import PaperConfig, PaperPlanner
from coverage_pkg.kinematic import run_kinematic
from coverage_pkg.world import world_from_dict

ROOM = {'name': 'room_two_pillars', 'start': [18.081, 8.864],
        'boundary': [[12.371, 5.452], [12.371, 11.287], [19.835, 11.287], [19.835, 5.452]],
        'obstacles': [[[16.274, 9.079], [16.115, 9.251], [15.867, 9.256], [15.799, 8.725],
                       [16.124, 8.695]],
                      [[14.624, 7.659], [14.507, 7.619], [14.257, 7.267], [14.301, 7.0],
                       [15.099, 6.944]]]}


def _lowest_left(r):
    """The least y the robot reached left of x 14 (the room's part left of the lower
    pillar)."""
    p = np.asarray(r['path'])
    return float(p[p[:, 0] < 14.0, 1].min())


def test_the_pair_is_the_closest_obstacle_on_either_side():
    """Two closest obstacles on one side of the heading give the closest on the other side
    instead; two on either side, or one ahead, give None (the GVD law)."""
    head = (np.cos(np.radians(-112)), np.sin(np.radians(-112)))     # as in the room below
    cone = PaperConfig().cone
    mins = [(1.5, np.radians(-80)), (1.65, np.radians(-1)), (1.8, np.radians(179))]
    assert PaperPlanner._side_pair(mins, head, cone) == [mins[0], mins[2]]
    assert PaperPlanner._side_pair([mins[0], mins[2], mins[1]], head, cone) is None
    ahead = [(1.4, np.radians(-105)), (1.6, np.radians(0)), (1.7, np.radians(180))]
    assert PaperPlanner._side_pair(ahead, head, cone) is None
    assert PaperPlanner._side_pair(ahead, head, 0.0) == [ahead[0], ahead[2]]
    assert PaperPlanner._side_pair(mins[:2], head, cone) is None    # no obstacle on the right


@pytest.mark.slow                         # two closed-loop runs, about 3 s
def test_past_a_meet_point_the_robot_follows_its_branchs_edge():
    """With the side pair, the robot traces the edge down the left wall and covers the room.
    With the GVD law of the two closest, it follows the edge between the pillars, never goes
    left of the lower pillar and leaves a tenth of the room uncovered. Both runs have
    ``way_come_held`` off, which reaches that part another way."""
    r = run_kinematic(world_from_dict(ROOM), PaperConfig(meet_side_pair=True, way_come_held=False),
                      max_time=3000)
    assert r['state'] == 'done' and r['covered_fraction'] >= 0.99
    assert _lowest_left(r) < 7.0

    off = run_kinematic(world_from_dict(ROOM),
                        PaperConfig(meet_side_pair=False, way_come_held=False), max_time=3000)
    assert off['state'] == 'done' and off['covered_fraction'] < 0.92
    assert _lowest_left(off) > 9.0
