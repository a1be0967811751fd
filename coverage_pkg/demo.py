"""``paramotion demo``: the coverage system of Acar, Choset and Lee, run the way a ROS 2 user
runs it: ``launch/coverage.launch.xml`` started as one process per node (simulator, sonar
ring, planner, monitor and the bag recorder) on the world shipped in the package, the simulator
free-running at ``--rtf`` times real time. The planner is the launch file's default, the
paper's Algorithm 1 (``--planner grid``: the grid planner, ours).

It watches the graph over DDS (``/clock``, ``/coverage/status``,
``/coverage/covered_fraction``) until the planner reports the end of coverage (``done``, or
``stuck``/``incomplete``) or ``--max-wall`` seconds pass, stops every process with Ctrl-C
(SIGINT) as ``paramotion launch`` does, and then works from the bag alone: the robot path from
``/coverage/ground_truth``, the decomposition graph, the planner's events and its path
segments with their primitives from ``/coverage/graph``, the covered fraction recomputed from
the path (the monitor's accounting), written to ``DIR/result.json`` and ``DIR/coverage.png``
beside ``DIR/bag/``.
"""
import datetime
import json
import math
import os
import threading
import time
from pathlib import Path

from coverage_pkg.algorithm1 import parse_modes, parse_without, primitive_lengths
from coverage_pkg.figure import planner_label
from coverage_pkg.scenario import add_planner_args, check_paper_options
from paramotion.errors import UserError
from paramotion.scenario_io import add_output_args, output_dir, write_json

END_STATES = ('done', 'stuck', 'incomplete')


def _watch(launcher, max_wall, echo):
    """Spin a watcher node until the planner ends, ``max_wall`` passes or a node dies."""
    import rclpy
    from diagnostic_msgs.msg import DiagnosticArray
    from rclpy.executors import SingleThreadedExecutor
    from rosgraph_msgs.msg import Clock
    from std_msgs.msg import Float64

    from paramotion.qos import CLOCK_QOS, LATCHED_QOS
    seen = {'sim_time': 0.0, 'state': None, 'message': '', 'fraction': None}
    context = rclpy.Context()
    rclpy.init(context=context)
    node = rclpy.create_node('paramotion_demo_watcher', context=context)
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(node)

    def on_status(msg):
        for st in msg.status:
            values = {kv.key: kv.value for kv in st.values}
            seen['state'] = values.get('state_now', seen['state'])
            seen['message'] = st.message
    node.create_subscription(Clock, '/clock', lambda m: seen.update(
        sim_time=m.clock.sec + m.clock.nanosec * 1e-9), CLOCK_QOS)
    node.create_subscription(DiagnosticArray, '/coverage/status', on_status, LATCHED_QOS)
    node.create_subscription(Float64, '/coverage/covered_fraction',
                             lambda m: seen.update(fraction=m.data), LATCHED_QOS)
    start = time.monotonic()
    last_report = start
    try:
        while time.monotonic() - start < max_wall:
            executor.spin_once(timeout_sec=0.05)
            if not launcher.poll():
                break
            if seen['state'] in END_STATES:
                break
            if time.monotonic() - last_report >= 10.0:
                last_report = time.monotonic()
                frac = seen['fraction']
                echo(f"[demo] {time.monotonic() - start:5.1f} s wall, {seen['sim_time']:6.1f} s "
                     f"sim, planner {seen['state']}, covered "
                     + ('-' if frac is None else f'{100 * frac:.1f} %'))
    finally:
        executor.shutdown()
        node.destroy_node()
        rclpy.try_shutdown(context=context)
    seen['wall_s'] = time.monotonic() - start
    return seen


def _from_bag(bag_dir, world, radius, delta):
    """Path, last graph and covered fraction of CVS, from the bag alone.

    Also the fraction recomputed from the path recorded up to the monitor's last published
    value (``fraction_at_monitor``), to compare the two at the same instant: the monitor
    publishes every 2 s of sim time, in which the robot can sweep several per cent of CVS."""
    import numpy as np

    from coverage_pkg.cvs import CoverableSet, CoverageAccumulator
    from paramotion.bag.reader import deserialize, read_messages
    path, stamps, graph, fractions = [], [], None, []
    for m in read_messages(bag_dir, ['/coverage/ground_truth', '/coverage/graph',
                                     '/coverage/covered_fraction']):
        msg = deserialize(m)
        if m.topic == '/coverage/ground_truth':
            p = msg.pose.pose.position
            if math.isfinite(p.x) and math.isfinite(p.y):
                path.append((p.x, p.y))
                stamps.append(m.log_time_ns)
        elif m.topic == '/coverage/graph':
            graph = json.loads(msg.data)
        else:
            fractions.append((m.log_time_ns, msg.data))
    cvs = CoverableSet(world, radius, delta)
    acc = CoverageAccumulator(cvs)
    at_monitor = None
    for (x, y), t in zip(path, stamps):
        if fractions and at_monitor is None and t > fractions[-1][0]:
            at_monitor = acc.fraction()
        acc.add_pose(x, y, min_step=0.1)
    if fractions and at_monitor is None:
        at_monitor = acc.fraction()
    arr = np.asarray(path) if path else np.zeros((0, 2))
    length = float(np.sum(np.hypot(*np.diff(arr, axis=0).T))) if len(arr) > 1 else 0.0
    return {'path': arr, 'graph': graph, 'fraction': acc.fraction(),
            'monitor_fraction': fractions[-1][1] if fractions else None,
            'fraction_at_monitor': at_monitor,
            'uncovered': acc.uncovered_points(), 'path_length_m': length,
            'lower_bound_path_m': cvs.lower_bound_path(), 'cvs_area_m2': cvs.area}


def demo_world():
    """The packaged demo world: two rooms (8 x 7 m with a pillar, 7 x 7 m) joined by a 1.5 m
    wide, 2 m long passage. Small enough that the whole graph finishes in about a minute at 2x
    real time, with every construct of the paper in it: vast cells, narrow cells, cusp points
    at the passage, critical points at the pillar. Found beside the launch files, so the same
    in the source tree and in an installed share/paramotion."""
    from paramotion import launch_xml
    return launch_xml.find_launch_file('coverage').parent.parent / 'coverage_pkg' / 'worlds' / (
        'demo_rooms.json')


def run_demo(out, rtf=2.0, max_wall=240.0, world=None, overwrite=False, echo=print,
             planner=None, without=(), modes=()):
    """Launch, watch, stop, evaluate from the bag; returns the result dict. ``planner``
    (default: the launch file's), ``without`` and ``modes`` (the paper planner's
    ``NAME=VALUE`` modes) become the launch arguments."""
    from coverage_pkg.scenario import _shift_events, _shift_graph
    from coverage_pkg.world import load_world
    from paramotion import launch_xml
    from paramotion.bag.reader import bag_info
    from paramotion.launch import Launcher

    without = parse_without(without)
    modes = [modes] if isinstance(modes, str) else list(modes or ())
    with output_dir(out, overwrite) as tmp:
        args = {'record': True, 'bag': str(tmp / 'bag'), 'real_time_factor': float(rtf),
                'world': str(world or demo_world())}
        if planner is not None:
            args['planner'] = planner
        if without:
            args['without'] = ','.join(without)
        if modes:
            args['modes'] = ','.join(modes)
        desc = launch_xml.load('coverage', args)
        sim = desc.node('coverage_sim').params
        world_path, radius = sim['world'], float(sim['radius'])
        delta = float(desc.node('coverage_monitor').params['delta'])
        planner_name = desc.node('coverage_planner').params['planner']
        world_obj = load_world(world_path, radius=radius)
        launcher = Launcher(desc, log_dir=tmp / 'logs',
                            echo=lambda line: None).prepare()
        lock = threading.Lock()

        def say(line):
            with lock:
                echo(line)
        say(f'[demo] {desc.path.name}: {len(desc.nodes)} processes '
            f"({', '.join(p.label for p in launcher.procs)}), world {world_obj.name}, "
            f'real_time_factor {rtf:g}; node output in {Path(out) / "logs"}')
        launcher.start()
        try:
            seen = _watch(launcher, max_wall, say)
        finally:
            codes = launcher.shutdown()
        failure = launcher.failure_message()
        if failure:
            raise UserError(f'{failure}; see {Path(out) / "logs"}')
        info = bag_info(tmp / 'bag')
        ev = _from_bag(tmp / 'bag', world_obj, radius, delta)
        sx, sy = map(float, world_obj.start)
        graph = _shift_graph(ev['graph'], sx, sy) if ev['graph'] else None
        events = graph.pop('events', None) if graph else None
        segments = graph.pop('path_segments', None) if graph else None
        state = seen['state']
        result = {
            'mode': 'processes (paramotion launch coverage)',
            'world': world_path, 'world_name': world_obj.name, 'radius_m': radius,
            'detector_range_m': delta, 'real_time_factor': rtf, 'planner': planner_name,
            'without': list(without), 'modes': parse_modes(modes),
            'outcome': 'complete' if state == 'done' else (
                state if state in END_STATES else 'stopped_at_wall_limit'),
            'planner_state': state, 'planner_message': seen['message'],
            'sim_time_s': seen['sim_time'], 'wall_time_s': seen['wall_s'],
            'covered_fraction_of_cvs': ev['fraction'],
            'monitor_covered_fraction': ev['monitor_fraction'],
            'covered_fraction_at_monitor': ev['fraction_at_monitor'],
            'cvs_area_m2': ev['cvs_area_m2'], 'path_length_m': ev['path_length_m'],
            'lower_bound_path_m': ev['lower_bound_path_m'],
            'exit_codes': codes, 'bag_messages': info.message_count,
            'bag_complete': info.complete,
            'bag_topics': {t: v.count for t, v in sorted(info.topics.items())},
            'frames': 'path, graph and events in map',
            'hierarchical_graph': graph,
        }
        if events is not None:
            # Every event of the paper planner (sensed: critical, cusp, meet; node_created,
            # cell_closed, branch_end, ...): [sim time, kind, x, y (map), detail].
            result['events'] = _shift_events(events, sx, sy)
        if segments is not None:
            # Each path segment and the primitive that drove it (lap, boundary, gvd, transit).
            result['path_segments'] = segments
            result['primitive_lengths_m'] = primitive_lengths(segments)
        write_json(tmp / 'result.json', result)
        from coverage_pkg.figure import render_coverage
        label = planner_label(planner_name, without, modes)
        title = (f"{world_obj.name}, {label}, one process per node at {rtf:g}x: "
                 f"path "
                 f"{ev['path_length_m']:.1f} m, covered {100 * ev['fraction']:.2f}% of CVS, "
                 f"{result['outcome']}")
        render_coverage(tmp / 'coverage.png', world_obj, ev['path'].tolist(), graph, None,
                        ev['uncovered'], title)
    return result


def _run(args):
    if not (math.isfinite(args.rtf) and 0 < args.rtf <= 50):
        raise UserError(f'--rtf {args.rtf}: must be in (0, 50]')
    if not (math.isfinite(args.max_wall) and args.max_wall > 0):
        raise UserError(f'--max-wall {args.max_wall}: must be a positive number of seconds')
    if args.world and not os.path.isfile(args.world):
        raise UserError(f'--world {args.world}: no such file')
    check_paper_options(args.planner, args.without, args.mode)
    r = run_demo(args.out, args.rtf, args.max_wall, args.world, args.overwrite,
                 planner=args.planner, without=args.without, modes=args.mode)
    out = Path(args.out)
    label = planner_label(r['planner'], r['without'], args.mode)
    print(f"coverage {r['world_name']} ({label}, one process per node): "
          f"{r['outcome']} after "
          f"{r['sim_time_s']:.1f} s sim time in {r['wall_time_s']:.1f} s wall")
    print(f"covered {100 * r['covered_fraction_of_cvs']:.2f}% of CVS "
          f"({r['cvs_area_m2']:.1f} m^2); path {r['path_length_m']:.1f} m (lower bound "
          f"{r['lower_bound_path_m']:.1f} m)")
    print(f"bag: {out / 'bag'} ({r['bag_messages']} messages); result: "
          f"{out / 'result.json'}; picture: {out / 'coverage.png'}; logs: {out / 'logs'}")
    return 0 if r['outcome'] == 'complete' else 1


def register(subparsers):
    """Add ``paramotion demo``."""
    stamp = datetime.datetime.now().strftime('%Y%m%d-%H%M%S')
    parser = subparsers.add_parser(
        'demo', help='the coverage system, one process per node, recorded',
        description='Launch launch/coverage.launch.xml (simulator, sonar, planner, monitor, '
        'recorder: one process each) on the packaged world, stop when the planner is done, '
        "and write bag/, result.json and coverage.png. The planner is the paper's Algorithm 1 "
        '(--planner grid: the frontier-driven grid planner, ours).')
    add_output_args(parser, default_out=os.path.join('bags', 'runs', f'demo-{stamp}'))
    parser.add_argument('--rtf', type=float, default=2.0,
                        help='real-time factor of the free-running simulator (default 2; '
                        'above about 3 the sonar and planner processes fall behind on 2 cores)')
    parser.add_argument('--max-wall', type=float, default=240.0,
                        help='stop after this many wall seconds if not done (default 240)')
    parser.add_argument('--world', default=None,
                        help='world JSON (default: the packaged demo_rooms)')
    add_planner_args(parser)
    parser.set_defaults(func=_run)
