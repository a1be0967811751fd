"""Ideal kinematic stand-in for the climbing robot (no dynamics), for tests and quick studies.

The clamped ring stays where it is; a leg command moves the free ring exactly to the pose whose
inverse kinematics are the commanded lengths (forward kinematics of the shared module), after
the command's duration. Clamps close/open after configurable delays. Ultrasonic distances are
ray casts against the true structure, with optional noise and dropouts. This is what the
PyBullet node does with a dynamic closed chain; here it is instantaneous and exact, so planner
logic can be exercised on many structures in seconds.
"""
from __future__ import annotations

import math
from collections.abc import Callable
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike

from climber_pkg.gait import RING1, RING2, Action, ClampCommand, LegCommand
from paramotion import gough_stewart as gs
from paramotion.rotations import matrix_from_rotvec

if TYPE_CHECKING:
    from climber_pkg.gait import ClimbingGait, GaitParams
    from climber_pkg.robot import RobotConfig
    from climber_pkg.trunk import Trunk


def start_direction(seed: int) -> tuple[float, float]:
    """Angles (rad) of the start offset's direction and of the start tilt's axis, both in the
    plane of ring 1, drawn from ``seed`` (the same seed gives the same start pose)."""
    phi, psi = np.random.default_rng([int(seed), 29]).uniform(0.0, 2.0 * math.pi, 2)
    return float(phi), float(psi)


def initial_pose_on_trunk(trunk: Trunk, robot: RobotConfig, s_start: float, lengths: ArrayLike,
                          offset: float = 0.0, tilt: float = 0.0, seed: int = 0
                          ) -> tuple[tuple[np.ndarray, np.ndarray], tuple[np.ndarray, np.ndarray]]:
    """World poses of ring 1 (on the axis at ``s_start``) and ring 2 from the leg lengths.

    With ``offset`` (m) the robot is shifted off the axis, in ring 1's plane, and with ``tilt``
    (rad) it is turned about an axis in that plane through its mid-height (so both rings stay
    within the bore); the directions of both come from :func:`start_direction` (``seed``).
    """
    p1, r1 = trunk.frame_at(s_start)
    geom = robot.geometry
    chord = np.linalg.norm(geom.platform_anchors[0, :2] - geom.base_anchors[0, :2])
    h = math.sqrt(max(float(np.mean(lengths)) ** 2 - chord ** 2, 1e-4))
    fk = gs.forward_kinematics(geom, lengths, [0, 0, h], np.eye(3))
    # Follow the axis: put ring 2 where the trunk is, by aligning ring 1 along the chord.
    p2_guess, _ = trunk.frame_at(s_start + h)
    axis = p2_guess - p1
    axis /= np.linalg.norm(axis)
    x = r1[:, 0] - (r1[:, 0] @ axis) * axis
    x /= np.linalg.norm(x)
    r1 = np.stack([x, np.cross(axis, x), axis], 1)
    if offset or tilt:
        phi, psi = start_direction(seed)
        p1 = p1 + offset * (r1 @ np.array([math.cos(phi), math.sin(phi), 0.0]))
        mid = p1 + 0.5 * (r1 @ fk.position)
        turn_axis = r1 @ np.array([math.cos(psi), math.sin(psi), 0.0])
        turn = matrix_from_rotvec(tilt * turn_axis)
        p1 = mid + turn @ (p1 - mid)
        r1 = turn @ r1
    return (p1, r1), (p1 + r1 @ fk.position, r1 @ fk.rotation)


class KinematicClimber:
    """World state of the robot: ring poses, clamps, leg lengths, sensor read-out."""

    def __init__(self, trunk: Trunk, robot: RobotConfig, s_start: float = 0.4,
                 lengths: ArrayLike | None = None, clamp_delay: float = 0.5,
                 noise: float = 0.0, dropout: float = 0.0, seed: int = 0,
                 start_offset: float = 0.0, start_tilt: float = 0.0,
                 cone: bool = True) -> None:
        self.trunk = trunk
        self.robot = robot
        geom = robot.geometry
        if lengths is None:
            lengths = np.full(6, geom.leg_min + 0.25 * (geom.leg_max - geom.leg_min))
        self.lengths = np.asarray(lengths, dtype=float)
        self.pose = list(initial_pose_on_trunk(trunk, robot, s_start, self.lengths,
                                               start_offset, start_tilt, seed))
        self.cone = cone
        self.clamp = [True, True]
        self.clamp_delay = clamp_delay
        self._clamp_due = [None, None]     # (time, closed)
        self._move = None                  # (t_end, target lengths)
        self.noise = noise
        self.dropout = dropout
        self.rng = np.random.default_rng(seed)
        self.violations = 0                # instants with no clamp closed
        self.moves_without_clamp = 0
        self._ray_cache = {}

    def apply(self, t: float, action: Action) -> None:
        if isinstance(action, ClampCommand):
            if action.close:
                self._clamp_due[action.ring] = (t + self.clamp_delay, True)
            else:
                self.clamp[action.ring] = False       # opening: not holding immediately
                self._clamp_due[action.ring] = None
        elif isinstance(action, LegCommand):
            self._move = (t + action.duration, np.asarray(action.lengths, dtype=float))

    def advance(self, t: float) -> None:
        for ring in (RING1, RING2):
            due = self._clamp_due[ring]
            if due is not None and t >= due[0]:
                self.clamp[ring] = due[1]
                self._clamp_due[ring] = None
        if self._move is not None and t >= self._move[0]:
            target = self._move[1]
            self._move = None
            if np.allclose(target, self.lengths, atol=1e-12):
                pass
            elif self.clamp[RING1] and self.clamp[RING2]:
                pass       # both rings clamped: the legs cannot move (stall)
            elif not (self.clamp[RING1] or self.clamp[RING2]):
                self.moves_without_clamp += 1
            else:
                self._move_free_ring(target)
        if not (self.clamp[RING1] or self.clamp[RING2]):
            self.violations += 1

    def _move_free_ring(self, target):
        geom = self.robot.geometry
        (p1, r1), (p2, r2) = self.pose
        rel_p = r1.T @ (p2 - p1)
        rel_r = r1.T @ r2
        fk = gs.forward_kinematics(geom, target, rel_p, rel_r)
        self.lengths = target.copy()
        if self.clamp[RING1]:
            self.pose[RING2] = (p1 + r1 @ fk.position, r1 @ fk.rotation)
        else:
            inv_r = fk.rotation.T
            self.pose[RING1] = (p2 - r2 @ inv_r @ fk.position, r2 @ inv_r)

    def ranges(self, ring: int) -> np.ndarray:
        """Three distances of a ring's ultrasonic sensors (REP 117 conventions)."""
        p, r = self.pose[ring]
        key = (ring, p.tobytes(), r.tobytes())
        if self._ray_cache.get(ring, (None,))[0] != key:       # poses change only on moves
            origins, dirs = self.robot.sensor_rays()
            fov = self.robot.sensor_fov if self.cone else 0.0
            self._ray_cache[ring] = (key, self.trunk.cone_distance(
                p + origins @ r.T, dirs @ r.T, fov, self.robot.sensor_max_range))
        out = self._ray_cache[ring][1].copy()
        out = out + self.rng.normal(scale=self.noise, size=3) if self.noise else out
        out[out < self.robot.sensor_min_range] = -math.inf
        if self.dropout:
            out[self.rng.random(3) < self.dropout] = math.inf
        return out


def run_gait(gait: ClimbingGait, model: KinematicClimber, dt: float = 0.05,
             max_time: float = 3000.0, sensor_period: float = 0.05,
             on_tick: Callable[[float, list[Action]], None] | None = None,
             until: Callable[[], bool] | None = None) -> float:
    """Close the loop between a ClimbingGait and a KinematicClimber until the gait finishes
    (or ``until()`` is true)."""
    t = 0.0
    next_sensor = 0.0
    while t < max_time and not gait.finished and not (until is not None and until()):
        model.advance(t)
        gait.update_encoders(t, model.lengths)
        for ring in (RING1, RING2):
            gait.update_clamp(t, ring, model.clamp[ring])
        if t >= next_sensor:
            for ring in (RING1, RING2):
                for k, v in enumerate(model.ranges(ring)):
                    gait.update_range(t, ring, k, v)
            next_sensor = t + sensor_period
        actions = gait.tick(t)
        for action in actions:
            model.apply(t, action)
        if on_tick is not None:
            on_tick(t, actions)
        t += dt
    return t


def climb_kinematic(trunk: Trunk, robot: RobotConfig, gait_params: GaitParams, *,
                    start_offset: float = 0.0, start_tilt: float = 0.0, seed: int = 0,
                    noise: float = 0.001, dropout: float = 0.0, cone: bool = True,
                    s_start: float = 0.4, max_time: float | None = None,
                    off_axis_limit: float = 0.02) -> dict[str, object]:

    """One ROS-free closed-loop climb (gait + ideal kinematic robot), evaluated on the truth.

    Returns the planner's outcome and, from the ground truth: the off-axis distance of the
    moving ring each time the planner measures it (centre to where the axis crosses the ring
    plane): at the first measurement (the start pose) and over every measurement from the
    second cycle on (both rings have been re-centred by then); the smallest ring-bore clearance
    over every pose; instants with no clamp closed; the arc length reached; and ``success``
    (top reached, off-axis max <= ``off_axis_limit``, no contact, clamps never both open).
    """
    from climber_pkg import evaluation as ev
    from climber_pkg.gait import ClimbingGait

    gait = ClimbingGait(robot.geometry, robot.sensor_mount_radius, robot.sensor_angles,
                        robot.sensor_min_range, robot.sensor_max_range, robot.ring_inner_radius,
                        gait_params)
    model = KinematicClimber(trunk, robot, s_start=s_start, noise=noise, dropout=dropout,
                             seed=seed, start_offset=start_offset, start_tilt=start_tilt,
                             cone=cone)
    off_axis, start_off_axis, clearance = [], [], [min(ev.ring_clearance(trunk, robot, *pose)
                                   for pose in model.pose)]
    seen = [0]

    def monitor(t, actions):
        for _, ring in gait.measure_log[seen[0]:]:
            pos, rot = model.pose[ring]
            if ev.ring_on_structure(trunk, pos):
                error = ev.centering_error(trunk, pos, rot)
                (off_axis if gait.semicycle >= 2 else start_off_axis).append(error)
        seen[0] = len(gait.measure_log)
        if actions:
            clearance.append(min(ev.ring_clearance(trunk, robot, *pose) for pose in model.pose))

    run_gait(gait, model, max_time=max_time or 120.0 + 60.0 * trunk.length, on_tick=monitor)
    s_top = float(trunk.closest(model.pose[RING2][0])[0])
    reached_top = bool(gait.state.value == 'done' and 'end of the structure' in gait.reason
                       and s_top >= trunk.length - gait_params.delta)
    finite = [v for v in off_axis if math.isfinite(v)]
    result = {
        'state': gait.state.value, 'message': gait.reason, 'reached_top': reached_top,
        'arc_length_reached_m': s_top, 'trunk_length_m': trunk.length,
        'height_reached_m': float(model.pose[RING2][0][2]),
        'steps': len(gait.steps), 'cycles': gait.cycle,
        'off_axis_start_m': start_off_axis[0] if start_off_axis else math.nan,
        'off_axis_per_step_m': start_off_axis + off_axis,
        'off_axis_median_m': float(np.median(finite)) if finite else math.nan,
        'off_axis_max_m': float(np.max(finite)) if finite else math.nan,
        'min_ring_clearance_m': float(min(clearance)),
        'clamp_violations': model.violations + model.moves_without_clamp,
        'refusal': gait.reason if gait.state.value in ('refused', 'lost_structure') else None,
    }
    result['success'] = bool(reached_top and finite and result['off_axis_max_m'] <= off_axis_limit
                             and result['min_ring_clearance_m'] > 0
                             and result['clamp_violations'] == 0)
    return result
