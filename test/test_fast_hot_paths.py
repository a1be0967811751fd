"""The FAST hot paths give what their straightforward formulations give.

Each optimised per-step function is compared with a reference written the plain way (the
numpy path, or the textbook formula) on random inputs or along a simulated trajectory. Speed
itself is measured by ``paramotion bench --only fast`` and ``cable_robot_pkg.fast.bench``.
"""
import math

import numpy as np
import pytest

from cable_robot_pkg.fast.configuration import load_config
from cable_robot_pkg.fast.plant import FeedSupportPlant, make_client
from cable_robot_pkg.fast.wind import WindModel


def _plant_trajectory(cfg, backend, monkeypatch, wind_intensity=2.0, steps=300,
                      compile_first=False):
    """Plant state along ``steps`` physics steps with random set-points, on ``backend``
    (``compile_first``: after ``compile_step``, as the simulator node builds it)."""
    monkeypatch.setenv('PARAMOTION_BACKEND', backend)
    client = make_client()
    try:
        wind = None if wind_intensity is None else WindModel.from_config(
            cfg.raw['wind'], cfg.raw['trolley'], intensity=wind_intensity)
        pl = FeedSupportPlant(cfg, client, wind=wind)
        if compile_first:
            pl.compile_step()
        rng = np.random.default_rng(7)
        out = []
        for k in range(steps):
            if k % 25 == 0:
                n = pl.cables.n
                # Winch set-points far enough off that the speed limit binds on some.
                pl.set_winch_command(pl.unstretched + rng.normal(0, 5e-3, n),
                                     rng.normal(0, 1e-2, n), pl.t - 0.003)
                pl.set_leg_command(pl.nominal_lengths + rng.normal(0, 2e-2, 6),
                                   rng.normal(0, 1e-2, 6), pl.t - 0.001)
                if k % 50 == 0:
                    pl.set_hinge_command(*(pl.hinge_cmd + rng.normal(0, 1e-3, 2)))
            pl.step()
            out.append(np.concatenate([
                pl.trolley_pose()[0], pl.trolley_pose()[1].ravel(), pl.feed_pose()[0],
                pl.upper_pose()[0], pl.leg_lengths()[0], pl.leg_lengths()[2],
                pl.hinge_angles(), pl.last_tensions, pl.last_lengths, pl.unstretched,
                pl.winch_rates, pl.slack, pl.wind_force, pl.wind_torque, pl.tension_range,
                [pl.slack_count]]))
            assert pl.tension_range == (pl.last_tensions.min(), pl.last_tensions.max())
            assert pl.slack_count == np.count_nonzero(pl.slack)
        return np.array(out)
    finally:
        client.disconnect()


@pytest.mark.parametrize('config, wind', [('fast.yaml', 2.0), ('coupled.yaml', 1.0),
                                          ('fast.yaml', None), ('fast.yaml', 0.0)])
def test_compiled_plant_step_equals_the_numpy_step(config, wind, monkeypatch):
    """``plant_step`` (winches, cables, wind, leg targets in one compiled call) against the
    numpy step (``CableSystem.wrench`` and ``WindModel.wrench``), bit for bit, with the servo
    and the force leg drives, with wind, calm and without a wind model."""
    pytest.importorskip('numba')
    from pathlib import Path

    import cable_robot_pkg.fast as pkg
    cfg = load_config(Path(pkg.__file__).parent / 'config' / config)
    fast = _plant_trajectory(cfg, 'numba', monkeypatch, wind)
    ref = _plant_trajectory(cfg, 'numpy', monkeypatch, wind)
    assert np.all(np.isfinite(fast))
    assert np.ptp(fast[:, 0]) > 0.0                     # the trolley moved
    assert np.array_equal(fast, ref)


def test_compiling_the_step_ahead_changes_nothing_of_the_run(monkeypatch):
    """``compile_step`` (the simulator node's start-up call) throws its results away and
    leaves the wind's generator alone: the run after it is the run without it, bit for bit."""
    pytest.importorskip('numba')
    from pathlib import Path

    import cable_robot_pkg.fast as pkg
    cfg = load_config(Path(pkg.__file__).parent / 'config' / 'fast.yaml')
    ahead = _plant_trajectory(cfg, 'numba', monkeypatch, 2.0, steps=200, compile_first=True)
    plain = _plant_trajectory(cfg, 'numba', monkeypatch, 2.0, steps=200)
    assert np.ptp(ahead[:, 0]) > 0.0
    assert np.array_equal(ahead, plain)


def test_the_simulator_node_compiles_its_kernels_while_it_starts(tmp_path):
    """In a fresh process, building the simulator node compiles (or loads) the plant step and
    dL/dt before any tick: its first physics step, which the controllers of a launch wait
    for, does not stall for the compiler."""
    pytest.importorskip('numba')
    import subprocess
    import sys
    code = (
        'import rclpy\n'
        'from cable_robot_pkg.fast import cable_kernel\n'
        'from cable_robot_pkg.fast.sim_node import FastSimNode\n'
        'ctx = rclpy.Context(); rclpy.init(context=ctx)\n'
        'kernels = (cable_kernel.plant_step, cable_kernel.cable_length_rates)\n'
        'before = [len(f.signatures) for f in kernels]\n'
        'node = FastSimNode(context=ctx)\n'
        'print(before, [len(f.signatures) for f in kernels])\n'
        'node.destroy_node()\n'
        'rclpy.shutdown(context=ctx)\n')
    r = subprocess.run([sys.executable, '-c', code], capture_output=True, text=True,
                       timeout=300, cwd=tmp_path)
    assert r.returncode == 0, r.stderr[-2000:]
    assert r.stdout.strip().splitlines()[-1] == '[0, 0] [1, 1]', r.stdout


def test_simulator_step_bookkeeping_equals_the_array_formulas():
    """``FastSimNode.step_physics`` counts slack and over-limit steps and keeps the tension
    extremes from the step's summary; the same as the array formulas on every step,
    including slack cables, tensions over the limit and NaN tensions."""
    from types import SimpleNamespace

    from cable_robot_pkg.fast.sim_node import FastSimNode
    rng = np.random.default_rng(9)
    n, t_max = 10, 5000.0

    class Plant:
        def step(self):
            t = rng.uniform(0.0, 6000.0, n) * (rng.random(n) > 0.1)
            if rng.random() < 0.1:
                t[rng.integers(n)] = np.nan
            self.last_tensions = t
            self.slack = t == 0.0
            self.slack_count = int(np.count_nonzero(self.slack))
            self.tension_range = (float(t.min()), float(t.max()))

    node = SimpleNamespace(plant=Plant(), slack_steps=np.zeros(n, int),
                           over_limit_steps=np.zeros(n, int), tension_min=np.inf,
                           tension_max=0.0)
    node.plant.t_max = t_max
    slack_steps, over_steps = np.zeros(n, int), np.zeros(n, int)
    t_min, t_hi = np.inf, 0.0
    for _ in range(500):
        FastSimNode.step_physics(node, 0.001)
        pl = node.plant
        slack_steps += pl.slack
        over_steps += pl.last_tensions > t_max
        t_min = min(t_min, float(pl.last_tensions.min()))
        t_hi = max(t_hi, float(pl.last_tensions.max()))
        assert np.array_equal(node.slack_steps, slack_steps)
        assert np.array_equal(node.over_limit_steps, over_steps)
        assert node.tension_min == t_min and node.tension_max == t_hi
    assert slack_steps.sum() > 0 and over_steps.sum() > 0


def test_compiled_step_summary_propagates_nan_as_numpy():
    """The compiled step's tension extremes are NaN when a tension is NaN (numpy's
    ``min``/``max``), and its slack count is the number of slack flags."""
    pytest.importorskip('numba')
    from cable_robot_pkg.fast.cable_kernel import plant_step
    cfg = load_config()
    c = cfg.cables
    n = c.n
    base_p = cfg.chain.coarse_targets(*cfg.track.pose(0.0))[0]
    L = c.lengths(base_p, np.eye(3))
    rng = np.random.default_rng(12)
    for lin in ([0.0, 0.0, 0.0], [np.nan, 0.0, 0.0]):
        L0 = L * (1.0 + rng.normal(0.0, 0.01, n))
        out, slack = np.empty(27 + 4 * n), np.empty(n, bool)
        plant_step(L0, np.zeros(n), 0.0, 1.0, 0.001, L0, c.attach.copy(), c.anchors,
                   c.anchor_mask, base_p, np.array(lin), np.zeros(3), c.EA, c.damping,
                   False, np.zeros(8), np.zeros((6, 1)), 0, np.zeros((6, 1)), 0, np.zeros(3),
                   np.full(6, 1.0), np.zeros(6), 0.0, 0.5, 2.0, np.zeros(6), out, slack)
        tensions = out[12:12 + n]
        lo, hi, count = out[24 + 4 * n:]
        want = (tensions.min(), tensions.max())
        assert np.array_equal([lo, hi], want, equal_nan=True)
        assert count == np.count_nonzero(slack) and 0 < count < n
    assert np.isnan(hi)


def test_wiener_predictions_and_peak_equal_the_formulas_while_the_history_changes():
    """``WienerPredictor.predict`` keeps its predictions per horizon and ``peak`` its value
    until the history or the weights change: every answer equals the formula evaluated
    afresh (``z_j + sum_l w_l (z_{j - l s} - z_j)``, linear between horizons; the largest
    fitted peak per group), through refits, extra views of a frame and a reset."""
    from cable_robot_pkg.fast.isolation import WienerPredictor
    rng = np.random.default_rng(21)
    period = 0.005
    wp = WienerPredictor(6, period, taps=8, spacing=2, window=4.0, refit=0.5, min_span=1.0,
                         peak_max=3.0)
    t = np.arange(0.0, 6.0, period)
    z = np.column_stack([np.sin(2 * np.pi * f * t) for f in (0.5, 0.8, 1.1, 1.4, 1.7, 2.0)])
    z += rng.normal(0.0, 1e-3, z.shape)
    checked = 0
    for j, stamp in enumerate(t):
        if j == 700:
            wp.reset()
        wp.add(stamp, z[j])
        if j % 3 == 0:
            wp.add(stamp, z[j] + rng.normal(0.0, 1e-3, 6))     # a second view of the frame
        for lead in (0.004, 0.006, 0.0, 0.0123, 0.004):
            got = wp.predict(stamp + lead)
            if got is None:
                continue
            h = max((stamp + lead - wp.last_stamp) / period, 0.0)
            n0 = int(np.floor(h + 1e-6))
            frac = h - n0 if h - n0 > 1e-6 else 0.0
            last = wp._buf[wp._n - 1]
            lags = wp._n - 1 - wp.spacing * np.arange(1, wp.taps)
            r = (wp._buf[lags] - last).T

            def at(n):
                return last if n == 0 else last + np.sum(wp.weights[n] * r, axis=1)
            want = at(n0) if frac == 0.0 else (1.0 - frac) * at(n0) + frac * at(n0 + 1)
            assert np.array_equal(got, want)
            checked += 1
        if wp.peaks:
            p = np.max(np.stack(list(wp.peaks.values())), axis=0)
            assert np.array_equal(wp.peak(), p.reshape(2, -1).max(axis=1))
    assert checked > 1000


def test_kalman_extrapolation_and_leg_clip_equal_the_formulas():
    """``ConstantAccelerationKF.predict`` keeps its transition matrices per horizon;
    ``IsolationController._clip`` checks floats: both equal the plain formulas."""
    from cable_robot_pkg.fast.isolation import (
        ConstantAccelerationKF,
        IsolationController,
        _transition,
    )
    rng = np.random.default_rng(5)
    kf = ConstantAccelerationKF(3, 10.0, 0.001)
    kf.reset(0.0, rng.normal(size=3))
    for k in range(1, 400):
        kf.update(0.005 * k, rng.normal(size=3))
        for lead in (0.02, 0.025, 0.02, 0.0031):
            for order in (1, 2, 2):
                F = _transition(0.005 * k + lead - kf.t)
                if order < 2:
                    F[0, 2] = F[1, 2] = 0.0
                assert np.array_equal(kf.predict(0.005 * k + lead, order), F @ kf.x)
    ctl = IsolationController.from_config(load_config())
    for _ in range(300):
        lengths = rng.uniform(ctl.lo - 0.02, ctl.hi + 0.02, 6)
        if rng.random() < 0.5:
            lengths = rng.uniform(ctl.lo, ctl.hi, 6)
        if rng.random() < 0.1:
            lengths[rng.integers(6)] = np.nan
        count = ctl.clip_count
        got, clipped = ctl._clip(lengths)
        want = bool(np.any(lengths < ctl.lo) or np.any(lengths > ctl.hi))
        assert clipped == want and ctl.clip_count == count + want
        assert np.array_equal(got, np.clip(lengths, ctl.lo, ctl.hi), equal_nan=True)
        assert got is not lengths


def test_rotation_helpers_give_the_plain_formulas():
    """``paramotion.rotations``: ``matrix_from_rotvec`` (floats read in one call from a
    float64 3-vector) equals Rodrigues' formula written out, for arrays, lists, integer
    arrays and longer vectors; ``rotvec_from_matrix`` equals ``quaternion axis * angle``
    with the angle from libm's ``atan2``, bit for bit; both agree with scipy to 1e-12."""
    from scipy.spatial.transform import Rotation

    from paramotion.rotations import matrix_from_rotvec, quat_from_matrix, rotvec_from_matrix
    rng = np.random.default_rng(13)
    for k in range(2000):
        v = rng.normal(size=3) * 10.0 ** rng.uniform(-14, 0.5)
        for arg in (v, list(v), np.concatenate([v, [7.0]]), v.astype(np.float32),
                    np.round(3.0 * v).astype(int)):
            got = matrix_from_rotvec(arg)
            x, y, z = (float(c) for c in arg[:3])
            th = np.sqrt(x * x + y * y + z * z)
            if th >= 1e-12:
                kx, ky, kz = x / th, y / th, z / th
                c, s = np.cos(th), np.sin(th)
                C = 1.0 - c
                want = np.array([
                    [c + kx * kx * C, kx * ky * C - kz * s, kx * kz * C + ky * s],
                    [ky * kx * C + kz * s, c + ky * ky * C, ky * kz * C - kx * s],
                    [kz * kx * C - ky * s, kz * ky * C + kx * s, c + kz * kz * C]])
            else:
                want = np.array([[1.0, -z, y], [z, 1.0, -x], [-y, x, 1.0]])
            assert np.array_equal(got, want)
        assert np.allclose(matrix_from_rotvec(v), Rotation.from_rotvec(v).as_matrix(),
                           rtol=0.0, atol=1e-12)
        R = matrix_from_rotvec(v)
        qx, qy, qz, qw = quat_from_matrix(R)
        if qw < 0.0:
            qx, qy, qz, qw = -qx, -qy, -qz, -qw
        # libm's sqrt and atan2, as the helper uses: numpy's own arctan2 differs from libm's
        # in the last bit on some machines (SIMD kernels), which is no change of formula
        s = math.sqrt(qx * qx + qy * qy + qz * qz)
        want = np.array([2.0 * qx, 2.0 * qy, 2.0 * qz]) if s < 1e-12 else \
            np.array([qx, qy, qz]) * (2.0 * math.atan2(s, qw) / s)
        assert np.array_equal(rotvec_from_matrix(R), want)
        assert np.allclose(rotvec_from_matrix(R), Rotation.from_matrix(R).as_rotvec(),
                           rtol=0.0, atol=1e-12)


def _lone_covariance(q, r, dt, tol=1e-12, max_iter=60):
    """The doubling algorithm of ``steady_state_covariance`` for one process noise, plain."""
    from cable_robot_pkg.fast.isolation import _process_noise, _transition
    A = _transition(dt).T
    G = np.zeros((3, 3))
    G[0, 0] = 1.0 / r
    H = _process_noise(q, dt)
    for _ in range(max_iter):
        W = np.linalg.inv(np.eye(3) + G @ H)
        A, G, H_next = A @ W @ A, G + A @ W @ G @ A.T, H + A.T @ H @ W @ A
        done = np.abs(H_next - H).max() <= tol * np.abs(H_next).max()
        H = H_next
        if done:
            break
    return H


def test_stacked_predictor_responses_equal_lone_ones():
    """The predictor schedule evaluates its 32 candidate bandwidths stacked
    (``steady_state_covariances``, ``predictor_responses``): each covariance and response
    equals the one computed alone with 3x3 matrices, bit for bit."""
    from cable_robot_pkg.fast.isolation import (
        _transition,
        predictor_response,
        predictor_responses,
        steady_state_covariances,
    )
    rng = np.random.default_rng(17)
    for _ in range(12):
        r, dt, tau = 10 ** rng.uniform(-9, -5), rng.uniform(0.003, 0.02), rng.uniform(0.01, 0.08)
        qs = 10 ** rng.uniform(0, 2) * np.logspace(0.0, -12.0, 32)
        freqs = np.geomspace(0.05, 0.5 / dt, 60)
        covariances = steady_state_covariances(qs, r, dt)
        responses = predictor_responses(qs, r, dt, tau, freqs)
        for q, P, H in zip(qs, covariances, responses):
            assert np.array_equal(P, _lone_covariance(q, r, dt))
            K = P[:, 0] / (P[0, 0] + r)
            A = (np.eye(3) - np.outer(K, [1.0, 0.0, 0.0])) @ _transition(dt)
            z = np.exp(2j * np.pi * freqs * dt)
            M = z[:, None, None] * np.eye(3) - A
            X = np.linalg.solve(M, np.broadcast_to(K, (len(z), 3))[..., None])[..., 0] \
                * z[:, None]
            want = (X @ np.array([1.0, tau, 0.5 * tau * tau])) \
                * np.exp(-2j * np.pi * freqs * tau)
            assert np.array_equal(H, want)
            assert np.array_equal(predictor_response(q, r, dt, tau, freqs), want)


def test_the_isolation_node_compiles_its_kernels_while_it_starts(tmp_path):
    """In a fresh process, building the isolation controller node compiles (or loads) the
    forward kinematics kernel of its base views before any message: the first tracker frame
    does not stall for about a second while a launched simulator waits for the legs."""
    pytest.importorskip('numba')
    import subprocess
    import sys
    code = (
        'import rclpy\n'
        'from paramotion import gough_stewart_numba\n'
        'from cable_robot_pkg.fast.isolation_node import IsolationNode\n'
        'ctx = rclpy.Context(); rclpy.init(context=ctx)\n'
        'kernel = gough_stewart_numba.fk_single_kernel\n'
        'before = len(kernel.signatures)\n'
        'node = IsolationNode(context=ctx)\n'
        'print(before, len(kernel.signatures))\n'
        'node.destroy_node()\n'
        'rclpy.shutdown(context=ctx)\n')
    r = subprocess.run([sys.executable, '-c', code], capture_output=True, text=True,
                       timeout=300, cwd=tmp_path)
    assert r.returncode == 0, r.stderr[-2000:]
    assert r.stdout.strip().splitlines()[-1] == '0 1', r.stdout


def _isolation_run(cfg, warm_up, steps=400):
    """Leg commands of a ``predictive`` controller fed a synthetic vibrating base, its feed
    and trolley views and encoders (the frames 20 ms late), with or without
    ``compile_kernels`` first."""
    from cable_robot_pkg.fast.isolation import IsolationController
    from paramotion.rotations import matrix_from_rotvec
    ctl = IsolationController.from_config(cfg, mode='predictive')
    if warm_up:
        ctl.compile_kernels()
    p_nom, R_nom = cfg.chain.nominal_relative_pose()
    out = []
    for k in range(steps):
        t = 0.005 * k
        stamp = t - 0.02
        ctl.add_leg_state(t, ctl.nominal_lengths + 1e-3 * np.sin(3.0 * t + np.arange(6)))
        ctl.add_hinge_state(t, [0.01 * np.sin(t), 0.0])
        if k % 2 == 0:
            ctl.set_target(t, *cfg.track.pose(t))
        if stamp >= 0.0:
            p_b = 0.01 * np.array([np.sin(7.0 * stamp), np.cos(5.0 * stamp), 0.0])
            R_b = matrix_from_rotvec([0.002 * np.sin(6.0 * stamp), 0.0, 0.001])
            ctl.add_base(t, stamp, p_b, R_b)
            ctl.add_feed(t, stamp, p_b + R_b @ p_nom, R_b @ R_nom)
        cmd = ctl.update(t)
        out.append(np.concatenate([cmd.lengths, cmd.rates, [cmd.holding]]))
    return np.array(out)


def test_compiling_the_isolation_kernels_ahead_changes_nothing():
    """``IsolationController.compile_kernels`` (the node's start-up call) throws its solve
    away: the controller's commands after it are those without it, bit for bit."""
    cfg = load_config()
    ahead, plain = _isolation_run(cfg, True), _isolation_run(cfg, False)
    assert np.ptp(ahead[:, 0]) > 0.0 and not ahead[-1, -1]     # the legs moved, not holding
    assert np.array_equal(ahead, plain)


def test_kalman_covariances_kept_per_input_equal_the_formulas():
    """``ConstantAccelerationKF.update`` keeps each covariance step's result by its input
    (covariance, step, noise): state and covariance equal the plain Kalman formulas bit for
    bit, along steps that revisit covariances, views sharing a stamp, a change of the process
    noise (a re-schedule) and a reset; the kept arrays are read-only."""
    from cable_robot_pkg.fast.isolation import (
        ConstantAccelerationKF,
        _process_noise,
        _transition,
    )
    rng = np.random.default_rng(29)
    kf = ConstantAccelerationKF(3, 20.0, 0.001)
    kf.reset(0.0, rng.normal(size=3))
    x, P, t = kf.x.copy(), kf.P.copy(), 0.0
    hits = 0
    clock = 0.0
    for k in range(1, 1500):
        if k == 700:
            kf.q = 3.0
        if k == 1100:
            z = rng.normal(size=3)
            kf.reset(t, z)
            x, P = kf.x.copy(), kf.P.copy()
        for _ in range(10 if k in (400, 900) else 5):   # stamps as the simulator's clock
            clock += 0.001                                # makes them, two frames dropped
        stamp = clock
        for _ in range(1 + (k % 3 != 0) * 2):          # most frames seen three times
            z = rng.normal(size=3)
            dt = stamp - t
            if dt > 0:
                F, Q = _transition(dt), _process_noise(kf.q, dt)
                x, P, t = F @ x, F @ P @ F.T + Q, stamp
            before = len(kf._fused) + len(kf._predicted)
            kf.update(stamp, z)
            hits += len(kf._fused) + len(kf._predicted) == before
            K = P[:, 0] / (P[0, 0] + kf.r)
            x = x + np.outer(K, z - x[0])
            P = P - np.outer(K, P[0])
            assert np.array_equal(kf.x, x) and np.array_equal(kf.P, P)
    assert hits > 600                                  # the kept results were used
    with pytest.raises(ValueError):
        kf.P[0, 0] = 1.0


def test_simulator_state_diagnostics_equal_the_array_formulas():
    """``FastSimNode.publish_state`` counts legs at a stroke end and names the slack cables,
    those over the tension limit and the legs at a stroke end from the step's summary and
    float tests: the counts and the warning equal the array formulas' on every publish,
    including NaN tensions and NaN leg lengths."""
    from collections import defaultdict
    from types import SimpleNamespace

    from cable_robot_pkg.fast.ros_messages import LEG_NAMES
    from cable_robot_pkg.fast.sim_node import FastSimNode
    rng = np.random.default_rng(41)
    n, t_max, leg_min, leg_max = 10, 5000.0, 0.9, 1.3
    names = [f'c{i}' for i in range(n)]
    warnings = []

    class Pub:
        def publish(self, msg):
            pass

        def get_subscription_count(self):
            return 0

    pose = (np.zeros(3), np.eye(3))
    pl = SimpleNamespace(geom=SimpleNamespace(leg_min=leg_min, leg_max=leg_max),
                         t_max=t_max, trolley_pose=lambda: pose, upper_pose=lambda: pose,
                         feed_pose=lambda: pose, trolley_velocity=lambda: (np.zeros(3),) * 2,
                         hinge_angles=lambda: np.zeros(2), unstretched=np.ones(n),
                         winch_rates=np.zeros(n), last_lengths=np.ones(n))
    node = SimpleNamespace(
        plant=pl, pubs={k: Pub() for k in ('truth_trolley', 'truth_upper', 'truth_feed',
                                             'cables_state', 'winches_state', 'legs_state',
                                             'orienting_state', 'wind', 'diagnostics')},
        msgs=defaultdict(lambda: None), stamp=lambda: None, cable_names=names,
        stroke_steps=np.zeros(6, int),
        cfg=SimpleNamespace(cables=SimpleNamespace(length_rates=lambda *a: np.zeros(n))),
        sim_time=0.0, _last_diag=-1.0,
        get_logger=lambda: SimpleNamespace(warning=warnings.append))
    stroke = np.zeros(6, int)
    for k in range(400):
        t = rng.uniform(0.0, 5400.0, n) * (rng.random(n) > 0.05)
        if rng.random() < 0.1:
            t[rng.integers(n)] = np.nan
        q = rng.uniform(leg_min + 0.0005, leg_max - 0.0005, 6) if rng.random() < 0.5 else \
            rng.uniform(leg_min + 0.002, leg_max - 0.002, 6)
        if rng.random() < 0.1:
            q[rng.integers(6)] = np.nan
        pl.last_tensions, pl.slack = t, t == 0.0
        pl.slack_count, pl.tension_range = int(np.count_nonzero(pl.slack)), (t.min(), t.max())
        pl.leg_lengths = lambda q=q: (q, np.zeros(6), np.zeros(6))
        node.sim_time = float(k)          # a warning may come on every publish
        before = len(warnings)
        FastSimNode.publish_state(node)
        at_end = (q <= leg_min + 1e-3) | (q >= leg_max - 1e-3)
        stroke += at_end
        over = t > t_max
        problems = []
        if pl.slack.any():
            problems.append('slack: ' + ', '.join(c for c, s in zip(names, pl.slack) if s))
        if over.any():
            problems.append('over tension limit: ' + ', '.join(
                c for c, o in zip(names, over) if o))
        if at_end.any():
            problems.append('at stroke end: ' + ', '.join(
                c for c, e in zip(LEG_NAMES, at_end) if e))
        assert np.array_equal(node.stroke_steps, stroke)
        assert warnings[before:] == (['; '.join(problems)] if problems else [])
    assert stroke.sum() > 0 and len(warnings) > 100
