"""Generalized Voronoi diagram (GVD): from the sonar ring and from the sensed grid.

Section III of Acar, Choset and Lee: a GVD edge is the set of points equidistant to two
obstacles, ``{x : d_i(x) = d_j(x) <= d_h(x) for all h, grad d_i(x) != grad d_j(x)}``; *meet
points* are where three or more obstacles are equidistant. Following every GVD edge passes an
infinite-range detector over the whole free space, and (Lemma 1) following the GVD inside the
narrow region ``NR = {r < D(x) <= delta}`` passes a delta-range detector over it.

Two views of the same object are provided:

* **From range data** (the sensor-based construction of Choset and Burdick [11]): the closest
  obstacles are the local minima of the range ring; the robot is on the GVD when the two
  smallest minima are equal, at a meet point when three are, and it detects a *cusp point*
  while tracing a narrow GVD edge when the minimum distance rises above delta (Fig. 11).
* **From the sensed evidence grid**: ``D`` is the Euclidean distance transform to the sensed
  obstacles and a cell is on the GVD when it and a neighbour have nearest obstacle points in
  clearly different directions (the discrete form of ``grad d_i != grad d_j``), which is how
  the planner builds the narrow subgraphs of the hierarchical decomposition.
"""
from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from numpy.typing import ArrayLike
from scipy import ndimage
from scipy.signal import find_peaks

# ------------------------------------------------------------------ range-ring (sensor) view


def ring_minima(ranges: ArrayLike, angles: ArrayLike,
                min_separation: float = math.radians(30.0)) -> list[tuple[float, float]]:
    """Closest obstacles seen by a range ring: local minima of range over bearing.

    ``ranges`` may hold REP 117 values; only finite ones count. Returns a list of
    ``(range, angle)`` sorted by range. Minima closer in bearing than ``min_separation`` are the
    same obstacle (a flat wall gives one minimum), so only the nearer one is kept.
    """
    r = np.asarray(ranges, dtype=float)
    a = np.asarray(angles, dtype=float)
    n = len(r)
    rr = np.where(np.isfinite(r) & (r > 0), r, np.inf)
    mins = []
    for k in range(n):
        if not np.isfinite(rr[k]):
            continue
        if rr[k] <= rr[(k - 1) % n] and rr[k] <= rr[(k + 1) % n]:
            mins.append((float(rr[k]), float(a[k])))
    mins.sort()
    kept = []
    for d, ang in mins:
        if all(abs(math.remainder(ang - b, 2 * math.pi)) >= min_separation for _, b in kept):
            kept.append((d, ang))
    return kept


def one_surface(ranges: ArrayLike, angles: ArrayLike, m1: tuple[float, float],
                m2: tuple[float, float], tol: float = 0.03) -> bool:
    """The closest echoes ``m1`` and ``m2`` (range, bearing) are one obstacle's surface.

    A GVD edge is equidistant to two obstacles whose distance gradients differ (Section
    III). Between two closest obstacles the range over bearing rises to a maximum: a gap
    between them, or a concave corner where two walls meet (whose bisector is a GVD edge).
    Along one flat or convex surface the distance to its points has no interior maximum,
    so two minima with no echo between them (the shorter way round) farther than the
    farther of the two (plus ``tol``, the ring's noise) are one minimum seen through
    several cones: a flat stretch of equal echoes, or two faces of a convex corner (a door
    jamb). False when no echo lies between the two bearings or they are more than 150
    degrees apart (the robot then stands between the two)."""
    (d1, a1), (d2, a2) = m1, m2
    span = math.remainder(a2 - a1, 2 * math.pi)
    if abs(span) > math.radians(150.0):
        return False
    top, found = max(d1, d2) + tol, False
    for rk, ak in zip(np.asarray(ranges, dtype=float).tolist(),
                      np.asarray(angles, dtype=float).tolist()):
        rel = (ak - a1) % (2 * math.pi) if span > 0 else (a1 - ak) % (2 * math.pi)
        if 1e-6 < rel < abs(span) - 1e-6:
            if not rk <= top:                    # farther, or no echo (nan, inf)
                return False
            found = True
    return found


def distinct_minima(ranges: ArrayLike, angles: ArrayLike, tol: float = 0.03,
                    min_separation: float = math.radians(30.0)) -> list[tuple[float, float]]:
    """The closest distinct obstacles seen by a range ring, ``(range, bearing)`` nearest first.

    Like :func:`ring_minima`, but a minimum is the whole run of neighbouring cones within
    ``tol`` (the ring's noise) of it, placed at the run's middle bearing: a flat stretch of
    equal echoes is one wall seen through several cones, its foot at their middle, not at
    the run's first cone. Minima closer than ``min_separation`` are one, and a minimum on
    one surface with a nearer kept one (:func:`one_surface`) is dropped."""
    r = np.asarray(ranges, dtype=float)
    a = np.asarray(angles, dtype=float)
    order = np.argsort(np.remainder(a, 2 * math.pi))
    rs = [v if v > 0 and math.isfinite(v) else math.inf for v in r[order].tolist()]
    as_ = a[order].tolist()
    n = len(rs)
    mins = []
    for k in range(n):
        if not math.isfinite(rs[k]) or rs[k] > rs[k - 1] or rs[k] > rs[(k + 1) % n]:
            continue
        lo = hi = 0
        while lo < n - 1 and rs[(k - lo - 1) % n] <= rs[k] + tol:
            lo += 1
        while hi < n - 1 - lo and rs[(k + hi + 1) % n] <= rs[k] + tol:
            hi += 1
        first = as_[(k - lo) % n]
        span = (as_[(k + hi) % n] - first) % (2 * math.pi)
        mins.append((rs[k], math.remainder(first + span / 2, 2 * math.pi)))
    mins.sort()
    kept = []
    for m in mins:
        if all(abs(math.remainder(m[1] - k[1], 2 * math.pi)) >= min_separation and
               not one_surface(rs, as_, k, m) for k in kept):
            kept.append(m)
    return kept


def cusp_from_ring(xy: Sequence[float], ranges: ArrayLike, angles: ArrayLike, delta: float,
                   min_angle: float = math.radians(30.0), max_shift: float = 0.5,
                   other_tol: float = 0.1) -> tuple[float, float] | None:
    """The cusp point near ``xy`` from one ring sweep: the point where the two closest
    obstacles are both at ``delta`` (on the GVD, D = delta), with the obstacles locally flat.

    With the closest echoes d1, d2 along unit bearings n1, n2, moving by s changes them by
    -n_i . s, so s solves n1 . s = d1 - delta, n2 . s = d2 - delta. Returns None where that is
    ill-posed (bearings within ``min_angle`` of parallel or opposite), the shift exceeds
    ``max_shift`` (then the two echoes are not the two sides of one cusp), or a third echo
    would be nearer than ``delta - other_tol`` at the point."""
    mins = ring_minima(ranges, angles)
    if len(mins) < 2:
        return None
    (d1, a1), (d2, a2) = mins[:2]
    sep = abs(math.remainder(a1 - a2, 2 * math.pi))
    if sep < min_angle or sep > math.pi - min_angle:
        return None
    n = np.array([[math.cos(a1), math.sin(a1)], [math.cos(a2), math.sin(a2)]])
    s = np.linalg.solve(n, np.array([d1 - delta, d2 - delta]))
    if not np.all(np.isfinite(s)) or float(np.hypot(*s)) > max_shift:
        return None
    # At a cusp point the two are the closest obstacles: no other echo may come nearer than
    # delta there (less a ring's worth of error), or the point is not on their GVD edge.
    for d, a in mins[2:]:
        if d - (math.cos(a) * s[0] + math.sin(a) * s[1]) < delta - other_tol:
            return None
    return (float(xy[0] + s[0]), float(xy[1] + s[1]))


def meet_from_ring(xy: Sequence[float], ranges: ArrayLike, angles: ArrayLike,
                   max_shift: float = 0.5, max_gap: float | None = math.radians(190.0)
                   ) -> tuple[float, float, float] | None:
    """The meet point near ``xy`` from one ring sweep: the point equidistant to the three
    closest obstacles, or None.

    Same linearisation as :func:`cusp_from_ring`: moving by ``s`` changes the echo along unit
    bearing ``n_i`` by ``-n_i . s``, so the point where the three closest obstacles are all at
    one distance ``rho`` solves ``n_i . s + rho = d_i`` (i = 1, 2, 3). The robot does not
    have to stand on the meet point (a path along a corridor's centre line passes a T
    junction's meet point 0.2 m off it, where the third obstacle is 0.3 m farther than the
    other two). Returns ``(x, y, rho)``; None when the three bearings do not surround the
    point (a gap between bearings wider than ``max_gap``: a half-plane plus the ring's
    bearing quantisation; None: no such test), the system is ill-posed, or the shift
    exceeds ``max_shift``."""
    mins = ring_minima(ranges, angles)
    if len(mins) < 3:
        return None
    three = mins[:3]
    bearings = np.sort([math.remainder(a, 2 * math.pi) for _, a in three])
    gaps = np.diff(np.r_[bearings, bearings[0] + 2 * math.pi])
    if max_gap is not None and gaps.max() > max_gap:
        return None
    a = np.array([[math.cos(b), math.sin(b), 1.0] for _, b in three])
    if np.linalg.cond(a) > 50.0:
        return None
    s = np.linalg.solve(a, np.array([d for d, _ in three]))
    if not np.all(np.isfinite(s)) or s[2] <= 0 or float(np.hypot(s[0], s[1])) > max_shift:
        return None
    return (float(xy[0] + s[0]), float(xy[1] + s[1]), float(s[2]))


def range_peaks(angles: ArrayLike, ranges: ArrayLike, beyond: float, prominence: float
                ) -> tuple[np.ndarray, np.ndarray, np.ndarray, list[tuple[float, float, float]]]:
    """Openings of a scan (bearings in any order, possibly from several sweeps): the peaks of
    the range over bearing reaching beyond ``beyond`` and standing out by at least
    ``prominence`` from the dips on either side, each as the bearings (lo, hi) bounding its
    upper half (above the greater of ``beyond`` and half its prominence below its top) and
    its top's bearing. lo may lie below 0 and hi above 2 pi (the scan wraps round). Also
    returns the sorting order and the scan sorted by bearing in [0, 2 pi) (non-finite
    ranges as 0): (order, bearings, ranges, peaks)."""
    ang = np.remainder(np.asarray(angles, dtype=float), 2 * math.pi)
    r = np.asarray(ranges, dtype=float)
    r = np.where(np.isfinite(r), r, 0.0)
    order = np.argsort(ang, kind='stable')
    ang, r = ang[order], r[order]
    k = len(r)
    if k < 3 or not (r > beyond).any():
        return order, ang, r, []
    r3 = np.concatenate([r, r, r])
    a3 = np.concatenate([ang - 2 * math.pi, ang, ang + 2 * math.pi])
    peaks, props = find_peaks(r3, prominence=prominence)
    out = []
    for p, prom in zip(peaks, props['prominences']):
        if not k <= p < 2 * k or r3[p] <= beyond:
            continue
        level = max(beyond, r3[p] - prom / 2)
        i = j = p
        while i > p - k + 1 and r3[i - 1] > level:
            i -= 1
        while j < p + k - 1 and r3[j + 1] > level:
            j += 1
        out.append((float(a3[i]), float(a3[j]), float(a3[p])))
    return order, ang, r, out


def gvd_order(ranges: ArrayLike, angles: ArrayLike, tol: float,
              min_separation: float = math.radians(30.0)) -> int:
    """How many obstacles are equidistant (within ``tol``) and closest: the GVD order.

    1 means the robot is not on the GVD, 2 on a GVD edge, 3 or more at a meet point.
    """
    mins = ring_minima(ranges, angles, min_separation)
    if not mins:
        return 0
    d0 = mins[0][0]
    return sum(1 for d, _ in mins if d - d0 <= tol)


def narrow_cusp_crossed(previous_min_distance: float, min_distance: float,
                        delta: float) -> bool:
    """Cusp test while tracing a narrow GVD edge (Fig. 11).

    In a narrow cell the minimum distance to the obstacles stays at most delta; the robot has
    crossed a cusp point into a vast cell when it rises above delta.
    """
    return previous_min_distance <= delta < min_distance


# ------------------------------------------------------------------ grid view


def distance_transform(obstacle: np.ndarray,
                       resolution: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Distance D (m) from every cell centre to the nearest obstacle cell, and that cell.

    Returns ``(D, rows, cols)``; ``rows[i, j], cols[i, j]`` index the nearest obstacle cell.
    D is measured from the cell centre to the near edge of that obstacle cell (centre distance
    minus half a cell), so a wall anywhere inside the obstacle cell is never closer than D
    by more than half a cell.
    """
    dist, (rows, cols) = ndimage.distance_transform_edt(~obstacle, return_indices=True)
    d = np.maximum(dist - 0.5, 0.0) * resolution
    return d, rows, cols


def gvd_cells(free: np.ndarray, rows: np.ndarray, cols: np.ndarray,
              min_angle: float = math.radians(50.0),
              min_distance_cells: float = 1.5) -> np.ndarray:
    """Cells of the discrete GVD of the free cells ``free``.

    A free cell is on the GVD if, for one of its 4-neighbours, the nearest obstacle points of
    the two cells are seen from the cell at an angle of at least ``min_angle`` (the two
    closest obstacles have different gradients, ``grad d_i != grad d_j``) and lie more than
    ``min_distance_cells`` apart. The angle test prunes the spurs that sonar-noisy walls would
    otherwise grow; a right-angle corner (bisector angle 90 degrees) is kept.
    """
    ny, nx = free.shape
    ii, jj = np.mgrid[0:ny, 0:nx]
    vr = (rows - ii).astype(float)
    vc = (cols - jj).astype(float)
    out = np.zeros_like(free)
    cos_min = math.cos(min_angle)
    for di, dj in ((0, 1), (1, 0)):
        a = (slice(0, ny - di), slice(0, nx - dj))
        b = (slice(di, ny), slice(dj, nx))
        fr_a, fc_a = rows[a], cols[a]
        fr_b, fc_b = rows[b], cols[b]
        sep = np.hypot(fr_a - fr_b, fc_a - fc_b) > min_distance_cells
        # angle seen from cell a between its own feature and the neighbour's feature
        v1r, v1c = vr[a], vc[a]
        v2r, v2c = (fr_b - ii[a]).astype(float), (fc_b - jj[a]).astype(float)
        n1 = np.hypot(v1r, v1c)
        n2 = np.hypot(v2r, v2c)
        with np.errstate(invalid='ignore', divide='ignore'):
            cosang = (v1r * v2r + v1c * v2c) / (n1 * n2)
        hit = sep & (cosang <= cos_min) & free[a] & free[b]
        out[a] |= hit
        out[b] |= hit
    return out & free


def prune_small(mask: np.ndarray, min_cells: int) -> np.ndarray:
    """Drop the 8-connected pieces of ``mask`` with fewer than ``min_cells`` cells."""
    lab, n = ndimage.label(mask, structure=np.ones((3, 3)))
    if n == 0:
        return mask
    size = np.bincount(lab.ravel())
    keep = size >= min_cells
    keep[0] = False
    return keep[lab]


def _clusters(mask, min_cells=1):
    """Centroids (row, col) of the 8-connected clusters of ``mask``."""
    lab, n = ndimage.label(mask, structure=np.ones((3, 3)))
    if n == 0:
        return []
    idx = np.arange(1, n + 1)
    cen = ndimage.center_of_mass(mask, lab, idx)
    size = ndimage.sum(mask, lab, idx)
    return [(float(r), float(c)) for (r, c), s in zip(cen, size) if s >= min_cells]


def meet_points(gvd: np.ndarray, radius_cells: int = 5) -> list[tuple[float, float]]:
    """Meet points of a discrete GVD: where three or more GVD edges come together.

    For every GVD cell the GVD is sampled on a circle of ``radius_cells`` around it; a cell
    whose circle crosses the GVD in three or more separate arcs (of at least two samples) is
    next to a meet point
    (two arcs: inside an edge; one: near the end of an edge). Returns ``(row, col)``
    centroids of the clusters of such cells. Works on GVD bands one or two cells thick.
    """
    rows, cols = np.nonzero(gvd)
    if len(rows) == 0:
        return []
    ny, nx = gvd.shape
    n = max(16, int(round(2 * math.pi * radius_cells * 1.5)))
    th = np.linspace(0.0, 2 * math.pi, n, endpoint=False)
    dr = np.rint(radius_cells * np.sin(th)).astype(int)
    dc = np.rint(radius_cells * np.cos(th)).astype(int)
    rr = np.clip(rows[:, None] + dr[None, :], 0, ny - 1)
    cc = np.clip(cols[:, None] + dc[None, :], 0, nx - 1)
    ring = gvd[rr, cc]
    # Arcs at least two samples long: a one-sample touch is a sensing burr on an edge.
    starts = (ring & np.roll(ring, -1, axis=1) & ~np.roll(ring, 1, axis=1)).sum(axis=1)
    branch = np.zeros_like(gvd)
    branch[rows[starts >= 3], cols[starts >= 3]] = True
    return _clusters(branch)


def cusp_cells(gvd: np.ndarray, distance: np.ndarray,
               delta: float) -> list[tuple[float, float]]:
    """Cusp points: GVD cells where D crosses delta (Section IV-B, ``D(x) = delta``).

    A GVD cell with ``D > delta`` that touches a GVD cell with ``D <= delta`` (8-neighbours)
    marks the boundary between the GVD of a vast cell and that of a narrow cell (Lemma 2).
    Returns ``(row, col)`` centroids of such clusters.
    """
    vast_gvd = gvd & (distance > delta)
    narrow_gvd = gvd & (distance <= delta)
    near_narrow = ndimage.binary_dilation(narrow_gvd, structure=np.ones((3, 3)))
    near_vast = ndimage.binary_dilation(vast_gvd, structure=np.ones((3, 3)))
    return _clusters((vast_gvd & near_narrow) | (narrow_gvd & near_vast))
