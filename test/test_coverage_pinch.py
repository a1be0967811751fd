"""The vast cell's motions keep to where a disk of radius delta fits (``pinch_ends_cell``).

The world is gen_halls_8055's shape: an L of halls, the upright 4.19 m wide and 6.04 m high,
the arm along the bottom 3.82 m high and 10.5 m long. The arm is narrower than 2 delta, so a
disk of radius delta fits only in the upright: the vast cell is a sliver there, and the arm is
narrow space, one GVD edge to trace. The arm's bottom wall runs on from the upright's: the
move between laps, following that wall at D = delta along +x, passes the cusp at the arm's
mouth and goes on along the arm's middle (D = 1.91 m there). With ``pinch_ends_cell`` the
cell ends where both walls lie nearer than delta either side of the robot, and a lap ends
where the disk touches a corner ahead.
"""
import pytest

from coverage_pkg.algorithm1 import PaperConfig
from coverage_pkg.kinematic import run_kinematic
from coverage_pkg.world import world_from_dict

L_HALL = {'name': 'l_hall', 'start': [3.346, 3.039], 'obstacles': [],
          'boundary': [[14.665, 3.819], [14.665, 0.0], [0.0, 0.0], [0.0, 6.037],
                       [4.194, 6.037], [4.194, 3.819]]}


def _vast_events_in_arm(r):
    """Laps' critical points and boundary circuits of a vast node sensed in the arm."""
    return [e for e in r['planner'].events
            if e[1] in ('critical', 'circuit') and e[2] > 5.0]


@pytest.mark.slow                         # two closed-loop runs, about 5 s
def test_the_cell_ends_where_the_move_between_laps_enters_narrow_space():
    """With ``pinch_ends_cell`` the cell closes at the arm's mouth ('the slice pinches'), no
    lap or circuit of the vast node runs in the arm, the arm is traced as the GVD edge it is,
    and the path is less than two thirds of the path without it, which drives the arm's
    length as laps, then circuits round the 'obstacles' the laps met there, then traces it."""
    on = run_kinematic(world_from_dict(L_HALL), PaperConfig(pinch_ends_cell=True),
                       max_time=3000)
    assert on['state'] == 'done' and on['covered_fraction'] >= 0.99
    pinch = [e for e in on['planner'].events if e[1] == 'cell_closed' and 'pinches' in e[4]]
    assert pinch and all(3.5 < e[2] < 6.0 for e in pinch)
    assert not _vast_events_in_arm(on)

    off = run_kinematic(world_from_dict(L_HALL), PaperConfig(pinch_ends_cell=False),
                        max_time=3000)
    assert off['state'] == 'done' and off['covered_fraction'] >= 0.99
    assert _vast_events_in_arm(off)
    assert on['path_length'] < 2 / 3 * off['path_length']


#: gen_halls_8019's shape: a T, the crossbar 13 m long and 4.25 m high (a vast sliver along
#: its middle), the stem 4.09 m wide (narrower than 2 delta) rising 4.74 m above it.
T_HALL = {'name': 't_hall_narrow_stem', 'start': [7.772, 1.778], 'obstacles': [],
          'boundary': [[12.984, 4.249], [12.984, 0.0], [0.0, 0.0], [0.0, 4.249],
                       [4.543, 4.249], [4.543, 8.99], [8.629, 8.99], [8.629, 4.249]]}


def _lap_tops(r):
    """The highest y of each lap the vast node drove (Morse cells' laps: (x, y_lo, y_hi))."""
    return [hi for n in r['planner'].nodes for c in n.cells for _, _, hi in c.laps]


@pytest.mark.slow                         # two closed-loop runs, about 6 s
def test_a_lap_ends_where_the_delta_disk_touches_a_corner_ahead():
    """With ``pinch_ends_cell`` a lap ends where the closest echo, ahead of the lap within
    60 degrees, is nearer than delta: no lap of the crossbar's sliver runs up into the stem,
    where the disk of radius delta does not fit. Without it, the lap along the slice by the
    stem runs up the stem until the stem's far wall is delta ahead, and the path is
    longer."""
    on = run_kinematic(world_from_dict(T_HALL), PaperConfig(pinch_ends_cell=True),
                       max_time=3000)
    assert on['state'] == 'done' and on['covered_fraction'] >= 0.99
    assert _lap_tops(on) and max(_lap_tops(on)) < 4.0

    off = run_kinematic(world_from_dict(T_HALL), PaperConfig(pinch_ends_cell=False),
                        max_time=3000)
    assert off['state'] == 'done' and off['covered_fraction'] >= 0.99
    assert max(_lap_tops(off)) > 6.0
    assert on['path_length'] < off['path_length'] - 10.0
