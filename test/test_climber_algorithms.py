"""Correction (eq. 5) and prediction (eqs. 6-8) functions against hand-computed cases."""
import math

import numpy as np
import pytest

from climber_pkg.correction import (
    SensorDataError,
    check_distances,
    circle_through_points,
    contour_points,
    correction,
)
from climber_pkg.prediction import (
    PredictionError,
    limit_correction,
    predict_orientation,
    predict_pose,
    rotate_about_axis,
)

ANGLES = [math.radians(a) for a in (90, 210, 330)]


def test_circle_through_three_points_by_hand():
    # (1, 0), (0, 1), (-1, 0) lie on the unit circle about the origin.
    assert circle_through_points([[1, 0], [0, 1], [-1, 0]]) == pytest.approx((0, 0, 1))
    # (3, 2), (1, 4), (-1, 2): centre (1, 2), radius 2.
    assert circle_through_points([[3, 2], [1, 4], [-1, 2]]) == pytest.approx((1, 2, 2))


def test_collinear_points_refused():
    with pytest.raises(SensorDataError, match='collinear'):
        circle_through_points([[0, 0], [1, 1], [2, 2]])


def test_correction_centred_trunk():
    # Sensors at 0.38 m; a 0.2 m trunk centred: every distance is 0.18 m.
    out = correction([0.18, 0.18, 0.18], 0.38, ANGLES)
    assert (out.dx, out.dy, out.radius) == pytest.approx((0, 0, 0.2), abs=1e-12)


def test_correction_offset_trunk_by_hand():
    # Trunk of radius 0.2 centred at (0.05, 0) in the ring frame. Sensor 1 at 90 deg looks
    # down -y along x = 0: hits the circle at y = sqrt(0.2^2 - 0.05^2) -> d1 = 0.38 - 0.19365.
    # Sensors 2 and 3 look along the 210 / 330 deg radials; solve |rho u - c| = 0.2 for rho.
    c = np.array([0.05, 0.0])
    d = []
    for a in ANGLES:
        u = np.array([math.cos(a), math.sin(a)])
        b = u @ c
        rho = b + math.sqrt(b * b - (c @ c - 0.04))
        d.append(0.38 - rho)
    assert d[0] == pytest.approx(0.38 - math.sqrt(0.04 - 0.0025))
    out = correction(d, 0.38, ANGLES)
    assert out.dx == pytest.approx(0.05, abs=1e-12)
    assert out.dy == pytest.approx(0.0, abs=1e-12)
    assert out.radius == pytest.approx(0.2, abs=1e-12)
    np.testing.assert_allclose(np.linalg.norm(out.points - c, axis=1), 0.2, atol=1e-12)


def test_contour_points_geometry():
    pts = contour_points([0.1, 0.2, 0.3], 0.4, ANGLES)
    np.testing.assert_allclose(pts[0], [0, 0.3], atol=1e-15)
    np.testing.assert_allclose(np.linalg.norm(pts, axis=1), [0.3, 0.2, 0.1])


@pytest.mark.parametrize('bad, msg', [
    ([0.1, math.nan, 0.1], r'ultrasonic 1: invalid reading \(NaN\)'),
    ([math.inf, 0.1, 0.1], r'ultrasonic 0: no echo'),
    ([0.1, 0.1, -math.inf], r'ultrasonic 2: object too close'),
    ([0.1, 0.1, 0.9], 'outside the valid range'),
])
def test_invalid_readings_refused(bad, msg):
    with pytest.raises(SensorDataError, match=msg):
        correction(bad, 0.38, ANGLES, 0.02, 0.4)
    with pytest.raises(SensorDataError):
        check_distances([0.1, 0.1], 0.0, 1.0)


def test_prediction_straight_up_by_hand():
    # Eq. (6) with A = I: r1 = r0 + [dx, dy, delta]; eq. (7): a = (dx, dy, delta)/norm.
    p, r = predict_pose([1.0, 2.0, 3.0], np.eye(3), 0.0, 0.0, 0.1)
    np.testing.assert_allclose(p, [1.0, 2.0, 3.1])
    np.testing.assert_allclose(r, np.eye(3), atol=1e-15)


def test_prediction_with_correction_by_hand():
    dx, dy, delta = 0.03, 0.0, 0.1
    p, r = predict_pose([0, 0, 0], np.eye(3), dx, dy, delta)
    np.testing.assert_allclose(p, [0.03, 0, 0.1])
    a = np.array([0.03, 0, 0.1]) / math.hypot(0.03, 0.1)
    n = np.cross([0, 1, 0], a)
    n /= np.linalg.norm(n)                      # (0.1, 0, -0.03) / |.|
    np.testing.assert_allclose(r[:, 2], a)
    np.testing.assert_allclose(r[:, 0], n)
    np.testing.assert_allclose(r[:, 1], np.cross(a, n))
    np.testing.assert_allclose(r[:, 0], np.array([0.1, 0, -0.03]) / math.hypot(0.1, 0.03))
    np.testing.assert_allclose(r @ r.T, np.eye(3), atol=1e-15)
    assert np.linalg.det(r) == pytest.approx(1.0)


def test_prediction_in_rotated_frame():
    # Previous frame turned 90 deg about z: its local x is world y.
    rot = np.array([[0, -1, 0], [1, 0, 0], [0, 0, 1.0]])
    p, r = predict_pose([0, 0, 0], rot, 0.02, 0.0, 0.1)
    np.testing.assert_allclose(p, [0, 0.02, 0.1])
    # New y = a x n stays in the plane of the old y's orthogonal complement of a.
    assert r[:, 1] @ rot[:, 1] > 0.99


def test_descending_keeps_z_up():
    p, r = predict_pose([0, 0, 1.0], np.eye(3), 0.0, 0.01, -0.1)
    np.testing.assert_allclose(p, [0, 0.01, 0.9])
    assert r[2, 2] > 0.99                   # z still points up the structure


def test_prediction_refuses_degenerate():
    with pytest.raises(PredictionError):
        predict_orientation([0, 0, 0], [0, 0, 0], np.eye(3))
    with pytest.raises(PredictionError):
        predict_orientation([0, 0, 0], [0, 1, 0], np.eye(3))


def test_limit_correction_and_turn():
    assert limit_correction(0.01, 0.0, 0.1, math.radians(12)) == (0.01, 0.0)
    dx, dy = limit_correction(0.06, 0.08, 0.1, math.radians(12))
    assert math.hypot(dx, dy) == pytest.approx(0.1 * math.tan(math.radians(12)))
    assert dy / dx == pytest.approx(0.08 / 0.06)
    r = rotate_about_axis(np.eye(3), math.pi / 2)
    np.testing.assert_allclose(r[:, 0], [0, 1, 0], atol=1e-15)
