"""Unit tests of the shared Gough-Stewart kinematics (paramotion/gough_stewart.py)."""
import math

import numpy as np
import pytest

from paramotion import gough_stewart as gs

DEG = math.pi / 180


@pytest.fixture(scope='module')
def geom():
    """Climber-like rings: 0.5 m anchor radius, 10 deg half angles, 0.45-1.0 m stroke."""
    return gs.GoughStewartGeometry.from_rings(0.5, 0.5, 10 * DEG, 10 * DEG, 0.45, 1.0)


def random_reachable_poses(geom, n, rng, max_condition=100.0):
    """Random poses inside the stroke and away from singularities (rejection sampling)."""
    out_p, out_r = [], []
    while len(out_p) < n:
        p = rng.uniform([-0.12, -0.12, 0.4], [0.12, 0.12, 0.95], size=(4 * n, 3))
        rot = gs.rotation_matrix(rng.uniform(-20 * DEG, 20 * DEG, size=(4 * n, 3)))
        lengths = gs.inverse_kinematics(geom, p, rot)
        ok = np.all((lengths > geom.leg_min) & (lengths < geom.leg_max), axis=1)
        cond = gs.jacobian_condition(geom, gs.jacobian(geom, p, rot))
        ok &= cond < max_condition
        out_p.extend(p[ok])
        out_r.extend(rot[ok])
    return np.array(out_p[:n]), np.array(out_r[:n])


def test_from_rings_layout(geom):
    base, plat = geom.base_anchors, geom.platform_anchors
    assert base.shape == plat.shape == (6, 3)
    np.testing.assert_allclose(np.linalg.norm(base, axis=1), 0.5)
    np.testing.assert_allclose(base[:, 2], 0.0)
    ang_b = np.degrees(np.arctan2(base[:, 1], base[:, 0])) % 360
    ang_p = np.degrees(np.arctan2(plat[:, 1], plat[:, 0])) % 360
    np.testing.assert_allclose(ang_b, [350, 10, 110, 130, 230, 250], atol=1e-9)
    np.testing.assert_allclose(ang_p, [310, 50, 70, 170, 190, 290], atol=1e-9)
    assert geom.characteristic_length == pytest.approx(0.5)


def test_geometry_validation():
    with pytest.raises(ValueError, match='leg_min'):
        gs.GoughStewartGeometry.from_rings(0.5, 0.5, 0.1, 0.1, 1.0, 0.5)
    with pytest.raises(ValueError, match='half angles'):
        gs.GoughStewartGeometry.from_rings(0.5, 0.5, 40 * DEG, 0.1, 0.4, 0.9)
    with pytest.raises(ValueError, match='shape'):
        gs.GoughStewartGeometry(np.zeros((5, 3)), np.zeros((6, 3)), 0.4, 0.9)


def test_inverse_kinematics_home_pose_by_hand(geom):
    # Rings parallel, coaxial, 0.6 m apart: every leg spans a 40 deg chord of a 0.5 m circle.
    chord = 2 * 0.5 * math.sin(20 * DEG)
    expected = math.sqrt(0.6 ** 2 + chord ** 2)           # 0.690636...
    lengths = gs.inverse_kinematics(geom, [0, 0, 0.6], np.eye(3))
    np.testing.assert_allclose(lengths, expected, rtol=0, atol=1e-15)
    assert expected == pytest.approx(0.6906358, abs=1e-7)


def test_inverse_kinematics_translation_by_hand(geom):
    # Shift the platform by +0.1 m along x: leg 1 joins base (cos10, sin10) * 0.5 to platform
    # (cos50, sin50) * 0.5 + (0.1, 0, 0.6).
    b = 0.5 * np.array([math.cos(10 * DEG), math.sin(10 * DEG), 0])
    p = 0.5 * np.array([math.cos(50 * DEG), math.sin(50 * DEG), 0]) + [0.1, 0, 0.6]
    lengths = gs.inverse_kinematics(geom, [0.1, 0, 0.6], np.eye(3))
    assert lengths[1] == pytest.approx(np.linalg.norm(p - b), abs=1e-15)
    # Mirror symmetry about the xz plane: legs 0 and 1 are mirror images.
    assert lengths[0] == pytest.approx(lengths[1], abs=1e-15)


def test_inverse_kinematics_vectorised_matches_loop(geom):
    rng = np.random.default_rng(1)
    p, rot = random_reachable_poses(geom, 50, rng)
    batch = gs.inverse_kinematics(geom, p, rot)
    for k in range(50):
        np.testing.assert_allclose(batch[k], gs.inverse_kinematics(geom, p[k], rot[k]))


def test_jacobian_matches_finite_differences(geom):
    rng = np.random.default_rng(2)
    p, rot = random_reachable_poses(geom, 5, rng)
    h = 1e-6
    for k in range(5):
        jac = gs.jacobian(geom, p[k], rot[k])
        num = np.empty((6, 6))
        for j in range(3):
            dp = np.zeros(3)
            dp[j] = h
            num[:, j] = (gs.inverse_kinematics(geom, p[k] + dp, rot[k])
                         - gs.inverse_kinematics(geom, p[k] - dp, rot[k])) / (2 * h)
            # small rotation about world axis j: R(+) = exp(h e_j) R
            rp = _axis_rotation(j, h) @ rot[k]
            rm = _axis_rotation(j, -h) @ rot[k]
            num[:, 3 + j] = (gs.inverse_kinematics(geom, p[k], rp)
                             - gs.inverse_kinematics(geom, p[k], rm)) / (2 * h)
        np.testing.assert_allclose(jac, num, atol=1e-8)


def _axis_rotation(axis, angle):
    rpy = np.zeros(3)
    rpy[axis] = angle
    return gs.rotation_matrix(rpy)


def test_quaternion_round_trip_and_haug_formula():
    rng = np.random.default_rng(3)
    q = rng.normal(size=(200, 4))
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    q *= np.sign(q[:, :1])
    rot = gs.matrix_from_quaternion(q)
    np.testing.assert_allclose(rot @ np.swapaxes(rot, 1, 2), np.broadcast_to(np.eye(3), rot.shape),
                               atol=1e-14)
    np.testing.assert_allclose(np.linalg.det(rot), 1.0, atol=1e-14)
    np.testing.assert_allclose(gs.quaternion_from_matrix(rot), q, atol=1e-12)
    # Haug: A = (2 e0^2 - 1) I + 2 (e e^T + e0 e~)
    e0, e = q[0, 0], q[0, 1:]
    skew = np.array([[0, -e[2], e[1]], [e[2], 0, -e[0]], [-e[1], e[0], 0]])
    np.testing.assert_allclose(rot[0], (2 * e0 ** 2 - 1) * np.eye(3)
                               + 2 * (np.outer(e, e) + e0 * skew), atol=1e-15)
    # 90 deg about z.
    np.testing.assert_allclose(gs.rotation_matrix([0, 0, math.pi / 2]),
                               [[0, -1, 0], [1, 0, 0], [0, 0, 1]], atol=1e-15)
    rpy = rng.uniform(-1.2, 1.2, size=(100, 3))
    np.testing.assert_allclose(gs.rpy_from_matrix(gs.rotation_matrix(rpy)), rpy, atol=1e-12)


def test_forward_kinematics_round_trip_single(geom):
    rng = np.random.default_rng(4)
    p, rot = random_reachable_poses(geom, 2000, rng)
    lengths = gs.inverse_kinematics(geom, p, rot)
    guess_p = p + rng.normal(scale=0.01, size=p.shape)
    guess_r = gs.rotation_matrix(rng.normal(scale=2 * DEG, size=(2000, 3))) @ rot
    worst_p = worst_r = worst_l = 0.0
    iters = []
    for k in range(2000):
        res = gs.forward_kinematics(geom, lengths[k], guess_p[k], guess_r[k])
        assert res.converged
        iters.append(res.iterations)
        worst_p = max(worst_p, np.abs(res.position - p[k]).max())
        worst_r = max(worst_r, np.abs(res.rotation - rot[k]).max())
        worst_l = max(worst_l, np.abs(gs.inverse_kinematics(geom, res.position, res.rotation)
                                      - lengths[k]).max())
        assert 1.0 <= res.jacobian_condition < 100.0
    assert worst_p < 1e-9 and worst_l < 1e-9 and worst_r < 1e-9
    assert np.median(iters) <= 4


def test_forward_kinematics_condition_matches_definition(geom):
    rng = np.random.default_rng(5)
    p, rot = random_reachable_poses(geom, 20, rng)
    for k in range(20):
        lengths = gs.inverse_kinematics(geom, p[k], rot[k])
        res = gs.forward_kinematics(geom, lengths, p[k] + 0.005, rot[k])
        want = gs.jacobian_condition(geom, gs.jacobian(geom, p[k], rot[k]))
        assert res.jacobian_condition == pytest.approx(want, rel=1e-6)
    # Exact guess: no iteration, condition at the guess itself.
    res = gs.forward_kinematics(geom, gs.inverse_kinematics(geom, p[0], rot[0]), p[0], rot[0])
    assert res.iterations == 0 and res.converged
    assert res.jacobian_condition == pytest.approx(
        gs.jacobian_condition(geom, gs.jacobian(geom, p[0], rot[0])), rel=1e-12)


def test_forward_kinematics_batch_round_trip(geom):
    rng = np.random.default_rng(6)
    p, rot = random_reachable_poses(geom, 3000, rng)
    lengths = gs.inverse_kinematics(geom, p, rot)
    guess_r = gs.rotation_matrix(rng.normal(scale=2 * DEG, size=(3000, 3))) @ rot
    out = gs.forward_kinematics_batch(geom, lengths, p + rng.normal(scale=0.01, size=p.shape),
                                      guess_r)
    assert out.converged.all() and not out.singular.any()
    assert np.abs(out.positions - p).max() < 1e-9
    assert np.abs(out.rotations - rot).max() < 1e-9
    back = gs.inverse_kinematics(geom, out.positions, out.rotations)
    assert np.abs(back - lengths).max() < 1e-9


def test_singular_fichter_pose_detected():
    # Coaxial rings with the platform turned 90 deg about the axis: the classic singularity of
    # the semi-regular 6-6 platform (Fichter 1986): det J = 0. (Long stroke so that it is
    # reachable.)
    geom = gs.GoughStewartGeometry.from_rings(0.5, 0.5, 10 * DEG, 10 * DEG, 0.45, 1.5)
    rot = gs.rotation_matrix([0, 0, math.pi / 2])
    p = np.array([0, 0, 0.6])
    jac = gs.jacobian(geom, p, rot)
    assert abs(np.linalg.det(jac)) < 1e-12
    assert gs.jacobian_condition(geom, jac) > 1e12
    with pytest.raises(gs.SingularPoseError, match='near-singular'):
        gs.check_pose(geom, p, rot)
    lengths = gs.inverse_kinematics(geom, p, rot)
    # From the exact pose or near guesses: refused, or at least never reported as converged.
    rng = np.random.default_rng(7)
    for k in range(20):
        guess_p = p + (0 if k == 0 else rng.normal(scale=0.01, size=3))
        guess_r = rot if k == 0 else gs.rotation_matrix(rng.normal(scale=DEG, size=3)) @ rot
        try:
            res = gs.forward_kinematics(geom, lengths, guess_p, guess_r)
        except gs.SingularPoseError:
            continue
        assert not res.converged
    out = gs.forward_kinematics_batch(geom, np.tile(lengths, (5, 1)), np.tile(p, (5, 1)) + 0.01,
                                      np.tile(rot, (5, 1, 1)))
    assert not out.converged.any()
    # Close to it (89.9 deg: condition ~2e3) the solver converges but refuses the answer
    # rather than return a pose whose assembly mode is ambiguous.
    near = gs.rotation_matrix([0, 0, 89.9 * DEG])
    near_lengths = gs.inverse_kinematics(geom, p, near)
    with pytest.raises(gs.SingularPoseError, match='near-singular'):
        gs.forward_kinematics(geom, near_lengths, p + 0.001, near)
    out = gs.forward_kinematics_batch(geom, near_lengths[None], p[None] + 0.001, near[None])
    assert out.singular.tolist() == [True] and out.converged.tolist() == [False]
    # ... unless the caller explicitly accepts such conditioning.
    res = gs.forward_kinematics(geom, near_lengths, p + 0.001, near, max_condition=1e4)
    assert res.converged and np.abs(res.position - p).max() < 1e-9


def test_singular_flat_pose_detected():
    # Platform in the base plane: every leg horizontal, no vertical stiffness.
    geom = gs.GoughStewartGeometry.from_rings(0.5, 0.3, 10 * DEG, 10 * DEG, 0.1, 1.0)
    jac = gs.jacobian(geom, [0, 0, 0], np.eye(3))
    assert np.allclose(jac[:, 2], 0)
    with pytest.raises(gs.SingularPoseError):
        gs.check_pose(geom, [0, 0, 0], np.eye(3))
    lengths = gs.inverse_kinematics(geom, [0, 0, 0], np.eye(3))
    with pytest.raises(gs.SingularPoseError):
        gs.forward_kinematics(geom, lengths, [0, 0, 0.01], np.eye(3))


def test_batch_flags_singular_and_unreachable():
    geom = gs.GoughStewartGeometry.from_rings(0.5, 0.5, 10 * DEG, 10 * DEG, 0.45, 1.5)
    p = np.array([[0, 0, 0.6], [0, 0, 0.6], [0, 0, 0.6]])
    rot = np.array([np.eye(3), gs.rotation_matrix([0, 0, 89.9 * DEG]), np.eye(3)])
    lengths = gs.inverse_kinematics(geom, p, rot)
    lengths[2, 0] = geom.leg_max + 0.1
    out = gs.forward_kinematics_batch(geom, lengths, p + 0.001, rot)
    assert out.converged.tolist() == [True, False, False]
    assert out.singular.tolist() == [False, True, False]


def test_unreachable_and_bad_lengths(geom):
    good = gs.inverse_kinematics(geom, [0, 0, 0.6], np.eye(3))
    for bad, msg in ((good + 0.5, 'outside the stroke'), (good - 0.3, 'outside the stroke'),
                     (np.where(np.arange(6) == 3, np.nan, good), 'not finite'),
                     (np.where(np.arange(6) == 5, np.inf, good), 'not finite')):
        with pytest.raises(gs.UnreachablePoseError, match=msg):
            gs.forward_kinematics(geom, bad, [0, 0, 0.6], np.eye(3))
    with pytest.raises(gs.UnreachablePoseError):
        gs.check_pose(geom, [0, 0, 1.2], np.eye(3))
    lengths, cond = gs.check_pose(geom, [0, 0, 0.6], np.eye(3))
    np.testing.assert_allclose(lengths, good)
    assert 1 < cond < 10


def test_not_converged_is_reported(geom):
    lengths = gs.inverse_kinematics(geom, [0.05, 0, 0.7], gs.rotation_matrix([0.1, 0, 0]))
    res = gs.forward_kinematics(geom, lengths, [0, 0, 0.6], np.eye(3), max_iter=1)
    assert res.iterations == 1 and not res.converged
