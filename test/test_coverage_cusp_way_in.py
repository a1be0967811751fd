"""A cusp sensed while tracing leads into the edge the robot came along (TraceGVD._way_in).

The world is gen_maze_1229's shape: a room 4.13 m wide and 4.13 m high (about 2 delta,
delta = 2 m) with a corridor 1.41 m wide rising from its top, left of the middle. The robot
starts in the room's lower right and traces the GVD edge of the bottom-right corner towards
the room's middle, where the edges of all four corners and the corridor's meet and D comes a
few centimetres above delta. There D crosses delta (a cusp, a vast node that is a sliver),
and in the same step the GVD law's two closest obstacles switch to the bottom and left walls:
the robot's heading turns onto the bottom-left corner's edge. The cusp's bearing into its
narrow cell, taken as that heading reversed, points into the bottom-left corner, an edge no
one traced; the vast node's circuit senses that corner's own cusp later, finds it known (same
place, same bearing) and the corner stays unentered. Read from the path 1.5 m behind, the
bearing points back along the bottom-right corner's edge, and the bottom-left corner's cusp
creates its narrow node.
"""
import math

import numpy as np
import pytest
from paper_rules import LATER_RULES_OFF

from coverage_pkg.algorithm1 import PaperConfig, PaperPlanner
from coverage_pkg.kinematic import run_kinematic
from coverage_pkg.world import world_from_dict

ROOM = {'name': 'room_2delta_corridor', 'start': [5.297, 1.218], 'obstacles': [],
        'boundary': [[6.974, 0.0], [2.846, 0.0], [2.846, 4.128], [4.204, 4.128],
                     [4.204, 6.5], [5.616, 6.5], [5.616, 4.128], [6.974, 4.128]]}
CORNER = (2.846, 0.0)                    # the bottom-left corner


def _corner_approach(r):
    """The robot's least distance to the bottom-left corner."""
    p = np.asarray(r['path'])
    return float(np.hypot(p[:, 0] - CORNER[0], p[:, 1] - CORNER[1]).min())


def _off(a, b):
    return abs(math.remainder(a - b, 2 * math.pi))


@pytest.mark.slow                         # two closed-loop runs, about 2 s
def test_the_cusp_in_a_rooms_middle_leads_back_along_the_edge_traced(monkeypatch):
    """With the bearing read from the path, the first cusp (sensed while tracing, it creates
    the vast node) leads back towards the bottom-right corner the robot came from, the
    bottom-left corner's cusp is a new narrow node, and the room is covered. With the heading
    reversed, the first cusp's bearing points at the bottom-left corner, whose cusp is then
    taken for the known one: the robot never comes within 2.5 m of that corner and part of
    the room stays unseen."""
    r = run_kinematic(world_from_dict(ROOM), PaperConfig(**LATER_RULES_OFF), max_time=3000)
    assert r['state'] == 'done' and r['covered_fraction'] >= 0.99
    pl = r['planner']
    vast = next(n for n in pl.nodes if n.kind == 'vast')
    first = pl.events[vast.created_by]
    into = pl._cusp_dirs[(round(first[2], 3), round(first[3], 3))]
    start = ROOM['start']
    assert _off(into, math.atan2(start[1] - first[3], start[0] - first[2])) < math.radians(30)
    assert any(_off(d, math.radians(-135)) < math.radians(20) for d in pl._cusp_dirs.values())
    assert _corner_approach(r) < 2.0

    monkeypatch.setattr(PaperPlanner, '_way_in',
                        lambda self, h, xy: math.atan2(-h[1], -h[0]))
    off = run_kinematic(world_from_dict(ROOM), PaperConfig(**LATER_RULES_OFF), max_time=3000)
    assert off['state'] == 'done' and off['covered_fraction'] < 0.99
    assert _corner_approach(off) > 2.5
