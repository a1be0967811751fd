"""The paper's forward kinematics: Newton-Raphson on the 49 constraint equations of eq. (4).

Almonacid et al. (2003, section III-C) model the 6-UPS robot with ring 1 as ground and
``nb = 7`` moving bodies: the platform (ring 2) and one body per actuator ("discarding one of
the two parts of each actuator, and making the prismatic and universal joints coincide"), each
with the generalized coordinates ``q_k = [x, y, z, e0, e1, e2, e3]`` (49 in all), and solve

    phi(q) = [phi^K (36); phi^D (6); phi^P (7)] = 0                          (4)

by Newton-Raphson. Here, for leg i (body k, frame origin at the spherical joint B_i, z_k along
the actuator from A_i to B_i, x_k the universal joint's cross axis on the leg):

* phi^K, 6 per leg: spherical joint ``r_k - (r_p + A_p s_Bi) = 0`` (3); the prismatic axis
  through the universal joint centre ``x_k . (A_i - r_k) = 0``, ``y_k . (A_i - r_k) = 0`` (2);
  the universal joint's crossed axes ``u_i . x_k = 0`` with ``u_i`` the base axis, tangent to
  ring 1 at A_i (1);
* phi^D, 1 per leg: the actuator length ``z_k . (r_k - A_i) - C_i = 0``;
* phi^P, 7: ``(e . e - 1) / 2 = 0`` for the platform and each leg body.

The Jacobian phi_q is formed by central differences (this is the reference formulation, not the
fast path); its determinant is the paper's singularity test (step 5). The planner's fast path,
:func:`paramotion.gough_stewart.forward_kinematics`, eliminates the leg bodies: a leg-length
Newton solve on the platform's 7 coordinates (six ``|r_ABi|^2 = C_i^2`` and one
normalisation). :func:`compare_with_leg_length_solve` and test_climber_fk.py check that the two
give the same pose.
"""
import math
import time
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from paramotion import gough_stewart as gs

N_COORDS = 49


@dataclass(frozen=True)
class ConstraintFKResult:
    """Solution of eq. (4): the platform pose, every body's coordinates and the solve's health."""

    position: np.ndarray          # platform position in the base frame (3,)
    rotation: np.ndarray          # platform rotation matrix (3, 3)
    q: np.ndarray                 # the 49 generalized coordinates
    iterations: int
    converged: bool
    residual: float               # max |phi(q)|
    det_phi_q: float              # determinant of the (normalised) constraint Jacobian


def universal_axes(geom: gs.GoughStewartGeometry) -> np.ndarray:
    """Base axes u_i (6, 3) of the universal joints: tangent to ring 1 at each anchor."""
    a = np.asarray(geom.base_anchors, dtype=float)
    u = np.stack([-a[:, 1], a[:, 0], np.zeros(len(a))], axis=1)
    return u / np.linalg.norm(u, axis=1, keepdims=True)


def coordinates_from_pose(geom: gs.GoughStewartGeometry, position: ArrayLike,
                          rotation: ArrayLike) -> np.ndarray:
    """The 49 coordinates of the assembly whose platform is at (position, rotation)."""
    position = np.asarray(position, dtype=float)
    rotation = np.asarray(rotation, dtype=float)
    q = [position, gs.quaternion_from_matrix(rotation)]
    for a, s, u in zip(geom.base_anchors, geom.platform_anchors, universal_axes(geom)):
        b = position + rotation @ s
        z = (b - a) / np.linalg.norm(b - a)
        x = np.cross(z, u)
        x /= np.linalg.norm(x)
        q += [b, gs.quaternion_from_matrix(np.stack([x, np.cross(z, x), z], axis=1))]
    return np.concatenate(q)


def _matrices(e):
    """Rotation matrices (n, 3, 3) of Euler parameters (n, 4): A = (2e0^2-1)I + 2(ee^T+e0 e~)."""
    e0, v = e[:, 0], e[:, 1:]
    tilde = np.zeros((len(e), 3, 3))
    tilde[:, 0, 1], tilde[:, 0, 2] = -v[:, 2], v[:, 1]
    tilde[:, 1, 0], tilde[:, 1, 2] = v[:, 2], -v[:, 0]
    tilde[:, 2, 0], tilde[:, 2, 1] = -v[:, 1], v[:, 0]
    return ((2 * e0 ** 2 - 1)[:, None, None] * np.eye(3)
            + 2 * (v[:, :, None] * v[:, None, :] + e0[:, None, None] * tilde))


def constraints(geom: gs.GoughStewartGeometry, q: ArrayLike, lengths: ArrayLike) -> np.ndarray:
    """phi(q) of eq. (4): [phi^K (36), phi^D (6), phi^P (7)]."""
    bodies = np.asarray(q, dtype=float).reshape(7, 7)
    r, e = bodies[:, :3], bodies[:, 3:]
    rot = _matrices(e)
    a = np.asarray(geom.base_anchors, dtype=float)
    s = np.asarray(geom.platform_anchors, dtype=float)
    r_leg, rot_leg = r[1:], rot[1:]
    x, y, z = rot_leg[:, :, 0], rot_leg[:, :, 1], rot_leg[:, :, 2]
    spherical = r_leg - (r[0] + s @ rot[0].T)
    w = a - r_leg
    phi_k = np.concatenate([spherical, np.einsum('ij,ij->i', x, w)[:, None],
                            np.einsum('ij,ij->i', y, w)[:, None],
                            np.einsum('ij,ij->i', universal_axes(geom), x)[:, None]], axis=1)
    phi_d = np.einsum('ij,ij->i', z, -w) - np.asarray(lengths, dtype=float)
    phi_p = 0.5 * (np.einsum('ij,ij->i', e, e) - 1.0)
    return np.concatenate([phi_k.reshape(-1), phi_d, phi_p])


def constraint_jacobian(geom: gs.GoughStewartGeometry, q: ArrayLike, lengths: ArrayLike,
                        step: float = 1e-7) -> np.ndarray:
    """phi_q (49, 49) by central differences."""
    q = np.asarray(q, dtype=float)
    jac = np.empty((N_COORDS, N_COORDS))
    for k in range(N_COORDS):
        dq = np.zeros(N_COORDS)
        dq[k] = step
        jac[:, k] = (constraints(geom, q + dq, lengths)
                     - constraints(geom, q - dq, lengths)) / (2 * step)
    return jac


def forward_kinematics_49(geom: gs.GoughStewartGeometry, lengths: ArrayLike,
                          guess_position: ArrayLike, guess_rotation: ArrayLike,
                          tol: float = 1e-12,
                          max_iter: int = 30) -> ConstraintFKResult:
    """Newton-Raphson on eq. (4) from the assembly at the guessed platform pose."""
    q = coordinates_from_pose(geom, guess_position, guess_rotation)
    it, converged, det = 0, False, math.nan
    for it in range(1, max_iter + 1):
        phi = constraints(geom, q, lengths)
        jac = constraint_jacobian(geom, q, lengths)
        scale = np.abs(jac).max(axis=1, keepdims=True)
        sign, logdet = np.linalg.slogdet(jac / scale)
        det = float(sign * math.exp(logdet)) if sign != 0 else 0.0
        if det == 0.0:
            break
        q = q - np.linalg.solve(jac, phi)
        if np.abs(constraints(geom, q, lengths)).max() < tol:
            converged = True
            break
    residual = float(np.abs(constraints(geom, q, lengths)).max())
    e = q[3:7] / np.linalg.norm(q[3:7])
    return ConstraintFKResult(q[:3].copy(), gs.matrix_from_quaternion(e), q, it, converged,
                              residual, det)


def compare_with_leg_length_solve(poses: int = 100, seed: int = 0) -> dict:
    """Random reachable poses of the climber: both solvers from the same guess (1 cm, 2 deg
    off); largest pose differences, residuals, iterations and time per solve."""
    from climber_pkg.robot import load_robot_config
    geom = load_robot_config().geometry
    rng = np.random.default_rng(seed)
    dp, dr, res, its, its7 = [], [], [], [], []
    t49 = t7 = 0.0
    while len(dp) < poses:
        pos = np.array([*rng.uniform(-0.04, 0.04, 2), rng.uniform(0.35, 0.75)])
        rot = gs.rotation_matrix(np.radians(rng.uniform(-8, 8, 3)))
        lengths = gs.inverse_kinematics(geom, pos, rot)
        if not (np.all(lengths > geom.leg_min) and np.all(lengths < geom.leg_max)):
            continue
        guess_p = pos + rng.normal(scale=0.01 / math.sqrt(3), size=3)
        guess_r = gs.rotation_matrix(np.radians(rng.normal(scale=2 / math.sqrt(3), size=3))) @ rot
        t0 = time.perf_counter()
        fk49 = forward_kinematics_49(geom, lengths, guess_p, guess_r)
        t1 = time.perf_counter()
        fk7 = gs.forward_kinematics(geom, lengths, guess_p, guess_r, backend='numpy')
        t2 = time.perf_counter()
        t49 += t1 - t0
        t7 += t2 - t1
        dp.append(float(np.abs(fk49.position - fk7.position).max()))
        dr.append(float(np.abs(fk49.rotation - fk7.rotation).max()))
        res.append(fk49.residual)
        its.append(fk49.iterations)
        its7.append(fk7.iterations)
    return {'poses': poses, 'max_position_diff_m': max(dp), 'max_rotation_diff': max(dr),
            'max_residual': max(res), 'iterations_median': float(np.median(its)),
            'reduced_iterations_median': float(np.median(its7)),
            'paper_s_per_solve': t49 / poses, 'reduced_s_per_solve': t7 / poses}
