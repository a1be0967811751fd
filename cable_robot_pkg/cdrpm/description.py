"""Robot description of a cable-driven parallel manipulator: load and validate the YAML file.

The paper (Aref & Taghirad, section II-A) describes the KNTU CDRPM by the fixed attachment
points ``A_i`` (on the fixed cuboid frame, coordinates ``a_i`` in frame A whose origin O is the
frame centroid), the moving attachment points ``B_i`` (coordinates ``b_i`` in the platform
frame B whose origin G is the platform centroid), the half sizes of the frame (Table I:
f_a, f_b, f_h) and of the platform box (a, b, h), and the cable radius epsilon (section III-A).

File format (YAML, metres)::

    name: kntu_neuron                 # optional
    frame_half_size: [1.0, 2.0, 1.0]  # optional: f_a, f_b, f_h (default: bounding box of A_i)
    frame_points: [[x, y, z], ...]    # n x 3, A_i in frame A
    platform_points: [[u, v, w], ...] # n x 3, B_i in frame B, on the platform box surface
    platform_half_size: [a, b, h]
    cable_radius: 0.0025              # epsilon >= 0
    body_delta: 0.1                   # optional: delta of eq. (8), default min(a, b, h)
    workpiece: [Wx, Wy, Wz]           # optional: box on the floor centre (section III-C)

Everything malformed raises :class:`paramotion.errors.UserError` with one line naming the
file, the field and what is wrong; a description that loads is safe to compute with.
"""
from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Optional

import numpy as np
import yaml

from paramotion import yamlfile
from paramotion.errors import UserError

#: Geometric tolerance (m) for "lies on the platform surface" and "inside the frame" checks.
GEOM_TOL = 1e-9

KNOWN_FIELDS = ('name', 'description', 'frame_half_size', 'frame_points', 'platform_points',
                'platform_half_size', 'cable_radius', 'body_delta', 'workpiece')

CONFIG_DIR = Path(__file__).resolve().parent / 'config'


def default_description_path() -> Path:
    """Path of the shipped default description: the Neuron fitted to Table II and the TOW box."""
    return CONFIG_DIR / 'kntu_neuron.yaml'


def shipped_descriptions() -> list[Path]:
    """Paths of all robot descriptions shipped in ``cable_robot_pkg/cdrpm/config``."""
    return sorted(CONFIG_DIR.glob('kntu_*.yaml'))


@dataclass(frozen=True)
class RobotDescription:
    """A validated robot description (all arrays float64, read-only).

    ``pair_i``/``pair_j`` list the cable pairs checked for cable-cable collision: every pair
    except those sharing an attachment point (two cables leaving the same eyelet always touch
    there, which is not a collision).
    """

    name: str
    frame_points: np.ndarray          # (n, 3) a_i
    platform_points: np.ndarray       # (n, 3) b_i
    frame_half_size: np.ndarray       # (3,) f_a, f_b, f_h
    platform_half_size: np.ndarray    # (3,) a, b, h
    cable_radius: float               # epsilon
    body_delta: float                 # delta of eq. (8)
    workpiece: Optional[np.ndarray]   # (3,) Wx, Wy, Wz or None
    pair_i: np.ndarray = field(repr=False, default=None)
    pair_j: np.ndarray = field(repr=False, default=None)
    source: str = ''

    @property
    def n_cables(self) -> int:
        """Number of cables n."""
        return self.frame_points.shape[0]

    @property
    def platform_corners(self) -> np.ndarray:
        """(8, 3) corners of the platform box in frame B."""
        signs = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)],
                         dtype=float)
        return signs * self.platform_half_size

    @property
    def workpiece_box(self) -> tuple[np.ndarray, np.ndarray] | None:
        """(lower, upper) corners of the workpiece box in frame A, or None."""
        if self.workpiece is None:
            return None
        wx, wy, wz = self.workpiece
        floor = -self.frame_half_size[2]
        return (np.array([-wx / 2, -wy / 2, floor]), np.array([wx / 2, wy / 2, floor + wz]))

    def checks_per_pose(self) -> int:
        """Collision checks per pose of the paper's eq. (9): n(n-1)/2 + 2n."""
        n = self.n_cables
        return n * (n - 1) // 2 + 2 * n

    def with_workpiece(self, workpiece: Sequence[float] | None) -> RobotDescription:
        """A copy with another workpiece (``[Wx, Wy, Wz]`` or None), validated."""
        data = self.to_dict()
        data['workpiece'] = None if workpiece is None else [float(v) for v in workpiece]
        return description_from_dict(data, self.source or '<description>')

    def to_dict(self) -> dict[str, object]:
        """Plain-Python form (for JSON results and round trips)."""
        return {
            'name': self.name,
            'frame_half_size': self.frame_half_size.tolist(),
            'frame_points': self.frame_points.tolist(),
            'platform_points': self.platform_points.tolist(),
            'platform_half_size': self.platform_half_size.tolist(),
            'cable_radius': self.cable_radius,
            'body_delta': self.body_delta,
            'workpiece': None if self.workpiece is None else self.workpiece.tolist(),
        }


def load_description(path: str | Path | None = None) -> RobotDescription:
    """Load and validate a robot description YAML file (default: the shipped Neuron)."""
    path = Path(path) if path is not None else default_description_path()
    try:
        text = path.read_text()
    except FileNotFoundError:
        raise UserError(f'robot description {path}: file not found') from None
    except OSError as exc:
        raise UserError(f'robot description {path}: cannot read ({exc.strerror})') from None
    try:
        data = yamlfile.safe_load(text)
    except yaml.YAMLError as exc:
        where = getattr(exc, 'problem_mark', None)
        line = f' at line {where.line + 1}' if where is not None else ''
        raise UserError(f'robot description {path}: invalid YAML{line}') from None
    return description_from_dict(data, str(path))


def _matrix(data, key, src, rows=None):
    """Read an (rows x 3) finite float matrix field."""
    if key not in data:
        raise UserError(f"robot description {src}: missing field '{key}'")
    try:
        arr = np.array(data[key], dtype=float)
    except (TypeError, ValueError):
        raise UserError(f"robot description {src}: '{key}' must be a list of [x, y, z] "
                        'numbers') from None
    if arr.ndim != 2 or arr.shape[1] != 3:
        raise UserError(f"robot description {src}: '{key}' must have shape (n, 3), got "
                        f'{arr.shape}')
    if rows is not None and arr.shape[0] != rows:
        raise UserError(f"robot description {src}: '{key}' has {arr.shape[0]} rows but "
                        f"'frame_points' has {rows} (one per cable)")
    if not np.all(np.isfinite(arr)):
        bad = np.argwhere(~np.isfinite(arr))[0]
        raise UserError(f"robot description {src}: '{key}' row {bad[0]} is not finite "
                        f'(NaN or inf)')
    return arr


def _vector(data, key, src, positive=True):
    """Read a finite 3-vector field, optionally strictly positive."""
    try:
        arr = np.array(data[key], dtype=float)
    except (TypeError, ValueError):
        raise UserError(f"robot description {src}: '{key}' must be 3 numbers") from None
    if arr.shape != (3,):
        raise UserError(f"robot description {src}: '{key}' must be 3 numbers, got shape "
                        f'{arr.shape}')
    if not np.all(np.isfinite(arr)):
        raise UserError(f"robot description {src}: '{key}' is not finite (NaN or inf)")
    if positive and np.any(arr <= 0):
        raise UserError(f"robot description {src}: '{key}' must be > 0, got {arr.tolist()}")
    return arr


def _scalar(data, key, src):
    """Read a finite float field."""
    value = data.get(key)
    if isinstance(value, bool):
        raise UserError(f"robot description {src}: '{key}' must be a number, got {value!r}")
    try:
        value = float(value)
    except (TypeError, ValueError):
        raise UserError(f"robot description {src}: '{key}' must be a number, got "
                        f'{value!r}') from None
    if not math.isfinite(value):
        raise UserError(f"robot description {src}: '{key}' is not finite ({value})")
    return value


def description_from_dict(data: object, source: str = '<description>') -> RobotDescription:

    """Validate a parsed description (mapping) and build a :class:`RobotDescription`."""
    src = source
    if not isinstance(data, dict):
        raise UserError(f'robot description {src}: expected a mapping of fields, got '
                        f'{type(data).__name__}')
    unknown = sorted(set(data) - set(KNOWN_FIELDS))
    if unknown:
        raise UserError(f"robot description {src}: unknown field '{unknown[0]}' (known: "
                        f'{", ".join(KNOWN_FIELDS)})')
    frame = _matrix(data, 'frame_points', src)
    n = frame.shape[0]
    if n < 2:
        raise UserError(f"robot description {src}: 'frame_points' needs at least 2 cables, "
                        f'got {n}')
    platform = _matrix(data, 'platform_points', src, rows=n)
    if 'platform_half_size' not in data:
        raise UserError(f"robot description {src}: missing field 'platform_half_size'")
    half = _vector(data, 'platform_half_size', src)
    if 'cable_radius' not in data:
        raise UserError(f"robot description {src}: missing field 'cable_radius'")
    radius = _scalar(data, 'cable_radius', src)
    if radius < 0:
        raise UserError(f"robot description {src}: 'cable_radius' must be >= 0, got {radius}")
    if data.get('frame_half_size') is not None:
        fhalf = _vector(data, 'frame_half_size', src)
        outside = np.abs(frame) > fhalf + GEOM_TOL
        if np.any(outside):
            row = int(np.argwhere(outside)[0][0])
            raise UserError(f"robot description {src}: 'frame_points' row {row} "
                            f'{frame[row].tolist()} lies outside the frame '
                            f'(frame_half_size {fhalf.tolist()})')
    else:
        fhalf = np.max(np.abs(frame), axis=0)
        if np.any(fhalf <= 0):
            raise UserError(f"robot description {src}: 'frame_points' span no volume; give "
                            "'frame_half_size'")
    if np.any(half >= fhalf):
        axis = 'xyz'[int(np.argmax(half >= fhalf))]
        raise UserError(f"robot description {src}: 'platform_half_size' {half.tolist()} is "
                        f'not smaller than the frame half size {fhalf.tolist()} along {axis}')
    if radius >= 0.5 * float(np.min(half)):
        raise UserError(f"robot description {src}: 'cable_radius' {radius} must be smaller "
                        'than half the smallest platform half size')
    # B_i must lie on the platform box surface: the body test of eq. (8) looks at the cable
    # just outside B_i, which only makes sense for an attachment point on the surface.
    excess = np.abs(platform) - half
    if np.any(excess > GEOM_TOL):
        row = int(np.argwhere(np.any(excess > GEOM_TOL, axis=1))[0][0])
        raise UserError(f"robot description {src}: 'platform_points' row {row} "
                        f'{platform[row].tolist()} lies outside the platform box '
                        f'(platform_half_size {half.tolist()})')
    inner = np.all(excess < -GEOM_TOL, axis=1)
    if np.any(inner):
        row = int(np.argmax(inner))
        raise UserError(f"robot description {src}: 'platform_points' row {row} "
                        f'{platform[row].tolist()} is inside the platform box, not on its '
                        'surface')
    default_delta = float(np.min(half))
    delta = default_delta
    if data.get('body_delta') is not None:
        delta = _scalar(data, 'body_delta', src)
    if not 0 < delta < 2 * float(np.min(half)):
        raise UserError(f"robot description {src}: 'body_delta' {delta} violates eq. (8): "
                        f'0 < delta < min(2a, 2b, 2h) = {2 * float(np.min(half))}')
    workpiece = None
    if data.get('workpiece') is not None:
        workpiece = _vector(data, 'workpiece', src)
        limit = np.array([2 * fhalf[0], 2 * fhalf[1], 2 * fhalf[2]])
        if np.any(workpiece >= limit):
            raise UserError(f"robot description {src}: 'workpiece' {workpiece.tolist()} does "
                            f'not fit in the frame {limit.tolist()}')
        lo = np.array([-workpiece[0] / 2, -workpiece[1] / 2, -fhalf[2]]) - radius
        hi = np.array([workpiece[0] / 2, workpiece[1] / 2, -fhalf[2] + workpiece[2]]) + radius
        inside = np.all((frame > lo) & (frame < hi), axis=1)
        if np.any(inside):
            row = int(np.argmax(inside))
            raise UserError(f"robot description {src}: 'frame_points' row {row} is inside "
                            "the 'workpiece'")
    name = data.get('name', Path(source).stem)
    if not isinstance(name, str) or not name:
        raise UserError(f"robot description {src}: 'name' must be a non-empty string")
    ii, jj = np.triu_indices(n, k=1)
    shared = (np.linalg.norm(frame[ii] - frame[jj], axis=1) <= GEOM_TOL) | \
        (np.linalg.norm(platform[ii] - platform[jj], axis=1) <= GEOM_TOL)
    arrays = [frame, platform, fhalf, half]
    if workpiece is not None:
        arrays.append(workpiece)
    pair_i, pair_j = ii[~shared], jj[~shared]
    for arr in arrays + [pair_i, pair_j]:
        arr.setflags(write=False)
    return RobotDescription(
        name=name, frame_points=frame, platform_points=platform, frame_half_size=fhalf,
        platform_half_size=half, cable_radius=radius, body_delta=delta, workpiece=workpiece,
        pair_i=pair_i, pair_j=pair_j, source=str(source))
