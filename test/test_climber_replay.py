"""Replay of the committed sample climb (bags/climber_sample): recorded data vs the algorithms.

The bag was recorded by ``paramotion climb`` on ``bags/climber_sample/trunk.json`` for one cycle
(see bags/climber_sample/README.md). Without any simulator, this test checks the recording
against the kinematics and the planner: forward kinematics of the recorded encoder lengths
reproduce the recorded true ring-to-ring pose; the correction function applied to recorded
ultrasonic triplets finds the true structure centre; the clamp invariant holds in the record;
and every recorded planner command respects the gait's rules (stroke margins, conditioning,
a command issued only once the previous one was reached).
"""
import math
from pathlib import Path

import numpy as np
import pytest

from climber_pkg.correction import correction
from climber_pkg.gait import GaitParams
from climber_pkg.robot import load_robot_config
from climber_pkg.trunk import Trunk
from paramotion import gough_stewart as gs
from paramotion.bag.reader import bag_info, deserialize, read_messages

SAMPLE = Path(__file__).resolve().parents[1] / 'bags' / 'climber_sample'
ROBOT = load_robot_config()


@pytest.fixture(scope='module')
def record():
    info = bag_info(SAMPLE / 'bag')
    assert info.complete, info.problem
    out = []
    for m in read_messages(SAMPLE / 'bag'):
        out.append((m.log_time_ns * 1e-9, m.topic, deserialize(m)))
    return out


def pose_of(p):
    q = p.orientation
    return (np.array([p.position.x, p.position.y, p.position.z]),
            gs.matrix_from_quaternion([q.w, q.x, q.y, q.z]))


def by_topic(record, topic):
    return [(t, m) for t, tp, m in record if tp == topic]


def test_sample_has_every_topic(record):
    topics = {tp for _, tp, _ in record}
    for name in ('/clock', '/climber/ground_truth', '/climber/joint_states',
                 '/climber/ring1/ultrasonic', '/climber/ring2/ultrasonic',
                 '/climber/ring1/clamp_closed', '/climber/ring2/clamp_closed',
                 '/climber/ring1/clamp_command', '/climber/ring2/clamp_command',
                 '/climber/leg_command', '/climber/planned_pose', '/climber/status'):
        assert name in topics, name


def test_clamp_invariant_and_stroke_in_record(record):
    state = [None, None]
    checked = 0
    for _, topic, msg in record:
        if topic.endswith('clamp_closed'):
            state[int(topic[len('/climber/ring')]) - 1] = msg.data
            if None not in state:
                assert state[0] or state[1], 'both clamps open in the recording'
                checked += 1
        elif topic == '/climber/joint_states':
            assert min(msg.position) >= ROBOT.geometry.leg_min - 1e-4
            assert max(msg.position) <= ROBOT.geometry.leg_max + 1e-4
    assert checked > 500


def test_forward_kinematics_of_recorded_encoders_matches_truth(record):
    truth = {round(t, 4): m for t, m in by_topic(record, '/climber/ground_truth')}
    geom = ROBOT.geometry
    worst = 0.0
    n = 0
    for t, js in by_topic(record, '/climber/joint_states'):
        gt = truth.get(round(t, 4))
        if gt is None:
            continue
        (p1, r1), (p2, r2) = pose_of(gt.poses[0]), pose_of(gt.poses[1])
        rel_p, rel_r = r1.T @ (p2 - p1), r1.T @ r2
        fk = gs.forward_kinematics(geom, js.position, rel_p + 0.01, rel_r)
        worst = max(worst, float(np.abs(fk.position - rel_p).max()))
        n += 1
    assert n > 500
    assert worst < 2e-4          # closed-chain PyBullet model vs exact kinematics


def test_correction_of_recorded_ranges_finds_true_centre(record):
    trunk = Trunk.from_file(SAMPLE / 'trunk.json')
    truth = by_topic(record, '/climber/ground_truth')
    times = np.array([t for t, _ in truth])
    errors = []
    for ring in (1, 2):
        triplet = {}
        for t, msg in by_topic(record, f'/climber/ring{ring}/ultrasonic'):
            triplet[int(msg.header.frame_id[-1])] = msg.range
            if len(triplet) < 3 or not all(math.isfinite(v) for v in triplet.values()):
                continue
            d = [triplet[k] for k in range(3)]
            triplet = {}
            pos, rot = pose_of(truth[int(np.argmin(np.abs(times - t)))][1].poses[ring - 1])
            axis_point, _ = trunk.axis_in_plane(pos, rot[:, 2])
            true_dxdy = (rot.T @ (axis_point - pos))[:2]
            c = correction(d, ROBOT.sensor_mount_radius, ROBOT.sensor_angles)
            errors.append(float(np.hypot(c.dx - true_dxdy[0], c.dy - true_dxdy[1])))
            assert c.radius == pytest.approx(float(trunk.radius_at(trunk.closest(pos)[0])),
                                             abs=0.006)
    assert len(errors) > 100
    assert np.median(errors) < 0.002 and max(errors) < 0.006   # 1 mm sensor noise


def test_recorded_commands_respect_the_gait_rules(record):
    """Every recorded leg command is within the stroke margins, away from singularities, and
    was reached by the encoders before the next command or clamp change was issued."""
    geom = ROBOT.geometry
    p = GaitParams()
    enc = None
    pending = None
    reached = 0
    rel = (np.array([0, 0, 0.4]), np.eye(3))
    for t, topic, msg in record:
        if topic == '/climber/joint_states':
            enc = np.array(msg.position)
            if pending is not None and np.abs(enc - pending).max() <= p.length_tolerance:
                reached += 1
                pending = None
        elif topic == '/climber/leg_command' or topic.endswith('clamp_command'):
            assert pending is None, f'new command at {t:.2f} s before the last was reached'
            if topic == '/climber/leg_command':
                target = np.array(msg.points[-1].positions)
                assert target.min() >= geom.leg_min + p.stroke_margin - 1e-9
                assert target.max() <= geom.leg_max - p.stroke_margin + 1e-9
                fk = gs.forward_kinematics(geom, target, *rel)
                rel = (fk.position, fk.rotation)
                assert fk.jacobian_condition < p.max_condition
                pending = target
    assert reached >= 6 and pending is None
