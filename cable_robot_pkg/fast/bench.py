"""FAST speed figures for ``paramotion bench``: the graph in one process and across processes.

- :func:`bench_one_process`: the real-time factor of the whole graph composed in one lock-step
  process (``paramotion fast bench``'s measurement), in wall time and in this process's CPU
  time (sim seconds per CPU second: what the graph would reach on a core of its own, which a
  loaded machine does not give it).
- :func:`bench_processes`: ``launch/fast.launch.xml`` started one process per node (as
  ``paramotion launch`` / ``ros2 launch`` do) at ``real_time_factor`` for a stretch of wall
  time on a private DDS domain, stopped with SIGINT; the feed error comes from the recorded bag
  and each node's CPU share from its rusage. ``PARAMOTION_EXECUTOR`` picks the nodes' executor.
"""
from __future__ import annotations

import math
import os
import random
import signal
import subprocess
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

SETTLE_S = 5.0


def bench_one_process(duration: float = 10.0, repeat: int = 3) -> dict[str, float]:
    """Median wall and CPU real-time factors of ``repeat`` one-process runs of ``duration``."""
    from cable_robot_pkg.fast.scenario import run_graph
    walls, cpus = [], []
    for _ in range(int(repeat)):
        c0 = time.process_time()
        run = run_graph(duration, record_series=False)
        cpu = time.process_time() - c0
        walls.append(run['real_time_factor'])
        cpus.append(run['sim_time_s'] / cpu if cpu > 0 else math.inf)
    walls.sort()
    cpus.sort()
    return {'fast_real_time_factor': float(walls[len(walls) // 2]),
            'fast_real_time_factor_cpu': float(cpus[len(cpus) // 2])}


def _process_env(executor: str, domain_id: int) -> dict:
    env = dict(os.environ)
    env['PARAMOTION_EXECUTOR'] = executor
    env['ROS_DOMAIN_ID'] = str(domain_id)
    env['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
    env['PYTHONUNBUFFERED'] = '1'
    return env


def _stop(procs: dict, timeout: float = 20.0) -> dict:
    """SIGINT every process, reap each, return ``{label: (exit code, cpu seconds)}``."""
    for proc in procs.values():
        # os.kill, not Popen.send_signal, which would reap a process that already exited
        # (os.wait4 below then finds no child and loses its rusage).
        os.kill(proc.pid, signal.SIGINT)
    out = {}
    end = time.monotonic() + timeout
    for label, proc in procs.items():
        while time.monotonic() < end:
            pid, status, usage = os.wait4(proc.pid, os.WNOHANG)
            if pid:
                proc.returncode = os.waitstatus_to_exitcode(status)
                out[label] = (proc.returncode, usage.ru_utime + usage.ru_stime)
                break
            time.sleep(0.05)
        else:
            proc.kill()
            _, status, usage = os.wait4(proc.pid, 0)
            out[label] = ('killed', usage.ru_utime + usage.ru_stime)
    return out


def bench_processes(wall_s: float = 40.0, real_time_factor: float = 1.0,
                    executor: str = 'events', launch_args: dict = None,
                    settle: float = SETTLE_S) -> dict:
    """Run the FAST launch file one process per node for ``wall_s`` seconds of wall time.

    Returns the feed and trolley errors after ``settle`` sim seconds (from the bag), the sim
    time reached, every node's CPU share (CPU seconds / wall seconds from its start to its
    exit) and exit code, and the load average at the end.
    """
    from cable_robot_pkg.fast.configuration import load_config
    from cable_robot_pkg.fast.scenario import bag_series, evaluate
    from paramotion.launch import find_executable, node_command
    from paramotion.launch_xml import load as load_launch

    with tempfile.TemporaryDirectory(prefix='fast_bench_') as tmp:
        bag = Path(tmp) / 'bag'
        args = {'record': True, 'bag': str(bag), 'real_time_factor': float(real_time_factor)}
        args.update(launch_args or {})
        desc = load_launch('fast', args)
        env = _process_env(executor, random.SystemRandom().randint(102, 200))
        procs, logs = {}, []
        start = time.monotonic()
        try:
            for action in desc.nodes:
                cmd = node_command(action, find_executable(action.package, action.executable))
                log = open(Path(tmp) / f'{action.label}.log', 'wb')
                logs.append(log)
                procs[action.label] = subprocess.Popen(
                    cmd, env=env, stdout=log, stderr=subprocess.STDOUT, start_new_session=True)
            time.sleep(wall_s)
        finally:
            exits = _stop(procs)
            wall = time.monotonic() - start
            for log in logs:
                log.close()
        failed = {label: (Path(tmp) / f'{label}.log').read_text(errors='replace')[-600:]
                  for label, (code, _) in exits.items() if code != 0}
        load = os.getloadavg()[0]
        cfg = load_config()
        series = bag_series(bag)
        sim_time = float(series['feed']['t'][-1]) if len(series['feed']['t']) else 0.0
        if sim_time < settle + 1.0:
            raise RuntimeError(f'FAST across processes reached only {sim_time:.1f} s of sim '
                               f'time in {wall:.0f} s of wall time (settling takes {settle} s)'
                               + ''.join(f'; {k} exited {exits[k][0]}: {v!r}'
                                         for k, v in failed.items()))
        result, _ = evaluate(series, settle, cfg.raw['cables']['tension_max'], cfg.geometry)
    return {
        'executor': executor, 'real_time_factor': float(real_time_factor),
        'wall_s': wall, 'sim_time_s': sim_time, 'load_average_1min': load,
        'feed_rms_position_mm': result['feed_rms_position_mm'],
        'feed_rms_orientation_deg': result['feed_rms_orientation_deg'],
        'trolley_rms_position_mm': result['trolley_rms_position_mm'],
        'leg_stroke_end_samples': result['leg_stroke_end_samples'],
        'cpu_share': {label: cpu / wall for label, (_, cpu) in exits.items()},
        'exit_codes': {label: code for label, (code, _) in exits.items()},
    }


def bench_fast(quick: bool, options: dict) -> dict[str, float]:
    """``paramotion bench``'s FAST figures: 1 sim second once (quick) or 5 s, median of 3."""
    return bench_one_process(duration=1.0 if quick else 5.0, repeat=1 if quick else 3)


#: Benchmarks that run a lock-step Graph (paramotion bench measures its levers on them).
LOCKSTEP = ('fast',)

def report_lines(quick: bool, log: Callable[[str], object] = print, wall_s: float = 60.0,
                 real_time_factor: float = 1.0) -> list[str]:
    """Markdown table for the performance page: the FAST launch file one process per node at
    ``real_time_factor`` for ``wall_s`` s of wall time, once per node executor, with each
    node's CPU share and the load average (not part of ``--quick``)."""
    lines = ['## FAST across processes (`launch/fast.launch.xml`, one process per node)', '']
    if quick:
        return lines + ['Not measured with `--quick` (each run takes a minute of wall time).']
    lines += [f'real_time_factor {real_time_factor}, {wall_s:.0f} s of wall time per run, '
              f'errors after {SETTLE_S:.0f} s of sim time; spec 4 mm / 0.1 deg RMS.', '',
              '| node executor | sim s reached | feed RMS mm | feed RMS deg | trolley RMS mm '
              '| CPU share per node | CPU s per sim s (all nodes) | exit codes | load |',
              '|---|---|---|---|---|---|---|---|---|']
    for executor in ('single_threaded', 'events'):
        log(f'bench fast across processes ({executor}) ...')
        try:
            r = bench_processes(wall_s, real_time_factor, executor)
        except Exception as exc:  # a run that fails is a row saying so, not a gap
            lines.append(f'| {executor} | not measured: {type(exc).__name__}: {exc} | | | | | | '
                         f'| {os.getloadavg()[0]:.1f} |')
            continue
        shares = ', '.join(f'{k.removeprefix("fast_")} {100 * v:.0f} %'
                           for k, v in r['cpu_share'].items())
        codes = sorted(set(map(str, r['exit_codes'].values())))
        per_sim = sum(r['cpu_share'].values()) * r['wall_s'] / max(r['sim_time_s'], 1e-9)
        lines.append(f'| {executor} | {r["sim_time_s"]:.1f} | {r["feed_rms_position_mm"]:.1f} '
                     f'| {r["feed_rms_orientation_deg"]:.3f} | '
                     f'{r["trolley_rms_position_mm"]:.1f} | {shares} | {per_sim:.2f} | '
                     f'{", ".join(codes)} | {r["load_average_1min"]:.1f} |')
    return lines


# name -> (function(quick, options) -> figures, {key: table label})
BENCHES = {'fast': (bench_fast, {
    'fast_real_time_factor': 'FAST real-time factor',
    'fast_real_time_factor_cpu': 'FAST sim s / CPU s (one process)'})}

__all__ = ['BENCHES', 'LOCKSTEP', 'bench_fast', 'bench_one_process', 'bench_processes',
           'report_lines']
