"""The FAST isolator on ideal legs, shared by the unit and mode tests.

A 'linear plant' of the isolation controller: the feed is the base pose composed with the
platform's forward kinematics of the commanded leg lengths, the base moves sinusoidally (40/30 mm,
0.3 deg), and the tracker is noise-free but ``latency`` seconds late.
"""
import math

import numpy as np

from cable_robot_pkg.fast.isolation import IsolationController
from paramotion.gough_stewart import forward_kinematics
from paramotion.rotations import matrix_from_rotvec


def control_period(ctl, t, legs, hist, measured, feed_p, feed_R):
    """One control period of ``ctl`` at ``t``: the legs' state, the tracker frame of period
    ``measured`` from ``hist`` (none while it is negative, i.e. within the latency) and the
    target; returns the commanded leg lengths."""
    ctl.add_leg_state(t, legs)
    if measured >= 0:
        ts, pbm, Rbm, fpm, fRm = hist[measured]
        ctl.add_base(t, ts, pbm, Rbm)
        ctl.add_feed(t, ts, fpm, fRm)
    ctl.set_target(t, feed_p, feed_R)
    return ctl.update(t).lengths


def kinematic_isolation_run(cfg, mode, latency, duration, settle, without=(),
                            stop_on_divergence=False, **attrs):
    """(feed RMS error in m from ``settle`` s on, the controller's stroke-clip count).

    ``attrs`` are set on the controller before the run. With ``stop_on_divergence`` a run
    whose legs go non-finite or whose feed strays over 1 m stops with an infinite error."""
    ctl = IsolationController.from_config(cfg, mode=mode, without=without)
    for key, value in attrs.items():
        setattr(ctl, key, value)
    feed_p, feed_R = cfg.track.pose(0.0)
    _, _, up0, upR0 = cfg.chain.coarse_targets(feed_p, feed_R)
    dt, n_lat = 0.005, int(round(latency / 0.005))
    legs = ctl.nominal_lengths.copy()
    guess = cfg.chain.nominal_relative_pose()
    hist, errs = [], []
    for k in range(int(duration / dt)):
        t = k * dt
        pb = up0 + np.array([0.04 * math.sin(2 * math.pi * 0.9 * t),
                             0.03 * math.sin(2 * math.pi * 0.6 * t + 1), 0.0])
        Rb = upR0 @ matrix_from_rotvec([0.005 * math.sin(2 * math.pi * 0.7 * t), 0, 0])
        fk = forward_kinematics(cfg.geometry, legs, *guess)
        guess = (fk.position, fk.rotation)
        fp, fR = pb + Rb @ fk.position, Rb @ fk.rotation
        hist.append((t, pb, Rb, fp, fR))
        legs = control_period(ctl, t, legs, hist, k - n_lat, feed_p, feed_R)
        if t >= settle:
            errs.append(np.linalg.norm(fp - feed_p))
        if stop_on_divergence and (not np.all(np.isfinite(legs)) or errs and errs[-1] > 1.0):
            return math.inf, ctl.clip_count
    return math.sqrt(np.mean(np.square(errs))), ctl.clip_count
