"""Determinant predicates and the distance measure rho, checked against direct geometry.

Every predicate is compared with an independent computation (shoelace areas, numpy's general
determinant, scalar triple products, parametric segment intersection, Moller-Trumbore), on
random cases and on degenerate ones (collinear, coplanar, touching) with integer coordinates so
that the determinants are exactly zero.
"""
import itertools

import numpy as np

from voronoi_pkg.distance import compile_rho
from voronoi_pkg.planar import PAPER_GOAL, PAPER_START, paper_model
from voronoi_pkg.predicates import (
    And,
    Delta,
    Not,
    Or,
    Xor,
    bracket3,
    bracket4,
    canonical,
    evaluate_determinants,
    fuse,
    holds,
    pure_condition_free,
    segment_pierces_triangle,
    segments_cross,
)

RNG = np.random.default_rng(20240607)


def shoelace(a, b, c):
    """Twice the signed area of triangle abc by the shoelace formula (independent)."""
    xs = np.stack([a[..., 0], b[..., 0], c[..., 0]])
    ys = np.stack([a[..., 1], b[..., 1], c[..., 1]])
    return np.sum(xs * np.roll(ys, -1, axis=0) - np.roll(xs, -1, axis=0) * ys, axis=0)


def proper_crossing(a, b, c, d):
    """Segments ab and cd cross at one interior point: parametric solve (independent)."""
    out = np.zeros(len(a), dtype=bool)
    for i in range(len(a)):
        m = np.column_stack([b[i] - a[i], c[i] - d[i]])
        if abs(np.linalg.det(m)) < 1e-12:
            continue   # parallel or collinear: no single crossing point
        s, t = np.linalg.solve(m, c[i] - a[i])
        out[i] = 0 < s < 1 and 0 < t < 1
    return out


def moller_trumbore(a, b, p0, p1, p2):
    """Segment ab crosses triangle p0p1p2 (interior), Moller-Trumbore (independent)."""
    out = np.zeros(len(a), dtype=bool)
    for i in range(len(a)):
        d = b[i] - a[i]
        e1, e2 = p1[i] - p0[i], p2[i] - p0[i]
        h = np.cross(d, e2)
        det = np.dot(e1, h)
        if abs(det) < 1e-12:
            continue
        s = a[i] - p0[i]
        u = np.dot(s, h) / det
        qv = np.cross(s, e1)
        v = np.dot(d, qv) / det
        t = np.dot(e2, qv) / det
        out[i] = u > 0 and v > 0 and u + v < 1 and 0 < t < 1
    return out


def dets_for(tree, points):
    prog = compile_rho(tree)
    return prog, dict(zip(prog.keys, evaluate_determinants(prog.keys, points)))


# --- determinants ---------------------------------------------------------------------------

def test_bracket3_is_twice_signed_area_and_zero_when_collinear():
    a, b, c = (RNG.uniform(-50, 50, (500, 2)) for _ in range(3))
    np.testing.assert_allclose(bracket3(a, b, c), shoelace(a, b, c), rtol=1e-12, atol=1e-9)
    # Counter-clockwise is positive.
    assert bracket3([0, 0], [1, 0], [0, 1]) == 1.0
    # Collinear integer points: exactly zero.
    base = RNG.integers(-20, 20, (200, 2)).astype(float)
    step = RNG.integers(-5, 6, (200, 2)).astype(float)
    k1, k2 = RNG.integers(-4, 5, (2, 200, 1))
    assert np.all(bracket3(base, base + k1 * step, base + k2 * step) == 0.0)


def test_bracket4_matches_numpy_determinant_and_signed_volume():
    pts = RNG.uniform(-3, 3, (4, 300, 3))
    mine = bracket4(*pts)
    homog = np.concatenate([pts, np.ones((4, 300, 1))], axis=-1)       # (4, N, 4)
    generic = np.linalg.det(np.transpose(homog, (1, 2, 0)))           # columns = points
    np.testing.assert_allclose(mine, generic, rtol=1e-9, atol=1e-9)
    a, b, c, d = pts
    volume = np.einsum('ij,ij->i', b - a, np.cross(c - a, d - a)) / 6.0
    np.testing.assert_allclose(mine, -6.0 * volume, rtol=1e-9, atol=1e-9)


def test_bracket4_zero_for_coplanar_points():
    origin = RNG.integers(-5, 5, (200, 3)).astype(float)
    u = RNG.integers(-3, 4, (200, 3)).astype(float)
    v = RNG.integers(-3, 4, (200, 3)).astype(float)
    k = RNG.integers(-3, 4, (6, 200, 1)).astype(float)
    p = [origin + k[2 * i] * u + k[2 * i + 1] * v for i in range(3)]
    assert np.all(bracket4(origin, *p) == 0.0)


def test_canonical_sign_matches_column_swaps():
    pts = {i: RNG.uniform(-1, 1, 3) for i in range(1, 6)}
    for perm in itertools.permutations((1, 2, 4, 5)):
        key, sign = canonical(perm)
        assert key == (1, 2, 4, 5)
        direct = bracket4(*(pts[i] for i in perm))
        assert np.isclose(direct, sign * bracket4(*(pts[i] for i in key)))
    assert canonical((3, 3, 1))[1] == 0


# --- AND-OR trees and rho -------------------------------------------------------------------

def test_rho_operators_implement_the_logic():
    a, b, c = RNG.normal(size=(3, 2000))
    pts = {}
    # Leaves whose determinants are a, b, c: P_i = (0, 0), (1, 0), (0, value).
    pts.update({'o': np.zeros((2000, 2)), 'x': np.tile([1.0, 0.0], (2000, 1))})
    pts['a'] = np.stack([np.zeros(2000), a], axis=1)
    pts['b'] = np.stack([np.zeros(2000), b], axis=1)
    pts['c'] = np.stack([np.zeros(2000), c], axis=1)
    da, db, dc = (Delta('o', 'x', k) for k in 'abc')
    cases = {
        And(da, db): np.minimum(a, b),
        Or(da, db): np.maximum(a, b),
        Not(da): -a,
        Xor(da, db): np.maximum(np.minimum(a, -b), np.minimum(-a, b)),
        Not(And(da, Or(db, Not(dc)))): -np.minimum(a, np.maximum(b, -c)),
    }
    for tree, expected in cases.items():
        prog, dets = dets_for(tree, pts)
        rho = prog.rho(np.stack([dets[k] for k in prog.keys]))
        np.testing.assert_allclose(rho, expected)
        assert np.array_equal(rho > 0, holds(tree, dets))
        rho2, active = prog.evaluate(np.stack([dets[k] for k in prog.keys]))
        np.testing.assert_array_equal(rho, rho2)
        # The active leaf's own value is rho.
        key_of = np.array([k for k, _ in prog.leaves])
        sign_of = np.array([s for _, s in prog.leaves])
        values = np.stack([dets[k] for k in prog.keys])[key_of[active], np.arange(2000)]
        np.testing.assert_allclose(sign_of[active] * values, rho)
    # XOR is true exactly when the signs differ.
    prog, dets = dets_for(Xor(da, db), pts)
    assert np.array_equal(holds(Xor(da, db), dets), (a > 0) != (b > 0))


def test_pure_condition_rho_is_smallest_absolute_determinant():
    pts = {i: RNG.uniform(-2, 2, (1000, 3)) for i in range(1, 10)}
    factors = [(1, 2, 3, 7), (5, 6, 7, 8), (4, 7, 8, 9)]
    tree = pure_condition_free(factors)
    prog, dets = dets_for(tree, pts)
    direct = np.min(np.abs([bracket4(*(pts[i] for i in f)) for f in factors]), axis=0)
    np.testing.assert_allclose(prog.rho(np.stack([dets[k] for k in prog.keys])), direct)
    assert holds(tree, dets).all()   # random points are never exactly singular
    # A degenerate tetrahedron (p7 on the plane of p1 p2 p3) is singular: rho = 0.
    pts[7] = pts[1] + 0.3 * (pts[2] - pts[1]) + 0.5 * (pts[3] - pts[1])
    prog, dets = dets_for(tree, pts)
    np.testing.assert_allclose(prog.rho(np.stack([dets[k] for k in prog.keys])), 0.0,
                               atol=1e-12)


def test_segments_cross_matches_parametric_intersection():
    n = 3000
    pts = {i: RNG.uniform(-10, 10, (n, 2)) for i in range(1, 5)}
    tree = segments_cross(1, 2, 3, 4)
    prog, dets = dets_for(tree, pts)
    rho = prog.rho(np.stack([dets[k] for k in prog.keys]))
    expected = proper_crossing(pts[1], pts[2], pts[3], pts[4])
    assert 0.1 < expected.mean() < 0.9     # both outcomes well represented
    assert np.array_equal(holds(tree, dets), expected)
    assert np.array_equal(rho > 0, expected)
    assert np.all(rho != 0)


def test_segments_cross_degenerate_cases_sit_on_the_boundary():
    n = 300
    a = RNG.integers(-10, 10, (n, 2)).astype(float)
    d = RNG.integers(1, 4, (n, 2)).astype(float)
    # Collinear segments, overlapping or disjoint: every determinant vanishes.
    for k1, k2 in ((1, 3), (4, 6), (-3, 2)):
        pts = {1: a, 2: a + 2 * d, 3: a + k1 * d, 4: a + k2 * d}
        prog, dets = dets_for(segments_cross(1, 2, 3, 4), pts)
        rho = prog.rho(np.stack([dets[k] for k in prog.keys]))
        assert np.all(rho == 0.0)
        assert not holds(segments_cross(1, 2, 3, 4), dets).any()
        assert not proper_crossing(pts[1], pts[2], pts[3], pts[4]).any()
    # Touching: P3 at the midpoint of P1P2, P4 off the line -> rho exactly 0 (contact).
    normal = np.stack([-d[:, 1], d[:, 0]], axis=1)
    pts = {1: a, 2: a + 2 * d, 3: a + d, 4: a + d + normal}
    prog, dets = dets_for(segments_cross(1, 2, 3, 4), pts)
    assert np.all(prog.rho(np.stack([dets[k] for k in prog.keys])) == 0.0)


def test_segment_pierces_triangle_matches_moller_trumbore():
    n = 3000
    pts = {i: RNG.uniform(-1, 1, (n, 3)) for i in range(1, 6)}
    tree = segment_pierces_triangle(1, 2, 3, 4, 5)
    prog, dets = dets_for(tree, pts)
    rho = prog.rho(np.stack([dets[k] for k in prog.keys]))
    expected = moller_trumbore(pts[1], pts[2], pts[3], pts[4], pts[5])
    assert 0.05 < expected.mean() < 0.95
    assert np.array_equal(holds(tree, dets), expected)
    assert np.array_equal(rho > 0, expected)


def test_segment_triangle_degenerate_coplanar_is_boundary():
    n = 200
    tri = [RNG.integers(-5, 5, (n, 3)).astype(float) for _ in range(3)]
    tri[0][:, 2] = tri[1][:, 2] = tri[2][:, 2] = 0.0
    seg_a = RNG.integers(-5, 5, (n, 3)).astype(float)
    seg_b = RNG.integers(-5, 5, (n, 3)).astype(float)
    seg_a[:, 2] = seg_b[:, 2] = 0.0           # segment in the triangle's plane
    pts = {1: seg_a, 2: seg_b, 3: tri[0], 4: tri[1], 5: tri[2]}
    tree = segment_pierces_triangle(1, 2, 3, 4, 5)
    prog, dets = dets_for(tree, pts)
    assert np.all(prog.rho(np.stack([dets[k] for k in prog.keys])) == 0.0)
    assert not holds(tree, dets).any()
    # Segment ending exactly on the triangle's plane inside it: contact, rho = 0.
    centroid = (tri[0] + tri[1] + tri[2]) * (1 / 3)
    pts = {1: centroid, 2: centroid + np.array([0, 0, 2.0]), 3: tri[0], 4: tri[1], 5: tri[2]}
    keep = np.abs(bracket3(tri[0][:, :2], tri[1][:, :2], tri[2][:, :2])) > 0
    pts = {k: v[keep] for k, v in pts.items()}
    prog, dets = dets_for(tree, pts)
    np.testing.assert_allclose(prog.rho(np.stack([dets[k] for k in prog.keys])), 0.0,
                               atol=1e-9)


def test_fuse_is_an_and_of_the_parts():
    pts = {i: RNG.uniform(-10, 10, (500, 2)) for i in range(1, 7)}
    p1 = pure_condition_free([(1, 2, 3)])
    p2 = Not(segments_cross(3, 4, 5, 6))
    fused = fuse(p1, p2)
    assert isinstance(fused, And)
    progs = [compile_rho(t) for t in (p1, p2, fused)]
    vals = [p.rho(evaluate_determinants(p.keys, pts)) for p in progs]
    np.testing.assert_allclose(vals[2], np.minimum(vals[0], vals[1]))


# --- the planar model of section 6 ----------------------------------------------------------

def _independent_planar_free(q, length=10.0):
    """Section 6 free space by direct geometry: singular signs and segment crossings."""
    q = np.atleast_2d(q)
    p3 = q[:, :2]
    p4 = p3 + length * np.stack([np.cos(q[:, 2]), np.sin(q[:, 2])], axis=1)
    p1, p2 = np.zeros_like(p3), np.tile([15.0, 0.0], (len(q), 1))
    u, w = p3 - p2, p4 - p2
    collinear = u[:, 0] * w[:, 1] - u[:, 1] * w[:, 0]
    free = (p3[:, 1] != 0) & (collinear != 0)
    square = np.array([[-25, 40], [-25, -40], [55, -40], [55, 40]], dtype=float)
    edges = [(p1, p2)] + [(np.tile(square[i], (len(q), 1)),
                           np.tile(square[(i + 1) % 4], (len(q), 1))) for i in range(4)]
    for a, b in edges:
        free &= ~proper_crossing(a, b, p3, p4)
    return free


def test_paper_predicates_match_direct_geometry():
    model = paper_model()
    q = RNG.uniform([-30, -45, -np.pi], [60, 45, np.pi], (4000, 3))
    rho = model.rho(q)
    assert np.array_equal(rho > 0, _independent_planar_free(q))
    # Sub-measures: P1 is min(|15 y|, |[p2 p3 p4]|).
    p4 = q[:, :2] + 10 * np.stack([np.cos(q[:, 2]), np.sin(q[:, 2])], axis=1)
    expected_p1 = np.minimum(np.abs(15 * q[:, 1]),
                             np.abs(bracket3(np.array([15.0, 0.0]), q[:, :2], p4)))
    np.testing.assert_allclose(model.rho(q, 'singularity'), expected_p1, rtol=1e-12)
    # The paper's start and goal are free.
    assert model.rho(np.array(PAPER_START)) > 0 and model.rho(np.array(PAPER_GOAL)) > 0
