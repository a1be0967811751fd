"""Simplified-Voronoi figures for ``paramotion bench`` (as ``paramotion voronoi bench``)."""
import statistics
import time


def bench_voronoi(quick: bool, options: dict) -> dict:
    """Planar rho configurations/s (random configurations, seed 0) and the paper's planar
    query planning time (a cold planner per query)."""
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


# name -> (function(quick, options) -> figures, {key: table label})
BENCHES = {'voronoi': (bench_voronoi, {'rho_per_s': 'planar rho configurations/s',
                                       'voronoi_paper_query_s': 'Voronoi paper query s'})}
