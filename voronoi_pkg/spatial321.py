"""The spatial 3-2-1 platform of Fig. 1 (left) of Vaca, Aranda & Thomas among polyhedral
obstacles: singularity, contact and containment predicates as signs of 4x4 determinants, and
the measure rho in 6-D (section 4).

Robot (labels as in the paper's pure condition): base attachments P1..P6 fixed on the ground,
platform triangle P7 P8 P9. Three legs meet at P7 (from P1, P2, P3), two at P8 (from P5, P6) and
one at P9 (from P4). The platform is singular iff a tetrahedron of the factorised pure
condition ``[p1 p2 p3 p7][p5 p6 p7 p8][p4 p7 p8 p9] = 0`` degenerates (section 2, eq. 2).

Forbidden configurations, each a factor of the fused AND tree (one *contact* each; rho is the
minimum over them, so the simplified Voronoi diagram is where two contacts tie):

* singularity: one factor ``Delta OR NOT Delta`` per pure-condition tetrahedron;
* segment-face contacts (section 3): every leg and platform edge against every (convex,
  quadrilateral) face of every box, and every box edge against the platform triangle;
* containment: a platform vertex inside a box (AND of the six face-plane signs), so a
  platform entirely inside a box without touching a face is forbidden too (a leg inside a box
  has its base point inside, which the scene refuses);
* leg-leg contacts: two legs (or a leg and a platform edge) that share no attachment pass
  through each other. Two segments ab, cd meet iff ``[a b c d] = 0`` (coplanar) while their
  projections along the common normal ``n = (b - a) x (d - c)`` cross; the crossing is four
  determinants ``[c d a e2]``, ``[c d b e2]``, ``[a b c e1]``, ``[a b d e1]`` with the derived
  points ``e1 = a + s n/|n|``, ``e2 = c + s n/|n|``. Free = ``NOT cross OR |[a b c d]| > 0``.
  This contact is a hypersurface (like a singularity), so path checks also refuse a sign change
  of ``[a b c d]`` between two samples while the projections cross;
* leg-length limits ``min <= |P_b - P_a| <= max`` and the planning bounds: not determinants
  (the paper has neither); margins in m (angles times ``angle_scale``) times ``s**2``
  (``s**2`` = twice the platform triangle's area, the scale of a plane-point determinant with
  the platform as its face), one factor per limit.

Configuration ``q = (x, y, z, roll, pitch, yaw)``: position of P7 (m) and ZYX Euler angles
(rad) of the platform. Everything is evaluated for many poses at once. No ROS imports.
"""
from __future__ import annotations

import math
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike

from paramotion.errors import UserError
from paramotion.jsonfile import load_json_object
from voronoi_pkg.distance import RhoProgram, compile_rho
from voronoi_pkg.planar import check_without
from voronoi_pkg.predicates import (
    And,
    Delta,
    Not,
    Or,
    Xor,
    bracket4,
    evaluate_determinants,
    fuse,
    pure_condition_free,
    segment_pierces_triangle,
)

#: Factors of the 3-2-1 pure condition [p1p2p3p7][p5p6p7p8][p4p7p8p9].
PURE_CONDITION = ((1, 2, 3, 7), (5, 6, 7, 8), (4, 7, 8, 9))
LEGS = ((1, 7), (2, 7), (3, 7), (5, 8), (6, 8), (4, 9))
PLATFORM_EDGES = ((7, 8), (8, 9), (9, 7))

DEMO_BASE = {1: (-0.40, -0.30, 0.0), 2: (0.10, -0.50, 0.0), 3: (-0.40, 0.30, 0.0),
             4: (0.40, 0.60, 0.0), 5: (0.70, -0.30, 0.0), 6: (0.70, 0.30, 0.0)}
DEMO_PLATFORM = {7: (0.0, 0.0, 0.0), 8: (0.40, 0.0, 0.0), 9: (0.20, 0.30, 0.0)}
# A block hanging at platform height between start and goal: the platform must pass beside
# or under it (its legs stay below the platform).
DEMO_BOXES = ({'center': (0.25, 0.15, 0.90), 'size': (0.15, 0.15, 0.20)},)
DEMO_START = (-0.2, -0.2, 0.85, math.radians(4), math.radians(-3), math.radians(-6))
DEMO_GOAL = (0.3, 0.3, 0.85, math.radians(-3), math.radians(4), math.radians(8))
DEMO_BOUNDS = {'position_min': (-0.25, -0.3, 0.45), 'position_max': (0.4, 0.4, 1.1),
               'angle_max_deg': 30.0}
#: Demo leg-length limits (m): the legs' actuator stroke.
DEMO_LEG_LIMITS = (0.35, 1.55)
#: Metres per radian when angles and positions are compared (metric, bounds margins).
ANGLE_SCALE = 0.5
_DERIVED = 1000        # first label of the derived points of the leg-leg contacts
_CHUNK = 1 << 12
#: Contact kind -> the construct of the paper (:data:`voronoi_pkg.planar.CONSTRUCTS`) that
#: ``without`` switches off. Leg-leg contacts (self-collision) stay: no obstacle decides them.
_CONSTRUCT_OF = {'singularity': 'singularity', 'collision': 'collision',
                 'containment': 'collision'}
_SMALL = 256     # below this batch size the flat evaluator is faster


def rpy_matrix(rpy: ArrayLike) -> np.ndarray:
    """Rotation matrices ``(..., 3, 3)`` of ZYX Euler angles ``(..., 3)`` = roll, pitch, yaw."""
    rpy = np.asarray(rpy, dtype=float)
    cr, sr = np.cos(rpy[..., 0]), np.sin(rpy[..., 0])
    cp, sp = np.cos(rpy[..., 1]), np.sin(rpy[..., 1])
    cy, sy = np.cos(rpy[..., 2]), np.sin(rpy[..., 2])
    return np.stack([
        np.stack([cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr], axis=-1),
        np.stack([sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr], axis=-1),
        np.stack([-sp, cp * sr, cp * cr], axis=-1)], axis=-2)


#: Faces of an axis-aligned box over its corners (index bits x, y, z), counter-clockwise seen
#: from outside (outward normals).
_BOX_QUADS = ((0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4),
              (1, 5, 7, 3))


def box_mesh(center: ArrayLike, size: ArrayLike) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Vertices (8, 3), quadrilateral faces (6, 4) with outward counter-clockwise order, edges
    (12, 2)."""
    c = np.asarray(center, dtype=float)
    h = 0.5 * np.asarray(size, dtype=float)
    corners = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)])
    verts = c + corners * h
    edges = sorted({tuple(sorted(e)) for a, b, cc, d in _BOX_QUADS
                    for e in ((a, b), (b, cc), (cc, d), (d, a))})
    return verts, np.array(_BOX_QUADS), np.array(edges)


def segment_pierces_face(a: int, b: int, face: Sequence[int]) -> And:
    """Segment ab crosses the convex planar polygon ``face`` (labels, counter-clockwise).

    Section 3's segment-triangle contact for a convex polygon: a and b on opposite sides of the
    face plane (``[a f0 f1 f2]``, ``[b f0 f1 f2]``) and the line ab on the same side of every
    edge line (``[a b f_i f_i+1]`` all positive or all negative). One contact per face (not per
    triangle), so the two halves of a quadrilateral never tie identically.
    """
    f = tuple(face)
    plane = f[:3]
    sides = [Delta(a, b, f[i], f[(i + 1) % len(f)]) for i in range(len(f))]
    return And(Xor(Delta(a, *plane), Delta(b, *plane)),
               Or(And(*sides), And(*(Not(e) for e in sides))))


def point_inside_box(p: int, faces: Iterable[Sequence[int]]) -> And:
    """Point p strictly inside the convex polyhedron with outward counter-clockwise ``faces``:
    ``[f0 f1 f2 p] > 0`` for every face (``[f0 f1 f2 p] = -(p - f0) . n_out``)."""
    return And(*(Delta(f[0], f[1], f[2], p) for f in faces))


def segments_meet(a: int, b: int, c: int, d: int, e1: int, e2: int) -> tuple[And, Or]:
    """Two segments ab, cd in space pass through each other: coplanar (``[a b c d] = 0``) and
    crossing in the projection along their common normal (derived points ``e1`` on the normal
    through a, ``e2`` through c). Returns ``(cross, free)``: the crossing predicate and the
    free predicate ``NOT cross OR [a b c d] != 0``."""
    cross = And(Xor(Delta(c, d, a, e2), Delta(c, d, b, e2)),
                Xor(Delta(a, b, c, e1), Delta(a, b, d, e1)))
    return cross, Or(Not(cross), Or(Delta(a, b, c, d), Not(Delta(a, b, c, d))))


def robot_segment_pairs() -> tuple[tuple[tuple[int, int], tuple[int, int]], ...]:
    """Legs and platform edges that share no attachment point (the leg-leg contacts)."""
    segs = list(LEGS) + list(PLATFORM_EDGES)
    out = []
    for i, s in enumerate(segs):
        for t in segs[i + 1:]:
            if set(s) & set(t) or (s in PLATFORM_EDGES and t in PLATFORM_EDGES):
                continue
            out.append((s, t))
    return tuple(out)


class FlatContacts:
    """All contacts of a compiled rho program evaluated level by level with numpy.

    The same min/max tree as :class:`~voronoi_pkg.distance.RhoProgram` (same values;
    ties resolve to the first child, as there), flattened so that every node of one height
    and operation is one ``reduceat``: a few dozen array operations per batch instead of one
    per node, and all 4x4 determinants in one vectorised expression.
    """

    def __init__(self, program: RhoProgram, labels: Iterable[int]) -> None:
        self.labels = list(labels)
        where = {lab: i for i, lab in enumerate(self.labels)}
        self.key_idx = np.array([[where[lab] for lab in key] for key in program.keys])
        leaves = program.leaves
        self.leaf_key = np.array([k for k, _ in leaves])
        self.leaf_sign = np.array([float(sg) for _, sg in leaves])
        self.leaf_code = (2 * self.leaf_key + (self.leaf_sign > 0)).astype(np.int32)
        n_leaf = len(leaves)
        nodes = []                       # (op, child ids), ids >= n_leaf
        height = {}

        def visit(node):
            if isinstance(node, (int, np.integer)):
                return int(node), 0
            kids = [visit(c) for c in node.children]
            nid = n_leaf + len(nodes)
            nodes.append((node.op, [k for k, _ in kids]))
            height[nid] = 1 + max(h for _, h in kids)
            return nid, height[nid]

        self.roots = np.array([visit(c)[0] for c in program.root.children])
        self.n_nodes = n_leaf + len(nodes)
        groups = {}
        for i, (op, kids) in enumerate(nodes):
            nid = n_leaf + i
            groups.setdefault((height[nid], op), []).append((nid, kids))
        self.groups = []
        for (_, op), items in sorted(groups.items()):
            ids = np.array([nid for nid, _ in items])
            kids = np.concatenate([np.array(k) for _, k in items])
            counts = np.array([len(k) for _, k in items])
            starts = np.r_[0, np.cumsum(counts)[:-1]]
            self.groups.append((op == 'min', ids, kids, starts, counts))

    def determinants(self, P: np.ndarray) -> np.ndarray:
        """All determinants ``(n_keys, n)`` from the point array ``P`` (n_labels, n, 3)."""
        if P.shape[1] >= _SMALL:            # row by row: no (n_keys, n, 3) temporaries
            return np.stack([bracket4(*(P[i] for i in row)) for row in self.key_idx])
        a, b, c, d = (P[self.key_idx[:, i]] for i in range(4))
        u, v, w = b - a, c - a, d - a
        return -(u[..., 0] * (v[..., 1] * w[..., 2] - v[..., 2] * w[..., 1])
                 + u[..., 1] * (v[..., 2] * w[..., 0] - v[..., 0] * w[..., 2])
                 + u[..., 2] * (v[..., 0] * w[..., 1] - v[..., 1] * w[..., 0]))

    def evaluate(self, dets: np.ndarray,
                 codes: bool = True) -> tuple[np.ndarray, np.ndarray | None]:
        """Values ``(n_contacts, n)`` and (if ``codes``) active-leaf codes of the contacts."""
        n = dets.shape[1]
        vals = np.empty((self.n_nodes, n))
        n_leaf = len(self.leaf_key)
        vals[:n_leaf] = self.leaf_sign[:, None] * dets[self.leaf_key]
        code = None
        if codes:
            code = np.empty((self.n_nodes, n), dtype=np.int32)
            code[:n_leaf] = self.leaf_code[:, None]
        for is_min, ids, kids, starts, counts in self.groups:
            cv = vals[kids]
            red = (np.minimum if is_min else np.maximum).reduceat(cv, starts, axis=0)
            vals[ids] = red
            if codes:
                eq = cv == np.repeat(red, counts, axis=0)
                pos = np.where(eq, np.arange(len(kids))[:, None], len(kids))
                first = np.minimum.reduceat(pos, starts, axis=0)
                code[ids] = np.take_along_axis(code[kids], first, axis=0)
        return vals[self.roots], (code[self.roots] if codes else None)


@dataclass(frozen=True)
class Contact:
    """One factor of the fused AND tree, with the words used in error messages."""

    name: str
    kind: str          # 'singularity', 'collision', 'containment', 'leg-leg'
    tree: object


@dataclass
class Spatial321Model:
    """3-2-1 platform, obstacle boxes, leg-length limits and the fused predicate.

    ``leg_limits`` is ``(min, max)`` leg length in m, or None for no limit. ``without``:
    constructs of the paper switched off (ablation, names of
    :data:`voronoi_pkg.planar.CONSTRUCTS`): their contacts are left out of rho.
    """

    base: dict
    platform: dict
    boxes: tuple
    position_min: tuple
    position_max: tuple
    angle_max: float
    leg_limits: tuple = None
    angle_scale: float = ANGLE_SCALE
    contacts: list = field(default_factory=list)
    without: tuple = ()

    def __post_init__(self):
        # Ablations, checked by the planar planner's rule: 'singularity' leaves out the three
        # pure-condition factors (rho, certificate and the sign-change check), 'collision' the
        # robot-obstacle contacts (segment-face, box edge-platform, containment).
        self.without = check_without(self.without)
        self.fixed = {k: np.asarray(v, dtype=float) for k, v in self.base.items()}
        self.moving = {k: np.asarray(v, dtype=float) for k, v in self.platform.items()}
        if self.leg_limits is not None:
            lo, hi = (float(v) for v in self.leg_limits)
            if not (0 <= lo < hi and math.isfinite(hi)):
                raise UserError(f'leg length limits {self.leg_limits}: need 0 <= min < max')
            self.leg_limits = (lo, hi)
        tri = [self.moving[k] for k in (7, 8, 9)]
        area2 = float(np.linalg.norm(np.cross(tri[1] - tri[0], tri[2] - tri[0])))
        if not area2 > 0:
            raise UserError('platform points 7, 8, 9 must form a triangle')
        self.area2 = area2                      # s**2 of the module docstring
        self.derived_length = math.sqrt(area2)  # s: distance of e1, e2 from the segment
        contacts = [Contact(
            f'singularity: [p{a} p{b} p{c} p{d}] = 0 (tetrahedron P{a}P{b}P{c}P{d} flat)',
            'singularity', pure_condition_free([(a, b, c, d)]))
            for a, b, c, d in PURE_CONDITION]
        self.meshes = []
        label = 10
        for n, box in enumerate(self.boxes):
            verts, quads, edges = box_mesh(box['center'], box['size'])
            lo, hi = verts.min(axis=0), verts.max(axis=0)
            for k, v in self.fixed.items():
                if np.all(v >= lo) and np.all(v <= hi):
                    raise UserError(f'box {n} contains or touches base point P{k} '
                                    f'{np.round(v, 4).tolist()}: its leg could never be free')
            labels = list(range(label, label + 8))
            label += 8
            for lab, v in zip(labels, verts):
                self.fixed[lab] = v
            self.meshes.append((verts, quads, edges))
            faces = [tuple(labels[i] for i in q) for q in quads]
            edge_l = [tuple(labels[i] for i in e) for e in edges]
            for a, b in LEGS + PLATFORM_EDGES:
                part = f'leg P{a}P{b}' if (a, b) in LEGS else f'platform edge P{a}P{b}'
                for fi, face in enumerate(faces):
                    contacts.append(Contact(f'collision: {part} crosses face {fi} of box {n}',
                                            'collision', Not(segment_pierces_face(a, b, face))))
            for ei, (a, b) in enumerate(edge_l):
                contacts.append(Contact(
                    f'collision: edge {ei} of box {n} crosses the platform P7P8P9',
                    'collision', Not(segment_pierces_triangle(a, b, 7, 8, 9))))
            for k in (7, 8, 9):
                contacts.append(Contact(f'containment: platform vertex P{k} inside box {n}',
                                        'containment', Not(point_inside_box(k, faces))))
        self.segment_pairs = robot_segment_pairs()
        self.cross_programs = []
        for i, ((a, b), (c, d)) in enumerate(self.segment_pairs):
            e1, e2 = _DERIVED + 2 * i, _DERIVED + 2 * i + 1
            cross, free = segments_meet(a, b, c, d, e1, e2)
            contacts.append(Contact(f'leg-leg: P{a}P{b} passes through P{c}P{d}', 'leg-leg',
                                    free))
            self.cross_programs.append(compile_rho(cross))
        contacts = [c for c in contacts if _CONSTRUCT_OF.get(c.kind) not in self.without]
        self.contacts = contacts
        self.tree = fuse(*[c.tree for c in contacts])
        self.program = compile_rho(self.tree)
        # Each contact compiles to one child (a max node) of the root min node, in order.
        assert len(self.program.root.children) == len(contacts)
        fixed_labels = sorted(self.fixed)
        self._fixed_arr = np.array([self.fixed[k] for k in fixed_labels])
        self._moving_arr = np.array([self.moving[k] for k in (7, 8, 9)])
        self.labels = fixed_labels + [7, 8, 9] + list(range(
            _DERIVED, _DERIVED + 2 * len(self.segment_pairs)))
        where = {lab: i for i, lab in enumerate(self.labels)}
        self._pair_idx = np.array([[where[k] for k in s + t] for s, t in self.segment_pairs])
        self.flat = FlatContacts(self.program, self.labels)
        self.contact_programs = [compile_rho(c.tree) for c in contacts]
        self.singular_keys = ([] if 'singularity' in self.without
                              else [tuple(sorted(f)) for f in PURE_CONDITION])
        self.coplanar_keys = [tuple(sorted(s + t)) for s, t in self.segment_pairs]
        self.extra_names = self._extra_names()
        span = float(np.linalg.norm(np.subtract(self.position_max, self.position_min)))
        self.free_tol = 1e-9 * span ** 3     # 4x4 brackets are volumes

    def _extra_names(self):
        names = []
        for axis, ch in enumerate('xyz'):
            names += [f'bounds: {ch} >= {self.position_min[axis]:g} m',
                      f'bounds: {ch} <= {self.position_max[axis]:g} m']
        for ch in ('roll', 'pitch', 'yaw'):
            names += [f'bounds: {ch} >= -{math.degrees(self.angle_max):g} deg',
                      f'bounds: {ch} <= {math.degrees(self.angle_max):g} deg']
        if self.leg_limits is not None:
            for a, b in LEGS:
                names += [f'leg length: |P{a}P{b}| >= {self.leg_limits[0]:g} m',
                          f'leg length: |P{a}P{b}| <= {self.leg_limits[1]:g} m']
        return names

    # -- geometry ------------------------------------------------------------------------------
    def point_array(self, q: ArrayLike) -> np.ndarray:
        """All labelled points at poses ``q`` (n, 6) as one array ``(n_labels, n, 3)`` in the
        order of ``self.labels``: fixed (base, box corners), platform, derived."""
        q = np.asarray(q, dtype=float).reshape(-1, 6)
        n = len(q)
        rot = rpy_matrix(q[:, 3:6])
        moving = q[None, :, :3] + np.einsum('nij,kj->kni', rot, self._moving_arr)
        fixed = np.broadcast_to(self._fixed_arr[:, None, :], (len(self._fixed_arr), n, 3))
        P = np.concatenate([fixed, moving, np.empty((2 * len(self.segment_pairs), n, 3))])
        a, b, c, d = (P[self._pair_idx[:, i]] for i in range(4))
        u, v = b - a, d - c
        nrm = np.stack([u[..., 1] * v[..., 2] - u[..., 2] * v[..., 1],
                        u[..., 2] * v[..., 0] - u[..., 0] * v[..., 2],
                        u[..., 0] * v[..., 1] - u[..., 1] * v[..., 0]], axis=-1)
        length = np.sqrt(np.einsum('pni,pni->pn', nrm, nrm))[..., None]
        nrm = np.divide(nrm, length, out=np.zeros_like(nrm), where=length > 0)
        nrm *= self.derived_length
        k0 = len(self._fixed_arr) + 3
        P[k0::2] = a + nrm
        P[k0 + 1::2] = c + nrm
        return P

    def points(self, q: ArrayLike, P: np.ndarray | None = None) -> dict[int, np.ndarray]:
        """Labelled points at poses ``q`` (..., 6): base, box corners, platform, derived."""
        q = np.asarray(q, dtype=float)
        P = self.point_array(q) if P is None else P
        shape = q.shape[:-1] + (3,)
        return {lab: P[i].reshape(shape) for i, lab in enumerate(self.labels)}

    def extra_values(self, q: ArrayLike,
                     pts: Mapping[int, np.ndarray] | None = None) -> np.ndarray:
        """Bounds and leg-length margins ``(n_extra, ...)`` (positive = satisfied)."""
        q = np.asarray(q, dtype=float)
        rows = []
        for axis in range(3):
            rows += [q[..., axis] - self.position_min[axis],
                     self.position_max[axis] - q[..., axis]]
        for axis in range(3, 6):
            rows += [(self.angle_max + q[..., axis]) * self.angle_scale,
                     (self.angle_max - q[..., axis]) * self.angle_scale]
        if self.leg_limits is not None:
            pts = self.points(q) if pts is None else pts
            for a, b in LEGS:
                length = np.linalg.norm(pts[b] - pts[a], axis=-1)
                rows += [length - self.leg_limits[0], self.leg_limits[1] - length]
        return np.stack(rows) * self.area2

    def _chunked(self, q, fn, dtypes):
        q = np.asarray(q, dtype=float)
        flat = q.reshape(-1, 6)
        outs = [np.empty((len(flat),) + shape, dtype=dt) for dt, shape in dtypes]
        for s in range(0, len(flat), _CHUNK):
            part = fn(flat[s:s + _CHUNK])
            part = part if isinstance(part, tuple) else (part,)
            for o, p in zip(outs, part):
                o[s:s + _CHUNK] = p
        outs = [np.moveaxis(o, 0, -1).reshape(o.shape[1:] + q.shape[:-1]) for o in outs]
        return outs[0] if len(outs) == 1 else tuple(outs)

    def rho(self, q: ArrayLike) -> np.ndarray:
        """rho of the fused predicate (all contacts, bounds, leg limits) at poses (..., 6)."""
        prog = self.program

        def fn(c):
            P = self.point_array(c)
            dets = self.flat.determinants(P)
            if len(c) < _SMALL:
                r = self.flat.evaluate(dets, codes=False)[0].min(axis=0)
            else:
                r = prog.rho(dets)
            return np.minimum(r, self.extra_values(c, self.points(c, P)).min(axis=0))
        return self._chunked(q, fn, [(float, ())])

    def contact_values(self, q: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
        """Per contact: value and active leaf, ``(n_contacts, ...)`` each.

        Contacts are the root's children (the fused factors) followed by the bounds and
        leg-length margins; a leaf is ``(determinant index, sign)`` coded as ``2 * index +
        (sign > 0)``, bounds and leg limits get codes past the determinants'. Two contacts tie
        only if their values are equal AND their active leaves differ (the same determinant
        deciding two contacts, e.g. a box edge shared by two faces, is one feature).
        """
        n_det = len(self.program.keys)
        n_extra = len(self.extra_names)

        def fn(c):
            P = self.point_array(c)
            dets = self.flat.determinants(P)
            if len(c) < _SMALL:
                vals, codes = self.flat.evaluate(dets)
            else:
                vals, codes = self.program.contact_values(dets)
            extra = self.extra_values(c, self.points(c, P))
            ecodes = 2 * n_det + np.arange(n_extra, dtype=np.int32)[:, None]
            return (np.concatenate([vals, extra]).T,
                    np.concatenate([codes, np.broadcast_to(ecodes, extra.shape)]).T)
        n = len(self.contacts) + n_extra
        return self._chunked(q, fn, [(float, (n,)), (np.int32, (n,))])

    def contact_names(self) -> list[str]:
        """Readable name of each row of :meth:`contact_values`."""
        return [c.name for c in self.contacts] + list(self.extra_names)

    def singular_signs(self, q: ArrayLike) -> np.ndarray:
        """Signs of the pure-condition determinants, ``(n_singular, ...)`` of -1/0/+1."""
        if not self.singular_keys:                  # singularities switched off
            return np.zeros((0,) + np.shape(q)[:-1])
        return np.sign(evaluate_determinants(self.singular_keys, self.points(q)))

    def thin_state(self, q: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
        """Sign of ``[a b c d]`` and the projected crossing of every leg-leg pair, (pairs, ...).

        Passing through each other between two poses = the sign changes while the projections
        cross at either pose (the contact is a hypersurface that point samples step over).
        """
        pts = self.points(q)
        signs = np.sign(evaluate_determinants(self.coplanar_keys, pts))
        cross = np.stack([p.rho(evaluate_determinants(p.keys, pts)) > 0
                          for p in self.cross_programs])
        return signs, cross

    def diagnose(self, q: ArrayLike) -> list[tuple[str, float]]:
        """Names and values of every violated contact, bound and leg limit at one pose."""
        q = np.asarray(q, dtype=float).reshape(6)
        pts = self.points(q)
        out = []
        for contact, prog in zip(self.contacts, self.contact_programs):
            v = float(prog.rho(evaluate_determinants(prog.keys, pts)))
            if not v > self.free_tol:
                out.append((contact.name, v))
        for name, v in zip(self.extra_names, self.extra_values(q, pts)):
            if not v > 0:
                out.append((name, float(v)))
        return out

    def in_bounds(self, q: ArrayLike) -> np.ndarray:
        q = np.asarray(q, dtype=float)
        return (np.all(q[..., :3] >= self.position_min, axis=-1)
                & np.all(q[..., :3] <= self.position_max, axis=-1)
                & np.all(np.abs(q[..., 3:]) <= self.angle_max, axis=-1))

    def leg_lengths(self, q: ArrayLike) -> np.ndarray:
        """Leg lengths ``(..., 6)`` in the order of :data:`LEGS`."""
        pts = self.points(q)
        return np.stack([np.linalg.norm(pts[b] - pts[a], axis=-1) for a, b in LEGS], axis=-1)

    @property
    def scale(self) -> np.ndarray:
        """Metric weights of (x, y, z, roll, pitch, yaw): metres, and metres per radian."""
        return np.r_[1.0, 1.0, 1.0, [self.angle_scale] * 3]

    def lower(self) -> np.ndarray:
        return np.r_[self.position_min, [-self.angle_max] * 3]

    def upper(self) -> np.ndarray:
        return np.r_[self.position_max, [self.angle_max] * 3]

    def sample(self, rng: np.random.Generator, n: int) -> np.ndarray:
        return rng.uniform(self.lower(), self.upper(), (n, 6))

    def world_points(self, q: ArrayLike) -> dict[int, np.ndarray]:
        """Platform and base points for drawing one pose ``q``."""
        return {k: np.asarray(v) for k, v in self.points(np.asarray(q, dtype=float)).items()}


def demo_model(boxes: Iterable[Mapping[str, Sequence[float]]] = DEMO_BOXES,
               leg_limits: tuple[float, float] | None = DEMO_LEG_LIMITS,
               without: Iterable[str] | None = ()) -> Spatial321Model:
    """The demo scene; ``without``: constructs switched off (ablation)."""
    return Spatial321Model(DEMO_BASE, DEMO_PLATFORM, tuple(boxes), DEMO_BOUNDS['position_min'],
                           DEMO_BOUNDS['position_max'], math.radians(DEMO_BOUNDS['angle_max_deg']),
                           leg_limits, without=tuple(without or ()))


def load_scene(path: str | Path, leg_limits: tuple[float, float] | None = None,
               without: Iterable[str] | None = ()) -> Spatial321Model:
    """Spatial scene JSON: ``boxes`` [{"center": [x, y, z], "size": [sx, sy, sz]}, ...],
    optional ``base`` {"1": [x, y, z], ... "6": ...}, ``platform`` {"7": ..., "8": ...,
    "9": ...} (platform frame, P7 at the origin), ``bounds`` {"position_min", "position_max",
    "angle_max_deg"}, ``leg_length`` {"min": m, "max": m} or null (no limits); missing keys
    take the demo values. ``leg_limits`` (min, max) overrides the file; ``without``: constructs
    switched off (ablation)."""
    path = Path(path)
    data = load_json_object(path, 'scene file')

    def vec(v, what):
        try:
            a = np.asarray(v, dtype=float)
        except (TypeError, ValueError):
            a = None
        if a is None or a.shape != (3,) or not np.all(np.isfinite(a)):
            raise UserError(f'scene file {path}: {what} must be three finite numbers')
        return tuple(a)

    unknown = set(data) - {'boxes', 'base', 'platform', 'bounds', 'leg_length'}
    if unknown:
        raise UserError(f'scene file {path}: unknown keys {sorted(unknown)}')
    boxes = []
    for i, b in enumerate(data.get('boxes', [])):
        if not isinstance(b, dict) or set(b) != {'center', 'size'}:
            raise UserError(f'scene file {path}: box {i} needs exactly "center" and "size"')
        size = vec(b['size'], f'box {i} size')
        if min(size) <= 0:
            raise UserError(f'scene file {path}: box {i} size must be positive')
        boxes.append({'center': vec(b['center'], f'box {i} center'), 'size': size})
    base = {k: vec(data.get('base', {}).get(str(k), v), f'base point {k}')
            for k, v in DEMO_BASE.items()}
    plat = {k: vec(data.get('platform', {}).get(str(k), v), f'platform point {k}')
            for k, v in DEMO_PLATFORM.items()}
    bounds = dict(DEMO_BOUNDS, **data.get('bounds', {}))
    pmin = vec(bounds['position_min'], 'bounds position_min')
    pmax = vec(bounds['position_max'], 'bounds position_max')
    if not np.all(np.less(pmin, pmax)):
        raise UserError(f'scene file {path}: bounds position_min must be below position_max')
    amax = bounds['angle_max_deg']
    if not isinstance(amax, (int, float)) or not 0 < amax <= 90:
        raise UserError(f'scene file {path}: bounds angle_max_deg must be in (0, 90]')
    if leg_limits is None:
        legs = data.get('leg_length', {'min': DEMO_LEG_LIMITS[0], 'max': DEMO_LEG_LIMITS[1]})
        if legs is not None:
            if not isinstance(legs, dict) or set(legs) != {'min', 'max'} or not all(
                    isinstance(legs[k], (int, float)) for k in legs):
                raise UserError(f'scene file {path}: leg_length must be {{"min": m, "max": m}} '
                                'or null')
            leg_limits = (legs['min'], legs['max'])
    try:
        return Spatial321Model(base, plat, tuple(boxes), pmin, pmax, math.radians(amax),
                               leg_limits, without=tuple(without or ()))
    except UserError as err:
        raise UserError(f'scene file {path}: {err}') from None


# ---------------------------------------------------------------------------------------------
# Dense path checking
# ---------------------------------------------------------------------------------------------

def densify6(waypoints: ArrayLike, step: float,
             dangle: float) -> tuple[np.ndarray, np.ndarray]:
    """Samples along a 6-D polyline: |d position| <= step, every |d angle| <= dangle."""
    w = np.asarray(waypoints, dtype=float)
    if len(w) < 2:
        return w.copy(), np.zeros(len(w), dtype=np.int64)
    d = np.diff(w, axis=0)
    n = np.maximum(1, np.ceil(np.maximum(np.linalg.norm(d[:, :3], axis=1) / step,
                                         np.max(np.abs(d[:, 3:]), axis=1) / dangle))
                   ).astype(np.int64)
    seg = np.repeat(np.arange(len(d)), n)
    k = np.arange(seg.size) - np.repeat(np.cumsum(n) - n, n)
    samples = np.vstack([w[seg] + (k / n[seg])[:, None] * d[seg], w[-1:]])
    return samples, np.r_[seg, len(d) - 1]


def bad_samples(model: Spatial321Model,
                samples: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per consecutive sample pair of a dense polyline: refused? ``(n - 1,)`` bool.

    A pair is refused if either sample has rho <= free_tol (contact, containment, bounds, leg
    limit), a pure-condition determinant changes sign or vanishes (singularity crossed), or two
    legs pass through each other (``[a b c d]`` changes sign while their projections cross).
    """
    rho = model.rho(samples)
    signs = model.singular_signs(samples)
    thin, cross = model.thin_state(samples)
    bad_pt = (rho <= model.free_tol) | np.any(signs == 0, axis=0)
    bad = bad_pt[1:] | bad_pt[:-1] | np.any(signs[:, 1:] != signs[:, :-1], axis=0)
    bad |= np.any((thin[:, 1:] != thin[:, :-1]) & (cross[:, 1:] | cross[:, :-1]), axis=0)
    return bad, rho


def check_path6(model: Spatial321Model, waypoints: ArrayLike, step: float = 0.005,
                dangle: float = 0.01) -> tuple[bool, float, np.ndarray]:
    """Dense check of a 6-D polyline: ``(ok, min_rho, bad segment indices)``."""
    samples, seg = densify6(waypoints, step, dangle)
    if len(samples) < 2:
        rho = model.rho(samples)
        return bool(np.all(rho > model.free_tol)), float(rho.min()), np.zeros(0, np.int64)
    bad, rho = bad_samples(model, samples)
    return (not bad.any()), float(rho.min()), np.unique(seg[:-1][bad])


def validate_pose(model: Spatial321Model, q: ArrayLike, name: str) -> None:
    q = np.asarray(q, dtype=float)
    if q.shape != (6,) or not np.all(np.isfinite(q)):
        raise UserError(f'{name}: expected six finite numbers (x, y, z, roll, pitch, yaw)')
    if not model.in_bounds(q):
        raise UserError(f'{name} {np.round(q, 4).tolist()} is outside the planning bounds '
                        f'(position {model.position_min}..{model.position_max} m, angles '
                        f'within +-{math.degrees(model.angle_max):g} deg)')
    failures = model.diagnose(q)
    if failures:
        raise UserError(f'{name} is not free: ' + '; '.join(
            f'{n} (rho = {v + 0.0:.3g})' for n, v in failures))
