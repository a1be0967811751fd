"""A component container: several nodes in one process, spun by one executor.

A ROS 2 user puts the nodes that talk to each other at a high rate into one component
container, so that their messages never leave the process and one executor serves them all.
:class:`ComponentContainer` is that container for paramotion's Python nodes: a node of its own
whose ``components`` parameter names the nodes it starts (its subclass lists which node classes
it can hold, by node name), each with

- **its own name**, as a separate process would have (``ros2 node list`` shows every one);
- **its own parameters**: the container declares ``<node>.<parameter>`` for every parameter of
  every component, with the component's descriptor, and hands the values given (launch-file
  ``<param name="fast_tracker.latency" .../>``, ``-p fast_tracker.latency:=0.03``) to that
  node as its start-up overrides; the node validates them as it would in its own process and
  refuses a bad one with its own one-line reason. At run time each node has its own parameter
  services (``ros2 param set /fast_tracker latency 0.03``);
- **the process's remappings**: topic remappings given to the container (``<remap>``, ``-r
  from:=to``, node-targeted ``fast_tracker:from:=to``) apply to its components, and its
  namespace is theirs; the node-name rule ``__node:=`` names the container only.

:func:`paramotion.node.run_node` runs a container like any node: ``spin_node`` adds the
components to the same executor (``PARAMOTION_EXECUTOR``), and the container destroys them
when it is destroyed.

**Messages among the container's nodes** (``in_process``, default true): spun on the
``events`` executor in its own process, the container hands a message one of its nodes
publishes for another over in process while no reader outside the container listens on the
topic (:class:`paramotion.intra_process.ContainerDelivery`): the reader's callback gets a copy
from the executor's queue and the message is never serialised; while a reader outside
listens, the message goes through the middleware to every reader, once each.

**Sim time in a container** (``sim_timers``, default ``container``): spun in its own process
(:meth:`ComponentContainer.start_clock`, called by ``spin_node``), the container subscribes to
``/clock`` once for all its nodes (:class:`ContainerClock`): each ``/clock`` message sets the
time of every node's clock, then the sim-time timers that the new time made due fire at once,
in the components' order, each once. The executor never dispatches them itself (they are
never due when it looks), so the timers tick at the same sim times with any executor.
``executor`` leaves each node its own ``/clock`` subscription and its timers to the executor:
rclpy 7.1.6's ``EventsExecutor`` then fires a sim-time timer twice at one time (and late
afterwards) when two clock jumps of its node are handled before the timer's dispatch, which a
busy container does (``test/test_fast_composition.py`` shows it).
"""
from __future__ import annotations

import sys
from collections.abc import Sequence
from typing import Any

from rclpy.clock_type import ClockType
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from rosgraph_msgs.msg import Clock as ClockMsg

from paramotion.clock import take_time_source
from paramotion.intra_process import ContainerDelivery
from paramotion.node import Param, ParamotionNode, overrides_from_dict

_NAME_RULES = ('__node', '__name', '__ns')
SIM_TIMERS = ('container', 'executor')

#: The container's one ``/clock`` subscription: best effort like rclpy's own (a free-running
#: simulator never waits on it), but deep enough that a container behind by a few periods
#: still sees every time its simulator said, in order, and fires each timer at its own time.
CONTAINER_CLOCK_QOS = QoSProfile(
    history=HistoryPolicy.KEEP_LAST, depth=20,
    reliability=ReliabilityPolicy.BEST_EFFORT, durability=DurabilityPolicy.VOLATILE)


def component_params(components: dict[str, type[ParamotionNode]]) -> tuple[Param, ...]:
    """The container's parameters for ``components`` ({node name: node class}): which to start,
    and ``<node>.<parameter>`` for each component parameter (read only: the start-up value)."""
    names = tuple(components)
    out = [Param('components', list(names), 'Nodes this container starts, by node name (a '
                 'subset of the default list).', choices=names, read_only=True),
           Param('sim_timers', 'container', "Who fires the nodes' sim-time timers in a "
                 "container process of its own: 'container' (one /clock subscription sets "
                 "every node's time and fires the timers it made due, in node order) or "
                 "'executor' (each node's own /clock subscription, the executor's timers).",
                 choices=SIM_TIMERS, read_only=True),
           Param('in_process', True, 'In a process of its own on the events executor: hand '
                 "messages among the container's nodes over in process while no reader "
                 'outside the container listens on the topic (paramotion.intra_process); '
                 'false: every message through the middleware.', read_only=True)]
    for name, cls in components.items():
        for spec in cls.PARAMS:
            out.append(Param(f'{name}.{spec.name}', spec.default,
                             f"Start-up value of {name}'s '{spec.name}' (set it on /{name} "
                             f'at run time): {spec.description}', min=spec.min, max=spec.max,
                             choices=spec.choices, read_only=True))
    return tuple(out)


def remap_rules(argv: Sequence[str]) -> list[str]:
    """The topic and service remapping rules of the ``--ros-args`` sections of ``argv``
    (``-r``/``--remap``), without the node-name and namespace rules, which name the process's
    own node."""
    rules, ros, i = [], False, 0
    argv = list(argv)
    while i < len(argv):
        arg = argv[i]
        if arg == '--ros-args':
            ros = True
        elif arg == '--':
            ros = False
        elif ros and arg in ('-r', '--remap') and i + 1 < len(argv):
            rule = argv[i + 1]
            i += 1
            lhs = rule.partition(':=')[0].rpartition(':')[2]
            if lhs not in _NAME_RULES:
                rules.append(rule)
        i += 1
    return rules


class ComponentContainer(ParamotionNode):
    """A node that starts its ``COMPONENTS`` in its own context, to be spun with them.

    Subclasses set ``COMPONENTS = {node name: node class}`` (in start order) and
    ``PARAMS = component_params(COMPONENTS)``. ``self.components`` holds the started nodes.
    """

    COMPONENTS: dict[str, type[ParamotionNode]] = {}

    def __init__(self, node_name: str, **kwargs: Any) -> None:
        own_args = list(kwargs.get('cli_args') or [])
        global_args = kwargs.get('use_global_arguments', True)
        super().__init__(node_name, **kwargs)
        given = set(self._parameter_overrides)
        rules = (remap_rules(sys.argv) if global_args else []) + remap_rules(own_args)
        cli = ['--ros-args'] + [x for rule in rules for x in ('-r', rule)] if rules else None
        namespace = self.get_namespace()
        sim_time = self.get_parameter('use_sim_time').value
        services = {k: kwargs[k] for k in ('start_parameter_services',) if k in kwargs}
        type_service = self.get_parameter('start_type_description_service').value
        self.components = []
        self.sim_clock = None
        self.delivery = None
        try:
            for name, cls in self.COMPONENTS.items():
                if name not in self.params.components:
                    continue
                prefix = name + '.'
                params = {key[len(prefix):]: self.get_parameter(key).value
                          for key in given if key.startswith(prefix)}
                params.setdefault('use_sim_time', sim_time)
                params.setdefault('start_type_description_service', type_service)
                self.components.append(cls(
                    node_name=name, context=self.context, namespace=namespace,
                    cli_args=cli, use_global_arguments=False,
                    parameter_overrides=overrides_from_dict(params), **services))
        except Exception:
            self.destroy_node()
            raise

    def start_clock(self) -> ContainerClock | None:
        """In a process of its own (``spin_node`` calls this): with ``sim_timers`` =
        ``container`` and sim time on, take the nodes' sim time over (:class:`ContainerClock`).
        """
        if self.params.sim_timers == 'container' and self.sim_clock is None and \
                self.get_parameter('use_sim_time').value:
            self.sim_clock = ContainerClock(self, [self, *self.components])
        return self.sim_clock

    def start_delivery(self, executor: Any, kind: str) -> ContainerDelivery | None:
        """In a process of its own (``spin_node`` calls this with its executor): with
        ``in_process`` on and the ``events`` executor, hand the messages among the container's
        nodes over in process (:class:`paramotion.intra_process.ContainerDelivery`)."""
        if self.params.in_process and kind == 'events' and self.delivery is None:
            self.delivery = ContainerDelivery(executor, [self, *self.components])
            self.get_logger().info('in-process delivery: ' +
                                   (', '.join(self.delivery.topics) or 'no topic'))
        return self.delivery

    def destroy_node(self) -> None:
        """Destroy the components (last started first), then the container."""
        if self.delivery is not None:
            self.delivery.close()
        while self.components:
            self.components.pop().destroy_node()
        return super().destroy_node()


class ContainerClock:
    """One ``/clock`` subscription (on ``owner``) for the sim time of ``nodes``.

    Each message sets the time of every node's clock (through its time source, whose own
    ``/clock`` subscription is dropped), then fires the sim-time timers it made due, node by
    node in ``nodes`` order, each at most once (a timer that missed periods catches up the
    way rcl counts them, as with any executor). The timers are called here, inside the
    ``/clock`` callback, so whichever executor spins the nodes finds them not due: it never
    fires one itself, twice or late. ``ticks`` counts the timer calls.
    """

    def __init__(self, owner: Node, nodes: Sequence[Node]) -> None:
        self.nodes = list(nodes)
        self.sources = []
        self.ticks = 0
        for node in self.nodes:
            source = take_time_source(node)
            if source is not None and source not in self.sources:
                self.sources.append(source)
        self.subscription = owner.create_subscription(ClockMsg, '/clock', self.on_clock,
                                                      CONTAINER_CLOCK_QOS)

    def on_clock(self, msg: ClockMsg) -> None:
        """Set every node's time to ``msg``, then fire the sim-time timers now due."""
        for source in self.sources:
            source.clock_callback(msg)
        for node in self.nodes:
            for timer in list(node.timers):
                if timer.clock.clock_type != ClockType.ROS_TIME:
                    continue
                handle = timer.handle
                with handle:
                    if not handle.is_timer_ready():
                        continue
                    handle.call_timer()
                self.ticks += 1
                timer.callback()


__all__ = ['CONTAINER_CLOCK_QOS', 'ComponentContainer', 'ContainerClock', 'component_params',
           'remap_rules']
