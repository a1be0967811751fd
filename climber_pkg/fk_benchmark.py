"""Benchmark of the Gough-Stewart forward kinematics (paramotion/gough_stewart.py).

Run: ``python -m climber_pkg.fk_benchmark [--poses 20000] [--repeats 5]``. Prints the median
over repeats of solves per second for (a) single-pose Newton-Raphson warm-started from the
previous solution along a smooth trajectory (what the climber does after every move and what a
1 kHz control loop does), (b) single-pose solves from a perturbed guess (1 cm, 2 deg), and (c)
the batched solver on all poses at once (the numba kernel when installed, and numpy), with the
median/max iteration counts and the worst IK(FK(L)) - L residual. Rates are given per
wall-clock second and per CPU second of the process (the latter is not diluted by other jobs
sharing the machine). Geometry: the climber's default parameter file. :func:`benchmark_fk`
returns the headline figures for ``paramotion bench``.
"""
from __future__ import annotations

import argparse
import statistics
import time
from collections.abc import Sequence

import numpy as np

from climber_pkg.robot import load_robot_config
from paramotion import gough_stewart as gs


def trajectory(geom: gs.GoughStewartGeometry, n: int, rng: np.random.Generator,
               step: float) -> tuple[np.ndarray, np.ndarray]:
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


def bench_tracking(geom: gs.GoughStewartGeometry, lengths: np.ndarray, pos: np.ndarray,
                   rot: np.ndarray) -> tuple[tuple[float, float], np.ndarray]:
    p, r = pos[0], rot[0]
    iters = np.empty(len(lengths), dtype=int)
    t0 = _clocks()
    for k in range(len(lengths)):
        out = gs.forward_kinematics(geom, lengths[k], p, r)
        p, r = out.position, out.rotation
        iters[k] = out.iterations
    return _rates(len(lengths), t0), iters


def bench_perturbed(geom: gs.GoughStewartGeometry, lengths: np.ndarray, gpos: np.ndarray,
                    grot: np.ndarray) -> tuple[tuple[float, float], np.ndarray]:
    iters = np.empty(len(lengths), dtype=int)
    t0 = _clocks()
    for k in range(len(lengths)):
        iters[k] = gs.forward_kinematics(geom, lengths[k], gpos[k], grot[k]).iterations
    return _rates(len(lengths), t0), iters


def _batch_run(geom, lengths, gpos, grot, backend):
    t0 = _clocks()
    out = gs.forward_kinematics_batch(geom, lengths, gpos, grot, backend=backend)
    rate = _rates(len(lengths), t0)
    if not out.converged.all():
        raise RuntimeError(f'batched FK ({backend}) failed on {np.count_nonzero(~out.converged)}'
                           ' benchmark poses')
    back = gs.inverse_kinematics(geom, out.positions, out.rotations)
    return rate, out.iterations, float(np.abs(back - lengths).max())


def run_benchmark(poses: int = 20000, repeats: int = 5, step: float = 5e-4,
                  backends: list[str] | None = None
                  ) -> tuple[dict[str, tuple[list[float], list[float], np.ndarray]],
                             dict[str, float]]:
    """Measure every mode; returns ``{mode: (wall_rates, cpu_rates, iterations)}`` and worst.

    Modes: ``tracking`` and ``perturbed`` (single solves) and ``batch_<backend>`` for each
    batched backend (numba when installed, and numpy). Each backend is run once before
    timing so that the numba kernel's compilation (or cache load) is not counted.
    """
    geom = load_robot_config().geometry
    rng = np.random.default_rng(0)
    pos, rot = trajectory(geom, poses, rng, step)
    lengths = gs.inverse_kinematics(geom, pos, rot)
    gpos = pos + rng.normal(scale=0.01, size=pos.shape)
    grot = gs.rotation_matrix(rng.normal(scale=np.radians(2), size=pos.shape)) @ rot
    if backends is None:
        backends = ['numpy']
        if gs.resolve_backend('auto') == 'numba':
            backends.insert(0, 'numba')
    for backend in backends:
        gs.forward_kinematics_batch(geom, lengths[:2], gpos[:2], grot[:2], backend=backend)
    modes = ['tracking', 'perturbed'] + [f'batch_{b}' for b in backends]
    rates = {m: [] for m in modes}
    iters = {}
    worst = {}
    for _ in range(repeats):
        rate, iters['tracking'] = bench_tracking(geom, lengths, pos, rot)
        rates['tracking'].append(rate)
        rate, iters['perturbed'] = bench_perturbed(geom, lengths, gpos, grot)
        rates['perturbed'].append(rate)
        for backend in backends:
            name = f'batch_{backend}'
            rate, iters[name], err = _batch_run(geom, lengths, gpos, grot, backend)
            rates[name].append(rate)
            worst[name] = max(worst.get(name, 0.0), err)
    out = {}
    for m in modes:
        out[m] = ([r[0] for r in rates[m]], [r[1] for r in rates[m]], iters[m])
    return out, worst


def benchmark_fk(poses: int = 20000, repeats: int = 5) -> dict[str, float | str]:
    """Headline FK figures for ``paramotion bench``: medians of ``repeats`` runs, wall clock.

    ``fk_single_per_s``: warm-started single solves along a trajectory; ``fk_batched_per_s``:
    the batched solver with the default backend on ``poses`` poses at once (guess off by
    1 cm / 2 deg); ``fk_batched_backend`` names that backend.
    """
    backend = gs.resolve_backend('auto')
    res, worst = run_benchmark(poses, repeats, backends=[backend])
    return {'fk_single_per_s': statistics.median(res['tracking'][0]),
            'fk_batched_per_s': statistics.median(res[f'batch_{backend}'][0]),
            'fk_batched_backend': backend,
            'fk_batched_worst_round_trip_m': worst[f'batch_{backend}']}


def main(argv: Sequence[str] | None = None) -> int:

    parser = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    parser.add_argument('--poses', type=int, default=20000, help='poses per run')
    parser.add_argument('--repeats', type=int, default=5, help='runs; the median is printed')
    parser.add_argument('--step', type=float, default=5e-4,
                        help='trajectory step between consecutive poses (m and rad)')
    args = parser.parse_args(argv)
    if args.poses < 1 or args.repeats < 1:
        parser.error('--poses and --repeats must be >= 1')
    res, worst = run_benchmark(args.poses, args.repeats, args.step)
    print(f'geometry: climber default, {args.poses} poses, median of {args.repeats} runs')
    labels = {'tracking': f'single, warm-started along trajectory ({args.step:g} step)',
              'perturbed': 'single, guess perturbed 1 cm / 2 deg'}
    for name, (wall, cpu, it) in res.items():
        label = labels.get(name, f'batched ({name[6:]}), guess perturbed 1 cm / 2 deg')
        print(f'{label:55s} {statistics.median(wall):8.0f} solves/s wall '
              f'{statistics.median(cpu):8.0f} /CPU-s   '
              f'iterations median {np.median(it):.0f} max {it.max()}')
    for name, err in worst.items():
        print(f'worst |IK(FK(L)) - L| over {name}: {err:.2e} m')
    print("(solves/s wall: wall-clock rate; /CPU-s: per second of this process's CPU time, "
          'which other load on the machine does not inflate)')
    return 0


if __name__ == '__main__':
    raise SystemExit(main())
