"""Each collision construct of section III decides a pose set of its own, and breaking it fails.

For every collision type of Aref & Taghirad (cable-cable III-A, cable-body III-B,
cable-workpiece III-C including the workpiece's side faces) the test builds a set of poses of
the fitted Neuron in which only that type can decide: the other types are ruled out by
independent reference implementations written here (golden-section search of the convex
point-to-segment distance along each cable; dense sampling of each cable against the platform
and the workpiece boxes). On that set the accessible share of :func:`classify_poses` must equal
the reference pose by pose. Each ``check_*`` function returns the list of disagreements.

The mutation tests then break one construct at a time with ``monkeypatch`` (segment distance
replaced by the distance of the cables' end points; the body test dropped or turned around;
the workpiece test reduced to the paper's top-plane projection or dropped) and assert that the
decisive check reports the breakage: the suite proves that it would notice. The mutations act
on the numpy path; ``test/test_workspace_backends.py`` pins the compiled kernel to it bit for
bit.
"""
import numpy as np
import pytest

from cable_robot_pkg.cdrpm import collisions as col
from cable_robot_pkg.cdrpm.description import description_from_dict, load_description
from cable_robot_pkg.cdrpm.kinematics import rotation_matrix_deg

#: Poses closer than this (m) to a reference decision boundary are left out of the sets.
TIE = 1e-7
#: Golden-section iterations: the bracket shrinks by 0.618 per step, to 1e-14 of its length.
GOLDEN_STEPS = 70
#: Workpiece of the section IV-D study used here (m).
WORKPIECE = (1.0, 1.0, 0.5)
#: Samples per cable of the workpiece reference.
WORKPIECE_SAMPLES = 2001
#: Cable radius (m) of the cable-cable set: with the shipped 2.5 mm, contact between cables
#: alone decides under 1 % of random poses; 15 mm cables make it decide about 10 %.
THICK_RADIUS = 0.015


# --- independent references -------------------------------------------------------------------

def _cables(desc, pos, rot):
    """Fixed anchors A_i and cable vectors A_iB_i, (N, n, 3) each."""
    b = pos[:, None, :] + desc.platform_points @ rot.T
    a = np.broadcast_to(desc.frame_points, b.shape)
    return a, b - a


def _point_segment(p, a, d):
    """Distance of points p to the segments a + t d, t in [0, 1] (projection, clamped)."""
    t = np.clip(np.einsum('...k,...k', p - a, d) / np.einsum('...k,...k', d, d), 0.0, 1.0)
    return np.linalg.norm(p - a - t[..., None] * d, axis=-1)


def ref_cable_gap(desc, pos, rot):
    """Smallest surface gap (segment distance - 2 eps) over all cable pairs, (N,).

    The distance from the point A_i + s d_i to segment j is convex in s, so a golden-section
    search over s in [0, 1] finds the segment-segment distance without the closed form of
    eqs. (6)-(7).
    """
    a, d = _cables(desc, pos, rot)
    ii, jj = np.triu_indices(desc.n_cables, 1)
    ai, di, aj, dj = a[:, ii], d[:, ii], a[:, jj], d[:, jj]

    def f(s):
        return _point_segment(ai + s[..., None] * di, aj, dj)

    g = (np.sqrt(5.0) - 1.0) / 2.0
    lo, hi = np.zeros(ai.shape[:2]), np.ones(ai.shape[:2])
    m1, m2 = hi - g, lo + g
    f1, f2 = f(m1), f(m2)
    for _ in range(GOLDEN_STEPS):
        left = f1 < f2
        hi = np.where(left, m2, hi)
        lo = np.where(left, lo, m1)
        new = np.where(left, hi - g * (hi - lo), lo + g * (hi - lo))
        fn = f(new)
        m2, f2, m1, f1 = (np.where(left, m1, new), np.where(left, f1, fn),
                          np.where(left, new, m2), np.where(left, fn, f2))
    dist = np.minimum.reduce([f1, f2, f(np.zeros_like(lo)), f(np.ones_like(lo))])
    return dist.min(axis=1) - 2.0 * desc.cable_radius


def ref_body_depth(desc, pos, rot):
    """Deepest penetration (m) of sampled cable points into the platform box, (N,).

    Samples every cable from B_i towards A_i (t from 1 mm to 0.4 m, which covers the box) and
    measures the depth below the box faces in platform coordinates: > 0 means a point of the
    cable other than B_i is inside the body.
    """
    a, d = _cables(desc, pos, rot)
    length = np.linalg.norm(d, axis=-1)
    ts = np.linspace(1e-3, 0.4, 400)
    t = np.minimum(ts[None, None, :], length[..., None])
    pts = a[..., None, :] + d[..., None, :] * (1.0 - t / length[..., None])[..., None]
    local = np.einsum('nckj,ji->ncki', pts - pos[:, None, None, :], rot)
    depth = np.min(desc.platform_half_size - np.abs(local), axis=-1)
    return depth.max(axis=(1, 2))


def ref_workpiece_depth(desc, pos, rot, lo, hi, samples=WORKPIECE_SAMPLES):
    """Deepest penetration (m) of sampled cable points into the box (lo, hi), (N,).

    > 0: a sampled point is inside. Depth is 1-Lipschitz along the cable, so a cable that truly
    enters has a sample deeper than minus half the sample spacing: poses within
    :func:`workpiece_margin` below 0 are undecided and left out of the set.
    """
    a, d = _cables(desc, pos, rot)
    ts = np.linspace(0.0, 1.0, samples)
    depth = np.full(pos.shape[0], -np.inf)
    for k in range(desc.n_cables):
        pts = a[:, k, None, :] + ts[None, :, None] * d[:, k, None, :]
        inner = np.minimum(pts - lo, hi - pts).min(axis=-1)
        depth = np.maximum(depth, inner.max(axis=1))
    return depth


def workpiece_margin(desc):
    """Twice the largest sample spacing (m) of :func:`ref_workpiece_depth` along a cable."""
    return 2.0 * np.linalg.norm(2.0 * desc.frame_half_size) / (WORKPIECE_SAMPLES - 1)


def ref_inside_frame(desc, pos, rot):
    """All eight platform corners inside the frame (with the classifier's slack), (N,)."""
    corners = pos[:, None, :] + desc.platform_corners @ rot.T
    return np.all(np.abs(corners) <= desc.frame_half_size + 1e-9, axis=(1, 2))


# --- pose sets where one type decides ---------------------------------------------------------

def _random_poses(desc, rng, count, max_deg, z_range=None):
    pos = rng.uniform(-1.0, 1.0, (count, 3)) * (desc.frame_half_size - desc.platform_half_size)
    if z_range is not None:
        pos[:, 2] = rng.uniform(*z_range, count)
    return pos, rotation_matrix_deg(*rng.uniform(-max_deg, max_deg, 3))


def _pose_set(decider, seed=1, groups=6, per_group=300, max_deg=45.0):
    """Groups of (positions, rotation) of the Neuron where ``decider`` alone can collide.

    Returns the description and a list of (pos, rot, expected_free) per group: in frame, far
    from every reference boundary, and free of every other collision type. The cable-cable
    set uses :data:`THICK_RADIUS`; the workpiece set adds :data:`WORKPIECE` and keeps the
    platform in the lower half of the frame, beside and above the workpiece.
    """
    rng = np.random.default_rng(seed)
    desc = load_description()
    if decider == 'cable_cable':
        desc = description_from_dict({**desc.to_dict(), 'cable_radius': THICK_RADIUS})
    lo = hi = None
    if decider == 'cable_workpiece':
        desc = desc.with_workpiece(WORKPIECE)
        lo, hi = desc.workpiece_box
        lo, hi = lo - desc.cable_radius, hi + desc.cable_radius
    groups_out = []
    for _ in range(groups):
        z_range = (-0.9, 0.0) if decider == 'cable_workpiece' else None
        pos, rot = _random_poses(desc, rng, per_group, max_deg, z_range)
        pos = pos[ref_inside_frame(desc, pos, rot)]
        gap = ref_cable_gap(desc, pos, rot)
        depth = ref_body_depth(desc, pos, rot)
        keep = (np.abs(gap) > TIE) & (np.abs(depth) > TIE)
        if decider == 'cable_cable':
            keep &= depth < 0
            free = gap > 0
        elif decider == 'cable_body':
            keep &= gap > 0
            free = depth < 0
        else:
            # The platform's bounding sphere clear of the workpiece box: no platform overlap.
            near = np.linalg.norm(pos - np.clip(pos, lo, hi), axis=1)
            keep &= (gap > 0) & (depth < 0) & (near > np.linalg.norm(desc.platform_half_size)
                                                + 1e-6)
            # The sampled reference (the slow part) only where the other conditions hold.
            work = np.full(pos.shape[0], np.nan)
            work[keep] = ref_workpiece_depth(desc, pos[keep], rot, lo, hi)
            keep &= (work > 0) | (work < -workpiece_margin(desc))
            free = work < 0
        groups_out.append((pos[keep], rot, free[keep]))
    return desc, groups_out


_SETS = {}


def pose_set(decider):
    """Cached :func:`_pose_set` (the references are the slow part of these tests)."""
    if decider not in _SETS:
        _SETS[decider] = _pose_set(decider)
    return _SETS[decider]


def _check(decider, backend, without=()):
    """Disagreements of :func:`classify_poses` with the reference on ``decider``'s set."""
    desc, groups = pose_set(decider)
    bit = col.FLAG_OF_TYPE[decider]
    problems, ours_free, ref_free, total = [], 0, 0, 0
    for pos, rot, expected_free in groups:
        flags = col.classify_poses(desc, pos, rot, backend=backend, without=without)
        ours = flags == 0
        other = flags & ~np.uint8(bit)
        if np.any(other):
            problems.append(f'{decider} set: another type decided ({int(np.count_nonzero(other))}'
                            ' poses)')
        wrong = np.count_nonzero(ours != expected_free)
        if wrong:
            problems.append(f'{decider} set: {wrong} of {pos.shape[0]} poses differ from the '
                            'reference')
        ours_free += int(ours.sum())
        ref_free += int(expected_free.sum())
        total += pos.shape[0]
    if ours_free != ref_free:
        problems.append(f'{decider}: accessible share {100.0 * ours_free / total:.1f} % against '
                        f'the independent {100.0 * ref_free / total:.1f} % ({total} poses)')
    return problems


def check_cable_cable(backend='numpy', without=()):
    """Cable-cable (III-A): the share decided by segment distances alone."""
    return _check('cable_cable', backend, without)


def check_cable_body(backend='numpy', without=()):
    """Cable-body (III-B): the share decided by cables entering the platform alone."""
    return _check('cable_body', backend, without)


def check_cable_workpiece(backend='numpy', without=()):
    """Cable-workpiece (III-C): the share decided by cables through the workpiece alone."""
    return _check('cable_workpiece', backend, without)


# --- the sets are informative and the code passes them ----------------------------------------

#: Building a pose set takes seconds (the references): the cable-body set runs with the unit
#: tests, the cable-cable and workpiece sets with the slow ones.
SLOW = pytest.mark.slow


@pytest.mark.parametrize('decider', [pytest.param('cable_cable', marks=SLOW), 'cable_body',
                                     pytest.param('cable_workpiece', marks=SLOW)])
def test_pose_set_is_decided_by_one_type(decider):
    """Every set has many poses, both outcomes, and its expected share is not trivial."""
    _, groups = pose_set(decider)
    total = sum(g[0].shape[0] for g in groups)
    free = sum(int(g[2].sum()) for g in groups)
    assert total >= 600
    assert 40 <= total - free and free >= 40, (total, free)


@SLOW
@pytest.mark.parametrize('backend', ['numpy', 'numba'])
def test_cable_cable_decides_its_set(backend):
    assert check_cable_cable(backend) == []


@pytest.mark.parametrize('backend', ['numpy', 'numba'])
def test_cable_body_decides_its_set(backend):
    assert check_cable_body(backend) == []


@SLOW
def test_cable_workpiece_decides_its_set():
    assert check_cable_workpiece() == []


@SLOW
def test_workpiece_set_needs_the_side_faces():
    """Some cables of the workpiece set pass through a side face and miss the top face."""
    desc, groups = pose_set('cable_workpiece')
    lo, hi = desc.workpiece_box
    side_only = 0
    for pos, rot, expected_free in groups:
        flags = col.classify_poses(desc, pos, rot)
        hit = (flags & col.CABLE_WORKPIECE) != 0
        top = _top_plane_hit(desc, pos, rot, lo - desc.cable_radius, hi + desc.cable_radius)
        side_only += int(np.count_nonzero(hit & ~top))
    assert side_only >= 20


# --- mutations: each broken construct fails its check ----------------------------------------

def _endpoint_distance(p0, d1, q0, d2):
    """Mutation: distance of the closest pair of cable end points instead of the segments."""
    ends1 = (np.asarray(p0, float), np.asarray(p0, float) + d1)
    ends2 = (np.asarray(q0, float), np.asarray(q0, float) + d2)
    dist = np.minimum.reduce([np.linalg.norm(u - v, axis=-1) for u in ends1 for v in ends2])
    zero = np.zeros_like(dist)
    return dist, zero, zero


def _line_distance(p0, d1, q0, d2):
    """Mutation: distance of the infinite lines (the segment ends ignored)."""
    n = np.cross(d1, d2)
    nn = np.einsum('...k,...k', n, n)
    w = np.asarray(p0, float) - q0
    dist = np.abs(np.einsum('...k,...k', w, n)) / np.sqrt(np.where(nn > 0, nn, 1.0))
    zero = np.zeros_like(dist)
    return dist, zero, zero


def _no_body(desc, d, lengths, rotations):
    """Mutation: the cable-body test dropped."""
    return np.zeros(d.shape[:2], dtype=bool)


_REAL_BODY = col._body_flags


def _body_turned_around(desc, d, lengths, rotations):
    """Mutation: D_i taken on the far side of B_i (B_i + delta S_i), outside the cable."""
    return _REAL_BODY(desc, -d, lengths, rotations)


def _top_plane_hit(desc, pos, rot, lo, hi):
    """The paper's III-C test per pose: a cable meets the top plane inside the footprint."""
    a, d = _cables(desc, pos, rot)
    return np.any(_top_only(a, d, lo, hi), axis=1)


def _top_only(p0, d, lo, hi):
    """Mutation: the paper's top-plane projection P_i -> P'_i; side faces ignored."""
    with np.errstate(divide='ignore', invalid='ignore'):
        t = (hi[2] - p0[..., 2]) / d[..., 2]
    crosses = np.isfinite(t) & (t > 0) & (t < 1)
    p = p0 + np.where(crosses, t, 0.0)[..., None] * d
    inside = ((p[..., 0] > lo[0]) & (p[..., 0] < hi[0]) & (p[..., 1] > lo[1])
              & (p[..., 1] < hi[1]))
    return crosses & inside


def _no_workpiece(p0, d, lo, hi):
    """Mutation: the cable-workpiece test dropped."""
    return np.zeros(np.shape(p0)[:-1], dtype=bool)


MUTATIONS = {
    'endpoint distance for segment distance': ('segment_distance', _endpoint_distance,
                                               check_cable_cable),
    'line distance for segment distance': ('segment_distance', _line_distance,
                                           check_cable_cable),
    'body test dropped': ('_body_flags', _no_body, check_cable_body),
    'body test turned around': ('_body_flags', _body_turned_around, check_cable_body),
    'workpiece side faces dropped': ('segment_box_hit', _top_only, check_cable_workpiece),
    'workpiece test dropped': ('segment_box_hit', _no_workpiece, check_cable_workpiece),
}


@pytest.mark.parametrize('mutation', [
    m if MUTATIONS[m][2] is check_cable_body else pytest.param(m, marks=SLOW)
    for m in sorted(MUTATIONS)])
def test_mutation_is_detected(monkeypatch, mutation):
    """The decisive check of the broken construct reports a failure under the mutation."""
    name, replacement, check = MUTATIONS[mutation]
    pose_set({check_cable_cable: 'cable_cable', check_cable_body: 'cable_body',
              check_cable_workpiece: 'cable_workpiece'}[check])   # built with the real code
    monkeypatch.setattr(col, name, replacement)
    problems = check('numpy')
    assert problems, f'{mutation}: not detected'
    assert any('share' in p for p in problems), problems


@pytest.mark.parametrize('construct,check', [
    pytest.param('cable_cable', check_cable_cable, marks=SLOW), ('cable_body', check_cable_body),
    pytest.param('cable_workpiece', check_cable_workpiece, marks=SLOW),
    pytest.param('workpiece_sides', check_cable_workpiece, marks=SLOW)])
def test_switching_a_construct_off_fails_its_check(construct, check):
    """``without=`` (the ``--without`` of the CLI) turns a construct off: its set then has a
    larger accessible share than the reference, as the mutations do."""
    problems = check('numpy', without={construct})
    assert any('share' in p for p in problems), problems


def test_unknown_construct_is_refused():
    desc = load_description()
    with pytest.raises(ValueError, match='without: unknown construct'):
        col.classify_poses(desc, np.zeros((1, 3)), np.eye(3), without={'cable'})
