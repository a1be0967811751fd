"""Benchmark of the Gough-Stewart forward kinematics (paramotion/gough_stewart.py).

Run: ``python -m climber_pkg.fk_benchmark [--poses 20000] [--repeats 5]``. Prints the median
over repeats of solves per second for (a) single-pose Newton-Raphson warm-started from the
previous solution along a smooth trajectory (what the climber does after every move and what a
1 kHz control loop does), (b) single-pose solves from a perturbed guess (1 cm, 2 deg), and (c)
the batched solver on all poses at once, with the median/max iteration counts and the worst
IK(FK(L)) - L residual. Rates are given per wall-clock second and per CPU second of the
process (the latter is not diluted by other jobs sharing the machine). Geometry: the climber's
default parameter file.
"""
import argparse
import statistics
import time

import numpy as np

from climber_pkg.robot import load_robot_config
from paramotion import gough_stewart as gs


def trajectory(geom, n, rng, step):
    """A smooth random pose trajectory (steps of about ``step`` m and ``step`` rad)."""
    home_h = 0.5 * (geom.leg_min + geom.leg_max)
    pos = np.array([0.0, 0.0, home_h]) + np.cumsum(rng.normal(scale=step, size=(n, 3)), axis=0)
    rpy = np.cumsum(rng.normal(scale=step, size=(n, 3)), axis=0)
    # Keep it inside the workspace: fold back with a smooth bounded map.
    pos[:, :2] = 0.05 * np.tanh(pos[:, :2] / 0.05)
    pos[:, 2] = home_h + 0.1 * np.tanh((pos[:, 2] - home_h) / 0.1)
    rpy = 0.15 * np.tanh(rpy / 0.15)
    return pos, gs.rotation_matrix(rpy)


def _clocks():
    return time.perf_counter(), time.process_time()


def _rates(n, start):
    wall, cpu = _clocks()
    return n / (wall - start[0]), n / max(cpu - start[1], 1e-9)


def bench_tracking(geom, lengths, pos, rot):
    p, r = pos[0], rot[0]
    iters = np.empty(len(lengths), dtype=int)
    t0 = _clocks()
    for k in range(len(lengths)):
        out = gs.forward_kinematics(geom, lengths[k], p, r)
        p, r = out.position, out.rotation
        iters[k] = out.iterations
    return _rates(len(lengths), t0), iters


def bench_perturbed(geom, lengths, gpos, grot):
    iters = np.empty(len(lengths), dtype=int)
    t0 = _clocks()
    for k in range(len(lengths)):
        iters[k] = gs.forward_kinematics(geom, lengths[k], gpos[k], grot[k]).iterations
    return _rates(len(lengths), t0), iters


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    parser.add_argument('--poses', type=int, default=20000, help='poses per run')
    parser.add_argument('--repeats', type=int, default=5, help='runs; the median is printed')
    parser.add_argument('--step', type=float, default=5e-4,
                        help='trajectory step between consecutive poses (m and rad)')
    args = parser.parse_args(argv)
    geom = load_robot_config().geometry
    rng = np.random.default_rng(0)
    pos, rot = trajectory(geom, args.poses, rng, args.step)
    lengths = gs.inverse_kinematics(geom, pos, rot)
    gpos = pos + rng.normal(scale=0.01, size=pos.shape)
    grot = gs.rotation_matrix(rng.normal(scale=np.radians(2), size=pos.shape)) @ rot
    rates = {'tracking': [], 'perturbed': [], 'batch': []}
    iters = {}
    worst = 0.0
    for _ in range(args.repeats):
        rate, iters['tracking'] = bench_tracking(geom, lengths, pos, rot)
        rates['tracking'].append(rate)
        rate, iters['perturbed'] = bench_perturbed(geom, lengths, gpos, grot)
        rates['perturbed'].append(rate)
        t0 = _clocks()
        out = gs.forward_kinematics_batch(geom, lengths, gpos, grot)
        rates['batch'].append(_rates(args.poses, t0))
        iters['batch'] = out.iterations
        assert out.converged.all()
        back = gs.inverse_kinematics(geom, out.positions, out.rotations)
        worst = max(worst, float(np.abs(back - lengths).max()))
    print(f'geometry: climber default, {args.poses} poses, median of {args.repeats} runs')
    tracking = f'single, warm-started along trajectory ({args.step:g} step)'
    for name, label in (('tracking', tracking),
                        ('perturbed', 'single, guess perturbed 1 cm / 2 deg'),
                        ('batch', 'batched, guess perturbed 1 cm / 2 deg')):
        it = iters[name]
        wall = statistics.median(r[0] for r in rates[name])
        cpu = statistics.median(r[1] for r in rates[name])
        print(f'{label:55s} {wall:8.0f} solves/s wall {cpu:8.0f} /CPU-s   '
              f'iterations median {np.median(it):.0f} max {it.max()}')
    print(f'worst |IK(FK(L)) - L| over batch: {worst:.2e} m')
    print("(solves/s wall: wall-clock rate; /CPU-s: per second of this process's CPU time, "
          'which other load on the machine does not inflate)')
    return 0


if __name__ == '__main__':
    raise SystemExit(main())
