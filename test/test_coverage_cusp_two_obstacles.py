"""The closest obstacle jumping to another one is Fig. 10's cusp however few degrees it turns
(EventSensing._two_obstacles).

The world is gen_maze_3014's shape: a square room 4.63 m across (about 2 delta + 0.6 m, so
its vast cell encloses area and is no sliver) entered from a long hall below through a door
1.47 m wide, with a corridor 1.44 m wide leaving its right wall and a stub 1.24 m wide and
2.18 m deep leaving its left wall. The vast node's boundary circuit passes the stub's cusp
about delta from both jambs; there the ring's closest echo moves from one jamb to the other
through one cone spacing (26 degrees), under the 45 degrees by which the bearing alone tells
a new obstacle, while an echo between the two bearings reaches into the stub. Read as one
obstacle, the stub's cusp is never sensed and the stub stays unentered.
"""
import math
from types import SimpleNamespace

import numpy as np
import pytest

from coverage_pkg.algorithm1 import PaperConfig
from coverage_pkg.kinematic import run_kinematic
from coverage_pkg.paper.sense_events import EventSensing
from coverage_pkg.world import world_from_dict

ROOM = {'name': 'room_with_stub', 'start': [4.757, 0.969],
        'boundary': [[0.0, 1.521], [3.899, 1.521], [3.899, 2.321], [2.321, 2.321],
                     [2.321, 4.017], [0.141, 4.017], [0.141, 5.256], [2.321, 5.256],
                     [2.321, 6.952], [6.952, 6.952], [6.952, 5.358], [9.235, 5.358],
                     [9.235, 3.915], [6.952, 3.915], [6.952, 2.321], [5.374, 2.321],
                     [5.374, 1.521], [5.397, 1.521], [5.397, 1.447], [9.2, 1.447],
                     [9.2, 1.365], [12.994, 1.365], [12.994, 0.156], [9.2, 0.156],
                     [9.2, 0.074], [5.397, 0.074], [5.397, 0.0], [0.0, 0.0]],
        'obstacles': []}


def _sweep(yaw, echoes, far=2.4):
    """A ring sweep of 16 cones from ``yaw`` (deg): ``far`` but where ``echoes`` (cone
    index: range) say otherwise; returns (ranges, angles)."""
    angles = np.radians(yaw + 22.5 * np.arange(16))
    ranges = np.full(16, far)
    for k, r in echoes.items():
        ranges[k] = r
    return ranges, angles


def _near(rng, ang, k):
    return (float(rng[k]), float(ang[k]), rng, ang)


def _in_stub(r):
    """How many path samples lie in the stub (x < 2.32, 4.02 < y < 5.26)."""
    p = np.asarray(r['path'])
    return int(((p[:, 0] < 2.32) & (p[:, 1] > 4.02) & (p[:, 1] < 5.26)).sum())


def test_a_deeper_echo_between_the_two_closest_echoes_is_two_obstacles():
    """The stub's mouth as the circuit read it: the closest echo at 165 degrees, then at 191
    (26 degrees on, one cone spacing and the ring's turn), the last sweep's cone at 187
    reaching 2.86 m into the stub: two obstacles. Along one wall the next cone's echo,
    with nothing between farther than both beyond the tolerance, is the same obstacle; so
    is a pair whose deep echo lies outside the bearings between them."""
    me = SimpleNamespace(cfg=PaperConfig())
    last = _sweep(-38.0, {9: 1.94, 10: 2.86, 11: 2.30})    # cones at 164.5, 187, 209.5
    now = _sweep(-33.5, {9: 2.29, 10: 1.94})                # cones at 169, 191.5
    assert EventSensing._two_obstacles(me, _near(*last, 9), _near(*now, 10))
    wall = _sweep(-38.0, {9: 1.98, 10: 2.05})
    wall_now = _sweep(-33.5, {9: 2.00, 10: 1.99})
    assert not EventSensing._two_obstacles(me, _near(*wall, 9), _near(*wall_now, 10))
    aside = _sweep(-38.0, {9: 1.98, 10: 2.05, 12: 3.5})
    assert not EventSensing._two_obstacles(me, _near(*aside, 9), _near(*wall_now, 10))


@pytest.mark.slow                         # two closed-loop runs, about 2 s
def test_the_stub_beside_the_room_is_entered_through_its_cusp(monkeypatch):
    """With the closest echoes compared as two obstacles, the circuit senses the stub's cusp
    and the robot traces the stub: the world is covered. Read by the bearing's jump alone,
    the stub stays unentered."""
    r = run_kinematic(world_from_dict(ROOM), PaperConfig(), max_time=3000)
    assert r['state'] == 'done' and r['covered_fraction'] >= 0.99
    assert _in_stub(r) > 0
    assert any(e[1] == 'cusp' and math.dist(e[2:4], (4.2, 4.63)) < 0.3
               for e in r['planner'].events)

    monkeypatch.setattr(EventSensing, '_two_obstacles', lambda self, last, near: False)
    off = run_kinematic(world_from_dict(ROOM), PaperConfig(), max_time=3000)
    assert off['state'] == 'done' and off['covered_fraction'] < 0.97
    assert _in_stub(off) == 0
