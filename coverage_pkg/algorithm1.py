"""Algorithm 1 of Acar, Choset and Lee, driven by sensed events alone (``planner:=paper``).

Every structure of the hierarchical decomposition graph ``(N, E)`` is created by an event
the sonar ring senses; no map is decomposed. The subroutines map one to one onto the paper:

* :meth:`PaperPlanner.create_node` is ``CreateNode(x, D(x))``: a vast node where ``D > delta``,
  a narrow node otherwise. It is called for the start and for every new *cusp point*
  (Section V-B): a cusp sensed while covering a vast node creates a narrow node, one sensed
  while tracing a narrow node creates a vast node, and the edge between them carries the cusp.
* :meth:`PaperPlanner._morse_step` is ``MorseDecompCoverage(n, L, F)``: laps along the slices
  of ``h = x`` spaced ``2 delta`` apart (the robot "as big as its detector", Section IV-A),
  ended at ``D = delta`` ahead, and the moves between laps following the boundary at
  ``D = delta``. A *critical point* sensed from a lap (the slice's connectivity changes ahead:
  the ring's echoes along ``+-x`` show two open stretches, or none) closes the current Morse
  cell and opens its successors in the node's Reeb graph; the node is covered when every
  Morse cell has closed.
* :meth:`PaperPlanner._gvd_step` is ``TraceGVD(n, L, F)``: from a cusp point the robot follows
  the GVD edge by a control law on its two closest echoes; a *meet point* (three closest
  obstacles equidistant) adds the GVD branches leaving it; the narrow node is covered when
  every branch has ended at a cusp point, a dead end or a meet point already known.
* :meth:`PaperPlanner.find_uncovered_node` is ``FindUncoveredNode(N)``, the uncovered node
  nearest along the traced paths; the path to ``x(n)`` runs along the robot's own traced path
  (:class:`TracedPaths`): a sample joins another when the segment between them lies in the
  free disk the ring measured there. Where that way runs back along a traced GVD edge, the
  robot follows the edge by the GVD control law (:meth:`PaperPlanner._retrace_velocity`).

Sensing details the paper leaves open: a cusp is known only on the same GVD edge (its bearing
into the narrow cell), since the cusps of a small vast cell lie within a step of one another;
D rising above delta on a traced edge is a cusp at the robot (Fig. 11) where the ring's
two-echo test placed none; a GVD edge ends where all ahead is within the detector's view,
and a gap beyond delta beside that end (a door by a corner) is a branch (a meet event); a
start on neither the GVD nor VR first moves off its single closest obstacle
(:meth:`PaperPlanner._access`).

``without`` switches the sensing of one event kind off (``cusp``, ``critical``, ``meet``), so
that the run shows what the paper predicts without it. Plain numpy; no ROS.
"""
from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike

from coverage_pkg import gvd as gvdmod
from paramotion.errors import UserError

EVENTS = ('cusp', 'critical', 'meet')
TERMINAL = ('done', 'stuck', 'incomplete')


def parse_without(value: str | Iterable[str] | None) -> tuple[str, ...]:
    """Event kinds from a comma-separated string or a list; UserError names a bad one."""
    items = value.split(',') if isinstance(value, str) else list(value or ())
    out = tuple(sorted({w.strip() for w in items if w.strip()}))
    bad = [w for w in out if w not in EVENTS]
    if bad:
        raise UserError(f'without "{bad[0]}" must be one of {", ".join(EVENTS)}')
    return out


@dataclass
class PaperConfig:
    """Parameters of the paper planner (SI units)."""

    delta: float = 2.0              # detector range (m)
    radius: float = 0.25            # robot radius r (m)
    max_speed: float = 1.0          # m/s
    spin_rate: float = 0.6          # rad/s, turns the ring over the gaps between its cones
    sonar_timeout: float = 0.5      # s without a sweep before stopping
    warmup: float = 1.0             # s spinning in place before the first move
    without: tuple = ()             # event kinds whose sensing is switched off
    event_tolerance: float = 0.15   # m, closest echoes this equal are equidistant
    cone: float = math.radians(20.0)   # half-angle of the echoes taken as 'ahead'
    slice_cone: float = math.radians(12.0)  # ... as along +-x when a lap reads the slice
    overlap: float = 0.2            # m, laps are 2 delta - overlap apart
    min_run: float = 0.5            # m, a stretch of a lap shorter than this is echo noise
    same_event: float = 0.5         # m, an event this near a known one is the known one
    view_margin: float = 0.3        # m, a GVD edge ends where all ahead is within delta - this
    access_time: float = 10.0       # s, longest move from the start onto the GVD or into VR
    stuck_time: float = 6.0         # s commanded but not moving -> the target is given up
    max_stuck: int = 6              # stuck events in a row before the run stops
    detector: str = 'extended'      # the paper planner is for the extended-range detector

    def detector_range(self) -> float:
        """Range of the detector used for coverage: delta."""
        return self.delta

    def validate(self, sonar_max_range: float | None = None) -> None:
        """Raise UserError (one line) for inconsistent parameters."""
        if not self.radius > 0:
            raise UserError(f'radius {self.radius:g} m must be > 0')
        if not self.delta > self.radius:
            raise UserError(f'delta {self.delta:g} m must be greater than the robot radius '
                            f'{self.radius:g} m')
        parse_without(self.without)
        if sonar_max_range is not None and not sonar_max_range > self.delta:
            raise UserError(f'sonar max range {sonar_max_range:g} m must exceed delta '
                            f'{self.delta:g} m')


@dataclass
class Command:
    """Velocity command in the robot body frame plus the planner state."""

    vx: float
    vy: float
    wz: float
    state: str


@dataclass
class MorseCell:
    """An edge of a vast node's Reeb graph: a cell between two critical points."""

    id: int
    start: tuple                    # where its first lap is driven from
    sweep: int                      # +1: laps advance along +x, -1: along -x
    prev_span: tuple = None         # (y_lo, y_hi) of the lap before its first one
    opened_by: int = None           # index of the event that opened it
    closed_by: int = None           # ... and of the event that closed it
    parent: int = None              # the cell whose critical point opened it
    resume: tuple = None            # (x, y, dir): a slice to resume beyond an obstacle
    laps: list = field(default_factory=list)   # (x, y_lo, y_hi) per lap driven
    status: str = 'open'            # open, covering, covered, given_up


@dataclass
class Branch:
    """A GVD edge of a narrow node, left from ``start`` along ``heading``."""

    start: tuple
    heading: tuple
    opened_by: int = None
    end: str = None                 # cusp, dead_end, meet, given_up (None: untraced)
    end_xy: tuple = None            # where the trace ended
    end_heading: tuple = None       # the direction it was traced in when it ended


@dataclass
class Node:
    """A node of the hierarchical decomposition graph."""

    id: int
    kind: str                       # 'vast' or 'narrow'
    anchor: tuple                   # x(n): where the robot starts covering it
    created_by: int = None          # event index (None: CreateNode at the start)
    closed_by: int = None
    covered: bool = False
    given_up: bool = False
    merged_into: int = None         # vast: the node whose boundary circuit passed its cusp
    circuits: list = field(default_factory=list)    # vast: boundaries to follow at D = delta
    cells: list = field(default_factory=list)       # vast: Morse cells (Reeb graph edges)
    critical: list = field(default_factory=list)    # vast: (x, y, kind, event index)
    branches: list = field(default_factory=list)    # narrow: GVD branches
    meets: list = field(default_factory=list)       # narrow: (x, y, event index)


class TracedPaths:
    """The robot's own path as a roadmap for transit (Algorithm 1: 'find a path ... in (N, E)').

    Samples every ``step`` m carry the distance ``D`` the ring measured there; two samples are
    joined when they are closer than ``min(D_i, D_j) - clearance`` (the segment then lies in a
    disk the ring saw free), and consecutive samples always. The joins are made when a sample
    is added (among the samples within ``hop``), so a transit plan is one shortest-path search
    over a fixed sparse graph.
    """

    def __init__(self, clearance: float, step: float = 0.3, bucket: float = 1.5,
                 hop: float = 1.5):
        self.clear, self.step, self.bucket, self.hop = clearance, step, bucket, hop
        self.xy, self.d, self.grid = [], [], {}
        self._i, self._j, self._w = [], [], []
        self._csr = None

    def add(self, x: float, y: float, d: float) -> None:
        if self.xy and math.dist(self.xy[-1], (x, y)) < self.step:
            return
        k = len(self.xy)
        for j in self._near_point((x, y), self.hop + self.clear):
            step = math.dist(self.xy[j], (x, y))
            if step <= min(d, self.d[j], self.hop + self.clear) - self.clear or \
                    (j == k - 1 and step <= self.hop):
                self._i.append(k)
                self._j.append(j)
                self._w.append(max(step, 1e-6))
        self.xy.append((x, y))
        self.d.append(d)
        key = (int(x // self.bucket), int(y // self.bucket))
        self.grid.setdefault(key, []).append(k)
        self._csr = None

    def nearest(self, xy: Sequence[float]) -> int | None:
        for reach in (1.0, 3.0, 10.0, 1e9):
            best = None
            for j in (self._near_point(xy, reach) if reach < 1e9 else range(len(self.xy))):
                dd = math.dist(self.xy[j], xy)
                if dd <= reach and (best is None or dd < best[0]):
                    best = (dd, j)
            if best:
                return best[1]
        return None

    def _near_point(self, xy, reach):
        k = int(math.ceil(reach / self.bucket))
        bx, by = int(xy[0] // self.bucket), int(xy[1] // self.bucket)
        for gx in range(bx - k, bx + k + 1):
            for gy in range(by - k, by + k + 1):
                yield from self.grid.get((gx, gy), ())

    def distances(self, src: int) -> dict:
        """Path length along the roadmap from sample ``src`` to every sample reached."""
        dist, _ = self._dijkstra(src)
        ok = np.flatnonzero(np.isfinite(dist))
        return dict(zip(ok.tolist(), dist[ok].tolist()))

    def route(self, src: int, dst: int) -> list:
        """Waypoints from sample ``src`` to sample ``dst`` (empty if not connected)."""
        dist, prev = self._dijkstra(src)
        if not np.isfinite(dist[dst]):
            return []
        out = [dst]
        while out[-1] != src:
            out.append(int(prev[out[-1]]))
        return [self.xy[i] for i in reversed(out)]

    def _dijkstra(self, src):
        from scipy.sparse import coo_matrix
        from scipy.sparse.csgraph import dijkstra
        n = len(self.xy)
        if self._csr is None:
            self._csr = coo_matrix((self._w, (self._i, self._j)), shape=(n, n)).tocsr()
        return dijkstra(self._csr, directed=False, indices=src, return_predecessors=True)


class PaperPlanner:
    """Algorithm 1 online. Feed :meth:`on_odometry` and :meth:`on_sweep`; call :meth:`update`.

    ``event_filter(kind, xy) -> bool`` (tests) drops a sensed event before it is used;
    ``injected`` holds ``(t, kind, (x, y))`` events handed to the planner as if sensed.
    """

    def __init__(self, config: PaperConfig, mount_angles: ArrayLike, beam_width: float,
                 min_range: float, max_range: float, noise_std: float = 0.01):
        config.validate(max_range)
        self.cfg = config
        self.mount = np.asarray(mount_angles, dtype=float)
        self.min_range, self.max_range = float(min_range), float(max_range)
        self.det = config.delta
        self.spacing = 2.0 * config.delta - config.overlap
        # A slice is open ahead where the echo along the sweep reaches beyond what the next
        # lap and the boundary circuit see (3 delta), as far as the ring can tell.
        self.far = min(3.0 * config.delta, 0.95 * self.max_range)
        self.nodes, self.edges = [], []            # N, E; edge: (vast id, narrow id, cusp)
        self.events = []                           # (t, kind, x, y, detail)
        self.segments = []                         # [primitive, length m]
        self.decisions = []
        self.paths = TracedPaths(config.radius + 0.1)
        self.event_filter = None
        self.injected = []
        self.pose = self.t_sweep = self.t_first_sweep = None
        self.t_plan = 0.0
        self.state = 'no_odometry'
        self.current = None                        # Algorithm 1's n
        self.mode, self.task = None, {}            # primitive being driven and its data
        self.route = []
        self.sweeps = 0
        self.D, self.mins, self.angles, self.ranges = math.inf, [], None, None
        self._prev_d, self._near_bearing, self._meet_cand = None, None, None
        self._hist, self.stuck_count, self.given_up = [], 0, []
        self.update_times = []
        self.last = {}                             # no decomposed map (the node's markers)
        self._cusp_dir = None                      # bearing into the narrow cell, this cusp
        self._cusp_dirs = {}                       # cusp (x, y) of an edge -> that bearing
        self._on_gvd = False                       # this transit step follows a GVD edge
        self.gvd_trace = {}                        # points of traced GVD edges, by 1 m bucket
        self._gvd_last = None

    # ------------------------------------------------------------------ inputs

    def on_odometry(self, t: float, x: float, y: float, yaw: float) -> None:
        """Robot pose in the odom frame at sim time t."""
        if all(math.isfinite(v) for v in (t, x, y, yaw)):
            kind = 'gvd' if self.mode == 'transit' and self._on_gvd else self.mode
            if self.pose is not None and kind:
                step = math.dist(self.pose[:2], (x, y))
                if self.segments and self.segments[-1][0] == kind:
                    self.segments[-1][1] += step
                elif step > 0:
                    self.segments.append([kind, step])
            self.pose = (float(x), float(y), float(yaw))

    def on_sweep(self, t: float, ranges: ArrayLike) -> None:
        """One sweep of the ring (REP 117 values, in mount order): D, closest echoes, events."""
        if self.pose is None:
            return
        r = np.asarray(ranges, dtype=float)
        with np.errstate(invalid='ignore'):
            ok = np.isfinite(r) & (r >= self.min_range)
        r = np.where(np.isposinf(r), self.max_range, np.where(ok, r, np.nan))
        if not np.isfinite(r).any():
            return
        self.t_sweep = t
        self.t_first_sweep = t if self.t_first_sweep is None else self.t_first_sweep
        self.sweeps += 1
        self.ranges, self.angles = r, self.mount + self.pose[2]
        rr = np.where(np.isfinite(r), r, np.inf)
        self.mins = gvdmod.ring_minima(rr, self.angles)
        prev, self.D = self.D, float(np.nanmin(r))
        self.paths.add(self.pose[0], self.pose[1], self.D)
        if self.mode == 'gvd' and (self._gvd_last is None or
                                   math.dist(self._gvd_last, self.pose[:2]) > 0.2):
            head = self.task.get('heading') or (0.0, 0.0)
            self._gvd_last = self.pose[:2]
            key = (int(self.pose[0] // 1.0), int(self.pose[1] // 1.0))
            self.gvd_trace.setdefault(key, []).append((*self.pose[:2], self.sweeps,
                                                       float(head[0]), float(head[1])))
        if t - self.t_first_sweep >= self.cfg.warmup and self.mode in ('lap', 'boundary',
                                                                      'gvd'):
            self._sense_cusp(t, prev)
            if self.mode == 'gvd':
                self._sense_meet(t)
        for ev in [e for e in self.injected if e[0] <= t]:
            self.injected.remove(ev)
            self._on_event(t, ev[1], ev[2], 'injected')
        if self.mode == 'lap':
            self._profile_sample()

    def echo(self, direction: float, cone: float = None) -> float:
        """Nearest echo within ``cone`` of the world bearing ``direction`` (max range if none)."""
        diff = np.abs(np.remainder(self.angles - direction + math.pi, 2 * math.pi) - math.pi)
        sel = (diff <= (cone or self.cfg.cone)) & np.isfinite(self.ranges)
        return float(self.ranges[sel].min()) if sel.any() else self.max_range

    # ------------------------------------------------------------------ event sensing

    def _sense_cusp(self, t, prev):
        """Cusp point (Section V-B): D crosses delta on the GVD (Fig. 11), or, while following
        a boundary at D = delta, the closest obstacle jumps to another one (Fig. 10; on a GVD
        edge the closest obstacle alternates between the two equidistant ones, which is no
        cusp); placed where both are at delta. On a GVD edge, D must cross delta + 0.015 m:
        between walls about 2 delta apart, echo noise makes D cross delta back and forth."""
        xy = None
        level = self.det + (0.015 if self.mode == 'gvd' else 0.0)
        if math.isfinite(prev) and (prev <= level) != (self.D <= level):
            xy = gvdmod.cusp_from_ring(self.pose[:2], self.ranges, self.angles, self.det)
        bearing = self.mins[0][1] if self.mins else None
        last, self._near_bearing = self._near_bearing, bearing
        if xy is None and self.mode == 'boundary' and last is not None and \
                bearing is not None and abs(self.D - self.det) < 0.3 and \
                abs(math.remainder(bearing - last, 2 * math.pi)) > math.radians(45):
            xy = gvdmod.cusp_from_ring(self.pose[:2], self.ranges, self.angles, self.det)
        if xy is not None:
            head = self.task.get('heading') if self.mode == 'gvd' else None
            # traced along its GVD edge: back along the trace is into the narrow cell
            self._cusp_dir = self._gvd_direction() if head is None else \
                math.atan2(-head[1], -head[0])
            self._on_event(t, 'cusp', xy, 'D = delta where two closest obstacles meet')
            self._cusp_dir = None

    def _sense_meet(self, t):
        """Meet point (Section III): three closest obstacles equidistant, two sweeps agreeing."""
        m = gvdmod.meet_from_ring(self.pose[:2], self.ranges, self.angles)
        if m is None or m[2] > self.det:
            self._meet_cand = None
            return
        prev, self._meet_cand = self._meet_cand, m
        if prev is not None and math.dist(prev[:2], m[:2]) <= 0.15:
            self._on_event(t, 'meet', ((m[0] + prev[0]) / 2, (m[1] + prev[1]) / 2),
                           f'three closest obstacles at {m[2]:.2f} m')

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
        return any(e[1] == kind and math.dist(e[2:4], xy) < near for e in self.events)

    def _same_edge(self, c, into):
        """The cusp ``c`` lies on the GVD edge leaving along ``into`` (bearing into its narrow
        cell; unknown either way: the same). A small vast cell's cusps lie within a step of
        one another, each on its own edge."""
        known = self._cusp_dirs.get((round(c[0], 3), round(c[1], 3)))
        if known is None or into is None:
            return True
        return abs(math.remainder(known - into, 2 * math.pi)) < math.radians(30)

    def _record(self, t, kind, xy, detail):
        self.events.append((round(float(t), 3), kind, round(float(xy[0]), 3),
                            round(float(xy[1]), 3), detail))
        return len(self.events) - 1

    # ------------------------------------------------------------------ Algorithm 1

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
        is that narrow cell's cusp: the edge joins the known node, no node is created."""
        n = self.nodes[self.current] if self.current is not None else None
        if n is None:
            return
        m = self._traced_narrow(xy) if n.kind == 'vast' else None
        if m is not None:
            self._add_edge(n.id, m.id, xy, f'cusp joins narrow node {m.id}: a traced GVD '
                           'branch of it ends here')
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

    def _traced_narrow(self, xy):
        """The narrow node whose traced GVD branch ended at this cusp (the cusp event that
        ended it, or the branch's last point, within ``same_event``), if any."""
        near = self.cfg.same_event
        for v, w, c in self.edges:
            if math.dist(c, xy) < near and self._created_from(v, w, self._cusp_dir):
                return self.nodes[w]
        for m in self.nodes:
            if m.kind == 'narrow' and any(self._arrived(b, xy, near, self._cusp_dir)
                                          for b in m.branches):
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
    def _arrived(b, xy, near, into):
        """Branch ``b`` ended at the cusp ``xy`` on the same GVD edge: within ``near`` of it,
        traced out of the narrow cell opposite to the cusp's bearing ``into`` it (the cusps
        of a small vast cell lie within a step of one another, each on its own edge)."""
        if b.end != 'cusp' or b.end_xy is None or math.dist(b.end_xy, xy) >= near:
            return False
        if into is None or b.end_heading is None:
            return True
        out = math.atan2(b.end_heading[1], b.end_heading[0])
        return abs(math.remainder(out - into - math.pi, 2 * math.pi)) < math.radians(45)

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

    def find_uncovered_node(self) -> Node | None:
        """FindUncoveredNode(N): the uncovered node nearest along the traced paths. A narrow
        node all of whose open branches run along GVD edges already traced is covered."""
        for n in self.nodes:
            if not n.covered and n.kind == 'narrow' and n.branches and \
                    not self._open_branches(n):
                n.covered = True
                n.closed_by = self._record(self.t_sweep or 0.0, 'node_covered', n.anchor,
                                           f'narrow node {n.id}: its GVD edges are traced')
        cands = [n for n in self.nodes if not n.covered]
        if not cands:
            return None
        cost = self._path_costs([n.anchor for n in cands])
        return min(zip(cost, [n.id for n in cands], cands))[2]

    def _path_costs(self, points):
        """Length of the way to each of ``points`` along the traced paths (the roadmap's
        shortest path to the sample nearest each, plus the straight rest)."""
        src = self.paths.nearest(self.pose[:2])
        if src is None:
            return [math.dist(self.pose[:2], q) for q in points]
        dist = self.paths.distances(src)
        out = []
        for q in points:
            j = self.paths.nearest(q)
            out.append(dist.get(j, 1e6) + math.dist(self.paths.xy[j], q))
        return out

    def update(self, t: float) -> Command:
        """Advance the planner at sim time t; returns the velocity command to send."""
        if self.pose is None:
            return Command(0.0, 0.0, 0.0, 'no_odometry')
        if self.state in TERMINAL:
            return Command(0.0, 0.0, 0.0, self.state)
        if self.t_sweep is None or t - self.t_sweep > self.cfg.sonar_timeout:
            if self.state != 'waiting_for_sonar':
                self._record(t, 'sonar_timeout', self.pose, 'no valid sonar sweep, stopped')
            self.state = 'waiting_for_sonar'
            self._hist.clear()
            return Command(0.0, 0.0, 0.0, self.state)
        if self.state == 'waiting_for_sonar':
            self._record(t, 'sonar_resumed', self.pose, 'sonar sweeps back, resuming')
        if t - self.t_first_sweep < self.cfg.warmup:
            self.state = 'warmup'
            return Command(0.0, 0.0, self.cfg.spin_rate, self.state)
        if self.current is None and not self.nodes:
            v = self._access(t)
            if v is not None:
                self.state = 'access'
                return self._body(*self._guard(v))
            self.current = self.create_node('vast' if self.D > self.det else 'narrow',
                                            self.pose[:2]).id
            self._begin_node(self.nodes[self.current])
        self.t_plan = t
        for _ in range(6):                 # a finished primitive hands over at once
            v = self._step(t)
            if v is not None or self.state in TERMINAL:
                break
        if self.state in TERMINAL or v is None:
            return Command(0.0, 0.0, 0.0, self.state)
        self._check_stuck(t, v)
        return self._body(*self._guard(v))

    def _access(self, t):
        """Before CreateNode: a start within delta of a single obstacle lies neither on the
        GVD nor in VR; the robot moves away from that obstacle until two closest obstacles
        are equidistant (on the GVD: a narrow node) or D exceeds delta (a vast node), for
        at most ``access_time`` s. None when the node can be created here."""
        if self.D > self.det or t - self.t_first_sweep > self.cfg.warmup + \
                self.cfg.access_time or not self.mins:
            return None
        d1, a = self.mins[0]
        if any(d - d1 < 2 * self.cfg.event_tolerance and
               abs(math.remainder(a - b, 2 * math.pi)) > math.radians(60)
               for d, b in self.mins[1:]):
            return None
        return -np.array([math.cos(a), math.sin(a)]) * self.cfg.max_speed

    def _step(self, t):
        """One control step of the primitive being driven; None when it has just ended."""
        n = self.nodes[self.current] if self.current is not None else None
        if self.mode == 'transit':
            return self._transit_step()
        if n is None or n.covered:
            return self._next_node(t)
        self.state = f'covering_{n.kind}'
        return self._morse_step(n) if n.kind == 'vast' else self._gvd_step(n)

    def _next_node(self, t):
        """Mark n covered, n <- FindUncoveredNode(N), path to x(n) in (N, E)."""
        if self.current is not None:
            n = self.nodes[self.current]
            if not n.covered:
                n.covered = True
            n.closed_by = len(self.events)
            self._record(t, 'node_covered', self.pose, f'{n.kind} node {n.id}')
        nxt = self.find_uncovered_node()
        if nxt is None:
            self.state = 'incomplete' if self.given_up else 'done'
            self.mode = None
            self._record(t, self.state, self.pose, 'no uncovered node left (FindUncoveredNode)'
                         + (f'; given up: {self.given_up}' if self.given_up else ''))
            return None
        self.current = nxt.id
        self.decisions.append((round(t, 3), nxt.id, nxt.kind, nxt.anchor[0], nxt.anchor[1]))
        self._begin_node(nxt)
        return None

    def _begin_node(self, n):
        """Start covering ``n``: a vast node's first Morse cell opens at x(n), a narrow
        node's first GVD branch leaves x(n)."""
        self.task, self.mode = {}, None
        if n.kind == 'vast' and not n.circuits:
            n.circuits.append({'start': n.anchor, 'done': False, 'opened_by': n.created_by})
        if n.kind == 'narrow' and not n.branches:
            n.branches.append(Branch(n.anchor, None, n.created_by))

    # ------------------------------------------------------------------ transit

    def _go_to(self, xy, then):
        """Transit along the traced paths to ``xy``; ``then`` is the mode after arrival."""
        if math.dist(self.pose[:2], xy) < 0.3:
            self.mode = then
            return
        src, dst = self.paths.nearest(self.pose[:2]), self.paths.nearest(xy)
        route = self.paths.route(src, dst) if src is not None and dst is not None else []
        self.route = route + [tuple(xy)]
        self.mode, self.task['after'] = 'transit', then

    def _transit_step(self):
        """One step of the path to x(n) along the traced paths. Where the way runs along a
        GVD edge (narrow space, the two closest echoes equal, the edge's tangent along the
        way ahead), the robot follows that edge back by the GVD control law; elsewhere it
        drives straight to the next waypoint."""
        self._on_gvd = False
        if len(self.route) > 1:               # passed: the nearest of the next waypoints
            near = min(range(min(len(self.route), 8)),
                       key=lambda i: math.dist(self.pose[:2], self.route[i]))
            del self.route[:near]
        while self.route and math.dist(self.pose[:2], self.route[0]) < 0.2:
            self.route.pop(0)
        if not self.route:
            self.mode = self.task.pop('after', None)
            return None
        v = self._retrace_velocity()
        if v is not None:
            self._on_gvd = True
            return v
        return self._towards(self.route[0], self.cfg.max_speed)

    def _retrace_velocity(self):
        """GVD following towards the route's point ~1 m ahead; None off the GVD, or where
        the edge's tangent does not lead there (a junction, a turn of the way)."""
        if self.D > self.det or len(self.mins) < 2 or len(self.route) < 2:
            return None
        (d1, a1), (d2, a2) = self.mins[:2]
        if abs(d1 - d2) > self.cfg.event_tolerance * 2:
            return None
        n1 = np.array([math.cos(a1), math.sin(a1)])
        n2 = np.array([math.cos(a2), math.sin(a2)])
        diff = n1 - n2
        if np.linalg.norm(diff) < 1.0:         # the two obstacles not on either side
            return None
        tang = np.array([-diff[1], diff[0]]) / np.linalg.norm(diff)
        goal = next((q for q in self.route if math.dist(q, self.pose[:2]) > 1.0),
                    self.route[-1])
        w = np.array(goal) - np.array(self.pose[:2])
        if np.linalg.norm(w) < 0.5:
            return None
        w = w / np.linalg.norm(w)
        if tang @ w < 0:
            tang = -tang
        if tang @ w < math.cos(math.radians(30)):
            return None
        v = tang * self.cfg.max_speed + diff / np.linalg.norm(diff) * (d1 - d2) * 2.0
        return v if v @ w >= 0.7 * self.cfg.max_speed else None

    # ------------------------------------------------------------------ MorseDecompCoverage

    def _morse_step(self, n):
        """MorseDecompCoverage: laps 2 delta apart in the current Morse cell; the moves
        between them follow the boundary at D = delta; critical points close cells."""
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
            if self._known_region(n, cell):
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
        if tk['phase'] == 'find_left':             # to the cell's opening side
            if self.echo(math.pi if s > 0 else 0.0) > self.det:
                return self._boundary_velocity(-s)
            tk.update(phase='advance', x0=self.pose[0], first=True)   # the circuit lapped it
            return None
        if tk['phase'] in ('lap_first', 'lap'):
            if self.echo(math.pi / 2 * tk['dir']) > self.det:
                return self._lap_velocity(tk['x'], tk['dir'])
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

    def _known_region(self, n, cell):
        """The lap about to start lies on a lap of another Morse cell: this cell has run into
        one already covered (a merge of the Reeb graph, recognised at a known slice)."""
        x, y = self.pose[:2]
        for m in self.nodes:
            for c in m.cells:
                if c is cell or (m is n and c.id == cell.parent):
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

    # ------------------------------------------------------------------ TraceGVD

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
        n1 = np.array([math.cos(self.mins[0][1]), math.sin(self.mins[0][1])]) if self.mins \
            else np.zeros(2)
        diff = n1 - np.array([math.cos(self.mins[1][1]), math.sin(self.mins[1][1])]) \
            if len(self.mins) >= 2 else np.zeros(2)
        if np.linalg.norm(diff) < 1e-6:
            return self._end_branch('dead_end')
        (d1, a1), (d2, a2) = self.mins[:2]
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
            return self._end_branch('traced')     # on a GVD edge traced before: joined it
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
        return all(self._near_trace((start[0] + s * heading[0], start[1] + s * heading[1]),
                                    0.4) for s in (0.8, 1.6, 2.4))

    def _near_trace(self, q, within, before=None, along=None):
        """A point of a traced GVD edge lies within ``within`` of ``q`` (traced before sweep
        ``before``, and along the direction ``along`` or against it within 30 degrees, if
        given: the same edge, not one that crosses it)."""
        bx, by = int(q[0] // 1.0), int(q[1] // 1.0)
        return any(math.dist(p[:2], q) < within and (before is None or p[2] < before) and
                   (along is None or abs(p[3] * along[0] + p[4] * along[1]) > 0.87)
                   for gx in (bx - 1, bx, bx + 1) for gy in (by - 1, by, by + 1)
                   for p in self.gvd_trace.get((gx, gy), ()))

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
        bearings) become branches of the narrow node; the robot goes on along one."""
        n = self.nodes[self.current] if self.current is not None else None
        if n is None or n.kind != 'narrow' or self.task.get('branch') is None:
            return
        n.meets.append((float(xy[0]), float(xy[1]), idx))
        head = np.asarray(self.task.get('heading') or self.task['branch'].heading or (1.0, 0.0))
        back = math.atan2(-head[1], -head[0])
        out = self._free_bearings([back], self.det)
        if not out:
            return
        out.sort(key=lambda m: abs(math.remainder(m - math.atan2(head[1], head[0]),
                                                  2 * math.pi)))
        for m in out[1:]:
            n.branches.append(Branch(tuple(xy), (math.cos(m), math.sin(m)), idx))
        self.task['heading'] = (math.cos(out[0]), math.sin(out[0]))
        self.task['meet'] = idx
        self.task['leave'] = self.pose[:2]

    def _free_bearings(self, exclude, beyond):
        """Bearings of the GVD edges leaving the robot's place: local maxima of the ring's
        range over bearing (a gap between two closest obstacles) reaching beyond ``beyond``
        (an edge whose end is in the detector's view is not one to trace), at least 60
        degrees from each bearing of ``exclude`` and 45 degrees from one another."""
        out = []
        r = np.where(np.isfinite(self.ranges), self.ranges, 0.0)
        k = len(r)
        order = np.argsort(self.angles % (2 * math.pi))
        r, ang = r[order], (self.angles % (2 * math.pi))[order]
        for i in range(k):
            if r[i] < r[i - 1] or r[i] < r[(i + 1) % k] or r[i] <= beyond:
                continue
            if any(abs(math.remainder(ang[i] - e, 2 * math.pi)) < math.radians(60)
                   for e in exclude):
                continue
            if all(abs(math.remainder(ang[i] - o, 2 * math.pi)) > math.radians(45)
                   for o in out):
                out.append(float(ang[i]))
        return out

    def _end_branch(self, how):
        br = self.task.get('branch')
        if br is not None:
            br.end, br.end_xy = how, (float(self.pose[0]), float(self.pose[1]))
            br.end_heading = self.task.get('heading')
            self._record(self.t_sweep, 'branch_end', self.pose, f'GVD branch ends: {how}')
        self.task, self.mode = {}, None
        return None

    # ------------------------------------------------------------------ control laws

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
        far side. The current cell goes on, on the near side."""
        if 'critical' in self.cfg.without:
            return
        d = self.echo(math.pi / 2 * direction)
        p = (self.pose[0], self.pose[1] + direction * d)
        for c in n.circuits:                # followed already, or about to be
            if (not c['done'] and math.dist(c['start'], p) < self.det + 0.5) or any(
                    math.dist(q, p) < 0.6 for q in c.get('wall', ())):
                return
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

    def _follow_velocity(self):
        """Boundary following at D = delta, obstacle on the right: along the tangent of the
        closest obstacle, pulled back to D = delta along its normal."""
        d, a = self.mins[0]
        nrm = np.array([math.cos(a), math.sin(a)])
        tang = np.array([-nrm[1], nrm[0]])
        return tang * self.cfg.max_speed + np.clip(2.0 * (d - self.det), -1.0, 1.0) * nrm

    def _circuit_step(self, n, circ):
        """Follow the boundary of the vast cell at D = delta once around (Section II's
        boundary following with the robot as big as its detector); cusp points are sensed
        on it (Fig. 10). Ends back where it began."""
        tk = self.task
        if tk.get('circuit') is not circ:
            self.task = tk = {'circuit': circ}
            self._go_to(circ['start'], then='boundary')
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
            tk.update(origin=self.pose[:2], length=0.0, last=self.pose[:2])
            self._record(self.t_sweep, 'circuit', self.pose, f'boundary of vast node {n.id}')
        tk['length'] += math.dist(tk['last'], self.pose[:2])
        tk['last'] = self.pose[:2]
        trace = circ.setdefault('trace', [])
        if not trace or math.dist(trace[-1], self.pose[:2]) > 0.3:
            trace.append(self.pose[:2])
            d, a = self.mins[0]               # the followed obstacle's point
            circ.setdefault('wall', []).append((self.pose[0] + d * math.cos(a),
                                                self.pose[1] + d * math.sin(a)))
        back = math.dist(tk['origin'], self.pose[:2])
        passed = tk['length'] > 3.0 and tk.get('back', math.inf) < 0.8 and back > tk['back']
        tk['back'] = back                     # closest pass by the start counts as back
        if (tk['length'] > 3.0 and back < 0.4) or passed or tk['length'] > 500.0:
            circ['done'] = True
            sliver = self._sliver_tips(circ['trace'])
            self._same_cell(n, circ['trace'])
            self._beyond(n, circ)
            if not n.cells:
                n.cells.append(MorseCell(0, self.pose[:2], +1, opened_by=circ['opened_by']))
                if sliver:        # narrower than a lap: the circuit has swept it (one lap)
                    self._close_cell(n, n.cells[0], None, 'the circuit encloses no area: '
                                     'the cell is narrower than one lap and swept by it')
            self.task, self.mode = {}, None
            return None
        return self._follow_velocity()

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

    def _towards(self, xy, speed):
        d = np.array(xy) - np.array(self.pose[:2])
        norm = float(np.hypot(*d))
        return d / norm * min(speed, 2.0 * norm + 0.2) if norm > 1e-9 else np.zeros(2)

    def _guard(self, v):
        """Never drive into the closest obstacle within r + 0.15 m; push away from it."""
        v = np.asarray(v, dtype=float)
        sp = float(np.hypot(*v))
        if sp > self.cfg.max_speed:
            v = v / sp * self.cfg.max_speed
        for d, a in self.mins[:3]:
            if d < self.cfg.radius + 0.2:
                nrm = np.array([math.cos(a), math.sin(a)])
                if v @ nrm > 0:
                    v = v - (v @ nrm) * nrm
                v = v - nrm * (self.cfg.radius + 0.2 - d) * 2.0
        return v

    def _body(self, vx, vy):
        c, s = math.cos(self.pose[2]), math.sin(self.pose[2])
        return Command(c * vx + s * vy, -s * vx + c * vy, self.cfg.spin_rate, self.state)

    def _check_stuck(self, t, v):
        """Commanded but not moving for ``stuck_time``: give the target up (reported)."""
        self._hist.append((t, self.pose[0], self.pose[1]))
        while self._hist and t - self._hist[0][0] > self.cfg.stuck_time:
            self._hist.pop(0)
        if len(self._hist) < 2 or t - self._hist[0][0] < self.cfg.stuck_time - 0.2:
            return
        if max(math.dist(h[1:], self.pose[:2]) for h in self._hist) > 0.15:
            self.stuck_count = 0
            return
        self._hist.clear()
        self.stuck_count += 1
        self._record(t, 'stuck', self.pose, f'no motion for {self.cfg.stuck_time:g} s in '
                     f'{self.mode}')
        if self.stuck_count >= self.cfg.max_stuck:
            self.state = 'stuck'
            return
        n = self.nodes[self.current]
        if self.mode == 'gvd' or (self.mode == 'transit' and n.kind == 'narrow'):
            self._end_branch('given_up')
        elif n.kind == 'vast':
            cell = next((c for c in n.cells if c.status == 'covering'), None)
            if cell is not None:
                self._close_cell(n, cell, None, 'given up: the robot cannot move')
                cell.status = 'given_up'
        self.route, self.mode = [], None
        if self.stuck_count >= 3:
            n.covered, n.given_up = True, True
            self.given_up.append(n.id)

    # ------------------------------------------------------------------ reporting

    def status(self) -> dict:
        """A compact, JSON-friendly status (published by the node)."""
        return {'state': self.state, 'current_node': self.current, 'sweeps': self.sweeps,
                'nodes': len(self.nodes),
                'uncovered': [n.id for n in self.nodes if not n.covered],
                'given_up': sorted(set(self.given_up)), 'mode': self.mode,
                'last_event': list(self.events[-1]) if self.events else None}

    def primitive_lengths(self) -> dict:
        """Path length per primitive (lap, boundary, gvd, transit)."""
        out = {}
        for kind, length in self.segments:
            out[kind] = out.get(kind, 0.0) + length
        return out

    def to_dict(self) -> dict:
        """The hierarchical decomposition graph: nodes with their Reeb graphs / GVD branches
        and the events that created and closed them; edges with their cusp points."""
        nodes = []
        for n in self.nodes:
            nodes.append({
                'id': n.id, 'type': n.kind, 'kind': n.kind, 'covered': n.covered,
                'given_up': n.given_up, 'merged_into': n.merged_into, 'alive': True,
                'anchor': list(n.anchor),
                'centroid': list(n.anchor), 'label_point': list(n.anchor),
                'created_by_event': n.created_by, 'closed_by_event': n.closed_by,
                'critical_points': [list(c[:2]) for c in n.critical],
                'meet_points': [list(m[:2]) for m in n.meets],
                'morse_cells': [{'id': c.id, 'sweep': c.sweep, 'status': c.status,
                                 'opened_by_event': c.opened_by,
                                 'closed_by_event': c.closed_by,
                                 'laps': [list(map(float, lap)) for lap in c.laps]}
                                for c in n.cells],
                'gvd_branches': [{'start': list(b.start), 'end': b.end,
                                  'opened_by_event': b.opened_by} for b in n.branches]})
        edges = [{'vast': v, 'narrow': w, 'cusp_points': [list(c)],
                  'sensed_cusp_points': [list(c)], 'shared_boundary_point': None}
                 for v, w, c in self.edges]
        return {'nodes': nodes, 'edges': edges}
