"""Climbing gait (section IV-E) closed with the ideal kinematic robot model.

Checks the safety invariant, climbing of structures never seen before, and the safe refusal of
bad inputs; the PyBullet graph is exercised in test_climber_graph.py.
"""
import math

import numpy as np
import pytest

from climber_pkg import evaluation as ev
from climber_pkg.gait import (
    RING1,
    RING2,
    ClampCommand,
    ClimbingGait,
    GaitParams,
    LegCommand,
    State,
)
from climber_pkg.kinematic_model import KinematicClimber, run_gait
from climber_pkg.robot import load_robot_config
from climber_pkg.trunk import Trunk
from paramotion import gough_stewart as gs

ROBOT = load_robot_config()


def make_gait(**params):
    return ClimbingGait(ROBOT.geometry, ROBOT.sensor_mount_radius, ROBOT.sensor_angles,
                        ROBOT.sensor_min_range, ROBOT.sensor_max_range, ROBOT.ring_inner_radius,
                        GaitParams(**params))


def unseen_trunk(kind, length=4.0, seed=0):
    """Structures the planner was never tuned on: arcs, tapers, leans, 3-D wiggles."""
    rng = np.random.default_rng(seed)
    z = np.linspace(0, length, 9)
    if kind == 'arc':              # gentle constant curvature, radius 12 m, random plane
        ang = z / 12.0
        phi = rng.uniform(0, 2 * np.pi)
        x = 12.0 * (1 - np.cos(ang))
        pts = np.stack([x * np.cos(phi), x * np.sin(phi), 12.0 * np.sin(ang)], 1)
        radius = 0.2
    elif kind == 'taper':          # straight, 0.29 -> 0.15 m
        pts = np.stack([0 * z, 0 * z, z], 1)
        radius = [[0, 0.29], [length, 0.15]]
    elif kind == 'lean':           # straight but leaning 10 deg
        tilt = math.radians(10)
        pts = np.stack([z * math.sin(tilt), 0 * z, z * math.cos(tilt)], 1)
        radius = 0.25
    elif kind == 'wiggle':         # 3-D gentle S in x and y, tapering
        pts = np.stack([0.25 * np.sin(z / 1.5), 0.2 * (1 - np.cos(z / 2.0)), z], 1)
        radius = [[0, 0.26], [length, 0.2]]
    else:
        raise ValueError(kind)
    return Trunk(pts.tolist(), radius, name=kind)


class SafetyMonitor:
    """Checks every action against the clamp states the gait last *reported* to it."""

    def __init__(self, gait, model):
        self.gait, self.model = gait, model
        self.bad_releases = 0
        self.stroke_violations = 0
        self.max_condition = 0.0
        self.min_ring_clearance = math.inf
        self.min_leg_clearance = math.inf
        self.centering = []

    def __call__(self, t, actions):
        for a in actions:
            if isinstance(a, ClampCommand) and not a.close:
                if self.gait.clamp_closed[1 - a.ring] is not True:
                    self.bad_releases += 1
                if not self.model.clamp[1 - a.ring]:
                    self.bad_releases += 1
            if isinstance(a, LegCommand):
                g = ROBOT.geometry
                if a.lengths.min() < g.leg_min or a.lengths.max() > g.leg_max:
                    self.stroke_violations += 1
        if actions:
            trunk = self.model.trunk
            poses = self.model.pose
            (p1, r1), (p2, r2) = poses
            rel_p, rel_r = r1.T @ (p2 - p1), r1.T @ r2
            self.max_condition = max(self.max_condition, float(gs.jacobian_condition(
                ROBOT.geometry, gs.jacobian(ROBOT.geometry, rel_p, rel_r))))
            for ring in (RING1, RING2):
                if ev.ring_on_structure(trunk, poses[ring][0]):
                    self.centering.append(ev.centering_error(trunk, *poses[ring]))
                    self.min_ring_clearance = min(
                        self.min_ring_clearance, ev.ring_clearance(trunk, ROBOT, *poses[ring]))
            self.min_leg_clearance = min(self.min_leg_clearance,
                                         ev.leg_clearance(trunk, ROBOT, poses[0], poses[1]))


def climb(trunk, seed=0, **kw):
    model_kw = {k: kw.pop(k) for k in ('noise', 'dropout', 'clamp_delay') if k in kw}
    gait = make_gait(**kw)
    model = KinematicClimber(trunk, ROBOT, seed=seed, **model_kw)
    mon = SafetyMonitor(gait, model)
    run_gait(gait, model, on_tick=mon)
    return gait, model, mon


@pytest.mark.slow
@pytest.mark.parametrize('kind', ['arc', 'taper', 'lean', 'wiggle'])
def test_climbs_unseen_structures_to_the_top(kind):
    trunk = unseen_trunk(kind, seed=len(kind))
    gait, model, mon = climb(trunk, noise=0.001, dropout=0.05, seed=3)
    assert gait.state is State.DONE, gait.reason
    assert 'end of the structure' in gait.reason
    s_top, _ = trunk.closest(model.pose[RING2][0])
    assert s_top >= trunk.length - gait.p.delta   # ring 2 within one step of the top
    assert model.violations == 0 and mon.bad_releases == 0
    assert mon.stroke_violations == 0
    assert mon.max_condition < gait.p.max_condition
    assert mon.min_ring_clearance > 0.05 and mon.min_leg_clearance > 0.05
    assert np.nanmax(mon.centering) < 0.01       # 1 mm sensor noise -> mm-level centering


def test_safety_invariant_with_slow_and_random_clamps():
    trunk = unseen_trunk('wiggle', length=3.0)
    for seed, delay in ((1, 0.05), (2, 1.5), (3, 2.9)):
        gait, model, mon = climb(trunk, seed=seed, clamp_delay=delay, n_cycles=2)
        assert gait.state is State.DONE, gait.reason
        assert model.violations == 0 and mon.bad_releases == 0


def test_release_only_when_other_confirmed_closed_fuzz():
    """Random, adversarial observations: a release is never emitted unconfirmed."""
    rng = np.random.default_rng(11)
    g = ROBOT.geometry
    home = gs.inverse_kinematics(g, [0, 0, 0.5], np.eye(3))
    for trial in range(30):
        gait = make_gait(clamp_timeout=0.3, sensor_timeout=0.3, settle_time=0.0)
        states = [True, True]
        for step in range(400):
            t = step * 0.05
            if rng.random() < 0.2:
                ring = int(rng.integers(2))
                states[ring] = bool(rng.integers(2))
                gait.update_clamp(t, ring, states[ring])
            elif step < 2:
                gait.update_clamp(t, 0, True)
                gait.update_clamp(t, 1, True)
            lengths = home + rng.normal(scale=0.002, size=6) if rng.random() < 0.95 else \
                np.full(6, np.nan)
            gait.update_encoders(t, lengths)
            for ring in (0, 1):
                for k in range(3):
                    v = rng.choice([0.18, 0.17, math.nan, math.inf, -math.inf, 0.3])
                    gait.update_range(t, ring, k, float(v))
            for a in gait.tick(t):
                if isinstance(a, ClampCommand) and not a.close:
                    assert gait.clamp_closed[1 - a.ring] is True, (trial, step)
            if gait.finished:
                break


def test_stale_clamp_state_confirms_nothing():
    g = ROBOT.geometry
    gait = make_gait()
    gait.update_encoders(0.0, gs.inverse_kinematics(g, [0, 0, 0.45], np.eye(3)))
    gait.update_clamp(0.0, RING1, True)          # ring 1's state never refreshed after t = 0
    actions = []
    for k in range(40, 60):                       # the planner starts 2 s later
        t = 0.05 * k
        gait.update_clamp(t, RING2, True)
        gait.update_encoders(t, gs.inverse_kinematics(g, [0, 0, 0.45], np.eye(3)))
        actions += gait.tick(t)
        if gait.finished:
            break
    assert gait.state is State.REFUSED and 's old' in gait.reason
    assert not any(isinstance(a, ClampCommand) and not a.close for a in actions)


def test_trunk_thicker_than_bore_refused_safely():
    trunk = Trunk([[0, 0, 0], [0, 0, 3]], 0.355, name='fat')
    gait, model, mon = climb(trunk)
    assert gait.state is State.REFUSED
    assert 'does not fit' in gait.reason and 'bore' in gait.reason
    assert model.clamp[RING1] and model.violations == 0 and mon.bad_releases == 0


def test_sharp_bend_refused_before_contact():
    # A 90 deg elbow of 1 m radius: far tighter than 0.5 m tall rings can follow.
    ang = np.linspace(0, math.pi / 2, 12)
    pts = np.stack([1 - np.cos(ang), 0 * ang, np.sin(ang)], 1) + [0, 0, 0]
    pts = np.vstack([[[0, 0, -1.5]], [[0, 0, -0.75]], pts])
    trunk = Trunk(pts.tolist(), 0.2, name='elbow')
    gait, model, mon = climb(trunk)
    assert gait.state is State.REFUSED, gait.reason
    assert model.violations == 0 and mon.bad_releases == 0
    assert mon.min_ring_clearance > 0.0 and mon.min_leg_clearance > 0.0
    assert model.clamp[RING1] or model.clamp[RING2]


def test_unreachable_predicted_pose_refused():
    # A step longer than the whole stroke cannot be taken even once.
    trunk = unseen_trunk('lean')
    gait, model, mon = climb(trunk, delta=0.6, delta_min=0.6)
    assert gait.state is State.REFUSED
    assert 'cannot make a single step' in gait.reason and 'leg' in gait.reason
    assert model.clamp[RING1] and mon.stroke_violations == 0


@pytest.mark.parametrize('ring, value, words', [
    (RING2, math.nan, 'ring2 ultrasonic 1: nan'), (RING2, -math.inf, 'too close (-inf)'),
    (RING2, None, 'no reading'), (RING1, math.nan, 'ring1 ultrasonic 1: nan'),
    (RING1, math.inf, 'ring1 ultrasonic 1: inf'), (RING1, None, 'no reading')])
def test_bad_sensor_data_refused_safely(ring, value, words):
    """NaN, -inf, nothing, or +inf on the trailing ring: refused, a clamp still holding."""
    trunk = unseen_trunk('taper')
    gait = make_gait(sensor_timeout=1.0)
    model = KinematicClimber(trunk, ROBOT)
    real = model.ranges

    def faulty(r):
        out = real(r)
        if r == ring:
            if value is None:
                return np.array([])
            out[1] = value
        return out

    model.ranges = faulty
    run_gait(gait, model, max_time=120)
    assert gait.state is State.REFUSED
    assert words in gait.reason.lower()
    assert model.clamp[1 - gait.moving] and model.violations == 0
    if ring == RING2:
        assert not gait.steps                      # refused before the first move
    else:
        assert gait.steps and gait.moving == RING1  # ring 2 climbed, then ring 1 was blind


def test_encoder_nan_refused():
    trunk = unseen_trunk('taper')
    gait = make_gait()
    model = KinematicClimber(trunk, ROBOT)
    gait.update_encoders(0.0, [np.nan] * 6)
    gait.update_clamp(0.0, 0, True)
    gait.update_clamp(0.0, 1, True)
    gait.tick(0.0)
    assert gait.state is State.REFUSED and 'not finite' in gait.reason
    del model


@pytest.mark.slow            # a climb of three cycles, then a descent
def test_descend_after_climbing():
    trunk = unseen_trunk('lean', length=5.0)
    gait, model, _ = climb(trunk, n_cycles=3)
    assert gait.state is State.DONE
    s_up = trunk.closest(model.pose[RING1][0])[0]
    down = make_gait(mode='descend', n_cycles=2)
    run_gait(down, model)
    assert down.state is State.DONE, down.reason
    s_down = trunk.closest(model.pose[RING1][0])[0]
    assert s_down < s_up - 0.5
    assert model.violations == 0


def test_turn_around_the_trunk():
    trunk = unseen_trunk('taper')
    gait = make_gait(mode='turn', turn_angle=math.radians(40))
    model = KinematicClimber(trunk, ROBOT)
    x_before = [model.pose[r][1][:, 0].copy() for r in (RING1, RING2)]
    run_gait(gait, model)
    assert gait.state is State.DONE, gait.reason
    for ring in (RING1, RING2):
        x0, x1 = x_before[ring], model.pose[ring][1][:, 0]
        ang = math.degrees(math.atan2(np.cross(x0, x1)[2], x0 @ x1))
        assert ang == pytest.approx(40.0, abs=0.5)
    assert model.violations == 0


def _released_ring2(**params):
    """A gait that has just commanded ring 2's release at t = 1.0 (ring 1 holds)."""
    g = ROBOT.geometry
    gait = make_gait(**params)
    lengths = gs.inverse_kinematics(g, [0, 0, 0.45], np.eye(3))
    released = []
    for k in range(0, 21):
        t = 0.05 * k
        gait.update_clamp(t, RING1, True)
        gait.update_clamp(t, RING2, True)
        gait.update_encoders(t, lengths)
        released += [t for a in gait.tick(t) if isinstance(a, ClampCommand) and not a.close]
    assert released and gait.state is State.RELEASE
    return gait, lengths, released[0]


def test_a_stalled_planner_does_not_time_out_on_the_gap_it_did_not_run():
    """The planner's process is starved for 4 s of sim time right after commanding a
    release: its first tick after the gap must not refuse before it has read the clamp
    states queued behind /clock; once they say released it plans. A clamp that never
    confirms is still refused clamp_timeout after the gap, and without a gap the timeout
    holds as before (causal: the stall handling is what keeps the planner going)."""
    gait, lengths, _ = _released_ring2()
    gait.tick(5.05)                               # 4 s later, nothing read in between
    assert not gait.finished, gait.reason
    gait, lengths, released = _released_ring2()
    for k in range(1, 80):                        # no gap: ticks at 20 Hz, clamp still closed
        gait.update_clamp(1.0 + 0.05 * k, RING2, True)
        gait.tick(1.0 + 0.05 * k)
        if gait.finished:
            break
    assert gait.finished and 'did not confirm release' in gait.reason
    assert 1.0 + 0.05 * k - released == pytest.approx(3.0, abs=0.06)
    gait, lengths, _ = _released_ring2()
    gait.tick(5.05)
    gait.update_clamp(5.06, RING2, False)
    gait.update_clamp(5.06, RING1, True)
    gait.update_encoders(5.06, lengths)
    gait.tick(5.10)
    assert not gait.finished and gait.state is State.PLAN
    gait, lengths, _ = _released_ring2()
    for k in range(1, 80):                        # after the gap, ticks again at 20 Hz
        gait.update_clamp(5.0 + 0.05 * k, RING2, True)
        gait.tick(5.0 + 0.05 * k)
        if gait.finished:
            break
    assert gait.finished and 'did not confirm release' in gait.reason
