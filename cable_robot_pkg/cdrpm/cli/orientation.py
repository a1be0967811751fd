"""``paramotion workspace orientation``: orientation workspace at one position (section IV-B,
Fig. 7).

Argument parsing lives in :mod:`cable_robot_pkg.cdrpm.cli`; this module turns parsed
arguments into a call of the analysis in :mod:`cable_robot_pkg.cdrpm` and writes its outputs.
"""

import numpy as np

from cable_robot_pkg.cdrpm.cli import common
from paramotion.errors import UserError


def run(args):
    from cable_robot_pkg.cdrpm.workspace import orientation_workspace

    desc = common.robot(args)
    common.finite('--position', args.position)
    if np.any(np.abs(args.position) > desc.frame_half_size):
        raise UserError(f'--position {args.position}: outside the frame '
                        f'(half sizes {desc.frame_half_size.tolist()})')
    common.finite('--rz', args.rz, -180, 180)
    common.finite('--max-angle', args.max_angle, 1, 180)
    common.finite('--angle-step', args.angle_step, 0.05, 45)
    without = common.without(args)
    out = common.out_dir(args.out)
    res = orientation_workspace(desc, args.position, rz_deg=args.rz,
                                rx_range=(-args.max_angle, args.max_angle),
                                ry_range=(-args.max_angle, args.max_angle),
                                step_deg=args.angle_step, without=without)
    boundary = res.boundary()
    from cable_robot_pkg.cdrpm.collisions import count_flags
    result = {
        'robot': desc.name, 'robot_file': desc.source, 'position_m': list(args.position),
        'without': sorted(without),
        'angle_step_deg': args.angle_step, 'max_angle_deg': args.max_angle,
        'per_rz': [{'rz_deg': b['rz'], **count_flags(res.flags[k]),
                    'accessible_percentage': 100.0 * float(np.mean(res.flags[k] == 0)),
                    'boundary': b['rows']} for k, b in enumerate(boundary)],
    }
    fig = orientation_figure(desc, res)
    common.write_outputs(out, result, fig, 'orientation.png')
    print(f'{common.robot_label(desc)}: orientation workspace at {list(args.position)} m')
    for entry in result['per_rz']:
        print(f'r_z = {entry["rz_deg"]:g} deg: {entry["accessible_percentage"]:.1f} % of the '
              f'(r_x, r_y) square accessible')
    print(f'-> {out}/result.json, {out}/orientation.png')
    return 0


def orientation_figure(desc, res):
    """Accessible (r_x, r_y) regions, one panel per r_z, boundaries overlaid (Fig. 7)."""
    n = res.rz_deg.size
    cols = min(n, 4)
    rows = -(-n // cols)
    fig, axes = common.subplots(rows, cols + 1, figsize=(3.6 * (cols + 1), 3.8 * rows),
                                squeeze=False)
    ext = [res.ry_deg[0], res.ry_deg[-1], res.rx_deg[0], res.rx_deg[-1]]
    summary = axes[0, -1]
    for k in range(n):
        ax = axes[k // cols, k % cols]
        ax.imshow(common.category_image(res.flags[k]), origin='lower', extent=ext,
                  cmap=common.cmap(),
                  vmin=-0.5, vmax=len(common.CATEGORY_COLOURS) - 0.5, interpolation='nearest',
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
    common.legend(fig)
    fig.tight_layout(rect=(0, 0.12, 1, 0.94))
    return fig
