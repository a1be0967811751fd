"""FAST across processes: the simulator one control period ahead of its controllers.

``launch/fast.launch.xml`` publishes the simulator's state every 10 ms across processes (5 ms
lock-step), states the tracker's and the isolation controller's rates that period allows
(100 Hz, 200 Hz lock-step) and sets ``sync_max_lag`` to one publish period: the simulator steps
the next period while the control container answers the last, so the two processes run at once
instead of one after the other (docs/fast.md, Speed). These tests pin those defaults, that the
stated rates are the rates the graph runs, what a period of lag means for a clock source, and
that the isolation controller does not reschedule its base predictor on the delay jitter a
period of lag brings.
"""
import math

import numpy as np
import pytest

from cable_robot_pkg.fast.configuration import load_config
from cable_robot_pkg.fast.isolation import IsolationController
from paramotion.graph import Graph
from paramotion.launch import compose
from paramotion.launch_xml import load as load_launch

MS = 1_000_000


def _source_class():
    from paramotion.clock import ClockSourceNode

    class Source(ClockSourceNode):
        def __init__(self, **kwargs):
            super().__init__('pipelined_source', **kwargs)
    return Source


def _defaults(**args):
    """(publish period, sync_max_lag, tracker rate, isolation rate) the launch file gives."""
    nodes = {n.label: n.params for n in load_launch('fast', args).nodes}
    sim = nodes['fast_sim']
    if 'fast_control_container' in nodes:
        box = nodes['fast_control_container']
        rates = box['fast_tracker.rate'], box['fast_isolation_controller.rate']
    else:
        rates = nodes['fast_tracker']['rate'], nodes['fast_isolation_controller']['rate']
    return (sim['publish_period'], sim['sync_max_lag']) + rates


def test_launch_default_lets_the_simulator_run_one_period_ahead():
    """Across processes: 10 ms, the tracker and the isolation controller at the 100 Hz that
    period allows, one period of lag; lock-step (``paramotion fast``): 5 ms and 200 Hz, the
    nodes' own defaults. Another period gives the rates it allows, at most 200 Hz."""
    assert _defaults() == (0.01, 0.01, 100.0, 100.0)
    assert _defaults(composed=False) == (0.01, 0.01, 100.0, 100.0)
    assert _defaults(lockstep=True) == (0.005, 0.005, 200.0, 200.0)
    assert _defaults(publish_period=0.005) == (0.005, 0.005, 200.0, 200.0)
    assert _defaults(publish_period=0.004) == (0.004, 0.004, 200.0, 200.0)
    assert _defaults(publish_period=0.02, sync_max_lag=0.0, isolation_rate=60.0) == \
        (0.02, 0.0, 50.0, 60.0)


def _launched_lockstep(duration, **args):
    """The launch file's separate control nodes (``composed:=false``) run lock-step for
    ``duration`` sim s: the feed position after every period, and how many times the tracker
    captured and the isolation controller updated."""
    desc = load_launch('fast', {'composed': False, 'lockstep': False, **args})
    feed = []
    with Graph() as graph:
        nodes = compose(graph, desc, extra_params={'fast_sim': {
            'lockstep': True, 'wait_for_clock_subscribers': 0, 'wait_for_matched': ['']}})
        sim = nodes['fast_sim']
        counts = {}
        for label in ('fast_tracker', 'fast_isolation_controller'):
            node = nodes[label]

            def counted(*a, _tick=node._tick, _label=label):
                counts[_label] = counts.get(_label, 0) + 1
                return _tick(*a)
            node._tick = counted
        graph.run_lockstep(sim, max_sim_time=duration, on_step=lambda: feed.append(
            tuple(sim.plant.feed_pose()[0]) + tuple(sim.plant.leg_lengths()[0])))
    return feed, counts


@pytest.mark.slow
def test_the_launched_rates_are_the_rates_the_graph_runs():
    """At the 10 ms default the tracker and the isolation controller act on every state
    message, 100 times per sim s, as their stated rate says; stating 200 Hz at that period
    changes nothing (bit-identical feed and legs): the clock caps it at 100 Hz."""
    stated, counts = _launched_lockstep(1.0)
    capped, capped_counts = _launched_lockstep(1.0, tracker_rate=200.0, isolation_rate=200.0)
    assert len(stated) == 100
    assert counts == {'fast_tracker': 100, 'fast_isolation_controller': 100}
    assert capped_counts == counts
    assert capped == stated
    _, fast_counts = _launched_lockstep(0.2, publish_period=0.005)
    assert fast_counts == {'fast_tracker': 40, 'fast_isolation_controller': 40}


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
