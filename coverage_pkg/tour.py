"""Shortest open tour through a node's remaining work (a small travelling-salesman problem).

Used by the planner to order the pieces of a narrow node: the work cells are grouped into
chunks, the geodesic distance between chunks is computed on a coarse copy of the travel-cost
grid, and an open tour starting at the robot is built by nearest neighbour and improved by
2-opt. Plain numpy/scipy, no ROS.
"""
from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike
from scipy import ndimage
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import dijkstra

COARSE_CELL = 0.4   # m, cell of the coarse grid the chunk distances are computed on


def chunk_cells(mask: np.ndarray, size: int) -> list[np.ndarray]:
    """Split the True cells of ``mask`` into chunks: squares of ``size`` cells, each split
    again into its 8-connected parts. Returns a list of (n, 2) arrays of (row, col)."""
    lab, n = ndimage.label(mask, structure=np.ones((3, 3)))
    if n == 0:
        return []
    rr, cc = np.nonzero(mask)
    # One key per (component, square row, square column), in that order.
    _, key = np.unique(np.stack([lab[rr, cc], rr // size, cc // size], axis=1), axis=0,
                       return_inverse=True)
    key = key.ravel()
    order = np.argsort(key, kind='stable')
    key, rr, cc = key[order], rr[order], cc[order]
    cuts = np.flatnonzero(np.diff(key)) + 1
    return [np.stack([r, c], axis=1) for r, c in zip(np.split(rr, cuts), np.split(cc, cuts))]


def coarse_distances(cost: np.ndarray, cells: ArrayLike, factor: int) -> np.ndarray:
    """Geodesic distances (in fine cells x cost) between ``cells`` on the cost grid reduced by
    ``factor``. A coarse cell is passable if any of its fine cells is (its cost is the
    smallest); two neighbouring coarse cells are joined only where passable fine cells touch
    across their shared side (or corner), so an impassable band at least one coarse cell wide
    separates its two sides wherever it falls on the coarse grid (around an obstacle, FCS_r
    leaves a band 2 (r + clearance margin) = 0.7 m wide; the coarse cell is 0.4 m). Returns a
    (k, k) array (inf where unreachable)."""
    h, w = cost.shape
    H, W = -(-h // factor), -(-w // factor)
    pad = np.full((H * factor, W * factor), np.inf)
    pad[:h, :w] = cost
    fine = np.isfinite(pad)
    coarse = pad.reshape(H, factor, W, factor).min(axis=(1, 3))
    ok = np.isfinite(coarse)
    idx = -np.ones((H, W), dtype=np.int64)
    idx[ok] = np.arange(int(ok.sum()))
    f = factor
    # Fine contact across each coarse side / corner.
    across_c = (fine[:, f - 1:-1:f] & fine[:, f::f]).reshape(H, f, W - 1).any(axis=1)
    across_r = (fine[f - 1:-1:f, :] & fine[f::f, :]).reshape(H - 1, W, f).any(axis=2)
    corner_d = fine[f - 1:-1:f, f - 1:-1:f] & fine[f::f, f::f]
    corner_a = fine[f - 1:-1:f, f::f] & fine[f::f, f - 1:-1:f]
    links = (
        ((0, 1), across_c, (slice(None), slice(0, W - 1)), (slice(None), slice(1, W))),
        ((1, 0), across_r, (slice(0, H - 1), slice(None)), (slice(1, H), slice(None))),
        ((1, 1), corner_d, (slice(0, H - 1), slice(0, W - 1)), (slice(1, H), slice(1, W))),
        ((1, -1), corner_a, (slice(0, H - 1), slice(1, W)), (slice(1, H), slice(0, W - 1))),
    )
    rows, cols, wts = [], [], []
    for (di, dj), touch, sa, sb in links:
        rows.append(idx[sa][touch])
        cols.append(idx[sb][touch])
        step = f * np.hypot(di, dj)
        wts.append(step * 0.5 * (coarse[sa][touch] + coarse[sb][touch]))
    n = int(ok.sum())
    g = coo_matrix((np.concatenate(wts), (np.concatenate(rows), np.concatenate(cols))),
                   shape=(n, n)).tocsr()
    src = np.array([idx[r // factor, c // factor] for r, c in cells])
    out = np.full((len(cells), len(cells)), np.inf)
    good = src >= 0
    if good.any():
        dd = dijkstra(g, directed=False, indices=src[good])
        out[np.ix_(good, good)] = dd[:, src[good]]
    return out


def open_tour(dist: np.ndarray, end: int | None = None) -> list[int]:
    """Order of the nodes of an open tour starting at node 0 and visiting all, that is short
    under ``dist``; it ends at node ``end`` if given, else anywhere. Nearest neighbour, then
    2-opt on the open path."""
    n = len(dist)
    big = np.where(np.isfinite(dist), dist, 1e9)
    tour = [0]
    left = set(range(1, n)) - {end}
    while left:
        cur = tour[-1]
        nxt = min(left, key=lambda j: big[cur, j])
        tour.append(nxt)
        left.remove(nxt)
    if end is not None:
        tour.append(end)
    tour = np.array(tour)
    last = n - 1 if end is None else n - 2     # the last position a reversal may reach
    improved = True
    while improved:
        improved = False
        for i in range(1, last):
            a, b = tour[i - 1], tour[i]
            # reversing tour[i:j+1]; with a free end, j = n-1 reverses the tail
            c = tour[i:last + 1]
            d_next = np.r_[tour[i + 1:last + 1], tour[last + 1:last + 2], -1][:len(c)]
            nxt = np.maximum(d_next, 0)
            old = big[a, b] + np.where(d_next >= 0, big[c, nxt], 0.0)
            new = big[a, c] + np.where(d_next >= 0, big[b, nxt], 0.0)
            gain = old - new
            gain[0] = 0.0
            j = int(np.argmax(gain))
            if gain[j] > 1e-9:
                tour[i:i + j + 1] = tour[i:i + j + 1][::-1]
                improved = True
    return [int(v) for v in tour]
