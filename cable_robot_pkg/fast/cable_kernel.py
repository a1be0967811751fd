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
