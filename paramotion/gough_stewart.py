"""Gough-Stewart (6-UPS / 6-SPS) platform kinematics, shared by every parallel robot here.

Implements the kinematics of Almonacid, Saltaren, Aracil and Reinoso, "Motion Planning of a
Climbing Parallel Robot" (IEEE T-RA 2003), section III:

* inverse kinematics, eqs. (2)-(3): ``r_ABi = r_1 + A_1 s_1^Bi - s_0^Ai``, ``C_i = |r_ABi|``;
* forward kinematics by Newton-Raphson on the constraint equations written with Euler
  parameters, eq. (4). We use the paper's *reduced* form with ring 1 (the base) as ground: the
  only moving body is the platform, with generalized coordinates ``q = [r, e0, e1, e2, e3]``
  (7 unknowns). The holonomic joint constraints phi^K are eliminated by construction (the legs
  are the vectors ``r_ABi`` between the joint centres), leaving the six driving constraints
  phi^D (``(r_ABi . r_ABi - C_i^2) / 2 = 0``) and the Euler-parameter normalisation phi^P
  (``(e . e - 1) / 2 = 0``): a square 7 x 7 Newton system, warm-started from the last pose;
  Naming note: this 7-unknown system is a leg-length Newton solve, a further reduction of the
  paper's own reduced form (nb = 7 bodies: the platform and one body per actuator, 49
  coordinates and constraints), which ``climber_pkg.constraint_fk.forward_kinematics_49``
  implements; test/test_climber_fk.py checks that both give the same pose;
* the rotation matrix from Euler parameters, ``A = (2 e0^2 - 1) I + 2 (e e^T + e0 e~)``
  (paper section IV-E step 3, Haug 1989);
* the inverse Jacobian and its conditioning for singularity detection (paper step 5: "a singular
  configuration is detected by the Jacobian matrix determinant").

Frames: the base frame is attached to the base ring (ring 1 of the climber, the fixed upper
platform of an isolator); the platform frame to the moving platform (ring 2). A pose is the
platform frame's position (3,) and rotation matrix (3, 3) in the base frame. Units: metres.

Everything is numpy only (no rclpy) so that it can be unit-tested and reused alone. Speed:
``python -m climber_pkg.fk_benchmark`` prints solves per second and iteration counts.
"""
from __future__ import annotations

import math
import os
import threading
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
from numpy.typing import ArrayLike
from scipy.linalg.lapack import dgesdd as _dgesdd
from scipy.linalg.lapack import dgesv as _dgesv

from paramotion.backend import BACKENDS, resolve_backend, usable_cores  # noqa: F401 (re-exported)

__all__ = [
    'DEFAULT_MAX_CONDITION', 'BatchFKResult', 'FKResult', 'GoughStewartGeometry',
    'SingularPoseError', 'UnreachablePoseError', 'check_lengths', 'check_pose',
    'forward_kinematics', 'forward_kinematics_batch', 'inverse_kinematics', 'jacobian',
    'jacobian_condition', 'matrix_from_quaternion', 'quaternion_from_matrix',
    'rotation_matrix', 'rpy_from_matrix',
]

#: Condition number of the homogenised inverse Jacobian above which a pose is treated as
#: singular: lengths measured to 1e-6 m would then give pose errors above ~1e-3 m.
DEFAULT_MAX_CONDITION = 1000.0


class SingularPoseError(ValueError):
    """The pose (or the pose the leg lengths lead to) is at or too near a singularity."""


class UnreachablePoseError(ValueError):
    """A leg length lies outside the actuator stroke [leg_min, leg_max]."""


@dataclass(frozen=True, eq=False)     # identity equality/hash: the fields are arrays
class GoughStewartGeometry:
    """Joint centres and actuator stroke of a 6-UPS platform.

    ``base_anchors[i]`` (universal joint A_i, vector s_0^Ai of eq. (2)) and
    ``platform_anchors[i]`` (spherical joint B_i, s_1^Bi) are the two ends of leg i.
    """

    base_anchors: np.ndarray
    platform_anchors: np.ndarray
    leg_min: float
    leg_max: float

    def __post_init__(self):
        base = np.array(self.base_anchors, dtype=float)
        plat = np.array(self.platform_anchors, dtype=float)
        if base.shape != (6, 3) or plat.shape != (6, 3):
            raise ValueError('base_anchors and platform_anchors must both have shape (6, 3), '
                             f'got {base.shape} and {plat.shape}')
        if not (np.all(np.isfinite(base)) and np.all(np.isfinite(plat))):
            raise ValueError('anchor coordinates must be finite')
        if not (np.isfinite(self.leg_min) and np.isfinite(self.leg_max)
                and 0.0 < self.leg_min < self.leg_max):
            raise ValueError(f'need 0 < leg_min < leg_max, got leg_min={self.leg_min} '
                             f'leg_max={self.leg_max}')
        base.setflags(write=False)
        plat.setflags(write=False)
        object.__setattr__(self, 'base_anchors', base)
        object.__setattr__(self, 'platform_anchors', plat)
        object.__setattr__(self, 'leg_min', float(self.leg_min))
        object.__setattr__(self, 'leg_max', float(self.leg_max))

    @classmethod
    def from_rings(cls, base_radius: float, platform_radius: float, base_half_angle: float,
                   platform_half_angle: float, leg_min: float,
                   leg_max: float) -> GoughStewartGeometry:
        """Semi-regular hexagons: joints in pairs at ``k * 120 deg +- half_angle``.

        Platform pairs are rotated by 60 deg, and leg i joins base joint i to the platform
        joint next to it, so the legs zig-zag around the rings (the classic octahedral layout).
        Angles in radians; anchors lie in the z = 0 plane of their ring.
        """
        if not (base_radius > 0 and platform_radius > 0):
            raise ValueError('ring radii must be positive')
        if not (0 < base_half_angle < np.pi / 6 and 0 < platform_half_angle < np.pi / 6):
            raise ValueError('half angles must lie in (0, 30 deg) to keep six distinct joints')
        k = np.repeat(np.arange(3), 2)
        sign = np.tile([-1.0, 1.0], 3)
        base_ang = k * 2 * np.pi / 3 + sign * base_half_angle
        # Leg 2k-1 / 2k of base pair k meet the platform pairs at k*120 -+ 60 deg.
        plat_ang = k * 2 * np.pi / 3 + sign * (np.pi / 3 - platform_half_angle)
        base = np.stack([base_radius * np.cos(base_ang), base_radius * np.sin(base_ang),
                         np.zeros(6)], axis=1)
        plat = np.stack([platform_radius * np.cos(plat_ang),
                         platform_radius * np.sin(plat_ang), np.zeros(6)], axis=1)
        return cls(base, plat, leg_min, leg_max)

    @property
    def characteristic_length(self) -> float:
        """Mean platform-anchor radius, used to homogenise the Jacobian's moment columns."""
        return float(np.mean(np.linalg.norm(self.platform_anchors, axis=1)))


class FKResult(NamedTuple):
    """Forward kinematics solution: platform pose in the base frame.

    ``rotation`` is returned read-only: the solver remembers the Euler parameters of the last
    rotations it returned, so that warm-starting from a previous result skips the matrix to
    quaternion conversion.
    """

    position: np.ndarray
    rotation: np.ndarray
    iterations: int
    converged: bool
    jacobian_condition: float


@dataclass(frozen=True)
class BatchFKResult:
    """Batched forward kinematics; entries whose ``converged`` is False must not be used.

    ``singular[k]`` is True when pose k was refused as (near-)singular.
    """

    positions: np.ndarray
    rotations: np.ndarray
    iterations: np.ndarray
    converged: np.ndarray
    jacobian_condition: np.ndarray
    singular: np.ndarray


# --------------------------------------------------------------------------------------------
# Rotations and Euler parameters
# --------------------------------------------------------------------------------------------

def matrix_from_quaternion(e: ArrayLike, normalize: bool = True) -> np.ndarray:
    """Rotation matrix from Euler parameters ``(e0, e1, e2, e3)`` = (w, x, y, z), vectorised.

    ``A = (2 e0^2 - 1) I + 2 (e e^T + e0 e~)`` (Haug 1989; paper section IV-E step 3). The input
    is normalised first (unless ``normalize`` is False, as inside the Newton iteration where
    the normalisation is one of the constraint equations).
    """
    q = np.asarray(e, dtype=float)
    if normalize:
        q = q / np.linalg.norm(q, axis=-1, keepdims=True)
    w, x, y, z = q[..., 0], q[..., 1], q[..., 2], q[..., 3]
    out = np.empty(q.shape[:-1] + (3, 3))
    out[..., 0, 0] = 2 * (w * w + x * x) - 1
    out[..., 0, 1] = 2 * (x * y - w * z)
    out[..., 0, 2] = 2 * (x * z + w * y)
    out[..., 1, 0] = 2 * (x * y + w * z)
    out[..., 1, 1] = 2 * (w * w + y * y) - 1
    out[..., 1, 2] = 2 * (y * z - w * x)
    out[..., 2, 0] = 2 * (x * z - w * y)
    out[..., 2, 1] = 2 * (y * z + w * x)
    out[..., 2, 2] = 2 * (w * w + z * z) - 1
    return out


def quaternion_from_matrix(rotation: ArrayLike) -> np.ndarray:
    """Euler parameters (w, x, y, z) with w >= 0 of rotation matrices (..., 3, 3); Shepperd."""
    m = np.asarray(rotation, dtype=float)
    shape = m.shape[:-2]
    m = m.reshape(-1, 3, 3)
    tr = m[:, 0, 0] + m[:, 1, 1] + m[:, 2, 2]
    cand = np.stack([tr, m[:, 0, 0], m[:, 1, 1], m[:, 2, 2]], axis=1)
    pick = np.argmax(cand, axis=1)
    q = np.empty((m.shape[0], 4))
    for k in range(4):
        sel = pick == k
        if not np.any(sel):
            continue
        s = m[sel]
        if k == 0:
            t = np.sqrt(1.0 + tr[sel]) * 2
            q[sel] = np.stack([0.25 * t, (s[:, 2, 1] - s[:, 1, 2]) / t,
                               (s[:, 0, 2] - s[:, 2, 0]) / t, (s[:, 1, 0] - s[:, 0, 1]) / t], 1)
        elif k == 1:
            t = np.sqrt(1.0 + s[:, 0, 0] - s[:, 1, 1] - s[:, 2, 2]) * 2
            q[sel] = np.stack([(s[:, 2, 1] - s[:, 1, 2]) / t, 0.25 * t,
                               (s[:, 0, 1] + s[:, 1, 0]) / t, (s[:, 0, 2] + s[:, 2, 0]) / t], 1)
        elif k == 2:
            t = np.sqrt(1.0 + s[:, 1, 1] - s[:, 0, 0] - s[:, 2, 2]) * 2
            q[sel] = np.stack([(s[:, 0, 2] - s[:, 2, 0]) / t, (s[:, 0, 1] + s[:, 1, 0]) / t,
                               0.25 * t, (s[:, 1, 2] + s[:, 2, 1]) / t], 1)
        else:
            t = np.sqrt(1.0 + s[:, 2, 2] - s[:, 0, 0] - s[:, 1, 1]) * 2
            q[sel] = np.stack([(s[:, 1, 0] - s[:, 0, 1]) / t, (s[:, 0, 2] + s[:, 2, 0]) / t,
                               (s[:, 1, 2] + s[:, 2, 1]) / t, 0.25 * t], 1)
    q *= np.where(q[:, :1] < 0, -1.0, 1.0)
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    return q.reshape(shape + (4,))


def rotation_matrix(rpy_or_quat: ArrayLike) -> np.ndarray:
    """Rotation matrices from roll-pitch-yaw (..., 3) or Euler parameters (w, x, y, z) (..., 4).

    Roll-pitch-yaw are fixed-axis angles (REP 103): ``R = Rz(yaw) Ry(pitch) Rx(roll)``.
    """
    a = np.asarray(rpy_or_quat, dtype=float)
    if a.shape[-1] == 4:
        return matrix_from_quaternion(a)
    if a.shape[-1] != 3:
        raise ValueError(f'expected (..., 3) roll-pitch-yaw or (..., 4) quaternion, got {a.shape}')
    cr, sr = np.cos(a[..., 0]), np.sin(a[..., 0])
    cp, sp = np.cos(a[..., 1]), np.sin(a[..., 1])
    cy, sy = np.cos(a[..., 2]), np.sin(a[..., 2])
    out = np.empty(a.shape[:-1] + (3, 3))
    out[..., 0, 0] = cy * cp
    out[..., 0, 1] = cy * sp * sr - sy * cr
    out[..., 0, 2] = cy * sp * cr + sy * sr
    out[..., 1, 0] = sy * cp
    out[..., 1, 1] = sy * sp * sr + cy * cr
    out[..., 1, 2] = sy * sp * cr - cy * sr
    out[..., 2, 0] = -sp
    out[..., 2, 1] = cp * sr
    out[..., 2, 2] = cp * cr
    return out


def rpy_from_matrix(rotation: ArrayLike) -> np.ndarray:
    """Roll, pitch, yaw (..., 3) of rotation matrices (inverse of :func:`rotation_matrix`)."""
    m = np.asarray(rotation, dtype=float)
    roll = np.arctan2(m[..., 2, 1], m[..., 2, 2])
    pitch = np.arcsin(np.clip(-m[..., 2, 0], -1.0, 1.0))
    yaw = np.arctan2(m[..., 1, 0], m[..., 0, 0])
    return np.stack([roll, pitch, yaw], axis=-1)


# --------------------------------------------------------------------------------------------
# Inverse kinematics and Jacobian
# --------------------------------------------------------------------------------------------

def _leg_vectors(geom, position, rotation):
    """r_ABi of eq. (2) for every leg: (..., 6, 3)."""
    position = np.asarray(position, dtype=float)
    rotation = np.asarray(rotation, dtype=float)
    world_plat = np.einsum('...jk,ik->...ij', rotation, geom.platform_anchors)
    return position[..., None, :] + world_plat - geom.base_anchors, world_plat


def inverse_kinematics(geom: GoughStewartGeometry, position: ArrayLike,
                       rotation: ArrayLike) -> np.ndarray:
    """Leg lengths C_i, eqs. (2)-(3): ``C_i = |r_1 + A_1 s_1^Bi - s_0^Ai|``.

    ``position`` (..., 3) and ``rotation`` (..., 3, 3) give the platform pose in the base frame;
    returns (..., 6). Pure geometry: use :func:`check_pose` to also enforce stroke and
    singularity limits.
    """
    legs, _ = _leg_vectors(geom, position, rotation)
    return np.sqrt(np.einsum('...ij,...ij->...i', legs, legs))


def jacobian(geom: GoughStewartGeometry, position: ArrayLike,
             rotation: ArrayLike) -> np.ndarray:
    """Inverse Jacobian (..., 6, 6): row i = ``[u_i, (R p_i) x u_i]`` with u_i the unit leg.

    It maps the platform twist (linear velocity of the platform origin, angular velocity, both
    in the base frame) to leg rates: ``dC/dt = J [v; w]``. ``det(J) = 0`` at a singularity.
    """
    legs, world_plat = _leg_vectors(geom, position, rotation)
    u = legs / np.linalg.norm(legs, axis=-1, keepdims=True)
    return np.concatenate([u, np.cross(world_plat, u)], axis=-1)


def jacobian_condition(geom: GoughStewartGeometry, jac: ArrayLike) -> np.ndarray | float:
    """2-norm condition number of the homogenised inverse Jacobian(s) (..., 6, 6).

    The moment columns are divided by the geometry's characteristic length so that both halves
    are dimensionless and the number does not depend on the unit of length. Infinite when
    singular.
    """
    jac = np.array(jac, dtype=float)
    jac[..., 3:] /= geom.characteristic_length
    sv = np.linalg.svd(jac, compute_uv=False)
    with np.errstate(divide='ignore'):
        return np.where(sv[..., -1] > 0, sv[..., 0] / sv[..., -1], np.inf)


def check_lengths(geom: GoughStewartGeometry, lengths: ArrayLike,
                  name: str = 'leg lengths') -> np.ndarray:
    """Raise :class:`UnreachablePoseError` unless every length is finite and within stroke."""
    lengths = np.asarray(lengths, dtype=float)
    if not np.all(np.isfinite(lengths)):
        raise UnreachablePoseError(f'{name} are not finite: {lengths}')
    lo, hi = float(lengths.min()), float(lengths.max())
    if lo < geom.leg_min or hi > geom.leg_max:
        raise UnreachablePoseError(
            f'{name} span [{lo:.4f}, {hi:.4f}] m, outside the stroke '
            f'[{geom.leg_min:.4f}, {geom.leg_max:.4f}] m')
    return lengths


def check_pose(geom: GoughStewartGeometry, position: ArrayLike, rotation: ArrayLike,
               max_condition: float = DEFAULT_MAX_CONDITION
               ) -> tuple[np.ndarray, np.ndarray | float]:
    """Inverse kinematics of one pose, refusing unreachable and near-singular poses.

    Returns ``(lengths, condition)``; raises :class:`UnreachablePoseError` or
    :class:`SingularPoseError` with the offending numbers.
    """
    lengths = inverse_kinematics(geom, position, rotation)
    check_lengths(geom, lengths)
    cond = float(jacobian_condition(geom, jacobian(geom, position, rotation)))
    if not cond <= max_condition:
        raise SingularPoseError(f'pose is near-singular: Jacobian condition {cond:.3g} '
                                f'> {max_condition:.3g}')
    return lengths, cond


# --------------------------------------------------------------------------------------------
# Forward kinematics: Newton-Raphson on the Euler-parameter constraint equations (4)
# --------------------------------------------------------------------------------------------

def _constraint_jacobian(legs, plat, e):
    """Rows of phi_q for the six driving constraints, batched: (..., 6, 7).

    phi^D_i = (L_i . L_i - C_i^2) / 2 with L_i = r + A(e) p_i - b_i. Its gradient is
    ``[L_i, L_i^T d(A p_i)/de]``; for A of a unit quaternion,
    ``L^T d(A p)/de0 = 4 e0 (L . p) + 2 L . (e x p)`` and
    ``L^T d(A p)/de = 2 (e . p) L + 2 (L . e) p - 2 e0 (L x p)``.
    """
    e0 = e[..., 0:1, None]
    ev = e[..., None, 1:]
    lp = np.sum(legs * plat, axis=-1, keepdims=True)
    d0 = 4 * e0 * lp + 2 * np.sum(legs * np.cross(ev, plat), axis=-1, keepdims=True)
    dv = (2 * np.sum(ev * plat, axis=-1, keepdims=True) * legs
          + 2 * np.sum(legs * ev, axis=-1, keepdims=True) * plat
          - 2 * e0 * np.cross(legs, plat))
    return np.concatenate([legs, d0, dv], axis=-1)


def _haug_quadratic_forms(plat):
    """T[i, k] (6, 3, 4, 4): symmetric Q with ``(A_h(e) p_i)_k = e^T Q e`` for every leg.

    ``A_h(e) = (e0^2 - e.e) I + 2 e e^T + 2 e0 e~`` is the homogeneous form of the rotation
    matrix; Haug's ``A(e) = A_h(e) + (e^T e - 1) I`` (they agree on unit quaternions). Built by
    polarisation so that the Newton Jacobian costs one small matrix product per iteration.
    """
    def ah_p(e):
        e0, ev = e[0], e[1:]
        skew = np.array([[0, -ev[2], ev[1]], [ev[2], 0, -ev[0]], [-ev[1], ev[0], 0]])
        a = (e0 * e0 - ev @ ev) * np.eye(3) + 2 * np.outer(ev, ev) + 2 * e0 * skew
        return plat @ a.T                               # (6, 3)

    basis = np.eye(4)
    diag = [ah_p(basis[a]) for a in range(4)]
    t = np.empty((6, 3, 4, 4))
    for a in range(4):
        t[:, :, a, a] = diag[a]
        for b in range(a + 1, 4):
            t[:, :, a, b] = t[:, :, b, a] = 0.5 * (ah_p(basis[a] + basis[b]) - diag[a] - diag[b])
    return t


def _quat_from_matrix_scalar(m):
    """Shepperd's method for one rotation matrix, in plain floats (fast path of FK)."""
    (m00, m01, m02), (m10, m11, m12), (m20, m21, m22) = np.asarray(m, dtype=float).tolist()
    tr = m00 + m11 + m22
    if tr >= max(m00, m11, m22):
        t = 2.0 * math.sqrt(1.0 + tr)
        q = (0.25 * t, (m21 - m12) / t, (m02 - m20) / t, (m10 - m01) / t)
    elif m00 >= m11 and m00 >= m22:
        t = 2.0 * math.sqrt(1.0 + m00 - m11 - m22)
        q = ((m21 - m12) / t, 0.25 * t, (m01 + m10) / t, (m02 + m20) / t)
    elif m11 >= m22:
        t = 2.0 * math.sqrt(1.0 + m11 - m00 - m22)
        q = ((m02 - m20) / t, (m01 + m10) / t, 0.25 * t, (m12 + m21) / t)
    else:
        t = 2.0 * math.sqrt(1.0 + m22 - m00 - m11)
        q = ((m10 - m01) / t, (m02 + m20) / t, (m12 + m21) / t, 0.25 * t)
    n = math.sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3])
    if not n > 0.0:
        raise ValueError('guess rotation is not a rotation matrix')
    s = (1.0 if q[0] >= 0 else -1.0) / n
    return [q[0] * s, q[1] * s, q[2] * s, q[3] * s]


class _FKCache:
    """Per-geometry constants of the single-pose Newton solver (computed once per geometry).

    ``legs = aug @ m`` with ``aug = [p_i, 1, e_i]`` (6, 10) and ``m = [A^T; r; -b]`` (10, 3)
    gives all r_ABi of eq. (2) in one product; ``quad2`` holds ``2 (Q_ik + p_ik I)`` so that
    ``L_i^T quad2_i e`` is the Euler-parameter half of a phi_q row (Haug's A adds the
    ``(e.e - 1) p`` term to the homogeneous form).
    """

    def __init__(self, geom):
        plat = geom.platform_anchors
        self.aug = np.hstack([plat, np.ones((6, 1)), np.eye(6)])
        self.m_tail = -geom.base_anchors
        quad = _haug_quadratic_forms(plat) + plat[:, :, None, None] * np.eye(4)
        self.quad2 = np.ascontiguousarray((2.0 * quad).reshape(72, 4))
        self.rho = geom.characteristic_length
        self.inv_rho = 1.0 / self.rho
        self.plat = np.ascontiguousarray(plat)
        self.base = np.ascontiguousarray(geom.base_anchors)
        self.half_inv_rho = 0.5 * self.inv_rho
        self.t_base = np.zeros((7, 6))
        self.t_base[:3, :3] = np.eye(3)
        self.ones3 = np.ones(3)
        self.m_base = np.zeros((10, 3))
        self.m_base[4:] = self.m_tail
        self.local = threading.local()     # per-thread work arrays, see buffers()

    def buffers(self):
        """This thread's work arrays (reused across solves; every solve overwrites them).

        Returns ``(m, m_head, legs, jac, jac_l, jac_e, jac_n, jac_6, legs_row, qe, qe_flat,
        tmat, tmat_e, inv_c, inv_c_col)``: ``m`` (10, 3) with its constant tail ``-b`` set
        and ``m_head`` its flat view; ``jac`` (7, 7) whose row 6 starts with three zeros that
        are never written, with views of its blocks; ``qe`` (6, 3, 4) for ``quad2 e``;
        ``tmat`` (7, 6) whose identity and zero blocks are never written (``tmat_e`` is its
        lower-right block); ``inv_c`` (6,) for 1 / C and ``inv_c_col`` its (6, 1) view.
        Allocating them per solve cost more than a tenth of the solve time.
        """
        bufs = getattr(self.local, 'bufs', None)
        if bufs is None:
            m = self.m_base.copy()
            legs = np.empty((6, 3))
            jac = np.zeros((7, 7))
            qe_flat = np.empty(72)
            tmat = self.t_base.copy()
            inv_c = np.empty(6)
            bufs = (m, m.reshape(30), legs, jac, jac[:6, :3], jac[:6, 3:].reshape(6, 1, 4),
                    jac[6, 3:], jac[:6], legs[:, None, :], qe_flat.reshape(6, 3, 4), qe_flat,
                    tmat, tmat[3:, 3:], inv_c, inv_c[:, None])
            self.local.bufs = bufs
        return bufs


_FK_CACHES = {}
_new_tuple = tuple.__new__     # builds an FKResult without NamedTuple.__new__'s overhead
_dot = np.dot            # np.dot has less per-call overhead than matmul on tiny arrays
# id(rotation) -> (rotation, Euler parameters) of the last few (read-only) FK rotations: the
# rotation object itself is kept, so an id is never matched by a different, recycled array.
_RECENT_QUATERNIONS = {}


def _fk_cache(geom):
    cache = _FK_CACHES.get(id(geom))
    if cache is None or cache[0] is not geom:
        if len(_FK_CACHES) > 64:
            _FK_CACHES.clear()
        cache = (geom, _FKCache(geom))
        _FK_CACHES[id(geom)] = cache
    return cache[1]


def forward_kinematics(geom: GoughStewartGeometry, lengths: ArrayLike, guess_position: ArrayLike,
                       guess_rotation: ArrayLike, tol: float = 1e-12, max_iter: int = 30,
                       max_condition: float = DEFAULT_MAX_CONDITION,
                       backend: str = 'auto') -> FKResult:
    """Platform pose from the six leg lengths by Newton-Raphson on eq. (4), warm-started.

    Unknowns ``q = [x, y, z, e0, e1, e2, e3]``; equations: the six driving constraints
    ``phi^D_i = (r_ABi . r_ABi - C_i^2) / 2`` and the normalisation
    ``phi^P = (e . e - 1) / 2``. Iterates ``phi_q dq = -phi`` from the guess (normally the last
    known pose) until every leg-length residual ``|r_ABi| - C_i`` is below ``tol`` metres.

    Raises :class:`UnreachablePoseError` if a length is outside the stroke and
    :class:`SingularPoseError` if the constraint Jacobian becomes singular during the iteration
    or the solution's homogenised Jacobian condition exceeds ``max_condition`` (near a
    singularity several assembly modes merge and the solution cannot be trusted). ``converged``
    is False when ``max_iter`` was exhausted.

    ``backend`` (see :func:`paramotion.backend.resolve_backend`): ``'numba'`` runs the
    iteration and the condition number in one compiled call
    (:func:`paramotion.gough_stewart_numba.fk_single_kernel`, the batched solver's Newton
    step); ``'numpy'`` the code below. Both stop at the same residual test; the poses agree to
    rounding (~1e-15 m).
    """
    c = np.asarray(lengths, dtype=float).reshape(6)
    cl = c.tolist()
    if not (min(cl) >= geom.leg_min and max(cl) <= geom.leg_max and math.isfinite(sum(cl))):
        check_lengths(geom, c)            # raises with the numbers (NaN included)
    cache = _FK_CACHES.get(id(geom))
    cache = cache[1] if cache is not None and cache[0] is geom else _fk_cache(geom)
    aug, quad2, ones3 = cache.aug, cache.quad2, cache.ones3
    # Squared lengths and per-leg tolerances on |L|^2 - C^2 as plain floats: the residual test
    # is done without numpy calls (same IEEE arithmetic as the array expressions).
    c0_, c1_, c2_, c3_, c4_, c5_ = cl
    s0_, s1_, s2_, s3_, s4_, s5_ = (c0_ * c0_, c1_ * c1_, c2_ * c2_, c3_ * c3_, c4_ * c4_,
                                    c5_ * c5_)
    tw = 2.0 * tol
    t0_, t1_, t2_, t3_, t4_, t5_ = tw * c0_, tw * c1_, tw * c2_, tw * c3_, tw * c4_, tw * c5_
    r0, r1, r2 = np.asarray(guess_position, dtype=float).reshape(3).tolist()
    known = _RECENT_QUATERNIONS.get(id(guess_rotation))
    if known is not None and known[0] is guess_rotation:
        e0, e1, e2, e3 = known[1]
    else:
        e0, e1, e2, e3 = _quat_from_matrix_scalar(guess_rotation)
    if (backend == 'auto' and _AUTO_BACKEND[0] == os.environ.get('PARAMOTION_BACKEND')
            and _AUTO_BACKEND[1] == 'numba') or resolve_backend(backend) == 'numba':
        if backend == 'auto':
            _AUTO_BACKEND[:] = [os.environ.get('PARAMOTION_BACKEND'), 'numba']
        return _forward_kinematics_numba(cache, c, r0, r1, r2, e0, e1, e2, e3, tol, max_iter,
                                         max_condition)
    # Solve phi_q x = [|L|^2 - C^2, e.e - 1], i.e. x = 2 dq, so that phi_q's leg columns are
    # L itself. jac_n (phi_q's last row, e) doubles as the array of e.
    try:
        bufs = cache.local.bufs
    except AttributeError:                 # first solve on this thread
        bufs = cache.buffers()
    (m, m_head, legs, jac, jac_l, jac_e, jac_n, jac_6, legs_row, qe, qe_flat, tmat, tmat_e,
     inv_c, inv_c_col) = bufs
    converged = False
    it = 0
    while True:
        # m_head[:12] = [A^T; r] flattened, Haug's A = (2 e0^2 - 1) I + 2 (e e^T + e0 e~)
        # written with shared products (scaling by 2 is exact in floating point, so
        # (2 a) b + (2 c) d rounds exactly as 2 (a b + c d)).
        a0, a1, a2, a3 = 2 * e0, 2 * e1, 2 * e2, 2 * e3
        w = a0 * e0 - 1
        p12, p03, p13, p02, p23, p01 = a1 * e2, a0 * e3, a1 * e3, a0 * e2, a2 * e3, a0 * e1
        m_head[:12] = (w + a1 * e1, p12 + p03, p13 - p02, p12 - p03, w + a2 * e2, p23 + p01,
                       p13 + p02, p23 - p01, w + a3 * e3, r0, r1, r2)
        _dot(aug, m, out=legs)
        q0, q1, q2, q3, q4, q5 = _dot(legs * legs, ones3).tolist()
        q0 -= s0_
        q1 -= s1_
        q2 -= s2_
        q3 -= s3_
        q4 -= s4_
        q5 -= s5_
        ee = e0 * e0 + e1 * e1 + e2 * e2 + e3 * e3 - 1.0
        if (abs(q0) < t0_ and abs(q1) < t1_ and abs(q2) < t2_ and abs(q3) < t3_
                and abs(q4) < t4_ and abs(q5) < t5_ and abs(ee) < tol):
            converged = True
            break
        if it >= max_iter:
            break
        jac_n[:] = (e0, e1, e2, e3)
        jac_l[...] = legs
        _dot(quad2, jac_n, out=qe_flat)
        np.matmul(legs_row, qe, out=jac_e)
        # (the wrapper converts the right-hand side itself: a tuple is cheaper than an array)
        _, _, x, info = _dgesv(jac, (q0, q1, q2, q3, q4, q5, ee))
        if info != 0:
            raise SingularPoseError('forward kinematics met a singular constraint Jacobian '
                                    f'at iteration {it}')
        d0, d1, d2, d3, d4, d5, d6 = x.tolist()
        r0 -= 0.5 * d0
        r1 -= 0.5 * d1
        r2 -= 0.5 * d2
        e0 -= 0.5 * d3
        e1 -= 0.5 * d4
        e2 -= 0.5 * d5
        e3 -= 0.5 * d6
        it += 1
        if not math.isfinite(e0 + e1 + e2 + e3 + r0 + r1 + r2):
            raise SingularPoseError('forward kinematics diverged (non-finite iterate) at '
                                    f'iteration {it}')
    n = math.sqrt(e0 * e0 + e1 * e1 + e2 * e2 + e3 * e3)
    if not n > 1e-6:
        raise SingularPoseError('forward kinematics collapsed the Euler parameters to zero')
    e0, e1, e2, e3 = e0 / n, e1 / n, e2 / n, e3 / n
    # Haug's A of the normalised e, row-major (same products as in the loop).
    a0, a1, a2, a3 = 2 * e0, 2 * e1, 2 * e2, 2 * e3
    w = a0 * e0 - 1
    p12, p03, p13, p02, p23, p01 = a1 * e2, a0 * e3, a1 * e3, a0 * e2, a2 * e3, a0 * e1
    rot = np.array((w + a1 * e1, p12 - p03, p13 + p02, p12 + p03, w + a2 * e2, p23 - p01,
                    p13 - p02, p23 + p01, w + a3 * e3)).reshape(3, 3)
    # Homogenised inverse Jacobian [u_i, (R p_i) x u_i / rho]: the moment (R p_i) x L_i is
    # 0.5 (L_i^T dA p_i / de) E^T with E = [-e, e0 I + e~] (Haug); the Haug extra term drops
    # out because E e = 0. The phi_q rows of the last Newton step are reused (that iterate is
    # within the previous residual, ~1e-7 m, of the solution: the same condition number to
    # many digits); with no step taken they are evaluated at the guess, which is the solution.
    if it == 0:
        jac_l[...] = legs
        jac_n[:] = (e0, e1, e2, e3)
        _dot(quad2, jac_n, out=qe_flat)
        np.matmul(legs_row, qe, out=jac_e)
    # jn = diag(1 / C) [L | phi_q^e] blockdiag(I, 0.5 E^T / rho): one product.
    h = cache.half_inv_rho
    tmat_e[...] = ((h * -e1, h * -e2, h * -e3), (h * e0, h * e3, h * -e2),
                    (h * -e3, h * e0, h * e1), (h * e2, h * -e1, h * e0))
    np.divide(1.0, c, out=inv_c)
    jn = _dot(jac_6 * inv_c_col, tmat)
    s0, _, _, _, _, s5 = _dgesdd(jn, 0)[1].tolist()      # compute_uv=0: values only
    cond = s0 / s5 if s5 > 0 else math.inf
    if not cond <= max_condition:
        raise SingularPoseError(f'forward kinematics solution is near-singular: Jacobian '
                                f'condition {cond:.3g} > {max_condition:.3g}')
    rot.setflags(write=False)
    if len(_RECENT_QUATERNIONS) >= 8:
        try:
            _RECENT_QUATERNIONS.pop(next(iter(_RECENT_QUATERNIONS)))
        except (KeyError, StopIteration, RuntimeError):   # another thread got there first
            pass
    _RECENT_QUATERNIONS[id(rot)] = (rot, (e0, e1, e2, e3))
    return _new_tuple(FKResult, (np.array((r0, r1, r2)), rot, it, converged, cond))


#: (PARAMOTION_BACKEND value, backend) last resolved for 'auto' by forward_kinematics: saves
#: the import check on every single solve.
_AUTO_BACKEND = [None, None]
_SINGLE_KERNEL = []


def _forward_kinematics_numba(cache, c, r0, r1, r2, e0, e1, e2, e3, tol, max_iter,
                              max_condition):
    """:func:`forward_kinematics` by the compiled single-pose kernel (same errors/result)."""
    if not _SINGLE_KERNEL:
        from paramotion.gough_stewart_numba import fk_single_kernel
        _SINGLE_KERNEL.append(fk_single_kernel)
    (r0, r1, r2, e0, e1, e2, e3, it, converged, sing, cond) = _SINGLE_KERNEL[0](
        c if c.flags.c_contiguous else c.copy(), r0, r1, r2, e0, e1, e2, e3, cache.plat,
        cache.base, cache.rho, float(tol), int(max_iter))
    if sing:
        raise SingularPoseError('forward kinematics met a singular constraint Jacobian (or a '
                                f'non-finite iterate) at iteration {it}')
    if e0 != e0:
        raise SingularPoseError('forward kinematics collapsed the Euler parameters to zero')
    if not cond <= max_condition:
        raise SingularPoseError(f'forward kinematics solution is near-singular: Jacobian '
                                f'condition {cond:.3g} > {max_condition:.3g}')
    a0, a1, a2, a3 = 2 * e0, 2 * e1, 2 * e2, 2 * e3
    w = a0 * e0 - 1
    p12, p03, p13, p02, p23, p01 = a1 * e2, a0 * e3, a1 * e3, a0 * e2, a2 * e3, a0 * e1
    rot = np.array((w + a1 * e1, p12 - p03, p13 + p02, p12 + p03, w + a2 * e2, p23 - p01,
                    p13 - p02, p23 + p01, w + a3 * e3)).reshape(3, 3)
    rot.setflags(write=False)
    if len(_RECENT_QUATERNIONS) >= 8:
        try:
            _RECENT_QUATERNIONS.pop(next(iter(_RECENT_QUATERNIONS)))
        except (KeyError, StopIteration, RuntimeError):   # another thread got there first
            pass
    _RECENT_QUATERNIONS[id(rot)] = (rot, (e0, e1, e2, e3))
    return _new_tuple(FKResult, (np.array((r0, r1, r2)), rot, it, converged, cond))


def forward_kinematics_batch(geom: GoughStewartGeometry, lengths: ArrayLike,
                             guess_positions: ArrayLike, guess_rotations: ArrayLike,
                             tol: float = 1e-12, max_iter: int = 30,
                             max_condition: float = DEFAULT_MAX_CONDITION,
                             backend: str = 'auto', threads: int | None = None
                             ) -> BatchFKResult:
    """Vectorised :func:`forward_kinematics` for N length sets (N, 6) at once.

    Does not raise per pose: poses with lengths outside the stroke, a singular Jacobian, too
    large a condition number or no convergence come back with ``converged`` False (and
    ``singular`` True for the singular ones). ``backend``: ``'numba'`` (one compiled loop
    over the poses, :mod:`paramotion.gough_stewart_numba`), ``'numpy'`` (Newton-Raphson
    vectorised over the poses with stacked 7 x 7 solves) or ``'auto'`` (see
    :func:`resolve_backend`). Both run the same iteration; results agree to rounding.
    ``threads`` (numba only): the poses are independent, so a large batch is cut into
    contiguous blocks solved side by side by the compiled kernel, which releases the GIL;
    ``None`` uses the cores this process may run on (:func:`usable_cores`), 1 solves in the
    calling thread. The blocks' results are bit-identical to one call on the whole batch.
    """
    c = np.asarray(lengths, dtype=float).reshape(-1, 6)
    n = c.shape[0]
    r = np.array(guess_positions, dtype=float).reshape(n, 3)
    e = quaternion_from_matrix(np.asarray(guess_rotations, dtype=float).reshape(n, 3, 3))
    valid = (np.all(np.isfinite(c), axis=1) & np.all(c >= geom.leg_min, axis=1)
             & np.all(c <= geom.leg_max, axis=1))
    c = np.where(valid[:, None], c, 1.0)
    if resolve_backend(backend) == 'numba':
        return _forward_kinematics_batch_numba(geom, c, r, e, valid, tol, max_iter,
                                               max_condition, threads)
    base = geom.base_anchors
    plat = geom.platform_anchors
    c2 = c * c
    iterations = np.zeros(n, dtype=int)
    done = ~valid
    singular = np.zeros(n, dtype=bool)
    converged = np.zeros(n, dtype=bool)
    for _ in range(max_iter + 1):
        act = np.flatnonzero(~done)
        if act.size == 0:
            break
        ea = e[act]
        a = matrix_from_quaternion(ea, normalize=False)
        world_plat = np.einsum('njk,ik->nij', a, plat)
        legs = r[act, None, :] + world_plat - base
        sq = np.einsum('nij,nij->ni', legs, legs)
        res = np.max(np.abs(sq - c2[act]) / (2 * c[act]), axis=1)
        norm_res = np.abs(np.einsum('ni,ni->n', ea, ea) - 1.0)
        ok = (res < tol) & (norm_res < tol)
        converged[act[ok]] = True
        done[act[ok]] = True
        give_up = ~ok & (iterations[act] >= max_iter)
        done[act[give_up]] = True
        step = ~ok & ~give_up
        if not np.any(step):
            continue
        idx = act[step]
        jac = np.zeros((idx.size, 7, 7))
        jac[:, :6] = _constraint_jacobian(legs[step], plat, ea[step])
        jac[:, 6, 3:] = ea[step]
        phi = np.empty((idx.size, 7))
        phi[:, :6] = 0.5 * (sq[step] - c2[idx])
        phi[:, 6] = 0.5 * (np.einsum('ni,ni->n', ea[step], ea[step]) - 1.0)
        det = np.linalg.det(jac)
        bad = ~np.isfinite(det) | (np.abs(det) < 1e-300)
        if np.any(bad):
            singular[idx[bad]] = True
            done[idx[bad]] = True
            jac[bad] = np.eye(7)
        dq = np.linalg.solve(jac, phi[..., None])[..., 0]
        good = idx[~bad]
        r[good] -= dq[~bad, :3]
        e[good] -= dq[~bad, 3:]
        iterations[good] += 1
    e /= np.linalg.norm(e, axis=1, keepdims=True)
    rot = matrix_from_quaternion(e)
    cond = np.full(n, np.inf)
    # Condition at the final iterate of every pose that was iterated (converged or not), so
    # that a run-off near a singularity is reported as singular rather than merely unsolved.
    finite = valid & np.all(np.isfinite(r), axis=1) & np.all(np.isfinite(rot), axis=(1, 2))
    if np.any(finite):
        cond[finite] = jacobian_condition(geom, jacobian(geom, r[finite], rot[finite]))
    near = valid & ~(cond <= max_condition)
    singular |= near
    converged &= ~near
    return BatchFKResult(r, rot, iterations, converged, cond, singular)


#: Smallest block of poses worth a thread of its own (a thread start costs ~50 us, about 25
#: solves); a multiple of the kernel's condition lanes.
_MIN_BLOCK = 2048


def _forward_kinematics_batch_numba(geom, c, r, e, valid, tol, max_iter, max_condition,
                                    threads):
    """The numba path of :func:`forward_kinematics_batch`, in blocks on ``threads`` threads.

    Each block is a contiguous slice of the pose arrays (views, written in place), so the
    blocks share nothing; the kernel is ``nogil``, so the threads run on separate cores.
    """
    from paramotion.gough_stewart_numba import fk_batch_kernel
    n = c.shape[0]
    c = np.ascontiguousarray(c)
    e = np.ascontiguousarray(e)
    rot = np.empty((n, 3, 3))
    iterations = np.zeros(n, dtype=int)
    converged = np.zeros(n, dtype=bool)
    singular = np.zeros(n, dtype=bool)
    cond = np.empty(n)
    consts = (geom.platform_anchors, geom.base_anchors, geom.characteristic_length,
              float(tol), int(max_iter), float(max_condition))

    def solve(lo, hi):
        fk_batch_kernel(c[lo:hi], r[lo:hi], e[lo:hi], valid[lo:hi], *consts, rot[lo:hi],
                        iterations[lo:hi], converged[lo:hi], singular[lo:hi], cond[lo:hi])

    workers = usable_cores() if threads is None else max(1, int(threads))
    workers = min(workers, max(1, n // _MIN_BLOCK))
    if workers == 1:
        solve(0, n)
    else:
        edges = np.linspace(0, n, workers + 1).astype(int)
        with ThreadPoolExecutor(workers - 1) as pool:
            rest = [pool.submit(solve, lo, hi) for lo, hi in zip(edges[1:-1], edges[2:])]
            solve(edges[0], edges[1])
            for job in rest:
                job.result()  # re-raises a block's error here
    return BatchFKResult(r, rot, iterations, converged, cond, singular)
