"""Bag recorder node: subscribes to topics and writes a rosbag2 MCAP bag (``ros2 bag record``).

Messages are received serialised (no deserialisation cost) and stamped with the node's clock,
which is sim time by default, as rosbag2 does with ``use_sim_time``. Subscriptions adapt their
QoS to the publishers and the publishers' profiles are stored as ``offered_qos_profiles``, so a
player can republish latched topics as latched. Chunks are flushed every ``flush_period``
seconds of wall time: a recorder killed with SIGKILL loses at most that much.

No silent loss: every subscription keeps *all* samples (``KEEP_ALL``) rather than the last N,
so a burst (the sonar ring's 16 Range messages per sweep) or a recorder that falls behind for a
while never overflows its queue; samples wait in the reader until the executor takes them.
What this guarantees depends on what the publisher offers: a *reliable* publisher's messages
are all recorded once matched (DDS retransmits), in one process and across processes. A
*best-effort* publisher (sensor data) gets no retransmission: in one process nothing is lost
(the data never leaves the participant), across processes a sample dropped by the transport
(loopback socket or shared-memory segment full under load) is gone, as with ``ros2 bag
record``; the recorder logs each such loss the middleware reports (its *message lost* event)
with the topic and the running count (:attr:`BagRecorderNode.lost`). The middleware finds a
loss as a gap in a writer's sequence numbers, so a writer's very first sample, if dropped, goes
unreported (nothing before it to tell), as do samples dropped after its last one received.
Samples published before the recorder matched a publisher are not recorded, unless
the publisher is transient-local (latched); free-running simulators hold time at zero until
the recorder listens (``wait_for_clock_subscribers``/``wait_for_matched``).
"""
from typing import Any

from rclpy.clock import Clock, ClockType
from rclpy.event_handler import SubscriptionEventCallbacks
from rclpy.qos import HistoryPolicy, QoSProfile

from paramotion.bag.qos_yaml import adapted_subscription_qos
from paramotion.bag.writer import BagWriter
from paramotion.msgtypes import message_class
from paramotion.node import Param, ParamotionNode, run_node


class BagRecorderNode(ParamotionNode):
    """Record the selected topics (all if none are given) into ``output``."""

    PARAMS = (
        Param('output', 'bag', 'Bag directory to create; it must not exist yet.',
              read_only=True),
        Param('topics', [''], 'Topics to record; empty records every topic discovered.',
              read_only=True),
        Param('flush_period', 1.0, 'Wall-clock seconds between chunk flushes to disk.',
              min=0.01, max=10.0, read_only=True),
        Param('discovery_period', 0.5, 'Wall-clock seconds between topic discovery passes.',
              min=0.05, max=10.0, read_only=True),
    )

    def __init__(self, node_name: str = 'bag_recorder', **kwargs: Any) -> None:
        super().__init__(node_name, **kwargs)
        self.wanted = {t for t in self.params.topics if t}
        self.writer = BagWriter(self.params.output, flush_period=self.params.flush_period)
        self._subs = {}
        #: Samples the middleware reports lost per topic (best-effort transport drops).
        self.lost = {}
        steady = Clock(clock_type=ClockType.STEADY_TIME)
        self._flush_timer = self.create_timer(
            self.params.flush_period, self.writer.maybe_flush, clock=steady)
        self._discovery_timer = self.create_timer(
            self.params.discovery_period, self.discover, clock=steady)

    def discover(self) -> list[str]:
        """Subscribe to every wanted topic that has a publisher and is not recorded yet.

        ``/clock`` is subscribed last, once every other wanted topic is recorded and matched
        with its publishers: a simulator waiting for its ``/clock`` subscribers then starts
        time only when nothing will be missed.
        """
        found = self.get_topic_names_and_types()
        for topic, types in sorted(found, key=lambda item: item[0] == '/clock'):
            if topic == '/clock' and self.wanted and not self._others_matched():
                continue
            if topic in self._subs or (self.wanted and topic not in self.wanted):
                continue
            if not self.wanted and topic in ('/rosout', '/parameter_events'):
                continue
            infos = [i for i in self.get_publishers_info_by_topic(topic)
                     if i.node_name != self.get_name()]
            if not infos:
                continue
            self.subscribe(topic, types[0], [i.qos_profile for i in infos])
        return sorted(self._subs)

    def _others_matched(self):
        if set(self.missing_topics()) - {'/clock'}:
            return False
        return all(sub.get_publisher_count() > 0 for topic, sub in self._subs.items()
                   if topic != '/clock')

    def missing_topics(self) -> list[str]:
        """Wanted topics not subscribed yet (no publisher seen)."""
        return sorted(self.wanted - set(self._subs))

    def subscribe(self, topic: str, msgtype: str, offered: list[QoSProfile]) -> None:
        """Start recording ``topic`` of ``msgtype`` with the publishers' ``offered`` QoS."""
        self.writer.add_topic(topic, msgtype, offered)
        qos = adapted_subscription_qos(offered)
        qos.history = HistoryPolicy.KEEP_ALL   # never overwrite a sample not yet written
        self._subs[topic] = self.create_subscription(
            message_class(msgtype), topic, lambda data, t=topic: self._on_message(t, data),
            qos, raw=True, event_callbacks=SubscriptionEventCallbacks(
                message_lost=lambda info, t=topic: self._on_lost(t, info)))

    def _on_lost(self, topic, info):
        """Log samples of ``topic`` that the transport dropped before they reached us."""
        self.lost[topic] = info.total_count
        self.get_logger().warning(
            f'{topic}: {info.total_count_change} sample(s) lost in transport '
            f'({info.total_count} so far); they are not in the bag')

    def _on_message(self, topic, data):
        self.writer.write(topic, self.get_clock().now().nanoseconds, data)

    def destroy_node(self) -> None:
        """Stop recording and close the bag (its summary and ``metadata.yaml``)."""
        for sub in self._subs.values():
            self.destroy_subscription(sub)
        self._subs.clear()
        self.writer.close()
        for topic, count in sorted(self.lost.items()):
            self.get_logger().warning(f'{topic}: {count} sample(s) lost in transport in all')
        return super().destroy_node()


def main(args: list[str] | None = None) -> None:
    """Console script ``bag_recorder``."""
    run_node(BagRecorderNode, args)


if __name__ == '__main__':
    main()
