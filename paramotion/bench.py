"""``paramotion bench [--json] [--quick] [--only NAMES] [--world FILE]``: every headline figure.

Runs each part's own benchmark function once, in this one process, warm, median of repeats,
and prints a table; with ``--json`` the last line of stdout is one JSON object with every figure
(``null`` plus a ``not_measured`` reason when a figure could not be measured, never a made-up
number) and the machine's core counts. The benchmarks live in the parts: each module named in
:data:`paramotion.cli.BENCH_MODULES` has ``BENCHES = {name: (function(quick, options),
{key: label})}``, so this shared module imports no robot package and a part's faster
implementation shows up here unchanged. Speed is printed here and never asserted by tests.
``--quick`` uses fewer/shorter repeats (for tests and a smoke check), so its figures are
noisier and flagged ``"quick": true``.

:func:`write_report` writes ``<out_dir>/performance.md``: the figures, the lock-step Graph's
speed levers switched one at a time on the parts' lock-step benchmarks, and each part's own
extra tables (e.g. a graph across processes).
"""
from __future__ import annotations

import argparse
import datetime
import importlib
import json
import os
import platform
import sys
import time
from collections.abc import Callable, Iterable, Mapping, Sequence
from pathlib import Path
from types import ModuleType
from typing import Any

from paramotion.errors import UserError

#: One benchmark: ``function(quick, options) -> {key: figure}`` and ``{key: label}``.
Bench = tuple[Callable[[bool, dict[str, Any]], dict[str, Any]], dict[str, str]]


def bench_modules() -> list[ModuleType]:
    """The parts' bench modules that import here, in :data:`paramotion.cli.BENCH_MODULES`
    order (a part that is not installed is skipped, as the CLI skips its subcommand)."""
    from paramotion.cli import BENCH_MODULES
    modules = []
    for name in BENCH_MODULES:
        try:
            modules.append(importlib.import_module(name))
        except ModuleNotFoundError as exc:
            if exc.name is not None and name.startswith(exc.name):
                continue
            raise
    return modules


def benches() -> dict[str, Bench]:
    """``{name: (function, {key: label})}`` over every bench module."""
    out = {}
    for module in bench_modules():
        out.update(module.BENCHES)
    return out


def lockstep_benches() -> list[str]:
    """Names of the benchmarks that run a lock-step Graph (the ones its levers change)."""
    return [n for m in bench_modules() for n in getattr(m, 'LOCKSTEP', ())]


def cores() -> dict[str, int | None]:
    """Logical cores of the machine and those this process may run on."""
    from paramotion.backend import usable_cores
    return {'cpu_count': os.cpu_count(), 'usable_cores': usable_cores()}


def run_benchmarks(names: Iterable[str], quick: bool = False,
                   options: Mapping[str, Any] | None = None,
                   log: Callable[[str], object] = print) -> dict[str, Any]:
    """Run the benchmarks ``names`` (keys of :func:`benches`); returns the figures dict.

    A benchmark that cannot run (missing input, a part failing) gives ``None`` for its keys and
    a reason in ``not_measured``."""
    table_ = benches()
    out = {'quick': bool(quick), **cores(), 'not_measured': {}, 'seconds': {}}
    for name in names:
        fn, keys = table_[name]
        for key in keys:
            out[key] = None
        log(f'bench {name} ...')
        start = time.perf_counter()
        try:
            res = fn(quick, dict(options or {}))
        except Exception as exc:  # one broken part must not hide the other figures
            out['not_measured'][name] = f'{type(exc).__name__}: {exc}'
            continue
        out['seconds'][name] = time.perf_counter() - start
        out.update(res)
    return out


def _format(v: float) -> str:
    return f'{v:14.3f}' if v < 100 else f'{v:14,.0f}'


def table(res: Mapping[str, Any]) -> list[str]:
    """The figures as printable lines."""
    lines = [f'{"figure":38s} {"value":>14s}']
    for name, (_, keys) in benches().items():
        for key, label in keys.items():
            if key not in res:
                continue
            v = res[key]
            text = f'not measured: {res["not_measured"].get(name, "?")}' if v is None else \
                _format(v)
            lines.append(f'{label:38s} {text}')
    lines.append(f'cores: {res["cpu_count"]} (usable {res["usable_cores"]})'
                 + ('; --quick: fewer/shorter repeats' if res['quick'] else ''))
    return lines


# ------------------------------------------------------------------------------ levers
#: The lock-step Graph's speed levers, switched on one after the other (paramotion.graph's
#: GRAPH_DEFAULTS); the last row but one is the default, the last swaps in rclpy's
#: EventsExecutor.
LEVERS = [
    ('rclpy SingleThreadedExecutor, /clock per node, parameter services',
     {'executor': 'single_threaded', 'direct_time': False, 'private_without_services': False}),
    ('+ no parameter services in a private graph',
     {'executor': 'single_threaded', 'direct_time': False, 'private_without_services': True}),
    ('+ time set directly by the clock source',
     {'executor': 'single_threaded', 'direct_time': True, 'private_without_services': True}),
    ('+ lock-step drain, QoS event handlers polled every round',
     {'executor': 'lockstep', 'direct_time': True, 'private_without_services': True,
      'qos_events_first_round_only': False, 'in_process_delivery': False}),
    ('+ QoS event handlers polled in the first round',
     {'executor': 'lockstep', 'direct_time': True, 'private_without_services': True,
      'qos_events_first_round_only': True, 'in_process_delivery': False}),
    ("+ messages between the graph's nodes handed over in process (default)",
     {'executor': 'lockstep', 'direct_time': True, 'private_without_services': True,
      'qos_events_first_round_only': True, 'in_process_delivery': True}),
    ('EventsExecutor instead of the lock-step drain',
     {'executor': 'events', 'direct_time': True, 'private_without_services': True}),
]


def measure_levers(names: Iterable[str], quick: bool = False,
                   options: Mapping[str, Any] | None = None,
                   log: Callable[[str], object] = print,
                   repeat: int = 2) -> list[tuple[str, dict[str, Any]]]:
    """Run the lock-step benchmarks ``names`` once per :data:`LEVERS` row, ``repeat`` times
    with the rows in alternating order (so a change of the machine's load during the runs
    weighs on every row alike), keeping each figure's best run; returns
    ``[(row label, figures), ...]`` with the load average after each row's last run."""
    from paramotion.graph import graph_defaults
    best = [dict() for _ in LEVERS]
    for r in range(int(repeat)):
        order = range(len(LEVERS)) if r % 2 == 0 else reversed(range(len(LEVERS)))
        for i in order:
            with graph_defaults(**LEVERS[i][1]):
                res = run_benchmarks(names, quick, options, log=log)
            for key, value in res.items():
                old = best[i].get(key)
                if isinstance(value, float) and isinstance(old, float):
                    value = max(value, old)
                best[i][key] = value
            best[i]['load_average_1min'] = os.getloadavg()[0]
    return [(label, figures) for (label, _), figures in zip(LEVERS, best)]


def _lever_lines(rows: Sequence[tuple[str, Mapping[str, Any]]],
                 names: Iterable[str]) -> list[str]:
    keys = [(k, lab) for n in names for k, lab in benches()[n][1].items()]
    lines = ['| Graph configuration | ' + ' | '.join(lab for _, lab in keys) + ' | load |',
             '|---|' + '---|' * (len(keys) + 1)]
    for label, res in rows:
        cells = [('n/a' if res.get(k) is None else f'{res[k]:.3f}') for k, _ in keys]
        lines.append(f'| {label} | ' + ' | '.join(cells)
                     + f' | {res.get("load_average_1min", 0.0):.1f} |')
    return lines


def _log_stderr(message: str) -> None:
    print(message, file=sys.stderr, flush=True)


def write_report(out_dir: Path, quick: bool = False) -> list[Path]:
    """Measure every figure, the Graph levers and the parts' extra tables; write
    ``<out_dir>/performance.md`` and return ``[path]``."""
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    log = _log_stderr
    start = time.monotonic()
    load0 = os.getloadavg()[0]
    res = run_benchmarks(list(benches()), quick=quick, log=log)
    res['load_average_1min'] = os.getloadavg()[0]
    names = lockstep_benches()
    rows = []
    for label, figures in measure_levers(names, quick=True, log=log,
                                         repeat=1 if quick else 2):
        rows.append((label, figures))
    extra = []
    for module in bench_modules():
        if hasattr(module, 'report_lines'):
            extra += module.report_lines(quick, log=log) + ['']
    now = datetime.datetime.now(datetime.timezone.utc)
    cmd = 'paramotion report --only performance' + (' --quick' if quick else '')
    lines = ['# Performance', '',
             f'- Date: {now:%Y-%m-%d %H:%M} UTC',
             f'- Machine: {platform.node()} ({platform.processor() or platform.machine()}, '
             f'{os.cpu_count()} cores); load average (1 min) {load0:.1f} at the start, '
             f'{os.getloadavg()[0]:.1f} at the end',
             f'- Command: `{cmd}` ({time.monotonic() - start:.0f} s)'
             + ('; --quick: fewer, shorter repeats' if quick else ''), '',
             '## Headline figures (`paramotion bench`)', '',
             '| figure | value |', '|---|---|']
    for name, (_, keys) in benches().items():
        for key, label in keys.items():
            v = res.get(key)
            text = f'not measured: {res["not_measured"].get(name, "?")}' if v is None else \
                _format(v).strip()
            lines.append(f'| {label} | {text} |')
    lines += ['', '## Lock-step Graph levers, one at a time', '',
              'Each row adds one lever to the row above (the last row swaps the executor); '
              'the same short (`--quick`) runs in the same process; without `--quick` each '
              'row runs twice, the rows in alternating order, and the best run counts. '
              "Sim s / CPU s counts this process's CPU time, which a loaded machine does not "
              'inflate the way it inflates wall time.', ''] + \
        _lever_lines(rows, names) + ['']
    lines += extra
    path = out_dir / 'performance.md'
    path.write_text('\n'.join(lines).rstrip() + '\n')
    return [path]


# ------------------------------------------------------------------------------ CLI
def _main(args: argparse.Namespace) -> int:
    available = benches()
    names = list(available) if not args.only else [n.strip() for n in args.only.split(',')]
    bad = [n for n in names if n not in available]
    if bad or not names:
        raise UserError(f'--only {args.only!r}: unknown {bad}; choose from '
                        f'{", ".join(available)}')
    options = {}
    if args.world:
        if not Path(args.world).is_file():
            raise UserError(f'--world {args.world}: no such file')
        options['world'] = Path(args.world)
    log = _log_stderr if args.json else print
    res = run_benchmarks(names, quick=args.quick, options=options, log=log)
    for line in table(res):
        print(line)
    if args.json:
        print(json.dumps(res, sort_keys=True, default=str))
    return 0


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add ``paramotion bench``."""
    p = subparsers.add_parser('bench', help='run every headline benchmark once, print a table',
                              description=__doc__.split('\n')[0])
    p.add_argument('--json', action='store_true', help='also print the figures as one JSON '
                   'object on the last line of stdout')
    p.add_argument('--quick', action='store_true', help='fewer, shorter repeats (noisier)')
    p.add_argument('--only', default='', help='comma-separated subset of the benchmarks '
                   '(see the table; e.g. fast,coverage)')
    p.add_argument('--world', default=None, help='world JSON for the benchmarks that take one '
                   '(default: their packaged world)')
    p.set_defaults(func=_main)
