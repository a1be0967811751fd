"""The simplified Voronoi diagram of the planar platform, per orientation slice and connected
across orientation (section 5 of Vaca, Aranda & Thomas; Canny & Donald 1988).

The diagram is the one defined in :mod:`voronoi_pkg.ties` (shared with the 3-2-1 planner):
free configurations where the two smallest *contacts* (children of rho's root min node)
decided by different determinants tie. For a fixed orientation phi every determinant is affine
in (x, y), so each contact is piecewise affine and each slice of the diagram is an arrangement
of straight pieces (the paper's "straight skeleton" remark).

Construction used by the planner (:mod:`voronoi_pkg.planner`):

* :func:`affine_coefficients`: the exact affine form ``A + B x + C y`` of every determinant in
  a slice (all moving points are P3 plus a constant), so grid fields (:func:`slice_fields`)
  and tie points need no per-point geometry;
* :func:`slice_fields`: rho, the smallest contact, the determinant deciding it and the
  singularity cell on an (phi, y, x) grid;
* :func:`diagram_slices`: per slice, a graph whose nodes are the exact tie points
  ``f_A = f_B`` on grid edges whose end vertices (free, same singularity cell) have different
  smallest contacts A and B decided by different determinants (regula falsi on the piecewise
  affine ``f_A - f_B``), kept when they lie on the diagram (:func:`voronoi_pkg.ties.on_diagram`),
  and whose edges are the straight pieces joining the tie points of one grid cell; where
  three or more pieces meet in a cell, the node is the exact vertex ``f_A = f_B = f_C`` (the
  three affine leaves solved), and where that vertex is not on the diagram inside the cell,
  pieces of one contact pair are joined directly and the others end;
* :func:`link_slices`: links between diagram vertices of consecutive slices (nearest of the
  same contact pair, two nearest of any pair, within a radius).

No roadmap edge comes from a free grid edge: the planner searches these pieces and links only.
:func:`tie_segments` draws the same pieces of one slice for figures and markers.
"""
from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike
from scipy.spatial import cKDTree

from voronoi_pkg.ties import on_diagram, tie_tolerance, two_smallest

if TYPE_CHECKING:
    from voronoi_pkg.planar import Domain, PlanarModel

__all__ = ['DiagramSlice', 'SliceFields', 'affine_coefficients', 'contact_evaluator',
           'diagram_mask', 'diagram_slices', 'grid_axes', 'link_slices', 'shifted_pairs',
           'slice_fields', 'tie_segments']


def grid_axes(domain: Domain, h: float) -> tuple[np.ndarray, np.ndarray]:
    """Grid coordinates covering the domain's x and y ranges with spacing about ``h``."""
    nx = max(2, int(round((domain.x[1] - domain.x[0]) / h)) + 1)
    ny = max(2, int(round((domain.y[1] - domain.y[0]) / h)) + 1)
    return np.linspace(domain.x[0], domain.x[1], nx), np.linspace(domain.y[0], domain.y[1], ny)


@dataclass
class SliceFields:
    """rho, smallest contact, its deciding determinant and singularity cell on a (phi, y, x)
    grid."""

    phis: np.ndarray
    xs: np.ndarray
    ys: np.ndarray
    rho: np.ndarray      # (nphi, ny, nx)
    contact: np.ndarray  # (nphi, ny, nx) int32 index of the smallest contact
    code: np.ndarray     # (nphi, ny, nx) int32 code of the determinant deciding it
    cell: np.ndarray     # (nphi, ny, nx) int64 code of the pure-condition sign vector
    tol: float = 0.0     # rho <= tol counts as forbidden (numerically on an obstacle)

    @property
    def free(self) -> np.ndarray:
        return self.rho > self.tol


def _configs(phis, xs, ys):
    P, Y, X = np.meshgrid(phis, ys, xs, indexing='ij')
    return np.stack([X, Y, P], axis=-1)


def slice_fields(model: PlanarModel, phis: ArrayLike, xs: np.ndarray, ys: np.ndarray,
                 program: str = 'total') -> SliceFields:
    """Evaluate rho, the smallest contact and the singularity cell on the grid (vectorised).

    Each determinant is affine in (x, y) within a slice (:func:`affine_coefficients`), so
    the grid values are ``A + B x + C y`` by broadcasting: no point coordinates per vertex.
    """
    phis = np.atleast_1d(np.asarray(phis, dtype=float))
    prog = model.programs[program]
    if any(k not in prog.keys for k in model.singular_keys):
        q = _configs(phis, xs, ys)
        rho, contact, code, cell = model.fields(q, program)
        return SliceFields(phis, xs, ys, rho, contact, code, cell, model.free_tol)
    A, B, C = affine_coefficients(model, phis, program)
    rows = [prog.keys.index(k) for k in model.singular_keys]
    shape = (len(phis), len(ys), len(xs))
    rho = np.empty(shape)
    contact = np.empty(shape, dtype=np.int32)
    code = np.empty(shape, dtype=np.int32)
    cell = np.zeros(shape, dtype=np.int64)
    step = max(1, (1 << 17) // (len(xs) * len(ys)))
    for k0 in range(0, len(phis), step):
        sl = slice(k0, k0 + step)
        dets = (A[sl].T[:, :, None, None] + B[sl].T[:, :, None, None] * xs[None, None, None, :]
                + C[sl].T[:, :, None, None] * ys[None, None, :, None])
        vals, codes = prog.contact_values(dets)
        i1 = np.argmin(vals, axis=0)
        contact[sl] = i1
        rho[sl] = np.take_along_axis(vals, i1[None], axis=0)[0]
        code[sl] = np.take_along_axis(codes, i1[None], axis=0)[0]
        for i, r in enumerate(rows):
            cell[sl] += (np.sign(dets[r]).astype(np.int64) + 1) * 3 ** i
    return SliceFields(phis, xs, ys, rho, contact, code, cell, model.free_tol)


def contact_evaluator(model: PlanarModel, phi: float, program: str = 'total'
                      ) -> tuple[Callable[[ArrayLike], tuple[np.ndarray, np.ndarray]],
                                 tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """``f(xy (n, 2)) -> (values, codes)`` of the contacts in the slice ``phi``, from the
    affine forms, and the forms ``(A, B, C)`` (each ``(n_keys,)``)."""
    prog = model.programs[program]
    A, B, C = affine_coefficients(model, [phi], program)

    def evaluate(xy):
        xy = np.atleast_2d(xy)
        dets = A[0][:, None] + B[0][:, None] * xy[None, :, 0] + C[0][:, None] * xy[None, :, 1]
        return prog.contact_values(dets)

    return evaluate, (A[0], B[0], C[0])


def shifted_pairs(shape: tuple, dy: int, dx: int) -> tuple:
    """Slices (a, b) of a (..., ny, nx) array such that b is a shifted by (dy, dx)."""
    ny, nx = shape[-2], shape[-1]
    ya = slice(max(0, -dy), ny - max(0, dy))
    yb = slice(max(0, dy), ny - max(0, -dy))
    xa = slice(max(0, -dx), nx - max(0, dx))
    xb = slice(max(0, dx), nx - max(0, -dx))
    return (Ellipsis, ya, xa), (Ellipsis, yb, xb)


def diagram_mask(rho: np.ndarray, contact: np.ndarray, code: np.ndarray,
                 cell: np.ndarray | None = None, tol: float = 0.0) -> np.ndarray:
    """Free vertices (rho > tol) whose smallest contact differs, decided by another
    determinant, from that of a free 4-neighbour in the same singularity cell: the grid
    vertices next to the diagram. Works on ``(..., ny, nx)`` arrays."""
    free = rho > tol
    mask = np.zeros(rho.shape, dtype=bool)
    for dy, dx in ((0, 1), (1, 0)):
        a, b = shifted_pairs(rho.shape, dy, dx)
        change = free[a] & free[b] & (contact[a] != contact[b]) & (code[a] != code[b])
        if cell is not None:
            change &= cell[a] == cell[b]
        mask[a] |= change
        mask[b] |= change
    return mask


def tie_segments(model: PlanarModel, phi: float, xs: np.ndarray, ys: np.ndarray,
                 program: str = 'total') -> np.ndarray:
    """Straight pieces of the diagram in one slice, ``(m, 2, 2)`` xy segments: the edges of
    :func:`diagram_slices` for that slice (the same pieces the planner searches)."""
    fields = slice_fields(model, np.array([phi]), xs, ys, program)
    sl = diagram_slices(model, fields, program)[0]
    if not len(sl.edges):
        return np.zeros((0, 2, 2))
    return sl.xyz[sl.edges][:, :, :2]


def affine_coefficients(model: PlanarModel, phis: ArrayLike, program: str = 'total'
                        ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Exact affine form of every determinant per orientation slice.

    For a fixed phi every moving point is P3 plus a constant, so each 3x3 determinant is affine
    in (x, y): ``D = A + B x + C y``. Returns ``(A, B, C)``, each ``(nphi, n_keys)``, from
    three evaluations per slice.
    """
    prog = model.programs[program]
    phis = np.atleast_1d(np.asarray(phis, dtype=float))
    q = np.zeros((3, len(phis), 3))
    q[1, :, 0] = 1.0
    q[2, :, 1] = 1.0
    q[:, :, 2] = phis
    d = model.determinants(q, prog)            # (n_keys, 3, nphi)
    return d[:, 0].T, (d[:, 1] - d[:, 0]).T, (d[:, 2] - d[:, 0]).T


@dataclass
class DiagramSlice:
    """The simplified Voronoi diagram of one orientation slice as a graph of exact tie points.

    ``xyz``: node configurations (x, y, phi); ``pair``: code ``a * n_contacts + b`` (a < b)
    of the two contacts that tie there (-1 for junction nodes); ``rho``: rho at the node;
    ``edges``: ``(m, 2)`` local node ids of the straight diagram pieces joining them.
    """

    phi: float
    xyz: np.ndarray
    pair: np.ndarray
    rho: np.ndarray
    edges: np.ndarray
    _tree: object = None
    _pair_tree: object = None

    @property
    def tree(self) -> cKDTree:
        """k-d tree over the nodes' (x, y) (built on first use)."""
        if self._tree is None:
            self._tree = cKDTree(self.xyz[:, :2] if len(self.xyz) else np.zeros((0, 2)))
        return self._tree

    def pair_tree(self, scale: float) -> cKDTree:
        """k-d tree over (x, y, scale * pair): nearest queries stay within one contact
        pair."""
        if self._pair_tree is None or self._pair_tree[0] != scale:
            self._pair_tree = (scale, cKDTree(np.c_[self.xyz[:, :2], scale * self.pair]))
        return self._pair_tree[1]


def _contacts_at(prog, A, B, C, k, x, y):
    """Contact values and codes at points ``(x, y)`` of slices ``k`` from the affine forms."""
    dets = A[k].T + B[k].T * x + C[k].T * y
    return prog.contact_values(dets)


def _tie_parameter(prog, A, B, C, k, xu, yu, xv, yv, ca, cb, iterations=40):
    """Parameter t in [0, 1] of the point of the segment u -> v where contacts ``ca`` and
    ``cb`` are equal (``f_ca <= f_cb`` at u, ``>=`` at v): regula falsi with the Illinois
    modification on ``g = f_ca - f_cb``, which is piecewise affine, so it ends exactly after
    a few steps (one when no contact changes its deciding determinant along the edge)."""
    cols = np.arange(len(k))

    def g(t, sel):
        vals, _ = _contacts_at(prog, A, B, C, k[sel], xu[sel] + t * (xv[sel] - xu[sel]),
                               yu[sel] + t * (yv[sel] - yu[sel]))
        c = np.arange(len(sel))
        return vals[ca[sel], c] - vals[cb[sel], c]

    lo, hi = np.zeros(len(k)), np.ones(len(k))
    glo, ghi = np.minimum(g(lo, cols), 0.0), np.maximum(g(hi, cols), 0.0)
    eps = 1e-13 * (np.abs(glo) + np.abs(ghi)) + 1e-300
    t = np.where(ghi - glo > 0, -glo / np.maximum(ghi - glo, 1e-300), 0.5)
    last = np.zeros(len(k), dtype=np.int8)      # side replaced last: -1 lo, +1 hi
    todo = cols
    for _ in range(iterations):
        if not todo.size:
            break
        gt = g(t[todo], todo)
        done = np.abs(gt) <= eps[todo]
        left = gt < 0
        i = todo[left & ~done]
        lo[i], glo[i] = t[i], gt[left & ~done]
        ghi[i] = np.where(last[i] == -1, 0.5 * ghi[i], ghi[i])
        last[i] = -1
        i = todo[~left & ~done]
        hi[i], ghi[i] = t[i], gt[~left & ~done]
        glo[i] = np.where(last[i] == 1, 0.5 * glo[i], glo[i])
        last[i] = 1
        todo = todo[~done]
        den = ghi[todo] - glo[todo]
        t[todo] = np.where(den > 0, (lo[todo] * ghi[todo] - hi[todo] * glo[todo])
                           / np.maximum(den, 1e-300), 0.5 * (lo[todo] + hi[todo]))
    return t


def _leaf_forms(A, B, C, k, codes):
    """Affine forms ``(a, b, c)`` of the signed determinants ``codes`` in slices ``k``."""
    codes = np.asarray(codes)
    key = codes // 2
    sign = np.where(codes % 2 == 1, 1.0, -1.0)
    return sign * A[k, key], sign * B[k, key], sign * C[k, key]


def _solve_ties(A, B, C, k, c1, c2, c3, c4):
    """Points where ``L_c1 = L_c2`` and ``L_c3 = L_c4`` (signed determinants, affine in a
    slice), batched over slices ``k``; NaN where the two lines are parallel."""
    a1, b1, d1 = (u - v for u, v in zip(_leaf_forms(A, B, C, k, c1), _leaf_forms(A, B, C, k, c2)))
    a2, b2, d2 = (u - v for u, v in zip(_leaf_forms(A, B, C, k, c3), _leaf_forms(A, B, C, k, c4)))
    det = b1 * d2 - d1 * b2
    scale = np.maximum(np.abs(b1) + np.abs(d1), 1e-300) * np.maximum(np.abs(b2) + np.abs(d2),
                                                                      1e-300)
    ok = np.abs(det) > 1e-12 * scale
    det = np.where(ok, det, 1.0)
    x = (-a1 * d2 + a2 * d1) / det
    y = (-b1 * a2 + b2 * a1) / det
    return np.where(ok, x, np.nan), np.where(ok, y, np.nan)


def _vertices(prog, A, B, C, k, centres):
    """Diagram vertices near ``centres`` (n, 2) of slices ``k``: the three smallest contacts
    decided by distinct determinants at each centre, their determinants solved as
    ``L_a = L_b = L_c``. Returns ``(n, 2)`` points, NaN where the system is singular."""
    vals, codes = _contacts_at(prog, A, B, C, k, centres[:, 0], centres[:, 1])
    n = len(k)
    cols = np.arange(n)
    order = np.argsort(vals, axis=0, kind='stable')
    chosen = np.full((3, n), -1, dtype=np.int64)
    found = np.zeros(n, dtype=np.int64)
    for r in range(order.shape[0]):
        c = codes[order[r], cols]
        fresh = (found < 3) & np.all(chosen != c[None], axis=0)
        chosen[np.minimum(found, 2)[fresh], cols[fresh]] = c[fresh]
        found += fresh
    x, y = _solve_ties(A, B, C, k, chosen[0], chosen[1], chosen[0], chosen[2])
    bad = found < 3
    x[bad], y[bad] = np.nan, np.nan
    return np.stack([x, y], axis=1)


def _in_cells(p, xs, ys, jj, ii):
    """Points ``p`` (n, 2) inside grid cells (jj, ii), with a margin of 1e-6 cell."""
    h = np.maximum(xs[ii + 1] - xs[ii], ys[jj + 1] - ys[jj]) * 1e-6
    with np.errstate(invalid='ignore'):
        return ((xs[ii] - h <= p[:, 0]) & (p[:, 0] <= xs[ii + 1] + h)
                & (ys[jj] - h <= p[:, 1]) & (p[:, 1] <= ys[jj + 1] + h))


def diagram_slices(model: PlanarModel, fields: SliceFields,
                   program: str = 'total') -> list[DiagramSlice]:
    """Exact diagram pieces of every slice in ``fields``, as :class:`DiagramSlice` graphs.

    Nodes: on every grid edge joining two free vertices of one singularity cell whose smallest
    contacts A and B differ and are decided by different determinants, the point where
    ``f_A = f_B`` (:func:`_tie_parameter`), kept when it is on the diagram
    (:func:`voronoi_pkg.ties.on_diagram`: free, and A and B the two smallest there). Within a
    grid cell the diagram is straight: two tie points of one contact pair are joined
    directly; where other pairs enter the cell, the exact vertex where three contacts tie
    (:func:`_vertex`) is a node joined to each, if it lies in the cell and on the diagram;
    otherwise only tie points of one pair are joined. Every node and every junction is on
    the diagram within :func:`voronoi_pkg.ties.tie_tolerance`.
    """
    prog = model.programs[program]
    n_c = prog.n_contacts
    A, B, C = affine_coefficients(model, fields.phis, program)
    rho, contact, code, cell = fields.rho, fields.contact, fields.code, fields.cell
    free = fields.free
    xs, ys = fields.xs, fields.ys
    tol = fields.tol
    shape = rho.shape
    nphi, ny, nx = shape
    # Tie points per grid edge: the tie of the two end contacts, or, where a third contact
    # is the smallest there, the ties on both sides of it (two per edge, layers 0 and 1).
    parts = []          # (direction, layer, k, j, i, x, y)
    for d, (dy, dx) in enumerate(((0, 1), (1, 0))):
        a, b = shifted_pairs(shape, dy, dx)
        cand = (free[a] & free[b] & (cell[a] == cell[b]) & (contact[a] != contact[b])
                & (code[a] != code[b]))
        k, j, i = np.nonzero(cand)
        ca, cb = contact[k, j, i], contact[k, j + dy, i + dx]
        xu, yu, xv, yv = xs[i], ys[j], xs[i + dx], ys[j + dy]
        t = _tie_parameter(prog, A, B, C, k, xu, yu, xv, yv, ca, cb)
        px, py = xu + t * (xv - xu), yu + t * (yv - yu)
        vals, codes = _contacts_at(prog, A, B, C, k, px, py)
        mid = np.argmin(vals, axis=0)
        c = np.arange(len(k))
        third = ((mid != ca) & (mid != cb) & (vals.min(axis=0) > tol)
                 & (codes[mid, c] != codes[ca, c]) & (codes[mid, c] != codes[cb, c]))
        parts.append((d, 0, k[~third], j[~third], i[~third], px[~third], py[~third]))
        w = third
        t1 = _tie_parameter(prog, A, B, C, k[w], xu[w], yu[w], px[w], py[w], ca[w], mid[w])
        t2 = _tie_parameter(prog, A, B, C, k[w], px[w], py[w], xv[w], yv[w], mid[w], cb[w])
        parts.append((d, 0, k[w], j[w], i[w], xu[w] + t1 * (px[w] - xu[w]),
                      yu[w] + t1 * (py[w] - yu[w])))
        parts.append((d, 1, k[w], j[w], i[w], px[w] + t2 * (xv[w] - px[w]),
                      py[w] + t2 * (yv[w] - py[w])))
    k = np.concatenate([p[2] for p in parts])
    px = np.concatenate([p[5] for p in parts])
    py = np.concatenate([p[6] for p in parts])
    vals, codes = _contacts_at(prog, A, B, C, k, px, py)
    i1, f1, i2, f2 = two_smallest(vals, codes)
    keep = (f1 > tol) & (f2 - f1 <= tie_tolerance(f1, f2, tol))
    lo_c, hi_c = np.minimum(i1, i2), np.maximum(i1, i2)
    pair = lo_c * n_c + hi_c
    cols = np.arange(len(k))
    # Deciding determinants of the pair (lower contact first): the straight line of the tie.
    line = np.stack([codes[lo_c, cols], codes[hi_c, cols]])
    q = np.stack([px, py, fields.phis[k]], axis=1)
    node_rho = f1
    gid = np.cumsum(keep) - 1
    ids = {(d, layer): np.full((nphi, ny - dy, nx - dx), -1, dtype=np.int64)
           for d, (dy, dx) in enumerate(((0, 1), (1, 0))) for layer in (0, 1)}
    start = 0
    for d, layer, pk, pj, pi, _, _ in parts:
        n = len(pk)
        sel = keep[start:start + n]
        ids[(d, layer)][pk[sel], pj[sel], pi[sel]] = gid[start:start + n][sel]
        start += n
    k, q, pair, node_rho, line = k[keep], q[keep], pair[keep], node_rho[keep], line[:, keep]
    sides = np.stack([s for layer in (0, 1) for s in (
        ids[(0, layer)][:, :-1, :], ids[(0, layer)][:, 1:, :],
        ids[(1, layer)][:, :, :-1], ids[(1, layer)][:, :, 1:])])     # per cell
    count = np.sum(sides >= 0, axis=0)
    big = np.iinfo(np.int64).max
    n1 = np.max(sides, axis=0)                         # the two ids when count == 2
    n2 = np.where(sides >= 0, sides, big).min(axis=0)
    two = count == 2
    same = np.zeros(two.shape, dtype=bool)
    same[two] = pair[n1[two]] == pair[n2[two]]
    new_q, new_k, new_pair, eu, ev = [], [], [], [], []
    n_nodes = len(q)

    def add_nodes(points, kk, pairs, on):
        """Append diagram nodes; returns their global ids."""
        first = n_nodes + sum(len(x) for x in new_q)
        new_q.append(np.c_[points[on], fields.phis[kk[on]]])
        new_k.append(kk[on])
        new_pair.append(pairs[on])
        return first + np.arange(int(on.sum()))

    # Cells crossed by one piece of one contact pair: straight unless a contact changes its
    # deciding determinant inside the cell; then the bend is the point where both lines meet.
    sk, sj, si = np.nonzero(same)
    a, b = n1[sk, sj, si], n2[sk, sj, si]
    bent = np.any(line[:, a] != line[:, b], axis=0)
    bx, by = _solve_ties(A, B, C, sk[bent], line[0, a[bent]], line[1, a[bent]],
                         line[0, b[bent]], line[1, b[bent]])
    bend = np.stack([bx, by], axis=1)
    vb, cb = _contacts_at(prog, A, B, C, sk[bent], np.nan_to_num(bx), np.nan_to_num(by))
    good = _in_cells(bend, xs, ys, sj[bent], si[bent]) & on_diagram(vb, cb, tol)
    mid = add_nodes(bend, sk[bent], pair[a[bent]], good)
    ab, bb = a[bent][good], b[bent][good]
    eu += [a[~bent], ab, bb]
    ev += [b[~bent], mid, mid]
    # Bends that are not on the diagram inside the cell: the chord (its midpoint is checked
    # by the tests against the tie tolerance of a grid spacing).
    eu.append(a[bent][~good])
    ev.append(b[bent][~good])
    # Cells where pieces of different pairs meet: the exact vertex where three contacts
    # tie, joined to every tie point of the cell; else only pieces of one pair are joined.
    jk, jj, ji = np.nonzero((count >= 3) | (two & ~same))
    members = sides[:, jk, jj, ji]                          # (8, nj)
    has = members >= 0
    safe = np.where(has, members, 0)
    centre = (np.sum(np.where(has[..., None], q[safe][..., :2], 0.0), axis=0)
              / np.maximum(has.sum(0), 1)[:, None])
    vert = _vertices(prog, A, B, C, jk, centre)
    vv, cv = _contacts_at(prog, A, B, C, jk, np.nan_to_num(vert[:, 0]),
                          np.nan_to_num(vert[:, 1]))
    good = _in_cells(vert, xs, ys, jj, ji) & on_diagram(vv, cv, tol)
    vid = add_nodes(vert, jk, np.full(len(jk), -1), good)
    vid_of = np.full(len(jk), -1)
    vid_of[good] = vid
    for s in range(len(sides)):
        sel = good & has[s]
        eu.append(members[s][sel])
        ev.append(vid_of[sel])
    for c in np.flatnonzero(~good):
        m = members[:, c][has[:, c]]
        for pc in np.unique(pair[m]):
            grp = m[pair[m] == pc]
            if len(grp) == 2:
                eu.append(grp[:1])
                ev.append(grp[1:])
    if new_q:
        extra = np.vstack(new_q)
        ek = np.concatenate(new_k)
        ev_, ec = _contacts_at(prog, A, B, C, ek, extra[:, 0], extra[:, 1])
        k = np.r_[k, ek]
        q = np.vstack([q, extra])
        pair = np.r_[pair, np.concatenate(new_pair)]
        node_rho = np.r_[node_rho, ev_.min(axis=0)]
    eu = np.concatenate(eu).astype(np.int64)
    ev = np.concatenate(ev).astype(np.int64)
    order = np.argsort(k, kind='stable')
    local = np.empty(len(k), dtype=np.int64)
    bounds = np.searchsorted(k[order], np.arange(nphi + 1))
    for s in range(nphi):
        local[order[bounds[s]:bounds[s + 1]]] = np.arange(bounds[s + 1] - bounds[s])
    edge_slice = k[eu] if len(eu) else np.zeros(0, dtype=np.int64)
    out = []
    for s in range(nphi):
        nodes = order[bounds[s]:bounds[s + 1]]
        sel = edge_slice == s
        out.append(DiagramSlice(float(fields.phis[s]), q[nodes], pair[nodes], node_rho[nodes],
                                np.stack([local[eu[sel]], local[ev[sel]]], axis=1)))
    return out


def link_slices(lower: DiagramSlice, upper: DiagramSlice, radius: float) -> np.ndarray:
    """Links between the diagram vertices of two consecutive slices: each node joins the
    nearest node of the same leaf pair (the same diagram sheet, moved by the rotation) and the
    two nearest nodes of any pair in the other slice, within ``radius`` in (x, y). Returns
    ``(m, 2)`` pairs of (lower id, upper id)."""
    out = []
    if not len(lower.xyz) or not len(upper.xyz):
        return np.zeros((0, 2), dtype=np.int64)
    big = 1e3 * (radius + 1.0)
    for a, b, flip in ((lower, upper, False), (upper, lower, True)):
        _, j = b.pair_tree(big).query(np.c_[a.xyz[:, :2], big * a.pair], k=1,
                                      distance_upper_bound=radius)
        ok = j < len(b.xyz)
        pairs = [np.stack([np.flatnonzero(ok), j[ok]], axis=1)]
        kk = min(2, len(b.xyz))
        _, j = b.tree.query(a.xyz[:, :2], k=kk, distance_upper_bound=radius)
        j = j.reshape(len(a.xyz), kk)
        for c in range(kk):
            ok = j[:, c] < len(b.xyz)
            pairs.append(np.stack([np.flatnonzero(ok), j[ok, c]], axis=1))
        p = np.vstack(pairs)
        out.append(p[:, ::-1] if flip else p)
    links = np.vstack(out)
    code = np.unique(links[:, 0] * len(upper.xyz) + links[:, 1])
    return np.stack([code // len(upper.xyz), code % len(upper.xyz)], axis=1)
