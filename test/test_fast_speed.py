"""The FAST speed-ups change nothing: fused hot paths equal their reference formulas bit for bit.

Speed itself is measured by ``paramotion fast bench`` (a benchmark, not a test).
"""
import math

import numpy as np
import pybullet
import pytest

from cable_robot_pkg.fast.cables import _cross
from cable_robot_pkg.fast.configuration import load_config
from cable_robot_pkg.fast.plant import FeedSupportPlant, _matrix, make_client
from cable_robot_pkg.fast.ros_messages import config_from_param
from cable_robot_pkg.fast.scenario import bench_real_time_factor, detach_qos_event_handlers
from cable_robot_pkg.fast.wind import WindModel
from paramotion.errors import UserError


@pytest.fixture(scope='module')
def cfg():
    return load_config()


def reference_cable_wrench(cables, position, rotation, linear_velocity, angular_velocity,
                           unstretched, unstretched_rates):
    """The per-step cable wrench written with the public geometry/rates/tension methods."""
    lengths, dirs = cables.geometry(position, rotation)
    r = cables.attach @ rotation.T
    v = linear_velocity + np.cross(angular_velocity, r)
    rates = -np.einsum('ij,ij->i', v, dirs)
    t, slack = cables.tensions(lengths, rates, unstretched, unstretched_rates)
    f_i = t[:, None] * dirs
    return f_i.sum(axis=0), np.cross(r, f_i).sum(axis=0), t, lengths, slack


@pytest.mark.parametrize('backend', ['numba', 'numpy'])
def test_fused_cable_wrench_is_bit_identical_to_reference(cfg, backend, monkeypatch):
    """Both the compiled kernel (cable_kernel.py) and the numpy path."""
    pytest.importorskip(backend)
    monkeypatch.setenv('PARAMOTION_BACKEND', backend)
    rng = np.random.default_rng(3)
    cables = cfg.cables
    base_p = cfg.chain.coarse_targets(*cfg.track.pose(0.0))[0]
    L = cables.lengths(base_p, np.eye(3))
    slack_seen = 0
    for _ in range(200):
        p = base_p + rng.normal(0.0, 0.3, 3)
        q = rng.normal(size=4)
        R = _matrix(list(q / np.linalg.norm(q)))
        lin, ang = rng.normal(0.0, 0.5, 3), rng.normal(0.0, 0.2, 3)
        # Some cables slack (unstretched longer than stretched), some taut.
        L0 = L * (1.0 + rng.normal(0.0, 0.01, cables.n))
        rates = rng.normal(0.0, 0.05, cables.n)
        got = cables.wrench(p, R, lin, ang, L0, rates)
        want = reference_cable_wrench(cables, p, R, lin, ang, L0, rates)
        for g, w in zip(got, want):
            assert np.array_equal(g, w)
        slack_seen += int(np.sum(got[4]))
    assert 0 < slack_seen < 200 * cables.n       # both taut and slack cables were exercised


@pytest.mark.parametrize('backend', ['numba', 'numpy'])
def test_length_rates_are_bit_identical_to_reference(cfg, backend, monkeypatch):
    """The simulator's cable state message uses the fused geometry for dL/dt (compiled in
    cable_kernel.py with numba)."""
    pytest.importorskip(backend)
    monkeypatch.setenv('PARAMOTION_BACKEND', backend)
    rng = np.random.default_rng(5)
    cables = cfg.cables
    base_p = cfg.chain.coarse_targets(*cfg.track.pose(0.0))[0]
    for _ in range(50):
        p = base_p + rng.normal(0.0, 0.3, 3)
        q = rng.normal(size=4)
        R = _matrix(list(q / np.linalg.norm(q)))
        lin, ang = rng.normal(0.0, 0.5, 3), rng.normal(0.0, 0.2, 3)
        _, dirs = cables.geometry(p, R)
        r = np.asarray(cables.attach) @ R.T
        want = -np.einsum('ij,ij->i', lin + np.cross(ang, r), dirs)
        assert np.array_equal(cables.length_rates(p, R, lin, ang), want)


def test_cross_helper_matches_numpy():
    rng = np.random.default_rng(0)
    a, b = rng.normal(size=(10, 3)), rng.normal(size=(10, 3))
    assert np.array_equal(_cross(a, b), np.cross(a, b))
    assert np.array_equal(_cross(a[0], b), np.cross(a[0], b))


def test_wind_wrench_is_bit_identical_to_reference_formula(cfg):
    wind = WindModel.from_config(cfg.raw['wind'], cfg.raw['trolley'], intensity=4.0, seed=5)
    ref = WindModel.from_config(cfg.raw['wind'], cfg.raw['trolley'], intensity=4.0, seed=5)
    rng = np.random.default_rng(1)
    gusty = 0
    for t in np.arange(0.0, 120.0, 0.037):
        R = _matrix(list(pybullet.getQuaternionFromEuler(rng.normal(0.0, 0.1, 3))))
        force, torque = wind.wrench(t, R)
        vel = ref.velocity(t)
        gusty += ref._gust(t) > 0.0
        f = 0.5 * 1.225 * ref.cd * ref.area * np.linalg.norm(vel) * vel
        shapes = ref._turbulence(t)[3:]
        tq = np.cross(R @ ref.r_cp, f) + np.linalg.norm(f) * ref.torque_scale * ref.I * shapes
        assert np.array_equal(force, f) and np.array_equal(torque, tq)
    assert gusty > 0          # the gust path was exercised


class ReferencePlant(FeedSupportPlant):
    """The plant step as first written: every call through BulletClient, six single leg-servo
    calls and both hinge servos re-sent every step, cables through the unfused methods."""

    def apply_commands(self, since):
        b = self.b
        kp, kv, fmax = self.leg_gains
        target = np.clip(self.leg_cmd + self.leg_rate_cmd * since, self.geom.leg_min,
                         self.geom.leg_max)
        for i in range(6):
            b.setJointMotorControl2(self.body, self.ROD[i], b.POSITION_CONTROL,
                                    targetPosition=float(target[i] - self.nominal_lengths[i]),
                                    targetVelocity=float(self.leg_rate_cmd[i]),
                                    positionGain=kp, velocityGain=kv, force=fmax)
        kp, kv, tmax = self.hinge_gains
        for j, link in enumerate((self.RING, self.UPPER)):
            b.setJointMotorControl2(self.body, link, b.POSITION_CONTROL,
                                    targetPosition=float(self.hinge_cmd[j]), positionGain=kp,
                                    velocityGain=kv, force=tmax)

    def step(self):
        b = self.b
        dt = self.dt
        goal = self.winch_cmd + self.winch_rate_cmd * (self.t - self.winch_cmd_time)
        step = np.clip(goal - self.unstretched, -self.winch_speed * dt, self.winch_speed * dt)
        self.unstretched = self.unstretched + step
        rates = step / dt
        pos, q = b.getBasePositionAndOrientation(self.body)
        lin, ang = b.getBaseVelocity(self.body)
        R = _matrix(q)
        f, tq, tens, lengths, slack = reference_cable_wrench(
            self.cables, np.array(pos), R, np.array(lin), np.array(ang), self.unstretched,
            rates)
        self.last_tensions, self.last_lengths, self.slack = tens, lengths, slack
        wf, wt = self.wind.wrench(self.t, R)
        f = f + wf
        tq = tq + wt
        b.applyExternalForce(self.body, -1, list(f), list(pos), b.WORLD_FRAME)
        b.applyExternalTorque(self.body, -1, list(tq), b.WORLD_FRAME)
        self.apply_commands(self.t - self.leg_cmd_time)
        b.stepSimulation()
        self.t += dt


def _trajectory(cls, cfg, steps=400):
    client = make_client()
    try:
        wind = WindModel.from_config(cfg.raw['wind'], cfg.raw['trolley'], intensity=2.0)
        pl = cls(cfg, client, wind=wind)
        rng = np.random.default_rng(2)
        out = []
        for k in range(steps):
            if k % 20 == 0:      # new winch, leg and hinge set-points, as the controllers send
                n = pl.cables.n
                pl.set_winch_command(pl.unstretched + rng.normal(0, 1e-3, n),
                                     rng.normal(0, 1e-3, n), pl.t - 0.002)
                pl.set_leg_command(pl.nominal_lengths + rng.normal(0, 1e-3, 6),
                                   rng.normal(0, 1e-3, 6), pl.t - 0.001)
                if k % 40 == 0:
                    pl.set_hinge_command(*(pl.hinge_cmd + rng.normal(0, 1e-3, 2)))
            pl.step()
            out.append(np.concatenate([
                pl.trolley_pose()[0], pl.trolley_pose()[1].ravel(), pl.feed_pose()[0],
                pl.upper_pose()[0], pl.leg_lengths()[0], pl.hinge_angles(), pl.last_tensions]))
        return np.array(out)
    finally:
        client.disconnect()


def test_plant_step_is_bit_identical_to_reference_step(cfg):
    fast = _trajectory(FeedSupportPlant, cfg)
    ref = _trajectory(ReferencePlant, cfg)
    assert np.all(np.isfinite(fast))
    assert np.ptp(fast[:, 0]) > 0.0             # the trolley moved
    assert np.array_equal(fast, ref)


def test_detach_qos_event_handlers_keeps_messages_flowing():
    from rclpy.node import Node
    from std_msgs.msg import Float64

    from paramotion.graph import Graph

    class Probe(Node):
        def __init__(self, **kwargs):
            super().__init__('speed_probe', **kwargs)

    got = []
    with Graph() as graph:
        node = graph.add(Probe)
        pub = node.create_publisher(Float64, '/speed_probe', 10)
        node.create_subscription(Float64, '/speed_probe', lambda m: got.append(m.data), 10)
        assert len(list(node.waitables)) > 0
        removed = detach_qos_event_handlers(graph.nodes)
        assert removed > 0 and len(list(node.waitables)) == 0
        pub.publish(Float64(data=1.5))
        graph.drain()
    assert got == [1.5]


def test_config_cache_gives_private_copies_and_sees_file_changes(tmp_path):
    path = tmp_path / 'f.yaml'
    path.write_text('wind: {seed: 3}\n')
    a = config_from_param(str(path))
    b = config_from_param(str(path))
    assert a is not b and a.raw == b.raw and a.raw['wind']['seed'] == 3
    a.raw['wind']['seed'] = 99
    assert config_from_param(str(path)).raw['wind']['seed'] == 3
    path.write_text('wind: {seed: 12}\n')
    assert config_from_param(str(path)).raw['wind']['seed'] == 12
    with pytest.raises(UserError, match='no such file'):
        config_from_param(str(tmp_path / 'missing.yaml'))


def test_bench_refuses_bad_arguments():
    with pytest.raises(UserError, match='duration'):
        bench_real_time_factor(duration=0.0)
    with pytest.raises(UserError, match='duration'):
        bench_real_time_factor(duration=math.inf)
    with pytest.raises(UserError, match='repeat'):
        bench_real_time_factor(duration=1.0, repeat=0)


@pytest.mark.slow
def test_graph_levers_leave_the_fast_run_bit_identical(monkeypatch):
    """The lock-step Graph's speed levers (its own drain, time set directly, no parameter
    services in a private graph) change nothing: the FAST series equal those of rclpy's
    SingleThreadedExecutor with every node's /clock subscription and parameter services."""
    from cable_robot_pkg.fast.scenario import run_graph
    from paramotion.graph import graph_defaults
    monkeypatch.delenv('ROS_DOMAIN_ID', raising=False)    # a private graph, as users get

    def series():
        run = run_graph(0.3)
        return {k: np.array(v) for k, v in run['series'].items()}
    with graph_defaults(executor='single_threaded', direct_time=False,
                        private_without_services=False):
        ref = series()
    fast = series()
    assert len(ref['t']) == 60 and np.ptp(np.array(ref['legs'])) > 0.0
    for key in ref:
        assert np.array_equal(ref[key], fast[key]), key


def test_refilled_messages_equal_new_ones_and_read_back_the_same():
    """The simulator, tracker and isolation controller refill one message per topic; the
    helpers write float64 arrays in bulk and read them back by position when the names are in
    order: the same bytes and values as a new message filled field by field."""
    import array

    from builtin_interfaces.msg import Time
    from geometry_msgs.msg import PoseStamped
    from rclpy.serialization import serialize_message
    from sensor_msgs.msg import JointState

    from cable_robot_pkg.fast.ros_messages import (
        LEG_NAMES,
        joint_state_msg,
        joint_vector,
        pose_from_msg,
        pose_msg,
    )
    from paramotion.rotations import matrix_from_quat, matrix_from_rotvec, quat_from_matrix
    rng = np.random.default_rng(11)
    kept_pose, kept_joints = PoseStamped(), JointState()
    for k in range(50):
        stamp = Time(sec=k, nanosec=5_000_000 * k)
        p, R = rng.normal(size=3), matrix_from_rotvec(rng.normal(size=3))
        want = PoseStamped()
        want.header.stamp, want.header.frame_id = stamp, 'map'
        want.pose.position.x, want.pose.position.y, want.pose.position.z = (float(v) for v in p)
        o = want.pose.orientation
        o.x, o.y, o.z, o.w = (float(v) for v in quat_from_matrix(R))
        got = pose_msg(stamp, 'map', p, R, msg=kept_pose)
        assert got is kept_pose
        assert serialize_message(got) == serialize_message(want)
        back_p, back_R = pose_from_msg(got)
        assert np.array_equal(back_p, p)
        assert np.array_equal(back_R, matrix_from_quat([o.x, o.y, o.z, o.w]))
        q, v, f = (rng.normal(size=6) for _ in range(3))
        want = JointState()
        want.header.stamp, want.name = stamp, list(LEG_NAMES)
        want.position, want.velocity, want.effort = ([float(x) for x in a] for a in (q, v, f))
        got = joint_state_msg(stamp, LEG_NAMES, q, v, f, msg=kept_joints)
        assert isinstance(got.position, array.array)
        assert serialize_message(got) == serialize_message(want)
        for field, a in (('position', q), ('velocity', v), ('effort', f)):
            assert np.array_equal(joint_vector(got, LEG_NAMES, field), a)   # names in order
            shuffled = list(reversed(LEG_NAMES))                            # by name
            assert np.array_equal(joint_vector(got, shuffled, field), a[::-1])
    assert joint_vector(kept_joints, LEG_NAMES + ['leg7']) is None
    nan_msg = PoseStamped()
    nan_msg.pose.orientation.w = math.nan
    assert np.isnan(pose_from_msg(nan_msg)[1]).all()
    zero = PoseStamped()
    zero.pose.orientation.w = 0.0
    assert np.isnan(pose_from_msg(zero)[1]).all()          # zero quaternion


def test_history_lookups_by_bisection_equal_the_linear_search():
    """``TargetHistory.at`` bisects the target times while they increase (the trajectory's
    stamps) and walks the items otherwise; ``SampleHistory.at`` bisects its times: both give
    what the walk over every item gives."""
    from cable_robot_pkg.fast.isolation import SampleHistory, TargetHistory
    rng = np.random.default_rng(4)
    for ordered in (True, False):
        hist, walk = TargetHistory(), TargetHistory()
        t = 0.0
        for _ in range(250):
            t += rng.choice([0.01, 0.0, 0.004]) if ordered else rng.normal(0.01, 0.01)
            p, R = rng.normal(size=3), rng.normal(size=(3, 3))
            hist.add(t, p, R)
            walk.add(t, p, R)
            walk.ordered = False                  # force the walk over every item
            assert hist.ordered == ordered or not ordered
            for q in (t - 0.02, t - 0.5, t + 0.1, t - 2.0, t, t - rng.random()):
                a, b = hist.at(q), walk.at(q)
                assert np.array_equal(a[0], b[0]) and np.array_equal(a[1], b[1])
        assert hist.ordered == ordered
    samples = SampleHistory()
    t = 0.0
    for _ in range(300):
        t += abs(rng.normal(0.005, 0.003))
        samples.add(t, rng.normal(size=6))
        times, values = list(samples.times), list(samples.values)
        for q in (t - 0.02, t - 0.3, t + 0.01, t - rng.random() * 0.5):
            got = samples.at(q)
            k = int(np.searchsorted(np.array(times), q))
            if got is None:
                assert q < times[0] - 0.02 or q > times[-1] + 0.02
                continue
            if 0 < k < len(times):
                w = (q - times[k - 1]) / max(times[k] - times[k - 1], 1e-12)
                want = (1.0 - w) * values[k - 1] + w * values[k]
            else:
                want = values[0] if k <= 0 else values[-1]
            assert np.array_equal(got, want)


def test_isolation_replay_times_the_controller_on_the_recorded_calls():
    """``bench.isolation_replay`` replays a loop run's controller calls on fresh controllers:
    every replay commands the same legs (it raises otherwise) and the figure is a CPU time."""
    from cable_robot_pkg.fast.bench import isolation_replay
    r = isolation_replay(0.5, repeat=2)
    assert r['calls'] > 400 and 0.0 < r['cpu_s_per_sim_s'] < 10.0
    assert len(r['commands']) == 12
