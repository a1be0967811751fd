"""Per-winch PID with anti-windup, winch speed limit and tension floor (the coarse loop).

Lu, Zhu, Ren control the trolley with "standard proportional-integral-derivative controllers
with direct terminal feedback from the optical sensors" (Abstract): the optical tracker measures
the trolley pose, the cable inverse kinematics turns the measured and the target poses into cable
lengths, and each winch runs its own PID on its cable's length error

    e_i = L_i(target pose) - L_i(measured pose)
    L0_cmd_i = L0_ff_i + Kp e_i + Ki int e_i + Kd de_i/dt

where ``L0_ff`` is the feedforward unstretched length of the cable inverse kinematics
(:meth:`CableSystem.inverse_kinematics`). Practical limits every winch drive has:

- *speed limit*: the commanded unstretched length moves at most ``speed_max * dt`` per update;
- *anti-windup*: the integrator is frozen (conditional integration) while the output is clipped
  by the correction bound, the speed limit or the tension floor in the direction of the error;
- *tension floor*: a winch whose measured tension is below ``tension_floor`` never pays out
  further (that would slacken its cable); it may still reel in.
"""
from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike

if TYPE_CHECKING:
    from cable_robot_pkg.fast.configuration import FastConfig


class PID:
    """Vectorised PID (one channel per element) with conditional-integration anti-windup and a
    first-order filtered derivative (time constant ``derivative_tau``)."""

    def __init__(self, n: int, kp: ArrayLike, ki: ArrayLike, kd: ArrayLike,
                 output_limit: ArrayLike = np.inf, derivative_tau: float = 0.02):
        self.n = n
        self.kp, self.ki, self.kd = (np.broadcast_to(np.asarray(g, float), (n,)).copy()
                                     for g in (kp, ki, kd))
        self.limit = np.broadcast_to(np.asarray(output_limit, float), (n,)).copy()
        self.tau = derivative_tau
        self.reset()

    def reset(self) -> None:
        """Forget the integral and derivative state."""
        self.integral = np.zeros(self.n)
        self.prev_error = None
        self.derivative = np.zeros(self.n)

    def update(self, error: ArrayLike, dt: float,
               blocked: ArrayLike | None = None) -> np.ndarray:
        """Output for this error. ``blocked`` (n,) of -1/0/+1 marks channels whose actuator
        cannot move in that direction (speed limit, tension floor): the integrator is frozen
        when the error would push further that way."""
        error = np.asarray(error, float)
        if self.prev_error is not None and dt > 0:
            raw = (error - self.prev_error) / dt
            a = dt / (self.tau + dt)
            self.derivative += a * (raw - self.derivative)
        self.prev_error = error.copy()
        candidate = self.integral + self.ki * error * dt
        out = self.kp * error + candidate + self.kd * self.derivative
        clipped = np.clip(out, -self.limit, self.limit)
        push = np.sign(self.ki * error)
        windup = ((out != clipped) & (np.sign(out) == push))
        if blocked is not None:
            windup |= (np.asarray(blocked) != 0) & (np.asarray(blocked) == push)
        self.integral = np.where(windup, self.integral, candidate)
        self.saturated = out != clipped
        return clipped


class WinchController:
    """The coarse loop: per-winch PID on cable length errors plus cable IK feedforward."""

    def __init__(self, n: int, kp: ArrayLike, ki: ArrayLike, kd: ArrayLike, speed_max: float,
                 correction_max: ArrayLike, tension_floor: float):
        self.pid = PID(n, kp, ki, kd, output_limit=correction_max)
        self.speed_max = float(speed_max)
        self.floor = float(tension_floor)
        self.command = None
        self.blocked = np.zeros(n, int)
        self.rate_limited = np.zeros(n, bool)
        self.floor_active = np.zeros(n, bool)

    @classmethod
    def from_config(cls, cfg: FastConfig) -> WinchController:
        """Build from a validated FastConfig (``cable_controller`` and ``cables`` sections)."""
        cc, cab = cfg.raw['cable_controller'], cfg.raw['cables']
        return cls(cfg.cables.n, cc['kp'], cc['ki'], cc['kd'], cab['winch_speed_max'],
                   cc['correction_max'], cab['tension_floor'])

    def reset(self, unstretched: ArrayLike) -> None:
        """Start from the winches' current unstretched lengths."""
        self.command = np.asarray(unstretched, float).copy()
        self.pid.reset()

    def update(self, dt: float, feedforward: ArrayLike, length_error: ArrayLike,
               tensions: ArrayLike | None = None) -> tuple[np.ndarray, np.ndarray]:
        """New unstretched-length commands (n,) and winch speeds (n,).

        ``feedforward``: L0 of the cable IK at the target; ``length_error``: ``L(target) -
        L(measured)`` (positive: the cable must get longer); ``tensions``: measured tensions
        for the floor (None: no floor check).
        """
        feedforward = np.asarray(feedforward, float)
        if self.command is None:
            self.reset(feedforward)
        correction = self.pid.update(length_error, dt, blocked=self.blocked)
        desired = feedforward + correction
        step = desired - self.command
        max_step = self.speed_max * dt
        limited = np.clip(step, -max_step, max_step)
        self.rate_limited = limited != step
        blocked = np.where(self.rate_limited, np.sign(step), 0).astype(int)
        self.floor_active = np.zeros_like(self.rate_limited)
        if tensions is not None:
            low = (np.asarray(tensions) < self.floor) & (limited > 0.0)
            limited = np.where(low, 0.0, limited)
            blocked = np.where(low, 1, blocked)
            self.floor_active = low
        self.blocked = blocked
        self.command = self.command + limited
        return self.command.copy(), limited / dt if dt > 0 else np.zeros_like(limited)


class CoarseController:
    """The coarse loop of one control period: the trolley target and hinge angles for a feed
    target (:class:`~cable_robot_pkg.fast.focal_surface.FeedSupportChain`), the cable inverse
    kinematics there (tension distribution re-planned after 1 mm of target motion) as
    feedforward, and the per-winch PID on ``L(target) - L(tracked trolley pose)``.

    ``open_loop`` (``without tracker_feedback``): feedforward only, the trolley measurement is
    not used. ``notes`` collects this period's warnings (for the node's log/diagnostics).
    """

    def __init__(self, cfg: FastConfig, dt: float, open_loop: bool = False):
        self.cfg = cfg
        self.dt = float(dt)
        self.open_loop = bool(open_loop)
        self.winches = WinchController.from_config(cfg)
        self.plan = None
        self.notes = []

    def targets(self, feed_p: ArrayLike, feed_R: ArrayLike
                ) -> tuple[np.ndarray, tuple[float, float]]:
        """``(trolley target position, (alpha, beta))`` for a feed target."""
        trolley_p, hinge, _, _ = self.cfg.chain.coarse_targets(feed_p, feed_R)
        return trolley_p, hinge

    def update(self, feed_p: ArrayLike, feed_R: ArrayLike,
               trolley: tuple[ArrayLike, ArrayLike] | None = None,
               tensions: ArrayLike | None = None) -> tuple[np.ndarray, np.ndarray] | None:
        """Winch ``(commands, rates)`` for this period; ``trolley`` = tracked ``(p, R)`` or
        None (no fresh measurement: the winches hold). None when the very first target is
        outside the tension-feasible workspace."""
        from cable_robot_pkg.fast.cables import InfeasibleTensionError
        self.notes = []
        cfg = self.cfg
        trolley_p, _ = self.targets(feed_p, feed_R)
        try:
            if self.plan is None or np.linalg.norm(self.plan[0] - trolley_p) > 1e-3:
                self.plan = (trolley_p, cfg.tension_targets(trolley_p, feed_R))
        except InfeasibleTensionError as exc:
            if self.plan is None:
                self.notes.append(f'target unreachable: {exc}')
                return None
            self.notes.append(f'target outside the tension-feasible workspace: {exc}')
        lengths = cfg.cables.lengths(trolley_p, np.eye(3))
        feedforward = cfg.cables.unstretched_for(lengths, self.plan[1])
        n = cfg.cables.n
        if self.open_loop:
            return self.winches.update(self.dt, feedforward, np.zeros(n), tensions)
        if trolley is None:
            if self.winches.command is None:
                return None
            return self.winches.command.copy(), np.zeros(n)
        error = lengths - cfg.cables.lengths(*trolley)
        out = self.winches.update(self.dt, feedforward, error, tensions)
        if self.winches.floor_active.any():
            self.notes.append('tension floor: not paying out ' + ', '.join(
                name for name, a in zip(cfg.cables.names, self.winches.floor_active) if a))
        return out
