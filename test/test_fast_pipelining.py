"""FAST across processes: the simulator one control period ahead of its controllers.

``launch/fast.launch.xml`` sets ``sync_max_lag`` to one publish period (0.005 s): the simulator
steps the next period while the control container answers the last, so the two processes run
at once instead of one after the other (docs/performance.md). These tests pin what that lag
means for a clock source, and that the isolation controller does not reschedule its base
predictor on the delay jitter a period of lag brings.
"""
import math

import numpy as np

from cable_robot_pkg.fast.configuration import load_config
from cable_robot_pkg.fast.isolation import IsolationController
from paramotion.graph import Graph
from paramotion.launch_xml import load as load_launch

MS = 1_000_000


def _source_class():
    from paramotion.clock import ClockSourceNode

    class Source(ClockSourceNode):
        def __init__(self, **kwargs):
            super().__init__('pipelined_source', **kwargs)
    return Source


def test_launch_default_lets_the_simulator_run_one_period_ahead():
    desc = load_launch('fast', {})
    sim = desc.nodes[0]
    assert sim.params['sync_max_lag'] == sim.params['publish_period'] == 0.005


def _held_at(lag_s):
    """Where a free-running source stops while the answer to the state of ``held`` is out."""
    with Graph() as graph:
        src = graph.add(_source_class(), lockstep=False, real_time_factor=0.0,
                        publish_period=0.01, sync_max_lag=lag_s, sync_timeout=5.0)
        graph.spin_wall(0.2)
        held = src.sim_time_ns
        src.answered('ctl', held - 20 * MS)
        src.answered('ctl', held - 10 * MS)        # period 10 ms: the answer to `held` is due
        graph.spin_wall(0.2)
        stopped = src.sim_time_ns - held
        src.answered('ctl', held)                  # answered: one more period is free
        graph.spin_wall(0.2)
        return stopped, src.sim_time_ns - held


def test_a_period_of_lag_steps_one_period_past_the_state_whose_answer_is_out():
    """With ``sync_max_lag`` 0 the source stops at the state it awaits the answer to; with one
    period of lag it steps exactly one period further (that period's physics overlaps the
    controller's answer), and never more; each answer frees one more period."""
    assert _held_at(0.0) == (0, 10 * MS)
    assert _held_at(0.01) == (10 * MS, 20 * MS)


def _schedules(delays):
    """Schedules of a ``predictive`` controller fed upper-platform frames every 5 ms that
    arrive ``delays`` (cycled) after capture."""
    cfg = load_config()
    ctl = IsolationController.from_config(cfg, mode='predictive')
    count = 0
    for k in range(400):
        stamp = 0.005 * k
        p = np.array([0.0, 0.0, 0.001 * math.sin(2 * math.pi * 0.5 * stamp)])
        ctl.add_base(stamp + delays[k % len(delays)], stamp, p, np.eye(3))
        if k >= 10 and ctl.schedule():
            count += 1
    return count, ctl._scheduled[0]


def test_delay_jitter_below_a_frame_period_does_not_reschedule_but_a_latency_change_does():
    """Across processes the controller's clock moves in 5 ms steps, so a 20 ms latency is
    measured as 15 to 25 ms (in runs, as the container falls behind and catches up); the
    schedule (64 predictor responses) follows the latency, not that jitter. A latency that
    does change (20 -> 40 ms) is rescheduled."""
    steady, _ = _schedules([0.02])
    jitter, _ = _schedules([0.015] * 10 + [0.025] * 10)    # runs of 50 ms
    assert jitter == steady
    changed, horizon = _schedules([0.02] * 200 + [0.04] * 200)
    assert changed > steady and horizon > 0.035
