"""Run ``paramotion launch`` in a subprocess and watch its graph from the test over DDS.

The launcher and its nodes inherit the test run's private ``ROS_DOMAIN_ID`` (conftest.py). The
launcher runs in a session of its own and its nodes share its process group, as in a terminal.
The watcher is a node in its own Context; every wait polls a condition with a deadline (no fixed
sleeps), and the launch is always stopped with Ctrl-C (SIGINT), escalating if it hangs, and any
node process left behind is killed by pid.
"""
import math
import os
import re
import shutil
import signal
import subprocess
import sys
import time
from contextlib import contextmanager
from pathlib import Path

import numpy as np
import rclpy
from rclpy.executors import SingleThreadedExecutor

from paramotion.qos import CLOCK_QOS

CLI = [sys.executable, '-m', 'paramotion.cli', 'launch']
REPO = Path(__file__).resolve().parents[1]
#: The real ROS 2 Jazzy ``ros2 launch`` (launch 3.4.3, launch_ros 0.26.6 sources and a script
#: that runs them), kept beside the repository on the machines that have it.
ROS2_LAUNCH = REPO.parent / 'shared' / 'ros2-launch' / 'ros2-launch'
_WORKSPACES = {}


def _tracked_files():
    try:
        out = subprocess.run(['git', 'ls-files'], cwd=REPO, capture_output=True, text=True,
                             check=True).stdout.split()
    except (OSError, subprocess.CalledProcessError):
        out = []
    return [f for f in out if (REPO / f).is_file()]


def colcon_workspace(tmp_path_factory):
    """A colcon workspace holding a copy of the package's tracked files (what a clone holds),
    built with ``colcon build --symlink-install`` as a ROS 2 user does; built once per test
    run and shared by the tests that need it. Returns the workspace directory."""
    if 'ws' in _WORKSPACES:
        return _WORKSPACES['ws']
    colcon = shutil.which('colcon', path=os.path.dirname(sys.executable)) or \
        shutil.which('colcon')
    assert colcon, 'colcon is in requirements.txt and must be installed'
    ws = tmp_path_factory.mktemp('ws')
    src = ws / 'src' / 'paramotion'
    files = _tracked_files()
    assert 'package.xml' in files
    for rel in files:
        dst = src / rel
        dst.parent.mkdir(parents=True, exist_ok=True)
        shutil.copy2(REPO / rel, dst)
    env = dict(os.environ, PATH=os.path.dirname(sys.executable) + os.pathsep
               + os.environ.get('PATH', ''))
    proc = subprocess.run([colcon, 'build', '--symlink-install', '--event-handlers',
                           'console_direct-'], cwd=ws, env=env, capture_output=True,
                          text=True, timeout=600)
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    _WORKSPACES['ws'] = ws
    return ws


def in_workspace(ws, command):
    """``bash -c`` command line running ``command`` after ``. WS/install/setup.bash``."""
    return ['bash', '-c', f'. {ws}/install/setup.bash && cd {ws} && exec {command}']


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
    """``paramotion launch ITEMS`` (or the command ``cmd``) as a subprocess in a session of its
    own; its output goes to ``log_path``."""

    def __init__(self, items, log_path, cmd=None):
        self.log_path = log_path
        self._log = open(log_path, 'wb')
        self.proc = subprocess.Popen(cmd or CLI + list(items), stdout=self._log,
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
                # A launcher that hangs says where first (paramotion launch: faulthandler).
                self.proc.send_signal(signal.SIGUSR1)
                time.sleep(1.0)
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
def launched(items, tmp_path, watcher=True, cmd=None):
    """Start ``paramotion launch ITEMS`` (or ``cmd``); yield (launch, watcher); always stop and
    clean up."""
    launch = Launch(items, tmp_path / 'launch.log', cmd=cmd)
    w = Watcher() if watcher else None
    try:
        yield launch, w
    finally:
        if w is not None:
            w.close()
        launch.stop()
        launch.kill_leftovers()


def check_clean_stop(launch, group=True, every_node=True):
    """Stop the launch with Ctrl-C (SIGINT to the whole process group as a terminal does, or to
    the launcher alone) and check the stop: the launcher exits 0, no node process is left, no
    traceback is printed, nothing had to be escalated to SIGTERM (``paramotion launch`` and
    ``ros2 launch`` wordings) and (``every_node``) every node process that was started reports
    a clean finish, i.e. exit code 0. Returns the launch output."""
    code = launch.stop(group=group)
    out = launch.output()
    assert code == 0, f'launcher exit code {code}\n' + out[-3000:]
    assert launch.leftover_pids() == [], out[-2000:]
    assert 'Traceback' not in out and 'KeyboardInterrupt' not in out, out[-3000:]
    assert 'sending SIGTERM' not in out and 'failed to terminate' not in out, out[-3000:]
    if every_node:
        labels = re.findall(r'\[INFO\] \[([\w-]+)\]: process started', out)
        assert labels, out[-3000:]
        for label in labels:
            assert f'[INFO] [{label}]: process has finished cleanly' in out, out[-3000:]
    return out


# --------------------------------------------------------------------------- graph checks
def check_coverage_rises(w, launch, rise=0.03):
    """The coverage graph works: the covered fraction rises by ``rise`` and /clock runs."""
    from std_msgs.msg import Float64

    from paramotion.qos import LATCHED_QOS
    fractions = []
    w.subscribe(Float64, '/coverage/covered_fraction',
                lambda m: fractions.append((w.sim_time, m.data)), LATCHED_QOS)
    # The monitor publishes every 2 s of sim time.
    assert w.spin_until(lambda: fractions and fractions[-1][1] > 0.0, 60, launch), \
        launch.output()[-3000:]
    first = fractions[-1][1]
    assert w.spin_until(lambda: fractions[-1][1] >= first + rise, 60, launch), (
        fractions[-5:], launch.output()[-3000:])
    # /clock comes from another process than the fractions, discovered on its own (about
    # 2 s): the covered fraction can rise before the first /clock reaches the watcher.
    assert w.spin_until(lambda: w.sim_time > 0.0, 45, launch), launch.output()[-3000:]
    return fractions


def check_climber_climbs(w, launch, rise=0.05):
    """The climber graph works: both rings end ``rise`` m above where they started (one
    semicycle raises ring 2 by delta, 0.1 m, the next brings ring 1 after it); ``rise`` 0:
    the ground truth arrives."""
    from geometry_msgs.msg import PoseArray

    from paramotion.qos import SENSOR_QOS
    heights = []
    w.subscribe(PoseArray, '/climber/ground_truth',
                lambda m: heights.append([p.position.z for p in m.poses]), SENSOR_QOS)
    assert w.spin_until(lambda: len(heights) > 0, 60, launch), launch.output()[-3000:]
    start = np.array(heights[0])
    if rise > 0:
        assert w.spin_until(lambda: np.all(np.array(heights[-1]) > start + rise), 60,
                            launch), (start, heights[-1], launch.output()[-3000:])
    return heights


def fast_feed_errors(w, launch, settle=1.5, window=0.8, timeout=110):
    """Feed pose (ground truth) against the feed target after ``settle`` s of sim time, for
    ``window`` s, both as received over DDS: returns (RMS position error in mm, RMS angle
    error in degrees, number of samples)."""
    from geometry_msgs.msg import PoseStamped

    from paramotion.qos import SENSOR_QOS, STATE_QOS
    feed, target = [], []

    def sample(m):
        p, q = m.pose.position, m.pose.orientation
        return (m.header.stamp.sec + m.header.stamp.nanosec * 1e-9,
                np.array([p.x, p.y, p.z]), np.array([q.x, q.y, q.z, q.w]))

    w.subscribe(PoseStamped, '/fast/ground_truth/feed', lambda m: feed.append(sample(m)),
                SENSOR_QOS)
    w.subscribe(PoseStamped, '/fast/feed_target', lambda m: target.append(sample(m)),
                STATE_QOS)
    assert w.spin_until(lambda: target and feed and feed[-1][0] >= settle + window, timeout,
                        launch), (feed[-1][0] if feed else 'no feed pose', len(target),
                                  launch.output()[-3000:])
    tt = np.array([t for t, _, _ in target])
    tp = np.array([p for _, p, _ in target])
    pos_err, ang_err = [], []
    for t, p, q in feed:
        if t < settle:
            continue
        goal = np.array([np.interp(t, tt, tp[:, k]) for k in range(3)])
        pos_err.append(np.linalg.norm(p - goal))
        q_goal = target[max(0, int(np.searchsorted(tt, t, side='right')) - 1)][2]
        ang_err.append(math.degrees(2 * math.acos(min(1.0, abs(float(q @ q_goal))))))
    return (1000 * math.sqrt(np.mean(np.square(pos_err))),
            math.sqrt(np.mean(np.square(ang_err))), len(pos_err))
