"""Helpers shared by scenario commands: output directories, result files, summaries.

A scenario writes ``DIR/bag/``, ``DIR/result.json`` and a PNG. Outputs are first written into a
temporary sibling directory and moved into place only when the run succeeded, so a failed or
interrupted run never leaves a half-written ``DIR``.
"""
from __future__ import annotations

import argparse
import json
import math
import shutil
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

from paramotion.errors import UserError


def _jsonable(value):
    """Make numpy scalars/arrays and non-finite floats JSON-safe (NaN/inf become null)."""
    if hasattr(value, 'tolist'):
        value = value.tolist()
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if isinstance(value, dict):
        return {str(k): _jsonable(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_jsonable(v) for v in value]
    return value


def write_json(path: str | Path, data: object) -> None:
    """Write ``data`` as indented JSON (numpy-aware, strict: no NaN literals)."""
    Path(path).write_text(json.dumps(_jsonable(data), indent=1, allow_nan=False) + '\n')


@contextmanager
def output_dir(out: str | Path, overwrite: bool = False) -> Iterator[Path]:
    """Yield a temporary directory that becomes ``out`` when the block succeeds.

    ``out`` must not exist unless ``overwrite``; on failure the temporary directory is removed
    and ``out`` is left as it was.
    """
    out = Path(out)
    if out.exists() and not overwrite:
        raise UserError(f'--out {out}: already exists (use --overwrite to replace it)')
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = out.parent / f'.{out.name}.partial-{int(time.time() * 1e6)}'
    tmp.mkdir()
    try:
        yield tmp
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    if out.exists():
        shutil.rmtree(out)
    tmp.rename(out)


def add_output_args(parser: argparse.ArgumentParser, default_out: str | None = None) -> None:
    """Add the common ``--out`` and ``--overwrite`` arguments."""
    parser.add_argument('--out', required=default_out is None, default=default_out,
                        help='output directory (bag/, result.json, PNG)'
                        + (f'; default {default_out}' if default_out else ''))
    parser.add_argument('--overwrite', action='store_true',
                        help='replace --out if it exists')
