"""Cable arrangements of the KNTU CDRPM: the searches behind the shipped Neuron description.

The paper does not list the anchor coordinates of its "Neuron" design. It says: the moving
anchors B_i are the eight corners of the platform box (II-B, Fig. 1); the fixed anchors A_i
"lie on the fixed cubic frame" (II-A); the design uses "opposite positioning" and "inherent
cross cabling" (I); collisions in +z under clockwise z-rotation mirror those in -z under
counter-clockwise z-rotation (IV-A), i.e. the arrangement is invariant under a half turn about
a horizontal axis and is chiral; and it is meant to be force feasible in its whole workspace.

Three searches:

1. **Corner pairings** (:func:`candidate_pairings`, :func:`score_pairings`, scored by wrench
   closure): A_i restricted to
   the eight frame corners, an arrangement is a permutation of the corners; kept are the
   *admissible* ones (every cable leaves its platform corner outwards along some axis, else it
   enters the platform at every pose, eq. (8)) that are invariant under the half turn about x or
   y and not under the z mirror. None is both collision-free and wrench-closed on more than a
   third of the frame: two cables crossing between parallel frame and platform edges are
   coplanar at every translation and always intersect, and the pairings that avoid such
   crossings twist the platform one way only (``kntu_pinwheel.yaml``) or
   have no moment about one axis (``kntu_uncrossed.yaml``).
2. **Edge anchors** (:func:`search_edge_arrangements`): every A_i may sit anywhere on the 12
   edges of the frame (on a ``pitch`` spacing, corners included), and the arrangement is
   invariant under the three half turns about x, y and z (the rotation group D2 of a box, which
   contains the half turn of IV-A), so two cables - those of platform corners (+,+,+) and
   (-,+,+) - generate all eight. Scored with the wrench-closure test of
   :mod:`.wrench_closure` around the home pose: the search behind ``kntu_neuron_home.yaml``.
3. **Fit to the paper's results** (:func:`search_table2_arrangements`): the same
   edge-anchored candidates that can hold the platform at home, kept when they match the
   paper's Table II (within 5 points on the in-frame grid) and hold its 1.2 x 1.2 x 1.4 m box in
   the total orientation workspace; the best Table II fit is the shipped default,
   ``kntu_neuron.yaml``, an arrangement fitted to Table II and the TOW box (not the paper's
   anchors, which are not published).
"""
from __future__ import annotations

import itertools
from collections.abc import Callable, Iterable, Sequence
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from cable_robot_pkg.cdrpm.collisions import check_pose, classify_poses
from cable_robot_pkg.cdrpm.description import RobotDescription, description_from_dict
from cable_robot_pkg.cdrpm.kinematics import rotation_matrix_deg
from cable_robot_pkg.cdrpm.workspace import grid_axes, grid_points
from cable_robot_pkg.cdrpm.wrench_closure import wrench_closure

#: Corner sign vectors in the order used by the shipped YAML files.
CORNERS = np.array([(sx, sy, sz) for sz in (1, -1) for sy in (1, -1) for sx in (1, -1)],
                   dtype=float)
HALF_TURN_X = np.array([1.0, -1.0, -1.0])
HALF_TURN_Y = np.array([-1.0, 1.0, -1.0])
MIRROR_Z = np.array([1.0, 1.0, -1.0])
#: How the searches evaluate independent candidates: ``map_cases(fn, cases)`` returns
#: ``[fn(case) for case in cases]`` in order (serially or with :func:`paramotion.sweep.run_tasks`).
MapCases = Callable[[Callable[[Any], Any], list[Any]], list[Any]]


def pairing_description(perm: Sequence[int], frame_half_size: ArrayLike,
                        platform_half_size: ArrayLike, cable_radius: float,
                        name: str | None = None) -> RobotDescription:
    """Robot description joining platform corner k to frame corner ``perm[k]``."""
    perm = list(perm)
    return description_from_dict({
        'name': name or 'pairing_' + ''.join(str(p) for p in perm),
        'frame_half_size': [float(v) for v in frame_half_size],
        'frame_points': (CORNERS[perm] * frame_half_size).tolist(),
        'platform_points': (CORNERS * platform_half_size).tolist(),
        'platform_half_size': [float(v) for v in platform_half_size],
        'cable_radius': float(cable_radius)})


def admissible(perm: Sequence[int]) -> bool:
    """Every cable has an outward direction component at its platform corner."""
    return bool(np.all(np.any(CORNERS[list(perm)] == CORNERS, axis=1)))


def invariant(perm: Sequence[int], signs: np.ndarray) -> bool:
    """Is the set of cables invariant under the sign flip ``signs`` (a half turn or mirror)?"""
    cables = {(tuple(CORNERS[k]), tuple(CORNERS[p])) for k, p in enumerate(perm)}
    return {(tuple(np.array(b) * signs), tuple(np.array(a) * signs))
            for b, a in cables} == cables


def candidate_pairings() -> list[tuple[tuple[int, ...], bool, bool]]:
    """Admissible pairings with the half-turn symmetry of section IV-A and no z mirror."""
    out = []
    for perm in itertools.permutations(range(8)):
        if not admissible(perm):
            continue
        about_x, about_y = invariant(perm, HALF_TURN_X), invariant(perm, HALF_TURN_Y)
        if (about_x or about_y) and not invariant(perm, MIRROR_Z):
            out.append((perm, about_x, about_y))
    return out


def score_pairings(frame_half_size: ArrayLike, platform_half_size: ArrayLike,
                   cable_radius: float, step: float = 0.2,
                   pairings: Sequence[tuple[Sequence[int], bool, bool]] | None = None,
                   progress: bool = False) -> list[dict[str, object]]:
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


def pairing_of(desc: RobotDescription) -> list[int] | None:
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


# --- edge-anchored arrangements with the half-turn symmetry of the frame box ------------------
#
# The corner-to-corner search above cannot give a robot that is both collision-free and
# wrench-closed: two cables that cross between parallel frame and platform edges are coplanar
# for every translation and always intersect, and the pairings that avoid such crossings twist
# the platform one way only (the pinwheel) or have no moment about one axis (uncrossed). The
# paper only says that the A_i "lie on the fixed cubic frame" (section II-A), so the search
# below lets each frame anchor slide along the 12 frame edges.

#: The half turns about x, y and z with the identity: the rotation group D2 of a box.
D2 = (np.ones(3), HALF_TURN_X, HALF_TURN_Y, HALF_TURN_X * HALF_TURN_Y)
#: Platform corners whose cables generate an arrangement under D2 (one per D2 orbit of corners:
#: corners with sx*sy*sz = +1 and = -1).
GENERATOR_CORNERS = np.array([[1.0, 1.0, 1.0], [-1.0, 1.0, 1.0]])


def edge_anchor_candidates(frame_half_size: ArrayLike, pitch: float) -> np.ndarray:
    """Points on the 12 edges of the frame box, at whole multiples of ``pitch`` (m) from an end.

    Includes the corners. Returns an (m, 3) array without duplicates.
    """
    frame_half_size = np.asarray(frame_half_size, dtype=float)
    if not pitch > 0:
        raise ValueError(f'pitch must be > 0, got {pitch}')
    points = set()
    for axis in range(3):
        f = frame_half_size[axis]
        count = int(np.floor(2 * f / pitch + 1e-9))
        along = {round(f - k * pitch, 9) for k in range(count + 1)}
        along |= {round(-f + k * pitch, 9) for k in range(count + 1)}
        others = [k for k in range(3) if k != axis]
        for s1 in (1.0, -1.0):
            for s2 in (1.0, -1.0):
                for t in along:
                    p = np.zeros(3)
                    p[axis] = t
                    p[others[0]] = s1 * frame_half_size[others[0]]
                    p[others[1]] = s2 * frame_half_size[others[1]]
                    points.add(tuple(np.round(p, 9) + 0.0))
    return np.array(sorted(points))


def symmetric_cables(anchor0: ArrayLike, anchor1: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
    """The eight (platform corner signs, frame anchor) cables generated under D2.

    The cable of platform corner (+,+,+) goes to ``anchor0`` and that of (-,+,+) to
    ``anchor1``; the half turns about x, y and z carry them to the other six corners. Returned
    in the corner order of :data:`CORNERS` as two (8, 3) arrays.
    """
    signs, anchors = [], []
    for corner, anchor in zip(GENERATOR_CORNERS, (anchor0, anchor1)):
        for g in D2:
            signs.append(corner * g)
            anchors.append(np.asarray(anchor, dtype=float) * g)
    signs, anchors = np.array(signs), np.array(anchors)
    order = [int(np.nonzero(np.all(signs == c, axis=1))[0][0]) for c in CORNERS]
    return signs[order], anchors[order]


def symmetric_description(anchor0: ArrayLike, anchor1: ArrayLike, frame_half_size: ArrayLike,
                          platform_half_size: ArrayLike, cable_radius: float,
                          name: str = 'edge_arrangement') -> RobotDescription:
    """Robot description of the D2-symmetric arrangement generated by two frame anchors."""
    signs, anchors = symmetric_cables(anchor0, anchor1)
    return description_from_dict({
        'name': name,
        'frame_half_size': [float(v) for v in frame_half_size],
        'frame_points': np.round(anchors, 9).tolist(),
        'platform_points': (signs * np.asarray(platform_half_size, dtype=float)).tolist(),
        'platform_half_size': [float(v) for v in platform_half_size],
        'cable_radius': float(cable_radius)})


def _cable_set(signs, anchors, transform=None):
    """The cables as a set of (platform sign, frame anchor) pairs rounded to 1e-9, optionally
    mapped by ``transform`` (a signed permutation or -I: exact in floating point). Rounded
    once per array, not per vector: this runs for every candidate pair under every symmetry
    of the boxes and dominated the search's serial part."""
    signs = np.asarray(signs, dtype=float)
    anchors = np.asarray(anchors, dtype=float)
    if transform is not None:
        signs = signs @ transform.T
        anchors = anchors @ transform.T
    s = (np.round(signs, 9) + 0.0).tolist()
    a = (np.round(anchors, 9) + 0.0).tolist()
    return frozenset(zip(map(tuple, s), map(tuple, a)))


def _box_symmetries(frame_half_size, platform_half_size):
    """Signed permutation matrices mapping both boxes onto themselves (incl. mirrors)."""
    out = []
    for perm in itertools.permutations(range(3)):
        for flips in itertools.product((1.0, -1.0), repeat=3):
            mat = np.zeros((3, 3))
            for row, (col, flip) in enumerate(zip(perm, flips)):
                mat[row, col] = flip
            if np.allclose(np.abs(mat) @ frame_half_size, frame_half_size) and np.allclose(
                    np.abs(mat) @ platform_half_size, platform_half_size):
                out.append(mat)
    return out


def arrangement_properties(signs: np.ndarray, anchors: np.ndarray,
                           platform_half_size: ArrayLike) -> dict[str, bool]:
    """Properties the paper asks of the Neuron, checked on an arrangement.

    ``opposite``: every cable is anchored on the opposite side of the platform along at least
    one axis (the paper's "opposite positioning" and "cross cabling"); ``outward``: every cable
    leaves its platform corner outwards along some axis (else it enters the platform at every
    pose, eq. (8)); ``chiral``: not invariant under the inversion through O (equivalently, for
    a D2-symmetric arrangement, under any mirror), so that clockwise and counter-clockwise
    z-rotations differ, as section IV-A describes; ``distinct``: no two cables share an anchor.
    """
    corners = signs * np.asarray(platform_half_size, dtype=float)
    opposite = bool(np.all(np.any(anchors * signs < 0, axis=1)))
    outward = bool(np.all(np.any(np.sign(anchors - corners) == signs, axis=1)))
    chiral = _cable_set(signs, anchors) != _cable_set(signs, anchors, -np.eye(3))
    distinct = len({tuple(a) for a in np.round(anchors, 9)}) == len(anchors)
    return {'opposite': opposite, 'outward': outward, 'chiral': chiral, 'distinct': distinct}


def home_check(desc: RobotDescription, orientations_deg: ArrayLike = ((0.0, 0.0, 0.0),)
               ) -> tuple[bool, bool, float]:
    """Wrench closure and collisions at the home position (centroid at O).

    Returns ``(closed, collision_free, min_gap_m)``: wrench-closed and collision-free at every
    orientation of ``orientations_deg`` ((K, 3), degrees), and the smallest surface distance
    between two cables (segment distance minus 2 epsilon) at zero rotation.
    """
    rots = rotation_matrix_deg(*np.asarray(orientations_deg, dtype=float).T)
    origin = np.zeros((rots.shape[0], 3))
    closed = bool(np.all(wrench_closure(desc, origin, rots)[0]))
    free = bool(np.all(classify_poses(desc, origin, rots) == 0))
    report = check_pose(desc, np.zeros(3), np.eye(3))
    return closed, free, float(np.min(report.clearance))


def grid_scores(desc: RobotDescription, points: ArrayLike,
                rotation: ArrayLike | None = None) -> tuple[float, float, float]:
    """Shares (%) of ``points`` that are collision-free and wrench-closed, free, closed."""
    rotation = np.eye(3) if rotation is None else rotation
    free = classify_poses(desc, points, rotation) == 0
    closed, _ = wrench_closure(desc, points, rotation)
    return (100.0 * float(np.mean(free & closed)), 100.0 * float(np.mean(free)),
            100.0 * float(np.mean(closed)))


#: Orientation box of the score: the paper's total-orientation-workspace range (section IV-C).
SCORE_THETA_DEG = (30.0, 30.0, 10.0)


def box_scores(desc: RobotDescription, points: np.ndarray,
               rotations: np.ndarray) -> tuple[float, float, float]:
    """Shares (%) of the (point, orientation) pairs that are collision-free and wrench-closed,
    collision-free, and wrench-closed: a sampled measure of the 6-D workspace."""
    both = free_n = closed_n = 0
    for rot in rotations:
        free = classify_poses(desc, points, rot) == 0
        closed, _ = wrench_closure(desc, points, rot)
        both += int(np.count_nonzero(free & closed))
        free_n += int(np.count_nonzero(free))
        closed_n += int(np.count_nonzero(closed))
    total = float(len(points) * len(rotations))
    return 100.0 * both / total, 100.0 * free_n / total, 100.0 * closed_n / total


def _map_in_order(fn, cases):
    """The default ``map_cases`` of the searches: ``[fn(c) for c in cases]`` here."""
    return [fn(case) for case in cases]


def _edge_coarse_case(case):
    """One candidate of :func:`search_edge_arrangements`: ``None`` unless wrench-closed and
    collision-free at every home orientation, else its coarse :func:`box_scores`."""
    desc, home_orientations, coarse, coarse_rots = case
    closed, free, _ = home_check(desc, home_orientations)
    if not (closed and free):
        return None
    return box_scores(desc, coarse, coarse_rots)


def _edge_final_case(case):
    """One of the best coarse candidates scored on the fine grid: its result row."""
    a0, a1, desc, gap, points, rots = case
    both, free, closed = box_scores(desc, points, rots)
    zero = grid_scores(desc, points)
    return {'anchor0': a0.tolist(), 'anchor1': a1.tolist(),
            'box_both_percent': both, 'box_collision_free_percent': free,
            'box_wrench_closed_percent': closed,
            'zero_rotation_both_percent': zero[0],
            'zero_rotation_collision_free_percent': zero[1],
            'zero_rotation_wrench_closed_percent': zero[2],
            'home_min_gap_m': gap}


def search_edge_arrangements(frame_half_size: ArrayLike, platform_half_size: ArrayLike,
                             cable_radius: float, pitch: float = 0.1,
                             min_home_gap: float = 0.02,
                             theta_deg: Sequence[float] = SCORE_THETA_DEG,
                             home_angle_step_deg: float = 10.0, coarse_step: float = 0.4,
                             coarse_angle_step_deg: float = 60.0, step: float = 0.2,
                             angle_step_deg: float = 10.0, keep: int = 40,
                             progress: bool = False, map_cases: MapCases | None = None
                             ) -> tuple[list[dict[str, object]], dict[str, int]]:
    """Search the D2-symmetric edge-anchored arrangements; best first.

    Candidates: every pair of frame anchors from :func:`edge_anchor_candidates` (``pitch``)
    for the generating corners (+,+,+) and (-,+,+), expanded by the half turns. Kept, one per
    class of arrangements related by a symmetry or mirror of the boxes: those with all four
    :func:`arrangement_properties` that, with the centroid at O, are wrench-closed and
    collision-free at every orientation within +-``theta_deg`` (sampled every
    ``home_angle_step_deg``; the platform can be turned in place at home) and keep every two
    cables at least ``min_home_gap`` (m) apart at zero rotation.
    Score: the share of the 6-D box "grid x orientations within +-``theta_deg``" that is both
    collision-free and wrench-closed (:func:`box_scores`), first on a ``coarse_step`` grid with
    ``coarse_angle_step_deg`` sampling, then for the best ``keep`` on the ``step`` grid with
    ``angle_step_deg`` sampling; ties broken by the collision-free share and the home gap.
    ``map_cases(fn, cases)`` evaluates the independent candidates (default: in order, here;
    ``paramotion workspace arrangements`` passes :func:`paramotion.sweep.run_tasks`); the
    result does not depend on it. Returns ``(rows, stats)``.
    """
    from cable_robot_pkg.cdrpm.workspace import orientation_samples

    frame_half_size = np.asarray(frame_half_size, dtype=float)
    platform_half_size = np.asarray(platform_half_size, dtype=float)
    home_orientations = orientation_samples(theta_deg, home_angle_step_deg)
    stats = {'home_ok': 0, 'home_orientations': int(len(home_orientations))}
    map_cases = _map_in_order if map_cases is None else map_cases
    candidates = _home_candidates(frame_half_size, platform_half_size, cable_radius, pitch,
                                  min_home_gap, stats, progress, map_cases)
    if not candidates:
        return [], stats
    coarse = grid_points(grid_axes(candidates[0][2], coarse_step))
    coarse_rots = rotation_matrix_deg(*orientation_samples(theta_deg, coarse_angle_step_deg).T)
    scored = map_cases(_edge_coarse_case, [(c[2], home_orientations, coarse, coarse_rots)
                                           for c in candidates])
    survivors = [c for c, score in zip(candidates, scored) if score is not None]
    scores = [score for score in scored if score is not None]
    stats['home_ok'] = len(survivors)
    if not survivors:
        return [], stats
    first = sorted(((score, k) for k, score in enumerate(scores)),
                   key=lambda r: (-r[0][0], -r[0][1], -survivors[r[1]][3]))
    points = grid_points(grid_axes(survivors[0][2], step))
    rots = rotation_matrix_deg(*orientation_samples(theta_deg, angle_step_deg).T)
    best = [survivors[k] for _, k in first[:keep]]
    rows = map_cases(_edge_final_case, [(a0, a1, desc, gap, points, rots)
                                        for a0, a1, desc, gap in best])
    rows.sort(key=lambda r: (-r['box_both_percent'], -r['box_collision_free_percent'],
                             -r['home_min_gap_m'], r['anchor0'], r['anchor1']))
    return rows, stats


def _pairs_with_properties(case):
    """Stage 1 of :func:`_home_candidates` for one first anchor ``i``: ``(j, key)`` for every
    second anchor ``j`` whose arrangement has all four :func:`arrangement_properties`, with
    the key of its class up to the symmetries of the boxes (the smallest sorted cable set over
    them). Independent of every other ``i``, so the anchor rows run as parallel cases."""
    i, anchors, platform_half_size, symmetries = case
    out = []
    for j in range(len(anchors)):
        signs, cable_anchors = symmetric_cables(anchors[i], anchors[j])
        props = arrangement_properties(signs, cable_anchors, platform_half_size)
        if all(props.values()):
            key = min(tuple(sorted(_cable_set(signs, cable_anchors, g))) for g in symmetries)
            out.append((j, key))
    return out


def _home_case(case):
    """Stage 2 of :func:`_home_candidates` for one class representative: its description and
    :func:`home_check` at zero rotation."""
    anchor0, anchor1, frame_half_size, platform_half_size, cable_radius = case
    desc = symmetric_description(anchor0, anchor1, frame_half_size, platform_half_size,
                                 cable_radius)
    return desc, home_check(desc)


def _home_candidates(frame_half_size, platform_half_size, cable_radius, pitch, min_home_gap,
                     stats, progress=False, map_cases=None):
    """``[(anchor0, anchor1, description, home_gap)]`` once per class of edge-anchored,
    D2-symmetric arrangements related by a symmetry or mirror of the boxes, for those with all
    four :func:`arrangement_properties` that are wrench-closed and collision-free with the
    centroid at O and zero rotation and keep every two cables ``min_home_gap`` (m) apart there.
    The class representative is its first pair in (i, j) order, whatever ``map_cases`` runs
    the two independent stages on (rows of pairs, then one home check per class). Counts go
    into ``stats``."""
    map_cases = _map_in_order if map_cases is None else map_cases
    anchors = edge_anchor_candidates(frame_half_size, pitch)
    symmetries = _box_symmetries(frame_half_size, platform_half_size)
    stats.update({'anchor_points': int(len(anchors)), 'pairs': int(len(anchors) ** 2),
                  'with_properties': 0, 'distinct_up_to_symmetry': 0,
                  'home_closed_and_free': 0, 'home_gap_ok': 0})
    rows = [(i, anchors, platform_half_size, symmetries) for i in range(len(anchors))]
    if progress and map_cases is _map_in_order:
        from tqdm import tqdm
        rows = tqdm(rows, desc='anchor rows', unit='row', leave=False, mininterval=1.0)
    found = map_cases(_pairs_with_properties, rows)
    seen, firsts = set(), []
    for i, row in enumerate(found):
        stats['with_properties'] += len(row)
        for j, key in row:
            if key not in seen:
                seen.add(key)
                firsts.append((i, j))
    stats['distinct_up_to_symmetry'] = len(seen)
    checked = map_cases(_home_case, [(anchors[i], anchors[j], frame_half_size,
                                      platform_half_size, cable_radius) for i, j in firsts])
    out = []
    for (i, j), (desc, (closed, free, gap)) in zip(firsts, checked):
        if not (closed and free):
            continue
        stats['home_closed_and_free'] += 1
        if gap < min_home_gap:
            continue
        stats['home_gap_ok'] += 1
        out.append((anchors[i], anchors[j], desc, gap))
    return out


def table2_in_frame(desc: RobotDescription, points: np.ndarray,
                    rotations_deg: Iterable[Sequence[float]] | None = None) -> np.ndarray:
    """Collision-free share (%) of the in-frame ``points`` at each Table II orientation.

    This is the measure comparable with the paper's Table II: the paper checks collisions
    only, so grid points where the rotated platform leaves the frame are not counted.
    """
    from cable_robot_pkg.cdrpm.collisions import OUTSIDE
    from cable_robot_pkg.cdrpm.workspace import TABLE2_ROWS
    if rotations_deg is None:
        rotations_deg = [row[0] for row in TABLE2_ROWS]
    out = []
    for rot in rotations_deg:
        flags = classify_poses(desc, points, rotation_matrix_deg(*rot))
        inside = np.count_nonzero((flags & OUTSIDE) == 0)
        out.append(100.0 * np.count_nonzero(flags == 0) / max(inside, 1))
    return np.array(out)


def _table2_case(case):
    """One candidate of :func:`search_table2_arrangements`: ``(stages passed, row or None)``;
    stages: 1 Table II screen, 2 Table II on the fine grid, 3 TOW box (then the row)."""
    from cable_robot_pkg.cdrpm.workspace import contains_box, total_orientation_workspace
    (a0, a1, desc, gap, paper, screen_points, screen_tolerance, points, tolerance, tow_step,
     box) = case
    if np.max(np.abs(table2_in_frame(desc, screen_points) - paper)) > screen_tolerance:
        return 0, None
    shares = table2_in_frame(desc, points)
    worst = float(np.max(np.abs(shares - paper)))
    if worst > tolerance:
        return 1, None
    tow = total_orientation_workspace(desc, (30, 30, 10), step=tow_step)
    if not contains_box(tow.accessible, tow.axes, box):
        return 2, None
    free = classify_poses(desc, points, np.eye(3)) == 0
    closed, _ = wrench_closure(desc, points, np.eye(3))
    return 3, {'anchor0': a0.tolist(), 'anchor1': a1.tolist(),
               'table2_in_frame_percent': shares.tolist(),
               'table2_max_difference_points': worst,
               'tow_percent': tow.accessible_percentage,
               'zero_rotation_both_percent': 100.0 * float(np.mean(free & closed)),
               'home_min_gap_m': gap}


def search_table2_arrangements(frame_half_size: ArrayLike, platform_half_size: ArrayLike,
                               cable_radius: float, pitch: float = 0.1,
                               min_home_gap: float = 0.02, screen_step: float = 0.2,
                               screen_tolerance: float = 8.0, step: float = 0.05,
                               tolerance: float = 5.0, tow_step: float = 0.1,
                               tow_box_m: Sequence[float] | None = None,
                               progress: bool = False, map_cases: MapCases | None = None
                               ) -> tuple[list[dict[str, object]], dict[str, int]]:

    """Fit the Neuron to the paper's published workspace results; best first.

    The paper gives no anchor coordinates but measures its arrangement: Table II (share of
    the grid free of collisions at five orientations) and a box of 1.2 x 1.2 x 1.4 m inside
    its total orientation workspace for +-30, +-30, +-10 deg (IV-C). Candidates: the
    edge-anchored, D2-symmetric arrangements with the paper's properties that are
    wrench-closed and collision-free at the home pose (:func:`_home_candidates`). Kept:

    1. Table II matched: every row's collision-free share of the in-frame grid
       (:func:`table2_in_frame`) within ``screen_tolerance`` points of the paper on a
       ``screen_step`` grid, then within ``tolerance`` points on the ``step`` grid;
    2. the paper's TOW box (or ``tow_box_m``) fits inside the TOW (``tow_step`` grid, 10 deg
       sampling).

    Ranked by the largest Table II difference on the ``step`` grid (best fit first), ties by
    the wrench-closed share of the zero-rotation grid. Held out for validation: the workpiece
    study (IV-D) and the orientation workspace (Fig. 7). ``map_cases(fn, cases)`` evaluates the
    independent candidates (see :func:`search_edge_arrangements`). Returns ``(rows, stats)``.
    """
    from cable_robot_pkg.cdrpm.workspace import PAPER_TOW_BOX_M, TABLE2_ROWS
    frame_half_size = np.asarray(frame_half_size, dtype=float)
    platform_half_size = np.asarray(platform_half_size, dtype=float)
    paper = np.array([row[1] for row in TABLE2_ROWS])
    box = PAPER_TOW_BOX_M if tow_box_m is None else tow_box_m
    stats = {'screen_ok': 0, 'table2_ok': 0, 'tow_box_ok': 0}
    candidates = _home_candidates(frame_half_size, platform_half_size, cable_radius, pitch,
                                  min_home_gap, stats, progress, map_cases)
    rows = []
    if candidates:
        desc0 = candidates[0][2]
        screen_points = grid_points(grid_axes(desc0, screen_step))
        points = grid_points(grid_axes(desc0, step))
        map_cases = _map_in_order if map_cases is None else map_cases
        results = map_cases(_table2_case, [
            (a0, a1, desc, gap, paper, screen_points, screen_tolerance, points, tolerance,
             tow_step, box) for a0, a1, desc, gap in candidates])
        for passed, row in results:
            for stage, key in enumerate(('screen_ok', 'table2_ok', 'tow_box_ok'), 1):
                stats[key] += int(passed >= stage)
            if row is not None:
                rows.append(row)
    rows.sort(key=lambda r: (round(r['table2_max_difference_points'], 6),
                             -r['zero_rotation_both_percent'], r['anchor0'], r['anchor1']))
    return rows, stats
