"""At a meet point the way come is the one peak holding the bearing to the path behind
(TraceGVD._meet_branches, ``PaperConfig.way_come_held``).

The world is gen_rooms_5024's top-right room (as in ``test_coverage_meet_side_pair.py``):
7.46 m x 5.84 m, a small pillar right of its middle near the top and a larger one left of its
middle lower down. With ``meet_side_pair`` off, the robot leaves the meet point by the top
left corner along the edge between the two pillars and reaches the meet point right of the
lower pillar. There the opening back under the lower pillar lies within 60 degrees of the
bearing to the path behind, though another peak of the range holds that bearing: read as
the way come, it is no branch, and the room's part left of the lower pillar stays unentered.
Read as a branch, the robot traces it and covers the room.
"""
import pytest
from test_coverage_meet_side_pair import ROOM, _lowest_left

from coverage_pkg.algorithm1 import PaperConfig
from coverage_pkg.kinematic import run_kinematic
from coverage_pkg.world import world_from_dict


@pytest.mark.slow                         # two closed-loop runs, about 3 s
def test_an_opening_beside_the_held_way_come_is_a_branch():
    """With the way come the one peak holding the bearing to the path behind, the opening
    under the lower pillar is a branch: the robot enters the room's left part and covers the
    room. With every peak within 60 degrees of that bearing the way come, it never goes left
    of the lower pillar and leaves a tenth of the room uncovered. Both runs have
    ``meet_side_pair`` off, which reaches that part another way."""
    r = run_kinematic(world_from_dict(ROOM), PaperConfig(way_come_held=True, meet_side_pair=False),
                      max_time=3000)
    assert r['state'] == 'done' and r['covered_fraction'] >= 0.99
    assert _lowest_left(r) < 7.0

    off = run_kinematic(world_from_dict(ROOM),
                        PaperConfig(way_come_held=False, meet_side_pair=False), max_time=3000)
    assert off['state'] == 'done' and off['covered_fraction'] < 0.92
    assert _lowest_left(off) > 9.0
