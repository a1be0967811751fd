"""The FAST hot paths give what their straightforward formulations give.

Each optimised per-step function is compared with a reference written the plain way (the
numpy path, or the textbook formula) on random inputs or along a simulated trajectory. Speed
itself is measured by ``paramotion bench --only fast`` and ``cable_robot_pkg.fast.bench``.
"""
import numpy as np
import pytest

from cable_robot_pkg.fast.configuration import load_config
from cable_robot_pkg.fast.plant import FeedSupportPlant, make_client
from cable_robot_pkg.fast.wind import WindModel


def _plant_trajectory(cfg, backend, monkeypatch, wind_intensity=2.0, steps=300):
    """Plant state along ``steps`` physics steps with random set-points, on ``backend``."""
    monkeypatch.setenv('PARAMOTION_BACKEND', backend)
    client = make_client()
    try:
        wind = None if wind_intensity is None else WindModel.from_config(
            cfg.raw['wind'], cfg.raw['trolley'], intensity=wind_intensity)
        pl = FeedSupportPlant(cfg, client, wind=wind)
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
