"""SIGINT and SIGTERM in a node process: the first one stops the node, later ones are absorbed.

A ROS user's terminal Ctrl-C sends SIGINT to the whole foreground process group, so a node
started by ``ros2 launch`` gets it twice: once from the terminal and once more from launch,
which forwards it (and escalates to SIGTERM after a timeout). With Python's default handler the
second one raises ``KeyboardInterrupt`` wherever the node happens to be, typically inside
``destroy_node``, and the process dies with a traceback and exit code -2; a bag recorder dies
before writing its MCAP footer and ``metadata.yaml``.

:class:`ShutdownSignals` installs one handler for both signals *before* ``rclpy.init``, so that
rclpy's own handler (which shuts the context down and wakes the executor) chains to it:

- while the node starts (imports done, constructor running, nothing spinning yet) the first
  signal raises ``KeyboardInterrupt``, which interrupts a long start-up as usual;
- once the node spins, a signal raises nothing: rclpy's handler stops the executor between
  callbacks (``ExternalShutdownException``), so no callback is cut in half;
- every later signal only counts, during clean-up too;
- :meth:`ShutdownSignals.finish` sets both signals to "ignore" for the last instants of the
  process: Python resets a Python-level handler to the default one while the interpreter
  finalises, and a signal arriving then would still kill the process.

SIGKILL, and launch's escalation to it, remain the way to stop a process that hangs. So that a
hang says where it is, a process still alive :data:`HANG_REPORT_S` seconds after the first signal
prints the stack of each of its threads to stderr (``faulthandler``, which needs no Python code to
run: it reports a thread stuck in C++ holding the interpreter lock too); ``kill -USR1 PID`` prints
them at any time.

:func:`exit_now` ends a node process once the node is destroyed and its context shut down (the
DDS participant and its shared-memory segments are gone by then): it flushes every output
stream and leaves without the interpreter's own tear-down of every imported module. That
tear-down owns nothing of the node's, but costs CPU: on the loaded 2-core machine it took 0.7 s
for the smallest node and 2.5 s for the climber simulator (PyBullet, SciPy), longer under a
whole graph, beyond the 5 s launch waits before it escalates to SIGTERM.
"""
from __future__ import annotations

import ctypes
import faulthandler
import logging
import os
import signal
import sys
import threading
from typing import TYPE_CHECKING, NoReturn, Self

if TYPE_CHECKING:
    from rclpy.node import Node
    from rclpy.signals import SignalHandlerOptions

SIGNALS = (signal.SIGINT, signal.SIGTERM)

#: Seconds after the first SIGINT/SIGTERM at which a process not yet gone prints its threads'
#: stacks: just before ``ros2 launch`` escalates to SIGTERM (its ``sigterm_timeout``, 5 s).
HANG_REPORT_S = 4.5


class ShutdownSignals:
    """The signal policy of one node process (see the module docstring)."""

    def __init__(self) -> None:
        self.received = []          # signal numbers, in arrival order
        self.interrupt = True       # raise KeyboardInterrupt on the first signal
        self._previous = {}
        self.ignored = set()        # signals the process was started with ignored

    def install(self) -> Self:
        """Take over SIGINT and SIGTERM; call before ``rclpy.init`` (rclpy chains to it).

        A signal the process was started with ignored stays ignored: a shell without job
        control starts background jobs with SIGINT ignored, so that a Ctrl-C meant for the
        foreground does not stop them (pass :meth:`rclpy_options` to ``rclpy.init`` so that
        rclpy leaves it alone too).
        """
        for sig in SIGNALS:
            if signal.getsignal(sig) == signal.SIG_IGN:
                self.ignored.add(sig)
                continue
            self._previous[sig] = signal.signal(sig, self._handle)
        faulthandler.register(signal.SIGUSR1, all_threads=True)
        return self

    def rclpy_options(self) -> SignalHandlerOptions:
        """The ``signal_handler_options`` for ``rclpy.init``: the signals not ignored."""
        from rclpy.signals import SignalHandlerOptions
        handled = set(SIGNALS) - self.ignored
        if handled == set(SIGNALS):
            return SignalHandlerOptions.ALL
        if handled == {signal.SIGTERM}:
            return SignalHandlerOptions.SIGTERM
        if handled == {signal.SIGINT}:
            return SignalHandlerOptions.SIGINT
        return SignalHandlerOptions.NO

    def spinning(self) -> None:
        """The node spins: from now on rclpy's handler stops it, nothing is raised."""
        self.interrupt = False

    @property
    def requested(self) -> bool:
        """True once a SIGINT or SIGTERM has arrived."""
        return bool(self.received)

    def _handle(self, signum, frame):
        self.received.append(signum)
        if len(self.received) == 1:
            faulthandler.dump_traceback_later(HANG_REPORT_S)
            if self.interrupt:
                raise KeyboardInterrupt

    def finish(self) -> None:
        """Ignore both signals from now on (the process is about to exit)."""
        self.interrupt = False
        for sig in SIGNALS:
            signal.signal(sig, signal.SIG_IGN)

    def restore(self) -> None:
        """Put back the handlers found by :meth:`install` (for use inside a longer program)."""
        self.interrupt = False
        faulthandler.cancel_dump_traceback_later()
        for sig, handler in self._previous.items():
            signal.signal(sig, handler)
        self._previous.clear()


class ShutdownWaker:
    """Wake ``node``'s executor once its context has been shut down.

    rclpy's signal handler shuts the context down and wakes the executors from a thread of its
    own; when two signals arrive together (a terminal Ctrl-C under launch), an executor can wake
    before the context is shut down, go back to waiting and never hear of it: a node without a
    timer (workspace monitor, Voronoi planner) then waits until launch escalates to SIGTERM. A
    daemon thread checks the context every ``period`` wall seconds and, once it is shut down,
    triggers a guard condition of the node, which ends the executor's wait.
    """

    def __init__(self, node: Node, period: float = 0.2) -> None:
        self.node = node
        self.period = float(period)
        self._guard = node.create_guard_condition(lambda: None)
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True,
                                        name=f'shutdown_waker_{node.get_name()}')
        self._thread.start()

    def _run(self):
        while not self._stop.wait(self.period):
            if not self.node.context.ok():
                try:
                    self._guard.trigger()
                except Exception:   # being destroyed: the executor has stopped anyway
                    return

    def stop(self) -> None:
        """Stop the thread (before the node is destroyed)."""
        self._stop.set()
        self._thread.join(2.0)


def exit_now(code: int = 0) -> NoReturn:
    """Flush Python's and C's output buffers and end the process with ``code`` at once."""
    for stream in (sys.stdout, sys.stderr):
        try:
            stream.flush()
        except Exception:   # closed or broken pipe: nothing more can be said there
            pass
    logging.shutdown()
    try:
        ctypes.CDLL(None).fflush(None)   # C stdio (PyBullet prints through it)
    except Exception:
        pass
    os._exit(code)
