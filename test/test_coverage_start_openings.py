"""The GVD edges leaving the start besides the one it lies on (TraceGVD._start_openings).

The world is gen_maze_1168. The robot starts in a room about 2 delta wide; a stub 1.54 m wide
goes up from the room's top wall, 1.3 m above and left of the start, and the GVD edge the
start lies on runs up-right into a corner (one way) and down-left into the room's small vast
cell (the other). Seen from the start, the stub is a peak of the range 4.1 m deep, 56 degrees
off the start's edge, with the stub's jamb (1.9 m away, within delta) between them.
"""
import math

import numpy as np
import pytest

from coverage_pkg.algorithm1 import PaperConfig, PaperPlanner
from coverage_pkg.kinematic import run_kinematic
from coverage_pkg.paper.trace_gvd import TraceGVD
from coverage_pkg.sonar import SonarRing
from coverage_pkg.world import world_from_dict

MAZE = {'name': 'gen_maze_1168', 'start': [3.008, 8.169],
        'boundary': [[1.637, 3.006], [1.637, 4.353], [0.0, 4.353], [0.0, 8.844], [1.476, 8.844],
                     [1.476, 11.678], [3.015, 11.678], [3.015, 8.844], [4.491, 8.844],
                     [4.491, 7.393], [5.871, 7.393], [5.871, 10.205], [5.852, 10.205],
                     [5.852, 11.613], [11.569, 11.613], [11.569, 10.205], [7.24, 10.205],
                     [7.24, 7.393], [7.35, 7.393], [7.35, 7.378], [11.645, 7.378],
                     [11.645, 5.82], [11.631, 5.82], [11.631, 1.523], [10.1, 1.523],
                     [10.1, 5.82], [7.35, 5.82], [7.35, 5.804], [4.491, 5.804], [4.491, 4.577],
                     [8.844, 4.577], [8.844, 0.0], [4.267, 0.0], [4.267, 1.571],
                     [1.528, 1.571], [1.528, 3.006]],
        'obstacles': [[[4.267, 4.353], [2.854, 4.353], [2.854, 3.006], [4.267, 3.006]]]}

# One sweep of the ring, world bearing (degrees) -> range (m): at gen_maze_1168's start
# (the stub at 100 degrees, the start's edge at 44) and at gen_maze_1055's (the start's edge
# at -176 degrees, the peak at 150 the shoulder of the same gap, 173-195 beyond delta).
STUB = {10: 1.57, 33: 1.73, 55: 1.45, 78: 1.28, 100: 4.11, 123: 2.42, 145: 1.95, 168: 2.97,
        190: 2.95, 213: 3.31, 235: 3.69, 258: 4.23, 280: 3.22, 303: 2.48, 325: 2.7, 348: 5.0}
SHOULDER = {15: 2.96, 38: 3.6, 60: 4.33, 83: 1.15, 105: 1.12, 128: 1.17, 150: 3.44, 173: 2.35,
            195: 2.38, 218: 1.93, 240: 1.46, 263: 1.33, 285: 1.37, 308: 1.58, 330: 2.3,
            353: 2.91}


def _planner_seeing(sweep, **kw):
    """A paper planner that has taken ``sweep`` at the origin (the ring turned so that its
    cones point along the sweep's bearings)."""
    ring = SonarRing()
    p = PaperPlanner(PaperConfig(**kw), ring.mount_angles(), ring.beam_width, ring.min_range,
                     ring.max_range)
    bearings = sorted(sweep)
    yaw = math.radians(bearings[0]) - float(np.asarray(ring.mount_angles())[0])
    world = np.remainder(np.asarray(ring.mount_angles()) + yaw, 2 * math.pi)
    ranges = [sweep[min(bearings, key=lambda b: abs(math.remainder(math.radians(b) - a,
                                                                      2 * math.pi)))]
              for a in world]
    p.on_odometry(0.0, 0.0, 0.0, yaw)
    p.on_sweep(0.0, np.asarray(ranges))
    return p


def _into_stub(r):
    """The highest y the robot reached over the stub's width (0 if never over it)."""
    xy = np.asarray(r['path'])[:, :2]
    over = (xy[:, 0] > 1.48) & (xy[:, 0] < 3.02)
    return float(xy[over, 1].max()) if over.any() else 0.0


def _near(bearings, deg, within=12.0):
    return any(abs(math.degrees(math.remainder(b - math.radians(deg), 2 * math.pi))) < within
               for b in bearings)


def test_a_stub_beyond_a_jamb_off_the_starts_edge_is_a_branch():
    """The stub's peak, 56 degrees off the start's edge with an echo within delta between
    them, is a GVD edge of its own: a branch of the start. The way come's test of a meet
    point (an opening within 60 degrees of it is the edge come along) drops it."""
    p = _planner_seeing(STUB)
    a = math.radians(44.0)
    assert _near(p._start_openings(a), 100.0)
    assert not _near(p._openings(p.angles, p.ranges, [a], p.det), 100.0)


@pytest.mark.parametrize('between, branch', [(2.35, False), (1.5, True)])
def test_the_shoulder_of_the_starts_own_gap_is_no_branch(between, branch):
    """A peak 34 degrees off the start's edge, seen through one gap with it (the cones
    between beyond delta), is that edge's own opening: no branch. With an echo within delta
    between them (a jamb), the same peak is an edge of its own."""
    p = _planner_seeing({**SHOULDER, 173: between})
    assert _near(p._start_openings(math.radians(-176.0)), 150.0) == branch


@pytest.mark.slow                         # two closed-loop runs, about 4 s
def test_the_stub_above_the_start_is_entered_from_the_start(monkeypatch):
    """With the sliver's openings off (``sliver_openings=false``), the stub is reached only
    as a branch of the start: the robot enters it and covers the world. Read with the way
    come's 60 degrees, the stub is no branch of the start, its cusp on the room's vast cell
    is joined to the start's traced edge (0.2-0.3 m from where it ended, on its line), and
    the stub stays unseen."""
    cfg = PaperConfig(sliver_openings=False)
    r = run_kinematic(world_from_dict(MAZE), cfg, max_time=3000)
    assert r['state'] == 'done' and r['covered_fraction'] >= 0.99
    assert _into_stub(r) > 9.5                   # the stub: x 1.48-3.02, above y 8.84

    def as_way_come(self, a):                                     # the rule before
        return [b for b in self._openings(self.angles, self.ranges, [a], self.det)
                if abs(math.remainder(b - a - math.pi, 2 * math.pi)) > math.radians(30)]

    monkeypatch.setattr(TraceGVD, '_start_openings', as_way_come)
    off = run_kinematic(world_from_dict(MAZE), cfg, max_time=3000)
    assert off['state'] == 'done' and off['covered_fraction'] < 0.98
    assert _into_stub(off) < 8.84
