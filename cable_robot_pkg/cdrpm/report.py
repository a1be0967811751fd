"""Headline measurements of the KNTU workspace part, written as ``<out_dir>/workspace.md``.

:func:`write_report` reruns, for the shipped Neuron (an arrangement fitted to Table II and the
TOW box), every published figure of Aref & Taghirad beside ours, marked fitted or held out
(:func:`cable_robot_pkg.cdrpm.paper_figures.published_table`); the Fig. 7 curves and what sets
them; the workpiece study; the ablation of each collision construct (``without``); and the
spread of every figure when the unknown anchors move by a few centimetres. The search over all
candidate arrangements (``paramotion workspace heldout``, about 10-20 minutes) is not rerun: its
committed result, ``<out_dir>/workspace_heldout/result.json``, is summarised with the command
and date that produced it.
"""
from __future__ import annotations

import json
import os
import platform
import sys
import time
from pathlib import Path

import numpy as np

from cable_robot_pkg.cdrpm import paper_figures as pf
from cable_robot_pkg.cdrpm.description import RobotDescription, load_description
from cable_robot_pkg.cdrpm.workspace import constant_orientation_workspace, workpiece_study

#: What the paper says happens without each construct, and what is measured for it.
ABLATIONS = (
    ('cable_cable', 'Table II 0/0/30 and 30/30/30 and the r_z panels of Fig. 7 lose their '
     'limit: cable-cable contact is what bounds them (IV-B: with z-rotation cable-cable '
     'collision comes first)'),
    ('cable_body', 'the r_x-r_y corner of Fig. 7 opens: the paper names cable-body contact as '
     "the limit of r_y as r_x grows; Table II's rotated rows rise"),
    ('cable_workpiece', 'the workpiece no longer removes any position (IV-D: 60 % kept)'),
    ('workpiece_sides', "the paper's own top-plane test (III-C): cables through a side face "
     'only are missed, so more of the plane looks accessible'),
)


def _fmt(value, digits=1, unit=''):
    if value is None or (isinstance(value, float) and not np.isfinite(value)):
        return '-'
    return f'{value:.{digits}f}{unit}'


def _table(header, rows):
    lines = ['| ' + ' | '.join(header) + ' |', '|' + '---|' * len(header)]
    lines += ['| ' + ' | '.join(str(c) for c in row) + ' |' for row in rows]
    return lines


def ablation_rows(desc: RobotDescription, step: float, plane_step: float,
                  fig7_step: float) -> list[dict[str, object]]:
    """Measured figures with each construct of :data:`ABLATIONS` switched off (and none)."""
    out = []
    for name, predicted in (('none', 'the fitted figures'),) + ABLATIONS:
        without = () if name == 'none' else (name,)
        z30 = constant_orientation_workspace(desc, (0, 0, 30), step=step, without=without)
        all30 = constant_orientation_workspace(desc, (30, 30, 30), step=step, without=without)
        trend = pf.fig7_trend(desc, rx_deg=(0.0, 45.0), rz_deg=(0.0, 30.0),
                              step_deg=fig7_step, without=without)
        verdict = pf.fig7_verdict(trend)
        work = workpiece_study(desc, pf.WORKPIECE_M, step=plane_step, without=without)
        out.append({'without': name, 'predicted': predicted,
                    'table2_0_0_30': z30.collision_free_percentage,
                    'table2_30_30_30': all30.collision_free_percentage,
                    'ry_limit_rx0': verdict['ry_limit_low'],
                    'ry_limit_rx45': verdict['ry_limit_high'],
                    'decided_rx45': verdict['decided_high'],
                    'workpiece_share': work['ratio_percent']})
    return out


def fig7_figure(desc: RobotDescription, trends: dict[str, list[pf.Fig7Row]],
                path: Path) -> Path:
    """Fig. 7 as curves, one panel per rotation convention (``trends``: label -> rows): the
    r_y limit against r_x per r_z, markers by the collision type that sets it."""
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt
    markers = {'cable_cable': 'o', 'cable_body': 's', 'cable_cable+cable_body': 'D',
               'outside_frame': 'x', 'range': '^'}
    fig, axes = plt.subplots(1, len(trends), figsize=(5.6 * len(trends), 4.4), sharey=True,
                             squeeze=False)
    for ax, (label, trend) in zip(axes[0], trends.items()):
        for k, rz in enumerate(sorted({r['rz'] for r in trend})):
            rows = [r for r in trend if r['rz'] == rz]
            ax.plot([r['rx'] for r in rows], [r['ry_limit'] for r in rows], color=f'C{k}',
                    label=f'r_z = {rz:g} deg')
            for r in rows:
                ax.plot(r['rx'], r['ry_limit'], markers.get(r['decided_by'], '*'),
                        color=f'C{k}', markersize=6)
        ax.set_xlabel('r_x (deg)')
        ax.set_title(label, fontsize=9)
        ax.grid(alpha=0.3)
    for name, m in markers.items():
        axes[0, 0].plot([], [], m, color='k', label=f'set by {name.replace("_", "-")}')
    axes[0, 0].set_ylabel('largest |r_y| reachable from 0 (deg)')
    axes[0, 0].legend(fontsize=7, ncol=2)
    fig.suptitle(f'{desc.name} (arrangement fitted to Table II and the TOW box): Fig. 7 at the '
                 'centre; the paper: the limit shrinks with r_x, set by cable-body contact',
                 fontsize=9)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def _heldout_lines(out_dir: Path) -> list:
    path = out_dir / 'workspace_heldout' / 'result.json'
    if not path.exists():
        return ['The candidate search (`paramotion workspace heldout --out '
                f'{out_dir}/workspace_heldout`) has not been run into this directory.']
    data = json.loads(path.read_text())
    s, st = data['summary'], data['stats']
    lines = [f'From `{data.get("command")}` ({data.get("date_utc")}, {data.get("machine")}, '
             f'{_fmt(data.get("wall_time_s", 0) / 60, 0)} min). Of the '
             f'{st["candidates_total"]:,} edge-anchored candidates of the fit that hold the '
             f'platform at home, {s["candidates"]:,} are evaluated: the '
             f'{st["near_table2_screen"]} within 8 points of Table II on a 0.2 m grid and '
             f'{st["sampled_others"]:,} others drawn at random (seed {st["sample_seed"]}).', '']
    lines += _table(['evaluated candidates that ...', 'moving axes', 'fixed axes'], [
        ('have a Fig. 7 r_y limit that shrinks from r_x = 0 to 45 deg (r_z = 0)',
         s['fig7_shrinks'], s['fig7_fixed_shrinks']),
        ("... with cable-body contact setting it at r_x = 45 deg (the paper's Fig. 7)",
         s['fig7_shrinks_by_cable_body'], s['fig7_fixed_shrinks_by_cable_body']),
        ('... among the sampled ones (far from Table II)', s['sampled_fig7_trend'],
         s['sampled_fig7_fixed_trend']),
        ('fitted set (below) with a shrinking limit', s['fitted_with_fig7_shrinking'],
         s['fitted_with_fig7_fixed_shrinking']),
        ("fitted set with the paper's Fig. 7", s['fitted_with_fig7_trend'],
         s['fitted_with_fig7_fixed_trend']),
        ("best Table II screen among those with the paper's Fig. 7 (points)",
         _fmt(s['best_table2_screen_with_fig7_trend']),
         _fmt(s['best_table2_screen_with_fig7_fixed_trend'])),
    ])
    lines += ['']
    lines += _table(['evaluated candidates that ...', 'count'], [
        ('keep 60 +- 5 % of the plane with a 1 x 1 x 0.5 m workpiece, closest approach '
         '0.5 +- 0.1 m', s['workpiece_60_at_default_size']),
        ('have the moving-axes Fig. 7 and that workpiece figure', s['fig7_and_workpiece']),
        ('match Table II within 5 points (in frame, 0.05 m grid)', s['table2_within_5']),
        ('... and hold the TOW box (the fitted set)', s['table2_and_tow_box']),
        ('of the fitted set, with the workpiece figures for some scanned workpiece size',
         s['fitted_with_workpiece_60_some_size']),
        ("of the fitted set, with the paper's Fig. 7 (moving axes) and the workpiece figures",
         s['fitted_with_both']),
    ])
    lines += ['', 'What sets the r_y limit at r_x = 45 deg in the fitted set: moving axes '
              + ', '.join(f'{k.replace("_", "-")} {v}'
                          for k, v in s['fitted_fig7_decided_by'].items())
              + '; fixed axes '
              + ', '.join(f'{k.replace("_", "-")} {v}'
                          for k, v in s['fitted_fig7_fixed_decided_by'].items()) + '.']
    return lines


def write_report(out_dir: Path, quick: bool = False) -> list[Path]:

    """Rerun the headline measurements; write ``out_dir/workspace.md`` and its PNG.

    ``quick`` uses coarse grids (0.1 m, 2 deg) and three perturbed samples (under two
    minutes); the full run uses the 0.05 m grid, 1 deg and twelve samples.
    """
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    start = time.perf_counter()
    desc = load_description()
    step = 0.1 if quick else 0.05
    plane_step = 0.04 if quick else 0.02
    fig7_step = 2.0 if quick else 1.0
    pub = pf.published_table(desc, quick=quick)
    ablation = ablation_rows(desc, step, plane_step, fig7_step)
    sens = pf.anchor_sensitivity(desc, samples=3 if quick else 12, spread_m=0.03, quick=quick)
    radii = pf.radius_sensitivity(desc, step=step, fig7_step=fig7_step)
    sizes = pub['workpiece_sizes']
    rx_fine = tuple(float(v) for v in range(0, 76, 5))
    curves = {f'{name} axes (R = {order})': [
        r.__dict__ for r in pf.fig7_trend(desc, rx_deg=rx_fine, step_deg=fig7_step, axes=name)]
        for name, order in (('moving', 'Rx Ry Rz'), ('fixed', 'Rz Ry Rx'))}
    png = fig7_figure(desc, curves, out_dir / 'workspace_fig7.png')
    elapsed = time.perf_counter() - start

    cmd = ('python -c "from pathlib import Path; from cable_robot_pkg.cdrpm.report import '
           f'write_report; write_report(Path(\'{out_dir}\'), quick={quick})"')
    lines = ['# KNTU CDRPM workspace: measured results', '',
             f'- date: {time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime())}',
             f'- machine: {platform.node()}, {platform.processor() or "unknown CPU"}, '
             f'{os.cpu_count()} cores; Python {sys.version.split()[0]}',
             f'- command: `{cmd}` (or `paramotion report`); {elapsed:.0f} s',
             f'- robot: `{desc.name}`, the arrangement fitted to Table II and the TOW box '
             f'(`{Path(desc.source).name}`); grid step {step} m, plane step {plane_step} m, '
             f'orientation step {fig7_step} deg', '',
             '## Every published figure, fitted or held out', '',
             'Fitted: used to choose the arrangement (`paramotion workspace arrangements '
             '--table2`). Held out: not used. "Agrees": within 5 points for shares, 0.1 m for '
             'the closest approach.', '']
    lines += _table(['published figure', 'paper', 'ours', 'use', 'agrees', 'note'],
                    [(r['figure'], r['paper'], r['ours'], r['use'],
                      'yes' if r['agrees'] else '**no**', r['note']) for r in pub['rows']])
    lines += ['', '## Table II in detail', '']
    lines += _table(['r_x r_y r_z', 'paper', 'in frame', 'eq. (10)', 'outside frame',
                     'cable-cable', 'cable-body', 'points'],
                    [(' '.join(f'{v:g}' for v in r['rotation_deg']), f'{r["paper"]:g} %',
                      _fmt(r['in_frame'], 1, ' %'), _fmt(r['eq10'], 1, ' %'),
                      r['outside_frame'], r['cable_cable'], r['cable_body'], r['total_points'])
                     for r in pub['table2']])
    lines += ['', '## Fig. 7 at the centre: the r_y limit and what sets it', '',
              f'![Fig. 7 curves]({png.name})', '',
              'Moving axes (R = Rx Ry Rz, the convention of IV-C and of this package); the '
              'fixed-axes panel of the picture uses R = Rz Ry Rx.', '']
    lines += _table(['r_z', 'r_x', 'largest r_y (deg)', 'set by'],
                    [(f'{r["rz"]:g}', f'{r["rx"]:g}', _fmt(r['ry_limit'], 0),
                      r['decided_by'].replace('_', '-')) for r in pub['fig7']])
    work = pub['workpiece']
    lines += ['', '## Workpiece (IV-D), plane y = 0', '',
              f'Workpiece {" x ".join(f"{v:g}" for v in work["size_m"])} m on the floor '
              f'centre: {_fmt(work["share"])} % of the plane kept (paper 60 %), closest platform '
              f'bottom above it {_fmt(work["gap_m"], 2)} m (paper 0.5 m). Share of the plane '
              'lost per type (a point may have several): '
              + ', '.join(f'{k.replace("_", "-")} {_fmt(v)} %'
                          for k, v in work['lost_percent'].items()) + '.', '']
    lines += ['Other workpiece sizes (the paper gives none; W_x = W_y, plane step '
              f'{0.05 if quick else 0.04} m):', '']
    lines += _table(['W_x = W_y (m)', 'W_z (m)', 'share kept', 'closest approach'],
                    [(f'{s["size_m"][0]:g}', f'{s["size_m"][2]:g}', _fmt(s['share'], 1, ' %'),
                      _fmt(s['gap_m'], 2, ' m')) for s in sizes])
    lines += ['']
    tow = pub['tow']
    lines += [f'TOW for +-30, +-30, +-10 deg: {_fmt(tow["tow_percent"])} % of the grid, '
              f'largest box {" x ".join(f"{v:.2f}" for v in tow["largest_box_m"] or [])} m; '
              f'for +-30 deg about every axis: {_fmt(tow["cube_tow_percent"])} %, largest box '
              f'{" x ".join(f"{v:.2f}" for v in tow["cube_largest_box_m"] or [])} m.', '',
              '## Ablation: each construct switched off (`--without NAME`)', '']
    lines += _table(['without', 'the paper predicts', 'Table II 0/0/30 in frame',
                     'Table II 30/30/30 in frame', 'Fig. 7 r_y limit at r_x = 0 / 45',
                     'set by at r_x = 45', 'workpiece share'],
                    [(r['without'], r['predicted'], _fmt(r['table2_0_0_30'], 1, ' %'),
                      _fmt(r['table2_30_30_30'], 1, ' %'),
                      f'{_fmt(r["ry_limit_rx0"], 0)} / {_fmt(r["ry_limit_rx45"], 0)} deg',
                      r['decided_rx45'].replace('_', '-'), _fmt(r['workpiece_share'], 1, ' %'))
                     for r in ablation])
    lines += ['', f'## Sensitivity to the unknown anchors (+-{100 * sens["spread_m"]:g} cm)', '',
              f'Each coordinate of each of the eight anchors moved independently (uniform, '
              f'clamped into the frame), {sens["samples"]} samples, grid step '
              f'{sens["grid_step_m"]} m. For yes/no figures the mean is the share of samples '
              'where it holds.', '']
    lines += _table(['figure', 'nominal', 'min', 'median', 'mean', 'max'],
                    [(r['figure'], _fmt(r['nominal'], 2), _fmt(r['min'], 2),
                      _fmt(r['median'], 2), _fmt(r['mean'], 2), _fmt(r['max'], 2))
                     for r in sens['rows']])
    lines += ['', '## Sensitivity to the cable radius (the paper gives none)', '']
    lines += _table(['epsilon (mm)', 'Table II in frame (%)', 'Fig. 7 limit at r_x = 0 / 45',
                     'set by at r_x = 45'],
                    [(f'{1000 * r["radius_m"]:g}',
                      ' / '.join(f'{v:.1f}' for v in r['table2_in_frame']),
                      f'{_fmt(r["fig7"]["ry_limit_low"], 0)} / '
                      f'{_fmt(r["fig7"]["ry_limit_high"], 0)} deg',
                      r['fig7']['decided_high'].replace('_', '-')) for r in radii])
    lines += ['', '## Which candidate arrangements meet the held-out figures', '']
    lines += _heldout_lines(out_dir)
    md = out_dir / 'workspace.md'
    md.write_text('\n'.join(lines) + '\n')
    return [md, png]


if __name__ == '__main__':  # pragma: no cover
    quick_run = '--quick' in sys.argv[1:]
    for written in write_report(Path(sys.argv[1] if len(sys.argv) > 1 and not
                                     sys.argv[1].startswith('--') else 'docs/results'),
                                quick=quick_run):
        print(written)
