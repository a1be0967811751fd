"""The compiled COW kernel (numba) gives the same collision flags as the numpy path, bit for bit.

numba is pinned in requirements.txt; the numpy path is the fallback used when it is missing or
``PARAMOTION_BACKEND=numpy``, and the reference here.
"""
import zlib

import numpy as np
import pytest

from cable_robot_pkg.cdrpm import collisions as col
from cable_robot_pkg.cdrpm import workspace as ws
from cable_robot_pkg.cdrpm.description import CONFIG_DIR, load_description
from cable_robot_pkg.cdrpm.kinematics import rotation_matrix_deg

ROBOTS = sorted(p.name for p in CONFIG_DIR.glob('kntu_*.yaml'))


@pytest.mark.parametrize('robot', ROBOTS)
def test_numba_matches_numpy_on_random_poses(robot):
    desc = load_description(CONFIG_DIR / robot)
    rng = np.random.default_rng(zlib.crc32(robot.encode()))
    half = desc.frame_half_size
    seen = set()
    for _ in range(12):
        rot = rotation_matrix_deg(*rng.uniform(-60, 60, size=3))
        # Mostly inside the frame, some outside; plus a cluster around one point so that
        # close calls (pairs near 2 eps) are sampled densely.
        pos = rng.uniform(-1.1 * half, 1.1 * half, size=(4000, 3))
        pos[:1000] = rng.normal(scale=0.05, size=(1000, 3)) + pos[0] * 0.5
        fast = col.classify_poses(desc, pos, rot, backend='numba')
        ref = col.classify_poses(desc, pos, rot, backend='numpy')
        assert fast.dtype == ref.dtype == np.uint8
        np.testing.assert_array_equal(fast, ref)
        seen.update(np.unique(ref).tolist())
    assert col.OUTSIDE in seen and 0 in seen


def test_numba_matches_numpy_on_table2_grids():
    desc = load_description()
    for rot, _, _ in ws.TABLE2_ROWS:
        pts = ws.grid_points(ws.grid_axes(desc, 0.1))
        r = rotation_matrix_deg(*rot)
        fast = col.classify_poses(desc, pts, r, backend='numba')
        np.testing.assert_array_equal(fast, col.classify_poses(desc, pts, r, backend='numpy'))


def test_numba_handles_degenerate_cables_like_numpy():
    # A platform point on its frame anchor (zero-length cable), parallel cables and poses
    # exactly on the frame limit.
    desc = load_description()
    rot = np.eye(3)
    b_minus_a = desc.frame_points - desc.platform_points
    on_anchor = b_minus_a[:3]
    edge = desc.frame_half_size - desc.platform_half_size
    pos = np.vstack([on_anchor, edge, -edge, np.zeros(3), [[0, 0, 1e-12]]])
    np.testing.assert_array_equal(col.classify_poses(desc, pos, rot, backend='numba'),
                                  col.classify_poses(desc, pos, rot, backend='numpy'))


def test_backend_choice_by_environment(monkeypatch):
    desc = load_description()
    pts = ws.grid_points(ws.grid_axes(desc, 0.2))
    rot = rotation_matrix_deg(0, 30, 0)
    monkeypatch.setenv('PARAMOTION_BACKEND', 'numpy')
    ref = col.classify_poses(desc, pts, rot)
    monkeypatch.setenv('PARAMOTION_BACKEND', 'numba')
    np.testing.assert_array_equal(col.classify_poses(desc, pts, rot), ref)
    monkeypatch.setenv('PARAMOTION_BACKEND', 'cython')
    with pytest.raises(ValueError, match='PARAMOTION_BACKEND'):
        col.classify_poses(desc, pts, rot)


def test_benchmark_cow_reports_a_rate():
    out = ws.benchmark_cow(step=0.2, repeats=2)
    assert out['kntu_points'] == ws.grid_points(ws.grid_axes(load_description(), 0.2)).shape[0]
    assert out['kntu_poses_per_s'] > 0 and len(out['kntu_times_s']) == 2
    assert out['kntu_backend'] in ('numba', 'numpy')
