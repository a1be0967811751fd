"""Compiled (numba) per-step cable wrench of ``CableSystem.wrench`` (``cables.py``).

The simulator evaluates the ten cables' wrench on the trolley 1000 times per simulated second;
in numpy that is some twenty array operations on (10, 2, 3) arrays, each costing more in call
overhead than in arithmetic. This kernel does the same arithmetic in one loop, in numpy's
order: the same products and quotients, sums over a cable's spans, over a vector's three
components and over the cables taken first to last as numpy's reductions of these small
arrays take them, the same clipping rules. The attachment offsets (a small matrix product)
are computed by the caller with numpy, so the kernel sees the same numbers. The results are
bit-identical to the numpy path (``test_fast_speed.py`` compares both with the reference
formulas on random poses and along a whole plant trajectory).

Only imported when numba is installed (``cables.py`` keeps the numpy path otherwise and when
``PARAMOTION_BACKEND=numpy``). Compiled on first use, cached on disk.
"""
import math

import numpy as np
from numba import njit


@njit(cache=True, nogil=True, error_model='numpy')
def cable_wrench(r: np.ndarray, anchors: np.ndarray, mask: np.ndarray, position: np.ndarray,
                 lin: np.ndarray, ang: np.ndarray, unstretched: np.ndarray,
                 unstretched_rates: np.ndarray, EA: np.ndarray, damping: np.ndarray,
                 force: np.ndarray, torque: np.ndarray, tensions: np.ndarray,
                 lengths: np.ndarray, slack: np.ndarray) -> None:
    """Fill ``force`` (3,), ``torque`` (3,), ``tensions``, ``lengths`` and ``slack`` (n,).

    ``r``: attachment offsets (n, 3) in world axes; ``anchors`` (n, k, 3) and ``mask`` (n, k):
    the pulley exits of each cable (padded); ``unstretched`` and ``unstretched_rates`` (n,).
    """
    n, k = mask.shape
    a0, a1, a2 = ang[0], ang[1], ang[2]
    spans = np.empty(3)
    for i in range(n):
        p0 = position[0] + r[i, 0]
        p1 = position[1] + r[i, 1]
        p2 = position[2] + r[i, 2]
        d0 = d1 = d2 = 0.0
        length = 0.0
        for j in range(k):
            spans[0] = anchors[i, j, 0] - p0
            spans[1] = anchors[i, j, 1] - p1
            spans[2] = anchors[i, j, 2] - p2
            span_len = math.sqrt(spans[0] * spans[0] + spans[1] * spans[1]
                                 + spans[2] * spans[2])
            if mask[i, j]:
                w0, w1, w2 = spans[0] / span_len, spans[1] / span_len, spans[2] / span_len
                lj = span_len
            else:
                w0 = w1 = w2 = lj = 0.0
            if j == 0:
                d0, d1, d2, length = w0, w1, w2, lj
            else:
                d0, d1, d2, length = d0 + w0, d1 + w1, d2 + w2, length + lj
        r0, r1, r2 = r[i, 0], r[i, 1], r[i, 2]
        v0 = lin[0] + (a1 * r2 - a2 * r1)
        v1 = lin[1] + (a2 * r0 - a0 * r2)
        v2 = lin[2] + (a0 * r1 - a1 * r0)
        rate = -((v0 * d0 + v2 * d2) + v1 * d1)     # numpy's einsum adds x and z first
        l0 = unstretched[i]
        if l0 < 1e-6:
            l0 = 1e-6
        strain = (length - l0) / l0
        t = EA[i] * strain + damping[i] * (rate - unstretched_rates[i])
        taut = strain > 0.0
        if not taut:
            t = 0.0
        elif t < 0.0:
            t = 0.0
        tensions[i] = t
        lengths[i] = length
        slack[i] = not taut
        f0, f1, f2 = t * d0, t * d1, t * d2
        c0 = r1 * f2 - r2 * f1
        c1 = r2 * f0 - r0 * f2
        c2 = r0 * f1 - r1 * f0
        if i == 0:
            force[0], force[1], force[2] = f0, f1, f2
            torque[0], torque[1], torque[2] = c0, c1, c2
        else:
            force[0] += f0
            force[1] += f1
            force[2] += f2
            torque[0] += c0
            torque[1] += c1
            torque[2] += c2


@njit(cache=True, nogil=True, error_model='numpy')
def plant_step(winch_cmd: np.ndarray, winch_rate_cmd: np.ndarray, winch_elapsed: float,
               winch_max_step: float, dt: float, unstretched: np.ndarray, r: np.ndarray,
               anchors: np.ndarray, mask: np.ndarray, position: np.ndarray, lin: np.ndarray,
               ang: np.ndarray, EA: np.ndarray, damping: np.ndarray, wind_on: bool,
               wind: np.ndarray, block: np.ndarray, j: int, block2: np.ndarray, j2: int,
               r_cp: np.ndarray, leg_cmd: np.ndarray, leg_rate_cmd: np.ndarray,
               leg_since: float, leg_min: float, leg_max: float, nominal: np.ndarray,
               out: np.ndarray, slack: np.ndarray) -> None:
    """The arithmetic of one ``FeedSupportPlant.step`` in one call, in numpy's order.

    Winches (``unstretched`` moves toward ``winch_cmd + winch_rate_cmd * winch_elapsed`` by
    at most ``winch_max_step``), the cable wrench (:func:`cable_wrench` with the winch rates),
    the wind wrench of ``WindModel.wrench`` (``wind``: mean speed U, cos and sin of the
    direction, ``0.5 rho Cd A``, torque scale, turbulence intensity, interpolation fraction,
    gust speed; turbulence columns ``block[:, j]`` and ``block2[:, j2]``; ``r_cp`` the centre
    of pressure in world axes) added to it, and the leg servo targets (clipped to the stroke).

    ``out`` (3 + 3 + 3 + 3 + 4 n + 6 + 6 + 3,) receives: force, torque (cables + wind), wind
    force, wind torque, tensions, stretched lengths, new unstretched lengths, winch rates,
    leg targets, leg targets minus ``nominal``, the smallest and largest tension (NaN if a
    tension is NaN, as numpy's ``min``/``max``) and the number of slack cables; ``slack``
    (n,) the slack flags.
    """
    n = unstretched.shape[0]
    o = 12
    tensions = out[o:o + n]
    lengths = out[o + n:o + 2 * n]
    new_l0 = out[o + 2 * n:o + 3 * n]
    rates = out[o + 3 * n:o + 4 * n]
    for i in range(n):
        goal = winch_cmd[i] + winch_rate_cmd[i] * winch_elapsed
        s = goal - unstretched[i]
        if s < -winch_max_step:
            s = -winch_max_step
        if s > winch_max_step:
            s = winch_max_step
        new_l0[i] = unstretched[i] + s
        rates[i] = s / dt
    force = out[0:3]
    torque = out[3:6]
    cable_wrench(r, anchors, mask, position, lin, ang, new_l0, rates, EA, damping, force,
                 torque, tensions, lengths, slack)
    if wind_on:
        frac = wind[6]
        tu = np.empty(6)
        for i in range(6):
            tu[i] = (1.0 - frac) * block[i, j] + frac * block2[i, j2]
        c, s = wind[1], wind[2]
        along = wind[0] + tu[0] + wind[7]
        v0 = along * c - tu[1] * s
        v1 = along * s + tu[1] * c
        v2 = tu[2]
        speed = wind[3] * math.sqrt(v0 * v0 + v1 * v1 + v2 * v2)
        f0, f1, f2 = speed * v0, speed * v1, speed * v2
        m = math.sqrt(f0 * f0 + f1 * f1 + f2 * f2) * wind[4] * wind[5]
        r0, r1, r2 = r_cp[0], r_cp[1], r_cp[2]
        t0 = (r1 * f2 - r2 * f1) + m * tu[3]
        t1 = (r2 * f0 - r0 * f2) + m * tu[4]
        t2 = (r0 * f1 - r1 * f0) + m * tu[5]
    else:
        f0 = f1 = f2 = t0 = t1 = t2 = 0.0
    out[6], out[7], out[8], out[9], out[10], out[11] = f0, f1, f2, t0, t1, t2
    force[0] += f0
    force[1] += f1
    force[2] += f2
    torque[0] += t0
    torque[1] += t1
    torque[2] += t2
    o = 12 + 4 * n
    for i in range(6):
        x = leg_cmd[i] + leg_rate_cmd[i] * leg_since
        if x < leg_min:
            x = leg_min
        if x > leg_max:
            x = leg_max
        out[o + i] = x
        out[o + 6 + i] = x - nominal[i]
    lo = hi = tensions[0]
    n_slack = 0
    has_nan = False
    for i in range(n):
        t = tensions[i]
        if t != t:
            has_nan = True
        if t < lo:
            lo = t
        if t > hi:
            hi = t
        if slack[i]:
            n_slack += 1
    if has_nan:
        lo = hi = np.nan
    o += 12
    out[o], out[o + 1], out[o + 2] = lo, hi, n_slack


@njit(cache=True, nogil=True, error_model='numpy')
def cable_length_rates(r: np.ndarray, anchors: np.ndarray, mask: np.ndarray,
                       position: np.ndarray, lin: np.ndarray, ang: np.ndarray,
                       rates: np.ndarray) -> None:
    """Fill ``rates`` (n,) with dL/dt of ``CableSystem.length_rates``: the directions and the
    projected velocities of :func:`cable_wrench`, operation for operation."""
    n, k = mask.shape
    a0, a1, a2 = ang[0], ang[1], ang[2]
    for i in range(n):
        p0 = position[0] + r[i, 0]
        p1 = position[1] + r[i, 1]
        p2 = position[2] + r[i, 2]
        d0 = d1 = d2 = 0.0
        for j in range(k):
            s0 = anchors[i, j, 0] - p0
            s1 = anchors[i, j, 1] - p1
            s2 = anchors[i, j, 2] - p2
            span_len = math.sqrt(s0 * s0 + s1 * s1 + s2 * s2)
            if mask[i, j]:
                w0, w1, w2 = s0 / span_len, s1 / span_len, s2 / span_len
            else:
                w0 = w1 = w2 = 0.0
            if j == 0:
                d0, d1, d2 = w0, w1, w2
            else:
                d0, d1, d2 = d0 + w0, d1 + w1, d2 + w2
        r0, r1, r2 = r[i, 0], r[i, 1], r[i, 2]
        v0 = lin[0] + (a1 * r2 - a2 * r1)
        v1 = lin[1] + (a2 * r0 - a0 * r2)
        v2 = lin[2] + (a0 * r1 - a1 * r0)
        rates[i] = -((v0 * d0 + v2 * d2) + v1 * d1)     # numpy's einsum adds x and z first
