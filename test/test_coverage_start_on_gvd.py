"""The start node's kind read from D on the GVD beside the start (``start_on_gvd``).

The world is a hall 12 m long and 4.13 m high (delta = 2 m): its middle line lies 2.065 m
from both walls, so the GVD along it is in VR (D > delta) and the hall is a vast cell, as
in gen_halls_3063 and gen_halls_204, the two lowest of the 1160 seen generated worlds
(99.18 and 99.53 % of CVS). The robot starts 1.6 m above the bottom wall, within delta of
it alone, and the access (``PaperPlanner._access``) moves it away from that wall until the
two walls' echoes lie within 2 ``event_tolerance`` of each other: about 0.15 m short of the
middle line, where D reads about 1.9 m. Read there, CreateNode makes a narrow node; the
robot traces the middle line, where D stays within the echoes' noise of 2.05 m and never
crosses delta + 0.015 m (a cusp) nor rises over delta + 0.1 m (a cusp ahead), and a strip
along each wall, just beyond the detector's range, stays unseen. With ``start_on_gvd`` (ours,
off) D is the mean of the two walls' echoes, D on the GVD beside the robot: a vast node,
whose boundary circuit at D = delta passes within delta of each wall.
"""
import pytest

from coverage_pkg.algorithm1 import PaperConfig, PaperPlanner
from coverage_pkg.kinematic import run_kinematic
from coverage_pkg.world import world_from_dict

HALL_OVER_2DELTA = {'name': 'hall_over_2delta', 'start': [6.0, 1.6], 'obstacles': [],
                    'boundary': [[0.0, 0.0], [12.0, 0.0], [12.0, 4.13], [0.0, 4.13]]}


@pytest.mark.slow                         # three closed-loop runs, about 4 s
def test_a_start_beside_a_gvd_beyond_delta_is_a_vast_node(monkeypatch):
    """With ``start_on_gvd`` the start node is vast and the hall is covered (over 99.5 % of
    CVS). Without the mode, or with it but ``PaperPlanner._start_D`` reading D where the robot
    stands, the start node is narrow, no vast node is ever created, and the strips along the
    walls stay unseen (under 99 %)."""
    on = run_kinematic(world_from_dict(HALL_OVER_2DELTA), PaperConfig(start_on_gvd=True),
                       max_time=3000)
    off = run_kinematic(world_from_dict(HALL_OVER_2DELTA), PaperConfig(), max_time=3000)
    monkeypatch.setattr(PaperPlanner, '_start_D', lambda self: self.D)
    stands = run_kinematic(world_from_dict(HALL_OVER_2DELTA), PaperConfig(start_on_gvd=True),
                           max_time=3000)
    assert on['state'] == off['state'] == stands['state'] == 'done'
    assert on['planner'].nodes[0].kind == 'vast'
    assert on['covered_fraction'] > 0.995
    for r in (off, stands):
        assert [n.kind for n in r['planner'].nodes] == ['narrow']
        assert r['covered_fraction'] < 0.99
