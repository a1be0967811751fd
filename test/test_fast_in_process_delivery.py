"""The lock-step Graph's in-process delivery (paramotion.executors.InProcessDelivery) changes what
the FAST graph costs, not what its nodes receive: the same values and types, the same queue
depths, and the middleware wherever a reader needs it."""
import array

import numpy as np
import pytest
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from geometry_msgs.msg import PoseStamped
from rclpy.node import Node
from rclpy.qos import QoSProfile
from rclpy.serialization import deserialize_message, serialize_message
from sensor_msgs.msg import Imu, JointState, LaserScan, Range
from std_msgs.msg import Float64

from paramotion.executors import copy_message
from paramotion.graph import Graph, graph_defaults


def _same(a, b, path='msg'):
    """Field by field: equal values of equal Python types (what a callback can tell apart)."""
    assert type(a) is type(b), f'{path}: {type(a).__name__} != {type(b).__name__}'
    if hasattr(a, 'get_fields_and_field_types'):
        for name in a.get_fields_and_field_types():
            _same(getattr(a, name), getattr(b, name), f'{path}.{name}')
    elif isinstance(a, np.ndarray):
        assert a.dtype == b.dtype and np.array_equal(a, b), path
    elif isinstance(a, (list, array.array)):
        if isinstance(a, array.array):
            assert a.typecode == b.typecode, path
        assert len(a) == len(b), path
        for i, (x, y) in enumerate(zip(a, b)):
            _same(x, y, f'{path}[{i}]')
    else:
        assert a == b, f'{path}: {a!r} != {b!r}'


def _messages():
    pose = PoseStamped()
    pose.header.stamp.sec, pose.header.stamp.nanosec = 3, 5_000_000
    pose.header.frame_id = 'map'
    pose.pose.position.x = np.float64(0.1)     # a numpy scalar, delivered as a float
    pose.pose.orientation.w = 1.0
    joints = JointState(name=('a', 'b'), position=[0.1, 0.2], velocity=np.array([1.0, 2.0]))
    rng = Range(range=0.1, min_range=0.3, max_range=2.5)   # float32 scalars: rounded
    scan = LaserScan(ranges=[0.1, 0.2, 0.3], angle_increment=0.01)
    imu = Imu()
    imu.orientation_covariance = np.arange(9.0)
    diag = DiagnosticArray(status=[DiagnosticStatus(name='x', level=b'\x01', values=[
        KeyValue(key='k', value='v')])])
    return [pose, joints, rng, scan, imu, diag]


@pytest.mark.parametrize('index', range(6))
def test_copy_message_gives_what_the_middleware_delivers(index):
    msg = _messages()[index]
    got = copy_message(msg)
    want = deserialize_message(serialize_message(msg), type(msg))
    _same(got, want)
    assert got is not msg


class _Talker(Node):
    def __init__(self, **kwargs):
        super().__init__('delivery_talker', **kwargs)


def _exchange(depth, raw_reader=False, outside_reader=False):
    """Three messages published in a row, one changed after it was published; a drain; what
    each reader got and whether the topic went in process."""
    with Graph() as graph:
        node = graph.add(_Talker)
        pub = node.create_publisher(Float64, '/delivery_probe', QoSProfile(depth=depth))
        got, raw, outside = [], [], []
        node.create_subscription(Float64, '/delivery_probe', lambda m: got.append(m.data),
                                 QoSProfile(depth=depth))
        if raw_reader:
            node.create_subscription(Float64, '/delivery_probe', raw.append,
                                     QoSProfile(depth=10), raw=True)
        if outside_reader:
            other = Node('delivery_outsider', context=graph.context)
            sub = other.create_subscription(Float64, '/delivery_probe',
                                            lambda m: outside.append(m.data), 10)
        graph.drain()
        msg = Float64(data=1.0)
        for value in (1.0, 2.0, 3.0):
            msg = Float64(data=value)
            pub.publish(msg)
        msg.data = 99.0            # changed after publishing: readers keep the published value
        graph.drain()
        fed = bool(graph._lockstep.delivery and graph._lockstep.delivery.fed)
        if outside_reader:
            for _ in range(3):
                taken = sub.handle.take_message(Float64, False)
                if taken is not None:
                    outside.append(taken[0].data)
            other.destroy_node()
        return got, len(raw), outside, fed


def test_in_process_delivery_keeps_the_queue_depth_and_the_published_values():
    with graph_defaults(in_process_delivery=False):
        want = _exchange(2)
    got = _exchange(2)
    assert got[0] == want[0] == [2.0, 3.0]     # depth 2: the oldest dropped, as DDS does
    assert not want[3] and got[3]               # in process only with the lever on
    assert _exchange(10)[0] == [1.0, 2.0, 3.0]


def test_topics_with_raw_or_outside_readers_stay_on_the_middleware():
    got, raw, _, fed = _exchange(10, raw_reader=True)
    assert got == [1.0, 2.0, 3.0] and raw == 3 and not fed
    got, _, outside, fed = _exchange(10, outside_reader=True)
    assert got == [1.0, 2.0, 3.0] and outside == [1.0, 2.0, 3.0] and not fed


def _late_reader():
    """A second reader joins after the topic went in process; what each reader gets."""
    with Graph() as graph:
        node = graph.add(_Talker)
        pub = node.create_publisher(Float64, '/delivery_late', 10)
        first, second = [], []
        node.create_subscription(Float64, '/delivery_late', lambda m: first.append(m.data), 10)
        graph.drain()
        pub.publish(Float64(data=1.0))
        graph.drain()
        node.create_subscription(Float64, '/delivery_late', lambda m: second.append(m.data), 10)
        pub.publish(Float64(data=2.0))       # the publisher sees a reader more than it fed
        graph.drain()
        pub.publish(Float64(data=3.0))
        graph.drain()
        return first, second


def test_a_reader_joining_later_gets_what_the_middleware_would_give_it():
    with graph_defaults(in_process_delivery=False):
        want = _late_reader()
    got = _late_reader()
    assert got == want
    assert got[0] == [1.0, 2.0, 3.0] and got[1][-1] == 3.0


def test_every_reader_of_the_fast_graph_is_fed_in_process(monkeypatch):
    """The lever is in use where it matters: in the FAST graph (no recorder) every
    subscription of every node is fed in process, so its drain rounds need no middleware
    wait."""
    from cable_robot_pkg.fast.scenario import LAUNCH_FILE, detach_qos_event_handlers
    from paramotion.launch import graph_from_launch
    monkeypatch.delenv('ROS_DOMAIN_ID', raising=False)    # a private graph, as users get
    with Graph() as graph:
        nodes, _ = graph_from_launch(graph, LAUNCH_FILE, {})
        detach_qos_event_handlers(graph.nodes)
        graph.run_lockstep(nodes['fast_sim'], max_sim_time=0.05)
        delivery = graph._lockstep.delivery
        subs = [sub for node in graph.nodes for sub in node.subscriptions]
        assert len(subs) >= 15
        assert {id(sub) for sub in subs} <= delivery.fed
        assert not graph._lockstep._wait_sets     # no round needed the middleware's wait


def test_spinning_on_wall_time_after_a_drain_uses_the_middleware_again():
    """After a lock-step drain handed messages over in process, ``spin_wall`` (rclpy's
    executor) still delivers, and the next drain goes in process again."""
    with Graph() as graph:
        node = graph.add(_Talker)
        pub = node.create_publisher(Float64, '/delivery_wall', 10)
        got = []
        node.create_subscription(Float64, '/delivery_wall', lambda m: got.append(m.data), 10)
        graph.drain()
        pub.publish(Float64(data=1.0))
        graph.drain()
        assert graph._lockstep.delivery.fed
        pub.publish(Float64(data=2.0))          # handed over, not yet taken
        graph.spin_wall(0.2, until=lambda: len(got) >= 2)
        assert got == [1.0, 2.0]
        pub.publish(Float64(data=3.0))          # through the middleware now
        assert graph.spin_wall(2.0, until=lambda: len(got) >= 3)
        pub.publish(Float64(data=4.0))
        graph.drain()
        assert got == [1.0, 2.0, 3.0, 4.0] and graph._lockstep.delivery.fed
