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
                pl.winch_rates, pl.slack, pl.wind_force, pl.wind_torque]))
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
