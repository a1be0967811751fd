"""Figures 2 and 3 of Vaca, Aranda & Thomas regenerated from the planar model (matplotlib,
headless Agg backend).

* Fig. 2: at phi = pi/4, the measure of distance of P1 (singularities, a) and its Voronoi
  diagram (b), of P2 (collisions, c-d) and of P1 AND P2 (e-f).
* Fig. 3: the configuration space over (x, y, phi) = ([-30, 60], [-45, 45], [-pi/2, pi/2]):
  rho of P1 AND P2 at phi = -pi/2, 0 and pi/2, diagram slices at the orientations where the
  slice's topology changes, and a singularity- and collision-free path.
"""
from __future__ import annotations

import math
from pathlib import Path
from typing import TYPE_CHECKING

import matplotlib

matplotlib.use('Agg')
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.collections import LineCollection  # noqa: E402
from mpl_toolkits.mplot3d.art3d import Line3DCollection  # noqa: E402
from numpy.typing import ArrayLike  # noqa: E402
from scipy import ndimage  # noqa: E402

from voronoi_pkg.diagram import diagram_mask, tie_segments  # noqa: E402

if TYPE_CHECKING:
    from voronoi_pkg.planar import PlanarModel
    from voronoi_pkg.spatial321 import Spatial321Model

__all__ = ['figure2', 'figure3', 'slice_summary', 'topology_signature']

_TITLES = {
    'singularity': 'singularities ($\\mathcal{P}_1$)',
    'collision': 'collisions ($\\mathcal{P}_2$)',
    'total': 'both ($\\mathcal{P}_1 \\wedge \\mathcal{P}_2$)',
}


def _grid(model, h):
    d = model.domain
    xs = np.arange(d.x[0], d.x[1] + h / 2, h)
    ys = np.arange(d.y[0], d.y[1] + h / 2, h)
    return xs, ys


def _scene_lines(model):
    pts = model.fixed
    return [(pts[a], pts[b]) for name, (a, b) in model.segments.items()
            if a in pts and b in pts]


def _draw_singularities(ax, model, X, Y, q):
    """Zero sets of the pure-condition determinants (singularities) as red dashed lines."""
    for signs in model.singular_signs(q):
        if np.any(signs > 0) and np.any(signs < 0):
            ax.contour(X, Y, signs, levels=[0.0], colors='red', linewidths=1.2,
                       linestyles='dashed')


def figure2(model: PlanarModel, path: str | Path, phi: float = math.pi / 4,
            h: float = 0.25) -> None:
    """Write Fig. 2 (a)-(f) to ``path``: rho and its simplified Voronoi diagram at ``phi``."""
    xs, ys = _grid(model, h)
    X, Y = np.meshgrid(xs, ys)
    q = np.stack([X, Y, np.full_like(X, phi)], axis=-1)
    extent = (xs[0], xs[-1], ys[0], ys[-1])
    fig, axes = plt.subplots(3, 2, figsize=(11, 14), constrained_layout=True)
    letters = iter('abcdef')
    for row, program in enumerate(('singularity', 'collision', 'total')):
        if program not in model.programs:       # switched off (ablation)
            for a in axes[row]:
                a.set_axis_off()
                a.set_title(f'({next(letters)}) {_TITLES[program]}: switched off')
            continue
        rho = model.rho(q, program)
        ax = axes[row, 0]
        lim = float(np.max(np.abs(rho)))
        im = ax.imshow(rho, origin='lower', extent=extent, cmap='RdYlGn', vmin=-lim, vmax=lim)
        ax.contour(X, Y, rho, levels=[0.0], colors='k', linewidths=0.8)
        fig.colorbar(im, ax=ax, shrink=0.8, label='rho')
        ax.set_title(f'({next(letters)}) measure of distance, {_TITLES[program]}')
        ax = axes[row, 1]
        ax.imshow(np.where(rho > 0, 1.0, 0.55), origin='lower', extent=extent, cmap='gray',
                  vmin=0, vmax=1)
        segs = tie_segments(model, phi, xs, ys, program)
        ax.add_collection(LineCollection(segs, colors='tab:blue', linewidths=0.9))
        ax.set_title(f'({next(letters)}) simplified Voronoi diagram, {_TITLES[program]}')
        for a in axes[row]:
            if program != 'collision':
                _draw_singularities(a, model, X, Y, q)
            a.add_collection(LineCollection(_scene_lines(model), colors='k', linewidths=2.0))
            a.set_xlim(extent[0], extent[1])
            a.set_ylim(extent[2], extent[3])
            a.set_xlabel('x')
            a.set_ylabel('y')
            a.set_aspect('equal')
    fig.suptitle(f'Slices of configuration space at phi = {math.degrees(phi):g} deg '
                 '(grey: forbidden, rho <= 0; red dashed: singularities; black: base and '
                 'boundary)')
    fig.savefig(path, dpi=90)
    plt.close(fig)


def slice_summary(model: PlanarModel, phi: float, xs: np.ndarray, ys: np.ndarray
                  ) -> tuple[tuple[int, int], np.ndarray]:
    """Coarse invariant and vertices of one diagram slice.

    Returns ``((#connected pieces, #vertices), vertices (m, 2))``: vertices are clusters of
    free grid cells that see three or more smallest contacts (where diagram edges meet). Fig. 3
    shows a slice where the invariant changes and links vertices of consecutive slices: the
    traces are the edges of the diagram across orientation.
    """
    X, Y = np.meshgrid(xs, ys)
    q = np.stack([X, Y, np.full_like(X, phi)], axis=-1)
    rho, contact, code, cell = model.fields(q)
    mask = diagram_mask(rho, contact, code, cell, model.free_tol)
    _, pieces = ndimage.label(mask, structure=np.ones((3, 3)))
    blocks = np.stack([contact[:-1, :-1], contact[1:, :-1], contact[:-1, 1:],
                       contact[1:, 1:]])
    srt = np.sort(blocks, axis=0)
    distinct = 1 + np.sum(srt[1:] != srt[:-1], axis=0)
    free = np.all(np.stack([rho[:-1, :-1], rho[1:, :-1], rho[:-1, 1:], rho[1:, 1:]])
                  > model.free_tol, axis=0)
    junction = (distinct >= 3) & free
    lab, n = ndimage.label(junction, structure=np.ones((3, 3)))
    if n:
        centres = np.array(ndimage.center_of_mass(junction, lab, range(1, n + 1)))
        verts = np.stack([np.interp(centres[:, 1] + 0.5, np.arange(len(xs)), xs),
                          np.interp(centres[:, 0] + 0.5, np.arange(len(ys)), ys)], axis=1)
    else:
        verts = np.zeros((0, 2))
    return (pieces, n), verts


def topology_signature(model: PlanarModel, phi: float, xs: np.ndarray,
                       ys: np.ndarray) -> tuple[int, int]:
    """(#connected pieces, #vertices) of a diagram slice (see :func:`slice_summary`)."""
    return slice_summary(model, phi, xs, ys)[0]


def _vertex_traces(sweep, vertices, max_jump):
    """Segments joining each vertex to the nearest vertex of the next slice (if close)."""
    segs = []
    for (p0, v0), (p1, v1) in zip(zip(sweep, vertices), zip(sweep[1:], vertices[1:])):
        if not len(v0) or not len(v1):
            continue
        d = np.linalg.norm(v0[:, None, :] - v1[None, :, :], axis=-1)
        k = np.argmin(d, axis=1)
        for i in np.flatnonzero(d[np.arange(len(v0)), k] <= max_jump):
            segs.append([(*v0[i], p0), (*v1[k[i]], p1)])
    return np.asarray(segs, dtype=float).reshape(-1, 2, 3)


def figure3(model: PlanarModel, path_file: str | Path, path: np.ndarray | None = None,
            phi_range: tuple[float, float] = (-math.pi / 2, math.pi / 2), h: float = 1.0,
            n_sweep: int = 73, max_slices: int = 8) -> list[float]:
    """Write Fig. 3 to ``path_file``: rho surfaces, diagram slices and the planned ``path``."""
    xs, ys = _grid(model, h)
    lo, hi = phi_range
    if path is not None and len(path):
        lo = min(lo, float(np.min(path[:, 2])))
        hi = max(hi, float(np.max(path[:, 2])))
    fig = plt.figure(figsize=(10, 10))
    # Draw in the order given (mplot3d's depth sort would bury the path under the surfaces).
    ax = fig.add_subplot(projection='3d', computed_zorder=False)
    X, Y = np.meshgrid(xs, ys)
    cmap = plt.get_cmap('RdYlGn')
    surfaces = [phi_range[0], 0.5 * (phi_range[0] + phi_range[1]), phi_range[1]]
    rhos = [model.rho(np.stack([X, Y, np.full_like(X, p)], axis=-1)) for p in surfaces]
    lim = max(float(np.max(np.abs(r))) for r in rhos)
    for p, rho in zip(surfaces, rhos):
        colors = cmap(0.5 + 0.5 * rho / lim)
        colors[..., 3] = 0.45
        ax.plot_surface(X, Y, np.full_like(X, p), facecolors=colors, rstride=1, cstride=1,
                        linewidth=0, antialiased=False, shade=False, zorder=1)
    # Diagram slices where the topology changes along the sweep.
    sweep = np.linspace(phi_range[0], phi_range[1], n_sweep)
    summaries = [slice_summary(model, p, xs, ys) for p in sweep]
    sigs = [sig for sig, _ in summaries]
    traces = _vertex_traces(sweep, [v for _, v in summaries], max_jump=4 * h)
    if len(traces):
        ax.add_collection3d(Line3DCollection(traces, colors='navy', linewidths=0.9,
                                             zorder=3))
    chosen = [i for i in range(1, len(sweep)) if sigs[i] != sigs[i - 1]]
    if len(chosen) > max_slices:
        chosen = [chosen[int(round(k))] for k in np.linspace(0, len(chosen) - 1, max_slices)]
    chosen = sorted(set(chosen) | {0, len(sweep) - 1})
    for i in chosen:
        p = sweep[i]
        segs = tie_segments(model, p, xs, ys)
        if len(segs):
            seg3 = np.concatenate([segs, np.full(segs.shape[:2] + (1,), p)], axis=-1)
            ax.add_collection3d(Line3DCollection(seg3, colors='tab:blue', linewidths=0.6,
                                                 zorder=2))
    if path is not None and len(path):
        ax.plot(path[:, 0], path[:, 1], path[:, 2], color='red', linewidth=2.5,
                label='planned path', zorder=10)
        ax.scatter(*path[0], color='black', s=50, label='start', zorder=11)
        ax.scatter(*path[-1], color='magenta', s=50, label='goal', zorder=11)
        ax.legend(loc='upper left')
    ax.set_xlim(xs[0], xs[-1])
    ax.set_ylim(ys[0], ys[-1])
    ax.set_zlim(lo, hi)
    ax.set_xlabel('x')
    ax.set_ylabel('y')
    ax.set_zlabel('phi (rad)')
    ax.set_title('rho of P1 AND P2 at phi = '
                 + ', '.join(f'{math.degrees(p):g}' for p in surfaces) + ' deg (green free, '
                 'red forbidden); diagram slices (blue) where its topology changes:\nphi = '
                 + ', '.join(f'{math.degrees(sweep[i]):.0f}' for i in chosen)
                 + ' deg; navy: diagram vertices traced across phi (diagram edges); red: '
                 'singularity- and collision-free path', fontsize=9)
    ax.view_init(elev=18, azim=-60)
    fig.savefig(path_file, dpi=90)
    plt.close(fig)
    return [float(sweep[i]) for i in chosen]


def figure321(model: Spatial321Model, path_file: str | Path, path: np.ndarray | None,
              start: ArrayLike, goal: ArrayLike) -> None:
    """3-D view of the platform at start, along the path and at the goal, and the boxes."""
    from mpl_toolkits.mplot3d.art3d import Poly3DCollection

    from voronoi_pkg.spatial321 import LEGS
    fig = plt.figure(figsize=(9, 8))
    ax = fig.add_subplot(projection='3d')
    for verts, quads, _ in model.meshes:
        ax.add_collection3d(Poly3DCollection(verts[quads], facecolor='tab:gray', alpha=0.35,
                                             edgecolor='k', linewidth=0.3))

    def draw(q, color, alpha, lw):
        p = model.world_points(q)
        for a, b in LEGS:
            ax.plot(*np.stack([p[a], p[b]]).T, color=color, alpha=alpha, linewidth=lw)
        tri = np.stack([p[7], p[8], p[9], p[7]])
        ax.plot(*tri.T, color=color, alpha=alpha, linewidth=lw + 1)

    poses = [start, goal]
    if path is not None and len(path):
        idx = np.linspace(0, len(path) - 1, 8).astype(int)[1:-1]
        for q in path[idx]:
            draw(q, 'tab:orange', 0.35, 0.8)
        ax.plot(*path[:, :3].T, color='red', linewidth=2, label='P7 path')
    draw(poses[0], 'black', 1.0, 1.5)
    draw(poses[1], 'tab:blue', 1.0, 1.5)
    base = np.array([model.fixed[k] for k in range(1, 7)])
    ax.scatter(*base.T, color='k', s=15)
    ax.set_xlabel('x (m)')
    ax.set_ylabel('y (m)')
    ax.set_zlabel('z (m)')
    ax.set_title('3-2-1 platform: start (black), goal (blue), intermediate poses (orange)')
    ax.set_box_aspect((1, 1, 0.9))
    if path is not None and len(path):
        ax.legend()
    fig.savefig(path_file, dpi=90)
    plt.close(fig)
