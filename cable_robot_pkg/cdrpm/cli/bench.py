"""``paramotion workspace bench``: COW poses per second with all checks, beside the paper's 373
s for 148,000 points.

Argument parsing lives in :mod:`cable_robot_pkg.cdrpm.cli`; this module turns parsed
arguments into a call of the analysis in :mod:`cable_robot_pkg.cdrpm` and writes its outputs.
"""

import os
import statistics

import numpy as np

from cable_robot_pkg.cdrpm.cli import common
from paramotion.errors import UserError


def run(args):
    from cable_robot_pkg.cdrpm.workspace import (
        PAPER_POINTS,
        PAPER_SECONDS,
        constant_orientation_workspace,
    )

    desc = common.robot(args)
    if not 1000 <= args.points <= common.MAX_GRID_POINTS:
        raise UserError(f'--points {args.points}: allowed [1000, {common.MAX_GRID_POINTS}]')
    if not 1 <= args.runs <= 100:
        raise UserError(f'--runs {args.runs}: allowed [1, 100]')
    common.finite('--rot', args.rot, -180, 180)
    span = 2 * (desc.frame_half_size - desc.platform_half_size)
    step = float((np.prod(span) / args.points) ** (1.0 / 3.0))
    constant_orientation_workspace(desc, args.rot, step=step)     # warm-up
    times, cow = [], None
    from tqdm import tqdm
    for _ in tqdm(range(args.runs), desc='bench', unit='run', leave=False):
        cow = constant_orientation_workspace(desc, args.rot, step=step)
        times.append(cow.wall_time_s)
    median = statistics.median(times)
    n = cow.counts['total_points']
    rate = n / median
    t_paper_grid = PAPER_POINTS / rate
    result = {
        'robot': desc.name, 'rotation_deg': list(args.rot), 'grid_points': n,
        'grid_step_m': step, 'runs': args.runs, 'times_s': times, 'median_s': median,
        'poses_per_second': rate, 'checks_per_pose_eq9': desc.checks_per_pose(),
        'time_for_148000_points_s': t_paper_grid, 'paper_time_s': PAPER_SECONDS,
        'speedup_vs_paper': PAPER_SECONDS / t_paper_grid, 'counts': cow.counts,
        'cpu_count': os.cpu_count(),
    }
    print(f'COW benchmark, robot {common.robot_label(desc)}, rotation {args.rot} deg, all checks '
          f'({desc.checks_per_pose()} per pose, eq. 9): {n} points, median of {args.runs} runs '
          f'{median * 1e3:.1f} ms')
    print(f'  {rate:,.0f} poses/s -> 148,000 points in {t_paper_grid:.3f} s '
          f'(paper: {PAPER_SECONDS:.0f} s on a 4.3 GHz CPU, x{PAPER_SECONDS / t_paper_grid:,.0f});'
          f' target >= 300,000 poses/s: {"met" if rate >= 300000 else "NOT met"}')
    if args.out:
        common.write_outputs(common.out_dir(args.out), result)
    return 0
