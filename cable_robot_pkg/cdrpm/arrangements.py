"""Corner-to-corner cable arrangements: the search behind the shipped Neuron description.

The paper does not list the anchor coordinates of its "Neuron" design. With the fixed anchors
A_i at the eight frame corners and the moving anchors B_i at the eight platform corners, an
arrangement is a pairing (a permutation of the corners): platform corner k is joined to frame
corner ``perm[k]``. This module enumerates the 8! = 40,320 pairings and keeps those that fit the
paper's description:

- *admissible*: every cable leaves its platform corner outwards along at least one axis (else it
  enters the platform at every position, eq. (8));
- *half-turn symmetric*: invariant under a half turn about the x or the y axis, which maps
  "+z with clockwise z-rotation" onto "-z with counter-clockwise z-rotation" (section IV-A),
  and *not* invariant under the z mirror (else the paper's remark would be pointless);

and scores each one by the collision-free share of a grid at zero rotation and by the share of
that grid where it is wrench-closed (:mod:`.wrench_closure`).
"""
import itertools

import numpy as np

from cable_robot_pkg.cdrpm.collisions import classify_poses
from cable_robot_pkg.cdrpm.description import description_from_dict
from cable_robot_pkg.cdrpm.workspace import grid_axes, grid_points
from cable_robot_pkg.cdrpm.wrench_closure import wrench_closure

#: Corner sign vectors in the order used by the shipped YAML files.
CORNERS = np.array([(sx, sy, sz) for sz in (1, -1) for sy in (1, -1) for sx in (1, -1)],
                   dtype=float)
HALF_TURN_X = np.array([1.0, -1.0, -1.0])
HALF_TURN_Y = np.array([-1.0, 1.0, -1.0])
MIRROR_Z = np.array([1.0, 1.0, -1.0])


def pairing_description(perm, frame_half_size, platform_half_size, cable_radius, name=None):
    """Robot description joining platform corner k to frame corner ``perm[k]``."""
    perm = list(perm)
    return description_from_dict({
        'name': name or 'pairing_' + ''.join(str(p) for p in perm),
        'frame_half_size': [float(v) for v in frame_half_size],
        'frame_points': (CORNERS[perm] * frame_half_size).tolist(),
        'platform_points': (CORNERS * platform_half_size).tolist(),
        'platform_half_size': [float(v) for v in platform_half_size],
        'cable_radius': float(cable_radius)})


def admissible(perm):
    """Every cable has an outward direction component at its platform corner."""
    return bool(np.all(np.any(CORNERS[list(perm)] == CORNERS, axis=1)))


def invariant(perm, signs):
    """Is the set of cables invariant under the sign flip ``signs`` (a half turn or mirror)?"""
    cables = {(tuple(CORNERS[k]), tuple(CORNERS[p])) for k, p in enumerate(perm)}
    return {(tuple(np.array(b) * signs), tuple(np.array(a) * signs))
            for b, a in cables} == cables


def candidate_pairings():
    """Admissible pairings with the half-turn symmetry of section IV-A and no z mirror."""
    out = []
    for perm in itertools.permutations(range(8)):
        if not admissible(perm):
            continue
        about_x, about_y = invariant(perm, HALF_TURN_X), invariant(perm, HALF_TURN_Y)
        if (about_x or about_y) and not invariant(perm, MIRROR_Z):
            out.append((perm, about_x, about_y))
    return out


def score_pairings(frame_half_size, platform_half_size, cable_radius, step=0.2,
                   pairings=None, progress=False):
    """Score pairings at zero rotation on a grid: list of dicts, best wrench closure first."""
    pairings = candidate_pairings() if pairings is None else pairings
    rows = []
    points = None
    iterator = pairings
    if progress:
        from tqdm import tqdm
        iterator = tqdm(pairings, desc='pairings', unit='pairing', leave=False)
    for perm, about_x, about_y in iterator:
        desc = pairing_description(perm, frame_half_size, platform_half_size, cable_radius)
        if points is None:
            points = grid_points(grid_axes(desc, step))
        free = classify_poses(desc, points, np.eye(3)) == 0
        closed, _ = wrench_closure(desc, points, np.eye(3))
        rows.append({
            'pairing': list(perm),
            'half_turn_axes': ''.join(a for a, ok in (('x', about_x), ('y', about_y)) if ok),
            'collision_free_percent': 100.0 * float(np.mean(free)),
            'wrench_closed_percent': 100.0 * float(np.mean(closed)),
            'both_percent': 100.0 * float(np.mean(free & closed)),
        })
    rows.sort(key=lambda r: (-r['both_percent'], -r['collision_free_percent'], r['pairing']))
    return rows


def pairing_of(desc):
    """The corner pairing of a corner-to-corner description, or None."""
    if desc.n_cables != 8:
        return None
    plat = np.sign(desc.platform_points)
    frame = np.sign(desc.frame_points)
    if not (np.allclose(np.abs(desc.platform_points), desc.platform_half_size)
            and np.allclose(np.abs(desc.frame_points), desc.frame_half_size)):
        return None
    index = {tuple(c): k for k, c in enumerate(CORNERS)}
    order = [index.get(tuple(p)) for p in plat]
    if None in order or len(set(order)) != 8:
        return None
    perm = [0] * 8
    for k, f in zip(order, frame):
        perm[k] = index.get(tuple(f))
    return perm if None not in perm and len(set(perm)) == 8 else None
