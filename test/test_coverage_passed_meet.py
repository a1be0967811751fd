"""A meet point just beyond delta, passed on an edge that ends in a dead end, adds branches.

The world is gen_halls_1199's shape: an L of a room 3.61 m wide rising to y 8.21 m and a hall
3.31 m high running from its foot to x 15.0 m (both narrower than 2 delta, delta = 2 m). The
robot starts in the room and traces its GVD down. Where the room's left wall, the floor and
the hall's inner corner (3.61, 3.31) are equidistant, at about (2.03, 2.03), the three
closest obstacles lie about 2.03 m away: just beyond delta, so the three-echo test takes no
meet point there, while D stays within the 0.1 m by which it must exceed delta before the
trace senses a cusp (Fig. 11). The trace goes on into the bottom-left corner and ends. From
there the edge's reversed heading lies in the hall's peak of the range and the room's peak
is within 60 degrees of it: both read as the way back, no gap is a branch, and the hall is
never entered (45.67 % of CVS). With the point kept and, once the edge beyond it ends in a
dead end, recorded as a meet point of the narrow node whose edges a meet scan there reads,
the hall's edge is a branch from it. This is the planner with ``meet_margin`` 0 and
``meet_surround`` on (the rule's own case); the default ``meet_margin`` (0.1 m) takes the point
as a meet point when it is sensed, which covers the hall as well.
"""
import numpy as np
import pytest

from coverage_pkg.algorithm1 import PaperConfig, PaperPlanner
from coverage_pkg.kinematic import run_kinematic
from coverage_pkg.world import world_from_dict

L_ROOM = {'name': 'l_room', 'start': [0.695, 4.999],
          'obstacles': [[[1.976, 5.067], [1.479, 5.009], [1.43, 4.968], [1.347, 4.354],
                         [1.734, 4.111], [2.098, 4.225]]],
          'boundary': [[14.995, 3.308], [14.995, 0.0], [0.0, 0.0], [0.0, 8.212],
                       [3.607, 8.212], [3.607, 3.308]]}


def _passed_meets(r):
    """Meet events added at a dead end for a point passed just beyond delta."""
    return [e for e in r['planner'].events if e[1] == 'meet' and 'just beyond delta' in e[4]]


@pytest.mark.slow                         # two closed-loop runs, about 3 s
def test_a_meet_point_just_beyond_delta_before_a_dead_end_adds_the_halls_branch(monkeypatch):
    """With the passed point made a meet point at the dead end, the robot goes back to it,
    reads the hall's edge from its scan, traces the hall and covers the world. Without it,
    no branch leads into the hall and most of it stays unseen (``meet_margin`` 0: the point
    is not a meet point when sensed; ``meet_surround`` on: no half-plane meet point nearby
    stands in for it)."""
    own = PaperConfig(meet_margin=0.0, meet_surround=True)
    r = run_kinematic(world_from_dict(L_ROOM), own, max_time=3000)
    assert r['state'] == 'done' and r['covered_fraction'] >= 0.99
    assert any(abs(e[2] - 2.03) < 0.5 and abs(e[3] - 2.03) < 0.5 for e in _passed_meets(r))
    assert float(np.asarray(r['path'])[:, 0].max()) > 10.0

    monkeypatch.setattr(PaperPlanner, '_passed_meet_branches', lambda self, n: None)
    off = run_kinematic(world_from_dict(L_ROOM), own, max_time=3000)
    assert off['state'] == 'done' and off['covered_fraction'] < 0.6
    assert not _passed_meets(off)
    assert float(np.asarray(off['path'])[:, 0].max()) < 5.0


@pytest.mark.slow                         # one closed-loop run, about 2 s
def test_a_meet_point_within_the_meet_margin_is_taken_when_sensed(monkeypatch):
    """With the default ``meet_margin`` (0.1 m) the point at about (2.03, 2.03) is a meet
    point when the trace senses it, so the hall's edge is a branch without the dead-end rule
    (patched out here), and the hall is covered."""
    monkeypatch.setattr(PaperPlanner, '_passed_meet_branches', lambda self, n: None)
    r = run_kinematic(world_from_dict(L_ROOM), PaperConfig(), max_time=3000)
    assert r['state'] == 'done' and r['covered_fraction'] >= 0.99
    meets = [e for e in r['planner'].events if e[1] == 'meet']
    assert any(abs(e[2] - 2.03) < 0.5 and abs(e[3] - 2.03) < 0.5 for e in meets)
    assert float(np.asarray(r['path'])[:, 0].max()) > 10.0
