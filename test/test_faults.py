"""Faults across processes: each node of a paper's graph in its own process (from its launch
file, started by paramotion.launch.Launcher in this process so that a test can kill and restart
single nodes), watched over DDS. Every wait polls a condition with a deadline.
"""
import os
import signal
import threading
import time
from contextlib import contextmanager

import pytest
from launch_helpers import Watcher

from paramotion.launch import Launcher
from paramotion.launch_xml import load

pytestmark = pytest.mark.slow  # faults injected into graphs of several processes


class Log:
    """Thread-safe list of the launched processes' prefixed output lines."""

    def __init__(self):
        self.lines = []
        self._lock = threading.Lock()

    def __call__(self, line):
        with self._lock:
            self.lines.append(line)

    def text(self):
        with self._lock:
            return '\n'.join(self.lines)

    def count(self, *parts):
        with self._lock:
            return sum(1 for line in self.lines if all(p in line for p in parts))


@contextmanager
def launched_graph(name, args, tmp_path, params=None):
    """Start launch file ``name`` with ``args``; ``params`` {node label: {param: value}} adds
    node parameters. Yields (launcher, log, watcher); always stops every process."""
    desc = load(name, args)
    for label, extra in (params or {}).items():
        desc.node(label).params.update(extra)
    log = Log()
    launcher = Launcher(desc, echo=log, log_dir=tmp_path / 'logs', sigterm_timeout=5.0,
                        sigkill_timeout=5.0)
    watcher = Watcher('fault_test_watcher')
    try:
        launcher.start()
        yield launcher, log, watcher
    finally:
        watcher.close()
        launcher.shutdown()


def proc(launcher, executable):
    return next(p for p in launcher.procs if p.action.executable == executable)


def kill(p, sig=signal.SIGKILL):
    p.signal(sig)
    p.popen.wait(10)


def cpu_seconds(pid):
    """User + system CPU time of process ``pid`` (and its reaped children) from /proc."""
    with open(f'/proc/{pid}/stat') as f:
        fields = f.read().rsplit(')', 1)[1].split()
    ticks = sum(int(v) for v in fields[11:15])   # utime stime cutime cstime
    return ticks / os.sysconf('SC_CLK_TCK')


def stamp_s(stamp):
    return stamp.sec + stamp.nanosec * 1e-9


def test_sonar_killed_planner_stops_and_says_why_then_resumes_on_respawn(tmp_path):
    """Coverage graph at 2x real time on the packaged demo_rooms world (about 90 s of sim
    time to cover). SIGKILL the sonar: the planner stops the robot (zero cmd_vel, state
    waiting_for_sonar with the reason) within 0.5 s of sim time of the last sweep it could
    have had; start the sonar again: the planner leaves waiting_for_sonar, the covered
    fraction rises again, and the run completes: the planner's own ``done`` with >= 99 % of
    CVS seen, nothing given up."""
    from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
    from geometry_msgs.msg import Twist
    from sensor_msgs.msg import LaserScan
    from std_msgs.msg import Float64

    from coverage_pkg.demo import demo_world
    from paramotion.qos import LATCHED_QOS, SENSOR_QOS, STATE_QOS
    world = str(demo_world())
    # sonar_timeout 0.4 s + the planner's 0.1 s check period = stop within 0.5 s of sim time.
    with launched_graph('coverage', {'real_time_factor': 2.0, 'world': world}, tmp_path,
                        params={'coverage_planner': {'sonar_timeout': 0.4}}) as (launcher, log,
                                                                                 w):
        scans, fractions, statuses, cmds = [], [], [], []
        w.subscribe(LaserScan, '/sonar/scan', lambda m: scans.append(stamp_s(m.header.stamp)),
                    SENSOR_QOS)
        w.subscribe(Float64, '/coverage/covered_fraction',
                    lambda m: fractions.append((w.sim_time, m.data)), LATCHED_QOS)
        w.subscribe(DiagnosticArray, '/coverage/status', lambda m: statuses.append(
            (stamp_s(m.header.stamp), m.status[0])), LATCHED_QOS)
        w.subscribe(Twist, '/cmd_vel', lambda m: cmds.append(
            (w.sim_time, abs(m.linear.x) + abs(m.linear.y) + abs(m.angular.z))), STATE_QOS)

        def state(entry=None):
            entry = entry or (statuses[-1] if statuses else None)
            return next((kv.value for kv in entry[1].values if kv.key == 'state_now'),
                        None) if entry else None
        # Covering first (moving, past warm-up), and this watcher hears the sonar itself (its
        # sweeps' stamps time the stop; on the small demo world 1 % of CVS can be covered
        # before DDS discovery has matched the watcher with the sonar process).
        assert w.spin_until(lambda: fractions and fractions[-1][1] > 0.01 and cmds
                            and cmds[-1][1] > 0.0 and len(scans) >= 5 and state() not in (
                                None, 'warmup', 'waiting_for_sonar'), 90), \
            (len(scans), [(t, state(e)) for t, e in ((e[0], e) for e in statuses)],
             log.text()[-3000:])
        sonar = proc(launcher, 'coverage_sonar')
        n_status = len(statuses)
        kill(sonar)
        n_scans = len(scans)
        assert w.spin_until(lambda: any(state(e) == 'waiting_for_sonar'
                                        for e in statuses[n_status:]), 30), \
            (state(), log.text()[-3000:])
        t_stop, status = next(e for e in statuses[n_status:]
                              if state(e) == 'waiting_for_sonar')
        last_sweep = scans[-1]
        assert len(scans) >= n_scans  # scans in flight at the kill may still arrive
        latency = t_stop - last_sweep
        print(f'stop latency after the last sweep: {latency:.3f} s of sim time')
        assert 0.0 < latency <= 0.5 + 1e-6, (latency, t_stop, last_sweep)
        assert 'sonar' in status.message and status.level == DiagnosticStatus.WARN, status
        # The planner keeps commanding zero while it waits.
        w.spin_until(lambda: w.sim_time > t_stop + 1.0, 30)
        assert cmds[-1][1] == 0.0
        stopped_fraction = fractions[-1][1]
        # Respawn the sonar: coverage resumes and makes progress.
        sonar.start()
        assert w.spin_until(lambda: state() not in (None, 'waiting_for_sonar'), 60), \
            (state(), log.text()[-3000:])
        # The status can arrive before the first moving command does, so wait for the robot
        # to be commanded again rather than sampling /cmd_vel at one instant.
        n_cmds = len(cmds)
        assert w.spin_until(lambda: any(c > 0.0 for _, c in cmds[n_cmds:]), 30), \
            (state(), cmds[-3:], log.text()[-3000:])
        assert w.spin_until(lambda: fractions[-1][1] >= stopped_fraction + 0.01, 90), \
            (stopped_fraction, fractions[-3:], log.text()[-3000:])
        # ... and completes: the graph has no uncovered node left.
        assert w.spin_until(lambda: state() in ('done', 'incomplete', 'stuck'), 240), \
            (state(), fractions[-1:], log.text()[-3000:])
        final = {kv.key: kv.value for kv in statuses[-1][1].values}
        print(f'after the respawn: {final.get("state_now")} at {statuses[-1][0]:.1f} s sim, '
              f'covered {fractions[-1][1]:.4f} of CVS')
        assert state() == 'done', final
        assert w.spin_until(lambda: fractions[-1][1] >= 0.99, 30), fractions[-3:]


def test_simulator_killed_every_node_warns_once_and_idles(tmp_path):
    """Coverage graph with the recorder. Once every node runs on sim time (the monitor reports
    coverage, the planner commands the robot), SIGKILL the simulator: every other node warns
    once that /clock stopped (log and /diagnostics) and uses well under 100 % of a core. (A
    node that never saw /clock advance does not warn: its simulator has not started.)"""
    from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
    from geometry_msgs.msg import Twist
    from std_msgs.msg import Float64

    from paramotion.qos import LATCHED_QOS, STATE_QOS
    with launched_graph('coverage', {'real_time_factor': 2.0, 'record': True,
                                     'bag': str(tmp_path / 'bag')}, tmp_path) as (launcher,
                                                                                   log, w):
        diags = []
        w.subscribe(DiagnosticArray, '/diagnostics', lambda m: diags.extend(m.status),
                    STATE_QOS)
        fractions = []
        w.subscribe(Float64, '/coverage/covered_fraction',
                    lambda m: fractions.append(m.data), LATCHED_QOS)
        commands = []
        w.subscribe(Twist, '/cmd_vel', commands.append, STATE_QOS)
        assert w.spin_until(lambda: fractions and fractions[-1] > 0.0 and commands, 90), \
            log.text()[-3000:]
        kill(proc(launcher, 'coverage_sim'))
        others = [p for p in launcher.procs if p.action.executable != 'coverage_sim']
        names = [p.action.label for p in others]

        def warned(name):
            return log.count(f'[{name}]:', '/clock stopped') >= 1 or \
                log.count(f'{name}', '/clock stopped') >= 1
        assert w.spin_until(lambda: all(warned(n) for n in names), 30), \
            (names, log.text()[-3000:])
        assert w.spin_until(lambda: {d.name.split(':')[0].lstrip('/') for d in diags
                                     if d.level == DiagnosticStatus.WARN} >= set(names), 10), \
            ([d.name for d in diags], names)
        # Idle, not spinning: CPU time over 3 s of wall time.
        before = {p.action.label: cpu_seconds(p.popen.pid) for p in others}
        t0 = time.monotonic()
        w.spin_until(lambda: False, 3.0)
        wall = time.monotonic() - t0
        usage = {label: (cpu_seconds(p.popen.pid) - before[label]) / wall
                 for label, p in ((p.action.label, p) for p in others)}
        print('CPU after the simulator died:', {k: f'{100 * v:.1f} %' for k, v in usage.items()})
        assert all(u < 0.2 for u in usage.values()), usage
        # Warned once each, not once per check.
        for name in names:
            assert log.count(name, '/clock stopped') == 1, (name, log.text()[-3000:])
        assert all(p.running() for p in others), log.text()[-3000:]


def test_recorder_of_the_coverage_graph_killed_with_sigkill_leaves_readable_chunks(tmp_path):
    """Coverage graph recorded by its launch file's recorder; SIGKILL the recorder mid-run:
    every complete chunk reads back (at most the last flush period is lost)."""
    from paramotion.bag.cli import reindex
    from paramotion.bag.reader import bag_info, read_messages
    bag = tmp_path / 'bag'
    with launched_graph('coverage', {'real_time_factor': 2.0, 'record': True,
                                     'bag': str(bag)}, tmp_path,
                        params={'bag_recorder': {'flush_period': 0.2}}) as (launcher, log, w):

        def readable():
            try:
                return sum(1 for _ in read_messages(bag, ['/coverage/ground_truth']))
            except Exception:
                return 0
        assert w.spin_until(lambda: w.sim_time > 4.0 and readable() > 100, 90), \
            log.text()[-3000:]
        kill(proc(launcher, 'bag_recorder'))
        assert proc(launcher, 'bag_recorder').popen.returncode == -signal.SIGKILL
    info = bag_info(bag)
    assert not (bag / 'metadata.yaml').exists()
    assert info.problem     # the unfinished file is reported, not hidden
    msgs = list(read_messages(bag, ['/coverage/ground_truth', '/clock']))
    assert len(msgs) >= 100
    times = [m.log_time_ns for m in msgs if m.topic == '/coverage/ground_truth']
    assert times == sorted(times) and times[-1] > 2_000_000_000
    reindex(bag)
    assert (bag / 'metadata.yaml').is_file()   # rosbag2 tools can open it again
    assert bag_info(bag).complete and bag_info(bag).message_count >= len(msgs)


def test_fast_tracker_killed_controllers_hold_then_recover_on_restart(tmp_path):
    """FAST graph at 0.1x real time (what the five processes keep up with on 2 cores).
    SIGKILL the optical tracker: the isolation controller holds the legs (same leg command,
    zero rate) and the cable controller holds the winches (same cable command, zero winch
    speed), each with a WARN diagnostic; restart the tracker: both say they resumed and their
    commands move again."""
    import numpy as np
    from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
    from geometry_msgs.msg import PoseStamped
    from sensor_msgs.msg import JointState

    from paramotion.qos import SENSOR_QOS, STATE_QOS
    with launched_graph('fast', {'real_time_factor': 0.1, 'composed': 'false'}, tmp_path) as (
            launcher, log, w):
        diags, legs, cables, tracked = [], [], [], []
        w.subscribe(DiagnosticArray, '/diagnostics',
                    lambda m: diags.extend((w.sim_time, d) for d in m.status), STATE_QOS)
        w.subscribe(JointState, '/fast/legs/command', lambda m: legs.append(
            (w.sim_time, np.array(m.position), np.array(m.velocity))), STATE_QOS)
        w.subscribe(JointState, '/fast/cables/command', lambda m: cables.append(
            (w.sim_time, np.array(m.position), np.array(m.velocity))), STATE_QOS)
        w.subscribe(PoseStamped, '/fast/tracker/trolley',
                    lambda m: tracked.append(w.sim_time), SENSOR_QOS)

        def said(node, level, text, since):
            return any(t >= since and d.name == node and d.level == level and text in d.message
                       for t, d in diags)
        # Running under control first.
        assert w.spin_until(lambda: w.sim_time > 1.0 and len(legs) > 50 and len(cables) > 20,
                            90), log.text()[-3000:]
        tracker = proc(launcher, 'fast_tracker')
        kill(tracker)
        t_kill = w.sim_time
        warn = DiagnosticStatus.WARN
        assert w.spin_until(lambda: said('fast_isolation_controller', warn, 'holding the legs',
                                         t_kill) and
                            said('fast_cable_controller', warn, 'holding the winches', t_kill),
                            60), ([d.message for _, d in diags[-10:]], log.text()[-3000:])
        # Holding: the commands published from now on repeat the last one, at zero rate.
        n_legs, n_cables = len(legs), len(cables)
        assert w.spin_until(lambda: len(legs) >= n_legs + 10 and len(cables) >= n_cables + 5,
                            60), log.text()[-3000:]
        for series, n in ((legs, n_legs), (cables, n_cables)):
            held = series[n:]
            assert all(np.array_equal(p, held[0][1]) for _, p, _ in held), series[n - 1:n + 3]
            assert all(not np.any(v) for _, _, v in held)
        # Restart the tracker: both resume and move their commands again.
        t_restart = w.sim_time
        tracker.start()
        ok = DiagnosticStatus.OK
        assert w.spin_until(lambda: said('fast_isolation_controller', ok, 'resumed', t_restart)
                            and said('fast_cable_controller', ok, 'resumed', t_restart), 90), \
            ([d.message for _, d in diags[-10:]], log.text()[-3000:])
        n_legs, n_cables = len(legs), len(cables)
        assert w.spin_until(lambda: len(legs) >= n_legs + 20 and len(cables) >= n_cables + 5,
                            60), log.text()[-3000:]
        assert any(not np.array_equal(p, legs[n_legs][1]) for _, p, _ in legs[n_legs:])
        assert any(not np.array_equal(p, cables[n_cables][1]) for _, p, _ in cables[n_cables:])
        print(f'tracker killed at sim {t_kill:.2f} s, restarted at {t_restart:.2f} s')


def test_clock_watchdog_warns_once_when_clock_stops_and_recovers():
    """The watchdog alone, in one process: a lock-step simulator stands still (the runner
    stops advancing it) for longer than the timeout, then advances again."""
    from paramotion.clock_watchdog import ClockWatchdog, uses_sim_time
    from paramotion.graph import Graph
    from paramotion.smoke.controller_node import SmokeControllerNode
    from paramotion.smoke.sim_node import SmokeSimNode
    changes = []
    with Graph() as graph:
        sim = graph.add(SmokeSimNode)
        ctl = graph.add(SmokeControllerNode)
        assert uses_sim_time(ctl) and not uses_sim_time(sim)
        dog = ClockWatchdog(ctl, timeout=0.3, period=0.05,
                            on_change=lambda stopped, text: changes.append((stopped, text)))
        try:
            graph.spin_wall(0.5)
            assert dog.warnings == 0            # time has not started: no warning
            graph.run_lockstep(sim, max_sim_time=0.5)
            assert graph.spin_wall(10.0, until=lambda: dog.stopped)
            graph.spin_wall(0.5)
            assert dog.warnings == 1 and len(changes) == 1, changes
            assert '/clock stopped at sim time 0.500 s' in changes[0][1]
            graph.run_lockstep(sim, max_sim_time=0.6)
            assert graph.spin_wall(10.0, until=lambda: not dog.stopped)
            assert changes[-1][0] is False and 'advances again' in changes[-1][1]
        finally:
            dog.stop()
