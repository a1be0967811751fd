"""MorseDecompCoverage(n, L, F) of Algorithm 1: covering a vast node by its Morse cells.

Laps along the slices of ``h = x`` spaced ``2 delta`` apart (the robot "as big as its
detector", Section IV-A), ended at ``D = delta`` ahead; the moves between laps follow the
boundary at ``D = delta``, and each cell's boundary circuit is followed once (cusp points are
sensed on it, Fig. 10). A *critical point* sensed from a lap (the slice's connectivity changes
ahead: the ring's echoes along ``+-x`` show two open stretches, or none) closes the current
Morse cell and opens its successors in the node's Reeb graph; the node is covered when every
Morse cell has closed.
"""
from __future__ import annotations

import math

import numpy as np

from coverage_pkg import gvd as gvdmod
from coverage_pkg.paper.graph_nodes import MorseCell


class MorseDecompCoverage:
    """Mixin of :class:`coverage_pkg.algorithm1.PaperPlanner`: laps, circuits, Morse cells."""

    def _morse_step(self, n):
        """MorseDecompCoverage: laps 2 delta apart in the current Morse cell; the moves
        between them follow the boundary at D = delta; critical points close cells."""
        if 'opening_scan' in self.task:            # a sliver's GVD edges, read as a meet's
            return self._opening_scan_step(n)
        busy = any(c.status == 'covering' for c in n.cells)
        circ = self.task.get('circuit') or (
            None if busy else next((c for c in n.circuits if not c['done']), None))
        if circ is not None:
            return self._circuit_step(n, circ)
        cell = self._open_cell(n)
        if cell is None:
            n.covered = True
            return None
        if self.mode == 'transit':
            return None
        tk, s = self.task, cell.sweep
        if tk.get('phase') is None:                # at the cell's start
            if self._known_region(n, cell, at_start=True):
                return None
            if cell.resume is not None:            # the slice beyond an obstacle
                tk.update(dir=cell.resume[2], x=self.pose[0], phase='lap')
                self.mode = 'lap'
                self._profile_reset()
                return None
            if cell.prev_span is None:             # a node's first cell: find its left side
                tk.update(phase='find_left')
            else:                                  # a successor: its first lap is ahead
                tk.update(phase='advance', x0=self.pose[0], first=True)
            self.mode = 'boundary'
        if tk['phase'] in ('find_left', 'advance') and self.cfg.pinch_ends_cell and \
                self._pinched():
            return self._close_cell(n, cell, None, 'the slice pinches: two obstacles either '
                                    'side nearer than delta')
        if tk['phase'] == 'find_left':             # to the cell's opening side
            if self.echo(math.pi if s > 0 else 0.0) > self.det:
                return self._boundary_velocity(-s)
            tk.update(phase='advance', x0=self.pose[0], first=True)   # the circuit lapped it
            return None
        if tk['phase'] in ('lap_first', 'lap'):
            ahead = self.echo(math.pi / 2 * tk['dir'])
            touch = self.cfg.pinch_ends_cell and self._touches_ahead(tk['dir'])
            if ahead > self.det and not touch:
                return self._lap_velocity(tk['x'], tk['dir'])
            if ahead <= self.det + self.cfg.event_tolerance:   # an obstacle ahead, not a touch
                self._island(n, cell, tk['dir'])
            if tk['phase'] == 'lap_first':         # one end of the slice reached: lap it
                tk.update(phase='lap', dir=-tk['dir'])
                self._profile_reset()
                return None
            return self._end_lap(n, cell)
        moved = s * (self.pose[0] - tk['x0'])      # advance: to the next slice, 2 delta on
        if moved < self.spacing and self.echo(0.0 if s > 0 else math.pi) > self.det:
            return self._boundary_velocity(s)
        if moved < 0.3:
            return self._close_cell(n, cell, None, 'no room for another lap')
        if self._known_region(n, cell):
            return None
        return self._start_lap(first=tk.get('first', False))

    def _start_lap(self, first):
        """Begin a lap at this column: a first lap goes to one end of the slice, then laps it
        whole; a later lap runs back from the end the last one reached."""
        tk = self.task
        if first:
            span = self._cell().prev_span
            up = span is None or self.pose[1] >= 0.5 * (span[0] + span[1])
            tk.update(phase='lap_first', dir=1 if up else -1)
        elif tk.pop('leave', False) and self.mins:    # away from the closest obstacle
            tk.update(phase='lap', dir=1 if math.sin(self.mins[0][1]) < 0 else -1)
        else:
            tk.update(phase='lap', dir=-tk.get('dir', 1))
        tk.update(x=self.pose[0], first=False)
        self.mode = 'lap'
        self._profile_reset()
        return None

    def _cell(self):
        n = self.nodes[self.current]
        return n.cells[self.task['cell']]

    def _open_cell(self, n):
        """The Morse cell being covered, else the nearest open one (transit to its start)."""
        cell = next((c for c in n.cells if c.status == 'covering'), None)
        if cell is not None:
            return cell
        opened = [c for c in n.cells if c.status == 'open' and c.start is not None]
        if not opened:
            return None
        src = self.paths.nearest(self.pose[:2])
        dist = self.paths.distances(src)
        cell = min(opened, key=lambda c: (dist.get(self.paths.nearest(c.start), 1e6), c.id))
        cell.status = 'covering'
        self.task = {'cell': cell.id, 'phase': None, 's': cell.sweep}
        self._go_to(cell.start, then=None)
        return cell

    def _known_region(self, n, cell, at_start=False):
        """The lap about to start lies on a lap of another Morse cell: this cell has run into
        one already covered (a merge of the Reeb graph, recognised at a known slice). At the
        cell's start the parent's laps do not count (a successor starts on its parent's last
        slice); a later lap on a lap of the parent is the merge of the slices on both sides
        of an obstacle inside the parent, beyond that obstacle (Fig. 3: the cell beyond an
        island ends where the island's far side joins the slices again)."""
        x, y = self.pose[:2]
        for m in self.nodes:
            for c in m.cells:
                if c is cell or (at_start and m is n and c.id == cell.parent):
                    continue
                for lx, lo, hi in c.laps:
                    if abs(lx - x) < 0.75 * self.det and lo - 0.5 <= y <= hi + 0.5:
                        self._close_cell(n, cell, None, f'reached Morse cell {m.id}.{c.id}')
                        return True
        return False

    def _end_lap(self, n, cell):
        """A lap has ended at D = delta: record it, read the slice ahead and behind from the
        lap's echoes (critical points), then advance or close the cell."""
        tk, s = self.task, cell.sweep
        prof = np.array(tk['profile']) if tk['profile'] else np.zeros((0, 3))
        y0 = tk['y0']
        lo, hi = sorted((y0, self.pose[1]))
        if hi - lo < self.cfg.min_run:
            # no slice to read: the cell pinches to the robot's width here (an obstacle
            # within 2 delta of the boundary, no critical point of h): on along the boundary,
            # and the next lap leaves the boundary followed
            tk.update(phase='advance', x0=self.pose[0], leave=True)
            self.mode = 'boundary'
            return None
        cell.laps.append((tk['x'], lo, hi))
        prev_span = tk.get('prev_span') or cell.prev_span or (lo, hi)
        tk['prev_span'] = (lo, hi)
        if 'critical' not in self.cfg.without and len(prof):
            runs = self._runs(prof[:, 0], prof[:, 1] > self.far)
            if len(runs) >= 2:
                return self._split(n, cell, prof, runs)
            for a, b in self._runs(prof[:, 0], prof[:, 2] > self.far):
                if b < prev_span[0] - 1.0 or a > prev_span[1] + 1.0:
                    self._birth_behind(n, cell, (a, b))
            if not runs:
                i = int(np.nanargmin(prof[:, 1]))
                return self._close_cell(n, cell, (tk['x'] + s * prof[i, 1], prof[i, 0]),
                                        'death: the slice ends ahead')
            if len(runs) == 1 and not runs[0][0] - 0.3 <= self.pose[1] <= runs[0][1] + 0.3:
                y = runs[0][1] if self.pose[1] > runs[0][1] else runs[0][0]
                tk.update(phase='advance', x0=tk['x'])
                self._go_to((tk['x'], y), then='boundary')
                return None
        tk.update(phase='advance', x0=self.pose[0])
        self.mode = 'boundary'
        return None

    def _runs(self, ys, mask):
        """Stretches (y_lo, y_hi) of a lap where ``mask`` holds, at least ``min_run`` long."""
        order = np.argsort(ys)
        ys, mask = ys[order], mask[order]
        runs, start, last = [], None, None
        for y, m in zip(np.r_[ys, np.inf], np.r_[mask, False]):
            if m and start is None:
                start = y
            elif not m and start is not None:
                if last - start >= self.cfg.min_run:
                    runs.append((float(start), float(last)))
                start = None
            last = y
        return runs

    def _split(self, n, cell, prof, runs):
        """Critical point ahead between two open stretches: the slice splits. The current
        Morse cell closes there and one successor per stretch opens (Reeb graph)."""
        tk, s = self.task, cell.sweep
        gap = (prof[:, 0] > runs[0][1]) & (prof[:, 0] < runs[1][0])
        i = int(np.nanargmin(np.where(gap, prof[:, 1], np.inf))) if gap.any() else 0
        xy = (tk['x'] + s * prof[i, 1], prof[i, 0])
        idx = self._critical(n, xy, 'split')
        if idx is None:
            return self._advance_anyway(cell)
        self._close_cell(n, cell, None, 'split', idx=idx)
        n.circuits.append({'start': (xy[0] - s * self.det, xy[1]), 'done': False,
                           'opened_by': idx})
        here = self.pose[1]
        runs = sorted(runs, key=lambda r: min(abs(here - r[0]), abs(here - r[1])))
        for a, b in runs:
            y = min((a, b), key=lambda v: abs(here - v)) if (a, b) == runs[0] else (a + b) / 2
            n.cells.append(MorseCell(len(n.cells), (tk['x'], y), s, prev_span=(a, b),
                                     opened_by=idx, parent=cell.id))
        return None

    def _advance_anyway(self, cell):
        self.task.update(phase='advance', x0=self.pose[0])
        self.mode = 'boundary'
        return None

    def _birth_behind(self, n, cell, run):
        """Open slice behind the lap, beyond the last lap's span: a cell opening towards -x."""
        y = (run[0] + run[1]) / 2
        start = (self.task['x'], y)
        for m in self.nodes:
            for c in m.cells:
                if (c.start is not None and math.dist(c.start, start) < self.det) or any(
                        abs(lx - start[0]) < 0.9 * self.det and lo - 0.5 <= y <= hi + 0.5
                        for lx, lo, hi in c.laps if c is not cell):
                    return
        idx = self._critical(n, (start[0] - cell.sweep * self.det, y), 'birth behind')
        if idx is not None:
            n.cells.append(MorseCell(len(n.cells), start, -cell.sweep, prev_span=run,
                                     opened_by=idx, parent=cell.id))

    def _critical(self, n, xy, kind):
        idx = self._on_event(self.t_sweep, 'critical', xy, f'{kind}: the slice changes '
                             'connectivity (critical point of h = x)')
        if idx is not None:
            n.critical.append((float(xy[0]), float(xy[1]), kind, idx))
        return idx

    def _close_cell(self, n, cell, xy, why, idx=None):
        if idx is None and xy is not None:
            idx = self._critical(n, xy, why)
        cell.status, cell.closed_by = 'covered', idx
        self._record(self.t_sweep, 'cell_closed', self.pose,
                     f'Morse cell {n.id}.{cell.id}: {why}')
        self.mode, self.task = None, {}
        return None

    def _profile_reset(self):
        self.task['profile'] = []
        self.task['y0'] = self.pose[1]

    def _profile_sample(self):
        """Echoes along +-x (the sweep direction and behind) at this point of the lap."""
        if 'profile' in self.task:
            ahead = 0.0 if self.task.get('s', 1) > 0 else math.pi
            c = self.cfg.slice_cone
            self.task['profile'].append((self.pose[1], self.echo(ahead, c),
                                         self.echo(ahead + math.pi, c)))

    def _pinched(self):
        """The two closest obstacles lie either side of the robot (over 120 degrees apart),
        both nearer than delta by over half the event tolerance: a disk of radius delta does
        not fit here, so the vast cell's slice has ended (the robot moving along the boundary
        between laps has passed a cusp into narrow space)."""
        m = self.gvd_mins
        if len(m) < 2:
            return False
        (_, a1), (d2, a2) = m[:2]
        return d2 < self.det - self.cfg.event_tolerance / 2 and math.cos(a1 - a2) < -0.5

    def _touches_ahead(self, direction):
        """With ``pinch_ends_cell``: the disk of radius delta about the robot, lapping along
        +-y (``direction``), touches an obstacle ahead of it: the closest echo is nearer than
        delta by over half the event tolerance, within 60 degrees of the lap's direction (a
        corner passed beside the lap; a wall along the lap lies 90 degrees off)."""
        if not self.mins:
            return False
        d, a = self.mins[0]
        return d < self.det - self.cfg.event_tolerance / 2 and \
            math.cos(a - math.pi / 2 * direction) > 0.5

    def _lap_velocity(self, x_col, direction):
        """A straight lap along the slice x = x_col (the holonomic base keeps the column)."""
        return np.array([1.5 * (x_col - self.pose[0]), direction * self.cfg.max_speed])

    def _boundary_velocity(self, s):
        """Along +-x between two laps, following the boundary at D = delta: never nearer,
        and pulled back to it when it is within reach."""
        v = np.array([s * self.cfg.max_speed, 0.0])
        if self.mins:
            d, a = self.mins[0]
            nrm = np.array([math.cos(a), math.sin(a)])
            if d < self.det + 0.3:
                v = v - max(v @ nrm, 0.0) * nrm + np.clip(d - self.det, -1.0, 0.3) * nrm
        return v

    def _island(self, n, cell, direction):
        """The lap ends at an obstacle no boundary circuit has followed: an obstacle inside
        the Morse cell. Where the slice meets it is a critical point (the slice splits); the
        obstacle's boundary is followed next, and a successor cell resumes the slice on its
        far side. The current cell goes on, on the near side. An obstacle is followed where a
        circuit recorded a closest echo within 0.6 m of the lap's end point ``p``, or where
        the lap ends on a circuit's path with ``p`` within delta (plus the equal-echo
        tolerance) of it: there the circuit kept D = delta, so ``p`` was among its closest
        obstacles (the cones' spacing can leave such a point unrecorded at a corner of the
        circuit). With ``circuit_join`` (ours) a circuit of any vast node counts: a curve
        D = delta is one boundary, whichever node followed it."""
        if 'critical' in self.cfg.without:
            return
        d = self.echo(math.pi / 2 * direction)
        p = (self.pose[0], self.pose[1] + direction * d)
        near = self.det + self.cfg.event_tolerance
        circuits = [c for m in self.nodes if m.kind == 'vast' for c in m.circuits] \
            if self.cfg.circuit_join else n.circuits    # any vast node's: one boundary
        for c in circuits:                  # followed already, or about to be
            if (not c['done'] and math.dist(c['start'], p) < self.det + 0.5) or any(
                    math.dist(q, p) < 0.6 for q in c.get('wall', ())) or any(
                    math.dist(q, self.pose[:2]) < 0.5 and math.dist(q, p) <= near
                    for q in c.get('trace', ())):
                return                      # (or on its path, p among its closest obstacles)
        idx = self._critical(n, p, 'split: the slice meets an obstacle inside the cell')
        if idx is None:
            return
        n.circuits.append({'start': self.pose[:2], 'done': False, 'opened_by': idx})
        n.cells.append(MorseCell(len(n.cells), None, cell.sweep, opened_by=idx, parent=cell.id,
                                 resume=(self.pose[0], self.pose[1], direction)))

    def _beyond(self, n, circ):
        """Where the obstacle's circuit crosses the interrupted slice on the far side, the
        successor cell starts; none: the slice ended at the obstacle."""
        for c in n.cells:
            if c.start is not None or c.opened_by != circ['opened_by'] or c.resume is None:
                continue
            x, y, direction = c.resume
            far = [q for q in circ['trace'] if abs(q[0] - x) < 0.4 and
                   direction * (q[1] - y) > 0.5]
            if far:
                c.start = max(far, key=lambda q: direction * (q[1] - y))
            else:
                c.status = 'covered'

    def _same_cell(self, n, trace):
        """A vast node not yet covered whose cusp lies on this boundary circuit is the cell
        just followed, reached through another cusp: it is covered with it."""
        for m in self.nodes:
            if m is n or m.kind != 'vast' or m.covered or m.id == self.current:
                continue
            if any(math.dist(m.anchor, q) < 0.7 for q in trace):
                m.covered, m.merged_into = True, n.id
                self._dedupe_edges()
                m.closed_by = self._record(self.t_sweep, 'same_cell', m.anchor,
                                           f'vast node {m.id} is vast node {n.id}: its cusp '
                                           'lies on that boundary circuit')

    def _follow_velocity(self, side=1):
        """Boundary following at D = delta, obstacle on the right (``side`` -1: on the
        left): along the tangent of the closest obstacle, pulled back to D = delta along its
        normal."""
        d, a = self.mins[0]
        nrm = np.array([math.cos(a), math.sin(a)])
        tang = side * np.array([-nrm[1], nrm[0]])
        return tang * self.cfg.max_speed + np.clip(2.0 * (d - self.det), -1.0, 1.0) * nrm

    def _circuit_step(self, n, circ):
        """Follow the boundary of the vast cell at D = delta once around (Section II's
        boundary following with the robot as big as its detector); cusp points are sensed
        on it (Fig. 10). Ends back where it began."""
        tk = self.task
        if tk.get('circuit') is not circ:
            held = circ.pop('suspended', None)       # cusp_detour: resume where it was left
            back = circ.get('reverse_from')          # circuit_join: the way the first half
            self.task = tk = dict(held[1]) if held else {'circuit': circ,  # did not go
                                                         'side': -1 if back else 1}
            self._go_to(held[0] if held else back or circ['start'], then='boundary')
            return None
        if self.mode == 'transit':
            return None
        self.mode = 'boundary'
        if not self.mins:
            return np.zeros(2)
        if 'origin' not in tk:
            if self.D > self.det + 0.1:           # approach the closest obstacle first
                d, a = self.mins[0]
                return np.array([math.cos(a), math.sin(a)]) * self.cfg.max_speed
            tk.update(origin=self.pose[:2], length=0.0, last=self.pose[:2],
                      first=len(circ.get('trace', ())),
                      facing=[a for d, a in self.mins
                              if d - self.mins[0][0] <= self.cfg.event_tolerance])
            self._record(self.t_sweep, 'circuit', self.pose, f'boundary of vast node {n.id}')
        tk['length'] += math.dist(tk['last'], self.pose[:2])
        if math.dist(tk['last'], self.pose[:2]) > 1e-6:
            tk['move'] = tuple(np.asarray(self.pose[:2]) - np.asarray(tk['last']))
        tk['last'] = self.pose[:2]
        if 'away' not in tk and math.dist(tk['origin'], self.pose[:2]) > 0.3:
            tk['away'] = tuple(np.asarray(self.pose[:2]) - np.asarray(tk['origin']))
        trace = circ.setdefault('trace', [])
        if not trace or math.dist(trace[-1], self.pose[:2]) > 0.3:
            if trace and 'closed_at' not in tk and self._retraced(circ, tk):
                tk['closed_at'] = tk['length']    # on a stretch followed this way already
            trace.append(self.pose[:2])
            circ.setdefault('runs', []).append(tk['length'])
            d, a = self.mins[0]               # the followed obstacle's point
            circ.setdefault('wall', []).append((self.pose[0] + d * math.cos(a),
                                                self.pose[1] + d * math.sin(a)))
            if self.cfg.circuit_join and 'closed_at' not in tk and tk['length'] > 1.5 and \
                    self._joins_known(circ, tk):
                return self._joined(n, circ, tk)
        back = math.dist(tk['origin'], self.pose[:2])
        passed = tk['length'] > 3.0 and tk.get('back', math.inf) < 0.8 and \
            back > tk['back'] and (not self.cfg.circuit_same_way or self._same_way(tk))
        tk['back'] = back                     # closest pass by the start counts as back
        near = tk['length'] > 3.0 and back < 0.4 and \
            (not self.cfg.circuit_same_side or self._same_side(tk))
        if 'closed_at' not in tk and (near or passed):
            tk['closed_at'] = tk['length']    # back at the start
        # handed over at a cusp, the circuit starts among the cell's cusps: on past the start
        # by same_event, so that the Fig. 10 test senses the ones there
        run_on = self.cfg.same_event if self.cfg.handover else 0.0
        if tk['length'] - tk.get('closed_at', math.inf) >= run_on or tk['length'] > 500.0:
            return self._circuit_done(n, circ, tk)
        return self._follow_velocity(tk.get('side', 1))

    @staticmethod
    def _same_way(tk):
        """The circuit moves the way it left its start (within 90 degrees of the bearing
        from its start to where it first was 0.3 m away): with ``circuit_same_way`` (ours),
        a closest pass by the start counts as back at the start only so. A vast cell less
        than 0.8 m across (a room just over 2 delta wide) has its curve D = delta's far side
        pass the start the other way round, before the circuit has followed the cell's far
        end and sensed the cusps there."""
        away, move = tk.get('away'), tk.get('move')
        return away is None or move is None or float(np.dot(away, move)) > 0.0

    def _same_side(self, tk):
        """The robot faces an obstacle it faced at the circuit's start: its closest echo's
        bearing lies within 60 degrees of one of the closest echoes there (equal within the
        equidistance tolerance: a start at a corner of the curve D = delta faces both
        walls), so that, both delta away, the two echoes' points lie within delta of each
        other. With ``circuit_same_side`` (ours), a pass within 0.4 m of the start counts as
        back at the start only so. Where a vast cell is a strip under 0.4 m across, the
        curve D = delta's far side passes within 0.4 m of the start facing the opposite
        wall, and a strip's end within 0.4 m of a start at its side faces the wall across
        the end, before the circuit has followed the strip's far end and sensed the cusps
        there."""
        if not tk.get('facing') or not self.mins:
            return True
        a = self.mins[0][1]
        return any(math.cos(a - b) > 0.5 for b in tk['facing'])

    def _retraced(self, circ, tk, near=0.3, behind=3.0):
        """The circuit is back on a stretch of its own trace followed the same way (within
        ``near`` of a point more than ``behind`` m of circuit back, heading within 45 degrees
        of the heading there): it has gone round the curve D = delta once. Where that
        curve is a sliver with a bend, boundary following can turn back and forth in one arm
        without passing its start again; the circuit is done there too."""
        trace, runs = circ['trace'], circ.get('runs', ())
        if len(runs) != len(trace):
            return False
        here = np.asarray(self.pose[:2]) - np.asarray(trace[-1])
        if not np.hypot(*here):
            return False
        for i in range(tk.get('first', 0), len(trace) - 1):     # this half's own trace
            if tk['length'] - runs[i] < behind:
                break
            if math.dist(trace[i], self.pose[:2]) < near:
                step = np.asarray(trace[i + 1]) - np.asarray(trace[i])
                if float(step @ here) > math.cos(math.radians(45)) * \
                        float(np.hypot(*step) * np.hypot(*here)):
                    return True
        return False

    def _joins_known(self, circ, tk):
        """Switch ``circuit_join`` (ours): the robot, following a boundary at D = delta, is on
        a stretch another circuit has followed (within the equal-echo tolerance of its path).
        A curve at D = delta bounds one vast cell, so that boundary is known from here on:
        its cusps are sensed and its far side recorded. A circuit's second half (the way the
        first one did not go round) also stops on the first half's path beyond 1.2 m of its
        start."""
        p = np.asarray(self.pose[:2])
        for m in self.nodes:
            if m.kind != 'vast':
                continue
            for c in m.circuits:
                pts = c.get('trace', ())
                if c is circ:
                    if tk.get('side', 1) > 0:
                        continue
                    o = circ['reverse_from']
                    pts = [q if math.dist(q, o) > 1.2 else None
                           for q in pts[:circ['first_len']]]
                if self._near_path(pts, p) < self.cfg.event_tolerance:
                    return True
        return False

    @staticmethod
    def _near_path(pts, p):
        """Distance from ``p`` to the polyline through ``pts`` (samples 0.3 m apart; a
        ``None`` or a gap over 0.6 m breaks it)."""
        best = math.inf
        for a, b in zip(pts, pts[1:]):
            if a is None or b is None or abs(a[0] - p[0]) > 1.0 or abs(a[1] - p[1]) > 1.0:
                continue
            a, b = np.asarray(a), np.asarray(b)
            d = b - a
            dd = float(d @ d)
            if dd > 0.36:
                continue
            t = min(max(float((p - a) @ d) / dd, 0.0), 1.0) if dd > 0 else 0.0
            best = min(best, float(np.hypot(*(a + t * d - p))))
        return best

    def _joined(self, n, circ, tk):
        """The circuit has reached a boundary followed already (``circuit_join``): the first
        half ends there and the boundary is followed from the circuit's start the other way
        round, until that half too reaches a known stretch; then the circuit is done."""
        self._record(self.t_sweep, 'circuit_joined', self.pose,
                     f'boundary of vast node {n.id} followed already from here')
        circ['joined'] = True
        if tk.get('side', 1) > 0:
            circ.update(reverse_from=tk['origin'], first_len=len(circ['trace']),
                        first_length=tk['length'])
            self.task, self.mode = {}, None
            return None
        tk['length'] += circ.get('first_length', 0.0)
        return self._circuit_done(n, circ, tk)

    def _circuit_done(self, n, circ, tk):
        """The circuit has gone round (or, ``circuit_join``, both its halves have reached
        known boundary): merge the vast nodes whose cusps lie on it, start the slices beyond
        the obstacles it went round, and open the node's first Morse cell."""
        circ.update(done=True, length=tk['length'], back_at=tk.get('closed_at'))
        whole = not circ.get('joined')      # an open stretch encloses nothing
        sliver = whole and self._sliver_tips(circ['trace'])
        self._same_cell(n, circ['trace'])
        self._beyond(n, circ)
        if not n.cells:
            n.cells.append(MorseCell(0, self.pose[:2], +1, opened_by=circ['opened_by']))
            if sliver:        # narrower than a lap: the circuit has swept it (one lap)
                self._close_cell(n, n.cells[0], None, 'the circuit encloses no area: '
                                 'the cell is narrower than one lap and swept by it')
            elif self.cfg.circuit_sweeps and whole and self._thin(circ['trace']):
                self._close_cell(n, n.cells[0], None, 'every point the circuit encloses '
                                 'lies within delta of it: swept by the circuit')
        self.task, self.mode = {}, None
        q = np.asarray(circ['trace'], dtype=float)
        mid = q.mean(axis=0)
        if sliver and self.cfg.sliver_openings and 'cusp' not in self.cfg.without and \
                float(np.hypot(*(q - mid).T).max()) <= 0.5 * self.det:
            self.task = {'opening_scan': {'at': tuple(map(float, mid)),
                                          'trace': circ['trace'], 't0': self.t_sweep}}
        return None

    def _opening_scan_step(self, n):
        """Switch ``sliver_openings`` (ours): a vast cell that is a sliver no longer than
        delta (its circuit within delta / 2 of its middle) is a place, read like a meet point
        once its circuit has closed. Every GVD edge leaving a vast cell meets it at
        a cusp point (Section IV-B), but on a small cell the circuit's Fig. 10 test (the
        closest obstacle's bearing jumps) can give two edges one node: a narrow door beside
        a corner has its cusp within ``same_event`` of the corner's, the jump between its
        jambs is about the test's 45 degrees, and the cusp sensed there leads between that
        sweep's two closest obstacles (a jamb and the wall beyond it: the corner's edge),
        so the other cusp reads as the same edge. The robot goes to the middle of the
        circuit, halts while its ring turns through one cone spacing (as on a meet point,
        ``meet_scan``), and takes the openings of the range over bearing beyond delta there
        (:meth:`_cell_openings`) as the GVD edges leaving the cell. An edge leaving along a
        bearing meets the cell where the circuit (the curve D = delta) reaches farthest
        that way. An opening along which a GVD edge is traced already (:meth:`_edge_traced`)
        is an edge of a known node; one with no cusp of the node's edges there
        (:meth:`_known`: within ``same_event``, on the same edge) is a cusp event at that
        point, creating its narrow node (CreateNode), which leaves along the opening. No
        traced branch ends on such an edge, whatever the heading a branch ended with nearby
        (a trace turns as it enters a small cell): the cusp joins no traced narrow node. A
        longer sliver is a stretch of GVD edge where D > delta: its tips are its cusps
        (:meth:`_sliver_tips`), and its middle lies beyond delta / 2 of the robot that has
        closed its circuit."""
        tk = self.task
        job = tk['opening_scan']
        if 'scan' not in tk:                       # to the middle of the sliver
            off = np.asarray(job['at']) - np.asarray(self.pose[:2])
            d = float(np.hypot(*off))
            if d > 0.1 and self.t_sweep - job['t0'] < 5.0:
                return off / d * min(self.cfg.max_speed, 2.0 * d)
            tk['scan'] = self._new_scan()
            return np.zeros(2)
        scan = tk['scan']
        if not self._scan_turned(scan):
            return np.zeros(2)                     # the ring turns (sweeps: _scan_sweep)
        self.task, self.mode = {}, None
        ang, rng = self._scan_echoes(scan)
        q = np.asarray(job['trace'], dtype=float)
        for m in self._cell_openings(ang, rng):
            u = (math.cos(m), math.sin(m))
            xy = tuple(map(float, q[int(np.argmax(q @ np.asarray(u)))]))
            if self._edge_traced(xy, u):
                continue                           # an edge traced already: a known node's
            self._cusp_dir, self._opening_untraced = float(math.remainder(m, 2 * math.pi)), True
            self._on_event(self.t_sweep, 'cusp', xy, 'GVD edge leaving a vast cell that is a '
                           'sliver: an opening of the range over bearing beyond delta from '
                           'its middle')
        self._cusp_dir, self._opening_untraced = None, False
        return None

    def _cell_openings(self, angles, ranges):
        """Bearings of the GVD edges leaving a vast cell, from a scan at its middle: the
        peaks of the range over bearing reaching beyond delta and standing out by at least
        the event tolerance from the dips on either side, each along the middle of its
        peak's upper half; a peak whose upper half holds another's top is that edge
        (:meth:`_openings`' rules for a meet point). Its other rule, that two peaks within
        45 degrees are one edge unless a bearing between them meets an obstacle within
        delta, does not apply: from inside a vast cell every bearing reaches beyond delta,
        and a door beside a room's corner is a peak of its own."""
        *_, peaks = gvdmod.range_peaks(angles, ranges, self.det, self.cfg.event_tolerance)
        kept = []                                  # (middle, top, lo, hi) per edge
        for lo, hi, top in peaks:
            if not any(lo <= q[1] + s <= hi or q[2] <= top + s <= q[3]
                       for q in kept for s in (-2 * math.pi, 0.0, 2 * math.pi)):
                kept.append(((lo + hi) / 2, top, lo, hi))
        return [float(math.remainder(q[0], 2 * math.pi)) for q in kept]

    def _thin(self, trace, step=0.25, most=4000):
        """Every point the circuit encloses lies within ``delta - overlap`` of the circuit
        (switch ``circuit_sweeps``, ours): the detector has swept the cell from its boundary
        and no lap is needed. No obstacle can lie inside such a circuit, since the circuit
        keeps D = delta from every obstacle. Only a circuit that turned around the cell (its
        heading turned by more than 1.4 pi: a loop closing at a corner turns 1.5 pi before
        it) counts; checked on a ``step`` grid of the enclosed points (a cell of more than
        ``most`` of them is taken as not thin). Off in the default: it drops the paper's laps,
        and lowers some generated worlds by up to 0.68 points of CVS, none below 99 %
        (docs/coverage.md, Modes)."""
        q = np.asarray(trace, dtype=float)
        if len(q) < 4:
            return False
        seg = np.diff(q, axis=0)
        head = np.arctan2(seg[:, 1], seg[:, 0])
        turn = float((np.remainder(np.diff(head) + np.pi, 2 * np.pi) - np.pi).sum())
        if abs(turn) < 1.4 * np.pi:
            return False                          # the circuit did not turn around the cell
        lo, hi = q.min(axis=0), q.max(axis=0)
        xs, ys = np.arange(lo[0], hi[0], step), np.arange(lo[1], hi[1], step)
        if len(xs) * len(ys) > most:
            return False
        px, py = (g.ravel() for g in np.meshgrid(xs, ys))
        a, b = q, np.roll(q, -1, axis=0)
        inside = np.zeros(px.shape, dtype=bool)
        for (x1, y1), (x2, y2) in zip(a, b):          # even-odd rule
            if y1 != y2:
                cross = ((y1 > py) != (y2 > py)) & \
                    (px < x1 + (py - y1) * (x2 - x1) / (y2 - y1))
                inside ^= cross
        p = np.column_stack([px[inside], py[inside]])
        if not len(p):
            return True
        d = b - a
        t = np.clip(((p[:, None, :] - a[None]) * d[None]).sum(-1) /
                    np.maximum((d * d).sum(-1), 1e-12)[None], 0.0, 1.0)
        dist = np.hypot(*(p[:, None, :] - (a[None] + t[..., None] * d[None])).transpose(2, 0, 1))
        return float(dist.min(axis=1).max()) < self.det - self.cfg.overlap

    def _sliver_tips(self, trace):
        """A circuit that encloses no area (mean width 2 A / length < 0.3 m) has followed the
        GVD itself: the vast cell is a sliver between walls about 2 delta apart (against the
        paper's assumption of Section IV-B). Its two tips are where D falls to delta on the
        GVD, i.e. cusp points by the paper's definition, which the Fig. 10 test does not
        place at a turn-around; each is sensed here, its bearing out along the sliver."""
        if len(trace) < 4:
            return False
        q = np.asarray(trace, dtype=float)
        x, y = q[:, 0], q[:, 1]
        area = 0.5 * abs(float(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1))))
        length = float(np.hypot(*np.diff(np.vstack([q, q[:1]]), axis=0).T).sum())
        if length < 2.0 or 2.0 * area / length >= 0.3:
            return False
        if 'cusp' in self.cfg.without:
            return True
        mid = q.mean(axis=0)
        axis = np.linalg.svd(q - mid)[2][0]
        proj = (q - mid) @ axis
        for tip, out in ((q[int(np.argmin(proj))], -axis), (q[int(np.argmax(proj))], axis)):
            self._cusp_dir = math.atan2(out[1], out[0])
            self._on_event(self.t_sweep, 'cusp', tuple(tip), 'tip of a vast cell that is a '
                           'sliver along the GVD (D = delta on the GVD)')
        self._cusp_dir = None
        return True
