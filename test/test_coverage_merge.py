"""After a narrow node turns out to be an earlier one (``same_cell``), FindUncoveredNode chooses.

The world is gen_mixed_1169: a room at the top (the start, beside an island), a corridor below
it along the whole width, and a room at the bottom left, each room joined to the corridor by a
door. The start's narrow node 0 holds the corridor. The bottom room is a vast node with a
narrow node at three of its corners (2, 3, 4); node 4's GVD trace runs out of the room's
corner onto the corridor's traced edge, so node 4 is node 0 (event ``same_cell``) while node
0 still has open branches in the top room.
"""
import pytest

from coverage_pkg.algorithm1 import PaperConfig
from coverage_pkg.kinematic import run_kinematic
from coverage_pkg.world import world_from_dict

ROOMS = {'name': 'gen_mixed_1169', 'start': [8.666, 11.037],
         'boundary': [[6.826, 0.0], [0.0, 0.0], [0.0, 6.209], [3.258, 6.209], [3.258, 6.409],
                      [0.0, 6.409], [0.0, 8.004], [7.491, 8.004], [7.491, 8.204],
                      [7.026, 8.204], [7.026, 13.511], [12.758, 13.511], [12.758, 8.204],
                      [8.911, 8.204], [8.911, 8.004], [13.225, 8.004], [13.225, 6.409],
                      [4.458, 6.409], [4.458, 6.209], [6.826, 6.209]],
         'obstacles': [[[5.02, 3.633], [4.782, 3.709], [4.772, 3.708], [4.631, 3.666],
                        [4.616, 3.049], [5.094, 3.154]],
                       [[10.253, 10.065], [9.636, 10.85], [8.582, 9.999], [10.084, 9.539],
                        [10.172, 9.685], [10.245, 9.931]]]}


def _covered_at(p, node_id):
    """Time of the event that closed node ``node_id``."""
    return p.events[p.nodes[node_id].closed_by][0]


@pytest.mark.slow                         # two closed-loop runs, about 2 s
def test_after_a_merge_find_uncovered_node_chooses_the_rooms_other_corners_first():
    """Default: at the ``same_cell`` event FindUncoveredNode runs and takes the bottom room's
    nearest corner node; the room's other corners are covered before the robot goes back to
    node 0's open branches in the top room. With ``merge_continues`` the merged node 0 goes
    on being covered at once: the robot drives up to the top room and back down for the two
    corners, over 10 m more."""
    runs = {mc: run_kinematic(world_from_dict(ROOMS), PaperConfig(merge_continues=mc),
                              max_time=3000) for mc in (False, True)}
    for r in runs.values():
        assert r['state'] == 'done' and r['covered_fraction'] >= 0.99
    for mc, r in runs.items():
        p = r['planner']
        merge = next(e for e in p.events if e[1] == 'same_cell')
        assert p.nodes[0].kind == 'narrow' and p.nodes[1].kind == 'vast'
        merged = [n for n in p.nodes if n.merged_into == 0]
        assert len(merged) == 1 and merged[0].anchor[1] < 6.2         # a bottom-room corner
        corners = [n for n in p.nodes if n.kind == 'narrow' and n.anchor[1] < 6.2
                   and n.merged_into is None]
        assert len(corners) == 2
        decided_at_merge = [d for d in p.decisions if d[0] == round(merge[0], 3)]
        last_corner = max(_covered_at(p, n.id) for n in corners)
        if mc:
            assert not decided_at_merge
            assert _covered_at(p, 0) < last_corner
        else:
            assert [d[1] for d in decided_at_merge] in [[n.id] for n in corners]
            assert last_corner < _covered_at(p, 0)
    assert runs[False]['path_length'] < runs[True]['path_length'] - 10.0
