"""Generated structures for closed-loop tests and the measured table (never seen by the planner).

Each function returns a :class:`climber_pkg.trunk.Trunk`: a constant-curvature ``arc`` in a
seeded oblique plane, a straight ``taper``, a straight ``lean``, a 3-D ``wiggle`` and 3-D
``s_bend`` shapes whose two opposite bends have a given radius (the smaller, the harder).
"""
import math

import numpy as np

from climber_pkg.trunk import Trunk


def _turn(vector: np.ndarray, axis: np.ndarray, angle: float) -> np.ndarray:
    """Rodrigues rotation of ``vector`` about the unit ``axis`` by ``angle`` (rad)."""
    c, s = math.cos(angle), math.sin(angle)
    return vector * c + np.cross(axis, vector) * s + axis * (axis @ vector) * (1 - c)


def arc(length: float = 6.0, bend_radius: float = 15.0, seed: int = 0) -> Trunk:
    """Constant curvature ``1 / bend_radius`` in a vertical plane at a seeded azimuth,
    tapering 0.26 -> 0.20 m."""
    phi = np.random.default_rng(seed).uniform(0, 2 * math.pi)
    ang = np.linspace(0, length / bend_radius, 13)
    x = bend_radius * (1 - np.cos(ang))
    pts = np.stack([x * math.cos(phi), x * math.sin(phi), bend_radius * np.sin(ang)], 1)
    return Trunk(pts.tolist(), [[0, 0.26], [length, 0.20]], name=f'arc_R{bend_radius:g}')


def taper(length: float = 6.0) -> Trunk:
    """Straight and vertical, 0.29 -> 0.15 m."""
    return Trunk([[0, 0, 0], [0, 0, length]], [[0, 0.29], [length, 0.15]], name='taper')


def lean(length: float = 6.0, degrees: float = 10.0) -> Trunk:
    """Straight, leaning ``degrees`` from the vertical, 0.25 m."""
    t = math.radians(degrees)
    return Trunk([[0, 0, 0], [length * math.sin(t), 0, length * math.cos(t)]], 0.25,
                 name=f'lean_{degrees:g}deg')


def wiggle(length: float = 6.0) -> Trunk:
    """3-D gentle S in x and y, tapering 0.26 -> 0.20 m."""
    z = np.linspace(0, length, 13)
    pts = np.stack([0.25 * np.sin(z / 1.5), 0.2 * (1 - np.cos(z / 2.0)), z], 1)
    return Trunk(pts.tolist(), [[0, 0.26], [length, 0.2]], name='wiggle')


def s_bend(bend_radius: float, turn_deg: float = 20.0, lead: float = 1.5, tail: float = 1.0,
           seed: int = 0) -> Trunk:
    """A 3-D S: straight ``lead``, a bend of ``bend_radius`` turning ``turn_deg``, a bend back
    of the same radius in a plane turned 60 deg about the vertical, straight ``tail``; radius
    0.22 m. The bend planes' azimuth is drawn from ``seed``."""
    phi = np.random.default_rng(seed).uniform(0, 2 * math.pi)
    axes = [np.array([-math.sin(a), math.cos(a), 0.0]) for a in (phi, phi + math.radians(60))]
    arc_len = bend_radius * math.radians(turn_deg)
    ds = 0.01
    t = np.array([0.0, 0.0, 1.0])
    p = np.zeros(3)
    pts = [p.copy()]
    for length, axis, sign in ((lead, None, 0), (arc_len, axes[0], 1), (arc_len, axes[1], -1),
                               (tail, None, 0)):
        for _ in range(int(round(length / ds))):
            if axis is not None:
                t = _turn(t, axis, sign * ds / bend_radius)
            p = p + t * ds
            pts.append(p.copy())
    pts = np.array(pts)[::20]
    return Trunk(pts.tolist(), 0.22, name=f's_bend_R{bend_radius:g}')


def generated_trunks(quick: bool = False) -> list:
    """The generated structures of the measured table (``quick``: a short subset)."""
    if quick:
        return [arc(4.0, 12.0, seed=3), s_bend(5.0, seed=1)]
    return [arc(seed=3), taper(), lean(), wiggle()] + [
        s_bend(r, seed=1) for r in (12.0, 8.0, 5.0, 3.0, 2.0)]
