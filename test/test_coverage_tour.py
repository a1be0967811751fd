"""The open tour that orders a narrow node's pieces (coverage_pkg/tour.py), checked against
brute force and against hand-computed grid distances."""
import itertools
import math

import numpy as np

from coverage_pkg.tour import chunk_cells, coarse_distances, open_tour


def _length(dist, order):
    return sum(dist[a, b] for a, b in zip(order[:-1], order[1:]))


def _best(dist, end=None):
    n = len(dist)
    best = math.inf
    for perm in itertools.permutations([i for i in range(1, n) if i != end]):
        order = [0, *perm] + ([end] if end is not None else [])
        best = min(best, _length(dist, order))
    return best


def test_a_dead_end_next_to_the_robot_is_done_before_the_far_branch():
    """Robot at x = 0 on a corridor; a dead end at x = -1, a branch at x = 1 .. 6. Nearest
    first goes right and comes all the way back; the open tour takes the dead end first."""
    xs = np.array([0.0, -1.0, 0.5, 2.0, 4.0, 6.0])
    dist = np.abs(xs[:, None] - xs[None, :])
    order = open_tour(dist)
    assert order[0] == 0 and order[1] == 1
    assert _length(dist, order) == 8.0          # 1 back + 7 out, against 0.5 + 5.5 + 7 = 13


def test_the_tour_ends_where_it_is_told_to():
    xs = np.array([0.0, -3.0, 1.0, 5.0, -1.0])
    dist = np.abs(xs[:, None] - xs[None, :])
    for end in range(1, 5):
        order = open_tour(dist, end)
        assert order[0] == 0 and order[-1] == end and sorted(order) == list(range(5))


def test_two_opt_is_within_a_quarter_of_the_optimum_on_random_plane_instances():
    rng = np.random.default_rng(4)
    worst = 1.0
    for _ in range(30):
        p = rng.uniform(0, 10, size=(8, 2))
        dist = np.hypot(*(p[:, None, :] - p[None, :, :]).transpose(2, 0, 1))
        order = open_tour(dist)
        assert sorted(order) == list(range(8)) and order[0] == 0
        worst = max(worst, _length(dist, order) / _best(dist))
        order = open_tour(dist, 7)
        assert order[-1] == 7
        worst = max(worst, _length(dist, order) / _best(dist, 7))
    assert worst <= 1.25


def test_chunks_split_by_square_and_by_connectivity():
    mask = np.zeros((10, 30), dtype=bool)
    mask[2, :] = True                   # one row, 30 cells: 3 squares of 12, 12, 6
    mask[7, 0:5] = True                 # same squares, another component
    chunks = chunk_cells(mask, 12)
    assert sorted(len(c) for c in chunks) == [5, 6, 12, 12]
    assert sum(len(c) for c in chunks) == int(mask.sum())


def test_coarse_distances_go_around_a_wall_wherever_it_falls_on_the_coarse_grid():
    """An impassable band 5 fine cells wide (FCS_r's band around a wall is 7 at 0.1 m) with
    one gap: the distance between its two sides is the way through the gap, for every offset
    of the band against the coarse cells of 4; closed, the sides are unreachable."""
    for offset in range(4):
        cost = np.ones((41, 43))
        band = slice(18 + offset, 23 + offset)
        cost[:, band] = np.inf
        cost[34:38, band] = 1.0                 # gap near the bottom
        a, b = (2, 8), (2, 34)
        d = coarse_distances(cost, [a, b], 4)
        # Through the gap: down ~32 rows, across ~26 columns, up ~32 rows; diagonals shave
        # the corners. The straight line (26) would mean the band leaked.
        assert 60.0 < d[0, 1] < 95.0, (offset, d[0, 1])
        assert d[0, 1] == d[1, 0] and d[0, 0] == 0.0
        cost[34:38, band] = np.inf              # closed
        assert math.isinf(coarse_distances(cost, [a, b], 4)[0, 1]), offset
