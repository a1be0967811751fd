"""``paramotion workspace table2``: the paper's Table II rows beside ours (eq. (10)).

Argument parsing lives in :mod:`cable_robot_pkg.cdrpm.cli`; this module turns parsed
arguments into a call of the analysis in :mod:`cable_robot_pkg.cdrpm` and writes its outputs.
"""

from cable_robot_pkg.cdrpm.cli import common


def run(args):
    from cable_robot_pkg.cdrpm.workspace import table2

    desc = common.robot(args)
    common.check_step(desc, args.step)
    out = common.out_dir(args.out) if args.out else None
    without = common.without(args)
    rows = table2(desc, step=args.step, progress=True, without=without)
    if without:
        print(f'constructs switched off: {", ".join(sorted(without))}')
    print(f'Table II, robot {common.robot_label(desc)} ({desc.source}), '
          f'grid step {args.step} m, {rows[0]["total_points"]} points per row')
    print(f'{"theta_x":>7} {"theta_y":>7} {"theta_z":>7} | {"paper":>6} {"WARP":>5} | '
          f'{"ours eq10":>9} {"diff":>6} | {"coll-free":>9} {"outside":>8} '
          f'{"cab-cab":>8} {"cab-body":>8}')
    for r in rows:
        rx, ry, rz = r['rotation_deg']
        warp = '-' if r['paper_warp_percent'] is None else f'{r["paper_warp_percent"]:.0f}%'
        print(f'{rx:>7g} {ry:>7g} {rz:>7g} | {r["paper_kntu_percent"]:>5.0f}% {warp:>5} | '
              f'{r["accessible_percentage"]:>8.1f}% {r["difference_points"]:>+6.1f} | '
              f'{r["collision_free_percentage_in_frame"]:>8.1f}% {r["outside_frame"]:>8} '
              f'{r["cable_cable"]:>8} {r["cable_body"]:>8}')
    print("eq10 counts every grid point (a platform poking out of the frame is not accessible); "
          "coll-free is the share of in-frame points without collision (the paper's checks).")
    if out is not None:
        common.write_outputs(out, {'robot': desc.name, 'robot_file': desc.source,
                                   'step_m': args.step, 'without': sorted(without),
                                   'rows': rows})
    return 0
