"""Ideal kinematic stand-in for the climbing robot (no dynamics), for tests and quick studies.

The clamped ring stays where it is; a leg command moves the free ring exactly to the pose whose
inverse kinematics are the commanded lengths (forward kinematics of the shared module), after
the command's duration. Clamps close/open after configurable delays. Ultrasonic distances are
ray casts against the true structure, with optional noise and dropouts. This is what the
PyBullet node does with a dynamic closed chain; here it is instantaneous and exact, so planner
logic can be exercised on many structures in seconds.
"""
import math

import numpy as np

from climber_pkg.gait import RING1, RING2, ClampCommand, LegCommand
from paramotion import gough_stewart as gs


def initial_pose_on_trunk(trunk, robot, s_start, lengths):
    """World poses of ring 1 (centred on the axis at ``s_start``) and ring 2 from the lengths."""
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
    return (p1, r1), (p1 + r1 @ fk.position, r1 @ fk.rotation)


class KinematicClimber:
    """World state of the robot: ring poses, clamps, leg lengths, sensor read-out."""

    def __init__(self, trunk, robot, s_start=0.4, lengths=None, clamp_delay=0.5,
                 noise=0.0, dropout=0.0, seed=0):
        self.trunk = trunk
        self.robot = robot
        geom = robot.geometry
        if lengths is None:
            lengths = np.full(6, geom.leg_min + 0.25 * (geom.leg_max - geom.leg_min))
        self.lengths = np.asarray(lengths, dtype=float)
        self.pose = list(initial_pose_on_trunk(trunk, robot, s_start, self.lengths))
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

    def apply(self, t, action):
        if isinstance(action, ClampCommand):
            if action.close:
                self._clamp_due[action.ring] = (t + self.clamp_delay, True)
            else:
                self.clamp[action.ring] = False       # opening: not holding immediately
                self._clamp_due[action.ring] = None
        elif isinstance(action, LegCommand):
            self._move = (t + action.duration, np.asarray(action.lengths, dtype=float))

    def advance(self, t):
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

    def ranges(self, ring):
        """Three distances of a ring's ultrasonic sensors (REP 117 conventions)."""
        p, r = self.pose[ring]
        key = (ring, p.tobytes(), r.tobytes())
        if self._ray_cache.get(ring, (None,))[0] != key:       # poses change only on moves
            origins, dirs = self.robot.sensor_rays()
            self._ray_cache[ring] = (key, self.trunk.ray_distance(
                p + origins @ r.T, dirs @ r.T, self.robot.sensor_max_range))
        out = self._ray_cache[ring][1].copy()
        out = out + self.rng.normal(scale=self.noise, size=3) if self.noise else out
        out[out < self.robot.sensor_min_range] = -math.inf
        if self.dropout:
            out[self.rng.random(3) < self.dropout] = math.inf
        return out


def run_gait(gait, model, dt=0.05, max_time=3000.0, sensor_period=0.05, on_tick=None):
    """Close the loop between a ClimbingGait and a KinematicClimber until the gait finishes."""
    t = 0.0
    next_sensor = 0.0
    while t < max_time and not gait.finished:
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
