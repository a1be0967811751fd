"""The coverage graph as ROS 2 nodes: integration in one executor, bad input, replay of a bag."""
import json
import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from paramotion.bag.reader import bag_info, deserialize, read_messages
from paramotion.cli import main as cli_main
from paramotion.errors import ParameterError

BAGS = Path(__file__).resolve().parents[1] / 'bags'

SMALL = {'name': 'small', 'boundary': [[0, 0], [9, 0], [9, 6], [0, 6]],
         'obstacles': [[[4, 2.5], [5.5, 2.5], [5.5, 3.5], [4, 3.5]]], 'start': [1.0, 1.0]}


def _world(tmp_path, data=SMALL, name='small.json'):
    p = tmp_path / name
    p.write_text(json.dumps(data))
    return p


def test_full_graph_covers_a_small_world_and_terminates(tmp_path):
    """Sim + sonar + planner + monitor + recorder in one executor, with 1.5 s of sonar silence
    half-way: the planner stops, resumes, covers >= 99 % of CVS and says it is done."""
    from coverage_pkg.scenario import run_coverage
    world = _world(tmp_path)
    bag = tmp_path / 'bag'
    r = run_coverage(world, bag_dir=bag, max_sim_time=400.0,
                     sonar_params={'silence_start': 8.0, 'silence_duration': 1.5})
    assert r['outcome'] == 'complete', r['events'][-3:]
    assert r['covered_fraction_of_cvs'] >= 0.99
    assert r['sim_time_s'] < 400.0
    assert r['path_length_m'] > r['lower_bound_path_m']
    kinds = [e[1] for e in r['events']]
    assert 'sonar_timeout' in kinds and 'sonar_resumed' in kinds
    stop = next(e for e in r['events'] if e[1] == 'sonar_timeout')
    assert 8.0 <= stop[0] <= 8.0 + 0.5 + 0.15
    # Every free point of the 9 m x 6 m room is within delta = 2 m of a wall or the obstacle:
    # VR is empty and the space is one narrow cell (Sec. IV-A), covered, with no edge.
    alive = [n for n in r['hierarchical_graph']['nodes'] if n['alive']]
    assert [(n['type'], n['covered']) for n in alive] == [('narrow', True)]
    assert r['hierarchical_graph']['edges'] == []
    assert r['given_up_nodes'] == []
    info = bag_info(bag)
    assert info.complete
    for topic in ('/coverage/ground_truth', '/sonar/scan', '/cmd_vel',
                  '/coverage/markers', '/coverage/status', '/odom'):
        assert info.topics[topic].count > 0, topic
    # While the sonar was silent the robot did not move (ground truth in the bag).
    truth = [deserialize(m) for m in read_messages(bag, ['/coverage/ground_truth'])]
    quiet = [(t.pose.pose.position.x, t.pose.pose.position.y) for t in truth
             if 8.8 <= t.header.stamp.sec + t.header.stamp.nanosec * 1e-9 <= 9.4]
    assert quiet and np.ptp(np.array(quiet), axis=0).max() < 0.02
    # The last status says done.
    status = [deserialize(m) for m in read_messages(bag, ['/coverage/status'])]
    values = {kv.key: kv.value for kv in status[-1].status[0].values}
    assert values['state_now'] == 'done'


@pytest.mark.parametrize('world, extra, words', [
    ({'boundary': [[0, 0], [4, 4], [4, 0], [0, 4]], 'start': [1, 1]}, [],
     'not a simple polygon'),
    ({'boundary': [[0, 0], [4, 0], [4, 4], [0, 4]], 'start': [9, 9]}, [], 'outside'),
    (SMALL, ['--delta', '0.2'], 'must be greater than --radius'),
    (SMALL, ['--sonar-max-range', '1.5'], 'must exceed the detector range delta'),
    (SMALL, ['--planner', 'grid', '--without', 'cusp'], 'applies to --planner paper only'),
    (SMALL, ['--planner', 'paper', '--detector', 'robot'], 'needs --planner grid'),
])
def test_bad_input_gives_one_line_error_and_no_output(tmp_path, capsys, world, extra, words):
    out = tmp_path / 'out'
    code = cli_main(['coverage', '--world', str(_world(tmp_path, world)), '--out', str(out)]
                    + extra)
    err = capsys.readouterr().err.strip()
    assert code == 2
    assert words in err and len(err.splitlines()) == 1
    assert not out.exists()
    assert not list(tmp_path.glob('.out.partial*'))


def test_sonar_ring_publishes_rep117_ranges_and_scan(tmp_path):
    from sensor_msgs.msg import LaserScan, Range

    from coverage_pkg.sim_node import CoverageSimNode
    from coverage_pkg.sonar_node import SONAR_QOS, CoverageSonarNode
    from paramotion.graph import Graph
    from paramotion.qos import SENSOR_QOS
    world = _world(tmp_path)
    with Graph() as graph:
        sim = graph.add(CoverageSimNode, world=str(world))
        sonar = graph.add(CoverageSonarNode, world=str(world), max_range=5.0, min_range=0.05,
                          beam_width=0.3, fault_probability=0.2)
        ranges, scans = [], []
        sonar.create_subscription(Range, 'sonar/ranges', ranges.append, SONAR_QOS)
        sonar.create_subscription(LaserScan, 'sonar/scan', scans.append, SENSOR_QOS)
        graph.run_lockstep(sim, max_sim_time=2.0)
    assert len(scans) >= 18
    assert all(len(s.ranges) == 16 and s.range_max == 5.0 for s in scans)
    values = np.array([v for s in scans for v in s.ranges])
    assert np.isinf(values).any() and np.isnan(values).any()   # far walls, injected faults
    finite = values[np.isfinite(values)]
    assert np.all((finite >= 0.05) & (finite <= 5.0))
    assert ranges
    for m in ranges:
        assert m.radiation_type == Range.ULTRASOUND
        assert m.field_of_view == pytest.approx(0.3)
        assert (m.min_range, m.max_range) == (pytest.approx(0.05), 5.0)
        assert m.header.frame_id.startswith('sonar_')
        assert math.isnan(m.range) or math.isinf(m.range) or 0.05 <= m.range <= 5.0


def test_planner_never_loads_the_world_or_the_monitor():
    """The planner process imports no world reader and no ground-truth consumer."""
    code = ('import sys, coverage_pkg.planner_node; '
            "print(sorted(m for m in sys.modules if m in ('coverage_pkg.world', "
            "'coverage_pkg.cvs', 'coverage_pkg.monitor_node', 'coverage_pkg.sim_node', "
            "'coverage_pkg.sonar_node', 'shapely')))")
    out = subprocess.run([sys.executable, '-c', code], capture_output=True, text=True,
                         cwd=Path(__file__).resolve().parents[1], check=True)
    assert out.stdout.strip() == '[]'


@pytest.mark.parametrize('node', ['sim', 'sonar', 'monitor'])
def test_nodes_refuse_a_bad_world_file_as_a_bad_parameter(tmp_path, node):
    from coverage_pkg.monitor_node import CoverageMonitorNode
    from coverage_pkg.sim_node import CoverageSimNode
    from coverage_pkg.sonar_node import CoverageSonarNode
    from paramotion.graph import Graph
    cls = {'sim': CoverageSimNode, 'sonar': CoverageSonarNode,
           'monitor': CoverageMonitorNode}[node]
    bad = _world(tmp_path, {'boundary': [[0, 0], [4, 4], [4, 0], [0, 4]], 'start': [1, 1]})
    with Graph() as graph:
        with pytest.raises(ParameterError, match="parameter 'world': .*not a simple polygon"):
            graph.add(cls, world=str(bad))


def test_planner_node_refuses_delta_not_above_radius():
    from coverage_pkg.planner_node import CoveragePlannerNode
    from paramotion.graph import Graph
    with Graph() as graph:
        with pytest.raises(ParameterError, match="'delta' = 0.2 must be greater than"):
            graph.add(CoveragePlannerNode, delta=0.2, radius=0.25)


@pytest.mark.parametrize('params, words', [
    ({'planner': 'paper', 'without': 'cusp,meets'}, 'without "meets" must be one of'),
    ({'planner': 'grid', 'without': 'cusp'}, "'without' applies to planner 'paper' only"),
])
def test_planner_node_refuses_a_bad_ablation(params, words):
    from coverage_pkg.planner_node import CoveragePlannerNode
    from paramotion.graph import Graph
    with Graph() as graph:
        with pytest.raises(ParameterError, match=words):
            graph.add(CoveragePlannerNode, **params)


def _replay(bag, config, beam_width):
    """Feed a fresh planner the recorded odometry and sonar; return its commands and it."""
    from coverage_pkg.planner import PlannerDriver
    from coverage_pkg.sonar import yaw_of
    driver = PlannerDriver(config, beam_width)
    mine, recorded = [], []
    for m in read_messages(bag, ['/odom', '/sonar/scan', '/cmd_vel'], strict=True):
        msg = deserialize(m)
        if m.topic == '/cmd_vel':
            recorded.append((msg.linear.x, msg.linear.y, msg.angular.z))
            continue
        t = msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9
        if m.topic == '/odom':
            p = msg.pose.pose
            driver.on_odometry(t, p.position.x, p.position.y, yaw_of(p.orientation))
        else:
            angles = msg.angle_min + msg.angle_increment * np.arange(len(msg.ranges))
            cmd = driver.on_scan(t, np.asarray(msg.ranges, dtype=float), angles,
                                 msg.range_min, msg.range_max)
            if cmd is not None:
                mine.append((cmd.vx, cmd.vy, cmd.wz))
    return mine, recorded, driver.planner


def test_replayed_bag_gives_the_same_decisions():
    """bags/coverage_sample: odometry and sonar recorded from a full run; a fresh planner fed
    the same inputs sends exactly the recorded velocity commands and finishes the same way."""
    from coverage_pkg.planner import PlannerConfig
    sample = BAGS / 'coverage_sample'
    params = json.loads((sample / 'params.json').read_text())
    config = PlannerConfig(delta=params['delta'], radius=params['radius'])
    mine, recorded, planner = _replay(sample / 'bag', config, params['beam_width'])
    assert len(recorded) > 150                 # the recorded run is 25.1 s
    assert mine == recorded
    assert planner.state == 'done'
    status = [deserialize(m) for m in read_messages(sample / 'bag', ['/coverage/status'])]
    last = {kv.key: kv.value for kv in status[-1].status[0].values}
    assert last['state_now'] == 'done'
    # Same decisions, not just the same motion: the sequence of chosen nodes is recorded.
    assert [d[1:3] for d in planner.decisions] == [tuple(d) for d in params['node_choices']]


def test_replay_detects_a_different_planner():
    """The replay comparison is sharp: a planner with another speed limit is caught."""
    from coverage_pkg.planner import PlannerConfig
    sample = BAGS / 'coverage_sample'
    params = json.loads((sample / 'params.json').read_text())
    config = PlannerConfig(delta=params['delta'], radius=params['radius'], max_speed=0.9)
    mine, recorded, _ = _replay(sample / 'bag', config, params['beam_width'])
    assert mine != recorded
    assert not math.isnan(sum(v for c in mine for v in c))
