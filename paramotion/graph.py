"""Compose nodes in one process on one executor and run them lock-step on simulated time.

:class:`Graph` is paramotion's component container: it owns a private ``rclpy.Context`` (so
tests and scenarios never share state), one ``SingleThreadedExecutor`` and the nodes added to
it. :meth:`Graph.run_lockstep` alternates "advance the simulator one period" (which publishes
``/clock`` and the simulated state) with "drain the executor" (run every callback made ready by
the new time and by the messages published in response, until nothing is left). Because
nothing waits on the wall clock, a scenario runs as fast as the machine allows and produces the
same results on a fast or a slow machine.
"""
import os
import random
import time

import rclpy
from rclpy.executors import (
    ExternalShutdownException,
    ShutdownException,
    SingleThreadedExecutor,
    TimeoutException,
)

from paramotion.clock import ClockSourceNode
from paramotion.node import overrides_from_dict


def private_domain_id():
    """DDS domain for a one-process run: ``ROS_DOMAIN_ID`` if the user set it (to watch the run
    live), else a random one in 102..200."""
    env = os.environ.get('ROS_DOMAIN_ID', '').strip()
    if env.isdigit():
        return int(env)
    return random.SystemRandom().randint(102, 200)


def _init_context(context, domain_id, private):
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
    ``domain_id``) to watch a run live from other processes.
    """

    def __init__(self, domain_id=None, max_callbacks_per_drain=200_000):
        private = domain_id is None and not os.environ.get('ROS_DOMAIN_ID', '').strip()
        if domain_id is None:
            domain_id = private_domain_id()
        self.domain_id = domain_id
        self.private = private
        self.context = rclpy.Context()
        _init_context(self.context, domain_id, private)
        self.executor = SingleThreadedExecutor(context=self.context)
        self.nodes = []
        self.max_callbacks_per_drain = max_callbacks_per_drain
        self.callbacks_run = 0

    def add(self, node_cls, *, name=None, namespace=None, remappings=None, **params):
        """Create ``node_cls`` in this graph with parameter overrides ``params``.

        ``name`` renames the node, ``namespace`` pushes it into a namespace, ``remappings``
        maps topic names ``{"from": "to"}`` as ``--ros-args -r`` would. Clock sources (simulators,
        players) are put in lock-step mode unless ``lockstep`` is given explicitly.
        """
        if isinstance(node_cls, type) and issubclass(node_cls, ClockSourceNode):
            params.setdefault('lockstep', True)
        kwargs = {'context': self.context,
                  'parameter_overrides': overrides_from_dict(params)}
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
        self.nodes.append(node)
        self.executor.add_node(node)
        return node

    def record(self, bag_dir, topics, flush_period=1.0):
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

    def drain(self):
        """Run ready callbacks until a whole wait finds nothing ready; returns how many ran.

        One zero-timeout wait yields at most one callback per entity (one message per
        subscription) and then reports a timeout *even if it yielded work*, so a single timeout
        does not mean the executor is idle: only a wait round that yields nothing does. A burst
        of N messages on one subscription therefore takes N rounds, all within this call.
        """
        count = 0
        while True:
            ran = 0
            try:
                while True:
                    handler, _, _ = self.executor.wait_for_ready_callbacks(timeout_sec=0.0)
                    handler()
                    if handler.exception() is not None:
                        raise handler.exception()
                    ran += 1
            except (ShutdownException, ExternalShutdownException):
                break
            except TimeoutException:
                pass
            count += ran
            if ran == 0:
                break
            if count > self.max_callbacks_per_drain:
                raise RuntimeError(
                    f'executor did not drain after {count} callbacks: a callback keeps '
                    'itself ready (zero-period wall timer or publish loop?)')
        self.callbacks_run += count
        return count

    def run_lockstep(self, clock_source, until=None, max_sim_time=None, on_step=None):
        """Advance ``clock_source`` period by period, draining the executor after each.

        Stops when ``until()`` is true (checked after every drain) or when the simulated time
        reaches ``max_sim_time`` seconds. Returns ``'done'`` or ``'time_limit'``.
        """
        if not clock_source.params.lockstep:
            raise ValueError(f'{clock_source.get_name()}: lockstep parameter is false')
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

    def spin_wall(self, seconds, until=None):
        """Spin on wall-clock time (free-running sources, DDS peers) for ``seconds``."""
        end = time.monotonic() + seconds
        while time.monotonic() < end:
            if until is not None and until():
                return True
            self.executor.spin_once(timeout_sec=min(0.05, max(0.0, end - time.monotonic())))
        return until() if until is not None else False

    def shutdown(self):
        """Destroy every node (recorders close their bags), the executor and the context."""
        for node in reversed(self.nodes):
            try:
                self.executor.remove_node(node)
            except Exception:
                pass
            node.destroy_node()
        self.nodes.clear()
        self.executor.shutdown()
        rclpy.try_shutdown(context=self.context)

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.shutdown()
