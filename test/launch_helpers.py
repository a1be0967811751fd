"""Run ``paramotion launch`` in a subprocess and watch its graph from the test over DDS.

The launcher and its nodes inherit the test run's private ``ROS_DOMAIN_ID`` (conftest.py). The
launcher runs in a session of its own and its nodes share its process group, as in a terminal.
The watcher is a node in its own Context; every wait polls a condition with a deadline (no fixed
sleeps), and the launch is always stopped with Ctrl-C (SIGINT), escalating if it hangs, and any
node process left behind is killed by pid.
"""
import os
import re
import signal
import subprocess
import sys
import time
from contextlib import contextmanager

import rclpy
from rclpy.executors import SingleThreadedExecutor

from paramotion.qos import CLOCK_QOS

CLI = [sys.executable, '-m', 'paramotion.cli', 'launch']


class Watcher:
    """A node in its own context that subscribes to what a test wants to see."""

    def __init__(self, name='launch_test_watcher'):
        from rosgraph_msgs.msg import Clock
        self.context = rclpy.Context()
        rclpy.init(context=self.context)
        self.node = rclpy.create_node(name, context=self.context)
        self.executor = SingleThreadedExecutor(context=self.context)
        self.executor.add_node(self.node)
        self.sim_time = 0.0
        self.node.create_subscription(Clock, '/clock', self._on_clock, CLOCK_QOS)

    def _on_clock(self, msg):
        self.sim_time = msg.clock.sec + msg.clock.nanosec * 1e-9

    def subscribe(self, msgtype, topic, callback, qos):
        return self.node.create_subscription(msgtype, topic, callback, qos)

    def spin_until(self, predicate, timeout, launch=None):
        """Spin until ``predicate()``; False after ``timeout`` s or if the launch ended."""
        end = time.monotonic() + timeout
        while time.monotonic() < end:
            if predicate():
                return True
            if launch is not None and launch.poll() is not None:
                return predicate()
            self.executor.spin_once(timeout_sec=0.05)
        return predicate()

    def close(self):
        self.executor.shutdown()
        self.node.destroy_node()
        rclpy.try_shutdown(context=self.context)


class Launch:
    """``paramotion launch`` as a subprocess; its output goes to ``log_path``."""

    def __init__(self, items, log_path):
        self.log_path = log_path
        self._log = open(log_path, 'wb')
        self.proc = subprocess.Popen(CLI + list(items), stdout=self._log,
                                     stderr=subprocess.STDOUT, start_new_session=True,
                                     env={**os.environ, 'PYTHONUNBUFFERED': '1'})

    def poll(self):
        return self.proc.poll()

    def output(self):
        if not self._log.closed:
            self._log.flush()
        with open(self.log_path, errors='replace') as f:
            return f.read()

    def node_pids(self):
        return [int(p) for p in re.findall(r'process started with pid \[(\d+)\]', self.output())]

    def stop(self, timeout=30.0, group=True):
        """Ctrl-C; returns the launcher's exit code. Escalates and reaps if it hangs.

        ``group``: SIGINT to the whole process group, launcher and nodes, as a terminal's
        Ctrl-C does (each node then gets it twice: from the terminal and from the launcher);
        otherwise to the launcher alone, which forwards it.
        """
        if self.proc.poll() is None:
            if group:
                os.killpg(self.proc.pid, signal.SIGINT)
            else:
                self.proc.send_signal(signal.SIGINT)
            try:
                self.proc.wait(timeout)
            except subprocess.TimeoutExpired:
                os.killpg(self.proc.pid, signal.SIGKILL)
                self.proc.wait()
        self._log.close()
        return self.proc.returncode

    def leftover_pids(self):
        alive = []
        for pid in self.node_pids():
            try:
                os.kill(pid, 0)
            except ProcessLookupError:
                continue
            alive.append(pid)
        return alive

    def kill_leftovers(self):
        for pid in self.leftover_pids():
            try:
                os.kill(pid, signal.SIGKILL)
            except ProcessLookupError:
                pass


@contextmanager
def launched(items, tmp_path, watcher=True):
    """Start ``paramotion launch ITEMS``; yield (launch, watcher); always stop and clean up."""
    launch = Launch(items, tmp_path / 'launch.log')
    w = Watcher() if watcher else None
    try:
        yield launch, w
    finally:
        if w is not None:
            w.close()
        launch.stop()
        launch.kill_leftovers()
