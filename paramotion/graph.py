"""Compose nodes in one process on one executor and run them lock-step on simulated time.

:class:`Graph` is paramotion's component container: it owns a private ``rclpy.Context`` (so
tests and scenarios never share state), one ``SingleThreadedExecutor`` and the nodes added to
it. :meth:`Graph.run_lockstep` alternates "advance the simulator one period" (which publishes
``/clock`` and the simulated state) with "drain the executor" (run every callback made ready by
the new time and by the messages published in response, until nothing is left). Because
nothing waits on the wall clock, a scenario runs as fast as the machine allows and produces the
same results on a fast or a slow machine.
"""
from __future__ import annotations

import os
import random
import time
from collections.abc import Callable, Iterable, Iterator, Mapping
from contextlib import contextmanager
from typing import TYPE_CHECKING, Any, Literal, TypeVar

import rclpy
from rclpy.executors import ExternalShutdownException, ShutdownException
from rclpy.node import Node

from paramotion.clock import ClockSourceNode, take_time_source
from paramotion.executors import EXECUTORS, LockstepDrain, make_executor, rclpy_wait_round
from paramotion.node import overrides_from_dict

if TYPE_CHECKING:
    from rosgraph_msgs.msg import Clock as ClockMsg

    from paramotion.bag.recorder_node import BagRecorderNode

NodeT = TypeVar('NodeT', bound=Node)

#: A Graph's executor unless told otherwise (one of :data:`paramotion.executors.EXECUTORS`).
DEFAULT_EXECUTOR = 'lockstep'

#: What a Graph does unless told otherwise (``paramotion bench --levers`` switches them one at
#: a time to measure each): the executor, whether the clock source sets the nodes' time
#: directly in lock-step, whether a private graph's nodes skip their parameter services,
#: whether the lock-step drain polls QoS event handlers only in a drain's first round, and
#: whether it hands messages between the graph's own nodes itself
#: (:class:`paramotion.executors.InProcessDelivery`).
GRAPH_DEFAULTS = {'executor': DEFAULT_EXECUTOR, 'direct_time': True,
                  'private_without_services': True, 'qos_events_first_round_only': True,
                  'in_process_delivery': True}


@contextmanager
def graph_defaults(**values: Any) -> Iterator[None]:
    """Temporarily change :data:`GRAPH_DEFAULTS` (for benchmarks comparing them)."""
    unknown = set(values) - set(GRAPH_DEFAULTS)
    if unknown:
        raise ValueError(f'unknown Graph defaults {sorted(unknown)}')
    saved = dict(GRAPH_DEFAULTS)
    GRAPH_DEFAULTS.update(values)
    try:
        yield
    finally:
        GRAPH_DEFAULTS.clear()
        GRAPH_DEFAULTS.update(saved)


def private_domain_id() -> int:
    """DDS domain for a one-process run: ``ROS_DOMAIN_ID`` if the user set it (to watch the run
    live), else a random one in 102..200."""
    env = os.environ.get('ROS_DOMAIN_ID', '').strip()
    if env.isdigit():
        return int(env)
    return random.SystemRandom().randint(102, 200)


def _init_context(context: rclpy.Context, domain_id: int, private: bool) -> None:
    """``rclpy.init`` of ``context``; ``private`` turns DDS discovery off for it.

    All nodes of a Graph share one context (one DDS participant), so they still talk to each
    other with discovery off, but no other process can join: a free-running simulator's
    ``/clock`` elsewhere on the machine can never leak into this run's simulated time. The
    environment variable is read when the participant is created and restored right after.
    """
    key = 'ROS_AUTOMATIC_DISCOVERY_RANGE'
    old = os.environ.get(key)
    if private:
        os.environ[key] = 'OFF'
    try:
        rclpy.init(context=context, domain_id=domain_id)
    finally:
        if private:
            if old is None:
                os.environ.pop(key, None)
            else:
                os.environ[key] = old


class Graph:
    """A set of nodes sharing one context and one executor. Use as a context manager.

    By default (``domain_id`` None and no ``ROS_DOMAIN_ID`` set) the graph is private: a random
    domain with discovery off, heard by nobody else. Set ``ROS_DOMAIN_ID`` (or pass
    ``domain_id``) to watch a run live from other processes. ``executor`` is one of
    :data:`EXECUTORS` (default from :data:`GRAPH_DEFAULTS`).
    """

    def __init__(self, domain_id: int | None = None, max_callbacks_per_drain: int = 200_000,
                 executor: str | None = None) -> None:
        kind = executor or GRAPH_DEFAULTS['executor']
        if kind not in EXECUTORS:
            raise ValueError(f'executor {kind!r}: expected one of {", ".join(EXECUTORS)}')
        private = domain_id is None and not os.environ.get('ROS_DOMAIN_ID', '').strip()
        if domain_id is None:
            domain_id = private_domain_id()
        self.domain_id = domain_id
        self.private = private
        self.context = rclpy.Context()
        _init_context(self.context, domain_id, private)
        self.executor_kind = kind
        self.executor = make_executor(kind, self.context)
        self._lockstep = LockstepDrain(self.executor, self.context,
                                       GRAPH_DEFAULTS['qos_events_first_round_only'],
                                       GRAPH_DEFAULTS['in_process_delivery'])
        self.nodes = []
        self.max_callbacks_per_drain = max_callbacks_per_drain
        self.callbacks_run = 0
        self._direct_time = []      # time sources whose node's clock the Graph sets itself
        self._direct_source = None
        self.direct_time = GRAPH_DEFAULTS['direct_time']
        self.node_services = not (private and GRAPH_DEFAULTS['private_without_services'])

    def add(self, node_cls: Callable[..., NodeT], *, name: str | None = None,
            namespace: str | None = None, remappings: Mapping[str, str] | None = None,
            **params: Any) -> NodeT:
        """Create ``node_cls`` in this graph with parameter overrides ``params``.

        ``name`` renames the node, ``namespace`` pushes it into a namespace, ``remappings``
        maps topic names ``{"from": "to"}`` as ``--ros-args -r`` would. Clock sources (simulators,
        players) are put in lock-step mode unless ``lockstep`` is given explicitly. In a private
        graph the nodes start without parameter services (``node.set_parameters`` still works).
        """
        if isinstance(node_cls, type) and issubclass(node_cls, ClockSourceNode):
            params.setdefault('lockstep', True)
        kwargs = {'context': self.context}
        if not self.node_services:
            # Nobody can reach a private graph's services (discovery is off), so its nodes do
            # not offer the parameter and type-description services: 7 services per node that
            # every executor wait would otherwise poll.
            kwargs['start_parameter_services'] = False
            params.setdefault('start_type_description_service', False)
        kwargs['parameter_overrides'] = overrides_from_dict(params)
        cli = []
        if name:
            cli += ['-r', f'__node:={name}']
        for src, dst in (remappings or {}).items():
            cli += ['-r', f'{src}:={dst}']
        if cli:
            kwargs['cli_args'] = ['--ros-args'] + cli
        if namespace:
            kwargs['namespace'] = namespace
        node = node_cls(**kwargs)
        # A component container's nodes join this graph's executor after it, in its order.
        for each in (node, *getattr(node, 'components', ())):
            self.nodes.append(each)
            self.executor.add_node(each)
        return node

    def record(self, bag_dir: str | os.PathLike[str], topics: Iterable[str],
               flush_period: float = 1.0) -> BagRecorderNode:
        """Add a bag recorder for ``topics`` (names) writing ``bag_dir``; returns the node.

        Every topic must already have a publisher in this graph (add the nodes first).
        """
        from paramotion.bag.recorder_node import BagRecorderNode
        recorder = self.add(BagRecorderNode, output=str(bag_dir), topics=list(topics),
                            flush_period=float(flush_period))
        recorder.discover()
        missing = recorder.missing_topics()
        if missing:
            raise ValueError(f'cannot record {missing}: no publisher in this graph')
        self.drain()
        return recorder

    def drain(self) -> int:
        """Run ready callbacks until nothing is left to run; returns how many handlers ran.

        Callbacks run by a drain may make others ready (a timer publishes, a subscription
        answers), and those run in the same drain, so one lock-step period carries every chain
        of messages it starts. The count is the executor's: callbacks for the waitset executor,
        queued events (messages, timer dispatches, clock updates) for the events executor.
        """
        if self.executor_kind == 'events':
            count = self._drain_events()
        elif self.executor_kind == 'lockstep':
            count = self._lockstep.drain(self._check_runaway)
        else:
            count = self._drain_waitset()
        self.callbacks_run += count
        return count

    def _check_runaway(self, count: int) -> None:
        if count > self.max_callbacks_per_drain:
            raise RuntimeError(
                f'executor did not drain after {count} callbacks: a callback keeps '
                'itself ready (zero-period wall timer or publish loop?)')

    def _drain_events(self) -> int:
        """EventsExecutor: every event is one handler on a FIFO queue and one ``spin_once`` runs
        exactly one of them. A marker task is queued behind the events; the spins until it has
        run are the events ahead of it (and the marker). Events those handlers queued sit
        behind the marker, so the round repeats until a marker is the only handler of its
        round. A timer made due by the new simulated time is queued by the executor's timer
        thread, not by the thread that set the time, so an idle round with a due timer waits
        for its event instead of ending the drain (else the timer would fire one period late).
        """
        count = 0
        while True:
            marker = []
            self.executor.create_task(marker.append, True)
            ran = 0
            try:
                while not marker:
                    self.executor.spin_once(timeout_sec=0.0)
                    ran += 1
                if ran == 1 and self._timer_due():
                    self._await_event()
                    ran += 1
            except (ShutdownException, ExternalShutdownException):
                break
            count += ran - 1
            if ran == 1:
                break
            self._check_runaway(count)
        return count

    def _timer_due(self) -> bool:
        """True when a timer of one of this graph's nodes is due and has not run yet."""
        return any(timer.is_ready() for node in self.nodes for timer in node.timers)

    def _await_event(self, limit_s: float = 5.0) -> None:
        """Run events as they arrive until no timer is due (at most ``limit_s`` s of wall time).
        """
        end = time.monotonic() + limit_s
        while self._timer_due():
            if time.monotonic() > end:
                raise RuntimeError(f'a due timer was not dispatched within {limit_s} s')
            self.executor.spin_once(timeout_sec=0.001)

    def _drain_waitset(self) -> int:
        """SingleThreadedExecutor: wait rounds (:func:`rclpy_wait_round`) until one runs
        nothing. A burst of N messages on one subscription therefore takes N rounds, all
        within this call."""
        count = 0
        while True:
            ran = rclpy_wait_round(self.executor)
            count += ran
            if ran == 0:
                return count
            self._check_runaway(count)

    def run_lockstep(self, clock_source: ClockSourceNode,
                     until: Callable[[], bool] | None = None,
                     max_sim_time: float | None = None,
                     on_step: Callable[[], object] | None = None,
                     ) -> Literal['done', 'time_limit']:
        """Advance ``clock_source`` period by period, draining the executor after each.

        Stops when ``until()`` is true (checked after every drain) or when the simulated time
        reaches ``max_sim_time`` seconds. Returns ``'done'`` or ``'time_limit'``.
        """
        if not clock_source.params.lockstep:
            raise ValueError(f'{clock_source.get_name()}: lockstep parameter is false')
        if self.direct_time:
            self._set_time_directly(clock_source)
        self.drain()
        while True:
            if until is not None and until():
                return 'done'
            if max_sim_time is not None and clock_source.sim_time >= max_sim_time - 1e-12:
                return 'time_limit'
            clock_source.advance()
            self.drain()
            if on_step is not None:
                on_step()

    def _set_time_directly(self, clock_source: ClockSourceNode) -> None:
        """Let ``clock_source`` set the simulated time of this graph's nodes itself.

        Each node on sim time normally learns the time from its own ``/clock`` subscription:
        one message taken and one callback per node per period. In lock-step the Graph knows
        the time when the source publishes it, so it hands each node's time source the same
        message directly and drops those subscriptions (``/clock`` is still published, for the
        recorder and for anyone watching). The callbacks see the same time: a node's ``/clock``
        subscription is its first, so the waitset executor ran it before the node's other
        callbacks of that period.
        """
        if self._direct_source is not clock_source:
            if self._direct_source is not None:
                self._direct_source.clock_hooks.remove(self._deliver_time)
            clock_source.clock_hooks.append(self._deliver_time)
            self._direct_source = clock_source
        for node in self.nodes:
            source = take_time_source(node)
            if source is not None and source not in self._direct_time:
                self._direct_time.append(source)

    def _deliver_time(self, msg: ClockMsg) -> None:
        for source in self._direct_time:
            if source.ros_time_is_active:
                source.clock_callback(msg)

    def spin_wall(self, seconds: float, until: Callable[[], bool] | None = None) -> bool:
        """Spin on wall-clock time (free-running sources, DDS peers) for ``seconds``.

        rclpy's executor spins here, so the publishers go back to the middleware first (the
        next lock-step drain hands messages over in process again); messages already handed
        over and not yet taken are run first, by a drain."""
        delivery = self._lockstep.delivery
        if delivery is not None:
            if delivery.snapshot():
                self.drain()
            delivery.close()
        end = time.monotonic() + seconds
        while time.monotonic() < end:
            if until is not None and until():
                return True
            self.executor.spin_once(timeout_sec=min(0.05, max(0.0, end - time.monotonic())))
        return until() if until is not None else False

    def shutdown(self) -> None:
        """Destroy every node (recorders close their bags), the executor and the context."""
        owned = {id(c) for node in self.nodes for c in getattr(node, 'components', ())}
        self._lockstep.close()
        for node in reversed(self.nodes):
            try:
                self.executor.remove_node(node)
            except Exception:
                pass
            if id(node) not in owned:     # a container destroys its own components
                node.destroy_node()
        self.nodes.clear()
        self.executor.shutdown()
        rclpy.try_shutdown(context=self.context)

    def __enter__(self) -> Graph:
        return self

    def __exit__(self, *exc: object) -> None:
        self.shutdown()
