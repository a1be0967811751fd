"""A boundary circuit is back at its start only going the way it left it (MorseDecompCoverage,
``PaperConfig.circuit_same_way``).

The world is gen_rooms_1210's shape: a room 6.68 m by 4.83 m, the robot starting below its
middle. The points more than delta (2 m) from every wall form a vast cell 2.68 m by 0.83 m;
the robot reaches its bottom side and follows the curve D = delta round it (east, north,
west), sensing a cusp at each corner (Fig. 10), where the corner's narrow cell meets it. The
cell's top side passes 0.8 m above the start, going west.
"""
import numpy as np
import pytest

from coverage_pkg.algorithm1 import PaperConfig
from coverage_pkg.kinematic import run_kinematic
from coverage_pkg.world import world_from_dict

ROOM = {'name': 'thin_vast_room', 'start': [3.38, 1.43],
        'boundary': [[0.0, 0.0], [6.68, 0.0], [6.68, 4.83], [0.0, 4.83]], 'obstacles': []}


def _cusps(r):
    """The cusp points sensed, as an array of (x, y)."""
    return np.array([e[2:4] for e in r['planner'].events if e[1] == 'cusp'])


@pytest.mark.slow                         # two closed-loop runs, about 2 s
def test_the_far_side_of_a_thin_cell_is_no_return_to_the_start():
    """Going the way it left its start, the circuit passes the start only after the cell's
    west end: all four corners' cusps are sensed (the bottom-left one at about (2, 2)), each
    corner's narrow cell is traced and the room is covered. With any pass within 0.8 m of
    the start taken for the return, the circuit ends on the top side going west: the
    bottom-left cusp is never sensed, its corner cell never traced, and the room's
    bottom-left corner stays unseen."""
    r = run_kinematic(world_from_dict(ROOM), PaperConfig(circuit_same_way=True), max_time=3000)
    assert r['state'] == 'done' and r['covered_fraction'] >= 0.99
    cusps = _cusps(r)
    assert len(cusps) == 4
    assert np.min(np.hypot(cusps[:, 0] - 2.0, cusps[:, 1] - 2.0)) < 0.3

    off = run_kinematic(world_from_dict(ROOM), PaperConfig(circuit_same_way=False),
                        max_time=3000)
    assert off['state'] == 'done' and off['covered_fraction'] < 0.97
    cusps = _cusps(off)
    assert len(cusps) == 3
    assert np.min(np.hypot(cusps[:, 0] - 2.0, cusps[:, 1] - 2.0)) > 0.6
