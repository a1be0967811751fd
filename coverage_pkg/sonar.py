"""Sonar ring: the forward (simulation) model and the inverse (mapping) model.

The robot carries a ring of ``count`` ultrasonic transducers at its centre, evenly spaced, each
a cone of full angle ``beam_width`` (REP 117 ``field_of_view``). A transducer reports the range
of the first echo, i.e. the nearest wall inside its cone. Readings follow REP 117:

* a finite value in ``[min_range, max_range]`` is an echo;
* ``+inf`` means no echo within ``max_range`` (the whole cone is free out to ``max_range``);
* ``-inf`` means an object closer than ``min_range``;
* ``NaN`` means an invalid reading and carries no information.

The inverse model turns one reading into evidence for an occupancy grid: every cell of the cone
closer than the echo is free (the echo is the *first* one) and the arc at the echo range holds
an obstacle somewhere. Free evidence is reliable, arc evidence is smeared over the beam width;
a log-odds grid (:mod:`coverage_pkg.mapping`) fuses both over many poses.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Protocol

import numpy as np
from numpy.typing import ArrayLike

from paramotion.errors import UserError

if TYPE_CHECKING:
    from coverage_pkg.world import World


class _Quaternion(Protocol):
    """A quaternion with fields x, y, z, w (e.g. geometry_msgs/Quaternion)."""

    x: float
    y: float
    z: float
    w: float


@dataclass
class SonarRing:
    """Geometry and error model of a ring of ultrasonic range sensors."""

    count: int = 16
    beam_width: float = 0.2        # rad, full cone angle
    min_range: float = 0.05        # m
    max_range: float = 5.0         # m
    noise_std: float = 0.01        # m, Gaussian range noise
    rays_per_beam: int = 7         # rays cast per cone by the simulator

    def mount_angles(self) -> np.ndarray:
        """Transducer axis angles in the robot frame (rad), counter-clockwise from +x."""
        return 2.0 * math.pi * np.arange(self.count) / self.count

    def validate(self, delta: float | None = None) -> None:
        """Raise UserError if the ring is inconsistent, or cannot see as far as ``delta``."""
        if self.count < 3:
            raise UserError(f'sonar count {self.count} must be at least 3')
        if not 0.0 < self.beam_width < math.pi:
            raise UserError(f'sonar beam_width {self.beam_width} must be in (0, pi) rad')
        if not 0.0 <= self.min_range < self.max_range:
            raise UserError(f'sonar min_range {self.min_range} must be in [0, max_range)')
        if self.noise_std < 0.0:
            raise UserError(f'sonar noise_std {self.noise_std} must be >= 0')
        if delta is not None and not self.max_range > delta:
            raise UserError(f'sonar max_range {self.max_range:g} m must exceed the detector '
                            f'range delta {delta:g} m')


def simulate_ring(world: World, pose: ArrayLike, ring: SonarRing,
                  rng: np.random.Generator | None = None) -> np.ndarray:
    """Readings of every transducer of ``ring`` at ``pose`` = (x, y, yaw) in ``world``.

    Each cone is sampled by ``rays_per_beam`` exact ray casts; the reading is the nearest hit
    (the first echo) plus Gaussian noise, mapped to REP 117 (+inf beyond ``max_range``, -inf
    below ``min_range``). A simulator sweeping many times builds one :class:`RingCaster`.
    """
    return RingCaster(world, ring)(pose, rng)


class RingCaster:
    """:func:`simulate_ring` for one world and one ring, with what does not change between
    sweeps computed once: the segments' direction vectors, the transducers' mount angles and
    the ray offsets across a cone. Every sweep then takes the same floating-point steps as
    :func:`coverage_pkg.world.raycast_segments` (the readings are equal bit for bit:
    ``test/test_sonar_caster.py``)."""

    def __init__(self, world: World, ring: SonarRing) -> None:
        self.ring = ring
        seg = np.asarray(world.segments, dtype=float)
        self._start = seg[:, :2]
        edge = seg[:, 2:] - seg[:, :2]
        self._ex, self._ey = edge[:, 0].copy(), edge[:, 1].copy()
        self._mount = ring.mount_angles()[:, None]
        self._offs = (np.linspace(-0.5, 0.5, ring.rays_per_beam) * ring.beam_width)[None, :]
        self._far = ring.max_range * 2.0

    def true_ranges(self, pose: ArrayLike) -> np.ndarray:
        """Noise-free nearest hit of each cone (capped at twice ``max_range``)."""
        x, y, yaw = pose
        angles = (yaw + self._mount + self._offs).ravel()
        cos, sin = np.cos(angles)[:, None], np.sin(angles)[:, None]
        ex, ey = self._ex, self._ey
        a = self._start - np.asarray((x, y), dtype=float)
        ax, ay = a[:, 0], a[:, 1]
        # p + t d = s1 + u e  ->  t = cross(a, e) / cross(d, e), u = cross(a, d) / cross(d, e)
        den = cos * ey - sin * ex                                            # (rays, k)
        num_t = ax * ey - ay * ex
        num_u = ax * sin - ay * cos
        with np.errstate(divide='ignore', invalid='ignore'):
            t = num_t / den
            u = num_u / den
        ok = (np.abs(den) > 1e-12) & (t >= 0.0) & (u >= -1e-9) & (u <= 1.0 + 1e-9)
        hits = np.minimum(np.where(ok, t, np.inf).min(axis=1), self._far)
        return hits.reshape(self._mount.shape[0], -1).min(axis=1)

    def __call__(self, pose: ArrayLike, rng: np.random.Generator | None = None) -> np.ndarray:
        """The REP 117 readings of one sweep at ``pose`` (noise drawn from ``rng``)."""
        ring = self.ring
        true = self.true_ranges(pose)
        out = true.copy()
        if rng is not None and ring.noise_std > 0.0:
            out = out + rng.normal(0.0, ring.noise_std, out.shape)
        # REP 117 as in paramotion.range_sensing.rep117_reading: the true distance decides
        # +inf / -inf, a valid noisy value is clipped into [min_range, max_range].
        out = np.clip(out, ring.min_range, ring.max_range)
        out[true > ring.max_range] = math.inf
        out[true < ring.min_range] = -math.inf
        return out


def yaw_of(q: _Quaternion) -> float:
    """Yaw (rad) of a quaternion with fields x, y, z, w (e.g. geometry_msgs/Quaternion)."""
    return math.atan2(2.0 * (q.w * q.z + q.x * q.y), 1.0 - 2.0 * (q.y * q.y + q.z * q.z))


def reading_kind(value: float | None, min_range: float, max_range: float) -> str:
    """Classify one REP 117 reading: 'echo', 'no_echo', 'too_close' or 'invalid'."""
    if value is None or math.isnan(value):
        return 'invalid'
    if value == math.inf:
        return 'no_echo'
    if value == -math.inf:
        return 'too_close'
    if min_range <= value <= max_range:
        return 'echo'
    return 'invalid'


def sweep_evidence(pose: ArrayLike, ranges: ArrayLike, mount_angles: ArrayLike,
                   beam_width: float, min_range: float, max_range: float, resolution: float,
                   noise_std: float = 0.01, arc_fraction: float = 0.35, edges: bool = False
                   ) -> (tuple[np.ndarray, np.ndarray, int]
                         | tuple[np.ndarray, np.ndarray, np.ndarray, int]):
    """Inverse sonar model for one sweep of the ring.

    Returns ``(free_xy, occ_xy, valid)``: sample points of cells that the sweep shows free and
    of cells on the central ``arc_fraction`` of each echo arc, and how many readings carried
    information. With ``edges``, returns ``(free_xy, occ_xy, edge_xy, valid)``: ``edge_xy``
    samples the rest of each echo arc, out to the cone's edges.

    The echo comes from the *nearest* point in the cone, which lies somewhere on the arc at the
    echo range. Seen head on, that is the middle of the arc, and the central part is marked
    occupied outright. At a grazing angle it is the arc's end nearer the wall, and the middle
    of the arc lies in front of the wall, in free space; marking the whole arc outright would
    thicken every wall. :meth:`coverage_pkg.mapping.EvidenceGrid.integrate` therefore marks
    an edge cell only where no other reading has shown it free. Readings classified 'invalid'
    (NaN, out of range) and 'too_close' (-inf) add nothing.
    """
    x, y, yaw = pose
    r = np.asarray(ranges, dtype=float)
    mount = np.asarray(mount_angles, dtype=float)
    with np.errstate(invalid='ignore'):
        echo = np.isfinite(r) & (r >= min_range) & (r <= max_range)
    no_echo = r == math.inf
    use = echo | no_echo                     # NaN, -inf and out-of-range values carry nothing
    valid = int(use.sum())
    if valid == 0:
        return (np.zeros((0, 2)),) * (3 if edges else 2) + (0,)
    gap = max(2.0 * noise_std, resolution)
    reach = np.where(echo, r, max_range)[use]
    free_len = np.where(echo, r - gap, max_range)[use]
    is_echo = echo[use]
    # All cones at once: n_sub rays across each cone (enough for one sample per cell across
    # the widest arc), samples every 0.7 cell along each ray up to the free length.
    n_sub = max(3, int(math.ceil(beam_width * max_range / resolution)) + 1)
    offs = np.linspace(-0.5, 0.5, n_sub)
    th = yaw + mount[use][:, None] + offs[None, :] * beam_width          # (k, n_sub)
    c, s = np.cos(th), np.sin(th)
    t = np.arange(0.0, max_range, 0.7 * resolution)
    keep = t[None, :] < free_len[:, None]                                 # (k, n_t)
    kk, tt = np.nonzero(keep)
    fx = x + c[kk, :] * t[tt, None]                                       # (m, n_sub)
    fy = y + s[kk, :] * t[tt, None]
    free_xy = np.stack([fx.ravel(), fy.ravel()], axis=1)
    mid = np.abs(offs) <= 0.5 * arc_fraction + 1e-9
    if not mid.any():
        mid[n_sub // 2] = True
    ce, se, re = c[is_echo][:, mid], s[is_echo][:, mid], reach[is_echo][:, None]
    occ_xy = np.stack([(x + ce * re).ravel(), (y + se * re).ravel()], axis=1)
    if not edges:
        return free_xy, occ_xy, valid
    ce, se = c[is_echo][:, ~mid], s[is_echo][:, ~mid]
    edge_xy = np.stack([(x + ce * re).ravel(), (y + se * re).ravel()], axis=1)
    return free_xy, occ_xy, edge_xy, valid
