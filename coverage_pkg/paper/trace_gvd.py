"""TraceGVD(n, L, F) of Algorithm 1: covering a narrow node by tracing its GVD edges.

From a cusp point the robot follows the GVD edge by a control law on its two closest echoes;
a *meet point* (three closest obstacles equidistant) adds the GVD branches leaving it; a
branch ends at a cusp point (D rises above delta, Fig. 11), a dead end, a meet point already
known, or on an edge traced before. A gap beyond delta beside a dead end (a door by a corner)
is a branch too (a meet event). The narrow node is covered when every branch has ended.
"""
from __future__ import annotations

import math

import numpy as np

from coverage_pkg.paper.graph_nodes import Branch


class TraceGVD:
    """Mixin of :class:`coverage_pkg.algorithm1.PaperPlanner`: GVD edges, meet points."""

    def _gvd_step(self, n):
        """TraceGVD: follow the GVD edge of the two closest echoes; branches end at a cusp
        point, a dead end or a known meet point; meet points add branches."""
        br = self.task.get('branch')
        if br is None:
            open_ = self._open_branches(n)
            if not open_:
                n.covered = True
                return None
            cost = self._path_costs([b.start for b in open_])
            br = min(zip(cost, range(len(open_)), open_))[2]   # nearest along traced paths
            self.task = {'branch': br}
            self._go_to(br.start, then='gvd')
            self.task['branch'] = br
            return None
        self.mode = 'gvd'
        head = self.task.get('heading') or br.heading
        leave = self.task.setdefault('leave', self.pose[:2])
        if head is not None and math.dist(leave, self.pose[:2]) < 0.6:
            return np.asarray(head) * self.cfg.max_speed   # off the meet point, onto its edge
        mins = self.gvd_mins
        n1 = np.array([math.cos(mins[0][1]), math.sin(mins[0][1])]) if mins else np.zeros(2)
        diff = n1 - np.array([math.cos(mins[1][1]), math.sin(mins[1][1])]) \
            if len(mins) >= 2 else np.zeros(2)
        if np.linalg.norm(diff) < 1e-6:
            return self._end_branch('dead_end')
        (d1, a1), (d2, a2) = mins[:2]
        n2 = np.array([math.cos(a2), math.sin(a2)])
        tang = np.array([-diff[1], diff[0]]) / np.linalg.norm(diff)
        if head is None:                  # from a cusp: into the narrow region (D falls)
            head = tang if tang @ (n1 + n2) >= 0 else -tang
            if br.opened_by is None:      # the start: the GVD edge leaves it both ways,
                n.branches.append(Branch(self.pose[:2], tuple(-np.asarray(head)), None))
                a = math.atan2(head[1], head[0])      # and other edges through its gaps
                for b in self._free_bearings([a], self.det):
                    if abs(math.remainder(b - a - math.pi, 2 * math.pi)) > math.radians(30):
                        n.branches.append(Branch(self.pose[:2], (math.cos(b), math.sin(b)),
                                                 None))
        if tang @ np.asarray(head) < 0:
            tang = -tang
        self.task['heading'] = tuple(tang)
        origin = self.task.setdefault('from', self.pose[:2])
        self.task['far'] = max(self.task.get('far', 0.0), math.dist(origin, self.pose[:2]))
        if self.echo(math.atan2(tang[1], tang[0])) <= self.cfg.radius + 0.35 or \
                self._ahead_in_view(tang):
            self._gap_at_end(n, tang)
            return self._end_branch('dead_end')
        if 'cusp' not in self.cfg.without and self.D > self.det + 0.1 and \
                self.task['far'] > 1.0:
            return self._cusp_ahead(tang)         # Fig. 11: D rose above delta
        if self.task['far'] > 3.0 and math.dist(origin, self.pose[:2]) < 0.5:
            return self._end_branch('loop')
        start = self.task.setdefault('sweep0', self.sweeps)
        if self.task['far'] > 1.0 and self._near_trace(self.pose[:2], 0.35, start, tang) and \
                self._near_trace(self.pose[:2] - 0.6 * tang, 0.35, start, tang):
            owner = self._trace_owner(self.pose[:2], 0.35, start, tang)
            self._end_branch('traced')            # on a GVD edge traced before: joined it
            return self._same_narrow(n, owner)
        for m in n.meets:
            if math.dist(m[:2], self.pose[:2]) < 0.5 and \
                    math.dist(m[:2], br.start) > 0.7 and m[2] != self.task.get('meet'):
                return self._end_branch('meet')
        corr = diff / np.linalg.norm(diff) * (d1 - d2) * 2.0
        return tang * self.cfg.max_speed + corr

    def _open_branches(self, n):
        """The untraced branches of narrow node ``n``. A branch whose GVD edge the robot has
        traced already (0.8, 1.6 and 2.4 m out along its heading all lie within 0.4 m of a
        traced GVD edge: an edge reached from its other end, or from another meet point
        sensed on it) is that edge: it ends 'traced' and is not traced again."""
        out = []
        for b in n.branches:
            if b.end is None and b.heading is not None and self._edge_traced(b.start,
                                                                             b.heading):
                b.end, b.end_xy = 'traced', tuple(b.start)
                self._record(self.t_sweep or 0.0, 'branch_end', b.start,
                             'GVD branch ends: its edge is traced already')
            if b.end is None:
                out.append(b)
        return out

    def _edge_traced(self, start, heading):
        """0.8, 1.6 and 2.4 m out along ``heading`` lie on a traced GVD edge; an edge that
        ends sooner at a known meet point (within 0.5 m of the way out, beyond 0.5 m from
        ``start``) is tested up to that meet point, at least at 0.8 m."""
        meets = [m[:2] for k in self.nodes for m in k.meets
                 if math.dist(m[:2], start) > 0.5]
        for s in (0.8, 1.6, 2.4):
            q = (start[0] + s * heading[0], start[1] + s * heading[1])
            if not self._near_trace(q, 0.4):
                return False
            if any(math.dist(m, q) < 0.5 for m in meets):
                return True
        return True

    def _near_trace(self, q, within, before=None, along=None):
        """A point of a traced GVD edge lies within ``within`` of ``q`` (traced before sweep
        ``before``, and along the direction ``along`` or against it within 30 degrees, if
        given: the same edge, not one that crosses it)."""
        return next(self._trace_points(q, within, before, along), None) is not None

    def _trace_owner(self, q, within, before=None, along=None):
        """The node that traced the nearest GVD edge point matching :meth:`_near_trace`'s
        test, None if no point matches."""
        _, p = min(self._trace_points(q, within, before, along), key=lambda m: m[0],
                   default=(None, None))
        return None if p is None else p[5]

    def _trace_points(self, q, within, before, along):
        """(distance, point) of each traced GVD edge point (x, y, sweep, heading x, heading y,
        tracing node) matching :meth:`_near_trace`'s test, from the 1 m buckets around ``q``."""
        bx, by = int(q[0] // 1.0), int(q[1] // 1.0)
        for gx in (bx - 1, bx, bx + 1):
            for gy in (by - 1, by, by + 1):
                for p in self.gvd_trace.get((gx, gy), ()):
                    d = math.dist(p[:2], q)
                    if d < within and (before is None or p[2] < before) and \
                            (along is None or abs(p[3] * along[0] + p[4] * along[1]) > 0.87):
                        yield d, p

    def _same_narrow(self, n, owner):
        """A trace of narrow node ``n`` has joined a GVD edge traced while covering narrow
        node ``owner``: the two are one narrow cell (a corridor entered through both of its
        cusps, Fig. 13's Cs2 and Cs3). ``n`` becomes that node: its branches, meet points and
        edges are the earlier node's, which goes on being covered."""
        if owner is None:
            return None
        m = self.nodes[self.same_node(owner)]
        if m is n or m.kind != 'narrow' or n.kind != 'narrow':
            return None
        lo, hi = (m, n) if m.id < n.id else (n, m)
        hi.merged_into, hi.covered = lo.id, True
        lo.branches.extend(hi.branches)
        lo.meets.extend(hi.meets)
        hi.branches, hi.meets = [], []
        self.edges[:] = [(v, lo.id if w == hi.id else w, c) for v, w, c in self.edges]
        self._dedupe_edges()
        hi.closed_by = self._record(self.t_sweep, 'same_cell', hi.anchor,
                                    f'narrow node {hi.id} is narrow node {lo.id}: its GVD '
                                    "trace joined that node's edge")
        lo.covered = False
        self.current = lo.id
        return None

    def _cusp_ahead(self, heading):
        """D has risen above delta on the GVD edge (Fig. 11): the robot has just passed its
        cusp point. Unless the ring's cusp test placed it already, it is sensed here."""
        self._cusp_dir = math.atan2(-heading[1], -heading[0])
        self._on_event(self.t_sweep, 'cusp', self.pose[:2], 'D rose above delta on the GVD '
                       'edge (Fig. 11)')
        self._cusp_dir = None
        return self._end_branch('cusp') if self.mode == 'gvd' else None

    def _gap_at_end(self, n, heading):
        """A GVD edge ends at an obstacle ahead; a gap between closest obstacles beyond
        delta off the way back (a door, a corridor opening next to the corner) is another
        GVD edge joining this one at a meet point here, which the three-echo test did not
        place: it becomes a branch of the node (a meet event)."""
        if 'meet' in self.cfg.without:
            return
        back = math.atan2(-heading[1], -heading[0])
        for b in self._free_bearings([back], self.det):
            if any(math.dist(q.start, self.pose[:2]) < 1.0 and q.heading is not None and
                   abs(math.remainder(math.atan2(q.heading[1], q.heading[0]) - b,
                                      2 * math.pi)) < math.radians(45) for q in n.branches):
                continue
            if self._been_along(b):
                continue
            idx = self._on_event(self.t_sweep, 'meet', self.pose[:2], 'a gap beyond delta '
                                 f'at {math.degrees(b):.0f} deg where the GVD edge ends')
            if idx is None:
                return
            n.meets.append((float(self.pose[0]), float(self.pose[1]), idx))
            n.branches.append(Branch(self.pose[:2], (math.cos(b), math.sin(b)), idx))

    def _been_along(self, bearing):
        """The robot's traced path passes 0.7 m or 1.4 m out along ``bearing``."""
        for s in (0.7, 1.4):
            q = (self.pose[0] + s * math.cos(bearing), self.pose[1] + s * math.sin(bearing))
            j = self.paths.nearest(q)
            if j is not None and math.dist(self.paths.xy[j], q) < 0.5:
                return True
        return False

    def _ahead_in_view(self, heading):
        """Every echo of the half-ring ahead lies within the detector's range (less a margin
        for the cones' width): the edge ends at an obstacle the detector already sees whole
        (a corner, a dead end), so the rest of it is covered from here."""
        ahead = np.cos(self.angles - math.atan2(heading[1], heading[0])) >= -0.05
        r = self.ranges[ahead & np.isfinite(self.ranges)]
        return bool(len(r)) and float(r.max()) < self.det - self.cfg.view_margin

    def _on_meet(self, idx, xy):
        """A meet point: the GVD edges leaving it (bisectors between the closest obstacles'
        bearings) become branches of the narrow node; the robot goes on along the one
        nearest its heading. Two branches equally near it (within half the cones' spacing,
        the ring's bearing resolution) are a symmetric fork: the robot takes the right-hand
        one, as at Fig. 13's Mp1 ('The robot chooses the lower edge', arriving along +x)."""
        n = self.nodes[self.current] if self.current is not None else None
        if n is None or n.kind != 'narrow' or self.task.get('branch') is None:
            return
        n.meets.append((float(xy[0]), float(xy[1]), idx))
        head = np.asarray(self.task.get('heading') or self.task['branch'].heading or (1.0, 0.0))
        back = math.atan2(-head[1], -head[0])
        out = self._free_bearings([back], self.det, one_door=True)
        if not out:
            return
        a = math.atan2(head[1], head[0])
        dev = [math.remainder(m - a, 2 * math.pi) for m in out]     # + left, - right
        order = sorted(range(len(out)), key=lambda i: abs(dev[i]))
        out, dev = [out[i] for i in order], [dev[i] for i in order]
        if len(out) > 1 and abs(dev[1]) - abs(dev[0]) < math.pi / len(self.mount) and \
                dev[0] > dev[1]:
            out[:2] = out[1::-1]       # a symmetric fork: the right-hand branch first
        for m in out[1:]:
            n.branches.append(Branch(tuple(xy), (math.cos(m), math.sin(m)), idx))
        self.task['heading'] = (math.cos(out[0]), math.sin(out[0]))
        self.task['meet'] = idx
        self.task['leave'] = self.pose[:2]

    def _free_bearings(self, exclude, beyond, one_door=False):
        """Bearings of the GVD edges leaving the robot's place: local maxima of the ring's
        range over bearing (a gap between two closest obstacles) reaching beyond ``beyond``
        (an edge whose end is in the detector's view is not one to trace), at least 60
        degrees from each bearing of ``exclude`` and 45 degrees from one another. With
        ``one_door`` (at a meet point), two maxima two cones apart with the cone between them
        also beyond ``beyond`` and the cones on either side of the three within it are one
        gap: a door seen from beside it, its jambs within ``beyond`` and the cone between
        meeting something behind the door. Its edge leaves along their mean bearing, between
        the two, not along the first of them, which runs diagonally past a jamb."""
        r = np.where(np.isfinite(self.ranges), self.ranges, 0.0)
        k = len(r)
        order = np.argsort(self.angles % (2 * math.pi))
        r, ang = r[order], (self.angles % (2 * math.pi))[order]
        gaps = []                                    # (cone, bearing) per gap
        for i in range(k):
            if r[i] < r[i - 1] or r[i] < r[(i + 1) % k] or r[i] <= beyond:
                continue
            if one_door and gaps and gaps[-1][0] == i - 2 and r[i - 1] > beyond and \
                    r[i - 3] <= beyond and r[(i + 1) % k] <= beyond:
                a = gaps[-1][1]
                gaps[-1] = (None, float((a + math.remainder(ang[i] - a, 2 * math.pi) / 2)
                                        % (2 * math.pi)))
            else:
                gaps.append((i, float(ang[i])))
        out = []
        for _, b in gaps:
            if any(abs(math.remainder(b - e, 2 * math.pi)) < math.radians(60)
                   for e in exclude):
                continue
            if all(abs(math.remainder(b - o, 2 * math.pi)) > math.radians(45) or
                   not self._one_opening(r, ang, b, o, beyond)
                   for o in out):
                out.append(b)
        return out

    @staticmethod
    def _one_opening(r, ang, b, o, beyond):
        """Every cone between bearings ``b`` and ``o`` (the shorter way round) reaches
        beyond ``beyond``: the two maxima look through one opening. A cone between them
        that meets an obstacle within ``beyond`` separates two openings, two GVD edges."""
        span = math.remainder(o - b, 2 * math.pi)
        rel = np.remainder(ang - b, 2 * math.pi) if span > 0 else \
            np.remainder(b - ang, 2 * math.pi)
        between = (rel > 1e-6) & (rel < abs(span) - 1e-6)
        return bool(np.all(r[between] > beyond))

    def _end_branch(self, how):
        br = self.task.get('branch')
        if br is not None:
            br.end, br.end_xy = how, (float(self.pose[0]), float(self.pose[1]))
            br.end_heading = self.task.get('heading')
            self._record(self.t_sweep, 'branch_end', self.pose, f'GVD branch ends: {how}')
        self.task, self.mode = {}, None
        return None
