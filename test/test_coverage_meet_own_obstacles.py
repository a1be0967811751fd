"""Two meet points under ``same_event`` apart are two when their obstacles differ (EventSensing).

The world is gen_halls_5125's hall without its tower: a hall 10.07 m long and 3.815 m high
(2 delta - 0.185 m, delta = 2 m) with a pillar about 4.3 m from its right end. Right of the
pillar the GVD edge between the hall's two walls meets the pillar's edge at a meet point
(bottom wall, top wall, pillar, about (7.72, 1.93)) and, 0.43 m farther right, the edges
into the two right corners at the end's meet point (bottom wall, top wall, end wall, about
(8.15, 1.92)). From the first meet point the right end is one opening; past the second the
GVD law follows one corner's edge into a dead end.
"""
import numpy as np
import pytest

from coverage_pkg.algorithm1 import PaperConfig
from coverage_pkg.kinematic import run_kinematic
from coverage_pkg.world import world_from_dict

HALL = {'name': 'hall_pillar_end', 'start': [3.293, 0.898],
        'boundary': [[10.07, 3.815], [10.07, 0.0], [0.0, 0.0], [0.0, 3.815]],
        'obstacles': [[[5.799, 2.203], [5.694, 2.349], [5.347, 2.424], [5.294, 1.717],
                       [5.558, 1.699], [5.664, 1.75]]]}


def _top_right_reached(r):
    """The greatest y the robot reached right of x 8 (the top-right corner's edge)."""
    p = np.asarray(r['path'])
    return float(p[p[:, 0] > 8.0][:, 1].max())


@pytest.mark.slow                         # two closed-loop runs, about 2 s
def test_the_end_meet_point_beside_the_pillars_is_another_meet_point():
    """With ``meet_own_obstacles`` (on in the default) the end's meet point, whose three
    closest obstacles leave the pillar 0.4 m farther away, is a meet point of its own: both
    corners' edges are branches, the robot traces the top-right one and the hall is
    covered. Off, it is taken for the pillar's meet point 0.43 m back: the robot follows
    the bottom corner's edge only, never rises above y 1.9 right of x 8, and the top-right
    corner stays unseen."""
    r = run_kinematic(world_from_dict(HALL), PaperConfig(), max_time=3000)
    assert r['state'] == 'done' and r['covered_fraction'] >= 0.99
    assert _top_right_reached(r) > 2.3
    meets = [e for e in r['planner'].events if e[1] == 'meet' and e[2] > 7.0 and
             e[4].startswith('three closest')]
    assert len(meets) == 2 and 0.3 < abs(meets[1][2] - meets[0][2]) < 0.5

    off = run_kinematic(world_from_dict(HALL), PaperConfig(meet_own_obstacles=False),
                        max_time=3000)
    assert off['state'] == 'done' and off['covered_fraction'] < 0.99
    assert _top_right_reached(off) < 1.95
