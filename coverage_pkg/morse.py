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
from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike

from coverage_pkg.gvd import ring_minima


def critical_from_ring(ranges: ArrayLike, angles: ArrayLike, yaw: float,
                       tol: float = math.radians(8.0)) -> int:
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


def slice_intervals(column: ArrayLike) -> list[tuple[int, int]]:
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
    lo: float = math.nan    # rows the event spans on its slice: the gap between the intervals
    hi: float = math.nan    # (split, merge) or the interval that opens or closes (birth, death)


def reeb_decomposition(mask: np.ndarray
                       ) -> tuple[np.ndarray, list[CriticalPoint], list[tuple[int, int, int]]]:
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
                points.append(CriticalPoint((a0 + a1) / 2.0, j - 1, 'death', [cell], [],
                                            a0, a1))
                edges.append((cell_open.pop(cell, -1), len(points) - 1, cell))
            elif len(succ[ai]) > 1:
                kids = []
                for bi in succ[ai]:
                    if assigned[bi] is None:
                        assigned[bi] = next_cell
                        next_cell += 1
                    kids.append(assigned[bi])
                lo, hi = runs[succ[ai][0]][1], runs[succ[ai][-1]][0]
                points.append(CriticalPoint((lo + hi) / 2.0, j, 'split', [cell], kids, lo, hi))
                edges.append((cell_open.pop(cell, -1), len(points) - 1, cell))
                for k in kids:
                    cell_open.setdefault(k, len(points) - 1)
        for bi, (b0, b1) in enumerate(runs):
            if not pred[bi]:
                assigned[bi] = next_cell
                next_cell += 1
                points.append(CriticalPoint((b0 + b1) / 2.0, j, 'birth', [], [assigned[bi]],
                                            b0, b1))
                cell_open[assigned[bi]] = len(points) - 1
            elif len(pred[bi]) > 1:
                if assigned[bi] is None:
                    assigned[bi] = next_cell
                    next_cell += 1
                parents = [prev[ai][2] for ai in pred[bi]]
                lo, hi = prev[pred[bi][0]][1], prev[pred[bi][-1]][0]
                points.append(CriticalPoint((lo + hi) / 2.0, j, 'merge', parents,
                                            [assigned[bi]], lo, hi))
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


@dataclass
class MorseCells:
    """Morse cells bounded by *sensed* critical points (see :func:`sensed_morse_cells`)."""

    labels: np.ndarray      # cell number per grid cell, 0 outside the region
    edges: list             # Reeb graph: (opening point, closing point, cell); -1 = not sensed
    confirmed: list         # (grid CriticalPoint, index of the sensed point that confirms it)
    ignored: list           # split/merge slices of the grid that no sensed point confirms


def _gap_persists(mask, p, span):
    """True if the gap of split/merge ``p`` (the rows between its intervals) stays outside
    ``mask`` for ``span`` columns on the obstacle's side (+x of a split, -x of a merge), with
    the region going on on both sides of it: an obstacle's delta-offset does; a notch of a
    ragged sensed wall closes, or one side of it ends, within a column or two."""
    lo, hi = int(math.floor(p.lo)) + 1, int(math.ceil(p.hi))
    if hi <= lo:
        return False
    step = 1 if p.kind == 'split' else -1
    for m in range(1, int(span) + 1):
        j = int(p.col) + step * m
        if not 0 <= j < mask.shape[1]:
            return False
        col = mask[:, j]
        if col[lo:hi].all() or not (col[:lo].any() and col[hi:].any()):
            return False                      # the gap closed, or a side ended: a notch
    return True


def sensed_morse_cells(mask: np.ndarray, sensed: Sequence[tuple[float, float, int]],
                       col_tol: float, row_tol: float, min_span: int = 2) -> MorseCells:
    """Morse cells of ``mask`` whose boundaries are the slices through **sensed** critical
    points, as in the incremental construction of Section II / Fig. 4.

    ``sensed`` lists the critical points the robot's sensor test found, in grid indices:
    ``(row, col, side)`` with ``side = +1`` when the closest obstacle lay along ``+x``
    (``grad h``: the slice meets an obstacle ahead, a cell *closes* or *splits*) and ``-1``
    along ``-x`` (a cell *opens* or two *merge* behind an obstacle).

    The grid (the robot's memory) only localises the slices: :func:`reeb_decomposition` finds
    where the connectivity of the slice of ``mask`` changes. A split or merge there is a cell
    boundary only if a sensed critical point of the matching side lies on it (within
    ``col_tol`` columns of the slice, its row within ``row_tol`` of the gap between the
    intervals); otherwise the cells on both sides are one cell. So a cell boundary appears
    when, and only when, the robot has sensed the critical point, and a jagged sonar wall
    (which makes grid splits that no ring ever reports) does not cut a cell. Births and deaths
    are matched the same way (their row along the interval that opens or closes) to name the
    cell's opening and closing points in the Reeb graph; they cut nothing.

    A wall parallel to the slice is a segment of degenerate critical points (the ring reports
    it all along the wall), and the grid's ragged copy of it has notches that look like
    splits: a split/merge whose gap closes within ``min_span`` columns is such a notch and
    never cuts (:func:`_gap_persists`).
    """
    labels, points, _ = reeb_decomposition(mask)
    parent = {}

    def find(a):
        parent.setdefault(a, a)
        while parent[a] != a:
            parent[a] = parent[parent[a]]
            a = parent[a]
        return a

    def match(p, side):
        best, best_d = -1, math.inf
        for k, (r, c, s) in enumerate(sensed):
            if s != side or abs(c - p.col) > col_tol:
                continue
            lo, hi = (p.lo, p.hi) if math.isfinite(p.lo) else (p.row, p.row)
            off = max(lo - r, r - hi, 0.0)
            if off <= row_tol and abs(c - p.col) + off < best_d:
                best, best_d = k, abs(c - p.col) + off
        return best

    confirmed, ignored, ends = [], [], []
    for p in points:
        side = +1 if p.kind in ('split', 'death') else -1
        k = match(p, side)
        if p.kind in ('split', 'merge'):
            if k < 0 or not _gap_persists(mask, p, min_span):
                ignored.append(p)
                cells = [find(c) for c in p.cells_before + p.cells_after]
                for c in cells[1:]:
                    parent[find(c)] = find(cells[0])
                continue
            confirmed.append((p, k))
        ends.append((p, k))
    n = int(labels.max())
    roots = sorted({find(c) for c in range(1, n + 1)})
    renum = {r: i + 1 for i, r in enumerate(roots)}
    lut = np.zeros(n + 1, dtype=np.int32)
    for c in range(1, n + 1):
        lut[c] = renum[find(c)]
    merged = lut[labels]
    opened, closed = {}, {}
    for p, k in ends:
        for c in p.cells_after:
            opened.setdefault(int(lut[c]), set()).add(k)
        for c in p.cells_before:
            closed.setdefault(int(lut[c]), set()).add(k)
    edges = []
    for cell in range(1, len(roots) + 1):
        a = sorted(opened.get(cell, {-1}))
        b = sorted(closed.get(cell, {-1}))
        a = [i for i in a if i >= 0] or [-1]
        b = [i for i in b if i >= 0] or [-1]
        edges.append((a[0], b[0], cell))
    return MorseCells(merged, edges, confirmed, ignored)


def cell_boundaries(labels: np.ndarray) -> np.ndarray:
    """Cells where the slice direction (x) passes from one Morse cell to another: the slices
    through the sensed critical points, for pictures and markers."""
    out = np.zeros(labels.shape, dtype=bool)
    out[:, 1:] = (labels[:, 1:] != labels[:, :-1]) & (labels[:, 1:] > 0) & (labels[:, :-1] > 0)
    return out


def lap_columns(nx: int, origin_x: float, resolution: float, x_ref: float,
                spacing: float) -> np.ndarray:
    """Boolean per grid column: True on the lapping slices ``x = x_ref + k * spacing``.

    The slices are ``2 * delta`` apart so that the detector disks swept along two neighbouring
    slices just meet (Section IV-A).
    """
    xs = origin_x + (np.arange(nx) + 0.5) * resolution
    off = xs - x_ref
    d = off - np.round(off / spacing) * spacing          # signed distance to the nearest slice
    # exactly one column per slice: the half-open window [-res/2, res/2), robust to rounding
    return (d >= -0.5 * resolution - 1e-9) & (d < 0.5 * resolution - 1e-9)


def boundary_cells(region: np.ndarray) -> np.ndarray:
    """Cells of ``region`` with a 4-neighbour outside it: the curve followed by boundary
    following (for the vast region, the contour ``D = delta``)."""
    p = np.pad(region, 1, constant_values=False)
    inner = p[1:-1, 1:-1] & p[:-2, 1:-1] & p[2:, 1:-1] & p[1:-1, :-2] & p[1:-1, 2:]
    return region & ~inner
