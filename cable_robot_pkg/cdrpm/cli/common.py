"""Argument checks, JSON output and figure helpers shared by the workspace analyses.

Every analysis writes its outputs only once everything is computed, atomically, so a
failed or interrupted run leaves nothing half-written.
"""
import json
import math
import os
import tempfile
from pathlib import Path

import numpy as np

from paramotion.errors import UserError

#: Largest grid accepted (points), so that a typo in --step cannot exhaust memory.
MAX_GRID_POINTS = 20_000_000
#: Colours of the collision categories in the figures.
CATEGORY_COLOURS = {
    'accessible': '#d9f0d3', 'outside_frame': '#bdbdbd', 'cable_cable': '#d7301f',
    'cable_body': '#2b8cbe', 'cable_workpiece': '#fd8d3c', 'platform_workpiece': '#756bb1'}


def robot(args):
    from cable_robot_pkg.cdrpm.description import load_description
    return load_description(args.robot)


def without(args):
    """The validated ``--without`` names (constructs switched off), as a frozenset."""
    from cable_robot_pkg.cdrpm.collisions import check_without
    try:
        return check_without(getattr(args, 'without', None) or ())
    except ValueError as exc:
        raise UserError(f'--{exc}') from None


#: What the shipped default arrangement is, said wherever the output names it.
FITTED_NOTE = 'arrangement fitted to Table II and the TOW box, not published anchors'


def robot_label(desc):
    """The robot's name, with :data:`FITTED_NOTE` for the shipped fitted Neuron."""
    from cable_robot_pkg.cdrpm.description import default_description_path
    try:
        fitted = Path(desc.source).resolve() == default_description_path().resolve()
    except (OSError, ValueError):
        fitted = False
    return f'{desc.name} ({FITTED_NOTE})' if fitted else desc.name


def finite(name, values, lo=None, hi=None):
    values = values if isinstance(values, (list, tuple)) else [values]
    for v in values:
        if not math.isfinite(v) or (lo is not None and v < lo) or (hi is not None and v > hi):
            rng = f' (allowed [{lo}, {hi}])' if lo is not None or hi is not None else ''
            raise UserError(f'{name} {v}: must be a finite number{rng}')


def check_step(desc, step, name='--step'):
    if not (math.isfinite(step) and step > 0):
        raise UserError(f'{name} {step}: must be a positive number of metres')
    span = 2 * (desc.frame_half_size - desc.platform_half_size)
    count = float(np.prod(np.maximum(np.floor(span / step + 1e-9), 1)))
    if count > MAX_GRID_POINTS:
        raise UserError(f'{name} {step}: grid of {count:.3g} points exceeds '
                        f'{MAX_GRID_POINTS:,}; use a larger step')


def out_dir(out):
    out = Path(out)
    if out.exists() and not out.is_dir():
        raise UserError(f'--out {out}: exists and is not a directory')
    return out


def to_json(value):
    if isinstance(value, dict):
        return {str(k): to_json(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [to_json(v) for v in value]
    if isinstance(value, np.ndarray):
        return to_json(value.tolist())
    if isinstance(value, (np.bool_,)):
        return bool(value)
    if isinstance(value, np.integer):
        return int(value)
    if isinstance(value, (float, np.floating)):
        value = float(value)
        return value if math.isfinite(value) else None
    return value


def write_outputs(out, result, figure=None, figure_name=None):
    """Write result.json (and a figure) atomically once everything is computed."""
    out.mkdir(parents=True, exist_ok=True)
    if figure is not None:
        tmp = out / f'.{figure_name}.tmp.png'
        figure.savefig(tmp, dpi=110)
        os.replace(tmp, out / figure_name)
        import matplotlib.pyplot as plt
        plt.close(figure)
    fd, tmp = tempfile.mkstemp(dir=out, prefix='.result.', suffix='.json')
    with os.fdopen(fd, 'w') as fh:
        json.dump(to_json(result), fh, indent=2)
        fh.write('\n')
    os.replace(tmp, out / 'result.json')


def subplots(*args, **kwargs):
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt
    return plt.subplots(*args, **kwargs)


def category_image(flags):
    """Map flag arrays to category indices (order of CATEGORY_COLOURS)."""
    from cable_robot_pkg.cdrpm.collisions import FLAG_OF_TYPE, OUTSIDE
    cat = np.zeros(flags.shape, dtype=int)
    assigned = flags == 0
    cat[(flags & OUTSIDE) != 0] = 1
    assigned |= (flags & OUTSIDE) != 0
    for k, bit in enumerate(FLAG_OF_TYPE.values()):
        hit = ((flags & bit) != 0) & ~assigned
        cat[hit] = 2 + k
        assigned |= hit
    return cat


def legend(fig):
    from matplotlib.patches import Patch
    handles = [Patch(color=c, label=name.replace('_', '-')) for name, c in
               CATEGORY_COLOURS.items()]
    fig.legend(handles=handles, loc='lower center', ncol=len(handles), fontsize=8)


def cmap():
    from matplotlib.colors import ListedColormap
    return ListedColormap(list(CATEGORY_COLOURS.values()))
