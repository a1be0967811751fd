"""Online coverage planner: Algorithm 1 of Acar, Choset and Lee, from sonar and odometry only.

Inputs are sonar sweeps (REP 117 ranges of a transducer ring) and odometry; the output is a
velocity command (holonomic base, body frame) and a status. Nothing else is known: the planner
never reads the world file or the ground truth.

How Algorithm 1 maps onto this code
-----------------------------------
* The sweeps are fused into an evidence grid (:mod:`coverage_pkg.mapping`, inverse sonar model
  in :mod:`coverage_pkg.sonar`). Every ``replan_period`` the planner recomputes, on the sensed
  part of the world, the distance function ``D`` (unknown space counts as obstacle, so the
  decomposition only claims what has been sensed), ``FCS_r = {D > r}`` reachable from the
  robot, the vast region ``VR = {D > delta}`` and the narrow region ``NR = FCS_r \\ VR``
  (Section IV-A), the GVD (:mod:`coverage_pkg.gvd`), the Morse cells and critical points of
  ``h = x`` in VR (:mod:`coverage_pkg.morse`) and the cusp points ``D = delta`` on the GVD.
* The hierarchical decomposition graph (:mod:`coverage_pkg.hierarchical_graph`) keeps the vast
  and narrow nodes across rebuilds, CreateNode for newly sensed cells, the cusp edges, and
  FindUncoveredNode.
* ``MorseDecompCoverage`` of a vast node = follow the lapping slices ``x = x0 + k 2 delta``
  inside VR and the boundary of VR (the curve ``D = delta``), in the current Morse cell first.
  ``TraceGVD`` of a narrow node = follow the GVD edges inside NR to their ends (cusp points,
  dead ends at ``D = r``, meet points branch). Which slices, boundary pieces and GVD edges have
  been followed is known from the robot's own trace (odometry), so the bookkeeping survives the
  map growing under the robot: a node is covered when none of its pieces is left, and grows
  new pieces (it is uncovered again) when new space is sensed next to it.
* When the current node is covered, FindUncoveredNode picks the next one (fewest cusp crossings
  away, then nearest), the robot moves there along a shortest path through sensed free space,
  and coverage ends when no uncovered node is left: ``state == 'done'``.

Faults: NaN readings are ignored, +inf clears the cone up to max range, -inf adds nothing
(REP 117). Without a sweep for more than ``sonar_timeout`` s of sim time the robot is stopped
(``waiting_for_sonar``) and resumes when sweeps return. A robot that does not move although
commanded is reported (``stuck`` events); after ``max_stuck`` consecutive ones it stops for good
with ``state == 'stuck'`` instead of looping.
"""
import math
from dataclasses import dataclass

import numpy as np
from scipy import ndimage

from coverage_pkg import gvd as gvdmod
from coverage_pkg import morse
from coverage_pkg.hierarchical_graph import HierarchicalGraph
from coverage_pkg.mapping import T_FREE, EvidenceGrid
from coverage_pkg.sonar import sweep_evidence
from paramotion.errors import UserError


@dataclass
class PlannerConfig:
    """Planner parameters (SI units)."""

    delta: float = 2.0                 # detector range (m)
    radius: float = 0.25               # robot radius r (m)
    detector: str = 'extended'         # 'extended' (this paper) or 'robot' (Section II baseline)
    resolution: float = 0.1            # evidence grid cell (m)
    clearance_margin: float = 0.1      # keep the centre at D > r + margin (m)
    lap_spacing: float = 0.0           # 0: 2 * detector range
    max_speed: float = 1.0             # m/s
    spin_rate: float = 0.6             # rad/s, turns the sonar ring to fill the gaps between cones
    trace_tolerance: float = 0.15      # a piece counts as followed if the centre passed this close
    replan_period: float = 1.5         # s of sim time between decomposition rebuilds
    sonar_timeout: float = 0.5         # s of sim time without a sweep before stopping
    stuck_time: float = 5.0            # s commanded but not moving -> a stuck event
    max_stuck: int = 6                 # consecutive stuck events before giving up
    gvd_min_angle: float = math.radians(50.0)
    gvd_min_length: float = 0.5        # m, shorter isolated GVD pieces are sensing artefacts
    warmup: float = 1.0                # s spinning in place before the first plan
    range_margin: float = 0.3          # m kept in hand: the decomposition uses delta - margin
    node_switch_cost: float = 3.0      # m added to pieces outside the current node
    gvd_tolerance: float = 0.4         # m, a GVD edge passed this close counts as followed
    lap_tolerance: float = 0.25        # m, same for slices and boundary (< range_margin)
    min_piece: float = 0.3             # m, shorter leftover pieces are ignored


    def detector_range(self):
        """Range of the detector used for coverage: delta, or r for the robot-size baseline."""
        return self.radius if self.detector == 'robot' else self.delta

    def validate(self, sonar_max_range=None):
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


class CoveragePlanner:
    """Algorithm 1, online. Feed :meth:`on_odometry` and :meth:`on_sweep`; call :meth:`update`."""

    def __init__(self, config, mount_angles, beam_width, min_range, max_range, noise_std=0.01):
        config.validate(max_range)
        self.cfg = config
        self.mount = np.asarray(mount_angles, dtype=float)
        self.beam_width = float(beam_width)
        self.min_range = float(min_range)
        self.max_range = float(max_range)
        self.noise_std = float(noise_std)
        # Detector range used by the decomposition: delta minus a margin that absorbs grid
        # quantisation, sonar noise and path tracking error (Section IV-A uses delta itself).
        self.det = config.detector_range()
        if config.detector == 'extended':
            self.det = max(self.det - config.range_margin, config.radius + config.resolution)
        self.spacing = config.lap_spacing or 2.0 * self.det
        self.grid = None
        self.graph = HierarchicalGraph()
        self.pose = None
        self.t_odom = None
        self.t_sweep = None
        self.t_first_sweep = None
        self.t_plan = -math.inf
        self.state = 'no_odometry'
        self.current = None             # current node id
        self.goal = None                # (x, y) of the piece being approached
        self.commit = None              # cell chosen at the last plan (kept while uncovered)
        self.goal_kind = None
        self.path = []                  # world waypoints
        self.path_i = 0
        self.x_ref = None
        self.events = []                # (t, kind, x, y, detail): decisions and faults
        self.decisions = []             # (t, node_id, node_kind, goal_x, goal_y) per plan
        self.stuck_count = 0
        self._hist = []                 # (t, x, y) once per second for stuck detection
        self.blocked = []               # goals given up after a stuck event
        self.last = {}                  # last decomposition, for markers and the result
        self.sweeps = 0
        self.min_distance = math.inf

    # ------------------------------------------------------------------ inputs

    def on_odometry(self, t, x, y, yaw):
        """Robot pose in the odom frame at sim time t."""
        if not all(math.isfinite(v) for v in (t, x, y, yaw)):
            return
        self.pose = (float(x), float(y), float(yaw))
        self.t_odom = t
        if self.grid is None:
            self.grid = EvidenceGrid(self.cfg.resolution, (x, y))
            self.x_ref = float(x)
        self.grid.mark_trace(x, y, self.cfg.trace_tolerance)

    def on_sweep(self, t, ranges):
        """One sweep of the ring (REP 117 values, one per transducer, in mount order)."""
        if self.pose is None:
            return
        ranges = np.asarray(ranges, dtype=float)
        free_xy, occ_xy, valid = sweep_evidence(
            self.pose, ranges, self.mount, self.beam_width, self.min_range, self.max_range,
            self.cfg.resolution, self.noise_std)
        if valid == 0:
            return                      # all NaN / -inf: no information, as good as silence
        self.t_sweep = t
        if self.t_first_sweep is None:
            self.t_first_sweep = t
        self.grid.integrate(free_xy, occ_xy)
        self.sweeps += 1
        finite = ranges[np.isfinite(ranges)]
        prev = self.min_distance
        self.min_distance = float(finite.min()) if len(finite) else self.max_range
        # Sensor-level cusp test while tracing a narrow GVD edge (Fig. 11): logged as an event;
        # the node bookkeeping uses the same criterion on the sensed grid (D crosses delta).
        if (self.cfg.detector == 'extended' and self.goal_kind == 'gvd'
                and gvdmod.narrow_cusp_crossed(prev, self.min_distance, self.det)):
            self._event(t, 'cusp_sensed', 'min range rose above delta while tracing the GVD')

    # ------------------------------------------------------------------ main step

    def update(self, t):
        """Advance the planner at sim time t; returns the velocity command to send."""
        if self.pose is None:
            self.state = 'no_odometry'
            return Command(0.0, 0.0, 0.0, self.state)
        if self.state in ('done', 'stuck'):
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
        if self._check_stuck(t):
            if self.state == 'stuck':
                return Command(0.0, 0.0, 0.0, self.state)
        at_end = self.path_i >= len(self.path) - 1 and (
            not self.path or math.dist(self.pose[:2], self.path[-1]) < 0.1)
        if at_end or t - self.t_plan >= self.cfg.replan_period:
            self._plan(t)
            if self.state == 'done':
                return Command(0.0, 0.0, 0.0, self.state)
        vx, vy = self._follow()
        yaw = self.pose[2]
        c, s = math.cos(yaw), math.sin(yaw)
        return Command(c * vx + s * vy, -s * vx + c * vy, self.cfg.spin_rate, self.state)

    # ------------------------------------------------------------------ decomposition + choice

    def decompose(self):
        """Rebuild the hierarchical decomposition of the sensed world around the robot.

        Returns a dict of grid layers (crop of the evidence grid) used by :meth:`_plan` and by
        the visualisation.
        """
        g = self.grid
        cfg = self.cfg
        rs, cs = g.known_bbox(margin_cells=4)
        res = g.res
        free = g.logodds[rs, cs] < T_FREE
        obstacle = ~free
        dist, fr, fc = gvdmod.distance_transform(obstacle, res)
        trav = free & (dist > cfg.radius + cfg.clearance_margin)
        r0, c0 = rs.start, cs.start

        def to_cell(x, y):
            i = int(math.floor((y - g.origin[1]) / res)) - r0
            j = int(math.floor((x - g.origin[0]) / res)) - c0
            if 0 <= i < trav.shape[0] and 0 <= j < trav.shape[1]:
                return i, j
            return None

        def to_world(rows, cols):
            return g.center(np.asarray(rows) + r0, np.asarray(cols) + c0)

        rc = to_cell(*self.pose[:2])
        start = None
        if rc is not None and trav[rc]:
            start = rc
        elif rc is not None and trav.any():
            _, (ir, ic) = ndimage.distance_transform_edt(~trav, return_indices=True)
            cand = (int(ir[rc]), int(ic[rc]))
            if math.hypot(cand[0] - rc[0], cand[1] - rc[1]) * res < 1.0:
                start = cand
        lab, _ = ndimage.label(trav)
        reach = (lab == lab[start]) if start is not None else np.zeros_like(trav)
        vast = reach & (dist > self.det)
        narrow = reach & ~vast
        out = dict(rs=rs, cs=cs, free=free, dist=dist, trav=trav, reach=reach, vast=vast,
                   narrow=narrow, start=start, to_cell=to_cell, to_world=to_world,
                   trace=g.trace[rs, cs], occupied=g.logodds[rs, cs] > 0.6)
        lap = morse.lap_columns(trav.shape[1], g.origin[0] + c0 * res, res, self.x_ref,
                                self.spacing)
        out['lap'] = vast & lap[None, :]
        out['boundary'] = morse.boundary_cells(vast)
        if cfg.detector == 'extended':
            min_cells = max(3, int(round(cfg.gvd_min_length / res)))
            gvd = gvdmod.prune_small(gvdmod.gvd_cells(free, fr, fc, cfg.gvd_min_angle) & reach,
                                     min_cells)
            out['gvd'] = gvd
            # Narrow cells: the GVD outside the vast region (proof of Lemma 3), in pieces
            # long enough not to be a sonar artefact.
            out['narrow_gvd'] = gvdmod.prune_small(gvd & narrow, min_cells)
            out['cusps'] = gvdmod.cusp_cells(gvd, dist, self.det)
        else:
            out['gvd'] = np.zeros_like(free)
            out['narrow_gvd'] = np.zeros_like(free)
            out['cusps'] = []
        out['reeb'], out['critical'], out['reeb_edges'] = morse.reeb_decomposition(vast)
        return out

    def _plan(self, t):
        from skimage.graph import MCP_Geometric
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
        trace = d['trace']
        blocked = np.zeros_like(trace)
        for bx, by in self.blocked:
            cell = d['to_cell'](bx, by)
            if cell is not None:
                k = int(math.ceil(0.4 / self.grid.res))
                blocked[max(cell[0] - k, 0):cell[0] + k + 1,
                        max(cell[1] - k, 0):cell[1] + k + 1] = True
        # Distance of every cell to the robot's trace: a slice or boundary piece counts as
        # followed within lap_tolerance (kept below range_margin, so the detector disks still
        # meet), a GVD edge within gvd_tolerance (the discrete GVD of a map still being refined
        # shifts by a cell or two, and a narrow cell is seen whole from anywhere near its GVD,
        # Lemma 1). Pieces shorter than min_piece are sonar artefacts, not cells to visit.
        dtrace = ndimage.distance_transform_edt(~trace) * self.grid.res + self.cfg.trace_tolerance
        min_cells = max(1, int(round(self.cfg.min_piece / self.grid.res)))
        undone_lap = gvdmod.prune_small(
            (d['lap'] | d['boundary']) & (dtrace > self.cfg.lap_tolerance) & ~blocked, min_cells)
        undone_gvd = gvdmod.prune_small(
            d['narrow_gvd'] & (dtrace > self.cfg.gvd_tolerance) & ~blocked, min_cells)
        # --- hierarchical graph bookkeeping
        vl, _ = ndimage.label(d['vast'], structure=np.ones((3, 3)))
        nl, _ = ndimage.label(d['narrow_gvd'], structure=np.ones((3, 3)))
        seeds = [self.pose[:2]] + [tuple(d['to_world']([r], [c])[0]) for r, c in d['cusps']]
        start_kind = 'vast' if d['dist'][d['start']] > self.det else 'narrow'
        vmap = self.graph.update('vast', vl, d['to_cell'], d['to_world'], self.grid.res, seeds)
        nmap = self.graph.update('narrow', nl, d['to_cell'], d['to_world'], self.grid.res,
                                 seeds)
        for r, c in d['cusps']:
            ri, ci = int(round(r)), int(round(c))
            win = (slice(max(ri - 3, 0), ri + 4), slice(max(ci - 3, 0), ci + 4))
            vs = [v for v in np.unique(vl[win]) if v]
            ns = [n for n in np.unique(nl[win]) if n]
            xy = tuple(d['to_world']([r], [c])[0])
            for v in vs:
                for n in ns:
                    self.graph.add_cusp(vmap[v], nmap[n], xy)
        d['meet'] = gvdmod.meet_points(d['narrow_gvd']) if d['narrow_gvd'].any() else []
        for nid in nmap.values():
            self.graph.nodes[nid].meet_points = []
        for r, c in d['meet']:
            lab = nl[int(round(r)), int(round(c))]
            if lab in nmap:
                self.graph.nodes[nmap[lab]].meet_points.append(
                    tuple(float(v) for v in d['to_world']([r], [c])[0]))
        node_of = np.zeros(vl.shape, dtype=np.int64) - 1
        for lab, nid in vmap.items():
            node_of[vl == lab] = nid
        for lab, nid in nmap.items():
            node_of[nl == lab] = nid
        undone = np.where(d['vast'], undone_lap, undone_gvd)
        counts = {}
        if undone.any():
            ids, cnt = np.unique(node_of[undone], return_counts=True)
            counts = {int(i): int(n) for i, n in zip(ids, cnt) if i >= 0}
        for nid in list(vmap.values()) + list(nmap.values()):
            node = self.graph.nodes[nid]
            was = node.covered
            node.covered = counts.get(nid, 0) == 0
            if node.covered and not was:
                self._event(t, 'node_covered', f'{node.kind} node {nid} covered')
        # Reeb graph of each vast node: its critical points and the cells joining them. A
        # split/merge point lies in the obstacle between two slice intervals, so it is
        # assigned to a vast cell through the Morse cells it opens or closes.
        reeb = d['reeb']
        n_reeb = int(reeb.max())
        cell_comp = np.zeros(n_reeb + 1, dtype=np.int64)
        if n_reeb:
            cell_comp[1:] = ndimage.maximum(vl, reeb, np.arange(1, n_reeb + 1)).astype(np.int64)
        comp_of_point = []
        for p in d['critical']:
            cells = p.cells_before + p.cells_after
            comp_of_point.append(int(cell_comp[cells[0]]) if cells else 0)
        for lab, nid in vmap.items():
            idx = [i for i, c in enumerate(comp_of_point) if c == lab]
            local = {i: k for k, i in enumerate(idx)}
            node = self.graph.nodes[nid]
            node.reeb_points = [
                tuple(float(v) for v in d['to_world']([d['critical'][i].row],
                                                      [d['critical'][i].col])[0])
                + (d['critical'][i].kind,) for i in idx]
            node.reeb_edges = [(local[a], local[b]) for a, b, _ in d['reeb_edges']
                               if a in local and b in local]
        cur = self.graph.nodes.get(self.current)
        while cur is not None and not cur.alive and cur.merged_into >= 0:
            cur = self.graph.nodes[cur.merged_into]
        self.current = cur.id if cur is not None and cur.alive else None
        first = self.current is None and not self.decisions
        # --- geodesic distances from the robot
        # Path cost grows near obstacles, so that transits through narrow space run along the
        # GVD (and follow it, as TraceGVD would) instead of hugging a wall.
        cost = np.where(d['reach'], 1.0 + 2.0 * np.clip(1.0 - d['dist'] / self.det, 0.0, 1.0),
                        np.inf)
        mcp = MCP_Geometric(cost)
        cum, _ = mcp.find_costs([d['start']])
        cum = cum * self.grid.res
        cand = undone & np.isfinite(cum)
        if not cand.any():
            self.state = 'done'
            self.path, self.path_i = [], 0
            self._event(t, 'done', 'no uncovered node left: coverage complete')
            return
        # --- choose the node (Algorithm 1) and the piece inside it
        def reach_dist(node):
            m = cand & (node_of == node.id)
            return float(cum[m].min()) if m.any() else math.inf
        if first:
            # CreateNode(x, D(x)): the first node is of the kind D(x) says, the nearest one.
            kinds = [n for n in self.graph.alive(start_kind) if not n.covered]
            if kinds:
                self.current = min(kinds, key=reach_dist).id
        if self.current is None or counts.get(self.current, 0) == 0 or not (
                cand & (node_of == self.current)).any():
            nxt = self.graph.find_uncovered_node(self.current, reach_dist)
            while nxt is not None and not math.isfinite(reach_dist(nxt)):
                nxt.covered = True        # nothing reachable is left in it
                nxt = self.graph.find_uncovered_node(self.current, reach_dist)
            if nxt is None:
                self.state = 'done'
                self.path, self.path_i = [], 0
                self._event(t, 'done', 'no uncovered node left: coverage complete')
                return
            if self.current is not None and nxt.id != self.current:
                hops = self.graph.graph_path(self.current, nxt.id)
                self._event(t, 'next_node', f'{nxt.kind} node {nxt.id} via {hops}')
            self.current = nxt.id
        # Cover the current node first: pieces of other nodes cost an extra
        # ``node_switch_cost`` (a soft form of "cover n, then FindUncoveredNode", which avoids
        # crossing a whole vast cell to finish it before visiting an adjacent corner), and
        # inside a vast node the current Morse cell comes first.
        score = cum + np.where(node_of == self.current, 0.0, self.cfg.node_switch_cost)
        node = self.graph.nodes[self.current]
        if node.kind == 'vast' and d['start'] is not None:
            rc = d['reeb'][d['start']]
            if rc:
                score = score + np.where((d['reeb'] == rc) | (node_of != self.current), 0.0,
                                         self.spacing)
        score = np.where(cand, score, np.inf)
        gi = np.unravel_index(int(np.argmin(score)), score.shape)
        # Keep the piece chosen at the last plan while it is still uncovered and reachable.
        if self.commit is not None:
            cc = d['to_cell'](*self.commit)
            if cc is not None and cand[cc]:
                gi = cc
        self.commit = tuple(d['to_world']([gi[0]], [gi[1]])[0])
        if node_of[gi] != self.current and node_of[gi] >= 0:
            nxt = self.graph.nodes[int(node_of[gi])]
            self._event(t, 'next_node', f'{nxt.kind} node {nxt.id} via '
                                        f'{self.graph.graph_path(self.current, nxt.id)}')
            self.current = nxt.id
            node = nxt
        path_cells = mcp.traceback(gi)
        kind_mask = undone_lap if d['vast'][gi] else undone_gvd
        path_cells = path_cells + self._extend(gi, kind_mask)
        pts = d['to_world']([p[0] for p in path_cells], [p[1] for p in path_cells])
        self.path = [tuple(p) for p in pts]
        self.path_i = 0
        self.goal = self.path[-1]
        self.goal_kind = 'lap' if d['vast'][gi] else 'gvd'
        self.state = 'covering_' + node.kind
        self.decisions.append((round(t, 3), int(node.id), node.kind,
                               round(float(pts[-1][0]), 2), round(float(pts[-1][1]), 2)))

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
        if getattr(self, '_escape', False):
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
        if self.goal is not None:
            self.blocked.append(self.goal)
        self.path, self.path_i = [], 0
        self.t_plan = -math.inf
        if self.stuck_count >= self.cfg.max_stuck:
            self.state = 'stuck'
        return True

    def _event(self, t, kind, detail):
        x, y = (self.pose[0], self.pose[1]) if self.pose else (math.nan, math.nan)
        self.events.append((round(float(t), 3), kind, round(x, 3), round(y, 3), detail))

    # ------------------------------------------------------------------ reporting

    def status(self):
        """A compact, JSON-friendly status (published by the node)."""
        return {'state': self.state, 'current_node': self.current, 'sweeps': self.sweeps,
                'nodes': len(self.graph.alive()),
                'uncovered': [n.id for n in self.graph.alive() if not n.covered],
                'goal': list(self.goal) if self.goal else None,
                'last_event': list(self.events[-1]) if self.events else None}


class PlannerDriver:
    """Turns message streams into planner calls, identically live (node) and in replay (tests).

    One sweep of the ring arrives as one scan (ranges with their bearings, REP 117 values).
    Odometry is buffered and applied, in stamp order, up to the stamp of the sweep being
    processed, so a decision depends only on stamped inputs, not on callback order. The
    planner is created at the first sweep with the bearings and range limits the scan carries;
    a max range not beyond delta is refused (UserError).
    """

    def __init__(self, config, beam_width):
        self.cfg = config
        self.beam_width = float(beam_width)
        self.planner = None
        self.odom = []              # [(t, x, y, yaw)] not yet applied
        self.last_stamp = -math.inf

    def on_odometry(self, t, x, y, yaw):
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

    def on_scan(self, t, ranges, angles, min_range, max_range):
        """Process one sweep stamped ``t``; returns the command to send (None if stale)."""
        if t <= self.last_stamp:
            return None
        self.last_stamp = t
        if self.planner is None:
            self.planner = CoveragePlanner(self.cfg, angles, self.beam_width, min_range,
                                           max_range)
        self._apply_odometry(t)
        self.planner.on_sweep(t, ranges)
        return self.planner.update(t)

    def on_timer(self, t):
        """Watchdog tick: a command only when sweeps have stopped (stop / keep stopped)."""
        p = self.planner
        if p is None or p.t_sweep is None or t - p.t_sweep <= self.cfg.sonar_timeout:
            return None
        self._apply_odometry(t)
        return p.update(t)
