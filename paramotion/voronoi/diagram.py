"""Simplified Voronoi diagram of the distance measure rho (section 5 of Vaca, Aranda & Thomas;
Canny & Donald 1988), per orientation slice and connected across orientation.

rho is a min/max tree of signed determinants (:mod:`paramotion.voronoi.distance`). Each
configuration has one *active* leaf - the determinant that currently decides rho. The
simplified Voronoi diagram is the set where two or more leaves tie, i.e. where the active
leaf changes. For a fixed orientation phi of the planar platform every determinant is affine
in (x, y), so each slice of the diagram is an arrangement of straight segments (the paper's
"straight skeleton" remark).

Sampled construction, used by the planner (:mod:`paramotion.voronoi.planner`):

* a grid of spacing ``h`` in (x, y) in every slice ``phi_k``; at each vertex rho, the active
  leaf and the sign vector of the pure-condition determinants (the singularity cell);
* *diagram vertices*: free vertices (rho > 0) with a free 4-neighbour of another active leaf
  (the diagram crosses the grid edge between them), plus slice-local maxima of rho;
* the *retraction*: from any free vertex, steepest ascent of rho over the 8-neighbours of its
  slice (never changing singularity cell) until a diagram vertex. rho increases along it, so
  moving off the obstacles onto the diagram never enters a forbidden region;
* *roadmap edges*: between the retractions of two free neighbouring vertices in the same
  slice (8-neighbours), or in consecutive slices (same (x, y)), when they retract to
  different diagram vertices. Two neighbouring diagram vertices are joined directly; across
  orientation, a diagram vertex is joined to where its rotated copy retracts in the next
  slice. Each edge keeps all its witnesses ``(u, v)`` best first, so a witness refused by
  dense checking is replaced by the next (lazy verification).

Because every free grid edge of the sampled configuration space maps onto a roadmap edge, the
roadmap connects two diagram vertices whenever the free vertices of the sampled grid connect
them (resolution completeness); the planner's tests compare it with a flood fill.

:func:`tie_segments` extracts the exact straight pieces of one slice (marching squares on the
active-leaf field, tie points from the two affine leaves), for figures and markers.
"""
from dataclasses import dataclass

import numpy as np

__all__ = ['Roadmap', 'SliceFields', 'build_roadmap', 'diagram_mask', 'grid_axes',
           'slice_fields', 'tie_segments']

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
    """Evaluate rho, the active leaf and the singularity cell on the grid (vectorised)."""
    q = _configs(np.asarray(phis, dtype=float), xs, ys)
    rho, active, cell = model.fields(q, program)
    return SliceFields(np.asarray(phis, dtype=float), xs, ys, rho, active, cell,
                       model.free_tol)


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


@dataclass
class Roadmap:
    """Sampled simplified Voronoi roadmap over all slices (see the module docstring)."""

    fields: SliceFields
    periodic: bool
    phi_scale: float          # length per radian used for edge costs
    node_mask: np.ndarray     # (nphi, ny, nx) diagram vertices
    succ: np.ndarray          # (N,) steepest-ascent successor (flat indices)
    root: np.ndarray          # (N,) diagram vertex each free vertex retracts to
    pair_lo: np.ndarray       # (E,) roadmap edges: flat index of the lower diagram vertex
    pair_hi: np.ndarray       # (E,) and of the higher one
    pair_start: np.ndarray    # (E + 1,) range of each pair in the witness arrays
    wit_u: np.ndarray         # witnesses, grouped by pair, largest clearance first
    wit_v: np.ndarray
    wit_clearance: np.ndarray  # min rho at the witness's two vertices

    def witness_cost(self, w):
        """Length of the roadmap edge through witnesses ``w``: root(u) -> u -> v -> root(v),
        phi weighted by ``phi_scale`` (straight-line estimate of the retraction chains)."""
        u, v = self.wit_u[w], self.wit_v[w]
        pts = [self.position(self.root[u]), self.position(u), self.position(v),
               self.position(self.root[v])]
        return sum(_dist(self.phi_scale, self.periodic, a, b) for a, b in zip(pts, pts[1:]))

    @property
    def shape(self):
        return self.fields.rho.shape

    @property
    def n_vertices(self):
        return int(np.prod(self.shape))

    def position(self, flat):
        """Configurations (x, y, phi) of flat vertex indices."""
        k, j, i = np.unravel_index(np.asarray(flat), self.shape)
        f = self.fields
        return np.stack([f.xs[i], f.ys[j], f.phis[k]], axis=-1)

    def chain(self, u):
        """Retraction path of vertex ``u``: ``[u, succ(u), ..., root(u)]``."""
        out = [int(u)]
        while self.succ[out[-1]] != out[-1]:
            out.append(int(self.succ[out[-1]]))
        return out

    def nearest_vertices(self, q, k=4):
        """Flat indices of free grid vertices near configuration ``q`` in slice ``q[2]``."""
        f = self.fields
        d = np.abs(f.phis - q[2])
        if self.periodic:
            d = np.minimum(d, 2 * np.pi - d)
        ks = int(np.argmin(d))
        ix = np.argsort(np.abs(f.xs - q[0]))[:3]
        iy = np.argsort(np.abs(f.ys - q[1]))[:3]
        cand = [(float(np.hypot(f.xs[i] - q[0], f.ys[j] - q[1])), ks, j, i)
                for i in ix for j in iy]
        cand.sort()
        out = []
        for _, kk, j, i in cand:
            if f.rho[kk, j, i] > f.tol:
                out.append(int(np.ravel_multi_index((kk, j, i), self.shape)))
        return out[:k]


def _dist(model_scale, periodic, a, b):
    d = np.array(b - a, dtype=float)
    if periodic:
        d[..., 2] = (d[..., 2] + np.pi) % (2 * np.pi) - np.pi
    d[..., 2] *= model_scale
    return np.sqrt(np.sum(d * d, axis=-1))


def build_roadmap(fields, periodic, phi_scale):
    """Diagram vertices, retraction and witnessed roadmap edges for ``fields``."""
    rho, active, cell = fields.rho, fields.active, fields.cell
    shape = rho.shape
    n = int(np.prod(shape))
    free = fields.free
    idx = np.arange(n, dtype=np.int64).reshape(shape)
    node = diagram_mask(rho, active, cell, fields.tol)

    # Steepest ascent over the 8-neighbours of the slice, within the same singularity cell.
    best = np.where(free, rho, -np.inf)
    succ = idx.copy()
    for dy, dx in _ALL8:
        a, b = _shifted_pairs(shape, dy, dx)
        ok = free[b] & (cell[b] == cell[a]) & (rho[b] > best[a])
        best_a = best[a]
        succ_a = succ[a]
        np.copyto(best_a, rho[b], where=ok)
        np.copyto(succ_a, idx[b], where=ok)
        best[a] = best_a
        succ[a] = succ_a
    local_max = free & (succ == idx)
    node |= local_max
    succ = np.where(node | ~free, idx, succ).ravel()
    root = succ.copy()
    while True:
        nxt = root[root]
        if np.array_equal(nxt, root):
            break
        root = nxt
    root3 = root.reshape(shape)

    us, vs = [], []

    def add(a_sl, b_sl):
        ok = free[a_sl] & free[b_sl] & (cell[a_sl] == cell[b_sl]) \
            & (root3[a_sl] != root3[b_sl])
        us.append(idx[a_sl][ok])
        vs.append(idx[b_sl][ok])

    for dy, dx in _HALF8:
        add(*_shifted_pairs(shape, dy, dx))
    nphi = shape[0]
    if nphi > 1:
        add((slice(0, nphi - 1),), (slice(1, nphi),))
        if periodic:
            add((slice(nphi - 1, nphi),), (slice(0, 1),))
    u = np.concatenate(us)
    v = np.concatenate(vs)
    # Compact ids of the diagram vertices keep the pair key small enough to carry the
    # clearance in its low bits: one integer sort orders witnesses by pair, best first.
    node_flat = np.flatnonzero(node.ravel())
    compact = np.full(n, -1, dtype=np.int64)
    compact[node_flat] = np.arange(len(node_flat))
    cu, cv = compact[root[u]], compact[root[v]]
    flat_rho = rho.ravel()
    clear = np.minimum(flat_rho[u], flat_rho[v])
    lo, hi = np.minimum(cu, cv), np.maximum(cu, cv)
    m_nodes = max(len(node_flat), 1)
    key = lo * m_nodes + hi
    bits = 62 - int(np.ceil(np.log2(float(m_nodes) ** 2 + 1)))
    if bits >= 12 and len(clear):
        top = float(clear.max()) or 1.0
        rank = ((1.0 - clear / top) * (2 ** bits - 1)).astype(np.int64)
        order = np.argsort((key << bits) | rank, kind='stable')
    else:
        order = np.lexsort((-clear, key))
    key, u, v, clear = key[order], u[order], v[order], clear[order]
    # Orient every witness as (side of lo, side of hi).
    flip = compact[root[u]] != key // m_nodes
    u2 = np.where(flip, v, u)
    v2 = np.where(flip, u, v)
    starts = np.flatnonzero(np.r_[True, key[1:] != key[:-1]])
    pkey = key[starts]
    return Roadmap(fields=fields, periodic=periodic, phi_scale=phi_scale,
                   node_mask=node, succ=succ, root=root,
                   pair_lo=node_flat[pkey // m_nodes], pair_hi=node_flat[pkey % m_nodes],
                   pair_start=np.r_[starts, len(key)],
                   wit_u=u2, wit_v=v2, wit_clearance=clear)
