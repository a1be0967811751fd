"""The climbing graph in one executor: PyBullet sim + two ultrasonic triplets + planner.

An integration test climbs a short curved, tapering structure never seen before to its top;
others check safe refusals inside the graph, the command line's input validation, the node
parameters and the structure-file validation.
"""
import json
import math

import numpy as np
import pytest

from climber_pkg.robot import load_robot_config
from climber_pkg.scenario import run_climb
from climber_pkg.trunk import Trunk
from paramotion.bag.reader import bag_info
from paramotion.cli import main as cli_main
from paramotion.errors import ParameterError, UserError

ROBOT = load_robot_config()


def write_trunk(path, centerline, radius, name='t'):
    path.write_text(json.dumps({'name': name, 'units': 'm', 'centerline': centerline,
                                'radius': radius}))
    return path


@pytest.mark.slow
def test_graph_climbs_short_curved_trunk_to_the_top(tmp_path):
    z = np.linspace(0.0, 1.9, 7)
    centre = np.stack([0.1 * (z / 1.9) ** 2, -0.05 * np.sin(z), z], 1)
    trunk = write_trunk(tmp_path / 'curved.json', centre.tolist(), [[0, 0.25], [1.9, 0.19]])
    result, trace, _ = run_climb(trunk, tmp_path / 'bag', delta=0.1, noise=0.001,
                                 dropout=0.05, max_time=100, start_offset=0.02, start_tilt=3.0,
                                 seed=2)
    assert result['planner_state'] == 'done', result['planner_message']
    assert result['reached_top']
    assert result['ring_trunk_contacts'] == 0
    assert result['min_ring_clearance_m'] > 0.05
    assert result['clamp_invariant_ok'] and result['interlock_trips'] == 0
    assert result['within_stroke']
    assert result['max_jacobian_condition'] < 30
    assert result['off_axis_start_m'] > 0.02             # started off the axis
    assert result['off_axis_settled_max_m'] < 0.015
    assert result['success']
    info = bag_info(tmp_path / 'bag')
    assert info.complete
    for topic in ('/climber/ground_truth', '/climber/joint_states', '/climber/leg_command',
                  '/climber/ring1/ultrasonic', '/climber/ring2/clamp_closed'):
        assert info.topics[topic].count > 0


@pytest.mark.slow
def test_graph_refuses_safely_on_nan_sensors(tmp_path):
    trunk = write_trunk(tmp_path / 'straight.json', [[0, 0, 0], [0, 0, 3]], 0.2)
    result, _, _ = run_climb(trunk, None, fault=1.0, max_time=8)
    assert result['planner_state'] == 'refused'
    assert 'nan' in result['refusal'].lower()
    assert result['clamp_invariant_ok'] and result['steps'] == 0


@pytest.mark.slow
def test_graph_turns_around_the_trunk(tmp_path):
    trunk = write_trunk(tmp_path / 'straight.json', [[0, 0, 0], [0, 0, 3]], 0.2)
    result, _, _ = run_climb(trunk, None, mode='turn', turn_deg=-30, max_time=30)
    assert result['planner_state'] == 'done', result['planner_message']
    assert result['ring_turn_deg'] == pytest.approx([-30, -30], abs=1.0)
    assert result['clamp_invariant_ok'] and result['ring_trunk_contacts'] == 0


def test_cli_refuses_trunk_thicker_than_bore(tmp_path, capsys):
    trunk = write_trunk(tmp_path / 'fat.json', [[0, 0, 0], [0, 0, 3]], [[0, 0.36], [3, 0.3]])
    out = tmp_path / 'out'
    assert cli_main(['climb', '--trunk', str(trunk), '--out', str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert 'thicker than the ring clearance' in err and err.count('\n') == 0
    assert not out.exists()


@pytest.mark.parametrize('content, words', [
    ('{"centerline": [[0,0,0]], "radius": 0.2}', 'at least two'),
    ('{"centerline": [[0,0,0],[0,0,1]], "radius": -1}', 'positive'),
    ('{"centerline": [[0,0,0],[0,0,1]]}', "missing key 'radius'"),
    ('{"centerline": [[0,0,0],[0,0,1],[0,0,0.5]], "radius": 0.2}', 'folds back'),
    ('{"centerline": [[0,0,0],[0,0,"a"]], "radius": 0.2}', 'numbers'),
    ('{"centerline": [[0,0,0],[0,0,1]], "radius": [[0, 0.2], [1, NaN]]}', 'non-finite'),
    ('not json', 'not valid JSON'),
])
def test_bad_trunk_files_rejected(tmp_path, content, words):
    path = tmp_path / 'bad.json'
    path.write_text(content)
    with pytest.raises(UserError, match=words):
        Trunk.from_file(path)


def test_cli_bad_arguments(tmp_path, capsys):
    trunk = write_trunk(tmp_path / 'ok.json', [[0, 0, 0], [0, 0, 2]], 0.2)
    assert cli_main(['climb', '--trunk', str(trunk), '--delta', '-1',
                     '--out', str(tmp_path / 'o')]) == 2
    assert '--delta' in capsys.readouterr().err
    assert cli_main(['climb', '--trunk', str(tmp_path / 'missing.json'),
                     '--out', str(tmp_path / 'o')]) == 2
    assert 'no such file' in capsys.readouterr().err


def test_cli_start_pose_and_ablation_arguments(tmp_path, capsys):
    trunk = write_trunk(tmp_path / 'ok.json', [[0, 0, 0], [0, 0, 2]], 0.2)
    for extra, words in ((['--start-offset', '-0.1'], '--start-offset'),
                         (['--start-offset', '0.5'], 'at most 0.2 m'),
                         (['--start-tilt', '40'], 'at most 30 deg')):
        assert cli_main(['climb', '--trunk', str(trunk), *extra,
                         '--out', str(tmp_path / 'o')]) == 2
        err = capsys.readouterr().err.strip()
        assert words in err and err.count('\n') == 0
    with pytest.raises(SystemExit):
        cli_main(['climb', '--trunk', str(trunk), '--without', 'gait'])
    assert "invalid choice: 'gait'" in capsys.readouterr().err
    assert not (tmp_path / 'o').exists()


def test_sim_starts_off_centre_and_tilted(tmp_path):
    from climber_pkg.kinematic_model import initial_pose_on_trunk
    from climber_pkg.sim_node import ClimberSimNode
    from paramotion.graph import Graph
    path = write_trunk(tmp_path / 'straight.json', [[0, 0, 0], [0, 0, 3]], 0.2)
    trunk = Trunk.from_file(path)
    with Graph() as graph:
        sim = graph.add(ClimberSimNode, trunk_file=str(path), start_offset=0.03,
                        start_tilt_deg=5.0, start_seed=4)
        (p1, r1), (p2, r2) = sim.ring_poses()
        (q1, s1), (q2, s2) = initial_pose_on_trunk(trunk, ROBOT, 0.4, np.full(6, 0.5), 0.03,
                                                   math.radians(5.0), 4)
        np.testing.assert_allclose(p1, q1, atol=2e-3)
        np.testing.assert_allclose(p2, q2, atol=2e-3)
        assert math.degrees(math.acos(r1[2, 2])) == pytest.approx(5.0, abs=0.2)
        assert np.hypot(*p1[:2]) > 0.01                   # off the axis
        with pytest.raises(ParameterError, match="'start_offset'"):
            graph.add(ClimberSimNode, name='too_far', trunk_file=str(path), start_offset=0.19)


def test_node_parameters_validated():
    from climber_pkg.planner_node import ClimberPlannerNode
    from climber_pkg.ultrasonic_node import ClimberUltrasonicNode
    from paramotion.graph import Graph
    with Graph() as graph:
        with pytest.raises(ParameterError, match="'delta'"):
            graph.add(ClimberPlannerNode, delta=2.0)
        with pytest.raises(ParameterError, match="'delta_min'"):
            graph.add(ClimberPlannerNode, delta=0.05, delta_min=0.1)
        with pytest.raises(ParameterError, match="'mode'"):
            graph.add(ClimberPlannerNode, mode='fly')
        with pytest.raises(ParameterError, match="'without'"):
            graph.add(ClimberPlannerNode, without='correction,gait')
        with pytest.raises(ParameterError, match="'approach'"):
            graph.add(ClimberPlannerNode, approach='secant')
        paper = graph.add(ClimberPlannerNode, name='planner_paper', approach='paper',
                          without='prediction')
        assert paper.gait.p.approach == 'paper' and paper.gait.p.without == ('prediction',)
        with pytest.raises(ParameterError, match="'ring'"):
            graph.add(ClimberUltrasonicNode, ring=3, trunk_file='x.json')
        planner = graph.add(ClimberPlannerNode, name='planner_ok')
        res = planner.set_parameters_atomically([])
        assert res.successful


def test_trunk_queries():
    trunk = Trunk([[0, 0, 0], [0, 0, 2]], [[0, 0.3], [2, 0.2]])
    assert trunk.length == pytest.approx(2.0)
    assert float(trunk.radius_at(1.0)) == pytest.approx(0.25)
    s, d = trunk.closest(np.array([[0.5, 0, 1.0], [0, 0, 3.0]]))
    assert s[0] == pytest.approx(1.0) and d[0] == pytest.approx(0.5)
    assert s[1] == pytest.approx(2.0)
    dist = trunk.ray_distance([[0.38, 0, 1.0]], [[-1, 0, 0]], 0.4)
    assert dist[0] == pytest.approx(0.38 - 0.25, abs=1e-6)
    assert math.isinf(trunk.ray_distance([[0.38, 0, 2.5]], [[-1, 0, 0]], 0.4)[0])
    point, s_at = trunk.axis_in_plane([0.01, 0.02, 1.3], [0, 0, 1])
    assert s_at == pytest.approx(1.3) and np.allclose(point, [0, 0, 1.3])


def test_batched_cone_distances_equal_the_trunk_cones():
    """The ultrasonic node casts every cone's centre and rim rays in one batch, by numpy or by
    the compiled kernels; each ray is computed on its own either way, so the distances equal
    Trunk.cone_distance bit for bit: on the packaged trunks, near and off the axis, tilted,
    past the foot and the top, with the robot's cone and other fields of view (0: the centre
    ray alone)."""
    from climber_pkg.cone_cast import cone_distances
    from paramotion.backend import resolve_backend
    backends = ['numpy'] + (['numba'] if resolve_backend('auto') == 'numba' else [])
    from paramotion.rotations import matrix_from_rotvec
    origins, dirs = ROBOT.sensor_rays()
    rng = np.random.default_rng(5)
    finite = 0
    for name in ('straight_palm', 's_bend_pipe', 'leaning_palm'):
        trunk = Trunk.from_file(f'climber_pkg/trunks/{name}.json')
        for k in range(60):
            s = rng.uniform(-0.3, trunk.length + 0.3)
            s_in = min(max(s, 0.0), trunk.length)
            pos, rot = trunk.frame_at(s_in)
            pos = pos + rng.normal(0.0, 0.08 if k % 3 == 0 else 0.01, 3) + (s - s_in) * rot[:, 2]
            rot = matrix_from_rotvec(rng.normal(0.0, 0.3 if k % 2 else 0.05, 3)) @ rot
            fov = (ROBOT.sensor_fov, 0.0, float(rng.uniform(0.05, 1.0)))[k % 3]
            o, d = pos + origins @ rot.T, dirs @ rot.T
            want = trunk.cone_distance(o, d, fov, ROBOT.sensor_max_range)
            for backend in backends:
                got = cone_distances(trunk, o, d, fov, ROBOT.sensor_max_range, backend=backend)
                assert np.array_equal(got, want), (name, k, backend, got, want)
            finite += int(np.isfinite(want).sum())
    assert finite > 300          # most cones see the structure: echoes are compared, not infs


def test_compiled_trunk_closest_points_equal_the_trunk_ones():
    """paramotion climb's evaluation queries closest points with the compiled refinement:
    the same arc lengths and distances bit for bit, for points near and far from the axis,
    past both ends, single points and batches."""
    from climber_pkg.cone_cast import CompiledTrunk
    rng = np.random.default_rng(7)
    for name in ('straight_palm', 's_bend_pipe', 'leaning_palm'):
        path = f'climber_pkg/trunks/{name}.json'
        plain, compiled = Trunk.from_file(path), CompiledTrunk.from_file(path)
        lo, hi = plain.points.min(axis=0) - 0.5, plain.points.max(axis=0) + 0.5
        batch = rng.uniform(lo, hi, (400, 3))
        near = plain.points[rng.integers(len(plain.points), size=200)] + rng.normal(
            0.0, 0.05, (200, 3))
        for pts in (batch, near, near.reshape(10, 20, 3), near[0]):
            for got, want in zip(compiled.closest(pts), plain.closest(pts)):
                assert got.shape == want.shape and np.array_equal(got, want), name
