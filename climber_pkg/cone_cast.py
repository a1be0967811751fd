"""Ultrasonic cone casts against the climbed structure, batched: what the simulated sensors of
``climber_ultrasonic`` measure (:meth:`climber_pkg.trunk.Trunk.cone_distance`), for one ring's
three sensors at a time, with fewer closest-point queries and optionally compiled kernels.
"""
from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from climber_pkg.trunk import Trunk, cone_rim
from paramotion.backend import resolve_backend

#: Rays sampling the rim of each cone (the default of :meth:`Trunk.cone_distance`).
RIM_RAYS = 24
_ARRAYS = {}


def cone_distances(trunk: Trunk, origins: np.ndarray, directions: np.ndarray,
                   field_of_view: float, max_range: float, rim_rays: int = RIM_RAYS,
                   backend: str = 'auto') -> np.ndarray:
    """:meth:`Trunk.cone_distance` of the sensors (n, 3), with the centre and rim rays of
    every cone cast together in one batch (half the closest-point queries of two calls).

    ``backend`` (:func:`paramotion.backend.resolve_backend`): ``'numpy'`` casts the batch with
    :meth:`Trunk.ray_distance`; ``'numba'`` with the compiled kernels of
    :mod:`climber_pkg.cone_cast_numba`, which take the same floating-point steps ray by ray.
    Every ray is computed on its own in each form, so the distances equal
    :meth:`Trunk.cone_distance` bit for bit
    (``test/test_climber_graph.py::test_batched_cone_distances_equal_the_trunk_cones``)."""
    o = np.asarray(origins, dtype=float).reshape(-1, 3)
    d = np.asarray(directions, dtype=float).reshape(-1, 3)
    d = d / np.linalg.norm(d, axis=1, keepdims=True)
    n = len(o)
    cone = field_of_view > 0
    if cone:
        half = 0.5 * float(field_of_view)
        rim = cone_rim(d, field_of_view, rim_rays)
        rays_o = np.concatenate([o, np.repeat(o, rim_rays, axis=0)])
        rays_d = np.concatenate([d, rim.reshape(-1, 3)])
    else:
        rays_o, rays_d = o, d
    if resolve_backend(backend) == 'numba':
        arrays = _trunk_arrays(trunk)
        dist, s_o = _ray_distance_compiled(trunk, arrays, rays_o, rays_d, max_range)
        if not cone:
            return dist
        from climber_pkg import cone_cast_numba as kernels
        best = np.minimum(dist[:n], dist[n:].reshape(n, rim_rays).min(axis=1))
        s = s_o[:n].copy()
        kernels.cone_near(o, d, s, np.asarray(trunk.radius_at(s), dtype=float), *arrays[1:],
                          half, float(max_range), best)
        return best
    dist = trunk.ray_distance(rays_o, rays_d, max_range)
    if not cone:
        return dist
    best = np.minimum(dist[:n], dist[n:].reshape(n, rim_rays).min(axis=1))
    return trunk.perpendicular_echo(o, d, field_of_view, max_range, best)


def _trunk_arrays(trunk: Trunk) -> tuple:
    """(KD tree of the centreline samples, arc lengths, points (3, n), tangents (3, n),
    length) of ``trunk``, built once per trunk object."""
    known = _ARRAYS.get(id(trunk))
    if known is None or known[0] is not trunk:
        if len(_ARRAYS) > 16:
            _ARRAYS.clear()
        known = (trunk, (cKDTree(trunk.points), np.ascontiguousarray(trunk.s, dtype=float),
                         np.ascontiguousarray(trunk.points.T, dtype=float),
                         np.ascontiguousarray(trunk.tangents.T, dtype=float),
                         float(trunk.length)))
        _ARRAYS[id(trunk)] = known
    return known[1]


def _ray_distance_compiled(trunk: Trunk, arrays: tuple, o: np.ndarray, d: np.ndarray,
                           max_range: float, iterations: int = 4
                           ) -> tuple[np.ndarray, np.ndarray]:
    """:meth:`Trunk.ray_distance` by the compiled kernels; also the arc lengths of the axis
    points closest to the ray origins."""
    from climber_pkg import cone_cast_numba as kernels
    tree, ts, pts, tans, length = arrays
    o = np.ascontiguousarray(o, dtype=float)

    def closest(points):
        idx = tree.query(points)[1]
        s_out, d_out = np.empty(len(points)), np.empty(len(points))
        kernels.closest_refine(points, idx, ts, pts, s_out, d_out)
        return s_out, d_out

    d = kernels.unit_rows(np.ascontiguousarray(d, dtype=float))
    s_o, dist_o = closest(o)
    s = closest(o + 0.5 * max_range * d)[0] if length > 0 else s_o
    t_hit = np.full(len(o), np.inf)
    hit = np.empty_like(o)
    for _ in range(iterations):
        if not kernels.tube_hits(o, d, s, np.asarray(trunk.radius_at(s), dtype=float), ts,
                                 pts, tans, length, t_hit, hit):
            break
        s = np.where(np.isfinite(t_hit), closest(hit)[0], s)
    inside = (dist_o < trunk.radius_at(s_o)) & (s_o > 0) & (s_o < length)
    out = np.where(np.isfinite(t_hit) & (t_hit >= 0) & (t_hit <= max_range), t_hit, np.inf)
    if np.any(np.isfinite(out)):
        s_hit = closest(o + np.where(np.isfinite(out), out, 0.0)[:, None] * d)[0]
        out = np.where((s_hit <= 0.0) | (s_hit >= length), np.inf, out)
    return np.where(inside, 0.0, out), s_o


class CompiledTrunk(Trunk):
    """A :class:`Trunk` whose closest-point query runs the compiled refinement of
    :mod:`climber_pkg.cone_cast_numba` after the same KD-tree query (when numba is installed):
    the same arc lengths and distances bit for bit (``test/test_climber_graph.py::
    test_compiled_trunk_closest_points_equal_the_trunk_ones``), for evaluations that query
    many points often (``paramotion climb``'s ground-truth monitor)."""

    def closest(self, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        if resolve_backend('auto') != 'numba':
            return super().closest(points)
        from climber_pkg import cone_cast_numba as kernels
        pts = np.asarray(points, dtype=float)
        flat = np.ascontiguousarray(pts.reshape(-1, 3))
        tree, ts, samples, _, _ = _trunk_arrays(self)
        idx = tree.query(flat)[1]
        s_out, d_out = np.empty(len(flat)), np.empty(len(flat))
        kernels.closest_refine(flat, idx, ts, samples, s_out, d_out)
        shape = pts.shape[:-1]
        return s_out.reshape(shape), d_out.reshape(shape)
