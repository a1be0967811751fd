"""Robot description validation and inverse kinematics (eqs. (1)-(3)) of cable_robot_pkg.cdrpm."""
import math

import numpy as np
import pytest
import yaml

from cable_robot_pkg.cdrpm import collisions as col
from cable_robot_pkg.cdrpm.description import (
    description_from_dict,
    load_description,
    shipped_descriptions,
)
from cable_robot_pkg.cdrpm.kinematics import (
    inverse_kinematics,
    matrix_to_angles_deg,
    quaternion_to_matrix,
    rotation_matrix,
    rotation_matrix_deg,
)
from paramotion.errors import UserError


def _neuron_dict():
    return load_description().to_dict()


def test_shipped_descriptions_load_and_are_consistent():
    paths = shipped_descriptions()
    names = {p.stem for p in paths}
    assert {'kntu_neuron', 'kntu_neuron_home', 'kntu_pinwheel', 'kntu_uncrossed',
            'kntu_tetra_cross'} <= names
    for path in paths:
        desc = load_description(path)
        assert desc.n_cables == 8
        np.testing.assert_allclose(desc.frame_half_size, [1.0, 2.0, 1.0])     # Table I
        np.testing.assert_allclose(desc.platform_half_size, [0.1, 0.1, 0.1])  # Table I
        # Cables to all eight platform corners, from eight distinct points on the frame edges
        # (at least two coordinates on the frame's faces).
        corners = {tuple(np.sign(p)) for p in desc.platform_points}
        assert len(corners) == 8
        assert len({tuple(a) for a in desc.frame_points}) == 8
        on_faces = np.isclose(np.abs(desc.frame_points), desc.frame_half_size)
        assert np.all(on_faces.sum(axis=1) >= 2)
        assert desc.checks_per_pose() == 44                                   # eq. (9)
        assert desc.pair_i.size == 28


def test_neuron_symmetry_stated_in_section_iv_a():
    """Invariant under the half turns about x and y, not under the z mirror (see the YAML)."""
    desc = load_description()

    def cables(t):
        return {(tuple(np.round(b * t, 9)), tuple(np.round(a * t, 9)))
                for a, b in zip(desc.frame_points, desc.platform_points)}

    base = cables(np.ones(3))
    assert cables(np.array([-1.0, 1.0, -1.0])) == base
    assert cables(np.array([1.0, -1.0, -1.0])) == base
    assert cables(np.array([1.0, 1.0, -1.0])) != base


@pytest.mark.parametrize('change,field', [
    ({'frame_points': [[0, 0, 0]] * 7 + [[1, 1]]}, 'frame_points'),
    ({'frame_points': [[1, 2, 1]] * 7}, 'platform_points'),
    ({'platform_points': [[0.1, 0.1, 0.1, 0.1]] * 8}, 'platform_points'),
    ({'platform_points': 'corners'}, 'platform_points'),
    ({'frame_points': [[float('nan'), 2.0, 1.0]] + [[1.0, 2.0, 1.0]] * 7}, 'frame_points'),
    ({'platform_half_size': [0.1, float('nan'), 0.1]}, 'platform_half_size'),
    ({'platform_half_size': [0.1, 0.1]}, 'platform_half_size'),
    ({'cable_radius': -0.001}, 'cable_radius'),
    ({'cable_radius': 'thin'}, 'cable_radius'),
    ({'cable_radius': float('inf')}, 'cable_radius'),
    ({'platform_half_size': [1.5, 0.1, 0.1]}, 'platform_half_size'),
    ({'platform_half_size': [1.0, 0.1, 0.1]}, 'platform_half_size'),
    ({'frame_half_size': [0.5, 2.0, 1.0]}, 'frame_points'),
    ({'platform_points': [[0.2, 0.1, 0.1]] + [[0.1, 0.1, 0.1]] * 7}, 'platform_points'),
    ({'platform_points': [[0.0, 0.0, 0.05]] + [[0.1, 0.1, 0.1]] * 7}, 'platform_points'),
    ({'workpiece': [1.0, 1.0, -0.5]}, 'workpiece'),
    ({'workpiece': [3.0, 1.0, 0.5]}, 'workpiece'),
    ({'body_delta': 0.5}, 'body_delta'),
    ({'colour': 'red'}, 'colour'),
])
def test_malformed_descriptions_are_refused_with_the_field_named(change, field):
    data = _neuron_dict()
    data.update(change)
    with pytest.raises(UserError) as info:
        description_from_dict(data, 'bad.yaml')
    message = str(info.value)
    assert field in message and 'bad.yaml' in message
    assert '\n' not in message


def test_missing_fields_and_files(tmp_path):
    for key in ('frame_points', 'platform_points', 'platform_half_size', 'cable_radius'):
        data = _neuron_dict()
        del data[key]
        with pytest.raises(UserError, match=f"missing field '{key}'"):
            description_from_dict(data)
    with pytest.raises(UserError, match='file not found'):
        load_description(tmp_path / 'nope.yaml')
    bad = tmp_path / 'broken.yaml'
    bad.write_text('frame_points: [[1, 2\n')
    with pytest.raises(UserError, match='invalid YAML'):
        load_description(bad)
    bad.write_text('- just a list\n')
    with pytest.raises(UserError, match='mapping'):
        load_description(bad)


def test_round_trip_through_yaml(tmp_path):
    path = tmp_path / 'robot.yaml'
    data = _neuron_dict()
    data['workpiece'] = [0.8, 0.6, 0.3]
    path.write_text(yaml.safe_dump(data))
    desc = load_description(path)
    np.testing.assert_allclose(desc.workpiece, [0.8, 0.6, 0.3])
    lo, hi = desc.workpiece_box
    np.testing.assert_allclose(lo, [-0.4, -0.3, -1.0])
    np.testing.assert_allclose(hi, [0.4, 0.3, -0.7])


def test_rotation_conventions():
    rng = np.random.default_rng(5)
    angles = rng.uniform(-80, 80, (50, 3))
    rots = rotation_matrix_deg(*angles.T)
    for (rx, ry, rz), rot in zip(angles, rots):
        rx_, ry_, rz_ = np.radians([rx, ry, rz])
        cx, sx, cy, sy, cz, sz = (math.cos(rx_), math.sin(rx_), math.cos(ry_), math.sin(ry_),
                                  math.cos(rz_), math.sin(rz_))
        mx = np.array([[1, 0, 0], [0, cx, -sx], [0, sx, cx]])
        my = np.array([[cy, 0, sy], [0, 1, 0], [-sy, 0, cy]])
        mz = np.array([[cz, -sz, 0], [sz, cz, 0], [0, 0, 1]])
        np.testing.assert_allclose(rot, mx @ my @ mz, atol=1e-14)
    np.testing.assert_allclose(np.stack(matrix_to_angles_deg(rots), axis=1), angles, atol=1e-9)
    # Quaternion about z by 90 deg (ROS order x, y, z, w).
    q = [0, 0, math.sin(math.pi / 4), math.cos(math.pi / 4)]
    np.testing.assert_allclose(quaternion_to_matrix(q), rotation_matrix(0, 0, math.pi / 2),
                               atol=1e-12)
    with pytest.raises(ValueError):
        quaternion_to_matrix([0, 0, 0, 0])


def test_inverse_kinematics_eqs_1_to_3():
    desc = load_description()
    rng = np.random.default_rng(2)
    pos = rng.uniform(-0.5, 0.5, (20, 3))
    rots = rotation_matrix(*rng.uniform(-0.5, 0.5, (3, 20)))
    ik = inverse_kinematics(desc, pos, rots)
    for k in range(20):
        for i in range(8):
            b = pos[k] + rots[k] @ desc.platform_points[i]
            vec = b - desc.frame_points[i]                    # A_iB_i from eq. (1)
            assert abs(ik.lengths[k, i] - np.linalg.norm(vec)) < 1e-12       # eq. (2)
            np.testing.assert_allclose(ik.directions[k, i], vec / np.linalg.norm(vec),
                                       atol=1e-12)                            # eq. (3)
    assert ik.reachable.all()
    # At the centre with zero rotation the Neuron's two cable orbits (generated by corners
    # (+,+,+) -> (-f_a, f_b, 0.2) and (-,+,+) -> (-f_a, -0.1, f_h)) have one length each.
    ik0 = inverse_kinematics(desc, [[0, 0, 0]], np.eye(3))
    first = math.sqrt(1.1 ** 2 + 1.9 ** 2 + 0.1 ** 2)
    second = math.sqrt(0.9 ** 2 + 0.2 ** 2 + 0.9 ** 2)
    np.testing.assert_allclose(ik0.lengths[0], [first, second, second, first,
                                                second, first, first, second])


def test_pose_outside_frame_is_reported_as_outside_not_collision():
    desc = load_description()
    outside = [[0.95, 0.0, 0.0], [0.0, 2.5, 0.0], [0.0, 0.0, -1.2]]
    flags = col.classify_poses(desc, outside, np.eye(3))
    assert np.all(flags == col.OUTSIDE)
    counts = col.count_flags(flags)
    assert counts['outside_frame'] == 3
    assert all(counts[t] == 0 for t in col.COLLISION_TYPES)
    # A pose whose centroid is inside but whose rotated platform pokes through a wall.
    flags = col.classify_poses(desc, [[0.89, 0.0, 0.0]], rotation_matrix_deg(0, 0, 45))
    assert flags[0] == col.OUTSIDE
    report = col.check_pose(desc, [0.0, 2.5, 0.0], np.eye(3))
    assert not report.inside_frame and not report.colliding_pairs and not report.body_cables
    assert not report.collision_free
    ik = inverse_kinematics(desc, [[0.0, 2.5, 0.0], [0.0, 0.0, 0.0]], np.eye(3))
    assert list(ik.reachable) == [False, True]
