"""No silent loss in recording: every message published on a recorded topic is in the bag, or
the recorder reports it lost in transport.

The sonar ring publishes a burst of ``count`` (16) sensor_msgs/Range messages per sweep on
``/sonar/ranges``. The tests count what the sonar node publishes (its publisher is wrapped) and
what the bag holds, in a lock-step one-process run (nothing may be lost) and with the recorder
and the simulator in processes of their own (best effort: what the transport drops must be in
the recorder's loss report); a recorder process stopped under a burst makes the transport drop
samples on purpose.
"""
import os
import re
import signal
import time
from collections import Counter
from pathlib import Path

import pytest

from paramotion.bag.reader import bag_info, read_messages
from paramotion.launch import NodeProcess, wait_until

pytestmark = pytest.mark.slow  # recorded coverage runs, one of them over several processes

WORLD = Path(__file__).resolve().parents[1] / 'coverage_pkg' / 'worlds' / 'two_rooms.json'


def _count_publishes(publisher):
    """Wrap ``publisher.publish`` so that the sent messages' stamps are listed."""
    sent = []
    publish = publisher.publish

    def counting(msg):
        sent.append((msg.header.stamp.sec, msg.header.stamp.nanosec))
        publish(msg)
    publisher.publish = counting
    return sent


def _recorded_stamps(bag, topic):
    from rclpy.serialization import deserialize_message
    from sensor_msgs.msg import Range
    out = []
    for m in read_messages(bag, [topic]):
        msg = deserialize_message(m.data, Range)
        out.append((msg.header.stamp.sec, msg.header.stamp.nanosec))
    return out


def test_lockstep_coverage_run_records_every_sonar_range(tmp_path):
    from paramotion.graph import Graph
    from paramotion.launch import graph_from_launch
    bag = tmp_path / 'bag'
    with Graph() as graph:
        nodes, topics = graph_from_launch(graph, 'coverage', {'world': str(WORLD)})
        sonar = nodes['coverage_sonar']
        sent = _count_publishes(sonar.range_pub)
        graph.record(bag, topics + ['/sonar/ranges'])
        graph.run_lockstep(nodes['coverage_sim'], max_sim_time=3.0)
        sweeps = sonar.sweeps
    assert sweeps >= 25
    assert len(sent) == 16 * sweeps
    got = _recorded_stamps(bag, '/sonar/ranges')
    print(f'one process: {len(sent)} Range messages published, {len(got)} recorded')
    assert len(got) == len(sent), (len(got), len(sent))
    assert Counter(got) == Counter(sent)
    assert all(n == 16 for n in Counter(got).values())
    assert bag_info(bag).topics['/sonar/scan'].count == sweeps


def test_recorder_in_its_own_process_records_every_sonar_range(tmp_path):
    """Simulator and recorder each in a process; the sonar in this one (to count exactly).

    ``/sonar/ranges`` is best effort (sensor data): across processes DDS does not retransmit,
    and a loaded machine can make the transport drop a sample (see
    paramotion/bag/recorder_node.py). Every published sample is in the bag or counted in the
    recorder's loss report; the test prints both.
    """
    from coverage_pkg.sonar_node import CoverageSonarNode
    from paramotion.graph import Graph
    bag = tmp_path / 'bag'
    domain = int(os.environ['ROS_DOMAIN_ID'])
    recorder = NodeProcess('paramotion.bag.recorder_node', params={
        'output': str(bag), 'topics': ['/sonar/ranges', '/clock'], 'flush_period': 0.2},
        log_path=tmp_path / 'recorder.log')
    sim = None
    try:
        with Graph(domain_id=domain) as graph:
            sonar = graph.add(CoverageSonarNode, world=str(WORLD))
            sent = _count_publishes(sonar.range_pub)
            # The sonar publishes ranges only once it has a pose, i.e. once simulated time runs,
            # and only to a matched reader: its writer must see the recorder's reader, and the
            # reader must see the writer, or it drops what arrives. The first is waited for
            # here; for the second, the recorder subscribes to /clock only once its own
            # /sonar/ranges reader has matched, so the simulator holds time until /clock has two
            # subscribers (the sonar and the recorder).
            assert graph.spin_wall(30.0, until=lambda:
                                   sonar.range_pub.get_subscription_count() > 0)
            sim = NodeProcess('coverage_pkg.sim_node', params={
                'world': str(WORLD), 'real_time_factor': 2.0,
                'wait_for_matched': ['/coverage/ground_truth:1'],
                'wait_for_clock_subscribers': 2},
                log_path=tmp_path / 'sim.log')
            assert graph.spin_wall(60.0, until=lambda: sonar.sweeps >= 40), \
                (tmp_path / 'sim.log').read_text()[-2000:]
        # The sonar is gone (nothing more is published): wait until the bag holds all of it.
        wait_until(lambda: _readable(bag) >= len(sent), 30.0, period=0.2)
        assert recorder.interrupt() == 0, (tmp_path / 'recorder.log').read_text()[-2000:]
    finally:
        recorder.kill()
        if sim is not None:
            sim.kill()
    got = _recorded_stamps(bag, '/sonar/ranges')
    log = (tmp_path / 'recorder.log').read_text()
    lost = _reported_lost(log, '/sonar/ranges')
    print(f'across processes: {len(sent)} Range messages published, {len(got)} recorded, '
          f'{lost} reported lost')
    assert len(sent) >= 16 * 40
    missing = sorted((Counter(sent) - Counter(got)).elements())
    assert len(got) + lost == len(sent), (
        f'{len(got)} of {len(sent)} recorded, {lost} reported lost; missing stamps '
        f'{missing[:20]}; published from {sent[0]} to {sent[-1]}; recorder log: {log[-1500:]}')
    assert not Counter(got) - Counter(sent)      # nothing recorded twice or never sent


def _readable(bag):
    if not any(Path(bag).glob('*.mcap')):
        return 0
    try:
        return sum(1 for _ in read_messages(bag, ['/sonar/ranges']))
    except Exception:   # a chunk being written
        time.sleep(0.05)
        return 0


def _reported_lost(log, topic):
    """The recorder's running count of ``topic``'s samples lost in transport (0 if none)."""
    counts = re.findall(re.escape(topic) + r': \d+ sample\(s\) lost in transport \((\d+) so far',
                        log)
    return int(counts[-1]) if counts else 0


def test_samples_the_transport_drops_are_reported_lost(tmp_path):
    """A recorder process stopped (SIGSTOP) while a best-effort publisher bursts 1,500 samples:
    the transport's queue to it overflows and samples are dropped. Each one missing from the
    bag is in the recorder's loss report (the middleware's *message lost* event), so recorded
    plus reported equals published, and some were really dropped."""
    from functools import partial

    from rclpy.node import Node
    from rclpy.qos import qos_profile_sensor_data
    from sensor_msgs.msg import Range

    from paramotion.graph import Graph
    bag = tmp_path / 'bag'
    log = tmp_path / 'recorder.log'
    recorder = NodeProcess('paramotion.bag.recorder_node', params={
        'output': str(bag), 'topics': ['/sonar/ranges'], 'flush_period': 0.2,
        'use_sim_time': False}, log_path=log)
    sent = []
    try:
        with Graph(domain_id=int(os.environ['ROS_DOMAIN_ID'])) as graph:
            node = graph.add(partial(Node, 'loss_talker'))
            pub = node.create_publisher(Range, '/sonar/ranges', qos_profile_sensor_data)

            def burst(count, pause):
                for _ in range(count):
                    msg = Range()
                    msg.header.stamp.sec = len(sent)
                    pub.publish(msg)
                    sent.append(len(sent))
                    time.sleep(pause)

            assert graph.spin_wall(30.0, until=lambda: pub.get_subscription_count() > 0)
            burst(32, 0.005)       # the reader has taken samples of this writer: it can tell
            assert wait_until(lambda: _readable(bag) >= 32, 30.0, period=0.2)   # a gap
            os.killpg(recorder.proc.pid, signal.SIGSTOP)
            try:
                burst(1500, 0.0)
            finally:
                os.killpg(recorder.proc.pid, signal.SIGCONT)
            burst(32, 0.005)
            wait_until(lambda: _readable(bag) + _reported_lost(log.read_text(), '/sonar/ranges')
                       >= len(sent), 30.0, period=0.2)
        assert recorder.interrupt() == 0, log.read_text()[-2000:]
    finally:
        recorder.kill()
    got = [stamp for stamp, _ in _recorded_stamps(bag, '/sonar/ranges')]
    lost = _reported_lost(log.read_text(), '/sonar/ranges')
    print(f'recorder stopped under a burst: {len(sent)} published, {len(got)} recorded, '
          f'{lost} reported lost')
    assert lost > 0
    assert len(got) + lost == len(sent), log.read_text()[-2000:]
    assert len(set(got)) == len(got) and set(got) <= set(sent)
