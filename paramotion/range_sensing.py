"""Range readings encoded as sensor_msgs/Range expects them (REP 117), without rclpy.

REP 117: a reading below ``min_range`` is ``-inf`` (too close to measure), no echo within
``max_range`` is ``+inf``, and an invalid measurement (sensor fault) is NaN. Valid readings are
the true distance plus Gaussian noise, clipped into ``[min_range, max_range]``.
"""
from __future__ import annotations

import math

import numpy as np


def rep117_reading(true_distance: float | None, min_range: float, max_range: float,
                   noise_std: float = 0.0, rng: np.random.Generator | None = None,
                   fault: bool = False) -> float:
    """Encode one range measurement of ``true_distance`` (m, may be inf for no target)."""
    if fault:
        return math.nan
    if true_distance is None or math.isnan(true_distance) or true_distance > max_range:
        return math.inf
    if true_distance < min_range:
        return -math.inf
    value = true_distance
    if noise_std > 0.0 and rng is not None:
        value += rng.normal(0.0, noise_std)
    return min(max(value, min_range), max_range)


def is_valid_reading(value: float) -> bool:
    """True for a finite measured distance (not +inf/-inf/NaN)."""
    return math.isfinite(value)
