"""Correction function of the climbing planner (Almonacid et al. 2003, section IV-B, eq. (5)).

Three ultrasonic sensors 120 deg apart in the ring plane measure distances d_1, d_2, d_3 to the
structure. With the sensor mounting known, each distance gives a point (x_i, y_i) of the
structure's contour in the ring frame; the circle through the three points,

    R = sqrt((x_i - dx)^2 + (y_i - dy)^2),  i = 1, 2, 3          (5)

gives the deviation (dx, dy) of the structure's centre from the ring centre and its radius R.
Subtracting the first equation from the other two leaves a 2 x 2 linear system in (dx, dy).
"""
from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike


class SensorDataError(ValueError):
    """The three readings do not define a usable circle (invalid, missing or collinear)."""


@dataclass(frozen=True)
class Correction:
    """Output of eq. (5): centre deviation in the ring frame and structure radius (m)."""

    dx: float
    dy: float
    radius: float
    points: np.ndarray     # (3, 2) contour points in the ring frame


def contour_points(distances: ArrayLike, mount_radius: float,
                   angles: ArrayLike) -> np.ndarray:
    """Points (3, 2) hit by sensors at ``mount_radius`` and ``angles`` looking at the ring axis.

    Sensor i sits at ``mount_radius * (cos a_i, sin a_i)`` and measures along the inward radial
    direction, so its echo comes from ``(mount_radius - d_i) * (cos a_i, sin a_i)``.
    """
    d = np.asarray(distances, dtype=float)
    a = np.asarray(angles, dtype=float)
    rho = mount_radius - d
    return np.stack([rho * np.cos(a), rho * np.sin(a)], axis=1)


def circle_through_points(points: ArrayLike) -> tuple[float, float, float]:
    """(dx, dy, R) of the circle through three points (3, 2): eq. (5) solved exactly."""
    p = np.asarray(points, dtype=float)
    (x1, y1), (x2, y2), (x3, y3) = p
    a = np.array([[x2 - x1, y2 - y1], [x3 - x1, y3 - y1]]) * 2.0
    b = np.array([x2 * x2 + y2 * y2 - x1 * x1 - y1 * y1, x3 * x3 + y3 * y3 - x1 * x1 - y1 * y1])
    scale = max(np.abs(a).max(), 1e-300)
    det = np.linalg.det(a / scale)
    if abs(det) < 1e-9:
        raise SensorDataError('the three contour points are collinear: no circle through them')
    dx, dy = np.linalg.solve(a, b)
    radius = math.hypot(x1 - dx, y1 - dy)
    return float(dx), float(dy), float(radius)


def check_distances(distances: ArrayLike, min_range: float, max_range: float,
                    names: Sequence[str] = ('0', '1', '2')) -> np.ndarray:
    """Refuse readings that are not a measured distance (REP 117 conventions).

    +inf = no echo, -inf = too close, NaN = invalid; anything outside [min_range, max_range]
    is not a valid measurement either. Raises SensorDataError naming the sensor and value.
    """
    d = np.asarray(distances, dtype=float)
    if d.shape != (3,):
        raise SensorDataError(f'need three distances, got {d.shape}')
    for name, value in zip(names, d):
        if math.isnan(value):
            raise SensorDataError(f'ultrasonic {name}: invalid reading (NaN)')
        if value == math.inf:
            raise SensorDataError(f'ultrasonic {name}: no echo (+inf)')
        if value == -math.inf:
            raise SensorDataError(f'ultrasonic {name}: object too close (-inf)')
        if not min_range <= value <= max_range:
            raise SensorDataError(f'ultrasonic {name}: {value:.4f} m outside the valid range '
                                  f'[{min_range}, {max_range}] m')
    return d


def correction(distances: ArrayLike, mount_radius: float, angles: ArrayLike,
               min_range: float = 0.0, max_range: float = math.inf) -> Correction:

    """The correction function: sensor distances -> deviation (dx, dy) and radius R, eq. (5)."""
    d = check_distances(distances, min_range, max_range)
    pts = contour_points(d, mount_radius, angles)
    dx, dy, radius = circle_through_points(pts)
    return Correction(dx, dy, radius, pts)
