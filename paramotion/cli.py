"""The ``paramotion`` command line: scenario runners and bag tools.

Each subcommand lives in the module that owns it and exposes ``register(subparsers)``; this
file only collects them, so adding a scenario never touches the others. A subcommand's handler
returns an exit code; :class:`paramotion.errors.UserError` is printed as one line.
"""
import argparse
import importlib
import sys
from collections.abc import Sequence

from paramotion.errors import UserError

# Modules providing ``register(subparsers)``; each adds one top-level subcommand, or a
# subcommand's action to one registered above it.
SUBCOMMAND_MODULES = [
    'paramotion.smoke.scenario',          # paramotion smoke
    'paramotion.bag.cli',                 # paramotion bag record|play|info
    'coverage_pkg.scenario',              # paramotion coverage
    'coverage_pkg.sweep',                 # paramotion coverage sweep --worlds DIR (Dask)
    'climber_pkg.scenario',               # paramotion climb
    'cable_robot_pkg.fast.scenario',      # paramotion fast
    'cable_robot_pkg.cdrpm.cli',         # paramotion workspace ...
    'voronoi_pkg.cli',                    # paramotion voronoi ...
    'paramotion.launch',                  # paramotion launch FILE|NAME [name:=value ...]
    'coverage_pkg.demo',                  # paramotion demo (README command 1)
    'paramotion.bench',                   # paramotion bench [--json]
    'paramotion.report',                  # paramotion report [--only PART] [--quick]
]

# Modules providing ``BENCHES`` for ``paramotion bench`` (see paramotion/bench.py), in the
# order of its table.
BENCH_MODULES = [
    'climber_pkg.bench',                  # FK solves/s, climbing graph speed
    'cable_robot_pkg.cdrpm.bench',        # KNTU workspace poses/s
    'voronoi_pkg.bench',                  # rho/s, the paper's query
    'cable_robot_pkg.fast.bench',         # FAST graph speed (one process; across processes)
    'coverage_pkg.bench',                 # coverage graph speed
]


def build_parser() -> argparse.ArgumentParser:
    """Build the argument parser with every available subcommand."""
    parser = argparse.ArgumentParser(
        prog='paramotion',
        description='Run paramotion scenarios headless on sim time and work with their bags.')
    subparsers = parser.add_subparsers(dest='command', metavar='COMMAND')
    subparsers.required = True
    for name in SUBCOMMAND_MODULES:
        try:
            module = importlib.import_module(name)
        except ModuleNotFoundError as exc:
            # A subcommand whose module is not written yet is simply absent; anything else
            # missing (a real dependency) is an error worth seeing.
            if exc.name is not None and name.startswith(exc.name):
                continue
            raise
        module.register(subparsers)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``paramotion`` console script."""
    try:
        parser = build_parser()   # imports every subcommand (SciPy, PyBullet): seconds
    except KeyboardInterrupt:
        print('paramotion: interrupted', file=sys.stderr)
        return 130
    args = parser.parse_args(argv)
    try:
        code = args.func(args)
    except UserError as exc:
        print(f'paramotion {args.command}: error: {exc}', file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f'paramotion {args.command}: interrupted', file=sys.stderr)
        return 130
    return 0 if code is None else int(code)


if __name__ == '__main__':
    sys.exit(main())
