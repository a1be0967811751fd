"""Algorithm 1 of Acar, Choset and Lee, driven by sensed events alone (``planner:=paper``).

Every structure of the hierarchical decomposition graph ``(N, E)`` is created by an event
the sonar ring senses; no map is decomposed. :class:`PaperPlanner` is Algorithm 1 itself:
:meth:`PaperPlanner.update` creates the start node (``CreateNode(x, D(x))``), covers the
current node ``n`` by its subroutine and, once ``n`` is covered, marks it, takes
``n <- FindUncoveredNode(N)`` and the path to ``x(n)`` (:meth:`PaperPlanner._next_node`),
until no uncovered node is left. The subroutines map one to one onto the paper, one module
each in :mod:`coverage_pkg.paper`:

* ``CreateNode(x, D(x))``: :mod:`coverage_pkg.paper.node_creation` (a vast node where
  ``D > delta``, a narrow node otherwise; for the start and for every new cusp point, with
  the edge carrying the cusp);
* ``MorseDecompCoverage(n, L, F)``: :mod:`coverage_pkg.paper.morse_coverage` (laps ``2 delta``
  apart, boundary following at ``D = delta``, critical points closing Morse cells);
* ``TraceGVD(n, L, F)``: :mod:`coverage_pkg.paper.trace_gvd` (GVD edges, meet points);
* ``FindUncoveredNode(N)`` and the path to ``x(n)``: :mod:`coverage_pkg.paper.find_uncovered`;
* the events that drive them (cusp and meet points sensed by the ring):
  :mod:`coverage_pkg.paper.sense_events`; the graph's nodes:
  :mod:`coverage_pkg.paper.graph_nodes`.

Sensing details the paper leaves open: a cusp is known only on the same GVD edge (its bearing
into the narrow cell), since the cusps of a small vast cell lie within a step of one another;
D rising above delta on a traced edge is a cusp at the robot (Fig. 11) where the ring's
two-echo test placed none; a GVD edge ends where all ahead is within the detector's view,
and a gap beyond delta beside that end (a door by a corner) is a branch (a meet event); a
start on neither the GVD nor VR first moves off its single closest obstacle
(:meth:`PaperPlanner._access`).

``without`` switches the sensing of one event kind off (``cusp``, ``critical``, ``meet``), so
that the run shows what the paper predicts without it. :func:`parse_modes` reads the
selectable modes (``handover=false``: Algorithm 1's pseudocode order; ``rules=paper``: every
sensing rule of ours set to the paper's reading, :data:`PAPER_RULES`; ``ours=on``: seven of
the modes of ours that are off in the default, on, :data:`OUR_MODES`). Plain numpy; no ROS.
"""
from __future__ import annotations

import math
import re
from collections.abc import Iterable
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from coverage_pkg import gvd as gvdmod
from coverage_pkg.paper.find_uncovered import FindUncoveredNode, TracedPaths
from coverage_pkg.paper.graph_nodes import Branch, MorseCell, Node
from coverage_pkg.paper.morse_coverage import MorseDecompCoverage
from coverage_pkg.paper.node_creation import CreateNode
from coverage_pkg.paper.sense_events import EventSensing
from coverage_pkg.paper.trace_gvd import TraceGVD
from paramotion.errors import UserError

__all__ = ['EVENTS', 'MODE_FIELDS', 'OUR_MODES', 'PAPER_RULES', 'TERMINAL', 'Branch', 'Command',
           'MorseCell', 'Node', 'PaperConfig', 'PaperPlanner', 'TracedPaths', 'parse_modes',
           'parse_without']

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


#: The :class:`PaperConfig` fields that select a mode of the paper planner (node parameter
#: ``modes``, ``paramotion coverage --mode``); the other fields are its thresholds and limits.
MODE_FIELDS = ('handover', 'merge_continues', 'circuit_sweeps', 'cusp_detour', 'circuit_join',
               'meet_scan', 'end_scan', 'sliver_openings', 'cusp_meet', 'meet_margin',
               'circuit_same_way', 'circuit_same_side', 'meet_side_pair', 'way_come_held',
               'meet_own_obstacles', 'traced_way', 'meet_surround', 'cusp_edge_traced',
               'cusp_meet_gap', 'pinch_ends_cell', 'fork_at_meet', 'start_on_gvd')

#: ``rules=paper``: each sensing rule of ours that is on in the default, set to the paper's
#: reading (the rules of ours that are off in the default are off here too). What remains is
#: Algorithm 1 with the paper's own tests as literally as the ring allows: a meet point's
#: branches from the one sweep that sensed it, every boundary circuit driven round to its
#: start, a meet point only at D <= delta, a cusp only a cusp, and so on (docs/coverage.md,
#: *Modes*).
PAPER_RULES = {'meet_scan': False, 'sliver_openings': False, 'circuit_join': False,
               'cusp_meet': False, 'meet_margin': 0.0, 'circuit_same_way': False,
               'circuit_same_side': False, 'meet_side_pair': False, 'way_come_held': False,
               'meet_own_obstacles': False}

#: ``ours=on``: seven of the modes of ours that are off in the default, on: the five that
#: shorten the path (``traced_way``, ``circuit_sweeps``, ``cusp_edge_traced``, ``cusp_meet_gap``,
#: ``pinch_ends_cell``) and the two that cover a corner and the strips of a hall the default
#: leaves unseen (``fork_at_meet``, ``start_on_gvd``). It is our planner beside the paper's,
#: measured side by side with the default in docs/coverage.md, *Results*, and in the
#: report's Modes table (``our_modes``). The other modes of ours that are off in the default
#: stay off in it: ``end_scan`` and ``merge_continues`` lengthen the path, ``cusp_detour``
#: and ``meet_surround=true`` leave a world below 99 % (docs/coverage.md, *Modes*).
OUR_MODES = {'traced_way': True, 'circuit_sweeps': True, 'cusp_edge_traced': True,
             'cusp_meet_gap': True, 'pinch_ends_cell': True, 'fork_at_meet': True,
             'start_on_gvd': True}

_TRUE, _FALSE = ('1', 'true', 'yes', 'on'), ('0', 'false', 'no', 'off')


def parse_modes(value: str | Iterable[str] | None,
                fields: Iterable[str] = MODE_FIELDS) -> dict[str, object]:
    """:class:`PaperConfig` keyword arguments from ``NAME=VALUE`` items (a comma-separated
    string or a list), each typed like the field's default. ``rules=paper`` stands for
    :data:`PAPER_RULES` and ``rules=ours`` for the default's rules; ``ours=on`` for
    :data:`OUR_MODES` and ``ours=off`` for the default's values of those fields; later items
    override earlier ones (``rules=paper,meet_scan=true``, ``ours=on,start_on_gvd=false``).
    ``fields``: the names accepted besides ``rules`` and ``ours``. UserError names the bad
    item in one line."""
    items = value.split(',') if isinstance(value, str) else list(value or ())
    base, allowed, out = PaperConfig(), tuple(fields), {}
    for item in (i.strip() for i in items):
        if not item:
            continue
        name, sep, text = (part.strip() for part in item.partition('='))
        if not sep or not text:
            raise UserError(f'mode "{item}" must be NAME=VALUE')
        if name == 'rules':
            if text not in ('paper', 'ours'):
                raise UserError(f'mode "{item}": rules takes paper or ours')
            for key in PAPER_RULES:
                out[key] = PAPER_RULES[key] if text == 'paper' else getattr(base, key)
            continue
        if name == 'ours':
            if text.lower() not in _TRUE + _FALSE:
                raise UserError(f'mode "{item}": ours takes on or off')
            on = text.lower() in _TRUE
            for key in OUR_MODES:
                out[key] = OUR_MODES[key] if on else getattr(base, key)
            continue
        if name not in allowed or not hasattr(base, name):
            raise UserError(f'mode "{item}": {name} is not a mode of the paper planner '
                            f'(rules, ours, {", ".join(allowed)})')
        kind = type(getattr(base, name))
        if kind is bool:
            if text.lower() not in _TRUE + _FALSE:
                raise UserError(f'mode "{item}": {name} takes true or false')
            out[name] = text.lower() in _TRUE
        elif kind is tuple:
            out[name] = tuple(v for v in re.split('[,;]', text) if v)
        else:
            try:
                number = kind(text)
            except ValueError:
                raise UserError(f'mode "{item}": {name} takes a {kind.__name__}') from None
            if isinstance(number, float) and not (math.isfinite(number) and number >= 0):
                raise UserError(f'mode "{item}": {name} must be finite and >= 0')
            out[name] = number
    return out


def primitive_lengths(segments: Iterable[tuple[str, float]]) -> dict[str, float]:
    """Path length per primitive (lap, boundary, gvd, transit) of [primitive, length m]
    segments."""
    out = {}
    for kind, length in segments:
        out[kind] = out.get(kind, 0.0) + length
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
    handover: bool = True           # Fig. 13's order: a cusp met while tracing hands over
    #                                 to the vast node beyond it at once (False: Algorithm
    #                                 1's pseudocode order, the narrow node traced whole)
    merge_continues: bool = False   # True: a narrow node whose GVD trace joins an edge an
    #                                 earlier narrow node traced hands over to that node,
    #                                 which goes on being covered at once (False: the later
    #                                 node is covered there, and FindUncoveredNode chooses
    #                                 the next node, the earlier one among the uncovered)
    circuit_sweeps: bool = False    # ours: no laps in a cell its circuit has swept (off:
    #                                 it drops the paper's laps; it lowers some worlds by up
    #                                 to 0.68 points, none below 99 %)
    cusp_detour: bool = False       # ours: a narrow node whose cusp the boundary circuit
    #                                 senses is traced at once; the circuit resumes after
    retrace_angle: float = 45.0     # deg, transit follows a traced GVD edge (a wall at
    #                                 D = delta) by the GVD (boundary) law where the edge's
    #                                 tangent is this near the way ahead
    circuit_join: bool = True       # ours: a boundary circuit that reaches a stretch of
    #                                 boundary another circuit followed ends there, and its
    #                                 start's other way round is followed to known boundary
    #                                 (False: each circuit goes round until back at its start)
    meet_scan: bool = True          # ours: on a meet point the robot halts and turns its
    #                                 ring through one cone spacing before it reads the
    #                                 branches (False: from the one sweep that sensed it)
    end_scan: bool = False          # ours: where a GVD edge ends at an obstacle the robot
    #                                 halts and turns its ring through one cone spacing
    #                                 before it reads the gaps beside the end (a door by a
    #                                 corner) (False: from the one sweep that found the end)
    sliver_openings: bool = True    # ours: a vast cell that is a sliver within delta / 2
    #                                 of its middle is read like a meet point once its
    #                                 circuit closes: each opening of the range over bearing
    #                                 beyond delta from its middle with no cusp of the
    #                                 node's edges on it is a cusp (False: only the cusps
    #                                 the circuit senses)
    cusp_meet: bool = True          # ours: a cusp sensed where three closest obstacles are
    #                                 equidistant is also a meet point; each gap between
    #                                 them but the one facing the vast cell is a branch of
    #                                 its narrow node (a door beside a corner's cusp)
    #                                 (False: the cusp's one branch)
    meet_margin: float = 0.1        # m, ours: a meet point is taken at D <= delta + this
    #                                 (0.1: as far as the GVD trace goes before D has risen
    #                                 above delta; a corner's edge leaving a wall's edge at
    #                                 D = delta within the echoes' noise) (0: one beyond
    #                                 delta is passed and kept, a meet point only if the
    #                                 edge beyond ends in a dead end without a cusp)
    circuit_same_way: bool = True   # ours: a boundary circuit's closest pass by its start
    #                                 counts as back only going the way it left the start
    #                                 (False: either way; a vast cell under 0.8 m across
    #                                 then ends its circuit on the far side)
    circuit_same_side: bool = True  # ours: a boundary circuit's pass within 0.4 m of its
    #                                 start counts as back only facing an obstacle it
    #                                 faced there (closest echo within 60 deg) (False: on
    #                                 either side; a vast strip under 0.4 m across then
    #                                 ends its circuit on the far side)
    meet_side_pair: bool = True     # ours: going on past a meet point along a branch, the
    #                                 robot follows the GVD edge of the closest obstacle on
    #                                 either side of its heading until its two closest
    #                                 obstacles lie either side of it (the branch's edge;
    #                                 TraceGVD._side_pair) (False: the GVD law of the two
    #                                 closest from the meet point on, which can follow a
    #                                 neighbouring branch's edge)
    way_come_held: bool = True      # ours: at a meet point, where a peak of the range
    #                                 holds the bearing to the robot's path behind, that
    #                                 peak (and the peaks one edge with it) is the way
    #                                 come and every other opening a branch, however near
    #                                 (TraceGVD._meet_branches) (False: as on a gap's
    #                                 branch only; elsewhere every peak within 60 deg of
    #                                 that bearing is the way come)
    meet_own_obstacles: bool = True   # ours: a meet point sensed within
    #                                 same_event of a known one, from over same_event
    #                                 beyond where the robot sensed that one, is another
    #                                 meet point where one of the known one's three closest
    #                                 obstacles lies farther from it than its own three by
    #                                 over 2 event_tolerance (the end of a hall past an
    #                                 obstacle's meet point; EventSensing._other_meet)
    #                                 (False: the known one)
    traced_way: bool = False        # ours: a branch whose way out (0.8, 1.6 or 2.4 m along
    #                                 its bearing) comes within 0.4 m of a traced GVD edge
    #                                 running across that way, or along it towards the
    #                                 branch's start or from a trace that passed the start,
    #                                 is traced already (TraceGVD._way_reaches_trace)
    #                                 (False: only where all three points lie on a traced
    #                                 edge; True loses a room in Algorithm 1's pseudocode
    #                                 order: a meet point missed by the first trace of an
    #                                 edge is not sensed on a second)
    cusp_edge_traced: bool = False  # ours: a GVD branch that ends at a cusp sensed before
    #                                 by a circuit, along that cusp's edge, has traced the
    #                                 cusp's narrow node's edge from its other end: the two
    #                                 narrow nodes are one and the cusp's branch ends traced
    #                                 (CreateNode._cusp_edge_traced) (False: the cusp's
    #                                 node is covered on its own, its branch traced until it
    #                                 joins the traced edge, then merged)
    cusp_meet_gap: bool = False     # ours, with cusp_meet: the cusp's own branch leaves
    #                                 along the gap between its three closest obstacles
    #                                 nearest its bearing (False: along the bisector of its
    #                                 two closest obstacles, which can point at the wall
    #                                 between a corner's gap and a door's beside it)
    pinch_ends_cell: bool = False   # ours: a Morse cell ends where the move between laps
    #                                 (or to the cell's left side) finds two obstacles
    #                                 either side nearer than delta (a cusp passed into
    #                                 narrow space; MorseDecompCoverage._pinched), and a
    #                                 lap where the delta disk touches a corner ahead
    #                                 (._touches_ahead) (False: the move follows the
    #                                 boundary at D = delta on along a corridor whose wall
    #                                 runs on from the room's; a lap runs while the echo
    #                                 straight ahead is beyond delta)
    fork_at_meet: bool = False      # ours: two peaks of a meet point's scan, one's upper
    #                                 half holding the other's top, are two GVD edges where
    #                                 the obstacle between their tops lies within rho + 2
    #                                 same_event of the meet point: the edge between them
    #                                 forks within same_event of it, where the fork would be
    #                                 taken for this meet point (a room about 2 delta
    #                                 square entered through a door: its far corners)
    #                                 (TraceGVD._fork_here) (False: one edge, along the
    #                                 middle of their joint span)
    start_on_gvd: bool = False      # ours: the start node's kind is read from D on the GVD
    #                                 beside which the access ends (the mean of the two
    #                                 closest obstacles' echoes), so a start in a hall just
    #                                 over 2 delta wide is a vast node (PaperPlanner._start_D)
    #                                 (False: from D where the robot stands, up to
    #                                 event_tolerance short of the GVD: a narrow node, whose
    #                                 trace along the hall's middle never sees D cross delta
    #                                 and leaves a strip along each wall unseen)
    meet_surround: bool = False     # True: a meet point is taken only where its three
    #                                 closest obstacles surround it (no gap over 190 deg
    #                                 between their bearings) (False, as the paper's
    #                                 definition allows: also within a half-plane, an obtuse
    #                                 triangle's circumcentre; and two peaks of a scan, one
    #                                 holding the other's top, leave along their joint
    #                                 span's middle, ours)

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


class PaperPlanner(EventSensing, CreateNode, MorseDecompCoverage, TraceGVD, FindUncoveredNode):
    """Algorithm 1 online. Feed :meth:`on_odometry` and :meth:`on_sweep`; call :meth:`update`.

    The subroutines are inherited from the modules of :mod:`coverage_pkg.paper`; this class
    keeps the inputs, the event log and the main loop.

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
        self.retraced = 0.0                        # m of 'gvd' driven back along traced edges
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
        self._gvd_mins = []                        # the closest distinct obstacles
        self._prev_d, self._near_echo, self._meet_cand = None, None, None
        self._passed_cand = None                   # a meet point just beyond delta
        self._meet_touch = {}                      # meet event -> (its obstacles' points,
        #                                            where it was sensed); meet_own_obstacles
        self._meet_new = None                      # (rho, where) of a meet being sensed
        self._hist, self.stuck_count, self.given_up = [], 0, []
        self.update_times = []
        self.last = {}                             # no decomposed map (the node's markers)
        self._cusp_dir = None                      # bearing into the narrow cell, this cusp
        self._cusp_dirs = {}                       # cusp (x, y) of an edge -> that bearing
        self._cusp_meets = set()                   # (narrow node, cusp) read as meet points
        self._cusp_meets_ev = set()                # ... and the meet events they made
        self._law = None                           # this transit step's control law:
        #                                            'gvd' along a traced GVD edge,
        #                                            'boundary' along a wall at D = delta
        self.gvd_trace = {}                        # points of traced GVD edges, by 1 m bucket:
        #                                            (x, y, sweep, heading x, heading y,
        #                                            node, start of the tracing branch)
        self._gvd_last = None

    def on_odometry(self, t: float, x: float, y: float, yaw: float) -> None:
        """Robot pose in the odom frame at sim time t."""
        if all(math.isfinite(v) for v in (t, x, y, yaw)):
            kind = self._law if self.mode == 'transit' and self._law else self.mode
            if self.pose is not None and kind:
                step = math.dist(self.pose[:2], (x, y))
                if kind == 'gvd' and self.mode == 'transit':
                    self.retraced += step          # a traced GVD edge followed back
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
        self._gvd_mins = None
        prev, self.D = self.D, float(np.nanmin(r))
        self.paths.add(self.pose[0], self.pose[1], self.D)
        self._scan_sweep()
        if self.mode == 'gvd' and (self._gvd_last is None or
                                   math.dist(self._gvd_last, self.pose[:2]) > 0.2):
            head = self.task.get('heading') or (0.0, 0.0)
            self._gvd_last = self.pose[:2]
            key = (int(self.pose[0] // 1.0), int(self.pose[1] // 1.0))
            br = self.task.get('branch')
            self.gvd_trace.setdefault(key, []).append((*self.pose[:2], self.sweeps,
                                                       float(head[0]), float(head[1]),
                                                       self.current,
                                                       None if br is None else
                                                       tuple(br.start)))
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

    @property
    def gvd_mins(self) -> list[tuple[float, float]]:
        """The closest distinct obstacles of this sweep (:func:`coverage_pkg.gvd.
        distinct_minima`), for GVD following; computed when first asked for."""
        if self._gvd_mins is None:
            rr = np.where(np.isfinite(self.ranges), self.ranges, np.inf)
            self._gvd_mins = gvdmod.distinct_minima(rr, self.angles)
        return self._gvd_mins

    def echo(self, direction: float, cone: float = None) -> float:
        """Nearest echo within ``cone`` of the world bearing ``direction`` (max range if none)."""
        diff = np.abs(np.remainder(self.angles - direction + math.pi, 2 * math.pi) - math.pi)
        sel = (diff <= (cone or self.cfg.cone)) & np.isfinite(self.ranges)
        return float(self.ranges[sel].min()) if sel.any() else self.max_range

    def _record(self, t, kind, xy, detail):
        self.events.append((round(float(t), 3), kind, round(float(xy[0]), 3),
                            round(float(xy[1]), 3), detail))
        return len(self.events) - 1

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
            d = self._start_D() if self.cfg.start_on_gvd else self.D
            self.current = self.create_node('vast' if d > self.det else 'narrow',
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
                self.cfg.access_time or not self.mins or self._second_closest() is not None:
            return None
        a = self.mins[0][1]
        return -np.array([math.cos(a), math.sin(a)]) * self.cfg.max_speed

    def _second_closest(self):
        """The range of a second closest obstacle as near as the closest (within 2
        ``event_tolerance``, over 60 degrees away): the robot stands beside the GVD between
        them. None where there is none."""
        d1, a = self.mins[0]
        return next((d for d, b in self.mins[1:] if d - d1 < 2 * self.cfg.event_tolerance and
                     abs(math.remainder(a - b, 2 * math.pi)) > math.radians(60)), None)

    def _start_D(self):
        """D(x) for CreateNode at the start with ``start_on_gvd`` (ours). Where the access
        ended beside the GVD (:meth:`_second_closest`, :meth:`_access`), the robot stands up
        to ``event_tolerance`` short of the GVD and D there is the mean of the two echoes: the
        start node is vast where the GVD beside it lies beyond delta (a hall just over 2 delta
        wide), as a trace entering that hall from elsewhere would find by D crossing delta
        (:meth:`_sense_cusp`)."""
        if self.D > self.det or not self.mins:
            return self.D
        d2 = self._second_closest()
        return self.D if d2 is None else (self.mins[0][0] + d2) / 2

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

    def status(self) -> dict:
        """A compact, JSON-friendly status (published by the node)."""
        return {'state': self.state, 'current_node': self.current, 'sweeps': self.sweeps,
                'nodes': len(self.nodes),
                'uncovered': [n.id for n in self.nodes if not n.covered],
                'given_up': sorted(set(self.given_up)), 'mode': self.mode,
                'last_event': list(self.events[-1]) if self.events else None}

    def primitive_lengths(self) -> dict:
        """Path length per primitive (lap, boundary, gvd, transit)."""
        return primitive_lengths(self.segments)

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
