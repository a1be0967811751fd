"""Measure the paper planner on generated worlds (issue 28's targets), ROS-free.

``python -m coverage_pkg.paper_measure --seeds 100-105 [--jobs 2] [--png DIR]`` generates the
worlds of :mod:`coverage_pkg.worldgen` for the seeds (``--world FILE.json``, repeatable:
world files instead, such as ``../shared/worlds/*.json``), covers each with the paper planner
(:mod:`coverage_pkg.algorithm1`) in :func:`coverage_pkg.kinematic.run_kinematic`, and prints
per world and overall: the covered share of CVS, path / lower bound |CVS| / (2 delta), the
share of the path driven by lap, boundary and GVD primitives (not transit), each primitive's
path as a multiple of the lower bound (where the path goes), and the planner
update time per sweep (median and 99th percentile of the CPU time of the planner's thread,
``time.thread_time``, so that other jobs on a shared machine do not count). ``--png`` draws
each run; ``--floor`` adds the floor of Algorithm 1's path on the true world
(:mod:`coverage_pkg.algorithm1_floor`) and path / floor: how far the planner is from what the
method needs, and the nearest-first walk over what it must drive (what an idealised online
order needs), also with each curve D = delta driven round before the edges that leave it
(Algorithm 1's order in a vast cell).
"""
from __future__ import annotations

import argparse
import dataclasses
import sys
import tempfile
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np

from coverage_pkg.algorithm1 import PaperConfig, parse_modes
from paramotion.errors import UserError

PRIMITIVES = ('lap', 'boundary', 'gvd', 'transit')


def parse_seeds(text: str) -> list[int]:
    """Seeds from '100-105' or '100,103,200-202'."""
    out = []
    for part in text.split(','):
        a, _, b = part.partition('-')
        out += list(range(int(a), int(b or a) + 1))
    return out


def parse_config(items: list[str]) -> dict[str, object]:
    """PaperConfig fields from 'name=value' strings (typed like the field's default; any
    field, the thresholds too; ``rules=paper`` and ``ours=on`` as in
    :func:`coverage_pkg.algorithm1.parse_modes`)."""
    try:
        return parse_modes(items, fields=[f.name for f in dataclasses.fields(PaperConfig)])
    except UserError as exc:
        raise SystemExit(f'--set: {exc}') from None


def measure_world(seed: int | str, png_dir: str | None = None, max_time: float = 3000.0,
                  config: dict[str, object] | None = None,
                  floor: bool = False) -> dict[str, object]:
    """One world covered by the paper planner; the measured figures. ``seed``: the
    generator's seed (int) or a world file's path (str). ``floor``: also the floor of
    Algorithm 1's path on the true world (:mod:`coverage_pkg.algorithm1_floor`)."""
    from coverage_pkg.kinematic import run_kinematic
    from coverage_pkg.world import load_world
    from coverage_pkg.worldgen import write_worlds
    if isinstance(seed, str):
        world = load_world(seed)
    else:
        with tempfile.TemporaryDirectory() as tmp:
            world = load_world(write_worlds(tmp, 1, seed=seed)[0])
    r = run_kinematic(world, PaperConfig(**(config or {})), max_time=max_time,
                      clock=time.thread_time)
    planner = r['planner']
    lengths = planner.primitive_lengths()
    total = sum(lengths.values())
    ut = np.asarray(r['update_times']) * 1e3
    row = {'world': world.name, 'state': r['state'], 'covered': r['covered_fraction'],
           'ratio': r['path_length'] / r['lower_bound'],
           'primitive': 1.0 - lengths.get('transit', 0.0) / total if total else 0.0,
           'median_ms': float(np.median(ut)), 'p99_ms': float(np.percentile(ut, 99)),
           'sim': r['sim_time'], 'wall': r['wall_time'],
           'per_bound': {k: lengths.get(k, 0.0) / r['lower_bound'] * (
               r['path_length'] / total if total else 0.0) for k in PRIMITIVES}}
    if floor:
        from coverage_pkg.algorithm1_floor import (
            algorithm1_floor,
            driven_again,
            nearest_first_walks,
        )
        cfg = PaperConfig(**(config or {}))
        f = algorithm1_floor(world, cfg.radius, cfg.delta, cfg.view_margin)
        row['floor'] = f['floor'] / r['lower_bound']
        w = nearest_first_walks(world, cfg.radius, cfg.delta, cfg.view_margin)
        row['walk'] = w['any_order']['walk'] / r['lower_bound']
        row['walk_circuits'] = w['circuits_first']['walk'] / r['lower_bound']
        row['required'] = w['required'] / r['lower_bound']
        row['again'] = driven_again(r['path']) / r['lower_bound']
    if png_dir:
        from coverage_pkg.figure import render_coverage
        Path(png_dir).mkdir(parents=True, exist_ok=True)
        render_coverage(Path(png_dir) / f'{world.name}.png', world, np.asarray(r['path']),
                        planner.to_dict(), None, r['accumulator'].uncovered_points(),
                        title=f"{world.name}: {100 * row['covered']:.1f} %")
    return row


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument('--seeds', default='100-105', help="e.g. '100-105' or '100,300-305'")
    ap.add_argument('--world', action='append', default=[], metavar='FILE.json',
                    help='a world file instead of generated seeds (repeatable)')
    ap.add_argument('--jobs', type=int, default=1, help='worlds run in parallel')
    ap.add_argument('--png', default=None, help='directory for one picture per world')
    ap.add_argument('--max-sim-time', type=float, default=3000.0)
    ap.add_argument('--floor', action='store_true',
                    help='also the floor of Algorithm 1 on the true world '
                    '(coverage_pkg/algorithm1_floor.py) as a multiple of the bound, path / '
                    'floor and the nearest-first walks (any order; circuits first) as multiples '
                    "of the bound, the floor's required length, and the path split into ground "
                    'driven for the first time and driven again (algorithm1_floor.driven_again)')
    ap.add_argument('--set', action='append', default=[], metavar='NAME=VALUE',
                    help="a PaperConfig field, e.g. 'circuit_sweeps=true', 'rules=paper' or "
                    "'ours=on' (repeatable; later ones override earlier ones)")
    args = ap.parse_args(argv)
    config = parse_config(args.set)
    if args.world:
        from coverage_pkg.world import load_world
        try:
            for path in args.world:
                load_world(path)          # a bad file: one line, before any run
        except UserError as exc:
            raise SystemExit(f'paper_measure: {exc}') from None
    seeds = list(args.world) or parse_seeds(args.seeds)
    with ProcessPoolExecutor(max(1, args.jobs)) as ex:
        rows = list(ex.map(measure_world, seeds, [args.png] * len(seeds),
                           [args.max_sim_time] * len(seeds), [config] * len(seeds),
                           [args.floor] * len(seeds)))
    floor_head = (' floor/bound | path/floor | nearest-first/bound | circuits-first/bound |'
                  ' required/bound | first-time/bound | again/bound |' if args.floor else '')
    print('| world | state | covered | path/bound | ' + ' | '.join(PRIMITIVES) +
          ' | primitives | update median ms (CPU) | p99 ms (CPU) | sim s |' + floor_head)
    print('|---' * (8 + len(PRIMITIVES) + 7 * args.floor) + '|')
    for r in rows:
        per = ' | '.join(f"{r['per_bound'][k]:.2f}" for k in PRIMITIVES)
        floor_cells = f" {r['floor']:.2f} | {r['ratio'] / r['floor']:.2f} | " \
            f"{r['walk']:.2f} | {r['walk_circuits']:.2f} | {r['required']:.2f} | " \
            f"{r['ratio'] - r['again']:.2f} | {r['again']:.2f} |" if args.floor else ''
        print(f"| {r['world']} | {r['state']} | {100 * r['covered']:.2f} % | {r['ratio']:.2f} | "
              f"{per} | {100 * r['primitive']:.1f} % | {r['median_ms']:.2f} | "
              f"{r['p99_ms']:.2f} | {r['sim']:.0f} |{floor_cells}")
    cov = [r['covered'] for r in rows]
    print(f"| mean ({len(rows)}) | - | {100 * np.mean(cov):.2f} % (min {100 * min(cov):.2f}) | "
          f"{np.mean([r['ratio'] for r in rows]):.2f} | " +
          ' | '.join(f"{np.mean([r['per_bound'][k] for r in rows]):.2f}" for k in PRIMITIVES) +
          f" | {100 * np.mean([r['primitive'] for r in rows]):.1f} % | "
          f"{np.median([r['median_ms'] for r in rows]):.2f} | "
          f"{max(r['p99_ms'] for r in rows):.2f} | - |" +
          (f" {np.mean([r['floor'] for r in rows]):.2f} | "
           f"{np.mean([r['ratio'] / r['floor'] for r in rows]):.2f} | "
           f"{np.mean([r['walk'] for r in rows]):.2f} | "
           f"{np.mean([r['walk_circuits'] for r in rows]):.2f} | "
           f"{np.mean([r['required'] for r in rows]):.2f} | "
           f"{np.mean([r['ratio'] - r['again'] for r in rows]):.2f} | "
           f"{np.mean([r['again'] for r in rows]):.2f} |" if args.floor else ''))
    sys.stdout.flush()
    return 0


if __name__ == '__main__':
    sys.exit(main())
