"""``paramotion voronoi``: simplified Voronoi diagram planning (Vaca, Aranda & Thomas).

* ``plan``: the planar platform of section 6 (or a scene file); writes ``result.json``,
  ``figure2.png`` (Fig. 2 (a)-(f) at phi = pi/4) and ``figure3.png`` (Fig. 3 with the path).
* ``plan321``: the spatial 3-2-1 platform of Fig. 1 in a polyhedral scene; writes
  ``result.json`` and ``figure321.png``.
* ``bench``: median planar query time and rho evaluations per second.
"""
import json
import math
import statistics
import time
from pathlib import Path

import numpy as np

from paramotion.errors import UserError

_STAGES = ('retract', 'slices', 'search', 'verify')


def register(subparsers):
    """Add ``paramotion voronoi {plan,plan321,bench}``."""
    parser = subparsers.add_parser(
        'voronoi', help='simplified Voronoi diagram planner (Gough-Stewart, Vaca et al.)',
        description='Motion planning on simplified Voronoi diagrams of determinant predicates.')
    sub = parser.add_subparsers(dest='voronoi_command', metavar='ACTION')
    sub.required = True

    p = sub.add_parser('plan', help='plan for the planar platform of section 6',
                       description='Plan a singularity- and collision-free path for the '
                       'planar platform; write DIR/result.json, DIR/figure2.png and '
                       'DIR/figure3.png.')
    p.add_argument('--start', nargs=3, type=float, required=True, metavar=('X', 'Y', 'PHI_DEG'))
    p.add_argument('--goal', nargs=3, type=float, required=True, metavar=('X', 'Y', 'PHI_DEG'))
    p.add_argument('--scene', help='planar scene JSON (default: the paper scene)')
    p.add_argument('--out', required=True, help='output directory')
    p.add_argument('--grid', type=float, default=1.0, help='grid spacing in x, y (units)')
    p.add_argument('--slice-deg', type=float, default=2.5, help='orientation slice spacing')
    p.add_argument('--no-figures', action='store_true', help='write result.json only')
    _add_without(p, 'singularity (the factors of P1), collision (the predicates of P2)')
    p.set_defaults(func=_plan)

    p = sub.add_parser('plan321', help='plan for the spatial 3-2-1 platform of Fig. 1',
                       description='Plan between two poses of the 3-2-1 platform among '
                       'polyhedral obstacles: samples retracted onto the simplified Voronoi '
                       'diagram (rho ascent until two contacts tie), edges traced along it; '
                       'write DIR/result.json and DIR/figure321.png.')
    p.add_argument('--start', nargs=6, type=float, metavar=('X', 'Y', 'Z', 'ROLL', 'PITCH',
                                                             'YAW'),
                   help='start pose, m and deg (default: the demo start)')
    p.add_argument('--goal', nargs=6, type=float, metavar=('X', 'Y', 'Z', 'ROLL', 'PITCH',
                                                            'YAW'),
                   help='goal pose, m and deg (default: the demo goal)')
    p.add_argument('--scene', help='spatial scene JSON (default: the demo scene)')
    p.add_argument('--samples', type=int, default=400,
                   help='Halton samples retracted onto the diagram (default 400)')
    p.add_argument('--neighbours', type=int, default=8,
                   help='nearest diagram points each point is joined to (default 8)')
    p.add_argument('--seed', type=int, default=0, help='Halton scrambling seed')
    p.add_argument('--probe-step', type=float, default=0.01,
                   help='edge tracing resolution along the diagram (scaled m, default 0.01)')
    p.add_argument('--max-gap', type=float, default=0.03,
                   help='largest gap between traced diagram points (scaled m, default 0.03)')
    p.add_argument('--leg-min', type=float, help='minimum leg length, m (default: scene, '
                   'demo 0.35)')
    p.add_argument('--leg-max', type=float, help='maximum leg length, m (default: scene, '
                   'demo 1.55)')
    p.add_argument('--no-leg-limits', action='store_true', help='legs of any length')
    p.add_argument('--repeats', type=int, default=1,
                   help='plan this many times and print the median planning time')
    _add_without(p, 'singularity (the three pure-condition factors), collision (the '
                 'robot-obstacle contacts: segment-face, box edge-platform, containment)')
    p.add_argument('--out', required=True, help='output directory')
    p.set_defaults(func=_plan321)

    p = sub.add_parser('bench', help='benchmark query time and rho evaluations per second')
    p.add_argument('--repeats', type=int, default=5)
    p.add_argument('--configs', type=int, default=1_000_000,
                   help='configurations per rho evaluation batch')
    p.set_defaults(func=_bench)


def _add_without(parser, constructs):
    """The repeatable ``--without NAME`` ablation option (names: planar.CONSTRUCTS)."""
    parser.add_argument('--without', action='append', default=[], metavar='NAME',
                        help='switch a construct of the paper off (ablation; repeatable): '
                             + constructs)


def _check_out(out):
    out = Path(out)
    if out.exists() and not out.is_dir():
        raise UserError(f'--out {out}: exists and is not a directory')
    return out


def _plan(args):
    from tqdm import tqdm

    from voronoi_pkg.planar import load_scene, paper_model
    from voronoi_pkg.planner import VoronoiPlanner, validate_configuration

    if not (args.grid > 0 and math.isfinite(args.grid)):
        raise UserError(f'--grid {args.grid}: must be a positive number')
    if not (0 < args.slice_deg <= 45):
        raise UserError(f'--slice-deg {args.slice_deg}: must be in (0, 45]')
    out = _check_out(args.out)
    model = (load_scene(args.scene, args.without) if args.scene
             else paper_model(without=args.without))
    start = np.array([args.start[0], args.start[1], math.radians(args.start[2])])
    goal = np.array([args.goal[0], args.goal[1], math.radians(args.goal[2])])
    validate_configuration(model, start, 'start')   # refuse bad input before writing
    validate_configuration(model, goal, 'goal')
    planner = VoronoiPlanner(model, h=args.grid, dphi_deg=args.slice_deg)
    bar = tqdm(total=len(_STAGES), desc='voronoi plan', unit='stage', leave=False)

    def progress(stage):
        bar.set_postfix_str(stage)
        bar.update(1)

    res = planner.plan(start, goal, progress=progress)
    bar.close()
    out.mkdir(parents=True, exist_ok=True)
    doc = {
        'status': res.status,
        'reason': res.reason,
        'start': start.tolist(),
        'goal': goal.tolist(),
        'scene': args.scene or 'paper (section 6)',
        'path': np.round(res.path, 9).tolist(),
        'path_note': 'configurations [x, y, phi_rad]; phi is continuous (unwrapped); '
                     'consecutive points differ by <= 0.05 units and <= 0.01 rad and every '
                     'point has rho > 0 with no sign change of a pure-condition determinant',
        'min_rho': None if math.isnan(res.min_rho) else res.min_rho,
        'max_rho_step': None if math.isnan(res.max_rho_step) else res.max_rho_step,
        'planning_time_s': res.planning_time,
        'on_diagram_fraction': None if not res.found else res.on_diagram_fraction,
        'on_diagram_note': 'length share of the path (phi weighted by the platform length) '
                           'on diagram edges: straight tie pieces within a slice and links '
                           'between diagram vertices of consecutive slices; the rest is the '
                           'two retraction climbs (see stats.length_by_kind)',
        'clearance_profile': _profile(res),
        'grid': args.grid,
        'slice_deg': args.slice_deg,
        'without': list(args.without),
        'stats': {k: (float(v) if isinstance(v, (np.floating, float)) else
                      int(v) if isinstance(v, np.integer) else v)
                  for k, v in res.stats.items()},
    }
    (out / 'result.json').write_text(_dump(doc))
    if not args.no_figures:
        from voronoi_pkg.figures import figure2, figure3
        figure2(model, out / 'figure2.png')
        figure3(model, out / 'figure3.png', res.path if res.found else None)
    if res.found:
        print(f'path found: {len(res.path)} configurations, min rho {res.min_rho:.4g}, '
              f'on diagram {res.on_diagram_fraction:.3f}, '
              f'planning time {res.planning_time:.2f} s -> {out}')
        return 0
    print(f'no path: {res.reason} (planning time {res.planning_time:.2f} s) -> {out}')
    return 1


def _profile(res, points=200):
    """Clearance profile (arc length, rho) along the path, at most ``points`` samples plus
    the minimum."""
    c = res.clearance
    if not len(c):
        return None
    idx = np.unique(np.r_[np.linspace(0, len(c) - 1, min(points, len(c))).astype(int),
                          int(np.argmin(c[:, 1]))])
    return {'arc_length': np.round(c[idx, 0], 6).tolist(), 'rho': np.round(c[idx, 1], 6).tolist(),
            'note': 'arc length with phi weighted by the platform length; rho as in section 4 '
                    '(determinant units, twice an area)'}


def _dump(doc):
    """JSON with one path point per line (readable, and diffs stay small)."""
    path = doc.pop('path')
    text = json.dumps(doc, indent=1)
    points = ',\n  '.join(json.dumps(p) for p in path)
    return text[:-2] + ',\n "path": [\n  ' + points + '\n ]\n}\n'


def _pose_arg(values, default):
    if values is None:
        return np.asarray(default, dtype=float)
    v = np.asarray(values, dtype=float)
    return np.r_[v[:3], np.radians(v[3:])]


def _json_value(v):
    if isinstance(v, (np.integer,)):
        return int(v)
    if isinstance(v, (np.floating, float)):
        return None if math.isnan(v) else float(v)
    return v


def _plan321(args):
    """Plan between two poses and write ``out/result.json`` and ``out/figure321.png``."""
    from tqdm import tqdm

    from voronoi_pkg.figures import figure321
    from voronoi_pkg.spatial321 import (
        DEMO_GOAL,
        DEMO_LEG_LIMITS,
        DEMO_START,
        Spatial321Model,
        check_path6,
        demo_model,
        load_scene,
        validate_pose,
    )
    from voronoi_pkg.spatial321_roadmap import DiagramRoadmapPlanner

    out = _check_out(args.out)
    if args.no_leg_limits and (args.leg_min is not None or args.leg_max is not None):
        raise UserError('--no-leg-limits cannot be combined with --leg-min/--leg-max')
    limits = None
    if args.leg_min is not None or args.leg_max is not None:
        if args.leg_min is None or args.leg_max is None:
            raise UserError('--leg-min and --leg-max go together')
        limits = (args.leg_min, args.leg_max)
        if not (0 <= args.leg_min < args.leg_max and math.isfinite(args.leg_max)):
            raise UserError(f'--leg-min {args.leg_min} --leg-max {args.leg_max}: need '
                            '0 <= min < max (m)')
    if args.scene:
        model = load_scene(args.scene, leg_limits=limits, without=args.without)
        if args.no_leg_limits:
            model = Spatial321Model(model.base, model.platform, model.boxes,
                                    model.position_min, model.position_max, model.angle_max,
                                    without=model.without)
    else:
        model = demo_model(leg_limits=None if args.no_leg_limits
                           else (limits or DEMO_LEG_LIMITS), without=args.without)
    start = _pose_arg(args.start, DEMO_START)
    goal = _pose_arg(args.goal, DEMO_GOAL)
    validate_pose(model, start, 'start')
    validate_pose(model, goal, 'goal')
    if args.samples < 10:
        raise UserError(f'--samples {args.samples}: need at least 10')
    if args.neighbours < 2:
        raise UserError(f'--neighbours {args.neighbours}: need at least 2')
    planner = DiagramRoadmapPlanner(model, n_samples=args.samples, k=args.neighbours,
                                    seed=args.seed, probe_step=args.probe_step,
                                    max_gap=args.max_gap)
    stages = ('sample', 'retract', 'search', 'verify')
    bar = tqdm(total=len(stages), desc='voronoi plan321', unit='stage', leave=False)

    def progress(stage):
        bar.set_postfix_str(stage)
        bar.update(1)

    res = planner.plan(start, goal, progress)
    bar.close()
    if args.repeats < 1:
        raise UserError(f'--repeats {args.repeats}: need at least 1')
    runs = [res] + [planner.plan(start, goal) for _ in range(args.repeats - 1)]
    if args.repeats > 1:
        times = [r.planning_time for r in runs]
        cpu = [r.stats['cpu_time_s'] for r in runs]
        print(f'planning time over {len(times)} runs: median {statistics.median(times):.2f} s '
              f'wall (min {min(times):.2f}, max {max(times):.2f}), median '
              f'{statistics.median(cpu):.2f} s CPU')
    straight_ok = check_path6(model, np.vstack([start, goal]))[0]
    out.mkdir(parents=True, exist_ok=True)
    doc = {
        'status': res.status, 'reason': res.reason,
        'start': start.tolist(), 'goal': goal.tolist(),
        'pose_note': '[x, y, z] of P7 in m, [roll, pitch, yaw] ZYX in rad',
        'leg_length_limits_m': None if model.leg_limits is None else list(model.leg_limits),
        'straight_line_free': bool(straight_ok),
        'without': list(model.without),
        'min_rho': None if math.isnan(res.min_rho) else res.min_rho,
        'planning_time_s': res.planning_time,
        'resolution': {
            'samples': planner.n_samples, 'sampler': f'scrambled Halton, seed {planner.seed}',
            'neighbours': planner.k, 'probe_step': planner.probe_step,
            'max_gap': planner.max_gap, 'tie_tol': planner.tie_tol,
            'diagram_tol': planner.diagram_tol, 'check_step_m': planner.check_step,
            'check_dangle_rad': planner.check_dangle,
            'metric_note': 'scaled metric: m for positions, angle_scale = '
                           f'{model.angle_scale} m per rad for angles',
            'no_path_means': 'start and goal retractions in different connected components '
                             'of the diagram roadmap at this resolution (or different '
                             'singularity cells, a certificate)'},
        'stats': {k: _json_value(v) for k, v in res.stats.items()},
        'waypoints': np.round(res.waypoints, 9).tolist(),
        'path': np.round(res.path, 9).tolist(),
    }
    (out / 'result.json').write_text(json.dumps(doc) + '\n')
    figure321(model, out / 'figure321.png', res.path if res.found else None, start, goal)
    if res.found:
        print(f'path found: {len(res.path)} poses, min rho {res.min_rho:.4g}, on the diagram '
              f'{res.stats["on_diagram_fraction"]:.0%} of its length, planning time '
              f'{res.planning_time:.2f} s (straight line free: {straight_ok}) -> {out}')
        return 0
    print(f'no path: {res.reason} -> {out}')
    return 1


def _bench(args):
    from voronoi_pkg.planar import PAPER_GOAL, PAPER_START, paper_model
    from voronoi_pkg.planner import VoronoiPlanner

    if args.repeats < 1 or args.configs < 1000:
        raise UserError('--repeats must be >= 1 and --configs >= 1000')
    model = paper_model()
    rng = np.random.default_rng(0)
    d = model.domain
    q = rng.uniform([d.x[0], d.y[0], d.phi[0]], [d.x[1], d.y[1], d.phi[1]], (args.configs, 3))
    rates, rates_cpu, rates_active = [], [], []
    for _ in range(args.repeats):
        t = time.perf_counter()
        cpu = time.process_time()
        model.rho(q)
        rates_cpu.append(args.configs / max(time.process_time() - cpu, 1e-9))
        rates.append(args.configs / (time.perf_counter() - t))
        t = time.perf_counter()
        model.fields(q)
        rates_active.append(args.configs / (time.perf_counter() - t))
    print(f'planar rho (P1 AND P2, {model.programs["total"].n_leaves} signed leaves, '
          f'{len(model.programs["total"].keys)} determinants): median '
          f'{statistics.median(rates):.3g} configurations/s wall, '
          f'{statistics.median(rates_cpu):.3g} per CPU second (target > 1e6)')
    print(f'planar rho + smallest contact + singularity cell: median '
          f'{statistics.median(rates_active):.3g} configurations/s')
    cold, cold_cpu, warm, prepared = [], [], [], []
    for _ in range(args.repeats):
        planner = VoronoiPlanner(model)
        cpu = time.process_time()
        res = planner.plan(PAPER_START, PAPER_GOAL)
        cold_cpu.append(time.process_time() - cpu)
        if not res.found:
            raise RuntimeError('paper query not solved')
        cold.append(res.planning_time)
        warm.append(planner.plan(PAPER_START, PAPER_GOAL).planning_time)
        planner = VoronoiPlanner(model)
        planner.prepare()
        prepared.append(planner.plan(PAPER_START, PAPER_GOAL).planning_time)
    print(f'paper planar query (35,-20,90deg) -> (-10,-15,-90deg): planning time median '
          f'{statistics.median(cold):.3f} s cold (diagram slices computed lazily; CPU '
          f'{statistics.median(cold_cpu):.3f} s), '
          f'{statistics.median(warm):.3f} s warm (same slices cached), '
          f'{statistics.median(prepared):.3f} s with all slices prepared (as in the node); '
          f'on diagram {res.on_diagram_fraction:.3f} of the path length (targets < 1 s, '
          'stretch 0.25 s)')
    try:
        from voronoi_pkg.spatial321 import demo_model
    except ImportError:
        return 0
    sm = demo_model()
    n = max(1000, args.configs // 10)
    poses = sm.sample(np.random.default_rng(1), n)
    srates = []
    for _ in range(args.repeats):
        t = time.perf_counter()
        sm.rho(poses)
        srates.append(n / (time.perf_counter() - t))
    print(f'spatial 3-2-1 rho ({len(sm.program.keys)} 4x4 determinants): median '
          f'{statistics.median(srates):.3g} configurations/s')
    return 0
