"""Compiled (numba) kernel of :func:`cable_robot_pkg.cdrpm.collisions.classify_poses` at one
shared orientation (the constant-orientation workspace), without a workpiece.

One loop over the poses doing, per pose, exactly the arithmetic of the numpy path: the frame
test, the cable vectors A_iB_i (eq. (1)), the line-distance screen of every cable pair, the
exact segment distance (:func:`~cable_robot_pkg.cdrpm.collisions.segment_distance`, same
candidates in the same order, same operations) of the pairs the screen keeps, and the
cable-body test of eq. (8). Why: the numpy path spends most of its time allocating and
streaming (chunk, pair) temporaries through memory; here a pose's 8 cables stay in registers
and a pose outside the frame costs only the frame test.

Only imported when numba is installed; the numpy path stays the fallback (and the reference
the tests compare this kernel with, bit for bit on the flags).
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit

OUTSIDE = 1
CABLE_CABLE = 2
CABLE_BODY = 4


@njit(cache=True, nogil=True, error_model='numpy')
def _segment_distance(rx, ry, rz, ux, uy, uz, vx, vy, vz):
    """Distance of segments ``q0 + r + s u`` and ``q0 + t v`` (segment_distance's float ops)."""
    a = ux * ux + uy * uy + uz * uz
    e = vx * vx + vy * vy + vz * vz
    b = ux * vx + uy * vy + uz * vz
    c = ux * rx + uy * ry + uz * rz
    f = vx * rx + vy * ry + vz * rz
    safe_a = a if a > 0 else 1.0
    safe_e = e if e > 0 else 1.0
    t_s0 = min(max(f / safe_e, 0.0), 1.0) if e > 0 else 0.0
    t_s1 = min(max((f + b) / safe_e, 0.0), 1.0) if e > 0 else 0.0
    s_t0 = min(max(-c / safe_a, 0.0), 1.0) if a > 0 else 0.0
    s_t1 = min(max((b - c) / safe_a, 0.0), 1.0) if a > 0 else 0.0
    nx = uy * vz - uz * vy
    ny = uz * vx - ux * vz
    nz = ux * vy - uy * vx
    nn = nx * nx + ny * ny + nz * nz
    regular = nn > 1e-24 * a * e
    safe_nn = nn if regular else 1.0
    # r x v and r x u
    cx = ry * vz - rz * vy
    cy = rz * vx - rx * vz
    cz = rx * vy - ry * vx
    s_in = -(cx * nx + cy * ny + cz * nz) / safe_nn
    cx = ry * uz - rz * uy
    cy = rz * ux - rx * uz
    cz = rx * uy - ry * ux
    t_in = -(cx * nx + cy * ny + cz * nz) / safe_nn
    inside = regular and s_in >= 0 and s_in <= 1 and t_in >= 0 and t_in <= 1
    best = math.inf
    for idx in range(5):
        if idx == 0:
            s, t = 0.0, t_s0
        elif idx == 1:
            s, t = 1.0, t_s1
        elif idx == 2:
            s, t = s_t0, 0.0
        elif idx == 3:
            s, t = s_t1, 1.0
        else:
            if not inside:
                break
            s, t = s_in, t_in
        dx = rx + s * ux - t * vx
        dy = ry + s * uy - t * vy
        dz = rz + s * uz - t * vz
        dist = math.sqrt(dx * dx + dy * dy + dz * dz)
        if idx == 0 or dist < best:
            best = dist
    return best


@njit(cache=True, nogil=True, error_model='numpy')
def classify_shared(pos: np.ndarray, rb: np.ndarray, extent: np.ndarray,
                    frame_limit: np.ndarray, frame_points: np.ndarray, pair_i: np.ndarray,
                    pair_j: np.ndarray, two_eps: float, screen_slack: float,
                    platform_points: np.ndarray, body_delta: float, rot: np.ndarray,
                    body_limit: np.ndarray, min_length: float, flags: np.ndarray) -> None:

    """Flags (OUTSIDE, CABLE_CABLE, CABLE_BODY bits) of every pose in ``pos`` (N, 3).

    ``rb`` (n, 3) = ``platform_points @ R.T``, ``extent`` (3,) the rotated platform's half
    extents, ``frame_limit`` (3,) = frame half size + FRAME_TOL, ``body_limit`` (3,) = platform
    half size - BODY_TOL; ``rot`` is R. One thread (robust on a shared machine).
    """
    n_cables = rb.shape[0]
    n_pairs = pair_i.shape[0]
    limit2 = two_eps * two_eps
    d = np.empty((n_cables, 3))
    for k in range(pos.shape[0]):
        gx, gy, gz = pos[k, 0], pos[k, 1], pos[k, 2]
        if not (abs(gx) + extent[0] <= frame_limit[0] and abs(gy) + extent[1] <= frame_limit[1]
                and abs(gz) + extent[2] <= frame_limit[2]):
            flags[k] = OUTSIDE
            continue
        for i in range(n_cables):
            d[i, 0] = (gx + rb[i, 0]) - frame_points[i, 0]
            d[i, 1] = (gy + rb[i, 1]) - frame_points[i, 1]
            d[i, 2] = (gz + rb[i, 2]) - frame_points[i, 2]
        out = 0
        if n_pairs > 0 and two_eps != 0.0:
            for p in range(n_pairs):
                i = pair_i[p]
                j = pair_j[p]
                ix, iy, iz = d[i, 0], d[i, 1], d[i, 2]
                jx, jy, jz = d[j, 0], d[j, 1], d[j, 2]
                wx = frame_points[i, 0] - frame_points[j, 0]
                wy = frame_points[i, 1] - frame_points[j, 1]
                wz = frame_points[i, 2] - frame_points[j, 2]
                nx = iy * jz - iz * jy
                ny = iz * jx - ix * jz
                nz = ix * jy - iy * jx
                wn = wx * nx + wy * ny + wz * nz
                nn = nx * nx + ny * ny + nz * nz
                if not wn * wn <= limit2 * nn * (1.0 + screen_slack):
                    continue
                if _segment_distance(wx, wy, wz, ix, iy, iz, jx, jy, jz) < two_eps:
                    out |= CABLE_CABLE
                    break
        for i in range(n_cables):
            dx, dy, dz = d[i, 0], d[i, 1], d[i, 2]
            length = math.sqrt(dx * dx + dy * dy + dz * dz)
            safe = 1.0 if length < min_length else length
            inside = True
            for m in range(3):
                local = dx * rot[0, m] + dy * rot[1, m] + dz * rot[2, m]
                v = platform_points[i, m] - body_delta * local / safe
                if not abs(v) < body_limit[m]:
                    inside = False
                    break
            if inside:
                out |= CABLE_BODY
                break
        flags[k] = out
