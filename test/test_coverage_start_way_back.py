"""The way come at a meet point near the start is read from where the start's branch began
(TraceGVD._to_path_behind, ``origin``).

The world is gen_rooms_6069's two top rooms: a room 5.95 m x 5.39 m with a pillar, whose left
wall has a door 1.21 m wide onto a room 7.92 m x 5.39 m with a triangular obstacle. The robot
starts 1 m inside the door, closer to the door's upper jamb than to anything else; it moves
away from that jamb onto the GVD, creates its narrow node there, and senses a meet point
0.2 m down the edge. The path's samples lie 0.3 m apart: the last one before the node lies on
the move from the start, towards the door. Read from that sample, the way come points at the
door, whose opening lies within 60 degrees of it and is taken for the edge come along: no
branch leaves through the door and the left room stays unentered. Read from the place the
branch began, the way come is the edge's own and the door is a branch.
"""
import numpy as np
import pytest

from coverage_pkg.algorithm1 import PaperConfig, PaperPlanner
from coverage_pkg.kinematic import run_kinematic
from coverage_pkg.world import world_from_dict

ROOMS = {'name': 'rooms_start_by_door', 'start': [15.198, 10.46],
         'boundary': [[6.121, 7.134], [6.121, 12.527], [14.038, 12.527], [14.038, 10.461],
                      [14.238, 10.461], [14.238, 12.527], [20.19, 12.527], [20.19, 7.134],
                      [14.238, 7.134], [14.238, 9.25], [14.038, 9.25], [14.038, 7.134]],
         'obstacles': [[[11.343, 10.583], [11.1, 10.717], [10.369, 9.933], [11.491, 9.9]],
                       [[18.286, 9.617], [17.595, 9.807], [17.64, 8.678], [17.663, 8.671],
                        [18.054, 8.702], [18.127, 8.74]]]}


def _leftmost(r):
    """The least x the robot reached (the left room is x 6.12-14.04)."""
    return float(np.asarray(r['path'])[:, 0].min())


@pytest.mark.slow                         # two closed-loop runs, about 3 s
def test_the_door_beside_the_start_is_a_branch(monkeypatch):
    """With the way come read from where the start's branch began, the robot passes the door
    and covers both rooms. Read from the path's last sample before it, on the move onto the
    GVD, the door is the way come, the robot never passes it and the left room, more than
    half of the world, stays unseen."""
    cfg = PaperConfig()
    r = run_kinematic(world_from_dict(ROOMS), cfg, max_time=3000)
    assert r['state'] == 'done' and r['covered_fraction'] >= 0.99
    assert _leftmost(r) < 12.0

    way_back = PaperPlanner._way_back

    def from_sample(self, heading, back=1.5, since=None, origin=None):   # the rule before
        return way_back(self, heading, back, since)

    monkeypatch.setattr(PaperPlanner, '_way_back', from_sample)
    off = run_kinematic(world_from_dict(ROOMS), cfg, max_time=3000)
    assert off['state'] == 'done' and off['covered_fraction'] < 0.6
    assert _leftmost(off) > 14.0
