"""``paramotion workspace``: geometric workspace of the KNTU CDRPM (Aref & Taghirad).

Subcommands (each writes ``DIR/result.json`` and a PNG, except ``table2`` and ``bench`` which
print a table and may write JSON):

* ``cow``: constant-orientation workspace at one orientation (section IV-A, Fig. 6 slices).
* ``table2``: the paper's Table II rows beside the paper's figures.
* ``orientation``: orientation workspace at one position (section IV-B, Fig. 7).
* ``tow``: total orientation workspace over a +-theta box and the largest box in it (IV-C).
* ``workpiece``: the workpiece study of section IV-D on the plane y = 0.
* ``wrench``: where positive cable tensions balance any wrench (beyond the paper).
* ``bench``: COW poses per second with all checks, beside the paper's 373 s for 148,000 points.

``--robot`` defaults to the shipped Neuron description (cable_robot_pkg/config/kntu_neuron.yaml).
"""
import json
import math
import os
import statistics
import tempfile
from pathlib import Path

import numpy as np

from paramotion.errors import UserError

#: Largest grid accepted (points), so that a typo in --step cannot exhaust memory.
MAX_GRID_POINTS = 20_000_000
#: Colours of the collision categories in the figures.
CATEGORY_COLOURS = {
    'accessible': '#d9f0d3', 'outside_frame': '#bdbdbd', 'cable_cable': '#d7301f',
    'cable_body': '#2b8cbe', 'cable_workpiece': '#fd8d3c', 'platform_workpiece': '#756bb1'}


def register(subparsers):
    """Add ``paramotion workspace {cow,table2,orientation,tow,workpiece,wrench,bench}``."""
    parser = subparsers.add_parser(
        'workspace', help='KNTU CDRPM collision-free workspace (Aref & Taghirad)',
        description='Geometric workspace analysis of a cable-driven redundant parallel '
                    'manipulator: constant-orientation, orientation and total orientation '
                    'workspaces, workpiece study, wrench closure and a speed benchmark.')
    sub = parser.add_subparsers(dest='workspace_command', metavar='ACTION')
    sub.required = True

    def robot_arg(p):
        p.add_argument('--robot', help='robot description YAML (default: shipped Neuron)')

    p = sub.add_parser('cow', help='constant-orientation workspace (IV-A, Fig. 6)',
                       description='Accessible centroid positions at one orientation; writes '
                                   'DIR/result.json and DIR/cow.png.')
    robot_arg(p)
    p.add_argument('--rot', nargs=3, type=float, required=True, metavar=('RX', 'RY', 'RZ'),
                   help='orientation in degrees (R = Rx Ry Rz)')
    p.add_argument('--step', type=float, default=0.05, help='grid step in m (default 0.05)')
    p.add_argument('--out', required=True, help='output directory')
    p.set_defaults(func=_cow)

    p = sub.add_parser('table2', help="the paper's Table II beside ours",
                       description="Accessible percentage (eq. (10)) for the rows of the "
                                   "paper's Table II.")
    robot_arg(p)
    p.add_argument('--step', type=float, default=0.05, help='grid step in m (default 0.05)')
    p.add_argument('--out', help='optional directory for result.json')
    p.set_defaults(func=_table2)

    p = sub.add_parser('orientation', help='orientation workspace at a position (IV-B, Fig. 7)',
                       description='Accessible (r_x, r_y) for several r_z at one position; '
                                   'writes DIR/result.json and DIR/orientation.png.')
    robot_arg(p)
    p.add_argument('--position', nargs=3, type=float, default=[0.0, 0.0, 0.0],
                   metavar=('X', 'Y', 'Z'), help='platform centroid in m (default origin)')
    p.add_argument('--rz', nargs='+', type=float, default=[0.0, 10.0, 20.0, 30.0],
                   help='r_z values in degrees (default 0 10 20 30)')
    p.add_argument('--max-angle', type=float, default=90.0,
                   help='scan r_x, r_y over +-this many degrees (default 90)')
    p.add_argument('--angle-step', type=float, default=1.0, help='degrees (default 1)')
    p.add_argument('--out', required=True, help='output directory')
    p.set_defaults(func=_orientation)

    p = sub.add_parser('tow', help='total orientation workspace and largest box (IV-C)',
                       description='Intersection of the COWs over a +-theta box of '
                                   'orientations and the largest axis-aligned box inside it; '
                                   'writes DIR/result.json and DIR/tow.png.')
    robot_arg(p)
    p.add_argument('--theta', nargs=3, type=float, default=[30.0, 30.0, 10.0],
                   metavar=('TX', 'TY', 'TZ'), help='half ranges in degrees (default 30 30 10)')
    p.add_argument('--step', type=float, default=0.05, help='grid step in m (default 0.05)')
    p.add_argument('--angle-step', type=float, default=10.0,
                   help='orientation sampling step in degrees (default 10)')
    p.add_argument('--out', required=True, help='output directory')
    p.set_defaults(func=_tow)

    p = sub.add_parser('workpiece', help='workpiece study on the plane y = 0 (IV-D)',
                       description='COW on the vertical plane y = 0 with and without a box '
                                   'workpiece on the floor centre; writes DIR/result.json and '
                                   'DIR/workpiece.png.')
    robot_arg(p)
    p.add_argument('--size', nargs=3, type=float, default=None, metavar=('WX', 'WY', 'WZ'),
                   help="workpiece size in m (default: the description's, else 1 1 0.5)")
    p.add_argument('--rot', nargs=3, type=float, default=[0.0, 0.0, 0.0],
                   metavar=('RX', 'RY', 'RZ'), help='platform orientation in degrees')
    p.add_argument('--step', type=float, default=0.02, help='grid step in m (default 0.02)')
    p.add_argument('--out', required=True, help='output directory')
    p.set_defaults(func=_workpiece)

    p = sub.add_parser('wrench', help='wrench-closure workspace (beyond the paper)',
                       description='Where positive cable tensions can balance any wrench, '
                                   'compared with the collision-free workspace; writes '
                                   'DIR/result.json and DIR/wrench.png.')
    robot_arg(p)
    p.add_argument('--rot', nargs=3, type=float, default=[0.0, 0.0, 0.0],
                   metavar=('RX', 'RY', 'RZ'), help='orientation in degrees')
    p.add_argument('--step', type=float, default=0.05, help='grid step in m (default 0.05)')
    p.add_argument('--out', required=True, help='output directory')
    p.set_defaults(func=_wrench)

    p = sub.add_parser('arrangements', help='search cable arrangements (the derived Neuron)',
                       description='Search the cable arrangements behind the shipped Neuron for '
                                   'the dimensions of --robot: frame anchors on the frame edges '
                                   '(--pitch), symmetric under the half turns about x, y and z, '
                                   'wrench-closed and collision-free at the home pose, ranked by '
                                   'the collision-free and wrench-closed share of the grid x '
                                   '(+-30, +-30, +-10 deg) box. With --corners: the older search '
                                   'of corner-to-corner pairings at zero rotation. Writes '
                                   'DIR/result.json with --out.')
    robot_arg(p)
    p.add_argument('--corners', action='store_true',
                   help='search corner-to-corner pairings instead (zero rotation only)')
    p.add_argument('--table2', action='store_true',
                   help="identify the Neuron from the paper's results instead: Table II "
                        'within 5 points on the in-frame grid and the TOW box 1.2 x 1.2 x 1.4 '
                        'm (the search behind the shipped default; about 5-10 minutes)')
    p.add_argument('--pitch', type=float, default=0.1,
                   help='anchor spacing along the frame edges in m (default 0.1)')
    p.add_argument('--min-gap', type=float, default=0.02,
                   help='smallest cable surface gap at the home pose in m (default 0.02)')
    p.add_argument('--step', type=float, default=0.2, help='grid step in m (default 0.2)')
    p.add_argument('--top', type=int, default=12, help='rows to print (default 12)')
    p.add_argument('--out', help='optional directory for result.json')
    p.set_defaults(func=_arrangements)

    p = sub.add_parser('bench', help='COW poses per second with all checks',
                       description="Median wall time of the COW at 30/30/10 deg on a grid of "
                                   "about 148,000 points (the paper's 373 s), all checks on.")
    robot_arg(p)
    p.add_argument('--points', type=int, default=148000,
                   help='approximate grid size (default 148000, as in the paper)')
    p.add_argument('--runs', type=int, default=7, help='timed runs (default 7)')
    p.add_argument('--rot', nargs=3, type=float, default=[30.0, 30.0, 10.0],
                   metavar=('RX', 'RY', 'RZ'), help='orientation in degrees (default 30 30 10)')
    p.add_argument('--out', help='optional directory for result.json')
    p.set_defaults(func=_bench)


# --- argument checks and output ----------------------------------------------------------------

def _robot(args):
    from cable_robot_pkg.cdrpm.description import load_description
    return load_description(args.robot)


def _finite(name, values, lo=None, hi=None):
    values = values if isinstance(values, (list, tuple)) else [values]
    for v in values:
        if not math.isfinite(v) or (lo is not None and v < lo) or (hi is not None and v > hi):
            rng = f' (allowed [{lo}, {hi}])' if lo is not None or hi is not None else ''
            raise UserError(f'{name} {v}: must be a finite number{rng}')


def _check_step(desc, step, name='--step'):
    if not (math.isfinite(step) and step > 0):
        raise UserError(f'{name} {step}: must be a positive number of metres')
    span = 2 * (desc.frame_half_size - desc.platform_half_size)
    count = float(np.prod(np.maximum(np.floor(span / step + 1e-9), 1)))
    if count > MAX_GRID_POINTS:
        raise UserError(f'{name} {step}: grid of {count:.3g} points exceeds '
                        f'{MAX_GRID_POINTS:,}; use a larger step')


def _out_dir(out):
    out = Path(out)
    if out.exists() and not out.is_dir():
        raise UserError(f'--out {out}: exists and is not a directory')
    return out


def _to_json(value):
    if isinstance(value, dict):
        return {str(k): _to_json(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_to_json(v) for v in value]
    if isinstance(value, np.ndarray):
        return _to_json(value.tolist())
    if isinstance(value, (np.bool_,)):
        return bool(value)
    if isinstance(value, np.integer):
        return int(value)
    if isinstance(value, (float, np.floating)):
        value = float(value)
        return value if math.isfinite(value) else None
    return value


def _write_outputs(out, result, figure=None, figure_name=None):
    """Write result.json (and a figure) atomically once everything is computed."""
    out.mkdir(parents=True, exist_ok=True)
    if figure is not None:
        tmp = out / f'.{figure_name}.tmp.png'
        figure.savefig(tmp, dpi=110)
        os.replace(tmp, out / figure_name)
        import matplotlib.pyplot as plt
        plt.close(figure)
    fd, tmp = tempfile.mkstemp(dir=out, prefix='.result.', suffix='.json')
    with os.fdopen(fd, 'w') as fh:
        json.dump(_to_json(result), fh, indent=2)
        fh.write('\n')
    os.replace(tmp, out / 'result.json')


def _figure(*args, **kwargs):
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt
    return plt.subplots(*args, **kwargs)


def _category_image(flags):
    """Map flag arrays to category indices (order of CATEGORY_COLOURS)."""
    from cable_robot_pkg.cdrpm.collisions import FLAG_OF_TYPE, OUTSIDE
    cat = np.zeros(flags.shape, dtype=int)
    assigned = flags == 0
    cat[(flags & OUTSIDE) != 0] = 1
    assigned |= (flags & OUTSIDE) != 0
    for k, bit in enumerate(FLAG_OF_TYPE.values()):
        hit = ((flags & bit) != 0) & ~assigned
        cat[hit] = 2 + k
        assigned |= hit
    return cat


def _legend(fig):
    from matplotlib.patches import Patch
    handles = [Patch(color=c, label=name.replace('_', '-')) for name, c in
               CATEGORY_COLOURS.items()]
    fig.legend(handles=handles, loc='lower center', ncol=len(handles), fontsize=8)


def _cmap():
    from matplotlib.colors import ListedColormap
    return ListedColormap(list(CATEGORY_COLOURS.values()))


# --- subcommands -------------------------------------------------------------------------------

def _cow(args):
    from cable_robot_pkg.cdrpm.workspace import constant_orientation_workspace

    desc = _robot(args)
    _finite('--rot', args.rot, -180, 180)
    _check_step(desc, args.step)
    out = _out_dir(args.out)
    cow = constant_orientation_workspace(desc, args.rot, step=args.step, progress=True)
    result = cow.to_dict(desc)
    result['robot_file'] = desc.source
    fig = _cow_figure(desc, cow)
    _write_outputs(out, result, fig, 'cow.png')
    print(f'{desc.name}: rotation {args.rot} deg, {result["total_points"]} points, '
          f'accessible {result["accessible_percentage"]:.1f} % '
          f'(collision-free {result["collision_free_percentage_in_frame"]:.1f} % of in-frame), '
          f'{result["wall_time_s"]:.3f} s -> {out}/result.json, {out}/cow.png')
    return 0


def _cow_figure(desc, cow):
    """Six horizontal slices of the COW coloured by outcome (like the paper's Fig. 6)."""
    xs, ys, zs = cow.axes
    cat = _category_image(cow.flags)
    first, last = (1, zs.size - 2) if zs.size > 8 else (0, zs.size - 1)
    picks = np.unique(np.linspace(first, last, 6).round().astype(int))
    fig, axes = _figure(2, 3, figsize=(13, 6.4), squeeze=False)
    ext = [ys[0], ys[-1], xs[0], xs[-1]]
    for ax, k in zip(axes.ravel(), picks):
        ax.imshow(cat[:, :, k], origin='lower', extent=ext, cmap=_cmap(), vmin=-0.5,
                  vmax=len(CATEGORY_COLOURS) - 0.5, interpolation='nearest', aspect='equal')
        acc = 100.0 * np.count_nonzero(cow.flags[:, :, k] == 0) / cow.flags[:, :, k].size
        ax.set_title(f'z = {zs[k]:+.3f} m: {acc:.1f} % accessible', fontsize=9)
        ax.set_xlabel('y (m)')
        ax.set_ylabel('x (m)')
    for ax in axes.ravel()[len(picks):]:
        ax.axis('off')
    rx, ry, rz = cow.rotation_deg
    fig.suptitle(f'{desc.name}: constant-orientation workspace at ({rx:g}, {ry:g}, {rz:g}) deg, '
                 f'{cow.accessible_percentage:.1f} % accessible (eq. 10)')
    _legend(fig)
    fig.tight_layout(rect=(0, 0.05, 1, 0.96))
    return fig


def _table2(args):
    from cable_robot_pkg.cdrpm.workspace import table2

    desc = _robot(args)
    _check_step(desc, args.step)
    out = _out_dir(args.out) if args.out else None
    rows = table2(desc, step=args.step, progress=True)
    print(f"Table II, robot '{desc.name}' ({desc.source}), grid step {args.step} m, "
          f'{rows[0]["total_points"]} points per row')
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
        _write_outputs(out, {'robot': desc.name, 'robot_file': desc.source, 'step_m': args.step,
                             'rows': rows})
    return 0


def _orientation(args):
    from cable_robot_pkg.cdrpm.workspace import orientation_workspace

    desc = _robot(args)
    _finite('--position', args.position)
    if np.any(np.abs(args.position) > desc.frame_half_size):
        raise UserError(f'--position {args.position}: outside the frame '
                        f'(half sizes {desc.frame_half_size.tolist()})')
    _finite('--rz', args.rz, -180, 180)
    _finite('--max-angle', args.max_angle, 1, 180)
    _finite('--angle-step', args.angle_step, 0.05, 45)
    out = _out_dir(args.out)
    res = orientation_workspace(desc, args.position, rz_deg=args.rz,
                                rx_range=(-args.max_angle, args.max_angle),
                                ry_range=(-args.max_angle, args.max_angle),
                                step_deg=args.angle_step)
    boundary = res.boundary()
    from cable_robot_pkg.cdrpm.collisions import count_flags
    result = {
        'robot': desc.name, 'robot_file': desc.source, 'position_m': list(args.position),
        'angle_step_deg': args.angle_step, 'max_angle_deg': args.max_angle,
        'per_rz': [{'rz_deg': b['rz'], **count_flags(res.flags[k]),
                    'accessible_percentage': 100.0 * float(np.mean(res.flags[k] == 0)),
                    'boundary': b['rows']} for k, b in enumerate(boundary)],
    }
    fig = _orientation_figure(desc, res)
    _write_outputs(out, result, fig, 'orientation.png')
    for entry in result['per_rz']:
        print(f'r_z = {entry["rz_deg"]:g} deg: {entry["accessible_percentage"]:.1f} % of the '
              f'(r_x, r_y) square accessible')
    print(f'-> {out}/result.json, {out}/orientation.png')
    return 0


def _orientation_figure(desc, res):
    """Accessible (r_x, r_y) regions, one panel per r_z, boundaries overlaid (Fig. 7)."""
    n = res.rz_deg.size
    cols = min(n, 4)
    rows = -(-n // cols)
    fig, axes = _figure(rows, cols + 1, figsize=(3.6 * (cols + 1), 3.8 * rows), squeeze=False)
    ext = [res.ry_deg[0], res.ry_deg[-1], res.rx_deg[0], res.rx_deg[-1]]
    summary = axes[0, -1]
    for k in range(n):
        ax = axes[k // cols, k % cols]
        ax.imshow(_category_image(res.flags[k]), origin='lower', extent=ext, cmap=_cmap(),
                  vmin=-0.5, vmax=len(CATEGORY_COLOURS) - 0.5, interpolation='nearest',
                  aspect='equal')
        ax.set_title(f'r_z = {res.rz_deg[k]:g} deg', fontsize=9)
        ax.set_xlabel('r_y (deg)')
        ax.set_ylabel('r_x (deg)')
        free = (res.flags[k] == 0).astype(float)
        if 0 < free.sum() < free.size:
            summary.contour(res.ry_deg, res.rx_deg, free, levels=[0.5],
                            colors=[f'C{k}'], linewidths=1.2)
        summary.plot([], [], color=f'C{k}', label=f'r_z = {res.rz_deg[k]:g}')
    summary.set_title('boundaries', fontsize=9)
    summary.set_xlabel('r_y (deg)')
    summary.set_ylabel('r_x (deg)')
    summary.set_xlim(ext[0], ext[1])
    summary.set_ylim(ext[2], ext[3])
    summary.set_aspect('equal')
    summary.legend(fontsize=7)
    for ax in axes.ravel()[n:]:
        if ax is not summary:
            ax.axis('off')
    p = res.position
    fig.suptitle(f'{desc.name}: orientation workspace at ({p[0]:g}, {p[1]:g}, {p[2]:g}) m')
    _legend(fig)
    fig.tight_layout(rect=(0, 0.12, 1, 0.94))
    return fig


def _tow(args):
    from cable_robot_pkg.cdrpm.workspace import largest_box, total_orientation_workspace

    desc = _robot(args)
    _finite('--theta', args.theta, 0, 90)
    _finite('--angle-step', args.angle_step, 0.5, 90)
    _check_step(desc, args.step)
    out = _out_dir(args.out)
    tow = total_orientation_workspace(desc, args.theta, step=args.step,
                                      angle_step_deg=args.angle_step, progress=True)
    box = largest_box(tow.accessible, tow.axes)
    result = {
        'robot': desc.name, 'robot_file': desc.source, 'theta_max_deg': list(args.theta),
        'angle_step_deg': args.angle_step, 'orientations_sampled': int(len(tow.orientations_deg)),
        'grid': {'step_m': args.step, 'shape': list(tow.accessible.shape)},
        'total_points': int(tow.accessible.size),
        'accessible_points': int(np.count_nonzero(tow.accessible)),
        'accessible_percentage': tow.accessible_percentage,
        'removed_by_first_cause': tow.removed_by, 'largest_box': box,
        'paper_box_m': [1.2, 1.2, 1.4], 'wall_time_s': tow.wall_time_s,
    }
    fig = _tow_figure(desc, tow, box)
    _write_outputs(out, result, fig, 'tow.png')
    size = 'none' if box is None else ' x '.join(f'{s:.2f}' for s in box['size_m'])
    print(f'{desc.name}: TOW for +-{args.theta} deg ({len(tow.orientations_deg)} orientations): '
          f'{tow.accessible_percentage:.1f} % of the grid; largest box {size} m '
          f'(paper 1.2 x 1.2 x 1.4 m); {tow.wall_time_s:.1f} s -> {out}/result.json, '
          f'{out}/tow.png')
    return 0


def _tow_figure(desc, tow, box):
    """TOW projections on the three coordinate planes through O, with the largest box."""
    from matplotlib.patches import Rectangle
    xs, ys, zs = tow.axes
    acc = tow.accessible
    mid = [int(np.argmin(np.abs(a))) for a in (xs, ys, zs)]
    views = [('y', 'x', acc[:, :, mid[2]], ys, xs, (1, 0), f'z = {zs[mid[2]]:+.3f} m'),
             ('x', 'z', acc[:, mid[1], :].T, xs, zs, (0, 2), f'y = {ys[mid[1]]:+.3f} m'),
             ('y', 'z', acc[mid[0], :, :].T, ys, zs, (1, 2), f'x = {xs[mid[0]]:+.3f} m')]
    fig, axes = _figure(1, 3, figsize=(14, 4.8))
    for ax, (hx, vy, img, ha, va, (i, j), title) in zip(axes, views):
        ax.imshow(img.astype(float), origin='lower', cmap='Greens', vmin=-0.3, vmax=1.2,
                  extent=[ha[0], ha[-1], va[0], va[-1]], aspect='equal',
                  interpolation='nearest')
        if box is not None:
            lo = np.array(box['lower_cell_centre_m'])
            size = np.array(box['size_m'])
            steps = [a[1] - a[0] for a in tow.axes]
            ax.add_patch(Rectangle((lo[i] - steps[i] / 2, lo[j] - steps[j] / 2), size[i],
                                   size[j], fill=False, color='k', lw=1.5))
        ax.set_xlabel(f'{hx} (m)')
        ax.set_ylabel(f'{vy} (m)')
        ax.set_title(f'section {title}', fontsize=9)
    t = tow.theta_max_deg
    fig.suptitle(f'{desc.name}: total orientation workspace for +-({t[0]:g}, {t[1]:g}, '
                 f'{t[2]:g}) deg, {tow.accessible_percentage:.1f} % (green); black: largest box')
    fig.tight_layout(rect=(0, 0.03, 1, 0.93))
    return fig


def _workpiece(args):
    from cable_robot_pkg.cdrpm.workspace import workpiece_study

    desc = _robot(args)
    size = args.size
    if size is None:
        size = desc.workpiece.tolist() if desc.workpiece is not None else [1.0, 1.0, 0.5]
    _finite('--size', size, 1e-6)
    _finite('--rot', args.rot, -180, 180)
    _check_step(desc, args.step)
    out = _out_dir(args.out)
    try:
        res = workpiece_study(desc, size, rotation_deg=args.rot, step=args.step)
    except UserError as exc:
        raise UserError(f'--size {size}: {exc}') from None
    result = {k: v for k, v in res.items() if not k.startswith('flags') and k not in ('x_m',
                                                                                      'z_m')}
    result.update({'robot': desc.name, 'robot_file': desc.source, 'step_m': args.step,
                   'paper_ratio_percent': 60.0, 'paper_min_gap_m': 0.5})
    fig = _workpiece_figure(desc, res)
    _write_outputs(out, result, fig, 'workpiece.png')
    gap = res['min_gap_above_workpiece_m']
    gap_text = 'none accessible' if gap is None else f'{gap:.3f} m'
    print(f'{desc.name}: workpiece {size} m on the floor; plane y = 0 accessible '
          f'{res["accessible_percentage_with"]:.1f} % vs '
          f'{res["accessible_percentage_without"]:.1f} % without '
          f'({res["ratio_percent"]:.1f} %, paper 60 %); closest platform bottom above '
          f'the workpiece top: {gap_text} (paper 0.5 m) -> {out}/result.json, '
          f'{out}/workpiece.png')
    return 0


def _workpiece_figure(desc, res):
    """Plane y = 0 without and with the workpiece, coloured by outcome (Fig. 8)."""
    from matplotlib.patches import Rectangle
    xs, zs = res['x_m'], res['z_m']
    fig, axes = _figure(1, 2, figsize=(11, 5.2))
    ext = [xs[0], xs[-1], zs[0], zs[-1]]
    wx, _, wz = res['workpiece_m']
    floor = -desc.frame_half_size[2]
    for ax, key, title in ((axes[0], 'flags_free', 'without workpiece'),
                           (axes[1], 'flags_workpiece', 'with workpiece')):
        ax.imshow(_category_image(res[key]).T, origin='lower', extent=ext, cmap=_cmap(),
                  vmin=-0.5, vmax=len(CATEGORY_COLOURS) - 0.5, interpolation='nearest',
                  aspect='equal')
        ax.add_patch(Rectangle((-wx / 2, floor), wx, wz, fill=False, hatch='//', color='k'))
        pct = 100.0 * np.mean(res[key] == 0)
        ax.set_title(f'{title}: {pct:.1f} % accessible', fontsize=9)
        ax.set_xlabel('x (m)')
        ax.set_ylabel('z (m)')
        ax.set_xlim(-desc.frame_half_size[0], desc.frame_half_size[0])
        ax.set_ylim(-desc.frame_half_size[2], desc.frame_half_size[2])
    fig.suptitle(f'{desc.name}: centroid positions on the plane y = 0, workpiece '
                 f'{res["workpiece_m"]} m (hatched), rotation {res["rotation_deg"]} deg')
    _legend(fig)
    fig.tight_layout(rect=(0, 0.07, 1, 0.95))
    return fig


def _wrench(args):
    from cable_robot_pkg.cdrpm.collisions import classify_poses
    from cable_robot_pkg.cdrpm.kinematics import rotation_matrix_deg
    from cable_robot_pkg.cdrpm.workspace import grid_axes, grid_points
    from cable_robot_pkg.cdrpm.wrench_closure import wrench_closure

    desc = _robot(args)
    _finite('--rot', args.rot, -180, 180)
    _check_step(desc, args.step)
    out = _out_dir(args.out)
    axes = grid_axes(desc, args.step)
    pts = grid_points(axes)
    rot = rotation_matrix_deg(*args.rot)
    flags = classify_poses(desc, pts, rot)
    closed, margin = wrench_closure(desc, pts, rot)
    free = flags == 0
    n_free = int(np.count_nonzero(free))
    result = {
        'robot': desc.name, 'robot_file': desc.source, 'rotation_deg': list(args.rot),
        'grid': {'step_m': args.step, 'shape': [int(a.size) for a in axes]},
        'total_points': int(pts.shape[0]), 'collision_free_points': n_free,
        'wrench_closed_points': int(np.count_nonzero(closed)),
        'wrench_closed_percentage': 100.0 * float(np.mean(closed)),
        'wrench_closed_and_collision_free_points': int(np.count_nonzero(closed & free)),
        'paper_claim_holds_percentage_of_collision_free':
            100.0 * float(np.count_nonzero(closed & free)) / max(n_free, 1),
        'margin_rad': {'min': float(margin.min()), 'median': float(np.median(margin)),
                       'max': float(margin.max())},
        'method': 'rank 6 and a strictly positive null vector of the 6 x n structure matrix',
    }
    fig = _wrench_figure(desc, axes, free.reshape([a.size for a in axes]),
                         closed.reshape([a.size for a in axes]), args.rot)
    _write_outputs(out, result, fig, 'wrench.png')
    print(f'{desc.name}: rotation {args.rot} deg: wrench-closed at '
          f'{result["wrench_closed_percentage"]:.1f} % of the grid; the paper\'s claim (force '
          f'feasible wherever collision-free) holds at '
          f'{result["paper_claim_holds_percentage_of_collision_free"]:.1f} % of the '
          f'collision-free points -> {out}/result.json, {out}/wrench.png')
    return 0


def _wrench_figure(desc, axes, free, closed, rot):
    """Horizontal slices: collision-free and wrench-closed, free only, not free."""
    from matplotlib.colors import ListedColormap
    from matplotlib.patches import Patch
    xs, ys, zs = axes
    cat = np.where(free & closed, 2, np.where(free, 1, 0))
    picks = np.unique(np.linspace(0, zs.size - 1, 6).round().astype(int))
    fig, panels = _figure(2, 3, figsize=(13, 6.4), squeeze=False)
    colours = ['#bdbdbd', '#fc9272', '#31a354']
    for ax, k in zip(panels.ravel(), picks):
        ax.imshow(cat[:, :, k], origin='lower', extent=[ys[0], ys[-1], xs[0], xs[-1]],
                  cmap=ListedColormap(colours), vmin=-0.5, vmax=2.5, interpolation='nearest',
                  aspect='equal')
        ax.set_title(f'z = {zs[k]:+.3f} m', fontsize=9)
        ax.set_xlabel('y (m)')
        ax.set_ylabel('x (m)')
    for ax in panels.ravel()[len(picks):]:
        ax.axis('off')
    labels = ['not accessible', 'collision-free, NOT wrench-closed',
              'collision-free and wrench-closed']
    fig.legend(handles=[Patch(color=c, label=t) for c, t in zip(colours, labels)],
               loc='lower center', ncol=3, fontsize=8)
    fig.suptitle(f'{desc.name}: wrench closure at rotation {list(rot)} deg')
    fig.tight_layout(rect=(0, 0.05, 1, 0.96))
    return fig


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


def _table2_arrangements(args, desc, out):
    from cable_robot_pkg.cdrpm.arrangements import search_table2_arrangements
    rows, stats = search_table2_arrangements(desc.frame_half_size, desc.platform_half_size,
                                             desc.cable_radius, pitch=args.pitch,
                                             min_home_gap=args.min_gap, progress=True)
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
          'closed: collision-free and wrench-closed share of the zero-rotation grid')
    if out is not None:
        _write_outputs(out, {'robot_dimensions_from': desc.source, 'criterion': 'table2',
                             'pitch_m': args.pitch, 'min_home_gap_m': args.min_gap,
                             'stats': stats, 'rows': rows})
    return 0


def _arrangements(args):
    if args.corners and args.table2:
        raise UserError('--corners and --table2: choose one search')
    if args.corners:
        return _corner_arrangements(args)
    from cable_robot_pkg.cdrpm.arrangements import search_edge_arrangements

    desc = _robot(args)
    _check_step(desc, args.step)
    _finite('--pitch', args.pitch, 0.01, float(np.max(desc.frame_half_size)))
    _finite('--min-gap', args.min_gap, 0.0, 1.0)
    if not 1 <= args.top <= 1000:
        raise UserError(f'--top {args.top}: allowed [1, 1000]')
    out = _out_dir(args.out) if args.out else None
    if args.table2:
        return _table2_arrangements(args, desc, out)
    rows, stats = search_edge_arrangements(desc.frame_half_size, desc.platform_half_size,
                                           desc.cable_radius, pitch=args.pitch,
                                           min_home_gap=args.min_gap, step=args.step,
                                           progress=True)
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
        _write_outputs(out, {'robot_dimensions_from': desc.source, 'pitch_m': args.pitch,
                             'min_home_gap_m': args.min_gap, 'step_m': args.step,
                             'stats': stats, 'rows': rows})
    return 0


def _corner_arrangements(args):
    from cable_robot_pkg.cdrpm.arrangements import CORNERS, pairing_of, score_pairings
    from cable_robot_pkg.cdrpm.description import load_description, shipped_descriptions

    desc = _robot(args)
    _check_step(desc, args.step)
    if not 1 <= args.top <= 1000:
        raise UserError(f'--top {args.top}: allowed [1, 1000]')
    out = _out_dir(args.out) if args.out else None
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
        _write_outputs(out, {'robot_dimensions_from': desc.source, 'step_m': args.step,
                             'rows': rows})
    return 0


def _bench(args):
    from cable_robot_pkg.cdrpm.workspace import (
        PAPER_POINTS,
        PAPER_SECONDS,
        constant_orientation_workspace,
    )

    desc = _robot(args)
    if not 1000 <= args.points <= MAX_GRID_POINTS:
        raise UserError(f'--points {args.points}: allowed [1000, {MAX_GRID_POINTS}]')
    if not 1 <= args.runs <= 100:
        raise UserError(f'--runs {args.runs}: allowed [1, 100]')
    _finite('--rot', args.rot, -180, 180)
    span = 2 * (desc.frame_half_size - desc.platform_half_size)
    step = float((np.prod(span) / args.points) ** (1.0 / 3.0))
    constant_orientation_workspace(desc, args.rot, step=step)     # warm-up
    times, cow = [], None
    from tqdm import tqdm
    for _ in tqdm(range(args.runs), desc='bench', unit='run', leave=False):
        cow = constant_orientation_workspace(desc, args.rot, step=step)
        times.append(cow.wall_time_s)
    median = statistics.median(times)
    n = cow.counts['total_points']
    rate = n / median
    t_paper_grid = PAPER_POINTS / rate
    result = {
        'robot': desc.name, 'rotation_deg': list(args.rot), 'grid_points': n,
        'grid_step_m': step, 'runs': args.runs, 'times_s': times, 'median_s': median,
        'poses_per_second': rate, 'checks_per_pose_eq9': desc.checks_per_pose(),
        'time_for_148000_points_s': t_paper_grid, 'paper_time_s': PAPER_SECONDS,
        'speedup_vs_paper': PAPER_SECONDS / t_paper_grid, 'counts': cow.counts,
        'cpu_count': os.cpu_count(),
    }
    print(f'COW benchmark, robot {desc.name}, rotation {args.rot} deg, all checks '
          f'({desc.checks_per_pose()} per pose, eq. 9): {n} points, median of {args.runs} runs '
          f'{median * 1e3:.1f} ms')
    print(f'  {rate:,.0f} poses/s -> 148,000 points in {t_paper_grid:.3f} s '
          f'(paper: {PAPER_SECONDS:.0f} s on a 4.3 GHz CPU, x{PAPER_SECONDS / t_paper_grid:,.0f});'
          f' target >= 300,000 poses/s: {"met" if rate >= 300000 else "NOT met"}')
    if args.out:
        _write_outputs(_out_dir(args.out), result)
    return 0
