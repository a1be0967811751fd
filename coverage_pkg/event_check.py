"""Evaluation only: are the cusp and meet points the planner sensed where the true world has them?

An independent check at a finer resolution than the planner: the planner sees 16 sonar cones
and a 0.1 m grid; here the true world is ray cast with 2880 rays (0.125 degrees) from candidate
points, the closest obstacles are the local minima of that fine ring (30 degrees apart, as
the GVD's ``grad d_i != grad d_j``), and a small search around each sensed point looks for a
point that really is what the event claims:

* a **cusp point** (Section IV-B): the two closest obstacles equidistant and at ``delta``;
* a **meet point** (Section III): the three closest obstacles equidistant.

The search minimises the mismatch (a sum of distance differences, m) with Nelder-Mead from a
few starts around the sensed point; the event is verified when a point with a mismatch below
``tol`` lies within ``radius`` of it. Reads the world file: never used by the planner.
"""
from __future__ import annotations

import math
from collections.abc import Callable, Iterable, Sequence
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike
from scipy.optimize import minimize

from coverage_pkg.gvd import ring_minima

if TYPE_CHECKING:
    from coverage_pkg.world import World

RAYS = np.linspace(0.0, 2.0 * math.pi, 2880, endpoint=False)


def _closest(world, q, k):
    """The ``k`` smallest closest-obstacle distances at ``q`` (None if fewer or in a wall)."""
    if world.clearance(q) <= 0.05:
        return None
    mins = ring_minima(world.raycast(q, RAYS, 50.0), RAYS, math.radians(30.0))
    return [d for d, _ in mins[:k]] if len(mins) >= k else None


def cusp_mismatch(world: World, q: ArrayLike, delta: float) -> float:
    """|d2 - d1| + |d1 - delta| at ``q`` (m): zero exactly at a cusp point."""
    d = _closest(world, q, 2)
    return 9.0 if d is None else abs(d[1] - d[0]) + abs(d[0] - delta)


def meet_mismatch(world: World, q: ArrayLike) -> float:
    """d3 - d1 at ``q`` (m): zero exactly at a meet point."""
    d = _closest(world, q, 3)
    return 9.0 if d is None else d[2] - d[0]


def nearest_true(world: World, xy: Sequence[float],
                 mismatch: Callable[[tuple[float, float]], float], radius: float,
                 tol: float = 0.02) -> float:
    """Distance (m) from ``xy`` to the nearest point within ``radius`` whose ``mismatch`` is
    below ``tol``; ``math.inf`` if the search finds none."""
    best = math.inf
    step = 0.5 * radius
    for dx, dy in ((0, 0), (step, 0), (-step, 0), (0, step), (0, -step)):
        # An explicit first simplex 5 cm wide: scipy's default around the origin is 0.25 mm
        # and never leaves it.
        simplex = np.array([[dx, dy], [dx + 0.05, dy], [dx, dy + 0.05]])
        res = minimize(lambda v: mismatch((xy[0] + v[0], xy[1] + v[1])), [dx, dy],
                       method='Nelder-Mead', options={'xatol': 0.003, 'fatol': 0.002,
                                                      'maxiter': 200,
                                                      'initial_simplex': simplex})
        r = math.hypot(*res.x)
        if res.fun < tol and r <= radius:
            best = min(best, r)
    return best


def check_events(world: World, events: Iterable[Sequence[object]], delta: float,
                 cusp_radius: float = 0.15, meet_radius: float = 0.3
                 ) -> dict[str, tuple[int, int] | list[Sequence[object]]]:
    """Verify the ``cusp`` and ``meet`` events (``[t, kind, x, y, detail]`` in the world
    frame) against ``world``. Returns ``{'cusp': (verified, sensed), 'meet': (...),
    'unverified': [event, ...]}``."""
    out = {'cusp': [0, 0], 'meet': [0, 0], 'unverified': []}
    for e in events:
        kind = e[1]
        if kind == 'cusp':
            d = nearest_true(world, e[2:4], lambda q: cusp_mismatch(world, q, delta),
                             cusp_radius)
        elif kind == 'meet':
            d = nearest_true(world, e[2:4], lambda q: meet_mismatch(world, q), meet_radius)
        else:
            continue
        out[kind][1] += 1
        if math.isfinite(d):
            out[kind][0] += 1
        else:
            out['unverified'].append(e)
    return {'cusp': tuple(out['cusp']), 'meet': tuple(out['meet']),
            'unverified': out['unverified']}
