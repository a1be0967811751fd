"""Feed targets on the spherical focal surface and the trolley / orienting-mechanism chain.

FAST's receivers must follow tracks on a spherical focal surface with the feed axis pointing at
the sphere's centre (Lu, Zhu, Ren, Sec. I, Fig. 1; Cheng, Ren, Dai, Sec. I). The field model
scales the surface down; its centre and radius come from the config.

The feed support is a chain: trolley (kept level by the cables) -> 2-DOF orienting mechanism
with orthogonal hinges (x then y) -> upper platform of the Gough-Stewart platform, whose axis is
aimed at the sphere's centre -> six legs -> lower platform carrying the feed. At rest the lower
platform sits ``nominal_height`` below the upper one along the axis, so the coarse targets of
the cable loop (trolley position) and of the orienting mechanism (hinge angles) follow from the
feed target alone (:class:`FeedSupportChain`).

Frames: a platform frame's z axis is the feed axis (pointing up, toward the centre).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike


def rot_x(a: float) -> np.ndarray:
    """Rotation matrix about x by ``a`` rad."""
    c, s = math.cos(a), math.sin(a)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def rot_y(a: float) -> np.ndarray:
    """Rotation matrix about y by ``a`` rad."""
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def hinge_angles(axis: ArrayLike) -> tuple[float, float]:
    """Hinge angles (alpha about x, then beta about y) with ``Rx(alpha) Ry(beta) e_z = axis``.

    ``Rx(a) Ry(b) e_z = (sin b, -sin a cos b, cos a cos b)``, hence ``b = asin(axis_x)`` and
    ``a = atan2(-axis_y, axis_z)``.
    """
    a = np.asarray(axis, float) / np.linalg.norm(axis)
    return math.atan2(-a[1], a[2]), math.asin(max(-1.0, min(1.0, a[0])))


def hinge_rotation(alpha: float, beta: float) -> np.ndarray:
    """Orientation of the upper platform relative to the trolley for hinge angles."""
    return rot_x(alpha) @ rot_y(beta)


@dataclass(frozen=True)
class FocalSurface:
    """Sphere of the focal surface: feed positions on it, axis toward ``centre``."""

    centre: np.ndarray
    radius: float

    def point(self, zenith: float, azimuth: float) -> np.ndarray:
        """Feed position on the focal surface at zenith angle ``zenith`` (0 = lowest point) and
        azimuth ``azimuth`` (rad): ``centre + radius (sin z cos a, sin z sin a, -cos z)``."""
        s = math.sin(zenith)
        down = np.array([s * math.cos(azimuth), s * math.sin(azimuth), -math.cos(zenith)])
        return np.asarray(self.centre, float) + self.radius * down

    def axis(self, position: ArrayLike) -> np.ndarray:
        """Unit feed axis at ``position``: toward the sphere's centre."""
        d = np.asarray(self.centre, float) - np.asarray(position, float)
        return d / np.linalg.norm(d)

    def feed_pose(self, zenith: float, azimuth: float) -> tuple[np.ndarray, np.ndarray]:
        """Target feed pose (position, rotation): on the surface, axis (z) to the centre, and
        the roll about the axis that the orthogonal-hinge mechanism produces on a level
        trolley (``R = Rx(alpha) Ry(beta)``)."""
        p = self.point(zenith, azimuth)
        a, b = hinge_angles(self.axis(p))
        return p, hinge_rotation(a, b)

    def zenith_of(self, position: ArrayLike) -> float:
        """Zenith angle (rad) of a point seen from the centre (0 at the bottom)."""
        d = np.asarray(position, float) - np.asarray(self.centre, float)
        return math.acos(max(-1.0, min(1.0, -d[2] / np.linalg.norm(d))))


@dataclass(frozen=True)
class Track:
    """A feed track on the focal surface, parametrised by time.

    kinds: ``circle`` (constant zenith, azimuth advancing: a source drifting across the sky),
    ``meridian`` (zenith swinging sinusoidally with amplitude ``zenith`` in the plane of
    ``azimuth``), ``hold`` (a fixed point at ``zenith``/``azimuth``). ``speed`` is the feed
    speed along the surface (m/s).
    """

    surface: FocalSurface
    kind: str
    zenith: float
    azimuth: float
    speed: float

    def angles(self, t: float) -> tuple[float, float]:
        """(zenith, azimuth) at time ``t`` (s)."""
        r = self.surface.radius
        if self.kind == 'circle':
            ring = max(r * math.sin(self.zenith), 1e-9)
            return self.zenith, self.azimuth + self.speed * t / ring
        if self.kind == 'meridian':
            amp = max(self.zenith, 1e-9)
            omega = self.speed / (r * amp)   # peak speed = speed
            return amp * math.sin(omega * t), self.azimuth
        return self.zenith, self.azimuth

    def pose(self, t: float) -> tuple[np.ndarray, np.ndarray]:
        """Target feed (position, rotation) at time ``t``."""
        z, a = self.angles(t)
        if z < 0.0:
            z, a = -z, a + math.pi
        return self.surface.feed_pose(z, a)

    def max_zenith(self) -> float:
        """Largest zenith angle the track reaches (rad)."""
        return abs(self.zenith)

    def sample(self, duration: float, n: int = 64) -> list[tuple[np.ndarray, np.ndarray]]:
        """Poses at ``n`` times spread over ``[0, duration]`` (used by config validation)."""
        period = duration
        if self.kind == 'circle' and self.speed > 0:
            period = min(duration, 2 * math.pi * self.surface.radius
                         * max(math.sin(self.zenith), 1e-9) / self.speed)
        return [self.pose(t) for t in np.linspace(0.0, period, n)]


@dataclass(frozen=True)
class FeedSupportChain:
    """Offsets of the trolley -> hinge -> upper platform -> lower platform chain."""

    hinge_offset: np.ndarray      # hinge centre in the trolley frame (m)
    upper_offset: float           # upper platform centre below the hinge along the axis (m)
    nominal_height: float         # lower platform centre below the upper one at rest (m)

    def coarse_targets(self, feed_position: ArrayLike, feed_rotation: ArrayLike
                       ) -> tuple[np.ndarray, tuple[float, float], np.ndarray, np.ndarray]:
        """Trolley position (level trolley), hinge angles and upper platform pose that put the
        feed at its target with the legs at their nominal lengths."""
        R = np.asarray(feed_rotation)
        axis = R[:, 2]
        alpha, beta = hinge_angles(axis)
        upper_p = np.asarray(feed_position) + self.nominal_height * axis
        hinge_p = upper_p + self.upper_offset * axis
        trolley_p = hinge_p - np.asarray(self.hinge_offset)
        return trolley_p, (alpha, beta), upper_p, hinge_rotation(alpha, beta)

    def upper_pose(self, trolley_position: ArrayLike, trolley_rotation: ArrayLike,
                   alpha: float, beta: float) -> tuple[np.ndarray, np.ndarray]:
        """Upper platform pose from the trolley pose and the hinge angles."""
        Rt = np.asarray(trolley_rotation)
        R = Rt @ hinge_rotation(alpha, beta)
        p = np.asarray(trolley_position) + Rt @ np.asarray(self.hinge_offset) \
            - self.upper_offset * R[:, 2]
        return p, R

    def nominal_relative_pose(self) -> tuple[np.ndarray, np.ndarray]:
        """Lower platform pose in the upper platform frame at rest."""
        return np.array([0.0, 0.0, -self.nominal_height]), np.eye(3)
