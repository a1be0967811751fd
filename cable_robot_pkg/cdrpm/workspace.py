"""Workspace analyses of section IV of Aref & Taghirad, built on :mod:`.collisions`.

- :func:`constant_orientation_workspace` (IV-A): the centroid positions, on a grid, reachable
  without collision at one fixed orientation; :func:`accessible_percentage` is eq. (10).
- :func:`table2`: the rows of the paper's Table II.
- :func:`orientation_workspace` (IV-B, Fig. 7): at one position, the accessible (r_x, r_y)
  region for given r_z and its boundary.
- :func:`total_orientation_workspace` (IV-C): the intersection of the COWs of all orientations
  in a +-theta_m box (sampled), and :func:`largest_box` inside it.
- :func:`workpiece_study` (IV-D): the COW on the plane y = 0 with and without a workpiece.

Grid: the paper lays "a grid pattern ... for the whole space" of the frame. Here the grid covers
the centroid positions at which the un-rotated platform fits inside the frame (the frame shrunk
by the platform half sizes), with points at cell centres ``step`` apart, symmetric about O.
At zero rotation every grid point is then inside the frame; a rotated platform near a wall
sticks out of the frame and that point is counted as ``outside_frame``, not as a collision.
Eq. (10) counts all grid points; :attr:`COWResult.collision_free_percentage` is the share of
in-frame points without collision (the paper's program checks collisions only).
"""
from __future__ import annotations

import time
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike

from cable_robot_pkg.cdrpm.collisions import (
    CABLE_BODY,
    CABLE_CABLE,
    CABLE_WORKPIECE,
    DEFAULT_CHUNK,
    FLAG_OF_TYPE,
    OUTSIDE,
    PLATFORM_WORKPIECE,
    classify_poses,
    count_flags,
)
from cable_robot_pkg.cdrpm.kinematics import rotation_matrix_deg

if TYPE_CHECKING:
    from cable_robot_pkg.cdrpm.description import RobotDescription

#: Table II of the paper: (theta_x, theta_y, theta_z) in degrees, KNTU CDRPM %, WARP %.
TABLE2_ROWS = (
    ((0, 0, 0), 100.0, 90.0),
    ((30, 0, 0), 97.0, 30.0),
    ((0, 30, 0), 97.0, 50.0),
    ((0, 0, 30), 85.0, 10.0),
    ((30, 30, 30), 71.0, None),
)
#: The paper's box inside the TOW for +-30, +-30, +-10 deg (IV-C), x, y, z in m.
PAPER_TOW_BOX_M = (1.2, 1.2, 1.4)
#: Paper's timing: 373 s of a 4.3 GHz CPU for 148,000 points (section IV).
PAPER_POINTS = 148000
PAPER_SECONDS = 373.0
#: Paper's grid resolution (section IV-A), points per cubic metre.
PAPER_RESOLUTION = 37000.0


def _progress(iterable, enabled, total=None, desc=None):
    """Wrap ``iterable`` in a tqdm progress bar when ``enabled``."""
    if not enabled:
        return iterable
    from tqdm import tqdm
    return tqdm(iterable, total=total, desc=desc, unit='step', leave=False)


def grid_axes(desc: RobotDescription, step: float) -> list[np.ndarray]:
    """Cell-centre grid axes over the centroid region (frame shrunk by the platform)."""
    if not step > 0:
        raise ValueError(f'grid step must be > 0, got {step}')
    span = 2 * (desc.frame_half_size - desc.platform_half_size)
    axes = []
    for k in range(3):
        n = max(1, int(np.floor(span[k] / step + 1e-9)))
        axes.append((np.arange(n) - (n - 1) / 2) * step)
    return axes


def grid_points(axes: Sequence[ArrayLike]) -> np.ndarray:
    """(N, 3) points of the grid given by three axes, x slowest, z fastest."""
    mesh = np.meshgrid(*axes, indexing='ij')
    return np.stack([m.ravel() for m in mesh], axis=1)


def step_for_resolution(points_per_m3: float) -> float:
    """Grid step (m) giving a resolution in points per cubic metre (paper: 37,000)."""
    return float(points_per_m3) ** (-1.0 / 3.0)


def accessible_percentage(flags: ArrayLike) -> float:
    """Eq. (10): accessible points / all points * 100."""
    flags = np.asarray(flags)
    return 100.0 * np.count_nonzero(flags == 0) / max(flags.size, 1)


@dataclass
class COWResult:
    """Constant-orientation workspace on a grid."""

    rotation_deg: tuple[float, float, float]
    axes: list[np.ndarray]
    flags: np.ndarray                 # (nx, ny, nz) uint8 collision flags (0 = accessible)
    wall_time_s: float
    counts: dict[str, int] = field(default_factory=dict)

    @property
    def accessible_percentage(self) -> float:
        """Eq. (10) over all grid points."""
        return accessible_percentage(self.flags)

    @property
    def collision_free_percentage(self) -> float:
        """Share (%) of the in-frame grid points without any collision."""
        inside = np.count_nonzero((self.flags & OUTSIDE) == 0)
        return 100.0 * np.count_nonzero(self.flags == 0) / max(inside, 1)

    def to_dict(self, desc: RobotDescription | None = None) -> dict[str, object]:
        """JSON-ready summary (no per-point data)."""
        step = float(self.axes[0][1] - self.axes[0][0]) if self.axes[0].size > 1 else None
        out = {
            'rotation_deg': list(self.rotation_deg),
            'rotation_convention': "R = Rx(rx) Ry(ry) Rz(rz), moving axes x, y', z''",
            'grid': {
                'step_m': step,
                'shape': [int(a.size) for a in self.axes],
                'lower_m': [float(a[0]) for a in self.axes],
                'upper_m': [float(a[-1]) for a in self.axes],
                'region': 'cell centres over the frame shrunk by the platform half sizes',
            },
            **self.counts,
            'accessible_percentage': self.accessible_percentage,
            'collision_free_percentage_in_frame': self.collision_free_percentage,
            'wall_time_s': self.wall_time_s,
            'poses_per_second': self.counts['total_points'] / max(self.wall_time_s, 1e-12),
        }
        if desc is not None:
            out['robot'] = desc.name
            out['checks_per_pose_eq9'] = desc.checks_per_pose()
        return out


def constant_orientation_workspace(desc: RobotDescription, rotation_deg: Sequence[float],
                                   step: float = 0.05,
                                   axes: Sequence[ArrayLike] | None = None,
                                   progress: bool = False, chunk: int = DEFAULT_CHUNK,
                                   without: Iterable[str] | None = ()) -> COWResult:
    """COW (section IV-A) at orientation ``rotation_deg`` = (r_x, r_y, r_z) in degrees;
    ``without`` switches constructs off (:func:`classify_poses`)."""
    axes = grid_axes(desc, step) if axes is None else [np.asarray(a, float) for a in axes]
    points = grid_points(axes)
    rot = rotation_matrix_deg(*rotation_deg)
    # Load the compiled kernel (numba backend) on one pose before the clock starts: a one-off
    # start-up cost of the process (about 0.1-0.3 s from the on-disk cache), not per pose.
    classify_poses(desc, points[:1], rot, chunk, without=without)
    start = time.perf_counter()
    if progress:
        block = max(chunk, points.shape[0] // 50)
        flags = np.empty(points.shape[0], dtype=np.uint8)
        for lo in _progress(range(0, points.shape[0], block), True,
                            total=-(-points.shape[0] // block), desc='COW'):
            flags[lo:lo + block] = classify_poses(desc, points[lo:lo + block], rot, chunk,
                                                  without=without)
    else:
        flags = classify_poses(desc, points, rot, chunk, without=without)
    wall = time.perf_counter() - start
    shape = tuple(a.size for a in axes)
    return COWResult(rotation_deg=tuple(float(v) for v in rotation_deg), axes=axes,
                     flags=flags.reshape(shape), wall_time_s=wall, counts=count_flags(flags))


def benchmark_cow(desc: RobotDescription | None = None,
                  rotation_deg: Sequence[float] = (30, 30, 10), step: float = 0.05,
                  repeats: int = 7, progress: bool = False) -> dict[str, object]:
    """Poses per second of the ``workspace cow`` path (:func:`constant_orientation_workspace`).

    Median over ``repeats`` runs of the classification wall time (all checks per pose, eq. (9))
    on the step-``step`` grid; the default robot is the shipped Neuron. Returns a dict with
    ``kntu_poses_per_s`` (wall clock), ``kntu_poses_per_cpu_s``, the point count, the median
    time, the backend and every run's time.
    For ``paramotion bench``; speed is measured here, never asserted by tests.
    """
    from cable_robot_pkg.cdrpm.description import load_description
    from paramotion.backend import resolve_backend
    desc = load_description(None) if desc is None else desc
    times, cpu, cow = [], [], None
    for _ in range(max(1, int(repeats))):
        start = time.process_time()
        cow = constant_orientation_workspace(desc, rotation_deg, step=step, progress=progress)
        cpu.append(time.process_time() - start)
        times.append(cow.wall_time_s)
    median = float(np.median(times))
    n = cow.counts['total_points']
    return {'kntu_poses_per_s': n / median, 'kntu_points': n, 'kntu_median_s': median,
            # CPU time of the whole call (grid set-up included): not diluted by other load.
            'kntu_poses_per_cpu_s': n / max(float(np.median(cpu)), 1e-9),
            'kntu_backend': resolve_backend('auto'), 'kntu_times_s': times,
            'kntu_rotation_deg': list(rotation_deg), 'kntu_step_m': step}


def table2(desc: RobotDescription, step: float = 0.05, progress: bool = False,
           without: Iterable[str] | None = ()) -> list[dict[str, object]]:
    """The paper's Table II rows for ``desc``: list of dicts with ours beside the paper's."""
    rows = []
    for rot, paper, warp in _progress(TABLE2_ROWS, progress, desc='Table II'):
        cow = constant_orientation_workspace(desc, rot, step=step, without=without)
        rows.append({
            'rotation_deg': list(rot),
            'paper_kntu_percent': paper,
            'paper_warp_percent': warp,
            'accessible_percentage': cow.accessible_percentage,
            'collision_free_percentage_in_frame': cow.collision_free_percentage,
            'difference_points': cow.accessible_percentage - paper,
            **cow.counts,
            'wall_time_s': cow.wall_time_s,
        })
    return rows


# --- orientation workspace (IV-B, Fig. 7) ------------------------------------------------------

@dataclass
class OrientationResult:
    """Accessible (r_x, r_y) region at one position for several r_z."""

    position: np.ndarray
    rx_deg: np.ndarray
    ry_deg: np.ndarray
    rz_deg: np.ndarray
    flags: np.ndarray       # (n_rz, n_rx, n_ry) collision flags

    def boundary(self) -> list[dict[str, object]]:
        """Per r_z and r_x: the r_y interval around 0 that is accessible, and what limits it.

        Returns a list (one per r_z) of dicts with ``rx``, ``ry_min``, ``ry_max`` (None where
        r_y = 0 itself is not accessible) and ``limit_max``/``limit_min``: the collision type
        met just beyond the interval ('range' if the scanned range ends first).
        """
        out = []
        zero = int(np.argmin(np.abs(self.ry_deg)))
        for k, rz in enumerate(self.rz_deg):
            rows = []
            for i, rx in enumerate(self.rx_deg):
                line = self.flags[k, i]
                if line[zero] != 0:
                    rows.append({'rx': float(rx), 'ry_min': None, 'ry_max': None,
                                 'limit_min': _flag_name(line[zero]),
                                 'limit_max': _flag_name(line[zero])})
                    continue
                hi = zero
                while hi + 1 < line.size and line[hi + 1] == 0:
                    hi += 1
                lo = zero
                while lo - 1 >= 0 and line[lo - 1] == 0:
                    lo -= 1
                rows.append({
                    'rx': float(rx), 'ry_min': float(self.ry_deg[lo]),
                    'ry_max': float(self.ry_deg[hi]),
                    'limit_min': _flag_name(line[lo - 1]) if lo > 0 else 'range',
                    'limit_max': _flag_name(line[hi + 1]) if hi + 1 < line.size else 'range'})
            out.append({'rz': float(rz), 'rows': rows})
        return out


def _flag_name(flag):
    """Name of the first collision type set in ``flag`` ('outside_frame' first)."""
    flag = int(flag)
    if flag & OUTSIDE:
        return 'outside_frame'
    for name, bit in FLAG_OF_TYPE.items():
        if flag & bit:
            return name
    return 'none'


def _first_cause_counts(flags):
    """Counts of flags by first cause, in the order of :func:`_flag_name`."""
    flags = np.asarray(flags)
    out = {'outside_frame': int(np.count_nonzero(flags & OUTSIDE))}
    seen = (flags & OUTSIDE) != 0
    for name, bit in FLAG_OF_TYPE.items():
        hit = ((flags & bit) != 0) & ~seen
        out[name] = int(np.count_nonzero(hit))
        seen |= hit
    return out


def orientation_workspace(desc: RobotDescription, position: ArrayLike,
                          rz_deg: ArrayLike = (0, 10, 20, 30),
                          rx_range: tuple[float, float] = (-90, 90),
                          ry_range: tuple[float, float] = (-90, 90), step_deg: float = 1.0,
                          without: Iterable[str] | None = ()) -> OrientationResult:
    """Orientation workspace at ``position`` (IV-B): flags over an (r_x, r_y) grid per r_z."""
    rx = np.arange(rx_range[0], rx_range[1] + step_deg / 2, step_deg)
    ry = np.arange(ry_range[0], ry_range[1] + step_deg / 2, step_deg)
    rz = np.asarray(rz_deg, dtype=float)
    mz, mx, my = np.meshgrid(rz, rx, ry, indexing='ij')
    rots = rotation_matrix_deg(mx.ravel(), my.ravel(), mz.ravel())
    pos = np.broadcast_to(np.asarray(position, dtype=float), (rots.shape[0], 3))
    flags = classify_poses(desc, pos, rots, without=without).reshape(mz.shape)
    return OrientationResult(position=np.asarray(position, float), rx_deg=rx, ry_deg=ry,
                             rz_deg=rz, flags=flags)


# --- total orientation workspace (IV-C) --------------------------------------------------------

@dataclass
class TOWResult:
    """Total orientation workspace: grid points accessible at every sampled orientation."""

    theta_max_deg: tuple[float, ...]
    orientations_deg: np.ndarray     # (K, 3) sampled orientations
    axes: list[np.ndarray]
    accessible: np.ndarray           # (nx, ny, nz) bool
    removed_by: dict[str, int]       # points removed per collision type (first cause)
    wall_time_s: float

    @property
    def accessible_percentage(self) -> float:
        """Eq. (10) of the TOW over the grid."""
        return 100.0 * np.count_nonzero(self.accessible) / self.accessible.size


def orientation_samples(theta_max_deg: Sequence[float], angle_step_deg: float) -> np.ndarray:
    """Orientations of the +-theta_m box, corners first (they prune most), (K, 3) degrees."""
    per_axis = []
    for t in theta_max_deg:
        t = abs(float(t))
        n = 1 if t == 0 else int(np.ceil(2 * t / angle_step_deg)) + 1
        per_axis.append(np.linspace(-t, t, n) if t > 0 else np.zeros(1))
    mesh = np.stack([m.ravel() for m in np.meshgrid(*per_axis, indexing='ij')], axis=1)
    tmax = np.array([max(abs(float(t)), 1e-12) for t in theta_max_deg])
    extremity = np.sum(np.abs(mesh) / tmax, axis=1)
    return mesh[np.argsort(-extremity, kind='stable')]


def total_orientation_workspace(desc: RobotDescription,
                                theta_max_deg: Sequence[float] = (30, 30, 10),
                                step: float = 0.05, angle_step_deg: float = 10.0,
                                progress: bool = False,
                                without: Iterable[str] | None = ()) -> TOWResult:
    """TOW (IV-C): intersection of the COWs over a sampled +-theta_m orientation box.

    As in the paper, points found inaccessible are removed and not tested again, so the cost
    falls as orientations are processed (extreme orientations first).
    """
    axes = grid_axes(desc, step)
    points = grid_points(axes)
    samples = orientation_samples(theta_max_deg, angle_step_deg)
    alive = np.arange(points.shape[0])
    removed = {'outside_frame': 0, **{name: 0 for name in FLAG_OF_TYPE}}
    start = time.perf_counter()
    for rot in _progress(samples, progress, total=len(samples), desc='TOW'):
        if alive.size == 0:
            break
        flags = classify_poses(desc, points[alive], rotation_matrix_deg(*rot), without=without)
        bad = flags != 0
        for name, count in _first_cause_counts(flags[bad]).items():
            removed[name] += count
        alive = alive[~bad]
    wall = time.perf_counter() - start
    mask = np.zeros(points.shape[0], dtype=bool)
    mask[alive] = True
    return TOWResult(theta_max_deg=tuple(float(t) for t in theta_max_deg),
                     orientations_deg=samples, axes=axes,
                     accessible=mask.reshape(tuple(a.size for a in axes)), removed_by=removed,
                     wall_time_s=wall)


def _largest_rectangle(mask2d):
    """Largest all-True axis-aligned rectangle of a 2-D mask: (area, r0, r1, c0, c1) inclusive."""
    rows, cols = mask2d.shape
    heights = np.zeros(cols, dtype=int)
    best = (0, 0, -1, 0, -1)
    for r in range(rows):
        heights = np.where(mask2d[r], heights + 1, 0)
        stack = []
        for c in range(cols + 1):
            h = heights[c] if c < cols else 0
            start = c
            while stack and stack[-1][1] >= h:
                start, height = stack.pop()
                area = height * (c - start)
                if area > best[0]:
                    best = (area, r - height + 1, r, start, c - 1)
            stack.append((start, h))
    return best


def largest_box(mask: np.ndarray, axes: Sequence[np.ndarray]) -> dict[str, object] | None:
    """Largest-volume axis-aligned box of grid cells all True in ``mask`` (nx, ny, nz).

    Exhaustive over x ranges with a largest-rectangle search in (y, z) for each, so exact on
    the grid. Returns dict with lower/upper cell centres, size (cell count * step) and volume.
    """
    nx = mask.shape[0]
    best = (0, None)
    for x0 in range(nx):
        column = np.ones(mask.shape[1:], dtype=bool)
        for x1 in range(x0, nx):
            column &= mask[x1]
            if not column.any():
                break
            # Upper bound: even a full-area rectangle cannot beat the best.
            if (x1 - x0 + 1) * column.size <= best[0]:
                continue
            area, r0, r1, c0, c1 = _largest_rectangle(column)
            volume = area * (x1 - x0 + 1)
            if volume > best[0]:
                best = (volume, (x0, x1, r0, r1, c0, c1))
    if best[1] is None:
        return None
    x0, x1, y0, y1, z0, z1 = best[1]
    steps = [float(a[1] - a[0]) if a.size > 1 else 0.0 for a in axes]
    lower = [round(float(axes[0][x0]), 9), round(float(axes[1][y0]), 9),
             round(float(axes[2][z0]), 9)]
    upper = [round(float(axes[0][x1]), 9), round(float(axes[1][y1]), 9),
             round(float(axes[2][z1]), 9)]
    size = [round((i1 - i0 + 1) * s, 9)
            for (i0, i1), s in zip(((x0, x1), (y0, y1), (z0, z1)), steps)]
    return {'lower_cell_centre_m': lower, 'upper_cell_centre_m': upper, 'size_m': size,
            'volume_m3': round(float(np.prod(size)), 9), 'cells': int(best[0])}


def contains_box(mask: ArrayLike, axes: Sequence[np.ndarray], size_m: Sequence[float]) -> bool:
    """True when an axis-aligned box of ``size_m`` (x, y, z in m) fits inside the cells of
    ``mask`` (nx, ny, nz) that are all True, anywhere on the grid ``axes``.

    A box of size s covers round(s / step) cells along each axis (the convention of
    :func:`largest_box`); the test slides it over every placement with a 3-D summed-area table.
    """
    mask = np.asarray(mask, dtype=bool)
    cells = []
    for a, s in zip(axes, size_m):
        step = float(a[1] - a[0]) if a.size > 1 else 1.0
        cells.append(max(1, int(round(float(s) / step))))
    if any(n < k for n, k in zip(mask.shape, cells)):
        return False
    c = np.pad(mask.astype(np.int64), ((1, 0), (1, 0), (1, 0))).cumsum(0).cumsum(1).cumsum(2)
    a, b, d = cells
    total = (c[a:, b:, d:] - c[:-a, b:, d:] - c[a:, :-b, d:] - c[a:, b:, :-d]
             + c[:-a, :-b, d:] + c[:-a, b:, :-d] + c[a:, :-b, :-d] - c[:-a, :-b, :-d])
    return bool(np.any(total == a * b * d))


# --- workpiece study (IV-D) --------------------------------------------------------------------

def workpiece_study(desc: RobotDescription, workpiece: Sequence[float],
                    rotation_deg: Sequence[float] = (0, 0, 0), step: float = 0.02,
                    plane_y: float = 0.0, without: Iterable[str] | None = ()
                    ) -> dict[str, object]:

    """COW on the vertical plane y = ``plane_y`` with and without a workpiece box (IV-D).

    Returns a dict with both flag maps (nx, nz), the accessible percentages, their ratio (the
    paper finds 60 %) and the smallest vertical gap between the platform bottom and the
    workpiece top among accessible points above the workpiece footprint (paper: 0.5 m).
    """
    with_wp = desc.with_workpiece(workpiece)
    axes = grid_axes(desc, step)
    xs, zs = axes[0], axes[2]
    points = grid_points([xs, np.array([float(plane_y)]), zs])
    rot = rotation_matrix_deg(*rotation_deg)
    free = classify_poses(desc.with_workpiece(None), points, rot,
                          without=without).reshape(xs.size, zs.size)
    flags = classify_poses(with_wp, points, rot, without=without).reshape(xs.size, zs.size)
    lo, hi = with_wp.workpiece_box
    above = (np.abs(points[:, 0]) <= workpiece[0] / 2).reshape(xs.size, zs.size)
    gap = (points[:, 2] - desc.platform_half_size[2] - hi[2]).reshape(xs.size, zs.size)
    ok = (flags == 0) & above
    counts = count_flags(flags.ravel())
    pct_free = accessible_percentage(free)
    pct_wp = accessible_percentage(flags)
    return {
        'workpiece_m': [float(v) for v in workpiece],
        'rotation_deg': list(rotation_deg),
        'plane_y_m': float(plane_y),
        'x_m': xs, 'z_m': zs, 'flags_free': free, 'flags_workpiece': flags,
        'accessible_percentage_without': pct_free,
        'accessible_percentage_with': pct_wp,
        'ratio_percent': 100.0 * pct_wp / pct_free if pct_free > 0 else 0.0,
        'min_gap_above_workpiece_m': float(gap[ok].min()) if ok.any() else None,
        'counts_with_workpiece': counts,
    }


__all__ = ['CABLE_BODY', 'CABLE_CABLE', 'CABLE_WORKPIECE', 'PLATFORM_WORKPIECE', 'OUTSIDE',
           'COWResult', 'OrientationResult', 'PAPER_TOW_BOX_M', 'TOWResult', 'TABLE2_ROWS',
           'accessible_percentage', 'constant_orientation_workspace', 'contains_box',
           'grid_axes', 'grid_points', 'largest_box',
           'orientation_samples', 'orientation_workspace', 'step_for_resolution', 'table2',
           'total_orientation_workspace', 'workpiece_study']
