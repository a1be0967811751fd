"""Messages among a component container's own nodes, handed over in process.

rclcpp's component container with intra-process communication hands a message published by
one of its nodes to its other nodes' subscriptions as an object; the middleware carries it
only to readers elsewhere. rclpy has no such path: a container's node publishes for its
neighbour through the middleware, which serialises the message and, on the reader's side,
converts it back into Python objects field by field (a ``PoseStamped`` from one component to
another: about 72 us of CPU through the middleware, 18 us in process, measured by
``cable_robot_pkg.fast.bench.delivery_cost``). :class:`ContainerDelivery` is that path for a
container spun on rclpy's ``EventsExecutor`` in its own process
(:func:`paramotion.executors.spin_node`); the lock-step :class:`paramotion.graph.Graph` has its
own (:class:`paramotion.executors.InProcessDelivery`), whose message copy
(:func:`paramotion.executors.copy_message`: the values and Python types the middleware delivers)
this one uses.

For a topic that the container's nodes publish and read (every container reader of it takes
messages as objects, without the message info, keeping a history; no transient-local
publisher), each message takes one of two paths, chosen by its publisher as it publishes:

- **in process**, while the middleware would carry it to the container's own readers only
  (``get_subscription_count`` counts no reader outside: no recorder, no other process on the
  topic): a copy goes into each reader's queue (kept at the reader's QoS depth, the oldest
  dropped as ``KEEP_LAST`` history drops it) and a task on the executor runs the reader's
  callback with the oldest message. The callback runs from the executor's queue after the
  publishing callback returns, where the middleware's new-message event would have queued it
  (the middleware's in-process delivery queues that event inside ``publish``). The message is
  never serialised.
- **through the middleware**, while a reader outside the container listens (the simulator, a
  recorder, ``ros2 topic echo``): published as usual, and the container's readers take it
  from the middleware as before.

Either way each reader gets each message once: the middleware never brings a container
reader a copy of a message that it also got in process. The readers are left as they are:
their middleware subscriptions (``ros2 topic info`` lists them, QoS is matched as before)
take what the middleware brings them (the second path, and any publisher outside the
container). This is the lock-step Graph's rule (a topic in process while every reader is
in the graph) decided message by message; rclcpp's intra-process communication also hands
the message over in process when outside readers listen, and then drops the middleware's
copy by the publisher's GID, which rclpy does not expose.

A topic stays on the middleware when a container reader of it is raw or wants the message
info, or its publishers are transient-local. Entities created after the start go over the
middleware (a new container reader counts as an outside reader).
"""
from __future__ import annotations

from collections import defaultdict, deque
from collections.abc import Callable, Sequence
from typing import Any

from rclpy.node import Node
from rclpy.qos import DurabilityPolicy
from rclpy.serialization import deserialize_message

from paramotion.executors import _depth, _put, copy_message, plain_reader


class ContainerDelivery:
    """In-process delivery among ``nodes`` (a container and its components), spun by
    ``executor`` (rclpy's ``EventsExecutor``, whose ``create_task`` queues a callable behind the
    events already queued). ``delivered`` counts the messages handed over in process;
    ``topics`` lists the routed topics."""

    def __init__(self, executor: Any, nodes: Sequence[Node]) -> None:
        self.executor = executor
        self.nodes = list(nodes)
        self.delivered = 0
        self._routes = {}        # topic -> publishers
        self.route()

    @property
    def topics(self) -> list[str]:
        """The topics routed here, sorted."""
        return sorted(self._routes)

    def route(self) -> None:
        """Route every topic that qualifies (module docstring)."""
        topics = defaultdict(lambda: ([], []))
        for node in self.nodes:
            for pub in node.publishers:
                topics[pub.topic_name][0].append(pub)
            for sub in node.subscriptions:
                topics[sub.topic_name][1].append(sub)
        for topic, (pubs, subs) in topics.items():
            if topic in self._routes or not pubs or not subs:
                continue
            msg_type = pubs[0].msg_type
            if any(p.msg_type is not msg_type or
                   p.qos_profile.durability == DurabilityPolicy.TRANSIENT_LOCAL
                   for p in pubs) or not all(plain_reader(s, msg_type) for s in subs):
                continue
            readers = [(deque(), _depth(sub), sub.callback) for sub in subs]
            for pub in pubs:
                pub.publish = self._publisher(pub, readers)
            self._routes[topic] = pubs

    def _publisher(self, pub: Any, readers: list) -> Callable[[Any], None]:
        msg_type = pub.msg_type
        middleware = type(pub).publish.__get__(pub)
        count = pub.handle.get_subscription_count
        inside = len(readers)
        create_task = self.executor.create_task
        run = self._run

        def publish(msg: Any) -> None:
            if count() > inside:         # a reader outside the container listens
                middleware(msg)
                return
            if type(msg) is not msg_type and not isinstance(msg, msg_type):
                if not isinstance(msg, bytes):
                    middleware(msg)      # the middleware's TypeError
                    return
                msg = deserialize_message(msg, msg_type)
            for queue, depth, callback in readers:
                _put(queue, copy_message(msg), depth)
                create_task(run, queue, callback)
        return publish

    def _run(self, queue: deque, callback: Callable[[Any], Any]) -> None:
        # A queue that dropped its oldest message has more tasks than messages.
        if queue:
            self.delivered += 1
            callback(queue.popleft())

    def close(self) -> None:
        """Give every topic back to the middleware (messages already queued still run)."""
        for pubs in self._routes.values():
            for pub in pubs:
                pub.__dict__.pop('publish', None)
        self._routes = {}


__all__ = ['ContainerDelivery']
