"""``paramotion coverage`` and ``paramotion coverage-benchmark``: the coverage graph headless.

``coverage`` composes the simulator, the sonar ring, the planner and the monitor in one
executor and runs them lock-step on sim time (as fast as the machine allows) until the planner
reports completion (or a stuck robot) or ``--max-sim-time``; it writes ``DIR/bag/`` (MCAP),
``DIR/result.json`` and ``DIR/coverage.png``. ``--detector robot`` runs the robot-size
baseline of Section II on the same world.

``coverage-benchmark`` runs the same graph without recording and prints the planner update time
per sonar sweep (median, p99) and the whole-run wall time against sim time.
"""
import datetime
import math
import os
import time
from pathlib import Path

import numpy as np

from coverage_pkg.algorithm1 import EVENTS, MODE_FIELDS, PaperConfig, parse_modes, parse_without
from coverage_pkg.figure import planner_label
from coverage_pkg.planner import PlannerConfig, graph_dict
from coverage_pkg.sonar import SonarRing
from coverage_pkg.world import load_world
from paramotion.errors import UserError
from paramotion.launch_xml import load as load_launch
from paramotion.launch_xml import recorded_topics
from paramotion.scenario_io import add_output_args, output_dir, write_json

# The graph (nodes, parameters, recorded topics) is described once, in
# launch/coverage.launch.xml; this runner composes it in one process.
# /sonar/ranges (16 Range messages per sweep) is not recorded by default, since the same sweep
# is recorded as /sonar/scan; add it with --record-topics if wanted (the recorder keeps every
# message of each burst: test/test_recording_loss.py).
LAUNCH_FILE = 'coverage'
TOPICS = recorded_topics(load_launch(LAUNCH_FILE, {'record': True}))
PLANNERS = ('paper', 'grid')
DEFAULT_PLANNER = 'paper'


def check_paper_options(planner, without=(), modes=()):
    """``--without`` and ``--mode`` apply to the paper planner only, and must parse; raise
    UserError with one line if not."""
    if without and planner != 'paper':
        raise UserError('--without: applies to --planner paper only')
    if modes and planner != 'paper':
        raise UserError('--mode: applies to --planner paper only')
    parse_without(without)
    try:
        parse_modes(modes)
    except UserError as exc:
        raise UserError(f'--mode: {exc}') from None


def validate_inputs(world_path, delta, radius, detector, sonar_max_range, max_sim_time=1.0,
                    planner=DEFAULT_PLANNER, without=(), modes=()):
    """Check every input before anything runs; raise UserError with one line if bad."""
    if planner not in PLANNERS:
        raise UserError(f'--planner {planner}: must be one of {", ".join(PLANNERS)}')
    check_paper_options(planner, without, modes)
    if planner == 'paper' and detector != 'extended':
        raise UserError('--detector robot: needs --planner grid')
    for name, v in (('--delta', delta), ('--radius', radius), ('--sonar-max-range',
                                                               sonar_max_range),
                    ('--max-sim-time', max_sim_time)):
        if not (isinstance(v, (int, float)) and math.isfinite(v) and v > 0):
            raise UserError(f'{name} {v}: must be a positive number')
    if detector == 'extended' and not delta > radius:
        raise UserError(f'--delta {delta:g}: must be greater than --radius {radius:g}')
    SonarRing(max_range=sonar_max_range).validate(delta if detector == 'extended' else None)
    PlannerConfig(delta=delta, radius=radius, detector=detector).validate(
        sonar_max_range if detector == 'extended' else None)
    return load_world(world_path, radius=radius)


def _modes_of(config):
    """The mode fields of a :class:`PaperConfig` that differ from the default's."""
    base = PaperConfig()
    return {k: getattr(config, k) for k in MODE_FIELDS if getattr(config, k) != getattr(base, k)}


def run_coverage(world_path, delta=2.0, radius=0.25, detector='extended', bag_dir=None,
                 max_sim_time=3000.0, sonar_max_range=5.0, seed=1, sonar_params=None,
                 planner_params=None, topics=None, domain_id=None, planner=DEFAULT_PLANNER,
                 without=(), modes=()):
    """Run the coverage graph lock-step and return the result dict (see ``_run``).

    ``bag_dir`` records ``topics`` (default :data:`TOPICS`); extra node parameters go in
    ``sonar_params`` / ``planner_params``; ``modes``: the paper planner's ``NAME=VALUE``
    modes (:func:`coverage_pkg.algorithm1.parse_modes`).
    """
    from paramotion.graph import Graph
    from paramotion.launch import graph_from_launch

    modes = [modes] if isinstance(modes, str) else list(modes or ())
    world = validate_inputs(world_path, delta, radius, detector, sonar_max_range, max_sim_time,
                            planner, without, modes)
    planner_name = planner
    det_range = radius if detector == 'robot' else delta
    wall0 = time.monotonic()
    with Graph(domain_id=domain_id) as graph:
        nodes, launch_topics = graph_from_launch(
            graph, LAUNCH_FILE, {'world': str(world_path), 'radius': float(radius),
                                 'delta': float(delta), 'detector': detector,
                                 'sonar_max_range': float(sonar_max_range), 'seed': int(seed),
                                 'planner': planner_name,
                                 'without': ','.join(parse_without(without)),
                                 'modes': ','.join(modes)},
            extra_params={'coverage_sonar': sonar_params, 'coverage_planner': planner_params})
        sim, planner, monitor = (nodes[n] for n in ('coverage_sim', 'coverage_planner',
                                                    'coverage_monitor'))
        if bag_dir is not None:
            graph.record(bag_dir, topics or launch_topics)

        def finished():
            p = planner.planner
            return p is not None and p.state in ('done', 'stuck', 'incomplete')
        outcome = graph.run_lockstep(sim, until=finished, max_sim_time=max_sim_time)
        # One more period so the final status, markers and monitor figures are published, and a
        # moment of wall time for the recorder to receive the last messages.
        sim.advance()
        graph.drain()
        monitor.publish()
        graph.drain()
        if bag_dir is not None:
            graph.spin_wall(0.3)
        p = planner.planner
        wall = time.monotonic() - wall0
        path = np.asarray(monitor.path)
        length = float(np.sum(np.hypot(*np.diff(path, axis=0).T))) if len(path) > 1 else 0.0
        ut = np.asarray(planner.update_times) * 1e3
        sx, sy = map(float, world.start)
        graph = _shift_graph(graph_dict(p), sx, sy) if p is not None else None
        lower = monitor.cvs.lower_bound_path()
        result = {
            'world': str(world_path), 'world_name': world.name, 'detector': detector,
            'delta_m': delta, 'radius_m': radius, 'detector_range_m': det_range,
            'sonar_max_range_m': sonar_max_range,
            'outcome': 'complete' if p is not None and p.state == 'done' else (
                p.state if p is not None and p.state in ('stuck', 'incomplete') else outcome),
            'given_up_nodes': sorted(set(p.given_up)) if p is not None else [],
            'planner_state': p.state if p is not None else 'no_sweep',
            'sim_time_s': sim.sim_time, 'wall_time_s': wall,
            'covered_fraction_of_cvs': monitor.fraction,
            'cvs_area_m2': monitor.cvs.area,
            'path_length_m': length, 'lower_bound_path_m': lower,
            'path_over_lower_bound': length / lower if lower > 0 else None,
            'planner_update_ms': {'median': float(np.median(ut)) if len(ut) else None,
                                  'p99': float(np.percentile(ut, 99)) if len(ut) else None,
                                  'sweeps': int(len(ut))},
            'planner': planner_name, 'without': list(parse_without(without)),
            # The modes the planner node ran with (its PaperConfig against the default's).
            'modes': _modes_of(planner.config) if planner_name == 'paper' else {},
            'hierarchical_graph': graph,
            'decisions': [list(d) for d in (p.decisions if p is not None else [])],
            # Every event (sensed: critical, cusp, meet; cell_closed, node_created, ...):
            # [sim time, kind, x, y (map), detail].
            'events': _shift_events(p.events if p is not None else [], sx, sy),
            'frames': 'path and graph in map; the planner works in odom (origin at start)',
            'path': np.round(path, 3).tolist(),
        }
        if p is not None and hasattr(p, 'primitive_lengths'):
            # Each path segment and the primitive that drove it (lap, boundary, gvd, transit).
            result['path_segments'] = [[k, round(v, 3)] for k, v in p.segments]
            result['primitive_lengths_m'] = p.primitive_lengths()
        layers = None
        if p is not None:
            from coverage_pkg.figure import planner_layers
            layers = planner_layers(p)
            if layers:
                e = layers['extent']
                layers['extent'] = (e[0] + sx, e[1] + sx, e[2] + sy, e[3] + sy)
        result['_layers'] = layers
        result['_uncovered'] = monitor.acc.uncovered_points()
        return result


def _shift_events(events, dx, dy):
    """Events [sim time, kind, x, y, detail] from the odom frame into the map frame."""
    return [[e[0], e[1], round(e[2] + dx, 3), round(e[3] + dy, 3), e[4]] for e in events]


def _shift_graph(g, dx, dy):
    """Graph dict from the odom frame (origin at the start) into the map frame."""
    def sh(p):
        return [p[0] + dx, p[1] + dy] + list(p[2:])
    for n in g['nodes']:
        n['anchor'] = sh(n['anchor'])
        n['centroid'] = sh(n['centroid'])
        if 'label_point' in n:
            n['label_point'] = sh(n['label_point'])
        n['critical_points'] = [sh(c) for c in n['critical_points']]
        n['meet_points'] = [sh(c) for c in n['meet_points']]
    for n in g['nodes']:
        for c in n.get('morse_cells', []):
            c['laps'] = [[x + dx, lo + dy, hi + dy] for x, lo, hi in c['laps']]
        for b in n.get('gvd_branches', []):
            b['start'] = sh(b['start'])
    for e in g['edges']:
        e['cusp_points'] = [sh(c) for c in e['cusp_points']]
        e['sensed_cusp_points'] = [sh(c) for c in e.get('sensed_cusp_points', [])]
        if e.get('shared_boundary_point') is not None:
            e['shared_boundary_point'] = sh(e['shared_boundary_point'])
    return g


def _run(args):
    validate_inputs(args.world, args.delta, args.radius, args.detector, args.sonar_max_range,
                    args.max_sim_time, args.planner, args.without, args.mode)
    label = planner_label(args.planner, args.without, args.mode)
    with output_dir(args.out, args.overwrite) as tmp:
        topics = [t for t in (args.record_topics or '').split(',') if t] or None
        result = run_coverage(args.world, args.delta, args.radius, args.detector,
                              bag_dir=tmp / 'bag', max_sim_time=args.max_sim_time,
                              sonar_max_range=args.sonar_max_range, seed=args.seed,
                              topics=topics, domain_id=args.domain_id, planner=args.planner,
                              without=args.without, modes=args.mode)
        layers = result.pop('_layers')
        uncovered = result.pop('_uncovered')
        write_json(tmp / 'result.json', result)
        from coverage_pkg.figure import render_coverage
        world = load_world(args.world)
        title = (f"{world.name}: {label}, {args.detector} detector "
                 f"(range {result['detector_range_m']:g}"
                 f" m), path {result['path_length_m']:.1f} m (lower bound "
                 f"{result['lower_bound_path_m']:.1f} m), covered "
                 f"{100 * result['covered_fraction_of_cvs']:.2f}% of CVS, "
                 f"{result['outcome']}")
        render_coverage(tmp / 'coverage.png', world, result['path'],
                        result['hierarchical_graph'], layers, uncovered, title)
    print(f"coverage {result['world_name']} ({label}, {args.detector} detector): "
          f"{result['outcome']} "
          f"after {result['sim_time_s']:.1f} s sim time in {result['wall_time_s']:.1f} s wall")
    print(f"covered {100 * result['covered_fraction_of_cvs']:.2f}% of CVS "
          f"({result['cvs_area_m2']:.1f} m^2); path {result['path_length_m']:.1f} m, lower "
          f"bound |CVS|/(2 range) {result['lower_bound_path_m']:.1f} m "
          f"(ratio {result['path_over_lower_bound']:.2f})")
    print(f'result: {Path(args.out) / "result.json"}; picture: '
          f'{Path(args.out) / "coverage.png"}')
    return 0 if result['outcome'] == 'complete' else 1


def _bench(args):
    validate_inputs(args.world, args.delta, args.radius, args.detector, args.sonar_max_range,
                    args.max_sim_time, args.planner, args.without, args.mode)
    result = run_coverage(args.world, args.delta, args.radius, args.detector, bag_dir=None,
                          max_sim_time=args.max_sim_time,
                          sonar_max_range=args.sonar_max_range, seed=args.seed,
                          domain_id=args.domain_id, planner=args.planner,
                          without=args.without, modes=args.mode)
    u = result['planner_update_ms']
    print(f"coverage benchmark {result['world_name']} ({args.detector} detector), "
          f"{result['outcome']}")
    print(f"planner update per sonar sweep: median {u['median']:.2f} ms, p99 {u['p99']:.2f} ms "
          f"over {u['sweeps']} sweeps (target: median < 5 ms)")
    print(f"whole run: {result['wall_time_s']:.1f} s wall for {result['sim_time_s']:.1f} s sim "
          f"(x{result['sim_time_s'] / max(result['wall_time_s'], 1e-9):.1f} real time)")
    print(f"covered {100 * result['covered_fraction_of_cvs']:.2f}% of CVS, path "
          f"{result['path_length_m']:.1f} m")
    return 0


def _common(parser):
    parser.add_argument('--world', required=True, help='world JSON file')
    parser.add_argument('--delta', type=float, default=2.0, help='detector range (m)')
    parser.add_argument('--radius', type=float, default=0.25, help='robot radius (m)')
    parser.add_argument('--detector', choices=('extended', 'robot'), default='extended',
                        help='extended-range detector (hierarchical decomposition) or the '
                        'robot-size baseline (plain boustrophedon; needs --planner grid)')
    parser.add_argument('--sonar-max-range', type=float, default=5.0,
                        help='sonar max range (m); must exceed --delta')
    parser.add_argument('--max-sim-time', type=float, default=4000.0,
                        help='sim-time limit (s)')
    parser.add_argument('--seed', type=int, default=1, help='sonar noise seed')
    add_planner_args(parser)
    parser.add_argument('--domain-id', type=int, default=None,
                        help='DDS domain of the run (default: $ROS_DOMAIN_ID, else a random '
                        'one in 101..232 so concurrent runs stay apart)')


def add_planner_args(parser):
    """``--planner``, the repeatable ``--without EVENT`` (paper planner ablations) and
    ``--mode NAME=VALUE`` (paper planner modes)."""
    parser.add_argument('--planner', choices=PLANNERS, default=DEFAULT_PLANNER,
                        help='paper: Algorithm 1 driven by sensed events alone '
                        '(coverage_pkg/algorithm1.py); grid: the frontier-driven evidence-grid '
                        f"planner (ours, not the paper's). Default: {DEFAULT_PLANNER}")
    parser.add_argument('--without', action='append', choices=EVENTS, default=[],
                        help='switch the sensing of this event off in the paper planner '
                        '(repeatable)')
    parser.add_argument('--mode', action='append', default=[], metavar='NAME=VALUE',
                        help="a mode of the paper planner (repeatable, later ones override "
                        "earlier ones): 'rules=paper' sets every sensing rule of ours to the "
                        "paper's reading, 'handover=false' is Algorithm 1's pseudocode order, "
                        "'ours=on' turns on seven of the modes of ours that are off in the "
                        'default (OUR_MODES); the names: coverage_pkg/algorithm1.py MODE_FIELDS')


def register(subparsers):
    """Add ``paramotion coverage`` and ``paramotion coverage-benchmark``."""
    stamp = datetime.datetime.now().strftime('%Y%m%d-%H%M%S')
    parser = subparsers.add_parser(
        'coverage', help='sensor-based coverage with an extended-range detector',
        description='Run the coverage graph (PyBullet robot, sonar ring, online planner, '
        'monitor) headless on sim time; write bag/, result.json and coverage.png.')
    _common(parser)
    add_output_args(parser, default_out=os.path.join('bags', 'runs', f'coverage-{stamp}'))
    parser.add_argument('--record-topics', default='',
                        help='comma-separated topics to record (default: ' + ','.join(TOPICS)
                        + ')')
    parser.set_defaults(func=_run)  # coverage_pkg.sweep adds ``sweep`` under it
    bench = subparsers.add_parser(
        'coverage-benchmark', help='time the coverage planner and the whole graph',
        description='Run the coverage graph without recording; print the planner update time '
        'per sonar sweep (median, p99) and wall time against sim time.')
    _common(bench)
    bench.set_defaults(func=_bench)
    gen = subparsers.add_parser(
        'coverage-worlds', help='write generated coverage worlds (unseen test inputs)',
        description='Write N seeded worlds (rooms with doors, corridor mazes with dead ends, '
        'L/T halls, clutter) in the world JSON format to a directory.')
    gen.add_argument('--out', required=True, help='directory to write the worlds into')
    gen.add_argument('--count', type=int, default=10, help='number of worlds')
    gen.add_argument('--seed', type=int, default=0, help='seed of the first world')
    gen.add_argument('--kind', default=None, help='rooms, maze, halls or mixed (default: the '
                     'seed chooses)')
    gen.set_defaults(func=_worlds)
    ratio = subparsers.add_parser(
        'coverage-ratio', help='path / lower bound over a directory of worlds (ROS-free loop)',
        description='Cover every world JSON in a directory with the planner in the ROS-free '
        'kinematic loop; print covered %% of CVS, path, lower bound |CVS|/(2 delta) and ratio '
        'per world, and the mean.')
    ratio.add_argument('--worlds', required=True, help='directory of world JSON files')
    ratio.add_argument('--baseline', action='store_true',
                       help='also run the robot-size baseline and print extended/baseline')
    ratio.add_argument('--oracle', action='store_true',
                       help='also plan the full-knowledge route (coverage_pkg/oracle.py, reads '
                       'the true world) and print its ratio and planner/oracle')
    ratio.add_argument('--floor', action='store_true',
                       help='also the floor of Algorithm 1 on the true world '
                       '(coverage_pkg/algorithm1_floor.py: its GVD edges and circles at D = '
                       'delta, each driven once) and planner/floor')
    ratio.add_argument('--events', action='store_true',
                       help='also check every sensed cusp and meet point against the true '
                       'world (coverage_pkg/event_check.py, fine ray casting; evaluation only)')
    ratio.add_argument('--max-sim-time', type=float, default=3000.0, help='per world (s)')
    add_planner_args(ratio)
    ratio.set_defaults(func=_ratio)


def _ratio(args):
    from coverage_pkg.kinematic import ratio_report
    paths = sorted(Path(args.worlds).glob('*.json'))
    if not paths:
        raise UserError(f'--worlds {args.worlds}: no .json world files there')
    validate_inputs(paths[0], 2.0, 0.25, 'extended', 5.0, 1.0, args.planner, args.without,
                    args.mode)
    config = PaperConfig(without=parse_without(args.without), **parse_modes(args.mode)) \
        if args.planner == 'paper' else None
    ratio_report(paths, config, baseline=args.baseline, oracle=args.oracle,
                 max_time=args.max_sim_time, events=args.events, floor=args.floor)
    return 0


def _worlds(args):
    from coverage_pkg.worldgen import write_worlds
    paths = write_worlds(args.out, args.count, args.seed, args.kind)
    print(f'{len(paths)} worlds written to {args.out}')
    return 0
