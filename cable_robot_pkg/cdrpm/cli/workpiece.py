"""``paramotion workspace workpiece``: the workpiece study of section IV-D on the plane y = 0.

Argument parsing lives in :mod:`cable_robot_pkg.cdrpm.cli`; this module turns parsed
arguments into a call of the analysis in :mod:`cable_robot_pkg.cdrpm` and writes its outputs.
"""

import numpy as np

from cable_robot_pkg.cdrpm.cli import common
from paramotion.errors import UserError


def run(args):
    from cable_robot_pkg.cdrpm.workspace import workpiece_study

    desc = common.robot(args)
    size = args.size
    if size is None:
        size = desc.workpiece.tolist() if desc.workpiece is not None else [1.0, 1.0, 0.5]
    common.finite('--size', size, 1e-6)
    common.finite('--rot', args.rot, -180, 180)
    common.check_step(desc, args.step)
    without = common.without(args)
    out = common.out_dir(args.out)
    try:
        res = workpiece_study(desc, size, rotation_deg=args.rot, step=args.step,
                              without=without)
    except UserError as exc:
        raise UserError(f'--size {size}: {exc}') from None
    result = {k: v for k, v in res.items() if not k.startswith('flags') and k not in ('x_m',
                                                                                      'z_m')}
    result.update({'robot': desc.name, 'robot_file': desc.source, 'step_m': args.step,
                   'without': sorted(without),
                   'paper_ratio_percent': 60.0, 'paper_min_gap_m': 0.5})
    fig = workpiece_figure(desc, res)
    common.write_outputs(out, result, fig, 'workpiece.png')
    gap = res['min_gap_above_workpiece_m']
    gap_text = 'none accessible' if gap is None else f'{gap:.3f} m'
    print(f'{common.robot_label(desc)}: workpiece {size} m on the floor; plane y = 0 accessible '
          f'{res["accessible_percentage_with"]:.1f} % vs '
          f'{res["accessible_percentage_without"]:.1f} % without '
          f'({res["ratio_percent"]:.1f} %, paper 60 %); closest platform bottom above '
          f'the workpiece top: {gap_text} (paper 0.5 m) -> {out}/result.json, '
          f'{out}/workpiece.png')
    return 0


def workpiece_figure(desc, res):
    """Plane y = 0 without and with the workpiece, coloured by outcome (Fig. 8)."""
    from matplotlib.patches import Rectangle
    xs, zs = res['x_m'], res['z_m']
    fig, axes = common.subplots(1, 2, figsize=(11, 5.2))
    ext = [xs[0], xs[-1], zs[0], zs[-1]]
    wx, _, wz = res['workpiece_m']
    floor = -desc.frame_half_size[2]
    for ax, key, title in ((axes[0], 'flags_free', 'without workpiece'),
                           (axes[1], 'flags_workpiece', 'with workpiece')):
        ax.imshow(common.category_image(res[key]).T, origin='lower', extent=ext,
                  cmap=common.cmap(),
                  vmin=-0.5, vmax=len(common.CATEGORY_COLOURS) - 0.5, interpolation='nearest',
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
    common.legend(fig)
    fig.tight_layout(rect=(0, 0.07, 1, 0.95))
    return fig
