"""How paramotion's nodes are executed: the executors of a node process and of the lock-step
:class:`paramotion.graph.Graph`, and the in-process hand-over of messages among nodes that
share one.

:func:`spin_node` spins a node (or a component container with its nodes) in its own process
on the executor ``$PARAMOTION_EXECUTOR`` names; :class:`LockstepDrain` drains a
``SingleThreadedExecutor`` in that executor's own order without its per-callback machinery;
:class:`InProcessDelivery` hands a message published by one of a graph's nodes to its readers
in the same graph without serialising it (:func:`copy_message`). This module imports no other
paramotion module, so :mod:`paramotion.node` (every node process's ``run_node``) and
:mod:`paramotion.graph` both build on it.
"""
from __future__ import annotations

import os
from collections import defaultdict, deque
from collections.abc import Callable
from typing import Any

import rclpy
from rclpy.event_handler import EventHandler
from rclpy.executors import (
    Executor,
    ExternalShutdownException,
    ShutdownException,
    SingleThreadedExecutor,
    TimeoutException,
)
from rclpy.experimental.events_executor import EventsExecutor
from rclpy.impl.implementation_singleton import rclpy_implementation as _rclpy
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, HistoryPolicy
from rclpy.serialization import deserialize_message
from rclpy.subscription import Subscription

#: How a Graph drains its callbacks: ``lockstep`` (a ``SingleThreadedExecutor`` whose ready
#: callbacks the Graph runs itself, in that executor's order, see :class:`LockstepDrain`),
#: ``single_threaded`` (the same executor's own ``wait_for_ready_callbacks``) or ``events``
#: (rclpy's ``EventsExecutor``).
EXECUTORS = ('lockstep', 'single_threaded', 'events')

def make_executor(kind: str, context: rclpy.Context) -> Executor:
    """A new rclpy executor for ``kind`` (one of :data:`EXECUTORS`) on ``context``."""
    if kind == 'events':
        return EventsExecutor(context=context)
    if kind in ('single_threaded', 'lockstep'):
        return SingleThreadedExecutor(context=context)
    raise ValueError(f'executor {kind!r}: expected one of {", ".join(EXECUTORS)}')


#: Environment variable choosing the executor of a node run as its own process
#: (:func:`spin_node`): ``events`` or ``single_threaded``.
NODE_EXECUTOR_ENV = 'PARAMOTION_EXECUTOR'
NODE_EXECUTORS = ('events', 'single_threaded', 'waitset')
DEFAULT_NODE_EXECUTOR = 'single_threaded'


def node_executor_kind() -> str:
    """The executor :func:`spin_node` uses: ``$PARAMOTION_EXECUTOR`` or the default."""
    kind = os.environ.get(NODE_EXECUTOR_ENV, '').strip() or DEFAULT_NODE_EXECUTOR
    if kind not in NODE_EXECUTORS:
        raise ValueError(f'{NODE_EXECUTOR_ENV}={kind!r}: expected one of '
                         f'{", ".join(NODE_EXECUTORS)}')
    return kind


def spin_node(node: Node, kind: str | None = None,
              stop: Callable[[], bool] | None = None) -> None:
    """Spin ``node`` (its own process) until its context shuts down.

    A component container (:class:`paramotion.container.ComponentContainer`) is spun together
    with its ``components`` on the same executor. ``single_threaded`` (default) is
    ``rclpy.spin(node)`` (a ``SingleThreadedExecutor`` over all the nodes for a container).
    ``events`` runs them on rclpy's ``EventsExecutor`` (less CPU per message; a callback's
    exception is also logged by it at FATAL level before ``run_node`` sees it); its
    ``spin()`` waits in C++ without returning to Python, so a signal's Python handler would
    never run: it is spun in ``spin_once`` slices of 0.1 s instead, which run every event as
    it arrives and end once ``stop()`` is true (a signal arrived: see
    :func:`paramotion.node.run_node`) or the context is shut down.
    """
    kind = kind or node_executor_kind()
    nodes = [node, *getattr(node, 'components', ())]
    if hasattr(node, 'start_clock'):
        node.start_clock()    # a container sets its nodes' sim time and fires their timers
    if kind == 'single_threaded' and len(nodes) == 1:
        rclpy.spin(node)
        return
    executor = make_executor('single_threaded' if kind == 'waitset' else kind, node.context)
    for each in nodes:
        executor.add_node(each)
    if hasattr(node, 'start_delivery'):
        node.start_delivery(executor, kind)   # a container's messages among its own nodes
    try:
        if kind == 'waitset':
            LockstepDrain(executor, node.context).spin(stop)
            return
        if kind == 'single_threaded':
            while node.context.ok():
                executor.spin_once()
            return
        while node.context.ok() and not (stop is not None and stop()):
            # One callback (or 0.1 s) per call, not a longer run: rclpy 7.1.6's event queue
            # runs past a deadline for as long as events keep arriving, so a busy node spun
            # that way would never come back to check stop().
            executor.spin_once(timeout_sec=0.1)
    finally:
        # Release the nodes here, while the context still exists, rather than whenever the
        # executor is collected (the C++ events executor then still holds their handles).
        executor.shutdown(timeout_sec=1.0)


class LockstepDrain:
    """Drain a ``SingleThreadedExecutor`` in its own order, without its per-callback machinery.

    ``SingleThreadedExecutor.wait_for_ready_callbacks`` rebuilds its wait set from every entity
    on every call and wraps each callback in a ``Task`` coroutine; in a lock-step graph that
    machinery cost more than the callbacks. One round here is one of its zero-timeout waits
    done once: the same entities in the same order (the executor's nodes as it lists them;
    waitables, then per node its timers, subscriptions, guard conditions, clients and
    services), the same ready test, and each message taken just before its callback runs, so
    the callbacks run in the same order with the same messages. Timers and subscriptions (the
    hot path) are called directly; the rare waitables, clients and services go through the
    executor's own handlers. The wait set is reused while the entities stay the same.

    The middleware's QoS event handlers (rclpy gives every publisher and subscription two,
    which only log an incompatible QoS or type; in the climber graph they are 64 of its 85
    entities) are polled in the first round of each drain only: such an event is logged at
    most one period later, and no callback of the graph depends on them.
    """

    def __init__(self, executor: Executor, context: rclpy.Context,
                 qos_events_first_round_only: bool = True,
                 in_process_delivery: bool = False) -> None:
        self.executor = executor
        self.context = context
        self.qos_events_first_round_only = qos_events_first_round_only
        self._wait_sets = {}
        self.delivery = InProcessDelivery() if in_process_delivery else None
        self._entities_key = {}      # with / without QoS event handlers -> entity key
        self._entities_value = {}

    def close(self) -> None:
        """Give the publishers back their middleware ``publish``."""
        if self.delivery is not None:
            self.delivery.close()

    def drain(self, check_runaway: Callable[[int], None]) -> int:
        """Run rounds until one finds nothing ready; returns how many callbacks ran."""
        count = 0
        first = True
        while True:
            ran = self._round(qos_events=first or not self.qos_events_first_round_only)
            first = False
            count += ran
            if ran == 0:
                return count
            check_runaway(count)

    def _fallback_needed(self, nodes: list[Node]) -> bool:
        ex = self.executor
        with ex._tasks_lock:
            pending = any(not t.done() for t, _, _ in ex._tasks)
        return pending or any(_live_lists(node)[6] for node in nodes)

    def _entities(self, nodes: list[Node], qos_events: bool) -> tuple[list, list]:
        """``(per_node, waited)``: per node its timers, subscriptions, clients, services and
        waitables (QoS event handlers only with ``qos_events``), and the same without the
        subscriptions fed in process (what the wait set holds). Rebuilt only when the nodes'
        entities or the in-process routing changed (read from rclpy's entity lists, not
        through its generator properties, a large part of a round's cost otherwise)."""
        lists = [_live_lists(node) for node in nodes]
        key = (tuple(id(node) for node in nodes),
               tuple(id(e) for group in lists for lst in group[:6] for e in lst))
        delivery = self.delivery
        if delivery is not None:
            delivery.route(nodes, key)
            key = key + (id(delivery.fed),)
        if key != self._entities_key.get(qos_events):
            per_node = [(node, list(timers), list(subs), list(clients), list(services),
                         [w for w in waitables
                          if qos_events or not isinstance(w, EventHandler)])
                        for node, (timers, subs, clients, services, waitables, *_)
                        in zip(nodes, lists)]
            waited = per_node if delivery is None else [
                (node, timers, [s for s in subs if id(s) not in delivery.fed], *rest)
                for node, timers, subs, *rest in per_node]
            self._entities_key[qos_events] = key
            self._entities_value[qos_events] = (per_node, waited)
        return self._entities_value[qos_events]

    def _round(self, qos_events: bool = True, timeout_ns: int = 0) -> int:
        """One wait (``timeout_ns``: 0 polls, > 0 blocks until something is ready or the time
        is up) and the callbacks it found ready; returns how many ran."""
        ex = self.executor
        nodes = ex.get_nodes()
        if ex._is_shutdown or not self.context.ok():
            return 0
        if self._fallback_needed(nodes):
            return self._rclpy_round()
        per_node, waited = self._entities(nodes, qos_events)
        delivery = self.delivery
        queues, held = {}, ()
        if delivery is not None:
            # Subscriptions fed in process are not in the wait set; like the wait, the
            # snapshot of their queues says which of them have a message this round.
            queues = delivery.queues
            held = delivery.snapshot()
        only_timers = timeout_ns == 0 and not any(
            group for _, _, *groups in waited for group in groups)
        ws = None if only_timers else self._fill_wait_set(waited)
        if only_timers:
            # Nothing but timers to wait for: their ready test is the one the wait applies
            # (rcl_timer_is_ready), so it is made here directly. A zero-timeout wait still
            # locks the middleware's wait set and, on a loaded machine, often gave the CPU
            # away for a millisecond or two, three times per lock-step period.
            subs_ready = clients_ready = services_ready = set()
            timers_ready = {tmr.handle.pointer for _, timers, *_ in waited for tmr in timers
                            if tmr.handle.is_timer_ready()}
        elif ws is not None:
            ws.wait(timeout_ns)
            subs_ready = set(ws.get_ready_entities('subscription'))
            timers_ready = set(ws.get_ready_entities('timer'))
            clients_ready = set(ws.get_ready_entities('client'))
            services_ready = set(ws.get_ready_entities('service'))
        else:
            subs_ready = timers_ready = clients_ready = services_ready = set()
        ran = 0
        ready_waitables = [(wt, node) for node, *_, waitables in per_node
                           for wt in waitables if ws is not None and wt.is_ready(ws)]
        for wt, node in ready_waitables:
            ran += self._run_handler(wt, node, ex._take_waitable)
        for node, timers, subs, clients, services, _ in per_node:
            for tmr in timers:
                if tmr.handle.pointer in timers_ready and tmr.handle.is_timer_ready():
                    tmr.handle.call_timer()
                    tmr.callback()
                    ran += 1
            for sub in subs:
                if id(sub) in held:
                    sub.callback(queues[id(sub)].popleft())
                    ran += 1
                elif sub.handle.pointer in subs_ready:
                    msg_info = sub.handle.take_message(sub.msg_type, sub.raw)
                    if msg_info is not None:
                        if sub._callback_type is Subscription.CallbackType.MessageOnly:
                            sub.callback(msg_info[0])
                        else:
                            sub.callback(*msg_info)
                    ran += 1
            for client in clients:
                if client.handle.pointer in clients_ready:
                    ran += self._run_handler(client, node, ex._take_client)
            for srv in services:
                if srv.handle.pointer in services_ready:
                    ran += self._run_handler(srv, node, ex._take_service)
        return ran

    def spin(self, stop: Callable[[], bool] | None = None, slice_s: float = 0.1,
             qos_every: int = 10) -> None:
        """Free-running: wait for ready callbacks (at most ``slice_s`` s per wait) and run them
        in the executor's order until ``stop()`` is true or the context shuts down; the QoS
        event handlers are polled every ``qos_every`` waits."""
        timeout_ns = int(slice_s * 1e9)
        waits = 0
        while self.context.ok() and not (stop is not None and stop()):
            self._round(qos_events=waits % qos_every == 0, timeout_ns=timeout_ns)
            waits += 1

    def _fill_wait_set(self, per_node: list[tuple]) -> Any:
        """The reused wait set of these entities, filled; None when there are none."""
        key = tuple(id(e) for entry in per_node for group in entry[1:] for e in group)
        if not key:
            return None
        ws = self._wait_sets.get(key)
        if ws is None:
            counts = [0, 0, 0, 0, 0, 0]   # subs, guards, timers, clients, services, events
            for _, timers, subs, clients, services, waitables in per_node:
                counts[0] += len(subs)
                counts[2] += len(timers)
                counts[3] += len(clients)
                counts[4] += len(services)
                for wt in waitables:
                    n = wt.get_num_entities()
                    counts[0] += n.num_subscriptions
                    counts[1] += n.num_guard_conditions
                    counts[2] += n.num_timers
                    counts[3] += n.num_clients
                    counts[4] += n.num_services
                    counts[5] += n.num_events
            if len(self._wait_sets) > 8:     # entities changed: forget the old sets
                self._wait_sets.clear()
            ws = self._wait_sets[key] = _rclpy.WaitSet(*counts, self.context.handle)
        ws.clear_entities()
        for _, timers, subs, clients, services, waitables in per_node:
            for sub in subs:
                ws.add_subscription(sub.handle)
            for client in clients:
                ws.add_client(client.handle)
            for srv in services:
                ws.add_service(srv.handle)
            for tmr in timers:
                ws.add_timer(tmr.handle)
            for wt in waitables:
                wt.add_to_wait_set(ws)
        return ws

    def _run_handler(self, entity: Any, node: Node, take: Callable[..., Any]) -> int:
        """Run one callback through the executor's own handler (as its spin would)."""
        ex = self.executor
        handler = ex._make_handler(entity, node, take)
        handler()
        with ex._tasks_lock:
            ex._tasks = [t for t in ex._tasks if not t[0].done()]
        if handler.exception() is not None:
            raise handler.exception()
        return 1

    def _rclpy_round(self) -> int:
        """One round of the executor's own wait (pending coroutine tasks or guard conditions,
        which the direct round does not handle)."""
        return rclpy_wait_round(self.executor)


class InProcessDelivery:
    """Messages between the nodes of one lock-step graph, handed over in process.

    A component container with intra-process communication does this in rclcpp; rclpy has
    none, so every message a graph's node published for another went through the middleware:
    serialised, written, taken, and converted back into Python objects field by field (in the
    FAST graph more CPU than the simulator's state computation). Here the publishers of a
    topic whose every reader is a subscription of this graph's nodes put a copy of each message
    (:func:`copy_message`: the same values and Python types the middleware would deliver, a
    float32 field rounded as it would be) straight into each reader's queue. Queues keep the
    reader's QoS depth (``KEEP_LAST``: the oldest is dropped, as the middleware's history
    does). :class:`LockstepDrain` takes a snapshot of the queues where it waits and runs each
    reader that had a message in its place in the executor's order, oldest message first, as
    it would after the wait: the callbacks run in the same order with the same messages.

    Only the lock-step drain reads the queues: :meth:`Graph.spin_wall` gives the publishers
    back to the middleware before rclpy's executor spins.

    A topic stays on the middleware when one of its readers is raw (a bag recorder), wants
    the message info, or lies outside the graph (the middleware counts more matched readers
    than the graph has: another process, a node not added to the graph); when its publishers
    are transient-local (late joiners get the history from the middleware); or when a reader
    has a publisher outside the graph. A publisher re-checks the count of matched readers on
    every message and goes back to the middleware when it changes.
    """

    def __init__(self) -> None:
        self.queues = {}     # id(subscription) -> deque of messages not yet taken
        self.fed = set()     # id(subscription) of the readers fed in process
        self._hooked = {}    # id(publisher) -> publisher whose publish is replaced
        self._key = None

    def snapshot(self) -> set[int]:
        """The readers with a message waiting (as the wait would find them ready)."""
        return {key for key, queue in self.queues.items() if queue}

    def route(self, nodes: list[Node], key: Any) -> None:
        """Decide each topic's path again when ``key`` (the graph's entities, publishers and
        readers among them) changed, or a publisher asked for it."""
        if key != self._key:
            self._route(nodes)
            self._key = key

    def _route(self, nodes: list[Node]) -> None:
        topics = defaultdict(lambda: ([], []))
        for node in nodes:
            for pub in node.publishers:
                topics[pub.topic_name][0].append(pub)
            for sub in node.subscriptions:
                topics[sub.topic_name][1].append(sub)
        fed, hooked = set(), {}
        for pubs, subs in topics.values():
            if not pubs or not _in_process_topic(pubs, subs):
                continue
            targets = [(self._queue(sub), _depth(sub)) for sub in subs]
            for pub in pubs:
                pub.publish = self._publisher(pub, targets, len(subs))
                hooked[id(pub)] = pub
            fed.update(id(sub) for sub in subs)
        for key, pub in self._hooked.items():
            if key not in hooked:
                pub.__dict__.pop('publish', None)
        self._hooked = hooked
        self.fed = fed

    def _queue(self, sub: Subscription) -> deque:
        """The reader's queue; messages the middleware holds for it (published before the
        topic went in process, or by a publisher that fell back to it) move there first."""
        queue = self.queues.setdefault(id(sub), deque())
        depth = _depth(sub)
        while True:
            taken = sub.handle.take_message(sub.msg_type, False)
            if taken is None:
                break
            _put(queue, taken[0], depth)
        return queue

    def _publisher(self, pub: Any, targets: list, readers: int) -> Callable[[Any], None]:
        msg_type = pub.msg_type
        middleware = type(pub).publish.__get__(pub)

        def publish(msg: Any) -> None:
            if type(msg) is not msg_type and not isinstance(msg, msg_type):
                if not isinstance(msg, bytes):
                    middleware(msg)      # the middleware's TypeError
                    return
                msg = deserialize_message(msg, msg_type)
            if pub.get_subscription_count() != readers:    # a reader came or went
                self._key = None
                pub.__dict__.pop('publish', None)
                middleware(msg)
                return
            for queue, depth in targets:
                _put(queue, copy_message(msg), depth)
        return publish

    def close(self) -> None:
        """Give every publisher back its middleware ``publish``."""
        for pub in self._hooked.values():
            pub.__dict__.pop('publish', None)
        self._hooked = {}
        self.fed = set()
        self._key = None


def _live_lists(node: Node) -> tuple:
    """rclpy's own lists of a node's timers, subscriptions, clients, services, waitables,
    publishers and guard conditions (its properties are generators over them); copies where
    this rclpy keeps them elsewhere."""
    try:
        return (node._timers, node._subscriptions, node._clients, node._services,
                node._Node__waitables, node._publishers, node._guards)
    except AttributeError:
        return (list(node.timers), list(node.subscriptions), list(node.clients),
                list(node.services), list(node.waitables), list(node.publishers),
                list(node.guards))


def _in_process_topic(pubs: list, subs: list) -> bool:
    """True when the graph's nodes are the only publishers and readers of the topic and no
    reader needs what only the middleware gives (raw bytes, message info, history for a late
    joiner)."""
    msg_type = pubs[0].msg_type
    for pub in pubs:
        if pub.msg_type is not msg_type or \
                pub.qos_profile.durability == DurabilityPolicy.TRANSIENT_LOCAL or \
                pub.get_subscription_count() != len(subs):
            return False
    return all(plain_reader(sub, msg_type) and sub.get_publisher_count() == len(pubs)
               for sub in subs)


def plain_reader(sub: Subscription, msg_type: type) -> bool:
    """True when ``sub`` reads ``msg_type`` messages as objects, without the message info, and
    keeps a history: what an in-process hand-over gives it."""
    return not sub.raw and sub.msg_type is msg_type and \
        sub._callback_type is Subscription.CallbackType.MessageOnly and \
        sub.qos_profile.history in (HistoryPolicy.KEEP_LAST, HistoryPolicy.KEEP_ALL)


def _depth(sub: Subscription) -> int:
    """The reader's queue length (0: unbounded, ``KEEP_ALL``)."""
    qos = sub.qos_profile
    return max(1, qos.depth) if qos.history == HistoryPolicy.KEEP_LAST else 0


def _put(queue: Any, msg: Any, depth: int) -> None:
    queue.append(msg)
    if depth and len(queue) > depth:
        queue.popleft()


_COPIERS: dict[type, Callable[[Any], Any]] = {}


def copy_message(msg: Any) -> Any:
    """A copy of a ROS message with what a subscriber of the middleware receives: every
    nested message new, sequences new (``array.array`` for numbers, lists otherwise), numpy
    arrays copied, scalars as Python ``float``/``int``/``bool``/``str`` (a ``float32`` field
    rounded to single precision). Built once per message type, without the field setters."""
    cls = type(msg)
    copier = _COPIERS.get(cls)
    if copier is None:
        copier = _COPIERS[cls] = _make_copier(cls)
    return copier(msg)


def _make_copier(cls: type) -> Callable[[Any], Any]:
    import array
    import struct

    import numpy as np
    from rosidl_parser.definition import (
        AbstractNestedType,
        AbstractString,
        AbstractWString,
        BasicType,
        NamespacedType,
    )
    ints = {'int8', 'uint8', 'int16', 'uint16', 'int32', 'uint32', 'int64', 'uint64'}
    f32 = struct.Struct('f')

    def scalar(t):
        if isinstance(t, (AbstractString, AbstractWString)):
            return str
        name = t.typename
        if name in ('double', 'long double'):
            return float
        if name == 'float':
            return lambda v: f32.unpack(f32.pack(v))[0]
        if name in ints:
            return int
        if name == 'boolean':
            return bool
        return None     # octet, char: as stored

    def sequence(t):
        inner = t.value_type
        if isinstance(inner, NamespacedType):
            return lambda v: [copy_message(m) for m in v]
        convert = scalar(inner) if isinstance(inner, (BasicType, AbstractString,
                                                      AbstractWString)) else None

        def copy(v):
            if isinstance(v, array.array):
                return array.array(v.typecode, v)
            if isinstance(v, np.ndarray):
                return v.copy()
            return [convert(x) for x in v] if convert is not None else list(v)
        return copy

    plan = []
    for name, t in zip(cls.get_fields_and_field_types(), cls.SLOT_TYPES):
        if isinstance(t, NamespacedType):
            plan.append(('_' + name, copy_message))
        elif isinstance(t, AbstractNestedType):
            plan.append(('_' + name, sequence(t)))
        else:
            plan.append(('_' + name, scalar(t)))
    # One straight-line function per type (no loop over the fields, no setattr by name); a
    # float or int field that already holds that type is taken as it is.
    names = {'new': cls.__new__, 'cls': cls}
    lines = ['def copier(msg):', '    out = new(cls)']
    for k, (slot, convert) in enumerate(plan):
        if convert is None:
            lines.append(f'    out.{slot} = msg.{slot}')
        elif convert in (float, int, str, bool):
            lines += [f'    v = msg.{slot}',
                      f'    out.{slot} = v if type(v) is {convert.__name__} '
                      f'else {convert.__name__}(v)']
        else:
            names[f'convert{k}'] = convert
            lines.append(f'    out.{slot} = convert{k}(msg.{slot})')
    if '_check_fields' in cls.__slots__:
        lines.append('    out._check_fields = msg._check_fields')
    lines.append('    return out')
    exec('\n'.join(lines), names)     # noqa: S102 (generated from the type's own fields)
    return names['copier']


def rclpy_wait_round(executor: Executor) -> int:
    """Run the callbacks of one zero-timeout ``wait_for_ready_callbacks`` round; returns how
    many ran (0 also after a shutdown).

    One zero-timeout wait yields at most one callback per entity (one message per
    subscription) and then reports a timeout *even if it yielded work*, so a single timeout
    does not mean the executor is idle: only a round that yields nothing does.
    """
    ran = 0
    try:
        while True:
            handler, _, _ = executor.wait_for_ready_callbacks(timeout_sec=0.0)
            handler()
            if handler.exception() is not None:
                raise handler.exception()
            ran += 1
    except (ShutdownException, ExternalShutdownException, TimeoutException):
        pass
    return ran
