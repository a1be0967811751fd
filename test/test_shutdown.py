"""A node process stops cleanly however many SIGINT/SIGTERM arrive, and the recorder always
finishes its bag.

A terminal Ctrl-C under ``ros2 launch`` sends every node SIGINT twice (the terminal's and the
one launch forwards), and launch escalates to SIGTERM. Each test starts a real node process,
waits until it is up on the graph, then sends a sequence of signals (or keeps sending them
every few milliseconds until the process is gone, so that some land during clean-up) and
checks exit code 0 and no traceback.
"""
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
import rclpy
import yaml
from rclpy.executors import SingleThreadedExecutor
from std_msgs.msg import String

import paramotion.shutdown as s
from paramotion.bag.reader import bag_info, read_messages
from paramotion.launch import NodeProcess, wait_until

pytestmark = pytest.mark.slow

WORLD = Path(__file__).resolve().parents[1] / 'coverage_pkg' / 'worlds' / 'two_rooms.json'
INT, TERM = signal.SIGINT, signal.SIGTERM


class Probe:
    """A node in its own context that looks at the graph (and publishes, for the recorder)."""

    def __init__(self):
        self.context = rclpy.Context()
        rclpy.init(context=self.context)
        self.node = rclpy.create_node('shutdown_probe', context=self.context)
        self.executor = SingleThreadedExecutor(context=self.context)
        self.executor.add_node(self.node)

    def close(self):
        self.executor.shutdown()
        self.node.destroy_node()
        rclpy.try_shutdown(context=self.context)


@pytest.fixture
def probe():
    p = Probe()
    yield p
    p.close()


def send(proc, sequence, gap=0.005):
    """Send the signals of ``sequence`` ``gap`` seconds apart (as long as the process runs)."""
    for sig in sequence:
        if proc.poll() is not None:
            break
        os.kill(proc.pid, sig)
        time.sleep(gap)


def storm(proc, period=0.005, timeout=30.0):
    """SIGINT and SIGTERM in turn every ``period`` s until the process is gone; returns how
    many were sent."""
    sent, end = 0, time.monotonic() + timeout
    while proc.poll() is None and time.monotonic() < end:
        os.kill(proc.pid, (INT, TERM)[sent % 2])
        sent += 1
        time.sleep(period)
    return sent


def finished(node_proc, log, timeout=30.0):
    """Exit code of ``node_proc`` (killed if it hangs) and its output."""
    try:
        node_proc.proc.wait(timeout)
    except Exception:
        node_proc.kill()
    node_proc.kill()   # closes the log
    return node_proc.proc.returncode, Path(log).read_text(errors='replace')


def assert_clean(code, out):
    assert code == 0, out[-3000:]
    assert 'Traceback' not in out and 'KeyboardInterrupt' not in out, out[-3000:]


@pytest.mark.parametrize('sequence', [(INT, INT), (INT, TERM, INT), (TERM, TERM)],
                         ids=['terminal-ctrl-c', 'int-term-int', 'sigterm-twice'])
def test_node_exits_0_without_traceback_on_repeated_signals(tmp_path, probe, sequence):
    log = tmp_path / 'controller.log'
    node = NodeProcess('paramotion.smoke.controller_node', log_path=log)
    try:
        assert wait_until(lambda: node.proc.poll() is not None or 'smoke_controller' in
                          probe.node.get_node_names(), 60.0), log.read_text()
        time.sleep(0.5)
        send(node.proc, sequence)
        code, out = finished(node, log)
    finally:
        node.kill()
    assert_clean(code, out)


def test_simulator_exits_0_under_a_storm_of_signals(tmp_path, probe):
    """The coverage simulator (PyBullet, /clock, watchdog thread): signals keep coming during
    its whole clean-up."""
    log = tmp_path / 'sim.log'
    node = NodeProcess('coverage_pkg.sim_node', params={'world': str(WORLD)}, log_path=log)
    try:
        assert wait_until(lambda: node.proc.poll() is not None or
                          probe.node.count_publishers('/clock') > 0, 60.0), log.read_text()
        time.sleep(0.5)
        sent = storm(node.proc)
        code, out = finished(node, log)
    finally:
        node.kill()
    assert sent >= 2
    assert_clean(code, out)


class CliRecorder:
    """``paramotion bag record`` as a subprocess, with NodeProcess's interface."""

    def __init__(self, bag, log):
        self._log = open(log, 'wb')
        self.proc = subprocess.Popen(
            [sys.executable, '-m', 'paramotion.cli', 'bag', 'record', '-o', str(bag),
             '/test/chatter', '--flush-period', '0.2'], stdout=self._log,
            stderr=subprocess.STDOUT, start_new_session=True,
            preexec_fn=lambda: signal.signal(INT, signal.SIG_DFL))

    def kill(self):
        if self.proc.poll() is None:
            self.proc.kill()
            self.proc.wait()
        self._log.close()


@pytest.mark.parametrize('how', ['storm', 'sigterm', 'cli-storm'])
def test_recorder_finishes_its_bag_however_many_signals_arrive(tmp_path, probe, how):
    """Every message published (reliable) is in a complete bag (MCAP footer and
    metadata.yaml) that rosbags and the mcap library open: the bag_recorder node, and
    ``paramotion bag record``."""
    from mcap.reader import make_reader
    from rosbags.highlevel import AnyReader
    bag = tmp_path / 'bag'
    log = tmp_path / 'recorder.log'
    if how.startswith('cli'):
        rec = CliRecorder(bag, log)
    else:
        rec = NodeProcess('paramotion.bag.recorder_node', params={
            'output': str(bag), 'topics': ['/test/chatter'], 'flush_period': 0.2,
            'use_sim_time': False}, log_path=log)
    pub = probe.node.create_publisher(String, '/test/chatter', 10)
    try:
        assert wait_until(lambda: rec.proc.poll() is not None or
                          pub.get_subscription_count() > 0, 60.0), log.read_text()
        time.sleep(1.0)     # the recorder's side of the match settles too
        sent = 300
        for i in range(sent):
            pub.publish(String(data=f'msg {i}'))
            probe.executor.spin_once(timeout_sec=0.002)
        # Signal once the recorder has written them all (flushed chunks read back).
        assert wait_until(lambda: _readable(bag) >= sent, 30.0, period=0.1), _readable(bag)
        if how.endswith('storm'):
            signals = storm(rec.proc)
            assert signals >= 2
        else:
            send(rec.proc, (TERM,))
        code, out = finished(rec, log)
    finally:
        rec.kill()
    assert_clean(code, out)
    info = bag_info(bag)
    assert info.complete, info.problem
    meta = yaml.safe_load((bag / 'metadata.yaml').read_text())['rosbag2_bagfile_information']
    assert meta['message_count'] == sent
    with AnyReader([bag]) as reader:
        got = [reader.deserialize(raw, c.msgtype).data for c, _, raw in reader.messages()]
    assert got == [f'msg {i}' for i in range(sent)]
    with open(next(bag.glob('*.mcap')), 'rb') as f:
        assert make_reader(f).get_summary().statistics.message_count == sent
    assert [m.data for m in read_messages(bag)]     # our own reader agrees it is readable


def test_a_node_started_with_sigint_ignored_keeps_ignoring_it(tmp_path, probe):
    """A shell without job control starts background jobs with SIGINT ignored so that a Ctrl-C
    meant for the foreground leaves them running: the node keeps it ignored (rclpy too), and
    stops cleanly on SIGTERM."""
    log = tmp_path / 'controller.log'
    out = open(log, 'wb')
    proc = subprocess.Popen([sys.executable, '-m', 'paramotion.smoke.controller_node'],
                            stdout=out, stderr=subprocess.STDOUT, start_new_session=True,
                            preexec_fn=lambda: signal.signal(INT, signal.SIG_IGN))
    try:
        assert wait_until(lambda: proc.poll() is not None or 'smoke_controller' in
                          probe.node.get_node_names(), 60.0), log.read_text()
        time.sleep(0.5)
        send(proc, (INT, INT))
        time.sleep(2.0)
        assert proc.poll() is None, log.read_text()
        assert 'smoke_controller' in probe.node.get_node_names()
        send(proc, (TERM,))
        proc.wait(30)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
        out.close()
    assert_clean(proc.returncode, log.read_text())


def _readable(bag):
    if not any(Path(bag).glob('*.mcap')):
        return 0
    try:
        return len(read_messages(bag, ['/test/chatter']))
    except Exception:   # a chunk being written
        return 0


def _signalled_process(tmp_path, report_s, cleanup):
    """Run a process that installs the node signal policy with ``HANG_REPORT_S`` =
    ``report_s``, signals itself once while spinning, runs ``cleanup`` (Python source of a
    function body) and exits 0; returns its completed run (stderr captured)."""
    script = tmp_path / 'signalled.py'
    script.write_text(
        'import os, signal, time\n'
        'import paramotion.shutdown as s\n'
        f's.HANG_REPORT_S = {report_s}\n'
        'signals = s.ShutdownSignals().install()\n'
        'signals.spinning()\n'
        'def stuck_in_cleanup():\n'
        f'    {cleanup}\n'
        'os.kill(os.getpid(), signal.SIGINT)\n'
        'stuck_in_cleanup()\n'
        'signals.finish()\n'
        's.exit_now(0)\n')
    return subprocess.run([sys.executable, str(script)], capture_output=True, text=True,
                          timeout=60)


def test_a_process_still_alive_after_a_signal_prints_where_its_threads_are(tmp_path):
    """A clean-up that hangs (here: a sleep standing in for a stuck call) prints the stack of
    each thread before launch escalates, so a hang in the field says where it is."""
    done = _signalled_process(tmp_path, 0.5, 'time.sleep(1.5)')
    assert done.returncode == 0, done.stderr
    assert 'Timeout (0:00:00.500000)!' in done.stderr, done.stderr
    assert 'stuck_in_cleanup' in done.stderr, done.stderr


def test_a_process_that_stops_in_time_prints_no_stacks(tmp_path):
    done = _signalled_process(tmp_path, 1.0, 'time.sleep(0.2)')
    assert done.returncode == 0 and done.stderr == '', done.stderr


def test_a_teardown_stuck_holding_the_interpreter_lock_ends_with_exit_0(tmp_path):
    """The middleware teardown after a signal is bounded even when the stuck call holds the
    interpreter lock (here a C ``sleep`` called without releasing it, as a C++ call into
    rcl/DDS does): stacks, one line saying so, exit 0, well before launch escalates (5 s)."""
    started = time.monotonic()
    done = _signalled_process(
        tmp_path, 4.5, "with s.bounded_middleware_teardown('probe_node'): "
        'import ctypes; ctypes.PyDLL(None).sleep(30); print("not reached")')
    took = time.monotonic() - started
    assert done.returncode == 0, done.stderr
    assert 'probe_node: the middleware teardown' in done.stdout, done.stdout
    assert 'not reached' not in done.stdout
    assert 'stuck_in_cleanup' in done.stderr, done.stderr
    assert took < 4.5 + 0.5 * s.TEARDOWN_LIMIT_S, took


@pytest.mark.parametrize('signalled', [False, True], ids=['no-signal', 'teardown-in-time'])
def test_the_teardown_limit_holds_only_while_a_signalled_teardown_runs(tmp_path, signalled):
    """Without a signal (a node that ends on its own, a test) nothing is armed; after a signal,
    a teardown that ends in time disarms it. Either way what follows the teardown (longer than
    the limit here) runs to its end."""
    script = tmp_path / 'teardown.py'
    script.write_text(
        'import os, signal, time\n'
        'import paramotion.shutdown as s\n'
        's.ShutdownSignals().install().spinning()\n'
        + ('os.kill(os.getpid(), signal.SIGINT)\n' if signalled else '')
        + "with s.bounded_middleware_teardown('probe_node'):\n"
        '    time.sleep(0.2)\n'
        f'time.sleep({s.TEARDOWN_LIMIT_S + 0.5})\n'
        "print('reached')\n")
    done = subprocess.run([sys.executable, str(script)], capture_output=True, text=True,
                          timeout=60)
    assert done.returncode == 0 and done.stdout == 'reached\n', done.stdout + done.stderr
    assert done.stderr == ''


def test_a_node_process_bounds_its_middleware_teardown_after_ctrl_c(tmp_path):
    """Through ``run_node``: a node whose rclpy teardown never returns (a C call holding the
    interpreter lock after rcl's, standing in for a Fast DDS participant deletion that
    blocks for good) still exits 0 within the limit after a terminal Ctrl-C, saying
    why."""
    script = tmp_path / 'stuck_node.py'
    script.write_text(
        'import ctypes\n'
        'import rclpy.node\n'
        'from paramotion.node import ParamotionNode, run_node\n'
        'rcl_teardown = rclpy.node.Node.destroy_node\n'
        'def teardown_that_never_returns(node):\n'
        '    rcl_teardown(node)\n'
        '    while True:  # a later signal ends a C sleep early: sleep again\n'
        '        ctypes.PyDLL(None).sleep(60)\n'
        'rclpy.node.Node.destroy_node = teardown_that_never_returns\n'
        'class StuckTeardownNode(ParamotionNode):\n'
        '    USE_SIM_TIME_DEFAULT = False\n'
        '    def __init__(self):\n'
        "        super().__init__('stuck_teardown', parameter_overrides=[])\n"
        '        self.timer = self.create_timer(0.05, self.spinning)\n'
        '    def spinning(self):\n'
        "        print('spinning', flush=True)\n"
        '        self.timer.cancel()\n'
        'run_node(StuckTeardownNode)\n')
    log = tmp_path / 'stuck.log'
    with open(log, 'w') as out:
        proc = subprocess.Popen([sys.executable, str(script)], stdout=out,
                                stderr=subprocess.STDOUT, start_new_session=True)
        try:
            assert wait_until(lambda: proc.poll() is not None or 'spinning' in
                              log.read_text(), 60.0), log.read_text()
            started = time.monotonic()
            send(proc, (INT, INT))
            proc.wait(30)
            took = time.monotonic() - started
        finally:
            if proc.poll() is None:
                proc.kill()
                proc.wait()
    text = log.read_text()
    assert_clean(proc.returncode, text)
    assert 'stuck_teardown: the middleware teardown' in text, text
    assert took < s.HANG_REPORT_S, (took, text)


@pytest.mark.parametrize('sig', [INT, TERM], ids=['ctrl-c', 'sigterm'])
def test_a_signal_while_a_node_imports_its_module_ends_it_quietly(tmp_path, sig):
    """A node executable (``paramotion.start``) stopped while it still imports its module (here
    one whose import takes 30 s) exits 0 with nothing printed, not with an import traceback."""
    (tmp_path / 'slow_node.py').write_text(
        'import time\n'
        'print("importing", flush=True)\n'
        'time.sleep(30)\n'
        'def main():\n'
        '    print("main ran")\n')
    proc = subprocess.Popen(
        [sys.executable, '-c', 'import paramotion.start as s; s.load("slow_node")()'],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
        env={**os.environ, 'PYTHONPATH': f'{tmp_path}{os.pathsep}' + os.environ.get(
            'PYTHONPATH', '')})
    try:
        assert proc.stdout.readline() == 'importing\n'
        os.kill(proc.pid, sig)
        out, err = proc.communicate(timeout=20)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    assert proc.returncode == 0 and out == '' and err == '', (proc.returncode, out, err)


def test_a_ctrl_c_while_pybullet_connects_leaves_no_ignored_error(monkeypatch):
    """A KeyboardInterrupt inside ``pybullet.connect`` (a Ctrl-C while the simulator node starts
    its physics client) propagates, and collecting the half-made client reports nothing (plain
    ``BulletClient``'s ``__del__`` raises an ``AttributeError`` there, printed as ignored)."""
    import gc

    import pybullet

    from paramotion.sim import bullet_client

    def interrupted(*args, **kwargs):
        raise KeyboardInterrupt

    unraisable = []
    monkeypatch.setattr(sys, 'unraisablehook', unraisable.append)
    monkeypatch.setattr(pybullet, 'connect', interrupted)
    with pytest.raises(KeyboardInterrupt):
        bullet_client()
    gc.collect()
    assert unraisable == []
    monkeypatch.undo()
    client = bullet_client()
    assert client.getConnectionInfo()['isConnected'] == 1
    client.disconnect()


_SCRIPT_PARENT = """
import subprocess, sys, time
from paramotion.launch import child_setup
child = subprocess.Popen([sys.executable, '-c', 'import time; time.sleep(60)'],
                         preexec_fn=child_setup(die_with_parent=%s), start_new_session=True)
print(child.pid, flush=True)
time.sleep(60)
"""


def _alive(pid):
    """The process exists and is not a zombie."""
    try:
        with open(f'/proc/{pid}/stat') as f:
            return f.read().split(')')[-1].split()[0] != 'Z'
    except FileNotFoundError:
        return False


@pytest.mark.skipif(not sys.platform.startswith('linux'), reason='PR_SET_PDEATHSIG is Linux')
@pytest.mark.parametrize('die_with_parent', [True, False])
def test_a_script_killed_leaves_no_node_of_its_own_session_running(die_with_parent):
    """A benchmark or test starts nodes in sessions of their own (no terminal Ctrl-C reaches
    them) and stops them in a ``finally``, which a SIGKILL or SIGTERM skips. With
    ``die_with_parent`` the nodes get SIGINT when the script dies; without it (a launcher's
    nodes, as under ``ros2 launch``) they go on running."""
    parent = subprocess.Popen([sys.executable, '-c', _SCRIPT_PARENT % die_with_parent],
                              stdout=subprocess.PIPE, text=True)
    child = int(parent.stdout.readline())
    try:
        assert _alive(child)
        parent.kill()
        parent.wait(10)
        gone = wait_until(lambda: not _alive(child), 5.0)
        assert gone == die_with_parent
    finally:
        if _alive(child):
            os.kill(child, signal.SIGKILL)
        parent.stdout.close()
