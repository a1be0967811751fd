"""The FAST part's measured results: ``write_report(out_dir)`` reruns them and writes
``<out_dir>/fast.md`` plus its PNGs.

Every figure comes from the ROS-free lock-step loop (:func:`cable_robot_pkg.fast.loop.run_loop`:
the PyBullet plant, the tracker model and the same controller objects the nodes wrap), run in
two worker processes:

1. modes and ablations at 20 ms (default wind);
2. Lu's delay instability: feed RMS against tracker latency per mode, and the cure;
3. the spec over conditions: feed RMS over unseen wind seeds/directions and latencies;
4. Cheng's coupled platforms (``config/coupled.yaml``): RMS of base and payload, control on
   and off;
5. the flexible-cable error analysis (:mod:`cable_robot_pkg.fast.flexible_cable`).
"""
import datetime
import os
import platform
import sys
from concurrent.futures import ProcessPoolExecutor
from multiprocessing import get_context
from pathlib import Path

SPEC_MM, SPEC_DEG = 4.0, 0.1
COUPLED = str(Path(__file__).parent / 'config' / 'coupled.yaml')
#: Winds (seed, direction deg) by role. The packaged config blows seed 1 toward 30 deg.
#: ``dev``: the winds the predictor's settings were chosen on; ``report``: validation winds,
#: not used for tuning but looked at while developing; ``held_out``: winds used nowhere else.
WINDS = {'dev': ((1, 30.0), (2, 160.0), (3, 340.0)),
         'report': ((23, 300.0), (7, 120.0), (11, 250.0), (42, 75.0), (99, 190.0)),
         'held_out': ((31, 45.0), (57, 135.0), (64, 215.0), (88, 280.0), (123, 350.0))}
UNSEEN_WINDS = WINDS['report'] + WINDS['held_out']
LU_CURE = {'isolation': {'lu_delay_limit': 1.2}}
KALMAN = {'isolation': {'predictor': 'kalman'}}
MODE_SOURCE = {'lu': 'Lu et al. (PID, direct terminal feedback)',
               'cheng': 'Cheng et al. (reaction-free base prediction + leg PD)',
               'predictive': 'ours (fused least-squares prediction + trim)',
               'predictive (kalman)': 'ours with the latency-scheduled Kalman predictor'}


def _case(spec: dict) -> dict:
    """One :func:`run_loop` run; the numbers only (picklable)."""
    from cable_robot_pkg.fast.loop import run_loop
    kw = {k: v for k, v in spec.items() if k not in ('key', 'series')}
    r = run_loop(**kw)
    keep = ('feed_rms_position_mm', 'feed_rms_orientation_deg', 'trolley_rms_position_mm',
            'upper_rms_position_mm', 'upper_rms_orientation_deg', 'unstable', 'clip_count',
            'diverged', 'sim_time_s')
    out = {k: r[k] for k in keep}
    out['feed_offset_mm'] = [1000 * float(x) for x in r['feed_offset']]
    out['key'] = spec['key']
    out['duration'] = spec['duration']
    if spec.get('series'):
        out['t'] = r['t'].tolist()
        out['feed_err'] = r['feed_err'].tolist()
        out['upper_err'] = r['upper_err'].tolist()
    return out


def _merge(*dicts):
    out = {}
    for d in dicts:
        for section, values in (d or {}).items():
            out.setdefault(section, {}).update(values)
    return out or None


#: (label, mode, config overrides) of the variants compared.
VARIANTS = {'lu': ('lu', None), 'lu + cure': ('lu', LU_CURE), 'cheng': ('cheng', None),
            'predictive': ('predictive', None), 'predictive (kalman)': ('predictive', KALMAN)}
LONG_RUN = (23, 300.0, 0.035, 60.0)     # the case: seed 23 at 300 deg, 35 ms, 60 s


def _cases(quick: bool) -> list:
    """The runs of the report. The least-squares predictor of ``predictive`` fits once it has
    4 s of base history (the Kalman predictor serves until then), so every run that compares
    modes lasts 12 s with statistics from 5 s (the same window for every mode); ``quick`` runs
    are shorter than that warm-up."""
    cases = []

    def add(key, mode, duration=None, settle=None, **kw):
        if duration is None:
            duration = 3.0 if quick else 12.0
        if settle is None:
            settle = 1.0 if quick else 5.0
        cases.append({'key': key, 'duration': duration, 'settle': settle, 'mode': mode, **kw})

    labels = ('lu', 'cheng', 'predictive') if quick else \
        ('lu', 'cheng', 'predictive', 'predictive (kalman)')
    for label in labels:
        mode, over = VARIANTS[label]
        add(('mode', label, ''), mode, overrides=over)
    if not quick:
        for mode, wo in (('cheng', 'prediction'), ('predictive', 'prediction'),
                         ('predictive', 'tracker_feedback'), ('predictive', 'isolation')):
            add(('mode', mode, wo), mode, without=(wo,))
    lat_sweep = (0.0, 0.06) if quick else (0.0, 0.02, 0.04, 0.06, 0.1)
    for variant, (mode, over) in VARIANTS.items():
        if quick and variant in ('lu + cure', 'predictive (kalman)'):
            continue
        for lat in lat_sweep:
            add(('sweep', variant, lat), mode, overrides=over, latency=lat)
    roles = (('held_out', WINDS['held_out'][:1]),) if quick else tuple(WINDS.items())
    d_spec = 8.0 if quick else 20.0
    for role, winds in roles:
        for seed, direction in winds:
            wind = {'wind': {'seed': seed, 'direction_deg': direction}}
            add(('spec', 'predictive', role, seed, direction, 0.04), 'predictive', d_spec,
                latency=0.04, overrides=wind)
            if not quick and role == 'report':
                add(('spec', 'cheng', role, seed, direction, 0.04), 'cheng', d_spec, 5.0,
                    latency=0.04, overrides=wind)
    if not quick:
        seed, direction, lat, duration = LONG_RUN
        add(('long', 'predictive', seed, direction, lat), 'predictive', duration, latency=lat,
            overrides={'wind': {'seed': seed, 'direction_deg': direction}})
    coupled = (('off', 'cheng', ('isolation',)), ('cheng', 'cheng', ()),
               ('cheng', 'cheng', ('reaction',)))
    if not quick:
        coupled += (('predictive', 'predictive', ()), ('predictive', 'predictive',
                                                         ('reaction',)))
    d_coupled = 3.0 if quick else 12.0
    for label, mode, without in coupled:
        add(('coupled', label, ','.join(without)), mode, d_coupled, 1.0 if quick else 5.0,
            config=COUPLED, without=without,
            series=not without or without == ('isolation',))
    return cases


def run_cases(cases: list, workers: int = 4) -> dict:
    """Run ``cases`` in ``workers`` processes; ``{key: result}``."""
    with ProcessPoolExecutor(max_workers=workers, mp_context=get_context('spawn')) as pool:
        return {r['key']: r for r in pool.map(_case, cases)}


# ----------------------------------------------------------------------------- tables
def _fmt(r):
    if r['unstable'] and (r['diverged'] or r['clip_count']):
        return 'unstable'
    mark = ' (u)' if r['unstable'] else ''
    return f"{r['feed_rms_position_mm']:.2f} / {r['feed_rms_orientation_deg']:.3f}{mark}"


def _mode_table(res):
    rows = ['| mode | without | feed RMS mm / deg | trolley RMS mm | stroke clips |',
            '|---|---|---|---|---|']
    for key in sorted(k for k in res if k[0] == 'mode'):
        r = res[key]
        src = MODE_SOURCE[key[1]]
        rows.append(f"| `{key[1]}`: {src} | {key[2] or '-'} | {_fmt(r)} | "
                    f"{r['trolley_rms_position_mm']:.1f} | {r['clip_count']} |")
    return rows


def _sweep_rows(res):
    variants = sorted({k[1] for k in res if k[0] == 'sweep'})
    lats = sorted({k[2] for k in res if k[0] == 'sweep'})
    rows = ['| variant | ' + ' | '.join(f'{1000 * x:g} ms' for x in lats) + ' | stable up to |',
            '|---|' + '---|' * (len(lats) + 1)]
    limits = {}
    for v in variants:
        cells, stable = [], None
        for lat in lats:
            r = res[('sweep', v, lat)]
            cells.append(_fmt(r))
            if not r['unstable'] and (stable is None or stable == lats[lats.index(lat) - 1]):
                stable = lat
        limits[v] = stable
        last = 'none' if stable is None else f'{1000 * stable:g} ms'
        rows.append(f'| {v} | ' + ' | '.join(cells) + f' | {last} |')
    return rows, limits


ROLE_NAME = {'dev': 'development', 'report': 'validation', 'held_out': 'held out'}


def _within_spec(r):
    return r['feed_rms_position_mm'] <= SPEC_MM and \
        r['feed_rms_orientation_deg'] <= SPEC_DEG and not r['unstable']


def _spec_rows(res):
    keys = [k for k in res if k[0] == 'spec']
    lats = sorted({k[5] for k in keys})
    rows = ['| mode | winds | wind seed / direction | '
            + ' | '.join(f'{1000 * x:g} ms' for x in lats) + ' |',
            '|---|---|---|' + '---|' * len(lats)]
    held = {}
    for mode in sorted({k[1] for k in keys}):
        for role in WINDS:
            for seed, direction in WINDS[role]:
                cells = []
                for lat in lats:
                    r = res.get(('spec', mode, role, seed, direction, lat))
                    if r is None:
                        cells.append('-')
                        continue
                    ok = _within_spec(r)
                    held.setdefault((mode, role, lat), []).append(ok)
                    cells.append(_fmt(r) + (' ok' if ok else ' **out**'))
                if any(c != '-' for c in cells):
                    rows.append(f'| {mode} | {ROLE_NAME[role]} | {seed} / {direction:g} deg | '
                                + ' | '.join(cells) + ' |')
    return rows, held


def _coupled_rows(res):
    rows = ['| mode | control | payload RMS mm / deg | base RMS mm / deg | trolley RMS mm | '
            'stroke clips |', '|---|---|---|---|---|---|']
    ratios = {}
    off = res[('coupled', 'off', 'isolation')]
    for key in sorted((k for k in res if k[0] == 'coupled'), key=lambda k: (k[1] != 'off', k)):
        r = res[key]
        label = key[1]
        control = 'off' if label == 'off' else \
            ('on, without ' + key[2] if key[2] else 'on')
        rows.append(f"| {'-' if label == 'off' else label} | {control} | {_fmt(r)} | "
                    f"{r['upper_rms_position_mm']:.1f} / {r['upper_rms_orientation_deg']:.3f} | "
                    f"{r['trolley_rms_position_mm']:.1f} | {r['clip_count']} |")
        if label != 'off':
            ratios[(label, key[2])] = (
                off['feed_rms_position_mm'] / max(r['feed_rms_position_mm'], 1e-9),
                off['feed_rms_orientation_deg'] / max(r['feed_rms_orientation_deg'], 1e-9),
                r['upper_rms_position_mm'] / max(off['upper_rms_position_mm'], 1e-9),
                r['upper_rms_orientation_deg'] / max(off['upper_rms_orientation_deg'], 1e-9),
                r['unstable'])
    return rows, ratios


# ----------------------------------------------------------------------------- plots
def _plot_sweep(path, res):
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(figsize=(8, 5))
    colors = {'lu': 'tab:red', 'lu + cure': 'tab:orange', 'cheng': 'tab:green',
              'predictive': 'tab:blue', 'predictive (kalman)': 'tab:purple'}
    for v, color in colors.items():
        keys = sorted(k for k in res if k[0] == 'sweep' and k[1] == v)
        if not keys:
            continue
        lat = [1000 * k[2] for k in keys]
        rms = [min(res[k]['feed_rms_position_mm'], 1000.0) for k in keys]
        ax.plot(lat, rms, 'o-', color=color, label=v)
        bad = [(a, b) for a, b, k in zip(lat, rms, keys) if res[k]['unstable']]
        if bad:
            ax.plot(*zip(*bad), 'x', color='k', ms=10, mew=2)
    ax.plot([], [], 'x', color='k', ms=10, mew=2, label='unstable (stroke ends / diverging)')
    ax.axhline(SPEC_MM, color='g', ls=':', label='4 mm RMS spec')
    ax.set_yscale('log')
    ax.set_xlabel('optical tracker latency (ms)')
    ax.set_ylabel('feed RMS position error (mm, capped at 1 m)')
    ax.set_title('Delay-induced instability per isolation mode (wind 1.0, 1 mm noise)')
    ax.grid(True, which='both', alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def coupled_masses(config: str = COUPLED) -> tuple:
    """``(payload kg, base kg)`` of a scenario: the feed platform against everything it
    hangs from that moves with the trolley (trolley, ring, upper platform, legs)."""
    from cable_robot_pkg.fast.configuration import load_config
    raw = load_config(config).raw
    g = raw['gough_stewart']
    base = raw['trolley']['mass'] + raw['orienting']['ring_mass'] + g['upper_mass'] \
        + 6 * g['leg_mass']
    return float(g['feed_mass']), float(base)


def _plot_coupled(path, res):
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt
    import numpy as np
    keys = [k for k in (('coupled', 'off', 'isolation'), ('coupled', 'cheng', ''),
                        ('coupled', 'cheng', 'reaction'), ('coupled', 'predictive', ''))
            if k in res]
    fig, axes = plt.subplots(1, 2, figsize=(11, 4.5))
    width = 0.8 / len(keys)
    for i, key in enumerate(keys):
        r = res[key]
        x = np.arange(2) + (i - (len(keys) - 1) / 2) * width
        label = 'control off' if key[1] == 'off' else f'control on ({key[1]}' + \
            (f', without {key[2]})' if key[2] else ')')
        axes[0].bar(x, [min(r['upper_rms_position_mm'], 1000.0),
                        min(r['feed_rms_position_mm'], 1000.0)], width, label=label)
    axes[0].set_xticks([0, 1], ['base (upper platform)', 'payload (feed)'])
    axes[0].set_yscale('log')
    axes[0].set_ylabel('RMS position response (mm)')
    axes[0].set_title('RMS responses of the two platforms')
    axes[0].legend(fontsize=8)
    mode = 'cheng'
    for key, style in ((('coupled', 'off', 'isolation'), '--'), (('coupled', 'cheng', ''), '-')):
        r = res[key]
        label = 'off' if key[1] == 'off' else 'on'
        axes[1].plot(r['t'], 1000 * np.asarray(r['upper_err']), style, lw=0.8,
                     label=f'base, control {label}')
        axes[1].plot(r['t'], 1000 * np.asarray(r['feed_err']), style, lw=0.8,
                     label=f'payload, control {label}')
    axes[1].set_yscale('log')
    axes[1].set_xlabel('sim time (s)')
    axes[1].set_ylabel('position error (mm)')
    payload, base = coupled_masses()
    axes[1].set_title(f'{mode} mode, payload / base mass {payload:g} / {base:g} kg')
    axes[1].legend(fontsize=8)
    for ax in axes:
        ax.grid(True, which='both', alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


# ----------------------------------------------------------------------------- report
def write_report(out_dir: Path, quick: bool = False) -> list:
    """Rerun the FAST measurements; write ``out_dir/fast.md`` and its PNGs; return the
    paths written."""
    from cable_robot_pkg.fast.configuration import load_config
    from cable_robot_pkg.fast.flexible_cable import error_table
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    start = datetime.datetime.now(datetime.timezone.utc)
    flex = error_table(quick)
    res = run_cases(_cases(quick))
    sweep_png = out_dir / 'fast_latency_sweep.png'
    coupled_png = out_dir / 'fast_coupled.png'
    _plot_sweep(sweep_png, res)
    _plot_coupled(coupled_png, res)
    sweep, limits = _sweep_rows(res)
    spec, held = _spec_rows(res)
    coupled, ratios = _coupled_rows(res)
    payload, base = coupled_masses()
    raw_g = load_config(COUPLED).raw['gough_stewart']
    spec_duration = max((r['duration'] for k, r in res.items() if k[0] == 'spec'), default=0)
    long_lines = []
    for key in (k for k in res if k[0] == 'long'):
        r = res[key]
        long_lines += [f"{r['duration']:g} s run, {key[1]} mode, wind seed {key[2]} at "
                       f"{key[3]:g} deg, {1000 * key[4]:g} ms latency: {_fmt(r)} "
                       f"({'within' if _within_spec(r) else 'outside'} the spec; trolley "
                       f"{r['trolley_rms_position_mm']:.1f} mm RMS).", '']
    wall = (datetime.datetime.now(datetime.timezone.utc) - start).total_seconds()
    lines = [
        '# FAST feed support: measured results', '',
        f"Generated {start:%Y-%m-%d %H:%M} UTC on `{platform.node()}` "
        f"({platform.processor() or platform.machine()}, {os.cpu_count()} cores) by "
        f'`python -m cable_robot_pkg.fast.report{" --quick" if quick else ""}` in '
        f"{wall / 60:.1f} min{' (quick: short runs, few cases)' if quick else ''}.",
        f'Python {sys.version.split()[0]}. All runs: ROS-free lock-step loop '
        '(`cable_robot_pkg.fast.loop.run_loop`), wind intensity 1.0, tracker noise 1 mm / '
        '0.01 deg at 200 Hz. Runs last 12 s with statistics from 5 s (the least-squares '
        'predictor of `predictive` fits after 4 s of base history) unless a section says '
        'otherwise. Cells: feed RMS position (mm) / '
        'orientation (deg); "unstable" = legs driven into their stroke ends or the feed '
        'diverged; "(u)" = error growing or feed moving more than twice the trolley.', '',
        '## Modes and ablations (20 ms latency, packaged wind)', '', *_mode_table(res), '',
        '## Delay-induced instability (Lu et al.): feed RMS against tracker latency', '',
        *sweep, '', '![latency sweep](fast_latency_sweep.png)', '',
        'Stable latency range per variant (last latency of the sweep before the first '
        'unstable one): ' + ', '.join(
            f"{v} {'none' if x is None else f'{1000 * x:g} ms'}" for v, x in limits.items())
        + '.', '',
        f'## Spec over conditions ({SPEC_MM:g} mm / {SPEC_DEG:g} deg RMS)', '',
        f'Runs of {spec_duration:g} s (statistics from 5 s). Winds: *development* = the '
        "winds the predictor's settings were chosen on; *validation* = winds not used for "
        'tuning but looked at while developing; *held out* = used nowhere else.', '',
        *spec, '',
        'Spec held (runs within spec / runs): ' + '; '.join(
            f'{m}, {ROLE_NAME[role]} winds, {1000 * lat:g} ms: {sum(v)}/{len(v)}'
            for (m, role, lat), v in sorted(held.items())) + '.', '',
        *long_lines,
        "## Cheng et al.'s coupled platforms (`config/coupled.yaml`, 20 ms, "
        f"{res[('coupled', 'off', 'isolation')]['duration']:g} s)", '',
        f'Payload (feed platform + receivers) {payload:g} kg against the {base:g} kg it hangs '
        f'from (trolley, ring, upper platform, legs): mass ratio {payload / base:.2f}. '
        f"Force-limited leg drives: PD {raw_g['actuator_stiffness'] / 1e3:g} kN/m, "
        f"{raw_g['actuator_damping'] / 1e3:g} kN s/m, {raw_g['actuator_bandwidth_hz']:g} Hz "
        f"force lag, {raw_g['drive_force_max'] / 1e3:g} kN. \"Control off\" = legs held at "
        'their nominal lengths by the same drives; base RMS against its commanded pose.', '',
        *coupled, '', *[
            f"- {m}{' without ' + wo if wo else ''}: "
            + ('unstable (legs in their stroke ends)' if bad else
               f'payload RMS reduced {a:.1f}x in position and {ar:.1f}x in orientation by '
               f'control; base RMS with / without control {b:.2f} (position), '
               f'{br:.2f} (orientation)')
            for (m, wo), (a, ar, b, br, bad) in ratios.items()], '',
        '![coupled platforms](fast_coupled.png)', '',
        '## Flexible cables (Lu et al.): static feed error', '', *flex, '',
    ]
    md = out_dir / 'fast.md'
    md.write_text('\n'.join(lines) + '\n', encoding='utf-8')
    return [md, sweep_png, coupled_png]


if __name__ == '__main__':
    for written in write_report(Path('docs/results'), quick='--quick' in sys.argv):
        print(written)
