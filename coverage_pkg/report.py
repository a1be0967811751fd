"""Headline measurements of the coverage part, written as ``<out_dir>/coverage.md``.

:func:`write_report` reruns, in the ROS-free loop (:func:`coverage_pkg.kinematic.run_kinematic`,
the same planner and sonar model as the ROS graph):

* the paper planner (Algorithm 1, :mod:`coverage_pkg.algorithm1`; the default) and the grid
  planner (ours, frontier-driven, :mod:`coverage_pkg.planner`) side by side on the packaged demo
  world, a hand-made room with a pillar (``pillar_room``) and generated worlds
  (:mod:`coverage_pkg.worldgen`): covered share of CVS, path / lower bound,
  sim and wall time, planner time per sweep, and for the paper planner the share of path
  driven by its primitives (lap, boundary, GVD) rather than transit;
* the paper planner's selectable modes (:data:`MODES`: ``PaperConfig`` switches set
  against the default, e.g. Algorithm 1's pseudocode order, ``handover`` off, or every rule of
  ours at the paper's reading, ``rules=paper``) on the same generated worlds beside the
  default (Algorithm 1 in Fig. 13's order);
* the ablations of the paper planner, each event's sensing switched off (``without``) on the
  world made to show it, beside what the paper predicts;

and draws both planners' runs on the demo world (``coverage_paper_demo.png``,
``coverage_grid_demo.png``).
"""
from __future__ import annotations

import math
import os
import platform
import sys
import tempfile
import time
from collections.abc import Iterable
from pathlib import Path

import numpy as np

from coverage_pkg.algorithm1 import OUR_MODES, PAPER_RULES, PaperConfig
from coverage_pkg.kinematic import run_kinematic
from coverage_pkg.planner import PlannerConfig, graph_dict
from coverage_pkg.world import World, load_world, world_from_dict

WORLDS = Path(__file__).resolve().parent / 'worlds'
#: the paper planner's primitives, in the order of the report's 'where the path goes' column
PRIMITIVES = ('lap', 'boundary', 'gvd', 'transit')
#: first seeds of the generated sets of six worlds (full report): two used while developing,
#: seven held out once and then looked at (no longer unseen); the held-out worlds are the
#: broad sample of :data:`BROAD_SETS`
DEV_SEEDS = (100, 200)
SEEN_SEEDS = (300, 400, 500, 600, 700, 800, 900)
#: broad samples of generated worlds, paper planner only (full report): first seed, count,
#: label. Seeds 1000-1259, 2000-2099, 3000-3099, 4000-4099, 6000-6099, 7000-7099 and
#: 8000-8099 were held out, measured, and their failures worked on; seeds 5000-5199 are a
#: development sample; seeds 9000-9099 were held out, measured, and the path of one world
#: (gen_mixed_9094) worked on; seeds 10000-10099 are held out (measured by this report, and
#: 10000-10009 once by paper_measure, with no planner change after either)
BROAD_SETS = ((1000, 260, 'seen'), (2000, 100, 'seen'), (3000, 100, 'seen'),
              (5000, 200, 'seen'), (4000, 100, 'seen'), (6000, 100, 'seen'),
              (7000, 100, 'seen'), (8000, 100, 'seen'), (9000, 100, 'seen'),
              (10000, 100, 'held out'))
#: sides (m) of the pillar halls of the scaling rows (full report only): area x4
HALL_SIZES = (10.0, 20.0)
#: packaged worlds compared in every report, before the generated ones
HAND_MADE = ('demo_rooms', 'pillar_room')

#: the paper planner's selectable modes beside the default (Algorithm 1 in Fig. 13's order):
#: (name, PaperConfig switches, what the mode changes)
MODES = (
    ('algorithm1_order', {'handover': False}, "Algorithm 1's pseudocode order: a narrow node "
     'is traced whole before FindUncoveredNode, so a corridor traced past a cusp is driven '
     'back to it'),
    ('paper_rules', PAPER_RULES, "every sensing rule of ours set to the paper's reading "
     '(rules=paper: the ten switches of ours that are on in the default; the rows below '
     'switch them one by one)'),
    ('merge_continues', {'merge_continues': True}, 'a narrow node found to be an earlier one '
     '(same_cell) hands over to it, which goes on being covered at once (the default goes on '
     'with FindUncoveredNode, ours)'),
    ('one_sweep_meets', {'meet_scan': False}, "a meet point's branches read from the one sweep "
     'that sensed it (the default halts there and turns the ring through one cone spacing, '
     'ours)'),
    ('slivers_by_circuit', {'sliver_openings': False}, "a small sliver's cusps left to its "
     "circuit (the default reads the GVD edges leaving it like a meet point's, ours)"),
    ('circuits_round', {'circuit_join': False}, 'every boundary circuit driven round to its '
     'start, over boundary other circuits followed (the default ends it there, ours)'),
    ('cusps_not_meets', {'cusp_meet': False}, 'a cusp whose three closest obstacles are '
     'equidistant gives only its one branch (the default also reads it as a meet point, ours)'),
    ('meets_surrounded', {'meet_surround': True}, 'ours: a meet point only where its three '
     'closest obstacles surround it (the default, as the paper defines it, also takes one '
     'whose three lie within a half-plane)'),
    ('meets_within_delta', {'meet_margin': 0.0}, 'a meet point only at D <= delta, one just '
     'beyond passed and kept for a dead end beyond it (the default takes it up to 0.1 m '
     'beyond delta when sensed, ours)'),
    ('circuits_either_way', {'circuit_same_way': False}, 'a boundary circuit back at its '
     'start at its closest pass either way round (the default only going the way it left '
     'the start, ours)'),
    ('circuits_any_side', {'circuit_same_side': False}, 'a boundary circuit back at its start '
     'at any pass within 0.4 m of it (the default only facing an obstacle it faced at the '
     'start, ours)'),
    ('meets_two_closest', {'meet_side_pair': False}, 'past a meet point the GVD law of the '
     'two closest obstacles at once (the default follows the edge of the closest obstacle on '
     'either side of the heading while the two closest lie on one side, ours)'),
    ('way_come_window', {'way_come_held': False}, 'at a meet point every peak within 60 '
     'degrees of the bearing to the path behind is the way come (the default takes only the '
     'peak that holds that bearing where one does, ours)'),
    ('meets_merged', {'meet_own_obstacles': False}, 'every meet point sensed within 0.5 m '
     'of a known one is the known one (the default reads it as another one, from over 0.5 '
     "m beyond where that one was sensed, where one of the known one's three closest "
     'obstacles lies farther from it than its own three by over 0.3 m, ours)'),
    ('traced_way', {'traced_way': True}, 'ours: a branch is traced already also where one '
     'of the points 0.8, 1.6 and 2.4 m out along its bearing lies near a traced GVD edge '
     "that runs across the way, or along it towards the branch's start or from a trace "
     'that passed the start (the default: only where all three lie on a traced edge)'),
    ('end_scan', {'end_scan': True}, 'ours: where a GVD edge ends at an obstacle ahead the '
     'robot halts and turns its ring through one cone spacing before it reads the gaps there '
     '(the default reads them from the one sweep that found the end)'),
    ('circuit_sweeps', {'circuit_sweeps': True}, 'ours: no laps in a vast cell every point of '
     'which lies within delta - 0.2 m of its closed boundary circuit'),
    ('cusp_detour', {'cusp_detour': True}, 'ours: a narrow node whose cusp the boundary circuit '
     'senses is covered at once and the circuit resumed where it was left (the paper finishes '
     'the vast cell first)'),
    ('cusp_edge_traced', {'cusp_edge_traced': True}, 'ours: a GVD branch that ends at a cusp a '
     "circuit sensed before, along that cusp's edge, has traced the edge of that cusp's narrow "
     'node: the two narrow nodes are one and the branch ends traced (the default covers the '
     "cusp's node on its own)"),
    ('cusp_meet_gap', {'cusp_meet_gap': True}, 'ours: a cusp read as a meet point gives its own '
     'branch the gap between its three closest obstacles nearest its bearing (the default: '
     'the bisector of its two closest)'),
    ('pinch_ends_cell', {'pinch_ends_cell': True}, 'ours: a Morse cell ends where the move '
     'between laps finds obstacles either side nearer than delta, a lap where the delta disk '
     'touches a corner ahead (the default follows the boundary and laps on)'),
    ('fork_at_meet', {'fork_at_meet': True}, "ours: two peaks of a meet point's scan, one's "
     "upper half holding the other's top, are two GVD edges where the obstacle between their "
     'tops lies within rho + 2 same_event of the meet point (the default: one edge)'),
    ('start_on_gvd', {'start_on_gvd': True}, "ours: the start node's kind read from D on the "
     'GVD beside which the access ends (the default: D where the robot stands)'),
    ('our_modes', OUR_MODES, 'ours: the '
     'five modes that shorten the path (traced_way, circuit_sweeps, cusp_edge_traced, '
     'cusp_meet_gap, pinch_ends_cell) with fork_at_meet and start_on_gvd'),
)

#: (event switched off, world, what the paper predicts without it)
ABLATIONS = (
    ('cusp', 'door_rooms', 'the corridor and the room beyond it are never discovered (Section '
     'V-B: cusp points are how the robot finds new cells); coverage far below 99 %, yet '
     '"done" for the part discovered'),
    ('critical', 'island_hall', 'the Morse cell is not split at the pillar (Section II: critical '
     'points delimit the cells); the region beyond it is missed'),
    ('meet', 't_hall', 'only one branch of the T junction is traced (Section III: meet points '
     'add the GVD edges); the other stays unseen'),
)


def _default_switches() -> str:
    """The default's switches as the Modes table's text, read from :class:`PaperConfig`, so the
    report names what the rows were measured against."""
    cfg = PaperConfig()
    flags = sorted({k for _, switches, _ in MODES for k in switches
                    if isinstance(getattr(cfg, k), bool)})
    names = [f'`{k}`' for k in flags]
    on = [n for n, k in zip(names, flags) if getattr(cfg, k)]
    off = [n for n, k in zip(names, flags) if not getattr(cfg, k)]
    return (f'{", ".join(on)} on, {", ".join(off)} off, '
            f'`meet_margin` {cfg.meet_margin:g} m')


def _run(world, config, max_time=3000.0, where=True):
    """One run in the ROS-free loop and its figures; ``where``: also where the paper
    planner's path goes and what of it ran over CVS swept before (:func:`swept_before`, a
    replay of the path as long as the run's own accounting), which the Modes table does
    not show."""
    r = run_kinematic(world, config, max_time=max_time, clock=time.thread_time)
    ut = np.asarray(r['update_times']) * 1e3
    row = {'state': r['state'], 'covered': r['covered_fraction'],
           'ratio': r['path_length'] / r['lower_bound'], 'path': r['path_length'],
           'sim': r['sim_time'], 'wall': r['wall_time'],
           'median_ms': float(np.median(ut)) if len(ut) else None,
           'p99_ms': float(np.percentile(ut, 99)) if len(ut) else None, 'run': r}
    prim = getattr(r['planner'], 'primitive_lengths', None)
    if prim is not None:
        lengths = prim()
        total = sum(lengths.values())
        row['primitive_share'] = 1.0 - lengths.get('transit', 0.0) / total if total else None
        scale = r['path_length'] / total / r['lower_bound'] if total else 0.0
        row['where'] = ' / '.join(f'{lengths.get(k, 0.0) * scale:.2f}' for k in PRIMITIVES)
        if not where:
            return row
        idle = swept_before(r)
        bound = r['lower_bound']
        row['lengths'] = {k: lengths.get(k, 0.0) * scale for k in PRIMITIVES}
        row['lengths']['retrace'] = r['planner'].retraced * scale
        row['idle'] = {k: v / bound for k, v in idle.items()}
    return row


def swept_before(run: dict[str, object], per_metre: float = 0.02) -> dict[str, float]:
    """Path length per primitive driven over CVS the detector had swept already: the run's
    path replayed through a fresh :class:`coverage_pkg.cvs.CoverageAccumulator`, a step
    counting when it adds less than ``per_metre`` square metres of CVS per metre. Each path
    step takes the primitive of the planner's segment at the same share of the path length."""
    from coverage_pkg.cvs import CoverageAccumulator
    segs = run['planner'].segments
    total = sum(length for _, length in segs)
    path = run['path']
    out = dict.fromkeys(PRIMITIVES, 0.0)
    if not segs or len(path) < 2 or not total:
        return out
    acc = CoverageAccumulator(run['accumulator'].cvs)
    mask, area = acc.cvs.mask, acc.cvs.res ** 2
    acc.add_pose(*path[0])
    ends = np.cumsum([length for _, length in segs]) / total
    length = sum(math.dist(a, b) for a, b in zip(path, path[1:]))
    done, k = 0.0, 0
    for a, b in zip(path, path[1:]):
        step = math.dist(a, b)
        rows, cols = acc.visible(*b)
        new = int((mask[rows, cols] & ~acc.seen[rows, cols]).sum()) * area
        acc.seen[rows, cols] = True
        done += step / length
        while k < len(segs) - 1 and done > ends[k]:
            k += 1
        if new < per_metre * step:
            out[segs[k][0]] = out.get(segs[k][0], 0.0) + step
    return out


def _rows_table(rows, first):
    """Markdown table of measured rows, the columns ``first`` leading."""
    return _table(list(first) + ['planner', 'end', 'covered CVS', 'path / bound',
                                 'lap / boundary / gvd / transit (x bound)', 'primitives',
                                 'sim s', 'wall s', 'update median ms', 'update p99 ms'],
                  [tuple(r[k] for k in first)
                   + (r['planner'], r['state'], _pct(r['covered']), _num(r['ratio']),
                      r.get('where', '-'), _pct(r.get('primitive_share')), _num(r['sim'], 0),
                      _num(r['wall'], 1), _num(r['median_ms']), _num(r['p99_ms']))
                   for r in rows])


def _table(header, rows):
    lines = ['| ' + ' | '.join(header) + ' |', '|' + '---|' * len(header)]
    lines += ['| ' + ' | '.join(str(c) for c in row) + ' |' for row in rows]
    return lines


def _pct(v):
    return '-' if v is None else f'{100 * v:.2f} %'


def _num(v, digits=2):
    return '-' if v is None else f'{v:.{digits}f}'


def comparison(worlds: Iterable[str | Path], quick: bool = False) -> list[dict[str, object]]:
    """Paper and grid planner on the same worlds; rows of measured figures."""
    rows = []
    for path in worlds:
        world = load_world(path)
        for name, config in (('paper', PaperConfig()), ('grid', PlannerConfig())):
            if quick and name == 'grid' and world.name not in HAND_MADE:
                continue
            row = _run(world, config)
            row.update(world=world.name, planner=name)
            rows.append(row)
    return rows


def _mode_row(task: tuple[str, dict[str, object]]) -> dict[str, object]:
    """One world file under one mode's switches (a task of :func:`modes`' process pool): the
    figures the Modes table keeps, without the run itself, which does not pickle."""
    path, switches = task
    row = _run(load_world(path), PaperConfig(**switches), where=False)
    return {k: row[k] for k in ('covered', 'ratio', 'primitive_share', 'p99_ms')}


def modes(sets: dict[str, list[Path]], jobs: int = 2) -> list[dict[str, object]]:
    """The paper planner's switches (:data:`MODES`) on the generated sets: per set and mode,
    mean covered share of CVS, its minimum, mean path / bound and mean primitive share;
    ``jobs`` worlds at a time (update times are CPU times of the process, free of the
    other's load)."""
    from multiprocessing import Pool
    groups = [(group, worlds) for group, worlds in sets.items() if group.startswith('seed')]
    tasks = [(str(w), switches) for _, worlds in groups for _, switches, _ in MODES
             for w in worlds]
    with Pool(jobs) as pool:
        done = iter(pool.map(_mode_row, tasks))
    out = []
    for group, worlds in groups:
        for name, switches, what in MODES:
            rows = [next(done) for _ in worlds]
            out.append({'set': group, 'mode': name, 'what': what,
                        'covered': float(np.mean([r['covered'] for r in rows])),
                        'min': min(r['covered'] for r in rows),
                        'ratio': float(np.mean([r['ratio'] for r in rows])),
                        'share': float(np.mean([r['primitive_share'] for r in rows])),
                        'p99_ms': max(r['p99_ms'] for r in rows)})
    return out


def ablations() -> list[dict[str, object]]:
    """The paper planner with and without each event's sensing on its world."""
    rows = []
    for event, name, predicted in ABLATIONS:
        world = load_world(WORLDS / f'{name}.json')
        full = _run(world, PaperConfig(), max_time=600.0)
        cut = _run(world, PaperConfig(without=(event,)), max_time=600.0)
        rows.append({'event': event, 'world': name, 'predicted': predicted, 'full': full,
                     'cut': cut})
    return rows


def broad(sets: Iterable[tuple[int, int, str]] = BROAD_SETS, jobs: int = 2
          ) -> list[dict[str, object]]:
    """The paper planner alone on many generated worlds per set (``paper_measure``'s
    figures, ``jobs`` worlds at a time): how often a world of the generator is left below
    99 % of CVS, which six worlds per set cannot show."""
    from multiprocessing import Pool

    from coverage_pkg.paper_measure import measure_world
    out = []
    with Pool(jobs) as pool:
        for first, count, label in sets:
            rows = pool.map(measure_world, range(first, first + count))
            out.append({'set': f'seeds {first}-{first + count - 1} ({label})', 'rows': rows})
    return out


def pillar_hall(size: float, spacing: float = 5.0, pillar: float = 1.0) -> World:
    """A square hall of side ``size`` with square pillars of side ``pillar`` on a ``spacing``
    grid: the same structure at any size, to see whether a planner's time grows with area."""
    k = int(size // spacing)
    h = pillar / 2
    pillars = [[[x - h, y - h], [x + h, y - h], [x + h, y + h], [x - h, y + h]]
               for x in (i * spacing for i in range(1, k)) for y in (j * spacing
                                                                    for j in range(1, k))]
    return world_from_dict({'name': f'pillar_hall_{size:g}',
                            'boundary': [[0, 0], [size, 0], [size, size], [0, size]],
                            'obstacles': pillars, 'start': [1.0, 1.0]})


def scaling(sizes: Iterable[float] = HALL_SIZES) -> list[dict[str, object]]:
    """Both planners on pillar halls of growing area: planner time per sweep and wall time."""
    rows = []
    for size in sizes:
        world = pillar_hall(size)
        for name, config in (('paper', PaperConfig()), ('grid', PlannerConfig())):
            row = _run(world, config, max_time=6000.0)
            row.update(world=world.name, planner=name)
            rows.append(row)
    return rows


def write_report(out_dir: Path, quick: bool = False) -> list[Path]:
    """Rerun the headline measurements; write ``out_dir/coverage.md`` and its PNG.

    ``quick``: the hand-made worlds and one generated world, the grid planner on the hand-made
    worlds only (under two minutes); the full run uses six generated worlds of each
    development set (seeds 100-105, 200-205), of each set held out once and then looked at
    (seeds 300-305 to 900-905) and the pillar halls, with both planners, the paper planner's
    modes on the generated sets, and the paper planner alone on broad samples
    (:data:`BROAD_SETS`: seeds 1000-1259, 2000-2099, 3000-3099, 5000-5199, 4000-4099,
    6000-6099, 7000-7099, 8000-8099, 9000-9099 and 10000-10099).
    """
    from coverage_pkg.figure import render_coverage
    from coverage_pkg.worldgen import write_worlds
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    start = time.perf_counter()
    count = 1 if quick else 6
    sets = {'hand-made': [WORLDS / f'{name}.json' for name in HAND_MADE]}
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for seed in DEV_SEEDS[:1] if quick else (*DEV_SEEDS, *SEEN_SEEDS):
            name = f'seeds {seed}-{seed + count - 1}' if count > 1 else f'seed {seed}'
            name += ' (seen)' if seed in SEEN_SEEDS else ''
            sets[name] = [Path(w) for w in write_worlds(str(Path(tmp) / str(seed)), count,
                                                        seed=seed)]
        for group, worlds in sets.items():
            for row in comparison(worlds, quick):
                row['set'] = group
                rows.append(row)
        switched = modes(sets)
    abl = ablations()
    halls = [] if quick else scaling()
    samples = [] if quick else broad()
    pngs = []
    for name in ('paper', 'grid'):
        demo = next(r for r in rows if r['world'] == 'demo_rooms' and r['planner'] == name)
        png = out_dir / f'coverage_{name}_demo.png'
        run = demo['run']
        render_coverage(png, load_world(WORLDS / 'demo_rooms.json'), run['path'],
                        graph_dict(run['planner']), None,
                        run['accumulator'].uncovered_points(),
                        f"demo_rooms, {name} planner (ROS-free loop): path "
                        f"{run['path_length']:.1f} m = {demo['ratio']:.2f} x bound, covered "
                        f"{_pct(demo['covered'])} of CVS, {demo['state']}")
        pngs.append(png)
    elapsed = time.perf_counter() - start

    shown = os.path.relpath(out_dir) if out_dir.resolve().is_relative_to(Path.cwd()) \
        else str(out_dir)
    cmd = ('python -c "from pathlib import Path; from coverage_pkg.report import write_report; '
           f'write_report(Path(\'{shown}\'), quick={quick})"')
    lines = ['# Coverage with an extended-range detector: measured results', '',
             f'- date: {time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime())}',
             f'- machine: {platform.node()}, {platform.processor() or "unknown CPU"}, '
             f'{os.cpu_count()} cores (shared with other jobs: wall times include their '
             f'load); Python {sys.version.split()[0]}',
             f'- command: `{cmd}` (or `paramotion report`); {elapsed:.0f} s',
             '- loop: ROS-free (`coverage_pkg/kinematic.py`): kinematic disk robot r = 0.25 m, '
             'simulated 16-transducer sonar ring (max range 5 m), detector range delta = 2 m; '
             'generated worlds: ' + ', '.join(
                 f'`paramotion coverage-worlds --count {count} --seed {g.split()[1][:3]}`'
                 for g in sets if g.startswith('seed')), '',
             '## Paper planner and grid planner on the same worlds', '',
             'paper: Algorithm 1 driven by sensed events alone (`--planner paper`, the '
             'default). grid: the frontier-driven evidence-grid planner (ours, not the '
             "paper's, `--planner grid`). pillar_room: a 9 m x 6 m room with a 1.5 m x 1 m "
             'pillar (`coverage_pkg/worlds/pillar_room.json`). Bound: '
             '|CVS| / (2 delta). lap / boundary / gvd / transit: where the path goes, the '
             'length driven by each primitive as a multiple of the bound (they add up to path '
             '/ bound; gvd includes following a traced GVD edge back). Primitives: share of the '
             'path driven by laps, boundary following and GVD following (the rest is transit '
             'along traced paths). The planner is developed on seeds 100-105 and 200-205. '
             'Seeds 300-305 (seen) were held out and have been measured, so they are no longer '
             'unseen (changes that lost coverage on some of them are not in the planner; '
             'their paths were looked at while the planner was tuned). Seeds 400-405, '
             '500-505, 600-605, 700-705, 800-805 and 900-905 (seen) were each held out and '
             'measured once, and have been measured since (changes that lost coverage on them '
             'are not in the planner; the worlds they left below 99 % when first measured, '
             'gen_rooms_502, gen_mixed_803, gen_maze_804 and gen_halls_902, were worked on and '
             'are covered). The held-out worlds are the broad sample of seeds 10000-10099 below. '
             'Update: '
             'CPU time of one planner update per sonar sweep (`time.thread_time`, free of '
             "other jobs' load); wall s: the whole run (sonar model, CVS accounting, planner).",
             '']
    lines += _rows_table(rows, first=('set', 'world'))
    lines += ['']
    for group in (g for g in sets if g.startswith('seed')):
        for name in ('paper', 'grid'):
            mine = [r for r in rows if r['planner'] == name and r['set'] == group]
            if mine:
                lines += [f'- {name}, generated worlds {group}: mean covered '
                          f'{_pct(float(np.mean([r["covered"] for r in mine])))}, min '
                          f'{_pct(min(r["covered"] for r in mine))}, mean path / bound '
                          f'{_num(float(np.mean([r["ratio"] for r in mine])))}'
                          + (f', mean primitive share '
                             f'{_pct(float(np.mean([r["primitive_share"] for r in mine])))}'
                             if name == 'paper' else '')]
    if samples:
        lines += ['', '## The paper planner on broad samples of generated worlds', '',
                  'The paper planner alone (`python -m coverage_pkg.paper_measure --seeds A-B '
                  '--jobs 2`, the same figures as above) on many worlds of the generator per '
                  'set. Seeds 1000-1259, 2000-2099, 3000-3099, 4000-4099, 6000-6099, '
                  '7000-7099 and 8000-8099 (seen) were held out and measured, and the worlds '
                  'they left below 99 % were worked on (4000-4099, 7000-7099 and 8000-8099 '
                  'left none; 6000-6099 left gen_rooms_6069, a start inside a door); seeds '
                  '5000-5199 (seen) are a development sample, measured and worked on. Seeds '
                  '9000-9099 (seen) were held out and measured, left none below 99 %, and the '
                  'path of one of them (gen_mixed_9094, a merged node covered before the '
                  'nearer corners of its room) was worked on. Seeds 10000-10099 (held out) are '
                  'measured by this report, and ten of them (10000-10009) once by '
                  'paper_measure; nothing in the planner was changed after either.', '']
        lines += _table(['set', 'worlds', 'mean covered CVS', 'min covered',
                         'worlds below 99 %', 'mean path / bound', 'mean primitive share'],
                        [(b['set'], str(len(b['rows'])),
                          _pct(float(np.mean([r['covered'] for r in b['rows']]))),
                          _pct(min(r['covered'] for r in b['rows'])),
                          ', '.join(f"{r['world']} {_pct(r['covered'])}"
                                    for r in b['rows'] if r['covered'] < 0.99) or 'none',
                          _num(float(np.mean([r['ratio'] for r in b['rows']]))),
                          _pct(float(np.mean([r['primitive'] for r in b['rows']]))))
                         for b in samples])
    lines += ['', "## Where the paper planner's path goes", '',
              'Per generated set, the mean length driven by each primitive as a multiple of '
              'the bound, and (in brackets) how much of it ran over CVS the detector had swept '
              'already (less than 0.02 m^2 of new CVS per metre: `coverage_pkg/report.py: '
              'swept_before`). gvd back: the part of gvd driven back along GVD edges traced '
              'before (to the next open branch or node).', '']
    where = []
    for group in (g for g in sets if g.startswith('seed')):
        mine = [r for r in rows if r['planner'] == 'paper' and r['set'] == group]
        if not mine:
            continue

        def mean(key, part):
            return float(np.mean([r[key].get(part, 0.0) for r in mine]))
        cells = [f"{mean('lengths', k):.2f} ({mean('idle', k):.2f})" for k in PRIMITIVES]
        where.append((group, *cells, f"{mean('lengths', 'retrace'):.2f}",
                      _num(float(np.mean([r['ratio'] for r in mine])))))
    lines += _table(['set', 'lap (swept before)', 'boundary (swept before)',
                     'gvd (swept before)', 'transit (swept before)', 'of gvd: back',
                     'path / bound'], where)
    lines += ['', '## Modes of the paper planner', '',
              "The paper planner above runs Algorithm 1 in Fig. 13's order (the default: "
              f'{_default_switches()}). Each row below sets the switches it names (`rules=paper`: '
              'ten; `our_modes`: seven; the others: one) against the default, on the same '
              'generated worlds (`python -m coverage_pkg.paper_measure --seeds A-B --set '
              'NAME=VALUE`).', '']
    base = {g: [r for r in rows if r['planner'] == 'paper' and r['set'] == g] for g in sets}
    lines += _table(['set', 'mode', 'what it changes', 'mean covered CVS', 'min covered',
                     'mean path / bound', 'mean primitive share', 'update p99 ms (max)'],
                    [row for g in sets if g.startswith('seed') for row in [
                        (g, 'default', "none: Algorithm 1 in Fig. 13's order",
                         _pct(float(np.mean([r['covered'] for r in base[g]]))),
                         _pct(min(r['covered'] for r in base[g])),
                         _num(float(np.mean([r['ratio'] for r in base[g]]))),
                         _pct(float(np.mean([r['primitive_share'] for r in base[g]]))),
                         _num(max(r['p99_ms'] for r in base[g])))] +
                        [(g, m['mode'], m['what'], _pct(m['covered']), _pct(m['min']),
                          _num(m['ratio']), _pct(m['share']), _num(m['p99_ms']))
                         for m in switched if m['set'] == g]])
    if halls:
        lines += ['', '## Planner time against world size', '',
                  'Square pillar halls (`coverage_pkg/report.py: pillar_hall`: 1 m pillars on a '
                  f'5 m grid) of side {" and ".join(f"{s:g}" for s in HALL_SIZES)} m (area x4), '
                  'both planners; update as above (10 sweeps per sim s).', '']
        lines += _rows_table(halls, first=('world',))
    lines += ['', '## Ablations of the paper planner', '',
              'Each row switches the sensing of one event off (`--without EVENT`) on the '
              'packaged world made to show it (`coverage_pkg/worlds/`).', '']
    lines += _table(['without', 'world', 'the paper predicts', 'with: covered, end',
                     'without: covered, end'],
                    [(a['event'], a['world'], a['predicted'],
                      f"{_pct(a['full']['covered'])}, {a['full']['state']}",
                      f"{_pct(a['cut']['covered'])}, {a['cut']['state']}") for a in abl])
    lines += ['', '| paper planner (default) | grid planner (ours) |', '|---|---|',
              f'| ![paper planner on demo_rooms]({pngs[0].name}) | '
              f'![grid planner on demo_rooms]({pngs[1].name}) |', '']
    md = out_dir / 'coverage.md'
    md.write_text('\n'.join(lines))
    return [md, *pngs]
