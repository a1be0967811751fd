"""``paramotion workspace tow``: total orientation workspace over a +-theta box and the largest
box in it (IV-C).

Argument parsing lives in :mod:`cable_robot_pkg.cdrpm.cli`; this module turns parsed
arguments into a call of the analysis in :mod:`cable_robot_pkg.cdrpm` and writes its outputs.
"""

import numpy as np

from cable_robot_pkg.cdrpm.cli import common


def run(args):
    from cable_robot_pkg.cdrpm.workspace import largest_box, total_orientation_workspace

    desc = common.robot(args)
    common.finite('--theta', args.theta, 0, 90)
    common.finite('--angle-step', args.angle_step, 0.5, 90)
    common.check_step(desc, args.step)
    without = common.without(args)
    out = common.out_dir(args.out)
    tow = total_orientation_workspace(desc, args.theta, step=args.step,
                                      angle_step_deg=args.angle_step, progress=True,
                                      without=without)
    box = largest_box(tow.accessible, tow.axes)
    result = {
        'robot': desc.name, 'robot_file': desc.source, 'theta_max_deg': list(args.theta),
        'without': sorted(without),
        'angle_step_deg': args.angle_step, 'orientations_sampled': int(len(tow.orientations_deg)),
        'grid': {'step_m': args.step, 'shape': list(tow.accessible.shape)},
        'total_points': int(tow.accessible.size),
        'accessible_points': int(np.count_nonzero(tow.accessible)),
        'accessible_percentage': tow.accessible_percentage,
        'removed_by_first_cause': tow.removed_by, 'largest_box': box,
        'paper_box_m': [1.2, 1.2, 1.4], 'wall_time_s': tow.wall_time_s,
    }
    fig = tow_figure(desc, tow, box)
    common.write_outputs(out, result, fig, 'tow.png')
    size = 'none' if box is None else ' x '.join(f'{s:.2f}' for s in box['size_m'])
    print(f'{common.robot_label(desc)}: TOW for +-{args.theta} deg '
          f'({len(tow.orientations_deg)} orientations): '
          f'{tow.accessible_percentage:.1f} % of the grid; largest box {size} m '
          f'(paper 1.2 x 1.2 x 1.4 m); {tow.wall_time_s:.1f} s -> {out}/result.json, '
          f'{out}/tow.png')
    return 0


def tow_figure(desc, tow, box):
    """TOW projections on the three coordinate planes through O, with the largest box."""
    from matplotlib.patches import Rectangle
    xs, ys, zs = tow.axes
    acc = tow.accessible
    mid = [int(np.argmin(np.abs(a))) for a in (xs, ys, zs)]
    views = [('y', 'x', acc[:, :, mid[2]], ys, xs, (1, 0), f'z = {zs[mid[2]]:+.3f} m'),
             ('x', 'z', acc[:, mid[1], :].T, xs, zs, (0, 2), f'y = {ys[mid[1]]:+.3f} m'),
             ('y', 'z', acc[mid[0], :, :].T, ys, zs, (1, 2), f'x = {xs[mid[0]]:+.3f} m')]
    fig, axes = common.subplots(1, 3, figsize=(14, 4.8))
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
