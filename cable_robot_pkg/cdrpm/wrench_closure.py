"""Wrench closure of a cable robot: can positive cable tensions balance *any* wrench?

Beyond the paper: Aref & Taghirad design the Neuron so that "force feasibility is achieved
within the whole determined geometric workspace" (section I) but never check it. A pose is
wrench-closed (Gouttefarde et al., the paper's ref. [13]) when every platform wrench w can be
produced by strictly positive tensions t: ``W t = w``, with the 6 x n structure matrix

    W = [ u_1          ...  u_n         ]      u_i = (A_i - B_i) / L_i = -S_i  (cable pull)
        [ (R b_i) x u_1 ... (R b_i) x u_n ]      moments about the centroid G.

Equivalent test: rank W = 6 and W has a strictly positive null vector. For n = 8 the null space
is two-dimensional; with basis rows ``N_i`` (one 2-vector per cable), a positive null vector
``N lambda > 0`` exists iff the eight 2-vectors lie strictly inside one open half-plane, i.e.
iff the largest angular gap between them exceeds pi. That test is exact, cheap and vectorised
(batched SVD); :func:`wrench_closed_lp` solves the same question with a linear program for
cross-checking and for other cable counts.
"""
from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike
from scipy.optimize import linprog

from cable_robot_pkg.cdrpm.kinematics import as_pose_arrays

if TYPE_CHECKING:
    from cable_robot_pkg.cdrpm.description import RobotDescription

#: Relative singular-value threshold below which W is rank deficient.
RANK_TOL = 1e-9


def structure_matrix(desc: RobotDescription, positions: ArrayLike,
                     rotations: ArrayLike) -> np.ndarray:
    """Structure (wrench) matrices W, (N, 6, n), for N poses."""
    positions, rotations = as_pose_arrays(positions, rotations)
    if rotations.ndim == 2:
        rb = np.broadcast_to(desc.platform_points @ rotations.T,
                             (positions.shape[0],) + desc.platform_points.shape)
    else:
        rb = np.einsum('mij,nj->mni', rotations, desc.platform_points)
    pull = desc.frame_points[None] - (positions[:, None, :] + rb)
    lengths = np.linalg.norm(pull, axis=-1, keepdims=True)
    u = pull / np.where(lengths > 0, lengths, 1.0)
    moment = np.cross(rb, u)
    return np.concatenate([u, moment], axis=-1).transpose(0, 2, 1)


def wrench_closure(desc: RobotDescription, positions: ArrayLike, rotations: ArrayLike,
                   chunk: int = 4096) -> tuple[np.ndarray, np.ndarray]:
    """Wrench-closure test of N poses.

    Returns ``(closed, margin)``: boolean (N,) and, for n = 8, the angular margin (rad) by
    which the largest gap between the null-space rows exceeds pi (> 0 iff closed; -pi when W
    is rank deficient). For other cable counts the margin is the LP's minimum normalised
    tension (> 0 iff closed).
    """
    positions, rotations = as_pose_arrays(positions, rotations)
    total = positions.shape[0]
    closed = np.zeros(total, dtype=bool)
    margin = np.full(total, -np.pi)
    for start in range(0, total, chunk):
        stop = min(start + chunk, total)
        rot = rotations if rotations.ndim == 2 else rotations[start:stop]
        mats = structure_matrix(desc, positions[start:stop], rot)
        if desc.n_cables == 8:
            closed[start:stop], margin[start:stop] = _closure_two_dim_null(mats)
        else:
            for k, mat in enumerate(mats):
                ok, value = wrench_closed_lp(mat)
                closed[start + k], margin[start + k] = ok, value
    return closed, margin


def _closure_two_dim_null(mats):
    """Exact test for 6 x 8 matrices via the half-plane condition on the 2-D null space."""
    _, sing, vt = np.linalg.svd(mats)
    full_rank = sing[:, 5] > RANK_TOL * sing[:, 0]
    null = vt[:, 6:, :]                                   # (m, 2, 8): rows span null(W)
    rows = np.transpose(null, (0, 2, 1))                  # (m, 8, 2): N_i per cable
    norms = np.linalg.norm(rows, axis=-1)
    nonzero = np.all(norms > 1e-9, axis=1)
    angles = np.sort(np.arctan2(rows[..., 1], rows[..., 0]), axis=1)
    gaps = np.diff(angles, axis=1)
    wrap = angles[:, 0] + 2 * np.pi - angles[:, -1]
    largest = np.maximum(gaps.max(axis=1), wrap)
    margin = np.where(full_rank & nonzero, largest - np.pi, -np.pi)
    return margin > 1e-9, margin


def wrench_closed_lp(mat: ArrayLike, tol: float = 1e-9) -> tuple[bool, float]:

    """LP test: maximise s subject to W t = 0, t_i >= s, sum t = 1; closed iff rank 6, s > 0.

    Returns ``(closed, s)``.
    """
    mat = np.asarray(mat, dtype=float)
    m, n = mat.shape
    if np.linalg.matrix_rank(mat, tol=RANK_TOL * np.linalg.norm(mat, 2)) < m:
        return False, -np.pi
    # Variables (t_1..t_n, s): minimise -s.
    cost = np.zeros(n + 1)
    cost[-1] = -1.0
    a_eq = np.zeros((m + 1, n + 1))
    a_eq[:m, :n] = mat
    a_eq[m, :n] = 1.0
    b_eq = np.zeros(m + 1)
    b_eq[m] = 1.0
    a_ub = np.hstack([-np.eye(n), np.ones((n, 1))])     # s - t_i <= 0
    res = linprog(cost, A_ub=a_ub, b_ub=np.zeros(n), A_eq=a_eq, b_eq=b_eq,
                  bounds=[(0, None)] * n + [(None, None)], method='highs')
    if res.status != 0:
        return False, -np.pi
    s = float(res.x[-1])
    return s > tol, s
