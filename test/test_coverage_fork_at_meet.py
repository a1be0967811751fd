"""A fork of the GVD within the merge distance of a meet point leaves from it (``fork_at_meet``).

The world is gen_maze_8039's top-left room: a room 4.02 m square (delta = 2 m: its middle
lies about delta from its walls, and the robot covers it by its GVD) entered through a door
1.24 m wide in the middle of its bottom wall, at the top of a corridor. The room's GVD is
nearly the square's diagonals: the edge up the corridor meets the edges into the two bottom
corners at a meet point below the room's middle, and forks into the edges into the two top
corners about 0.3 m above it. That fork lies within the merge distance of events
(``same_event``, 0.5 m) of the meet point, so it is taken for the meet point and never
sensed. From the meet point the two top corners are two peaks of the range over bearing, one's
upper half holding the other's top; read as one edge (a far wall's corners seen through a
door), the robot goes up the middle, the GVD law takes it into one top corner, and the other
stays unseen (gen_maze_8039: 99.38 %; gen_maze_6035, whose top-left room is the same:
99.30 %). With ``fork_at_meet`` (ours, off) the obstacle between the two tops (the top wall)
lies within rho + 2 ``same_event`` of the meet point, so each top is a branch of its own.
"""
import numpy as np
import pytest

from coverage_pkg.algorithm1 import PaperConfig, PaperPlanner
from coverage_pkg.kinematic import run_kinematic
from coverage_pkg.world import world_from_dict

ROOM_ON_CORRIDOR = {
    'name': 'room_on_corridor', 'start': [3.0, 6.6], 'obstacles': [],
    'boundary': [[2.37, 6.0], [3.611, 6.0], [3.611, 9.744], [5.0, 9.744], [5.0, 13.763],
                 [0.981, 13.763], [0.981, 9.744], [2.37, 9.744]]}
TOP_RIGHT, TOP_LEFT = (5.0, 13.763), (0.981, 13.763)


def _nearest(r, corner):
    """How near the robot came to ``corner`` (m)."""
    p = np.asarray(r['path'])[:, :2]
    return float(np.hypot(*(p - np.asarray(corner)).T).min())


@pytest.mark.slow                         # three closed-loop runs, about 3 s
def test_the_rooms_two_top_corners_are_two_branches_of_its_meet_point(monkeypatch):
    """With ``fork_at_meet`` the robot drives into both top corners (within 2 m of each,
    where the detector sees the corner) and covers the room. Without the mode, or with it
    but its test (``TraceGVD._fork_here``) answering no, the two tops are one edge: the
    robot never comes within 2.5 m of the top-right corner, and a triangle of the room by
    that corner stays unseen (about 3 % of CVS)."""
    on = run_kinematic(world_from_dict(ROOM_ON_CORRIDOR), PaperConfig(fork_at_meet=True),
                       max_time=3000)
    off = run_kinematic(world_from_dict(ROOM_ON_CORRIDOR), PaperConfig(), max_time=3000)
    monkeypatch.setattr(PaperPlanner, '_fork_here', lambda self, *args: False)
    no_fork = run_kinematic(world_from_dict(ROOM_ON_CORRIDOR),
                            PaperConfig(fork_at_meet=True), max_time=3000)
    assert on['state'] == off['state'] == no_fork['state'] == 'done'
    assert on['covered_fraction'] >= 0.999
    assert max(_nearest(on, TOP_RIGHT), _nearest(on, TOP_LEFT)) < 2.0
    for r in (off, no_fork):
        assert r['covered_fraction'] < 0.99
        assert _nearest(r, TOP_RIGHT) > 2.5
