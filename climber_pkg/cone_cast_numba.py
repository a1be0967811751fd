"""Compiled kernels of the ultrasonic cone casts (:func:`climber_pkg.cone_cast.cone_distances`
with ``backend`` numba).

They take the floating-point steps of :meth:`climber_pkg.trunk.Trunk.ray_distance`,
:meth:`~climber_pkg.trunk.Trunk.closest` and the cone test of
:meth:`~climber_pkg.trunk.Trunk.cone_distance` one ray at a time, in numpy's order: a row's
``einsum('ij,ij->i')`` of three products is ``(p0 + p2) + p1``, a row's ``norm`` is
``sqrt((x0^2 + x1^2) + x2^2)``, ``interp`` is numpy's (the slope, then ``slope * (x - xp[j]) +
fp[j]``), and nothing is fused or reordered (no fastmath). The nearest centreline sample of
each closest-point query still comes from the trunk's KD tree, between the kernels; the
distances equal the numpy path bit for bit
(``test/test_climber_graph.py::test_batched_cone_distances_equal_the_trunk_cones``).
Compiled on first use, cached on disk.
"""
import math

import numpy as np
from numba import njit

_KW = {'cache': True, 'nogil': True, 'error_model': 'numpy'}


@njit(**_KW)
def _interp(x, xp, fp):
    """``np.interp(x, xp, fp)`` for one x (the default left/right values)."""
    n = xp.shape[0]
    if x != x:
        return x
    if x < xp[0]:
        return fp[0]
    if x > xp[n - 1]:
        return fp[n - 1]
    j = np.searchsorted(xp, x, side='right') - 1
    if j == n - 1 or xp[j] == x:
        return fp[j]
    slope = (fp[j + 1] - fp[j]) / (xp[j + 1] - xp[j])
    y = slope * (x - xp[j]) + fp[j]
    if y != y:
        y = slope * (x - xp[j + 1]) + fp[j + 1]
        if y != y and fp[j] == fp[j + 1]:
            y = fp[j]
    return y


@njit(**_KW)
def _clip(x, lo, hi):
    """``np.clip`` of one value (NaN stays NaN)."""
    if x < lo:
        return lo
    if x > hi:
        return hi
    return x


@njit(**_KW)
def _axis_frame(s, ts, pts, tans, length):
    """Axis point and unit tangent at arc length ``s`` (``point_at``, ``tangent_at``)."""
    sc = _clip(s, 0.0, length)
    cx = _interp(sc, ts, pts[0])
    cy = _interp(sc, ts, pts[1])
    cz = _interp(sc, ts, pts[2])
    tx = _interp(sc, ts, tans[0])
    ty = _interp(sc, ts, tans[1])
    tz = _interp(sc, ts, tans[2])
    norm = math.sqrt((tx * tx + ty * ty) + tz * tz)
    return cx, cy, cz, tx / norm, ty / norm, tz / norm


@njit(**_KW)
def closest_refine(q: np.ndarray, idx: np.ndarray, ts: np.ndarray, pts: np.ndarray,
                   s_out: np.ndarray, d_out: np.ndarray) -> None:
    """``Trunk.closest`` of the points ``q`` (m, 3) from their nearest samples ``idx``."""
    n = ts.shape[0]
    px, py, pz = pts[0], pts[1], pts[2]
    for i in range(q.shape[0]):
        k = idx[i]
        x, y, z = q[i, 0], q[i, 1], q[i, 2]
        dx, dy, dz = x - px[k], y - py[k], z - pz[k]
        best_d = math.sqrt((dx * dx + dy * dy) + dz * dz)
        best_s = ts[k]
        for off in (-1, 0):
            i0 = min(max(k + off, 0), n - 2)
            ax, ay, az = px[i0], py[i0], pz[i0]
            bx, by, bz = px[i0 + 1] - ax, py[i0 + 1] - ay, pz[i0 + 1] - az
            ux, uy, uz = x - ax, y - ay, z - az
            t = _clip(((ux * bx + uz * bz) + uy * by) / ((bx * bx + bz * bz) + by * by),
                      0.0, 1.0)
            ex, ey, ez = x - (ax + t * bx), y - (ay + t * by), z - (az + t * bz)
            d = math.sqrt((ex * ex + ey * ey) + ez * ez)
            if d < best_d:
                best_d = d
                best_s = ts[i0] + t * (ts[i0 + 1] - ts[i0])
        s_out[i] = best_s
        d_out[i] = best_d


@njit(**_KW)
def unit_rows(d: np.ndarray) -> np.ndarray:
    """``d / norm(d, axis=1, keepdims=True)``."""
    out = np.empty_like(d)
    for i in range(d.shape[0]):
        norm = math.sqrt((d[i, 0] * d[i, 0] + d[i, 1] * d[i, 1]) + d[i, 2] * d[i, 2])
        out[i, 0] = d[i, 0] / norm
        out[i, 1] = d[i, 1] / norm
        out[i, 2] = d[i, 2] / norm
    return out


@njit(**_KW)
def tube_hits(o: np.ndarray, d: np.ndarray, s: np.ndarray, radius: np.ndarray, ts: np.ndarray,
              pts: np.ndarray, tans: np.ndarray, length: float, t_hit: np.ndarray,
              hit: np.ndarray) -> bool:
    """One iteration of ``Trunk.ray_distance``: each ray against the cylinder tangent to the
    tube at ``s`` (``radius``: the tube's radius there); fills ``t_hit`` (inf: no hit) and
    the hit points (``o`` where none); returns whether any ray hit."""
    any_hit = False
    for i in range(o.shape[0]):
        cx, cy, cz, ax, ay, az = _axis_frame(s[i], ts, pts, tans, length)
        r = radius[i]
        wx, wy, wz = o[i, 0] - cx, o[i, 1] - cy, o[i, 2] - cz
        dx, dy, dz = d[i, 0], d[i, 1], d[i, 2]
        ew = (wx * ax + wz * az) + wy * ay
        ed = (dx * ax + dz * az) + dy * ay
        wpx, wpy, wpz = wx - ew * ax, wy - ew * ay, wz - ew * az
        dpx, dpy, dpz = dx - ed * ax, dy - ed * ay, dz - ed * az
        qa = (dpx * dpx + dpz * dpz) + dpy * dpy
        qb = 2 * ((wpx * dpx + wpz * dpz) + wpy * dpy)
        qc = ((wpx * wpx + wpz * wpz) + wpy * wpy) - r * r
        disc = qb * qb - 4 * qa * qc
        t = math.inf
        if disc >= 0 and qa > 1e-12:
            t = (-qb - math.sqrt(disc)) / (2 * qa)
        t_hit[i] = t
        if math.isfinite(t):
            any_hit = True
        else:
            t = 0.0
        hit[i, 0] = o[i, 0] + t * dx
        hit[i, 1] = o[i, 1] + t * dy
        hit[i, 2] = o[i, 2] + t * dz
    return any_hit


@njit(**_KW)
def cone_near(o: np.ndarray, d: np.ndarray, s: np.ndarray, radius: np.ndarray, ts: np.ndarray,
              pts: np.ndarray, tans: np.ndarray, length: float, half: float, max_range: float,
              best: np.ndarray) -> None:
    """The cone test of ``Trunk.cone_distance``: where the perpendicular to the axis lies in
    a sensor's cone, its distance to the surface if nearer than ``best`` (in place)."""
    cos_half = math.cos(half)
    for i in range(o.shape[0]):
        si = s[i]
        cx, cy, cz, ax, ay, az = _axis_frame(si, ts, pts, tans, length)
        wx, wy, wz = o[i, 0] - cx, o[i, 1] - cy, o[i, 2] - cz
        ew = (wx * ax + wz * az) + wy * ay
        wpx, wpy, wpz = wx - ew * ax, wy - ew * ay, wz - ew * az
        dist_axis = math.sqrt((wpx * wpx + wpy * wpy) + wpz * wpz)
        tx, ty, tz = -wpx / dist_axis, -wpy / dist_axis, -wpz / dist_axis
        inside_cone = ((tx * d[i, 0] + tz * d[i, 2]) + ty * d[i, 1]) >= cos_half
        near = dist_axis - radius[i]
        if (inside_cone and si > 0.0 and si < length and near >= 0.0 and near <= max_range
                and dist_axis > 1e-9):
            b = best[i]
            best[i] = b if (b != b or b < near) else near
