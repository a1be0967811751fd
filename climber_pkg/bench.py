"""Climber figures for ``paramotion bench``: Gough-Stewart FK speed and the climbing graph's
speed in one lock-step process."""
import statistics
import time
from pathlib import Path

TRUNK = Path(__file__).resolve().parent / 'trunks' / 'straight_palm.json'


def bench_fk(quick: bool, options: dict) -> dict:
    """Warm single FK solves/s and batched solves/s (:mod:`climber_pkg.fk_benchmark`)."""
    from climber_pkg.fk_benchmark import benchmark_fk
    res = benchmark_fk(poses=2000 if quick else 20000, repeats=1 if quick else 5)
    return {'fk_single_per_s': float(res['fk_single_per_s']),
            'fk_batched_per_s': float(res['fk_batched_per_s']),
            'fk_batched_backend': res.get('fk_batched_backend')}


def bench_graph(quick: bool, options: dict) -> dict:
    """Sim seconds per wall second of the climbing graph on the straight palm (one process,
    lock-step, no bag), over the first 2 (quick) or 30 sim seconds; also per CPU second of
    this process (what a core of its own would give it on a loaded machine). Without
    ``quick``, the medians of three runs (the shared machine's load varies between runs)."""
    from climber_pkg.scenario import run_climb
    walls, cpus = [], []
    for _ in range(1 if quick else 3):
        t0, c0 = time.monotonic(), time.process_time()
        result, _, _ = run_climb(str(TRUNK), max_time=2.0 if quick else 30.0)
        wall, cpu = time.monotonic() - t0, time.process_time() - c0
        sim = float(result['sim_time_s'])
        walls.append(sim / max(wall, 1e-9))
        cpus.append(sim / max(cpu, 1e-9))
    return {'climber_sim_per_wall': statistics.median(walls),
            'climber_sim_per_cpu': statistics.median(cpus)}


#: Benchmarks that run a lock-step Graph (paramotion bench measures its levers on them).
LOCKSTEP = ('climber',)

# name -> (function(quick, options) -> figures, {key: table label})
BENCHES = {
    'fk': (bench_fk, {'fk_single_per_s': 'FK single (warm) solves/s',
                      'fk_batched_per_s': 'FK batched solves/s'}),
    'climber': (bench_graph, {'climber_sim_per_wall': 'climber graph sim s / wall s',
                              'climber_sim_per_cpu': 'climber graph sim s / CPU s'}),
}
