"""Clock watchdog: a sim-time node notices when ``/clock`` stops (the simulator died or hangs).

On simulated time a node whose simulator is gone simply stops: its sim-time timers never fire
again and nothing tells the user why. :class:`ClockWatchdog` checks the node's clock on a
*wall-clock* (steady) timer every ``period`` seconds. When simulated time has advanced once and
then not advanced for ``timeout`` wall seconds it warns **once** (log and a WARN status on
``/diagnostics``, diagnostic_msgs/DiagnosticArray as ROS diagnostics tools expect); when time
advances again it says so once (log and an OK status). Checking runs in a daemon thread that
sleeps ``period`` (default 0.5 s) between passes, so a node with a stopped clock sleeps rather
than spins. (A wall timer in the node's executor instead was seen to upset the climber graph
across processes: the planner's clock lagged by seconds of sim time on a loaded machine.)

:func:`paramotion.node.run_node` attaches one to every node that runs on sim time in its own
process. One-process Graph runs do not get one: there the runner drives the clock itself and a
long callback is not a stopped simulator.
"""
import threading
import time
from collections.abc import Callable

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from rclpy.node import Node

from paramotion.qos import STATE_QOS


class ClockWatchdog:
    """Watch ``node``'s ROS clock; ``on_change(stopped, message)`` is called on each change."""

    def __init__(self, node: Node, timeout: float = 2.0, period: float = 0.5,
                 on_change: Callable[[bool, str], object] | None = None) -> None:
        if not timeout > 0.0 or not period > 0.0:
            raise ValueError(f'clock watchdog: timeout {timeout} and period {period} must be > 0')
        self.node = node
        self.timeout = float(timeout)
        self.on_change = on_change
        self.stopped = False
        self.warnings = 0
        self.period = float(period)
        self._last_ns = None
        self._last_change_wall = None
        self._pub = node.create_publisher(DiagnosticArray, '/diagnostics', STATE_QOS)
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True,
                                        name=f'clock_watchdog_{node.get_name()}')
        self._thread.start()

    def _run(self):
        while not self._stop.wait(self.period):
            try:
                self.check()
            except Exception:   # node or context being destroyed: stop watching
                if self._stop.is_set() or not self.node.context.ok():
                    return
                raise

    def check(self) -> None:
        """One watchdog pass (called by the thread; callable directly in tests)."""
        now_ns = self.node.get_clock().now().nanoseconds
        wall = time.monotonic()
        if now_ns != self._last_ns:
            self._last_ns = now_ns
            self._last_change_wall = wall
            if self.stopped:
                self.stopped = False
                message = f'/clock advances again (sim time {now_ns * 1e-9:.3f} s)'
                self.node.get_logger().info(message)
                self._report(DiagnosticStatus.OK, message)
            return
        if self.stopped or now_ns == 0:
            return   # already said, or simulated time has not started yet (start-up gate)
        idle = wall - self._last_change_wall
        if idle >= self.timeout:
            self.stopped = True
            self.warnings += 1
            message = (f'/clock stopped at sim time {now_ns * 1e-9:.3f} s: no advance for '
                       f'{idle:.1f} s of wall time (simulator stopped?); waiting for it')
            self.node.get_logger().warning(message)
            self._report(DiagnosticStatus.WARN, message)

    def _report(self, level, message):
        arr = DiagnosticArray()
        arr.header.stamp = self.node.get_clock().now().to_msg()
        arr.status.append(DiagnosticStatus(
            level=level, name=f'{self.node.get_fully_qualified_name()}: clock',
            message=message, hardware_id='',
            values=[KeyValue(key='clock_stopped', value=str(self.stopped).lower())]))
        self._pub.publish(arr)
        if self.on_change is not None:
            self.on_change(self.stopped, message)

    def stop(self) -> None:
        """Stop watching (before the node is destroyed)."""
        self._stop.set()
        self._thread.join(2.0 * self.period + 1.0)


def uses_sim_time(node: Node) -> bool:
    """True if ``node`` runs on simulated time and does not own ``/clock`` itself (a
    :class:`paramotion.clock.ClockSourceNode`, marked ``OWNS_CLOCK``)."""
    if getattr(node, 'OWNS_CLOCK', False):
        return False
    return bool(node.get_parameter('use_sim_time').value)


def attach(node: Node, timeout: float = 2.0, period: float = 0.5) -> ClockWatchdog | None:
    """Give ``node`` a :class:`ClockWatchdog` if it runs on sim time; returns it or None.

    A node with an ``on_clock_stopped(stopped, message)`` method is told about each change (to
    hold its outputs or put it in its own status).
    """
    if not uses_sim_time(node):
        return None
    node.clock_watchdog = ClockWatchdog(node, timeout, period,
                                        getattr(node, 'on_clock_stopped', None))
    return node.clock_watchdog


__all__ = ['ClockWatchdog', 'attach', 'uses_sim_time']
