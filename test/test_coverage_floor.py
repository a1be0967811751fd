"""The floor of Algorithm 1's path and its nearest-first walk (coverage_pkg/algorithm1_floor.py)
against hand-computed values, and the paper planner's path against the floor."""
import math
from pathlib import Path

import pytest

from coverage_pkg.algorithm1 import PaperConfig
from coverage_pkg.algorithm1_floor import algorithm1_floor, driven_again, nearest_first_walk
from coverage_pkg.kinematic import run_kinematic
from coverage_pkg.world import load_world, world_from_dict

WORLDS = Path(__file__).resolve().parents[1] / 'coverage_pkg' / 'worlds'
# The medial axis ends where D = r, at (11.75, 0.25) and (11.75, 1.15) by the far corners
# (and at x = 0.25 by the near ones). A branch is ended where all it leaves lies within
# delta - view_margin = 1.7 m: on the centre line y = 0.7 that is 1.7 m from those ends.
TRIM = math.sqrt(1.7 ** 2 - 0.45 ** 2)


def test_a_dead_end_corridor_needs_its_centre_line_up_to_the_trimmed_ends():
    world = world_from_dict({'name': 'dead_end', 'boundary': [[0, 0], [12, 0], [12, 1.4],
                                                              [0, 1.4]],
                             'obstacles': [], 'start': [1.0, 0.7]})
    f = algorithm1_floor(world)
    left, right = 0.25 + TRIM, 11.75 - TRIM
    assert f['circles'] == 0.0                       # D < delta everywhere: all narrow
    assert f['lead'] == pytest.approx(left - 1.0, abs=0.08)
    assert f['gvd'] == pytest.approx(right - left, abs=0.1)
    assert f['extra'] == pytest.approx(f['lead'], abs=1e-9)   # in at the left end, out right
    assert right - 1.0 - 0.15 <= f['floor'] <= right - 1.0 + 0.05


def test_a_room_needs_its_circle_at_delta_and_the_corner_edges_up_to_their_trimmed_ends():
    # 10 x 8 m, no obstacle: {D >= 2} is the 6 x 4 m rectangle around the middle, so its
    # circle is 20 m. The corner edges run from its corners to (0.25, 0.25) and the like,
    # 2.47 m, of which 2.47 - 1.7 m is left. The robot starts in the middle, 2 m from the
    # circle, and drives each corner edge out and back but the last one.
    world = world_from_dict({'name': 'room', 'boundary': [[0, 0], [10, 0], [10, 8], [0, 8]],
                             'obstacles': [], 'start': [5.0, 4.0]})
    f = algorithm1_floor(world)
    spur = math.hypot(1.75, 1.75) - 1.7
    need = 2.0 + 20.0 + 4 * 2 * spur - spur
    assert f['circles'] == pytest.approx(20.0, abs=0.4)
    assert f['gvd'] == pytest.approx(4 * spur, abs=0.4)
    assert f['odd'] == 8                                # four corners, four edge ends
    assert need - 1.0 <= f['floor'] <= need + 0.1


def test_a_start_in_the_middle_of_an_l_drives_the_shorter_arm_twice():
    # An L of 1.4 m corridors: 4 m up (x in [0, 1.4], y in [0, 5.4]) and 10 m along
    # (y in [0, 1.4]); the robot starts in the corner. The walk drives one arm out and back
    # and ends in the other: the required length plus the shorter arm once more (less up to
    # 0.4 m: the entry cells are tried every 0.2 m and the bound gives away the cells between).
    world = world_from_dict({'name': 'l', 'boundary': [[0, 0], [11.4, 0], [11.4, 1.4],
                                                       [1.4, 1.4], [1.4, 5.4], [0, 5.4]],
                             'obstacles': [], 'start': [0.7, 0.7]})
    f = algorithm1_floor(world)
    up = 5.15 - TRIM - 0.7                        # the trimmed up arm beyond the corner
    required = f['gvd']
    assert required == pytest.approx(up + (11.15 - TRIM - 0.7), abs=0.4)
    assert required + up - 0.5 <= f['floor'] <= required + up + 0.1


def test_a_loop_round_an_obstacle_is_needed_once_and_not_out_and_back():
    # A 1.4 m ring corridor round a 7.2 m square obstacle: its GVD is one loop (with four
    # short corner edges, trimmed away), driven once from a start on it: at least 4 x 7.2 m.
    # A tree's out-and-back would be about twice that.
    world = world_from_dict({'name': 'ring', 'boundary': [[0, 0], [10, 0], [10, 10], [0, 10]],
                             'obstacles': [[[1.4, 1.4], [8.6, 1.4], [8.6, 8.6], [1.4, 8.6]]],
                             'start': [5.0, 0.7]})
    f = algorithm1_floor(world)
    assert 4 * 7.2 <= f['floor'] <= 4 * 8.6
    assert f['extra'] == pytest.approx(0.0, abs=0.2)


@pytest.mark.slow                     # one closed-loop run, about 10 s
@pytest.mark.parametrize('name', ['t_hall.json', 'door_rooms.json'])
def test_the_paper_planner_drives_at_least_the_floor(name):
    """The floor counts only what Algorithm 1 must drive; a paper planner path below it
    would mean the planner skipped a GVD edge or a circle at D = delta (or the floor counts
    one the method does not need)."""
    world = load_world(WORLDS / name)
    r = run_kinematic(world, PaperConfig())
    f = algorithm1_floor(world)
    assert r['state'] == 'done'
    assert f['floor'] <= r['path_length']
    assert f['lower_bound'] == pytest.approx(r['lower_bound'])


def test_the_floor_does_not_depend_on_how_the_medial_axis_breaks_ties(tmp_path):
    """The grid's medial axis breaks ties at random and leaves small loops round no
    obstacle; filled, they leave the same required set whatever the tie-breaking."""
    from coverage_pkg.algorithm1_floor import _chains, required_cells
    from coverage_pkg.cvs import CoverableSet
    from coverage_pkg.worldgen import write_worlds
    world = load_world(write_worlds(tmp_path, 1, seed=6007)[0])      # a maze with rooms
    cvs = CoverableSet(world, 0.25, 2.0, 0.05)
    lengths = []
    for rng in range(3):
        gvd, ring = required_cells(cvs, 2.0, 0.25, rng=rng)
        lengths.append(sum(e[2] for e in _chains(gvd | ring, cvs.res)[1]))
    assert max(lengths) - min(lengths) < 0.01 * min(lengths)


def test_the_nearest_first_walk_drives_either_arm_of_an_l_first():
    """From the corner of an L the two arms are one vertex's edges: an online order cannot
    tell which is shorter. The walk drives one out and back and ends in the other; over its
    random tie-breaks the least walk is the floor's (the shorter arm twice) and the largest
    drives the longer arm twice."""
    world = world_from_dict({'name': 'l', 'boundary': [[0, 0], [11.4, 0], [11.4, 1.4],
                                                       [1.4, 1.4], [1.4, 5.4], [0, 5.4]],
                             'obstacles': [], 'start': [0.7, 0.7]})
    w = nearest_first_walk(world)
    f = algorithm1_floor(world)
    up, along = 5.15 - TRIM - 0.7, 11.15 - TRIM - 0.7
    assert w['required'] == pytest.approx(up + along, abs=0.4)
    assert w['walk_min'] == pytest.approx(w['required'] + up, abs=0.5)
    assert w['walk_max'] == pytest.approx(w['required'] + along, abs=0.5)
    assert w['walk_min'] < w['walk'] < w['walk_max']
    assert f['floor'] <= w['walk_min'] + 0.05


@pytest.mark.parametrize('shape', ['dead_end', 'ring'])
def test_the_nearest_first_walk_needs_no_more_than_the_floor_without_a_choice(shape):
    """Where no order has a choice to make (a dead-end corridor entered at its end, a loop
    round an obstacle) the nearest-first walk is the floor."""
    if shape == 'dead_end':
        world = world_from_dict({'name': 'dead_end', 'boundary': [[0, 0], [12, 0], [12, 1.4],
                                                                  [0, 1.4]],
                                 'obstacles': [], 'start': [1.0, 0.7]})
    else:
        world = world_from_dict({'name': 'ring', 'boundary': [[0, 0], [10, 0], [10, 10],
                                                              [0, 10]],
                                 'obstacles': [[[1.4, 1.4], [8.6, 1.4], [8.6, 8.6],
                                                [1.4, 8.6]]],
                                 'start': [5.0, 0.7]})
    w = nearest_first_walk(world)
    f = algorithm1_floor(world)
    assert w['walk_max'] - w['walk_min'] < 0.05
    assert w['walk'] == pytest.approx(f['floor'], abs=0.3)


def test_the_nearest_first_walk_is_never_below_the_floor(tmp_path):
    """The floor bounds every walk that drives the required set: the least of the
    nearest-first walks on generated worlds is at or above it."""
    from coverage_pkg.worldgen import write_worlds
    for path in write_worlds(tmp_path, 3, seed=6000):
        world = load_world(path)
        assert algorithm1_floor(world)['floor'] <= nearest_first_walk(world)['walk_min'] + 0.05


def test_circuits_first_drives_the_curve_round_before_the_corners():
    """In a 10 x 8 m room (the circle D = delta of 20 m, a 0.77 m corner edge at each of its
    corners) the nearest-first walk can take each corner's edge as it passes its cusp; with
    the circuit first, as Algorithm 1 covers a vast cell, it comes back round to the four
    cusps after the circle: about a second circle, less a side."""
    world = world_from_dict({'name': 'room', 'boundary': [[0, 0], [10, 0], [10, 8], [0, 8]],
                             'obstacles': [], 'start': [5.0, 4.0]})
    any_order = nearest_first_walk(world)
    circuits = nearest_first_walk(world, circuits_first=True)
    assert circuits['walk_max'] - circuits['walk_min'] < 0.05     # no choice left to chance
    assert 2.0 + 20.0 + 14.0 <= circuits['walk'] <= 2.0 + 20.0 + 24.0
    assert circuits['walk'] >= any_order['walk_min'] + 12.0
    assert any_order['walk_min'] == pytest.approx(algorithm1_floor(world)['floor'], abs=0.6)


def test_driven_again_counts_the_way_back_and_a_second_lap_not_the_way_out():
    """Out 10 m along a line and back: the way back is driven again but for its first
    (lag - within) / 2 = 0.35 m, where the path it passes lies less than ``lag`` behind; a
    circle of radius 2 m driven once: only the 0.3 m where it closes onto its start; twice:
    the whole second lap as well; a straight line: nothing."""
    import numpy as np
    x = np.linspace(0.0, 10.0, 1001)
    out = np.c_[x, np.zeros_like(x)]
    assert driven_again(out) == 0.0
    assert driven_again(np.r_[out, out[::-1][1:]]) == pytest.approx(10.0 - 0.35, abs=0.02)
    t = np.linspace(0.0, 2 * math.pi, 2001)
    circle = np.c_[2 * np.cos(t), 2 * np.sin(t)]
    assert driven_again(circle) == pytest.approx(0.3, abs=0.02)
    assert driven_again(np.r_[circle, circle[1:]]) == pytest.approx(4 * math.pi + 0.3, abs=0.03)

