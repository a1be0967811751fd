"""The coverage picture (like Fig. 13 of Acar, Choset and Lee): world, path, cells and graph."""
from __future__ import annotations

import textwrap
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike

if TYPE_CHECKING:
    from coverage_pkg.algorithm1 import PaperPlanner
    from coverage_pkg.planner import CoveragePlanner
    from coverage_pkg.world import World


def planner_label(planner: str, without: Sequence[str] = (),
                  modes: Sequence[str] = ()) -> str:
    """How a run's figure title and summary name its planner: an ablation or a mode of the
    paper planner is part of what the picture shows (``paper planner, without cusp, modes
    ours=on``), so a picture of an ablation is never taken for the default's."""
    label = f'{planner} planner'
    if without:
        label += f", without {','.join(without)}"
    if modes:
        label += f", modes {','.join(modes)}"
    return label


def render_coverage(path_png: str | Path, world: World, path: ArrayLike,
                    graph_dict: Mapping[str, object] | None = None,
                    layers: Mapping[str, object] | None = None,
                    uncovered: np.ndarray | None = None, title: str = '') -> None:
    """Draw the world, the robot path, the sensed vast/narrow cells, the GVD, critical, cusp
    and meet points and the hierarchical graph, and save to ``path_png``.

    ``layers`` is a dict with boolean grids ``vast``, ``narrow``, ``gvd`` and an ``extent``
    (xmin, xmax, ymin, ymax) in the world frame (the planner's last decomposition).
    """
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt
    from matplotlib.patches import Polygon as MplPolygon

    xmin, ymin, xmax, ymax = world.bounds
    w = xmax - xmin
    h = ymax - ymin
    fig, ax = plt.subplots(figsize=(min(16, 4 + w * 0.45), min(12, 1.5 + h * 0.45)))
    ax.add_patch(MplPolygon(world.boundary, closed=True, fill=False, lw=2, color='k'))
    for o in world.obstacles:
        ax.add_patch(MplPolygon(o, closed=True, color='0.25'))
    if layers:
        ext = layers['extent']
        img = np.zeros(layers['vast'].shape + (4,))
        img[layers['vast']] = (0.75, 0.75, 0.75, 0.6)
        img[layers['narrow']] = (0.85, 0.93, 1.0, 0.6)
        ax.imshow(img, origin='lower', extent=ext, interpolation='nearest', zorder=0)
        gy, gx = np.nonzero(layers['gvd'])
        if len(gy):
            res = (ext[1] - ext[0]) / layers['gvd'].shape[1]
            ax.plot(ext[0] + (gx + 0.5) * res, ext[2] + (gy + 0.5) * res, ',', color='tab:blue',
                    alpha=0.5, zorder=1)
        my, mx = np.nonzero(layers.get('morse', np.zeros((0, 0), bool)))
        if len(my):
            res = (ext[1] - ext[0]) / layers['vast'].shape[1]
            ax.plot(ext[0] + mx * res, ext[2] + (my + 0.5) * res, '|', color='indigo', ms=4,
                    label='Morse cell boundaries', zorder=2)
    if uncovered is not None and len(uncovered):
        ax.plot(uncovered[:, 0], uncovered[:, 1], 's', ms=1.5, color='red', alpha=0.6,
                label='CVS not seen', zorder=2)
    p = np.asarray(path)
    if len(p):
        ax.plot(p[:, 0], p[:, 1], '-', color='tab:green', lw=0.8, label='robot path', zorder=3)
        ax.plot(p[0, 0], p[0, 1], 'o', color='tab:green', ms=7, zorder=4)
    if graph_dict:
        nodes = {n['id']: n for n in graph_dict['nodes'] if n['alive']}
        crit = [c for n in nodes.values() for c in n.get('critical_points', [])]
        if crit:
            c = np.array([[q[0], q[1]] for q in crit], dtype=float)
            ax.plot(c[:, 0], c[:, 1], 'k.', ms=5, label='critical points', zorder=5)
        meet = [m for n in nodes.values() for m in n.get('meet_points', [])]
        if meet:
            m = np.array(meet, dtype=float)
            ax.plot(m[:, 0], m[:, 1], 'o', color='0.5', ms=5, label='meet points', zorder=5)
        first = True
        for e in graph_dict['edges']:
            a, b = nodes.get(e['vast']), nodes.get(e['narrow'])
            for cp in e['cusp_points']:
                ax.plot(cp[0], cp[1], 'o', mfc='white', mec='k', ms=6, zorder=6,
                        label='cusp points' if first else None)
                first = False
                if a and b:
                    pa, pb = _where(a), _where(b)
                    ax.plot([pa[0], cp[0], pb[0]], [pa[1], cp[1], pb[1]], ':', color='purple',
                            lw=1, zorder=6)
        # Each node is drawn at a point of its cell nearest its centroid: the centroid of a
        # ring-shaped cell (a band around an obstacle, the vast ring around it) lies outside
        # the cell, and several such centroids fall on one point.
        for n in nodes.values():
            style = dict(boxstyle='round', fc='0.7' if n['type'] == 'vast' else 'white',
                         ec='purple')
            ax.text(*_where(n), f"{n['type'][0].upper()}{n['id']}",
                    ha='center', va='center', fontsize=8, bbox=style, zorder=7)
    ax.set_xlim(xmin - 0.5, xmax + 0.5)
    ax.set_ylim(ymin - 0.5, ymax + 0.5)
    ax.set_aspect('equal')
    # a 9 pt character is about 0.075 in wide: wrap the title to the figure's width
    ax.set_title(textwrap.fill(title, max(30, int(fig.get_figwidth() / 0.075))), fontsize=9)
    ax.legend(loc='upper right', fontsize=7, framealpha=0.8)
    fig.tight_layout()
    fig.savefig(path_png, dpi=110)
    plt.close(fig)


def _where(node):
    """Where a node of the graph dict is drawn (older results have no ``label_point``)."""
    return tuple(node.get('label_point', node['centroid'])[:2])


def planner_layers(planner: CoveragePlanner | PaperPlanner
                   ) -> dict[str, np.ndarray | tuple[float, float, float, float]] | None:
    """The planner's last decomposition as picture layers (see :func:`render_coverage`)."""
    d = planner.last
    if not d:
        return None
    g = planner.grid
    rs, cs = d['rs'], d['cs']
    x0 = g.origin[0] + cs.start * g.res
    y0 = g.origin[1] + rs.start * g.res
    ny, nx = d['vast'].shape
    from coverage_pkg.morse import cell_boundaries
    reeb = d.get('reeb')
    morse = cell_boundaries(reeb) if reeb is not None else np.zeros_like(d['vast'])
    return {'vast': d['vast'], 'narrow': d['narrow'], 'gvd': d['gvd'] & d['reach'],
            'morse': morse, 'extent': (x0, x0 + nx * g.res, y0, y0 + ny * g.res)}
