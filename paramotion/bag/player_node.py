"""Bag player node: replays a rosbag2 MCAP bag onto the graph on sim time (like ``ros2 bag play
--clock``).

The player owns ``/clock``: simulated time starts at the bag's first message and advances by
``publish_period``; after each advance the messages received up to that time are published, on
their recorded topics (or remapped ones) with the QoS they were recorded with. The recorded
``/clock`` itself is not republished, the player's own clock replaces it. In lock-step (one
process, :class:`paramotion.graph.Graph`) replay is exact and as fast as the machine allows;
free-running it follows ``real_time_factor``.
"""
from typing import Any

from paramotion.bag.qos_yaml import adapted_subscription_qos, profiles_from_yaml
from paramotion.bag.reader import bag_info, read_messages
from paramotion.clock import NS, ClockSourceNode
from paramotion.errors import UserError
from paramotion.msgtypes import message_class
from paramotion.node import Param, run_node


def parse_remaps(items: list[str]) -> dict[str, str]:
    """['/a:=/b', ...] -> {'/a': '/b'}; a malformed entry is a UserError naming it."""
    remaps = {}
    for item in items:
        if not item:
            continue
        src, sep, dst = item.partition(':=')
        if not sep or not src or not dst:
            raise UserError(f"remap {item!r}: expected 'from:=to'")
        remaps[src] = dst
    return remaps


class BagPlayerNode(ClockSourceNode):
    """Publish a bag's messages and ``/clock`` as simulated time advances."""

    PARAMS = ClockSourceNode.PARAMS + (
        Param('bag', '', 'Bag directory (or .mcap file) to play.', read_only=True),
        Param('topics', [''], 'Topics to play; empty plays every recorded topic.',
              read_only=True),
        Param('remap', [''], "Topic remappings 'from:=to' applied when publishing.",
              read_only=True),
    )

    def __init__(self, node_name: str = 'bag_player', **kwargs: Any) -> None:
        super().__init__(node_name, **kwargs)
        if not self.params.bag:
            raise UserError("parameter 'bag' is empty: give the bag directory to play")
        remaps = parse_remaps(self.params.remap)
        wanted = {t for t in self.params.topics if t} or None
        self.info = bag_info(self.params.bag)
        if self.info.problem:
            self.get_logger().warning(f'playing what could be recovered: {self.info.problem}')
        self.messages = [m for m in read_messages(self.params.bag, topics=wanted)
                         if m.topic != '/clock']
        self.publishers_by_topic = {}
        for topic, tinfo in self.info.topics.items():
            if topic == '/clock' or (wanted and topic not in wanted):
                continue
            profiles = profiles_from_yaml(tinfo.offered_qos_profiles)
            qos = profiles[0] if len(profiles) == 1 else adapted_subscription_qos(profiles, 10)
            self.publishers_by_topic[topic] = self.create_publisher(
                message_class(tinfo.msgtype), remaps.get(topic, topic), qos)
        self._next = 0
        period = self._period_ns
        first = self.messages[0].log_time_ns if self.messages else 0
        # Start one period before the first message so it is published at its own time.
        self.sim_time_ns = max(0, (first // period) * period - period)
        self.published = 0

    @property
    def finished(self) -> bool:
        """True once every message has been published."""
        return self._next >= len(self.messages)

    def publish_state(self) -> None:
        """Publish every message recorded up to the current sim time."""
        msgs = self.messages
        while self._next < len(msgs) and msgs[self._next].log_time_ns <= self.sim_time_ns:
            msg = msgs[self._next]
            self.publishers_by_topic[msg.topic].publish(msg.data)
            self._next += 1
            self.published += 1


def main(args: list[str] | None = None) -> None:
    """Console script ``bag_player``."""
    run_node(BagPlayerNode, args)


if __name__ == '__main__':
    main()


__all__ = ['BagPlayerNode', 'NS', 'parse_remaps']
