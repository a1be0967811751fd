"""The paper's forward kinematics (49 coordinates, eq. (4)) against the leg-length solve."""
import math

import numpy as np
import pytest

from climber_pkg.constraint_fk import (
    N_COORDS,
    compare_with_leg_length_solve,
    constraints,
    coordinates_from_pose,
    forward_kinematics_49,
    universal_axes,
)
from climber_pkg.robot import load_robot_config
from paramotion import gough_stewart as gs

GEOM = load_robot_config().geometry


def test_the_assembly_of_a_pose_satisfies_the_49_constraints():
    pos, rot = np.array([0.01, -0.02, 0.5]), gs.rotation_matrix(np.radians([3, -2, 5]))
    lengths = gs.inverse_kinematics(GEOM, pos, rot)
    q = coordinates_from_pose(GEOM, pos, rot)
    phi = constraints(GEOM, q, lengths)
    assert q.shape == (N_COORDS,) and phi.shape == (N_COORDS,)
    assert np.abs(phi).max() < 1e-12
    # Each leg body's cross axis is perpendicular to its universal joint's base axis.
    legs = q.reshape(7, 7)[1:]
    for body, u in zip(legs, universal_axes(GEOM)):
        x = gs.matrix_from_quaternion(body[3:])[:, 0]
        assert abs(x @ u) < 1e-12
    # A different length breaks exactly the driving constraint of that leg.
    bad = lengths.copy()
    bad[2] += 0.01
    phi = constraints(GEOM, q, bad)
    assert phi[36 + 2] == pytest.approx(-0.01)
    assert np.abs(np.delete(phi, 36 + 2)).max() < 1e-12


def test_paper_and_leg_length_solves_agree():
    c = compare_with_leg_length_solve(12, seed=4)
    assert c['max_position_diff_m'] < 1e-9
    assert c['max_rotation_diff'] < 1e-9
    assert c['max_residual'] < 1e-10


def test_paper_solve_from_a_distant_guess_and_its_singularity_measure():
    pos, rot = np.array([0.0, 0.0, 0.45]), np.eye(3)
    lengths = gs.inverse_kinematics(GEOM, pos, rot)
    fk = forward_kinematics_49(GEOM, lengths, pos + [0.03, -0.02, 0.05],
                               gs.rotation_matrix(np.radians([4, 0, -6])))
    assert fk.converged and fk.residual < 1e-12
    np.testing.assert_allclose(fk.position, pos, atol=1e-10)
    np.testing.assert_allclose(fk.rotation, rot, atol=1e-10)
    assert abs(fk.det_phi_q) > 1e-6
    assert math.isfinite(fk.det_phi_q)
