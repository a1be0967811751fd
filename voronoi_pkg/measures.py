"""Measurements of a planar path against the simplified Voronoi diagram, from rho's contacts
alone (ours: for the tests and the report, independent of the planner's own labels).

* :func:`tie_distance`: distance in (x, y) of each configuration from the diagram
  (:mod:`voronoi_pkg.ties`): the gap between the two smallest contacts over the norm of its
  gradient (central differences). Contacts are affine in (x, y) within a slice, so this is
  exact where one pair of determinants decides the gap.
* :func:`on_diagram_share`: length share of a path within ``delta`` of the diagram, counted
  between the first and the last sample within ``delta`` (the retraction climbs onto the
  diagram are excluded, found from rho).
* :func:`path_length`: length with phi weighted by ``phi_scale``.

No ROS imports.
"""
from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike

from voronoi_pkg.ties import tie_gap

if TYPE_CHECKING:
    from voronoi_pkg.planar import PlanarModel

__all__ = ['on_diagram_share', 'path_length', 'tie_distance']


def tie_distance(model: PlanarModel, path: ArrayLike, eps: float = 1e-3) -> np.ndarray:
    """Distance in (x, y) of each configuration of ``path`` (M, 3) from the diagram."""
    path = np.asarray(path, dtype=float)
    gap = tie_gap(*model.contact_values(path))
    grad = [(tie_gap(*model.contact_values(path + d)) - tie_gap(*model.contact_values(path - d)))
            / (2 * eps) for d in (np.array([eps, 0, 0]), np.array([0, eps, 0]))]
    return gap / np.maximum(np.hypot(*grad), 1e-300)


def path_length(path: ArrayLike, phi_scale: float = 10.0) -> float:
    """Length of a polyline in (x, y, phi), phi weighted by ``phi_scale``."""
    d = np.diff(np.asarray(path, dtype=float), axis=0)
    return float(np.sum(np.sqrt(d[:, 0] ** 2 + d[:, 1] ** 2 + (phi_scale * d[:, 2]) ** 2)))


def on_diagram_share(model: PlanarModel, path: ArrayLike, delta: float,
                     phi_scale: float = 10.0) -> tuple[float, float]:
    """``(share, excluded length)``: the share of the path's length (between its first and
    last sample within ``delta`` of the diagram) whose steps have both ends within ``delta``,
    and the length outside that stretch (the two retraction climbs)."""
    path = np.asarray(path, dtype=float)
    near = tie_distance(model, path) <= delta
    d = np.diff(path, axis=0)
    length = np.sqrt(d[:, 0] ** 2 + d[:, 1] ** 2 + (phi_scale * d[:, 2]) ** 2)
    idx = np.flatnonzero(near)
    if len(idx) < 2:
        return 0.0, float(length.sum())
    inner = slice(idx[0], idx[-1])
    on = near[:-1] & near[1:]
    return (float(length[inner][on[inner]].sum() / length[inner].sum()),
            float(length.sum() - length[inner].sum()))
