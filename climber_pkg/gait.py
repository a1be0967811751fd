"""Climbing gait and kinematics control algorithm (Almonacid et al. 2003, section IV-E).

A pure-Python state machine (no ROS) fed with observations (encoder lengths, clamp states,
ultrasonic distances, time) that returns actions (clamp commands, leg length commands, planned
poses, status). The planner node is only its adapter. Steps of the paper's Fig. 7:

1. one ring is clamped (the reference); the other ring's clamp is released; the encoder lengths
   and the forward kinematics give the robot configuration (the leg-length Newton solve of
   :func:`paramotion.gough_stewart.forward_kinematics` on the platform's 7 coordinates, which
   gives the pose of the paper's 49-coordinate system, :mod:`climber_pkg.constraint_fk`);
2. the moving ring's three ultrasonic distances give (dx, dy) by the correction function;
3. the prediction function (6)-(8) gives the next planned pose of the moving ring, Delta further
   along its axis;
4. the inverse kinematics (2)-(3) give the leg lengths C_i;
5. the lengths are commanded; steps 2-5 repeat until the next planned pose (Delta further)
   would take an actuator within ``stroke_margin`` of either stroke end (a look-ahead in place
   of the paper's ``L_max - max C <= Delta`` on the lengths reached) or to a near-singular
   configuration (Jacobian condition above a threshold);
6. the moving ring is clamped and, once its clamp is *confirmed* closed, the other ring is
   released: it becomes the moving ring. Steps 1-6 repeat until the top (every echo of the
   leading ring lost together above a structure the other ring still senses), ``n_cycles``
   cycles, or a refusal. Losing the structure otherwise (echoes lost off-centre, or below
   nothing sensed) is a fault of its own, state ``lost_structure``.

Ablations (``GaitParams.without``): ``correction`` drops eq. (5)'s deviation, ``prediction``
keeps the ring's orientation (eqs. (7)-(8) off) and steps it along its own axis; with both off
the robot is blind. ``GaitParams.approach``: ``paper`` is eq. (7) verbatim, ``centres`` (ours,
the default) aims along the secant of the sensed structure centres.

Safety invariant (enforced in one place, :meth:`ClimbingGait._release`): a clamp is released
only while the other clamp is confirmed closed; so at every instant at least one clamp holds.
Any fault (invalid sensor data for too long, an unreachable or near-singular predicted pose at
the start of a semicycle, encoders not reaching the command, NaN encoders, a trunk thicker than
the bore, a ring too close to the trunk) stops the gait in a safe state: the legs hold their
lengths, the clamped ring stays clamped, no clamp is released.

Frames: poses are estimated in ``odom``, the initial frame of ring 1 (the planner never sees the
world frame). Ring 1 is the base of the Gough-Stewart kinematics (universal joints), ring 2 the
platform; the kinematics always take ring 2's pose in ring 1's frame.
"""
from __future__ import annotations

import enum
import math
from collections.abc import Iterable
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike

from climber_pkg.correction import SensorDataError, correction
from climber_pkg.prediction import (
    PredictionError,
    limit_correction,
    measured_centre,
    predict_pose,
    rotate_about_axis,
)
from paramotion import gough_stewart as gs
from paramotion.errors import UserError

RING1, RING2 = 0, 1
RING_NAMES = ('ring1', 'ring2')


class State(enum.Enum):
    WAIT_START = 'wait_start'      # waiting for encoders and clamp states
    RELEASE = 'release'            # step 1: moving ring's clamp opening
    PLAN = 'plan'                  # steps 2-4: waiting for fresh sensor data, then planning
    MOVE = 'move'                  # step 5: actuators moving to the commanded lengths
    CLAMP = 'clamp'                # step 6: moving ring's clamp closing
    DONE = 'done'
    REFUSED = 'refused'
    LOST = 'lost_structure'        # fault: the moving ring no longer senses the structure


#: Constructs of the paper that ``GaitParams.without`` can switch off (ablations).
CONSTRUCTS = ('correction', 'prediction')
#: Approach vectors of the prediction: eq. (7) as printed, or the secant of measured centres.
APPROACHES = ('paper', 'centres')


def parse_without(value: str | Iterable[str] | None, name: str = 'without') -> tuple[str, ...]:
    """Constructs to switch off, from 'a,b' or a list of names; UserError names a bad one."""
    items = value.split(',') if isinstance(value, str) else list(value or ())
    names = sorted({str(x).strip() for x in items if str(x).strip()})
    for item in names:
        if item not in CONSTRUCTS:
            raise UserError(f'{name} {item}: unknown construct; known: {", ".join(CONSTRUCTS)}')
    return tuple(names)


@dataclass(frozen=True)
class GaitParams:
    """Inputs of the control algorithm (section IV-C) and its safety limits."""

    delta: float = 0.10                 # displacement per step along the ring axis, m
    delta_min: float = 0.05             # smallest step when adapting to curvature, m
    adaptive_delta: bool = True         # shrink Delta where the structure bends
    max_turn_per_step: float = math.radians(4.0)  # direction change per step allowed, rad
    n_cycles: int = 0                   # 0: until the end of the structure
    mode: str = 'climb'                 # 'climb', 'descend' or 'turn'
    turn_angle: float = 0.0             # rad, for mode 'turn' (sign gives the direction)
    turn_step: float = math.radians(15.0)  # rotation per semicycle when turning, rad
    max_condition: float = 30.0         # near-singular threshold for the gait (< FK's limit)
    stroke_margin: float = 0.005        # keep this far from the stroke ends, m
    max_relative_tilt: float = math.radians(25.0)  # ring-to-ring tilt limit, rad
    max_correction_tilt: float = math.radians(12.0)  # tilt a single correction may cause
    approach: str = 'centres'           # eq. (7) approach vector: 'centres' or 'paper'
    without: tuple[str, ...] = ()       # constructs switched off: 'correction', 'prediction'
    edge_tolerance: float = 0.02        # partial echo loss counts as the top edge within this
    max_edge_steps: int = 2             # blind steps allowed across the top edge
    secant_baseline: float = 0.09       # shortest centre-to-centre secant for 'centres', m
    min_clearance: float = 0.015        # refuse when a sensor sees the trunk closer, m
    bore_margin: float = 0.03           # trunk must be this much thinner than the bore, m
    length_tolerance: float = 0.002     # encoder-to-command agreement that ends a move, m
    settle_time: float = 0.2            # wait after the move before trusting sensors, s
    sensor_timeout: float = 2.0         # longest wait for a valid triplet, s
    no_echo_time: float = 0.5           # persistent +inf on a leading ring = structure end, s
    clamp_timeout: float = 3.0          # longest wait for a clamp confirmation, s
    clamp_state_max_age: float = 1.0    # a clamp state older than this confirms nothing, s
    move_timeout: float = 3.0           # extra time allowed beyond the planned move, s
    stall_gap: float = 0.5              # ticks further apart than this: planner not running, s
    leg_speed: float = 0.10             # actuator speed used to time moves, m/s

    def __post_init__(self):
        if isinstance(self.without, str):
            object.__setattr__(self, 'without', (self.without,) if self.without else ())
        object.__setattr__(self, 'without', tuple(sorted(set(self.without))))

    def validate(self) -> GaitParams:
        """Raise ValueError naming the first inconsistent parameter."""
        checks = [
            ('delta', 0.0 < self.delta <= 1.0, '(0, 1] m'),
            ('delta_min', 0.0 < self.delta_min <= self.delta, '(0, delta]'),
            ('n_cycles', self.n_cycles >= 0, '>= 0'),
            ('mode', self.mode in ('climb', 'descend', 'turn'), 'climb|descend|turn'),
            ('approach', self.approach in APPROACHES, '|'.join(APPROACHES)),
            ('without', all(w in CONSTRUCTS for w in self.without), '|'.join(CONSTRUCTS)),
            ('turn_step', 0.0 < self.turn_step <= math.radians(45), '(0, 45] deg'),
            ('max_condition', 1.0 < self.max_condition <= gs.DEFAULT_MAX_CONDITION,
             f'(1, {gs.DEFAULT_MAX_CONDITION}]'),
            ('leg_speed', self.leg_speed > 0, '> 0'),
            ('length_tolerance', self.length_tolerance > 0, '> 0'),
            ('stall_gap', self.stall_gap > 0, '> 0'),
        ]
        for name, ok, allowed in checks:
            if not ok:
                raise ValueError(f'gait parameter {name}={getattr(self, name)!r} outside '
                                 f'{allowed}')
        return self


@dataclass
class ClampCommand:
    ring: int
    close: bool


@dataclass
class LegCommand:
    lengths: np.ndarray
    duration: float


@dataclass
class PlannedPose:
    ring: int
    position: np.ndarray
    rotation: np.ndarray


@dataclass
class StatusUpdate:
    state: str
    message: str
    ok: bool
    values: dict[str, object] = field(default_factory=dict)


@dataclass
class StepRecord:
    """One executed prediction step (for the path, markers and evaluation)."""

    cycle: int
    semicycle: int
    ring: int
    dx: float
    dy: float
    radius: float
    delta: float
    condition: float
    position: np.ndarray


#: Everything :meth:`ClimbingGait.tick` can ask the adapter to execute.
Action = ClampCommand | LegCommand | PlannedPose | StatusUpdate



def _inv(p, r):
    return -r.T @ p, r.T


def _compose(p1, r1, p2, r2):
    return p1 + r1 @ p2, r1 @ r2


class ClimbingGait:
    """Event-driven implementation of steps 1-6; see the module docstring."""

    def __init__(self, geometry: gs.GoughStewartGeometry, sensor_mount_radius: float,
                 sensor_angles: Iterable[float], sensor_min_range: float,
                 sensor_max_range: float, bore_radius: float,
                 params: GaitParams | None = None) -> None:
        self.geom = geometry
        self.mount = float(sensor_mount_radius)
        self.angles = tuple(sensor_angles)
        self.range_min = float(sensor_min_range)
        self.range_max = float(sensor_max_range)
        self.bore = float(bore_radius)
        self.p = (params or GaitParams()).validate()
        self.state = State.WAIT_START
        self.reason = ''
        self.cycle = 0                 # completed cycles
        self.semicycle = 0             # completed semicycles
        self.steps_in_semicycle = 0
        self.steps = []                # StepRecord list
        self.turned = 0.0              # rotation achieved by the last moved ring, rad
        # Observations.
        self.lengths = None
        self.lengths_time = -math.inf
        self.clamp_closed = [None, None]
        self.clamp_time = [-math.inf, -math.inf]
        self.ranges = [[[] for _ in range(3)] for _ in range(2)]   # (t, value) per sensor
        # Estimates in odom: ring poses (position, rotation).
        self.pose = [None, None]
        self.fixed = RING1
        self.moving = RING2
        self._deadline = math.inf
        self._last_tick = None
        self._since = 0.0
        self._target = None
        self._planned_rel = None
        self._prev_direction = [None, None]
        self._last_radius = None
        self._edge_steps = 0
        self._last_deviation = [None, None]   # |(dx, dy)| of each ring's latest correction
        self._turn_left = 0.0
        self._pending = []
        self._pending_pose = None
        self._centres = [[], []]         # measured structure centres per ring (odom)
        self.centre_log = []             # every measured structure centre (odom), for markers
        self.measure_log = []            # (t, ring) of every correction taken (evaluation)

    # ------------------------------------------------------------------ observations
    def update_encoders(self, t: float, lengths: ArrayLike) -> None:
        self.lengths = np.asarray(lengths, dtype=float).reshape(6).copy()
        self.lengths_time = t

    def update_clamp(self, t: float, ring: int, closed: bool) -> None:
        self.clamp_closed[ring] = bool(closed)
        self.clamp_time[ring] = t

    def update_range(self, t: float, ring: int, index: int, value: float) -> None:
        buf = self.ranges[ring][index]
        buf.append((t, float(value)))
        if len(buf) > 200:
            del buf[:100]

    # ------------------------------------------------------------------ helpers
    @property
    def finished(self) -> bool:
        return self.state in (State.DONE, State.REFUSED, State.LOST)

    @property
    def leading_ring(self) -> int:
        """The ring that goes first into unknown structure (upper when climbing)."""
        return RING1 if self.p.mode == 'descend' else RING2

    def _emit(self, action):
        self._pending.append(action)

    def _status(self, ok=True, message=''):
        self._emit(StatusUpdate(self.state.value, message or self.reason, ok, {
            'cycle': self.cycle, 'semicycle': self.semicycle,
            'fixed': RING_NAMES[self.fixed], 'moving': RING_NAMES[self.moving],
            'steps': len(self.steps)}))

    def _refuse(self, reason):
        """Stop safely: hold the legs, keep every closed clamp closed, release nothing."""
        self.state = State.REFUSED
        self.reason = reason
        if self.lengths is not None and np.all(np.isfinite(self.lengths)):
            self._emit(LegCommand(self.lengths.copy(), 0.0))
        self._status(ok=False)

    def _done(self, reason):
        self.state = State.DONE
        self.reason = reason
        self._status(ok=True)

    def _release(self, ring, t):
        """The only place a clamp is opened: only while the other one is confirmed closed."""
        other = 1 - ring
        if self.clamp_closed[other] is not True:
            self._refuse(f'refusing to release the {RING_NAMES[ring]} clamp: the '
                         f'{RING_NAMES[other]} clamp is not confirmed closed')
            return False
        age = t - self.clamp_time[other]
        if not age <= self.p.clamp_state_max_age:
            self._refuse(f'refusing to release the {RING_NAMES[ring]} clamp: the last '
                         f'{RING_NAMES[other]} clamp state is {age:.2f} s old '
                         f'(> {self.p.clamp_state_max_age} s)')
            return False
        self._emit(ClampCommand(ring, close=False))
        self.state = State.RELEASE
        self._deadline = t + self.p.clamp_timeout
        return True

    def _relative(self):
        """Ring 2's pose in ring 1's frame from the current estimates."""
        p1, r1 = self.pose[RING1]
        p2, r2 = self.pose[RING2]
        ip, ir = _inv(p1, r1)
        return _compose(ip, ir, p2, r2)

    def _fresh_triplet(self, ring, since, t):
        """Latest valid reading per sensor newer than ``since``; or a reason why not.

        Returns (values, problems, lost): the valid readings, a text per sensor without one,
        and the indices of the sensors whose every reading since ``since`` is "no echo"
        (+inf) for at least ``no_echo_time``.
        """
        values, problems, lost = [], [], []
        for k in range(3):
            recent = [(ts, v) for ts, v in self.ranges[ring][k] if ts >= since]
            valid = [v for _, v in recent
                     if math.isfinite(v) and self.range_min <= v <= self.range_max]
            if valid:
                values.append(valid[-1])
                continue
            if recent and all(v == math.inf for _, v in recent) \
                    and recent[-1][0] - recent[0][0] >= self.p.no_echo_time:
                lost.append(k)
            last = f'{recent[-1][1]!r}' if recent else 'no reading'
            problems.append(f'{RING_NAMES[ring]} ultrasonic {k}: {last}')
        return values, problems, lost

    def _senses_structure(self, ring, t):
        """True when every sensor of ``ring`` gave a valid echo within ``no_echo_time``."""
        since = t - self.p.no_echo_time - 1e-9
        return all(any(ts >= since and math.isfinite(v) and self.range_min <= v <= self.range_max
                       for ts, v in self.ranges[ring][k]) for k in range(3))

    def _echo_loss(self, t, ring, values, lost):
        """Leading ring lost echoes: the end of the structure, the top edge, or a drift.

        * all three echoes lost together, the leading ring centred (within ``edge_tolerance``)
          at its previous measurement, and the clamped ring still sensing the structure below:
          the end of the structure (done);
        * some lost and the remaining ones read what a centred ring on the last measured radius
          reads (within ``edge_tolerance``): the sensor plane crosses the top edge obliquely;
          step once more along the ring's own axis (at most ``max_edge_steps`` times);
        * anything else (all lost with nothing sensed below, or the remaining echoes off-centre,
          or more edge steps needed): the robot has drifted off the structure (fault).
        """
        names = ', '.join(str(k) for k in lost)
        other = 1 - ring
        if len(lost) == 3:
            last = self._last_deviation[ring]
            if last is None or last > self.p.edge_tolerance:
                seen = 'never measured' if last is None else f'{last * 1000:.0f} mm off-centre'
                self._lose(f'no echo from the 3 ultrasonic sensors of the {RING_NAMES[ring]}, '
                           f'which was {seen} at its previous measurement')
            elif self._senses_structure(other, t):
                self._end_semicycle(t, end_of_structure=(
                    f'no echo from the 3 ultrasonic sensors of the leading {RING_NAMES[ring]} '
                    f'above a structure the {RING_NAMES[other]} still senses: end of the '
                    'structure reached'))
            else:
                self._lose(f'no echo from the 3 ultrasonic sensors of the {RING_NAMES[ring]} '
                           f'and the {RING_NAMES[other]} does not sense the structure either')
            return
        if len(lost) + len(values) < 3:
            return                        # other sensors not valid yet: keep waiting
        expected = self.mount - (self._last_radius or 0.0)
        off = max(abs(v - expected) for v in values)
        if self._last_radius is None or off > self.p.edge_tolerance:
            self._lose(f'{RING_NAMES[ring]} ultrasonic {names}: no echo while the others read '
                       f'{off * 1000:.0f} mm off a centred ring (tolerance '
                       f'{self.p.edge_tolerance * 1000:.0f} mm): drifted off the structure')
            return
        if self._edge_steps >= self.p.max_edge_steps:
            self._lose(f'{RING_NAMES[ring]} ultrasonic {names}: no echo after '
                       f'{self._edge_steps} steps across the top edge: drifted off the structure')
            return
        self._edge_steps += 1
        if self._pose_from_encoders(*self._relative()) is not None:
            self._plan_step(t, None)

    def _lose(self, reason):
        """Fault: the structure is lost. Stop safely exactly like a refusal, in its own state."""
        self._refuse(f'lost the structure: {reason}')
        self.state = State.LOST
        self._pending[-1].state = self.state.value

    # ------------------------------------------------------------------ main entry
    def tick(self, t: float) -> list[Action]:

        """Advance the state machine at time t (s); returns the actions to execute.

        Ticks further apart than ``stall_gap`` mean the planner did not run in between (a
        process starved of CPU catching up on ``/clock``, the rest of its inputs still queued
        behind): that gap is not counted against the deadline of what it waits for, which
        would otherwise expire on the first tick after the gap, before the confirmation it
        waits for is read. Ticks at the planner's rate (and every lock-step run) never shift
        it.
        """
        self._pending = []
        if self._last_tick is not None and t - self._last_tick > self.p.stall_gap:
            self._deadline += t - self._last_tick
        self._last_tick = t
        if self.finished:
            return []
        if self.lengths is not None and not np.all(np.isfinite(self.lengths)):
            self._refuse(f'encoder lengths are not finite: {self.lengths}')
            return self._pending
        handler = {
            State.WAIT_START: self._tick_start, State.RELEASE: self._tick_release,
            State.PLAN: self._tick_plan, State.MOVE: self._tick_move,
            State.CLAMP: self._tick_clamp}[self.state]
        handler(t)
        return self._pending

    def _tick_start(self, t):
        if self.lengths is None or None in self.clamp_closed:
            return
        if not any(self.clamp_closed):
            self._refuse('no clamp is closed at start: the robot must be mounted with at '
                         'least one ring clamped')
            return
        # Step 1: reference = ring 1 at the odom origin; ring 2 from FK of the encoders.
        guess_h = math.sqrt(max(np.mean(self.lengths) ** 2
                                - self._chord() ** 2, 1e-4))
        try:
            fk = gs.forward_kinematics(self.geom, self.lengths, [0, 0, guess_h], np.eye(3),
                                       max_condition=self.p.max_condition)
        except (gs.SingularPoseError, gs.UnreachablePoseError) as exc:
            self._refuse(f'initial configuration rejected: {exc}')
            return
        if not fk.converged:
            self._refuse('initial forward kinematics did not converge')
            return
        self.pose[RING1] = (np.zeros(3), np.eye(3))
        self.pose[RING2] = (fk.position, fk.rotation)
        self._turn_left = self.p.turn_angle if self.p.mode == 'turn' else 0.0
        # Climbing: ring 1 holds and ring 2 moves first; descending: the mirror.
        self.moving = RING1 if self.p.mode == 'descend' else RING2
        self.fixed = 1 - self.moving
        for ring in (RING1, RING2):
            self._emit(PlannedPose(ring, *self.pose[ring]))
        self._start_semicycle(t)

    def _chord(self):
        b = self.geom.base_anchors[0]
        p = self.geom.platform_anchors[0]
        return float(np.hypot(*(p[:2] - b[:2])))

    def _start_semicycle(self, t):
        self.steps_in_semicycle = 0
        if self.clamp_closed[self.fixed] is not True:
            # The reference ring must hold first (it was just commanded closed).
            self._refuse(f'{RING_NAMES[self.fixed]} clamp not confirmed closed at the start '
                         f'of a semicycle')
            return
        if self.clamp_closed[self.moving]:
            if not self._release(self.moving, t):
                return
        else:
            self.state = State.RELEASE
            self._deadline = t + self.p.clamp_timeout
        self._status()

    def _tick_release(self, t):
        if self.clamp_closed[self.moving] is False:
            self.state = State.PLAN
            self._since = t + self.p.settle_time
            self._deadline = self._since + self.p.sensor_timeout
            self._status()
        elif t > self._deadline:
            self._refuse(f'{RING_NAMES[self.moving]} clamp did not confirm release within '
                         f'{self.p.clamp_timeout} s')

    def _tick_plan(self, t):
        if t < self._since:
            return
        ring = self.moving
        values, problems, lost = self._fresh_triplet(ring, self._since, t)
        too_close = [k for k in range(3)
                     if any(v == -math.inf for ts, v in self.ranges[ring][k] if ts >= self._since)]
        if too_close:
            self._refuse(f'{RING_NAMES[ring]} ultrasonic {too_close[0]} reports the structure '
                         'too close (-inf): ring about to touch it')
            return
        if problems:
            if lost and ring == self.leading_ring and self.p.mode != 'turn':
                self._echo_loss(t, ring, values, lost)
                if self.state is not State.PLAN:
                    return
            if t > self._deadline:
                self._refuse('no valid ultrasonic data for '
                             f'{self.p.sensor_timeout} s: ' + '; '.join(problems))
            return
        try:
            corr = correction(values, self.mount, self.angles, self.range_min, self.range_max)
        except SensorDataError as exc:
            if t > self._deadline:
                self._refuse(f'{RING_NAMES[ring]} correction failed: {exc}')
            return
        if corr.radius > self.bore - self.p.bore_margin:
            self._refuse(f'measured structure radius {corr.radius:.3f} m does not fit the '
                         f'{self.bore:.3f} m ring bore with a {self.p.bore_margin} m margin')
            return
        if min(values) < self.p.min_clearance:
            self._refuse(f'{RING_NAMES[ring]} is {min(values):.3f} m from the structure, '
                         f'closer than min_clearance={self.p.min_clearance} m')
            return
        self._last_radius = corr.radius
        self._last_deviation[ring] = math.hypot(corr.dx, corr.dy)
        if ring == self.leading_ring:
            self._edge_steps = 0
        # The ring has settled since the move ended: refresh its pose from the encoders so
        # that the correction (measured now) and the pose it is applied to agree.
        if self._pose_from_encoders(*self._relative()) is None:
            return
        self.measure_log.append((t, ring))
        pos, rot = self.pose[ring]
        self._centres[ring].append(measured_centre(pos, rot, corr.dx, corr.dy))
        self.centre_log.append(self._centres[ring][-1])
        del self._centres[ring][:-20]
        self._plan_step(t, corr)

    def _previous_centre(self, ring, centre, axis, delta):
        """Structure centre measured one step back, for the secant approach vector.

        The moving ring's own latest centre at least ``secant_baseline`` back along the motion
        (a shorter secant would amplify the measurement noise into tilt); failing that, the
        other ring's latest centre; None if neither exists (then eq. (7) as printed: the
        approach vector along the displacement).
        """
        sign = math.copysign(1.0, delta)
        for cand in reversed(self._centres[ring][:-1]):
            if (centre - cand) @ axis * sign >= self.p.secant_baseline:
                return cand
        if self._centres[1 - ring]:
            cand = self._centres[1 - ring][-1]
            if (centre - cand) @ axis * sign >= self.p.secant_baseline:
                return cand
        return None

    def _step_delta(self, ring):
        """Delta for the next step, shrunk where the sensed direction changes fast."""
        delta = self.p.delta
        if self.p.adaptive_delta and len(self.steps) >= 2:
            prev = [s for s in self.steps if s.ring == ring][-3:]
            if len(prev) >= 3:
                a1 = prev[-2].position - prev[-3].position
                a2 = prev[-1].position - prev[-2].position
                n1, n2 = np.linalg.norm(a1), np.linalg.norm(a2)
                if n1 > 1e-6 and n2 > 1e-6:
                    ang = math.acos(float(np.clip(a1 @ a2 / (n1 * n2), -1, 1)))
                    curvature = ang / n2
                    if curvature * delta > self.p.max_turn_per_step:
                        delta = max(self.p.delta_min, self.p.max_turn_per_step / curvature)
        return -delta if self.p.mode == 'descend' else delta

    def _plan_step(self, t, corr):
        ring = self.moving
        pos, rot = self.pose[ring]
        if self.p.mode == 'turn':
            angle = math.copysign(min(abs(self._turn_left), self.p.turn_step), self._turn_left)
            if self.moving == RING1:
                angle = self.turned       # ring 1 catches up with ring 2
            if abs(angle) < 1e-9:
                self._end_semicycle(t)
                return
            new_p = pos + rot @ np.array([corr.dx, corr.dy, 0.0])
            new_r = rotate_about_axis(rot, angle)
            delta = 0.0
        else:
            delta = self._step_delta(ring)
            new_p, new_r = self._predict(pos, rot, corr, delta)
            if new_p is None:
                return
        old = self.pose[ring]
        self.pose[ring] = (new_p, new_r)
        rel_p, rel_r = self._relative()
        self.pose[ring] = old
        reason = self._limit_reason(rel_p, rel_r)
        if reason is not None:
            if self.steps_in_semicycle == 0:
                self._refuse(f'{RING_NAMES[ring]} cannot make a single step: {reason} '
                             '(structure curvature or shape beyond what the legs can follow)')
            else:
                self._end_semicycle(t)
            return
        lengths, cond = self._ik(rel_p, rel_r)
        self._planned_rel = (rel_p, rel_r)
        self._target = lengths
        self._pending_pose = (new_p, new_r, corr, delta, cond)
        duration = float(np.max(np.abs(lengths - self.lengths))) / self.p.leg_speed
        duration = max(duration, 0.05)
        self._emit(LegCommand(lengths, duration))
        self._emit(PlannedPose(ring, new_p, new_r))
        self.state = State.MOVE
        self._deadline = t + duration + self.p.move_timeout

    def _predict(self, pos, rot, corr, delta):
        """Steps 2-3: the moving ring's next pose from the correction (None: top-edge step).

        ``without`` switches the paper's constructs off: 'correction' drops eq. (5)'s deviation
        (and with it the measured centres the 'centres' approach aims along); 'prediction'
        keeps the ring's orientation and steps it along its own axis, re-centred in its plane
        by the correction (eqs. (7)-(8) off). Both off: a blind robot following its own axis.
        """
        off = self.p.without
        dx, dy = (0.0, 0.0) if corr is None or 'correction' in off else (corr.dx, corr.dy)
        dx, dy = limit_correction(dx, dy, delta, self.p.max_correction_tilt)
        if 'prediction' in off or corr is None:
            return pos + rot @ np.array([dx, dy, delta]), rot.copy()
        prev_centre = None
        if self.p.approach == 'centres' and 'correction' not in off:
            prev_centre = self._previous_centre(self.moving, measured_centre(pos, rot, dx, dy),
                                                rot[:, 2], delta)
        try:
            return predict_pose(pos, rot, dx, dy, delta, prev_centre)
        except PredictionError as exc:
            self._refuse(f'prediction failed: {exc}')
            return None, None

    def _ik(self, rel_p, rel_r):
        lengths = gs.inverse_kinematics(self.geom, rel_p, rel_r)
        cond = float(gs.jacobian_condition(self.geom, gs.jacobian(self.geom, rel_p, rel_r)))
        return lengths, cond

    def _limit_reason(self, rel_p, rel_r):
        """Step 5's end-of-semicycle test on the next planned relative pose, or None if fine:
        a leg within ``stroke_margin`` of a stroke end, a near-singular configuration, the
        rings tilted apart or crossing."""
        lengths, cond = self._ik(rel_p, rel_r)
        lo = self.geom.leg_min + self.p.stroke_margin
        hi = self.geom.leg_max - self.p.stroke_margin
        if not np.all(np.isfinite(lengths)):
            return 'non-finite leg lengths'
        if lengths.max() > hi:
            k = int(lengths.argmax())
            return f'leg {k + 1} would reach {lengths[k]:.4f} m > {hi:.4f} m'
        if lengths.min() < lo:
            k = int(lengths.argmin())
            return f'leg {k + 1} would reach {lengths[k]:.4f} m < {lo:.4f} m'
        if not cond <= self.p.max_condition:
            return f'near-singular configuration (Jacobian condition {cond:.1f} > ' \
                   f'{self.p.max_condition})'
        tilt = math.acos(float(np.clip(rel_r[2, 2], -1, 1)))
        if tilt > self.p.max_relative_tilt:
            return f'ring-to-ring tilt {math.degrees(tilt):.1f} deg > ' \
                   f'{math.degrees(self.p.max_relative_tilt):.1f} deg'
        if rel_p[2] <= 0:
            return 'rings would cross'
        return None

    def _tick_move(self, t):
        if self.lengths_time < 0 or self._target is None:
            return
        err = float(np.max(np.abs(self.lengths - self._target)))
        if err <= self.p.length_tolerance:
            self._finish_move(t)
        elif t > self._deadline:
            self._refuse(f'actuators did not reach the command: max error {err:.4f} m after '
                         f'{self.p.move_timeout} s extra')

    def _pose_from_encoders(self, guess_p, guess_r):
        """Step 1 / after each move: FK of the encoder lengths, warm-started from the guess
        (ring 2 in ring 1's frame); updates the moving ring's estimate. None after a refusal."""
        try:
            fk = gs.forward_kinematics(self.geom, self.lengths, guess_p, guess_r)
        except (gs.SingularPoseError, gs.UnreachablePoseError) as exc:
            self._refuse(f'forward kinematics from encoders failed: {exc}')
            return None
        if not fk.converged:
            self._refuse('forward kinematics from encoders did not converge')
            return None
        p1, r1 = self.pose[RING1]
        p2, r2 = self.pose[RING2]
        if self.moving == RING2:
            self.pose[RING2] = _compose(p1, r1, fk.position, fk.rotation)
        else:
            ip, ir = _inv(fk.position, fk.rotation)
            self.pose[RING1] = _compose(p2, r2, ip, ir)
        return fk

    def _finish_move(self, t):
        """Forward kinematics from the encoders: the moved ring's new estimated pose."""
        fk = self._pose_from_encoders(*self._planned_rel)
        if fk is None:
            return
        new_p, new_r, corr, delta, cond = self._pending_pose
        dx, dy, radius = (corr.dx, corr.dy, corr.radius) if corr is not None else (
            math.nan, math.nan, math.nan)
        self.steps.append(StepRecord(self.cycle, self.semicycle, self.moving, dx, dy,
                                     radius, delta, fk.jacobian_condition,
                                     self.pose[self.moving][0].copy()))
        self.steps_in_semicycle += 1
        if self.p.mode == 'turn':
            # One rotation step per ring and semicycle.
            if self.moving == RING2:
                step = math.copysign(min(abs(self._turn_left), self.p.turn_step),
                                     self._turn_left)
                self.turned = step
            self._end_semicycle(t)
            return
        self.state = State.PLAN
        self._since = t + self.p.settle_time
        self._deadline = self._since + self.p.sensor_timeout

    def _end_semicycle(self, t, end_of_structure=None):
        """Step 6: clamp the moving ring (or stop at the end of the structure)."""
        if end_of_structure is not None:
            # The leading ring has left the structure: it cannot clamp there. Stop with the
            # other ring holding (it is clamped: the semicycle started only once it was).
            self._done(end_of_structure)
            return
        self._emit(ClampCommand(self.moving, close=True))
        self.state = State.CLAMP
        self._deadline = t + self.p.clamp_timeout
        self._status()

    def _tick_clamp(self, t):
        if self.clamp_closed[self.moving] is True and self.clamp_time[self.moving] >= 0:
            self.semicycle += 1
            if self.p.mode == 'turn' and self.moving == RING1:
                self._turn_left -= self.turned
                self.turned = 0.0
            if self.semicycle % 2 == 0:
                self.cycle += 1
            if self.p.mode == 'turn' and abs(self._turn_left) < 1e-9 and self.moving == RING1:
                self._done(f'turned {math.degrees(self.p.turn_angle):.1f} deg around the '
                           'structure')
                return
            if self.p.n_cycles and self.cycle >= self.p.n_cycles and self.semicycle % 2 == 0:
                self._done(f'{self.cycle} cycles completed')
                return
            self.fixed, self.moving = self.moving, self.fixed
            self._start_semicycle(t)
        elif t > self._deadline:
            self._refuse(f'{RING_NAMES[self.moving]} clamp did not confirm closing within '
                         f'{self.p.clamp_timeout} s')
