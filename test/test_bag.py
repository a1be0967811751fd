"""rosbag2 MCAP bags: format checked with independent readers, replay, damage, SIGKILL."""
import os
import shutil
import subprocess
import sys
import time
from pathlib import Path

import pytest
import rclpy
import yaml
from mcap.reader import make_reader
from rclpy.executors import SingleThreadedExecutor
from rclpy.serialization import deserialize_message
from rosbags.highlevel import AnyReader
from sensor_msgs.msg import Range
from std_msgs.msg import String

from paramotion.bag.cli import reindex
from paramotion.bag.player_node import BagPlayerNode
from paramotion.bag.reader import BagReadError, bag_info, read_messages
from paramotion.cli import main as cli_main
from paramotion.graph import Graph
from paramotion.launch import wait_until
from paramotion.smoke.controller_node import SmokeControllerNode
from paramotion.smoke.scenario import TOPICS, run_lockstep

SAMPLE = Path(__file__).resolve().parents[1] / 'bags' / 'smoke_sample'


@pytest.fixture(scope='module')
def recorded(tmp_path_factory):
    bag = tmp_path_factory.mktemp('rec') / 'bag'
    result = run_lockstep(bag, duration=3.0)
    return bag, result


def test_bag_is_rosbag2_v9_mcap_readable_by_rosbags(recorded):
    bag, _ = recorded
    assert (bag / 'metadata.yaml').is_file()
    meta = yaml.safe_load((bag / 'metadata.yaml').read_text())['rosbag2_bagfile_information']
    assert meta['version'] == 9 and meta['storage_identifier'] == 'mcap'
    with AnyReader([bag]) as reader:
        topics = {c.topic: c for c in reader.connections}
        assert set(topics) == set(TOPICS)
        status = topics['/smoke/status']
        assert status.ext.offered_qos_profiles[0].durability.name == 'TRANSIENT_LOCAL'
        assert topics['/smoke/range'].ext.offered_qos_profiles[0].reliability.name == \
            'BEST_EFFORT'
        ranges = [reader.deserialize(raw, c.msgtype)
                  for c, _, raw in reader.messages([topics['/smoke/range']])]
    assert len(ranges) >= 55  # 20 Hz for 3 s, first reading after the first pose
    for r in ranges:
        assert r.radiation_type == Range.ULTRASOUND
        assert r.max_range > r.min_range > 0 and r.field_of_view > 0


def test_mcap_file_has_ros2_profile_msg_schemas_and_cdr(recorded):
    bag, _ = recorded
    mcap_file = next(bag.glob('*.mcap'))
    with open(mcap_file, 'rb') as f:
        reader = make_reader(f)
        header = reader.get_header()
        summary = reader.get_summary()
        assert header.profile == 'ros2'
        assert {s.encoding for s in summary.schemas.values()} == {'ros2msg'}
        assert {c.message_encoding for c in summary.channels.values()} == {'cdr'}
        assert all('offered_qos_profiles' in c.metadata for c in summary.channels.values())
        first = next(reader.iter_messages(topics=['/smoke/ground_truth']))
        from geometry_msgs.msg import PoseStamped
        pose = deserialize_message(first[2].data, PoseStamped)
        assert pose.header.frame_id == 'map'


def _replay(bag, out, topics, record, remap=None, extra=None):
    with Graph() as graph:
        player = graph.add(BagPlayerNode, bag=str(bag), topics=topics,
                           remap=[f'{a}:={b}' for a, b in (remap or {}).items()] or [''])
        if extra:
            extra(graph)
        graph.record(out, record)
        graph.run_lockstep(player, until=lambda: player.finished)
        # one more period so the last messages' responses are recorded too
        player.advance()
        graph.drain()
        return player.published


def test_replayed_messages_equal_recorded(tmp_path):
    topics = ['/smoke/ground_truth', '/smoke/range', '/smoke/cmd_vel', '/smoke/status']
    _replay(SAMPLE, tmp_path / 'replay', topics, topics)
    for topic in topics:
        original = [m.data for m in read_messages(SAMPLE, [topic])]
        replayed = [m.data for m in read_messages(tmp_path / 'replay', [topic])]
        assert replayed == original, topic
        assert original


def test_replay_into_fresh_controller_makes_same_decisions(tmp_path):
    _replay(SAMPLE, tmp_path / 'decisions', ['/smoke/range'], ['/smoke/cmd_vel'],
            extra=lambda g: g.add(SmokeControllerNode, target=1.0))
    original = [m.data for m in read_messages(SAMPLE, ['/smoke/cmd_vel'])]
    fresh = [m.data for m in read_messages(tmp_path / 'decisions', ['/smoke/cmd_vel'])]
    assert len(original) > 50 and fresh == original


def test_replay_topic_selection_and_remapping(tmp_path):
    n = _replay(SAMPLE, tmp_path / 'remap', ['/smoke/range'], ['/replayed/range'],
                remap={'/smoke/range': '/replayed/range'})
    info = bag_info(tmp_path / 'remap')
    expected = bag_info(SAMPLE).topics['/smoke/range'].count
    assert n == expected
    assert set(info.topics) == {'/replayed/range'}
    assert info.topics['/replayed/range'].count == expected


def test_replay_publishes_clock_from_bag(tmp_path):
    _replay(SAMPLE, tmp_path / 'clock', ['/smoke/range'], ['/clock', '/smoke/range'])
    times = [m.log_time_ns for m in read_messages(tmp_path / 'clock', ['/smoke/range'])]
    original = [m.log_time_ns for m in read_messages(SAMPLE, ['/smoke/range'])]
    assert times == original


def test_truncated_bag_reports_file_and_recovered_count(tmp_path, capsys):
    damaged = tmp_path / 'damaged'
    shutil.copytree(SAMPLE, damaged)
    mcap_file = next(damaged.glob('*.mcap'))
    data = mcap_file.read_bytes()
    mcap_file.write_bytes(data[: len(data) * 2 // 3])
    info = bag_info(damaged)
    assert str(mcap_file) in info.problem and 'recovered' in info.problem
    with pytest.raises(BagReadError) as err:
        read_messages(damaged, strict=True)
    assert str(mcap_file) in str(err.value) and '\n' not in str(err.value)
    assert cli_main(['bag', 'info', str(damaged)]) == 1
    err_text = capsys.readouterr().err.strip()
    assert len(err_text.splitlines()) == 1 and 'recovered' in err_text


def test_garbage_file_is_a_clear_error(tmp_path, capsys):
    bad = tmp_path / 'garbage'
    bad.mkdir()
    (bad / 'garbage.mcap').write_bytes(os.urandom(4096))
    assert 'garbage.mcap' in bag_info(bad).problem
    assert cli_main(['bag', 'info', str(tmp_path / 'missing')]) == 2
    assert 'no such bag' in capsys.readouterr().err


def _readable_count(bag, topic):
    """Messages of ``topic`` that the reader recovers from a bag still being written."""
    if not any(bag.glob('*.mcap')):
        return 0
    try:
        return sum(1 for _ in read_messages(bag, [topic]))
    except Exception:
        return 0


@pytest.mark.slow
def test_recorder_killed_with_sigkill_leaves_complete_chunks(tmp_path):
    """A recorder process SIGKILLed mid-run: everything up to its last flush reads back, and
    ``paramotion bag reindex`` turns the file into a complete bag."""
    bag = tmp_path / 'killed'
    env = dict(os.environ)
    proc = subprocess.Popen(
        [sys.executable, '-m', 'paramotion.bag.recorder_node', '--ros-args',
         '-p', f'output:={bag}', '-p', 'topics:=[/test/chatter]', '-p', 'flush_period:=0.2',
         '-p', 'use_sim_time:=false'],
        env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    context = rclpy.Context()
    rclpy.init(context=context)
    node = rclpy.create_node('chatter', context=context)
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(node)
    pub = node.create_publisher(String, '/test/chatter', 10)
    try:
        assert wait_until(lambda: pub.get_subscription_count() > 0, timeout=20.0)
        time.sleep(1.0)  # let the recorder's discovery-side match settle too
        sent = 0
        end = time.monotonic() + 2.0
        while time.monotonic() < end:
            pub.publish(String(data=f'msg {sent}'))
            sent += 1
            executor.spin_once(timeout_sec=0.01)
        # Wait until the flushed chunks hold what was sent (a loaded machine can lag the
        # recorder by more than a few flush periods), then kill it mid-run.
        end = time.monotonic() + 15.0
        while time.monotonic() < end and _readable_count(bag, '/test/chatter') < sent:
            time.sleep(0.2)
        time.sleep(0.3)
        proc.kill()
        proc.wait(10)
    finally:
        if proc.poll() is None:
            proc.kill()
        executor.shutdown()
        node.destroy_node()
        rclpy.try_shutdown(context=context)
    info = bag_info(bag)
    assert not (bag / 'metadata.yaml').exists()
    assert info.problem  # unfinished file is reported, not hidden
    got = [deserialize_message(m.data, String).data
           for m in read_messages(bag, ['/test/chatter'])]
    assert len(got) >= 0.8 * sent, (len(got), sent)
    assert got == [f'msg {i}' for i in range(int(got[0].split()[1]), int(got[0].split()[1])
                                             + len(got))]
    _check_reindexed(bag, got)


def _check_reindexed(bag, recovered):
    """``paramotion bag reindex`` makes the bag complete: footer, summary and metadata.yaml,
    opened by rosbags and by the mcap library's seeking reader (as Foxglove's), holding exactly
    the messages that were readable before."""
    assert cli_main(['bag', 'reindex', str(bag)]) == 0
    assert (bag / 'metadata.yaml').is_file()
    info = bag_info(bag)
    assert info.complete, info.problem
    meta = yaml.safe_load((bag / 'metadata.yaml').read_text())['rosbag2_bagfile_information']
    assert meta['message_count'] == len(recovered) == info.message_count
    with AnyReader([bag]) as reader:
        assert [reader.deserialize(raw, c.msgtype).data for c, _, raw in reader.messages()] \
            == recovered
    mcap_file = next(bag.glob('*.mcap'))
    with open(mcap_file, 'rb') as f:
        reader = make_reader(f)
        assert reader.get_header().profile == 'ros2'
        summary = reader.get_summary()
        assert summary.statistics.message_count == len(recovered)
        assert all('offered_qos_profiles' in c.metadata for c in summary.channels.values())
        assert [deserialize_message(m.data, String).data
                for _, _, m in reader.iter_messages()] == recovered
    assert (bag / (mcap_file.name + '.truncated')).is_file()    # the original is kept
    assert cli_main(['bag', 'info', str(bag)]) == 0


def test_reindex_recovers_every_whole_message_of_a_cut_file(tmp_path):
    """The sample bag cut at two thirds: its one chunk is cut off, yet every message that lies
    wholly before the cut is recovered, in order, into a complete file (as mcap recover)."""
    damaged = tmp_path / 'cut'
    shutil.copytree(SAMPLE, damaged)
    (damaged / 'metadata.yaml').unlink()
    mcap_file = next(damaged.glob('*.mcap'))
    data = mcap_file.read_bytes()
    mcap_file.write_bytes(data[: len(data) * 2 // 3])
    original = read_messages(SAMPLE)
    reindex(damaged)
    info = bag_info(damaged)
    assert info.complete, info.problem
    got = read_messages(damaged, strict=True)
    assert 0.6 * len(original) < len(got) < len(original)
    assert [(m.topic, m.log_time_ns, m.data) for m in got] == \
        [(m.topic, m.log_time_ns, m.data) for m in original[:len(got)]]
    with AnyReader([damaged]) as reader:
        assert sum(1 for _ in reader.messages()) == len(got)
        assert {c.topic for c in reader.connections} == set(bag_info(SAMPLE).topics)


def test_metadata_names_the_ros_distro(recorded):
    bag, _ = recorded
    meta = yaml.safe_load((bag / 'metadata.yaml').read_text())['rosbag2_bagfile_information']
    assert meta['ros_distro'] == 'jazzy'
