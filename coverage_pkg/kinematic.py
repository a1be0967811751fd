"""A pure-Python, ROS-free closed loop: kinematic disk robot + simulated sonar + planner.

Used by the tests and for quick experiments; the ROS graph (PyBullet sim node, sonar node,
planner node, monitor node) runs the very same planner and sonar model. The robot integrates
the body-frame velocity command; a move that would bring the centre within r of a wall is
refused (the robot stops there, as against a wall), so a planner error shows up as a stuck
robot rather than as a robot passing through walls.
"""
from __future__ import annotations

import math
import time
from collections.abc import Callable, Iterable
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
import shapely

from coverage_pkg.algorithm1 import Command, PaperConfig, PaperPlanner
from coverage_pkg.cvs import CoverableSet, CoverageAccumulator
from coverage_pkg.planner import CoveragePlanner, PlannerConfig
from coverage_pkg.sonar import RingCaster, SonarRing

if TYPE_CHECKING:
    from coverage_pkg.world import World


def run_kinematic(world: World, config: PaperConfig | PlannerConfig | None = None,
                  ring: SonarRing | None = None, dt: float = 0.05, sweep_period: float = 0.1,
                  max_time: float = 3000.0, seed: int = 0,
                  dropout: Callable[[float], bool] | None = None,
                  corrupt: Callable[[float, np.ndarray], np.ndarray] | None = None,
                  cvs_resolution: float = 0.05, clock: Callable[[], float] = time.perf_counter,
                  on_step: (Callable[[float, CoveragePlanner | PaperPlanner, Command], object]
                            | None) = None) -> dict[str, object]:
    """Run coverage on ``world`` until the planner is done/stuck or ``max_time`` sim seconds.

    ``config`` is a :class:`PaperConfig` (the paper planner, :mod:`coverage_pkg.algorithm1`)
    or a :class:`PlannerConfig` (the grid planner). ``dropout(t) -> bool`` suppresses
    sweeps (sonar silence); ``corrupt(t, ranges) -> ranges`` alters readings (NaN/inf
    faults). ``clock`` times each planner update (``time.thread_time``: CPU time of this
    thread, free of other jobs' load). Returns a result dict with the path, its length, the
    covered fraction of CVS and the planner.
    """
    cfg = config or PlannerConfig()
    ring = ring or SonarRing()
    ring.validate(cfg.delta if cfg.detector == 'extended' else None)
    cls = PaperPlanner if isinstance(cfg, PaperConfig) else CoveragePlanner
    planner = cls(cfg, ring.mount_angles(), ring.beam_width, ring.min_range, ring.max_range,
                  ring.noise_std)
    rng = np.random.default_rng(seed)
    sonar = RingCaster(world, ring)          # simulate_ring, with the world's segments ready
    cvs = CoverableSet(world, cfg.radius, cfg.detector_range(), cvs_resolution)
    acc = CoverageAccumulator(cvs)
    x, y = map(float, world.start)
    yaw = 0.0
    t = 0.0
    next_sweep = 0.0
    path = [(x, y)]
    length = 0.0
    boundary = world.free.boundary
    update_times = []
    t0 = time.perf_counter()
    cmd = None
    while t < max_time:
        planner.on_odometry(t, x, y, yaw)
        acc.add_pose(x, y, min_step=0.05)
        if t >= next_sweep - 1e-9:
            next_sweep += sweep_period
            if dropout is None or not dropout(t):
                ranges = sonar((x, y, yaw), rng)
                if corrupt is not None:
                    ranges = corrupt(t, ranges)
                a = clock()
                planner.on_sweep(t, ranges)
                cmd = planner.update(t)
                update_times.append(clock() - a)
            else:
                cmd = planner.update(t)
        if cmd is None:
            cmd = planner.update(t)
        if on_step is not None:
            on_step(t, planner, cmd)
        if cmd.state in ('done', 'stuck', 'incomplete'):
            break
        c, s = math.cos(yaw), math.sin(yaw)
        vx, vy = c * cmd.vx - s * cmd.vy, s * cmd.vx + c * cmd.vy
        nx_, ny_ = x + vx * dt, y + vy * dt
        if (vx or vy) and boundary.distance(shapely.Point(nx_, ny_)) > cfg.radius and \
                world.free.contains(shapely.Point(nx_, ny_)):
            length += math.hypot(nx_ - x, ny_ - y)
            x, y = nx_, ny_
            if math.hypot(x - path[-1][0], y - path[-1][1]) >= 0.05:
                path.append((x, y))
        yaw = math.remainder(yaw + cmd.wz * dt, 2 * math.pi)
        t += dt
    acc.add_pose(x, y)
    return {'state': planner.state, 'sim_time': t, 'wall_time': time.perf_counter() - t0,
            'path': path, 'path_length': length, 'covered_fraction': acc.fraction(),
            'cvs_area': cvs.area, 'lower_bound': cvs.lower_bound_path(), 'planner': planner,
            'accumulator': acc, 'update_times': update_times}


def ratio_report(paths: Iterable[str | Path], config: PaperConfig | PlannerConfig | None = None,
                 baseline: bool = False, oracle: bool = False, max_time: float = 3000.0,
                 out: Callable[[str], object] = print, events: bool = False,
                 floor: bool = False) -> list[dict[str, object]]:
    """Cover every world file in ``paths`` in the ROS-free loop and print, per world, the
    covered fraction of CVS, the path, the lower bound |CVS|/(2 delta) and their ratio (and,
    with ``baseline``, the robot-size baseline's path and the extended/baseline ratio; with
    ``oracle``, the full-knowledge route of :mod:`coverage_pkg.oracle` and planner/oracle;
    with ``events``, how many sensed cusp and meet points :mod:`coverage_pkg.event_check`
    finds where the true world has them; with ``floor``, the floor of Algorithm 1's path of
    :mod:`coverage_pkg.algorithm1_floor` and planner/floor); then the mean and median ratio.
    Returns the rows."""
    from coverage_pkg.baseline import robot_size_config
    from coverage_pkg.world import load_world
    rows = []
    for p in paths:
        world = load_world(p, radius=(config or PlannerConfig()).radius)
        r = run_kinematic(world, config, max_time=max_time)
        row = {'world': world.name, 'state': r['state'], 'covered': r['covered_fraction'],
               'path_m': r['path_length'], 'bound_m': r['lower_bound'],
               'ratio': r['path_length'] / r['lower_bound']}
        line = (f"{world.name}: {r['state']}, covered {100 * row['covered']:.2f} % of CVS, "
                f"path {row['path_m']:.1f} m, bound {row['bound_m']:.1f} m, "
                f"ratio {row['ratio']:.2f}")
        if baseline:
            b = run_kinematic(world, robot_size_config((config or PlannerConfig()).radius),
                              max_time=4 * max_time)
            row.update(base_covered=b['covered_fraction'], base_path_m=b['path_length'])
            line += (f"; robot-size baseline {b['state']}, covered "
                     f"{100 * b['covered_fraction']:.2f} %, path {b['path_length']:.1f} m, "
                     f"extended/baseline {r['path_length'] / b['path_length']:.2f}")
        if oracle:
            from coverage_pkg.oracle import oracle_route
            cfg = config or PlannerConfig()
            o = oracle_route(world, cfg.radius, cfg.detector_range())
            row.update(oracle_m=o['path_length'], oracle_covered=o['covered_fraction'])
            line += (f"; oracle {o['path_length']:.1f} m ({100 * o['covered_fraction']:.2f} %), "
                     f"ratio {o['path_length'] / r['lower_bound']:.2f}, planner/oracle "
                     f"{r['path_length'] / o['path_length']:.2f}")
        if floor:
            from coverage_pkg.algorithm1_floor import algorithm1_floor
            cfg = config if isinstance(config, PaperConfig) else PaperConfig()
            f = algorithm1_floor(world, cfg.radius, cfg.detector_range(), cfg.view_margin)
            row.update(floor_m=f['floor'])
            line += (f"; floor of Algorithm 1 {f['floor']:.1f} m, ratio "
                     f"{f['floor'] / r['lower_bound']:.2f}, planner/floor "
                     f"{r['path_length'] / f['floor']:.2f}")
        if events:
            from coverage_pkg.event_check import check_events
            cfg = config or PlannerConfig()
            ev = check_events(world, r['planner'].events, cfg.detector_range())
            row.update(cusps=ev['cusp'], meets=ev['meet'])
            line += (f"; cusps verified {ev['cusp'][0]}/{ev['cusp'][1]}, meets verified "
                     f"{ev['meet'][0]}/{ev['meet'][1]}")
        out(line)
        rows.append(row)
    if rows:
        ratios = [r['ratio'] for r in rows]
        out(f'{len(rows)} worlds: mean ratio {np.mean(ratios):.2f}, median '
            f'{np.median(ratios):.2f}, min covered {100 * min(r["covered"] for r in rows):.2f} %')
        if events:
            for kind, key in (('cusp', 'cusps'), ('meet', 'meets')):
                ok, n = (sum(r[key][i] for r in rows) for i in (0, 1))
                out(f'{kind} points: {ok} of {n} sensed are where the true world has one '
                    f'({100 * ok / n if n else 0:.0f} %)')
        if floor:
            out(f"floor of Algorithm 1 (full knowledge): mean ratio "
                f"{np.mean([r['floor_m'] / r['bound_m'] for r in rows]):.2f}; planner/floor "
                f"mean {np.mean([r['path_m'] / r['floor_m'] for r in rows]):.2f}")
        if oracle:
            o = [r['oracle_m'] / r['bound_m'] for r in rows]
            out(f'oracle (full knowledge): mean ratio {np.mean(o):.2f}, median '
                f'{np.median(o):.2f}; planner/oracle mean '
                f'{np.mean([r["path_m"] / r["oracle_m"] for r in rows]):.2f}')
    return rows
