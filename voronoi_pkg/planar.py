"""The planar example of section 6 of Vaca, Aranda & Thomas, reproduced exactly, and its
generalisation to other planar scenes.

Robot: base segment P1P2 with P1 = (0, 0), P2 = (15, 0); moving platform P3P4 with
P3 = (x, y) and P4 = P3 + 10 (cos phi, sin phi); legs P1P3, P2P3 and P2P4. Configuration
``q = (x, y, phi)``. Boundary square P5P6P7P8 = (-25, 40), (-25, -40), (55, -40), (55, 40).

* Singularity-free predicate ``P1 = (D(1,2,3) | ~D(1,2,3)) & (D(2,3,4) | ~D(2,3,4))``:
  the platform is singular when P3 is on the base line or when P2, P3, P4 are collinear.
* Collision-free predicate ``P2``: the platform P3P4 crosses neither the base P1P2 nor any
  of the boundary edges P5P6, P6P7, P7P8, P8P5 (``NOT segments_cross`` for each; 3x3
  determinants as in the paper's formula).

For a fixed ``phi`` every determinant is affine in (x, y), so rho is piecewise linear in each
orientation slice and the simplified Voronoi diagram is an arrangement of straight segments.

A scene file (JSON) can move the base, change the platform length, replace the boundary and
add convex polygonal obstacles; the paper's scene is :func:`paper_model`. No ROS imports.
"""
from __future__ import annotations

import math
from collections.abc import Hashable, Iterable, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike

from paramotion.errors import UserError
from paramotion.jsonfile import load_json_object
from voronoi_pkg.distance import RhoProgram, compile_rho
from voronoi_pkg.predicates import (
    And,
    Delta,
    Not,
    Or,
    bracket3,
    evaluate_determinants,
    fuse,
    pure_condition_free,
    segments_cross,
)

__all__ = ['CONSTRUCTS', 'Domain', 'NamedPredicate', 'PlanarModel', 'check_without', 'load_scene',
           'paper_model', 'planar_model', 'PAPER_START', 'PAPER_GOAL']

#: The query of Fig. 3: from (35, -20, pi/2) to (-10, -15, -pi/2).
PAPER_START = (35.0, -20.0, math.pi / 2)
PAPER_GOAL = (-10.0, -15.0, -math.pi / 2)

_CHUNK = 1 << 16

#: Constructs of the paper that ``without`` switches off (ablations): the singularity factors
#: of P1 and the collision predicates of P2.
CONSTRUCTS = ('singularity', 'collision')


def check_without(without: Iterable[str] | None) -> tuple[str, ...]:
    """The ablation names as a tuple; refuses unknown names with one line."""
    names = tuple(w for w in (without or ()) if w)
    bad = [w for w in names if w not in CONSTRUCTS]
    if bad:
        raise UserError(f'without: unknown construct {bad[0]!r} (choose from '
                        f'{", ".join(CONSTRUCTS)})')
    if set(names) >= set(CONSTRUCTS):
        raise UserError('without: switching off both singularity and collision leaves no '
                        'predicate to plan with')
    return names


@dataclass(frozen=True)
class Domain:
    """Region of configuration space searched: boxes in x, y and an orientation interval.

    ``phi`` covering a full turn (``phi_max - phi_min >= 2 pi``) makes it periodic (S^1).
    """

    x: tuple = (-30.0, 60.0)
    y: tuple = (-45.0, 45.0)
    phi: tuple = (-math.pi, math.pi)

    @property
    def periodic(self) -> bool:
        return self.phi[1] - self.phi[0] >= 2 * math.pi - 1e-12

    def contains(self, q: ArrayLike) -> np.ndarray:
        q = np.asarray(q, dtype=float)
        inside = ((self.x[0] <= q[..., 0]) & (q[..., 0] <= self.x[1])
                  & (self.y[0] <= q[..., 1]) & (q[..., 1] <= self.y[1]))
        if not self.periodic:
            inside &= (self.phi[0] <= q[..., 2]) & (q[..., 2] <= self.phi[1])
        return inside


@dataclass(frozen=True)
class NamedPredicate:
    """One factor of the fused AND tree, with the words used in error messages."""

    name: str
    kind: str          # 'singularity' or 'collision'
    tree: object


@dataclass
class PlanarModel:
    """A planar 3-leg platform with its fused singularity and collision predicates.

    ``fixed``: label -> (2,) world point; ``moving``: label -> (2,) point in the platform frame
    (origin P3, x axis along the platform). ``predicates``: AND-ed factors, in order.
    """

    fixed: dict
    moving: dict
    predicates: list
    domain: Domain = field(default_factory=Domain)
    segments: dict = field(default_factory=dict)   # name -> (label_a, label_b), for drawing

    def __post_init__(self):
        self.fixed = {k: np.asarray(v, dtype=float) for k, v in self.fixed.items()}
        self.moving = {k: np.asarray(v, dtype=float) for k, v in self.moving.items()}
        if not self.predicates:
            raise UserError('the model has no predicate left (every construct switched off)')
        self.tree = fuse(*[p.tree for p in self.predicates])
        # One program per kind present (an ablation may remove a kind), and the fused one.
        self.programs = {kind: compile_rho(fuse(*[p.tree for p in self.predicates
                                                  if p.kind == kind]))
                         for kind in CONSTRUCTS if any(p.kind == kind for p in self.predicates)}
        self.programs['total'] = compile_rho(self.tree)
        self.factor_programs = [compile_rho(p.tree) for p in self.predicates]
        # rho at or below this counts as forbidden: a configuration whose determinant is zero
        # up to rounding (e.g. exactly singular) must not be taken as free. Determinants are
        # areas, so the scale is the squared size of the domain.
        d = self.domain
        self.free_tol = 1e-9 * ((d.x[1] - d.x[0]) ** 2 + (d.y[1] - d.y[0]) ** 2)
        # Determinants of the pure condition: the path must never change their sign.
        self.singular_keys = []
        for p in self.predicates:
            if p.kind == 'singularity':
                for key in compile_rho(p.tree).keys:
                    if key not in self.singular_keys:
                        self.singular_keys.append(key)

    # -- geometry ------------------------------------------------------------------------------
    def points(self, q: ArrayLike) -> dict[Hashable, np.ndarray]:
        """World coordinates of every labelled point for configurations ``q`` (..., 3)."""
        q = np.asarray(q, dtype=float)
        c, s = np.cos(q[..., 2]), np.sin(q[..., 2])
        out = {}
        for label, p in self.fixed.items():
            out[label] = np.broadcast_to(p, q.shape[:-1] + (2,))
        for label, p in self.moving.items():
            out[label] = np.stack([q[..., 0] + c * p[0] - s * p[1],
                                   q[..., 1] + s * p[0] + c * p[1]], axis=-1)
        return out

    def determinants(self, q: ArrayLike, program: str | RhoProgram = 'total',
                     stack: bool = True) -> np.ndarray | list[np.ndarray]:
        """Determinants read by ``program`` at ``q``: ``(n_keys, ...)``."""
        prog = self.programs[program] if isinstance(program, str) else program
        return evaluate_determinants(prog.keys, self.points(q), stack)

    def _chunked(self, q, fn, n_out):
        q = np.asarray(q, dtype=float)
        flat = q.reshape(-1, 3)
        outs = [np.empty(flat.shape[0], dtype=dt) for dt in n_out]
        for start in range(0, flat.shape[0], _CHUNK):
            part = fn(flat[start:start + _CHUNK])
            part = part if isinstance(part, tuple) else (part,)
            for o, p in zip(outs, part):
                o[start:start + _CHUNK] = p
        outs = [o.reshape(q.shape[:-1]) for o in outs]
        return outs[0] if len(outs) == 1 else tuple(outs)

    def rho(self, q: ArrayLike, program: str = 'total') -> np.ndarray:
        """Distance measure rho (section 4) at configurations ``q`` (..., 3), vectorised."""
        prog = self.programs[program]
        return self._chunked(q, lambda c: prog.rho(self.determinants(c, prog, False)),
                             [float])

    def evaluate(self, q: ArrayLike,
                 program: str = 'total') -> tuple[np.ndarray, np.ndarray]:
        """``(rho, active_leaf)`` at configurations ``q`` (..., 3)."""
        prog = self.programs[program]
        return self._chunked(q, lambda c: prog.evaluate(self.determinants(c, prog, False)),
                             [float, np.int32])

    def contact_values(self, q: ArrayLike,
                       program: str = 'total') -> tuple[np.ndarray, np.ndarray]:
        """Value and deciding determinant code of every contact (root child of rho's tree,
        :mod:`voronoi_pkg.ties`) at configurations ``q`` (..., 3): ``(n_contacts, ...)``
        each."""
        prog = self.programs[program]
        q = np.asarray(q, dtype=float)
        vals, codes = prog.contact_values(self.determinants(q.reshape(-1, 3), prog))
        n = vals.shape[0]
        return vals.reshape((n,) + q.shape[:-1]), codes.reshape((n,) + q.shape[:-1])

    def fields(self, q: ArrayLike, program: str = 'total'
               ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """``(rho, contact, code, cell)`` at ``q`` in one pass: rho, the smallest contact,
        the determinant deciding it, and ``cell``, the sign vector of the pure-condition
        determinants (the singularity cell) as an integer."""
        prog = self.programs[program]
        rows = [prog.keys.index(k) for k in self.singular_keys if k in prog.keys]
        extra = [k for k in self.singular_keys if k not in prog.keys]

        def one(c):
            dets = self.determinants(c, prog, False)
            vals, codes = prog.contact_values(dets)
            i1 = np.argmin(vals, axis=0)
            rho = np.take_along_axis(vals, i1[None], axis=0)[0]
            code = np.take_along_axis(codes, i1[None], axis=0)[0]
            sing = [dets[r] for r in rows]
            if extra:
                sing += evaluate_determinants(extra, self.points(c), False)
            cell = np.zeros(len(c), dtype=np.int64)
            for i, d in enumerate(sing):
                cell += (np.sign(d).astype(np.int64) + 1) * 3 ** i
            return rho, i1, code, cell

        return self._chunked(q, one, [float, np.int32, np.int32, np.int64])

    def singular_signs(self, q: ArrayLike) -> np.ndarray:
        """Signs of the pure-condition determinants, ``(n_singular, ...)`` of -1/0/+1."""
        if not self.singular_keys:                  # singularities switched off
            return np.zeros((0,) + np.shape(q)[:-1])
        pts = self.points(q)
        return np.sign(evaluate_determinants(self.singular_keys, pts))

    def swept_hits(self, a: ArrayLike, b: ArrayLike) -> np.ndarray:
        """Whether the platform, moving straight from configurations ``a`` to ``b`` (each
        ``(n, 3)``, one small step), sweeps across a fixed scene segment: the quadrilateral
        P3(a) P4(a) P4(b) P3(b) meets the segment (closed test). Samples of rho step over a
        wall the platform crosses while parallel to it (there the collision set of one slice
        is a line, of zero width); this catches it. Empty when collisions are switched off."""
        a, b = np.atleast_2d(a), np.atleast_2d(b)
        hit = np.zeros(len(a), dtype=bool)
        if 'collision' not in self.programs or not len(a):
            return hit
        pa, pb = self.points(a), self.points(b)
        m0, m1 = sorted(self.moving)[0], sorted(self.moving)[-1]
        quad = [pa[m0], pa[m1], pb[m1], pb[m0]]
        lo, hi = np.minimum.reduce(quad), np.maximum.reduce(quad)
        for u, v in self.segments.values():
            if u not in self.fixed or v not in self.fixed:
                continue
            s, e = self.fixed[u], self.fixed[v]
            k = np.flatnonzero(np.all((lo <= np.maximum(s, e)) & (hi >= np.minimum(s, e)),
                                      axis=1))
            sub = [c[k] for c in quad]
            for i in range(4):
                hit[k] |= _closed_cross(sub[i], sub[(i + 1) % 4], s, e)
            inside = np.stack([_orient(sub[i], sub[(i + 1) % 4], s) for i in range(4)])
            flat = np.stack([np.all(sub[i] == sub[(i + 1) % 4], axis=-1) for i in range(4)])
            hit[k] |= (np.all((inside > 0) | flat, axis=0) | np.all((inside < 0) | flat, axis=0))
        return hit

    def diagnose(self, q: ArrayLike) -> list[tuple[str, float]]:
        """Names and rho values of the AND-ed factors that fail (rho <= 0) at one ``q``."""
        q = np.asarray(q, dtype=float).reshape(3)
        failures = []
        for pred, prog in zip(self.predicates, self.factor_programs):
            value = float(prog.rho(evaluate_determinants(prog.keys, self.points(q))))
            if not value > self.free_tol:
                failures.append((pred.name, value))
        return failures


def _orient(p, q, r):
    """Twice the signed area of the triangle p q r (broadcast over leading axes)."""
    return ((q[..., 0] - p[..., 0]) * (r[..., 1] - p[..., 1])
            - (q[..., 1] - p[..., 1]) * (r[..., 0] - p[..., 0]))


def _closed_cross(p, q, r, s):
    """Closed segments pq and rs meet (touching counts; collinear ones count as meeting when
    their bounding boxes overlap)."""
    o1, o2 = _orient(p, q, r), _orient(p, q, s)
    o3, o4 = _orient(r, s, p), _orient(r, s, q)
    lo = np.maximum(np.minimum(p, q), np.minimum(r, s))
    hi = np.minimum(np.maximum(p, q), np.maximum(r, s))
    boxes = np.all(lo <= hi, axis=-1)
    return (o1 * o2 <= 0) & (o3 * o4 <= 0) & boxes


def planar_model(base: Sequence[ArrayLike], length: float, boundary: Sequence[ArrayLike],
                 obstacles: Iterable[Sequence[ArrayLike]], domain: Domain,
                 without: Iterable[str] | None = ()) -> PlanarModel:
    """Build a planar model: base segment, platform length, boundary polygon (its edges are
    obstacles, as in the paper), convex obstacle polygons (counter-clockwise) and the domain.
    ``without``: constructs switched off (:data:`CONSTRUCTS`): their predicates are left out
    of rho, so the planner neither sees nor checks them.

    Labels: 1, 2 base; 3, 4 platform; 5.. boundary vertices; then obstacle vertices.
    """
    without = check_without(without)
    fixed = {1: base[0], 2: base[1]}
    moving = {3: (0.0, 0.0), 4: (float(length), 0.0)}
    predicates = [
        NamedPredicate('P1: Delta(1,2,3) - singular, P3 on the base line P1P2', 'singularity',
                       pure_condition_free([(1, 2, 3)])),
        NamedPredicate('P1: Delta(2,3,4) - singular, P2, P3 and P4 collinear', 'singularity',
                       pure_condition_free([(2, 3, 4)])),
        NamedPredicate('P2: platform P3P4 crosses base P1P2', 'collision',
                       Not(segments_cross(1, 2, 3, 4))),
    ]
    segments = {'base': (1, 2), 'platform': (3, 4)}
    label = 5
    if boundary:
        labels = list(range(label, label + len(boundary)))
        for lab, p in zip(labels, boundary):
            fixed[lab] = p
        for a, b in zip(labels, labels[1:] + labels[:1]):
            predicates.append(NamedPredicate(
                f'P2: platform P3P4 crosses boundary edge P{a}P{b}', 'collision',
                Not(segments_cross(a, b, 3, 4))))
            segments[f'boundary P{a}P{b}'] = (a, b)
        label += len(boundary)
    for n, poly in enumerate(obstacles):
        labels = list(range(label, label + len(poly)))
        for lab, p in zip(labels, poly):
            fixed[lab] = p
        ring = list(zip(labels, labels[1:] + labels[:1]))
        crossings = [segments_cross(a, b, 3, 4) for a, b in ring]
        inside = And(*(Delta(a, b, 3) for a, b in ring))   # P3 inside the convex polygon
        predicates.append(NamedPredicate(
            f'P2: platform P3P4 overlaps obstacle {n} (P{labels[0]}..P{labels[-1]})',
            'collision', Not(Or(*crossings, inside))))
        for a, b in ring:
            segments[f'obstacle {n} P{a}P{b}'] = (a, b)
        label += len(poly)
    predicates = [p for p in predicates if p.kind not in without]
    return PlanarModel(fixed, moving, predicates, domain, segments)


def paper_model(domain: Domain | None = None,
                without: Iterable[str] | None = ()) -> PlanarModel:
    """Section 6 exactly: P1 and P2 of the paper over Fig. 3's region (phi over a full turn)."""
    return planar_model(base=((0.0, 0.0), (15.0, 0.0)), length=10.0,
                         boundary=((-25.0, 40.0), (-25.0, -40.0), (55.0, -40.0), (55.0, 40.0)),
                         obstacles=(), domain=domain or Domain(), without=without)


def _points(value, name, count=None):
    try:
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise UserError(f'scene: {name} must be a list of [x, y] points') from None
    if arr.ndim != 2 or arr.shape[1] != 2 or not np.all(np.isfinite(arr)):
        raise UserError(f'scene: {name} must be a list of finite [x, y] points')
    if count is not None and arr.shape[0] != count:
        raise UserError(f'scene: {name} must have {count} points, got {arr.shape[0]}')
    return [tuple(p) for p in arr]


def _convex_ccw(poly, name):
    """Return the polygon counter-clockwise; refuse non-convex or degenerate ones."""
    if len(poly) < 3:
        raise UserError(f'scene: {name} needs at least 3 vertices')
    p = np.asarray(poly)
    area = 0.5 * np.sum(p[:, 0] * np.roll(p[:, 1], -1) - np.roll(p[:, 0], -1) * p[:, 1])
    if abs(area) < 1e-12:
        raise UserError(f'scene: {name} has zero area')
    if area < 0:
        p = p[::-1]
    turns = [float(bracket3(p[i], p[(i + 1) % len(p)], p[(i + 2) % len(p)]))
             for i in range(len(p))]
    if min(turns) <= 0:
        raise UserError(f'scene: {name} must be a convex polygon without repeated or '
                        'collinear vertices')
    return [tuple(v) for v in p]


def load_scene(path: str | Path, without: Iterable[str] | None = ()) -> PlanarModel:
    """Read a planar scene JSON file; keys (all optional, defaults = the paper's scene):

    ``base`` [[x, y], [x, y]], ``platform_length`` > 0, ``boundary`` polygon (the robot moves
    inside; its edges are obstacles, as in the paper), ``obstacles`` list of convex polygons,
    ``domain`` {"x": [lo, hi], "y": [lo, hi], "phi_deg": [lo, hi]}.
    """
    path = Path(path)
    data = load_json_object(path, 'scene file')
    unknown = set(data) - {'base', 'platform_length', 'boundary', 'obstacles', 'domain',
                           'comment'}
    if unknown:
        raise UserError(f'scene file {path}: unknown keys {sorted(unknown)}')
    base = _points(data.get('base', [[0, 0], [15, 0]]), 'base', 2)
    if np.allclose(base[0], base[1]):
        raise UserError('scene: base points must differ')
    length = data.get('platform_length', 10.0)
    if not isinstance(length, (int, float)) or not math.isfinite(length) or length <= 0:
        raise UserError(f'scene: platform_length must be a positive number, got {length!r}')
    boundary = data.get('boundary', [[-25, 40], [-25, -40], [55, -40], [55, 40]])
    boundary = _points(boundary, 'boundary') if boundary else []
    obstacles = [_convex_ccw(_points(o, f'obstacle {i}'), f'obstacle {i}')
                 for i, o in enumerate(data.get('obstacles', []))]
    dom = data.get('domain', {})
    try:
        x = tuple(float(v) for v in dom.get('x', (-30, 60)))
        y = tuple(float(v) for v in dom.get('y', (-45, 45)))
        phi = tuple(math.radians(float(v)) for v in dom.get('phi_deg', (-180, 180)))
    except (TypeError, ValueError):
        raise UserError('scene: domain x, y, phi_deg must be [lo, hi] numbers') from None
    for name, (lo, hi) in (('x', x), ('y', y), ('phi_deg', phi)):
        if not (math.isfinite(lo) and math.isfinite(hi) and lo < hi):
            raise UserError(f'scene: domain {name} must be [lo, hi] with lo < hi')
    return planar_model(base, float(length), boundary, obstacles, Domain(x, y, phi), without)
