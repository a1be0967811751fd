"""A vast cell that is a sliver, read like a meet point (switch ``sliver_openings``, ours).

The room is 4.37 m square, 2 delta + 0.37 m wide (delta = 2 m), the shape of gen_maze_804's:
the robot starts by its exit at the bottom (a corridor 1.54 m wide, a dead end below) and a
corridor 1.21 m wide leaves its right wall eastwards to a dead end at x 11.75. The vast cell
(D > delta) is a small patch in the room's middle whose boundary circuit encloses no area.
Its Fig. 10 test (the closest obstacle's bearing jumps) gives the corridor and the room's
upper right corner one node: their cusps lie within 0.5 m of one another, the jump between
the jambs is about the test's 45 degrees, and the cusp sensed there leads between the upper
jamb and the top wall (that sweep's two closest obstacles), into the corner; the other reads
as the same edge. Every GVD edge leaving a vast cell meets it at a cusp (Section IV-B); the
scan from the sliver's middle reads the corridor's edge as an opening of the range over
bearing beyond delta, and its cusp creates the narrow node that traces the corridor.
"""
import math

import numpy as np
import pytest

from coverage_pkg.algorithm1 import PaperConfig, PaperPlanner
from coverage_pkg.kinematic import run_kinematic
from coverage_pkg.sonar import SonarRing
from coverage_pkg.world import world_from_dict

ROOM = {'name': 'room_two_exits', 'start': [2.36, 3.88], 'obstacles': [],
        'boundary': [[1.42, 0.0], [2.96, 0.0], [2.96, 3.06], [4.37, 3.06], [4.37, 4.64],
                     [11.75, 4.64], [11.75, 5.85], [4.37, 5.85], [4.37, 7.43], [0.0, 7.43],
                     [0.0, 3.06], [1.42, 3.06]]}


@pytest.fixture(scope='module')
def runs():
    """The room covered with the switch on (the default) and off, ``cusp_meet`` off in both:
    the corridor's cusp, where its jambs and the top wall are about equidistant, read as a
    meet point is a second read of the corridor's edge (test_coverage_cusp_meet.py)."""
    return {on: run_kinematic(world_from_dict(ROOM), PaperConfig(sliver_openings=on,
                                                                 cusp_meet=False),
                              max_time=3000) for on in (True, False)}


def _corridor_swept(r):
    """The farthest x the robot reached in the corridor (y 4.64-5.85)."""
    p = np.asarray(r['path'])
    inside = (p[:, 1] > 4.64) & (p[:, 1] < 5.85) & (p[:, 0] > 4.37)
    return float(p[inside, 0].max()) if inside.any() else 0.0


@pytest.mark.slow                         # two closed-loop runs, about 5 s
def test_the_corridor_leaving_a_sliver_is_covered_only_with_its_opening_read(runs):
    """On: a cusp east of the sliver (the opening whose bearing into its narrow cell
    points east) creates a narrow node that traces the corridor to its dead end (within
    delta of x 11.75), and the room and corridor are covered. Off: no node
    is created for the corridor's edge, the robot never enters it, and the corridor beyond
    the room's reach stays uncovered."""
    on, off = runs[True], runs[False]
    assert on['state'] == off['state'] == 'done'
    assert on['covered_fraction'] >= 0.99
    assert _corridor_swept(on) > 11.75 - 2.0
    pl = on['planner']
    opened = {i for i, e in enumerate(pl.events) if e[1] == 'cusp' and 'opening' in e[4]}
    made = [n for n in pl.nodes if n.created_by in opened and
            abs(math.atan2(n.branches[0].heading[1], n.branches[0].heading[0])) <
            math.radians(30)]
    assert len(made) == 1 and made[0].kind == 'narrow'   # the corridor's edge, eastwards
    assert made[0].branches[0].end == 'dead_end' and made[0].branches[0].end_xy[0] > 9.0
    assert off['covered_fraction'] < 0.9
    assert _corridor_swept(off) < 4.37 + 0.5
    assert not any('opening' in e[4] for e in off['planner'].events)


def test_cell_openings_keep_a_door_beside_two_corners():
    """From the middle of a 4.4 m room with a 1.2 m door in its right wall, the range over
    bearing has a peak per corner (3.1 m, at 45 degrees to the door) and one through the door
    (5 m); walls 2.2 m away lie beyond delta on every bearing, so the meet point's rule that
    peaks within 45 degrees look through one opening would merge the door with a corner.
    Each peak is an edge: five bearings, the door's along +x."""
    ring = SonarRing()
    p = PaperPlanner(PaperConfig(), ring.mount_angles(), ring.beam_width, ring.min_range,
                     ring.max_range)
    ang = np.radians(np.arange(0.0, 360.0, 2.0))
    ray = np.column_stack([np.cos(ang), np.sin(ang)])
    with np.errstate(divide='ignore'):      # the room's walls at 2.2 m from its middle
        wall = np.min(np.where(np.abs(ray) > 1e-9, 2.2 / np.abs(ray), np.inf), axis=1)
    door = (ray[:, 0] > 0) & (np.abs(wall * ray[:, 1]) < 0.6)
    rng = np.where(door, 5.0, wall)
    out = sorted(round(math.degrees(m)) for m in p._cell_openings(ang, rng))
    assert len(out) == 5
    assert min(abs(b) for b in out) <= 2
    for corner in (45, 135, -135, -45):
        assert any(abs(b - corner) <= 3 for b in out)
    assert p._openings(ang, rng, [], p.det) != p._cell_openings(ang, rng)
