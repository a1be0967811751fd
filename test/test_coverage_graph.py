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
ROOM = {'name': 'room', 'boundary': [[0, 0], [7, 0], [7, 6], [0, 6]], 'obstacles': [],
        'start': [1.0, 1.0]}


def _world(tmp_path, data=SMALL, name='small.json'):
    p = tmp_path / name
    p.write_text(json.dumps(data))
    return p


def _run_with_silence(tmp_path, world, **kwargs):
    """The coverage graph in one executor, recorded, with 1.5 s of sonar silence from 8 s."""
    from coverage_pkg.scenario import run_coverage
    bag = tmp_path / 'bag'
    r = run_coverage(_world(tmp_path, world), bag_dir=bag, max_sim_time=400.0,
                     sonar_params={'silence_start': 8.0, 'silence_duration': 1.5}, **kwargs)
    assert r['outcome'] == 'complete', r['events'][-3:]
    assert r['covered_fraction_of_cvs'] >= 0.99
    assert r['sim_time_s'] < 400.0
    assert r['path_length_m'] > r['lower_bound_path_m']
    kinds = [e[1] for e in r['events']]
    assert 'sonar_timeout' in kinds and 'sonar_resumed' in kinds
    stop = next(e for e in r['events'] if e[1] == 'sonar_timeout')
    assert 8.0 <= stop[0] <= 8.0 + 0.5 + 0.15
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
    return r


@pytest.mark.slow
def test_full_graph_covers_a_room_with_the_paper_planner_and_terminates(tmp_path):
    """The default graph (paper planner): sim + sonar + planner + monitor + recorder in one
    executor, with 1.5 s of sonar silence half-way: the planner stops, resumes, covers >= 99 %
    of CVS and says it is done. In the 7 m x 6 m room VR is the rectangle 2 m from the walls
    and NR the band along them, whose GVD is the four corners' diagonals: the hand-computed
    graph is one vast node joined by one cusp each to four narrow corner nodes, the start's
    corner first; every node but the start is created by a sensed cusp, and all are covered."""
    r = _run_with_silence(tmp_path, ROOM)
    assert r['planner'] == 'paper'
    g = r['hierarchical_graph']
    alive = [n for n in g['nodes'] if n['alive']]
    assert [n['type'] for n in alive] == ['narrow', 'vast', 'narrow', 'narrow', 'narrow']
    assert all(n['covered'] for n in alive)
    assert alive[0]['created_by_event'] is None
    for n in alive[1:]:
        assert r['events'][n['created_by_event']][1] == 'cusp', n
    vast = alive[1]['id']
    assert sorted((e['vast'], e['narrow'], len(e['cusp_points'])) for e in g['edges']) == \
        [(vast, n['id'], 1) for n in alive if n['id'] != vast]
    corners = [(0, 0), (7, 0), (7, 6), (0, 6)]
    assert sorted(min(range(4), key=lambda i: math.dist(corners[i], n['anchor'][:2]))
                  for n in alive if n['type'] == 'narrow') == [0, 1, 2, 3]
    assert set(r['primitive_lengths_m']) >= {'lap', 'boundary', 'gvd'}


@pytest.mark.slow
def test_full_graph_with_the_grid_planner_covers_a_small_world(tmp_path):
    """``planner='grid'`` (ours) in the same graph: every free point of the 9 m x 6 m room is
    within delta = 2 m of a wall or the obstacle, so VR is empty and the grid planner's space
    is one narrow cell, covered, with no edge."""
    r = _run_with_silence(tmp_path, SMALL, planner='grid')
    assert r['planner'] == 'grid'
    alive = [n for n in r['hierarchical_graph']['nodes'] if n['alive']]
    assert [(n['type'], n['covered']) for n in alive] == [('narrow', True)]
    assert r['hierarchical_graph']['edges'] == []


@pytest.mark.parametrize('world, extra, words', [
    ({'boundary': [[0, 0], [4, 4], [4, 0], [0, 4]], 'start': [1, 1]}, [],
     'not a simple polygon'),
    ({'boundary': [[0, 0], [4, 0], [4, 4], [0, 4]], 'start': [9, 9]}, [], 'outside'),
    (SMALL, ['--delta', '0.2'], 'must be greater than --radius'),
    (SMALL, ['--sonar-max-range', '1.5'], 'must exceed the detector range delta'),
    (SMALL, ['--planner', 'grid', '--without', 'cusp'], 'applies to --planner paper only'),
    (SMALL, ['--planner', 'paper', '--detector', 'robot'], 'needs --planner grid'),
    (SMALL, ['--detector', 'robot'], 'needs --planner grid'),     # the default: paper
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


def test_the_paper_planner_is_the_default_everywhere():
    """coverage_planner, the launch file, paramotion coverage / demo / coverage-ratio /
    coverage sweep all run Algorithm 1 unless asked for the grid planner."""
    import argparse

    from coverage_pkg import demo, scenario, sweep
    from coverage_pkg.planner_node import CoveragePlannerNode
    from paramotion import launch_xml
    assert scenario.DEFAULT_PLANNER == 'paper'
    assert next(p for p in CoveragePlannerNode.PARAMS if p.name == 'planner').default == 'paper'
    assert launch_xml.load('coverage').node('coverage_planner').params['planner'] == 'paper'
    sub = argparse.ArgumentParser().add_subparsers()
    scenario.register(sub)
    sweep.register(sub)    # ``sweep`` under ``coverage``, as paramotion.cli registers it
    demo.register(sub)
    for name, args in (('coverage', ['--world', 'w.json']), ('coverage-benchmark',
                                                             ['--world', 'w.json']),
                       ('coverage-ratio', ['--worlds', 'd']), ('demo', []),
                       ('coverage', ['sweep', '--worlds', 'd'])):
        assert sub.choices[name].parse_args(args).planner == 'paper', name


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


def _sample_config(params, **changes):
    """The planner configuration of the recorded run (params.json), with ``changes``."""
    from coverage_pkg.algorithm1 import PaperConfig
    from coverage_pkg.planner import PlannerConfig
    cls = {'paper': PaperConfig, 'grid': PlannerConfig}[params['planner']]
    return cls(delta=params['delta'], radius=params['radius'], **changes)


def test_replayed_bag_gives_the_same_decisions():
    """bags/coverage_sample: odometry and sonar recorded from a full run of the default graph
    (the paper planner); a fresh planner fed the same inputs sends exactly the recorded
    velocity commands and finishes the same way."""
    sample = BAGS / 'coverage_sample'
    params = json.loads((sample / 'params.json').read_text())
    assert params['planner'] == 'paper'
    mine, recorded, planner = _replay(sample / 'bag', _sample_config(params),
                                      params['beam_width'])
    assert len(recorded) > 150                 # the recorded run is about 31 s
    assert mine == recorded
    assert planner.state == 'done'
    status = [deserialize(m) for m in read_messages(sample / 'bag', ['/coverage/status'])]
    last = {kv.key: kv.value for kv in status[-1].status[0].values}
    assert last['state_now'] == 'done'
    # Same decisions, not just the same motion: the sequence of chosen nodes is recorded.
    assert [d[1:3] for d in planner.decisions] == [tuple(d) for d in params['node_choices']]
    # ... made on the same sensed events at the same sim times (cusps, critical points, nodes
    # created and covered, the end).
    assert [[e[0], e[1]] for e in planner.events] == params['events']
    assert [e[1] for e in planner.events].count('cusp') >= 4


def test_replay_detects_a_different_planner():
    """The replay comparison is sharp: a planner with another speed limit is caught."""
    sample = BAGS / 'coverage_sample'
    params = json.loads((sample / 'params.json').read_text())
    mine, recorded, _ = _replay(sample / 'bag', _sample_config(params, max_speed=0.9),
                                params['beam_width'])
    assert mine != recorded
    assert not math.isnan(sum(v for c in mine for v in c))
