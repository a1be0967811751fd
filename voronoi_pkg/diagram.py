"""Simplified Voronoi diagram of the distance measure rho (section 5 of Vaca, Aranda & Thomas;
Canny & Donald 1988), per orientation slice and connected across orientation.

rho is a min/max tree of signed determinants (:mod:`voronoi_pkg.distance`). Each
configuration has one *active* leaf - the determinant that currently decides rho. The
simplified Voronoi diagram is the set where two or more leaves tie, i.e. where the active
leaf changes. For a fixed orientation phi of the planar platform every determinant is affine
in (x, y), so each slice of the diagram is an arrangement of straight segments (the paper's
"straight skeleton" remark).

Construction used by the planner (:mod:`voronoi_pkg.planner`):

* :func:`affine_coefficients`: the exact affine form ``A + B x + C y`` of every determinant in
  a slice (all moving points are P3 plus a constant), so grid fields (:func:`slice_fields`)
  and tie points need no per-point geometry;
* :func:`diagram_slices`: per slice, a graph whose nodes are the exact tie points
  ``L_a = L_b`` on grid edges whose end vertices (free, same singularity cell) have different
  active leaves, and whose edges are the straight pieces joining the tie points of one grid
  cell (a junction node where three or more meet);
* :func:`link_slices`: links between diagram vertices of consecutive slices (nearest of the
  same leaf pair, two nearest of any pair, within a radius).

No roadmap edge comes from a free grid edge: the planner searches these pieces and links only.
:func:`tie_segments` extracts the same straight pieces of one slice for figures and markers.
"""
from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

__all__ = ['DiagramSlice', 'SliceFields', 'affine_coefficients', 'diagram_mask',
           'diagram_slices', 'grid_axes', 'leaf_evaluator', 'link_slices', 'slice_fields',
           'tie_segments']

# In-slice neighbour offsets (dy, dx) covering the 8-neighbourhood once per unordered pair.
_HALF8 = ((0, 1), (1, 0), (1, 1), (1, -1))
_ALL8 = ((0, 1), (1, 0), (1, 1), (1, -1), (0, -1), (-1, 0), (-1, -1), (-1, 1))


def grid_axes(domain, h):
    """Grid coordinates covering the domain's x and y ranges with spacing about ``h``."""
    nx = max(2, int(round((domain.x[1] - domain.x[0]) / h)) + 1)
    ny = max(2, int(round((domain.y[1] - domain.y[0]) / h)) + 1)
    return np.linspace(domain.x[0], domain.x[1], nx), np.linspace(domain.y[0], domain.y[1], ny)


@dataclass
class SliceFields:
    """rho, active leaf and singularity-cell code on a (phi, y, x) grid."""

    phis: np.ndarray
    xs: np.ndarray
    ys: np.ndarray
    rho: np.ndarray      # (nphi, ny, nx)
    active: np.ndarray   # (nphi, ny, nx) int32 leaf ids
    cell: np.ndarray     # (nphi, ny, nx) int64 code of the pure-condition sign vector
    tol: float = 0.0     # rho <= tol counts as forbidden (numerically on an obstacle)

    @property
    def free(self):
        return self.rho > self.tol


def _configs(phis, xs, ys):
    P, Y, X = np.meshgrid(phis, ys, xs, indexing='ij')
    return np.stack([X, Y, P], axis=-1)


def slice_fields(model, phis, xs, ys, program='total'):
    """Evaluate rho, the active leaf and the singularity cell on the grid (vectorised).

    Each determinant is affine in (x, y) within a slice (:func:`affine_coefficients`), so
    the grid values are ``A + B x + C y`` by broadcasting: no point coordinates per vertex.
    """
    phis = np.atleast_1d(np.asarray(phis, dtype=float))
    prog = model.programs[program]
    if any(k not in prog.keys for k in model.singular_keys):
        q = _configs(phis, xs, ys)
        rho, active, cell = model.fields(q, program)
        return SliceFields(phis, xs, ys, rho, active, cell, model.free_tol)
    A, B, C = affine_coefficients(model, phis, program)
    rows = [prog.keys.index(k) for k in model.singular_keys]
    shape = (len(phis), len(ys), len(xs))
    rho = np.empty(shape)
    active = np.empty(shape, dtype=np.int32)
    cell = np.zeros(shape, dtype=np.int64)
    step = max(1, (1 << 18) // (len(xs) * len(ys)))
    for k0 in range(0, len(phis), step):
        sl = slice(k0, k0 + step)
        dets = (A[sl].T[:, :, None, None] + B[sl].T[:, :, None, None] * xs[None, None, None, :]
                + C[sl].T[:, :, None, None] * ys[None, None, :, None])
        rho[sl], active[sl] = prog.evaluate(dets)
        for i, r in enumerate(rows):
            cell[sl] += (np.sign(dets[r]).astype(np.int64) + 1) * 3 ** i
    return SliceFields(phis, xs, ys, rho, active, cell, model.free_tol)


def leaf_evaluator(model, phi, program='total'):
    """``f(xy (n, 2)) -> (rho, active)`` in the slice ``phi``, from the affine forms."""
    prog = model.programs[program]
    A, B, C = affine_coefficients(model, [phi], program)

    def evaluate(xy):
        xy = np.atleast_2d(xy)
        dets = A[0][:, None] + B[0][:, None] * xy[None, :, 0] + C[0][:, None] * xy[None, :, 1]
        return prog.evaluate(dets)

    return evaluate, (A[0], B[0], C[0])


def _shifted_pairs(shape, dy, dx):
    """Slices (a, b) of a (..., ny, nx) array such that b is a shifted by (dy, dx)."""
    ny, nx = shape[-2], shape[-1]
    ya = slice(max(0, -dy), ny - max(0, dy))
    yb = slice(max(0, dy), ny - max(0, -dy))
    xa = slice(max(0, -dx), nx - max(0, dx))
    xb = slice(max(0, dx), nx - max(0, -dx))
    return (Ellipsis, ya, xa), (Ellipsis, yb, xb)


def diagram_mask(rho, active, cell=None, tol=0.0):
    """Free vertices (rho > tol) where the active leaf differs from that of a free
    4-neighbour. Works on ``(..., ny, nx)`` arrays; neighbours within the last two axes.
    """
    free = rho > tol
    mask = np.zeros(rho.shape, dtype=bool)
    for dy, dx in ((0, 1), (1, 0)):
        a, b = _shifted_pairs(rho.shape, dy, dx)
        change = free[a] & free[b] & (active[a] != active[b])
        if cell is not None:
            change &= cell[a] == cell[b]
        mask[a] |= change
        mask[b] |= change
    return mask


def tie_segments(model, phi, xs, ys, program='total', free_only=True):
    """Straight pieces of the diagram in one slice, as an array ``(m, 2, 2)`` of xy segments.

    On every grid edge whose end vertices have different active leaves a and b, the tie point
    solves ``L_a = L_b`` exactly (both leaves are affine along the edge). Tie points in the same
    cell are joined (two points: a segment; more: a star through their mean, a junction).
    """
    prog = model.programs[program]
    X, Y = np.meshgrid(xs, ys)
    q = np.stack([X, Y, np.full_like(X, phi)], axis=-1)
    dets = model.determinants(q, prog)
    rho, active = prog.evaluate(dets)
    key_of = np.array([k for k, _ in prog.leaves])
    sign_of = np.array([s for _, s in prog.leaves], dtype=float)
    ny, nx = rho.shape

    def leaf_value(leaf, iy, ix):
        return sign_of[leaf] * dets[key_of[leaf], iy, ix]

    points = {}   # (cell iy, cell ix) -> list of tie points
    for dy, dx in ((0, 1), (1, 0)):
        a, b = _shifted_pairs(rho.shape, dy, dx)
        iy, ix = np.nonzero(active[a] != active[b])
        iy_b, ix_b = iy + dy, ix + dx
        la, lb = active[iy, ix], active[iy_b, ix_b]
        du = leaf_value(la, iy, ix) - leaf_value(lb, iy, ix)
        dv = leaf_value(la, iy_b, ix_b) - leaf_value(lb, iy_b, ix_b)
        denom = du - dv
        t = np.clip(np.divide(du, denom, out=np.full_like(du, 0.5), where=denom != 0), 0, 1)
        px = xs[ix] + t * (xs[ix_b] - xs[ix])
        py = ys[iy] + t * (ys[iy_b] - ys[iy])
        keep = np.ones(len(t), dtype=bool)
        if free_only:
            # The tie must be free: a change between D and -D is the zero set of D (an
            # obstacle such as a singularity), not part of the diagram.
            va = leaf_value(la, iy, ix)
            value = va + t * (leaf_value(la, iy_b, ix_b) - va)
            keep = value > 1e-9 * (np.abs(rho[iy, ix]) + np.abs(rho[iy_b, ix_b]))
        for k in np.nonzero(keep)[0]:
            # The edge borders one or two cells: (iy, ix) cell and the one before it.
            cells = [(iy[k], ix[k])]
            if dy == 0:
                cells.append((iy[k] - 1, ix[k]))
            else:
                cells.append((iy[k], ix[k] - 1))
            for c in cells:
                if 0 <= c[0] < ny - 1 and 0 <= c[1] < nx - 1:
                    points.setdefault(c, []).append((px[k], py[k]))
    segs = []
    for pts in points.values():
        if len(pts) == 2:
            segs.append(pts)
        elif len(pts) > 2:
            centre = tuple(np.mean(pts, axis=0))
            segs.extend([p, centre] for p in pts)
    return np.asarray(segs, dtype=float).reshape(-1, 2, 2)


def affine_coefficients(model, phis, program='total'):
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

    ``xyz``: node configurations (x, y, phi); ``pair``: code ``la * n_leaves + lb`` (la < lb)
    of the two leaves that tie there (-1 for junction nodes); ``rho``: rho at the node;
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
    def tree(self):
        """k-d tree over the nodes' (x, y) (built on first use)."""
        if self._tree is None:
            self._tree = cKDTree(self.xyz[:, :2] if len(self.xyz) else np.zeros((0, 2)))
        return self._tree

    def pair_tree(self, scale):
        """k-d tree over (x, y, scale * pair): nearest queries stay within one leaf pair."""
        if self._pair_tree is None or self._pair_tree[0] != scale:
            self._pair_tree = (scale, cKDTree(np.c_[self.xyz[:, :2], scale * self.pair]))
        return self._pair_tree[1]


def diagram_slices(model, fields, program='total'):
    """Exact diagram pieces of every slice in ``fields``, as :class:`DiagramSlice` graphs.

    Nodes: on every grid edge joining two free vertices of one singularity cell whose active
    leaves ``a`` and ``b`` differ, the point where ``L_a = L_b`` (both leaves are affine along
    the edge, so the tie point is exact), kept when rho there is free. Within one grid cell
    the diagram is the straight tie line: two tie points in a cell are joined directly; three
    or more meet at a junction node (their mean), joined to each - the pieces
    :func:`tie_segments` draws.
    """
    prog = model.programs[program]
    key_of = np.array([k for k, _ in prog.leaves])
    sign_of = np.array([s for _, s in prog.leaves], dtype=float)
    n_leaves = len(prog.leaves)
    A, B, C = affine_coefficients(model, fields.phis, program)
    rho, active, cell = fields.rho, fields.active, fields.cell
    free = fields.free
    xs, ys = fields.xs, fields.ys
    shape = rho.shape
    nphi, ny, nx = shape
    ids = {}
    parts = []          # (k, x, y, pair) per edge direction
    for dy, dx in ((0, 1), (1, 0)):
        a, b = _shifted_pairs(shape, dy, dx)
        cand = free[a] & free[b] & (cell[a] == cell[b]) & (active[a] != active[b])
        k, j, i = np.nonzero(cand)
        la, lb = active[k, j, i], active[k, j + dy, i + dx]
        xu, yu, xv, yv = xs[i], ys[j], xs[i + dx], ys[j + dy]

        def leaf(lf, x, y):
            key = key_of[lf]
            return sign_of[lf] * (A[k, key] + B[k, key] * x + C[k, key] * y)

        du = leaf(la, xu, yu) - leaf(lb, xu, yu)
        dv = leaf(la, xv, yv) - leaf(lb, xv, yv)
        den = du - dv
        t = np.clip(np.divide(du, den, out=np.full_like(du, 0.5), where=den != 0), 0.0, 1.0)
        parts.append((k, j, i, xu + t * (xv - xu), yu + t * (yv - yu),
                      np.minimum(la, lb) * n_leaves + np.maximum(la, lb)))
        ids[(dy, dx)] = np.full((nphi, ny - dy, nx - dx), -1, dtype=np.int64)
    k = np.concatenate([p[0] for p in parts])
    px = np.concatenate([p[3] for p in parts])
    py = np.concatenate([p[4] for p in parts])
    pair = np.concatenate([p[5] for p in parts])
    q = np.stack([px, py, fields.phis[k]], axis=1)
    node_rho = model.rho(q, program) if len(q) else np.zeros(0)
    keep = node_rho > fields.tol
    gid = np.cumsum(keep) - 1
    start = 0
    for (dy, dx), p in zip(((0, 1), (1, 0)), parts):
        n = len(p[0])
        sel = keep[start:start + n]
        ids[(dy, dx)][p[0][sel], p[1][sel], p[2][sel]] = gid[start:start + n][sel]
        start += n
    k, q, pair, node_rho = k[keep], q[keep], pair[keep], node_rho[keep]
    H, V = ids[(0, 1)], ids[(1, 0)]
    sides = np.stack([H[:, :-1, :], H[:, 1:, :], V[:, :, :-1], V[:, :, 1:]])  # per cell
    count = np.sum(sides >= 0, axis=0)
    eu, ev = [], []
    two = count == 2
    for s1 in range(4):
        for s2 in range(s1 + 1, 4):
            ok = two & (sides[s1] >= 0) & (sides[s2] >= 0)
            eu.append(sides[s1][ok])
            ev.append(sides[s2][ok])
    # Junctions: cells where three or more tie lines enter.
    jk, jj, ji = np.nonzero(count >= 3)
    n_nodes = len(q)
    if len(jk):
        members = sides[:, jk, jj, ji]                        # (4, nj)
        has = members >= 0
        safe = np.where(has, members, 0)
        centre = np.sum(np.where(has[..., None], q[safe], 0.0), axis=0) / has.sum(0)[:, None]
        c_rho = model.rho(centre, program)
        ok = c_rho > fields.tol
        cid = n_nodes + np.cumsum(ok) - 1
        for s in range(4):
            sel = ok & has[s]
            eu.append(members[s][sel])
            ev.append(cid[sel])
        k = np.r_[k, jk[ok]]
        q = np.vstack([q, centre[ok]])
        pair = np.r_[pair, np.full(int(ok.sum()), -1)]
        node_rho = np.r_[node_rho, c_rho[ok]]
    eu, ev = np.concatenate(eu), np.concatenate(ev)
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


def link_slices(lower, upper, radius):
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
