"""Inverse kinematics of a cable-driven parallel manipulator, eqs. (1)-(3) of Aref & Taghirad.

A pose is the position ``g = OG`` of the platform centroid in the fixed frame A and the rotation
matrix ``R = A_R_B``. For cable i (eq. (1), loop closure)::

    A_iB_i = g + R b_i - a_i                     (E_i = R b_i in eq. (2))
    L_i    = |A_iB_i|                            eq. (2)
    S_i    = A_iB_i / L_i                        eq. (3), unit vector from A_i to B_i

Everything is vectorised: ``positions`` is (N, 3) and ``rotations`` is either one (3, 3)
matrix shared by all poses (a constant-orientation workspace) or (N, 3, 3).

The paper calls a pose "not reachable" when eq. (2) has no real solution, which never happens
for a real square root; the meaningful tests, made here and reported separately from
collisions, are: the platform box must lie inside the fixed frame (:func:`inside_frame`) and no
cable may have zero length (B_i on A_i, direction undefined).

Orientation convention: ``rotation_matrix(rx, ry, rz) = Rx(rx) @ Ry(ry) @ Rz(rz)``, i.e.
rotations about the x, then the new y, then the new z axis of the moving frame (the paper's
section IV-C rotates "about the corresponding axes of the moving coordinate").
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike

from paramotion.rotations import matrices_from_quats

if TYPE_CHECKING:
    from cable_robot_pkg.cdrpm.description import RobotDescription

#: Shortest cable (m) treated as a defined direction; shorter means B_i sits on A_i.
MIN_CABLE_LENGTH = 1e-9
#: Slack (m) allowed when testing that the platform box is inside the frame.
FRAME_TOL = 1e-9


def rotation_matrix(rx: ArrayLike, ry: ArrayLike, rz: ArrayLike) -> np.ndarray:
    """Rotation matrices ``Rx(rx) Ry(ry) Rz(rz)`` for angles in radians: (..., 3, 3)."""
    rx, ry, rz = np.broadcast_arrays(np.asarray(rx, float), np.asarray(ry, float),
                                     np.asarray(rz, float))
    cx, sx = np.cos(rx), np.sin(rx)
    cy, sy = np.cos(ry), np.sin(ry)
    cz, sz = np.cos(rz), np.sin(rz)
    out = np.empty(rx.shape + (3, 3))
    # Expanded product Rx @ Ry @ Rz.
    out[..., 0, 0] = cy * cz
    out[..., 0, 1] = -cy * sz
    out[..., 0, 2] = sy
    out[..., 1, 0] = cx * sz + sx * sy * cz
    out[..., 1, 1] = cx * cz - sx * sy * sz
    out[..., 1, 2] = -sx * cy
    out[..., 2, 0] = sx * sz - cx * sy * cz
    out[..., 2, 1] = sx * cz + cx * sy * sz
    out[..., 2, 2] = cx * cy
    return out


def rotation_matrix_deg(rx: ArrayLike, ry: ArrayLike, rz: ArrayLike) -> np.ndarray:
    """:func:`rotation_matrix` with angles in degrees."""
    return rotation_matrix(np.radians(rx), np.radians(ry), np.radians(rz))


def quaternion_to_matrix(q: ArrayLike) -> np.ndarray:
    """Rotation matrices from (x, y, z, w) quaternions ``(..., 4)``, normalised
    (:func:`paramotion.rotations.matrices_from_quats`); ValueError for a zero or non-finite one.
    """
    return matrices_from_quats(q)


def matrix_to_angles_deg(rot: ArrayLike) -> tuple[np.ndarray | float, np.ndarray | float,
                                                  np.ndarray | float]:
    """Inverse of :func:`rotation_matrix_deg` (for rot[0, 2] away from +-1): (rx, ry, rz)."""
    rot = np.asarray(rot, dtype=float)
    ry = np.arcsin(np.clip(rot[..., 0, 2], -1.0, 1.0))
    rx = np.arctan2(-rot[..., 1, 2], rot[..., 2, 2])
    rz = np.arctan2(-rot[..., 0, 1], rot[..., 0, 0])
    return np.degrees(rx), np.degrees(ry), np.degrees(rz)


def as_pose_arrays(positions: ArrayLike,
                   rotations: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
    """Normalise pose inputs: positions (N, 3) and rotations (3, 3) or (N, 3, 3)."""
    positions = np.atleast_2d(np.asarray(positions, dtype=float))
    rotations = np.asarray(rotations, dtype=float)
    if positions.ndim != 2 or positions.shape[1] != 3:
        raise ValueError(f'positions must be (N, 3), got {positions.shape}')
    if rotations.shape != (3, 3) and rotations.shape != (positions.shape[0], 3, 3):
        raise ValueError(f'rotations must be (3, 3) or (N, 3, 3), got {rotations.shape}')
    return positions, rotations


def platform_points_world(desc: RobotDescription, positions: ArrayLike,
                          rotations: ArrayLike) -> np.ndarray:
    """World coordinates ``g + R b_i`` of the moving attachment points, (N, n, 3)."""
    positions, rotations = as_pose_arrays(positions, rotations)
    if rotations.ndim == 2:
        rb = desc.platform_points @ rotations.T
        return positions[:, None, :] + rb[None, :, :]
    return positions[:, None, :] + np.einsum('mij,nj->mni', rotations, desc.platform_points)


def platform_extent(desc: RobotDescription, rotations: ArrayLike) -> np.ndarray:
    """Half extents of the axis-aligned box bounding the rotated platform, (3,) or (N, 3)."""
    return np.abs(np.asarray(rotations)) @ desc.platform_half_size


def inside_frame(desc: RobotDescription, positions: ArrayLike,
                 rotations: ArrayLike) -> np.ndarray:
    """True where the whole platform box lies inside the fixed frame, (N,)."""
    positions, rotations = as_pose_arrays(positions, rotations)
    extent = platform_extent(desc, rotations)
    return np.all(np.abs(positions) + extent <= desc.frame_half_size + FRAME_TOL, axis=-1)


@dataclass
class IKResult:
    """Inverse kinematics of N poses for n cables."""

    lengths: np.ndarray        # (N, n) L_i, eq. (2)
    directions: np.ndarray     # (N, n, 3) S_i, eq. (3), unit vector A_i -> B_i
    attachment: np.ndarray     # (N, n, 3) B_i in the fixed frame
    inside_frame: np.ndarray   # (N,) platform box inside the fixed frame
    degenerate: np.ndarray     # (N,) some cable of zero length (direction undefined)

    @property
    def reachable(self) -> np.ndarray:
        """(N,) poses that are inside the frame and have well-defined cables."""
        return self.inside_frame & ~self.degenerate


def inverse_kinematics(desc: RobotDescription, positions: ArrayLike,
                       rotations: ArrayLike) -> IKResult:

    """Cable lengths and unit vectors for N poses, eqs. (1)-(3)."""
    positions, rotations = as_pose_arrays(positions, rotations)
    b_world = platform_points_world(desc, positions, rotations)
    vec = b_world - desc.frame_points[None, :, :]           # A_iB_i, eq. (1)
    lengths = np.sqrt(np.einsum('mnk,mnk->mn', vec, vec))   # eq. (2)
    degenerate = np.any(lengths < MIN_CABLE_LENGTH, axis=1)
    safe = np.where(lengths < MIN_CABLE_LENGTH, 1.0, lengths)
    directions = vec / safe[..., None]                       # eq. (3)
    return IKResult(lengths=lengths, directions=directions, attachment=b_world,
                    inside_frame=inside_frame(desc, positions, rotations),
                    degenerate=degenerate)
