"""The two backends of the batched forward kinematics agree (numba kernel vs numpy fallback).

numba is pinned in requirements.txt; the numpy path is the fallback used when it is missing or
``PARAMOTION_BACKEND=numpy``. Both run the same Newton-Raphson on eq. (4), so they must give
the same poses (to rounding), the same iteration counts and the same singular/unreachable
verdicts.
"""
import math

import numpy as np
import pytest

from paramotion import gough_stewart as gs

DEG = math.pi / 180
BACKENDS = ('numba', 'numpy')


@pytest.fixture(scope='module')
def geom():
    return gs.GoughStewartGeometry.from_rings(0.35, 0.3, 12 * DEG, 8 * DEG, 0.45, 0.95)


def _random_poses(geom, n, rng):
    """Random poses with lengths in stroke and condition below 100 (rejection sampling)."""
    home = 0.5 * (geom.leg_min + geom.leg_max)
    pos, rot = [], []
    while len(pos) < n:
        p = np.array([0, 0, home]) + rng.uniform(-0.08, 0.08, size=(4 * n, 3))
        r = gs.rotation_matrix(rng.uniform(-12, 12, size=(4 * n, 3)) * DEG)
        lengths = gs.inverse_kinematics(geom, p, r)
        cond = gs.jacobian_condition(geom, gs.jacobian(geom, p, r))
        keep = ((lengths >= geom.leg_min) & (lengths <= geom.leg_max)).all(1) & (cond < 100)
        pos.extend(p[keep])
        rot.extend(r[keep])
    return np.array(pos[:n]), np.array(rot[:n])


def test_backends_agree_on_random_poses(geom):
    rng = np.random.default_rng(13)
    p, rot = _random_poses(geom, 2000, rng)
    lengths = gs.inverse_kinematics(geom, p, rot)
    guess_p = p + rng.normal(scale=0.01, size=p.shape)
    guess_r = gs.rotation_matrix(rng.normal(scale=2 * DEG, size=p.shape)) @ rot
    out = {b: gs.forward_kinematics_batch(geom, lengths, guess_p, guess_r, backend=b)
           for b in BACKENDS}
    for res in out.values():
        assert res.converged.all() and not res.singular.any()
        assert np.abs(res.positions - p).max() < 1e-9
        assert np.abs(res.rotations - rot).max() < 1e-9
        back = gs.inverse_kinematics(geom, res.positions, res.rotations)
        assert np.abs(back - lengths).max() < 1e-9
    a, b = out['numba'], out['numpy']
    assert np.abs(a.positions - b.positions).max() < 1e-11
    assert np.abs(a.rotations - b.rotations).max() < 1e-11
    # Same iteration (a pose may stop one step apart when its residual sits at the tolerance).
    assert np.abs(a.iterations - b.iterations).max() <= 1
    assert np.mean(a.iterations == b.iterations) > 0.99
    np.testing.assert_allclose(a.jacobian_condition, b.jacobian_condition, rtol=1e-10)
    # The inputs are not modified.
    assert np.array_equal(lengths, gs.inverse_kinematics(geom, p, rot))


def test_numba_blocks_on_threads_are_bit_identical_to_one_block(geom):
    """A batch solved in blocks on several threads gives exactly what one call gives: the
    blocks are contiguous slices solved independently, with unreachable, singular and NaN
    poses spread over every block (an off-by-one at a block edge would move a verdict)."""
    rng = np.random.default_rng(21)
    p, rot = _random_poses(geom, 9000, rng)
    lengths = gs.inverse_kinematics(geom, p, rot)
    lengths[::997] = geom.leg_max + 0.1          # out of stroke
    lengths[5::1499] = np.nan                    # bad input
    guess_p = p + rng.normal(scale=0.01, size=p.shape)
    guess_r = gs.rotation_matrix(rng.normal(scale=2 * DEG, size=p.shape)) @ rot
    one = gs.forward_kinematics_batch(geom, lengths, guess_p, guess_r, backend='numba',
                                      threads=1)
    for threads in (2, 3):
        many = gs.forward_kinematics_batch(geom, lengths, guess_p, guess_r, backend='numba',
                                           threads=threads)
        for field in ('positions', 'rotations', 'iterations', 'converged',
                      'jacobian_condition', 'singular'):
            assert np.array_equal(getattr(one, field), getattr(many, field),
                                  equal_nan=field not in ('iterations', 'converged',
                                                          'singular')), (threads, field)
    assert (~one.converged).sum() >= 9 + 6
    assert one.converged.sum() > 8900


@pytest.mark.parametrize('backend', BACKENDS)
def test_backends_flag_singular_unreachable_and_bad_input(backend):
    geom = gs.GoughStewartGeometry.from_rings(0.5, 0.5, 10 * DEG, 10 * DEG, 0.45, 1.5)
    p = np.tile([0, 0, 0.6], (6, 1))
    rot = np.array([np.eye(3), gs.rotation_matrix([0, 0, 89.9 * DEG]), np.eye(3), np.eye(3),
                    gs.rotation_matrix([0, 0, 90 * DEG]), np.eye(3)])
    lengths = gs.inverse_kinematics(geom, p, rot)
    lengths[2, 0] = geom.leg_max + 0.1         # unreachable
    lengths[3, 4] = np.nan                      # not finite
    out = gs.forward_kinematics_batch(geom, lengths, p + 0.001, rot, backend=backend)
    assert out.converged.tolist() == [True, False, False, False, False, True]
    assert out.singular.tolist() == [False, True, False, False, True, False]
    assert math.isinf(out.jacobian_condition[2]) and math.isinf(out.jacobian_condition[3])
    assert out.jacobian_condition[1] > 1000 and out.jacobian_condition[0] < 100
    # Near (89.9 deg) is accepted when the caller allows such conditioning.
    relaxed = gs.forward_kinematics_batch(geom, lengths[1:2], p[1:2] + 0.001, rot[1:2],
                                          max_condition=1e4, backend=backend)
    assert relaxed.converged.tolist() == [True]
    assert np.abs(relaxed.positions[0] - p[1]).max() < 1e-9


@pytest.mark.parametrize('backend', BACKENDS)
def test_backends_report_no_convergence(backend, geom):
    p = np.array([[0, 0, 0.7]])
    lengths = gs.inverse_kinematics(geom, p, np.eye(3)[None])
    out = gs.forward_kinematics_batch(geom, lengths, p + 0.05, np.eye(3)[None], max_iter=1,
                                      backend=backend)
    assert out.converged.tolist() == [False] and out.iterations.tolist() == [1]
    assert out.singular.tolist() == [False]


def test_backend_selection(monkeypatch):
    monkeypatch.setenv('PARAMOTION_BACKEND', 'numpy')
    assert gs.resolve_backend() == 'numpy'
    assert gs.resolve_backend('numba') == 'numba'
    monkeypatch.setenv('PARAMOTION_BACKEND', 'numba')
    assert gs.resolve_backend() == 'numba'
    monkeypatch.setenv('PARAMOTION_BACKEND', 'fortran')
    with pytest.raises(ValueError, match='PARAMOTION_BACKEND'):
        gs.resolve_backend()
    with pytest.raises(ValueError, match='backend'):
        gs.resolve_backend('cuda')


def test_single_solver_backends_agree(geom):
    rng = np.random.default_rng(14)
    p, rot = _random_poses(geom, 300, rng)
    lengths = gs.inverse_kinematics(geom, p, rot)
    guess_p = p + rng.normal(scale=0.01, size=p.shape)
    guess_r = gs.rotation_matrix(rng.normal(scale=2 * DEG, size=p.shape)) @ rot
    for k in range(len(p)):
        a = gs.forward_kinematics(geom, lengths[k], guess_p[k], guess_r[k], backend='numba')
        b = gs.forward_kinematics(geom, lengths[k], guess_p[k], guess_r[k], backend='numpy')
        assert a.converged and b.converged
        assert abs(a.iterations - b.iterations) <= 1
        assert np.abs(a.position - p[k]).max() < 1e-9 and np.abs(a.rotation - rot[k]).max() < 1e-9
        assert np.abs(a.position - b.position).max() < 1e-11
        assert np.abs(a.rotation - b.rotation).max() < 1e-11
        assert a.jacobian_condition == pytest.approx(b.jacobian_condition, rel=1e-6)
        assert not a.rotation.flags.writeable
    # Warm-started from its own previous result along a path (the quaternion cache).
    prev = gs.forward_kinematics(geom, lengths[0], p[0], rot[0], backend='numba')
    for k in range(1, 20):
        path_l = gs.inverse_kinematics(geom, p[0] + k * 1e-4, rot[0])
        prev = gs.forward_kinematics(geom, path_l, prev.position, prev.rotation, backend='numba')
        assert prev.converged and np.abs(prev.position - (p[0] + k * 1e-4)).max() < 1e-9


@pytest.mark.parametrize('backend', BACKENDS)
def test_single_solver_refusals(backend):
    geom = gs.GoughStewartGeometry.from_rings(0.5, 0.5, 10 * DEG, 10 * DEG, 0.45, 1.5)
    p = np.array([0, 0, 0.6])
    near = gs.rotation_matrix([0, 0, 89.9 * DEG])
    lengths = gs.inverse_kinematics(geom, p, near)
    with pytest.raises(gs.SingularPoseError, match='near-singular'):
        gs.forward_kinematics(geom, lengths, p + 0.001, near, backend=backend)
    res = gs.forward_kinematics(geom, lengths, p + 0.001, near, max_condition=1e4,
                                backend=backend)
    assert res.converged and np.abs(res.position - p).max() < 1e-9
    with pytest.raises(gs.UnreachablePoseError):
        gs.forward_kinematics(geom, lengths + 1.0, p, near, backend=backend)
    flat = gs.GoughStewartGeometry.from_rings(0.5, 0.3, 10 * DEG, 10 * DEG, 0.1, 1.0)
    flat_l = gs.inverse_kinematics(flat, [0, 0, 0], np.eye(3))
    with pytest.raises(gs.SingularPoseError):
        gs.forward_kinematics(flat, flat_l, [0, 0, 0.01], np.eye(3), backend=backend)
    few = gs.forward_kinematics(geom, gs.inverse_kinematics(geom, p, np.eye(3)), p + 0.05,
                                np.eye(3), max_iter=1, backend=backend)
    assert not few.converged and few.iterations == 1
