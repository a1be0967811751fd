"""The grid planner (``planner:=grid``, ours): frontier-driven coverage on an evidence grid.

This is not the paper's algorithm; Algorithm 1 of Acar, Choset and Lee, driven by sensed events
alone, is :mod:`coverage_pkg.algorithm1` (``planner:=paper``). Inputs are sonar sweeps (REP 117
ranges of a transducer ring) and odometry; the output is a velocity command (holonomic base,
body frame) and a status. The planner never reads the world file or the ground truth.

What decides here
-----------------
* **The evidence grid decides.** The sweeps are fused into an evidence grid
  (:mod:`coverage_pkg.mapping`), re-decomposed every ``replan_period`` (1.5 s of sim time) and
  at the end of each path: VR = {D > delta} and NR = FCS_r \\ VR on the grid give the vast and
  narrow cells, the graph's nodes and edges (:mod:`coverage_pkg.hierarchical_graph`), the work
  left (laps, boundary and GVD pieces next to cells the detector has not seen), the covered
  flags and the end: coverage is complete when no unseen or frontier cell is left, which is
  frontier exploration.
* **Sensed events annotate.** Every sweep, the ring's tests fire ``cusp`` (D crosses delta on
  the GVD, Fig. 10 and 11), ``meet`` (three closest obstacles equidistant) and ``critical``
  (at D = delta the closest obstacle lies along +-x) events; they are stored with time and
  pose and mark edges' cusp points as sensed; a sensed critical point confirms a grid slice
  event as a Morse cell boundary. They do not create nodes, edges or work.
* **Order of work** (ours): the current Morse cell first, laps begun at an end, a narrow
  cell's pieces in the order of the shortest open tour (:mod:`coverage_pkg.tour`), a vast
  cell not left behind (``leave_far``/``leave_near``), GVD paths trimmed to what they show.
* **Recovery**: a robot that is commanded but does not move raises a ``stuck`` event; it backs
  away from the closest sensed obstacle for ``backoff_time``, the goal is marked blocked and
  the node is retried by another route (up to ``max_retries``); then the
  node is given up, reported (``gave_up`` event, :attr:`CoveragePlanner.given_up`), and the run
  ends ``incomplete``, never ``done``.

Faults: NaN readings are ignored, +inf clears the cone up to max range, -inf adds nothing
(REP 117). Without a sweep for more than ``sonar_timeout`` s of sim time the robot is stopped
(``waiting_for_sonar``) and resumes when sweeps return.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike
from scipy import ndimage

from coverage_pkg import gvd as gvdmod
from coverage_pkg import morse
from coverage_pkg.algorithm1 import Command, PaperConfig, PaperPlanner
from coverage_pkg.hierarchical_graph import HierarchicalGraph
from coverage_pkg.mapping import T_FREE, T_OCC, EvidenceGrid, drop_speckles
from coverage_pkg.sonar import sweep_evidence
from coverage_pkg.tour import COARSE_CELL, chunk_cells, coarse_distances, open_tour
from paramotion.errors import UserError

TERMINAL = ('done', 'stuck', 'incomplete')


@dataclass
class PlannerConfig:
    """Planner parameters (SI units)."""

    delta: float = 2.0                 # detector range (m)
    radius: float = 0.25               # robot radius r (m)
    detector: str = 'extended'         # 'extended' (this paper) or 'robot' (Section II baseline)
    resolution: float = 0.1            # evidence grid cell (m)
    clearance_margin: float = 0.1      # keep the centre at D > r + margin (m)
    lap_spacing: float = 0.0           # 0: 2 * detector range (Section IV-A)
    max_speed: float = 1.0             # m/s
    spin_rate: float = 0.6             # rad/s, turns the sonar ring to fill the gaps between cones
    trace_tolerance: float = 0.15      # a piece counts as followed if the centre passed this close
    replan_period: float = 1.5         # s of sim time between refreshes of the memory
    sonar_timeout: float = 0.5         # s of sim time without a sweep before stopping
    stuck_time: float = 5.0            # s commanded but not moving -> a stuck event
    max_stuck: int = 6                 # consecutive stuck events before stopping for good
    max_retries: int = 3               # stuck events on one node before it is given up
    backoff_time: float = 1.5          # s backing away from the closest obstacle after one
    gvd_min_angle: float = math.radians(50.0)
    cusp_min_angle: float = math.radians(25.0)  # a 1.2 m door seen from D = delta: 35 deg
    gvd_min_length: float = 0.5        # m, shorter isolated GVD pieces are sensing artefacts
    warmup: float = 1.0                # s spinning in place before the first plan
    gvd_tolerance: float = 0.4         # m, a GVD edge passed this close counts as followed
    lap_tolerance: float = 0.1         # m, same for slices and boundary
    min_charge: int = 2                # unseen cells charged to a work cell to make it work
    rejudge_footprint: bool = True     # past detector poses re-judged on today's map
    min_unseen_area: float = 0.2       # m^2, smaller unseen pockets off the frontier: speckles
    unseen_budget: float = 0.005       # ... left unseen up to this share of known free space
    min_vast_area: float = 0.5         # m^2, smaller VR components are sensing slivers
    event_tolerance: float = 0.15      # m, equal closest ranges (GVD order) within this
    critical_angle: float = math.radians(12.0)  # bearing tolerance of the critical point test
    jump_band: float = 0.3             # m, |D - delta| within this for the Fig. 10 cusp test
    jump_angle: float = math.radians(45.0)  # ... and the closest obstacle's bearing jumps this
    meet_agree: float = 0.15           # m, two sweeps' meet point solves must agree this well
    critical_col_tol: float = 0.5      # m, a sensed critical point confirms a slice this near
    critical_row_tol: float = 1.0      # m, ... and this far along it from the event's gap
    boundary_cost: float = 0.7         # travel cost of an undone boundary cell (open space: 1)
    piece_order: str = 'tour'          # narrow node: 'tour' (shortest open tour) or 'nearest'
    tour_chunk: float = 1.2            # m, size of the work chunks the tour visits
    trim_view: bool = True             # end a GVD path where its unseen cells come in view
    view_margin: float = 0.2           # m, ... within delta - view_margin of the robot
    lap_ends: bool = True              # a lap is begun at an end of what is left of it
    leave_far: float = 4.0             # m, a narrow node whose work left is this far ...
    leave_near: float = 2.0            # ... first covers an uncovered vast neighbour this near

    def detector_range(self) -> float:
        """Range of the detector used for coverage: delta, or r for the robot-size baseline."""
        return self.radius if self.detector == 'robot' else self.delta

    def validate(self, sonar_max_range: float | None = None) -> None:
        """Raise UserError (one line) for inconsistent parameters."""
        if self.detector not in ('extended', 'robot'):
            raise UserError(f'detector "{self.detector}" must be "extended" or "robot"')
        if not self.radius > 0:
            raise UserError(f'radius {self.radius:g} m must be > 0')
        if self.detector == 'extended' and not self.delta > self.radius:
            raise UserError(f'delta {self.delta:g} m must be greater than the robot radius '
                            f'{self.radius:g} m')
        if not 0 < self.resolution <= self.radius:
            raise UserError(f'resolution {self.resolution:g} m must be in (0, radius]')
        if not self.min_unseen_area >= 0:
            raise UserError(f'min_unseen_area {self.min_unseen_area:g} m^2 must be >= 0')
        if not 0 <= self.unseen_budget <= 1:
            raise UserError(f'unseen_budget {self.unseen_budget:g} must be in [0, 1]')
        if self.piece_order not in ('tour', 'nearest'):
            raise UserError(f'piece_order "{self.piece_order}" must be "tour" or "nearest"')
        if not self.tour_chunk >= self.resolution:
            raise UserError(f'tour_chunk {self.tour_chunk:g} m must be >= resolution '
                            f'{self.resolution:g} m')
        if not 0 <= self.view_margin < self.delta:
            raise UserError(f'view_margin {self.view_margin:g} m must be in [0, delta)')
        if not (self.leave_far >= 0 and self.leave_near >= 0):
            raise UserError(f'leave_far {self.leave_far:g} m and leave_near '
                            f'{self.leave_near:g} m must be >= 0')
        if not 0 < self.boundary_cost <= 1:
            raise UserError(f'boundary_cost {self.boundary_cost:g} must be in (0, 1]')
        if sonar_max_range is not None and not sonar_max_range > self.delta:
            raise UserError(f'sonar max range {sonar_max_range:g} m must exceed delta '
                            f'{self.delta:g} m')


class CoveragePlanner:
    """The grid planner (ours, frontier-driven). Feed :meth:`on_odometry` and :meth:`on_sweep`;
    call :meth:`update`."""

    def __init__(self, config: PlannerConfig, mount_angles: ArrayLike, beam_width: float,
                 min_range: float, max_range: float, noise_std: float = 0.01) -> None:
        config.validate(max_range)
        self.cfg = config
        self.mount = np.asarray(mount_angles, dtype=float)
        self.beam_width = float(beam_width)
        self.min_range = float(min_range)
        self.max_range = float(max_range)
        self.noise_std = float(noise_std)
        self.det = config.detector_range()          # delta itself (Section IV-A)
        self.spacing = config.lap_spacing or 2.0 * self.det
        self.grid = None
        self.graph = HierarchicalGraph()
        self.pose = None
        self.t_odom = None
        self.t_sweep = None
        self.t_first_sweep = None
        self.t_plan = -math.inf
        self.state = 'no_odometry'
        self.current = None             # current node id (Algorithm 1's n)
        self.goal = None                # (x, y) of the piece being approached
        self.commit = None              # piece chosen at the last plan (kept while undone)
        self.goal_kind = None
        self.path = []                  # world waypoints
        self.path_i = 0
        self.x_ref = None
        self.events = []                # (t, kind, x, y, detail): sensed events and decisions
        self.decisions = []             # (t, node_id, node_kind, goal_x, goal_y) per plan
        self.stuck_count = 0
        self._hist = []                 # (t, x, y) once per second for stuck detection
        self.blocked = []               # goals given up after a stuck event
        self.retries = {}               # node id -> stuck events while covering it
        self.given_up = []              # node ids given up (reported, never 'done')
        self.last = {}                  # last decomposition, for markers and the result
        self.sweeps = 0
        self.min_distance = math.inf
        self._meet_candidate = None
        self._near_bearing = None
        self._last_sweep = None
        self.sensed = {'cusp': [], 'critical': [], 'meet': []}   # (x, y, detail) in odom
        self._closed_cells = []         # centroids of Morse cells reported closed
        self._escape = False
        self._backoff_until = -math.inf
        self._lap_x = None              # x of the lapping slice being driven (None: no lap)
        self._tour_chunk = None         # world points of the tour's chunk being covered
        self._stuck_at = []             # (x, y) where stuck events happened: routes avoid them
        self._viewed_at = None
        self._footprints = []           # detector poses (x, y), every 0.1 m of path

    # ------------------------------------------------------------------ inputs

    def on_odometry(self, t: float, x: float, y: float, yaw: float) -> None:
        """Robot pose in the odom frame at sim time t."""
        if not all(math.isfinite(v) for v in (t, x, y, yaw)):
            return
        self.pose = (float(x), float(y), float(yaw))
        self.t_odom = t
        if self.grid is None:
            self.grid = EvidenceGrid(self.cfg.resolution, (x, y))
            self.x_ref = float(x)
        self.grid.mark_trace(x, y, self.cfg.trace_tolerance)

    def on_sweep(self, t: float, ranges: ArrayLike) -> None:
        """One sweep of the ring (REP 117 values, one per transducer, in mount order)."""
        if self.pose is None:
            return
        ranges = np.asarray(ranges, dtype=float)
        free_xy, occ_xy, edge_xy, valid = sweep_evidence(
            self.pose, ranges, self.mount, self.beam_width, self.min_range, self.max_range,
            self.cfg.resolution, self.noise_std, edges=True)
        if valid == 0:
            return                      # all NaN / -inf: no information, as good as silence
        self.t_sweep = t
        if self.t_first_sweep is None:
            self.t_first_sweep = t
        self.grid.integrate(free_xy, occ_xy, edge_xy)
        self.sweeps += 1
        self._detector_footprint()
        if self.cfg.detector == 'extended' and t - self.t_first_sweep >= self.cfg.warmup:
            self._sense_events(t, ranges)
        else:
            self.min_distance = self._ring_distance(ranges)

    def _detector_footprint(self):
        """Record what the detector (range delta, line of sight) has seen, every 0.1 m."""
        last = getattr(self, '_viewed_at', None)
        if last is None or math.dist(last, self.pose[:2]) >= 0.1:
            self._viewed_at = self.pose[:2]
            self.grid.mark_viewed(self.pose[0], self.pose[1], self.det)
            self._footprints.append(self.pose[:2])

    # ------------------------------------------------------------------ sensor tests

    def _ring_distance(self, ranges):
        """D(x) from the ring: the smallest valid echo (max range if none)."""
        with np.errstate(invalid='ignore'):
            ok = np.isfinite(ranges) & (ranges >= self.min_range)
        return float(ranges[ok].min()) if ok.any() else self.max_range

    def _sense_events(self, t, ranges):
        """The paper's sensor tests on one sweep: cusp, meet and critical points."""
        prev, prev_pose = self.min_distance, getattr(self, '_prev_pose', self.pose)
        dist = self._ring_distance(ranges)
        self.min_distance, self._prev_pose = dist, self.pose
        angles = self.mount + self.pose[2]
        order = gvdmod.gvd_order(ranges, angles, self.cfg.event_tolerance)
        self._sense_cusp(t, prev, dist, prev_pose, order, ranges, angles)
        self._sense_normal_jump(t, prev, dist, ranges, angles)
        if self.goal_kind == 'gvd' and dist <= self.det:
            self._sense_meet(t, ranges, angles, order, dist)
        side = morse.critical_from_ring(ranges, self.mount, self.pose[2],
                                        self.cfg.critical_angle)
        if side and abs(dist - self.det) <= 2.0 * self.cfg.resolution and (
                self.goal_kind == 'lap' or self._on_boundary()):
            self._sense_critical(t, side)

    def _sense_meet(self, t, ranges, angles, order, dist):
        """Meet point while tracing a narrow GVD edge: three closest obstacles equidistant.
        Placed where the three echoes solve to one distance (:func:`gvd.meet_from_ring`,
        within 0.5 m of the robot), else at the robot when the ring shows GVD order 3. Two
        sweeps in a row must agree (within ``meet_agree``): a single solve from a noisy echo
        or a cone's edge is not a meet point."""
        m = gvdmod.meet_from_ring(self.pose[:2], ranges, angles)
        if m is not None and m[2] <= self.det:
            cand = (m[0], m[1], f'three closest obstacles at {m[2]:.2f} m')
        elif order >= 3:
            cand = (self.pose[0], self.pose[1], f'GVD order {order} at D = {dist:.2f} m')
        else:
            self._meet_candidate = None
            return
        prev, self._meet_candidate = self._meet_candidate, cand
        if prev is not None and math.hypot(cand[0] - prev[0], cand[1] - prev[1]) <= \
                self.cfg.meet_agree:
            xy = (0.5 * (cand[0] + prev[0]), 0.5 * (cand[1] + prev[1]))
            self._record(t, 'meet', xy, cand[2], spacing=1.0)

    def _on_boundary(self):
        """True if the robot is on the boundary D = delta of a vast cell as memory knows it
        (within a cell): a transit along the boundary follows it too, and senses its critical
        points."""
        d = self.last
        if not d or 'boundary' not in d:
            return False
        rc = d['to_cell'](*self.pose[:2])
        if rc is None:
            return False
        win = (slice(max(rc[0] - 1, 0), rc[0] + 2), slice(max(rc[1] - 1, 0), rc[1] + 2))
        return bool(d['boundary'][win].any())

    def _sense_cusp(self, t, prev, dist, prev_pose, order, ranges, angles):
        """Cusp point: D crosses delta where two closest obstacles are equidistant (on the GVD).

        Fig. 11 (tracing a narrow GVD edge, D rises above delta) and Fig. 10 (following the
        boundary at D = delta, a second closest obstacle appears) are the same crossing seen
        from the two sides. The point is where both closest distances equal delta: from the two
        closest echoes (d_i along unit bearings n_i), the offset s with n_i . s = d_i - delta
        (flat obstacles). That solve also senses a cusp passed a little off the GVD (the
        second obstacle within ``max_shift`` of delta, e.g. a boundary followed into a room
        corner, or left from its end): it places the point where both distances are delta.
        Where the bearings are too close to parallel or opposite for it (a corridor's two
        walls), the crossing counts only on the GVD (order 2) and the point is interpolated
        between the two sweeps.
        """
        last, self._last_sweep = self._last_sweep, (self.pose[:2], ranges, angles)
        if not math.isfinite(prev) or (prev <= self.det) == (dist <= self.det):
            return
        # The crossing happened between the two sweeps: either may solve (the one after it
        # can already see the second obstacle more than max_shift beyond delta).
        xy = gvdmod.cusp_from_ring(self.pose[:2], ranges, angles, self.det)
        if xy is None and last is not None:
            xy = gvdmod.cusp_from_ring(last[0], last[1], last[2], self.det)
        if xy is None and order < 2:
            return
        if xy is None:
            f = (self.det - prev) / (dist - prev) if dist != prev else 0.5
            f = min(max(f, 0.0), 1.0)
            xy = (prev_pose[0] + f * (self.pose[0] - prev_pose[0]),
                  prev_pose[1] + f * (self.pose[1] - prev_pose[1]))
        way = 'rose above' if dist > self.det else 'fell below'
        self._record(t, 'cusp', xy, f'D {way} delta on the GVD', spacing=0.5)

    def _sense_normal_jump(self, t, prev, dist, ranges, angles):
        """Cusp point by Fig. 10: following the boundary at D = delta, the direction to the
        closest obstacle (the surface normal) jumps from one obstacle to another, where two
        are at delta. The crossing test of :meth:`_sense_cusp` needs D to cross delta, which
        a robot that follows the boundary just inside D = delta does not do; a door's cusp
        point, where the two jambs' delta-circles meet, was then never sensed. Fires when D
        is within ``jump_band`` of delta on two sweeps in a row and the closest obstacle's
        bearing moved by at least ``jump_angle``; the point is solved from the two closest
        echoes as in :func:`gvd.cusp_from_ring` (within 0.5 m)."""
        mins = gvdmod.ring_minima(ranges, angles)
        bearing = mins[0][1] if mins else None
        last, self._near_bearing = self._near_bearing, bearing
        band = self.cfg.jump_band
        if last is None or bearing is None or not math.isfinite(prev) or \
                abs(dist - self.det) > band or abs(prev - self.det) > band:
            return
        if abs(math.remainder(bearing - last, 2 * math.pi)) < self.cfg.jump_angle:
            return
        xy = gvdmod.cusp_from_ring(self.pose[:2], ranges, angles, self.det)
        if xy is not None:
            self._record(t, 'cusp', xy, 'closest obstacle jumped at D = delta (Fig. 10)',
                         spacing=0.5)

    def _sense_critical(self, t, side):
        """Critical point of h = x: the closest obstacle is along +-x (normal parallel to
        grad h) while the robot follows the boundary at D = delta. Localised at delta from the
        closest obstacle point on the sensed side held in memory (the ring's cones quantise
        bearing)."""
        occ = self.grid.occupied()
        x, y = self.pose[:2]
        k = int(math.ceil((self.det + 0.5) / self.grid.res))
        r0, c0 = self.grid.cells(np.array([[x, y]]))
        rs = slice(max(r0[0] - k, 0), r0[0] + k + 1)
        cs = slice(max(c0[0] - k, 0), c0[0] + k + 1)
        rr, cc = np.nonzero(occ[rs, cs])
        if len(rr) == 0:
            return
        pts = self.grid.center(rr + rs.start, cc + cs.start)
        # The obstacle point on the sensed side (within 30 degrees of +-x): in a room corner the
        # other wall is as close, and would put the point delta off along the wrong axis.
        dx, dy = pts[:, 0] - x, pts[:, 1] - y
        ahead = side * dx >= math.cos(math.radians(30.0)) * np.hypot(dx, dy)
        if not ahead.any():
            return
        pts, dx, dy = pts[ahead], dx[ahead], dy[ahead]
        # Nearest, with a penalty off the robot's slice: along a wall parallel to the slice
        # the cell straight ahead (the grid's wall cells jitter by a cell); at a convex vertex
        # the vertex itself.
        near = pts[int(np.argmin(np.hypot(dx, dy) + np.abs(dy)))]
        xy = (float(near[0] - side * self.det), float(near[1]))
        kind = 'closes' if side > 0 else 'opens'
        self._record(t, 'critical', xy, f'obstacle at {"+" if side > 0 else "-"}x: the slice '
                     f'{kind} a Morse cell', spacing=1.0, tag=side)

    def _record(self, t, kind, xy, detail, spacing, tag=None):
        """Store a sensed event unless the same one was sensed within ``spacing`` m."""
        for ox, oy, _, otag in self.sensed[kind]:
            if otag == tag and math.hypot(ox - xy[0], oy - xy[1]) < spacing:
                return
        self.sensed[kind].append((float(xy[0]), float(xy[1]), detail, tag))
        self.events.append((round(float(t), 3), kind, round(float(xy[0]), 3),
                            round(float(xy[1]), 3), detail))

    # ------------------------------------------------------------------ main step

    def update(self, t: float) -> Command:
        """Advance the planner at sim time t; returns the velocity command to send."""
        if self.pose is None:
            self.state = 'no_odometry'
            return Command(0.0, 0.0, 0.0, self.state)
        if self.state in TERMINAL:
            return Command(0.0, 0.0, 0.0, self.state)
        if self.t_sweep is None or t - self.t_sweep > self.cfg.sonar_timeout:
            if self.state != 'waiting_for_sonar':
                self._event(t, 'sonar_timeout', 'no valid sonar sweep, robot stopped')
            self.state = 'waiting_for_sonar'
            self._hist.clear()
            return Command(0.0, 0.0, 0.0, self.state)
        if self.state == 'waiting_for_sonar':
            self._event(t, 'sonar_resumed', 'sonar sweeps back, resuming')
            self.t_plan = -math.inf
        if t - self.t_first_sweep < self.cfg.warmup:
            self.state = 'warmup'
            return Command(0.0, 0.0, self.cfg.spin_rate, self.state)
        if self._check_stuck(t) and self.state == 'stuck':
            return Command(0.0, 0.0, 0.0, self.state)
        if t < self._backoff_until:
            # After a stuck event: back away from the closest sensed obstacle first (a robot
            # that grazed a corner is held by it, and the same plan would push it there again).
            vx, vy = self._escape_velocity()
            return self._body(vx, vy)
        at_end = self.path_i >= len(self.path) - 1 and (
            not self.path or math.dist(self.pose[:2], self.path[-1]) < 0.1)
        if at_end or t - self.t_plan >= self.cfg.replan_period:
            self._plan(t)
            if self.state in TERMINAL:
                return Command(0.0, 0.0, 0.0, self.state)
        vx, vy = self._follow()
        return self._body(vx, vy)

    def _body(self, vx, vy):
        """The command for a world-frame velocity (holonomic base, body frame)."""
        yaw = self.pose[2]
        c, s = math.cos(yaw), math.sin(yaw)
        return Command(c * vx + s * vy, -s * vx + c * vy, self.cfg.spin_rate, self.state)

    # ------------------------------------------------------------------ memory: the cells

    def decompose(self) -> dict[str, object]:
        """The cells of Section IV-A on the sensed part of the world (the robot's memory).

        Returns a dict of grid layers (crop of the evidence grid): D, FCS_r reachable from the
        robot, VR (``D > delta``, components smaller than ``min_vast_area`` are slivers and
        count as narrow), NR, the GVD, the lapping slices and the boundary ``D = delta``.
        """
        g, cfg = self.grid, self.cfg
        rs, cs = g.known_bbox(margin_cells=4)
        res = g.res
        free = g.logodds[rs, cs] < T_FREE
        occupied = g.logodds[rs, cs] > T_OCC
        dist, fr, fc = gvdmod.distance_transform(~(free | self._sonar_gaps(free, occupied)),
                                                 res)
        # FCS_r as sensed, plus the cells that held the robot centre: it got through there,
        # so a passage the sonar pinched behind it (a false echo, a gap) cannot cut it off
        # from the space, and the nodes, it has already sensed.
        trav = (free & (dist > cfg.radius + cfg.clearance_margin)) | g.visited[rs, cs]
        r0, c0 = rs.start, cs.start

        def to_cell(x, y):
            i = int(math.floor((y - g.origin[1]) / res)) - r0
            j = int(math.floor((x - g.origin[0]) / res)) - c0
            if 0 <= i < trav.shape[0] and 0 <= j < trav.shape[1]:
                return i, j
            return None

        def to_world(rows, cols):
            return g.center(np.asarray(rows) + r0, np.asarray(cols) + c0)

        start = self._start_cell(trav, to_cell(*self.pose[:2]), res)
        lab, _ = ndimage.label(trav, structure=np.ones((3, 3)))
        reach = (lab == lab[start]) if start is not None else np.zeros_like(trav)
        vast = reach & (dist > self.det)
        vl, nv = ndimage.label(vast, structure=np.ones((3, 3)))
        if nv:
            size = ndimage.sum(vast, vl, np.arange(1, nv + 1)) * res ** 2
            keep = np.r_[False, size >= cfg.min_vast_area]
            vast = keep[vl]
        narrow = reach & ~vast
        d = dict(rs=rs, cs=cs, free=free, dist=dist, trav=trav, reach=reach, vast=vast,
                 narrow=narrow, start=start, to_cell=to_cell, to_world=to_world,
                 trace=g.trace[rs, cs], occupied=occupied)
        self._lapping_layers(d, g.origin[0] + c0 * res, res)
        self._gvd_layers(d, fr, fc, res)
        self._morse_cells(d, res)
        return d

    def _morse_cells(self, d, res):
        """The Morse cells of the vast region (``h = x``), bounded by the critical points the
        ring has sensed (:func:`morse.sensed_morse_cells`): a slice where memory shows the
        connectivity change is a cell boundary once a critical point of the matching side was
        sensed on it (within ``critical_col_tol`` along x, ``critical_row_tol`` along the
        slice). Until then the cells on both sides are one cell: Fig. 4's incremental
        construction, where a cell ends when the robot senses its critical point. A split
        whose gap closes within delta / 2 is a notch of the sensed wall, not an obstacle."""
        sensed = []
        for x, y, _, side in self.sensed['critical']:
            rc = d['to_cell'](x, y)
            sensed.append((rc[0], rc[1], side) if rc is not None else (-10 ** 6, -10 ** 6, 0))
        mc = morse.sensed_morse_cells(d['morse_region'], sensed,
                                      self.cfg.critical_col_tol / res,
                                      self.cfg.critical_row_tol / res,
                                      max(2, round(0.5 * self.det / res)))
        d['reeb'], d['reeb_edges'], d['morse'] = mc.labels, mc.edges, mc

    @staticmethod
    def _sonar_gaps(free, occ, max_cells=8):
        """Unknown pockets of at most ``max_cells`` cells enclosed by known free cells (no
        echo cell next to them): gaps between the ring's cones, not obstacles. An obstacle
        there would have returned an echo; counted as obstacles, they pinch corridors shut
        and cut the robot off from space it has already sensed."""
        unknown = ~free & ~occ
        lab, n = ndimage.label(unknown, structure=np.ones((3, 3)))
        if n == 0:
            return np.zeros_like(free)
        idx = np.arange(1, n + 1)
        size = ndimage.sum(unknown, lab, idx)
        near_occ = ndimage.maximum(ndimage.binary_dilation(occ, structure=np.ones((3, 3))),
                                   lab, idx) > 0
        edge = np.zeros_like(unknown)
        edge[0, :] = edge[-1, :] = edge[:, 0] = edge[:, -1] = True
        on_edge = ndimage.maximum(edge, lab, idx) > 0
        gap = (size <= max_cells) & ~near_occ & ~on_edge
        return np.r_[False, gap][lab]

    @staticmethod
    def _start_cell(trav, rc, res):
        """The robot's cell in FCS_r (or the nearest one within 1 m), None if lost."""
        if rc is None or not trav.any():
            return None
        if trav[rc]:
            return rc
        _, (ir, ic) = ndimage.distance_transform_edt(~trav, return_indices=True)
        cand = (int(ir[rc]), int(ic[rc]))
        return cand if math.hypot(cand[0] - rc[0], cand[1] - rc[1]) * res < 1.0 else None

    def _lapping_layers(self, d, x0, res):
        """Lapping slices x = x_ref + k * spacing and the boundary followed at D = delta.

        The boundary is the curve ``D = delta`` as the grid knows it: the ring of narrow cells
        one cell outside VR (D one to two cells below delta). The grid places a wall only to
        within a cell, so following the first ring (D just below delta) left strips along the
        walls unseen (two_rooms: 95 % of CVS); one cell in, the wall is within delta. The
        lap spacing stays exactly 2 delta. The
        robot-size baseline, which has no narrow region, follows the edge of FCS_r.
        """
        vast = d['vast']
        if self.cfg.detector == 'extended':
            ring = ndimage.binary_dilation(vast, structure=np.ones((3, 3)))
            ring2 = ndimage.binary_dilation(ring, structure=np.ones((3, 3)))
            boundary = d['narrow'] & ring2 & ~ring
            d['morse_region'] = vast | (d['narrow'] & ring2)
        else:
            boundary = morse.boundary_cells(vast)
            d['morse_region'] = vast
        lap = morse.lap_columns(vast.shape[1], x0, res, self.x_ref, self.spacing)
        d['boundary'] = boundary
        d['lap'] = (vast | boundary) & lap[None, :]

    def _gvd_layers(self, d, fr, fc, res):
        """GVD of the sensed free space, its part in NR (followed by TraceGVD), cusp cells."""
        cfg = self.cfg
        if cfg.detector != 'extended':
            d['gvd'] = d['narrow_gvd'] = np.zeros_like(d['free'])
            d['cusps'] = []
            return
        min_cells = max(3, int(round(cfg.gvd_min_length / res)))
        gvd = gvdmod.prune_small(gvdmod.gvd_cells(d['free'], fr, fc, cfg.gvd_min_angle)
                                 & d['reach'], min_cells)
        d['gvd'] = gvd
        d['narrow_gvd'] = gvdmod.prune_small(gvd & d['narrow'], min_cells)
        # Cusps are predicted on a GVD kept down to a smaller angle: seen from D = delta, the
        # two jambs of a 1.2 m door are only 35 degrees apart (the followed GVD keeps 50 to
        # drop the spurs that noisy walls grow near them, where D is small).
        wide = gvdmod.gvd_cells(d['free'], fr, fc, cfg.cusp_min_angle) & d['reach']
        d['cusps'] = gvdmod.cusp_cells(wide, np.where(d['vast'], np.inf, d['dist']), self.det)

    # ------------------------------------------------------------------ graph and work

    def _plan(self, t):
        """One round of the grid planner: refresh the grid's graph, cover n, or move on."""
        self.t_plan = t
        d = self.decompose()
        self.last = d
        if d['start'] is None:
            self._event(t, 'no_free_space', 'robot not in sensed free space; backing off')
            self.path, self.path_i = [], 0
            self._escape = True
            self.state = 'escaping'
            return
        self._escape = False
        vmap, nmap, node_of = self._update_graph(t, d)
        undone = self._remaining_work(d)
        work = self._work_per_node(d, undone, node_of)
        if self._retry_blocked(t, d, work):
            undone = self._remaining_work(d)
            work = self._work_per_node(d, undone, node_of)
        self._mark_covered(t, d, work, vmap, nmap)
        self._close_morse_cells(t, d, undone, node_of)
        cost = self._travel_costs(d)
        cand = undone & np.isfinite(cost[0])
        n = self._current_node(t, d, cand, node_of, cost)
        if n is None:
            self._finish(t)
            return
        self._cover_node(t, d, n, cand, undone, node_of, cost)

    def _update_graph(self, t, d):
        """CreateNode for newly sensed cells; edges between touching vast and narrow cells with
        their cusp points; Reeb graph (critical points) of each vast node; meet points."""
        vl, _ = ndimage.label(d['vast'], structure=np.ones((3, 3)))
        nl, _ = ndimage.label(d['narrow'], structure=np.ones((3, 3)))
        res = self.grid.res
        cusps = [tuple(c[:2]) for c in self.sensed['cusp']]
        seeds = [self.pose[:2]] + cusps
        before = set(self.graph.nodes)
        vmap = self.graph.update('vast', vl, d['to_cell'], d['to_world'], res, seeds)
        nmap = self.graph.update('narrow', nl, d['to_cell'], d['to_world'], res, seeds)
        for nid in sorted(set(self.graph.nodes) - before):
            node = self.graph.nodes[nid]
            self._event(t, 'node_created', f'{node.kind} node {nid} (CreateNode '
                                           f'{self._created_at(node.anchor, seeds)})')
        node_of = np.full(vl.shape, -1, dtype=np.int64)
        for lab, nid in vmap.items():
            node_of[vl == lab] = nid
        for lab, nid in nmap.items():
            node_of[nl == lab] = nid
        self._link_cells(d, vl, nl, vmap, nmap)
        self._attach_critical_points(d, vl, vmap)
        self._attach_meet_points(nl, nmap, d)
        return vmap, nmap, node_of

    def _created_at(self, anchor, seeds):
        """Where a new node came from, for its ``node_created`` event: the robot's position
        (the start, or a cell the robot stands in), a sensed cusp point, or a cell that
        memory holds before any of its cusp points was sensed (the sonar reaches 5 m; the
        graph then links it through a cusp predicted on the memory's GVD)."""
        if tuple(anchor) == tuple(seeds[0]):
            return 'at the robot'
        for x, y, _, _ in self.sensed['cusp']:
            if (x, y) == tuple(anchor):
                return 'at ' + self._sensed_name('cusp', x, y)
        return 'for a cell sensed in memory before its cusp point'

    def _link_cells(self, d, vl, nl, vmap, nmap):
        """One graph edge per touching vast/narrow pair, with its cusp points: the sensed ones
        near the shared boundary, else the GVD points at D = delta predicted from memory."""
        self.graph.edges = {}
        grown = ndimage.grey_dilation(vl, footprint=np.ones((3, 3)))
        touch = (grown > 0) & (nl > 0)
        pairs = set(zip(grown[touch].tolist(), nl[touch].tolist()))
        sensed = [c for c in self.sensed['cusp']]
        for v, n in sorted(pairs):
            a, b = vmap.get(v), nmap.get(n)
            if a is None or b is None:
                continue
            shared = touch & (grown == v) & (nl == n)
            rr, cc = np.nonzero(shared)
            pts = d['to_world'](rr, cc)
            own = [c[:2] for c in sensed
                   if np.min(np.hypot(pts[:, 0] - c[0], pts[:, 1] - c[1])) < 0.5]
            predicted = []
            for r, c in d['cusps']:
                ri, ci = int(round(r)), int(round(c))
                win = (slice(max(ri - 2, 0), ri + 3), slice(max(ci - 2, 0), ci + 3))
                if (vl[win] == v).any() and (nl[win] == n).any():
                    predicted.append(tuple(d['to_world']([r], [c])[0]))
            here = np.asarray(self.pose[:2])
            near = pts[int(np.argmin(np.hypot(*(pts - here).T)))]
            self.graph.link(a, b, own, predicted, tuple(near))

    def _attach_critical_points(self, d, vl, vmap):
        """The sensed critical points of each vast node and its Morse cells (Reeb graph edges:
        the cells between critical points, sliced from memory)."""
        crit = self.sensed['critical']
        for lab, nid in vmap.items():
            node = self.graph.nodes[nid]
            mask = ndimage.binary_dilation(vl == lab, iterations=3)
            mine = []
            for k, (x, y, detail, side) in enumerate(crit):
                cell = d['to_cell'](x, y)
                if cell is not None and mask[cell]:
                    mine.append((k, x, y, 'closes' if side > 0 else 'opens'))
            node.reeb_points = [(x, y, kind) for _, x, y, kind in mine]
            local = {k: i for i, (k, _, _, _) in enumerate(mine)}
            cells = set(np.unique(d['reeb'][vl == lab]).tolist())
            node.reeb_edges = [(local.get(a, -1), local.get(b, -1)) for a, b, c in
                               d['reeb_edges'] if c in cells]

    def _attach_meet_points(self, nl, nmap, d):
        for nid in nmap.values():
            self.graph.nodes[nid].meet_points = []
        for x, y, _, _ in self.sensed['meet']:
            cell = d['to_cell'](x, y)
            if cell is not None and nl[cell] in nmap:
                self.graph.nodes[nmap[nl[cell]]].meet_points.append((x, y))

    def _remaining_work(self, d):
        """Pieces not yet followed: laps and boundary (vast), GVD edges (narrow)."""
        cfg, res = self.cfg, self.grid.res
        dtrace = ndimage.distance_transform_edt(~d['trace']) * res
        blocked = np.zeros_like(d['reach'])
        for bx, by in self.blocked:
            c = d['to_cell'](bx, by)
            if c is not None:
                k = int(math.ceil(0.5 / res))
                blocked[max(c[0] - k, 0):c[0] + k + 1, max(c[1] - k, 0):c[1] + k + 1] = True
        d['dtrace'] = dtrace
        need = self._needed_work(d, res)
        # Laps inside VR are driven whole (boustrophedon, Section II); the boundary and the
        # GVD only where something is still unseen.
        laps = d['lap'] & d['vast']
        lap = (laps | (d['boundary'] & need)) & (dtrace > cfg.lap_tolerance)
        gvd = d['narrow_gvd'] & need & (dtrace > cfg.gvd_tolerance)
        d['undone_lap'] = lap & ~blocked
        d['undone_gvd'] = gvd & ~blocked
        d['undone_view'] = d['approach'] & ~blocked
        d['blocked'] = blocked
        # Work that would be undone but for a block (it keeps its node uncovered).
        d['blocked_undone'] = (lap | gvd | d['approach']) & blocked
        return d['undone_lap'] | d['undone_gvd'] | d['undone_view']

    def _needed_work(self, d, res):
        """Work cells (laps, boundary, narrow GVD) that still have something to show: each
        known free cell (or wall cell next to one) that the detector has not seen yet is
        charged to its nearest work cell (the one whose pass would see it, Lemma 1 for the
        GVD); cells without a charge are done."""
        work = d['lap'] | d['boundary'] | d['narrow_gvd']
        d['approach'] = np.zeros_like(work)
        if not work.any():
            return np.zeros_like(work)
        rs, cs = d['rs'], d['cs']
        # Unknown cells next to known free space (the frontier, not an echo) are unseen too:
        # the map grows there, and the cell decomposition with it.
        # (A ray of the detector ends on such a cell, so it is never 'viewed'; it is work
        # until the map has grown past it. Unknown cells next to an echo are the wall.)
        frontier = (~d['free'] & ~d['occupied'] & ndimage.binary_dilation(d['free'])
                    & ~ndimage.binary_dilation(d['occupied'], iterations=2))
        # What the detector must see: the known free cells, and the wall cells next to them.
        # CVS reaches the wall surface, and the surface lies in the cell the echo marked
        # (possibly a whole cell beyond the last free cell).
        targets = d['free'] | (d['occupied'] & ndimage.binary_dilation(d['free']))
        if self.cfg.rejudge_footprint:
            ur, uc = np.nonzero(targets & ~self.grid.viewed[rs, cs])
            self.grid.rejudge_viewed(np.asarray(self._footprints), self.det,
                                     ur + rs.start, uc + cs.start)
        budget = self.cfg.unseen_budget * float(d['free'].sum()) * res ** 2
        unseen = drop_speckles(targets & ~self.grid.viewed[rs, cs], frontier, res,
                               self.cfg.min_unseen_area, budget) | frontier
        dw, (ir, ic) = ndimage.distance_transform_edt(~work, return_indices=True)
        sel = unseen & (dw * res <= self.det + res)
        charge = np.zeros(work.shape, dtype=np.int32)
        np.add.at(charge, (ir[sel], ic[sel]), 1)
        d['charged'] = (np.nonzero(sel), (ir[sel], ic[sel]))
        d['approach'] = self._approach_left_pockets(d, sel & ~frontier, ir, ic, res)
        # A single unseen cell is a sonar speckle more often than a place: two make work.
        return work & (charge >= self.cfg.min_charge)

    def _approach_left_pockets(self, d, sel, ir, ic, res):
        """Cells from which to see what a finished pass left unseen.

        A cell still unseen although the work cell it is charged to has been followed lies
        beyond the detector from that pass: e.g. a hall a little wider than 2 delta, whose VR
        sliver is too small to be a vast cell, traced on its GVD, leaves its walls a few
        centimetres out of range. Such cells get a piece of their own: the cells of FCS_r one
        cell wide at delta - res - lap_tolerance from them, with a line of sight through known free
        cells, each followed once (a traced cell is done whether or not the pocket was seen,
        so a pocket that cannot be seen costs one pass, never a loop)."""
        cfg = self.cfg
        dtrace = d['dtrace']
        followed = np.where(d['narrow_gvd'], dtrace <= cfg.gvd_tolerance,
                            dtrace <= cfg.lap_tolerance)
        left = sel & followed[ir, ic]
        out = np.zeros_like(left)
        if left.sum() < cfg.min_charge:
            return out
        dl, (lr, lc) = ndimage.distance_transform_edt(~left, return_indices=True)
        dl = dl * res
        # A pass within lap_tolerance of the band is still within delta - res of the pocket.
        reach = self.det - res - cfg.lap_tolerance
        band = d['reach'] & (dl > reach - res) & (dl <= reach) & (dtrace > cfg.lap_tolerance)
        rr, cc = np.nonzero(band)
        if len(rr) == 0:
            return out
        tr, tc = lr[rr, cc], lc[rr, cc]
        t = np.linspace(0.0, 1.0, max(2, int(math.ceil(self.det / (0.5 * res)))))[:-1]
        pr = np.rint(rr[:, None] + (tr - rr)[:, None] * t[None, :]).astype(np.int64)
        pc = np.rint(cc[:, None] + (tc - cc)[:, None] * t[None, :]).astype(np.int64)
        clear = d['free'][pr, pc].all(axis=1)
        out[rr[clear], cc[clear]] = True
        return out

    def _work_per_node(self, d, undone, node_of):
        """Remaining work per node. Boundary cells lie in NR but are the vast node's work
        (MorseDecompCoverage follows the boundary): they count for the nearest vast cell."""
        owner = node_of.copy()
        if d['vast'].any():
            _, (ir, ic) = ndimage.distance_transform_edt(~d['vast'], return_indices=True)
            lapwork = d['lap'] | d['boundary']
            owner = np.where(lapwork, node_of[ir, ic], node_of)
        d['owner'] = owner
        ids, cnt = np.unique(owner[undone], return_counts=True)
        return {int(i): int(n) for i, n in zip(ids, cnt) if i >= 0}

    def _mark_covered(self, t, d, work, vmap, nmap):
        """A node is covered when none of its pieces is left; newly sensed space next to it
        can give it work again (it is uncovered again)."""
        blocked_work = self._blocked_work(d)
        for nid in list(vmap.values()) + list(nmap.values()):
            node = self.graph.nodes[nid]
            was = node.covered
            node.covered = work.get(nid, 0) == 0
            if node.covered and nid in blocked_work and nid not in self.given_up:
                node.covered = False                # only blocked work left: not covered
                self.given_up.append(nid)
                self._event(t, 'gave_up', f'{node.kind} node {nid}: its remaining pieces '
                                          'are blocked')
            if node.covered and not was:
                self._event(t, 'node_covered', f'{node.kind} node {nid} covered')

    @staticmethod
    def _blocked_work(d):
        """Ids of the nodes with blocked work that would otherwise be undone."""
        ids = np.unique(d['owner'][d['blocked_undone']])
        return {int(i) for i in ids if i >= 0}

    def _retry_blocked(self, t, d, work):
        """Recovery: a node whose only work left is blocked, with stuck events to spare, has
        its blocks lifted and is retried by another route (the place where the robot got stuck
        costs more to cross now); with ``max_retries`` stuck events it is given up instead
        (:meth:`_mark_covered`). True if a block was lifted."""
        lifted = False
        for nid in self._blocked_work(d):
            if work.get(nid, 0) or nid in self.given_up or \
                    self.retries.get(nid, 0) >= self.cfg.max_retries:
                continue
            keep = []
            for b in self.blocked:
                c = d['to_cell'](*b)
                if c is None or d['owner'][c] != nid:
                    keep.append(b)
            if len(keep) < len(self.blocked):
                self.blocked = keep
                lifted = True
                self._event(t, 'retry', f'node {nid}: only blocked pieces left, retried by '
                                        'another route')
        return lifted

    def _close_morse_cells(self, t, d, undone, node_of):
        """Report each Morse cell (between two critical points) of a vast node whose laps and
        boundary are all followed: ``cell_closed``."""
        reeb = d['reeb']
        n = int(reeb.max())
        if n == 0:
            return
        idx = np.arange(1, n + 1)
        left = ndimage.sum(undone, reeb, idx)
        size = ndimage.sum(reeb > 0, reeb, idx) * self.grid.res ** 2
        cen = ndimage.center_of_mass(reeb > 0, reeb, idx)
        for k in range(n):
            if left[k] or size[k] < self.cfg.min_vast_area:
                continue
            xy = tuple(d['to_world']([cen[k][0]], [cen[k][1]])[0])
            if any(math.hypot(xy[0] - a, xy[1] - b) < self.spacing for a, b in
                   self._closed_cells):
                continue
            self._closed_cells.append(xy)
            a, b, _ = d['reeb_edges'][k]
            self.events.append((round(float(t), 3), 'cell_closed', round(float(xy[0]), 3),
                                round(float(xy[1]), 3),
                                f'Morse cell {k + 1} covered: opened at {self._crit_name(a)}, '
                                f'closed at {self._crit_name(b)}'))

    def _crit_name(self, k):
        """Sensed critical point ``k`` for an event's text, or 'no sensed critical point'."""
        if k < 0:
            return 'no sensed critical point'
        return self._sensed_name('critical', *self.sensed['critical'][k][:2])

    def _sensed_name(self, kind, x, y):
        """A sensed point for an event's text, named by the sim time of its event (the text
        cannot carry coordinates: events move into the map frame, their text does not)."""
        xy = (round(x, 3), round(y, 3))
        t = next((e[0] for e in self.events if e[1] == kind and e[2:4] == xy), None)
        return f'the {kind} point sensed at t = {t:.2f} s' if t is not None else \
            f'a sensed {kind} point'

    def _travel_costs(self, d):
        """Geodesic cost from the robot through sensed FCS_r (higher near obstacles, so that
        transits through narrow space run along the GVD)."""
        from skimage.graph import MCP_Geometric
        cost = np.where(d['reach'],
                        1.0 + 2.0 * np.clip(1.0 - d['dist'] / self.det, 0.0, 1.0), np.inf)
        # Undone boundary pieces are cheaper than open space: a transit that runs beside one
        # (from the end of a lap to the next, the boustrophedon link of Section II) follows
        # it and does that work on the way, instead of leaving it for a trip of its own.
        cost = np.where(d['reach'] & d['boundary'] & d['undone_lap'], self.cfg.boundary_cost,
                        cost)
        # Where the robot got stuck, the next route goes another way if there is one (a
        # pinch the map shows passable but the robot is not: retry by another route).
        for sx, sy in self._stuck_at:
            c = d['to_cell'](sx, sy)
            if c is not None:
                k = int(math.ceil(0.3 / self.grid.res))
                win = (slice(max(c[0] - k, 0), c[0] + k + 1),
                       slice(max(c[1] - k, 0), c[1] + k + 1))
                cost[win] = cost[win] * 20.0
        mcp = MCP_Geometric(cost)
        cum, _ = mcp.find_costs([d['start']])
        return cum * self.grid.res, mcp, cost

    def _current_node(self, t, d, cand, node_of, cost):
        """Algorithm 1's n: CreateNode at the start, the current node while it has work left,
        then FindUncoveredNode (fewest graph edges away, then nearest)."""
        cum = cost[0]
        owner = d['owner']
        cur = self.graph.resolve(self.current)
        self.current = cur
        if cur is None and not self.decisions:
            kind = 'vast' if d['vast'][d['start']] else 'narrow'
            here = int(node_of[d['start']])
            self.current = here if here >= 0 else None
            self._event(t, 'start', f'CreateNode: D(x) says {kind}, node {self.current}')
        def reach_dist(node, far=False):
            """Travel to the node's nearest (``far``: farthest) remaining work."""
            m = cand & (owner == node.id)
            if not m.any():
                return math.inf
            return float(cum[m].max() if far else cum[m].min())
        if self.current is not None and (cand & (owner == self.current)).any():
            node = self.graph.nodes[self.current]
            vast = self._vast_left_behind(node, reach_dist)
            if vast is None:
                return node
            self._event(t, 'next_node', f'vast node {vast.id} before narrow node {node.id} '
                                        'leaves it behind')
            self._route = [node.id, vast.id]
            self.current = vast.id
            return vast
        skip = set(self.given_up)
        nxt = self.graph.find_uncovered_node(self.current, reach_dist, skip)
        while nxt is not None and not math.isfinite(reach_dist(nxt)):
            skip.add(nxt.id)           # work only behind blocked goals: retried via the graph
            nxt = self.graph.find_uncovered_node(self.current, reach_dist, skip)
        if nxt is None:
            return None
        if nxt.id != self.current:
            hops = self.graph.graph_path(self.current, nxt.id) if self.current is not None \
                else [nxt.id]
            self._event(t, 'next_node', f'FindUncoveredNode: {nxt.kind} node {nxt.id} via '
                                        f'{hops}')
            self._route = hops
        self.current = nxt.id
        return nxt

    def _vast_left_behind(self, node, reach_dist):
        """The uncovered vast neighbour of narrow ``node`` that the robot is about to leave
        behind, or None: the node's nearest work is ``leave_far`` or more away, the vast
        cell's nearest is within ``leave_near`` and all of the vast cell's work is nearer than
        the node's next piece.

        A narrow cell is one component of NR, and in a world of rooms that is the wall band of
        every room, joined through the doors: traced whole first, it leaves each room's vast
        cell for a trip back across the world at the end. In Fig. 13(5) the robot that reaches
        a new vast cell covers it before it follows the corridor on; here the vast cell is
        covered once the band around it is done and the robot would move away.

        The last condition keeps the robot out of a hall whose band is not done: there the
        narrow node's next piece is the rest of the band, nearer than the far end of the
        hall's laps, and the robot that lapped the hall first came back for the band
        piecewise (an empty 18 x 10 room: 3.64 times the lower bound against 2.78 with it)."""
        far, near = self.cfg.leave_far, self.cfg.leave_near
        if node.kind != 'narrow' or far <= 0 or reach_dist(node) < far:
            return None
        best = None
        for vid in sorted(self.graph.neighbours(node.id)):
            v = self.graph.nodes[vid]
            if v.kind != 'vast' or v.covered or vid in self.given_up:
                continue
            dv = reach_dist(v)
            if reach_dist(v, far=True) >= reach_dist(node):
                continue                    # the node's next piece is nearer than the hall's
            if dv <= near and (best is None or dv < best[0]):
                best = (dv, v)
        return None if best is None else best[1]

    def _finish(self, t):
        """No uncovered node reachable: done, unless a node was given up (then incomplete)."""
        self.path, self.path_i = [], 0
        left = [n.id for n in self.graph.alive() if not n.covered]
        if self.given_up or left:
            self.state = 'incomplete'
            self._event(t, 'incomplete', f'nodes given up {sorted(set(self.given_up))}, '
                                         f'uncovered {left}')
        else:
            self.state = 'done'
            self._event(t, 'done', 'no uncovered node left: coverage complete')

    def _cover_node(self, t, d, node, cand, undone, node_of, cost):
        """MorseDecompCoverage (vast) or TraceGVD (narrow) of ``node``: go to its nearest
        undone piece (the current Morse cell first), by way of the cusp points of the graph
        route when the node was just chosen, and follow the piece."""
        cum, mcp, _ = cost
        mine = cand & (d['owner'] == node.id)
        score = np.where(mine, cum, np.inf)
        if node.kind == 'vast':
            score = np.where(self._lap_middles(d, mine), np.inf, score)
            rc = d['reeb'][d['start']]
            if rc:
                score = score + np.where(d['reeb'] == rc, 0.0, self.spacing)
        gi = np.unravel_index(int(np.argmin(score)), score.shape)
        on_lap = self._lap_ahead(d, mine, cum) if node.kind == 'vast' else None
        if on_lap is not None:
            gi = on_lap
        if node.kind == 'narrow' and self._tour_applies(node):
            gi = self._tour_next(d, mine, cum, cost[2]) or gi
        else:
            self._tour_chunk = None
        if self.commit is not None:
            cc = d['to_cell'](*self.commit)
            if cc is not None and mine[cc]:
                gi = cc
        self.commit = tuple(d['to_world']([gi[0]], [gi[1]])[0])
        via = self._route_waypoints(d, node)
        path_cells = self._path_via(d, mcp, cost[2], via, gi)
        kind_mask = (d['undone_lap'] if node.kind == 'vast' else d['undone_gvd']) \
            | d['undone_view']
        # A lap is followed 4 m at a time; a boundary or GVD piece 1 m at a time, so that the
        # robot turns back as soon as what it was going to see has been seen (the need is
        # re-evaluated at every plan).
        lap_goal = bool(d['lap'][gi] and d['vast'][gi])
        self._lap_x = float(d['to_world']([gi[0]], [gi[1]])[0][0]) if lap_goal else None
        ext = self._extend(gi, kind_mask & (d['owner'] == node.id),
                           max_cells=40 if lap_goal else 10)
        n_ext = len(ext)
        path_cells = path_cells + ext
        pts = d['to_world']([p[0] for p in path_cells], [p[1] for p in path_cells])
        if node.kind == 'narrow' and self.cfg.trim_view:
            pts = self._trim_to_view(d, pts, path_cells, len(path_cells) - n_ext - 1)
        self.path = [tuple(p) for p in pts]
        self.path_i = 0
        self.goal = self.path[-1]
        self.goal_kind = 'lap' if node.kind == 'vast' else 'gvd'
        self.state = 'covering_' + node.kind
        self.decisions.append((round(t, 3), int(node.id), node.kind,
                               round(float(pts[-1][0]), 2), round(float(pts[-1][1]), 2)))

    def _lap_middles(self, d, mine):
        """Undone lap cells with undone lap cells above and below them on their slice: a lap
        is begun at one end of what is left of it and driven to the other (boustrophedon),
        never entered in the middle, which would split it into two runs. The slice the robot
        is on is exempt: a lap under way goes on from where the robot is."""
        if not self.cfg.lap_ends:
            return np.zeros_like(mine)
        lap = mine & d['lap'] & d['vast']
        here = d['to_cell'](*self.pose[:2])
        if here is not None:
            k = int(math.ceil(2.0 * self.cfg.lap_tolerance / self.grid.res))
            lap[:, max(here[1] - k, 0):here[1] + k + 1] = False   # the slice being driven
        up = np.zeros_like(lap)
        down = np.zeros_like(lap)
        up[:-1] = lap[1:]
        down[1:] = lap[:-1]
        return lap & up & down

    def _lap_ahead(self, d, mine, cum):
        """A lap being driven is driven to its end (boustrophedon, Section II): while the
        robot is on a slice, the undone cells of that slice right ahead of it (within 1 m of
        travel) come before any other piece of the vast cell."""
        lx = self._lap_x
        if lx is None or abs(self.pose[0] - lx) > 2.0 * self.cfg.lap_tolerance:
            return None
        res = self.grid.res
        col = d['to_cell'](lx, self.pose[1])
        if col is None:
            return None
        on = np.zeros_like(mine)
        on[:, col[1]] = True
        cand = mine & d['lap'] & d['vast'] & on & (cum <= 1.0 + res)
        if not cand.any():
            return None
        return np.unravel_index(int(np.argmin(np.where(cand, cum, np.inf))), cand.shape)

    def _trim_to_view(self, d, pts, cells, k_goal):
        """End the path at its first point from which every unseen cell charged to the goal
        piece (the goal cell and the cells followed after it) is within the detector's range:
        the tip of a GVD branch is the work cell nearest a room corner, but the corner is in
        view well before it."""
        (ur, uc), (tr, tc) = d['charged']
        if len(ur) == 0 or k_goal < 0:
            return pts
        on = np.zeros(d['reach'].shape, dtype=bool)
        tail = np.asarray(cells[k_goal:])
        on[tail[:, 0], tail[:, 1]] = True
        mine = on[tr, tc]
        if not mine.any():
            return pts
        u = d['to_world'](ur[mine], uc[mine])
        far = np.max(np.hypot(pts[:, None, 0] - u[None, :, 0], pts[:, None, 1] - u[None, :, 1]),
                     axis=1)
        ok = np.flatnonzero(far <= self.det - self.cfg.view_margin)
        if len(ok) == 0:
            return pts
        k = int(ok[0])
        if np.hypot(*(pts[k] - np.asarray(self.pose[:2]))) < 0.3:
            return pts              # in view from here already: the map disagrees; go on
        return pts[:k + 1]

    def _tour_applies(self, node):
        """The tour orders a narrow node's pieces once no uncovered vast cell borders it. While
        one does, the narrow cell is the ring around it: its pieces are taken nearest first,
        which passes the vast cell's corners where the cusps are sensed (Fig. 10, 11); the tour
        cuts across and leaves them unsensed."""
        if self.cfg.piece_order != 'tour':
            return False
        return not any(self.graph.nodes[v].kind == 'vast' and not self.graph.nodes[v].covered
                       for v in self.graph.neighbours(node.id) if v in self.graph.nodes)

    def _tour_next(self, d, mine, cum, cost):
        """The tour's chunk is kept until its work is done (a tour solved anew at every plan
        can swap its first two chunks as the map grows, and the robot would zig-zag)."""
        keep = self._tour_chunk
        if keep is not None:
            rc = [d['to_cell'](x, y) for x, y in keep]
            rc = np.array([c for c in rc if c is not None and mine[c]])
            if len(rc):
                k = int(np.argmin(cum[rc[:, 0], rc[:, 1]]))
                return int(rc[k, 0]), int(rc[k, 1])
        chunk = self._tour_first(d, mine, cum, cost)
        if chunk is None:
            self._tour_chunk = None
            return None
        self._tour_chunk = [tuple(p) for p in d['to_world'](chunk[:, 0], chunk[:, 1])]
        k = int(np.argmin(cum[chunk[:, 0], chunk[:, 1]]))
        return int(chunk[k, 0]), int(chunk[k, 1])

    def _tour_first(self, d, mine, cum, cost):
        """The first chunk ((n, 2) cells) of the shortest open tour from the robot through the
        node's work; None if there are fewer than two chunks.

        The work cells are grouped in chunks (``tour_chunk`` squares, split by connectivity);
        geodesic distances between chunks come from Dijkstra on a coarse copy of the cost
        grid; the tour is nearest-neighbour then 2-opt. Unlike the nearest cell, the tour
        finishes a short dead-end branch before the branch that leads on (it would otherwise
        come back for it). The tour's end is free: on the sonar map nearly every chunk faces some
        frontier (a gap in a mapped wall, a pocket between two cones), so a tour made to end
        at a chunk facing the frontier would send the robot across the world."""
        res = self.grid.res
        f = max(1, int(round(COARSE_CELL / res)))
        chunks = chunk_cells(mine, max(1, int(round(self.cfg.tour_chunk / res))))
        if len(chunks) < 2:
            return None
        reps = [c[np.argmin(cum[c[:, 0], c[:, 1]])] for c in chunks]
        dist = coarse_distances(cost, [d['start']] + reps, f) * res
        order = open_tour(dist)
        return chunks[order[1] - 1]

    def _route_waypoints(self, d, node):
        """Cusp points (or shared-boundary points) along the graph route to ``node``, once,
        right after FindUncoveredNode chose it."""
        hops = getattr(self, '_route', None)
        self._route = None
        if not hops or len(hops) < 2:
            return []
        pts = self.graph.route_crossings(hops, self.pose[:2])
        return [p for p in pts if d['to_cell'](*p) is not None]

    def _path_via(self, d, mcp, cost, via, goal):
        """Grid path from the robot through the route waypoints to ``goal`` (cells)."""
        from skimage.graph import MCP_Geometric
        cells = []
        src = d['start']
        for p in via:
            c = d['to_cell'](*p)
            if c is None or not np.isfinite(cost[c]):
                continue
            m = MCP_Geometric(cost)
            m.find_costs([src])
            cells += m.traceback(c)
            src = c
        if src == d['start']:
            return cells + mcp.traceback(goal)
        m = MCP_Geometric(cost)
        cum, _ = m.find_costs([src])
        if not np.isfinite(cum[goal]):
            return mcp.traceback(goal)
        return cells + m.traceback(goal)

    def _extend(self, start, mask, max_cells=40):
        """Continue from ``start`` along adjacent undone pieces of the same kind (the lapping
        slice, the boundary or the GVD edge being followed), keeping the heading."""
        out = []
        cur = start
        heading = None
        seen = {start}
        ny, nx = mask.shape
        for _ in range(max_cells):
            best, best_s = None, -math.inf
            for di in (-1, 0, 1):
                for dj in (-1, 0, 1):
                    if di == 0 and dj == 0:
                        continue
                    n = (cur[0] + di, cur[1] + dj)
                    if not (0 <= n[0] < ny and 0 <= n[1] < nx) or n in seen or not mask[n]:
                        continue
                    s = 0.0 if heading is None else (di * heading[0] + dj * heading[1])
                    s -= 0.01 * (abs(di) + abs(dj))
                    if s > best_s:
                        best, best_s = n, s
            if best is None:
                break
            heading = (best[0] - cur[0], best[1] - cur[1])
            seen.add(best)
            out.append(best)
            cur = best
        return out

    # ------------------------------------------------------------------ motion

    def _follow(self):
        """Holonomic pursuit of the path: world-frame velocity towards a lookahead point."""
        x, y, _ = self.pose
        if self._escape:
            return self._escape_velocity()
        if not self.path:
            return 0.0, 0.0
        pts = np.asarray(self.path)
        # advance the progress index past points already reached
        while self.path_i < len(pts) - 1 and math.hypot(pts[self.path_i, 0] - x,
                                                         pts[self.path_i, 1] - y) < 0.2:
            self.path_i += 1
        look = 0.3
        j = self.path_i
        while j < len(pts) - 1 and math.hypot(pts[j, 0] - x, pts[j, 1] - y) < look:
            j += 1
        tx, ty = pts[j]
        dx, dy = tx - x, ty - y
        dn = math.hypot(dx, dy)
        if dn < 1e-6:
            return 0.0, 0.0
        remaining = dn + float(np.sum(np.hypot(*np.diff(pts[j:], axis=0).T))) if j < len(
            pts) - 1 else dn
        v = min(self.cfg.max_speed, 1.5 * remaining + 0.05)
        return v * dx / dn, v * dy / dn

    def _escape_velocity(self):
        """Move away from the closest sensed obstacle (robot outside sensed free space)."""
        d = self.last
        if not d:
            return 0.0, 0.0
        occ = d['occupied']
        rc = d['to_cell'](*self.pose[:2])
        if rc is None or not occ.any():
            return 0.0, 0.0
        _, (ir, ic) = ndimage.distance_transform_edt(~occ, return_indices=True)
        oy, ox = d['to_world']([ir[rc]], [ic[rc]])[0][::-1]
        dx, dy = self.pose[0] - ox, self.pose[1] - oy
        n = math.hypot(dx, dy) or 1.0
        return 0.2 * dx / n, 0.2 * dy / n

    def _check_stuck(self, t):
        """Report a robot that is commanded to move but does not; True if stuck now."""
        x, y, _ = self.pose
        if not self._hist or t - self._hist[-1][0] >= 1.0:
            self._hist.append((t, x, y))
        while self._hist and t - self._hist[0][0] > self.cfg.stuck_time + 1.0:
            self._hist.pop(0)
        if len(self._hist) < 2 or t - self._hist[0][0] < self.cfg.stuck_time:
            return False
        moved = max(math.hypot(x - hx, y - hy) for _, hx, hy in self._hist)
        if moved > 0.15:
            self.stuck_count = 0
            return False
        self.stuck_count += 1
        self._hist.clear()
        self._event(t, 'stuck', f'robot has not moved for {self.cfg.stuck_time:g} s '
                                f'({self.stuck_count}/{self.cfg.max_stuck})')
        self._retry_or_give_up(t)
        self._backoff_until = t + self.cfg.backoff_time
        self.path, self.path_i = [], 0
        self.t_plan = -math.inf
        if self.stuck_count >= self.cfg.max_stuck:
            self.state = 'stuck'
        return True

    def _retry_or_give_up(self, t):
        """Recovery: block the goal so the next plan takes another piece or route; after
        ``max_retries`` stuck events on the same node, give the node up (reported)."""
        if self.goal is not None:
            self.blocked.append(self.goal)
        self._stuck_at.append(self.pose[:2])
        self.commit = None
        self._tour_chunk = None
        n = self.current
        if n is None:
            return
        self.retries[n] = self.retries.get(n, 0) + 1
        if self.retries[n] >= self.cfg.max_retries and n not in self.given_up:
            self.given_up.append(n)
            self._event(t, 'gave_up', f'node {n} after {self.retries[n]} stuck events')
            self.current = None
        else:
            self._event(t, 'retry', f'node {n}: retry {self.retries[n]} by another route')

    def _event(self, t, kind, detail):
        x, y = (self.pose[0], self.pose[1]) if self.pose else (math.nan, math.nan)
        self.events.append((round(float(t), 3), kind, round(x, 3), round(y, 3), detail))

    # ------------------------------------------------------------------ reporting

    def status(self) -> dict[str, object]:
        """A compact, JSON-friendly status (published by the node)."""
        return {'state': self.state, 'current_node': self.current, 'sweeps': self.sweeps,
                'nodes': len(self.graph.alive()),
                'uncovered': [n.id for n in self.graph.alive() if not n.covered],
                'given_up': sorted(set(self.given_up)),
                'goal': list(self.goal) if self.goal else None,
                'last_event': list(self.events[-1]) if self.events else None}


def graph_dict(planner: CoveragePlanner | PaperPlanner) -> dict[str, object]:
    """The hierarchical decomposition graph of either planner as a JSON-friendly dict."""
    return planner.to_dict() if isinstance(planner, PaperPlanner) else planner.graph.to_dict()


class PlannerDriver:
    """Turns message streams into planner calls, identically live (node) and in replay (tests).

    One sweep of the ring arrives as one scan (ranges with their bearings, REP 117 values).
    Odometry is buffered and applied, in stamp order, up to the stamp of the sweep being
    processed, so a decision depends only on stamped inputs, not on callback order. The
    planner is created at the first sweep with the bearings and range limits the scan carries;
    a max range not beyond delta is refused (UserError).
    """

    def __init__(self, config: PaperConfig | PlannerConfig, beam_width: float) -> None:
        """``config``: a PaperConfig (the paper planner) or a PlannerConfig (grid)."""
        self.cfg = config
        self.beam_width = float(beam_width)
        self.planner = None
        self.odom = []              # [(t, x, y, yaw)] not yet applied
        self.last_stamp = -math.inf

    def on_odometry(self, t: float, x: float, y: float, yaw: float) -> None:
        self.odom.append((t, x, y, yaw))
        if self.planner is None and len(self.odom) > 200:
            self.odom = self.odom[-200:]

    def _apply_odometry(self, t):
        keep = []
        for o in self.odom:
            if o[0] <= t + 1e-9:
                if self.planner is not None:
                    self.planner.on_odometry(*o)
            else:
                keep.append(o)
        self.odom = keep

    def on_scan(self, t: float, ranges: ArrayLike, angles: ArrayLike, min_range: float,
                max_range: float) -> Command | None:
        """Process one sweep stamped ``t``; returns the command to send (None if stale)."""
        if t <= self.last_stamp:
            return None
        self.last_stamp = t
        if self.planner is None:
            cls = PaperPlanner if isinstance(self.cfg, PaperConfig) else CoveragePlanner
            self.planner = cls(self.cfg, angles, self.beam_width, min_range, max_range)
        self._apply_odometry(t)
        self.planner.on_sweep(t, ranges)
        return self.planner.update(t)

    def on_timer(self, t: float) -> Command | None:
        """Watchdog tick: a command only when sweeps have stopped (stop / keep stopped)."""
        p = self.planner
        if p is None or p.t_sweep is None or t - p.t_sweep <= self.cfg.sonar_timeout:
            return None
        self._apply_odometry(t)
        return p.update(t)
