"""A boundary circuit is back at its start by the 0.4 m rule only facing an obstacle it faced
there (MorseDecompCoverage._same_side, ``PaperConfig.circuit_same_side``).

The world is gen_halls_5016's shape without its island: a hall 13.08 m by 4.41 m with a tower
3.05 m wide rising from its middle. The points more than delta (2 m) from every wall form a
vast cell that is a strip 0.41 m across along the hall's middle, widening into the tower.
The robot starts below the strip, reaches its bottom side (facing the floor) and follows the
curve D = delta east, round the tower's foot and the hall's east end, then west along the
strip's top side (facing the ceiling), which passes 0.4 m above the start.
"""
import numpy as np
import pytest

from coverage_pkg.algorithm1 import PaperConfig
from coverage_pkg.kinematic import run_kinematic
from coverage_pkg.world import world_from_dict

HALL = {'name': 'hall_thin_vast_strip', 'start': [6.27, 1.42],
        'boundary': [[13.08, 4.41], [13.08, 0.0], [0.0, 0.0], [0.0, 4.41], [6.54, 4.41],
                     [6.54, 8.22], [9.59, 8.22], [9.59, 4.41]],
        'obstacles': []}


def _cusps(r):
    """The cusp points sensed, as an array of (x, y)."""
    return np.array([e[2:4] for e in r['planner'].events if e[1] == 'cusp'])


@pytest.mark.slow                         # two closed-loop runs, about 3 s
def test_the_far_side_of_a_thin_strip_is_no_return_to_the_start():
    """Facing the ceiling, the strip's top side is no return to the start, which faced the
    floor: the circuit follows the strip's west end and senses both its cusps, the one of
    the hall's bottom-left corner at about (2, 2) too, and the hall is covered. With a pass
    within 0.4 m on either side taken for the return, the circuit ends above the start: the
    bottom-left cusp is never sensed, its corner cell never traced, and the corner stays
    unseen."""
    r = run_kinematic(world_from_dict(HALL), PaperConfig(circuit_same_side=True),
                      max_time=3000)
    assert r['state'] == 'done' and r['covered_fraction'] >= 0.99
    cusps = _cusps(r)
    assert np.min(np.hypot(cusps[:, 0] - 2.0, cusps[:, 1] - 2.0)) < 0.2

    off = run_kinematic(world_from_dict(HALL), PaperConfig(circuit_same_side=False),
                        max_time=3000)
    assert off['state'] == 'done' and off['covered_fraction'] < 0.98
    cusps = _cusps(off)
    assert np.min(np.hypot(cusps[:, 0] - 2.0, cusps[:, 1] - 2.0)) > 0.3


class _Ring:
    """Stand-in for the planner: the closest echoes of this sweep, (range, bearing)."""

    def __init__(self, *mins):
        self.mins = [(d, np.radians(a)) for d, a in mins]


def test_a_start_at_a_corner_of_the_curve_faces_both_walls():
    """At a start where two obstacles are equidistant (a corner of the curve D = delta), a
    return facing either of them is on the start's side; the strip's far side, facing the
    opposite wall, is not, nor is a point facing the wall across a strip's end from a start
    facing its side."""
    from coverage_pkg.paper.morse_coverage import MorseDecompCoverage
    same_side = MorseDecompCoverage._same_side
    corner = {'facing': [np.radians(52.0), np.radians(-83.0)]}
    assert same_side(_Ring((1.98, -102.0), (2.06, 168.0)), corner)
    assert same_side(_Ring((1.98, 47.0)), corner)
    strip = {'facing': [np.radians(280.0)]}
    assert not same_side(_Ring((2.04, 98.0), (2.38, -82.0)), strip)
    assert same_side(_Ring((2.02, 275.0)), strip)
    end = {'facing': [np.radians(96.0), np.radians(186.0)]}
    assert not same_side(_Ring((2.01, 8.0), (2.35, 98.0)), end)
