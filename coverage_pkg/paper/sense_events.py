"""Event sensing from the sonar ring: cusp points (Section IV-B) and meet points (Section III).

A cusp is sensed where D crosses delta (on the GVD, Fig. 11) or where the closest obstacle
jumps while following a boundary at D = delta (Fig. 10); a meet point where three closest
obstacles are equidistant. Each sensed event is dropped if switched off (``without``) or
filtered, merged with a known one nearby, else recorded and handed to the subroutine it
belongs to: a cusp to :mod:`coverage_pkg.paper.node_creation`, a meet point to
:mod:`coverage_pkg.paper.trace_gvd`. Critical points are sensed from a lap's echoes in
:mod:`coverage_pkg.paper.morse_coverage`.
"""
from __future__ import annotations

import math

from coverage_pkg import gvd as gvdmod


class EventSensing:
    """Mixin of :class:`coverage_pkg.algorithm1.PaperPlanner`: events from the ring."""

    def _sense_cusp(self, t, prev):
        """Cusp point (Section V-B): D crosses delta on the GVD (Fig. 11), or, while following
        a boundary at D = delta, the closest obstacle jumps to another one (Fig. 10: its echo
        turns by more than 45 degrees between two sweeps, or a farther echo lies between the
        two, :meth:`_two_obstacles`; on a GVD edge the closest obstacle alternates between
        the two equidistant ones, which is no cusp); placed where both are at delta. On a GVD
        edge, D must cross delta + 0.015 m: between walls about 2 delta apart, echo noise
        makes D cross delta back and forth."""
        xy = None
        level = self.det + (0.015 if self.mode == 'gvd' else 0.0)
        if math.isfinite(prev) and (prev <= level) != (self.D <= level):
            xy = gvdmod.cusp_from_ring(self.pose[:2], self.ranges, self.angles, self.det)
        # the closest echo, compared between sweeps of one boundary following
        near = (*self.mins[0], self.ranges, self.angles) \
            if self.mins and self.mode == 'boundary' else None
        last, self._near_echo = self._near_echo, near
        if xy is None and last is not None and near is not None and \
                abs(self.D - self.det) < 0.3 and \
                (abs(math.remainder(near[1] - last[1], 2 * math.pi)) > math.radians(45) or
                 self._two_obstacles(last, near)):
            xy = gvdmod.cusp_from_ring(self.pose[:2], self.ranges, self.angles, self.det)
        if xy is not None:
            head = self._trace_heading()
            # traced along its GVD edge: back along the path is into the narrow cell
            self._cusp_dir = self._gvd_direction() if head is None else \
                self._way_in(head, xy)
            self._on_event(t, 'cusp', xy, 'D = delta where two closest obstacles meet')
            self._cusp_dir = None
            self._cusp_meet(t, xy)

    def _two_obstacles(self, last, near):
        """The closest echo of the last sweep and that of this one (``(range, bearing,
        ranges, angles)`` each) lie on two obstacles: an echo of either sweep between their
        bearings lies farther than both by more than ``PaperConfig.event_tolerance`` (the
        echoes' equidistance tolerance). Along one flat or convex surface the distance has
        no interior maximum (:func:`coverage_pkg.gvd.one_surface`); a maximum between the
        two is a gap (a corridor's mouth) or a concave corner, and the closest point has
        jumped from one obstacle to another (Fig. 10) however few degrees apart the two lie.
        The ring reads bearings through cones 22.5 degrees apart, so the bearing's jump
        alone cannot tell a new obstacle from the next cone on the same wall below two cone
        spacings (45 degrees): a corridor 1.24 m wide seen from its cusp delta away turns
        the closest echo through about one spacing (gen_maze_3014)."""
        (d1, a1, *_), (d2, a2, *_) = last, near
        span = math.remainder(a2 - a1, 2 * math.pi)
        top = max(d1, d2) + self.cfg.event_tolerance
        for ranges, angles in (last[2:], near[2:]):
            for rk, ak in zip(ranges.tolist(), angles.tolist()):
                rel = math.remainder(ak - a1, 2 * math.pi)
                if 0 < rel * math.copysign(1, span) < abs(span) and rk > top:
                    return True
        return False

    def _trace_heading(self):
        """The heading of the GVD trace under way (None outside one): the GVD law's tangent,
        or, off a branch's start (its first 0.6 m, driven along the branch's bearing before
        the law gives a tangent), that bearing. A cusp crossed there is still on the edge the
        robot came along, and its way in is read from the path behind
        (:meth:`TraceGVD._way_in`), not from the GVD law's present pair of closest obstacles:
        where a vast cell's tip lies between two corners' cusps 0.4 m apart, that pair is
        already the other corner's as D crosses delta, and the other corner's untraced edge
        would be claimed for this cusp (gen_halls_5102)."""
        br = self.task.get('branch') if self.mode == 'gvd' else None
        if br is None:
            return None
        return self.task.get('heading') or br.heading

    def _sense_meet(self, t):
        """Meet point (Section III): three closest obstacles equidistant, two sweeps agreeing,
        at D up to delta + ``PaperConfig.meet_margin`` (ours; 0.1 m is as far as the trace
        follows the GVD edge before it takes D to have risen above delta, Fig. 11's cusp in
        ``TraceGVD._gvd_step``): where a corner's diagonal edge leaves the edge
        traced along the walls at D = delta within the echoes' noise, the three-echo solve
        puts D at delta plus a few centimetres either way, and the corner's edge is a branch
        only if the meet point is taken. With ``meet_surround`` off, the three need not
        surround the point: a meet point is the centre of a circle touching three obstacles,
        which lies outside the triangle of the touching points where that triangle is
        obtuse, and then their bearings lie within a half-plane (a door beside a room's side
        wall: the door's two jambs and the wall are equidistant from a point inside the
        room, and the GVD edge between the wall and the far jamb leaves it into the room,
        away from all three). One whose obstacles lie beyond that, up to delta +
        ``cusp_margin``, is passed and kept (:meth:`_passed_meet`)."""
        gap = math.radians(190.0) if self.cfg.meet_surround else None
        m = gvdmod.meet_from_ring(self.pose[:2], self.ranges, self.angles, max_gap=gap)
        reach = self.det + self.cfg.meet_margin
        if m is not None and reach < m[2] <= self.det + self.cusp_margin:
            self._meet_cand = None
            prev, self._passed_cand = self._passed_cand, m
            if prev is not None and math.dist(prev[:2], m[:2]) <= 0.15:
                self._passed_meet(((m[0] + prev[0]) / 2, (m[1] + prev[1]) / 2))
            return
        self._passed_cand = None
        if m is None or m[2] > reach:
            self._meet_cand = None
            return
        prev, self._meet_cand = self._meet_cand, m
        if prev is not None and math.dist(prev[:2], m[:2]) <= 0.15:
            self._meet_rho = (m[2] + prev[2]) / 2      # the meet scan's closest obstacles
            here = (float(self.pose[0]), float(self.pose[1]))
            if self.cfg.meet_own_obstacles:
                self._meet_new = (self._meet_rho, here)
            idx = self._on_event(t, 'meet', ((m[0] + prev[0]) / 2, (m[1] + prev[1]) / 2),
                                 f'three closest obstacles at {m[2]:.2f} m')
            self._meet_rho, self._meet_new = None, None
            if idx is not None and self.cfg.meet_own_obstacles:
                self._meet_touch[idx] = ([(here[0] + d * math.cos(a), here[1] + d * math.sin(a))
                                          for d, a in gvdmod.ring_minima(self.ranges,
                                                                         self.angles)[:3]],
                                         here)

    def _passed_meet(self, xy):
        """Three closest obstacles equidistant just beyond delta (within the margin by which
        D must exceed delta on a traced GVD edge before the trace senses Fig. 11's cusp,
        ``cusp_margin``): the trace passes this point without a halt, since a vast cell may
        open beyond it (D rising further: a cusp follows). The point is kept for
        :meth:`TraceGVD._passed_meet_branches` should the edge end in a dead end instead
        (the last such point of the edge; none at a known meet point)."""
        if self.task.get('branch') is None or self._known('meet', xy):
            return
        pm = self.task.get('passed_meet')
        if pm is None or math.dist(pm, xy) >= self.cfg.same_event:
            self.task['passed_meet'] = tuple(xy)

    def _on_event(self, t, kind, xy, detail):
        """A sensed (or injected) event: dropped if switched off or filtered, merged with a
        known one nearby; else recorded and handed to the subroutine it belongs to."""
        if kind in self.cfg.without or (self.event_filter and not self.event_filter(kind, xy)):
            return None
        if self._known(kind, xy):
            if kind == 'cusp':
                self._join_known_cusp(xy)
            return None
        idx = self._record(t, kind, xy, detail)
        if kind == 'cusp':
            self._on_cusp(idx, xy)
        elif kind == 'meet':
            self._on_meet(idx, xy)
        return idx

    def _known(self, kind, xy):
        """An event sensed again. A cusp is known to a vast node only through its own
        edges: the cusp that ends a narrow cell's GVD edge can lie within a step of the one
        where a corner's narrow cell meets the same vast cell."""
        near = self.cfg.same_event
        n = self.nodes[self.current] if self.current is not None else None
        if kind == 'critical':
            return False
        if kind == 'cusp' and n is not None and n.kind == 'vast':
            return any(math.dist(c, xy) < near and self._same_edge(c, self._cusp_dir)
                       for v, _, c in self.edges if self.same_node(v) == n.id)
        return any(e[1] == kind and math.dist(e[2:4], xy) < near and
                   not (kind == 'meet' and self._other_meet(i, xy))
                   for i, e in enumerate(self.events))

    def _other_meet(self, idx, xy):
        """The meet point being sensed at ``xy`` is another one than known meet event ``idx``
        nearby (``meet_own_obstacles``, ours, on): a meet point is the centre of a circle touching
        its three closest obstacles, so one that leaves a known one's closest obstacle
        farther than its own three (by over twice the event tolerance: more than a wall's
        point moves in distance when the point moves by ``same_event`` with the ring's
        bearing error) touches another obstacle. Where a hall ends beyond an obstacle 2 delta
        from its end wall, the edge past the obstacle's meet point (its two walls and the
        obstacle) meets the two corners' edges at the end's meet point (the two walls and
        the end wall) under ``same_event`` away: read as one, the corner the robot does not
        follow is never a branch (gen_halls_5125). Only a meet point sensed by the
        three-echo test is compared (its obstacles' points are kept), and only from over
        ``same_event`` beyond where the robot sensed the known one: from one place (halted
        there for its scan) the ring's three closest can be another triple of the same
        junction (a T of corridors whose walls jog beside it, gen_maze_102)."""
        if not self.cfg.meet_own_obstacles or self._meet_new is None:
            return False
        known = self._meet_touch.get(idx)
        if known is None:
            return False
        (pts, there), (rho, here) = known, self._meet_new
        if math.dist(here, there) <= self.cfg.same_event:
            return False
        return any(math.dist(q, xy) > rho + 2 * self.cfg.event_tolerance for q in pts)

    def _same_edge(self, c, into):
        """The cusp ``c`` lies on the GVD edge leaving along ``into`` (bearing into its narrow
        cell; unknown either way: the same). A small vast cell's cusps lie within a step of
        one another, each on its own edge."""
        known = self._cusp_dirs.get((round(c[0], 3), round(c[1], 3)))
        if known is None or into is None:
            return True
        return abs(math.remainder(known - into, 2 * math.pi)) < math.radians(30)
