"""``paramotion bench [--json] [--quick] [--only NAMES] [--world FILE]``: every headline figure.

Runs each part's own benchmark function once, in this one process, warm, median of repeats,
and prints a table; with ``--json`` the last line of stdout is one JSON object with every figure
(``null`` plus a ``not_measured`` reason when a figure could not be measured, never a made-up
number) and the machine's core counts. Each figure comes from a small adapter below that calls
the function its part maintains, so a part's faster implementation shows up here unchanged.
Speed is printed here and never asserted by tests. ``--quick`` uses fewer/shorter repeats (for
tests and a smoke check), so its figures are noisier and flagged ``"quick": true``.
"""
import json
import os
import statistics
import sys
import time
from pathlib import Path

from paramotion.errors import UserError

PACKAGED_WORLD = Path(__file__).resolve().parents[1] / 'coverage_pkg' / 'worlds' / \
    'two_rooms.json'


def bench_fk(quick):
    """Gough-Stewart FK: warm single solves/s and batched solves/s (climber_pkg.fk_benchmark)."""
    from climber_pkg.fk_benchmark import benchmark_fk
    res = benchmark_fk(poses=2000 if quick else 20000, repeats=1 if quick else 5)
    return {'fk_single_per_s': float(res['fk_single_per_s']),
            'fk_batched_per_s': float(res['fk_batched_per_s']),
            'fk_batched_backend': res.get('fk_batched_backend')}


def bench_kntu(quick):
    """KNTU constant-orientation workspace poses/s at step 0.05 m (``workspace cow`` path)."""
    from cable_robot_pkg.cdrpm.workspace import benchmark_cow
    res = benchmark_cow(step=0.05, repeats=1 if quick else 7)
    return {'kntu_poses_per_s': float(res['kntu_poses_per_s']),
            'kntu_backend': res.get('kntu_backend')}


def bench_voronoi(quick):
    """Planar rho configurations/s and the paper's planar query planning time (as in
    ``paramotion voronoi bench``: random configurations, seed 0; cold planner per query)."""
    import numpy as np

    from voronoi_pkg.planar import PAPER_GOAL, PAPER_START, paper_model
    from voronoi_pkg.planner import VoronoiPlanner
    model = paper_model()
    n = 20000 if quick else 200000
    d = model.domain
    q = np.random.default_rng(0).uniform([d.x[0], d.y[0], d.phi[0]],
                                         [d.x[1], d.y[1], d.phi[1]], (n, 3))
    model.rho(q[:1000])  # warm-up
    rates = []
    for _ in range(1 if quick else 5):
        t = time.perf_counter()
        model.rho(q)
        rates.append(n / (time.perf_counter() - t))
    times = []
    for _ in range(1 if quick else 3):
        res = VoronoiPlanner(model).plan(PAPER_START, PAPER_GOAL)
        if not res.found:
            raise RuntimeError('paper query not solved')
        times.append(float(res.planning_time))
    return {'rho_per_s': statistics.median(rates),
            'voronoi_paper_query_s': statistics.median(times)}


def bench_fast(quick):
    """Real-time factor of the whole FAST graph in one process (fast.scenario)."""
    from cable_robot_pkg.fast.scenario import bench_real_time_factor
    res = bench_real_time_factor(duration=1.0 if quick else 10.0, repeat=1 if quick else 3)
    return {'fast_real_time_factor': float(res['real_time_factor'])}


def bench_coverage(quick, world):
    """Sim seconds per wall second of the coverage graph on ``world`` (two_rooms)."""
    from coverage_pkg.scenario import run_coverage
    res = run_coverage(str(world), bag_dir=None, max_sim_time=20.0 if quick else 3000.0)
    return {'coverage_two_rooms_sim_per_wall':
            float(res['sim_time_s']) / max(float(res['wall_time_s']), 1e-9),
            'coverage_world': str(world)}


# name -> (adapter, keys it measures, table label with unit)
BENCHES = {
    'fk': (bench_fk, {'fk_single_per_s': 'FK single (warm) solves/s',
                      'fk_batched_per_s': 'FK batched solves/s'}),
    'kntu': (bench_kntu, {'kntu_poses_per_s': 'KNTU cow poses/s (step 0.05)'}),
    'voronoi': (bench_voronoi, {'rho_per_s': 'planar rho configurations/s',
                                'voronoi_paper_query_s': 'Voronoi paper query s'}),
    'fast': (bench_fast, {'fast_real_time_factor': 'FAST real-time factor'}),
    'coverage': (bench_coverage, {'coverage_two_rooms_sim_per_wall':
                                  'coverage two_rooms sim s / wall s'}),
}


def cores():
    """Logical cores of the machine and those this process may run on."""
    from paramotion.backend import usable_cores
    return {'cpu_count': os.cpu_count(), 'usable_cores': usable_cores()}


def run_benchmarks(names, quick=False, world=None, log=print):
    """Run the benchmarks ``names`` (keys of :data:`BENCHES`); returns the figures dict.

    A benchmark that cannot run (missing world, a part failing) gives ``None`` for its keys and
    a reason in ``not_measured``."""
    out = {'quick': bool(quick), **cores(), 'not_measured': {}, 'seconds': {}}
    for name in names:
        fn, keys = BENCHES[name]
        for key in keys:
            out[key] = None
        if name == 'coverage' and world is None:
            out['not_measured']['coverage'] = 'no two_rooms world (use --world FILE)'
            continue
        log(f'bench {name} ...')
        start = time.perf_counter()
        try:
            res = fn(quick, world) if name == 'coverage' else fn(quick)
        except Exception as exc:  # one broken part must not hide the other figures
            out['not_measured'][name] = f'{type(exc).__name__}: {exc}'
            continue
        out['seconds'][name] = time.perf_counter() - start
        out.update(res)
    return out


def table(res):
    """The figures as printable lines."""
    lines = [f'{"figure":38s} {"value":>14s}']
    for name, (_, keys) in BENCHES.items():
        for key, label in keys.items():
            if key not in res:
                continue
            v = res[key]
            text = f'not measured: {res["not_measured"].get(name, "?")}' if v is None else \
                (f'{v:14.3f}' if v < 100 else f'{v:14,.0f}')
            lines.append(f'{label:38s} {text}')
    lines.append(f'cores: {res["cpu_count"]} (usable {res["usable_cores"]})'
                 + ('; --quick: fewer/shorter repeats' if res['quick'] else ''))
    return lines


def _main(args):
    names = list(BENCHES) if not args.only else [n.strip() for n in args.only.split(',')]
    bad = [n for n in names if n not in BENCHES]
    if bad or not names:
        raise UserError(f'--only {args.only!r}: unknown {bad}; choose from {", ".join(BENCHES)}')
    world = None
    if 'coverage' in names:
        world = Path(args.world) if args.world else (PACKAGED_WORLD if PACKAGED_WORLD.is_file()
                                                     else None)
        if world is not None and not world.is_file():
            raise UserError(f'--world {args.world}: no such file')
    log = (lambda m: print(m, file=sys.stderr, flush=True)) if args.json else print
    res = run_benchmarks(names, quick=args.quick, world=world, log=log)
    for line in table(res):
        print(line)
    if args.json:
        print(json.dumps(res, sort_keys=True))
    return 0


def register(subparsers):
    """Add ``paramotion bench``."""
    p = subparsers.add_parser('bench', help='run every headline benchmark once, print a table',
                              description=__doc__.split('\n')[0])
    p.add_argument('--json', action='store_true', help='also print the figures as one JSON '
                   'object on the last line of stdout')
    p.add_argument('--quick', action='store_true', help='fewer, shorter repeats (noisier)')
    p.add_argument('--only', default='', help='comma-separated subset of: ' + ', '.join(BENCHES))
    p.add_argument('--world', default=None, help='coverage world JSON (default: the packaged '
                   'coverage_pkg/worlds/two_rooms.json)')
    p.set_defaults(func=_main)
