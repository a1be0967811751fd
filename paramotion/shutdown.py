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

Once the node has stopped and done its own clean-up (a recorder has closed its bag, a simulator
has disconnected PyBullet), what is left is the middleware's teardown: rcl destroys the node's
entities and, with the last node, Fast DDS deletes the participant, joining its threads. That
join can, rarely, block for good: after a terminal Ctrl-C of the five-process FAST graph the
isolation controller's main thread can stay in ``Node.destroy_node`` after every other node has
gone.
:func:`bounded_middleware_teardown` bounds it: a process stopped by a signal that is still in
that teardown :data:`TEARDOWN_LIMIT_S` seconds after it began prints its threads' stacks and one
line saying so, and exits 0, its own work being done. The deadline runs in a thread the C library
starts for a POSIX timer (``timer_create`` with ``SIGEV_THREAD``), which calls ``puts``,
``fflush`` and ``_exit`` directly: it needs no Python, so it fires even when the stuck call holds
the interpreter lock.

SIGKILL, and launch's escalation to it, remain the way to stop a process that hangs elsewhere.
So that a hang says where it is, a process still alive :data:`HANG_REPORT_S` seconds after the
first signal prints the stack of each of its threads to stderr (``faulthandler``, which needs no
Python code to run: it reports a thread stuck in C++ holding the interpreter lock too);
``kill -USR1 PID`` prints them at any time.

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
import time
from collections.abc import Iterator
from contextlib import contextmanager
from typing import TYPE_CHECKING, NoReturn, Self

if TYPE_CHECKING:
    from rclpy.node import Node
    from rclpy.signals import SignalHandlerOptions

SIGNALS = (signal.SIGINT, signal.SIGTERM)

#: Seconds after the first SIGINT/SIGTERM at which a process not yet gone prints its threads'
#: stacks: just before ``ros2 launch`` escalates to SIGTERM (its ``sigterm_timeout``, 5 s).
HANG_REPORT_S = 4.5

#: Seconds the middleware's teardown may take in a process stopped by a signal (see
#: :func:`bounded_middleware_teardown`); it normally takes a few tens of milliseconds.
TEARDOWN_LIMIT_S = 2.0


class ShutdownSignals:
    """The signal policy of one node process (see the module docstring)."""

    #: The instance installed in this process, if any (:func:`bounded_middleware_teardown`).
    current: ShutdownSignals | None = None

    def __init__(self) -> None:
        self.received = []          # signal numbers, in arrival order
        self.interrupt = True       # raise KeyboardInterrupt on the first signal
        self._previous = {}
        self.ignored = set()        # signals the process was started with ignored
        self.first_at = 0.0         # time.monotonic() of the first signal

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
        ShutdownSignals.current = self
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

    def report_hang_later(self) -> None:
        """Print the threads' stacks :data:`HANG_REPORT_S` s after the first signal, if the
        process is still there then."""
        left = HANG_REPORT_S - (time.monotonic() - self.first_at)
        faulthandler.dump_traceback_later(max(left, 0.05))

    def _handle(self, signum, frame):
        self.received.append(signum)
        if len(self.received) == 1:
            self.first_at = time.monotonic()
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
        if ShutdownSignals.current is self:
            ShutdownSignals.current = None


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


class _SigEvent(ctypes.Structure):
    """glibc's ``struct sigevent`` (64 bytes) with the ``SIGEV_THREAD`` members."""
    _fields_ = [('value', ctypes.c_void_p), ('signo', ctypes.c_int), ('notify', ctypes.c_int),
                ('function', ctypes.c_void_p), ('attribute', ctypes.c_void_p),
                ('pad', ctypes.c_int * 8)]


class _TimeSpec(ctypes.Structure):
    _fields_ = [('sec', ctypes.c_long), ('nsec', ctypes.c_long)]


class _ITimerSpec(ctypes.Structure):
    _fields_ = [('interval', _TimeSpec), ('value', _TimeSpec)]


_SIGEV_THREAD = 2
_CLOCK_MONOTONIC = 1
def _c_timer(libc: ctypes.CDLL, seconds: float, function, argument) -> ctypes.c_void_p:
    """Call the C function ``function(argument)`` in a C-library thread after ``seconds``;
    returns the POSIX timer (for ``timer_delete``)."""
    event = _SigEvent(value=argument, notify=_SIGEV_THREAD,
                      function=ctypes.cast(function, ctypes.c_void_p).value)
    timer = ctypes.c_void_p()
    if libc.timer_create(_CLOCK_MONOTONIC, ctypes.byref(event), ctypes.byref(timer)) != 0:
        raise OSError(ctypes.get_errno(), 'timer_create')
    sec = int(seconds)
    spec = _ITimerSpec(value=_TimeSpec(sec, int(round((seconds - sec) * 1e9))))
    if libc.timer_settime(timer, 0, ctypes.byref(spec), None) != 0:
        libc.timer_delete(timer)
        raise OSError(ctypes.get_errno(), 'timer_settime')
    return timer


class ExitDeadline:
    """In ``seconds``, print the threads' stacks (stderr) and ``message`` (stdout), and end the
    process with exit code 0, whatever its threads are doing then; unless :meth:`cancel` is
    called first.

    Python's and C's buffered output is flushed when it is armed; the deadline itself runs no
    Python. ``armed`` is False where the C library has no POSIX timers (the process then waits
    as it would without one).
    """

    def __init__(self, seconds: float, message: str) -> None:
        self._timers = []
        self._text = ctypes.create_string_buffer(message.encode())   # kept alive while armed
        try:
            self._libc = libc = ctypes.CDLL(None, use_errno=True)
            _flush_all()
            faulthandler.dump_traceback_later(max(seconds - 0.1, 0.05))
            for delay, function, argument in (
                    (seconds, libc.puts, ctypes.cast(self._text, ctypes.c_void_p).value),
                    (seconds + 0.03, libc.fflush, None),    # fflush(NULL): every C stream
                    (seconds + 0.06, libc._exit, None)):
                self._timers.append(_c_timer(libc, delay, function, argument))
        except (OSError, AttributeError):   # no timer_create/SIGEV_THREAD here
            self.cancel()
        self.armed = bool(self._timers)

    def cancel(self) -> None:
        """Disarm (the stack report too)."""
        faulthandler.cancel_dump_traceback_later()
        while self._timers:
            self._libc.timer_delete(self._timers.pop())
        self.armed = False


@contextmanager
def bounded_middleware_teardown(name: str) -> Iterator[None]:
    """Bound the rcl/DDS teardown of node ``name`` run inside this block to
    :data:`TEARDOWN_LIMIT_S` seconds, if this process is a node process stopping on a signal
    (:class:`ShutdownSignals` installed, a signal received); otherwise do nothing.

    Used by :meth:`paramotion.node.ParamotionNode.destroy_node` around rclpy's own, after the
    node's clean-up. On leaving the block the stack report of :class:`ShutdownSignals` is
    re-armed for what is left of its :data:`HANG_REPORT_S`.
    """
    signals = ShutdownSignals.current
    if signals is None or not signals.requested:
        yield
        return
    deadline = ExitDeadline(TEARDOWN_LIMIT_S, (
        f'[paramotion] {name}: the middleware teardown (rcl node and DDS participant) did not '
        f'finish {TEARDOWN_LIMIT_S:.1f} s after it began (stacks above); the node had stopped '
        f'and done its clean-up: exiting 0 without waiting for it'))
    try:
        yield
    finally:
        deadline.cancel()
        signals.report_hang_later()


def _flush_all() -> None:
    """Flush Python's output streams, its logging handlers and C stdio."""
    for stream in (sys.stdout, sys.stderr):
        try:
            stream.flush()
        except Exception:   # closed or broken pipe: nothing more can be said there
            pass
    for handler in logging.getLogger().handlers:
        try:
            handler.flush()
        except Exception:
            pass
    try:
        ctypes.CDLL(None).fflush(None)   # C stdio (PyBullet prints through it)
    except Exception:
        pass


def exit_now(code: int = 0) -> NoReturn:
    """Flush Python's and C's output buffers and end the process with ``code`` at once."""
    logging.shutdown()
    _flush_all()
    os._exit(code)
