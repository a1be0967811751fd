"""Clock-owning nodes: the simulator (and the bag player) publish ``/clock``.

A :class:`ClockSourceNode` advances simulated time in fixed periods. Two ways to drive it:

- **lock-step** (``lockstep: true``, used by :class:`paramotion.graph.Graph` when all nodes share
  one executor): the runner calls :meth:`advance` itself, then lets the executor drain every
  callback that the new time and the new messages made ready, then advances again. Nothing
  depends on wall-clock speed, so a scenario is as fast as the machine allows and its results
  are the same on a fast and a slow machine.
- **free-running** (``lockstep: false``, the default when a node runs as its own process): a
  steady wall-clock timer calls :meth:`advance` at ``real_time_factor`` times real time, so
  nodes in other processes see ``/clock`` advance smoothly over DDS.
"""
from __future__ import annotations

import time
from collections import deque
from collections.abc import Callable
from typing import Any

from builtin_interfaces.msg import Time
from rclpy.clock import Clock, ClockType
from rosgraph_msgs.msg import Clock as ClockMsg

from paramotion.node import Param, ParamotionNode
from paramotion.qos import CLOCK_QOS

NS = 1_000_000_000


def stamp_from_ns(ns: int) -> Time:
    """builtin_interfaces/Time from integer nanoseconds."""
    return Time(sec=int(ns // NS), nanosec=int(ns % NS))


def take_time_source(node: Any) -> Any | None:
    """The time source of ``node`` on sim time, its own ``/clock`` subscription dropped, for a
    caller that hands it each ``/clock`` message itself (``source.clock_callback``): the lock-step
    Graph and a component container. None when the node is not on sim time."""
    source = getattr(node, '_time_source', None)
    if source is None or not source.ros_time_is_active:
        return None
    if source._clock_sub is not None:
        node.destroy_subscription(source._clock_sub)
        source._clock_sub = None
    return source


class ClockSourceNode(ParamotionNode):
    """Base of nodes that own simulated time and publish ``/clock``."""

    USE_SIM_TIME_DEFAULT = False
    #: Publishes ``/clock`` itself (:func:`paramotion.clock_watchdog.uses_sim_time`).
    OWNS_CLOCK = True
    PARAMS = (
        Param('publish_period', 0.01, 'Simulated seconds advanced per step; /clock and state '
              'are published once per step.', min=1e-4, max=1.0, read_only=True),
        Param('real_time_factor', 1.0, 'Free-running speed as a multiple of wall-clock time '
              '(0 = as fast as possible). Ignored in lock-step.', min=0.0, max=1000.0),
        Param('lockstep', False, 'True when a Graph runner drives advance() itself (one '
              'process, one executor); false to free-run on a wall-clock timer.',
              read_only=True),
        Param('wait_for_clock_subscribers', 0, 'Free-running only: hold time at zero until this '
              'many subscribers listen to /clock (multi-process start-up over DDS).',
              min=0, max=1000, read_only=True),
        Param('wait_for_matched', [''], "Free-running only: also hold time until this node's "
              "publishers have these many matched subscribers, as 'topic:count' entries.",
              read_only=True),
        Param('sync_max_lag', -1.0, 'Free-running only: do not advance while an answer of a '
              'controller (the commands the simulator names as answers) has been due for '
              'longer than this many sim seconds, so real_time_factor becomes a ceiling the '
              'simulator slows down from instead of running away from a late controller '
              '(< 0: never wait).', min=-1.0, max=10.0, read_only=True),
        Param('sync_timeout', 1.0, 'Free-running with sync_max_lag >= 0: wall seconds to wait '
              'for an answer before advancing anyway (warning: controller gone; it is waited for '
              'again once it answers).',
              min=0.01, max=60.0, read_only=True),
        Param('sync_expect', [''], 'Free-running with sync_max_lag >= 0: the controllers '
              '(answer sources) expected to answer; each must have answered by sync_first_by '
              'sim seconds, or the simulator waits for it there.', read_only=True),
        Param('sync_first_by', 0.25, 'Free-running with sync_max_lag >= 0: sim seconds within '
              'which an expected controller answers first, and its second answer follows its '
              'first (its period is known from its second answer on).', min=0.001, max=60.0,
              read_only=True),
        Param('sync_on_answer', True, 'Free-running with sync_max_lag >= 0: a simulator '
              'holding for an answer advances right after the answer arrives (at most at '
              'real_time_factor) instead of at its next wall-timer tick.', read_only=True),
        Param('sync_repeat', 0.05, 'Free-running with sync_max_lag >= 0: while waiting for an '
              'answer, publish the current time on /clock again at most this often (wall s; '
              '/clock is best effort, a controller that lost the sample would never answer).',
              min=0.001, max=10.0, read_only=True),
    )

    def __init__(self, node_name: str, **kwargs: Any) -> None:
        super().__init__(node_name, **kwargs)
        self.sim_time_ns = 0
        self._period_ns = int(round(self.params.publish_period * NS))
        self._clock_pub = self.create_publisher(ClockMsg, '/clock', CLOCK_QOS)
        self._wall_timer = None
        #: Called with each ``/clock`` message right after it is published (a lock-step
        #: :class:`paramotion.graph.Graph` sets its nodes' clocks this way).
        self.clock_hooks: list[Callable[[ClockMsg], None]] = []
        self._waiting = (self.params.wait_for_clock_subscribers > 0
                         or any(self.params.wait_for_matched))
        #: Per answering controller: [stamp of its last answer, its period, its last
        #: intervals between answers] in sim ns (:meth:`answered`).
        self.answers = {}
        self.sync_waits = 0           # timer ticks that waited for an answer
        self._sync_lag_ns = int(round(self.params.sync_max_lag * NS))
        self._first_by_ns = int(round(self.params.sync_first_by * NS))
        self._expected = [name for name in self.params.sync_expect if name]
        self._sync_since = None       # wall time (monotonic) the current wait began
        self._said_at = 0.0           # wall time (monotonic) /clock was last published
        self._advanced_at = 0.0       # wall time (monotonic) of the last advance
        self._wall_period = 0.0       # wall seconds per period at real_time_factor
        self._answer_tick_queued = False
        #: Controllers silent for ``sync_timeout``: not waited for until they answer again.
        self.given_up: set[str] = set()
        if not self.params.lockstep:
            self._start_free_running()

    def check_params(self, values: dict[str, Any]) -> str | None:
        """Refuse a ``wait_for_matched`` entry that is not ``'topic:count'``."""
        for entry in values['wait_for_matched']:
            topic, sep, count = entry.rpartition(':')
            if entry and (not sep or not topic or not count.isdigit()):
                return (f"parameter 'wait_for_matched' entry {entry!r}: expected "
                        "'topic:count' with a whole count")
        return None

    @property
    def sim_time(self) -> float:
        """Current simulated time in seconds."""
        return self.sim_time_ns / NS

    def stamp(self) -> Time:
        """Current simulated time as builtin_interfaces/Time, for message headers."""
        return stamp_from_ns(self.sim_time_ns)

    def _start_free_running(self) -> None:
        rtf = self.params.real_time_factor
        period = self.params.publish_period / rtf if rtf > 0 else 0.0
        self._wall_period = period
        self._wall_timer = self.create_timer(
            period, self._free_running_tick, clock=Clock(clock_type=ClockType.STEADY_TIME))

    def on_params_changed(self, changed: dict[str, Any]) -> None:
        """Restart the wall-clock timer at the new ``real_time_factor``."""
        if 'real_time_factor' in changed and self._wall_timer is not None:
            self.destroy_timer(self._wall_timer)
            self._start_free_running()

    def _start_condition_met(self) -> bool:
        if self._clock_pub.get_subscription_count() < self.params.wait_for_clock_subscribers:
            return False
        counts = {}
        for pub in self.publishers:
            counts[pub.topic_name] = max(counts.get(pub.topic_name, 0),
                                         pub.get_subscription_count())
        for entry in self.params.wait_for_matched:
            if entry:
                topic, _, count = entry.rpartition(':')
                if counts.get(topic, 0) < int(count):
                    return False
        return True

    def answered(self, source: str, stamp_ns: int) -> None:
        """Subclass hook: controller ``source`` answered the state of sim time ``stamp_ns``
        (the stamp of the command it computed from that state).

        A controller's next answer is due one interval (its period: the median of its last
        nine intervals between answers, robust to a tick that fired late) after its last;
        with ``sync_max_lag`` >= 0 a free-running source waits while an answer has been due
        for longer than the lag.
        """
        if source in self.given_up:
            # A controller given up on answers again: the simulator waits for it again (it
            # catches up while the simulator holds), rather than running away from it.
            self.given_up.discard(source)
            self.get_logger().info(f'{source} answering again: simulator waits for it again')
        entry = self.answers.get(source)
        if entry is None:
            self.answers[source] = [stamp_ns, None, deque(maxlen=9)]
        elif stamp_ns > entry[0]:
            entry[2].append(stamp_ns - entry[0])
            entry[1] = sorted(entry[2])[len(entry[2]) // 2]
            entry[0] = stamp_ns
        if self._sync_since is not None and not self._answer_tick_queued and \
                self.params.sync_on_answer and self.executor is not None:
            # Holding for an answer: look again right after this callback (which applies the
            # command), not up to a wall-timer period later; each round trip of a waiting
            # simulator would otherwise idle half a period on average.
            self._answer_tick_queued = True
            self.executor.create_task(self._answer_tick)

    def _answer_tick(self) -> None:
        """The advance of a wall-timer tick that found the source waiting, done as soon as
        the answer is in rather than at the next tick. Every advance so belongs to its own
        wall tick (one that advanced or one that waited; the wait ends with the advance), so
        the source never runs ahead of ``real_time_factor`` over the ticks; measured from the
        last advance instead, a tick that fired late would hold the answer's advance back to
        the tick after."""
        self._answer_tick_queued = False
        if self._sync_since is not None or \
                time.monotonic() - self._advanced_at >= self._wall_period:
            self._free_running_tick()

    def _late_answer(self) -> str | None:
        """The first controller whose answer is overdue by more than the lag, else None: an
        expected one that has not answered by ``sync_first_by``, one with a single answer
        ``sync_first_by`` after it, any other one period (its median interval) after its last.
        """
        limit = self.sim_time_ns - self._sync_lag_ns
        first_by = self._first_by_ns
        if first_by <= limit:
            for source in self._expected:
                if source not in self.answers and source not in self.given_up:
                    return source
        for source, (last, interval, _) in self.answers.items():
            if last + (first_by if interval is None else interval) <= limit and \
                    source not in self.given_up:
                return source
        return None

    def _must_wait_for_answer(self) -> bool:
        if self._sync_lag_ns < 0:
            return False
        late = self._late_answer()
        if late is None:
            self._sync_since = None
            return False
        now = time.monotonic()
        if self._sync_since is None:
            self._sync_since = now
        if now - self._sync_since < self.params.sync_timeout:
            self.sync_waits += 1
            # /clock is best effort: a controller that lost the sample of this time (a reader
            # matched late, a full queue) would never tick and answer; say the time again
            # (not at every wall tick: each repeat costs every /clock reader a callback).
            if now - self._said_at >= self.params.sync_repeat:
                self._said_at = now
                self._clock_pub.publish(ClockMsg(clock=self.stamp()))
            return True
        self.given_up.add(late)
        self._sync_since = None
        self.get_logger().warning(
            f'no answer from {late} for {self.params.sync_timeout:g} s of wall time: '
            'advancing without it until it answers again')
        return False

    def _free_running_tick(self) -> None:
        if self._waiting:
            if not self._start_condition_met():
                return
            self._waiting = False
        if self._must_wait_for_answer():
            return
        self.advance()

    def advance(self) -> None:
        """Advance simulated time by one period, then publish ``/clock`` and state."""
        self.advance_time(self._period_ns)
        self.sim_time_ns += self._period_ns
        msg = ClockMsg(clock=self.stamp())
        self._clock_pub.publish(msg)
        if self._sync_lag_ns >= 0:
            self._said_at = self._advanced_at = time.monotonic()
        for hook in self.clock_hooks:
            hook(msg)
        self.publish_state()

    def advance_time(self, period_ns: int) -> None:
        """Subclass hook: bring the world from ``sim_time_ns`` to ``sim_time_ns + period_ns``."""

    def publish_state(self) -> None:
        """Subclass hook: publish what the world looks like at ``sim_time_ns``."""
