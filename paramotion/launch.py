"""Run a launch file's nodes: one process per node (``paramotion launch``), or composed in one
Graph (the scenario runners); and the older :class:`NodeProcess` helper.

``paramotion launch FILE|NAME [name:=value ...]`` does what ``ros2 launch`` does with the XML
that :mod:`paramotion.launch_xml` reads (``launch_ros`` is not installable here): it starts each
``<node>`` through its installed executable (the console script ``ros2 run`` would run) as
``EXEC --ros-args -r __node:=NAME -p k:=v -r from:=to``, prefixes every line a process prints
with ``[EXEC-N]``, and on Ctrl-C (SIGINT) or SIGTERM interrupts every process, escalating to
SIGTERM and then SIGKILL after timeouts. As under ``ros2 launch``, the node processes share the
launcher's process group, so a terminal Ctrl-C reaches each node twice (from the terminal and
from the launcher); every process's exit is reported (``process has finished cleanly`` or
``process has died [..., exit code N]``) and a node that does not exit 0 when stopped makes the
launch exit 1. A node that dies stops the launch with a non-zero exit naming it, unless it has
``respawn="true"`` (restarted after ``respawn_delay`` seconds). Before anything starts, a
missing executable or a parameter the node does not declare is refused with one line.
"""
from __future__ import annotations

import argparse
import faulthandler
import importlib
import inspect
import os
import shutil
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Any, Self, TypeVar

from paramotion.launch_xml import (
    PACKAGE,
    LaunchDescription,
    LaunchError,
    NodeAction,
    ParamValue,
    load,
    recorded_topics,
)

if TYPE_CHECKING:
    from rclpy.node import Node

    from paramotion.graph import Graph

_T = TypeVar('_T')

# --------------------------------------------------------------------------- executables


def format_param(value: object) -> str:
    """Render a parameter value for ``-p name:=value`` (YAML syntax, as ros2 run expects)."""
    if isinstance(value, bool):
        return 'true' if value else 'false'
    if isinstance(value, (list, tuple)):
        return '[' + ','.join(format_param(v) for v in value) + ']'
    if isinstance(value, str):
        return "'" + value.replace("'", "''") + "'"
    return repr(value)


def console_scripts() -> dict[str, str]:
    """paramotion's node executables: name -> 'module:main' (:data:`paramotion.start.NODES`,
    which setup.py registers as console scripts)."""
    from paramotion.start import NODES
    return {name: f'{module}:main' for name, module in NODES.items()}


def node_class(executable: str) -> type[Node]:
    """The node class that executable ``executable`` runs (its module's one node class)."""
    from rclpy.node import Node
    target = console_scripts().get(executable)
    if target is None:
        raise LaunchError(f"executable '{executable}' is not a node of package '{PACKAGE}' "
                          f'(known: {", ".join(sorted(console_scripts()))})')
    module = importlib.import_module(target.partition(':')[0])
    found = [c for _, c in inspect.getmembers(module, inspect.isclass)
             if issubclass(c, Node) and c.__module__ == module.__name__]
    leaves = [c for c in found if not any(o is not c and issubclass(o, c) for o in found)]
    if len(leaves) != 1:
        raise LaunchError(f"executable '{executable}': module {module.__name__} defines "
                          f'{len(leaves)} node classes, expected one')
    return leaves[0]


def find_executable(package: str, executable: str) -> str:
    """Path of ``executable`` of ``package`` as ``ros2 run`` finds it: ``lib/<package>/`` under
    each ament prefix, then (for paramotion's own console scripts) the Python environment's
    scripts directory, where ``pip install`` puts them. LaunchError (one line) if missing."""
    looked = []
    prefixes = [p for p in os.environ.get('AMENT_PREFIX_PATH', '').split(os.pathsep) if p]
    for prefix in prefixes + [sys.prefix]:
        candidate = Path(prefix) / 'lib' / package / executable
        looked.append(str(candidate.parent))
        if candidate.is_file() and os.access(candidate, os.X_OK):
            return str(candidate)
    if package == PACKAGE and executable in console_scripts():
        for d in dict.fromkeys([Path(sys.executable).parent,
                                Path(sys.prefix) / 'bin']):
            candidate = d / executable
            looked.append(str(d))
            if candidate.is_file() and os.access(candidate, os.X_OK):
                return str(candidate)
        which = shutil.which(executable)
        if which:
            return which
    raise LaunchError(f"executable '{executable}' of package '{package}' not found (looked in "
                      f"{', '.join(dict.fromkeys(looked))})")


def check_parameters(desc: LaunchDescription) -> None:
    """Refuse, with one line, a ``<param>`` that the node does not declare."""
    for action in desc.nodes:
        if action.package != PACKAGE:
            continue
        cls = node_class(action.executable)
        declared = {p.name for p in getattr(cls, 'PARAMS', ())} | {
            'use_sim_time', 'start_type_description_service'}
        for name in action.params:
            if name not in declared and not name.startswith('qos_overrides.'):
                raise LaunchError(
                    f"{action.where}: node '{action.label}' ({action.executable}) has no "
                    f"parameter '{name}' (declared: "
                    f"{', '.join(p.name for p in getattr(cls, 'PARAMS', ()))})")


def node_command(action: NodeAction, executable_path: str) -> list[str]:
    """The command line that starts ``action`` (a launch_xml.NodeAction)."""
    cmd = [executable_path] + list(action.args) + ['--ros-args']
    if action.name:
        cmd += ['-r', f'__node:={action.name}']
    if action.namespace:
        ns = action.namespace if action.namespace.startswith('/') else '/' + action.namespace
        cmd += ['-r', f'__ns:={ns}']
    for key, value in action.params.items():
        cmd += ['-p', f'{key}:={format_param(value)}']
    for src, dst in action.remaps:
        cmd += ['-r', f'{src}:={dst}']
    return cmd + list(action.ros_args)


# --------------------------------------------------------------------------- one process
def compose(graph: Graph, desc: LaunchDescription,
            extra_params: dict[str, dict[str, Any]] | None = None) -> dict[str, Node]:
    """Add the launch description's nodes to ``graph`` (one process, one executor), in file
    order, with their parameters, names, namespaces and remappings; returns {label: node}.

    ``extra_params`` maps a node label to further parameter overrides (test fixtures and
    scenario options beyond the launch arguments). The recorder is left to the caller
    (``Graph.record``), which checks that every recorded topic has a publisher.
    """
    check_parameters(desc)
    extra = dict(extra_params or {})
    nodes = {}
    for action in desc.nodes:
        if action.executable == 'bag_recorder':
            continue
        params = {**action.params, **(extra.pop(action.label, None) or {})}
        nodes[action.label] = graph.add(
            node_class(action.executable), name=action.name or None,
            namespace=action.namespace or None, remappings=dict(action.remaps), **params)
    if extra:
        raise LaunchError(f"{desc.path}: no node named '{sorted(extra)[0]}'")
    return nodes


def graph_from_launch(graph: Graph, name: str, launch_args: dict[str, object] | None = None,
                      extra_params: dict[str, dict[str, Any]] | None = None
                      ) -> tuple[dict[str, Node], list[str]]:
    """Read launch file ``name`` with ``launch_args`` plus ``lockstep:=true`` and
    ``record:=true`` and compose its nodes in ``graph``: the scenario runners' one-process
    version of the graph. Returns ({label: node}, recorded topics)."""
    args = {'lockstep': True, 'record': True, **(launch_args or {})}
    desc = load(name, args)
    return compose(graph, desc, extra_params), recorded_topics(desc)


# --------------------------------------------------------------------------- processes
def _sigint_default():
    """Child set-up: SIGINT back to its default (see :func:`child_setup`)."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def _die_with(parent: int, sigint_default: bool) -> Callable[[], None]:
    """Child set-up: SIGINT when the process that started this one dies (Linux
    ``PR_SET_PDEATHSIG``); SIGINT at its default first when ``sigint_default``."""
    def setup() -> None:
        if sigint_default:
            _sigint_default()
        if sys.platform.startswith('linux'):
            import ctypes
            ctypes.CDLL(None, use_errno=True).prctl(1, int(signal.SIGINT))  # PR_SET_PDEATHSIG
        if os.getppid() != parent:                  # it died before the set-up
            os.kill(os.getpid(), signal.SIGINT)
    return setup


def child_setup(die_with_parent: bool = False) -> Callable[[], None] | None:
    """``preexec_fn`` for a node process: none, unless this process ignores SIGINT (started as
    a background job by a shell without job control). A node inherits an ignored SIGINT and
    then rightly keeps ignoring it; a launcher is the node's terminal, so its nodes start with
    SIGINT at its default, as under ``ros2 launch``.

    ``die_with_parent``: the node also gets SIGINT when this process dies, however it dies
    (SIGTERM, SIGKILL). For nodes in a session of their own that a script starts and stops
    (a benchmark, a test), which no terminal Ctrl-C reaches: a killed script leaves no graph
    running. A launcher's nodes do not have it, as under ``ros2 launch``."""
    sigint_default = signal.getsignal(signal.SIGINT) == signal.SIG_IGN
    if die_with_parent:
        return _die_with(os.getpid(), sigint_default)
    return _sigint_default if sigint_default else None


class _Proc:
    """One launched node process (restarted in place when it respawns)."""

    def __init__(self, action, label, cmd, env, echo, log_dir, own_session=False):
        self.action, self.label, self.cmd, self.env = action, label, cmd, env
        self.echo = echo
        self.own_session = own_session
        self.log = open(Path(log_dir) / f'{label}.log', 'a') if log_dir else None
        self.popen = None
        self.respawn_at = None
        self.handled = False
        self.threads = []

    def start(self):
        self.handled = False
        self.popen = subprocess.Popen(self.cmd, env=self.env, stdout=subprocess.PIPE,
                                      stderr=subprocess.PIPE, preexec_fn=child_setup(),
                                      start_new_session=self.own_session)
        self.threads = [threading.Thread(target=self._pump, args=(stream, show), daemon=True)
                        for stream, show in ((self.popen.stdout,
                                              self.action.output in ('screen', 'both')),
                                             (self.popen.stderr, True))]
        for t in self.threads:
            t.start()
        self.echo(f'[INFO] [{self.label}]: process started with pid [{self.popen.pid}]')

    def _pump(self, stream, show):
        for raw in iter(stream.readline, b''):
            line = raw.decode(errors='replace').rstrip('\n')
            if self.log is not None:
                self.log.write(line + '\n')
                self.log.flush()
            if show:
                self.echo(f'[{self.label}] {line}')
        stream.close()

    def running(self):
        return self.popen is not None and self.popen.poll() is None

    def signal(self, sig):
        """Send ``sig`` to this node's process (its whole session if it has one of its own)."""
        if self.running():
            try:
                if self.own_session:
                    os.killpg(self.popen.pid, sig)
                else:
                    self.popen.send_signal(sig)
            except ProcessLookupError:
                pass

    def report_exit(self):
        """Say how the process ended, as ros2 launch does."""
        code = self.popen.returncode
        if code == 0:
            self.echo(f'[INFO] [{self.label}]: process has finished cleanly '
                      f'[pid {self.popen.pid}]')
        else:
            self.echo(f'[ERROR] [{self.label}]: process has died [pid {self.popen.pid}, exit '
                      f"code {code}, cmd '{' '.join(self.cmd)}']")

    def join_output(self, timeout=2.0):
        for t in self.threads:
            t.join(timeout)


class Launcher:
    """Start, watch and stop the processes of a launch description.

    ``start()`` checks everything first (executables, parameters), then starts the nodes in
    file order; ``poll()`` handles exits (respawn, or failure naming the node) and returns
    False once the launch is over; ``shutdown()`` interrupts and reaps every process.
    ``failed`` names the node that died, if one did; ``unclean`` lists the nodes that did not
    exit 0 when stopped. With ``own_sessions`` each node runs in a session of its own (a
    terminal Ctrl-C then reaches only the launcher); by default they share the launcher's
    process group, as under ``ros2 launch``.
    """

    def __init__(self, desc: LaunchDescription, echo: Callable[[str], None] | None = None,
                 log_dir: str | os.PathLike[str] | None = None, sigterm_timeout: float = 5.0,
                 sigkill_timeout: float = 5.0, env: dict[str, str] | None = None,
                 own_sessions: bool = False) -> None:
        self.desc = desc
        self.echo_lock = threading.Lock()
        self._echo = echo or self._print
        self.log_dir = log_dir
        self.sigterm_timeout, self.sigkill_timeout = sigterm_timeout, sigkill_timeout
        self.env = {**os.environ, **(env or {}), 'PYTHONUNBUFFERED': '1'}
        self.procs = []
        self.failed = None
        self.unclean = []
        self.stopping = False
        self.own_sessions = own_sessions

    def _print(self, line):
        print(line, flush=True)

    def echo(self, line: str) -> None:
        """Print ``line`` (one process's lines never interleave with another's)."""
        with self.echo_lock:
            self._echo(line)

    def prepare(self) -> Self:
        """Resolve every executable and check every parameter; nothing starts on error."""
        paths = []
        for a in self.desc.nodes:
            try:
                paths.append(find_executable(a.package, a.executable))
            except LaunchError as exc:
                raise LaunchError(f"{a.where}: node '{a.label}': {exc}") from None
        check_parameters(self.desc)
        if self.log_dir:
            Path(self.log_dir).mkdir(parents=True, exist_ok=True)
        counts = {}
        for k, (action, path) in enumerate(zip(self.desc.nodes, paths), start=1):
            base = Path(action.executable).name
            counts[base] = counts.get(base, 0) + 1
            self.procs.append(_Proc(action, f'{base}-{k}', node_command(action, path),
                                    {**self.env, **action.env}, self.echo, self.log_dir,
                                    own_session=self.own_sessions))
        return self

    def start(self) -> Self:
        """Start every node in file order (preparing first if needed)."""
        if not self.procs:
            self.prepare()
        for p in self.procs:
            p.start()
        return self

    def poll(self) -> bool:
        """Handle exited processes; False when the launch is over (all gone or one died)."""
        now = time.monotonic()
        alive = False
        for p in self.procs:
            if p.respawn_at is not None:
                if now >= p.respawn_at and not self.stopping:
                    p.respawn_at = None
                    self.echo(f'[INFO] [{p.label}]: respawning')
                    p.start()
                alive = True
                continue
            code = p.popen.poll()
            if code is None:
                alive = True
                continue
            if p.handled:
                continue
            p.handled = True
            p.join_output()
            if self.stopping:
                continue
            p.report_exit()
            if p.action.respawn:
                p.respawn_at = now + p.action.respawn_delay
                alive = True
            elif code != 0 and self.failed is None:
                self.failed = p
        return alive and self.failed is None

    def shutdown(self) -> dict[str, int]:
        """SIGINT every process; SIGTERM after ``sigterm_timeout``, SIGKILL after
        ``sigkill_timeout`` more. Reports each exit; returns {label: exit code}."""
        self.stopping = True
        stopped = [p for p in self.procs if p.popen is not None and not p.handled]
        for sig, timeout in ((signal.SIGINT, self.sigterm_timeout),
                             (signal.SIGTERM, self.sigkill_timeout), (signal.SIGKILL, 10.0)):
            running = [p for p in self.procs if p.running()]
            if not running:
                break
            if sig != signal.SIGINT:
                self.echo(f'[WARNING] [launch]: sending {sig.name} to '
                          f"{', '.join(p.label for p in running)}")
            for p in running:
                p.signal(sig)
            end = time.monotonic() + timeout
            while time.monotonic() < end and any(p.running() for p in running):
                time.sleep(0.02)
        codes = {}
        for p in self.procs:
            if p.popen is not None:
                p.popen.wait()
                p.join_output()
                codes[p.label] = p.popen.returncode
                if p in stopped:
                    p.handled = True
                    p.report_exit()
                    if p.popen.returncode != 0:
                        self.unclean.append(p)
            if p.log is not None:
                p.log.close()
        return codes

    def failure_message(self) -> str | None:
        """One line naming the node that died while the launch ran, or None."""
        p = self.failed
        if p is not None:
            return (f"node '{p.action.label}' ({p.label}) died with exit code "
                    f'{p.popen.returncode}')
        return None

    def unclean_message(self) -> str | None:
        """One line naming the nodes that did not exit 0 when stopped, or None."""
        if self.unclean:
            return 'stopped, but not cleanly: ' + ', '.join(
                f"node '{p.action.label}' ({p.label}) exited with code {p.popen.returncode}"
                for p in self.unclean)
        return None


def run(desc: LaunchDescription, log_dir: str | os.PathLike[str] | None = None,
        period: float = 0.05) -> int:
    """``paramotion launch``: start, watch until Ctrl-C/SIGTERM or a node dies, stop.

    Returns 0 after a requested stop where every node exited 0, 1 if a node died or did not
    stop cleanly (the message names it)."""
    launcher = Launcher(desc, log_dir=log_dir).prepare()
    stop = threading.Event()
    previous = {}

    def on_signal(signum, frame):
        if stop.is_set():          # second Ctrl-C: go straight to the escalation
            launcher.sigterm_timeout = 0.0
        stop.set()
    for sig in (signal.SIGINT, signal.SIGTERM):
        previous[sig] = signal.signal(sig, on_signal)
    faulthandler.register(signal.SIGUSR1, all_threads=True)   # kill -USR1: where it is
    try:
        launcher.start()
        while not stop.wait(period):
            if not launcher.poll():
                break
        if stop.is_set():
            launcher.echo('[WARNING] [launch]: user interrupted with ctrl-c (SIGINT)')
    finally:
        launcher.shutdown()
        for sig, handler in previous.items():
            signal.signal(sig, handler)
    message = launcher.failure_message() or launcher.unclean_message()
    if message:
        print(f'paramotion launch: error: {message}', file=sys.stderr, flush=True)
        return 1
    return 0


# --------------------------------------------------------------------------- CLI
def _cli(args):
    from paramotion import launch_xml
    items = list(args.items)
    if len(items) >= 2 and items[0] == PACKAGE and ':=' not in items[1]:
        items = items[1:]  # ros2 launch form: paramotion launch paramotion coverage.launch.xml
    if not items or ':=' in items[0]:
        raise LaunchError('expected a launch file or name first (e.g. coverage)')
    launch_args = launch_xml.parse_cli_args(items[1:])
    if args.show_args:
        path = launch_xml.find_launch_file(items[0])
        desc = launch_xml.load(path, {})
        print(f'Arguments of {path} (pass arguments as <name>:=<value>):')
        for decl in desc.args.values():
            print(f"    '{decl.name}':")
            print(f'        {decl.description or "no description given"}')
            if decl.choices:
                print(f'        Valid choices are: {list(decl.choices)}')
            print(f"        (default: '{decl.default}')" if decl.default is not None
                  else '        (required)')
        return 0
    desc = launch_xml.load(items[0], launch_args)
    if args.print:
        launcher = Launcher(desc).prepare()
        for p in launcher.procs:
            print(f'[{p.label}] ' + ' '.join(p.cmd))
        return 0
    return run(desc, log_dir=args.log_dir)


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add ``paramotion launch``."""
    parser = subparsers.add_parser(
        'launch', help='start a launch file, one process per node (like ros2 launch)',
        description='Start the nodes of a ROS 2 XML launch file (a path, or one of the '
        'packaged ones by name: coverage, climber, fast, workspace, voronoi), each in its own '
        'process; Ctrl-C stops them all.')
    parser.add_argument('items', nargs='+', metavar='FILE|NAME [name:=value ...]',
                        help='launch file or name, then launch arguments')
    parser.add_argument('-s', '--show-args', action='store_true',
                        help="show the launch file's arguments and exit")
    parser.add_argument('-p', '--print', action='store_true',
                        help='print the command of every process and exit')
    parser.add_argument('--log-dir', default=None,
                        help='also write each process output to LOG_DIR/<process>.log')
    parser.set_defaults(func=_cli)


# --------------------------------------------------------------------------- older helper
class NodeProcess:
    """One node running in a child process (``python -m module``), output to a log file."""

    def __init__(self, module: str, name: str | None = None,
                 params: dict[str, ParamValue] | None = None,
                 remap: dict[str, str] | None = None, env: dict[str, str] | None = None,
                 log_path: str | os.PathLike[str] | None = None) -> None:
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
                                     preexec_fn=child_setup(die_with_parent=True),
                                     start_new_session=True)

    def interrupt(self, timeout: float = 10.0) -> int | None:
        """SIGINT (clean shutdown), then SIGKILL if it does not exit within ``timeout``."""
        if self.proc.poll() is None:
            os.killpg(self.proc.pid, signal.SIGINT)
            try:
                self.proc.wait(timeout)
            except subprocess.TimeoutExpired:
                self.kill()
        self._close_log()
        return self.proc.returncode

    def kill(self) -> None:
        """SIGKILL, no clean-up (simulates a crashed process)."""
        if self.proc.poll() is None:
            os.killpg(self.proc.pid, signal.SIGKILL)
            self.proc.wait()
        self._close_log()

    def _close_log(self):
        if self._log not in (None, subprocess.DEVNULL):
            self._log.close()
            self._log = None


def wait_until(predicate: Callable[[], _T], timeout: float, period: float = 0.05) -> _T | bool:
    """Poll ``predicate`` until true or ``timeout`` seconds pass; returns its last value."""
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        if predicate():
            return True
        time.sleep(period)
    return predicate()
