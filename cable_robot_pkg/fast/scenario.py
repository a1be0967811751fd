"""``paramotion fast``: the FAST feed-support graph headless on sim time; sweep and benchmark.

- ``paramotion fast [--config F] [--duration 60] [--wind 1.0] [--latency 0.02]
  [--isolation on|off] [--isolation-mode MODE] [--without NAME]... --out DIR``:
  runs the graph (simulator, tracker, trajectory, cable PID,
  isolation) in one executor, lock-step, recording ``DIR/bag/``; then runs the same wind with
  isolation the other way round (no bag) for comparison; writes ``DIR/result.json`` and
  ``DIR/fast.png``.
- ``paramotion fast sweep --out DIR``: feed RMS against tracker latency (0-100 ms) for each
  isolation mode (lu, cheng, predictive); ``DIR/sweep.json`` and ``DIR/latency_sweep.png``.
- ``paramotion fast bench``: real-time factor of the whole graph and controller update times
  (medians).

All errors are computed from the bag (ground truth vs targets) after ``--settle`` seconds.
"""
import math
import os
import time
from pathlib import Path

import numpy as np

from cable_robot_pkg.fast.configuration import ABLATIONS, ISOLATION_MODES, parse_without
from paramotion.errors import UserError
from paramotion.launch_xml import load as load_launch
from paramotion.launch_xml import recorded_topics
from paramotion.scenario_io import add_output_args, output_dir, write_json
from paramotion.sweep import add_dask_args, run_args, run_tasks

# The graph (nodes, parameters, recorded topics) is described once, in
# launch/fast.launch.xml; this runner composes it in one process.
LAUNCH_FILE = 'fast'
BAG_TOPICS = recorded_topics(load_launch(LAUNCH_FILE, {'record': True}))
SPEC_POSITION_MM = 4.0
SPEC_ORIENTATION_DEG = 0.1


def run_graph(duration, config='', wind=1.0, latency=0.02, isolation=True, mode='config',
              bag_dir=None, tracker=None, wind_seed=-1, record_series=True, domain_id=None,
              topics=None, without=()):
    """Run the FAST graph lock-step for ``duration`` sim seconds (private DDS domain unless
    ``domain_id`` is given).

    Returns a dict with the nodes' statistics and, when ``record_series``, time series of the
    ground truth and targets captured in-process (used when no bag is written).
    """
    from paramotion.graph import Graph
    from paramotion.launch import graph_from_launch

    tracker = dict(tracker or {})
    tracker.setdefault('latency', float(latency))
    wall = time.monotonic()
    series = {'t': [], 'trolley': [], 'feed': [], 'feed_R': [], 'legs': []}
    with Graph(domain_id=domain_id) as graph:
        nodes, launch_topics = graph_from_launch(
            graph, LAUNCH_FILE, {'config': str(config or ''), 'wind': float(wind),
                                 'wind_seed': int(wind_seed), 'latency': tracker['latency'],
                                 'isolation': bool(isolation), 'isolation_mode': mode,
                                 'without': ','.join(sorted(without))},
            extra_params={'fast_tracker': tracker})
        sim, trk, cab, iso = (nodes[n] for n in ('fast_sim', 'fast_tracker',
                                                 'fast_cable_controller',
                                                 'fast_isolation_controller'))
        if bag_dir is not None:
            graph.record(bag_dir, topics or launch_topics)

        def sample():
            if not record_series:
                return
            pl = sim.plant
            series['t'].append(sim.sim_time)
            series['trolley'].append(pl.trolley_pose()[0])
            fp, fR = pl.feed_pose()
            series['feed'].append(fp)
            series['feed_R'].append(fR)
            series['legs'].append(pl.leg_lengths()[0])

        detach_qos_event_handlers(graph.nodes)
        graph.run_lockstep(sim, max_sim_time=duration, on_step=sample)
        wall = time.monotonic() - wall
        return {
            'sim_time_s': sim.sim_time, 'wall_time_s': wall,
            'real_time_factor': sim.sim_time / wall if wall > 0 else math.inf,
            'cable_update_s': list(cab.update_times), 'isolation_update_s':
            list(iso.update_times), 'hold_events': iso.hold_events,
            'recoveries': iso.recoveries, 'tracker_published': trk.published,
            'tracker_dropped': trk.dropped, 'slack_steps': dict(zip(
                sim.cable_names, sim.slack_steps.tolist())),
            'over_limit_steps': dict(zip(sim.cable_names, sim.over_limit_steps.tolist())),
            'stroke_end_steps': sim.stroke_steps.tolist(), 'tension_min_N': sim.tension_min,
            'tension_max_N': sim.tension_max, 'clip_count': iso.ctl.clip_count,
            'compensation_gain': iso.ctl.gain, 'measured_latency_s': iso.ctl.latency,
            'series': series,
            'track': sim.cfg.track, 'chain': sim.cfg.chain, 'geometry': sim.cfg.geometry,
            'tension_limit_N': sim.cfg.raw['cables']['tension_max'],
            'mode': iso.ctl.mode, 'without': sorted(iso.without),
            'cable_open_loop': cab.ctl.open_loop,
        }


def detach_qos_event_handlers(nodes):
    """Stop the executor polling the publishers' and subscriptions' QoS event handlers.

    rclpy gives every publisher and subscription two default event handlers (incompatible QoS,
    incompatible type) and adds them to the executor's wait set: in this one-process graph
    they were 88 of its ~170 entities and about 70 % of the cost of each executor wait, the
    largest single cost of a lock-step run. All nodes here share one process and one launch
    description, so these middleware warnings have nothing to report; the handlers are
    destroyed now rather than when their publisher or subscription is (which is all rclpy
    would do with them later). Nodes started on their own (``ros2 run``, launch) keep theirs.
    Returns how many were removed.
    """
    removed = 0
    for node in nodes:
        for entity in list(node.publishers) + list(node.subscriptions):
            for handler in entity.event_handlers:
                node.remove_waitable(handler)
                handler.destroy()
                removed += 1
            entity.event_handlers = []
    return removed


# ---------------------------------------------------------------------------- metrics
def _angle_deg(Ra, Rb):
    c = (np.trace(np.swapaxes(Ra, -1, -2) @ Rb, axis1=-2, axis2=-1) - 1.0) / 2.0
    return np.degrees(np.arccos(np.clip(c, -1.0, 1.0)))


def errors_from_series(t, positions, rotations, target_t, target_p, target_R):
    """Position (m) and orientation (deg) errors at times ``t`` against targets sampled at
    ``target_t`` (position interpolated linearly, rotation taken from the nearest earlier)."""
    target_t = np.asarray(target_t)
    tp = np.stack([np.interp(t, target_t, np.asarray(target_p)[:, k]) for k in range(3)], 1)
    idx = np.clip(np.searchsorted(target_t, t, side='right') - 1, 0, len(target_t) - 1)
    pos_err = np.linalg.norm(np.asarray(positions) - tp, axis=1)
    if rotations is None:
        return pos_err, None
    rot_err = _angle_deg(np.asarray(rotations), np.asarray(target_R)[idx])
    return pos_err, rot_err


def _rms(x):
    x = np.asarray(x)
    return float(math.sqrt(np.mean(np.square(x)))) if len(x) else math.nan


def bag_series(bag_dir):
    """Time series from a FAST bag: ground truth, targets, cable and leg states."""
    from cable_robot_pkg.fast.ros_messages import (
        LEG_NAMES,
        joint_vector,
        pose_from_msg,
        stamp_seconds,
    )
    from paramotion.bag.reader import deserialize, read_messages
    topics = {'/fast/ground_truth/trolley': 'trolley', '/fast/ground_truth/feed': 'feed',
              '/fast/ground_truth/upper_platform': 'upper', '/fast/feed_target': 'feed_target',
              '/fast/trolley_target': 'trolley_target', '/fast/cables/state': 'cables',
              '/fast/legs/state': 'legs'}
    out = {v: {'t': [], 'p': [], 'R': []} for v in topics.values()}
    cable_names = None
    for m in read_messages(bag_dir, list(topics)):
        key = topics[m.topic]
        msg = deserialize(m)
        t = stamp_seconds(msg.header.stamp)
        if key == 'cables':
            cable_names = cable_names or list(msg.name)
            out[key]['t'].append(t)
            out[key]['p'].append(np.array(msg.effort))
        elif key == 'legs':
            out[key]['t'].append(t)
            out[key]['p'].append(joint_vector(msg, LEG_NAMES))
        else:
            p, R = pose_from_msg(msg)
            out[key]['t'].append(t)
            out[key]['p'].append(p)
            out[key]['R'].append(R)
    for v in out.values():
        for k in v:
            v[k] = np.array(v[k])
    out['cable_names'] = cable_names or []
    return out


def evaluate(series, settle, tension_limit, geometry):
    """Result numbers from bag series (see :func:`bag_series`)."""
    s = series
    if len(s['feed']['t']) < 2 or len(s['feed_target']['t']) < 2 \
            or len(s['trolley_target']['t']) < 2:
        raise UserError('bag holds too few ground-truth/target messages to evaluate')
    keep = s['feed']['t'] >= settle
    fe, fr = errors_from_series(s['feed']['t'][keep], s['feed']['p'][keep],
                                s['feed']['R'][keep], s['feed_target']['t'],
                                s['feed_target']['p'], s['feed_target']['R'])
    keep_t = s['trolley']['t'] >= settle
    te, tr = errors_from_series(s['trolley']['t'][keep_t], s['trolley']['p'][keep_t],
                                s['trolley']['R'][keep_t], s['trolley_target']['t'],
                                s['trolley_target']['p'], s['trolley_target']['R'])
    tensions = s['cables']['p']
    legs = s['legs']['p']
    stroke = geometry.leg_max - geometry.leg_min
    slack = {n: int(np.sum(tensions[:, i] <= 0.0)) for i, n in enumerate(s['cable_names'])}
    over = {n: int(np.sum(tensions[:, i] > tension_limit))
            for i, n in enumerate(s['cable_names'])}
    at_end = (legs <= geometry.leg_min + 1e-3) | (legs >= geometry.leg_max - 1e-3)
    result = {
        'settle_s': settle,
        'feed_rms_position_mm': 1000 * _rms(fe), 'feed_max_position_mm': 1000 * float(fe.max()),
        'feed_rms_orientation_deg': _rms(fr), 'feed_max_orientation_deg': float(fr.max()),
        'trolley_rms_position_mm': 1000 * _rms(te),
        'trolley_max_position_mm': 1000 * float(te.max()),
        'trolley_rms_orientation_deg': _rms(tr),
        'trolley_max_orientation_deg': float(tr.max()),
        'cable_tension_min_N': float(tensions.min()), 'cable_tension_max_N':
        float(tensions.max()), 'cable_tension_limit_N': tension_limit,
        'slack_samples': {k: v for k, v in slack.items() if v},
        'over_limit_samples': {k: v for k, v in over.items() if v},
        'leg_length_min_m': float(legs.min()), 'leg_length_max_m': float(legs.max()),
        'leg_stroke_used_fraction': float((legs.max(0) - legs.min(0)).max() / stroke),
        'leg_stroke_end_samples': int(at_end.any(axis=1).sum()),
    }
    result['isolation_ratio'] = result['trolley_rms_position_mm'] / max(
        result['feed_rms_position_mm'], 1e-12)
    problems = []
    if result['slack_samples']:
        problems.append('slack cable(s): ' + ', '.join(result['slack_samples']))
    if result['over_limit_samples']:
        problems.append('tension limit exceeded: ' + ', '.join(result['over_limit_samples']))
    if result['leg_stroke_end_samples']:
        problems.append(f"legs at a stroke end in {result['leg_stroke_end_samples']} samples")
    result['violations'] = problems
    return result, (s['feed']['t'][keep], fe, fr, s['trolley']['t'][keep_t], te)


def evaluate_run(run, settle):
    """Errors of an in-process run (series captured from the simulator)."""
    s = run['series']
    t = np.array(s['t'])
    track, chain = run['track'], run['chain']
    targets = [track.pose(ti) for ti in t]
    fp_t = np.array([p for p, _ in targets])
    fR_t = np.array([R for _, R in targets])
    tp_t = np.array([chain.coarse_targets(p, R)[0] for p, R in targets])
    keep = t >= settle
    fe = np.linalg.norm(np.array(s['feed'])[keep] - fp_t[keep], axis=1)
    fr = _angle_deg(np.array(s['feed_R'])[keep], fR_t[keep])
    te = np.linalg.norm(np.array(s['trolley'])[keep] - tp_t[keep], axis=1)
    return {'feed_rms_position_mm': 1000 * _rms(fe), 'feed_max_position_mm':
            1000 * float(fe.max()), 'feed_rms_orientation_deg': _rms(fr),
            'trolley_rms_position_mm': 1000 * _rms(te)}, (t[keep], fe, fr, te)


# ---------------------------------------------------------------------------- plots
def plot_errors(path, main_label, main, other_label, other, title):
    """Time series of feed and trolley position errors (and feed orientation), both runs."""
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt
    fig, axes = plt.subplots(3, 1, figsize=(10, 9), sharex=True)
    for label, (t, fe, fr, tt, te), style in ((main_label, main, '-'),
                                              (other_label, other, '--')):
        axes[0].plot(tt, 1000 * te, style, lw=0.8, label=f'trolley, {label}')
        axes[1].plot(t, 1000 * fe, style, lw=0.8, label=f'feed, {label}')
        axes[2].plot(t, fr, style, lw=0.8, label=f'feed, {label}')
    axes[1].axhline(SPEC_POSITION_MM, color='r', lw=0.8, ls=':', label='4 mm spec (RMS)')
    axes[2].axhline(SPEC_ORIENTATION_DEG, color='r', lw=0.8, ls=':', label='0.1 deg spec (RMS)')
    axes[1].set_yscale('log')
    axes[2].set_yscale('log')
    axes[0].set_ylabel('trolley position error (mm)')
    axes[1].set_ylabel('feed position error (mm)')
    axes[2].set_ylabel('feed orientation error (deg)')
    axes[2].set_xlabel('sim time (s)')
    for ax in axes:
        ax.legend(loc='upper right', fontsize=8)
        ax.grid(True, which='both', alpha=0.3)
    axes[0].set_title(title)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


# ---------------------------------------------------------------------------- commands
def _check_args(args):
    if not (args.duration > 0 and math.isfinite(args.duration)):
        raise UserError(f'--duration {args.duration}: must be a positive number of seconds')
    if not (0.0 <= args.wind <= 5.0):
        raise UserError(f'--wind {args.wind}: must be in [0, 5]')
    if hasattr(args, 'latency') and not (0.0 <= args.latency <= 0.2):
        raise UserError(f'--latency {args.latency}: must be in [0, 0.2] s')
    if args.config:
        from cable_robot_pkg.fast.configuration import load_config
        load_config(args.config)      # raises UserError before anything runs
    if args.settle >= args.duration:
        raise UserError(f'--settle {args.settle}: must be shorter than --duration')
    mode = getattr(args, 'isolation_mode', 'config')
    if mode not in ('config',) + ISOLATION_MODES:
        raise UserError(f'--isolation-mode {mode!r}: must be one of config, '
                        + ', '.join(ISOLATION_MODES))
    args.without_set = parse_without(getattr(args, 'without', None) or (), '--without')


def _run(args):
    _check_args(args)
    iso_on = args.isolation == 'on'
    with output_dir(args.out, args.overwrite) as tmp:
        run = run_graph(args.duration, args.config, args.wind, args.latency, iso_on,
                        mode=args.isolation_mode, bag_dir=tmp / 'bag', record_series=False,
                        without=args.without_set)
        series = bag_series(tmp / 'bag')
        result, main_curves = evaluate(series, args.settle, run['tension_limit_N'],
                                       run['geometry'])
        other = run_graph(args.duration, args.config, args.wind, args.latency, not iso_on,
                          mode=args.isolation_mode, without=args.without_set - {'isolation'})
        other_res, (t, fe, fr, te) = evaluate_run(other, args.settle)
        result.update({
            'isolation': args.isolation, 'isolation_mode': run['mode'],
            'without': run['without'], 'wind': args.wind, 'latency_s': args.latency,
            'duration_s': args.duration, 'config': args.config or 'default fast.yaml',
            'sim_time_s': run['sim_time_s'], 'wall_time_s': run['wall_time_s'],
            'real_time_factor': run['real_time_factor'],
            'isolation_hold_events': run['hold_events'],
            'compensation_gain': run['compensation_gain'],
            'comparison': {'isolation': 'off' if iso_on else 'on', **other_res},
        })
        on = result if iso_on else other_res
        result['meets_spec'] = bool(on['feed_rms_position_mm'] <= SPEC_POSITION_MM
                                    and on['feed_rms_orientation_deg'] <= SPEC_ORIENTATION_DEG)
        result['trolley_error_at_least_40mm'] = bool(result['trolley_rms_position_mm'] >= 40.0)
        write_json(tmp / 'result.json', result)
        other_label = 'isolation ' + ('off' if iso_on else 'on')
        plot_errors(tmp / 'fast.png', f'isolation {args.isolation}', main_curves, other_label,
                    (t, fe, fr, t, te),
                    f'FAST feed support: wind {args.wind:g}, latency {1000 * args.latency:g} '
                    f'ms, 1 mm tracker noise')
    print(f"trolley RMS {result['trolley_rms_position_mm']:.1f} mm, "
          f"{result['trolley_rms_orientation_deg']:.3f} deg; feed RMS "
          f"{result['feed_rms_position_mm']:.2f} mm, {result['feed_rms_orientation_deg']:.4f} "
          f"deg (isolation {args.isolation}); isolation ratio {result['isolation_ratio']:.1f}")
    print(f"comparison (isolation {result['comparison']['isolation']}): feed RMS "
          f"{other_res['feed_rms_position_mm']:.2f} mm, "
          f"{other_res['feed_rms_orientation_deg']:.4f} deg")
    print(f"cable tensions {result['cable_tension_min_N']:.0f}.."
          f"{result['cable_tension_max_N']:.0f} N; legs {result['leg_length_min_m']:.3f}.."
          f"{result['leg_length_max_m']:.3f} m")
    for v in result['violations']:
        print('VIOLATION: ' + v)
    print(f"real-time factor {result['real_time_factor']:.2f}; result: "
          f"{Path(args.out) / 'result.json'}")
    return 0


def sweep_case(case):
    """One case of ``paramotion fast sweep``: a whole graph run (its own private ROS domain)
    for ``case['mode']`` at ``case['latency_s']``, evaluated into one row of sweep.json.
    Module-level so that Dask can ship it to a worker process."""
    run = run_graph(case['duration_s'], case['config'], case['wind'], case['latency_s'], True,
                    mode=case['mode'])
    res, (t, fe, fr, te) = evaluate_run(run, case['settle_s'])
    half = len(fe) // 2
    growing = _rms(fe[half:]) > 3.0 * _rms(fe[:half]) + 1e-3
    unstable = is_unstable(run['clip_count'], growing, res['feed_rms_position_mm'],
                           res['trolley_rms_position_mm'])
    return {'mode': case['mode'], 'latency_s': case['latency_s'], 'unstable': unstable,
            'stroke_clips': run['clip_count'], 'compensation_gain': run['compensation_gain'],
            **res}


def _sweep(args):
    _check_args(args)
    try:
        latencies = [float(x) for x in args.latencies.split(',')]
    except ValueError:
        raise UserError(f'--latencies {args.latencies!r}: expected comma-separated seconds') \
            from None
    if not latencies or any(not (0.0 <= x <= 0.2) for x in latencies):
        raise UserError(f'--latencies {args.latencies!r}: each must be in [0, 0.2] s')
    cases = [{'mode': mode, 'latency_s': lat, 'duration_s': args.duration,
              'config': args.config, 'wind': args.wind, 'settle_s': args.settle}
             for mode in ISOLATION_MODES for lat in latencies]
    with output_dir(args.out, args.overwrite) as tmp:
        rows = run_tasks(sweep_case, cases, desc='fast sweep', **run_args(args))
        for row in rows:
            print(f"{row['mode']:>10} latency {1000 * row['latency_s']:5.1f} ms: feed RMS "
                  f"{row['feed_rms_position_mm']:8.2f} mm "
                  f"{row['feed_rms_orientation_deg']:.4f} deg, trolley "
                  f"{row['trolley_rms_position_mm']:.1f} mm"
                  + ('  UNSTABLE' if row['unstable'] else ''), flush=True)
        write_json(tmp / 'sweep.json', {'wind': args.wind, 'duration_s': args.duration,
                                        'settle_s': args.settle, 'rows': rows})
        _plot_sweep(tmp / 'latency_sweep.png', rows, args.wind)
    return 0


def is_unstable(stroke_clips, growing, feed_rms, trolley_rms):
    """A loop counts as unstable when it drove the legs into their stroke limits, when its
    error kept growing, or when it made the feed move more than twice as much as the trolley
    (a passive, rigid feed would move about as much as the trolley)."""
    return bool(stroke_clips > 0 or growing or feed_rms > 2.0 * trolley_rms)


def _plot_sweep(path, rows, wind):
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(figsize=(8, 5))
    labels = {'lu': 'lu: PID on terminal feedback (Lu et al.)',
              'cheng': 'cheng: base prediction + leg PD (Cheng et al.)',
              'predictive': 'predictive: fused, scheduled prediction + trim (ours)'}
    for mode, color in (('lu', 'tab:red'), ('cheng', 'tab:green'), ('predictive', 'tab:blue')):
        r = [x for x in rows if x['mode'] == mode]
        lat = [1000 * x['latency_s'] for x in r]
        rms = [x['feed_rms_position_mm'] for x in r]
        label = labels[mode]
        ax.plot(lat, rms, 'o-', color=color, label=label)
        bad = [(a, b) for a, b, x in zip(lat, rms, r) if x['unstable']]
        if bad:
            ax.plot(*zip(*bad), 'x', color='k', ms=10, mew=2)
    ax.plot([], [], 'x', color='k', ms=10, mew=2, label='unstable (stroke limit hit / diverging)')
    ax.axhline(SPEC_POSITION_MM, color='g', ls=':', label='4 mm RMS spec')
    ax.set_yscale('log')
    ax.set_xlabel('tracker latency (ms)')
    ax.set_ylabel('feed RMS position error (mm)')
    ax.set_title(f'Feed RMS vs tracker latency (wind {wind:g}, 1 mm noise)')
    ax.grid(True, which='both', alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def bench_real_time_factor(duration=5.0, repeat=3, config='', wind=1.0, latency=0.02,
                           progress=None):
    """Real-time factor of the whole FAST graph in one process (median of ``repeat`` runs).

    Each run is :func:`run_graph` for ``duration`` sim seconds with isolation on and no bag or
    series (wall time from graph construction to the end of the run, as ``paramotion fast``
    reports it). ``progress(i, run)`` is called after each run. Returns a dict with
    ``real_time_factor`` (median), ``real_time_factors`` (each run), the median controller
    update times in ms, ``duration_s``, ``repeat`` and ``cores``. Used by ``paramotion fast
    bench`` and ``paramotion bench``.
    """
    if not (duration > 0 and math.isfinite(duration)):
        raise UserError(f'duration {duration}: must be a positive number of seconds')
    if int(repeat) < 1:
        raise UserError(f'repeat {repeat}: must be at least 1')
    runs = []
    for i in range(int(repeat)):
        run = run_graph(duration, config, wind, latency, True, record_series=False)
        runs.append(run)
        if progress is not None:
            progress(i, run)
    factors = [r['real_time_factor'] for r in runs]
    return {
        'real_time_factor': float(np.median(factors)),
        'real_time_factors': [float(x) for x in factors],
        'cable_update_ms': 1e3 * float(np.median(np.concatenate(
            [r['cable_update_s'] for r in runs]))),
        'isolation_update_ms': 1e3 * float(np.median(np.concatenate(
            [r['isolation_update_s'] for r in runs]))),
        'duration_s': float(duration), 'repeat': int(repeat), 'cores': os.cpu_count(),
    }


def _bench(args):
    _check_args(args)
    if args.repeat < 1:
        raise UserError(f'--repeat {args.repeat}: must be at least 1')

    def progress(i, run):
        print(f"run {i + 1}: {run['sim_time_s']:.1f} s sim in {run['wall_time_s']:.1f} s wall, "
              f"real-time factor {run['real_time_factor']:.2f}", flush=True)

    res = bench_real_time_factor(args.duration, args.repeat, args.config, args.wind,
                                 args.latency, progress=progress)
    print(f"median real-time factor of the whole graph: {res['real_time_factor']:.2f}")
    print(f"median cable controller update: {res['cable_update_ms']:.3f} ms; median isolation "
          f"controller update: {res['isolation_update_ms']:.3f} ms")
    return 0


SAMPLE_TOPICS = [
    '/fast/ground_truth/trolley', '/fast/ground_truth/upper_platform',
    '/fast/ground_truth/feed', '/fast/feed_target',
    '/fast/trolley_target', '/fast/tracker/trolley', '/fast/tracker/upper_platform',
    '/fast/tracker/feed', '/fast/cables/state', '/fast/legs/state', '/fast/legs/command',
    '/fast/orienting/state',
]


def _sample(args):
    """Record the small replay-test bag (bags/fast_sample) and its expected numbers."""
    _check_args(args)
    with output_dir(args.out, args.overwrite) as tmp:
        run = run_graph(args.duration, args.config, args.wind, args.latency, True,
                        bag_dir=tmp / 'bag', record_series=False, topics=SAMPLE_TOPICS)
        result, _ = evaluate(bag_series(tmp / 'bag'), args.settle, run['tension_limit_N'],
                             run['geometry'])
        write_json(tmp / 'expected.json', result)
    print(f"sample bag {args.out}: feed RMS {result['feed_rms_position_mm']:.2f} mm")
    return 0


def register(subparsers):
    """Add ``paramotion fast`` (with ``sweep`` and ``bench`` subcommands)."""
    parser = subparsers.add_parser(
        'fast', help='FAST cable-driven Gough-Stewart feed support (run, sweep, bench)',
        description='Run the FAST feed-support graph headless on sim time: cable trolley with '
        'per-winch PID, Gough-Stewart isolation, optical trackers, wind. Without a '
        'subcommand: one run with a bag, result.json and fast.png.')

    def common(p, duration):
        p.add_argument('--config', default='', help='config YAML (default: packaged fast.yaml)')
        p.add_argument('--duration', type=float, default=duration,
                       help=f'sim seconds (default {duration:g})')
        p.add_argument('--wind', type=float, default=1.0, help='wind intensity (default 1.0)')
        p.add_argument('--settle', type=float, default=3.0,
                       help='seconds excluded from the statistics at the start (default 3)')

    common(parser, 60.0)
    parser.add_argument('--latency', type=float, default=0.02,
                        help='tracker latency in s (default 0.02)')
    parser.add_argument('--isolation', choices=('on', 'off'), default='on',
                        help='Gough-Stewart isolation (default on)')
    parser.add_argument('--isolation-mode', default='config', metavar='MODE',
                        help="lu (Lu et al.), cheng (Cheng et al.), predictive (ours); default: "
                        "the config's isolation.mode")
    parser.add_argument('--without', action='append', metavar='NAME',
                        help='switch a construct off (repeatable): ' + ', '.join(ABLATIONS))
    parser.add_argument('--out', default=None, help='output directory (bag/, result.json, '
                        'fast.png); required for a run')
    parser.add_argument('--overwrite', action='store_true', help='replace --out if it exists')
    sub = parser.add_subparsers(dest='fast_command', metavar='SUBCOMMAND')
    sweep = sub.add_parser('sweep', help='feed RMS vs tracker latency, per isolation mode')
    common(sweep, 15.0)
    sweep.add_argument('--latencies', default='0,0.01,0.02,0.03,0.04,0.05,0.06,0.07,0.08,'
                       '0.09,0.1', help='comma-separated latencies in s (default 0..0.1)')
    add_output_args(sweep)
    add_dask_args(sweep)
    sweep.set_defaults(func=_sweep)
    bench = sub.add_parser('bench', help='real-time factor and controller update times')
    common(bench, 10.0)
    bench.add_argument('--latency', type=float, default=0.02, help='tracker latency (s)')
    bench.add_argument('--repeat', type=int, default=3, help='runs (default 3)')
    bench.set_defaults(func=_bench)
    sample = sub.add_parser('record-sample', help='record the small replay-test bag')
    common(sample, 2.5)
    sample.add_argument('--latency', type=float, default=0.02, help='tracker latency (s)')
    add_output_args(sample, default_out=os.path.join('bags', 'fast_sample'))
    sample.set_defaults(func=_sample, settle=1.0)

    def run_or_fail(args):
        if args.out is None:
            raise UserError('--out DIR is required for a run (or use a subcommand: sweep, '
                            'bench)')
        return _run(args)

    parser.set_defaults(func=run_or_fail)


__all__ = ['BAG_TOPICS', 'bag_series', 'bench_real_time_factor', 'detach_qos_event_handlers',
           'evaluate', 'evaluate_run', 'register', 'run_graph']

