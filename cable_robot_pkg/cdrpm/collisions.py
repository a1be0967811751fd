"""Collision detection for cable robots, section III of Aref & Taghirad, vectorised over poses.

Three collision types (plus two geometric facts reported separately, never as collisions):

- **cable-cable** (III-A, eqs. (4)-(7)): the distance between two cable segments A_iB_i and
  A_jB_j is the distance of their closest points M_i, M_j (eq. (4)); the cables collide when it
  is below 2*epsilon. Eqs. (6)-(7) give the closest points of the two *lines*; the paper then
  declares "no collision" whenever a line parameter falls outside its segment, which misses a
  segment end passing within 2*epsilon of the other cable. :func:`segment_distance` computes
  the exact segment-segment distance instead (Eberly's closest-point approach, ref. [18]): the
  minimum of the convex quadratic |M_i - M_j|^2 over the parameter square is either the
  interior solution of eqs. (6)-(7) or lies on one of the four edges, where it is a clamped
  1-D minimum. Parallel cables (eqs. (6)-(7) linearly dependent) have no interior solution
  and are handled by the edges, as the paper's "let k_i = 0" suggests.
  For speed, a pair is first screened with the *line* distance |w . n| / |n| (n = S_i x S_j,
  w = A_i - A_j): the segment distance is never smaller, so a pair whose lines are 2*epsilon
  apart cannot collide and needs no further work. The screen is exact (no false negatives).
  At one shared orientation (a COW) the screen is one matrix product over the positions
  (:class:`_SharedRotationScreen`).
- **cable-body** (III-B, eq. (8)): the point D_i = B_i - delta S_i, on the cable at distance
  delta from B_i, must not be inside the platform box. For attachment points at the box corners
  and 0 < delta < min(2a, 2b, 2h) this is exact: a straight cable leaving a corner of a convex box
  either enters the box right away or never does.
- **cable-workpiece** (III-C): the paper intersects the cable with the workpiece's top plane
  and tests the footprint; that misses cables passing through a side face below the top. Here
  the cable segment is clipped against the workpiece box grown by epsilon (slab method, the
  box-based test of ref. [19]), which includes the paper's top-face case.
- **platform-workpiece**: the platform box itself overlapping the workpiece (separating-axis
  test); not in the paper, reported as its own type.
- **outside frame**: the platform box is not inside the fixed frame; such a pose is reported as
  outside and not tested for collisions.
"""
from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike

from cable_robot_pkg.cdrpm.kinematics import (
    FRAME_TOL,
    MIN_CABLE_LENGTH,
    as_pose_arrays,
    platform_extent,
)
from paramotion.backend import resolve_backend

if TYPE_CHECKING:
    from cable_robot_pkg.cdrpm.description import RobotDescription

#: Collision types, in the order of the bit flags of :func:`classify_poses`.
COLLISION_TYPES = ('cable_cable', 'cable_body', 'cable_workpiece', 'platform_workpiece')
OUTSIDE = 1
CABLE_CABLE = 2
CABLE_BODY = 4
CABLE_WORKPIECE = 8
PLATFORM_WORKPIECE = 16
FLAG_OF_TYPE = {'cable_cable': CABLE_CABLE, 'cable_body': CABLE_BODY,
                'cable_workpiece': CABLE_WORKPIECE, 'platform_workpiece': PLATFORM_WORKPIECE}
#: Constructs that ``without`` can switch off (ablation): the three collision checks of
#: section III, and the workpiece's side faces (leaving the paper's top-plane projection).
CONSTRUCTS = ('cable_cable', 'cable_body', 'cable_workpiece', 'workpiece_sides')

#: Slack (m) inside the platform box before D_i counts as inside (a cable lying along a face
#: grazes the box without entering it).
BODY_TOL = 1e-12
#: Relative slack of the line-distance screen, so that rounding never drops a candidate.
SCREEN_SLACK = 1e-9
#: Default number of poses processed at once (working set ~ 2 MB per 1000 poses for 8 cables).
DEFAULT_CHUNK = 2048


def _dot(u, v):
    return u[..., 0] * v[..., 0] + u[..., 1] * v[..., 1] + u[..., 2] * v[..., 2]


def _cross(u, v):
    return np.stack([u[..., 1] * v[..., 2] - u[..., 2] * v[..., 1],
                     u[..., 2] * v[..., 0] - u[..., 0] * v[..., 2],
                     u[..., 0] * v[..., 1] - u[..., 1] * v[..., 0]], axis=-1)


def segment_distance(p0: ArrayLike, d1: ArrayLike, q0: ArrayLike,
                     d2: ArrayLike) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Exact distance between segments ``p0 + s d1`` and ``q0 + t d2``, s, t in [0, 1].

    Arrays broadcast over leading dimensions, last dimension 3. Returns ``(dist, s, t)``: the
    distance |M_i M_j| of eq. (4) and the segment parameters of the closest points (eq. (5) with
    k_i = s L_i). Works for parallel, collinear, touching and zero-length segments.
    """
    p0, d1, q0, d2 = np.broadcast_arrays(*(np.asarray(x, dtype=float) for x in (p0, d1, q0, d2)))
    r = p0 - q0
    a = _dot(d1, d1)
    e = _dot(d2, d2)
    b = _dot(d1, d2)
    c = _dot(d1, r)
    f = _dot(d2, r)
    safe_a = np.where(a > 0, a, 1.0)
    safe_e = np.where(e > 0, e, 1.0)
    cands = []
    # Edges of the parameter square: clamped 1-D minima (exact for a convex quadratic).
    t_s0 = np.where(e > 0, np.clip(f / safe_e, 0.0, 1.0), 0.0)
    t_s1 = np.where(e > 0, np.clip((f + b) / safe_e, 0.0, 1.0), 0.0)
    s_t0 = np.where(a > 0, np.clip(-c / safe_a, 0.0, 1.0), 0.0)
    s_t1 = np.where(a > 0, np.clip((b - c) / safe_a, 0.0, 1.0), 0.0)
    zeros, ones = np.zeros_like(a), np.ones_like(a)
    cands += [(zeros, t_s0), (ones, t_s1), (s_t0, zeros), (s_t1, ones)]
    # Interior stationary point of eqs. (6)-(7), written with cross products so that it has no
    # cancellation: s = -(r x d2).n / |n|^2, t = -(r x d1).n / |n|^2 with n = d1 x d2.
    n = _cross(d1, d2)
    nn = _dot(n, n)
    regular = nn > 1e-24 * a * e
    safe_nn = np.where(regular, nn, 1.0)
    s_in = -_dot(_cross(r, d2), n) / safe_nn
    t_in = -_dot(_cross(r, d1), n) / safe_nn
    inside = regular & (s_in >= 0) & (s_in <= 1) & (t_in >= 0) & (t_in <= 1)
    cands.append((np.where(inside, s_in, 0.0), np.where(inside, t_in, 0.0)))
    best = best_s = best_t = None
    for idx, (s, t) in enumerate(cands):
        diff = r + s[..., None] * d1 - t[..., None] * d2
        dist = np.sqrt(_dot(diff, diff))
        if idx == len(cands) - 1:
            dist = np.where(inside, dist, np.inf)
        if best is None:
            best, best_s, best_t = dist, s, t
        else:
            better = dist < best
            best = np.where(better, dist, best)
            best_s = np.where(better, s, best_s)
            best_t = np.where(better, t, best_t)
    return best, best_s, best_t


def segment_box_hit(p0: np.ndarray, d: np.ndarray, lo: ArrayLike,
                    hi: ArrayLike) -> np.ndarray:
    """True where segment ``p0 + t d`` (t in [0, 1]) meets the open box (lo, hi) (slab method)."""
    t_enter = np.zeros(p0.shape[:-1])
    t_exit = np.ones(p0.shape[:-1])
    hit = np.ones(p0.shape[:-1], dtype=bool)
    with np.errstate(divide='ignore', invalid='ignore'):
        for k in range(3):
            dk = d[..., k]
            pk = p0[..., k]
            flat = np.abs(dk) < 1e-15
            t1 = (lo[k] - pk) / np.where(flat, 1.0, dk)
            t2 = (hi[k] - pk) / np.where(flat, 1.0, dk)
            t_lo = np.where(flat, -np.inf, np.minimum(t1, t2))
            t_hi = np.where(flat, np.inf, np.maximum(t1, t2))
            hit &= ~flat | ((pk > lo[k]) & (pk < hi[k]))
            t_enter = np.maximum(t_enter, t_lo)
            t_exit = np.minimum(t_exit, t_hi)
    return hit & (t_enter < t_exit)


def obb_aabb_overlap(centres: ArrayLike, rotations: ArrayLike, half: ArrayLike,
                     lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """True where the oriented platform box overlaps the axis-aligned box [lo, hi] (SAT)."""
    centres = np.atleast_2d(centres)
    rot = np.broadcast_to(rotations, (centres.shape[0], 3, 3))
    box_c = (lo + hi) / 2
    box_e = (hi - lo) / 2
    delta = centres - box_c
    world = np.eye(3)
    axes = [world[k] for k in range(3)]
    axes += [rot[:, :, k] for k in range(3)]
    axes += [np.cross(world[i], rot[:, :, k]) for i in range(3) for k in range(3)]
    overlap = np.ones(centres.shape[0], dtype=bool)
    for axis in axes:
        axis = np.broadcast_to(axis, centres.shape)
        proj_obb = sum(np.abs(_dot(axis, rot[:, :, k])) * half[k] for k in range(3))
        proj_aabb = np.abs(axis) @ box_e
        separated = np.abs(_dot(axis, delta)) > proj_obb + proj_aabb + 1e-12
        overlap &= ~separated
    return overlap


@dataclass
class PoseCheck:
    """Detailed collision report of one pose (used by the ROS node and the CLI)."""

    inside_frame: bool
    lengths: np.ndarray            # (n,) cable lengths
    pair_distance: np.ndarray      # (P,) segment distances of the checked pairs
    pairs: np.ndarray              # (P, 2) cable indices of the checked pairs
    colliding_pairs: list[tuple[int, int, float]]  # closer than 2*epsilon
    body_cables: list[int]         # cables whose D_i is inside the platform
    workpiece_cables: list[int]    # cables through the workpiece
    platform_workpiece: bool
    clearance: np.ndarray          # (n,) per cable: min surface gap to any other cable (m)

    @property
    def collision_free(self) -> bool:
        """True when the pose is inside the frame and has no collision of any type."""
        return (self.inside_frame and not self.colliding_pairs and not self.body_cables
                and not self.workpiece_cables and not self.platform_workpiece)


def _body_flags(desc, d, lengths, rotations):
    """Eq. (8): cables whose point D_i = B_i - delta S_i lies inside the platform, (m, n)."""
    safe = np.where(lengths < MIN_CABLE_LENGTH, 1.0, lengths)
    if rotations.ndim == 2:
        local = d @ rotations          # R^T (B_i - A_i) in platform coordinates
    else:
        local = np.einsum('mnk,mkj->mnj', d, rotations)
    d_local = desc.platform_points[None] - desc.body_delta * local / safe[..., None]
    limit = desc.platform_half_size - BODY_TOL
    return np.all(np.abs(d_local) < limit, axis=-1)


def _cable_pair_flags(desc, d):
    """Cable-cable collisions of a chunk: (m, P) boolean, pairs (desc.pair_i, desc.pair_j)."""
    pi, pj = desc.pair_i, desc.pair_j
    two_eps = 2.0 * desc.cable_radius
    flags = np.zeros((d.shape[0], pi.size), dtype=bool)
    if pi.size == 0 or two_eps == 0.0:
        return flags
    w = desc.frame_points[pi] - desc.frame_points[pj]             # (P, 3), A_i - A_j
    dx, dy, dz = d[..., 0], d[..., 1], d[..., 2]
    ix, iy, iz = dx[:, pi], dy[:, pi], dz[:, pi]
    jx, jy, jz = dx[:, pj], dy[:, pj], dz[:, pj]
    nx = iy * jz - iz * jy
    ny = iz * jx - ix * jz
    nz = ix * jy - iy * jx
    wn = w[:, 0] * nx + w[:, 1] * ny + w[:, 2] * nz
    nn = nx * nx + ny * ny + nz * nz
    # Line distance^2 = wn^2 / nn; a candidate has it below (2 eps)^2 (parallel lines: nn = 0).
    cand = wn * wn <= (two_eps * two_eps) * nn * (1.0 + SCREEN_SLACK)
    return _exact_pairs(desc, d, cand)


def _exact_pairs(desc, d, cand):
    """Exact segment-distance test of the candidate (pose, pair) entries of ``cand`` (m, P)."""
    pi, pj = desc.pair_i, desc.pair_j
    flags = np.zeros(cand.shape, dtype=bool)
    rows, cols = np.nonzero(cand)
    if rows.size:
        dist, _, _ = segment_distance(desc.frame_points[pi[cols]], d[rows, pi[cols]],
                                      desc.frame_points[pj[cols]], d[rows, pj[cols]])
        flags[rows, cols] = dist < 2.0 * desc.cable_radius
    return flags


class _SharedRotationScreen:
    """Line-distance screen for many positions at one orientation (a COW), via one matmul.

    With d_i = g + c_i (c_i = R b_i - a_i constant), n = d_i x d_j = g x dc + m0 with
    dc = c_j - c_i and m0 = c_i x c_j, so w.n = g.(dc x w) + w.m0 is affine in g and
    |n|^2 = |g|^2 |dc|^2 - (g.dc)^2 + 2 g.(dc x m0) + |m0|^2 is quadratic in g. The expansion
    loses a few ulps to cancellation, so the screen keeps a small absolute slack; it stays
    conservative (every colliding pair remains a candidate) and the exact test decides.
    """

    def __init__(self, desc, rot):
        pi, pj = desc.pair_i, desc.pair_j
        c = desc.platform_points @ rot.T - desc.frame_points
        w = desc.frame_points[pi] - desc.frame_points[pj]
        dc = c[pj] - c[pi]
        m0 = np.cross(c[pi], c[pj])
        self.lin = np.concatenate([np.cross(dc, w), dc, np.cross(dc, m0)], axis=0).T
        self.wm0 = np.einsum('pk,pk->p', w, m0)
        self.dc2 = np.einsum('pk,pk->p', dc, dc)
        self.m02 = np.einsum('pk,pk->p', m0, m0)
        self.count = pi.size
        self.limit = (2.0 * desc.cable_radius) ** 2

    def candidates(self, pos):
        """(m, P) boolean: pairs whose lines come within 2 eps (or are parallel)."""
        p = self.count
        prod = pos @ self.lin                        # (m, 3P): g.(dc x w), g.dc, g.(dc x m0)
        wn = prod[:, :p] + self.wm0
        gdc = prod[:, p:2 * p]
        gg = np.einsum('mk,mk->m', pos, pos)[:, None]
        nn = gg * self.dc2 - gdc * gdc + 2.0 * prod[:, 2 * p:] + self.m02
        return wn * wn <= self.limit * (np.abs(nn) * (1.0 + SCREEN_SLACK) + 1e-9)


def check_without(without: Iterable[str] | None) -> frozenset[str]:
    """Validated set of construct names to switch off (see :data:`CONSTRUCTS`)."""
    names = frozenset(without or ())
    unknown = sorted(names - set(CONSTRUCTS))
    if unknown:
        raise ValueError(f'without: unknown construct {unknown[0]!r} '
                         f'(known: {", ".join(CONSTRUCTS)})')
    return names


def top_plane_hit(p0: ArrayLike, d: ArrayLike, lo: ArrayLike, hi: ArrayLike) -> np.ndarray:
    """The paper's cable-workpiece test (III-C): the point P_i where segment ``p0 + t d``
    crosses the workpiece's top plane z = hi_z, projected on the floor (P'_i), lies inside the
    footprint (lo, hi) in x and y. Misses cables that pass through a side face only."""
    p0 = np.asarray(p0, dtype=float)
    d = np.asarray(d, dtype=float)
    dz = d[..., 2]
    with np.errstate(divide='ignore', invalid='ignore'):
        t = (hi[2] - p0[..., 2]) / np.where(dz == 0.0, 1.0, dz)
    crosses = (dz != 0.0) & (t > 0.0) & (t < 1.0)
    px = p0[..., 0] + t * d[..., 0]
    py = p0[..., 1] + t * d[..., 1]
    return crosses & (px > lo[0]) & (px < hi[0]) & (py > lo[1]) & (py < hi[1])


def classify_poses(desc: RobotDescription, positions: ArrayLike, rotations: ArrayLike,
                   chunk: int = DEFAULT_CHUNK, detail: bool = False, backend: str = 'auto',
                   without: Iterable[str] | None = ()
                   ) -> np.ndarray | tuple[np.ndarray, dict[str, np.ndarray]]:
    """Collision status of N poses as bit flags (uint8, (N,)), processed in chunks.

    Flags: ``OUTSIDE`` (platform not inside the frame; then no other flag is set),
    ``CABLE_CABLE``, ``CABLE_BODY``, ``CABLE_WORKPIECE``, ``PLATFORM_WORKPIECE``. A pose with
    flags == 0 is accessible. With ``detail=True`` also returns per-pose boolean arrays
    ``pairs`` (N, P) and ``body`` (N, n), ``workpiece`` (N, n).
    The result does not depend on ``chunk`` nor on ``backend``: at one shared orientation,
    without a workpiece and without ``detail``, ``'numba'`` (or ``'auto'`` with numba
    installed, see :func:`paramotion.backend.resolve_backend`) runs the compiled kernel of
    :mod:`.collisions_numba`; everything else runs the numpy code below.
    ``without`` names constructs of :data:`CONSTRUCTS` to switch off (an ablation; always the
    numpy code): their flags are never set.
    """
    positions, rotations = as_pose_arrays(positions, rotations)
    without = check_without(without)
    if (not detail and not without and rotations.ndim == 2 and desc.workpiece is None
            and resolve_backend(backend) == 'numba'):
        return _classify_shared_numba(desc, positions, rotations)
    total = positions.shape[0]
    flags = np.zeros(total, dtype=np.uint8)
    extra = None
    if detail:
        extra = {'pairs': np.zeros((total, desc.pair_i.size), dtype=bool),
                 'body': np.zeros((total, desc.n_cables), dtype=bool),
                 'workpiece': np.zeros((total, desc.n_cables), dtype=bool)}
    shared = rotations.ndim == 2
    screen = None
    if shared and desc.pair_i.size and desc.cable_radius > 0:
        screen = _SharedRotationScreen(desc, rotations)
    for start in range(0, total, chunk):
        stop = min(start + chunk, total)
        rot = rotations if shared else rotations[start:stop]
        flags[start:stop], part = _classify_chunk(desc, positions[start:stop], rot, detail,
                                                  screen, without)
        if detail:
            for key, value in part.items():
                extra[key][start:stop] = value
    return (flags, extra) if detail else flags


def _classify_shared_numba(desc, positions, rot):
    """Flags of poses at one orientation by the compiled kernel (same arithmetic as numpy)."""
    from cable_robot_pkg.cdrpm.collisions_numba import classify_shared
    flags = np.empty(positions.shape[0], dtype=np.uint8)
    classify_shared(np.ascontiguousarray(positions), desc.platform_points @ rot.T,
                    platform_extent(desc, rot), desc.frame_half_size + FRAME_TOL,
                    np.ascontiguousarray(desc.frame_points, dtype=float),
                    np.ascontiguousarray(desc.pair_i, dtype=np.int64),
                    np.ascontiguousarray(desc.pair_j, dtype=np.int64),
                    2.0 * desc.cable_radius, SCREEN_SLACK,
                    np.ascontiguousarray(desc.platform_points, dtype=float),
                    float(desc.body_delta), np.ascontiguousarray(rot, dtype=float),
                    desc.platform_half_size - BODY_TOL, MIN_CABLE_LENGTH, flags)
    return flags


def _classify_chunk(desc, pos, rot, detail, screen=None, without=frozenset()):
    """Flags of one chunk of poses (see :func:`classify_poses`)."""
    flags = np.zeros(pos.shape[0], dtype=np.uint8)
    extent = platform_extent(desc, rot)
    inside = np.all(np.abs(pos) + extent <= desc.frame_half_size + FRAME_TOL, axis=-1)
    flags[~inside] = OUTSIDE
    part = {}
    if detail:
        part = {'pairs': np.zeros((pos.shape[0], desc.pair_i.size), dtype=bool),
                'body': np.zeros((pos.shape[0], desc.n_cables), dtype=bool),
                'workpiece': np.zeros((pos.shape[0], desc.n_cables), dtype=bool)}
    idx = np.nonzero(inside)[0]
    if idx.size == 0:
        return flags, part
    pos = pos[idx]
    if rot.ndim == 3:
        rot = rot[idx]
        rb = np.einsum('mij,nj->mni', rot, desc.platform_points)
    else:
        rb = (desc.platform_points @ rot.T)[None]
    d = pos[:, None, :] + rb - desc.frame_points[None]              # A_iB_i, eq. (1)
    lengths = np.sqrt(_dot(d, d))                                    # eq. (2)
    if 'cable_cable' in without:
        pair_flags = np.zeros((idx.size, desc.pair_i.size), dtype=bool)
    elif screen is not None:
        pair_flags = _exact_pairs(desc, d, screen.candidates(pos))
    else:
        pair_flags = _cable_pair_flags(desc, d)
    if 'cable_body' in without:
        body = np.zeros((idx.size, desc.n_cables), dtype=bool)
    else:
        body = _body_flags(desc, d, lengths, rot)
    sub = np.zeros(idx.size, dtype=np.uint8)
    sub[pair_flags.any(axis=1)] |= CABLE_CABLE
    sub[body.any(axis=1)] |= CABLE_BODY
    work = None
    if desc.workpiece is not None:
        lo, hi = desc.workpiece_box
        eps = desc.cable_radius
        a = np.broadcast_to(desc.frame_points[None], d.shape)
        if 'cable_workpiece' in without:
            work = np.zeros(d.shape[:2], dtype=bool)
        elif 'workpiece_sides' in without:
            work = top_plane_hit(a, d, lo - eps, hi + eps)
        else:
            work = segment_box_hit(a, d, lo - eps, hi + eps)
        sub[work.any(axis=1)] |= CABLE_WORKPIECE
        sub[obb_aabb_overlap(pos, rot, desc.platform_half_size, lo, hi)] |= PLATFORM_WORKPIECE
    flags[idx] = sub
    if detail:
        part['pairs'][idx] = pair_flags
        part['body'][idx] = body
        if work is not None:
            part['workpiece'][idx] = work
    return flags, part


def count_flags(flags: ArrayLike) -> dict[str, int]:
    """Counts per outcome of a flag array: total, accessible, outside_frame and per type."""
    flags = np.asarray(flags)
    counts = {'total_points': int(flags.size),
              'accessible_points': int(np.count_nonzero(flags == 0)),
              'outside_frame': int(np.count_nonzero(flags & OUTSIDE))}
    for name, bit in FLAG_OF_TYPE.items():
        counts[name] = int(np.count_nonzero(flags & bit))
    return counts


def check_pose(desc: RobotDescription, position: ArrayLike, rotation: ArrayLike,
               without: Iterable[str] | None = ()) -> PoseCheck:

    """Full report of one pose: lengths, pair distances, which pair or body collides.

    ``without`` switches constructs off as in :func:`classify_poses` (the pair distances and
    clearances are still reported).
    """
    without = check_without(without)
    position = np.asarray(position, dtype=float).reshape(3)
    rotation = np.asarray(rotation, dtype=float).reshape(3, 3)
    b_world = position + desc.platform_points @ rotation.T
    d = b_world - desc.frame_points
    lengths = np.sqrt(_dot(d, d))
    extent = platform_extent(desc, rotation)
    inside = bool(np.all(np.abs(position) + extent <= desc.frame_half_size + FRAME_TOL))
    pi, pj = desc.pair_i, desc.pair_j
    dist, _, _ = segment_distance(desc.frame_points[pi], d[pi], desc.frame_points[pj], d[pj])
    two_eps = 2 * desc.cable_radius
    gap = dist - two_eps
    clearance = np.full(desc.n_cables, np.inf)
    np.minimum.at(clearance, pi, gap)
    np.minimum.at(clearance, pj, gap)
    colliding, body, work, plat = [], [], [], False
    if inside:
        if 'cable_cable' not in without:
            colliding = [(int(i), int(j), float(x)) for i, j, x in zip(pi, pj, dist)
                         if x < two_eps]
        if 'cable_body' not in without:
            body = [int(k) for k in np.nonzero(
                _body_flags(desc, d[None], lengths[None], rotation)[0])[0]]
        if desc.workpiece is not None and 'cable_workpiece' not in without:
            lo, hi = desc.workpiece_box
            eps = desc.cable_radius
            box_test = top_plane_hit if 'workpiece_sides' in without else segment_box_hit
            hits = box_test(desc.frame_points, d, lo - eps, hi + eps)
            work = [int(k) for k in np.nonzero(hits)[0]]
        if desc.workpiece is not None:
            lo, hi = desc.workpiece_box
            plat = bool(obb_aabb_overlap(position[None], rotation, desc.platform_half_size,
                                         lo, hi)[0])
    return PoseCheck(inside_frame=inside, lengths=lengths, pair_distance=dist,
                     pairs=np.stack([pi, pj], axis=1), colliding_pairs=colliding,
                     body_cables=body, workpiece_cables=work, platform_workpiece=plat,
                     clearance=clearance)
