"""``paramotion workspace wrench``: where positive cable tensions balance any wrench (beyond
the paper).

Argument parsing lives in :mod:`cable_robot_pkg.cdrpm.cli`; this module turns parsed
arguments into a call of the analysis in :mod:`cable_robot_pkg.cdrpm` and writes its outputs.
"""

import numpy as np

from cable_robot_pkg.cdrpm.cli import common


def run(args):
    from cable_robot_pkg.cdrpm.collisions import classify_poses
    from cable_robot_pkg.cdrpm.kinematics import rotation_matrix_deg
    from cable_robot_pkg.cdrpm.workspace import grid_axes, grid_points
    from cable_robot_pkg.cdrpm.wrench_closure import wrench_closure

    desc = common.robot(args)
    common.finite('--rot', args.rot, -180, 180)
    common.check_step(desc, args.step)
    out = common.out_dir(args.out)
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
    fig = wrench_figure(desc, axes, free.reshape([a.size for a in axes]),
                         closed.reshape([a.size for a in axes]), args.rot)
    common.write_outputs(out, result, fig, 'wrench.png')
    print(f'{common.robot_label(desc)}: rotation {args.rot} deg: wrench-closed at '
          f'{result["wrench_closed_percentage"]:.1f} % of the grid; the paper\'s claim (force '
          f'feasible wherever collision-free) holds at '
          f'{result["paper_claim_holds_percentage_of_collision_free"]:.1f} % of the '
          f'collision-free points -> {out}/result.json, {out}/wrench.png')
    return 0


def wrench_figure(desc, axes, free, closed, rot):
    """Horizontal slices: collision-free and wrench-closed, free only, not free."""
    from matplotlib.colors import ListedColormap
    from matplotlib.patches import Patch
    xs, ys, zs = axes
    cat = np.where(free & closed, 2, np.where(free, 1, 0))
    picks = np.unique(np.linspace(0, zs.size - 1, 6).round().astype(int))
    fig, panels = common.subplots(2, 3, figsize=(13, 6.4), squeeze=False)
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
