"""Evaluation of a climb against the true structure (ground truth only; never the planner).

* centering error: distance from a ring's centre to the structure axis, measured in the ring
  plane (where the axis crosses it), as the issue defines it;
* ring-trunk clearance: smallest distance from the ring bore (its two rim circles, the bore
  being a cylinder of ``inner_radius`` and ``thickness``) to the structure surface;
* leg-trunk clearance: smallest distance from the leg axes (minus the leg radius) to it.
"""
from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike

if TYPE_CHECKING:
    from climber_pkg.robot import RobotConfig
    from climber_pkg.trunk import Trunk

RIM_SAMPLES = 72


def centering_error(trunk: Trunk, position: ArrayLike, rotation: ArrayLike) -> float:
    """Distance (m) from the ring centre to where the axis crosses the ring plane (NaN: none)."""
    point, _ = trunk.axis_in_plane(position, np.asarray(rotation)[:, 2])
    if point is None:
        return float('nan')
    return float(np.linalg.norm(point - np.asarray(position)))


def ring_on_structure(trunk: Trunk, position: ArrayLike, margin: float = 0.0) -> bool:
    """True when the ring centre is alongside the structure (not above its top / below foot)."""
    s, _ = trunk.closest(np.asarray(position, dtype=float))
    return margin < float(s) < trunk.length - margin


def bore_points(robot: RobotConfig, position: ArrayLike, rotation: ArrayLike) -> np.ndarray:
    """Points on the two rim circles of a ring bore in the world frame (2 * RIM_SAMPLES, 3)."""
    ang = np.linspace(0, 2 * np.pi, RIM_SAMPLES, endpoint=False)
    circle = np.stack([np.cos(ang), np.sin(ang), np.zeros_like(ang)], 1) * robot.ring_inner_radius
    half = robot.ring_thickness / 2
    local = np.concatenate([circle + [0, 0, half], circle - [0, 0, half]])
    return np.asarray(position) + local @ np.asarray(rotation).T


def ring_clearance(trunk: Trunk, robot: RobotConfig, position: ArrayLike,
                   rotation: ArrayLike) -> float:
    """Smallest bore-to-surface distance of one ring (m); +inf if the bore is off the trunk."""
    pts = bore_points(robot, position, rotation)
    on = trunk.inside_span(pts)
    if not np.any(on):
        return float('inf')
    return float(trunk.surface_clearance(pts[on]).min())


def leg_clearance(trunk: Trunk, robot: RobotConfig, pose1: tuple[np.ndarray, np.ndarray],
                  pose2: tuple[np.ndarray, np.ndarray], samples: int = 12) -> float:

    """Smallest leg-surface distance (m) with the legs as capsules of ``robot.leg_radius``."""
    geom = robot.geometry
    (p1, r1), (p2, r2) = pose1, pose2
    a = p1 + geom.base_anchors @ r1.T
    b = p2 + geom.platform_anchors @ r2.T
    t = np.linspace(0, 1, samples)[None, :, None]
    pts = (a[:, None, :] * (1 - t) + b[:, None, :] * t).reshape(-1, 3)
    on = trunk.inside_span(pts)
    if not np.any(on):
        return float('inf')
    return float(trunk.surface_clearance(pts[on]).min() - robot.leg_radius)
