"""Two peaks of a meet scan, one holding the other's top, leave along their joint span's middle
(TraceGVD._openings, ``PaperConfig.meet_surround`` off).

The world is gen_halls_2008's shape: a hall 9.09 m by 3.87 m with a tower rising from its
left middle and two islands below the tower. Tracing the GVD edge down the tower's right
side, the robot senses the meet point of the tower's right corner and the two islands
(three bearings within a half-plane). Of its scan, the hall's right part is one wide peak
of the range (about 240 to 20 degrees) and, where one sweep dips, a narrow one at its lower
edge (about 240 degrees, towards the lower island).
"""
import numpy as np
import pytest

from coverage_pkg.algorithm1 import PaperConfig, PaperPlanner
from coverage_pkg.kinematic import run_kinematic
from coverage_pkg.world import world_from_dict

HALL = {'name': 'hall_two_islands', 'start': [3.88, 5.52],
        'boundary': [[9.086, 3.872], [9.086, 0.0], [0.0, 0.0], [0.0, 3.872], [2.676, 3.872],
                     [2.676, 7.019], [6.87, 7.019], [6.87, 3.872]],
        'obstacles': [[[5.213, 1.688], [4.6, 1.732], [4.58, 1.681], [4.947, 1.259],
                       [5.052, 1.294]],
                      [[5.069, 3.365], [4.737, 3.747], [4.289, 3.52], [4.253, 3.291],
                       [4.37, 3.052], [4.66, 2.933]]]}


def _rightmost(r):
    """The greatest x the robot reached (the hall's right part is x > 7)."""
    return float(np.asarray(r['path'])[:, 0].max())


@pytest.mark.slow                         # two closed-loop runs, about 2 s
def test_the_wide_peak_holding_a_narrow_ones_top_is_the_opening(monkeypatch):
    """With the two peaks one opening along their joint span's middle, the robot leaves
    the meet point south-east into the hall's right part and the world is covered. With
    the first peak kept (the narrow one, towards the lower island), that bearing's edge is
    traced already: the branch ends at once and the hall's right part stays unentered. Both
    runs have ``meet_side_pair`` and ``way_come_held`` off: each of them alone leads the robot
    into the hall's right part with the first peak kept."""
    cfg = PaperConfig(meet_surround=False, meet_side_pair=False, way_come_held=False)
    r = run_kinematic(world_from_dict(HALL), cfg, max_time=3000)
    assert r['state'] == 'done' and r['covered_fraction'] >= 0.99
    assert _rightmost(r) > 7.5

    monkeypatch.setattr(PaperPlanner, 'join_held', False)
    off = run_kinematic(world_from_dict(HALL), cfg, max_time=3000)
    assert off['state'] == 'done' and off['covered_fraction'] < 0.9
    assert _rightmost(off) < 7.0
