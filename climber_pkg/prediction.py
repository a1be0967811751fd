"""Prediction function of the climbing planner (Almonacid et al. 2003, section IV-D).

Given the moving ring's pose (r^(i-1), A^(i-1)) and the deviation (dx_i, dy_i) from the
correction function, the next planned pose is

    r^(i) = r^(i-1) + A^(i-1) [dx_i, dy_i, Delta]^T                           (6)
    a_i = (r^(i) - r^(i-1)) / |r^(i) - r^(i-1)|
    n_i = (y^(i-1) x a_i) / |y^(i-1) x a_i|,   s_i = a_i x n_i                  (7)
    A^(i) = [n_i, s_i, a_i]                                                    (8)

where y^(i-1) is the second column of A^(i-1). For descending (Delta < 0) the approach vector
is taken as -(r^(i) - r^(i-1)) / |...| so that the ring's z axis keeps pointing up the
structure (the paper descends by running steps 1-6 in reverse; the frame convention must not
flip). Turning around the structure composes A^(i) with a rotation about a_i.

Approach vector, and why there are two variants. Taken literally, eq. (7) aims the new z axis
along the jump r^(i) - r^(i-1), which contains the lateral correction: a ring that was off by e
is re-centred but tilted by atan(e / Delta), and its next move along that tilted axis puts it
off by about e on the other side. The lateral error then never decays (it alternates sign every
step) and sensor noise makes it random-walk. ``approach='centres'`` (the default of the
planner) keeps eq. (6) and eqs. (7)-(8) but takes the approach vector along the structure
itself: the line joining the previous and the new *measured centres* of the structure
(``r + A [dx, dy, 0]`` at each step), i.e. the secant of the structure's axis. ``'paper'``
is eq. (7) as printed.
"""
from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike


class PredictionError(ValueError):
    """The prediction is undefined (zero displacement or approach parallel to y)."""


def predict_position(position: ArrayLike, rotation: ArrayLike, dx: float, dy: float,
                     delta: float) -> np.ndarray:
    """Eq. (6): the new planned position of the moving ring in the reference frame."""
    return (np.asarray(position, dtype=float)
            + np.asarray(rotation, dtype=float) @ np.array([dx, dy, delta], dtype=float))


def predict_orientation(prev_position: ArrayLike, new_position: ArrayLike,
                        prev_rotation: ArrayLike, descending: bool = False) -> np.ndarray:
    """Eqs. (7)-(8): rotation matrix [n, s, a] of the new planned pose."""
    step = np.asarray(new_position, dtype=float) - np.asarray(prev_position, dtype=float)
    norm = np.linalg.norm(step)
    if not norm > 1e-12:
        raise PredictionError('prediction needs a non-zero displacement (Delta = 0?)')
    a = step / norm
    if descending:
        a = -a
    y_prev = np.asarray(prev_rotation, dtype=float)[:, 1]
    n = np.cross(y_prev, a)
    n_norm = np.linalg.norm(n)
    if n_norm < 1e-9:
        raise PredictionError('approach vector parallel to the previous y axis')
    n /= n_norm
    s = np.cross(a, n)
    return np.stack([n, s, a], axis=1)


def measured_centre(position: ArrayLike, rotation: ArrayLike, dx: float,
                    dy: float) -> np.ndarray:
    """The structure's centre in the reference frame, from the correction (dx, dy)."""
    return (np.asarray(position, dtype=float)
            + np.asarray(rotation, dtype=float) @ np.array([dx, dy, 0.0]))


def predict_pose(position: ArrayLike, rotation: ArrayLike, dx: float, dy: float, delta: float,
                 previous_centre: ArrayLike | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Eqs. (6)-(8) together: (new_position, new_rotation) of the moving ring.

    Without ``previous_centre`` this is the paper's eq. (7) verbatim. With it (the centre of the
    structure measured at the previous step, in the same reference frame) the approach vector
    is the structure's secant from that centre to the one measured now (see module docstring);
    the position is eq. (6) either way.
    """
    new_p = predict_position(position, rotation, dx, dy, delta)
    if previous_centre is None:
        new_r = predict_orientation(position, new_p, rotation, descending=delta < 0)
        return new_p, new_r
    centre = measured_centre(position, rotation, dx, dy)
    prev = np.asarray(previous_centre, dtype=float)
    # Orient the secant like the motion (up the structure for delta > 0).
    step = centre - prev
    if np.linalg.norm(step) < 1e-3 or step @ np.asarray(rotation)[:, 2] * np.sign(delta) < 0:
        step = np.asarray(rotation)[:, 2] * np.sign(delta)     # too short: keep the axis
    new_r = predict_orientation(prev, prev + step, rotation, descending=delta < 0)
    return new_p, new_r


def rotate_about_axis(rotation: ArrayLike, angle: float) -> np.ndarray:
    """Turn a ring frame about its own z axis (the structure axis after centering)."""
    c, s = math.cos(angle), math.sin(angle)
    rz = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    return np.asarray(rotation, dtype=float) @ rz


def limit_correction(dx: float, dy: float, delta: float,
                     max_tilt: float) -> tuple[float, float]:

    """Scale (dx, dy) so that the approach vector tilts at most ``max_tilt`` rad from z.

    A large deviation corrected in one step of length Delta would tilt the ring by
    atan(|d| / Delta); the rest of the deviation is corrected in the following steps (the
    algorithm is predictive: the error seen at one step is corrected in the next ones).
    """
    lateral = math.hypot(dx, dy)
    cap = abs(delta) * math.tan(max_tilt)
    if lateral <= cap or lateral == 0.0:
        return dx, dy
    k = cap / lateral
    return dx * k, dy * k
