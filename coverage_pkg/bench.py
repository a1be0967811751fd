"""Coverage figure for ``paramotion bench``: the coverage graph's speed in one process."""
import statistics
import time
from pathlib import Path

PACKAGED_WORLD = Path(__file__).resolve().parent / 'worlds' / 'two_rooms.json'


class NotMeasured(Exception):
    """The figure cannot be measured here; the message says why."""


def bench_coverage(quick: bool, options: dict) -> dict:
    """Sim seconds per wall second of the coverage graph on ``options['world']`` (default the
    packaged two_rooms world): 10 sim seconds (quick) or the whole coverage; also per CPU
    second of this process. Without ``quick``, the medians of three runs (the shared
    machine's load varies between runs)."""
    from coverage_pkg.scenario import run_coverage
    world = options.get('world') or (PACKAGED_WORLD if PACKAGED_WORLD.is_file() else None)
    if world is None:
        raise NotMeasured('no two_rooms world (use --world FILE)')
    walls, cpus = [], []
    for _ in range(1 if quick else 3):
        c0 = time.process_time()
        res = run_coverage(str(world), bag_dir=None, max_sim_time=10.0 if quick else 3000.0)
        cpu = time.process_time() - c0
        walls.append(float(res['sim_time_s']) / max(float(res['wall_time_s']), 1e-9))
        cpus.append(float(res['sim_time_s']) / max(cpu, 1e-9))
    return {'coverage_two_rooms_sim_per_wall': statistics.median(walls),
            'coverage_two_rooms_sim_per_cpu': statistics.median(cpus),
            'coverage_world': str(world)}


#: Benchmarks that run a lock-step Graph (paramotion bench measures its levers on them).
LOCKSTEP = ('coverage',)

# name -> (function(quick, options) -> figures, {key: table label})
BENCHES = {'coverage': (bench_coverage, {
    'coverage_two_rooms_sim_per_wall': 'coverage two_rooms sim s / wall s',
    'coverage_two_rooms_sim_per_cpu': 'coverage two_rooms sim s / CPU s'})}
