"""One process, one executor, lock-step sim time: the smoke graph end to end."""
import random
import time

import pytest
from rclpy.parameter import Parameter

from paramotion.bag.reader import read_messages
from paramotion.graph import Graph
from paramotion.smoke.controller_node import SmokeControllerNode
from paramotion.smoke.range_sensor_node import SmokeRangeSensorNode
from paramotion.smoke.scenario import run_lockstep
from paramotion.smoke.sim_node import SmokeSimNode


def test_smoke_graph_reaches_target_on_sim_time(tmp_path):
    result = run_lockstep(tmp_path / 'bag', duration=8.0)
    assert abs(result['sim_time_s'] - 8.0) < 1e-9
    assert abs(result['final_gap_m'] - result['target_gap_m']) < 0.02
    assert result['controller_state'] == 'tracking'
    # 20 Hz sensor on sim time: 160 periods, the first before any pose arrived
    assert 155 <= result['readings'] <= 160


@pytest.mark.slow
def test_lockstep_results_do_not_depend_on_wall_clock_speed(tmp_path):
    """Two runs, one slowed down at random between steps, record identical messages."""
    def run(bag, slow):
        rng = random.Random(3)
        with Graph() as graph:
            sim = graph.add(SmokeSimNode)
            graph.add(SmokeRangeSensorNode, noise_std=0.01)
            graph.add(SmokeControllerNode)
            graph.record(bag, ['/smoke/range', '/smoke/cmd_vel', '/smoke/ground_truth'])
            on_step = (lambda: time.sleep(rng.random() * 0.002)) if slow else None
            graph.run_lockstep(sim, max_sim_time=2.0, on_step=on_step)
    run(tmp_path / 'fast', False)
    run(tmp_path / 'slow', True)
    for topic in ['/smoke/range', '/smoke/cmd_vel', '/smoke/ground_truth']:
        a = [(m.log_time_ns, m.data) for m in read_messages(tmp_path / 'fast', [topic])]
        b = [(m.log_time_ns, m.data) for m in read_messages(tmp_path / 'slow', [topic])]
        assert a == b and a, topic


def test_each_reading_answered_within_the_same_step():
    """Drain runs chained callbacks: sensor -> controller -> simulator in one period."""
    with Graph() as graph:
        sim = graph.add(SmokeSimNode)
        graph.add(SmokeRangeSensorNode)
        ctl = graph.add(SmokeControllerNode)
        graph.run_lockstep(sim, max_sim_time=0.2)
        assert ctl.readings >= 3
        assert sim.command > 0.0  # the cart was commanded forward by the controller


def test_sensor_silence_stops_cart_and_recovery_resumes():
    with Graph() as graph:
        sim = graph.add(SmokeSimNode)
        sensor = graph.add(SmokeRangeSensorNode)
        ctl = graph.add(SmokeControllerNode)
        graph.run_lockstep(sim, max_sim_time=1.0)
        assert ctl.state == 'tracking'
        sensor.set_parameters([Parameter('dropout_probability', value=1.0)])
        graph.run_lockstep(sim, max_sim_time=2.0)
        assert ctl.state == 'sensor_timeout' and sim.command == 0.0
        stopped_at = sim.cart_x
        graph.run_lockstep(sim, max_sim_time=2.5)
        assert abs(sim.cart_x - stopped_at) < 0.01
        sensor.set_parameters([Parameter('dropout_probability', value=0.0)])
        graph.run_lockstep(sim, max_sim_time=3.0)
        assert ctl.state == 'tracking' and sim.cart_x > stopped_at + 0.1


def test_nan_readings_stop_the_cart():
    with Graph() as graph:
        sim = graph.add(SmokeSimNode)
        graph.add(SmokeRangeSensorNode, fault_probability=1.0)
        graph.add(SmokeControllerNode)
        graph.run_lockstep(sim, max_sim_time=1.0)
        assert abs(sim.cart_x) < 1e-3 and sim.command == 0.0


def test_node_renaming_and_topic_remapping():
    with Graph() as graph:
        sensor = graph.add(SmokeRangeSensorNode, name='front_sonar',
                           remappings={'/smoke/range': '/front/range'})
        assert sensor.get_name() == 'front_sonar'
        names = [n for n, _ in sensor.get_topic_names_and_types()]
        assert '/front/range' in names and '/smoke/range' not in names


def test_graph_uses_private_domain_unless_user_sets_one(monkeypatch):
    from paramotion.graph import private_domain_id
    monkeypatch.setenv('ROS_DOMAIN_ID', '42')
    assert private_domain_id() == 42
    monkeypatch.delenv('ROS_DOMAIN_ID')
    ids = {private_domain_id() for _ in range(20)}
    assert all(102 <= i <= 200 for i in ids) and len(ids) > 1


def test_drain_delivers_every_message_of_a_burst():
    """16 messages published at once on a reliable depth-32 topic all arrive in one drain."""
    import rclpy
    from rclpy.qos import QoSProfile
    from std_msgs.msg import Float64
    with Graph() as graph:
        talker = rclpy.create_node('talker', context=graph.context)
        listener = rclpy.create_node('listener', context=graph.context)
        for node in (talker, listener):
            graph.executor.add_node(node)
            graph.nodes.append(node)
        got = []
        listener.create_subscription(Float64, '/burst', lambda m: got.append(m.data),
                                     QoSProfile(depth=32))
        pub = talker.create_publisher(Float64, '/burst', QoSProfile(depth=32))
        graph.drain()
        for i in range(16):
            pub.publish(Float64(data=float(i)))
        assert graph.drain() == 16
        assert got == [float(i) for i in range(16)]


def ticker_class(period):
    """A sim-time node recording the clock time of each tick of a ``period`` s timer."""
    from paramotion.node import ParamotionNode

    class Ticker(ParamotionNode):
        def __init__(self, **kwargs):
            super().__init__('ticker', **kwargs)
            self.times = []
            self.create_timer(period, lambda: self.times.append(
                self.get_clock().now().nanoseconds))
    return Ticker


def clock_source_class(name):
    """A bare clock source named ``name`` (its wall timer, /clock, the sync gate)."""
    from paramotion.clock import ClockSourceNode

    class Source(ClockSourceNode):
        def __init__(self, **kwargs):
            super().__init__(name, **kwargs)
    return Source


def test_sim_time_timers_fire_on_time_with_the_new_clock():
    """A 0.1 s sim-time timer in a graph stepped every 0.01 s runs at 0.1, 0.2, ... and sees
    exactly that time (not the previous step's clock)."""
    Ticker = ticker_class(0.1)

    with Graph() as graph:
        sim = graph.add(SmokeSimNode, publish_period=0.01)
        ticker = graph.add(Ticker)
        graph.run_lockstep(sim, max_sim_time=1.0)
    assert ticker.times[-5:] == [600_000_000, 700_000_000, 800_000_000, 900_000_000,
                                 1_000_000_000]


@pytest.mark.slow
def test_private_graph_is_not_heard_from_outside(monkeypatch):
    """Without ROS_DOMAIN_ID a Graph turns discovery off: another context on the same domain
    never sees its publishers (no stray /clock can cross between runs)."""
    import rclpy
    from rosgraph_msgs.msg import Clock

    from paramotion.launch import wait_until
    monkeypatch.delenv('ROS_DOMAIN_ID')
    with Graph() as graph:
        assert graph.private
        sim = graph.add(SmokeSimNode)
        graph.run_lockstep(sim, max_sim_time=0.1)
        outside = rclpy.Context()
        rclpy.init(context=outside, domain_id=graph.domain_id)
        try:
            node = rclpy.create_node('outsider', context=outside)
            node.create_subscription(Clock, '/clock', lambda m: None, 1)
            heard = wait_until(lambda: node.count_publishers('/clock') > 0, timeout=3.0)
            node.destroy_node()
        finally:
            rclpy.try_shutdown(context=outside)
        assert not heard


def _smoke_bag(bag, executor):
    with Graph(executor=executor) as graph:
        sim = graph.add(SmokeSimNode)
        graph.add(SmokeRangeSensorNode, noise_std=0.01)
        graph.add(SmokeControllerNode)
        graph.record(bag, ['/clock', '/smoke/range', '/smoke/cmd_vel', '/smoke/ground_truth'])
        graph.run_lockstep(sim, max_sim_time=1.5)
        return graph.callbacks_run


@pytest.mark.slow
def test_lockstep_drain_records_what_the_single_threaded_executor_does(tmp_path):
    """The Graph's own drain runs the same callbacks in the same order as rclpy's
    SingleThreadedExecutor: every recorded message, with its receive time, is identical."""
    runs = {kind: _smoke_bag(tmp_path / kind, kind) for kind in ('single_threaded', 'lockstep')}
    assert runs['lockstep'] > 0
    for topic in ['/clock', '/smoke/range', '/smoke/cmd_vel', '/smoke/ground_truth']:
        a = [(m.log_time_ns, m.data) for m in read_messages(tmp_path / 'single_threaded', [topic])]
        b = [(m.log_time_ns, m.data) for m in read_messages(tmp_path / 'lockstep', [topic])]
        assert a == b and a, topic


def test_lockstep_graph_sets_node_clocks_without_their_clock_subscriptions():
    """In lock-step the Graph hands each node the new time: the nodes' own /clock
    subscriptions are gone, /clock is still published, and a sim-time timer still fires at
    exactly its period."""
    Ticker = ticker_class(0.05)

    with Graph() as graph:
        sim = graph.add(SmokeSimNode)
        ticker = graph.add(Ticker)
        assert '/clock' in [s.topic_name for s in ticker.subscriptions]
        graph.run_lockstep(sim, max_sim_time=0.2)
        assert '/clock' not in [s.topic_name for s in ticker.subscriptions]
        assert sim.get_publishers_info_by_topic('/clock')
    assert ticker.times == [50_000_000, 100_000_000, 150_000_000, 200_000_000]


def test_events_executor_runs_the_smoke_graph_on_time():
    """The EventsExecutor option: sim-time timers fire in the period they are due (the drain
    waits for the timer events its clock thread queues), and the controller stops the cart."""
    Ticker = ticker_class(0.1)

    with Graph(executor='events') as graph:
        sim = graph.add(SmokeSimNode)
        graph.add(SmokeRangeSensorNode)
        ctl = graph.add(SmokeControllerNode)
        ticker = graph.add(Ticker)
        graph.run_lockstep(sim, max_sim_time=8.0)
        assert ctl.state == 'tracking'
        assert abs(sim.cart_x - (5.0 - 0.2 - 1.0)) < 0.05
    assert ticker.times[:3] == [100_000_000, 200_000_000, 300_000_000]
    assert len(ticker.times) == 80


def test_unknown_executor_is_refused():
    import pytest
    with pytest.raises(ValueError, match='executor'):
        Graph(executor='threads')


def test_free_running_source_waits_for_its_controllers_answers_then_times_out():
    """sync_max_lag: once a controller has answered twice (its interval known), a free-running
    clock source does not advance while that controller's next answer has been due for longer
    than the lag; without it for sync_timeout wall seconds it advances anyway, and waits for
    it again once it answers again."""
    Source = clock_source_class('sync_source')

    ms = 1_000_000
    with Graph() as graph:
        src = graph.add(Source, lockstep=False, real_time_factor=0.0, publish_period=0.01,
                        sync_max_lag=0.0, sync_timeout=0.5)
        graph.spin_wall(0.3)
        assert src.sim_time_ns > 50 * ms              # nobody answered yet: free-running
        held = src.sim_time_ns
        src.answered('slow', held - 40 * ms)           # a controller at 50 Hz whose answer
        src.answered('slow', held - 20 * ms)           # to the state of `held` is due
        src.answered('fast', held)                     # one answer: no interval yet
        graph.spin_wall(0.2)
        assert src.sim_time_ns == held and src.sync_waits > 0
        start = time.monotonic()
        src.answered('slow', held)
        graph.spin_wall(0.2)
        assert src.sim_time_ns == held + 20 * ms       # one more interval, then waits again
        graph.spin_wall(2.0, until=lambda: src.sim_time_ns > held + 80 * ms)
        assert src.sim_time_ns > held + 80 * ms        # controller gone: advancing again
        assert time.monotonic() - start > 0.5 and src.given_up == {'slow'}
        src.answered('slow', held + 20 * ms)           # back, behind: waited for again
        assert not src.given_up
        back = src.sim_time_ns
        graph.spin_wall(0.2)
        assert src.sim_time_ns == back


def test_waiting_source_says_its_time_again_at_most_every_sync_repeat():
    """While a free-running source waits for an answer it publishes its (unchanged) time on
    /clock again, for a reader that lost the best-effort sample, but at most once per
    ``sync_repeat`` wall seconds, not at every tick of its wall timer."""
    from rosgraph_msgs.msg import Clock

    from paramotion.qos import CLOCK_QOS

    Source = clock_source_class('repeat_source')

    def repeats(sync_repeat):
        with Graph() as graph:
            src = graph.add(Source, lockstep=False, real_time_factor=0.0, publish_period=0.01,
                            sync_max_lag=0.0, sync_timeout=5.0, sync_repeat=sync_repeat)
            heard = []
            listener = graph.add(ticker_class(1.0))
            listener.create_subscription(Clock, '/clock', heard.append, CLOCK_QOS)
            graph.spin_wall(0.1)
            held = src.sim_time_ns
            src.answered('ctl', held - 20_000_000)
            src.answered('ctl', held - 10_000_000)     # next answer due at `held`: waits
            graph.spin_wall(0.05)
            assert src.sim_time_ns == held
            heard.clear()
            graph.spin_wall(0.5)
            assert src.sim_time_ns == held and src.sync_waits > 20
            return len(heard)

    assert 2 <= repeats(0.2) <= 4
    assert repeats(0.001) > 20


def test_waiting_source_gates_expected_controllers_before_their_period_is_known():
    """sync_expect / sync_first_by: an expected controller that has not answered holds the
    source at sync_first_by; one that answered once holds it sync_first_by after that
    answer (its period is known only from its second answer); without sync_expect nothing
    holds a source whose controllers have not answered."""
    Source = clock_source_class('first_source')

    ms = 1_000_000
    with Graph() as graph:
        src = graph.add(Source, lockstep=False, real_time_factor=0.0, publish_period=0.01,
                        sync_max_lag=0.0, sync_timeout=5.0, sync_first_by=0.1,
                        sync_expect=['ctl'])
        graph.spin_wall(0.3)
        assert src.sim_time_ns == 100 * ms and src.sync_waits > 0
        src.answered('ctl', 30 * ms)
        graph.spin_wall(0.2)
        assert src.sim_time_ns == 130 * ms
        src.answered('ctl', 50 * ms)                   # period 20 ms: overdue since 70 ms
        graph.spin_wall(0.2)
        assert src.sim_time_ns == 130 * ms
        src.answered('ctl', 110 * ms)
        src.answered('ctl', 130 * ms)                  # median interval 20 ms
        graph.spin_wall(0.2)
        assert src.sim_time_ns == 150 * ms
        free = graph.add(Source, name='free_source', lockstep=False, real_time_factor=0.0,
                         publish_period=0.01, sync_max_lag=0.0, sync_first_by=0.1)
        graph.spin_wall(0.3)
        assert free.sim_time_ns > 150 * ms


def test_waiting_source_advances_on_the_answer_not_on_its_next_wall_tick():
    """A source holding for an answer advances right after the answering callback (once it
    has applied the command), not up to a wall-timer period later, and never faster than
    real_time_factor: here a tick every 2 s of wall time, the answer's advance within 1 s
    (half a tick: a machine busy with other tests may delay a callback by a few hundred ms);
    the next one waits for the next answer."""
    Source = clock_source_class('answer_source')
    ms = 1_000_000
    with Graph() as graph:
        src = graph.add(Source, lockstep=False, real_time_factor=0.005, publish_period=0.01,
                        sync_max_lag=0.0, sync_timeout=60.0)
        src.answered('ctl', 0)
        src.answered('ctl', 10 * ms)                   # period 10 ms: due at 20 ms
        assert graph.spin_wall(20.0, until=lambda: src.sync_waits > 0)
        assert src.sim_time_ns == 20 * ms
        src.answered('ctl', 20 * ms)
        start = time.monotonic()
        graph.spin_wall(1.5, until=lambda: src.sim_time_ns > 20 * ms)
        assert src.sim_time_ns == 30 * ms and time.monotonic() - start < 1.0
        graph.spin_wall(0.5)
        assert src.sim_time_ns == 30 * ms
