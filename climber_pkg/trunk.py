"""The climbed structure: a tube of varying radius around a smooth spatial centreline.

Reads the structure files of ``shared/trunks`` (``name``, ``centerline`` polyline of [x, y, z]
points from foot to top, ``radius`` as one number or ``[s, r]`` pairs linear in arc length).
The centreline is the cubic spline through the points (parameterised by chord length; two
points give a straight trunk), resampled densely by arc length so that closest-point, axis and
ray queries are cheap and vectorised.

Used by the simulator (collision geometry), the simulated ultrasonic sensors (ray casts) and the
evaluation (centering error, clearance). Never by the planner: it knows only its encoders and
its ultrasonic sensors.
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike
from scipy.interpolate import CubicSpline
from scipy.spatial import cKDTree

from paramotion.errors import UserError
from paramotion.jsonfile import load_json_object

#: Arc-length spacing of the dense resampling of the centreline, m.
SAMPLE_STEP = 0.005


class Trunk:
    """Smooth tube: centreline c(s), unit tangent t(s), radius r(s), s in [0, length]."""

    def __init__(self, centerline: list[list[float]], radius: float | list[list[float]],
                 name: str = 'trunk', source: str = 'trunk') -> None:
        pts = _validate_centerline(centerline, source)
        self.name = str(name)
        self.source = source
        chord = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(pts, axis=0), axis=1))])
        if len(pts) == 2:
            dense_u = np.linspace(0.0, chord[-1], max(2, int(chord[-1] / SAMPLE_STEP) + 1))
            dense = pts[0] + np.outer(dense_u / chord[-1], pts[1] - pts[0])
        else:
            spline = CubicSpline(chord, pts, bc_type='natural')
            dense_u = np.linspace(0.0, chord[-1], max(50, int(4 * chord[-1] / SAMPLE_STEP)))
            dense = spline(dense_u)
        seg = np.linalg.norm(np.diff(dense, axis=0), axis=1)
        s_dense = np.concatenate([[0.0], np.cumsum(seg)])
        self.length = float(s_dense[-1])
        n = max(2, int(math.ceil(self.length / SAMPLE_STEP)) + 1)
        self.s = np.linspace(0.0, self.length, n)
        self.points = np.stack([np.interp(self.s, s_dense, dense[:, k]) for k in range(3)], 1)
        tang = np.gradient(self.points, self.s, axis=0)
        self.tangents = tang / np.linalg.norm(tang, axis=1, keepdims=True)
        curv = np.gradient(self.tangents, self.s, axis=0)
        self.curvature = np.linalg.norm(curv, axis=1)
        self._radius_s, self._radius_r = _validate_radius(radius, self.length, source)
        self.radii = self.radius_at(self.s)
        self._tree = cKDTree(self.points)

    # ---------------------------------------------------------------- construction
    @classmethod
    def from_file(cls, path: str | Path) -> Trunk:
        """Load and validate a structure JSON file; UserError names the file and the problem."""
        data = load_json_object(path, 'trunk file')
        return cls.from_dict(data, source=f'trunk file {path}')

    @classmethod
    def from_dict(cls, data: object, source: str = 'trunk') -> Trunk:
        if not isinstance(data, dict):
            raise UserError(f'{source}: expected a JSON object')
        for key in ('centerline', 'radius'):
            if key not in data:
                raise UserError(f'{source}: missing key {key!r}')
        units = data.get('units', 'm')
        if units != 'm':
            raise UserError(f'{source}: units must be "m", got {units!r}')
        return cls(data['centerline'], data['radius'], data.get('name', 'trunk'), source)

    def to_dict(self) -> dict[str, object]:
        """A structure-file object equivalent to this trunk (for generated test trunks)."""
        return {'name': self.name, 'units': 'm',
                'centerline': self.points[::20].tolist() + [self.points[-1].tolist()],
                'radius': [[float(s), float(r)]
                           for s, r in zip(self._radius_s, self._radius_r)]}

    # ---------------------------------------------------------------- queries along s
    def radius_at(self, s: ArrayLike) -> np.ndarray | float:
        """Radius at arc length s (linear between the file's [s, r] pairs, held at the ends)."""
        return np.interp(s, self._radius_s, self._radius_r)

    def point_at(self, s: ArrayLike) -> np.ndarray:
        s = np.clip(s, 0.0, self.length)
        return np.stack([np.interp(s, self.s, self.points[:, k]) for k in range(3)], -1)

    def tangent_at(self, s: ArrayLike) -> np.ndarray:
        s = np.clip(s, 0.0, self.length)
        t = np.stack([np.interp(s, self.s, self.tangents[:, k]) for k in range(3)], -1)
        return t / np.linalg.norm(t, axis=-1, keepdims=True)

    @property
    def top(self) -> np.ndarray:
        return self.points[-1]

    @property
    def max_radius(self) -> float:
        return float(self.radii.max())

    @property
    def max_curvature(self) -> float:
        return float(self.curvature.max())

    def frame_at(self, s: float,
                 x_hint: ArrayLike = (1.0, 0.0, 0.0)) -> tuple[np.ndarray, np.ndarray]:
        """Position and rotation (columns x, y, z = tangent) of a frame on the axis at s."""
        p = self.point_at(s)
        z = self.tangent_at(s)
        x = np.asarray(x_hint, dtype=float) - np.dot(x_hint, z) * z
        if np.linalg.norm(x) < 1e-6:
            x = np.array([0.0, 1.0, 0.0]) - z[1] * z
        x /= np.linalg.norm(x)
        return p, np.stack([x, np.cross(z, x), z], axis=1)

    # ---------------------------------------------------------------- spatial queries
    def closest(self, points: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
        """Arc length of the closest axis point and distance to the axis, for points (..., 3).

        Points beyond the ends project onto the end caps' planes' nearest axis point (s clamped).
        """
        pts = np.asarray(points, dtype=float)
        flat = pts.reshape(-1, 3)
        _, idx = self._tree.query(flat)
        # Refine on the two segments around the nearest sample.
        best_s = self.s[idx].copy()
        best_d = np.linalg.norm(flat - self.points[idx], axis=1)
        for off in (-1, 0):
            i0 = np.clip(idx + off, 0, len(self.s) - 2)
            a, b = self.points[i0], self.points[i0 + 1]
            ab = b - a
            t = np.clip(np.einsum('ij,ij->i', flat - a, ab) / np.einsum('ij,ij->i', ab, ab), 0, 1)
            q = a + t[:, None] * ab
            d = np.linalg.norm(flat - q, axis=1)
            better = d < best_d
            best_d[better] = d[better]
            best_s[better] = (self.s[i0] + t * (self.s[i0 + 1] - self.s[i0]))[better]
        shape = pts.shape[:-1]
        return best_s.reshape(shape), best_d.reshape(shape)

    def surface_clearance(self, points: ArrayLike) -> np.ndarray:
        """Signed distance from points to the tube surface (negative inside the trunk)."""
        s, d = self.closest(points)
        return d - self.radius_at(s)

    def inside_span(self, points: ArrayLike) -> np.ndarray:
        """True where the closest axis point lies strictly between the foot and the top."""
        s, _ = self.closest(points)
        return (s > 0.0) & (s < self.length)

    def axis_in_plane(self, origin: ArrayLike, normal: ArrayLike, s_guess: float | None = None
                      ) -> tuple[np.ndarray, float] | tuple[None, None]:
        """Where the centreline crosses the plane (origin, normal): (point, s) or (None, None).

        Searches the crossing nearest to ``s_guess`` (default: the arc length closest to
        ``origin``) by bracketing on the dense samples.
        """
        origin = np.asarray(origin, dtype=float)
        normal = np.asarray(normal, dtype=float)
        side = (self.points - origin) @ normal
        crossings = np.flatnonzero(np.sign(side[:-1]) * np.sign(side[1:]) <= 0)
        if crossings.size == 0:
            return None, None
        if s_guess is None:
            s_guess = float(self.closest(origin)[0])
        k = crossings[np.argmin(np.abs(self.s[crossings] - s_guess))]
        f0, f1 = side[k], side[k + 1]
        t = 0.0 if f1 == f0 else f0 / (f0 - f1)
        s = self.s[k] + t * (self.s[k + 1] - self.s[k])
        return self.point_at(s), float(s)

    def ray_distance(self, origins: ArrayLike, directions: ArrayLike, max_range: float,
                     iterations: int = 4) -> np.ndarray:
        """Distance along each ray (n, 3) to the tube surface; +inf when none within max_range.

        Intersects each ray with the cylinder tangent to the tube at the axis point closest to
        the ray origin, then re-linearises the tube at the hit point and repeats (the tube
        bends and tapers slowly on the scale of a sensor range). Rays whose hit lies past the
        foot or the top miss: the tube has open ends, beyond the top nothing echoes. A ray
        starting inside the tube returns 0.
        """
        o = np.asarray(origins, dtype=float).reshape(-1, 3)
        d = np.asarray(directions, dtype=float).reshape(-1, 3)
        d = d / np.linalg.norm(d, axis=1, keepdims=True)
        s, dist0 = self.closest(o)
        if self.length > 0:
            s_c, _ = self.closest(o + 0.5 * max_range * d)
            s = s_c
        t_hit = np.full(len(o), np.inf)
        for _ in range(iterations):
            c = self.point_at(s)
            a = self.tangent_at(s)
            r = self.radius_at(s)
            w = o - c
            wp = w - np.einsum('ij,ij->i', w, a)[:, None] * a
            dp = d - np.einsum('ij,ij->i', d, a)[:, None] * a
            qa = np.einsum('ij,ij->i', dp, dp)
            qb = 2 * np.einsum('ij,ij->i', wp, dp)
            qc = np.einsum('ij,ij->i', wp, wp) - r * r
            disc = qb * qb - 4 * qa * qc
            with np.errstate(invalid='ignore', divide='ignore'):
                root = (-qb - np.sqrt(disc)) / (2 * qa)
            t_hit = np.where((disc >= 0) & (qa > 1e-12), root, np.inf)
            finite = np.isfinite(t_hit)
            if not np.any(finite):
                break
            hit = o + np.where(finite, t_hit, 0.0)[:, None] * d
            s_new, _ = self.closest(hit)
            s = np.where(finite, s_new, s)
        s_end, dist_end = self.closest(o)
        inside = (dist_end < self.radius_at(s_end)) & (s_end > 0) & (s_end < self.length)
        out = np.where(np.isfinite(t_hit) & (t_hit >= 0) & (t_hit <= max_range), t_hit, np.inf)
        if np.any(np.isfinite(out)):
            hit = o + np.where(np.isfinite(out), out, 0.0)[:, None] * d
            s_hit, _ = self.closest(hit)
            off = (s_hit <= 0.0) | (s_hit >= self.length)
            out = np.where(off, np.inf, out)
        out = np.where(inside, 0.0, out)
        del dist0
        return out

    def cone_distance(self, origins: ArrayLike, directions: ArrayLike, field_of_view: float,
                      max_range: float, boundary_rays: int = 24) -> np.ndarray:
        """Nearest echo within each sensor's cone (n, 3): +inf when none within max_range.

        An ultrasonic sensor answers with the first echo of its beam, i.e. the nearest surface
        point inside its cone (``field_of_view``: full apex angle, rad, as in
        sensor_msgs/Range), not the point on its centre line. The nearest point of a locally
        straight tube seen from outside lies on the perpendicular to the axis; when that
        direction is inside the cone it is the answer, otherwise the nearest echo lies on the
        cone's boundary, sampled by ``boundary_rays`` rays. ``field_of_view = 0`` is the thin
        centre ray of :meth:`ray_distance`.
        """
        o = np.asarray(origins, dtype=float).reshape(-1, 3)
        d = np.asarray(directions, dtype=float).reshape(-1, 3)
        d = d / np.linalg.norm(d, axis=1, keepdims=True)
        best = self.ray_distance(o, d, max_range)
        if not field_of_view > 0:
            return best
        rim = cone_rim(d, field_of_view, boundary_rays)
        rim_d = self.ray_distance(np.repeat(o, boundary_rays, axis=0), rim.reshape(-1, 3),
                                  max_range).reshape(len(o), boundary_rays)
        best = np.minimum(best, rim_d.min(axis=1))
        return self.perpendicular_echo(o, d, field_of_view, max_range, best)

    def perpendicular_echo(self, origins: np.ndarray, directions: np.ndarray,
                           field_of_view: float, max_range: float,
                           best: np.ndarray) -> np.ndarray:
        """``best`` (n,) lowered to the perpendicular distance to the tube where the
        perpendicular from the sensor to the axis lies inside its cone (unit ``directions``):
        the nearest echo of a locally straight tube seen from outside."""
        o, d = origins, directions
        half = 0.5 * float(field_of_view)
        s, _ = self.closest(o)
        w = o - self.point_at(s)
        a = self.tangent_at(s)
        wp = w - np.einsum('ij,ij->i', w, a)[:, None] * a
        dist_axis = np.linalg.norm(wp, axis=1)
        with np.errstate(invalid='ignore', divide='ignore'):
            toward = -wp / dist_axis[:, None]
            inside_cone = np.einsum('ij,ij->i', toward, d) >= math.cos(half)
        near = dist_axis - self.radius_at(s)
        ok = (inside_cone & (s > 0.0) & (s < self.length) & (near >= 0.0) & (near <= max_range)
              & (dist_axis > 1e-9))
        return np.where(ok, np.minimum(best, near), best)


def cone_rim(directions: np.ndarray, field_of_view: float, rays: int) -> np.ndarray:
    """Unit directions (n, rays, 3) of ``rays`` rays evenly around the rim of each sensor's
    cone (full apex angle ``field_of_view``, rad) about its unit centre ``directions`` (n, 3)."""
    d = directions
    half = 0.5 * float(field_of_view)
    helper = np.where(np.abs(d[:, :1]) < 0.9, [[1.0, 0.0, 0.0]], [[0.0, 1.0, 0.0]])
    e1 = np.cross(d, helper)
    e1 /= np.linalg.norm(e1, axis=1, keepdims=True)
    e2 = np.cross(d, e1)
    ang = np.linspace(0.0, 2 * np.pi, rays, endpoint=False)
    return (math.cos(half) * d[:, None, :]
            + math.sin(half) * (np.cos(ang)[None, :, None] * e1[:, None, :]
                                + np.sin(ang)[None, :, None] * e2[:, None, :]))


def _validate_centerline(centerline, source):
    if not isinstance(centerline, list) or len(centerline) < 2:
        raise UserError(f'{source}: centerline must be a list of at least two [x, y, z] points')
    try:
        pts = np.array(centerline, dtype=float)
    except (TypeError, ValueError) as exc:
        raise UserError(f'{source}: centerline points must be [x, y, z] numbers') from exc
    if pts.ndim != 2 or pts.shape[1] != 3:
        raise UserError(f'{source}: centerline points must be [x, y, z] triples, got shape '
                        f'{pts.shape}')
    if not np.all(np.isfinite(pts)):
        raise UserError(f'{source}: centerline has non-finite coordinates')
    seg = np.linalg.norm(np.diff(pts, axis=0), axis=1)
    if np.any(seg < 1e-6):
        k = int(np.argmin(seg))
        raise UserError(f'{source}: centerline points {k} and {k + 1} coincide')
    if len(pts) > 2:
        d = np.diff(pts, axis=0) / seg[:, None]
        turn = np.degrees(np.arccos(np.clip(np.einsum('ij,ij->i', d[:-1], d[1:]), -1, 1)))
        if np.any(turn > 90):
            k = int(np.argmax(turn)) + 1
            raise UserError(f'{source}: centerline folds back by {turn.max():.0f} deg at point '
                            f'{k}: not a climbable structure')
    return pts


def _validate_radius(radius, length, source):
    if isinstance(radius, bool):
        raise UserError(f'{source}: radius must be a number or a list of [s, r] pairs')
    if isinstance(radius, (int, float)):
        if not (math.isfinite(radius) and radius > 0):
            raise UserError(f'{source}: radius must be positive and finite, got {radius}')
        return np.array([0.0, length]), np.array([float(radius), float(radius)])
    if not isinstance(radius, list) or not radius:
        raise UserError(f'{source}: radius must be a number or a list of [s, r] pairs')
    try:
        table = np.array(radius, dtype=float)
    except (TypeError, ValueError) as exc:
        raise UserError(f'{source}: radius pairs must be [s, r] numbers') from exc
    if table.ndim != 2 or table.shape[1] != 2:
        raise UserError(f'{source}: radius must be a list of [s, r] pairs')
    if not np.all(np.isfinite(table)):
        raise UserError(f'{source}: radius table has non-finite values')
    if np.any(table[:, 1] <= 0):
        raise UserError(f'{source}: radius values must be positive')
    if np.any(np.diff(table[:, 0]) < 0):
        raise UserError(f'{source}: radius table arc lengths must be non-decreasing')
    if len(table) == 1:
        table = np.array([[0.0, table[0, 1]], [length, table[0, 1]]])
    return table[:, 0], table[:, 1]
