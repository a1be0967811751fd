"""A door beside a corner is read at the corner's dead end from a scan (``end_scan``).

The world is gen_rooms_1067's left column: a room 5.0 m by 5.4 m (a vast node with a
narrow node in each corner, delta = 2 m) below a second room, joined by a door 1.54 m wide in
the wall between them, 0.86 m from the lower room's top-left corner. The corner's narrow node
traces the GVD edge into that corner, where it ends at an obstacle ahead. From there the door
subtends about one cone spacing (22.5 degrees) of the 16-cone ring, between the top wall and
the room's diagonal (the way back). One sweep can read the door's far jamb (about delta away)
and the wall beyond it as one slope of the way back's peak: no gap, no branch, and the upper
room stays unseen (gen_rooms_1067: 47.62 %; gen_rooms_1068 and gen_rooms_1114 end such a
corner the same way). Whether it does depends on the ring's yaw when the end is reached;
from this start it does. With ``end_scan`` the robot halts there while the ring turns through
one cone spacing, the door stands out as a peak of its own, and its edge is a branch.

The second world (gen_mixed_1118's shape) pins the way come at a meet point reached on such a
gap's branch (TraceGVD._meet_branches).

The third (gen_halls_1170's shape: a hall 3.5 m high and 11 m long with an arm 3.4 m wide
rising from its west end) pins the way come at a dead end read from the scan: the one peak
holding the reversed heading (TraceGVD._gap_at_end). The hall's GVD edge ends in the
south-west corner, where the arm's opening is a peak of its own beside the way back's,
separated from it by the arm's convex corner 3.1 m away. Excluding the peaks within 60
degrees of the reversed heading, as from one sweep, drops the arm: it stays unentered
(gen_halls_1170 with ``end_scan``: 65.57 %).
"""
import math

import numpy as np
import pytest
from paper_rules import LATER_RULES_OFF

from coverage_pkg import gvd as gvdmod
from coverage_pkg.algorithm1 import PaperConfig, PaperPlanner
from coverage_pkg.kinematic import run_kinematic
from coverage_pkg.world import world_from_dict

DOOR_BY_CORNER = {
    'name': 'door_by_corner', 'start': [2.35, 2.7], 'obstacles': [],
    'boundary': [[0.0, 0.0], [5.015, 0.0], [5.015, 5.416], [2.395, 5.416], [2.395, 5.616],
                 [5.015, 5.616], [5.015, 11.809], [0.0, 11.809], [0.0, 5.616],
                 [0.859, 5.616], [0.859, 5.416], [0.0, 5.416]]}


def _corner_gaps(r):
    """Gaps found where a GVD edge ends, within 1.5 m of the lower room's top-left corner."""
    return [e for e in r['planner'].events if e[1] == 'meet' and
            'where the GVD edge ends' in e[4] and e[2] < 1.5 and e[3] > 4.0]


@pytest.mark.slow                         # two closed-loop runs, about 3 s
def test_the_door_beside_the_corner_is_read_from_the_scan_at_the_dead_end(monkeypatch):
    """With ``end_scan`` the corner's dead end finds the door as a gap, the robot goes
    through it and covers both rooms. Reading the gaps from the one sweep that found the end
    (the scan's first sweep), the corner's end finds no gap and the upper room is never
    entered."""
    cfg = PaperConfig(end_scan=True, **LATER_RULES_OFF)
    r = run_kinematic(world_from_dict(DOOR_BY_CORNER), cfg, max_time=3000)
    assert r['state'] == 'done' and r['covered_fraction'] >= 0.99
    assert _corner_gaps(r)
    assert float(np.asarray(r['path'])[:, 1].max()) > 7.0

    first = PaperPlanner._scan_echoes
    monkeypatch.setattr(PaperPlanner, '_scan_echoes', staticmethod(
        lambda scan: first(dict(scan, sweeps=scan['sweeps'][:1]) if 'end' in scan else scan)))
    off = run_kinematic(world_from_dict(DOOR_BY_CORNER), cfg, max_time=3000)
    assert off['state'] == 'done' and off['covered_fraction'] < 0.6
    assert not _corner_gaps(off)
    assert float(np.asarray(off['path'])[:, 1].max()) < 5.416


# gen_mixed_1118's shape: a room 4.8 m by 4.6 m with a door 1.24 m wide in its bottom wall,
# 1.07 m from its bottom-left corner, onto a corridor 1.54 m high running 9.4 m west and
# 4.7 m east of the room's left wall.
ROOM_OVER_CORRIDOR = {
    'name': 'room_over_corridor', 'start': [12.658, 9.245], 'obstacles': [],
    'boundary': [[0.0, 6.037], [16.417, 6.037], [16.417, 7.581], [11.76, 7.581],
                 [11.76, 7.781], [14.257, 7.781], [14.257, 12.413], [9.447, 12.413],
                 [9.447, 7.781], [10.519, 7.781], [10.519, 7.581], [0.0, 7.581]]}


@pytest.mark.slow                         # two closed-loop runs, about 4 s
def test_a_meet_point_reached_off_a_curved_path_keeps_the_corridors_other_way(monkeypatch):
    """The room's corner dead end finds the door (``end_scan``); the branch of that gap
    leaves the corner diagonally through the door and turns down onto the corridor's meet
    point, so the bearing to the path 1.5 m behind points between the door's peak and the
    corridor's west peak, within 60 degrees of the latter. On such a branch the one peak
    nearest that bearing (the door's) is the way come: the west way is a branch and the
    corridor is covered both ways. Excluding every opening within 60 degrees of that
    bearing, as on other branches, takes the west way for the way come: the robot never
    goes west of the door and the west corridor stays uncovered."""
    cfg = PaperConfig(end_scan=True, **LATER_RULES_OFF)
    r = run_kinematic(world_from_dict(ROOM_OVER_CORRIDOR), cfg, max_time=3000)
    assert r['state'] == 'done' and r['covered_fraction'] >= 0.99
    assert float(np.asarray(r['path'])[:, 0].min()) < 3.0

    first = PaperPlanner._openings

    def within_60_of_the_way_back(self, angles, ranges, exclude, beyond, close=None,
                                  held_first=False, found=None, meet=None):
        if close is None:                 # not a meet point's scan
            return first(self, angles, ranges, exclude, beyond, close, held_first, found,
                         meet)
        head = np.asarray(self.task.get('heading') or self.task['branch'].heading)
        return first(self, angles, ranges, [self._way_back(head)], beyond, close, False,
                     found, meet)

    monkeypatch.setattr(PaperPlanner, '_openings', within_60_of_the_way_back)
    off = run_kinematic(world_from_dict(ROOM_OVER_CORRIDOR), cfg, max_time=3000)
    assert off['state'] == 'done' and off['covered_fraction'] < 0.8
    assert float(np.asarray(off['path'])[:, 0].min()) > 9.0


L_HALL = {
    'name': 'l_hall', 'start': [4.824, 2.091], 'obstacles': [],
    'boundary': [[10.965, 3.516], [10.965, 0.0], [0.0, 0.0], [0.0, 9.837], [3.376, 9.837],
                 [3.376, 3.516]]}


@pytest.mark.slow                         # two closed-loop runs, about 3 s
def test_the_arm_beside_a_corners_way_back_is_a_gap_of_the_dead_end_scan(monkeypatch):
    """With ``end_scan`` the corner's dead end takes only the peak holding the reversed
    heading for the way come: the arm is a gap, a branch, and the arm is covered. Taking
    every peak within 60 degrees of it for the way come where one holds it (the one-sweep
    rule), the arm is dropped and the robot never leaves the hall. The meet point the trace
    passes just beyond delta at the L's corner leads into the arm too, so that rule is
    patched out in both runs."""
    monkeypatch.setattr(PaperPlanner, '_passed_meet_branches', lambda self, n: None)
    cfg = PaperConfig(end_scan=True, **LATER_RULES_OFF)
    r = run_kinematic(world_from_dict(L_HALL), cfg, max_time=3000)
    assert r['state'] == 'done' and r['covered_fraction'] >= 0.99
    assert float(np.asarray(r['path'])[:, 1].max()) > 7.0

    first = PaperPlanner._openings

    def one_sweep_rule(self, angles, ranges, exclude, beyond, close=None, held_first=False,
                       found=None, meet=None):
        if close is None and held_first:  # a dead end's gaps: held first only if curved
            head = self.task['heading']
            peaks = (found or gvdmod.range_peaks(angles, ranges, beyond,
                                                 self.cfg.event_tolerance))[3]
            held_first = self._curved_end(math.atan2(-head[1], -head[0]), peaks)
        return first(self, angles, ranges, exclude, beyond, close, held_first, found, meet)

    monkeypatch.setattr(PaperPlanner, '_openings', one_sweep_rule)
    off = run_kinematic(world_from_dict(L_HALL), cfg, max_time=3000)
    assert off['state'] == 'done' and off['covered_fraction'] < 0.7
    assert float(np.asarray(off['path'])[:, 1].max()) < 3.516
