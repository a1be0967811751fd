"""Morse decomposition of the vast region: slices, critical points, Reeb graph, lapping.

Section II of Acar, Choset and Lee. The slice function is ``h(x, y) = x``; a slice is
``CS_lambda = {(x, y) in CS : h = lambda}``. Cells are bounded by the slices through the
critical points of ``h`` restricted to the obstacle boundary, where the connectivity of the
slice changes; at such a point the surface normal is parallel to ``grad h`` (Fig. 3). The
Reeb graph has the critical points as nodes and the cells as edges. A cell is covered by
back-and-forth motion along slices with lap spacing ``2 * delta`` (the robot "pretends" to be
as big as its detector, Section IV-A) plus boundary following along ``D = delta``.

Sensor view (Acar and Choset [3]): while following a boundary the robot is at a critical point
when the direction to the closest obstacle is parallel to ``grad h`` (the +/-x axis),
:func:`critical_from_ring`. Grid view: the planner slices the sensed vast region column by
column and finds the critical points as the columns where the number or adjacency of slice
intervals changes, :func:`reeb_decomposition`.
"""
import math
from dataclasses import dataclass, field

import numpy as np

from coverage_pkg.gvd import ring_minima


def critical_from_ring(ranges, angles, yaw, tol=math.radians(8.0)):
    """Critical point test from a range ring, for the slice function h = x.

    At a critical point of ``h`` restricted to the boundary, the boundary normal (the direction
    from the robot to its closest obstacle) is parallel to ``grad h = (1, 0)``. Returns
    ``+1`` if the closest obstacle is straight ahead in +x, ``-1`` if in -x, ``0`` otherwise.
    ``angles`` are in the robot frame, ``yaw`` turns them into the world frame.
    """
    mins = ring_minima(ranges, angles)
    if not mins:
        return 0
    bearing = math.remainder(mins[0][1] + yaw, 2 * math.pi)
    if abs(bearing) <= tol:
        return 1
    if abs(abs(bearing) - math.pi) <= tol:
        return -1
    return 0


def slice_intervals(column):
    """Maximal runs of True in a 1-D boolean array: list of (start, end) inclusive."""
    col = np.asarray(column, dtype=np.int8)
    d = np.diff(np.concatenate([[0], col, [0]]))
    starts = np.flatnonzero(d == 1)
    ends = np.flatnonzero(d == -1) - 1
    return list(zip(starts.tolist(), ends.tolist()))


@dataclass
class CriticalPoint:
    """A critical point of h on the boundary of the (sensed) vast region, in grid indices."""

    row: float
    col: float
    kind: str           # 'birth' (cell opens), 'death' (cell closes), 'split', 'merge'
    cells_before: list = field(default_factory=list)
    cells_after: list = field(default_factory=list)


def reeb_decomposition(mask):
    """Boustrophedon (Morse, h = x) decomposition of a boolean region ``mask[row, col]``.

    Sweeps the slice column by column. Interval ``b`` of column ``j`` continues the cell of
    interval ``a`` of column ``j - 1`` when they overlap one-to-one; any other overlap pattern
    is a critical point: an interval without predecessor is a *birth* (leftmost point of a
    cell), one without successor a *death*, one predecessor with several successors a *split*
    (the slice meets the leftmost point of an obstacle), several predecessors into one a
    *merge* (rightmost point of an obstacle).

    Returns ``(labels, points, edges)``: ``labels`` numbers the cells (0 outside ``mask``), the
    critical points, and the Reeb graph edges ``(point_a, point_b, cell)`` (a cell joins the
    critical point that opened it to the one that closed it; -1 if still open at the map
    edge).
    """
    ny, nx = mask.shape
    labels = np.zeros((ny, nx), dtype=np.int32)
    points = []
    cell_open = {}           # cell -> index of the critical point that opened it
    edges = []
    prev = []                # [(start, end, cell)] of column j - 1
    next_cell = 1
    for j in range(nx):
        runs = slice_intervals(mask[:, j])
        succ = [[] for _ in prev]
        pred = [[] for _ in runs]
        for bi, (b0, b1) in enumerate(runs):
            for ai, (a0, a1, _) in enumerate(prev):
                if a0 <= b1 and b0 <= a1:
                    succ[ai].append(bi)
                    pred[bi].append(ai)
        cur = []
        assigned = [None] * len(runs)
        for bi, (b0, b1) in enumerate(runs):
            if len(pred[bi]) == 1 and len(succ[pred[bi][0]]) == 1:
                assigned[bi] = prev[pred[bi][0]][2]
        # Critical events.
        for ai, (a0, a1, cell) in enumerate(prev):
            if not succ[ai]:
                points.append(CriticalPoint((a0 + a1) / 2.0, j - 1, 'death', [cell], []))
                edges.append((cell_open.pop(cell, -1), len(points) - 1, cell))
            elif len(succ[ai]) > 1:
                kids = []
                for bi in succ[ai]:
                    if assigned[bi] is None:
                        assigned[bi] = next_cell
                        next_cell += 1
                    kids.append(assigned[bi])
                gap = (runs[succ[ai][0]][1] + runs[succ[ai][1]][0]) / 2.0
                points.append(CriticalPoint(gap, j, 'split', [cell], kids))
                edges.append((cell_open.pop(cell, -1), len(points) - 1, cell))
                for k in kids:
                    cell_open.setdefault(k, len(points) - 1)
        for bi, (b0, b1) in enumerate(runs):
            if not pred[bi]:
                assigned[bi] = next_cell
                next_cell += 1
                points.append(CriticalPoint((b0 + b1) / 2.0, j, 'birth', [], [assigned[bi]]))
                cell_open[assigned[bi]] = len(points) - 1
            elif len(pred[bi]) > 1:
                if assigned[bi] is None:
                    assigned[bi] = next_cell
                    next_cell += 1
                parents = [prev[ai][2] for ai in pred[bi]]
                gap = (prev[pred[bi][0]][1] + prev[pred[bi][1]][0]) / 2.0
                points.append(CriticalPoint(gap, j, 'merge', parents, [assigned[bi]]))
                for c in parents:
                    if c in cell_open:
                        edges.append((cell_open.pop(c), len(points) - 1, c))
                cell_open.setdefault(assigned[bi], len(points) - 1)
            elif assigned[bi] is None:
                # One predecessor that split: already numbered in the split branch above.
                assigned[bi] = next_cell
                next_cell += 1
            labels[b0:b1 + 1, j] = assigned[bi]
            cur.append((b0, b1, assigned[bi]))
        prev = cur
    for cell, start in cell_open.items():
        edges.append((start, -1, cell))
    return labels, points, edges


def lap_columns(nx, origin_x, resolution, x_ref, spacing):
    """Boolean per grid column: True on the lapping slices ``x = x_ref + k * spacing``.

    The slices are ``2 * delta`` apart so that the detector disks swept along two neighbouring
    slices just meet (Section IV-A).
    """
    xs = origin_x + (np.arange(nx) + 0.5) * resolution
    off = xs - x_ref
    d = off - np.round(off / spacing) * spacing          # signed distance to the nearest slice
    # exactly one column per slice: the half-open window [-res/2, res/2), robust to rounding
    return (d >= -0.5 * resolution - 1e-9) & (d < 0.5 * resolution - 1e-9)


def boundary_cells(region):
    """Cells of ``region`` with a 4-neighbour outside it: the curve followed by boundary
    following (for the vast region, the contour ``D = delta``)."""
    p = np.pad(region, 1, constant_values=False)
    inner = p[1:-1, 1:-1] & p[:-2, 1:-1] & p[2:, 1:-1] & p[1:-1, :-2] & p[1:-1, 2:]
    return region & ~inner
