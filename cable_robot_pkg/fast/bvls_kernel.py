"""Compiled bounded-variable least squares: scipy's ``lsq_linear(..., method='bvls')``.

The cable controller re-plans the tension distribution (:meth:`CableSystem.
tension_distribution`) some 25 times per simulated second; when the minimum-norm tensions
leave their limits it solves a bounded least-squares problem with the BVLS algorithm (Stark &
Parker, 1995). scipy's implementation is Python around a dozen ``lstsq`` calls per problem,
and its call overhead costs more than the arithmetic of a 16 x 10 problem. This module is the
same algorithm, statement for statement (scipy 1.17 ``optimize/_lsq/lsq_linear.py`` and
``optimize/_lsq/bvls.py``: the unbounded solution first, the initialisation loop that clamps
violating variables, then loops A and B with the same tolerances and tie-breaking), compiled
with numba. Its least-squares solves are LAPACK's ``gelsd`` as numpy's are, so the results
agree with scipy's to rounding (``test_fast_hot_paths.py`` checks 1e-12 relative on random
and on the controller's own problems).

Only imported when numba is installed (``cables.py`` calls scipy otherwise and with
``PARAMOTION_BACKEND=numpy``).
"""
import numpy as np
from numba import njit


@njit(cache=True, nogil=True, error_model='numpy')
def _kkt_optimality(g, on_bound):
    """scipy's ``compute_kkt_optimality``: the largest violation of the KKT conditions."""
    best = -np.inf
    for i in range(g.shape[0]):
        v = abs(g[i]) if on_bound[i] == 0 else g[i] * on_bound[i]
        if v > best:
            best = v
    return best


@njit(cache=True, nogil=True, error_model='numpy')
def _cost(A, x, b):
    r = A.dot(x) - b
    return r, 0.5 * np.dot(r, r)


@njit(cache=True, nogil=True, error_model='numpy')
def _free_lstsq(A, free_set, b_free, eps):
    """numpy's ``lstsq(A[:, free_set], b_free)[0]`` (default ``rcond``; no free variable:
    an empty solution, as numpy returns)."""
    if free_set.size == 0:
        return np.empty(0)
    A_free = np.ascontiguousarray(A[:, free_set])
    return np.linalg.lstsq(A_free, b_free, rcond=eps * max(A_free.shape))[0]


@njit(cache=True, nogil=True, error_model='numpy')
def bvls(A: np.ndarray, b: np.ndarray, lb: np.ndarray, ub: np.ndarray,
         tol: float = 1e-10) -> np.ndarray:
    """Solution ``x`` of ``min |A x - b|`` with ``lb <= x <= ub`` (``lsq_linear`` with
    ``method='bvls'``, ``tol``, ``max_iter=None``)."""
    m, n = A.shape
    eps = np.finfo(np.float64).eps    # numpy's default rcond: eps * max(rows, columns)
    x_lsq = np.linalg.lstsq(A, b, rcond=-1.0)[0]
    inside = True
    for i in range(n):
        if not (x_lsq[i] >= lb[i] and x_lsq[i] <= ub[i]):
            inside = False
    if inside:
        return x_lsq
    x = x_lsq.copy()
    on_bound = np.zeros(n)
    for i in range(n):
        if x[i] <= lb[i]:
            x[i] = lb[i]
            on_bound[i] = -1.0
    for i in range(n):
        if x[i] >= ub[i]:
            x[i] = ub[i]
            on_bound[i] = 1.0
    free_set = np.nonzero(on_bound == 0)[0]
    active = on_bound != 0
    r, cost = _cost(A, x, b)
    g = A.T.dot(r)
    iteration = 0
    # Initialisation: least squares on the free variables until feasible.
    while free_set.size > 0:
        iteration += 1
        z = _free_lstsq(A, free_set, b - A.dot(x * active), eps)
        lbv = z < lb[free_set]
        ubv = z > ub[free_set]
        v = lbv | ubv
        for k in range(free_set.size):
            i = free_set[k]
            if lbv[k]:
                x[i] = lb[i]
                active[i] = True
                on_bound[i] = -1.0
        for k in range(free_set.size):
            i = free_set[k]
            if ubv[k]:
                x[i] = ub[i]
                active[i] = True
                on_bound[i] = 1.0
        for k in range(free_set.size):
            if not v[k]:
                x[free_set[k]] = z[k]
        r, cost = _cost(A, x, b)
        g = A.T.dot(r)
        if v.any():
            free_set = free_set[~v]
        else:
            break
    max_iter = n + iteration
    terminated = False
    optimality = _kkt_optimality(g, on_bound)
    for _ in range(iteration, max_iter):
        if optimality < tol:
            terminated = True
        if terminated:
            break
        move_to_free = np.argmax(g * on_bound)
        on_bound[move_to_free] = 0.0
        while True:
            free_set = np.nonzero(on_bound == 0)[0]
            active = on_bound != 0
            x_free = x[free_set]
            lb_free = lb[free_set]
            ub_free = ub[free_set]
            z = _free_lstsq(A, free_set, b - A.dot(x * active), eps)
            lbv = np.nonzero(z < lb_free)[0]
            ubv = np.nonzero(z > ub_free)[0]
            v = np.concatenate((lbv, ubv))
            if v.size > 0:
                alphas = np.concatenate((lb_free[lbv] - x_free[lbv],
                                         ub_free[ubv] - x_free[ubv])) / (z[v] - x_free[v])
                i = np.argmin(alphas)
                i_free = v[i]
                alpha = alphas[i]
                x_free *= 1 - alpha
                x_free += alpha * z
                x[free_set] = x_free
                if i < lbv.size:
                    on_bound[free_set[i_free]] = -1.0
                else:
                    on_bound[free_set[i_free]] = 1.0
            else:
                x[free_set] = z
                break
        r, cost_new = _cost(A, x, b)
        cost_change = cost - cost_new
        if cost_change < tol * cost:
            terminated = True
        cost = cost_new
        g = A.T.dot(r)
        optimality = _kkt_optimality(g, on_bound)
    return x
