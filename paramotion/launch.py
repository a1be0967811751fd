"""Start nodes as separate processes (what ``ros2 launch`` would do; launch_ros is not on PyPI).

Each node runs ``python -m <module> --ros-args -r __node:=<name> -p name:=value ...`` in its own
process group so that it can be interrupted (SIGINT, like Ctrl-C) and, if it hangs, killed.
"""
import os
import signal
import subprocess
import sys
import time


def format_param(value):
    """Render a parameter value for ``-p name:=value`` (YAML syntax, as ros2 run expects)."""
    if isinstance(value, bool):
        return 'true' if value else 'false'
    if isinstance(value, (list, tuple)):
        return '[' + ','.join(format_param(v) for v in value) + ']'
    if isinstance(value, str):
        return "'" + value.replace("'", "''") + "'"
    return repr(value)


class NodeProcess:
    """One node running in a child process."""

    def __init__(self, module, name=None, params=None, remap=None, env=None, log_path=None):
        args = [sys.executable, '-m', module, '--ros-args']
        if name:
            args += ['-r', f'__node:={name}']
        for src, dst in (remap or {}).items():
            args += ['-r', f'{src}:={dst}']
        for key, value in (params or {}).items():
            args += ['-p', f'{key}:={format_param(value)}']
        self.module = module
        self.args = args
        self._log = open(log_path, 'wb') if log_path else subprocess.DEVNULL
        self.proc = subprocess.Popen(args, env={**os.environ, **(env or {})},
                                     stdout=self._log, stderr=subprocess.STDOUT,
                                     start_new_session=True)

    def interrupt(self, timeout=10.0):
        """SIGINT (clean shutdown), then SIGKILL if it does not exit within ``timeout``."""
        if self.proc.poll() is None:
            os.killpg(self.proc.pid, signal.SIGINT)
            try:
                self.proc.wait(timeout)
            except subprocess.TimeoutExpired:
                self.kill()
        self._close_log()
        return self.proc.returncode

    def kill(self):
        """SIGKILL, no clean-up (simulates a crashed process)."""
        if self.proc.poll() is None:
            os.killpg(self.proc.pid, signal.SIGKILL)
            self.proc.wait()
        self._close_log()

    def _close_log(self):
        if self._log not in (None, subprocess.DEVNULL):
            self._log.close()
            self._log = None


def wait_until(predicate, timeout, period=0.05):
    """Poll ``predicate`` until true or ``timeout`` seconds pass; returns its last value."""
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        if predicate():
            return True
        time.sleep(period)
    return predicate()
