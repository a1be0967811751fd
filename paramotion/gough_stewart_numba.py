"""Compiled (numba) kernels of the Gough-Stewart forward kinematics (batched and single).

One loop over the poses, each solved by the same Newton-Raphson as the numpy path of
:func:`paramotion.gough_stewart.forward_kinematics_batch` (eq. (4), 7 unknowns ``[r, e]``): the
same residual test (written ``|L|^2 - C^2 < 2 C tol`` as in the single solver), the same phi_q
rows (``_constraint_jacobian``), the same 7 x 7 step (here by Gaussian elimination with partial
pivoting, the algorithm of LAPACK's ``dgesv``), the same "singular when |det phi_q| < 1e-300 or
not finite" rule, and at the end the 2-norm condition of the homogenised inverse Jacobian (here
by one-sided Jacobi, which gives the singular values to full relative accuracy, instead of
LAPACK's SVD). Why: the numpy path spends its time in per-matrix LAPACK calls on (N, 7, 7) and
(N, 6, 6) stacks (about 1 us and 4.6 us per pose); here a solve takes about 2 us.

Only imported when numba is installed; :mod:`paramotion.gough_stewart` falls back to numpy
otherwise (and when ``PARAMOTION_BACKEND=numpy``). Compiled on first use, cached on disk.
"""
import math

import numpy as np
from numba import njit

#: Poses whose Jacobian singular values are computed together (lanes of one Jacobi run): with
#: 64 the compiler vectorises the lane loops (0.6 us per matrix here, against 2 us with 8).
_LANES = 64


@njit(cache=True, nogil=True, error_model='numpy')
def _block_condition(jb, norms, gamma, cs, sn, tt, out, count):
    """2-norm condition numbers of ``count`` 6 x 6 matrices at once, into ``out[:count]``.

    ``jb[p, i, l]`` is entry (i, p) of matrix l. One-sided (Hestenes) Jacobi: plane rotations
    of column pairs until every pair is orthogonal to 1e-15 relative; the column norms are then
    the singular values, to full relative accuracy. All lanes run together with branch-free
    updates (a lane whose columns are already orthogonal gets the identity rotation) so that
    the compiler vectorises over lanes and the square roots and divisions of different
    matrices overlap, instead of waiting on one matrix's chain of dependent ones. Lanes past
    ``count`` are zero matrices, left alone.
    """
    n = jb.shape[0]
    lanes = _LANES
    for p in range(n):
        for ln in range(lanes):
            norms[p, ln] = 0.0
        for i in range(n):
            for ln in range(lanes):
                norms[p, ln] += jb[p, i, ln] * jb[p, i, ln]
    for _ in range(40):
        rotated = 0
        for p in range(n - 1):
            for q in range(p + 1, n):
                for ln in range(lanes):
                    gamma[ln] = 0.0
                for i in range(n):
                    for ln in range(lanes):
                        gamma[ln] += jb[p, i, ln] * jb[q, i, ln]
                for ln in range(lanes):
                    g = gamma[ln]
                    alpha = norms[p, ln]
                    beta = norms[q, ln]
                    act = g * g > 1e-30 * (alpha * beta)   # |cos| > 1e-15, no sqrt
                    gs = g if act else 1.0
                    zeta = (beta - alpha) / (2.0 * gs)
                    t = math.copysign(1.0, zeta) / (abs(zeta) + math.sqrt(1.0 + zeta * zeta))
                    t = t if act else 0.0
                    c = 1.0 / math.sqrt(1.0 + t * t)
                    cs[ln] = c
                    sn[ln] = c * t
                    tt[ln] = t * g
                    rotated += 1 if act else 0
                for ln in range(lanes):
                    norms[p, ln] -= tt[ln]
                    norms[q, ln] += tt[ln]
                for i in range(n):
                    for ln in range(lanes):
                        a = jb[p, i, ln]
                        b = jb[q, i, ln]
                        jb[p, i, ln] = cs[ln] * a - sn[ln] * b
                        jb[q, i, ln] = sn[ln] * a + cs[ln] * b
        if rotated == 0:
            break
    for ln in range(count):
        smax = 0.0
        smin = math.inf
        for p in range(n):
            s = 0.0
            for i in range(n):
                s += jb[p, i, ln] * jb[p, i, ln]
            s = math.sqrt(s)
            smax = max(smax, s)
            smin = min(smin, s)
        out[ln] = smax / smin if smin > 0 else math.inf


@njit(cache=True, nogil=True, error_model='numpy')
def _solve_pivoted(a, b):
    """Solve ``a x = b`` in place (x in ``b``); returns det(a). ``a`` is overwritten."""
    n = a.shape[0]
    det = 1.0
    for k in range(n):
        piv = k
        big = abs(a[k, k])
        for i in range(k + 1, n):
            v = abs(a[i, k])
            if v > big:
                big = v
                piv = i
        if piv != k:
            det = -det
            for m in range(n):
                tmp = a[k, m]
                a[k, m] = a[piv, m]
                a[piv, m] = tmp
            tmp = b[k]
            b[k] = b[piv]
            b[piv] = tmp
        det *= a[k, k]
        if a[k, k] == 0.0 or not math.isfinite(det):
            return det
        inv = 1.0 / a[k, k]
        for i in range(k + 1, n):
            f = a[i, k] * inv
            if f != 0.0:
                for m in range(k + 1, n):
                    a[i, m] -= f * a[k, m]
                b[i] -= f * b[k]
    for k in range(n - 1, -1, -1):
        s = b[k]
        for m in range(k + 1, n):
            s -= a[k, m] * b[m]
        b[k] = s / a[k, k]
    return det


@njit(cache=True, nogil=True, error_model='numpy')
def _rotation(e0, e1, e2, e3, out):
    """Haug's A(e) (un-normalised e, as ``matrix_from_quaternion(normalize=False)``)."""
    out[0, 0] = 2 * (e0 * e0 + e1 * e1) - 1
    out[0, 1] = 2 * (e1 * e2 - e0 * e3)
    out[0, 2] = 2 * (e1 * e3 + e0 * e2)
    out[1, 0] = 2 * (e1 * e2 + e0 * e3)
    out[1, 1] = 2 * (e0 * e0 + e2 * e2) - 1
    out[1, 2] = 2 * (e2 * e3 - e0 * e1)
    out[2, 0] = 2 * (e1 * e3 - e0 * e2)
    out[2, 1] = 2 * (e2 * e3 + e0 * e1)
    out[2, 2] = 2 * (e0 * e0 + e3 * e3) - 1


@njit(cache=True, nogil=True, error_model='numpy')
def _newton(ck, r0, r1, r2, e0, e1, e2, e3, run, plat, base, tol, max_iter, a, legs, sq, jac,
            phi, c2, lim):
    """Newton-Raphson on eq. (4) for one pose (lengths ``ck``) from the guess ``r``, ``e``.

    Returns ``(r0, r1, r2, e0, e1, e2, e3, iterations, converged, singular)``; ``run`` False
    skips the iteration (invalid lengths). The other arrays are work space.
    """
    it = 0
    ok = False
    sing = False
    for i in range(6):
        c2[i] = ck[i] * ck[i]
        lim[i] = 2 * ck[i] * tol       # |L|^2 - C^2 < 2 C tol  <=>  |L| - C < tol (to 1e-24)
    while run:
        _rotation(e0, e1, e2, e3, a)
        res = 0.0
        for i in range(6):
            px, py, pz = plat[i, 0], plat[i, 1], plat[i, 2]
            lx = r0 + (a[0, 0] * px + a[0, 1] * py + a[0, 2] * pz) - base[i, 0]
            ly = r1 + (a[1, 0] * px + a[1, 1] * py + a[1, 2] * pz) - base[i, 1]
            lz = r2 + (a[2, 0] * px + a[2, 1] * py + a[2, 2] * pz) - base[i, 2]
            legs[i, 0] = lx
            legs[i, 1] = ly
            legs[i, 2] = lz
            sq[i] = lx * lx + ly * ly + lz * lz
            if not abs(sq[i] - c2[i]) < lim[i]:     # NaN counts as not converged
                res = 1.0
        ee = e0 * e0 + e1 * e1 + e2 * e2 + e3 * e3
        if res == 0.0 and abs(ee - 1.0) < tol:
            ok = True
            break
        if it >= max_iter:
            break
        # phi_q rows of the driving constraints: [L, L^T d(A p)/de] (_constraint_jacobian).
        for i in range(6):
            lx, ly, lz = legs[i, 0], legs[i, 1], legs[i, 2]
            px, py, pz = plat[i, 0], plat[i, 1], plat[i, 2]
            lp = lx * px + ly * py + lz * pz
            cx = e2 * pz - e3 * py
            cy = e3 * px - e1 * pz
            cz = e1 * py - e2 * px
            ep = e1 * px + e2 * py + e3 * pz
            le = lx * e1 + ly * e2 + lz * e3
            jac[i, 0] = lx
            jac[i, 1] = ly
            jac[i, 2] = lz
            jac[i, 3] = 4 * e0 * lp + 2 * (lx * cx + ly * cy + lz * cz)
            jac[i, 4] = 2 * ep * lx + 2 * le * px - 2 * e0 * (ly * pz - lz * py)
            jac[i, 5] = 2 * ep * ly + 2 * le * py - 2 * e0 * (lz * px - lx * pz)
            jac[i, 6] = 2 * ep * lz + 2 * le * pz - 2 * e0 * (lx * py - ly * px)
            phi[i] = 0.5 * (sq[i] - c2[i])
        jac[6, 0] = 0.0
        jac[6, 1] = 0.0
        jac[6, 2] = 0.0
        jac[6, 3] = e0
        jac[6, 4] = e1
        jac[6, 5] = e2
        jac[6, 6] = e3
        phi[6] = 0.5 * (ee - 1.0)
        det = _solve_pivoted(jac, phi)
        if not math.isfinite(det) or abs(det) < 1e-300:
            sing = True
            break
        r0 -= phi[0]
        r1 -= phi[1]
        r2 -= phi[2]
        e0 -= phi[3]
        e1 -= phi[4]
        e2 -= phi[5]
        e3 -= phi[6]
        it += 1
    return r0, r1, r2, e0, e1, e2, e3, it, ok, sing


@njit(cache=True, nogil=True, error_model='numpy')
def fk_batch_kernel(c: np.ndarray, r: np.ndarray, e: np.ndarray, valid: np.ndarray,
                    plat: np.ndarray, base: np.ndarray, rho: float, tol: float, max_iter: int,
                    max_condition: float, rot: np.ndarray, iterations: np.ndarray,
                    converged: np.ndarray, singular: np.ndarray, cond: np.ndarray) -> None:
    """Solve every pose in place: ``r`` (N, 3), ``e`` (N, 4) in, solution out; see module."""
    n = c.shape[0]
    a = np.empty((3, 3))
    legs = np.empty((6, 3))
    sq = np.empty(6)
    jac = np.empty((7, 7))
    phi = np.empty(7)
    c2 = np.empty(6)
    lim = np.empty(6)
    ok_k = np.zeros(n, dtype=np.bool_)
    sing_k = np.zeros(n, dtype=np.bool_)
    check = np.zeros(n, dtype=np.bool_)
    for k in range(n):
        r0, r1, r2 = r[k, 0], r[k, 1], r[k, 2]
        e0, e1, e2, e3 = e[k, 0], e[k, 1], e[k, 2], e[k, 3]
        r0, r1, r2, e0, e1, e2, e3, it, ok, sing = _newton(
            c[k], r0, r1, r2, e0, e1, e2, e3, valid[k], plat, base, tol, max_iter, a, legs, sq,
            jac, phi, c2, lim)
        norm = math.sqrt(e0 * e0 + e1 * e1 + e2 * e2 + e3 * e3)
        e0, e1, e2, e3 = e0 / norm, e1 / norm, e2 / norm, e3 / norm
        _rotation(e0, e1, e2, e3, a)
        finite = math.isfinite(r0 + r1 + r2)
        for i in range(3):
            for m in range(3):
                rot[k, i, m] = a[i, m]
                finite = finite and math.isfinite(a[i, m])
        r[k, 0], r[k, 1], r[k, 2] = r0, r1, r2
        e[k, 0], e[k, 1], e[k, 2], e[k, 3] = e0, e1, e2, e3
        iterations[k] = it
        ok_k[k] = ok
        sing_k[k] = sing
        check[k] = valid[k] and finite
    # Condition of the homogenised inverse Jacobian [u_i, ((R p_i) x u_i) / rho] (jacobian()
    # and jacobian_condition()) at each final iterate, _LANES poses at a time.
    jb = np.zeros((6, 6, _LANES))
    norms = np.empty((6, _LANES))
    gamma = np.empty(_LANES)
    cs = np.empty(_LANES)
    sn = np.empty(_LANES)
    tt = np.empty(_LANES)
    block = np.empty(_LANES)
    members = np.empty(_LANES, dtype=np.int64)
    count = 0
    for k in range(n + 1):
        if k < n:
            cond[k] = math.inf
            if not check[k]:
                continue
            for i in range(6):
                px, py, pz = plat[i, 0], plat[i, 1], plat[i, 2]
                wx = rot[k, 0, 0] * px + rot[k, 0, 1] * py + rot[k, 0, 2] * pz
                wy = rot[k, 1, 0] * px + rot[k, 1, 1] * py + rot[k, 1, 2] * pz
                wz = rot[k, 2, 0] * px + rot[k, 2, 1] * py + rot[k, 2, 2] * pz
                lx = r[k, 0] + wx - base[i, 0]
                ly = r[k, 1] + wy - base[i, 1]
                lz = r[k, 2] + wz - base[i, 2]
                ln = math.sqrt(lx * lx + ly * ly + lz * lz)
                ux, uy, uz = lx / ln, ly / ln, lz / ln
                jb[0, i, count] = ux
                jb[1, i, count] = uy
                jb[2, i, count] = uz
                jb[3, i, count] = (wy * uz - wz * uy) / rho
                jb[4, i, count] = (wz * ux - wx * uz) / rho
                jb[5, i, count] = (wx * uy - wy * ux) / rho
            members[count] = k
            count += 1
            if count < _LANES:
                continue
        if count == 0:
            continue
        _block_condition(jb, norms, gamma, cs, sn, tt, block, count)
        for m in range(count):
            kc = block[m]
            cond[members[m]] = math.inf if math.isnan(kc) else kc
        jb[...] = 0.0
        count = 0
    for k in range(n):
        near = valid[k] and not cond[k] <= max_condition
        singular[k] = sing_k[k] or near
        converged[k] = ok_k[k] and not near


@njit(cache=True, nogil=True, error_model='numpy')
def _condition_one(jt, norms):
    """2-norm condition of one square matrix given by its columns ``jt[p]`` (overwritten).

    One-sided Jacobi, the same rotations as :func:`_block_condition` on a single lane.
    """
    n = jt.shape[0]
    for p in range(n):
        s = 0.0
        for i in range(n):
            s += jt[p, i] * jt[p, i]
        norms[p] = s
    for _ in range(40):
        rotated = False
        for p in range(n - 1):
            for q in range(p + 1, n):
                g = 0.0
                for i in range(n):
                    g += jt[p, i] * jt[q, i]
                alpha = norms[p]
                beta = norms[q]
                if not abs(g) > 1e-15 * math.sqrt(alpha * beta):
                    continue
                rotated = True
                zeta = (beta - alpha) / (2.0 * g)
                t = math.copysign(1.0, zeta) / (abs(zeta) + math.sqrt(1.0 + zeta * zeta))
                cs = 1.0 / math.sqrt(1.0 + t * t)
                sn = cs * t
                for i in range(n):
                    x = jt[p, i]
                    y = jt[q, i]
                    jt[p, i] = cs * x - sn * y
                    jt[q, i] = sn * x + cs * y
                norms[p] = alpha - t * g
                norms[q] = beta + t * g
        if not rotated:
            break
    smax = 0.0
    smin = math.inf
    for p in range(n):
        s = 0.0
        for i in range(n):
            s += jt[p, i] * jt[p, i]
        s = math.sqrt(s)
        smax = max(smax, s)
        smin = min(smin, s)
    kc = smax / smin if smin > 0 else math.inf
    return math.inf if math.isnan(kc) else kc


@njit(cache=True, nogil=True, error_model='numpy')
def fk_single_kernel(c: np.ndarray, r0: float, r1: float, r2: float, e0: float, e1: float,
                     e2: float, e3: float, plat: np.ndarray, base: np.ndarray, rho: float,
                     tol: float, max_iter: int
                     ) -> tuple[float, float, float, float, float, float, float, int, bool,
                                bool, float]:
    """One warm-started solve: ``(r0, r1, r2, e0, e1, e2, e3, iterations, converged,
    singular, condition)`` with e normalised (NaN when it collapsed below 1e-6) and the
    condition of the homogenised inverse Jacobian at the solution (inf when not finite)."""
    a = np.empty((3, 3))
    legs = np.empty((6, 3))
    sq = np.empty(6)
    jac = np.empty((7, 7))
    phi = np.empty(7)
    c2 = np.empty(6)
    lim = np.empty(6)
    r0, r1, r2, e0, e1, e2, e3, it, ok, sing = _newton(
        c, r0, r1, r2, e0, e1, e2, e3, True, plat, base, tol, max_iter, a, legs, sq, jac, phi,
        c2, lim)
    cond = math.inf
    if sing:
        return r0, r1, r2, e0, e1, e2, e3, it, ok, sing, cond
    norm = math.sqrt(e0 * e0 + e1 * e1 + e2 * e2 + e3 * e3)
    if not norm > 1e-6:
        return r0, r1, r2, math.nan, math.nan, math.nan, math.nan, it, ok, sing, cond
    e0, e1, e2, e3 = e0 / norm, e1 / norm, e2 / norm, e3 / norm
    _rotation(e0, e1, e2, e3, a)
    if math.isfinite(r0 + r1 + r2):
        jt = np.empty((6, 6))
        for i in range(6):
            px, py, pz = plat[i, 0], plat[i, 1], plat[i, 2]
            wx = a[0, 0] * px + a[0, 1] * py + a[0, 2] * pz
            wy = a[1, 0] * px + a[1, 1] * py + a[1, 2] * pz
            wz = a[2, 0] * px + a[2, 1] * py + a[2, 2] * pz
            lx = r0 + wx - base[i, 0]
            ly = r1 + wy - base[i, 1]
            lz = r2 + wz - base[i, 2]
            ln = math.sqrt(lx * lx + ly * ly + lz * lz)
            ux, uy, uz = lx / ln, ly / ln, lz / ln
            jt[0, i] = ux
            jt[1, i] = uy
            jt[2, i] = uz
            jt[3, i] = (wy * uz - wz * uy) / rho
            jt[4, i] = (wz * ux - wx * uz) / rho
            jt[5, i] = (wx * uy - wy * ux) / rho
        cond = _condition_one(jt, sq)
    return r0, r1, r2, e0, e1, e2, e3, it, ok, sing, cond
