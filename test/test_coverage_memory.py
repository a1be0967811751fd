"""The planner's footprint memory (re-judged poses, speckles) and the full-knowledge oracle."""
import math

import numpy as np
import pytest
import shapely

from coverage_pkg.mapping import EvidenceGrid, drop_speckles
from coverage_pkg.oracle import oracle_route
from coverage_pkg.world import world_from_dict


def _free_line(grid, a, b, times=3):
    """Known-free evidence on the cells of the segment a-b (integrated ``times``)."""
    n = int(math.hypot(b[0] - a[0], b[1] - a[1]) / 0.02) + 1
    pts = np.linspace(a, b, n)
    for _ in range(times):
        grid.integrate(pts, np.zeros((0, 2)))


def test_a_cell_cleared_after_the_pass_is_rejudged_viewed_from_the_old_pose():
    g = EvidenceGrid(0.1, (0.0, 0.0))
    g.mark_viewed(0.0, 0.0, 2.0)                 # nothing known yet: rays stop at once
    _free_line(g, (0.0, 0.05), (1.95, 0.05))     # the sonar clears the line later
    _free_line(g, (0.0, 0.05), (1.05, 1.05))
    g.integrate(np.zeros((0, 2)), np.array([[0.55, 0.55]] * 1))
    for _ in range(3):
        g.integrate(np.zeros((0, 2)), np.array([[0.55, 0.55]]))
    near = g.cells(np.array([[1.05, 0.05]]))
    far = g.cells(np.array([[1.95, 0.05]]))     # beyond delta - one cell
    hidden = g.cells(np.array([[1.05, 1.05]]))  # behind the echo at (0.55, 0.55)
    rows = np.concatenate([near[0], far[0], hidden[0]])
    cols = np.concatenate([near[1], far[1], hidden[1]])
    assert not g.viewed[rows, cols].any()
    marked = g.rejudge_viewed(np.array([[0.0, 0.0]]), 2.0, rows, cols)
    assert marked == 1
    assert g.viewed[near].all()
    assert not g.viewed[far].any() and not g.viewed[hidden].any()


def test_speckles_are_small_pockets_away_from_the_frontier():
    unseen = np.zeros((40, 40), dtype=bool)
    frontier = np.zeros_like(unseen)
    unseen[5:7, 5:7] = True                      # 4 cells, 0.04 m^2, alone: speckle
    unseen[20:22, 30:32] = True                  # 4 cells next to the frontier: kept
    frontier[20:22, 33] = True
    unseen[30:36, 5:10] = True                   # 30 cells, 0.3 m^2: a place
    out = drop_speckles(unseen, frontier, 0.1, 0.2)
    assert not out[5:7, 5:7].any()
    assert out[20:22, 30:32].all()
    assert out[30:36, 5:10].all()
    assert (drop_speckles(unseen, frontier, 0.1, 0.0) == unseen).all()
    # What is knowingly left unseen is bounded: smallest pockets first, within the budget.
    unseen[10:13, 20:22] = True                  # 6 cells, 0.06 m^2
    out = drop_speckles(unseen, frontier, 0.1, 0.2, budget=0.05)
    assert not out[5:7, 5:7].any() and out[10:13, 20:22].all()
    out = drop_speckles(unseen, frontier, 0.1, 0.2, budget=0.11)
    assert not out[5:7, 5:7].any() and not out[10:13, 20:22].any()


CORRIDOR = {'name': 'dead_end', 'boundary': [[0, 0], [12, 0], [12, 1.4], [0, 1.4]],
            'obstacles': [], 'start': [1.0, 0.7]}


def test_oracle_drives_a_dead_end_corridor_exactly_as_far_as_its_end_needs():
    # The far corners (12, 0) and (12, 1.4) are in range delta = 2 only from x >= 12 -
    # sqrt(4 - 0.7^2) = 10.127 on the centre line (off it, one corner is farther): the
    # shortest path that sees the whole corridor from the start x = 1 is 9.127 m.
    world = world_from_dict(CORRIDOR)
    r = oracle_route(world, radius=0.25, delta=2.0, target=1.0)
    need = 12.0 - math.sqrt(4.0 - 0.49) - 1.0
    assert r['covered_fraction'] >= 0.998
    assert need - 0.05 <= r['path_length'] <= need + 0.3
    # 1.4 m wide, 4 m sweep assumed by the bound: even the best route is twice the bound.
    assert r['path_length'] / r['lower_bound'] > 2.0
    walls = world.free.boundary
    for x, y in r['path']:
        assert walls.distance(shapely.Point(x, y)) >= 0.25


@pytest.mark.slow
def test_oracle_route_sees_the_target_share_of_cvs_in_a_room_with_an_obstacle():
    world = world_from_dict({'name': 'room', 'boundary': [[0, 0], [8, 0], [8, 6], [0, 6]],
                             'obstacles': [[[3, 2], [5, 2], [5, 4], [3, 4]]],
                             'start': [1.0, 1.0]})
    r = oracle_route(world, radius=0.25, delta=2.0, target=0.998)
    assert r['covered_fraction'] >= 0.995
    assert r['lower_bound'] <= r['path_length'] < 4.0 * r['lower_bound']
    assert r['path'][0] == pytest.approx((1.025, 1.025), abs=0.05)


def test_result_graph_is_shifted_whole_into_the_map_frame():
    """Every point of the graph in result.json is in ``map``: the sensed cusps and the shared
    boundary points too, not only the nodes and the cusp list."""
    from coverage_pkg.scenario import _shift_graph
    g = {'nodes': [{'anchor': [0, 0], 'centroid': [1, 1], 'critical_points': [[2, 2, 'opens']],
                    'meet_points': [[3, 3]], 'label_point': [7, 7]}],
         'edges': [{'cusp_points': [[4, 4]], 'sensed_cusp_points': [[4, 4]],
                    'shared_boundary_point': [5, 5]},
                   {'cusp_points': [], 'sensed_cusp_points': [], 'shared_boundary_point': None}]}
    out = _shift_graph(g, 1.0, -1.0)
    assert out['nodes'][0]['critical_points'] == [[3.0, 1.0, 'opens']]
    assert out['nodes'][0]['label_point'] == [8.0, 6.0]
    assert out['edges'][0]['sensed_cusp_points'] == [[5.0, 3.0]]
    assert out['edges'][0]['shared_boundary_point'] == [6.0, 4.0]
    assert out['edges'][1]['shared_boundary_point'] is None
