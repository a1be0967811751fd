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

from coverage_pkg import gvd as gvdmod
from coverage_pkg.paper.graph_nodes import Branch


class TraceGVD:
    """Mixin of :class:`coverage_pkg.algorithm1.PaperPlanner`: GVD edges, meet points."""

    #: off a meet point, the robot keeps a branch's bearing only while its closest obstacle
    #: is at least this share of its second closest's distance away (fitted: 0.3-0.5 cover
    #: gen_mixed_1181, 0 leaves it at 22.80 %, 0.5 leaves gen_halls_1012 at 98.62 %)
    keep_ratio = 0.4
    #: on a traced GVD edge D must exceed delta by this before the trace senses Fig. 11's
    #: cusp there (echo noise between walls about 2 delta apart)
    cusp_margin = 0.1
    #: with ``meet_surround`` off, two peaks of a scan, one's upper half holding the other's
    #: top, leave along the middle of their joint span (:meth:`_openings`; False: along the
    #: first peak's middle)
    join_held = True
    _meet_rho = None    # the distance of the sensed meet point's three closest obstacles

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
        if 'scan' in self.task:
            return self._scan_step(n)
        if br.scan and 'scanned' not in self.task:     # a passed meet point's edges
            self.task['scanned'] = True
            scan = self._new_scan(meet=br.opened_by, xy=tuple(br.start))
            if not self.cfg.meet_scan:
                self._meet_branches(n, scan)
                return None
            self.task['scan'] = scan
            return np.zeros(2)
        head = self.task.get('heading') or br.heading
        leave = self.task.setdefault('leave', self.pose[:2])
        self.task.setdefault('path0', len(self.paths.xy) - 1)
        self.task.setdefault('xy0', tuple(self.pose[:2]))
        off = math.dist(leave, self.pose[:2])
        if head is not None and off < 0.6:
            return np.asarray(head) * self.cfg.max_speed   # off the meet point, onto its edge
        mins = self.gvd_mins
        if head is not None and self.task.get('past_meet') and not self.task.get('on_edge'):
            # going on past a meet point: the edge of an obstacle on either side of the way
            pair = self._side_pair(mins, head, self.cfg.cone)
            if pair is not None and off < self.det:
                mins = pair
            else:
                self.task['on_edge'] = True
        n1 = np.array([math.cos(mins[0][1]), math.sin(mins[0][1])]) if mins else np.zeros(2)
        diff = n1 - np.array([math.cos(mins[1][1]), math.sin(mins[1][1])]) \
            if len(mins) >= 2 else np.zeros(2)
        if np.linalg.norm(diff) < 1e-6:
            return self._end_branch('dead_end')
        (d1, a1), (d2, a2) = mins[:2]
        n2 = np.array([math.cos(a2), math.sin(a2)])
        tang = np.array([-diff[1], diff[0]]) / np.linalg.norm(diff)
        if head is not None and not self.task.get('on_edge') and not self.task.get('past_meet'):
            # Off a meet point along a branch's bearing: the GVD edge of the two closest
            # obstacles may be a neighbouring branch's (a door's edge leaves a meet point
            # next to the one sensed). The robot keeps the bearing until the edge it is on
            # runs along it, within delta of the branch's start, while it stays between
            # the two closest obstacles (the nearer at least keep_ratio times as far as the
            # other): a bearing that leads onto an obstacle (two openings read as one past
            # an obstacle's corner) is left to the GVD law there.
            if abs(float(tang @ np.asarray(head))) < math.cos(math.radians(45)) and \
                    off < self.det and d1 >= self.keep_ratio * d2:
                return np.asarray(head) * self.cfg.max_speed
            self.task['on_edge'] = True
        if head is None:                  # from a cusp: into the narrow region (D falls)
            head = tang if tang @ (n1 + n2) >= 0 else -tang
            if br.opened_by is None:      # the start: the GVD edge leaves it both ways,
                n.branches.append(Branch(self.pose[:2], tuple(-np.asarray(head)), None))
                a = math.atan2(head[1], head[0])      # and other edges through its gaps
                for b in self._start_openings(a):
                    n.branches.append(Branch(self.pose[:2], (math.cos(b), math.sin(b)), None))
        if tang @ np.asarray(head) < 0:
            tang = -tang
        self.task['heading'] = tuple(tang)
        origin = self.task.setdefault('from', self.pose[:2])
        self.task['far'] = max(self.task.get('far', 0.0), math.dist(origin, self.pose[:2]))
        if self.echo(math.atan2(tang[1], tang[0])) <= self.cfg.radius + 0.35 or \
                self._ahead_in_view(tang):
            if self.cfg.end_scan:         # the gaps at the end are read from a scan
                self.task['scan'] = self._new_scan(end=tuple(tang))
                return np.zeros(2)
            self._gap_at_end(n, tang)
            return self._end_branch('dead_end')
        if 'cusp' not in self.cfg.without and self.D > self.det + self.cusp_margin and \
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

    def _start_openings(self, a):
        """The GVD edges leaving the start other than the one it lies on (bearing ``a`` one
        way, ``a + pi`` the other): the openings of this sweep beyond delta
        (:meth:`_openings`), less that edge's own: an opening within 30 degrees of either
        way, or within 60 degrees of ``a`` and seen through one gap with it (no cone between
        them meets an obstacle within delta, :meth:`_one_opening`). Nothing was come along
        at the start, so the way come's test at a meet point (any opening within 60 degrees
        of it) does not apply: a stub 56 degrees off the start's edge, beyond a jamb 1.9 m
        away, is a branch (gen_maze_1168)."""
        found = gvdmod.range_peaks(self.angles, self.ranges, self.det,
                                   self.cfg.event_tolerance)
        _, ang, r, _ = found
        sep = r <= self.det
        out = []
        for b in self._openings(self.angles, self.ranges, [], self.det, found=found):
            off = abs(math.remainder(b - a, 2 * math.pi))
            if min(off, math.pi - off) <= math.radians(30):
                continue
            if off < math.radians(60) and self._one_opening(sep, ang, b, a):
                continue
            out.append(b)
        return out

    def _open_branches(self, n):
        """The untraced branches of narrow node ``n``. A branch whose GVD edge the robot has
        traced already (0.8, 1.6 and 2.4 m out along its heading all lie within 0.4 m of a
        traced GVD edge: an edge reached from its other end, or from another meet point
        sensed on it; with ``traced_way``, also as :meth:`_way_reaches_trace` tests) is that
        edge: it ends 'traced' and is not traced again."""
        out = []
        for b in n.branches:
            if b.end is None and b.heading is not None and self._edge_traced(b.start,
                                                                             b.heading):
                b.end, b.end_xy = 'traced', tuple(b.start)
                self._record(self.t_sweep or 0.0, 'branch_end', b.start,
                             'GVD branch ends: its edge is traced already')
            if b.end is None and self._other_cusps_edge(n, b):
                b.end, b.end_xy = 'other_cusp', tuple(b.start)
                self._record(self.t_sweep or 0.0, 'branch_end', b.start,
                             "GVD branch ends: its edge is another cusp's")
            if b.end is None:
                out.append(b)
        return out

    def _other_cusps_edge(self, n, b):
        """Branch ``b`` of narrow node ``n``, added where a cusp read as a meet point
        (``CreateNode._cusp_meet``), leaves along the GVD edge of another narrow node's cusp:
        one within the merge distance of its start whose bearing into its narrow cell lies
        within 30 degrees of the branch's heading (the equal-edge test of
        ``EventSensing._same_edge``). The cusps of a small vast cell lie within a step of one
        another, each on its own edge: that edge is the other node's to trace."""
        if b.opened_by not in self._cusp_meets_ev or b.heading is None:
            return False
        a = math.atan2(b.heading[1], b.heading[0])
        for _, w, c in self.edges:
            d = self._cusp_dirs.get((round(c[0], 3), round(c[1], 3)))
            if self.same_node(w) != self.same_node(n.id) and d is not None and \
                    math.dist(c, b.start) < self.cfg.same_event and \
                    abs(math.remainder(d - a, 2 * math.pi)) < math.radians(30):
                return True
        return False

    def _edge_traced(self, start, heading):
        """0.8, 1.6 and 2.4 m out along ``heading`` lie on a traced GVD edge; an edge that
        ends sooner at a known meet point (within 0.5 m of the way out, beyond 0.5 m from
        ``start``) is tested up to that meet point, at least at 0.8 m. With ``traced_way``
        (ours, off), also where the way out reaches a traced edge
        (:meth:`_way_reaches_trace`)."""
        if self.cfg.traced_way and self._way_reaches_trace(start, heading):
            return True
        meets = [m[:2] for k in self.nodes for m in k.meets
                 if math.dist(m[:2], start) > 0.5]
        for s in (0.8, 1.6, 2.4):
            q = (start[0] + s * heading[0], start[1] + s * heading[1])
            if not self._near_trace(q, 0.4):
                return False
            if any(math.dist(m, q) < 0.5 for m in meets):
                return True
        return True

    def _way_reaches_trace(self, start, heading):
        """One of the points 0.8, 1.6 and 2.4 m out along a branch's ``heading`` lies within
        0.4 m of a point of a traced GVD edge over 0.7 m from the branch's ``start`` where
        that edge runs across the way (its tangent over 50 degrees from the heading: GVD
        edges meet only at meet points, so the branch's edge ends on the traced one within
        2.4 m, a stretch the detector has swept from both ends), or along it (within 30
        degrees) either towards the start (the branch's own edge, reached from its other end,
        curving off the straight way out so that the three points do not all lie on it) or
        away from it on a trace that passed the start (the edge traced on through the
        branch's meet point before that was sensed). A traced edge within 0.7 m of the start
        leaves or reaches the same meet point (``gen_maze_1216``); one along the way from a
        trace that began at the start is a sibling edge diverging from it
        (``gen_mixed_7023``), one at 30-50 degrees a neighbour (``gen_maze_105``): none
        counts."""
        across, passed = math.cos(math.radians(50.0)), None
        for s in (0.8, 1.6, 2.4):
            q = (start[0] + s * heading[0], start[1] + s * heading[1])
            for _, p in self._trace_points(q, 0.4, None, None):
                if math.hypot(p[3], p[4]) < 0.5 or math.dist(p[:2], start) < 0.7:
                    continue                  # no tangent recorded; the same junction
                c = p[3] * heading[0] + p[4] * heading[1]
                if abs(c) < across or c < -0.87:
                    return True
                if c > 0.87 and p[6] is not None and math.dist(p[6], start) > 0.5:
                    if passed is None:    # the branches whose traces passed the start
                        passed = {t[6] for _, t in self._trace_points(start, 0.5, None, None)}
                    if p[6] in passed:
                        return True
        return False

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
        tracing node, start of the tracing branch) matching :meth:`_near_trace`'s test, from
        the 1 m buckets around ``q``."""
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
        edges are the earlier node's, uncovered while it has open branches. The trace that
        joined has covered ``n`` as far as it went, so Algorithm 1 goes on with
        FindUncoveredNode, which chooses among all uncovered nodes, the merged one as one
        of them (with ``merge_continues``, the merged node goes on being covered at once,
        however far its open branches lie: where three corner cells of one room merge into
        the start's corridor node one after another, the robot drives to the far ends of
        the corridors after each, ``gen_mixed_9094``)."""
        if owner is None:
            return None
        m = self.nodes[self.same_node(owner)]
        if m is n or m.kind != 'narrow' or n.kind != 'narrow':
            return None
        lo = self._merge_narrow(m, n, "its GVD trace joined that node's edge")
        self.current = lo.id if self.cfg.merge_continues else None
        return None

    def _merge_narrow(self, a, b, why):
        """Narrow nodes ``a`` and ``b`` are one narrow cell: the later one (higher id)
        becomes the earlier, which takes its branches, meet points and edges and is
        uncovered while it has open branches. Returns the earlier node."""
        lo, hi = (a, b) if a.id < b.id else (b, a)
        hi.merged_into, hi.covered = lo.id, True
        lo.branches.extend(hi.branches)
        lo.meets.extend(hi.meets)
        hi.branches, hi.meets = [], []
        self.edges[:] = [(v, lo.id if w == hi.id else w, c) for v, w, c in self.edges]
        self._dedupe_edges()
        hi.closed_by = self._record(self.t_sweep, 'same_cell', hi.anchor,
                                    f'narrow node {hi.id} is narrow node {lo.id}: {why}')
        lo.covered = False
        return lo

    def _cusp_ahead(self, heading):
        """D has risen above delta on the GVD edge (Fig. 11): the robot has just passed its
        cusp point. Unless the ring's cusp test placed it already, it is sensed here."""
        self._cusp_dir = self._way_in(heading, self.pose[:2])
        self._on_event(self.t_sweep, 'cusp', self.pose[:2], 'D rose above delta on the GVD '
                       'edge (Fig. 11)')
        self._cusp_dir = None
        return self._end_branch('cusp') if self.mode == 'gvd' else None

    def _gap_at_end(self, n, heading, scan=None):
        """A GVD edge ends at an obstacle ahead; a gap between closest obstacles beyond
        delta off the way back (a door, a corridor opening next to the corner) is another
        GVD edge joining this one at a meet point here, which the three-echo test did not
        place: it becomes a branch of the node (a meet event). The way back is the edge's
        last heading reversed, unless the edge curved near its end (:meth:`_curved_end`);
        then it is the bearing to the path 1.5 m behind: the peak holding it, and only that
        one, where there is one (a gap beside it, a room opening off a corridor's end, is a
        branch); else the peaks within 60 degrees of it. The echoes are the one sweep that
        found the end, or with ``end_scan`` those of a ``scan`` taken there while the ring
        turned through one cone spacing: a door beside a corner subtends about one cone
        spacing from the corner's end, and a single sweep can read its jamb and the wall
        beyond as one slope of the way back's peak. Read from a scan, the way come is the one
        peak holding the reversed heading (as at a meet point, :meth:`_meet_branches`): a
        neighbouring peak beyond delta is another opening (a hall's arm rising beside the
        corner the edge ends in), which one sweep's coarse peaks cannot tell apart. All the
        gaps found are branches of one meet point here; the branch just traced is no branch
        known at it (its edge lies behind)."""
        if 'meet' in self.cfg.without:
            return
        self._passed_meet_branches(n)
        back, way = math.atan2(-heading[1], -heading[0]), self._way_back(heading)
        ang, rng = (self.angles, self.ranges) if scan is None else self._scan_echoes(scan)
        found = gvdmod.range_peaks(ang, rng, self.det, self.cfg.event_tolerance)
        curved = self._curved_end(back, found[3])
        this = self.task.get('branch')
        gaps = [b for b in self._openings(ang, rng, [way] if curved else [back], self.det,
                                          held_first=curved or scan is not None, found=found)
                if not self._been_along(b) and not any(
                    q is not this and math.dist(q.start, self.pose[:2]) < 1.0 and
                    q.heading is not None and self._known_branch(q, b) for q in n.branches)]
        if not gaps:
            return
        idx = self._on_event(self.t_sweep, 'meet', self.pose[:2], 'a gap beyond delta at ' +
                             ', '.join(f'{math.degrees(b):.0f}' for b in gaps) +
                             ' deg where the GVD edge ends')
        if idx is None:
            return
        n.meets.append((float(self.pose[0]), float(self.pose[1]), idx))
        for b in gaps:                  # one meet point, every gap at it a branch
            n.branches.append(Branch(self.pose[:2], (math.cos(b), math.sin(b)), idx, gap=True))

    def _known_branch(self, q, b):
        """Gap bearing ``b``, read here, leads along the edge of branch ``q``, which leaves
        a point up to a metre away: the place delta out along ``b`` lies within 45 degrees of
        ``q``'s bearing seen from ``q``'s start. The two bearings are read from different
        places, so they are compared from one: a door beside a corner, seen from the corner's
        dead end, and the edge that leaves a meet point beside that corner towards the room's
        inside can point within 45 degrees of each other yet lead a couple of metres apart."""
        x = self.pose[0] + self.det * math.cos(b) - q.start[0]
        y = self.pose[1] + self.det * math.sin(b) - q.start[1]
        return abs(math.remainder(math.atan2(y, x) - math.atan2(q.heading[1], q.heading[0]),
                                  2 * math.pi)) < math.radians(45)

    def _passed_meet_branches(self, n):
        """The GVD edge ends in a dead end after passing a point where its three closest
        obstacles were equidistant just beyond delta (``EventSensing._passed_meet``): the
        edge beyond that point stayed narrow (no cusp), so the point is a meet point of this
        narrow node: the end of a hall about 2 delta high, where the edges into its two
        corners leave the centre line, or the outer corner of an L between two halls
        narrower than 2 delta. It is recorded as one (a meet event) with a branch that
        starts there by a meet scan (:meth:`_scan_step`): its openings other than the way
        the robot came back from the dead end are its GVD edges. From the dead end the
        other edges can hold no peak of the range (a hall's other corner, seen along its
        end wall) or one read as the way back (:meth:`_gap_at_end`)."""
        xy = self.task.get('passed_meet')
        if xy is None or self._known('meet', xy):
            return
        idx = self._record(self.t_sweep, 'meet', xy, 'three closest obstacles just beyond '
                           'delta on an edge that ended in a dead end')
        n.meets.append((float(xy[0]), float(xy[1]), idx))
        n.branches.append(Branch(tuple(xy), None, idx, scan=True))

    def _curved_end(self, back, peaks):
        """The traced edge curved into a corner near its end (past a meet point the ring did
        not sense): no peak of the range (``peaks``) holds the reversed heading ``back``.
        The edge came straight along its last heading where a peak holds it; where none
        does, the reversed heading points along the curve's chord, past the unsensed meet
        point, into the other edge leaving it (the room a door opens into), and the way
        back is the bearing to the path behind (:meth:`_way_back`), whether or not a peak
        holds it."""
        return not any(self._holds(back, lo, hi) for lo, hi, _ in peaks)

    def _way_back(self, heading, back=1.5, since=None, origin=None):
        """Bearing from here to the robot's path ``back`` m behind (-``heading`` when the
        path is shorter): the way the GVD edge came, also where it curved in its last metre
        (into a corner's edge past a meet point the ring did not sense). ``since`` and
        ``origin``: the path's sample and the place where the branch being traced began
        (:meth:`_to_path_behind`)."""
        return self._to_path_behind(self.pose[:2], heading, back, since, origin)

    def _to_path_behind(self, xy, heading, back, since=None, origin=None):
        """Bearing from ``xy`` to the robot's path ``back`` m behind its last sample
        (-``heading`` when the path is shorter). With ``since`` (the path's sample where
        the branch being traced began), not farther back than the branch's start: the path
        before it is another primitive's (a transit to the branch's start from elsewhere, or
        the start's move onto the GVD before CreateNode), not the edge come along; the
        bearing is then to ``origin``, the place the branch began (the path's samples lie
        0.3 m apart, so the sample ``since`` can lie up to 0.3 m back along that other
        primitive: gen_rooms_6069, a start 1 m inside a door, whose sample before the GVD
        lay towards the door), or to the sample ``since`` without ``origin``, when at least
        0.3 m away, else -``heading``."""
        j = self.paths.back_index(back)
        if since is not None and (j is None or j < since):
            q = origin if origin is not None else \
                self.paths.xy[since] if 0 <= since < len(self.paths.xy) else None
            if q is None or math.dist(q, xy) < 0.3:
                return math.atan2(-heading[1], -heading[0])
            return math.atan2(q[1] - xy[1], q[0] - xy[0])
        if j is None:
            return math.atan2(-heading[1], -heading[0])
        q = self.paths.xy[j]
        return math.atan2(q[1] - xy[1], q[0] - xy[0])

    def _way_in(self, heading, xy):
        """Bearing from a cusp ``xy`` sensed while tracing into its narrow cell: to the
        robot's path 1.5 m behind (the GVD edge the robot came along), not its heading
        reversed. In a room about 2 delta across the edges from its corners meet in its
        middle, where D comes within a few centimetres of delta; there the GVD law's two
        closest obstacles switch to another corner's within a step, its heading turns onto
        that corner's edge as D crosses delta, and the reversed heading would claim that
        untraced edge for this cusp (a cusp sensed on it later is then known, a branch along
        it another cusp's edge: gen_maze_1229, gen_maze_1168)."""
        return self._to_path_behind(xy, heading, 1.5)

    def _been_along(self, bearing, recent=1.5):
        """The robot's path passes 0.7 m or 1.4 m out along ``bearing``; its last
        ``recent`` m, the way it came (excluded as such), do not count: where the edge curved
        near its end they pass beside a gap that opens off the way back."""
        j = self.paths.back_index(recent)
        last = min(1, len(self.paths.xy)) if j is None else j + 1
        for s in (0.7, 1.4):
            q = (self.pose[0] + s * math.cos(bearing), self.pose[1] + s * math.sin(bearing))
            if self.paths.passes(q, 0.5, before=last):
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
        """A meet point: the robot halts on it and turns its ring through one cone spacing
        (:meth:`_scan_step`), so that the GVD edges leaving it are read at several times the
        ring's bearing resolution: a door whose jambs fall into every cone of one sweep is
        seen through from the same place by cones turned between them (``meet_scan``, ours;
        off, the branches are read from the one sweep that sensed the meet point)."""
        n = self.nodes[self.current] if self.current is not None else None
        if n is None or n.kind != 'narrow' or self.task.get('branch') is None:
            return
        n.meets.append((float(xy[0]), float(xy[1]), idx))
        self.task.pop('passed_meet', None)    # the edges beyond leave this meet point
        scan = self._new_scan(meet=idx, xy=tuple(xy), rho=self._meet_rho)
        if self.cfg.meet_scan:
            self.task['scan'] = scan
        else:
            self._meet_branches(n, scan)

    def _new_scan(self, **data):
        """A scan taken from here while the ring turns (``task['scan']``, fed by
        :meth:`_scan_sweep`): this moment's sweep, and ``data``."""
        return dict(data, yaw=self.pose[2], turned=0.0,
                    sweeps=[(self.angles.copy(), self.ranges.copy())])

    def _scan_turned(self, scan):
        """The ring has turned through one cone spacing since the scan began."""
        return scan['turned'] >= 2.0 * math.pi / len(self.mount)

    @staticmethod
    def _scan_echoes(scan):
        """Bearings and ranges of all the sweeps of a scan."""
        return (np.concatenate([a for a, _ in scan['sweeps']]),
                np.concatenate([r for _, r in scan['sweeps']]))

    def _scan_sweep(self):
        """A sweep taken while the robot turns for a scan: kept with its bearings."""
        scan = self.task.get('scan')
        if scan is not None:
            scan['turned'] += abs(math.remainder(self.pose[2] - scan['yaw'], 2 * math.pi))
            scan['yaw'] = self.pose[2]
            scan['sweeps'].append((self.angles.copy(), self.ranges.copy()))

    def _scan_step(self, n):
        """Halted on a meet point while the ring turns; once it has turned through one cone
        spacing, the openings of all the sweeps taken there give the branches
        (:meth:`_meet_branches`). None when the scan has just ended."""
        scan = self.task['scan']
        if not self._scan_turned(scan):
            return np.zeros(2)
        del self.task['scan']
        if 'end' in scan:                 # a dead end: its gaps (:meth:`_gap_at_end`)
            self._gap_at_end(n, scan['end'], scan)
            return self._end_branch('dead_end')
        self._meet_branches(n, scan)
        if self.task['branch'].scan and self.task.get('heading') is None:
            return self._end_branch('meet')       # no edge leaves it but the way come
        return None

    def _meet_branches(self, n, scan):
        """The GVD edges leaving a meet point (one per opening of the scan beyond delta)
        become branches of the narrow node; the robot goes on along the one nearest its
        heading. Two branches equally near it (within half the cones' spacing, the ring's
        bearing resolution) are a symmetric fork: the robot takes the right-hand one, as at
        Fig. 13's Mp1 ('The robot chooses the lower edge', arriving along +x). The edge
        the robot came along is read from the bearing to its path 1.5 m behind, not from its
        heading: halted up to half a metre past the meet point, it can face off the edge it
        came along, and an opening within 60 degrees of the reversed heading would be taken
        for the way come. The path read is the branch's own trace: a meet point sensed
        within 1.5 m of the branch's start has behind it, farther back, the transit that
        brought the robot to that start from elsewhere, whose bearing is no edge's and can
        claim an untraced opening for the way come (gen_maze_1179: a room's top-left corner;
        gen_maze_2013: a stub north of a crossing); the bearing then points to the branch's
        start (:meth:`_way_back`, ``since``). On a branch opened by a gap
        beside a dead end (:meth:`_gap_at_end`), the robot left the dead end along the gap's
        bearing, across the gap, not along a GVD edge, so the path behind bends where it
        met the edge it then followed: the bearing to it is no edge's. The robot came along
        one edge there: the way come is the one peak of the range that holds that bearing or
        lies nearest to it, within 60 degrees, with the peaks one edge with it
        (:meth:`_openings`, ``held_first``); every other opening is a branch, however near
        (a corridor's other way at a T reached through a door beside a corner). With
        ``way_come_held`` (ours, on) the same holds on any branch where a peak holds the
        bearing to the path behind: an opening beside the way come, within 60 degrees of
        that bearing, is a branch (a pillar's far side, reached along the edge between two
        pillars)."""
        head = np.asarray(self.task.get('heading') or self.task['branch'].heading or (1.0, 0.0))
        back = self._way_back(head, since=self.task.get('path0'), origin=self.task.get('xy0'))
        ang, rng = self._scan_echoes(scan)
        found = gvdmod.range_peaks(ang, rng, self.det, self.cfg.event_tolerance)
        near = min(found[3], key=lambda q: self._off_span(back, q[0], q[1]), default=None)
        gap = self.task['branch'].gap and near is not None
        if gap and self._off_span(back, near[0], near[1]) < math.radians(60):
            back = near[2]              # the one peak the robot came along
        held = gap or (self.cfg.way_come_held and near is not None and
                       self._off_span(back, near[0], near[1]) == 0.0)
        rho = scan.get('rho')
        out = self._openings(ang, rng, [back], self.det,
                             self._meet_obstacles(ang, rng, scan['xy'], rho),
                             held_first=held, found=found,
                             meet=None if rho is None else (*scan['xy'], rho))
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
            n.branches.append(Branch(tuple(scan['xy']), (math.cos(m), math.sin(m)),
                                     scan['meet']))
        self.task['heading'] = (math.cos(out[0]), math.sin(out[0]))
        self.task['meet'] = scan['meet']
        self.task['leave'] = self.pose[:2]
        if self.cfg.meet_side_pair:
            self.task['past_meet'] = True
            self.task.pop('on_edge', None)

    @staticmethod
    def _side_pair(mins, head, cone):
        """The two obstacles whose GVD edge the robot follows going on past a meet point
        (``meet_side_pair``, ours), ``mins`` being the closest obstacles ((distance, bearing)
        each, nearest first) and ``head`` its heading (the branch's bearing off the meet point,
        then the edge's). The GVD edge that leaves a meet point through an opening runs
        between the obstacle on its left and the one on its right. Where the two closest
        obstacles lie on one side of the heading, their GVD edge crosses the way ahead: it is
        a neighbouring branch's, leaving through another opening (near the meet point three
        obstacles are about equally near, and a second meet point within the ring's error of
        the first splits the branch's edge). The robot then follows the edge of the closest
        obstacle on either side of its heading, the branch's own. None once the two closest
        lie either side (the robot is on the branch's edge and the GVD law takes over), where
        one of them lies ahead (within ``cone`` of the heading: on neither side, the edge
        ends ahead and its end is read there), or where one side has no obstacle."""
        def side(a):
            return head[0] * math.sin(a) - head[1] * math.cos(a) > 0
        h = math.atan2(head[1], head[0])
        if len(mins) < 2 or side(mins[0][1]) != side(mins[1][1]) or \
                any(abs(math.remainder(a - h, 2 * math.pi)) <= cone for _, a in mins[:2]):
            return None
        left = [m for m in mins if side(m[1])]
        right = [m for m in mins if not side(m[1])]
        if not left or not right:
            return None
        return sorted([min(left), min(right)])

    def _meet_obstacles(self, angles, ranges, xy, rho):
        """Which echoes of a scan taken near meet point ``xy`` lie on its closest obstacles:
        within ``rho`` (the three closest obstacles' distance from it) plus the event
        tolerance of ``xy``. The robot halts where it sensed the meet point, up to half a
        metre off it; from there a closest obstacle of the meet point (a door's jamb beside a
        corner) can lie beyond delta, and every GVD edge leaving the meet point lies between
        two of them. None without ``rho``."""
        if rho is None:
            return None
        ang = np.asarray(angles, dtype=float)
        r = np.asarray(ranges, dtype=float)
        hit = np.isfinite(r) & (r < self.max_range - 1e-6)
        return hit & (self._echo_dist(ang, np.where(hit, r, 0.0), xy) <=
                      rho + self.cfg.event_tolerance)

    def _echo_dist(self, ang, r, xy):
        """Distance from ``xy`` of each echo (bearing, range) of a sweep taken here."""
        return np.hypot(self.pose[0] + r * np.cos(ang) - xy[0],
                        self.pose[1] + r * np.sin(ang) - xy[1])

    def _openings(self, angles, ranges, exclude, beyond, close=None, held_first=False,
                  found=None, meet=None):
        """Bearings of the GVD edges leaving the place a scan was taken from: the peaks of the
        range over bearing (a gap between two closest obstacles) reaching beyond ``beyond``
        and standing out by at least the event tolerance from the dips on either side (echo
        noise makes smaller ones). Each edge leaves along the middle of its peak's upper
        half (the bisector of a door's jambs, a corner's diagonal). A peak whose upper half
        holds a bearing of ``exclude``, or whose middle lies within 60 degrees of one, is
        the edge the robot came along. Two peaks are one edge when one's upper half holds the
        other's top (a far wall's corners seen through one door), or when they lie
        within 45 degrees of each other and look through one opening (no bearing between
        them meets an obstacle within ``beyond``, nor one of the echoes ``close`` marks: a
        closest obstacle of the meet point the scan was taken near). By either test the edge
        leaves along the middle of the span covering both peaks' upper halves: an obstacle
        beyond a door, seen through it, splits the door's one peak in two, and the middle of
        either part points at a jamb, the middle of the whole at the bisector of the jambs;
        the range of a wide opening seen past an obstacle's edge also peaks just beyond that
        edge, a narrow peak at the wide one's side whose middle points at the obstacle.
        With ``fork_at_meet`` (ours, off) two peaks of a meet point's scan that the first test
        would join are two edges where their fork lies within ``same_event`` of the meet
        point (:meth:`_fork_here`). With ``held_first``, where some peak's upper half holds a
        bearing of ``exclude``, only those peaks, and the peaks one edge with them by the
        first test, are the way come.
        ``found``: :func:`coverage_pkg.gvd.range_peaks` of these echoes, if the caller has it.
        ``meet``: (x, y, rho) of the meet point the scan was taken on, for ``fork_at_meet``."""
        order, ang, r, peaks = found or gvdmod.range_peaks(angles, ranges, beyond,
                                                           self.cfg.event_tolerance)
        sep = r <= beyond if close is None else (r <= beyond) | np.asarray(close)[order]

        inside = self._holds
        held = [(lo, hi, top) for lo, hi, top in peaks
                if any(inside(e, lo, hi) for e in exclude)] if held_first else []

        def came(lo, hi, top, mid):
            if held:
                return any(inside(top, q[0], q[1]) or inside(q[2], lo, hi) for q in held)
            return any(inside(e, lo, hi) or
                       abs(math.remainder(mid - e, 2 * math.pi)) < math.radians(60)
                       for e in exclude)

        kept = []                                  # [middle, top, lo, hi] per edge
        for lo, hi, top in peaks:
            mid = ((lo + hi) / 2) % (2 * math.pi)
            if came(lo, hi, top, mid):
                continue
            held_top = [q for q in kept if inside(top, q[2], q[3]) or inside(q[1], lo, hi)]
            if held_top and meet is not None and self.cfg.fork_at_meet and \
                    self._fork_here(ang, r, top, held_top[0][1], meet):
                q = held_top[0]          # each edge of the fork leaves along its peak's top
                q[0], q[2], q[3] = q[1], q[1], q[1]
                kept.append([top, top, top, top])
                continue
            if held_top:
                if self.join_held and not self.cfg.meet_surround:
                    self._join_opening(held_top[0], lo, hi)
                continue
            same = [q for q in kept
                    if abs(math.remainder(mid - q[0], 2 * math.pi)) <= math.radians(45) and
                    self._one_opening(sep, ang, mid, q[0])]
            if not same:
                kept.append([mid, top, lo, hi])
                continue
            self._join_opening(same[0], lo, hi)
        return [q[0] for q in kept]

    @classmethod
    def _off_span(cls, x, lo, hi):
        """Angle from bearing ``x`` to the span from ``lo`` anticlockwise to ``hi`` (0 when
        the span holds it)."""
        if cls._holds(x, lo, hi):
            return 0.0
        return min(abs(math.remainder(x - lo, 2 * math.pi)),
                   abs(math.remainder(x - hi, 2 * math.pi)))

    @staticmethod
    def _join_opening(q, lo, hi):
        """Peak (``lo``, ``hi``) looks through the opening of kept edge ``q`` ([middle, top,
        lo, hi]): the opening's span grows to cover both peaks' upper halves and the edge
        leaves along its middle (the bisector of a door's jambs, where an obstacle beyond
        the door splits its peak in two and either part's middle points at a jamb)."""
        shift = math.remainder(lo - q[2], 2 * math.pi) - (lo - q[2])
        q[2], q[3] = min(q[2], lo + shift), max(q[3], hi + shift)
        q[0] = ((q[2] + q[3]) / 2) % (2 * math.pi)

    @staticmethod
    def _holds(x, lo, hi):
        """Bearing ``x`` lies in the span from ``lo`` anticlockwise to ``hi``."""
        return math.remainder(x - lo, 2 * math.pi) % (2 * math.pi) <= hi - lo

    def _fork_here(self, ang, r, top, other, meet):
        """``fork_at_meet`` (ours): on the scan of meet point ``meet`` (x, y, rho), the peaks
        topping at bearings ``top`` and ``other`` lead along two GVD edges. The edge along
        their joint span runs between the two obstacles either side of it until the obstacle
        between the tops (the echo between them, the shorter way round, nearest the meet
        point, at ``dip`` from it) is as near as they are: about (dip - rho) / 2 out it forks
        into one edge per top. Within ``same_event`` of the meet point that fork would be
        taken for the meet point itself and never sensed (a room about 2 delta square
        entered through its wall's middle: the edges into its two far corners), so both
        edges leave here. Beyond, the robot senses the fork where it lies (a far wall's
        corners seen through a door)."""
        hit = np.isfinite(r) & (r > 0) & (r < self.max_range - 1e-6)
        between = self._between(ang, top, other) & hit
        if not between.any():
            return False
        dip = float(self._echo_dist(ang[between], r[between], meet[:2]).min())
        return (dip - meet[2]) / 2.0 < self.cfg.same_event

    @staticmethod
    def _between(ang, b, o):
        """Which bearings of ``ang`` lie strictly between bearings ``b`` and ``o``, the
        shorter way round."""
        span = math.remainder(o - b, 2 * math.pi)
        rel = np.remainder(ang - b, 2 * math.pi) if span > 0 else \
            np.remainder(b - ang, 2 * math.pi)
        return (rel > 1e-6) & (rel < abs(span) - 1e-6)

    @staticmethod
    def _one_opening(sep, ang, b, o):
        """No cone between bearings ``b`` and ``o`` (the shorter way round) is marked in
        ``sep`` (an obstacle within delta, or a closest obstacle of the meet point): the two
        maxima look through one opening. A cone between them that meets such an obstacle
        separates two openings, two GVD edges."""
        return not bool(np.any(sep[TraceGVD._between(ang, b, o)]))

    def _end_branch(self, how):
        br = self.task.get('branch')
        if br is not None:
            br.end, br.end_xy = how, (float(self.pose[0]), float(self.pose[1]))
            # off its start the robot drives along the branch's own bearing
            br.end_heading = self.task.get('heading') or br.heading
            self._record(self.t_sweep, 'branch_end', self.pose, f'GVD branch ends: {how}')
        self.task, self.mode = {}, None
        if how == 'cusp' and br is not None:
            self._cusp_edge_traced(br)
        return None
