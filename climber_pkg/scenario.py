"""``paramotion climb``: climb a structure headless on sim time, record it, evaluate it.

Composes ``climber_sim`` (PyBullet), two ``climber_ultrasonic`` nodes and ``climber_planner`` in
one executor and runs them lock-step (physics at 500 Hz: the loop-closure error measured 4 um,
against 1.5 um at 1 kHz) until the planner stops (top of the structure, ``--cycles``
cycles, or a refusal) or ``--max-time`` sim seconds. Writes ``DIR/bag/`` (rosbag2 MCAP),
``DIR/result.json`` and ``DIR/climb.png``. The evaluation uses the ground truth and the
structure file (never given to the planner): centering error at every step (distance from the
moved ring's centre to the structure axis in the ring plane), smallest ring-bore and leg
clearances to the surface, leg lengths against the stroke, the true configuration's Jacobian
condition, and the clamp invariant (at least one clamp closed at every simulator
publish period, 20 ms).
"""
from __future__ import annotations

import argparse
import datetime
import math
import os
import time
from collections.abc import Iterable
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from climber_pkg import evaluation as ev
from climber_pkg.cone_cast import CompiledTrunk
from climber_pkg.gait import APPROACHES, CONSTRUCTS, parse_without
from climber_pkg.robot import RobotConfig, load_robot_config
from climber_pkg.trunk import Trunk
from paramotion import gough_stewart as gs
from paramotion.errors import UserError
from paramotion.launch_xml import load as load_launch
from paramotion.launch_xml import recorded_topics
from paramotion.scenario_io import add_output_args, output_dir, write_json

if TYPE_CHECKING:
    from climber_pkg.gait import ClimbingGait
    from climber_pkg.sim_node import ClimberSimNode

# The graph (nodes, parameters, recorded topics) is described once, in
# launch/climber.launch.xml; this runner composes it in one process.
LAUNCH_FILE = 'climber'
TOPICS = recorded_topics(load_launch(LAUNCH_FILE, {'record': True}))


def check_trunk_fits(trunk: Trunk, robot: RobotConfig, path: str | Path,
                     margin: float = 0.03) -> None:
    """UserError unless the structure passes through the ring bore with ``margin``."""
    limit = robot.ring_inner_radius - margin
    if trunk.max_radius > limit:
        s = float(trunk.s[int(np.argmax(trunk.radii))])
        raise UserError(f'--trunk {path}: radius {trunk.max_radius:.3f} m at s = {s:.2f} m is '
                        f'thicker than the ring clearance allows ({robot.ring_inner_radius:.3f} '
                        f'm bore - {margin} m margin = {limit:.3f} m)')


def turn_angle(rot0: np.ndarray, rot1: np.ndarray) -> float:
    """Signed rotation (deg) of a ring about its own axis between two orientations."""
    x0, x1, z = rot0[:, 0], rot1[:, 0], rot1[:, 2]
    return math.degrees(math.atan2(float(np.cross(x0, x1) @ z), float(x0 @ x1)))


def geom_span(robot: RobotConfig) -> float:
    """Height of the robot at its shortest legs plus a step: the room it needs to start."""
    return robot.geometry.leg_max


class ClimbMonitor:
    """Ground-truth evaluation of a climb, called after every lock-step period (it reads the
    simulator, never steers): centering error of the moving ring each time the planner
    measures it, and every ``sample_every`` periods the ring and leg clearances, leg lengths,
    the Jacobian condition and the ring paths for the figure."""

    def __init__(self, sim: ClimberSimNode, gait: ClimbingGait, trunk: Trunk,
                 robot: RobotConfig, sample_every: int) -> None:
        self.sim, self.gait, self.trunk, self.robot = sim, gait, trunk, robot
        self.sample_every = sample_every
        self.k = 0
        self.measures = 0
        self.centering = []
        self.settled = []          # measurement taken from the second cycle on
        self.trace = {'t': [], 'ring1': [], 'ring2': [], 'steps': [], 'frames': [],
                      'bore_radius': robot.ring_inner_radius}
        self.stats = {'min_ring_clearance': math.inf, 'min_leg_clearance': math.inf,
                      'min_leg_length': math.inf, 'max_leg_length': -math.inf,
                      'max_condition': 0.0, 'both_clamps_open_samples': 0, 'samples': 0}

    def __call__(self) -> None:
        sim, stats = self.sim, self.stats
        self.k += 1
        if not (sim.clamp_closed[0] or sim.clamp_closed[1]):
            stats['both_clamps_open_samples'] += 1
        self._measured_steps()
        if self.k % self.sample_every:
            return
        self._sample()

    def _measured_steps(self):
        """Centering error of the moving ring each time the planner measures it (the ring has
        settled after the previous step): distance to the axis in the ring plane."""
        log = self.gait.measure_log
        for _, ring in log[self.measures:]:
            pos, rot = self.sim.ring_poses()[ring]
            if ev.ring_on_structure(self.trunk, pos):
                self.centering.append(ev.centering_error(self.trunk, pos, rot))
                self.settled.append(self.gait.semicycle >= 2)
            self.trace['steps'].append(pos)
            self.trace['frames'].append((ring, pos, rot))
        self.measures = len(log)

    def _sample(self):
        sim, stats, trunk, robot = self.sim, self.stats, self.trunk, self.robot
        poses = sim.ring_poses()
        lengths = sim.leg_lengths()
        stats['samples'] += 1
        stats['min_leg_length'] = min(stats['min_leg_length'], float(lengths.min()))
        stats['max_leg_length'] = max(stats['max_leg_length'], float(lengths.max()))
        for ring, (pos, rot) in enumerate(poses):
            stats['min_ring_clearance'] = min(stats['min_ring_clearance'],
                                              ev.ring_clearance(trunk, robot, pos, rot))
            self.trace[f'ring{ring + 1}'].append(pos)
        stats['min_leg_clearance'] = min(stats['min_leg_clearance'],
                                         ev.leg_clearance(trunk, robot, poses[0], poses[1]))
        (p1, r1), (p2, r2) = poses
        geom = robot.geometry
        stats['max_condition'] = max(stats['max_condition'], float(gs.jacobian_condition(
            geom, gs.jacobian(geom, r1.T @ (p2 - p1), r1.T @ r2))))
        self.trace['t'].append(sim.sim_time)


def _climb_launch_args(trunk_file, robot, robot_config, start_s, publish_period, physics_dt,
                       start_length, noise, dropout, fault, seed, delta, cycles, mode,
                       turn_deg, approach, without, start_offset, start_tilt):
    """The arguments of ``climber.launch.xml`` for this run (start leg length: mid-stroke to
    turn, else the shortest legs + 5 cm)."""
    geom = robot.geometry
    return {
        'trunk': str(trunk_file), 'robot_config': robot_config, 'start_s': float(start_s),
        'publish_period': float(publish_period), 'physics_dt': float(physics_dt),
        'start_length': float(start_length or (
            0.5 * (geom.leg_min + geom.leg_max) if mode == 'turn' else geom.leg_min + 0.05)),
        'noise': float(noise), 'dropout': float(dropout), 'fault': float(fault),
        'seed': int(seed), 'delta': float(delta), 'cycles': int(cycles), 'mode': mode,
        'turn_deg': float(turn_deg), 'approach': approach, 'without': ','.join(without),
        'start_offset': float(start_offset), 'start_tilt': float(start_tilt)}


def _climb_result(trunk_file, trunk, robot, sim, gait, monitor, outcome, start_poses, delta,
                  cycles, mode, wall0):
    """result.json of a climb: the planner's outcome and the ground-truth evaluation."""
    geom = robot.geometry
    stats, centering = monitor.stats, monitor.centering
    poses = sim.ring_poses()
    s_top = float(trunk.closest(poses[1][0])[0])
    s_bottom = float(trunk.closest(poses[0][0])[0])
    reached_top = bool(gait.state.value == 'done' and 'end of the structure' in gait.reason
                       and s_top >= trunk.length - delta)
    refused = gait.state.value in ('refused', 'lost_structure')
    result = {
        'trunk': str(trunk_file), 'trunk_name': trunk.name,
        'trunk_length_m': trunk.length, 'delta_m': delta, 'cycles_requested': cycles,
        'outcome': outcome, 'planner_state': gait.state.value,
        'approach': gait.p.approach, 'without': list(gait.p.without),
        'planner_message': gait.reason,
        'refusal': gait.reason if refused else None,
        'cycles': gait.cycle, 'semicycles': gait.semicycle, 'steps': len(gait.steps),
        'reached_top': reached_top,
        'height_reached_m': float(poses[1][0][2]),
        'arc_length_reached_m': s_top, 'ring1_arc_length_m': s_bottom,
        'centering_error_per_step_m': centering,
        'centering_error_median_m': float(np.median(centering)) if centering else None,
        'centering_error_max_m': float(np.max(centering)) if centering else None,
        'off_axis_start_m': centering[0] if centering else None,
        'off_axis_settled_max_m': max((c for c, ok in zip(centering, monitor.settled) if ok),
                                      default=None),
        'min_ring_clearance_m': stats['min_ring_clearance'],
        'min_leg_clearance_m': stats['min_leg_clearance'],
        'ring_trunk_contacts': sim.contacts,
        'leg_length_range_m': [stats['min_leg_length'], stats['max_leg_length']],
        'stroke_m': [geom.leg_min, geom.leg_max],
        'max_jacobian_condition': stats['max_condition'],
        'planner_max_condition': gait.p.max_condition,
        'clamp_invariant_ok': stats['both_clamps_open_samples'] == 0,
        'ring_turn_deg': [turn_angle(a[1], b[1]) for a, b in zip(start_poses, poses)],
        'interlock_trips': sim.interlock_trips,
        'sim_time_s': sim.sim_time, 'wall_time_s': time.monotonic() - wall0,
    }
    within_stroke = (stats['min_leg_length'] >= geom.leg_min - 1e-4
                     and stats['max_leg_length'] <= geom.leg_max + 1e-4)
    result['within_stroke'] = bool(within_stroke)
    goal = reached_top or (cycles and gait.cycle >= cycles and not refused) or (
        mode == 'turn' and gait.state.value == 'done')
    result['success'] = bool(goal and within_stroke and sim.contacts == 0
                             and result['clamp_invariant_ok']
                             and stats['max_condition'] < gs.DEFAULT_MAX_CONDITION)
    return result


def run_climb(trunk_file: str | Path, bag_dir: str | Path | None = None, delta: float = 0.10,
              cycles: int = 0, max_time: float | None = None, noise: float = 0.001,
              dropout: float = 0.0, fault: float = 0.0, start_s: float = 0.4, seed: int = 1,
              robot_config: str = '', publish_period: float = 0.02, sample_every: int = 5,
              domain_id: int | None = None, physics_dt: float = 0.002, mode: str = 'climb',
              turn_deg: float = 0.0, start_length: float | None = None,
              approach: str = 'centres', without: str | Iterable[str] | None = (),
              start_offset: float = 0.0, start_tilt: float = 0.0
              ) -> tuple[dict[str, object], dict[str, object], Trunk]:
    """Run the climbing graph of ``climber.launch.xml`` in one process, lock-step, until the
    planner's gait is finished or ``max_time``; returns (result dict, trace dict for
    plotting, trunk). ``start_offset`` (m) and ``start_tilt`` (deg) start the robot off the
    axis and tilted, in directions drawn from ``seed``."""
    from paramotion.graph import Graph
    from paramotion.launch import graph_from_launch

    # The evaluation queries the structure's closest points often: the compiled query (the
    # same figures bit for bit).
    trunk = CompiledTrunk.from_file(trunk_file)
    robot = load_robot_config(robot_config or None)
    check_trunk_fits(trunk, robot, trunk_file)
    if not 0.0 <= start_s <= trunk.length - geom_span(robot):
        raise UserError(f'--start-s {start_s}: the robot ({geom_span(robot):.2f} m tall) must '
                        f'start on the structure (0 .. {trunk.length - geom_span(robot):.2f} m)')
    if max_time is None:
        max_time = 60.0 + 40.0 * trunk.length
    wall0 = time.monotonic()
    with Graph(domain_id=domain_id) as graph:
        nodes, topics = graph_from_launch(graph, LAUNCH_FILE, _climb_launch_args(
            trunk_file, robot, robot_config, start_s, publish_period, physics_dt,
            start_length, noise, dropout, fault, seed, delta, cycles, mode, turn_deg,
            approach, parse_without(without, '--without'), start_offset, start_tilt))
        sim, planner = nodes['climber_sim'], nodes['climber_planner']
        if bag_dir is not None:
            graph.record(bag_dir, topics)
        gait = planner.gait
        start_poses = sim.ring_poses()
        monitor = ClimbMonitor(sim, gait, trunk, robot, sample_every)
        outcome = graph.run_lockstep(sim, until=lambda: gait.finished, max_sim_time=max_time,
                                     on_step=monitor)
        result = _climb_result(trunk_file, trunk, robot, sim, gait, monitor, outcome,
                               start_poses, delta, cycles, mode, wall0)
        trace = monitor.trace
        trace['planned'] = [s.position for s in gait.steps]
    return result, trace, trunk


def plot_climb(path: str | Path, trunk: Trunk, trace: dict[str, object],
               result: dict[str, object]) -> None:
    """climb.png: the structure and the ring paths in 3-D, and the centering error."""
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt

    fig = plt.figure(figsize=(14, 7))
    ax = fig.add_subplot(1, 3, 1, projection='3d')
    pts = trunk.points
    ax.plot(pts[:, 0], pts[:, 1], pts[:, 2], color='saddlebrown', lw=1, label='trunk axis')
    ang = np.linspace(0, 2 * np.pi, 25)
    for s in np.arange(0.0, trunk.length + 1e-9, 0.5):
        p, rot = trunk.frame_at(s)
        r = float(trunk.radius_at(s))
        circle = p + (np.stack([np.cos(ang), np.sin(ang), 0 * ang], 1) * r) @ rot.T
        ax.plot(circle[:, 0], circle[:, 1], circle[:, 2], color='peru', lw=0.6)
    for key, color in (('ring1', 'tab:blue'), ('ring2', 'tab:orange')):
        if trace[key]:
            q = np.array(trace[key])
            ax.plot(q[:, 0], q[:, 1], q[:, 2], color=color, lw=1.5, label=f'{key} centre')
    if trace['steps']:
        q = np.array(trace['steps'])
        ax.scatter(q[:, 0], q[:, 1], q[:, 2], s=4, color='k', label='ring after each step')
    bore = np.stack([np.cos(ang), np.sin(ang), 0 * ang], 1) * trace['bore_radius']
    for k, (ring, pos, rot) in enumerate(trace['frames']):
        if k % 4 == 0:
            c = pos + bore @ rot.T
            ax.plot(c[:, 0], c[:, 1], c[:, 2], lw=0.7,
                    color='tab:blue' if ring == 0 else 'tab:orange')
    span = np.ptp(pts, axis=0).max() / 2 + 0.5
    mid = (pts.max(0) + pts.min(0)) / 2
    ax.set_xlim(mid[0] - span, mid[0] + span)
    ax.set_ylim(mid[1] - span, mid[1] + span)
    ax.set_zlim(mid[2] - span, mid[2] + span)
    ax.set_xlabel('x (m)')
    ax.set_ylabel('y (m)')
    ax.set_zlabel('z (m)')
    ax.legend(loc='upper left', fontsize=7)
    status = 'top reached' if result['reached_top'] else result['planner_state']
    ax.set_title(f'{trunk.name}: {status}')
    ax2 = fig.add_subplot(2, 3, 2)
    cen = np.array(result['centering_error_per_step_m']) * 1000
    if cen.size:
        ax2.plot(np.arange(cen.size), cen, '.-', ms=3)
    ax2.set_xlabel('step')
    ax2.set_ylabel('centering error (mm)')
    ax2.grid(alpha=0.3)
    ax3 = fig.add_subplot(2, 3, 5)
    q1 = np.array(trace['ring1']) if trace['ring1'] else np.zeros((0, 3))
    q2 = np.array(trace['ring2']) if trace['ring2'] else np.zeros((0, 3))
    if q1.size:
        ax3.plot(trace['t'], q1[:, 2], label='ring 1 z')
        ax3.plot(trace['t'], q2[:, 2], label='ring 2 z')
    ax3.set_xlabel('sim time (s)')
    ax3.set_ylabel('height (m)')
    ax3.legend(fontsize=7)
    ax3.grid(alpha=0.3)
    # Side views with the lateral axis magnified: the shape of the structure and how the
    # rings follow it (the 3-D view keeps true proportions).
    for k, (col, name) in enumerate(((0, 'x'), (1, 'y'))):
        axs = fig.add_subplot(2, 3, 3 + 3 * k)
        axs.plot(pts[:, col], pts[:, 2], color='saddlebrown', lw=1, label='trunk axis')
        if q1.size:
            axs.plot(q1[:, col], q1[:, 2], '.', ms=1.5, color='tab:blue', label='ring 1')
            axs.plot(q2[:, col], q2[:, 2], '.', ms=1.5, color='tab:orange', label='ring 2')
        axs.set_xlabel(f'{name} (m)')
        axs.locator_params(axis='x', nbins=5)
        axs.set_ylabel('z (m)')
        axs.grid(alpha=0.3)
        if k == 0:
            axs.legend(fontsize=7)
    fig.suptitle(f"cycles {result['cycles']}, centering median "
                 f"{1000 * (result['centering_error_median_m'] or 0):.1f} mm max "
                 f"{1000 * (result['centering_error_max_m'] or 0):.1f} mm, min ring clearance "
                 f"{1000 * result['min_ring_clearance_m']:.0f} mm", fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def _positive(name, value, allow_zero=False):
    if not math.isfinite(value) or value < 0 or (value == 0 and not allow_zero):
        raise UserError(f'{name} {value}: must be a positive number')


def _run(args):
    _positive('--delta', args.delta)
    if args.delta > 0.5:
        raise UserError(f'--delta {args.delta}: at most 0.5 m per step')
    if args.cycles < 0:
        raise UserError(f'--cycles {args.cycles}: must be >= 0 (0 = until the top)')
    if args.max_time is not None:
        _positive('--max-time', args.max_time)
    _positive('--noise', args.noise, allow_zero=True)
    if not os.path.isfile(args.trunk):
        raise UserError(f'--trunk {args.trunk}: no such file')
    if args.mode == 'descend' and args.cycles == 0:
        raise UserError('--mode descend needs --cycles N (the foot is not sensed)')
    if args.mode == 'turn' and not (math.isfinite(args.turn_deg) and args.turn_deg != 0
                                    and abs(args.turn_deg) <= 360):
        raise UserError(f'--turn-deg {args.turn_deg}: need a non-zero angle within +-360 deg')
    _positive('--start-s', args.start_s, allow_zero=True)
    _positive('--start-offset', args.start_offset, allow_zero=True)
    if args.start_offset > 0.2:
        raise UserError(f'--start-offset {args.start_offset}: at most 0.2 m')
    _positive('--start-tilt', args.start_tilt, allow_zero=True)
    if args.start_tilt > 30:
        raise UserError(f'--start-tilt {args.start_tilt}: at most 30 deg')
    without = parse_without(args.without or (), '--without')
    # Validate the structure before creating anything.
    check_trunk_fits(Trunk.from_file(args.trunk), load_robot_config(), args.trunk)
    with output_dir(args.out, args.overwrite) as tmp:
        result, trace, trunk = run_climb(args.trunk, tmp / 'bag', delta=args.delta,
                                         cycles=args.cycles, max_time=args.max_time,
                                         noise=args.noise, dropout=args.dropout,
                                         mode=args.mode, turn_deg=args.turn_deg,
                                         start_s=args.start_s, seed=args.seed,
                                         approach=args.approach, without=without,
                                         start_offset=args.start_offset,
                                         start_tilt=args.start_tilt)
        write_json(tmp / 'result.json', result)
        plot_climb(tmp / 'climb.png', trunk, trace, result)
    r = result
    print(f"climb {r['trunk_name']} (approach {r['approach']}, without "
          f"{','.join(r['without']) or 'nothing'}): {r['planner_state']} "
          f"({r['planner_message']})")
    print(f"  cycles {r['cycles']}, steps {r['steps']}, reached s = "
          f"{r['arc_length_reached_m']:.2f} of {r['trunk_length_m']:.2f} m "
          f"(height {r['height_reached_m']:.2f} m), top reached: {r['reached_top']}")
    if r['centering_error_median_m'] is not None:
        settled = r['off_axis_settled_max_m']
        print(f"  off-axis median {1000 * r['centering_error_median_m']:.2f} mm, max "
              f"{1000 * r['centering_error_max_m']:.2f} mm over {len(centering_list(r))} "
              f"measurements; at start {1000 * r['off_axis_start_m']:.2f} mm, max from the "
              f"second cycle on "
              f"{'-' if settled is None else f'{1000 * settled:.2f} mm'}")
    print(f"  min ring-trunk clearance {1000 * r['min_ring_clearance_m']:.1f} mm, min leg "
          f"clearance {1000 * r['min_leg_clearance_m']:.1f} mm, contacts "
          f"{r['ring_trunk_contacts']}")
    print(f"  legs {r['leg_length_range_m'][0]:.4f}..{r['leg_length_range_m'][1]:.4f} m "
          f"(stroke {r['stroke_m'][0]}..{r['stroke_m'][1]}), max condition "
          f"{r['max_jacobian_condition']:.1f}, clamp invariant "
          f"{'ok' if r['clamp_invariant_ok'] else 'VIOLATED'}")
    print(f"  {r['sim_time_s']:.1f} s sim in {r['wall_time_s']:.1f} s wall; "
          f"outputs in {Path(args.out)}")
    return 0 if r['success'] else 1


def centering_list(result: dict[str, object]) -> list[float]:
    return result['centering_error_per_step_m']


def register(subparsers: argparse._SubParsersAction) -> None:

    """Add ``paramotion climb``."""
    stamp = datetime.datetime.now().strftime('%Y%m%d-%H%M%S')
    parser = subparsers.add_parser(
        'climb', help='climbing parallel robot on a trunk (PyBullet, ultrasonic, planner)',
        description='Climb a structure file headless on sim time; write bag/, result.json and '
                    'climb.png. Exit status 0 when the goal (top or --cycles) was reached with '
                    'no contact, no stroke overrun and the clamp invariant kept.')
    parser.add_argument('--trunk', required=True, help='structure JSON (shared/trunks format)')
    parser.add_argument('--delta', type=float, default=0.10,
                        help='displacement per step Delta in metres (default 0.10)')
    parser.add_argument('--cycles', type=int, default=0,
                        help='cycles to climb; 0 (default) = until the top')
    parser.add_argument('--max-time', type=float, default=None,
                        help='sim-time limit in seconds (default 60 + 40 per metre of trunk)')
    parser.add_argument('--noise', type=float, default=0.001,
                        help='ultrasonic noise standard deviation in metres (default 0.001)')
    parser.add_argument('--dropout', type=float, default=0.0,
                        help='probability that an ultrasonic reading is lost (default 0)')
    parser.add_argument('--mode', choices=('climb', 'descend', 'turn'), default='climb',
                        help='climb up (default), descend --cycles cycles, or turn in place')
    parser.add_argument('--turn-deg', type=float, default=0.0,
                        help='rotation around the structure for --mode turn (deg)')
    parser.add_argument('--start-s', type=float, default=0.4,
                        help='arc length of ring 1 on the structure at start (m, default 0.4)')
    parser.add_argument('--start-offset', type=float, default=0.0, metavar='METRES',
                        help='start off the structure axis by this distance (direction drawn '
                             'from --seed; default 0)')
    parser.add_argument('--start-tilt', type=float, default=0.0, metavar='DEGREES',
                        help='start tilted from the structure axis (axis drawn from --seed; '
                             'default 0)')
    parser.add_argument('--seed', type=int, default=1,
                        help='seed of the ultrasonic noise and of the start offset/tilt '
                             'directions (default 1)')
    parser.add_argument('--approach', choices=APPROACHES, default='centres',
                        help='approach vector of the prediction: centres (ours, default: secant '
                             'of the sensed structure centres) or paper (eq. (7) verbatim)')
    parser.add_argument('--without', action='append', choices=CONSTRUCTS, metavar='NAME',
                        help='switch a construct of the paper off (repeatable): correction '
                             '(eq. (5)), prediction (eqs. (6)-(8): step along the ring axis)')
    add_output_args(parser, default_out=os.path.join('bags', 'runs', f'climb-{stamp}'))
    parser.set_defaults(func=_run)
