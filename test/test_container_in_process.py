"""In-process delivery among a component container's nodes (paramotion.intra_process).

A message published by one component for another in the same container process arrives once,
with the content the middleware would deliver: handed over as an object while no reader
outside the container listens (the middleware never carries it), through the middleware while
one does (the outside reader gets it too); a publisher outside the container still reaches the
container's reader.
"""
import time

import pytest
import rclpy
from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy
from rclpy.serialization import serialize_message
from sensor_msgs.msg import JointState

from paramotion.container import ComponentContainer, component_params
from paramotion.executors import spin_node
from paramotion.graph import private_domain_id
from paramotion.node import ParamotionNode
from paramotion.qos import STATE_QOS

TOPIC = '/in_process_test/joints'


class _Talker(ParamotionNode):
    USE_SIM_TIME_DEFAULT = False

    def __init__(self, node_name='talker', **kwargs):
        super().__init__(node_name, **kwargs)
        self.pub = self.create_publisher(JointState, TOPIC, STATE_QOS)


class _Listener(ParamotionNode):
    USE_SIM_TIME_DEFAULT = False

    def __init__(self, node_name='listener', **kwargs):
        super().__init__(node_name, **kwargs)
        self.received = []
        self.sub = self.create_subscription(JointState, TOPIC, self.received.append, STATE_QOS)


class _Box(ComponentContainer):
    COMPONENTS = {'talker': _Talker, 'listener': _Listener}
    PARAMS = component_params(COMPONENTS)
    USE_SIM_TIME_DEFAULT = False

    def __init__(self, **kwargs):
        super().__init__('box', **kwargs)


def _message(k: int) -> JointState:
    msg = JointState(name=[f'leg{i}' for i in range(3)], position=[k + 0.1, k + 0.2, k / 3],
                     velocity=[float(k)] * 3, effort=[])
    msg.header.stamp.sec = k
    msg.header.frame_id = 'base'
    return msg


def _until(cond, limit=10.0):
    """Yield (let the executor run) until ``cond()``."""
    end = time.monotonic() + limit
    while not cond():
        assert time.monotonic() < end, 'timed out'
        yield False


@pytest.fixture
def contexts(monkeypatch):
    monkeypatch.setenv('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')
    domain = private_domain_id()
    inside, outside = rclpy.Context(), rclpy.Context()
    rclpy.init(context=inside, domain_id=domain)
    rclpy.init(context=outside, domain_id=domain)
    yield inside, outside
    rclpy.try_shutdown(context=inside)
    rclpy.try_shutdown(context=outside)


def _run(box, script, *others):
    """Spin ``box`` as its own process would (spin_node, events executor) while ``script``
    (a generator, advanced between executor slices) drives the publishers; then destroy
    ``box`` and the ``others`` nodes."""
    steps = iter(script)

    def stop():
        return next(steps, True) is True
    try:
        spin_node(box, 'events', stop=stop)
    finally:
        for node in (box, *others):
            node.destroy_node()


def test_component_message_arrives_once_in_process_and_outside_readers_still_get_it(contexts):
    """Each message reaches the listener once with the published content: through the
    middleware while a reader outside listens (which gets it too), handed over in process
    (never taken from the middleware, never deserialised) once it has gone."""
    inside, outside = contexts
    box = _Box(context=inside, start_parameter_services=False, enable_rosout=False)
    talker, listener = box.components
    peer = rclpy.create_node('outside_peer', context=outside, start_parameter_services=False,
                             enable_rosout=False)
    reader = peer.create_subscription(JointState, TOPIC, lambda m: None, QoSProfile(
        history=HistoryPolicy.KEEP_LAST, depth=100, reliability=ReliabilityPolicy.RELIABLE))
    sent = [_message(k) for k in range(40)]
    outside_got = []
    state = {}

    def script():
        delivery = box.delivery
        assert delivery is not None and delivery.topics == [TOPIC]
        yield from _until(lambda: talker.pub.get_subscription_count() == 2 and
                          reader.get_publisher_count() == 1)
        # A reader outside listens: the middleware carries the message to both.
        for k, msg in enumerate(sent[:20]):      # one at a time: within the QoS depth
            talker.pub.publish(msg)
            yield from _until(lambda: len(listener.received) == k + 1)
        state['with_reader'] = delivery.delivered

        def take_all():
            taken = reader.handle.take_message(JointState, False)
            while taken is not None:
                outside_got.append(taken[0])
                taken = reader.handle.take_message(JointState, False)
            return len(outside_got) >= 20
        yield from _until(take_all)
        # No reader outside: handed over in process, the middleware carries nothing.
        peer.destroy_subscription(reader)
        yield from _until(lambda: talker.pub.get_subscription_count() == 1)
        for k, msg in enumerate(sent[20:], 21):
            talker.pub.publish(msg)
            yield from _until(lambda: len(listener.received) == k)
        for _ in range(5):
            yield False
        state['without_reader'] = delivery.delivered
        yield True

    _run(box, script(), peer)
    assert [serialize_message(m) for m in listener.received] == \
        [serialize_message(m) for m in sent]
    assert all(got is not msg for got, msg in zip(listener.received, sent))
    assert state['with_reader'] == 0        # all 20 through the middleware
    assert state['without_reader'] == 20    # and the next 20 in process, none of them twice
    assert [serialize_message(m) for m in outside_got] == \
        [serialize_message(m) for m in sent[:20]]
    assert 'publish' not in vars(talker.pub)      # given back to the middleware on destroy


def test_without_in_process_delivery_the_reader_takes_the_middleware_copy(contexts):
    """The causal counterpart: ``in_process`` off, the same messages come through the
    middleware (the reader deserialises them), once each."""
    inside, _ = contexts
    box = _Box(context=inside, start_parameter_services=False, enable_rosout=False,
               parameter_overrides=[rclpy.parameter.Parameter('in_process', value=False)])
    talker, listener = box.components
    sent = [_message(k) for k in range(10)]

    def script():
        assert box.delivery is None
        for k, msg in enumerate(sent, 1):
            talker.pub.publish(msg)
            yield from _until(lambda: len(listener.received) == k)
        yield from _until(lambda: len(listener.received) == 10)
        yield True

    _run(box, script())
    assert [serialize_message(m) for m in listener.received] == \
        [serialize_message(m) for m in sent]


def test_a_publisher_outside_the_container_still_reaches_the_container_reader(contexts):
    """A publisher outside the container on a routed topic: its messages come through the
    middleware, the container's own in process; the listener gets each once."""
    inside, outside = contexts
    box = _Box(context=inside, start_parameter_services=False, enable_rosout=False)
    talker, listener = box.components
    peer = rclpy.create_node('outside_talker', context=outside, start_parameter_services=False,
                             enable_rosout=False)
    other = peer.create_publisher(JointState, TOPIC, STATE_QOS)
    state = {}

    def script():
        assert box.delivery.topics == [TOPIC]
        yield from _until(lambda: listener.sub.get_publisher_count() == 2 and
                          other.get_subscription_count() == 1)
        for j in range(5):
            other.publish(_message(200 + j))
            talker.pub.publish(_message(300 + j))
            yield from _until(lambda: len(listener.received) == 2 * (j + 1))
        for _ in range(5):
            yield False
        state['delivered'] = box.delivery.delivered
        yield True

    _run(box, script(), peer)
    assert sorted(m.header.stamp.sec for m in listener.received) == \
        [200, 201, 202, 203, 204, 300, 301, 302, 303, 304]
    assert state['delivered'] == 5      # the container's own; the outside ones came through
