"""Off a meet point, a branch's bearing is kept only between two obstacles (TraceGVD).

The world is gen_mixed_1181's shape: a room 6 m x 4.6 m with a pillar left of its middle and
a door 1.45 m wide in its floor, right of the pillar, to a corridor below. The robot starts
by the room's top right, on the GVD. The meet point it senses there reads the GVD edges
left (over the pillar) and down (right of the pillar, past the door) as one opening whose
bearing leads onto the pillar's corner. Kept for delta, that bearing takes the robot to
within half a metre of the pillar, off the edge that passes the door, so the meet point by
the door is never sensed and the corridor never entered. Where the closest obstacle is
nearer than ``keep_ratio`` of the second closest, the GVD law takes over and the robot
traces the edge that passes the door.
"""
import numpy as np
import pytest
from paper_rules import LATER_RULES_OFF

from coverage_pkg.algorithm1 import PaperConfig, PaperPlanner
from coverage_pkg.kinematic import run_kinematic
from coverage_pkg.world import world_from_dict

ROOM = {'name': 'room_pillar_door', 'start': [9.53, 11.14],
        'boundary': [[5.0, 5.5], [15.0, 5.5], [15.0, 7.0], [10.64, 7.0], [10.64, 7.2],
                     [11.04, 7.2], [11.04, 11.83], [5.01, 11.83], [5.01, 7.2], [9.19, 7.2],
                     [9.19, 7.0], [5.0, 7.0]],
        'obstacles': [[[7.786, 10.14], [7.276, 10.283], [7.057, 10.212], [6.876, 9.188],
                       [6.918, 9.145], [7.956, 9.329]]]}


def _lowest(r):
    """The least y the robot reached (the corridor is y 5.5-7.0)."""
    return float(np.asarray(r['path'])[:, 1].min())


@pytest.mark.slow                         # two closed-loop runs, about 3 s
def test_a_bearing_onto_an_obstacle_is_left_to_the_gvd_law(monkeypatch):
    """With the bearing kept only between two obstacles, the robot passes the door, traces
    the corridor and covers the world. Kept whatever the closest obstacle (the ratio 0), the
    robot hugs the pillar, never enters the corridor and leaves most of it uncovered."""
    r = run_kinematic(world_from_dict(ROOM), PaperConfig(**LATER_RULES_OFF), max_time=3000)
    assert r['state'] == 'done' and r['covered_fraction'] >= 0.99
    assert _lowest(r) < 6.5

    monkeypatch.setattr(PaperPlanner, 'keep_ratio', 0.0)
    off = run_kinematic(world_from_dict(ROOM), PaperConfig(**LATER_RULES_OFF), max_time=3000)
    assert off['state'] == 'done' and off['covered_fraction'] < 0.9
    assert _lowest(off) > 7.0
