"""Determinant predicates of Vaca, Aranda & Thomas, "Simplified Voronoi diagrams for motion
planning of quadratically-solvable Gough-Stewart platforms" (sections 2 and 3).

Everything a planner needs to know about singularities and collisions is a Boolean combination
of signs of determinants of homogeneous point coordinates:

* spatial: ``[p_i p_j p_k p_l]``, the 4x4 determinant of the columns ``(x, y, z, 1)``
  (-6 times the signed volume of the tetrahedron ``P_i P_j P_k P_l``, see :func:`bracket4`);
* planar: ``[p_i p_j p_k]``, the 3x3 determinant of the columns ``(x, y, 1)``
  (twice the signed area of the triangle ``P_i P_j P_k``, positive counter-clockwise).

The predicate of eq. (1) is ``Delta(i, j, k[, l]) = true iff [p_i p_j p_k (p_l)] > 0``.
Predicates are built as AND-OR trees (:class:`Delta`, :class:`Not`, :class:`And`,
:class:`Or`, and :func:`Xor` = ``(a AND NOT b) OR (NOT a AND b)``), from

* :func:`pure_condition_free`: the singularity-free region of a factorised pure condition,
  eq. (2): ``AND_f (Delta_f OR NOT Delta_f)``;
* :func:`segments_cross` (2D, used by section 6's ``P2``) and :func:`segment_pierces_triangle`
  (3D, section 3) - the basic contacts, whose negations are collision-free predicates;
* :func:`fuse`: the AND node joining singularity- and collision-free predicates.

A determinant is identified by the labels of its points. Labels are canonicalised (sorted)
so that ``Delta(5, 3, 4)`` and ``Delta(3, 4, 5)`` share one evaluation and ``Delta(8, 5, 3)`` is
recognised as ``NOT``-free ``-[p3 p5 p8]``: :func:`canonical` returns the sorted key and the
permutation sign. Point coordinates are supplied by a model as a mapping label -> array
``(..., d)``; nothing here knows about robots. No ROS imports.
"""
from __future__ import annotations

from collections.abc import Hashable, Iterable, Mapping, Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

__all__ = [
    'And', 'Delta', 'Not', 'Or', 'Xor', 'bracket', 'bracket3', 'bracket4', 'canonical',
    'determinant_keys', 'evaluate_determinants', 'fuse', 'holds', 'pure_condition_free',
    'segment_pierces_triangle', 'segments_cross', 'to_text',
]


# ---------------------------------------------------------------------------------------------
# Determinants of homogeneous coordinates
# ---------------------------------------------------------------------------------------------

def bracket3(a: ArrayLike, b: ArrayLike, c: ArrayLike) -> np.ndarray:
    """``[a b c]`` for planar points ``(..., 2)``: det of columns ``(x, y, 1)``.

    Equals ``(b - a) x (c - a)``, twice the signed area of triangle abc (positive when a, b, c
    turn counter-clockwise). Broadcasts over leading axes.
    """
    a = np.asarray(a, dtype=float)
    b = np.asarray(b, dtype=float)
    c = np.asarray(c, dtype=float)
    return ((b[..., 0] - a[..., 0]) * (c[..., 1] - a[..., 1])
            - (c[..., 0] - a[..., 0]) * (b[..., 1] - a[..., 1]))


def bracket4(a: ArrayLike, b: ArrayLike, c: ArrayLike, d: ArrayLike) -> np.ndarray:
    """``[a b c d]`` for spatial points ``(..., 3)``: det of columns ``(x, y, z, 1)``.

    Subtracting the first column and expanding along the homogeneous row gives
    ``-(b - a) . ((c - a) x (d - a))``, i.e. -6 times the signed volume of tetrahedron abcd.
    It vanishes iff the four points are coplanar (the tetrahedron degenerates, section 2).
    """
    a = np.asarray(a, dtype=float)
    u = np.asarray(b, dtype=float) - a
    v = np.asarray(c, dtype=float) - a
    w = np.asarray(d, dtype=float) - a
    return -(u[..., 0] * (v[..., 1] * w[..., 2] - v[..., 2] * w[..., 1])
             + u[..., 1] * (v[..., 2] * w[..., 0] - v[..., 0] * w[..., 2])
             + u[..., 2] * (v[..., 0] * w[..., 1] - v[..., 1] * w[..., 0]))


def bracket(*points: ArrayLike) -> np.ndarray:
    """``[p_1 ... p_n]`` for n = 3 planar or n = 4 spatial points."""
    if len(points) == 3:
        return bracket3(*points)
    if len(points) == 4:
        return bracket4(*points)
    raise ValueError(f'a bracket takes 3 (planar) or 4 (spatial) points, got {len(points)}')


def canonical(labels: Iterable[Hashable]) -> tuple[tuple[Hashable, ...], int]:
    """Sorted label tuple and the sign of the permutation that sorts ``labels``.

    ``[p_i p_j p_k] = sign * [p_sorted]``: swapping two columns negates a determinant.
    Repeated labels make the determinant identically zero (sign 0).
    """
    labels = tuple(labels)
    if len(set(labels)) != len(labels):
        return tuple(sorted(labels)), 0
    order = sorted(range(len(labels)), key=lambda i: labels[i])
    sign = 1
    seen = [False] * len(order)
    for start in range(len(order)):
        if seen[start]:
            continue
        j, length = start, 0
        while not seen[j]:
            seen[j] = True
            j = order[j]
            length += 1
        if length % 2 == 0:
            sign = -sign
    return tuple(labels[i] for i in order), sign


# ---------------------------------------------------------------------------------------------
# AND-OR predicate trees
# ---------------------------------------------------------------------------------------------

@dataclass(frozen=True)
class Delta:
    """Eq. (1): true iff ``[p_i p_j p_k (p_l)] > 0`` for the labelled points."""

    points: tuple

    def __init__(self, *points: Hashable | Sequence[Hashable]) -> None:
        if len(points) == 1 and isinstance(points[0], (tuple, list)):
            points = tuple(points[0])
        if len(points) not in (3, 4):
            raise ValueError(f'Delta takes 3 or 4 point labels, got {points!r}')
        object.__setattr__(self, 'points', tuple(points))


@dataclass(frozen=True)
class Not:
    """Logical negation (a bar over a predicate in the paper)."""

    child: object


@dataclass(frozen=True)
class And:
    """Logical conjunction of the children."""

    children: tuple

    def __init__(self, *children: Predicate) -> None:
        object.__setattr__(self, 'children', tuple(children))


@dataclass(frozen=True)
class Or:
    """Logical disjunction of the children."""

    children: tuple

    def __init__(self, *children: Predicate) -> None:
        object.__setattr__(self, 'children', tuple(children))


Predicate = Delta | Not | And | Or
"""An AND-OR predicate tree node."""


def Xor(a: Predicate, b: Predicate) -> Or:  # noqa: N802 - reads like the other node constructors
    """Exclusive or, written as the paper does: ``(a AND NOT b) OR (NOT a AND b)``."""
    return Or(And(a, Not(b)), And(Not(a), b))


def pure_condition_free(factors: Iterable[Sequence[Hashable]]) -> And:
    """Singularity-free region of a factorised pure condition, eq. (2).

    ``factors`` lists the point-label tuples of the determinants whose product is the pure
    condition; the platform is singular iff one of them vanishes, so the free region is
    ``AND_f (Delta_f OR NOT Delta_f)``.
    """
    return And(*(Or(Delta(*f), Not(Delta(*f))) for f in factors))


def segments_cross(a: Hashable, b: Hashable, c: Hashable, d: Hashable) -> And:
    """2D basic contact: segment ab properly crosses segment cd (section 6, one term of P2).

    ``(Delta(a,b,c) XOR Delta(a,b,d)) AND (Delta(a,c,d) XOR Delta(b,c,d))``: c and d lie on
    opposite sides of line ab, and a and b on opposite sides of line cd.
    """
    return And(Xor(Delta(a, b, c), Delta(a, b, d)), Xor(Delta(a, c, d), Delta(b, c, d)))


def segment_pierces_triangle(a: Hashable, b: Hashable, c: Hashable, d: Hashable,
                             e: Hashable) -> And:
    """3D basic contact of section 3: segment ab crosses triangle cde.

    ``(Delta(a,c,d,e) XOR Delta(b,c,d,e)) AND [(Delta(a,b,c,d) AND Delta(a,b,d,e) AND
    Delta(a,b,e,c)) OR (NOT ... AND NOT ... AND NOT ...)]``: a and b on opposite sides of the
    triangle's plane, and the line ab on the same side of the three edge lines.
    """
    e1, e2, e3 = Delta(a, b, c, d), Delta(a, b, d, e), Delta(a, b, e, c)
    return And(Xor(Delta(a, c, d, e), Delta(b, c, d, e)),
               Or(And(e1, e2, e3), And(Not(e1), Not(e2), Not(e3))))


def fuse(*predicates: Predicate) -> And:
    """Join singularity-free and collision-free predicates through an AND node (section 3)."""
    flat = []
    for p in predicates:
        flat.extend(p.children if isinstance(p, And) else (p,))
    return And(*flat)


def determinant_keys(tree: Predicate) -> list[tuple[Hashable, ...]]:
    """Canonical keys of every determinant in ``tree``, in first-seen order."""
    keys = []

    def walk(node):
        if isinstance(node, Delta):
            key, _ = canonical(node.points)
            if key not in keys:
                keys.append(key)
        elif isinstance(node, Not):
            walk(node.child)
        else:
            for child in node.children:
                walk(child)

    walk(tree)
    return keys


def evaluate_determinants(keys: Iterable[Sequence[Hashable]],
                          points: Mapping[Hashable, ArrayLike],
                          stack: bool = True) -> np.ndarray | list[np.ndarray]:
    """Values of the canonical determinants ``keys`` for ``points`` (label -> ``(..., d)``).

    Returns an array ``(len(keys), ...)``, or a list of arrays with ``stack=False`` (faster
    when the caller only indexes rows).
    """
    rows = [bracket(*(points[label] for label in key)) for key in keys]
    return np.stack(rows) if stack else rows


def holds(tree: Predicate, dets: Mapping[tuple[Hashable, ...], ArrayLike]) -> np.ndarray:
    """Boolean value of ``tree`` given ``dets`` (canonical key -> value array).

    Implements eq. (1) literally (``Delta`` is ``value > 0``), for checking the real-valued
    measure of :mod:`voronoi_pkg.distance` against the logic it encodes.
    """
    if isinstance(tree, Delta):
        key, sign = canonical(tree.points)
        return sign * np.asarray(dets[key]) > 0
    if isinstance(tree, Not):
        return np.logical_not(holds(tree.child, dets))
    parts = [holds(child, dets) for child in tree.children]
    op = np.logical_and if isinstance(tree, And) else np.logical_or
    out = parts[0]
    for part in parts[1:]:
        out = op(out, part)
    return out


def to_text(tree: Predicate) -> str:
    """Human-readable form, e.g. ``(D(1,2,3) | ~D(1,2,3)) & ...``."""
    if isinstance(tree, Delta):
        return 'D(' + ','.join(str(p) for p in tree.points) + ')'
    if isinstance(tree, Not):
        return '~' + to_text(tree.child)
    sep = ' & ' if isinstance(tree, And) else ' | '
    return '(' + sep.join(to_text(c) for c in tree.children) + ')'
