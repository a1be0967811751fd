"""A traced edge that curved into a corner past an unsensed meet point: the way back is the
path behind, not the reversed heading (TraceGVD._gap_at_end, _curved_end).

The world is gen_mixed_1119's shape: a corridor 1.50 m high (narrow, delta = 2 m) from x 16 to
x 24.5, and a room 5.31 m x 4.65 m below it entered by a door 1.30 m wide (x 22.27 to 23.57)
in a wall 0.2 m thick, 0.67 m from the room's right wall; a small obstacle in the room lies
about 1.3 m below-left of the door's inner end. The robot traces the corridor eastwards and
turns down through the door. Where the door's edge meets the edges of the right wall and of
the room (about 1.2 m inside the door), four obstacles are nearly equidistant, the three
closest change between sweeps and no two sweeps agree: the meet point is not sensed, and the
trace curves onto the edge into the room's top-right corner, where it ends (all ahead is in
view). There no peak of the range holds the reversed heading (it points down-left, along the
curve's chord), nor the bearing to the path 1.5 m behind (between the door's and the room's
peaks). The room's peak lies within 60 degrees of the reversed heading, more than 60 degrees
from the path behind.
"""
import math

import numpy as np
import pytest
from paper_rules import LATER_RULES_OFF

from coverage_pkg.algorithm1 import PaperConfig, PaperPlanner
from coverage_pkg.kinematic import run_kinematic
from coverage_pkg.world import world_from_dict

CORRIDOR_DOOR_CORNER = {
    'name': 'corridor_door_corner_room', 'start': [17.0, 7.3],
    'boundary': [[16.0, 6.563], [16.0, 8.066], [24.537, 8.066], [24.537, 6.563],
                 [23.567, 6.563], [23.567, 6.363], [24.234, 6.363], [24.234, 1.711],
                 [18.929, 1.711], [18.929, 6.363], [22.271, 6.363], [22.271, 6.563]],
    'obstacles': [[[22.012, 4.31], [21.005, 4.628], [20.874, 4.426], [21.65, 3.662]]]}


def _lowest(r):
    """The least y the robot reached (the room spans y 1.71 to 6.36)."""
    return float(np.asarray(r['path'])[:, 1].min())


def _old_curved_end(self, back, peaks):
    """The rule replaced: curved only where some peak holds the bearing to the path behind."""
    way = self._way_back((-math.cos(back), -math.sin(back)))
    return not any(self._holds(back, lo, hi) for lo, hi, _ in peaks) and \
        any(self._holds(way, lo, hi) for lo, hi, _ in peaks)


@pytest.mark.slow                         # two closed-loop runs, about 3 s
def test_the_room_past_an_unsensed_meet_point_is_a_branch_at_the_corner(monkeypatch):
    """With the way back read from the path behind wherever no peak holds the reversed
    heading, the room's peak is a gap at the corner's dead end: a branch, traced into the
    room, and the world is covered. With the reversed heading kept when no peak holds the
    path behind either, the room's peak is taken for the way come, no branch is added, and
    the run ends 'done' at the corner with the room unentered."""
    cfg = PaperConfig(**LATER_RULES_OFF)
    r = run_kinematic(world_from_dict(CORRIDOR_DOOR_CORNER), cfg, max_time=3000)
    assert r['state'] == 'done' and r['covered_fraction'] >= 0.99
    assert _lowest(r) < 3.5

    monkeypatch.setattr(PaperPlanner, '_curved_end', _old_curved_end)
    off = run_kinematic(world_from_dict(CORRIDOR_DOOR_CORNER), cfg, max_time=3000)
    assert off['state'] == 'done' and off['covered_fraction'] < 0.7
    assert _lowest(off) > 5.0
