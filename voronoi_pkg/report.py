"""The Voronoi planner's measured results: ``write_report(out_dir)`` reruns them and writes
``<out_dir>/voronoi.md`` and ``<out_dir>/voronoi_paths.png``.

1. The diagram's construction on the paper scene (every slice): nodes, edges, vertices, the
   share of nodes and of edge midpoints where the two smallest contacts tie.
2. The paper's query (Fig. 3) and the detour scenes of ``test/test_voronoi_detours.py``:
   the planner on the diagram beside the clearance-weighted grid planner (ours,
   :mod:`voronoi_pkg.grid_baseline`) on the same grid: length, min rho, Euclidean clearance,
   wall and CPU time, size of the searched graph, on-diagram share measured from rho
   (:mod:`voronoi_pkg.measures`).
3. "No path" answers and which component gives them.
4. Ablations: each construct switched off (planar and 3-2-1), checked against the full
   model.
5. rho evaluation rate.
"""
import datetime
import math
import os
import platform
import sys
import time
from pathlib import Path

import numpy as np

from voronoi_pkg.diagram import diagram_slices, grid_axes, slice_fields
from voronoi_pkg.grid_baseline import ClearanceGridPlanner, segment_clearance
from voronoi_pkg.measures import on_diagram_share, path_length
from voronoi_pkg.planar import PAPER_GOAL, PAPER_START, Domain, paper_model, planar_model
from voronoi_pkg.planner import VoronoiPlanner, check_path
from voronoi_pkg.ties import on_diagram

__all__ = ['write_report']

BASE = ((0.0, 0.0), (15.0, 0.0))
SQUARE = ((-25.0, 40.0), (-25.0, -40.0), (55.0, -40.0), (55.0, 40.0))
WALL = [(-30.0, -22.0), (60.0, -22.0), (60.0, -18.0), (-30.0, -18.0)]


def _rect(x0, x1, y0, y1):
    return [(x0, y0), (x1, y0), (x1, y1), (x0, y1)]


#: The scenes of ``test/test_voronoi_detours.py`` and the paper's query: (obstacles, start,
#: goal).
SCENES = {
    'paper query (Fig. 3)': ([], PAPER_START, PAPER_GOAL),
    'block': ([_rect(10, 20, -35, -15)], (-10.0, -25.0, 0.0), (40.0, -25.0, 0.0)),
    'slot': ([_rect(18, 22, -40, -24), _rect(18, 22, -20, 40)], (5.0, -22.0, math.pi / 2),
             (35.0, -22.0, math.radians(150))),
    'u_trap': ([_rect(10, 34, -9, -6), _rect(10, 34, -36, -33), _rect(31, 34, -33, -9)],
               (22.0, -21.0, math.pi), (48.0, -21.0, math.pi)),
}


def _model(obstacles, without=()):
    return planar_model(BASE, 10.0, SQUARE, obstacles, Domain(), without)


def _timed(fn):
    wall, cpu = time.perf_counter(), time.process_time()
    out = fn()
    return out, time.perf_counter() - wall, time.process_time() - cpu


def _construction():
    """Diagram of the paper scene at the planner's defaults (1-unit grid, 144 slices)."""
    model = paper_model()
    xs, ys = grid_axes(model.domain, 1.0)
    phis = np.radians(np.arange(-180.0, 180.0, 2.5))
    slices, wall, cpu = _timed(lambda: diagram_slices(model, slice_fields(model, phis, xs, ys)))
    q = np.vstack([s.xyz for s in slices])
    tied = on_diagram(*model.contact_values(q), model.free_tol)
    mids = np.vstack([s.xyz[s.edges].mean(axis=1) for s in slices if len(s.edges)])
    mid_tied = on_diagram(*model.contact_values(mids), model.free_tol)
    return {'slices': len(slices), 'nodes': len(q), 'vertices': int(sum((s.pair == -1).sum()
                                                                         for s in slices)),
            'edges': len(mids), 'nodes_tied': float(tied.mean()),
            'mids_tied': float(mid_tied.mean()), 'wall': wall, 'cpu': cpu}


def _compare(name, obstacles, start, goal):
    model = _model(obstacles)
    res, v_wall, v_cpu = _timed(lambda: VoronoiPlanner(model).plan(start, goal))
    grid, g_wall, g_cpu = _timed(lambda: ClearanceGridPlanner(model).plan(start, goal))
    share = on_diagram_share(model, res.path, 0.05)[0] if res.found else float('nan')
    row = {'scene': name, 'model': model, 'res': res, 'grid': grid}
    for key, r, wall, cpu, size in (('v', res, v_wall, v_cpu, res.stats.get('diagram_nodes')),
                                    ('g', grid, g_wall, g_cpu,
                                     grid.stats.get('grid_vertices'))):
        row[key] = {'found': r.found, 'length': path_length(r.path) if r.found else math.nan,
                    'min_rho': r.min_rho,
                    'clear': float(segment_clearance(model, r.path).min()) if r.found
                    else math.nan, 'wall': wall, 'cpu': cpu, 'size': size}
    row['v']['share'] = share
    return row


def _ablations():
    """Each construct off: (construct, query, answer with it, answer without, what the full
    model says of the path found without)."""
    full = paper_model()
    rows = []
    across = (-10.0, 15.0, -math.pi / 2)
    coarse = {'h': 1.5, 'dphi_deg': 5.0}
    with_ = VoronoiPlanner(full, **coarse).plan(PAPER_START, across)
    without = VoronoiPlanner(paper_model(without=['singularity']), **coarse).plan(PAPER_START,
                                                                              across)
    rows.append(('singularity (P1)', 'paper start to P3 above the base line', with_, without,
                 full))
    walled = _model([WALL])
    start, goal = (30.0, -10.0, 1.0), (30.0, -32.0, 1.0)
    with_ = VoronoiPlanner(walled, **coarse).plan(start, goal)
    without = VoronoiPlanner(_model([WALL], ['collision']), **coarse).plan(start, goal)
    rows.append(('collision (P2)', 'across a wall spanning the square', with_, without, walled))
    out = []
    for name, query, a, b, model in rows:
        verdict = '—'
        if b.found:
            ok, min_rho, _, samples, _ = check_path(model, b.path)
            signs = model.singular_signs(samples)
            crossed = bool(signs.size and np.any(signs != signs[:, :1]))
            verdict = ('free' if ok else f'not free under the full model: min rho '
                       f'{min_rho + 0.0:.3g}' + (', crosses a singularity' if crossed else ''))
        out.append(f"| {name} | {query} | {a.status} ({a.stats.get('decided_by', '')}) | "
                   f"{b.status} | {verdict} |")
    return out + _spatial_ablations()


#: A free demo pose across the singularity [p4 p7 p8 p9] = 0 from the demo start (as in
#: ``test/test_voronoi_spatial.py``).
ACROSS_SINGULARITY = (-0.154, -0.143, 0.518, math.radians(-25.21), math.radians(19.77),
                      math.radians(-14.44))


def _spatial_wall(without=()):
    """The walled-off 3-2-1 scene of ``test/test_voronoi_spatial.py``: a wall across x = 0,
    P7 held at z in [0.6, 0.7]."""
    from voronoi_pkg.spatial321 import DEMO_BASE, Spatial321Model

    plat = {7: (0.0, 0.0, 0.0), 8: (-0.2, 0.12, 0.0), 9: (-0.2, -0.12, 0.0)}
    wall = ({'center': (0.0, 0.05, 0.95), 'size': (0.06, 1.6, 0.8)},)
    return Spatial321Model(DEMO_BASE, plat, wall, (-0.25, -0.3, 0.6), (0.4, 0.4, 0.7),
                           math.radians(20), (0.3, 1.6), without=tuple(without))


def _spatial_ablations():
    """The 3-2-1 roadmap (100 Halton samples) with each construct switched off."""
    from voronoi_pkg.spatial321 import DEMO_START, check_path6, demo_model, densify6
    from voronoi_pkg.spatial321_roadmap import DiagramRoadmapPlanner

    wall_start, wall_goal = (-0.2, 0.3, 0.65, 0.0, 0.0, 0.0), (0.3, 0.3, 0.65, 0.0, 0.0, 0.0)
    cases = [('singularity (3-2-1)', 'demo start to a pose across [p4 p7 p8 p9] = 0',
              demo_model, DEMO_START, ACROSS_SINGULARITY),
             ('collision (3-2-1)', 'across a wall spanning the bounds', _spatial_wall,
              wall_start, wall_goal)]
    out = []
    for name, query, make, start, goal in cases:
        full = make()
        a = DiagramRoadmapPlanner(full, n_samples=100).plan(start, goal)
        b = DiagramRoadmapPlanner(make(without=[name.split()[0]]), n_samples=100).plan(start,
                                                                                      goal)
        decided = ('singularity certificate' if 'singularity cells' in a.reason
                   else 'diagram search' if a.reason else '')
        verdict = '—'
        if b.found:
            ok, min_rho, _ = check_path6(full, b.path)
            signs = full.singular_signs(densify6(b.path, 0.005, 0.01)[0])
            crossed = bool(np.any(signs != signs[:, :1]))
            verdict = ('free' if ok else f'not free under the full model: min rho '
                       f'{min_rho + 0.0:.3g}' + (', crosses a singularity' if crossed else ''))
        out.append(f'| {name} | {query} | {a.status} ({decided}) | {b.status} | {verdict} |')
    return out


def _spatial():
    """The 3-2-1 demo query (straight line blocked by the box): roadmap on the diagram."""
    from voronoi_pkg.spatial321 import DEMO_GOAL, DEMO_START, demo_model
    from voronoi_pkg.spatial321_roadmap import DiagramRoadmapPlanner
    model = demo_model()
    out = []
    for n in (200, 400):
        res, wall, cpu = _timed(lambda: DiagramRoadmapPlanner(model, n_samples=n).plan(
            np.array(DEMO_START), np.array(DEMO_GOAL)))
        s = res.stats
        length = s.get('path_length_scaled', math.nan)
        straight = float(np.linalg.norm((np.array(DEMO_GOAL) - np.array(DEMO_START))
                                        * model.scale))
        out.append(f"| {n} | {res.status} | {wall:.1f} ({cpu:.1f}) | "
                   f"{_f(s.get('on_diagram_fraction'), '.3f')} | "
                   f"{_f(s.get('on_diagram_fraction_between_retractions'), '.3f')} | "
                   f"{_f(length, '.2f')} vs {straight:.2f} | "
                   f"{s.get('retracted_on_diagram')}/{s.get('free_samples')} | "
                   f"{_f(res.min_rho, '.3g')} |")
    return out


def _rho_rate(n):
    model = paper_model()
    rng = np.random.default_rng(0)
    d = model.domain
    q = rng.uniform([d.x[0], d.y[0], d.phi[0]], [d.x[1], d.y[1], d.phi[1]], (n, 3))
    _, wall, cpu = _timed(lambda: model.rho(q))
    return n / wall, n / max(cpu, 1e-9)


def _plot(path, rows):
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt
    from matplotlib.collections import LineCollection

    from voronoi_pkg.diagram import tie_segments
    fig, axes = plt.subplots(1, len(rows), figsize=(5 * len(rows), 5), squeeze=False)
    for ax, row in zip(axes[0], rows):
        model = row['model']
        xs, ys = grid_axes(model.domain, 0.5)
        segs = tie_segments(model, float(row['res'].path[0, 2]) if row['res'].found else 0.0,
                            xs, ys)
        ax.add_collection(LineCollection(segs, colors='0.75', linewidths=0.6))
        scene = [(model.fixed[a], model.fixed[b]) for a, b in model.segments.values()
                 if a in model.fixed and b in model.fixed]
        ax.add_collection(LineCollection(scene, colors='k', linewidths=2))
        for r, colour, label in ((row['res'], 'tab:blue', 'on the diagram'),
                                 (row['grid'], 'tab:orange', 'clearance-weighted grid')):
            if r.found:
                ax.plot(r.path[:, 0], r.path[:, 1], color=colour, lw=1.6, label=label)
        ax.set_xlim(-30, 60)
        ax.set_ylim(-45, 45)
        ax.set_aspect('equal')
        ax.set_title(f"{row['scene']} (grey: diagram slice at the start's orientation)",
                     fontsize=9)
        ax.legend(loc='upper right', fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=80)
    plt.close(fig)


def _f(v, fmt='.1f'):
    return '—' if v is None or (isinstance(v, float) and math.isnan(v)) else format(v, fmt)


def write_report(out_dir: Path, quick: bool = False) -> list:
    """Rerun the Voronoi planner's measurements; write ``out_dir/voronoi.md`` and
    ``out_dir/voronoi_paths.png``; return the paths written. ``quick``: the paper query and
    the block scene only, no 3-2-1 runs, and a smaller rho batch."""
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    start = datetime.datetime.now(datetime.timezone.utc)
    build = _construction()
    names = list(SCENES)[:2] if quick else list(SCENES)
    rows = [_compare(n, *SCENES[n]) for n in names]
    walled = _model([WALL])
    nopath, np_wall, _ = _timed(lambda: VoronoiPlanner(walled).plan((20.0, -10.0, 0.0),
                                                                    (20.0, -30.0, 0.0)))
    ablation = _ablations()
    rate, rate_cpu = _rho_rate(200_000 if quick else 1_000_000)
    spatial = ['| — | skipped in quick mode | | | | | | |'] if quick else _spatial()
    png = out_dir / 'voronoi_paths.png'
    _plot(png, rows[:2])
    wall = (datetime.datetime.now(datetime.timezone.utc) - start).total_seconds()
    table = []
    for r in rows:
        v, g = r['v'], r['g']
        table.append(
            f"| {r['scene']} | {_f(v['length'])} / {_f(g['length'])} | "
            f"{_f(v['min_rho'], '.3g')} / {_f(g['min_rho'], '.3g')} | "
            f"{_f(v['clear'], '.2f')} / {_f(g['clear'], '.2f')} | "
            f"{_f(v['wall'], '.2f')} ({_f(v['cpu'], '.2f')}) / {_f(g['wall'], '.2f')} "
            f"({_f(g['cpu'], '.2f')}) | {v['size']} / {g['size']} | {_f(v['share'], '.3f')} |")
    lines = [
        '# Simplified Voronoi planning: measured results', '',
        f"Generated {start:%Y-%m-%d %H:%M} UTC on `{platform.node()}` "
        f"({platform.processor() or platform.machine()}, {os.cpu_count()} cores) by "
        f"`paramotion report --only voronoi{' --quick' if quick else ''}` "
        f"(`voronoi_pkg.report.write_report`) in "
        f"{wall / 60:.1f} min{' (quick: paper query and block scene)' if quick else ''}. "
        f'Python {sys.version.split()[0]}. Times are wall seconds on a machine shared with '
        'other jobs, CPU seconds in brackets.', '',
        '## The diagram (paper scene, 1-unit grid, 144 slices 2.5° apart)', '',
        '| nodes | vertices (three contacts tie) | edges | nodes on the diagram | edge '
        'midpoints on the diagram | build time |', '| --- | --- | --- | --- | --- | --- |',
        f"| {build['nodes']} | {build['vertices']} | {build['edges']} | "
        f"{build['nodes_tied']:.4f} | {build['mids_tied']:.4f} | {build['wall']:.2f} s "
        f"({build['cpu']:.2f}) |", '',
        '"On the diagram": the two smallest contacts, decided by different determinants, tie '
        'within `voronoi_pkg.ties.tie_tolerance`.', '',
        '## Planner on the diagram / clearance-weighted grid planner (same grid and slices)',
        '',
        '| scene | length | min rho | min Euclidean clearance | time, s | searched graph '
        '(diagram nodes / free grid vertices) | on the diagram (within 0.05, climbs '
        'excluded) |', '| --- | --- | --- | --- | --- | --- | --- |', *table, '',
        'Length: x, y and phi × 10 (the platform length). Clearance: distance between the '
        'platform segment and the nearest base, boundary or obstacle segment '
        '(`grid_baseline.segment_clearance`). Picture: `voronoi_paths.png`.', '',
        '## "No path"', '',
        '| query | answer | decided by | time, s |', '| --- | --- | --- | --- |',
        f"| wall across the square, start (20, -10, 0°) and goal (20, -30, 0°) in one "
        f"singularity cell | {nopath.status} | {nopath.stats.get('decided_by')} "
        f"({nopath.stats.get('slices')} slices, {nopath.stats.get('diagram_nodes')} diagram "
        f"nodes) | {np_wall:.2f} |", '',
        '## Ablations (`--without NAME`; planar: 1.5-unit grid, 5° slices; 3-2-1: 100 '
        'Halton samples)', '',
        '| switched off | query | with it | without it | the path found without it |',
        '| --- | --- | --- | --- | --- |', *ablation, '',
        '## 3-2-1 platform (demo scene, straight line blocked by the box)', '',
        '| Halton samples | status | time, s | on the diagram (2 mm) | between the '
        'retraction chains | path length vs straight (scaled metric) | samples retracted onto '
        'the diagram | min rho |', '| --- | --- | --- | --- | --- | --- | --- | --- |',
        *spatial, '',
        '## rho', '',
        f'rho of the paper scene (P1 ∧ P2): {rate:.3g} configurations/s wall, '
        f'{rate_cpu:.3g} per CPU second.', '',
    ]
    md = out_dir / 'voronoi.md'
    md.write_text('\n'.join(lines))
    return [md, png]
