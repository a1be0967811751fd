"""``paramotion workspace cow``: constant-orientation workspace at one orientation (section
IV-A, Fig. 6 slices).

Argument parsing lives in :mod:`cable_robot_pkg.cdrpm.cli`; this module turns parsed
arguments into a call of the analysis in :mod:`cable_robot_pkg.cdrpm` and writes its outputs.
"""

import numpy as np

from cable_robot_pkg.cdrpm.cli import common


def run(args):
    from cable_robot_pkg.cdrpm.workspace import constant_orientation_workspace

    desc = common.robot(args)
    common.finite('--rot', args.rot, -180, 180)
    common.check_step(desc, args.step)
    without = common.without(args)
    out = common.out_dir(args.out)
    cow = constant_orientation_workspace(desc, args.rot, step=args.step, progress=True,
                                         without=without)
    result = cow.to_dict(desc)
    result['without'] = sorted(without)
    result['robot_file'] = desc.source
    fig = cow_figure(desc, cow)
    common.write_outputs(out, result, fig, 'cow.png')
    print(f'{common.robot_label(desc)}: rotation {args.rot} deg, {result["total_points"]} points, '
          f'accessible {result["accessible_percentage"]:.1f} % '
          f'(collision-free {result["collision_free_percentage_in_frame"]:.1f} % of in-frame), '
          f'{result["wall_time_s"]:.3f} s -> {out}/result.json, {out}/cow.png')
    return 0


def cow_figure(desc, cow):
    """Six horizontal slices of the COW coloured by outcome (like the paper's Fig. 6)."""
    xs, ys, zs = cow.axes
    cat = common.category_image(cow.flags)
    first, last = (1, zs.size - 2) if zs.size > 8 else (0, zs.size - 1)
    picks = np.unique(np.linspace(first, last, 6).round().astype(int))
    fig, axes = common.subplots(2, 3, figsize=(13, 6.4), squeeze=False)
    ext = [ys[0], ys[-1], xs[0], xs[-1]]
    for ax, k in zip(axes.ravel(), picks):
        ax.imshow(cat[:, :, k], origin='lower', extent=ext, cmap=common.cmap(), vmin=-0.5,
                  vmax=len(common.CATEGORY_COLOURS) - 0.5, interpolation='nearest', aspect='equal')
        acc = 100.0 * np.count_nonzero(cow.flags[:, :, k] == 0) / cow.flags[:, :, k].size
        ax.set_title(f'z = {zs[k]:+.3f} m: {acc:.1f} % accessible', fontsize=9)
        ax.set_xlabel('y (m)')
        ax.set_ylabel('x (m)')
    for ax in axes.ravel()[len(picks):]:
        ax.axis('off')
    rx, ry, rz = cow.rotation_deg
    fig.suptitle(f'{desc.name}: constant-orientation workspace at ({rx:g}, {ry:g}, {rz:g}) deg, '
                 f'{cow.accessible_percentage:.1f} % accessible (eq. 10)')
    common.legend(fig)
    fig.tight_layout(rect=(0, 0.05, 1, 0.96))
    return fig
