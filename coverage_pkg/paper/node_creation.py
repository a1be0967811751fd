"""CreateNode(x, D(x)) of Algorithm 1 and the edges (L, F) that carry cusp points.

A new node is vast where ``D > delta`` and narrow otherwise; it is created for the start and
for every new cusp point: a cusp sensed while covering a vast node creates a narrow node, one
sensed while tracing a narrow node creates a vast node, and the edge between them carries the
cusp. A cusp that ends a traced GVD branch of a known narrow node joins that node instead.
"""
from __future__ import annotations

import math
from collections.abc import Sequence

from coverage_pkg.paper.graph_nodes import Branch, Node


class CreateNode:
    """Mixin of :class:`coverage_pkg.algorithm1.PaperPlanner`: nodes and cusp edges."""

    _opening_untraced = False   # the cusp being handled lies on an opening of a sliver no
    #                             traced GVD edge runs along (MorseDecompCoverage)

    def create_node(self, kind: str, x: Sequence[float], created_by: int | None = None) -> Node:
        """CreateNode(x, D(x)): a new uncovered node of ``kind`` anchored at ``x``."""
        n = Node(len(self.nodes), kind, (float(x[0]), float(x[1])), created_by)
        self.nodes.append(n)
        self._record(self.t_sweep or 0.0, 'node_created', x,
                     f'{kind} node {n.id}' + ('' if created_by is None else
                                              f' by event {created_by}'))
        return n

    def _on_cusp(self, idx, xy):
        """A new cusp point: a node of the other kind beyond it and an edge to it (L, F).
        A cusp sensed from a vast node where a traced GVD branch of a known narrow node ended
        is that narrow cell's cusp: the edge joins the known node, no node is created (not
        for an opening of a sliver along which no GVD edge is traced)."""
        n = self.nodes[self.current] if self.current is not None else None
        if n is None:
            return
        m = self._traced_narrow(xy) if n.kind == 'vast' and not self._opening_untraced \
            else None
        if m is not None:
            self._add_edge(n.id, m.id, xy, f'cusp joins narrow node {m.id}: a traced GVD '
                           'branch of it ends here')
            return
        v = self._followed_vast(xy) if n.kind == 'narrow' and self.mode == 'gvd' else None
        if v is not None:
            self._add_edge(v.id, n.id, xy, f'cusp joins vast node {v.id}: its boundary '
                           'circuit passed here')
            self._end_branch('cusp')
            return
        new = self.create_node('narrow' if n.kind == 'vast' else 'vast', xy, idx)
        self.edges.append((n.id, new.id, xy) if n.kind == 'vast' else (new.id, n.id, xy))
        self._note_dir(xy)
        if new.kind == 'narrow':
            into = None if self._cusp_dir is None else (math.cos(self._cusp_dir),
                                                        math.sin(self._cusp_dir))
            new.branches.append(Branch(xy, into, idx))   # leaves along the cusp's GVD edge
        if n.kind == 'narrow' and self.mode == 'gvd':
            self._end_branch('cusp')
            if self.cfg.handover:
                self._hand_over(new)
        elif new.kind == 'narrow' and self.cfg.cusp_detour and self.mode == 'boundary' and \
                'origin' in self.task and self.task.get('circuit') is not None:
            self._detour(n, new)

    def _cusp_meet(self, t, xy):
        """A cusp the ring senses where three closest obstacles are equidistant (within the
        event tolerance) is also a meet point (Section III), at D = delta: a door's GVD edge
        and a corner's leave the vast cell there together (a door beside a corner of a small
        room), and the three-echo test takes no meet point there (its three obstacles lie
        within half a turn). Every GVD edge leaving a meet point runs between two of its
        closest obstacles. D grows only away from all three, inside the gap between them
        wider than half a turn: that gap faces the vast cell; each other gap is a GVD edge
        into the narrow region, of the narrow node whose cusp edge this is. The edges known
        there are the gaps nearest them: the cusp's own untraced branch (along the bisector
        of its two closest obstacles; with ``cusp_meet_gap``, ours, it then leaves along
        that gap, since the bisector can point at the wall between a corner's gap and a
        door's beside it) and a branch traced into the cusp (the way it came); every other
        gap becomes a branch (a meet event). Read once per cusp edge, from the
        vast node's side (covered, or handed over to where a traced branch ends). In a small
        vast cell whose corners' cusps lie within a step of one another, a gap added here
        can be another cusp's edge; such a branch ends untraced
        (``TraceGVD._other_cusps_edge``). Switch ``cusp_meet`` (ours, on by default)."""
        n = self.nodes[self.current] if self.current is not None else None
        if n is None or n.kind != 'vast' or 'meet' in self.cfg.without or \
                not self.cfg.cusp_meet:
            return
        gaps = self._meet_gaps()
        if gaps is None:
            return
        near = self.cfg.same_event
        cands = [(math.dist(c, xy), w, c) for v, w, c in self.edges
                 if self.same_node(v) == self.same_node(n.id) and math.dist(c, xy) < near]
        if not cands:
            return
        _, w, c = min(cands)
        key = (w, round(float(c[0]), 3), round(float(c[1]), 3))
        if key in self._cusp_meets or self.nodes[w].kind != 'narrow':
            return
        m = self.nodes[w]
        own = [b for b in m.branches if b.end is None and math.dist(b.start, c) < near]
        came = [b for b in m.branches if b.end == 'cusp' and b.end_xy is not None and
                b.end_heading is not None and math.dist(b.end_xy, xy) < near]
        for b in own:                    # cusp_meet_gap: its own edge is the nearest gap
            if self.cfg.cusp_meet_gap and b.heading is not None:
                k = math.atan2(b.heading[1], b.heading[0])
                g = min(gaps, key=lambda g: abs(math.remainder(g - k, 2 * math.pi)))
                b.heading = (math.cos(g), math.sin(g))
        known = [math.atan2(b.heading[1], b.heading[0]) for b in own if b.heading is not None]
        known += [math.atan2(-b.end_heading[1], -b.end_heading[0]) for b in came]
        if not known:
            return
        self._cusp_meets.add(key)
        for k in known:                  # the edges known at the cusp: the nearest gaps
            if gaps:
                gaps.remove(min(gaps, key=lambda g: abs(math.remainder(g - k, 2 * math.pi))))
        if not gaps:
            return
        idx = self._record(t, 'meet', xy, 'three closest obstacles equidistant at the cusp '
                           '(D = delta): GVD edges at ' +
                           ', '.join(f'{math.degrees(g) % 360:.0f}' for g in gaps) + ' deg')
        m.meets.append((float(xy[0]), float(xy[1]), idx))
        self._cusp_meets_ev.add(idx)
        for g in gaps:
            m.branches.append(Branch(tuple(c), (math.cos(g), math.sin(g)), idx))
        m.covered = False

    def _meet_gaps(self):
        """Bisectors of the gaps between the sweep's three closest obstacles, when they are
        equidistant within the event tolerance, except the gap wider than half a turn (none
        such: None, as when they are not equidistant)."""
        mins = self.mins[:3]
        if len(mins) < 3 or mins[2][0] - mins[0][0] > self.cfg.event_tolerance:
            return None
        b = sorted(a % (2 * math.pi) for _, a in mins)
        spans = [(b[i], (b[(i + 1) % 3] - b[i]) % (2 * math.pi)) for i in range(3)]
        if not any(w > math.pi for _, w in spans):
            return None
        return [a + w / 2 for a, w in spans if w <= math.pi]

    def _detour(self, n, new):
        """Switch ``cusp_detour`` (ours, not the paper's): the boundary circuit of vast
        node ``n`` has sensed the cusp of narrow node ``new``; the circuit is suspended where
        the robot stands and ``new`` is covered at once, so that the robot does not drive
        round the circuit a second time to reach the cusps it passed. The circuit resumes
        from the same place when FindUncoveredNode returns to ``n`` (Algorithm 1 and Fig. 13
        finish the vast cell first, then come back to the cusp)."""
        circ = self.task['circuit']
        circ['suspended'] = (tuple(self.pose[:2]), dict(self.task))
        self.decisions.append((round(float(self.t_sweep or 0.0), 3), new.id, new.kind,
                               new.anchor[0], new.anchor[1]))
        self.current = new.id
        self._begin_node(new)

    def _hand_over(self, new):
        """Fig. 13's order (switch ``handover``): the vast node beyond a cusp sensed while
        tracing is covered at once, from where the robot stands; the narrow node keeps its
        open branches and is resumed when FindUncoveredNode returns to it."""
        self.decisions.append((round(float(self.t_sweep or 0.0), 3), new.id, new.kind,
                               new.anchor[0], new.anchor[1]))
        self.current = new.id
        self._begin_node(new)

    def _traced_narrow(self, xy):
        """The narrow node whose traced GVD branch ended at this cusp (the cusp event that
        ended it, or the branch's last point, within ``same_event``), if any."""
        near = self.cfg.same_event
        for v, w, c in self.edges:
            if math.dist(c, xy) < near and self._created_from(v, w, self._cusp_dir):
                return self.nodes[w]
        for m in self.nodes:
            if m.kind == 'narrow' and any(self._arrived(b, xy, near, self._cusp_dir,
                                                        self.cfg.radius)
                                          for b in m.branches):
                return m
        return None

    def _followed_vast(self, xy, within=0.4):
        """Switch ``circuit_join`` (ours): the vast node whose boundary circuit passed within
        ``within`` of the cusp ``xy`` sensed while tracing. A cusp lies on the curve
        D = delta of the one vast cell beyond it (Section IV-B), so that cell is the node
        the circuit went round: the cusp gives it an edge, and no node is created for a
        cell known already (one node per cell, Section IV-C)."""
        if not self.cfg.circuit_join:
            return None
        for m in self.nodes:
            if m.kind == 'vast' and m.merged_into is None and any(
                    math.dist(q, xy) < within for c in m.circuits for q in c.get('trace', ())):
                return m
        return None

    def _gvd_direction(self):
        """Bearing from a cusp into its narrow cell: between its two closest obstacles."""
        if len(self.mins) < 2:
            return None
        (_, a1), (_, a2) = self.mins[:2]
        v = (math.cos(a1) + math.cos(a2), math.sin(a1) + math.sin(a2))
        return math.atan2(v[1], v[0]) if math.hypot(*v) > 0.2 else None

    @staticmethod
    def _arrived(b, xy, near, into, width=None):
        """Branch ``b`` ended at the cusp ``xy`` on the same GVD edge: within ``near`` of it,
        traced out of the narrow cell opposite to the cusp's bearing ``into`` it (the cusps
        of a small vast cell lie within a step of one another, each on its own edge), and,
        given the robot's radius ``width``, on the line it was traced along
        (:meth:`_on_traced_line`)."""
        if b.end != 'cusp' or b.end_xy is None or math.dist(b.end_xy, xy) >= near:
            return False
        if width is not None and not CreateNode._on_traced_line(b, xy, width):
            return False
        if into is None or b.end_heading is None:
            return True
        out = math.atan2(b.end_heading[1], b.end_heading[0])
        return abs(math.remainder(out - into - math.pi, 2 * math.pi)) < math.radians(45)

    @staticmethod
    def _on_traced_line(b, xy, width):
        """The cusp ``xy`` lies within ``width`` (the robot's radius) of the line through
        where branch ``b`` ended along the heading it was traced in. The robot tracing a GVD
        edge sweeps a strip of its radius either side of the edge, and the edge goes on
        through its cusp, so the cusp of the same edge lies in that strip continued past the
        branch's end (how far along it depends on when it is sensed); a cusp farther across
        lies on another edge (ours). A door in a room's wall 2 m from a corner leaves the
        vast room 0.5 m from the corner edge's cusp, its edge 43 degrees from the corner
        edge's reversed heading, its cusp 0.44 m across the corner edge's line."""
        if b.end_heading is None:
            return True
        hx, hy = b.end_heading
        n = math.hypot(hx, hy)
        if n == 0:
            return True
        dx, dy = xy[0] - b.end_xy[0], xy[1] - b.end_xy[1]
        off = abs(hx * dy - hy * dx) / n
        return off < width

    def _created_from(self, v, w, into=None):
        """Vast node ``v`` was created while narrow node ``w`` was traced (its cusp ended a
        GVD branch of ``w``, on the edge that leaves the cusp along ``into``)."""
        ev = self.nodes[v].created_by
        return ev is not None and any(self._arrived(b, self.events[ev][2:4], 1.0, into)
                                      for b in self.nodes[w].branches)

    def _join_known_cusp(self, xy):
        """A known cusp sensed while tracing a narrow node: the vast nodes it belongs to get
        their edge to this node (F of Algorithm 1), once."""
        n = self.nodes[self.current] if self.current is not None else None
        if n is None or n.kind != 'narrow' or self.mode != 'gvd':
            return
        near = self.cfg.same_event
        vast = {v for v, _, c in self.edges if math.dist(c, xy) < near}
        vast |= {m.id for m in self.nodes if m.kind == 'vast' and m.created_by is not None
                 and math.dist(self.events[m.created_by][2:4], xy) < near}
        for v in sorted(vast):
            self._add_edge(v, n.id, xy, f'known cusp: vast node {v} joins narrow node {n.id}')

    def _cusp_edge_traced(self, br):
        """Branch ``br`` of the narrow node being traced has ended at a cusp that a vast
        node's circuit sensed before, and that cusp created a narrow node of its own: its
        GVD edge is the one just traced, from its other end, so the two narrow nodes are one
        narrow cell (a cusp joins one vast cell and one narrow cell, Section IV-C) and the
        cusp's own branch is traced. The cusp is the one within ``same_event`` of the
        branch's end whose bearing into its narrow cell points, within 45 degrees and
        nearest, at where the robot was 0.8 m of path before the end: the edge it came
        along. (The heading at the end does not tell: near a cusp the GVD bends, and the
        cusps of a small vast cell lie a step apart, each on its own edge.) The merged node
        keeps being covered. Switch ``cusp_edge_traced`` (ours, off by default)."""
        n = self.nodes[self.current] if self.current is not None else None
        if not self.cfg.cusp_edge_traced or n is None or n.kind != 'narrow' or \
                br.end_xy is None:
            return
        k = self.paths.back_index(0.8)
        if k is None:
            return
        came, near, best = self.paths.xy[k], self.cfg.same_event, None
        for _, w, c in self.edges:
            m = self.nodes[self.same_node(w)]
            into = self._cusp_dirs.get((round(c[0], 3), round(c[1], 3)))
            if m.id == self.same_node(n.id) or m.kind != 'narrow' or into is None or \
                    math.dist(c, br.end_xy) >= near or math.dist(c, came) < 0.5:
                continue
            off = abs(math.remainder(math.atan2(came[1] - c[1], came[0] - c[0]) - into,
                                     2 * math.pi))
            if off < math.radians(45) and (best is None or off < best[0]):
                best = (off, m, c, into)
        if best is None:
            return
        _, m, c, into = best
        for b in m.branches:            # the cusp's own branch: leaves c along ``into``
            if b.end is None and math.dist(b.start, c) < near and (
                    b.heading is None or
                    b.heading[0] * math.cos(into) + b.heading[1] * math.sin(into) > 0.7):
                b.end, b.end_xy = 'traced', tuple(b.start)
                self._record(self.t_sweep or 0.0, 'branch_end', b.start,
                             'GVD branch ends: its cusp edge is traced from its other end')
        n = self._merge_narrow(self.nodes[self.same_node(n.id)], m,
                               "its cusp's GVD edge is that node's, traced into it")
        self.current = n.id

    def same_node(self, i: int) -> int:
        """The node that node ``i`` was found to be (a vast node whose cusp lies on another
        vast node's boundary circuit is that node), else ``i``."""
        while self.nodes[i].merged_into is not None:
            i = self.nodes[i].merged_into
        return i

    def _dedupe_edges(self):
        """One edge per cusp between a vast node and a narrow node: once two vast nodes are
        found to be one, an edge of each carrying the same cusp is kept once (the first)."""
        kept = []
        for v, w, c in self.edges:
            if not any(self.same_node(a) == self.same_node(v) and b == w and
                       math.dist(k, c) < self.cfg.same_event for a, b, k in kept):
                kept.append((v, w, c))
        self.edges[:] = kept

    def _add_edge(self, v, w, xy, detail):
        """Edge (vast v, narrow w) carrying the cusp xy, unless one carries a cusp near it."""
        if any(self.same_node(a) == self.same_node(v) and b == w and
               math.dist(c, xy) < self.cfg.same_event for a, b, c in self.edges):
            return
        self.edges.append((v, w, (float(xy[0]), float(xy[1]))))
        self._note_dir(xy)
        self._record(self.t_sweep, 'cusp_joins', xy, detail)

    def _note_dir(self, xy):
        if self._cusp_dir is not None:
            self._cusp_dirs[(round(float(xy[0]), 3), round(float(xy[1]), 3))] = self._cusp_dir
