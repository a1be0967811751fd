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


def cpu_breakdown(duration: float = 3.0, launch_args: dict | None = None) -> dict[str, float]:
    """Where the one-process FAST graph's CPU time goes: CPU seconds per sim second of a
    lock-step run (as ``run_graph`` composes it) by part: the simulator's physics step
    (PyBullet, cable and wind models), its state messages, each node's callbacks (timers and
    subscriptions, message conversion and the control algorithm), and the rest (the executor,
    messages taken, ``/clock``). Callbacks are timed with ``time.process_time``; the physics
    step is also split into PyBullet's ``stepSimulation``, the compiled winch, cable and wind
    arithmetic (:func:`cable_robot_pkg.fast.cable_kernel.plant_step`; with numpy the cable
    and the wind wrench), the servo commands and the rest (state reads, turbulence and gust
    look-ups, Python), rows "of which" that are not added again.
    ``launch_args``: launch arguments over the defaults (e.g. ``{'config': path}``)."""
    import types
    from collections import Counter

    import pybullet

    import cable_robot_pkg.fast.plant as plant_module
    from cable_robot_pkg.fast.scenario import LAUNCH_FILE, detach_qos_event_handlers
    from paramotion.graph import Graph
    from paramotion.launch import graph_from_launch

    acc = Counter()
    within = Counter()       # parts of the physics step (already in its figure)

    def timed(key, fn, into=acc):
        def wrapper(*args):
            t0 = time.process_time()
            try:
                return fn(*args)
            finally:
                into[key] += time.process_time() - t0
        return wrapper

    with Graph() as graph:
        nodes, _ = graph_from_launch(graph, LAUNCH_FILE, dict(launch_args or {}))
        sim = nodes['fast_sim']
        sim.advance_time = timed('fast_sim: physics step (PyBullet, cables, wind)',
                                 sim.advance_time)
        sim.publish_state = timed('fast_sim: state messages', sim.publish_state)
        plant = sim.plant
        kernel = plant._kernel
        for key, owner, name in (('cable wrench', plant.cables, 'wrench'),
                                 ('wind wrench', plant.wind, 'wrench'),
                                 ('leg and hinge servo commands', plant, '_send_commands')):
            if owner is not None:
                setattr(owner, name, timed(f'  of which {key}', getattr(owner, name), within))
        # PyBullet's step and the compiled step, timed through the plant module's names.
        bullet = types.SimpleNamespace(**vars(pybullet))
        bullet.stepSimulation = _timed_keywords('  of which PyBullet stepSimulation',
                                                pybullet.stepSimulation, within)
        saved_module = plant_module.pybullet
        plant_module.pybullet = bullet
        if kernel is not None:
            plant._kernel = timed('  of which winches, cables, wind (compiled)', kernel, within)
        for label, node in nodes.items():
            key = f'{label}: callbacks' if node is not sim else 'fast_sim: command callbacks'
            for sub in node.subscriptions:
                sub.callback = timed(key, sub.callback)
            for tmr in node.timers:
                tmr.callback = timed(key, tmr.callback)
        detach_qos_event_handlers(graph.nodes)
        try:
            graph.run_lockstep(sim, max_sim_time=0.2)
            acc.clear()
            within.clear()
            c0 = time.process_time()
            graph.run_lockstep(sim, max_sim_time=0.2 + duration)
        finally:
            plant_module.pybullet = saved_module
        total = time.process_time() - c0
    out = {}
    for key, value in acc.most_common():
        out[key] = value / duration
        if key.startswith('fast_sim: physics step'):
            out.update((k, v / duration) for k, v in within.most_common())
            out['  of which the rest (state reads, look-ups, Python)'] = (
                value - sum(within.values())) / duration
    out['executor, messages taken, /clock'] = (total - sum(acc.values())) / duration
    out['total'] = total / duration
    return out


def isolation_replay(duration: float = 8.0, mode: str = 'predictive', latency: float = 0.04,
                     repeat: int = 7) -> dict[str, float | str]:
    """CPU seconds per sim second of the isolation controller alone, steady against the
    machine's load: the calls a ROS-free loop run (:func:`cable_robot_pkg.fast.loop.run_loop`,
    ``duration`` s, ``mode``, ``latency``) makes on its controller (frames, encoders, targets,
    updates) are recorded, then replayed on ``repeat`` fresh controllers; the least CPU time
    counts (other work on the machine only adds to it). ``commands`` fingerprints the leg
    lengths the replays commanded (the same in every replay, and between two trees whose
    results are bit-identical)."""
    import copy
    import hashlib

    import numpy as np

    import cable_robot_pkg.fast.isolation as isolation
    from cable_robot_pkg.fast.configuration import load_config
    from cable_robot_pkg.fast.loop import run_loop

    cls = isolation.IsolationController
    names = ('update', 'add_base', 'add_feed', 'add_trolley', 'add_leg_state',
             'add_hinge_state', 'set_target')
    calls = []
    saved = {name: getattr(cls, name) for name in names}

    def recording(name, method):
        def wrapper(self, *args):
            calls.append((name, copy.deepcopy(args)))
            return method(self, *args)
        return wrapper
    try:
        for name, method in saved.items():
            setattr(cls, name, recording(name, method))
        run_loop(duration, mode=mode, latency=latency)
    finally:
        for name, method in saved.items():
            setattr(cls, name, method)
    cfg = load_config()
    best, digest = math.inf, None
    for _ in range(int(repeat)):
        ctl = cls.from_config(cfg, mode=mode)
        ctl.compile_kernels()
        lengths = []
        c0 = time.process_time()
        for name, args in calls:
            out = getattr(ctl, name)(*args)
            if name == 'update':
                lengths.append(out.lengths)
        best = min(best, time.process_time() - c0)
        replayed = hashlib.sha1(np.array(lengths).tobytes()).hexdigest()[:12]
        if digest not in (None, replayed):
            raise RuntimeError('isolation_replay: two replays of the same calls commanded '
                               'different leg lengths')
        digest = replayed
    return {'cpu_s_per_sim_s': best / duration, 'calls': len(calls), 'commands': digest}


def _timed_keywords(key, fn, into):
    """``fn`` (called with keyword arguments) timed into ``into[key]``."""
    def wrapper(*args, **kwargs):
        t0 = time.process_time()
        try:
            return fn(*args, **kwargs)
        finally:
            into[key] += time.process_time() - t0
    return wrapper


#: Physics settings compared by :func:`physics_settings`: (label, physics_dt s, solver
#: iterations); the first is the packaged one.
PHYSICS_SETTINGS = (('1 kHz, 60 iterations (used)', 0.001, 60),
                    ('1 kHz, 30 iterations', 0.001, 30),
                    ('1 kHz, 20 iterations', 0.001, 20),
                    ('500 Hz, 60 iterations', 0.002, 60))
PHYSICS_WINDS = ((23, 300.0), (7, 120.0))


def physics_settings(duration: float = 12.0, settle: float = 5.0, latency: float = 0.04,
                     settings: tuple = PHYSICS_SETTINGS,
                     winds: tuple = PHYSICS_WINDS) -> list[dict]:
    """What cheaper PyBullet settings would save and what they change: for each setting and
    wind, the ROS-free loop (``predictive``, ``latency``) for ``duration`` sim s; its CPU s per
    sim s and the feed RMS after ``settle``. The packaged setting is the first."""
    from cable_robot_pkg.fast.loop import run_loop
    rows = []
    for label, dt, iterations in settings:
        for seed, direction in winds:
            c0 = time.process_time()
            r = run_loop(duration, mode='predictive', latency=latency, settle=settle,
                         overrides={'wind': {'seed': seed, 'direction_deg': direction},
                                    'sim': {'physics_dt': dt,
                                            'solver_iterations': iterations}})
            cpu = time.process_time() - c0
            rows.append({'setting': label, 'wind': f'{seed} / {direction:g} deg',
                         'cpu_per_sim_s': cpu / max(r['sim_time_s'], 1e-9),
                         'feed_rms_position_mm': r['feed_rms_position_mm'],
                         'feed_rms_orientation_deg': r['feed_rms_orientation_deg']})
    return rows


#: (label, publish period s, command lag in periods) of :func:`publish_period_winds`.
PERIOD_CASES = (('5 ms lock-step', 0.005, 0), ('5 ms, one period of lag', 0.005, 1),
                ('10 ms lock-step', 0.01, 0), ('10 ms, one period of lag', 0.01, 1))


def publish_period_winds(latency: float = 0.02, duration: float = 20.0, settle: float = 5.0,
                         cases: tuple = PERIOD_CASES, workers: int = 2) -> list[dict]:
    """The feed error at the launched graph's publish periods on the 13 winds of the spec
    region (``report.WINDS``: development, validation, held out), on the ROS-free loop
    (``predictive``, ``latency``, ``duration`` sim s, statistics after ``settle``): the tracker
    and the isolation controller act once per period (5 ms: 200 Hz, 10 ms: 100 Hz), and the
    commands reach the plant at once (lock-step) or one period later, the launched graph's
    worst case with ``sync_max_lag`` one period. One row per case and wind, with whether the
    spec (4 mm / 0.1 deg RMS, stable) holds."""
    from cable_robot_pkg.fast.report import WINDS, run_cases
    specs = []
    for label, period, lag in cases:
        for role, winds in WINDS.items():
            for seed, direction in winds:
                specs.append({'key': (label, role, seed, direction), 'duration': duration,
                              'settle': settle, 'mode': 'predictive', 'latency': latency,
                              'period': period, 'command_lag': lag,
                              'overrides': {'wind': {'seed': seed,
                                                     'direction_deg': direction}}})
    res = run_cases(specs, workers=workers)
    rows = []
    for spec in specs:
        r = res[spec['key']]
        label, role, seed, direction = spec['key']
        rows.append({'case': label, 'winds': role, 'wind': f'{seed} / {direction:g} deg',
                     'feed_rms_position_mm': r['feed_rms_position_mm'],
                     'feed_rms_orientation_deg': r['feed_rms_orientation_deg'],
                     'within_spec': r['feed_rms_position_mm'] <= 4.0
                     and r['feed_rms_orientation_deg'] <= 0.1 and not r['unstable']})
    return rows


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


class _ClockProbe:
    """Samples ``/clock`` on ``domain_id`` against the wall clock (its own context and a
    daemon thread), for the sim seconds per wall second the launched graph reaches."""

    def __init__(self, domain_id: int):
        import threading

        import rclpy
        from rclpy.executors import SingleThreadedExecutor
        from rosgraph_msgs.msg import Clock

        from paramotion.qos import CLOCK_QOS
        self.context = rclpy.Context()
        rclpy.init(context=self.context, domain_id=domain_id)
        self.node = rclpy.create_node('fast_bench_clock_probe', context=self.context)
        self.samples = []          # (wall s, sim s)
        self.node.create_subscription(Clock, '/clock', lambda m: self.samples.append(
            (time.monotonic(), m.clock.sec + m.clock.nanosec * 1e-9)), CLOCK_QOS)
        self.executor = SingleThreadedExecutor(context=self.context)
        self.executor.add_node(self.node)
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._spin, daemon=True)
        self._thread.start()

    def _spin(self):
        while not self._stop.is_set():
            self.executor.spin_once(timeout_sec=0.1)

    def sim_per_wall(self, skip: float = 0.25) -> float:
        """Sim seconds per wall second after the first ``skip`` of the running time."""
        running = [s for s in self.samples if s[1] > 0.0]
        if len(running) < 2:
            return 0.0
        w0 = running[0][0] + skip * (running[-1][0] - running[0][0])
        later = [s for s in running if s[0] >= w0]
        if len(later) < 2 or later[-1][0] <= later[0][0]:
            return 0.0
        return (later[-1][1] - later[0][1]) / (later[-1][0] - later[0][0])

    def close(self):
        import rclpy
        self._stop.set()
        self._thread.join(timeout=2.0)
        self.executor.shutdown()
        self.node.destroy_node()
        rclpy.try_shutdown(context=self.context)


def bench_processes(wall_s: float = 40.0, real_time_factor: float = 1.0,
                    executor: str = 'events', launch_args: dict = None,
                    settle: float = SETTLE_S) -> dict:
    """Run the FAST launch file, each of its nodes a process (the launch defaults: the
    simulator, the control container and the recorder), for ``wall_s`` seconds of wall time.

    Returns the feed and trolley errors after ``settle`` sim seconds (from the bag), the sim
    time reached, every node's CPU share (CPU seconds / wall seconds from its start to its
    exit) and exit code, and the load average at the end.
    """
    from cable_robot_pkg.fast.configuration import load_config
    from cable_robot_pkg.fast.scenario import bag_series, evaluate
    from paramotion.launch import child_setup, find_executable, node_command
    from paramotion.launch_xml import load as load_launch

    with tempfile.TemporaryDirectory(prefix='fast_bench_') as tmp:
        bag = Path(tmp) / 'bag'
        args = {'record': True, 'bag': str(bag), 'real_time_factor': float(real_time_factor),
                'executor': executor}
        args.update(launch_args or {})
        desc = load_launch('fast', args)
        domain = random.SystemRandom().randint(102, 200)
        env = _process_env(executor, domain)
        procs, logs = {}, []
        start = time.monotonic()
        saved = os.environ.get('ROS_AUTOMATIC_DISCOVERY_RANGE')
        os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
        try:
            probe = _ClockProbe(domain)
        finally:
            if saved is None:
                os.environ.pop('ROS_AUTOMATIC_DISCOVERY_RANGE')
            else:
                os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = saved
        try:
            for action in desc.nodes:
                cmd = node_command(action, find_executable(action.package, action.executable))
                log = open(Path(tmp) / f'{action.label}.log', 'wb')
                logs.append(log)
                procs[action.label] = subprocess.Popen(
                    cmd, env={**env, **action.env}, stdout=log, stderr=subprocess.STDOUT,
                    preexec_fn=child_setup(die_with_parent=True),
                    start_new_session=True)
            time.sleep(wall_s)
        finally:
            exits = _stop(procs)
            wall = time.monotonic() - start
            probe.close()
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
        'sim_per_wall': probe.sim_per_wall(),
        'feed_rms_position_mm': result['feed_rms_position_mm'],
        'feed_rms_orientation_deg': result['feed_rms_orientation_deg'],
        'trolley_rms_position_mm': result['trolley_rms_position_mm'],
        'leg_stroke_end_samples': result['leg_stroke_end_samples'],
        'cpu_share': {label: cpu / wall for label, (_, cpu) in exits.items()},
        'exit_codes': {label: code for label, (code, _) in exits.items()},
    }


def delivery_cost(messages: int = 3000, repeat: int = 3) -> dict[str, float]:
    """CPU microseconds per message handed from one component to another in one container
    process on the events executor (as ``spin_node`` spins it), a ``PoseStamped`` like the
    tracker's frames, each run until the reader's callback has it: with in-process delivery
    (``in_process``) and through the middleware (``middleware``), without a reader outside the
    container and with one (``*_outside_reader``: another context in this process, whose
    middleware threads this process's CPU time counts too). Median of ``repeat`` runs each,
    alternated."""
    import rclpy
    from geometry_msgs.msg import PoseStamped
    from rclpy.parameter import Parameter

    from paramotion.container import ComponentContainer, component_params
    from paramotion.executors import make_executor
    from paramotion.graph import private_domain_id
    from paramotion.node import ParamotionNode
    from paramotion.qos import SENSOR_QOS

    class Talker(ParamotionNode):
        USE_SIM_TIME_DEFAULT = False

        def __init__(self, node_name='talker', **kwargs):
            super().__init__(node_name, **kwargs)
            self.pub = self.create_publisher(PoseStamped, '/delivery_cost', SENSOR_QOS)

    class Listener(ParamotionNode):
        USE_SIM_TIME_DEFAULT = False

        def __init__(self, node_name='listener', **kwargs):
            super().__init__(node_name, **kwargs)
            self.count = 0
            self.create_subscription(PoseStamped, '/delivery_cost', self.on_msg, SENSOR_QOS)

        def on_msg(self, msg):
            self.count += 1

    class Box(ComponentContainer):
        COMPONENTS = {'talker': Talker, 'listener': Listener}
        PARAMS = component_params(COMPONENTS)
        USE_SIM_TIME_DEFAULT = False

        def __init__(self, **kwargs):
            super().__init__('delivery_cost', **kwargs)

    def run(in_process: bool, outside: bool) -> float:
        domain = private_domain_id()
        inside_ctx, outside_ctx = rclpy.Context(), rclpy.Context()
        rclpy.init(context=inside_ctx, domain_id=domain)
        rclpy.init(context=outside_ctx, domain_id=domain)
        peer = rclpy.create_node('delivery_cost_peer', context=outside_ctx)
        box = Box(context=inside_ctx,
                  parameter_overrides=[Parameter('in_process', value=in_process)])
        talker, listener = box.components
        executor = make_executor('events', inside_ctx)
        try:
            if outside:
                peer.create_subscription(PoseStamped, '/delivery_cost', lambda m: None,
                                         SENSOR_QOS)
                end = time.monotonic() + 10.0
                while talker.pub.get_subscription_count() < 2 and time.monotonic() < end:
                    time.sleep(0.05)
            for node in (box, talker, listener):
                executor.add_node(node)
            box.start_delivery(executor, 'events')
            executor.spin_once(timeout_sec=0.1)
            msg = PoseStamped()
            msg.pose.position.x = 1.5
            c0 = time.process_time()
            for k in range(messages):
                talker.pub.publish(msg)
                while listener.count <= k:
                    executor.spin_once(timeout_sec=0.5)
            return (time.process_time() - c0) / messages * 1e6
        finally:
            executor.shutdown(timeout_sec=1.0)
            box.destroy_node()
            peer.destroy_node()
            rclpy.try_shutdown(context=inside_ctx)
            rclpy.try_shutdown(context=outside_ctx)

    runs = {}
    for _ in range(int(repeat)):
        for outside in (False, True):
            for in_process in (True, False):
                key = ('in_process' if in_process else 'middleware') + \
                    ('_outside_reader' if outside else '')
                runs.setdefault(key, []).append(run(in_process, outside))
    return {key: sorted(v)[len(v) // 2] for key, v in runs.items()}


def bench_fast(quick: bool, options: dict) -> dict[str, float]:
    """``paramotion bench``'s FAST figures: 1 sim second once (quick) or 5 s, median of 3."""
    return bench_one_process(duration=1.0 if quick else 5.0, repeat=1 if quick else 3)


#: Benchmarks that run a lock-step Graph (paramotion bench measures its levers on them).
LOCKSTEP = ('fast',)

#: The topics :func:`bench_processes` evaluates (``scenario.bag_series``): a recorder on these
#: alone is the lightest that still measures the feed error.
EVALUATED_TOPICS = ['/fast/ground_truth/trolley', '/fast/ground_truth/upper_platform',
                    '/fast/ground_truth/feed', '/fast/feed_target', '/fast/trolley_target',
                    '/fast/cables/state', '/fast/legs/state']

#: The cross-process configurations the performance page measures side by side:
#: (label, node executor, launch arguments).
PROCESS_CONFIGS = [
    ('one process per node, rclpy.spin, free-running', 'single_threaded',
     {'composed': False, 'sync_max_lag': -1.0}),
    ('one process per node, events executor, free-running', 'events',
     {'composed': False, 'sync_max_lag': -1.0}),
    ('control nodes composed, events executor, free-running', 'events',
     {'composed': True, 'sync_max_lag': -1.0}),
    ('one process per node, rclpy.spin, simulator waits for every answer', 'single_threaded',
     {'composed': False, 'sync_max_lag': 0.0}),
    ('one process per node, events executor, simulator waits for every answer', 'events',
     {'composed': False, 'sync_max_lag': 0.0}),
    ('control nodes composed, events executor, simulator waits for every answer '
     '(sync_max_lag:=0.0)', 'events', {'sync_max_lag': 0.0}),
    ('control nodes composed, events executor, simulator one period ahead (launch defaults: '
     '/clock and state every 10 ms, tracker and isolation controller at 100 Hz, sync_max_lag '
     '0.01)', 'events', {}),
    ('launch defaults, two periods ahead (sync_max_lag:=0.02)', 'events',
     {'sync_max_lag': 0.02}),
    ('launch defaults, timers fired by the events executor (sim_timers:=executor)', 'events',
     {'composed': True, 'sim_timers': 'executor'}),
    ('launch defaults, waitset executor', 'waitset', {}),
    ('launch defaults, /clock and state every 5 ms, tracker and isolation controller at '
     '200 Hz (publish_period:=0.005)', 'events', {'publish_period': 0.005}),
    ('launch defaults, recorder on the evaluated topics only (record_topics:=[7 topics])',
     'events', {'record_topics': EVALUATED_TOPICS}),
    ('launch defaults without in-process delivery in the container (in_process:=false)',
     'events', {'in_process': False}),
    ('recorder on the evaluated topics only, without in-process delivery (in_process:=false)',
     'events', {'record_topics': EVALUATED_TOPICS, 'in_process': False}),
]


def report_lines(quick: bool, log: Callable[[str], object] = print, wall_s: float = 60.0,
                 real_time_factor: float = 1.0) -> list[str]:
    """Markdown table for the performance page: the FAST launch file (with the recorder) at
    ``real_time_factor`` for ``wall_s`` s of wall time in each of :data:`PROCESS_CONFIGS`,
    with the sim seconds per wall second reached, the feed errors, each process's CPU share,
    the CPU seconds all processes used per sim second and the load average (not part of
    ``--quick``)."""
    log('bench fast CPU breakdown ...')
    parts = cpu_breakdown(1.0 if quick else 4.0)
    total = parts.pop('total')
    lines = ['## Where the one-process FAST graph spends its CPU time', '',
             f'`cable_robot_pkg.fast.bench.cpu_breakdown`: a lock-step run of '
             f'{1.0 if quick else 4.0:g} sim s, callbacks timed with `time.process_time`; '
             f'{total:.3f} CPU s per sim s in all (at most {1 / total:.2f} sim s per CPU s).',
             '', '| part | CPU s per sim s | share |', '|---|---|---|']
    lines += [f'| {key} | {value:.3f} | {100 * value / total:.0f} % |'
              for key, value in parts.items()]
    lines += ['', '## FAST across processes (`launch/fast.launch.xml`)', '']
    if quick:
        return lines + ['Not measured with `--quick` (each run takes a minute of wall time).']
    lines += [f'real_time_factor {real_time_factor}, {wall_s:.0f} s of wall time per run with '
              f'the recorder (`record:=true`), errors after {SETTLE_S:.0f} s of sim time; spec '
              '4 mm / 0.1 deg RMS. Sim s / wall s is measured on `/clock` after start-up; CPU '
              's per sim s counts every process, start-up and discovery included.', '',
              '| configuration | sim s reached | sim s / wall s | feed RMS mm | feed RMS deg '
              '| trolley RMS mm | CPU share per process | CPU s per sim s (all processes) '
              '| exit codes | load |',
              '|---|---|---|---|---|---|---|---|---|---|']
    for label, executor, args in PROCESS_CONFIGS:
        log(f'bench fast across processes ({label}) ...')
        try:
            r = bench_processes(wall_s, real_time_factor, executor, launch_args=args)
        except Exception as exc:  # a run that fails is a row saying so, not a gap
            lines.append(f'| {label} | not measured: {type(exc).__name__}: {exc} | | | | | | '
                         f'| | {os.getloadavg()[0]:.1f} |')
            continue
        lines.append(process_row(label, r))
    return lines


def process_row(label: str, r: dict) -> str:
    """One table row of :func:`report_lines` from a :func:`bench_processes` result."""
    shares = ', '.join(f'{k.removeprefix("fast_")} {100 * v:.0f} %'
                       for k, v in r['cpu_share'].items())
    codes = sorted(set(map(str, r['exit_codes'].values())))
    per_sim = sum(r['cpu_share'].values()) * r['wall_s'] / max(r['sim_time_s'], 1e-9)
    return (f'| {label} | {r["sim_time_s"]:.1f} | {r["sim_per_wall"]:.2f} | '
            f'{r["feed_rms_position_mm"]:.1f} | {r["feed_rms_orientation_deg"]:.3f} | '
            f'{r["trolley_rms_position_mm"]:.1f} | {shares} | {per_sim:.2f} | '
            f'{", ".join(codes)} | {r["load_average_1min"]:.1f} |')


# name -> (function(quick, options) -> figures, {key: table label})
BENCHES = {'fast': (bench_fast, {
    'fast_real_time_factor': 'FAST real-time factor',
    'fast_real_time_factor_cpu': 'FAST sim s / CPU s (one process)'})}

__all__ = ['BENCHES', 'EVALUATED_TOPICS', 'LOCKSTEP', 'PHYSICS_SETTINGS', 'PROCESS_CONFIGS',
           'bench_fast', 'bench_one_process', 'bench_processes', 'delivery_cost',
           'physics_settings',
           'process_row', 'report_lines']
