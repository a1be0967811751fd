"""Collision tests of cable_robot_pkg.cdrpm against independent methods.

Cable-cable distances are compared with (a) exact rational arithmetic over the KKT cases of the
segment-segment problem and (b) scipy's bounded least squares (BVLS), to 1e-9 m, on random,
parallel, collinear, touching, crossing and near-parallel pairs.
"""
from fractions import Fraction

import numpy as np
import pytest
from scipy.optimize import lsq_linear

from cable_robot_pkg.cdrpm import collisions as col
from cable_robot_pkg.cdrpm.description import CONFIG_DIR, description_from_dict, load_description
from cable_robot_pkg.cdrpm.kinematics import rotation_matrix, rotation_matrix_deg


def _exact_sq_distance(p0, d1, q0, d2):
    """Squared segment distance in exact rational arithmetic (independent closed form).

    The minimum of |r + s d1 - t d2|^2 over [0, 1]^2 is at a KKT point: interior stationary
    point, or a point-segment projection from one of the four endpoints. All candidates are
    evaluated exactly; the smallest value is the minimum.
    """
    p0, d1, q0, d2 = ([Fraction(float(v)) for v in x] for x in (p0, d1, q0, d2))

    def dot(u, v):
        return sum(a * b for a, b in zip(u, v))

    def point(s, t):
        return [p0[k] + s * d1[k] - q0[k] - t * d2[k] for k in range(3)]

    def clamp(x):
        return min(max(x, Fraction(0)), Fraction(1))

    a, b, e = dot(d1, d1), dot(d1, d2), dot(d2, d2)
    r = [p0[k] - q0[k] for k in range(3)]
    c, f = dot(d1, r), dot(d2, r)
    cands = []
    # Endpoint of segment 1 against segment 2, and vice versa (point-segment projections).
    for s in (Fraction(0), Fraction(1)):
        t = clamp((dot(d2, r) + s * b) / e) if e else Fraction(0)
        cands.append((s, t))
    for t in (Fraction(0), Fraction(1)):
        s = clamp((t * b - c) / a) if a else Fraction(0)
        cands.append((s, t))
    den = a * e - b * b
    if den != 0:
        s = (b * f - c * e) / den
        t = (a * f - b * c) / den
        if 0 <= s <= 1 and 0 <= t <= 1:
            cands.append((s, t))
    return min(dot(point(s, t), point(s, t)) for s, t in cands)


def _bvls_distance(p0, d1, q0, d2):
    """Segment distance by bounded linear least squares: min |[d1, -d2] (s, t) + r|."""
    mat = np.stack([d1, -d2], axis=1)
    res = lsq_linear(mat, -(p0 - q0), bounds=(0.0, 1.0), method='bvls', tol=1e-15)
    s, t = res.x
    return float(np.linalg.norm(p0 + s * d1 - q0 - t * d2))


def _random_pairs(rng, count):
    """Random segment pairs of many kinds: (p0, d1, q0, d2) arrays (count, 3)."""
    p0 = rng.uniform(-2, 2, (count, 3))
    d1 = rng.uniform(-2, 2, (count, 3))
    q0 = rng.uniform(-2, 2, (count, 3))
    d2 = rng.uniform(-2, 2, (count, 3))
    kind = np.arange(count) % 8
    # 1: parallel, 2: collinear overlapping, 3: touching end to end, 4: crossing interiors,
    # 5: near-parallel, 6: anti-parallel offset, 7: general (kept).
    k = kind == 1
    d2[k] = d1[k] * rng.uniform(-1.5, 1.5, (k.sum(), 1))
    k = kind == 2
    q0[k] = p0[k] + d1[k] * rng.uniform(-0.5, 1.0, (k.sum(), 1))
    d2[k] = d1[k] * rng.uniform(0.2, 1.2, (k.sum(), 1))
    k = kind == 3
    q0[k] = p0[k] + d1[k]
    k = kind == 4
    s = rng.uniform(0.1, 0.9, (k.sum(), 1))
    t = rng.uniform(0.1, 0.9, (k.sum(), 1))
    q0[k] = p0[k] + s * d1[k] - t * d2[k]
    k = kind == 5
    d2[k] = d1[k] + rng.normal(0, 1e-7, (k.sum(), 3))
    q0[k] = p0[k] + rng.normal(0, 0.01, (k.sum(), 3))
    k = kind == 6
    d2[k] = -d1[k]
    q0[k] = p0[k] + d1[k] + rng.normal(0, 0.003, (k.sum(), 3))
    return p0, d1, q0, d2


@pytest.mark.parametrize('pairs', [200, pytest.param(800, marks=pytest.mark.slow)])
def test_segment_distance_matches_exact_arithmetic_and_bvls(pairs):
    """``pairs`` pairs of every kind (exact arithmetic per pair is the slow part)."""
    rng = np.random.default_rng(1234)
    p0, d1, q0, d2 = _random_pairs(rng, pairs)
    dist, s, t = col.segment_distance(p0, d1, q0, d2)
    assert np.all((s >= 0) & (s <= 1) & (t >= 0) & (t <= 1))
    # The reported closest points realise the reported distance.
    realised = np.linalg.norm(p0 + s[:, None] * d1 - q0 - t[:, None] * d2, axis=1)
    np.testing.assert_allclose(realised, dist, atol=1e-12, rtol=0)
    for i in range(len(dist)):
        exact = float(_exact_sq_distance(p0[i], d1[i], q0[i], d2[i])) ** 0.5
        assert abs(dist[i] - exact) < 1e-9, (i, dist[i], exact)
        assert abs(dist[i] - _bvls_distance(p0[i], d1[i], q0[i], d2[i])) < 1e-9, i


def test_segment_distance_special_cases():
    o = np.zeros(3)
    x = np.array([1.0, 0, 0])
    # Touching at a shared endpoint, crossing, parallel with gap, collinear disjoint.
    cases = [
        (o, x, x, np.array([0, 1.0, 0]), 0.0),
        (np.array([-1.0, 0, 0]), 2 * x, np.array([0, -1.0, 0]), np.array([0, 2.0, 0]), 0.0),
        (o, x, np.array([0.5, 0.3, 0]), x, 0.3),
        (o, x, np.array([3.0, 0, 0]), x, 2.0),
        (o, x, np.array([0.2, 0, 0.4]), np.zeros(3), 0.4),   # zero-length second segment
        (o, np.zeros(3), o + 1.0, np.zeros(3), 3 ** 0.5),    # two points
    ]
    for p0, d1, q0, d2, expected in cases:
        dist, _, _ = col.segment_distance(p0, d1, q0, d2)
        assert abs(float(dist) - expected) < 1e-12


def test_touching_at_clearance_is_not_a_collision():
    """Two cables exactly 2 eps apart touch but do not collide (strict < 2 eps, eq. (4))."""
    eps = 0.0025
    base = {'frame_half_size': [1, 2, 1], 'platform_half_size': [0.1, 0.1, 0.1],
            'cable_radius': eps}
    # Two parallel vertical cables 2 eps + margin apart in x.
    for gap, expected in ((2 * eps + 1e-6, False), (2 * eps - 1e-6, True)):
        desc = description_from_dict({
            **base,
            'frame_points': [[0.1, 0.5, 1.0], [0.1 - gap, 0.5, 1.0]],
            'platform_points': [[0.1, 0.1, 0.1], [0.1 - gap, 0.1, 0.1]]})
        flags = col.classify_poses(desc, [[0.0, 0.4, 0.3]], np.eye(3))
        assert bool(flags[0] & col.CABLE_CABLE) is expected


def _brute_flags(desc, positions, rot):
    """Reference: all pairs by full segment distance (no screen), body by dense sampling."""
    out = []
    for g in positions:
        b = g + desc.platform_points @ rot.T
        d = b - desc.frame_points
        flag = 0
        if np.any(np.abs(g) + np.abs(rot) @ desc.platform_half_size
                  > desc.frame_half_size + 1e-9):
            out.append(col.OUTSIDE)
            continue
        for i, j in zip(desc.pair_i, desc.pair_j):
            dist = _bvls_distance(desc.frame_points[i], d[i], desc.frame_points[j], d[j])
            if dist < 2 * desc.cable_radius:
                flag |= col.CABLE_CABLE
        # Body: is any cable point (other than B_i) strictly inside the platform box?
        ts = np.linspace(0.0, 1.0, 4001)[:-1]
        for i in range(desc.n_cables):
            pts = desc.frame_points[i] + ts[:, None] * d[i]
            local = (pts - g) @ rot
            if np.any(np.all(np.abs(local) < desc.platform_half_size - 1e-9, axis=1)):
                flag |= col.CABLE_BODY
        out.append(flag)
    return np.array(out, dtype=np.uint8)


#: Collision types met by the Neuron with thick (0.049 m) cables on random poses.
NEURON_FLAGS = col.CABLE_CABLE | col.CABLE_BODY | col.OUTSIDE


#: The brute-force reference takes about a second per 60 poses: one batch of the shipped Neuron
#: (which meets all three collision types) runs with the unit tests, four batches of every
#: description with the slow ones.
SLOW = pytest.mark.slow


@pytest.mark.parametrize('name,expected,batches', [
    ('kntu_neuron', NEURON_FLAGS, 1),
    pytest.param('kntu_neuron', NEURON_FLAGS, 4, marks=SLOW),
    pytest.param('kntu_neuron_home', NEURON_FLAGS, 4, marks=SLOW),
    pytest.param('kntu_pinwheel', col.CABLE_CABLE | col.OUTSIDE, 4, marks=SLOW),
    pytest.param('kntu_tetra_cross', col.CABLE_CABLE | col.CABLE_BODY | col.OUTSIDE, 4,
                 marks=SLOW),
    pytest.param('kntu_uncrossed', col.OUTSIDE, 4, marks=SLOW)])
def test_classification_matches_brute_force(name, expected, batches):
    """Screened, vectorised classification equals a brute-force reference on random poses.

    A large cable radius makes cable-cable collisions frequent, so the screen is exercised.
    """
    rng = np.random.default_rng(7)
    desc = load_description(CONFIG_DIR / f'{name}.yaml')
    data = desc.to_dict()
    data['cable_radius'] = 0.049
    desc = description_from_dict(data)
    seen = 0
    for _ in range(batches):
        rot = rotation_matrix(*rng.uniform(-0.8, 0.8, 3))
        pos = rng.uniform(-1, 1, (60, 3)) * (desc.frame_half_size - 0.15)
        fast = col.classify_poses(desc, pos, rot)
        ref = _brute_flags(desc, pos, rot)
        # The body test of eq. (8) is exact for corner attachments; sampling can only miss an
        # entry, never invent one, so compare exactly.
        np.testing.assert_array_equal(fast, ref)
        seen |= int(np.bitwise_or.reduce(fast))
    assert seen == expected      # the uncrossed cables never meet


@pytest.mark.parametrize('small', [300, pytest.param(5000, marks=SLOW)])
def test_results_do_not_depend_on_batching(small):
    """Chunk sizes change nothing; ``small`` poses go through the one- and seven-pose chunks
    (a pose at a time is the slow part)."""
    rng = np.random.default_rng(3)
    desc = load_description(CONFIG_DIR / 'kntu_tetra_cross.yaml')
    pos = rng.uniform(-0.9, 0.9, (5000, 3)) * [1, 2, 1]
    rots = rotation_matrix(*rng.uniform(-0.7, 0.7, (3, 5000)))
    ref = col.classify_poses(desc, pos, rots, chunk=5000)
    assert np.any(ref != 0) and np.any(ref == 0)
    for chunk in (1, 7):
        np.testing.assert_array_equal(
            col.classify_poses(desc, pos[:small], rots[:small], chunk=chunk), ref[:small])
    for chunk in (256, 4096):
        np.testing.assert_array_equal(col.classify_poses(desc, pos, rots, chunk=chunk), ref)
    # Pose by pose through check_pose gives the same verdicts.
    for k in rng.choice(5000, 40, replace=False):
        report = col.check_pose(desc, pos[k], rots[k])
        assert report.collision_free == (ref[k] == 0)
        assert bool(report.colliding_pairs) == bool(ref[k] & col.CABLE_CABLE)
        assert bool(report.body_cables) == bool(ref[k] & col.CABLE_BODY)
    # A shared rotation (matmul screen of a COW) gives the same result, pair by pair, as the
    # same rotation repeated per pose (generic screen).
    for rot in (rotation_matrix_deg(30, 30, 10), rotation_matrix_deg(-20, 45, 80)):
        shared, shared_detail = col.classify_poses(desc, pos, rot, detail=True)
        each, each_detail = col.classify_poses(desc, pos, np.broadcast_to(rot, (5000, 3, 3)),
                                               detail=True)
        np.testing.assert_array_equal(shared, each)
        np.testing.assert_array_equal(shared_detail['pairs'], each_detail['pairs'])
        assert shared_detail['pairs'].sum() > 50


def test_workpiece_box_test_matches_sampling():
    rng = np.random.default_rng(11)
    lo, hi = np.array([-0.5, -0.5, -1.0]), np.array([0.5, 0.5, -0.5])
    p0 = rng.uniform(-1, 1, (3000, 3)) * [1, 2, 1]
    d = rng.uniform(-1.5, 1.5, (3000, 3))
    hit = col.segment_box_hit(p0, d, lo, hi)
    ts = np.linspace(0, 1, 2001)
    pts = p0[:, None, :] + ts[None, :, None] * d[:, None, :]
    sampled = np.any(np.all((pts > lo) & (pts < hi), axis=2), axis=1)
    # Sampling can miss a grazing hit but never report a false one.
    assert np.all(hit[sampled])
    assert np.count_nonzero(hit & ~sampled) <= 3
    assert hit.sum() > 200


def test_workpiece_collisions_are_counted():
    desc = load_description().with_workpiece([1.0, 1.0, 0.5])
    # Right above the workpiece, near its top: cables to the floor corners pass through it.
    report = col.check_pose(desc, [0.0, 0.0, -0.3], np.eye(3))
    assert report.inside_frame and report.workpiece_cables and not report.collision_free
    # Platform sunk into the workpiece.
    report = col.check_pose(desc, [0.0, 0.0, -0.6], np.eye(3))
    assert report.platform_workpiece
    # High up, clear.
    assert col.check_pose(desc, [0.0, 0.0, 0.8], np.eye(3)).collision_free


def test_screen_misses_nothing_where_cables_graze():
    """Next to the pinwheel's end walls cables pass within millimetres: screened == unscreened."""
    from cable_robot_pkg.cdrpm.workspace import grid_axes, grid_points
    desc = load_description(CONFIG_DIR / 'kntu_pinwheel.yaml')
    xs, ys, zs = grid_axes(desc, 0.05)
    pos = grid_points([xs, ys[[0, 1, 2, -3, -2, -1]], zs])
    for rot in (np.eye(3), rotation_matrix_deg(3, -2, 4)):
        flags, detail = col.classify_poses(desc, pos, rot, detail=True)
        d = pos[:, None, :] + (desc.platform_points @ rot.T)[None] - desc.frame_points[None]
        pi, pj = desc.pair_i, desc.pair_j
        dist, _, _ = col.segment_distance(desc.frame_points[pi][None], d[:, pi],
                                          desc.frame_points[pj][None], d[:, pj])
        np.testing.assert_array_equal(detail['pairs'], dist < 2 * desc.cable_radius)
        assert detail['pairs'].any() and (dist < 4 * desc.cable_radius).sum() > \
            detail['pairs'].sum()
