"""Entry point of every node executable: ``ros2 run paramotion fast_sim`` calls
``paramotion.start:fast_sim``, which imports the node's module and runs its ``main()``.

:data:`NODES` is the one table of node executables (``setup.py`` reads it to register the
console scripts). The indirection is for the seconds a node spends importing its module
(rclpy, NumPy, SciPy, PyBullet: 1-3 s, over 10 s on a loaded 2-core machine) before
:func:`paramotion.node.run_node` takes over SIGINT and SIGTERM. A terminal Ctrl-C in that time
would otherwise print a ``KeyboardInterrupt`` traceback from deep inside an import and end the
process with -2 (launch's SIGTERM with -15); here either ends it quietly with status 0, as
once the node runs. This module imports nothing but the standard library, so that the window
it cannot cover is as short as Python's own start-up.
"""
from __future__ import annotations

import importlib
import os
import signal
import sys
from collections.abc import Callable
from typing import NoReturn

#: Node executable -> module whose ``main()`` runs it.
NODES: dict[str, str] = {
    # Shared / smoke graph (paramotion/)
    'smoke_sim': 'paramotion.smoke.sim_node',
    'smoke_range_sensor': 'paramotion.smoke.range_sensor_node',
    'smoke_controller': 'paramotion.smoke.controller_node',
    'bag_recorder': 'paramotion.bag.recorder_node',
    'bag_player': 'paramotion.bag.player_node',
    # coverage_pkg
    'coverage_sim': 'coverage_pkg.sim_node',
    'coverage_sonar': 'coverage_pkg.sonar_node',
    'coverage_planner': 'coverage_pkg.planner_node',
    'coverage_monitor': 'coverage_pkg.monitor_node',
    # climber_pkg
    'climber_sim': 'climber_pkg.sim_node',
    'climber_ultrasonic': 'climber_pkg.ultrasonic_node',
    'climber_planner': 'climber_pkg.planner_node',
    # cable_robot_pkg: FAST
    'fast_sim': 'cable_robot_pkg.fast.sim_node',
    'fast_tracker': 'cable_robot_pkg.fast.optical_tracker_node',
    'fast_trajectory': 'cable_robot_pkg.fast.feed_trajectory_node',
    'fast_cable_controller': 'cable_robot_pkg.fast.cable_pid_node',
    'fast_isolation_controller': 'cable_robot_pkg.fast.isolation_node',
    'fast_control_container': 'cable_robot_pkg.fast.control_container_node',
    # cable_robot_pkg: KNTU workspace
    'workspace_monitor': 'cable_robot_pkg.cdrpm.workspace_monitor_node',
    # voronoi_pkg: Gough-Stewart simplified Voronoi planner
    'voronoi_planner': 'voronoi_pkg.planner_node',
}


class _StopDuringImport(BaseException):
    """SIGTERM while the node's module is imported (SIGINT raises KeyboardInterrupt)."""


_received: list[int] = []   # signals that arrived while the node's module was imported


def _stop_import(signum, frame):
    _received.append(signum)
    raise KeyboardInterrupt if signum == signal.SIGINT else _StopDuringImport


def load(module: str) -> Callable[[], object]:
    """Import ``module`` and return its ``main``; a SIGINT or SIGTERM during the import ends
    the process quietly with status 0. The exception the signal raises can be swallowed where
    it lands (Python ignores exceptions in some import-machinery callbacks) or turned into
    another (an extension module's initialisation), so whether a signal arrived is what
    decides, once the import returns or fails. The signals' dispositions are restored
    afterwards (``run_node`` installs its own); a signal the process was started with
    ignored stays ignored."""
    previous = {}
    for sig in (signal.SIGINT, signal.SIGTERM):
        if signal.getsignal(sig) != signal.SIG_IGN:
            previous[sig] = signal.signal(sig, _stop_import)
    try:
        main = importlib.import_module(module).main
    except BaseException:
        # The signal's exception itself, or what an extension module's initialisation made
        # of it (pybind11 raises ImportError "initialization failed" from it).
        if _received:
            _quiet_exit()
        raise
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, handler)
    if _received:
        _quiet_exit()
    return main


def _quiet_exit() -> NoReturn:
    for stream in (sys.stdout, sys.stderr):
        try:
            stream.flush()
        except Exception:   # closed or broken pipe
            pass
    os._exit(0)


def __getattr__(name: str) -> Callable[[], object]:
    """``paramotion.start.<executable>``: the console-script entry of a node in :data:`NODES`."""
    if name not in NODES:
        raise AttributeError(f"module 'paramotion.start' has no node executable {name!r}")

    def entry() -> object:
        return load(NODES[name])()
    entry.__name__ = entry.__qualname__ = name
    entry.__doc__ = f'Run node executable {name} ({NODES[name]}.main).'
    return entry
