"""Hierarchical decomposition graph (Section IV-C) and its incremental construction (Sec. V).

Two kinds of nodes: *vast* nodes (connected components of the vast region
``VR = {x in FCS_r : D(x) > delta}``, each holding a Reeb graph of its Morse cells) and
*narrow* nodes (components of ``NR = FCS_r \\ VR``, each holding a piece of the GVD with its
meet points). A vast and a narrow node whose cells touch are joined by an edge carrying the
*cusp points* (GVD points with ``D = delta``) between them, those sensed by the ring and those
predicted from the map; two nodes of the same kind are never adjacent.

The planner rebuilds the components from its growing sensor map; this class keeps node
*identity* across rebuilds (a node is anchored at the point where it was first sensed, e.g. the
start or a cusp point; components that grow together merge their nodes), the covered flags of
Algorithm 1, the cusp edges, and answers ``FindUncoveredNode`` and paths through the graph.
"""
from __future__ import annotations

from collections import deque
from collections.abc import Callable, Collection, Iterable, Sequence
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike

XY = tuple[float, float]
"""A point (x, y) in the map frame, metres."""


@dataclass
class GraphNode:
    """One vast or narrow cell of the hierarchical decomposition."""

    id: int
    kind: str                      # 'vast' or 'narrow'
    anchor: tuple                  # (x, y) where the node was first sensed
    covered: bool = False
    alive: bool = True             # False once merged into another node or no longer sensed
    merged_into: int = -1
    centroid: tuple = (0.0, 0.0)
    label_point: tuple = (0.0, 0.0)  # a point of the cell nearest its centroid
    area: float = 0.0
    reeb_points: list = field(default_factory=list)    # vast: [(x, y, kind)] critical points
    reeb_edges: list = field(default_factory=list)     # vast: Morse cells as (i, j) point pairs
    meet_points: list = field(default_factory=list)    # narrow: [(x, y)]


def _label_near(labels, cell, window):
    """Most common non-zero label within ``window`` cells of ``cell`` (0 if none).

    Thin components (GVD edges) shift by a cell when the map is refined; looking in a small
    window keeps a node attached to its component.
    """
    if cell is None:
        return 0
    i, j = cell
    win = labels[max(i - window, 0):i + window + 1, max(j - window, 0):j + window + 1]
    if labels[i, j]:
        return int(labels[i, j])
    vals = win[win > 0]
    if vals.size == 0:
        return 0
    return int(np.bincount(vals).argmax())


class HierarchicalGraph:
    """Nodes, cusp edges, covered flags; node identity kept across map rebuilds."""

    def __init__(self):
        self.nodes = {}
        self.edges = {}            # (vast_id, narrow_id) -> {'sensed', 'predicted', 'shared'}
        self._next = 0

    def create_node(self, kind: str, anchor: Sequence[float]) -> GraphNode:
        """CreateNode of Algorithm 1: a new uncovered node of the given kind."""
        node = GraphNode(self._next, kind, (float(anchor[0]), float(anchor[1])))
        self.nodes[node.id] = node
        self._next += 1
        return node

    def alive(self, kind: str | None = None) -> list[GraphNode]:
        return [n for n in self.nodes.values() if n.alive and (kind is None or n.kind == kind)]

    def update(self, kind: str, labels: np.ndarray,
               to_cell: Callable[[float, float], tuple[int, int] | None],
               to_world: Callable[[np.ndarray, np.ndarray], np.ndarray], resolution: float,
               seeds: Iterable[Sequence[float]] = (), window: int = 3) -> dict[int, int]:
        """Match the components ``labels`` (0 = none) of one kind to graph nodes.

        ``to_cell(x, y) -> (row, col) or None`` and ``to_world(rows, cols) -> (n, 2)`` convert
        between the map and the grid crop. Components holding the anchors of existing nodes
        keep the smallest such id (the others are merged into it); a component without any
        anchor is a newly sensed cell and gets a new node anchored at its first seed in it
        (a cusp point or the robot) or at its centroid. Returns ``{label: node_id}``.
        """
        n_lab = int(labels.max()) if labels.size else 0
        owners = {}
        for node in self.alive(kind):
            lab = _label_near(labels, to_cell(*node.anchor), window)
            if lab == 0:
                node.alive = False          # the sensed cell it stood for has vanished
                continue
            owners.setdefault(lab, []).append(node.id)
        mapping = {}
        if n_lab == 0:
            return mapping
        from scipy import ndimage
        idx = np.arange(1, n_lab + 1)
        cents = ndimage.center_of_mass(np.ones_like(labels), labels, idx)
        sizes = ndimage.sum(np.ones_like(labels), labels, idx)
        for lab in range(1, n_lab + 1):
            ids = sorted(owners.get(lab, []))
            if ids:
                keep = self.nodes[ids[0]]
                for other in ids[1:]:
                    o = self.nodes[other]
                    o.alive = False
                    o.merged_into = keep.id
                    self._merge_edges(other, keep.id)
            else:
                anchor = None
                for s in seeds:
                    if _label_near(labels, to_cell(*s), window) == lab:
                        anchor = s
                        break
                if anchor is None:
                    rr, cc = np.nonzero(labels == lab)
                    anchor = tuple(to_world(rr[:1], cc[:1])[0])
                keep = self.create_node(kind, anchor)
            c = to_world(np.array([cents[lab - 1][0]]), np.array([cents[lab - 1][1]]))[0]
            keep.centroid = (float(c[0]), float(c[1]))
            # A point of the cell itself, nearest its centroid (the centroid of a ring-shaped
            # cell lies outside it): where pictures and markers put the node.
            rr, cc = np.nonzero(labels == lab)
            k = int(np.argmin((rr - cents[lab - 1][0]) ** 2 + (cc - cents[lab - 1][1]) ** 2))
            q = to_world(rr[k:k + 1], cc[k:k + 1])[0]
            keep.label_point = (float(q[0]), float(q[1]))
            keep.area = float(sizes[lab - 1]) * resolution ** 2
            mapping[lab] = keep.id
        return mapping

    def _merge_edges(self, old, new):
        for (v, n), edge in list(self.edges.items()):
            if old in (v, n):
                del self.edges[(v, n)]
                key = (new if v == old else v, new if n == old else n)
                self.link(key[0], key[1], edge['sensed'], edge['predicted'], edge['shared'])

    def link(self, vast_id: int, narrow_id: int, sensed: Iterable[Sequence[float]] = (),
             predicted: Iterable[Sequence[float]] = (), shared: Sequence[float] | None = None,
             merge_radius: float = 0.5) -> dict[str, list[XY] | XY | None]:
        """Edge between a vast node and a narrow node whose cells touch, with the cusp points
        between them: ``sensed`` by the ring (events), ``predicted`` on the GVD at D = delta
        from memory (not yet sensed), and a point of the shared boundary (``shared``)."""
        edge = self.edges.setdefault((vast_id, narrow_id),
                                     {'sensed': [], 'predicted': [], 'shared': shared})
        for key, pts in (('sensed', sensed), ('predicted', predicted)):
            for c in pts:
                if all(np.hypot(c[0] - e[0], c[1] - e[1]) > merge_radius
                       for e in edge['sensed'] + edge['predicted']):
                    edge[key].append((float(c[0]), float(c[1])))
        if shared is not None:
            edge['shared'] = (float(shared[0]), float(shared[1]))
        return edge

    def add_cusp(self, vast_id: int, narrow_id: int,
                 cusps: tuple[float, float] | Iterable[Sequence[float]]) -> None:
        """Record sensed cusp point(s) linking a vast node and a narrow node."""
        if isinstance(cusps, tuple):
            cusps = [cusps]
        self.link(vast_id, narrow_id, sensed=cusps)

    def cusp_points(self, vast_id: int, narrow_id: int) -> list[XY]:
        """All cusp points of an edge (sensed first)."""
        e = self.edges.get((vast_id, narrow_id))
        return [] if e is None else e['sensed'] + e['predicted']

    def crossing(self, a: int, b: int, here: ArrayLike) -> XY | None:
        """Where the route crosses from node ``a`` to node ``b``: the cusp point of their edge
        nearest to ``here`` (or a shared boundary point when the edge has no cusp)."""
        e = self.edges.get((a, b)) or self.edges.get((b, a))
        if e is None:
            return None
        pts = e['sensed'] + e['predicted']
        if not pts:
            return e['shared']
        return min(pts, key=lambda c: np.hypot(c[0] - here[0], c[1] - here[1]))

    def route_crossings(self, hops: Sequence[int], here: Sequence[float]) -> list[XY]:
        """The crossing points of a graph route ``hops`` (node ids): one cusp point (or shared
        boundary point) per edge, chosen together so that the straight-line length
        ``here -> c1 -> c2 -> ...`` is least (dynamic programming over the edges)."""
        options = []
        for a, b in zip(hops[:-1], hops[1:]):
            e = self.edges.get((a, b)) or self.edges.get((b, a))
            if e is None:
                return []
            pts = e['sensed'] + e['predicted'] or ([e['shared']] if e['shared'] else [])
            if not pts:
                return []
            options.append(pts)
        if not options:
            return []
        best = [(float(np.hypot(p[0] - here[0], p[1] - here[1])), [p]) for p in options[0]]
        for pts in options[1:]:
            best = [min(((c + float(np.hypot(p[0] - q[-1][0], p[1] - q[-1][1])), q + [p])
                         for c, q in best), key=lambda v: v[0]) for p in pts]
        return min(best, key=lambda v: v[0])[1]

    def resolve(self, node_id: int) -> int | None:
        """The live node standing for ``node_id`` (following merges), or None."""
        node = self.nodes.get(node_id)
        while node is not None and not node.alive and node.merged_into >= 0:
            node = self.nodes[node.merged_into]
        return node.id if node is not None and node.alive else None

    def neighbours(self, node_id: int) -> set[int]:
        out = set()
        for (v, n) in self.edges:
            if v == node_id and self.nodes[n].alive:
                out.add(n)
            elif n == node_id and self.nodes[v].alive:
                out.add(v)
        return out

    def graph_path(self, start: int, goal: int) -> list[int]:
        """Shortest path (fewest cusp crossings) between two nodes; [] if not connected."""
        if start == goal:
            return [start]
        prev = {start: None}
        q = deque([start])
        while q:
            u = q.popleft()
            for v in sorted(self.neighbours(u)):
                if v not in prev:
                    prev[v] = u
                    if v == goal:
                        path = [v]
                        while prev[path[-1]] is not None:
                            path.append(prev[path[-1]])
                        return path[::-1]
                    q.append(v)
        return []

    def find_uncovered_node(self, current: int | None,
                            distance: Callable[[GraphNode], float] | None = None,
                            skip: Collection[int] = ()) -> GraphNode | None:
        """FindUncoveredNode of Algorithm 1: the uncovered node to visit next, or None.

        Prefers the node fewest graph edges away from ``current``; ties (and nodes the graph
        does not connect yet) are broken by ``distance(node) -> metres`` when given. Nodes in
        ``skip`` (given up) are not offered.
        """
        cands = [n for n in self.alive() if not n.covered and n.id not in skip]
        if not cands:
            return None

        def key(n):
            hops = len(self.graph_path(current, n.id)) if current is not None else 0
            hops = hops if hops > 0 else 10 ** 6
            return (hops, distance(n) if distance else 0.0, n.id)
        return min(cands, key=key)

    def to_dict(self) -> dict[str, list[dict[str, object]]]:
        """JSON-friendly snapshot: nodes (type vast/narrow) and edges with their cusp points."""
        return {
            'nodes': [{'id': n.id, 'type': n.kind, 'kind': n.kind, 'covered': n.covered,
                       'anchor': list(n.anchor), 'centroid': list(n.centroid),
                       'label_point': list(n.label_point),
                       'area_m2': round(n.area, 3), 'alive': n.alive,
                       'merged_into': n.merged_into,
                       'critical_points': [list(p) for p in n.reeb_points],
                       'reeb_edges': [list(e) for e in n.reeb_edges],
                       'meet_points': [list(p) for p in n.meet_points]}
                      for n in self.nodes.values()],
            'edges': [{'vast': v, 'narrow': n,
                       'cusp_points': [list(c) for c in e['sensed'] + e['predicted']],
                       'sensed_cusp_points': [list(c) for c in e['sensed']],
                       'shared_boundary_point': list(e['shared']) if e['shared'] else None}
                      for (v, n), e in self.edges.items()
                      if self.nodes[v].alive and self.nodes[n].alive],
        }
