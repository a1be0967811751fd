"""``paramotion smoke``: run the smoke graph headless on sim time, record it, summarise it.

By default all nodes compose in one process and run lock-step (deterministic, as fast as the
machine allows). With ``--processes`` every node runs in its own process, talking over DDS,
with the simulator free-running at ``--rtf`` times real time.
"""
import argparse
import datetime
import math
import os
import time
from pathlib import Path
from typing import Any

from paramotion.bag.reader import bag_info, deserialize, read_messages
from paramotion.scenario_io import add_output_args, output_dir, write_json

TOPICS = ['/clock', '/smoke/ground_truth', '/smoke/range', '/smoke/cmd_vel', '/smoke/status']
DEFAULTS = {'wall_x': 5.0, 'start_x': 0.0, 'cart_half_length': 0.2, 'target': 1.0}


def run_lockstep(bag_dir: str | os.PathLike[str] | None, duration: float,
                 sensor_params: dict[str, Any] | None = None, seed: int = 1) -> dict[str, Any]:
    """Run the smoke graph in one executor for ``duration`` sim seconds, recording ``bag_dir``.

    Returns a dict with the final true distance to the wall and run statistics.
    """
    from paramotion.graph import Graph
    from paramotion.smoke.controller_node import SmokeControllerNode
    from paramotion.smoke.range_sensor_node import SmokeRangeSensorNode
    from paramotion.smoke.sim_node import SmokeSimNode

    d = DEFAULTS
    wall = time.monotonic()
    with Graph() as graph:
        sim = graph.add(SmokeSimNode, wall_x=d['wall_x'], start_x=d['start_x'],
                        cart_half_length=d['cart_half_length'])
        graph.add(SmokeRangeSensorNode, wall_x=d['wall_x'],
                  cart_half_length=d['cart_half_length'], seed=seed, **(sensor_params or {}))
        ctl = graph.add(SmokeControllerNode, target=d['target'])
        if bag_dir is not None:
            graph.record(bag_dir, TOPICS)
        graph.run_lockstep(sim, max_sim_time=duration)
        final_gap = d['wall_x'] - (sim.cart_x + d['cart_half_length'])
        return {'mode': 'lockstep', 'sim_time_s': sim.sim_time,
                'wall_time_s': time.monotonic() - wall, 'final_gap_m': final_gap,
                'target_gap_m': d['target'], 'readings': ctl.readings,
                'controller_state': ctl.state, 'callbacks': graph.callbacks_run}


def run_processes(bag_dir: str | os.PathLike[str], duration: float, rtf: float,
                  log_dir: str | os.PathLike[str]) -> dict[str, Any]:
    """Run each smoke node in its own process over DDS; the simulator free-runs at ``rtf``."""
    import rclpy
    from rclpy.executors import SingleThreadedExecutor
    from rosgraph_msgs.msg import Clock

    from paramotion.launch import NodeProcess, wait_until
    from paramotion.qos import CLOCK_QOS

    d = DEFAULTS
    log_dir = Path(log_dir)
    log_dir.mkdir(parents=True, exist_ok=True)
    wall = time.monotonic()
    context = rclpy.Context()
    rclpy.init(context=context)
    watcher = rclpy.create_node('smoke_watcher', context=context)
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(watcher)
    now = {'t': 0.0}
    watcher.create_subscription(
        Clock, '/clock', lambda m: now.update(t=m.clock.sec + m.clock.nanosec * 1e-9),
        CLOCK_QOS)
    procs = []
    try:
        procs.append(NodeProcess('paramotion.bag.recorder_node', params={
            'output': str(bag_dir), 'topics': TOPICS, 'use_sim_time': True},
            log_path=log_dir / 'recorder.log'))
        procs.append(NodeProcess('paramotion.smoke.range_sensor_node', params={
            'wall_x': d['wall_x'], 'cart_half_length': d['cart_half_length']},
            log_path=log_dir / 'range_sensor.log'))
        procs.append(NodeProcess('paramotion.smoke.controller_node',
                                 params={'target': d['target']},
                                 log_path=log_dir / 'controller.log'))
        # Everyone must hear /clock before time starts: the sensor's and controller's time
        # sources, the recorder's time source and its recording subscription (made only once
        # every other topic is found) and this watcher. DDS discovery takes ~2 s.
        sim = NodeProcess('paramotion.smoke.sim_node', params={
            'wall_x': d['wall_x'], 'start_x': d['start_x'], 'real_time_factor': float(rtf),
            'cart_half_length': d['cart_half_length'], 'wait_for_clock_subscribers': 5,
            'wait_for_matched': ['/smoke/ground_truth:2']},
            log_path=log_dir / 'sim.log')
        procs.append(sim)
        done = wait_until(lambda: (executor.spin_once(timeout_sec=0.05),
                                   now['t'] >= duration)[1],
                          timeout=30.0 + 2.0 * duration / max(rtf, 1e-3))
        for proc in reversed(procs):  # simulator first, recorder last: it closes the bag
            proc.interrupt()
        if not done:
            raise RuntimeError(f'smoke graph over processes reached only {now["t"]:.2f} s of '
                               f'sim time; logs in {log_dir}')
    finally:
        for proc in procs:
            proc.kill()
        executor.shutdown()
        watcher.destroy_node()
        rclpy.try_shutdown(context=context)
    truths = [deserialize(m) for m in read_messages(bag_dir, ['/smoke/ground_truth'])]
    final_gap = d['wall_x'] - (truths[-1].pose.position.x + d['cart_half_length'])
    return {'mode': 'processes', 'sim_time_s': now['t'], 'wall_time_s': time.monotonic() - wall,
            'final_gap_m': final_gap, 'target_gap_m': d['target'],
            'real_time_factor': rtf}


def _summary(result, bag_dir):
    info = bag_info(bag_dir)
    lines = [f"smoke graph ({result['mode']}): {result['sim_time_s']:.2f} s sim time in "
             f"{result['wall_time_s']:.2f} s wall time",
             f"final gap to wall {result['final_gap_m']:.3f} m (target "
             f"{result['target_gap_m']:.3f} m)",
             f'bag {bag_dir}: {info.message_count} messages, {info.duration_s:.2f} s'
             + ('' if info.complete else f' (INCOMPLETE: {info.problem})')]
    for topic in sorted(info.topics):
        t = info.topics[topic]
        lines.append(f'  {topic:<24} {t.msgtype:<32} {t.count:>6} msgs')
    return '\n'.join(lines)


def _run(args):
    if args.duration <= 0 or not math.isfinite(args.duration):
        from paramotion.errors import UserError
        raise UserError(f'--duration {args.duration}: must be a positive number of seconds')
    with output_dir(args.out, args.overwrite) as tmp:
        bag_dir = tmp / 'bag'
        if args.processes:
            result = run_processes(bag_dir, args.duration, args.rtf, tmp / 'logs')
        else:
            result = run_lockstep(bag_dir, args.duration)
        ok = abs(result['final_gap_m'] - result['target_gap_m']) < 0.05
        result['reached_target'] = ok
        write_json(tmp / 'result.json', result)
        summary = _summary(result, bag_dir)
    print(summary.replace(str(tmp), str(args.out)))
    print(f'result: {Path(args.out) / "result.json"}')
    return 0 if ok else 1


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add ``paramotion smoke``."""
    stamp = datetime.datetime.now().strftime('%Y%m%d-%H%M%S')
    parser = subparsers.add_parser(
        'smoke', help='run the smoke graph (PyBullet cart, range sensor, controller)',
        description='Run the smoke graph headless on sim time, record a bag and summarise it.')
    add_output_args(parser, default_out=os.path.join('bags', 'runs', f'smoke-{stamp}'))
    parser.add_argument('--duration', type=float, default=8.0, help='sim seconds (default 8)')
    parser.add_argument('--processes', action='store_true',
                        help='one process per node over DDS instead of one executor')
    parser.add_argument('--rtf', type=float, default=4.0,
                        help='real-time factor of the free-running sim with --processes')
    parser.set_defaults(func=_run)
