"""``paramotion workspace arrangements``: search of the cable arrangements behind the shipped
Neuron.

Argument parsing lives in :mod:`cable_robot_pkg.cdrpm.cli`; this module turns parsed
arguments into a call of the analysis in :mod:`cable_robot_pkg.cdrpm` and writes its outputs.
"""

import numpy as np

from cable_robot_pkg.cdrpm.cli import common
from paramotion.errors import UserError


def run(args):
    if args.corners and args.table2:
        raise UserError('--corners and --table2: choose one search')
    if args.corners:
        return _corner_arrangements(args)
    from cable_robot_pkg.cdrpm.arrangements import search_edge_arrangements

    desc = common.robot(args)
    common.check_step(desc, args.step)
    common.finite('--pitch', args.pitch, 0.01, float(np.max(desc.frame_half_size)))
    common.finite('--min-gap', args.min_gap, 0.0, 1.0)
    if not 1 <= args.top <= 1000:
        raise UserError(f'--top {args.top}: allowed [1, 1000]')
    out = common.out_dir(args.out) if args.out else None
    if args.table2:
        return _table2_arrangements(args, desc, out)
    rows, stats = search_edge_arrangements(desc.frame_half_size, desc.platform_half_size,
                                           desc.cable_radius, pitch=args.pitch,
                                           min_home_gap=args.min_gap, step=args.step,
                                           progress=True, map_cases=_mapper(args))
    shipped = _shipped_names(desc.platform_half_size)
    for rank, row in enumerate(rows, 1):
        row['rank'] = rank
        row['shipped_as'] = _row_shipped_as(row, desc.platform_half_size, shipped)
    print(f'{stats["pairs"]:,} anchor pairs on the frame edges (pitch {args.pitch} m); '
          f'{stats["distinct_up_to_symmetry"]:,} distinct arrangements with the required '
          f'properties; {stats["home_closed_and_free"]:,} wrench-closed and collision-free at '
          f'home; {stats["home_gap_ok"]:,} also with cables >= {args.min_gap} m apart; '
          f'{stats["home_ok"]:,} also wrench-closed and collision-free there at all '
          f'{stats["home_orientations"]} orientations within +-30, +-30, +-10 deg')
    print(f'{"rank":>4} {"anchor of (+,+,+)":>20} {"anchor of (-,+,+)":>20} | {"box both":>8} '
          f'{"free":>6} {"closed":>6} | {"0 deg both":>10} {"free":>6} | {"gap mm":>6}  shipped')
    for r in rows[:args.top]:
        a0 = ' '.join(f'{v:+.2f}' for v in r['anchor0'])
        a1 = ' '.join(f'{v:+.2f}' for v in r['anchor1'])
        print(f'{r["rank"]:>4} {a0:>20} {a1:>20} | {r["box_both_percent"]:>7.1f}% '
              f'{r["box_collision_free_percent"]:>5.1f}% '
              f'{r["box_wrench_closed_percent"]:>5.1f}% | '
              f'{r["zero_rotation_both_percent"]:>9.1f}% '
              f'{r["zero_rotation_collision_free_percent"]:>5.1f}% | '
              f'{1000 * r["home_min_gap_m"]:>6.1f}  {r["shipped_as"] or ""}')
    print('box: share of (grid point, orientation within +-30, +-30, +-10 deg) pairs that are '
          'collision-free and wrench-closed; 0 deg: the zero-rotation grid')
    if out is not None:
        common.write_outputs(out, {'robot_dimensions_from': desc.source, 'pitch_m': args.pitch,
                             'min_home_gap_m': args.min_gap, 'step_m': args.step,
                             'stats': stats, 'rows': rows})
    return 0


def _mapper(args):
    """Evaluate the search's independent candidates as Dask tasks (or --serial)."""
    from paramotion.sweep import run_args, run_tasks

    def map_cases(fn, cases):
        return run_tasks(fn, cases, desc='candidates', **run_args(args))
    return map_cases


def _table2_arrangements(args, desc, out):
    from cable_robot_pkg.cdrpm.arrangements import search_table2_arrangements
    rows, stats = search_table2_arrangements(desc.frame_half_size, desc.platform_half_size,
                                             desc.cable_radius, pitch=args.pitch,
                                             min_home_gap=args.min_gap, progress=True,
                                             map_cases=_mapper(args))
    shipped = _shipped_names(desc.platform_half_size)
    for rank, row in enumerate(rows, 1):
        row['rank'] = rank
        row['shipped_as'] = _row_shipped_as(row, desc.platform_half_size, shipped)
    print(f'{stats["distinct_up_to_symmetry"]:,} distinct arrangements with the required '
          f'properties; {stats["home_gap_ok"]:,} wrench-closed and collision-free at home with '
          f'cables >= {args.min_gap} m apart; {stats["screen_ok"]:,} near Table II on a 0.2 m '
          f'grid; {stats["table2_ok"]:,} within 5 points of every row on the 0.05 m grid; '
          f'{stats["tow_box_ok"]:,} also hold the paper\'s 1.2 x 1.2 x 1.4 m TOW box')
    print(f'{"rank":>4} {"anchor of (+,+,+)":>20} {"anchor of (-,+,+)":>20} | '
          f'{"Table II in frame (%)":>31} {"worst":>5} | {"TOW":>5} {"closed":>6}  shipped')
    for r in rows[:args.top]:
        a0 = ' '.join(f'{v:+.2f}' for v in r['anchor0'])
        a1 = ' '.join(f'{v:+.2f}' for v in r['anchor1'])
        t2 = ' '.join(f'{v:5.1f}' for v in r['table2_in_frame_percent'])
        print(f'{r["rank"]:>4} {a0:>20} {a1:>20} | {t2:>31} '
              f'{r["table2_max_difference_points"]:>5.1f} | {r["tow_percent"]:>4.1f}% '
              f'{r["zero_rotation_both_percent"]:>5.1f}%  {r["shipped_as"] or ""}')
    print('Table II rows 0/0/0, 30/0/0, 0/30/0, 0/0/30, 30/30/30 (paper 100, 97, 97, 85, 71); '
          'worst: largest difference in points; TOW: +-30, +-30, +-10 deg on a 0.1 m grid; '
          'closed: collision-free and wrench-closed share of the zero-rotation grid; every '
          'row is an arrangement fitted to Table II and the TOW box')
    if out is not None:
        common.write_outputs(out, {'robot_dimensions_from': desc.source, 'criterion': 'table2',
                             'pitch_m': args.pitch, 'min_home_gap_m': args.min_gap,
                             'stats': stats, 'rows': rows})
    return 0


def _corner_arrangements(args):
    from cable_robot_pkg.cdrpm.arrangements import CORNERS, pairing_of, score_pairings
    from cable_robot_pkg.cdrpm.description import load_description, shipped_descriptions

    desc = common.robot(args)
    common.check_step(desc, args.step)
    if not 1 <= args.top <= 1000:
        raise UserError(f'--top {args.top}: allowed [1, 1000]')
    out = common.out_dir(args.out) if args.out else None
    rows = score_pairings(desc.frame_half_size, desc.platform_half_size, desc.cable_radius,
                          step=args.step, progress=True)
    shipped = {}
    for path in shipped_descriptions():
        other = load_description(path)
        if np.allclose(other.frame_half_size, desc.frame_half_size) and np.allclose(
                other.platform_half_size, desc.platform_half_size):
            perm = pairing_of(other)
            if perm is not None:
                shipped[tuple(perm)] = other.name
    for rank, row in enumerate(rows, 1):
        row['rank'] = rank
        row['shipped_as'] = shipped.get(tuple(row['pairing']))
        row['frame_corner_signs'] = CORNERS[row['pairing']].astype(int).tolist()
    print(f'{len(rows)} admissible corner-to-corner pairings with a half turn about x or y and '
          f'no z mirror; frame {desc.frame_half_size.tolist()}, platform '
          f'{desc.platform_half_size.tolist()}, zero rotation, grid step {args.step} m')
    print(f'{"rank":>4} {"pairing":>17} {"axes":>4} {"coll-free":>9} {"wrench":>7} '
          f'{"both":>6}  shipped')
    listed = rows[:args.top] + [r for r in rows[args.top:] if r['shipped_as']]
    for r in listed:
        print(f'{r["rank"]:>4} {" ".join(str(p) for p in r["pairing"]):>17} '
              f'{r["half_turn_axes"]:>4} {r["collision_free_percent"]:>8.1f}% '
              f'{r["wrench_closed_percent"]:>6.1f}% {r["both_percent"]:>5.1f}%  '
              f'{r["shipped_as"] or ""}')
    print('pairing: frame corner joined to platform corners 0..7 (corner k has signs '
          '(sx, sy, sz) in the order of the shipped YAML files)')
    if out is not None:
        common.write_outputs(out, {'robot_dimensions_from': desc.source, 'step_m': args.step,
                             'rows': rows})
    return 0


def _shipped_names(platform_half_size):
    """Shipped descriptions by their cable set, to mark search rows that were shipped."""
    from cable_robot_pkg.cdrpm.description import load_description, shipped_descriptions
    shipped = {}
    for path in shipped_descriptions():
        other = load_description(path)
        key = frozenset(zip(map(tuple, np.round(other.platform_points, 9)),
                            map(tuple, np.round(other.frame_points, 9))))
        shipped[key] = other.name
    return shipped


def _row_shipped_as(row, platform_half_size, shipped):
    from cable_robot_pkg.cdrpm.arrangements import symmetric_cables
    signs, anchors = symmetric_cables(row['anchor0'], row['anchor1'])
    key = frozenset(zip(map(tuple, np.round(signs * platform_half_size, 9)),
                        map(tuple, np.round(anchors, 9))))
    return shipped.get(key)
