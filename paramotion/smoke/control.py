"""Approach controller of the smoke graph: stop at ``target`` metres from a wall seen by a range
sensor. Pure Python so it can be tested and replayed without ROS.
"""
import math


def approach_velocity(reading: float, target: float, gain: float, max_speed: float) -> float:
    """Forward speed (m/s) from one REP 117 range reading.

    A valid reading gives a saturated proportional law on the distance error; ``+inf`` (no
    echo: the wall is farther than the sensor sees) drives forward at ``max_speed``; ``-inf``
    (too close to measure) backs off slowly; NaN (sensor fault) stops.
    """
    if math.isnan(reading):
        return 0.0
    if reading == math.inf:
        return max_speed
    if reading == -math.inf:
        return -0.25 * max_speed
    return max(-max_speed, min(max_speed, gain * (reading - target)))
