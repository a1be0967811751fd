"""The tip of a sliver-shaped vast cell in a hall about 2 delta high (the paper planner).

The hall is gen_halls_902's shape: 12.55 m long and 4.32 m high (2 delta + 0.32 m, delta =
2 m), an alcove above its left half and an island near its left end. The robot starts right
of the island, in the vast cell (D > delta), a sliver 0.32 m high along the hall's middle.
Its circuit senses the sliver's left tip about 0.5 m short of where D = delta on the GVD: the
narrow node created there traces its GVD edge leftwards and, within its first half metre, D
rises above delta again, so the trace ends at a cusp and a second vast node is created (the
rest of the same sliver). That node's circuit senses the cusp where the island closes in,
a step from the first one but on another GVD edge (between the bottom wall and the island).
Whether that cusp is the known one is decided by the bearing the first trace ended along
(``Branch.end_heading``): the trace ended while the robot still drove along its branch's
bearing, before the GVD law gave it a heading of its own.
"""
import math

import numpy as np
import pytest

from coverage_pkg.algorithm1 import Branch, PaperConfig
from coverage_pkg.kinematic import run_kinematic
from coverage_pkg.paper.node_creation import CreateNode
from coverage_pkg.world import world_from_dict

HALL = {'name': 'hall_island', 'start': [8.46, 1.88],
        'boundary': [[12.55, 4.32], [12.55, 0.0], [0.0, 0.0], [0.0, 4.32], [2.95, 4.32],
                     [2.95, 6.57], [7.04, 6.57], [7.04, 4.32]],
        'obstacles': [[[5.9, 2.94], [5.53, 3.16], [5.3, 3.18], [4.62, 2.42], [4.91, 1.86],
                       [5.61, 1.75]]]}


def test_a_cusp_on_another_gvd_edge_is_not_the_end_of_a_branch_traced_along_its_bearing():
    """A branch that ended at a cusp at (7.72, 2.26) driving along -x: a cusp sensed 0.26 m
    from there, leading into the narrow cell at -138 degrees (between the bottom wall and the
    island), is not where that branch left its narrow cell; one leading back along +x is.
    Without the bearing the branch ended along, both would be (the direction unknown)."""
    b = Branch((8.32, 2.29), (-1.0, 0.0), 6)
    b.end, b.end_xy, b.end_heading = 'cusp', (7.72, 2.26), (-1.0, 0.0)
    tip = (7.69, 2.0)
    assert not CreateNode._arrived(b, tip, 0.5, math.radians(-138.0))
    assert CreateNode._arrived(b, tip, 0.5, 0.0)
    b.end_heading = None
    assert CreateNode._arrived(b, tip, 0.5, math.radians(-138.0))


@pytest.mark.slow                         # one closed-loop run, about 3 s
def test_the_hall_beyond_the_sliver_tip_is_covered():
    """The cusp where the island closes in creates a narrow node: its GVD edges run round
    the island and into the alcove, the robot passes left of the island, and the hall is
    covered (45 % when that cusp was taken for the known one: only the right of the hall,
    the part within delta of the sliver, was seen). Every trace that ends at a cusp records
    the bearing it ended along."""
    r = run_kinematic(world_from_dict(HALL), PaperConfig(), max_time=3000)
    assert r['state'] == 'done' and r['covered_fraction'] >= 0.99
    p = np.asarray(r['path'])
    assert float(p[:, 0].min()) < 4.6            # left of the island's leftmost vertex
    ended = [b for n in r['planner'].nodes for b in n.branches if b.end == 'cusp']
    assert ended and all(b.end_heading is not None for b in ended)
