"""``paramotion coverage sweep --worlds DIR [--planner paper|grid]``: coverage over many worlds.

Every world JSON in ``DIR`` is one independent case: a whole lock-step coverage run
(:func:`coverage_pkg.scenario.run_coverage`, no bag) in its own private ROS domain, run as a
Dask task (:mod:`paramotion.sweep`; ``--serial`` runs them here one after the other). Writes
``OUT/<world>.json`` (the run's result, as ``paramotion coverage`` writes it) per world and
``OUT/summary.json`` with covered % of CVS, path, lower bound |CVS|/(2 delta) and their ratio per
world and the mean ratio. Results do not depend on Dask: the runs are lock-step and seeded.
"""
from __future__ import annotations

import argparse
import datetime
import os
from collections.abc import Mapping
from pathlib import Path

from coverage_pkg.scenario import DEFAULT_PLANNER, PLANNERS, run_coverage, validate_inputs
from paramotion.errors import UserError
from paramotion.scenario_io import add_output_args, output_dir, write_json
from paramotion.sweep import add_dask_args, run_args, run_tasks


def coverage_case(case: Mapping[str, object]) -> dict[str, object]:
    """One world of the sweep: the result dict of :func:`run_coverage` (JSON-ready).
    Module-level so that Dask can ship it to a worker process."""
    result = run_coverage(case['world'], case['delta'], case['radius'], case['detector'],
                          bag_dir=None, max_sim_time=case['max_sim_time'],
                          sonar_max_range=case['sonar_max_range'], seed=case['seed'],
                          planner=case.get('planner', DEFAULT_PLANNER))
    result.pop('_layers', None)
    result.pop('_uncovered', None)
    return result


def summary_row(name: str, result: Mapping[str, object]) -> dict[str, object]:
    """The summary line of one world: coverage, path, lower bound, ratio, outcome."""
    return {'world': name, 'outcome': result['outcome'],
            'covered_percent_of_cvs': 100.0 * result['covered_fraction_of_cvs'],
            'path_length_m': result['path_length_m'],
            'lower_bound_path_m': result['lower_bound_path_m'],
            'path_over_lower_bound': result['path_over_lower_bound'],
            'sim_time_s': result['sim_time_s']}


def _sweep(args):
    folder = Path(args.worlds)
    if not folder.is_dir():
        raise UserError(f'--worlds {args.worlds}: not a directory')
    paths = sorted(folder.glob('*.json'))
    if not paths:
        raise UserError(f'--worlds {args.worlds}: no .json world files there')
    for path in paths:  # every world checked before any run starts
        validate_inputs(str(path), args.delta, args.radius, args.detector,
                        args.sonar_max_range, args.max_sim_time, args.planner)
    cases = [{'world': str(p), 'delta': args.delta, 'radius': args.radius,
              'detector': args.detector, 'max_sim_time': args.max_sim_time,
              'sonar_max_range': args.sonar_max_range, 'seed': args.seed,
              'planner': args.planner} for p in paths]
    with output_dir(args.out, args.overwrite) as tmp:
        results = run_tasks(coverage_case, cases, desc='coverage sweep', **run_args(args))
        rows = []
        for path, result in zip(paths, results):
            write_json(tmp / f'{path.stem}.json', result)
            rows.append(summary_row(path.stem, result))
        ratios = [r['path_over_lower_bound'] for r in rows
                  if r['path_over_lower_bound'] is not None]
        mean = sum(ratios) / len(ratios) if ratios else None
        write_json(tmp / 'summary.json', {
            'worlds': str(folder), 'planner': args.planner, 'detector': args.detector,
            'delta_m': args.delta,
            'radius_m': args.radius, 'max_sim_time_s': args.max_sim_time, 'seed': args.seed,
            'rows': rows, 'mean_path_over_lower_bound': mean})
    print(f'{"world":24s} {"outcome":>10s} {"covered %":>9s} {"path m":>8s} {"bound m":>8s} '
          f'{"ratio":>6s}')
    for r in rows:
        ratio = r['path_over_lower_bound']
        print(f'{r["world"]:24s} {r["outcome"]:>10s} {r["covered_percent_of_cvs"]:9.2f} '
              f'{r["path_length_m"]:8.1f} {r["lower_bound_path_m"]:8.1f} '
              + (f'{ratio:6.2f}' if ratio is not None else '     -'))
    print('mean ratio path / lower bound: ' + (f'{mean:.2f}' if mean is not None else '-')
          + f'; results: {Path(args.out) / "summary.json"}')
    return 0


def register_sweep(parser: argparse.ArgumentParser) -> None:
    """Hang ``sweep`` under the ``paramotion coverage`` parser without changing a plain run:
    ``--world`` stays required for a run (checked when no action is given)."""
    for action in parser._actions:
        if action.dest == 'world':
            action.required = False
    run = parser.get_default('func')

    def run_or_fail(args):
        if args.world is None:
            raise UserError('--world FILE is required for a run (or: paramotion coverage '
                            'sweep --worlds DIR)')
        return run(args)

    parser.set_defaults(func=run_or_fail)
    sub = parser.add_subparsers(dest='coverage_action', metavar='ACTION')
    sweep = sub.add_parser(
        'sweep', help='coverage over every world JSON of a directory, cases as Dask tasks',
        description=__doc__.split('\n')[0])
    sweep.add_argument('--worlds', required=True, help='directory of world JSON files')
    sweep.add_argument('--delta', type=float, default=2.0, help='detector range (m)')
    sweep.add_argument('--radius', type=float, default=0.25, help='robot radius (m)')
    sweep.add_argument('--planner', choices=PLANNERS, default=DEFAULT_PLANNER,
                       help='paper: Algorithm 1 (coverage_pkg/algorithm1.py); grid: ours, '
                            f'the frontier-driven grid planner. Default: {DEFAULT_PLANNER}')
    sweep.add_argument('--detector', choices=('extended', 'robot'), default='extended',
                       help='extended-range detector or the robot-size baseline')
    sweep.add_argument('--sonar-max-range', type=float, default=5.0, help='sonar max range (m)')
    sweep.add_argument('--max-sim-time', type=float, default=4000.0,
                       help='sim-time limit per world (s)')
    sweep.add_argument('--seed', type=int, default=1, help='sonar noise seed')
    stamp = datetime.datetime.now().strftime('%Y%m%d-%H%M%S')
    add_output_args(sweep, default_out=os.path.join('bags', 'runs', f'coverage-sweep-{stamp}'))
    add_dask_args(sweep)
    sweep.set_defaults(func=_sweep)


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add ``sweep`` to the ``paramotion coverage`` subcommand that
    :mod:`coverage_pkg.scenario` registered (``paramotion.cli`` registers that module first)."""
    register_sweep(subparsers.choices['coverage'])
