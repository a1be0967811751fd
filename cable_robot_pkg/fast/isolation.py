"""Gough-Stewart vibration isolation of the feed on the vibrating trolley (the fine loop).

Cheng, Ren, Dai (Sec. I) isolate the receiver platform of a Gough-Stewart platform whose base
(the cable car) vibrates in the wind, with "a simple control law of the prediction of the base
platform and proportional derivative (PD) feedback". Lu, Zhu, Ren report that the direct terminal
feedback loop through the optical trackers becomes unstable when the measurement is delayed.
This module implements both loops so that the difference can be measured:

**Predictive (shipped) controller** -- :class:`IsolationController` with ``mode='predictive'``:

1. The tracker's base (upper platform) poses carry their capture stamps. A constant-acceleration
   Kalman filter per pose coordinate (:class:`PosePredictor`; position, and rotation vector
   relative to a reference attitude) is updated at the capture times and *predicted* forward to
   ``now + lead``: the tracker latency is compensated instead of being fed back. The same
   platform is also measured through two other sensor chains and fused at the same stamps:
   trolley tracker + hinge encoders (chain kinematics) and feed tracker + leg encoders (the
   shared forward kinematics), which averages the tracker noise.
2. The desired lower-platform pose relative to the predicted base follows from the feed target
   (plus a slow trim, step 4): ``p_rel = R_b^T (p_d - p_b)``, ``R_rel = R_b^T R_d``.
3. The shared inverse kinematics (:func:`paramotion.gough_stewart.inverse_kinematics`) turns
   it into leg lengths, and a finite difference of the same chain into leg rates; lengths are
   clipped to the stroke minus a margin. The leg drives close a local PD around these commands
   at the physics rate (in the simulator: the actuator's servo).
4. The tracked feed pose closes a *slow* integral trim on the target (gain ``trim_gain``, 1/s)
   that removes steady offsets (leg compliance, hinge sag); its delay margin is
   ``pi / (2 trim_gain)`` seconds, far beyond any tracker latency.

5. The two platforms are dynamically coupled (Cheng et al.): leg reaction forces shake the
   trolley, and a prediction that lags the trolley's modes by a phase ``phi`` acts as negative
   damping ``~ m_feed * omega * phi``. Beyond ``latency_full`` of measured latency the
   compensated vibration (about a 1 s low-passed base reference) is therefore scaled by
   ``(latency_full / latency)^2`` (:meth:`IsolationController.compensation_gain`): isolation
   is traded for stability.

**Naive terminal-feedback loop** -- ``mode='naive'``: PI on the latest tracked feed error, in
velocity form on the commanded relative pose, ignoring capture stamps and without base
prediction. To reject vibration it needs a high gain, and a loop gain ``naive_ki`` with a delay
``tau`` loses stability near ``naive_ki * tau ~ pi / 2`` -- the delay-induced instability of
Lu et al. The latency sweep of ``paramotion fast sweep`` shows it.

Faults: a base measurement that is not finite is dropped; when no valid base measurement has
arrived for ``dropout_timeout`` the controller *holds* the last leg command (zero rate) and
reports ``holding``; when measurements return it re-initialises the predictor and resumes.
"""
import math
from collections import deque
from dataclasses import dataclass

import numpy as np

from cable_robot_pkg.fast.rotations import matrix_from_rotvec, rotvec_from_matrix
from paramotion.gough_stewart import (
    SingularPoseError,
    UnreachablePoseError,
    forward_kinematics,
    inverse_kinematics,
)


def _transition(dt):
    """Constant-acceleration state transition for [p, v, a]."""
    return np.array([[1.0, dt, 0.5 * dt * dt], [0.0, 1.0, dt], [0.0, 0.0, 1.0]])


def _process_noise(q, dt):
    """Discrete process noise of a white-jerk model with spectral density ``q``."""
    d2, d3, d4, d5 = dt ** 2, dt ** 3, dt ** 4, dt ** 5
    return q * np.array([[d5 / 20, d4 / 8, d3 / 6], [d4 / 8, d3 / 3, d2 / 2],
                         [d3 / 6, d2 / 2, dt]])


class ConstantAccelerationKF:
    """Kalman filter for m independent coordinates sharing one [p, v, a] model and noise."""

    def __init__(self, m, process_noise, measurement_std):
        self.m = m
        self.q = float(process_noise)
        self.r = float(measurement_std) ** 2
        self.x = np.zeros((3, m))
        self.P = np.diag([1.0, 1.0, 1.0])
        self.t = None

    def reset(self, t, z):
        """Start at measurement ``z`` (m,) at time ``t`` with unknown rates."""
        self.x = np.zeros((3, self.m))
        self.x[0] = z
        self.P = np.diag([self.r, 1.0, 100.0])
        self.t = t

    def update(self, t, z):
        """Predict to ``t`` and fuse measurement ``z`` (m,)."""
        dt = t - self.t
        if dt > 0:
            F = _transition(dt)
            self.x = F @ self.x
            self.P = F @ self.P @ F.T + _process_noise(self.q, dt)
            self.t = t
        S = self.P[0, 0] + self.r
        K = self.P[:, 0] / S
        self.x = self.x + np.outer(K, np.asarray(z) - self.x[0])
        self.P = self.P - np.outer(K, self.P[0])

    def predict(self, t):
        """State [p, v, a] (3, m) extrapolated to time ``t`` (no update)."""
        return _transition(t - self.t) @ self.x


class PosePredictor:
    """Predicts a tracked rigid body's pose forward from stamped, delayed measurements."""

    def __init__(self, process_noise, process_noise_rotation, position_std, rotation_std,
                 reset_gap=0.5):
        self.pos = ConstantAccelerationKF(3, process_noise, max(position_std, 1e-6))
        self.rot = ConstantAccelerationKF(3, process_noise_rotation, max(rotation_std, 1e-7))
        self.R_ref = None
        self.last_stamp = None
        self.reset_gap = reset_gap

    @property
    def ready(self):
        """True once a measurement has been fused."""
        return self.last_stamp is not None

    def add(self, stamp, position, rotation):
        """Fuse a pose captured at ``stamp``; older or non-finite measurements are refused
        (returns False). Several measurements with the same stamp (the same body seen through
        different sensor chains) are all fused."""
        position = np.asarray(position, float)
        rotation = np.asarray(rotation, float)
        if not (np.all(np.isfinite(position)) and np.all(np.isfinite(rotation))):
            return False
        if self.last_stamp is not None and stamp < self.last_stamp:
            return False
        if self.last_stamp is None or stamp - self.last_stamp > self.reset_gap:
            self.R_ref = rotation.copy()
            self.pos.reset(stamp, position)
            self.rot.reset(stamp, np.zeros(3))
        else:
            phi = rotvec_from_matrix(self.R_ref.T @ rotation)
            self.pos.update(stamp, position)
            self.rot.update(stamp, phi)
            if np.linalg.norm(self.rot.x[0]) > 0.2:
                # Re-anchor the rotation-vector chart so that it stays small.
                self.R_ref = self.R_ref @ matrix_from_rotvec(self.rot.x[0])
                self.rot.x[0] = 0.0
        self.last_stamp = stamp
        return True

    def predict(self, t):
        """(position, rotation, velocity, angular velocity in the reference frame) at ``t``."""
        xp = self.pos.predict(t)
        xr = self.rot.predict(t)
        R = self.R_ref @ matrix_from_rotvec(xr[0])
        return xp[0], R, xp[1], self.R_ref @ xr[1]


class TargetHistory:
    """Recent feed targets by time, so that a delayed measurement is compared with the target
    at its own capture time."""

    def __init__(self, horizon=1.0):
        self.items = deque()
        self.horizon = horizon

    def add(self, t, position, rotation):
        self.items.append((t, np.asarray(position, float), np.asarray(rotation, float)))
        while len(self.items) > 2 and self.items[-1][0] - self.items[0][0] > self.horizon:
            self.items.popleft()

    def latest(self):
        return self.items[-1] if self.items else None

    def at(self, t):
        """Target (position, rotation) at ``t``: linear in position, nearest in rotation."""
        if not self.items:
            return None
        prev = self.items[0]
        if t <= prev[0]:
            return prev[1], prev[2]
        for item in self.items:
            if item[0] >= t:
                w = (t - prev[0]) / max(item[0] - prev[0], 1e-12)
                rot = item[2] if w > 0.5 else prev[2]
                return prev[1] + w * (item[1] - prev[1]), rot
            prev = item
        last = self.items[-1]
        return last[1], last[2]

    def velocity(self):
        """Finite-difference target velocity (3,) and angular velocity (3,), map frame."""
        if len(self.items) < 2:
            return np.zeros(3), np.zeros(3)
        (t0, p0, R0), (t1, p1, R1) = self.items[-2], self.items[-1]
        dt = max(t1 - t0, 1e-9)
        w = rotvec_from_matrix(R1 @ R0.T) / dt
        return (p1 - p0) / dt, w


def pose_error(target_p, target_R, p, R):
    """Position error (3,) and rotation-vector error (3,) target minus actual, map frame."""
    return (np.asarray(target_p) - np.asarray(p),
            rotvec_from_matrix(np.asarray(target_R) @ np.asarray(R).T))


class SampleHistory:
    """Encoder samples (time, vector) kept for ``horizon`` seconds, read at a past time."""

    def __init__(self, horizon=0.5):
        self.times = deque()
        self.values = deque()
        self.horizon = horizon

    def add(self, t, value):
        value = np.asarray(value, float)
        if not np.all(np.isfinite(value)) or (self.times and t < self.times[-1]):
            return
        self.times.append(t)
        self.values.append(value)
        while len(self.times) > 2 and self.times[-1] - self.times[0] > self.horizon:
            self.times.popleft()
            self.values.popleft()

    def at(self, t, tolerance=0.02):
        """Linearly interpolated value at ``t`` (None when ``t`` is not covered)."""
        if not self.times or t < self.times[0] - tolerance or t > self.times[-1] + tolerance:
            return None
        times = np.fromiter(self.times, float)
        k = int(np.searchsorted(times, t))
        if k <= 0:
            return self.values[0]
        if k >= len(times):
            return self.values[-1]
        w = (t - times[k - 1]) / max(times[k] - times[k - 1], 1e-12)
        return (1.0 - w) * self.values[k - 1] + w * self.values[k]


@dataclass
class LegCommand:
    """Output of one controller update."""

    lengths: np.ndarray
    rates: np.ndarray
    clipped: bool
    holding: bool


class IsolationController:
    """Leg commands that keep the feed at its target while the upper platform vibrates."""

    def __init__(self, geometry, nominal_relative, mode='predictive', lead=0.005,
                 trim_gain=1.5, trim_limit=(0.03, math.radians(0.5)), naive_kp=0.3,
                 naive_ki=40.0, stroke_margin=0.005, dropout_timeout=0.1,
                 process_noise=20.0, process_noise_rotation=10.0, position_std=0.001,
                 rotation_std=math.radians(0.01), latency_full=0.05, slow_time=1.0,
                 chain=None, fuse=True):
        if mode not in ('predictive', 'naive'):
            raise ValueError(f'unknown isolation mode {mode!r}')
        self.geometry = geometry
        self.mode = mode
        self.lead = lead
        self.trim_gain = trim_gain
        self.trim_limit = trim_limit
        self.naive_kp, self.naive_ki = naive_kp, naive_ki
        self.lo = geometry.leg_min + stroke_margin
        self.hi = geometry.leg_max - stroke_margin
        self.timeout = dropout_timeout
        # A gap longer than the dropout timeout restarts the predictor (recovery).
        self.base = PosePredictor(process_noise, process_noise_rotation, position_std,
                                  rotation_std, reset_gap=dropout_timeout)
        self.targets = TargetHistory()
        self.nominal_p, self.nominal_R = (np.asarray(a, float) for a in nominal_relative)
        self.nominal_lengths = inverse_kinematics(geometry, self.nominal_p, self.nominal_R)
        self.trim = np.zeros(6)
        self.naive_cmd = np.concatenate([self.nominal_p, np.zeros(3)])
        self.naive_prev_error = None
        self.last_feed_time = None
        self.last_base_arrival = None
        self.last_base_R = None
        self.command = LegCommand(self.nominal_lengths.copy(), np.zeros(6), False, True)
        self.clip_count = 0
        self.hold_count = 0
        self.latency_full = latency_full
        self.slow_time = slow_time
        self.latency = 0.0
        self.gain = 1.0
        self.slow = None          # (time, position, rotation) of the slow base reference
        # Sensor fusion: the upper platform is also seen through the trolley tracker + hinge
        # encoders and through the feed tracker + leg encoders (forward kinematics).
        self.chain = chain
        self.fuse = fuse
        self.hinges = SampleHistory()
        self.legs = SampleHistory()
        self.fk_guess = (self.nominal_p, self.nominal_R)

    @classmethod
    def from_config(cls, cfg, mode=None):
        """Build from a validated :class:`~cable_robot_pkg.fast.config.FastConfig`."""
        iso = cfg.raw['isolation']
        tr = cfg.raw['tracker']
        return cls(cfg.geometry, cfg.chain.nominal_relative_pose(),
                   mode=mode or iso['mode'], lead=iso['lead'], trim_gain=iso['trim_gain'],
                   naive_kp=iso['naive_kp'], naive_ki=iso['naive_ki'],
                   stroke_margin=iso['stroke_margin'], dropout_timeout=iso['dropout_timeout'],
                   process_noise=iso['process_noise'],
                   process_noise_rotation=iso['process_noise_rotation'],
                   position_std=max(tr['noise_position'], 1e-4),
                   rotation_std=math.radians(max(tr['noise_orientation_deg'], 1e-3)),
                   latency_full=iso['latency_full'], chain=cfg.chain, fuse=iso['fuse'])

    # ------------------------------------------------------------------ inputs
    def set_target(self, t, position, rotation):
        """New feed target (map frame) valid at time ``t``."""
        self.targets.add(t, position, rotation)

    def add_base(self, now, stamp, position, rotation):
        """Tracked upper platform pose captured at ``stamp``, received at ``now``."""
        if self.base.add(stamp, position, rotation):
            self.last_base_arrival = now
            self.last_base_R = np.asarray(rotation, float)
            self.latency += 0.05 * (max(now - stamp, 0.0) - self.latency)
            return True
        return False

    def add_hinge_state(self, t, angles):
        """Orienting-mechanism encoder angles (alpha, beta) at time ``t``."""
        self.hinges.add(t, angles)

    def add_leg_state(self, t, lengths):
        """Leg encoder lengths at time ``t``."""
        self.legs.add(t, lengths)

    def add_trolley(self, now, stamp, position, rotation):
        """Tracked trolley pose: with the hinge angles at ``stamp`` it is one more
        measurement of the upper platform (chain kinematics)."""
        if not self.fuse or self.chain is None or self.mode != 'predictive':
            return False
        hinge = self.hinges.at(stamp)
        if hinge is None:
            return False
        p, R = self.chain.upper_pose(position, rotation, hinge[0], hinge[1])
        return self.add_base(now, stamp, p, R)

    def _base_from_feed(self, stamp, position, rotation):
        """Upper platform pose from the tracked feed and the leg lengths at ``stamp``
        (forward kinematics of the shared Gough-Stewart module), or None."""
        lengths = self.legs.at(stamp)
        if lengths is None:
            return None
        g = self.geometry
        lengths = np.clip(lengths, g.leg_min + 1e-9, g.leg_max - 1e-9)
        try:
            fk = forward_kinematics(g, lengths, *self.fk_guess)
        except (SingularPoseError, UnreachablePoseError, ValueError):
            return None
        if not fk.converged:
            return None
        self.fk_guess = (fk.position, fk.rotation)
        R_b = np.asarray(rotation) @ fk.rotation.T
        return np.asarray(position) - R_b @ fk.position, R_b

    def compensation_gain(self):
        """Share of the predicted base vibration that is compensated: 1 up to
        ``latency_full`` of measured tracker latency, ``(latency_full / latency)^2`` beyond.

        Why: a prediction that lags the base by a phase phi at a structural mode makes the leg
        reaction forces act like negative damping ~ m_feed * omega * phi on the trolley (the two
        platforms are coupled, Cheng et al.). The lag grows with the latency, so beyond
        ``latency_full`` the controller gives up isolation bandwidth to stay stable."""
        if self.latency <= self.latency_full:
            return 1.0
        return (self.latency_full / self.latency) ** 2

    def add_feed(self, now, stamp, position, rotation):
        """Tracked feed pose: integral trim (predictive) or the naive PI loop."""
        position = np.asarray(position, float)
        rotation = np.asarray(rotation, float)
        if not (np.all(np.isfinite(position)) and np.all(np.isfinite(rotation))):
            return False
        if self.mode == 'naive':
            # Direct terminal feedback: the latest error, as if it were current.
            target = self.targets.latest()
            if target is None or self.last_base_R is None:
                return False
            e = np.concatenate(pose_error(target[1], target[2], position, rotation))
            dt = 0.0 if self.last_feed_time is None else now - self.last_feed_time
            prev = e if self.naive_prev_error is None else self.naive_prev_error
            step = self.naive_kp * (e - prev) + self.naive_ki * dt * e
            Rb = self.last_base_R
            self.naive_cmd[:3] += Rb.T @ step[:3]
            self.naive_cmd[3:] += Rb.T @ step[3:]
            self.naive_prev_error = e
        else:
            if self.fuse:
                base = self._base_from_feed(stamp, position, rotation)
                if base is not None:
                    self.add_base(now, stamp, *base)
            target = self.targets.at(stamp)
            if target is None or self.last_feed_time is None:
                self.last_feed_time = now
                return True
            e = np.concatenate(pose_error(target[0], target[1], position, rotation))
            dt = min(now - self.last_feed_time, 0.1)
            self.trim += self.trim_gain * dt * e
            self.trim[:3] = np.clip(self.trim[:3], -self.trim_limit[0], self.trim_limit[0])
            self.trim[3:] = np.clip(self.trim[3:], -self.trim_limit[1], self.trim_limit[1])
        self.last_feed_time = now
        return True

    # ------------------------------------------------------------------ output
    def _base_command(self, t):
        """Base pose the legs compensate at ``t``: the slow base reference plus the gain-scaled
        predicted vibration about it."""
        p_b, R_b, _, _ = self.base.predict(t)
        if self.gain >= 1.0 or self.slow is None:
            return p_b, R_b
        _, p_s, R_s = self.slow
        dphi = rotvec_from_matrix(R_s.T @ R_b)
        return (p_s + self.gain * (p_b - p_s),
                R_s @ matrix_from_rotvec(self.gain * dphi))

    def _update_slow(self, now):
        p_b, R_b, _, _ = self.base.predict(now)
        if self.slow is None:
            self.slow = (now, p_b, R_b)
            return
        t0, p_s, R_s = self.slow
        a = min(1.0, max(now - t0, 0.0) / self.slow_time)
        dphi = rotvec_from_matrix(R_s.T @ R_b)
        self.slow = (now, p_s + a * (p_b - p_s), R_s @ matrix_from_rotvec(a * dphi))

    def _relative(self, t, target_p, target_R):
        """Desired lower platform pose in the (compensated) upper platform frame at ``t``."""
        p_b, R_b = self._base_command(t)
        p_d = target_p + self.trim[:3]
        R_d = matrix_from_rotvec(self.trim[3:]) @ target_R
        return R_b.T @ (p_d - p_b), R_b.T @ R_d

    def _clip(self, lengths):
        clipped = bool(np.any(lengths < self.lo) or np.any(lengths > self.hi))
        if clipped:
            self.clip_count += 1
        return np.clip(lengths, self.lo, self.hi), clipped

    def update(self, now):
        """Leg command (:class:`LegCommand`) for the current time ``now``."""
        stale = (self.last_base_arrival is None
                 or now - self.last_base_arrival > self.timeout)
        latest = self.targets.latest()
        if stale or latest is None or not self.base.ready:
            self.hold_count += 1
            self.command = LegCommand(self.command.lengths, np.zeros(6), False, True)
            return self.command
        if self.mode == 'naive':
            R = matrix_from_rotvec(self.naive_cmd[3:])
            lengths, clipped = self._clip(inverse_kinematics(self.geometry, self.naive_cmd[:3], R))
            rates = np.zeros(6)
        else:
            self._update_slow(now)
            self.gain = self.compensation_gain()
            h = 0.002
            v, w = self.targets.velocity()
            t0 = now + self.lead
            age = t0 - latest[0]
            p0 = latest[1] + v * age
            R0 = matrix_from_rotvec(w * age) @ latest[2]
            p1 = p0 + v * h
            R1 = matrix_from_rotvec(w * h) @ R0
            l0 = inverse_kinematics(self.geometry, *self._relative(t0, p0, R0))
            l1 = inverse_kinematics(self.geometry, *self._relative(t0 + h, p1, R1))
            lengths, clipped = self._clip(l0)
            rates = np.where((l0 < self.lo) | (l0 > self.hi), 0.0, (l1 - l0) / h)
        self.command = LegCommand(lengths, rates, clipped, False)
        return self.command
