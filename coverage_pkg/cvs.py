"""Coverable set CVS (Section VI) and covered-fraction accounting (evaluation only).

Section VI of Acar, Choset and Lee: with ``B^V_delta(x)`` the points of the disk of radius
delta around ``x`` that ``x`` can see (the segment between them lies in the free workspace),

    CVS = ( union over x in FCS_r of B^V_delta(x) ) intersected with FWS

is everything *any* planner could cover; a planner is complete if the union of
``B^V_delta(p(t))`` along its path equals CVS. We take FCS_r as the component of
``{D > r}`` that contains the start (the paper assumes FCS_r connected).

Computed on a grid: cells of FCS_r are in CVS trivially; for every other free cell within delta
of FCS_r we look for a configuration that sees it. It is enough to test configurations on the
boundary of FCS_r: if an interior configuration x sees p outside FCS_r, the segment from x to
p leaves FCS_r at a boundary point that is closer to p and sees it too.

This module reads the true world; only the monitor and the scenario use it, never the planner.
"""
from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike
from scipy import ndimage
from scipy.spatial import cKDTree

from coverage_pkg.world import World, rasterize, raycast_segments


def segments_clear(p: ArrayLike, q: ArrayLike, walls: np.ndarray) -> np.ndarray:
    """True where the segment p[i]-q[i] crosses no wall segment (rows x1, y1, x2, y2)."""
    p = np.asarray(p, float)
    q = np.asarray(q, float)
    out = np.ones(len(p), dtype=bool)
    a, b = walls[:, :2], walls[:, 2:]
    for k in range(0, len(p), 4096):
        pp, qq = p[k:k + 4096, None, :], q[k:k + 4096, None, :]
        d1 = qq - pp
        d2 = b - a

        def cross(u, v):
            return u[..., 0] * v[..., 1] - u[..., 1] * v[..., 0]
        den = cross(d1, d2)
        ap = a - pp
        with np.errstate(divide='ignore', invalid='ignore'):
            t = cross(ap, d2) / den
            u = cross(ap, d1) / den
        hit = (np.abs(den) > 1e-12) & (t > 1e-9) & (t < 1 - 1e-9) & (u >= 0) & (u <= 1)
        out[k:k + 4096] = ~hit.any(axis=1)
    return out


def cell_clearance(world: World, free: np.ndarray, origin: ArrayLike,
                   resolution: float) -> np.ndarray:
    """Exact distance from every free cell centre to the nearest wall (0 elsewhere)."""
    import shapely
    ny, nx = free.shape
    rr, cc = np.nonzero(free)
    xs = origin[0] + (cc + 0.5) * resolution
    ys = origin[1] + (rr + 0.5) * resolution
    d = np.zeros(free.shape)
    d[rr, cc] = shapely.distance(shapely.points(xs, ys), world.free.boundary)
    return d


class CoverableSet:
    """CVS of a world for a disk robot of radius r and a detector of range delta, on a grid."""

    def __init__(self, world: World, radius: float, delta: float,
                 resolution: float = 0.05) -> None:
        self.world = world
        self.radius = float(radius)
        self.delta = float(delta)
        self.res = float(resolution)
        self.free, self.origin = rasterize(world, resolution, margin=resolution)
        self.clearance = cell_clearance(world, self.free, self.origin, self.res)
        fcs = self.free & (self.clearance > self.radius)
        lab, _ = ndimage.label(fcs)
        sr, sc = self.cell_of(world.start)
        self.fcs = lab == lab[sr, sc] if lab[sr, sc] else fcs
        self.mask = self._compute()

    def cell_of(self, xy: ArrayLike) -> tuple[int, int]:
        c = int(math.floor((xy[0] - self.origin[0]) / self.res))
        r = int(math.floor((xy[1] - self.origin[1]) / self.res))
        return r, c

    def centers(self, rows: ArrayLike, cols: ArrayLike) -> np.ndarray:
        return np.stack([self.origin[0] + (np.asarray(cols) + 0.5) * self.res,
                         self.origin[1] + (np.asarray(rows) + 0.5) * self.res], axis=-1)

    def _compute(self):
        mask = self.fcs.copy()
        dist_out = ndimage.distance_transform_edt(~self.fcs) * self.res
        cand = self.free & ~self.fcs & (dist_out <= self.delta + self.res)
        inner = ndimage.binary_erosion(self.fcs, structure=np.ones((3, 3)))
        edge = self.fcs & ~inner
        er, ec = np.nonzero(edge)
        if len(er) == 0:
            return mask
        # Boundary configurations: the edge cells of FCS_r pushed onto the exact curve D = r
        # (away from their nearest wall point), so the grid does not shrink FCS_r.
        import shapely
        eq = self.centers(er, ec)
        near = shapely.get_coordinates(shapely.shortest_line(
            shapely.points(eq[:, 0], eq[:, 1]), self.world.free.boundary))[1::2]
        v = eq - near
        vn = np.hypot(v[:, 0], v[:, 1])[:, None]
        eq = np.where(vn > 1e-9, near + v / np.maximum(vn, 1e-9) * self.radius * (1 + 1e-9),
                      eq)
        tree = cKDTree(eq)
        cr, cc = np.nonzero(cand)
        cp = self.centers(cr, cc)
        resolved = np.zeros(len(cp), dtype=bool)
        # First the few nearest boundary configurations (usually enough), then all in range.
        kq = min(6, len(eq))
        dist, idx = tree.query(cp, k=kq)
        dist = dist.reshape(len(cp), -1)
        idx = idx.reshape(len(cp), -1)
        for j in range(dist.shape[1]):
            todo = np.flatnonzero(~resolved & (dist[:, j] <= self.delta))
            if len(todo) == 0:
                continue
            ok = segments_clear(cp[todo], eq[idx[todo, j]], self.world.segments)
            resolved[todo[ok]] = True
        rest = np.flatnonzero(~resolved)
        if len(rest):
            lists = tree.query_ball_point(cp[rest], self.delta)
            pi = np.concatenate([np.full(len(lst), i) for i, lst in zip(rest, lists)]
                                + [np.zeros(0, int)]).astype(int)
            qi = np.concatenate([np.asarray(lst, int) for lst in lists]
                                + [np.zeros(0, int)]).astype(int)
            if len(pi):
                ok = segments_clear(cp[pi], eq[qi], self.world.segments)
                resolved[np.unique(pi[ok])] = True
        mask[cr[resolved], cc[resolved]] = True
        return mask

    @property
    def area(self) -> float:
        """|CVS| in square metres."""
        return float(self.mask.sum()) * self.res ** 2

    def lower_bound_path(self) -> float:
        """Path length lower bound |CVS| / (2 delta): a detector sweeps at most 2 delta wide."""
        return self.area / (2.0 * self.delta)


class CoverageAccumulator:
    """What the detector has seen along the true path: union of B^V_delta(p(t)) on the grid."""

    def __init__(self, cvs: CoverableSet, n_rays: int | None = None) -> None:
        self.cvs = cvs
        self.seen = np.zeros_like(cvs.mask)
        d, res = cvs.delta, cvs.res
        self.n_rays = n_rays or max(360, int(math.ceil(2 * math.pi * d / (0.5 * res))))
        k = int(math.ceil(d / res)) + 1
        rr, cc = np.mgrid[-k:k + 1, -k:k + 1]
        self._k = k
        self._off = (rr, cc)
        self._last = None

    def add_pose(self, x: float, y: float, min_step: float | None = None) -> None:
        """Add the visible detector disk at (x, y); skipped if closer than ``min_step`` to the
        last pose added."""
        if min_step is not None and self._last is not None:
            if math.hypot(x - self._last[0], y - self._last[1]) < min_step:
                return
        self._last = (x, y)
        rows, cols = self.visible(x, y)
        self.seen[rows, cols] = True

    def visible(self, x: float, y: float) -> tuple[np.ndarray, np.ndarray]:
        """Rows and columns of the cells of B^V_delta((x, y)): within delta, line of sight."""
        cvs = self.cvs
        ang = np.linspace(-math.pi, math.pi, self.n_rays, endpoint=False)
        reach = raycast_segments(cvs.world.segments, (x, y), ang, cvs.delta + cvs.res)
        r0, c0 = cvs.cell_of((x, y))
        rr, cc = self._off
        rows, cols = r0 + rr, c0 + cc
        ny, nx = self.seen.shape
        ok = (rows >= 0) & (rows < ny) & (cols >= 0) & (cols < nx)
        cen = cvs.centers(rows, cols)
        dx, dy = cen[..., 0] - x, cen[..., 1] - y
        rho = np.hypot(dx, dy)
        b = np.floor((np.arctan2(dy, dx) + math.pi) / (2 * math.pi) * self.n_rays).astype(int)
        b = np.clip(b, 0, self.n_rays - 1)
        vis = ok & (rho <= cvs.delta) & (rho <= reach[b])
        return rows[vis], cols[vis]

    def fraction(self) -> float:
        """Covered fraction of CVS."""
        n = self.cvs.mask.sum()
        return float((self.seen & self.cvs.mask).sum() / n) if n else 1.0

    def uncovered_points(self) -> np.ndarray:
        """Centres of CVS cells not yet seen (for diagnostics and the picture)."""
        r, c = np.nonzero(self.cvs.mask & ~self.seen)
        return self.cvs.centers(r, c)
