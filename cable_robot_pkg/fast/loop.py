"""The FAST control loops without ROS: plant, tracker model and both controllers in lock-step.

The same algorithm objects the nodes wrap (:class:`~cable_robot_pkg.fast.plant.FeedSupportPlant`,
:class:`~cable_robot_pkg.fast.pid.CoarseController`,
:class:`~cable_robot_pkg.fast.isolation.IsolationController`), called in the order the
lock-step graph calls them every publish period (``period``, 5 ms by default): physics steps;
encoder samples; tracker frames released ``latency`` after capture (noise, optional calibration
offset); feed targets at 100 Hz; the cable loop at 50 Hz; the isolation update; leg commands
stamped now. The tracker captures and the isolation controller updates once per period, as the
nodes do on the simulator's state messages: ``period`` 0.01 runs them at 100 Hz. No messages,
no executor: several times cheaper than the graph, so sweeps and long causal tests use it
(:func:`run_loop`); the graph (:func:`cable_robot_pkg.fast.scenario.run_graph`) remains the
product and is what ``paramotion fast`` runs.
"""
from __future__ import annotations

import math
import os
from collections import deque
from collections.abc import Iterable

import numpy as np
from numpy.typing import ArrayLike

from cable_robot_pkg.fast.configuration import load_config, parse_without
from cable_robot_pkg.fast.isolation import IsolationController
from cable_robot_pkg.fast.pid import CoarseController
from cable_robot_pkg.fast.plant import FeedSupportPlant, make_client
from cable_robot_pkg.fast.wind import WindModel
from paramotion.rotations import matrix_from_rotvec

PERIOD = 0.005          # the simulator's publish period (s): tracker and isolation clock
TRAJECTORY_PERIOD = 0.01
CABLE_PERIOD = 0.02


class TrackerModel:
    """Optical tracker of trolley, upper platform and feed: Gaussian noise, a constant
    calibration ``offset`` (m, map frame) on every position, release ``latency`` s after
    capture (stamp = capture time)."""

    def __init__(self, latency: float, noise_position: float, noise_orientation_deg: float,
                 offset: ArrayLike = (0.0, 0.0, 0.0), seed: int = 1):
        self.latency = float(latency)
        self.sigma_p = float(noise_position)
        self.sigma_r = math.radians(noise_orientation_deg)
        self.offset = np.asarray(offset, float)
        self.rng = np.random.default_rng(seed)
        self.queue = deque()

    def capture(self, t: float, poses: dict[str, tuple[np.ndarray, np.ndarray]]) -> None:
        """Capture ``{body: (p, R)}`` at ``t``."""
        for body, (p, R) in poses.items():
            dn = self.rng.normal(0.0, self.sigma_p, 3)
            dr = self.rng.normal(0.0, self.sigma_r, 3)
            self.queue.append((t + self.latency, t, body, p + dn + self.offset,
                               matrix_from_rotvec(dr) @ R))

    def release(self, now: float) -> list[tuple[float, str, np.ndarray, np.ndarray]]:
        """Frames due at ``now``: ``[(stamp, body, p, R)]``."""
        out = []
        while self.queue and self.queue[0][0] <= now + 1e-9:
            _, stamp, body, p, R = self.queue.popleft()
            out.append((stamp, body, p, R))
        return out


def run_loop(duration: float, config: str | os.PathLike[str] | None = None,
             overrides: dict | None = None, latency: float = 0.02, mode: str | None = None,
             without: str | Iterable[str] = (), wind: float = 1.0, wind_seed: int | None = None,
             tracker_offset: ArrayLike = (0.0, 0.0, 0.0), tracker_seed: int = 1,
             settle: float = 3.0, abort_mm: float = 2000.0, period: float = PERIOD,
             command_lag: int = 0) -> dict:
    """Run the loops for ``duration`` sim seconds; returns the error series and RMS figures.

    ``config``/``overrides``: YAML path and dict merged over the defaults; ``mode`` None: the
    config's; ``without``: ablation names; ``abort_mm``: stop early once the feed is this far
    off (a diverged loop); ``period``: the publish period (s), a whole number of physics steps
    dividing the 10 ms trajectory period, at which the tracker captures and the isolation
    controller updates; ``command_lag``: periods the plant runs before it gets the commands
    computed on a state (0: the lock-step graph; 1: the launched graph's worst case with
    ``sync_max_lag`` one period, where the simulator steps the next period before the answer
    arrives; the commands keep their stamps and are held first-order from them). Result keys:
    ``t``, ``feed_err`` (m), ``feed_rot_err`` (deg), ``feed_offset`` (mean error vector after
    ``settle``, m), ``trolley_err``, ``upper_err`` (m), ``upper_rot_err`` (deg, against the
    chain's commanded upper pose),
    ``feed_rms_position_mm``, ``feed_rms_orientation_deg``, ``trolley_rms_position_mm``,
    ``upper_rms_position_mm``, ``upper_rms_orientation_deg``, ``clip_count``, ``diverged``.
    """
    cfg = load_config(config, overrides)
    without = parse_without(without)
    raw = cfg.raw
    ctl = IsolationController.from_config(cfg, mode=mode, without=without)
    coarse = CoarseController(cfg, CABLE_PERIOD, 'tracker_feedback' in without)
    isolate = 'isolation' not in without
    tr = raw['tracker']
    tracker = TrackerModel(latency, tr['noise_position'], tr['noise_orientation_deg'],
                           tracker_offset, tracker_seed)
    bullet = make_client()
    try:
        wind_model = WindModel.from_config(raw['wind'], raw['trolley'], intensity=wind,
                                           seed=wind_seed)
        plant = FeedSupportPlant(cfg, bullet, wind=wind_model)
        steps = max(1, int(round(period / plant.dt)))
        every_target = int(round(TRAJECTORY_PERIOD / period))
        every_cable = int(round(CABLE_PERIOD / period))
        if every_target < 1 or abs(every_target * period - TRAJECTORY_PERIOD) > 1e-9:
            raise ValueError(f'period {period:g} s does not divide the trajectory period '
                             f'{TRAJECTORY_PERIOD:g} s')
        rec = {k: [] for k in ('t', 'feed_p', 'feed_R', 'target_p', 'target_R', 'trolley_p',
                               'upper_p', 'upper_R', 'trolley_target', 'upper_target_p',
                               'upper_target_R')}
        target = None
        trolley_meas = None
        n = int(round(duration / period))
        diverged = False
        pending = deque()       # per period, the commands computed on its state
        for k in range(1, n + 1):
            for _ in range(steps):
                plant.step()
            t = plant.t
            trolley = plant.trolley_pose()
            upper = plant.upper_pose()
            feed = plant.feed_pose()
            ctl.add_leg_state(t, plant.leg_lengths()[0])
            ctl.add_hinge_state(t, plant.hinge_angles())
            tracker.capture(t, {'trolley': trolley, 'upper': upper, 'feed': feed})
            for stamp, body, p, R in tracker.release(t):
                if body == 'upper':
                    ctl.add_base(t, stamp, p, R)
                elif body == 'trolley':
                    ctl.add_trolley(t, stamp, p, R)
                    trolley_meas = (p, R)
                else:
                    ctl.add_feed(t, stamp, p, R)
            if (k - 1) % every_target == 0 or target is None:
                target = cfg.track.pose(t)
                ctl.set_target(t, *target)
            commands = []
            if (k - 1) % every_cable == 0:
                _, hinge = coarse.targets(*target)
                commands.append((plant.set_hinge_command, tuple(hinge), {}))
                out = coarse.update(*target, trolley_meas, plant.last_tensions)
                if out is not None:
                    commands.append((plant.set_winch_command, tuple(np.array(x) for x in out),
                                     {'stamp': t}))
            if isolate:
                cmd = ctl.update(t)
                if ctl.last_base_arrival is not None or ctl.open_loop:
                    commands.append((plant.set_leg_command,
                                     (np.array(cmd.lengths), np.array(cmd.rates)),
                                     {'stamp': t}))
            pending.append(commands)
            while len(pending) > command_lag:
                for apply, args, kwargs in pending.popleft():
                    apply(*args, **kwargs)
            goal_p, goal_R = cfg.track.pose(t)
            trolley_goal, _, up_goal_p, up_goal_R = cfg.chain.coarse_targets(goal_p, goal_R)
            for key, value in (('t', t), ('feed_p', feed[0]), ('feed_R', feed[1]),
                               ('target_p', goal_p), ('target_R', goal_R),
                               ('trolley_p', trolley[0]), ('upper_p', upper[0]),
                               ('upper_R', upper[1]), ('trolley_target', trolley_goal),
                               ('upper_target_p', up_goal_p), ('upper_target_R', up_goal_R)):
                rec[key].append(value)
            if np.linalg.norm(feed[0] - goal_p) > abort_mm / 1000.0 \
                    or not np.all(np.isfinite(feed[0])):
                diverged = True
                break
    finally:
        bullet.disconnect()
    return _summarise({k: np.array(v) for k, v in rec.items()}, settle, ctl, diverged)


def _angles_deg(Ra, Rb):
    c = (np.trace(np.swapaxes(Ra, -1, -2) @ Rb, axis1=-2, axis2=-1) - 1.0) / 2.0
    return np.degrees(np.arccos(np.clip(c, -1.0, 1.0)))


def _rms(x):
    return float(math.sqrt(np.mean(np.square(x)))) if len(x) else math.nan


def _summarise(rec, settle, ctl, diverged):
    t = rec['t']
    keep = t >= settle
    feed_vec = rec['feed_p'] - rec['target_p']
    feed_err = np.linalg.norm(feed_vec, axis=1)
    feed_rot = _angles_deg(rec['feed_R'], rec['target_R'])
    trolley_err = np.linalg.norm(rec['trolley_p'] - rec['trolley_target'], axis=1)
    upper_err = np.linalg.norm(rec['upper_p'] - rec['upper_target_p'], axis=1)
    upper_rot = _angles_deg(rec['upper_R'], rec['upper_target_R'])
    out = {'t': t, 'feed_err': feed_err, 'feed_rot_err': feed_rot,
           'trolley_err': trolley_err, 'upper_err': upper_err, 'upper_rot_err': upper_rot,
           'feed_vec': feed_vec, 'diverged': bool(diverged), 'clip_count': ctl.clip_count,
           'sim_time_s': float(t[-1]) if len(t) else 0.0}
    if not keep.any():
        keep = np.ones_like(t, bool)
    out.update({
        'feed_offset': feed_vec[keep].mean(axis=0),
        'feed_rms_position_mm': 1000 * _rms(feed_err[keep]),
        'feed_rms_orientation_deg': _rms(feed_rot[keep]),
        'trolley_rms_position_mm': 1000 * _rms(trolley_err[keep]),
        'upper_rms_position_mm': 1000 * _rms(upper_err[keep]),
        'upper_rms_orientation_deg': _rms(upper_rot[keep]),
    })
    half = len(feed_err[keep]) // 2
    e = feed_err[keep]
    out['growing'] = bool(half > 10 and _rms(e[half:]) > 3.0 * _rms(e[:half]) + 1e-3)
    out['unstable'] = bool(diverged or ctl.clip_count > 0 or out['growing']
                           or out['feed_rms_position_mm'] > 2.0 * out['trolley_rms_position_mm'])
    return out
