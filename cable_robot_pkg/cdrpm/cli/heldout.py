"""``paramotion workspace heldout``: which candidate arrangements reproduce the paper's held-out
figures (Fig. 7's trend, the workpiece share) together with the fitted ones (Table II, the TOW
box).

Argument parsing lives in :mod:`cable_robot_pkg.cdrpm.cli`; this module turns parsed
arguments into a call of the analysis in :mod:`cable_robot_pkg.cdrpm` and writes its outputs.
"""
import os
import platform
import time

from cable_robot_pkg.cdrpm.cli import common


def trimmed(res):
    """The result without the per-candidate rows that meet none of the published figures:
    kept are the rows near Table II and those with the paper's Fig. 7 trend or workpiece share
    (the counts in ``summary`` cover every candidate)."""
    from cable_robot_pkg.cdrpm.paper_figures import PAPER_WORKPIECE_SHARE, TOLERANCE_POINTS

    def keep(r):
        return ('table2_worst' in r or (r['fig7']['shrinks'] and r['fig7']['body_decides'])
                or (r['fig7_fixed']['shrinks'] and r['fig7_fixed']['body_decides'])
                or abs(r['workpiece_share'] - PAPER_WORKPIECE_SHARE) <= TOLERANCE_POINTS)
    rows = [r for r in res['rows'] if keep(r)]
    return {**res, 'rows': rows, 'rows_kept': len(rows), 'rows_total': len(res['rows'])}


def run(args):
    from cable_robot_pkg.cdrpm.cli.arrangements import _mapper
    from cable_robot_pkg.cdrpm.paper_figures import heldout_search

    desc = common.robot(args)
    common.finite('--pitch', args.pitch, 0.05, 1.0)
    out = common.out_dir(args.out)
    start = time.perf_counter()
    if args.sample < -1:
        from paramotion.errors import UserError
        raise UserError(f'--sample {args.sample}: must be >= 0, or -1 for all')
    res = heldout_search(desc, pitch=args.pitch, sample=args.sample, map_cases=_mapper(args))
    res.update({'robot_dimensions_from': desc.source, 'pitch_m': args.pitch,
                'date_utc': time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime()),
                'machine': f'{platform.node()}, {platform.processor() or "unknown CPU"}, '
                           f'{os.cpu_count()} cores',
                'wall_time_s': time.perf_counter() - start,
                'command': f'paramotion workspace heldout --pitch {args.pitch} '
                           f'--sample {args.sample} --out {out}'})
    common.write_outputs(out, trimmed(res))
    s = res['summary']
    st = res['stats']
    print(f'{st["candidates_total"]:,} candidates (edge anchors, pitch {args.pitch} m, held at '
          f'home), {st["near_table2_screen"]} near Table II, {st["sampled_others"]} others '
          f'sampled; of these {s["candidates"]:,} evaluated: '
          f'Fig. 7 limit shrinking with r_x: {s["fig7_shrinks"]:,}, set by cable-body contact: '
          f'{s["fig7_shrinks_by_cable_body"]:,}; workpiece share 60 +- 5 % and gap 0.5 +- 0.1 m '
          f'at {" x ".join("1 1 0.5".split())} m: {s["workpiece_60_at_default_size"]:,}; '
          f'Table II within 5 points: {s["table2_within_5"]}, also the TOW box: '
          f'{s["table2_and_tow_box"]}, of which with the Fig. 7 trend: '
          f'{s["fitted_with_fig7_trend"]}, with the workpiece figures at some size: '
          f'{s["fitted_with_workpiece_60_some_size"]}, both: {s["fitted_with_both"]} '
          f'-> {out}/result.json')
    return 0
