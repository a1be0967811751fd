"""The planner's memory of the world: a growable log-odds evidence grid built from sonar.

Algorithm 1 of Acar, Choset and Lee constructs the hierarchical decomposition *incrementally*
from sensor data. Our planner keeps the accumulated range data as an occupancy evidence grid in
the ``odom`` frame (the world is unknown, so the grid grows as the robot senses new space) and
a *trace* layer marking where the robot centre has been, which is how the planner knows which
lapping lines, boundary pieces and GVD edges it has already followed, and a *viewed* layer,
the detector's footprint (range delta, line of sight through known free cells), which tells
which boundary and GVD pieces still have something to show.
"""
from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike
from scipy import ndimage

L_FREE = -0.4       # log-odds added by a free observation
L_OCC = 0.9         # log-odds added by an echo arc
L_MIN, L_MAX = -4.0, 4.0
T_FREE = -0.6       # below: known free
T_OCC = 0.6         # above: known occupied


class EvidenceGrid:
    """Log-odds occupancy grid plus a trace layer, growing in 4 m chunks as needed.

    Cell (i, j) is row i (y) and column j (x); its centre is
    ``origin + (j + 0.5, i + 0.5) * resolution``.
    """

    CHUNK = 4.0

    def __init__(self, resolution: float = 0.1, center: tuple[float, float] = (0.0, 0.0),
                 half_size: float = 6.0) -> None:
        self.res = float(resolution)
        n = int(math.ceil(2 * half_size / self.res))
        self.origin = np.array([center[0] - half_size, center[1] - half_size], dtype=float)
        self.logodds = np.zeros((n, n), dtype=np.float32)
        self.trace = np.zeros((n, n), dtype=bool)
        self.visited = np.zeros((n, n), dtype=bool)   # held the robot centre
        self.seen = np.zeros((n, n), dtype=bool)      # ever observed (free or occupied)
        self.viewed = np.zeros((n, n), dtype=bool)    # passed under the detector (range delta)
        self.version = 0                              # bumped when the grid changes shape

    @property
    def shape(self) -> tuple[int, int]:
        return self.logodds.shape

    def ensure(self, xmin: float, ymin: float, xmax: float, ymax: float) -> None:
        """Grow the grid so that the given box lies inside it."""
        ny, nx = self.shape
        x1, y1 = self.origin + np.array([nx, ny]) * self.res
        pad = [0, 0, 0, 0]                                # left, bottom, right, top (cells)
        step = int(math.ceil(self.CHUNK / self.res))
        if xmin < self.origin[0]:
            pad[0] = step * int(math.ceil((self.origin[0] - xmin) / self.CHUNK))
        if ymin < self.origin[1]:
            pad[1] = step * int(math.ceil((self.origin[1] - ymin) / self.CHUNK))
        if xmax > x1:
            pad[2] = step * int(math.ceil((xmax - x1) / self.CHUNK))
        if ymax > y1:
            pad[3] = step * int(math.ceil((ymax - y1) / self.CHUNK))
        if not any(pad):
            return
        widths = ((pad[1], pad[3]), (pad[0], pad[2]))
        self.logodds = np.pad(self.logodds, widths)
        self.trace = np.pad(self.trace, widths)
        self.visited = np.pad(self.visited, widths)
        self.seen = np.pad(self.seen, widths)
        self.viewed = np.pad(self.viewed, widths)
        self.origin = self.origin - np.array([pad[0], pad[1]]) * self.res
        self.version += 1

    def cells(self, xy: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
        """(rows, cols) integer indices of points ``xy`` (n, 2)."""
        ij = np.floor((np.asarray(xy) - self.origin) / self.res).astype(np.int64)
        return ij[:, 1], ij[:, 0]

    def center(self, rows: ArrayLike, cols: ArrayLike) -> np.ndarray:
        """World (x, y) of cell centres."""
        return np.stack([self.origin[0] + (np.asarray(cols) + 0.5) * self.res,
                         self.origin[1] + (np.asarray(rows) + 0.5) * self.res], axis=-1)

    def integrate(self, free_xy: ArrayLike, occ_xy: ArrayLike,
                  edge_xy: ArrayLike | None = None) -> None:
        """Add one sweep's evidence; a cell counts once per sweep, echoes win over free.

        ``edge_xy`` are the outer parts of the echo arcs (see
        :func:`coverage_pkg.sonar.sweep_evidence`). The obstacle that returned an echo lies
        somewhere on its arc, so an arc cell that other readings show free (known free after
        this sweep's free evidence) cannot be it; the other edge cells get the echo's
        evidence. This is how a wall seen only at grazing angles, whose echo comes from the
        edge of the cone, enters the map; the arc's middle, in front of such a wall, is
        cleared by the readings that pass through it."""
        pts = [p for p in (free_xy, occ_xy) if len(p)]
        if not pts:
            return
        allp = np.vstack(pts)
        lo, hi = allp.min(axis=0), allp.max(axis=0)
        self.ensure(lo[0] - 1.0, lo[1] - 1.0, hi[0] + 1.0, hi[1] + 1.0)
        nx = self.shape[1]
        flat = self.logodds.reshape(-1)
        seen = self.seen.reshape(-1)
        # Fancy-index updates apply once per distinct cell even with repeated indices, so one
        # sweep adds at most one observation per cell; echo cells keep their echo update.
        occ = np.zeros(0, dtype=np.int64)
        if len(occ_xy):
            r, c = self.cells(occ_xy)
            occ = r * nx + c
        before = flat[occ]
        if len(free_xy):
            r, c = self.cells(free_xy)
            free = r * nx + c
            flat[free] = np.maximum(flat[free] + L_FREE, L_MIN)
            seen[free] = True
        if len(occ):
            flat[occ] = np.minimum(before + L_OCC, L_MAX)
            seen[occ] = True
        if edge_xy is not None and len(edge_xy):
            r, c = self.cells(edge_xy)
            ok = (r >= 0) & (c >= 0) & (r < self.shape[0]) & (c < nx)
            edge = np.setdiff1d(r[ok] * nx + c[ok], occ)
            edge = edge[flat[edge] >= T_FREE]
            flat[edge] = np.minimum(flat[edge] + L_OCC, L_MAX)
            seen[edge] = True

    def mark_trace(self, x: float, y: float, radius: float) -> None:
        """Mark the cells within ``radius`` of the robot centre as traced, and the cell of
        the centre itself as visited."""
        self.ensure(x - radius - 1, y - radius - 1, x + radius + 1, y + radius + 1)
        k = int(math.ceil(radius / self.res))
        r0, c0 = self.cells(np.array([[x, y]]))
        self.visited[r0[0], c0[0]] = True
        rr, cc = np.mgrid[-k:k + 1, -k:k + 1]
        cen = self.center(r0[0] + rr, c0[0] + cc)
        inside = np.hypot(cen[..., 0] - x, cen[..., 1] - y) <= radius
        self.trace[(r0[0] + rr)[inside], (c0[0] + cc)[inside]] = True

    def mark_viewed(self, x: float, y: float, radius: float) -> None:
        """Mark the cells the detector of range ``radius`` sees from (x, y): along rays through
        known free cells, up to and including the first cell that is not known free. Only
        free cells sampled within ``radius - res`` count, so a cell marked viewed is within
        range as a whole even where the grid misplaces a wall by a cell (the grid must not
        claim more than the detector saw). The first cell that is not free (the wall, where
        the echo put it) counts if its centre is within ``radius - res / 2``: the wall surface
        the detector must reach lies in that cell, at most half a cell beyond its centre."""
        self.ensure(x - radius - 1, y - radius - 1, x + radius + 1, y + radius + 1)
        reach = radius - self.res
        wall_reach = radius - 0.5 * self.res
        n = max(32, int(math.ceil(2 * math.pi * reach / (0.5 * self.res))))
        th = np.linspace(0.0, 2 * math.pi, n, endpoint=False)
        steps = np.arange(0.0, wall_reach, 0.5 * self.res)
        px = x + np.cos(th)[:, None] * steps[None, :]
        py = y + np.sin(th)[:, None] * steps[None, :]
        rows, cols = self.cells(np.stack([px.ravel(), py.ravel()], axis=1))
        rows, cols = rows.reshape(px.shape), cols.reshape(px.shape)
        opaque = ~(self.logodds[rows, cols] < T_FREE)
        opaque[:, 0] = False                               # the robot's own cell
        before = np.cumsum(opaque, axis=1) - opaque        # opaque cells before this sample
        vis = (before == 0) & (steps[None, :] < reach)
        self.viewed[rows[vis], cols[vis]] = True
        first = opaque & (before == 0)
        wr, wc = rows[first], cols[first]
        cen = self.center(wr, wc)
        near = np.hypot(cen[:, 0] - x, cen[:, 1] - y) <= wall_reach
        self.viewed[wr[near], wc[near]] = True

    def rejudge_viewed(self, poses: ArrayLike, radius: float, rows: np.ndarray, cols: np.ndarray,
                       k: int = 12) -> int:
        """Mark viewed the candidate cells ``rows, cols`` (not yet viewed) that one
        of the past detector ``poses`` (n, 2) sees on **today's** map: centre within
        ``radius - res`` and every sample of the segment on known free cells.

        :meth:`mark_viewed` judges a ray on the map of the moment it was cast; a cell the
        sonar cleared only later (a gap between cones, a grazing wall) stays unviewed although
        the detector had a clear line to it. The world is static, so a segment through cells
        known free now was free then. Returns the number of cells marked."""
        if len(poses) == 0 or len(rows) == 0:
            return 0
        from scipy.spatial import cKDTree
        reach = radius - self.res
        cen = self.center(rows, cols)
        dist, idx = cKDTree(poses).query(cen, k=min(k, len(poses)), distance_upper_bound=reach)
        dist = dist.reshape(len(cen), -1)
        idx = idx.reshape(len(cen), -1)
        ci, pj = np.nonzero(np.isfinite(dist))
        if len(ci) == 0:
            return 0
        a = np.asarray(poses, dtype=float)[idx[ci, pj]]
        b = cen[ci]
        n = int(math.ceil(reach / (0.5 * self.res))) + 1
        t = np.linspace(0.0, 1.0, n)
        px = a[:, 0, None] + (b[:, 0] - a[:, 0])[:, None] * t[None, :]
        py = a[:, 1, None] + (b[:, 1] - a[:, 1])[:, None] * t[None, :]
        r, c = self.cells(np.stack([px.ravel(), py.ravel()], axis=1))
        # Every sample on known free cells, except in the candidate cell itself (a wall cell
        # next to free space is a candidate too: the wall surface lies in it).
        own = (r.reshape(px.shape) == rows[ci][:, None]) & \
            (c.reshape(px.shape) == cols[ci][:, None])
        clear = ((self.logodds[r, c] < T_FREE).reshape(px.shape) | own).all(axis=1)
        hit = np.unique(ci[clear])
        self.viewed[rows[hit], cols[hit]] = True
        return int(len(hit))

    def occupied(self) -> np.ndarray:
        return self.logodds > T_OCC

    def free(self) -> np.ndarray:
        return self.logodds < T_FREE

    def known_bbox(self, margin_cells: int = 3) -> tuple[slice, slice]:
        """Row/column slice of the part of the grid that has been observed (plus a margin)."""
        rows = np.flatnonzero(self.seen.any(axis=1))
        cols = np.flatnonzero(self.seen.any(axis=0))
        if len(rows) == 0:
            return slice(0, self.shape[0]), slice(0, self.shape[1])
        ny, nx = self.shape
        return (slice(max(rows[0] - margin_cells, 0), min(rows[-1] + margin_cells + 1, ny)),
                slice(max(cols[0] - margin_cells, 0), min(cols[-1] + margin_cells + 1, nx)))


def drop_speckles(unseen: np.ndarray, frontier: np.ndarray, resolution: float, min_area: float,
                  budget: float = np.inf) -> np.ndarray:
    """``unseen`` without its speckles: 8-connected pockets smaller than ``min_area`` (m^2)
    that do not come within two cells of the ``frontier``, smallest first, as long as their
    total area stays within ``budget`` (m^2).

    A small pocket of known free cells that the detector has not seen, away from the frontier,
    is most often a sensing artefact (a wall mapped a cell off, a gap between two cones), and
    otherwise a sliver (a corner just out of range); neither is worth a trip across the world.
    A place not yet seen is a large patch of free space or lies where the map still grows, at
    the frontier, and is always kept. The budget bounds what the planner knowingly leaves
    unseen. ``min_area <= 0`` keeps everything."""
    if min_area <= 0 or not unseen.any():
        return unseen
    lab, n = ndimage.label(unseen, structure=np.ones((3, 3)))
    idx = np.arange(1, n + 1)
    size = ndimage.sum(unseen, lab, idx) * resolution ** 2
    keep = (size >= min_area) | (
        ndimage.maximum(ndimage.binary_dilation(frontier, iterations=2), lab, idx) > 0)
    cand = np.flatnonzero(~keep)
    cand = cand[np.argsort(size[cand], kind='stable')]
    over = np.cumsum(size[cand]) > budget
    keep[cand[over]] = True
    return np.r_[False, keep][lab]
