"""The published figures of Aref & Taghirad beside ours, each marked fitted or held out.

The paper does not give its anchor coordinates; the shipped ``kntu_neuron.yaml`` is the
edge-anchored arrangement fitted to Table II (collision-free share of the in-frame grid) and
the TOW box (:func:`cable_robot_pkg.cdrpm.arrangements.search_table2_arrangements`). Every other
published number is held out and measured here:

- :func:`table2_measures`: Table II rows by eq. (10) (every grid point) and in-frame;
- :func:`tow_measures`: the 1.2 x 1.2 x 1.4 m box in the TOW for +-30, +-30, +-10 deg (IV-C)
  and the conclusion's cube of 60 % of each frame dimension for +-30 deg about every axis;
- :func:`fig7_trend`: the limit of r_y at the centre as r_x grows, and the collision type that
  sets it (IV-B: the limit shrinks, set by cable-body contact);
- :func:`workpiece_measures`: the share of the plane y = 0 kept with a workpiece (IV-D: 60 %)
  and the closest approach above it (0.5 m);
- :func:`claim_90`: the conclusion's "90 % of the positional workspace kept at 30/30/10 deg".

:func:`published_table` puts them in one table; :func:`anchor_sensitivity` perturbs the
unknown anchor coordinates by a few centimetres and reports the spread of every figure.
"""
from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike

from cable_robot_pkg.cdrpm.collisions import FLAG_OF_TYPE, OUTSIDE, classify_poses
from cable_robot_pkg.cdrpm.description import RobotDescription, description_from_dict
from cable_robot_pkg.cdrpm.kinematics import rotation_matrix_deg
from cable_robot_pkg.cdrpm.workspace import (
    PAPER_TOW_BOX_M,
    TABLE2_ROWS,
    constant_orientation_workspace,
    contains_box,
    largest_box,
    total_orientation_workspace,
    workpiece_study,
)

if TYPE_CHECKING:
    from cable_robot_pkg.cdrpm.arrangements import MapCases


#: The paper's workpiece figures (IV-D): share of the plane kept, closest approach (m).
PAPER_WORKPIECE_SHARE = 60.0
PAPER_WORKPIECE_GAP_M = 0.5
#: Workpiece size used for the held-out comparison (the paper gives none), m.
WORKPIECE_M = (1.0, 1.0, 0.5)
#: The conclusion's claim: 90 % of the positional workspace kept at 30/30/10 deg.
CLAIM_90_ROTATION = (30.0, 30.0, 10.0)
CLAIM_90_PERCENT = 90.0
#: The conclusion's cube: 60 % of each frame dimension for +-30 deg about every axis.
CUBE_THETA_DEG = (30.0, 30.0, 30.0)
CUBE_FRACTION = 0.6
#: r_x values (deg) at which the r_y limit of Fig. 7 is read.
FIG7_RX_DEG = (0.0, 15.0, 30.0, 45.0, 60.0)
FIG7_RZ_DEG = (0.0, 10.0, 20.0, 30.0)
#: Agreement tolerance (points) used for the shares, as in the fitting of Table II.
TOLERANCE_POINTS = 5.0


def table2_measures(desc: RobotDescription, step: float = 0.05) -> list[dict[str, object]]:
    """Table II rows: paper, ours by eq. (10), ours in-frame, and the points lost per type."""
    rows = []
    for rot, paper, _ in TABLE2_ROWS:
        cow = constant_orientation_workspace(desc, rot, step=step)
        rows.append({'rotation_deg': list(rot), 'paper': paper,
                     'eq10': cow.accessible_percentage,
                     'in_frame': cow.collision_free_percentage,
                     'outside_frame': cow.counts['outside_frame'],
                     'cable_cable': cow.counts['cable_cable'],
                     'cable_body': cow.counts['cable_body'],
                     'total_points': cow.counts['total_points']})
    return rows


def tow_measures(desc: RobotDescription, step: float = 0.05,
                 angle_step_deg: float = 10.0) -> dict:
    """The paper's TOW box (fitted) and the conclusion's +-30 deg cube (held out)."""
    tow = total_orientation_workspace(desc, (30, 30, 10), step=step,
                                      angle_step_deg=angle_step_deg)
    cube_size = tuple(CUBE_FRACTION * 2 * desc.frame_half_size)
    cube = total_orientation_workspace(desc, CUBE_THETA_DEG, step=step,
                                       angle_step_deg=angle_step_deg)
    box = largest_box(tow.accessible, tow.axes)
    cube_box = largest_box(cube.accessible, cube.axes)
    return {'tow_percent': tow.accessible_percentage,
            'box_fits': contains_box(tow.accessible, tow.axes, PAPER_TOW_BOX_M),
            'largest_box_m': None if box is None else box['size_m'],
            'cube_size_m': [round(float(v), 6) for v in cube_size],
            'cube_fits': contains_box(cube.accessible, cube.axes, cube_size),
            'cube_tow_percent': cube.accessible_percentage,
            'cube_largest_box_m': None if cube_box is None else cube_box['size_m']}


def _types_of(flag: int) -> str:
    """The collision types set in ``flag``, joined by '+' ('outside_frame' or 'none')."""
    if flag & OUTSIDE:
        return 'outside_frame'
    names = [name for name, bit in FLAG_OF_TYPE.items() if flag & bit]
    return '+'.join(names) if names else 'none'


@dataclass
class Fig7Row:
    """The r_y limit at one (r_x, r_z): the smaller of the two sides and what sets it."""

    rz: float
    rx: float
    ry_limit: float        # degrees; NaN where r_y = 0 itself collides
    decided_by: str


def fig7_rotations(rx: ArrayLike, ry: ArrayLike, rz: ArrayLike,
                   axes: str = 'moving') -> np.ndarray:
    """Rotation matrices for Fig. 7 angles (degrees, broadcast), (..., 3, 3).

    ``'moving'``: R = Rx(r_x) Ry(r_y) Rz(r_z), about the moving x, y', z'' axes (the convention
    of IV-C and of the rest of the package); ``'fixed'``: R = Rz(r_z) Ry(r_y) Rx(r_x), about the
    fixed axes. The paper does not say which one Fig. 7 uses.
    """
    if axes == 'moving':
        return rotation_matrix_deg(rx, ry, rz)
    if axes != 'fixed':
        raise ValueError(f"axes {axes!r}: must be 'moving' or 'fixed'")
    zero = np.zeros(np.broadcast(rx, ry, rz).shape)
    return (rotation_matrix_deg(zero, zero, zero + rz) @ rotation_matrix_deg(zero, zero + ry,
                                                                          zero)
            @ rotation_matrix_deg(zero + rx, zero, zero))


def fig7_trend(desc: RobotDescription, position: ArrayLike = (0.0, 0.0, 0.0),
               rx_deg: Iterable[float] = FIG7_RX_DEG, rz_deg: Iterable[float] = FIG7_RZ_DEG,
               step_deg: float = 1.0, max_deg: float = 90.0,
               without: Iterable[str] | None = (), axes: str = 'moving') -> list[Fig7Row]:
    """Orientation workspace of IV-B read as Fig. 7's curves: the r_y limit per (r_z, r_x).

    r_y is scanned outwards from 0 in ``step_deg`` steps on both sides; the limit is the last
    accessible r_y of the side that ends first, and ``decided_by`` the collision type(s) of
    the first inaccessible r_y there ('range' if the scan ends first). ``without`` switches
    constructs off (:func:`classify_poses`); ``axes`` chooses the rotation convention
    (:func:`fig7_rotations`).
    """
    ry = np.arange(0.0, max_deg + step_deg / 2, step_deg)
    out = []
    for rz in rz_deg:
        for rx in rx_deg:
            limits = []
            for sign in (1.0, -1.0):
                rots = fig7_rotations(np.full(ry.size, rx), sign * ry, np.full(ry.size, rz), axes)
                pos = np.broadcast_to(np.asarray(position, float), (ry.size, 3))
                flags = classify_poses(desc, pos, rots, without=without)
                blocked = np.nonzero(flags != 0)[0]
                if blocked.size == 0:
                    limits.append((float(ry[-1]), 'range'))
                elif blocked[0] == 0:
                    limits.append((float('nan'), _types_of(int(flags[0]))))
                else:
                    k = blocked[0]
                    limits.append((float(ry[k - 1]), _types_of(int(flags[k]))))
            limit, cause = min(limits, key=lambda v: (np.nan_to_num(v[0], nan=-1.0)))
            out.append(Fig7Row(rz=float(rz), rx=float(rx), ry_limit=limit, decided_by=cause))
    return out


def fig7_verdict(rows: list[Fig7Row], rx_low: float = 0.0,
                 rx_high: float = 45.0) -> dict[str, object]:
    """The paper's Fig. 7 statements tested on :func:`fig7_trend` rows at r_z = 0.

    ``shrinks``: the r_y limit at ``rx_high`` is below the one at ``rx_low``;
    ``body_decides``: cable-body contact sets the limit at ``rx_high``;
    ``cable_first_with_rz``: at the largest r_z, cable-cable contact sets the limit at r_x = 0
    (the paper: with z-rotation, cable-cable collision comes before cable-body collision).
    """
    at = {(r.rz, r.rx): r for r in rows}
    low, high = at[(0.0, rx_low)], at[(0.0, rx_high)]
    rz_max = max(r.rz for r in rows)
    with_rz = at[(rz_max, rx_low)]
    return {'ry_limit_low': low.ry_limit, 'ry_limit_high': high.ry_limit,
            'decided_low': low.decided_by, 'decided_high': high.decided_by,
            'shrinks': bool(high.ry_limit < low.ry_limit),
            'body_decides': 'cable_body' in high.decided_by,
            'rz_max': rz_max, 'decided_at_rz_max': with_rz.decided_by,
            'cable_first_with_rz': with_rz.decided_by.startswith('cable_cable')}


def workpiece_measures(desc: RobotDescription, size: Sequence[float] = WORKPIECE_M,
                       step: float = 0.02) -> dict[str, object]:
    """IV-D on the plane y = 0: share kept with the workpiece, closest approach above it,
    and the share of the plane's points lost to each collision type."""
    res = workpiece_study(desc, size, step=step)
    flags = res['flags_workpiece']
    total = flags.size
    lost = {name: 100.0 * np.count_nonzero(flags & bit) / total
            for name, bit in FLAG_OF_TYPE.items()}
    return {'size_m': list(size), 'share': res['ratio_percent'],
            'gap_m': res['min_gap_above_workpiece_m'], 'lost_percent': lost}


def claim_90(desc: RobotDescription, step: float = 0.05) -> dict:
    """The conclusion's 90 % at 30/30/10 deg, by eq. (10) and in-frame."""
    cow = constant_orientation_workspace(desc, CLAIM_90_ROTATION, step=step)
    return {'eq10': cow.accessible_percentage, 'in_frame': cow.collision_free_percentage}


def _row(figure, paper, ours, use, agrees, note=''):
    return {'figure': figure, 'paper': paper, 'ours': ours, 'use': use,
            'agrees': bool(agrees), 'note': note}


def published_table(desc: RobotDescription, quick: bool = False) -> dict:
    """Every published number, the paper's value, ours, and whether it was fitted.

    Returns ``{'rows': [...], 'table2': ..., 'tow': ..., 'fig7': ..., 'workpiece': ...,
    'claim_90': ...}``; ``quick`` uses coarser grids (0.1 m, 0.04 m plane, 2 deg).
    """
    step = 0.1 if quick else 0.05
    t2 = table2_measures(desc, step)
    tow = tow_measures(desc, step=step)
    trend = fig7_trend(desc, step_deg=2.0 if quick else 1.0)
    verdict = fig7_verdict(trend)
    fixed = fig7_verdict(fig7_trend(desc, rx_deg=(0.0, 45.0), rz_deg=(0.0, 30.0),
                                    step_deg=2.0 if quick else 1.0, axes='fixed'))
    work = workpiece_measures(desc, step=0.04 if quick else 0.02)
    sizes = workpiece_size_scan(desc, step=0.05 if quick else 0.04)
    c90 = claim_90(desc, step)
    rows = []
    for r in t2:
        rot = '/'.join(f'{v:g}' for v in r['rotation_deg'])
        rows.append(_row(f'Table II {rot}, in frame', f'{r["paper"]:g} %',
                         f'{r["in_frame"]:.1f} %', 'fitted',
                         abs(r['in_frame'] - r['paper']) <= TOLERANCE_POINTS))
    for r in t2:
        rot = '/'.join(f'{v:g}' for v in r['rotation_deg'])
        rows.append(_row(f'Table II {rot}, eq. (10)', f'{r["paper"]:g} %',
                         f'{r["eq10"]:.1f} %', 'held out',
                         abs(r['eq10'] - r['paper']) <= TOLERANCE_POINTS,
                         f'{r["outside_frame"]} of {r["total_points"]} points leave the frame'))
    rows.append(_row('TOW +-30/30/10 holds 1.2 x 1.2 x 1.4 m', 'yes',
                     f'{"yes" if tow["box_fits"] else "no"} (largest '
                     f'{" x ".join(f"{v:.2f}" for v in tow["largest_box_m"] or [])} m)',
                     'fitted', tow['box_fits']))
    for name, v in (('moving axes', verdict), ('fixed axes', fixed)):
        rows.append(_row(f'Fig. 7 ({name}): r_y limit shrinks as r_x grows (r_z = 0)',
                         'shrinks', f'{v["ry_limit_low"]:.0f} deg at r_x = 0 -> '
                         f'{v["ry_limit_high"]:.0f} deg at r_x = 45', 'held out', v['shrinks'],
                         'the paper does not give the convention' if name == 'fixed axes'
                         else 'R = Rx Ry Rz, as IV-C'))
        rows.append(_row(f'Fig. 7 ({name}): cable-body contact sets that limit', 'cable-body',
                         v['decided_high'].replace('_', '-'), 'held out', v['body_decides']))
    rows.append(_row(f'Fig. 7: with r_z = {verdict["rz_max"]:g}, cable-cable comes first',
                     'cable-cable', verdict['decided_at_rz_max'].replace('_', '-'), 'held out',
                     verdict['cable_first_with_rz']))
    size = ' x '.join(f'{v:g}' for v in work['size_m'])
    rows.append(_row(f'workpiece ({size} m): share of the plane y = 0 kept',
                     f'{PAPER_WORKPIECE_SHARE:g} %', f'{work["share"]:.1f} %', 'held out',
                     abs(work['share'] - PAPER_WORKPIECE_SHARE) <= TOLERANCE_POINTS,
                     'the paper gives no workpiece size'))
    gap = work['gap_m']
    rows.append(_row('workpiece: closest approach above it', f'{PAPER_WORKPIECE_GAP_M:g} m',
                     'none' if gap is None else f'{gap:.2f} m', 'held out',
                     gap is not None and abs(gap - PAPER_WORKPIECE_GAP_M) <= 0.1))
    both = [s for s in sizes if _workpiece_ok(s['share'], s['gap_m'])]
    rows.append(_row('workpiece: some size gives 60 % and 0.5 m together', 'one size',
                     '; '.join(f'{" x ".join(f"{v:g}" for v in s["size_m"])} m: '
                               f'{s["share"]:.1f} %, {s["gap_m"]:.2f} m' for s in both)
                     or f'none of {len(sizes)} sizes', 'held out', bool(both),
                     'sizes scanned: W_x = W_y 0.4-1.8 m, W_z 0.05-0.65 m'))
    rows.append(_row('90 % kept at 30/30/10, in frame', f'{CLAIM_90_PERCENT:g} %',
                     f'{c90["in_frame"]:.1f} %', 'held out',
                     abs(c90['in_frame'] - CLAIM_90_PERCENT) <= TOLERANCE_POINTS))
    rows.append(_row('90 % kept at 30/30/10, eq. (10)', f'{CLAIM_90_PERCENT:g} %',
                     f'{c90["eq10"]:.1f} %', 'held out',
                     abs(c90['eq10'] - CLAIM_90_PERCENT) <= TOLERANCE_POINTS))
    cube = ' x '.join(f'{v:.1f}' for v in tow['cube_size_m'])
    rows.append(_row(f'TOW +-30/30/30 holds a {cube} m cube (60 % of each dimension)', 'yes',
                     f'{"yes" if tow["cube_fits"] else "no"} (largest '
                     f'{" x ".join(f"{v:.2f}" for v in tow["cube_largest_box_m"] or [])} m)',
                     'held out', tow['cube_fits']))
    return {'rows': rows, 'table2': t2, 'tow': tow,
            'fig7': [r.__dict__ for r in trend], 'fig7_verdict': verdict,
            'fig7_fixed_verdict': fixed,
            'workpiece': work, 'workpiece_sizes': sizes, 'claim_90': c90, 'step_m': step}


# --- sensitivity to the unknown anchor coordinates --------------------------------------------

def perturbed_description(desc: RobotDescription, rng: np.random.Generator,
                          spread_m: float) -> RobotDescription:
    """``desc`` with every frame anchor moved by up to ``spread_m`` per coordinate.

    Each coordinate of each A_i moves independently (uniform in +-``spread_m``) and is clamped
    into the frame, so anchors on a face or an edge may move inwards but never out: the
    symmetry of the arrangement is not kept.
    """
    moved = desc.frame_points + rng.uniform(-spread_m, spread_m, desc.frame_points.shape)
    moved = np.clip(moved, -desc.frame_half_size, desc.frame_half_size)
    return description_from_dict({**desc.to_dict(), 'frame_points': moved.tolist(),
                                  'name': f'{desc.name}_perturbed'})


def sensitivity_figures(desc: RobotDescription, step: float, angle_step_deg: float,
                        plane_step: float, fig7_step_deg: float) -> dict:
    """The published figures of one description as numbers (for :func:`anchor_sensitivity`)."""
    t2 = table2_measures(desc, step)
    tow = total_orientation_workspace(desc, (30, 30, 10), step=step,
                                      angle_step_deg=angle_step_deg)
    verdict = fig7_verdict(fig7_trend(desc, rx_deg=(0.0, 45.0), rz_deg=(0.0, 30.0),
                                      step_deg=fig7_step_deg))
    fixed = fig7_verdict(fig7_trend(desc, rx_deg=(0.0, 45.0), rz_deg=(0.0, 30.0),
                                    step_deg=fig7_step_deg, axes='fixed'))
    work = workpiece_measures(desc, step=plane_step)
    c90 = claim_90(desc, step)
    out = {}
    for r in t2:
        rot = '/'.join(f'{v:g}' for v in r['rotation_deg'])
        out[f'Table II {rot} in frame (%)'] = r['in_frame']
        out[f'Table II {rot} eq. (10) (%)'] = r['eq10']
    out['TOW box 1.2 x 1.2 x 1.4 m fits (share of samples)'] = float(
        contains_box(tow.accessible, tow.axes, PAPER_TOW_BOX_M))
    out['Fig. 7 r_y limit at r_x = 0 (deg)'] = verdict['ry_limit_low']
    out['Fig. 7 r_y limit at r_x = 45 (deg)'] = verdict['ry_limit_high']
    out['Fig. 7 limit shrinks (share of samples)'] = float(verdict['shrinks'])
    out['Fig. 7 cable-body sets it (share of samples)'] = float(verdict['body_decides'])
    out['Fig. 7 fixed axes: r_y limit at r_x = 45 (deg)'] = fixed['ry_limit_high']
    out['Fig. 7 fixed axes: limit shrinks (share of samples)'] = float(fixed['shrinks'])
    out['Fig. 7 fixed axes: cable-body sets it (share of samples)'] = float(
        fixed['body_decides'])
    out['workpiece share (%)'] = work['share']
    out['workpiece closest approach (m)'] = np.nan if work['gap_m'] is None else work['gap_m']
    out['30/30/10 in frame (%)'] = c90['in_frame']
    out['30/30/10 eq. (10) (%)'] = c90['eq10']
    return out


def anchor_sensitivity(desc: RobotDescription, samples: int = 12, spread_m: float = 0.03,
                       seed: int = 0, quick: bool = False) -> dict:
    """Spread of every published figure when the anchors move by up to ``spread_m``.

    Returns ``{'nominal': {...}, 'rows': [{'figure', 'nominal', 'min', 'median', 'mean',
    'max'}], 'samples', 'spread_m'}``; for the yes/no figures the mean is the share of samples
    where they hold.
    """
    kw = dict(step=0.1 if quick else 0.05, angle_step_deg=10.0,
              plane_step=0.05 if quick else 0.02, fig7_step_deg=2.0 if quick else 1.0)
    nominal = sensitivity_figures(desc, **kw)
    rng = np.random.default_rng(seed)
    values = {k: [] for k in nominal}
    for _ in range(samples):
        figs = sensitivity_figures(perturbed_description(desc, rng, spread_m), **kw)
        for k, v in figs.items():
            values[k].append(v)
    rows = []
    for k, v in values.items():
        arr = np.asarray(v, dtype=float)
        rows.append({'figure': k, 'nominal': float(nominal[k]), 'min': float(np.nanmin(arr)),
                     'median': float(np.nanmedian(arr)), 'mean': float(np.nanmean(arr)),
                     'max': float(np.nanmax(arr))})
    return {'nominal': nominal, 'rows': rows, 'samples': samples, 'spread_m': spread_m,
            'grid_step_m': kw['step']}


# --- which candidate arrangements meet the held-out figures -----------------------------------

#: Workpiece sizes (W_x = W_y, W_z in m) scanned for the held-out workpiece share: the paper
#: gives none.
WORKPIECE_SIZES_M = tuple((w, w, h) for w in (0.4, 0.6, 0.8, 1.0, 1.2, 1.4, 1.6, 1.8)
                          for h in (0.05, 0.1, 0.2, 0.35, 0.5, 0.65))


def workpiece_size_scan(desc: RobotDescription,
                        sizes: Iterable[Sequence[float]] = WORKPIECE_SIZES_M,
                        step: float = 0.05) -> list[dict[str, object]]:
    """Workpiece share of the plane y = 0 and closest approach for each size (m)."""
    out = []
    for size in sizes:
        res = workpiece_study(desc, size, step=step)
        out.append({'size_m': list(size), 'share': res['ratio_percent'],
                    'gap_m': res['min_gap_above_workpiece_m']})
    return out


def radius_sensitivity(desc: RobotDescription,
                       radii_m: Iterable[float] = (0.001, 0.0025, 0.005, 0.01),
                       step: float = 0.05, fig7_step: float = 1.0) -> list[dict[str, object]]:
    """Table II in frame and the Fig. 7 verdict for other cable radii (the paper gives none)."""
    from cable_robot_pkg.cdrpm.arrangements import table2_in_frame
    from cable_robot_pkg.cdrpm.workspace import grid_axes, grid_points
    points = grid_points(grid_axes(desc, step))
    out = []
    for radius in radii_m:
        d = description_from_dict({**desc.to_dict(), 'cable_radius': float(radius)})
        verdict = fig7_verdict(fig7_trend(d, rx_deg=(0.0, 45.0), rz_deg=(0.0, 30.0),
                                          step_deg=fig7_step))
        out.append({'radius_m': float(radius),
                    'table2_in_frame': table2_in_frame(d, points).tolist(),
                    'fig7': verdict})
    return out


def _heldout_case(case):
    """Fig. 7 verdict and workpiece share of one candidate (for :func:`heldout_search`)."""
    desc, plane_step, fig7_step = case
    verdicts = [fig7_verdict(fig7_trend(desc, rx_deg=(0.0, 45.0), rz_deg=(0.0, 30.0),
                                        step_deg=fig7_step, axes=axes))
                for axes in ('moving', 'fixed')]
    work = workpiece_study(desc, WORKPIECE_M, step=plane_step)
    return verdicts, work['ratio_percent'], work['min_gap_above_workpiece_m']


def _fitted_case(case):
    """Table II on the fine grid, TOW box and workpiece size scan of one screened candidate."""
    from cable_robot_pkg.cdrpm.arrangements import table2_in_frame
    from cable_robot_pkg.cdrpm.workspace import grid_axes, grid_points
    desc, step, tow_step, plane_step = case
    paper = np.array([row[1] for row in TABLE2_ROWS])
    shares = table2_in_frame(desc, grid_points(grid_axes(desc, step)))
    worst = float(np.max(np.abs(shares - paper)))
    out = {'table2_in_frame': shares.tolist(), 'table2_worst': worst}
    if worst <= TOLERANCE_POINTS:
        tow = total_orientation_workspace(desc, (30, 30, 10), step=tow_step)
        out.update({'tow_box_fits': contains_box(tow.accessible, tow.axes, PAPER_TOW_BOX_M),
                    'workpiece_sizes': workpiece_size_scan(desc, WORKPIECE_SIZES_M,
                                                           plane_step)})
    return out


def heldout_search(desc: RobotDescription, pitch: float = 0.1, min_home_gap: float = 0.02,
                   screen_step: float = 0.2, screen_tolerance: float = 8.0,
                   plane_step: float = 0.05, fig7_step: float = 2.0, sample: int = 1000,
                   seed: int = 0, map_cases: MapCases | None = None) -> dict[str, object]:
    """Which edge-anchored candidates reproduce the held-out figures together with the fitted?

    Candidates: those of the fit (:func:`cable_robot_pkg.cdrpm.arrangements._home_candidates`,
    the dimensions of ``desc``), screened by Table II on the ``screen_step`` grid. Evaluated:
    every candidate within ``screen_tolerance`` points of Table II there, and a random
    ``sample`` of the others (``seed``; ``sample`` < 0: all). For each: Fig. 7's verdict
    (:func:`fig7_verdict`) under both rotation conventions (:func:`fig7_rotations`) and the
    workpiece share at :data:`WORKPIECE_M`. For the screened ones also Table II on the 0.05 m
    grid and, within 5 points, the TOW box and the workpiece share over
    :data:`WORKPIECE_SIZES_M`. Returns counts and the per-candidate rows.
    """
    from cable_robot_pkg.cdrpm.arrangements import (
        _home_candidates,
        _map_in_order,
        table2_in_frame,
    )
    from cable_robot_pkg.cdrpm.workspace import grid_axes, grid_points
    map_cases = _map_in_order if map_cases is None else map_cases
    stats = {}
    cands = _home_candidates(desc.frame_half_size, desc.platform_half_size, desc.cable_radius,
                             pitch, min_home_gap, stats, map_cases=map_cases)
    paper = np.array([row[1] for row in TABLE2_ROWS])
    screen = grid_points(grid_axes(desc, screen_step))
    worst = [float(np.max(np.abs(table2_in_frame(c[2], screen) - paper))) for c in cands]
    near = [k for k, w in enumerate(worst) if w <= screen_tolerance]
    others = [k for k, w in enumerate(worst) if w > screen_tolerance]
    if 0 <= sample < len(others):
        others = sorted(np.random.default_rng(seed).choice(others, sample, replace=False))
    chosen = sorted(near + [int(k) for k in others])
    heldout = map_cases(_heldout_case, [(cands[k][2], plane_step, fig7_step) for k in chosen])
    rows = []
    for k, (verdicts, share, gap) in zip(chosen, heldout):
        a0, a1 = cands[k][0], cands[k][1]
        rows.append({'anchor0': a0.tolist(), 'anchor1': a1.tolist(), 'screen_worst': worst[k],
                     'near_table2': worst[k] <= screen_tolerance,
                     'fig7': verdicts[0], 'fig7_fixed': verdicts[1],
                     'workpiece_share': share, 'workpiece_gap_m': gap})
    index = {k: n for n, k in enumerate(chosen)}
    fitted = map_cases(_fitted_case, [(cands[k][2], 0.05, 0.1, plane_step) for k in near])
    for k, extra in zip(near, fitted):
        rows[index[k]].update(extra)
    stats.update({'candidates_total': len(cands), 'near_table2_screen': len(near),
                  'sampled_others': len(others), 'sample_seed': seed})
    return {'stats': stats, 'rows': rows, 'summary': summarise_heldout(rows)}


def _paper_trend(row, key='fig7'):
    return row[key]['shrinks'] and row[key]['body_decides']


def _workpiece_ok(share, gap):
    return (abs(share - PAPER_WORKPIECE_SHARE) <= TOLERANCE_POINTS and gap is not None
            and abs(gap - PAPER_WORKPIECE_GAP_M) <= 0.1)


def summarise_heldout(rows: list[dict[str, object]]) -> dict[str, object]:

    """Counts of :func:`heldout_search` rows meeting each published figure and their overlap."""
    fig7 = [r for r in rows if _paper_trend(r)]
    shrink = [r for r in rows if r['fig7']['shrinks']]
    work = [r for r in rows if _workpiece_ok(r['workpiece_share'], r['workpiece_gap_m'])]
    t2 = [r for r in rows if r.get('table2_worst', np.inf) <= TOLERANCE_POINTS]
    sampled = [r for r in rows if not r.get('near_table2', 'table2_worst' in r)]
    fitted = [r for r in t2 if r.get('tow_box_fits')]

    def any_size(r):
        return any(_workpiece_ok(s['share'], s['gap_m']) for s in r['workpiece_sizes'])

    def decided_by(key):
        out = {}
        for r in fitted:
            name = r[key]['decided_high']
            out[name] = out.get(name, 0) + 1
        return out

    fixed = [r for r in rows if _paper_trend(r, 'fig7_fixed')]
    return {
        'candidates': len(rows),
        'sampled_far_from_table2': len(sampled),
        'sampled_fig7_trend': sum(1 for r in sampled if _paper_trend(r)),
        'sampled_fig7_fixed_trend': sum(1 for r in sampled if _paper_trend(r, 'fig7_fixed')),
        'fig7_shrinks': len(shrink),
        'fig7_shrinks_by_cable_body': len(fig7),
        'workpiece_60_at_default_size': len(work),
        'fig7_and_workpiece': sum(1 for r in fig7 if r in work),
        'table2_within_5': len(t2),
        'table2_and_tow_box': len(fitted),
        'fitted_with_fig7_trend': sum(1 for r in fitted if _paper_trend(r)),
        'fitted_with_fig7_shrinking': sum(1 for r in fitted if r['fig7']['shrinks']),
        'fitted_with_workpiece_60_some_size': sum(1 for r in fitted if any_size(r)),
        'fitted_with_both': sum(1 for r in fitted if _paper_trend(r) and any_size(r)),
        'fitted_fig7_decided_by': decided_by('fig7'),
        'fig7_fixed_shrinks': sum(1 for r in rows if r['fig7_fixed']['shrinks']),
        'fig7_fixed_shrinks_by_cable_body': len(fixed),
        'fitted_with_fig7_fixed_shrinking': sum(1 for r in fitted
                                                if r['fig7_fixed']['shrinks']),
        'fitted_with_fig7_fixed_trend': sum(1 for r in fitted
                                            if _paper_trend(r, 'fig7_fixed')),
        'fitted_fig7_fixed_decided_by': decided_by('fig7_fixed'),
        'best_table2_screen_with_fig7_fixed_trend': min((r['screen_worst'] for r in fixed),
                                                        default=None),
        'best_table2_screen_with_fig7_trend': min((r['screen_worst'] for r in fig7),
                                                  default=None),
        'best_table2_screen_with_workpiece_60': min((r['screen_worst'] for r in work),
                                                    default=None),
    }
