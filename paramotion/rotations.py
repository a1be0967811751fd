"""The project's one rotations module: quaternions, rotation vectors, yaw.

**Quaternion order: ROS order (x, y, z, w)** everywhere in this module, as in
``geometry_msgs/Quaternion`` and PyBullet. The only other order in the project is the Euler
parameters (w, x, y, z) of Haug's formulation inside :mod:`paramotion.gough_stewart`, which the
Gough-Stewart equations are written in; :func:`xyzw_from_wxyz` and :func:`wxyz_from_xyzw`
convert between the two.

The single-pose helpers are scalar math (no per-call library overhead), for the 200 Hz loops
where ``scipy.spatial.transform.Rotation`` costs more in call overhead than the arithmetic.
"""
from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike


def matrix_from_rotvec(v: ArrayLike) -> np.ndarray:
    """Rotation matrix of a rotation vector (Rodrigues)."""
    if type(v) is np.ndarray and v.dtype == np.float64 and v.shape == (3,):
        x, y, z = v.tolist()           # the same floats as below, in one call
    else:
        x, y, z = float(v[0]), float(v[1]), float(v[2])
    th = math.sqrt(x * x + y * y + z * z)
    if th < 1e-12:
        return np.array([[1.0, -z, y], [z, 1.0, -x], [-y, x, 1.0]])
    kx, ky, kz = x / th, y / th, z / th
    c, s = math.cos(th), math.sin(th)
    C = 1.0 - c
    return np.array([
        [c + kx * kx * C, kx * ky * C - kz * s, kx * kz * C + ky * s],
        [ky * kx * C + kz * s, c + ky * ky * C, ky * kz * C - kx * s],
        [kz * kx * C - ky * s, kz * ky * C + kx * s, c + kz * kz * C]])


def rotvec_from_matrix(R: ArrayLike) -> np.ndarray:
    """Rotation vector of a rotation matrix (via the quaternion, robust near 0 and pi)."""
    x, y, z, w = quat_from_matrix(R)
    if w < 0.0:
        x, y, z, w = -x, -y, -z, -w
    s = math.sqrt(x * x + y * y + z * z)
    if s < 1e-12:
        return np.array([2.0 * x, 2.0 * y, 2.0 * z])
    k = 2.0 * math.atan2(s, w) / s
    return np.array([x * k, y * k, z * k])     # np.array([x, y, z]) * k, one array less


def quat_from_matrix(R: ArrayLike) -> tuple[float, float, float, float]:
    """(x, y, z, w) unit quaternion of a rotation matrix (Shepperd's method)."""
    # One conversion to Python floats (exact) instead of nine element reads of an array.
    (m00, m01, m02), (m10, m11, m12), (m20, m21, m22) = np.asarray(R, dtype=float).tolist()
    tr = m00 + m11 + m22
    if tr >= max(m00, m11, m22):
        t = math.sqrt(1.0 + tr) * 2.0
        q = ((m21 - m12) / t, (m02 - m20) / t, (m10 - m01) / t, 0.25 * t)
    elif m00 >= m11 and m00 >= m22:
        t = math.sqrt(1.0 + m00 - m11 - m22) * 2.0
        q = (0.25 * t, (m01 + m10) / t, (m02 + m20) / t, (m21 - m12) / t)
    elif m11 >= m22:
        t = math.sqrt(1.0 + m11 - m00 - m22) * 2.0
        q = ((m01 + m10) / t, 0.25 * t, (m12 + m21) / t, (m02 - m20) / t)
    else:
        t = math.sqrt(1.0 + m22 - m00 - m11) * 2.0
        q = ((m02 + m20) / t, (m12 + m21) / t, 0.25 * t, (m10 - m01) / t)
    q0, q1, q2, q3 = q
    n = math.sqrt(q0 * q0 + q1 * q1 + q2 * q2 + q3 * q3)
    return (q0 / n, q1 / n, q2 / n, q3 / n)


def matrix_from_quat(q: ArrayLike) -> np.ndarray:
    """Rotation matrix of an (x, y, z, w) quaternion (normalised first)."""
    x, y, z, w = (float(c) for c in q)
    n = math.sqrt(x * x + y * y + z * z + w * w)
    x, y, z, w = x / n, y / n, z / n, w / n
    return np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
        [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
        [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])


def xyzw_from_wxyz(q: ArrayLike) -> np.ndarray:
    """ROS-order (x, y, z, w) quaternion of Euler parameters (w, x, y, z); works on (..., 4)."""
    q = np.asarray(q, dtype=float)
    return np.concatenate([q[..., 1:], q[..., :1]], axis=-1)


def wxyz_from_xyzw(q: ArrayLike) -> np.ndarray:
    """Euler parameters (w, x, y, z) of a ROS-order (x, y, z, w) quaternion; works on (..., 4)."""
    q = np.asarray(q, dtype=float)
    return np.concatenate([q[..., 3:], q[..., :3]], axis=-1)


def quat_from_yaw(yaw: float) -> tuple[float, float, float, float]:
    """(x, y, z, w) quaternion of a rotation by ``yaw`` radians about +z (REP 103)."""
    return (0.0, 0.0, math.sin(yaw / 2.0), math.cos(yaw / 2.0))


def yaw_from_quat(q: ArrayLike) -> float:
    """Yaw (rad) about +z of an (x, y, z, w) quaternion (normalised first).

    Raises ValueError for a zero or non-finite quaternion.
    """
    x, y, z, w = (float(c) for c in q)
    n = math.sqrt(x * x + y * y + z * z + w * w)
    if not math.isfinite(n) or n < 1e-12:
        raise ValueError(f'quaternion {[x, y, z, w]} is zero or not finite')
    x, y, z, w = x / n, y / n, z / n, w / n
    return math.atan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))


def matrices_from_quats(q: ArrayLike) -> np.ndarray:
    """Rotation matrices ``(..., 3, 3)`` of (x, y, z, w) quaternions ``(..., 4)``, normalised.

    Vectorised (many poses at once). Raises ValueError for a zero or non-finite quaternion.
    """
    q = np.asarray(q, dtype=float)
    norm = np.linalg.norm(q, axis=-1, keepdims=True)
    if not np.all(np.isfinite(q)) or np.any(norm < 1e-12):
        raise ValueError('quaternion is zero or not finite')
    x, y, z, w = np.moveaxis(q / norm, -1, 0)
    out = np.empty(q.shape[:-1] + (3, 3))
    out[..., 0, 0] = 1 - 2 * (y * y + z * z)
    out[..., 0, 1] = 2 * (x * y - z * w)
    out[..., 0, 2] = 2 * (x * z + y * w)
    out[..., 1, 0] = 2 * (x * y + z * w)
    out[..., 1, 1] = 1 - 2 * (x * x + z * z)
    out[..., 1, 2] = 2 * (y * z - x * w)
    out[..., 2, 0] = 2 * (x * z - y * w)
    out[..., 2, 1] = 2 * (y * z + x * w)
    out[..., 2, 2] = 1 - 2 * (x * x + y * y)
    return out
