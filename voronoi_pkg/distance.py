"""Measure of distance to forbidden regions in configuration space (section 4 of Vaca, Aranda &
Thomas, after Canny & Donald's simplified Voronoi diagrams).

A predicate tree (:mod:`voronoi_pkg.predicates`) becomes a real-valued function rho by
letting positive values stand for true: ``min`` implements AND, ``max`` implements OR and
negation implements NOT (so XOR, built from AND/OR/NOT, becomes
``max(min(a, -b), min(-a, b))``). Each ``Delta`` leaf contributes its determinant. rho is
positive where the predicate holds (free space) and negative inside forbidden regions; the
singularity factor ``Delta OR NOT Delta`` contributes ``max(D, -D) = |D|``.

Negations are pushed to the leaves first (De Morgan: ``-min(a, b) = max(-a, -b)``), so the
compiled :class:`RhoProgram` is a tree of min/max nodes over *signed leaves* ``+-[p...]``. At a
configuration, exactly one leaf value equals rho unless there is a tie: that leaf is *active*
("critical in determining the value of rho"). The simplified Voronoi diagram (section 5) is
where the active leaf changes. :meth:`RhoProgram.evaluate` returns rho and the active leaf for
many configurations at once (numpy, vectorised over the last axis).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from voronoi_pkg.predicates import And, Delta, Not, Or, Predicate, canonical, determinant_keys

__all__ = ['RhoProgram', 'compile_rho']

_REL_TIE = 1e-9


@dataclass(frozen=True)
class _Node:
    op: str          # 'min' or 'max'
    children: tuple  # of _Node or int (leaf id)


def _nnf(tree, negate, leaf_id):
    """Negation normal form: returns a _Node or a leaf id; ``leaf_id(key, sign)`` interns."""
    if isinstance(tree, Delta):
        key, sign = canonical(tree.points)
        return leaf_id(key, -sign if negate else sign)
    if isinstance(tree, Not):
        return _nnf(tree.child, not negate, leaf_id)
    if isinstance(tree, (And, Or)):
        is_min = isinstance(tree, And) != negate  # De Morgan swaps AND and OR under NOT
        op = 'min' if is_min else 'max'
        kids = []
        for child in tree.children:
            sub = _nnf(child, negate, leaf_id)
            # Flatten min(min(..)) and max(max(..)): same value, fewer passes.
            if isinstance(sub, _Node) and sub.op == op:
                kids.extend(sub.children)
            else:
                kids.append(sub)
        if len(kids) == 1:
            return kids[0]
        return _Node(op, tuple(kids))
    raise TypeError(f'not a predicate node: {tree!r}')


class RhoProgram:
    """Compiled measure rho of one predicate tree.

    Attributes:
        keys: canonical determinant keys (point-label tuples) the program reads, in the order
            of the rows of the ``dets`` array given to :meth:`evaluate`.
        leaves: list of ``(key_index, sign)``; leaf ``i`` has value ``sign * dets[key_index]``.
    """

    def __init__(self, tree: Predicate) -> None:
        self.tree = tree
        self.keys = determinant_keys(tree)
        self._key_index = {k: i for i, k in enumerate(self.keys)}
        self.leaves = []
        index = {}

        def leaf_id(key, sign):
            item = (self._key_index[key], sign)
            if item not in index:
                index[item] = len(self.leaves)
                self.leaves.append(item)
            return index[item]

        self.root = _nnf(tree, False, leaf_id)

    @property
    def n_leaves(self) -> int:
        """Number of distinct signed leaves (labels of the Voronoi regions)."""
        return len(self.leaves)

    def leaf_text(self, leaf: int) -> str:
        """Readable name of a signed leaf, e.g. ``-[p1 p2 p3]``."""
        key_index, sign = self.leaves[leaf]
        body = '[' + ' '.join(f'p{k}' for k in self.keys[key_index]) + ']'
        return ('-' if sign < 0 else '+' if sign > 0 else '0*') + body

    def _leaf_values(self, dets, cache):
        def value(leaf):
            if leaf not in cache:
                key_index, sign = self.leaves[leaf]
                row = dets[key_index]
                cache[leaf] = row if sign > 0 else (-row if sign < 0 else np.zeros_like(row))
            return cache[leaf]
        return value

    def rho(self, dets: ArrayLike) -> np.ndarray:
        """rho only (no active leaf): ``dets`` is ``(len(keys), ...)``; returns ``(...)``."""
        value = self._leaf_values(_rows(dets), {})

        def ev(node):
            if not isinstance(node, _Node):
                return value(node)
            fn = np.minimum if node.op == 'min' else np.maximum
            out = np.asarray(fn(ev(node.children[0]), ev(node.children[1])))
            for child in node.children[2:]:
                fn(out, ev(child), out=out)
            return out

        out = ev(self.root)
        return np.array(out, dtype=float, copy=True) if not isinstance(self.root, _Node) else out

    def evaluate(self, dets: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
        """rho and the active signed leaf: returns ``(rho, active)``, both shaped ``(...)``.

        Ties resolve to the first child in tree order, deterministically; values within a
        relative 1e-9 count as tied, so leaves that coincide identically (e.g. determinants of
        points on one line parallel to the platform) do not flicker with rounding noise.
        """
        dets = _rows(dets)
        value = self._leaf_values(dets, {})
        shape = np.shape(dets[0])

        def ev(node):
            if not isinstance(node, _Node):
                return value(node), np.full(shape, node, dtype=np.int32)
            best, arg = ev(node.children[0])
            best = np.array(best, copy=True)
            for child in node.children[1:]:
                val, idx = ev(child)
                gap = best - val if node.op == 'min' else val - best
                better = gap > _REL_TIE * (np.abs(best) + np.abs(val))
                np.copyto(best, val, where=better)
                np.copyto(arg, idx, where=better)
            return best, arg

        return ev(self.root)

    @property
    def n_contacts(self) -> int:
        """Number of children of the root min node: the *contacts* of the simplified Voronoi
        diagram (:mod:`voronoi_pkg.ties`)."""
        return len(self.root.children) if _is_min(self.root) else 1

    def contact_values(self, dets: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
        """Value and deciding leaf of every contact (child of the root min node).

        Returns ``(values, codes)``, each ``(n_contacts, ...)``; a code is ``2 * key_index +
        (sign > 0)`` of the signed determinant that decides the contact's value (first child
        on ties, as in :meth:`evaluate`). rho is ``values.min(axis=0)``.
        """
        dets = _rows(dets)
        value = self._leaf_values(dets, {})
        shape = np.shape(dets[0])

        def ev(node):
            if not isinstance(node, _Node):
                key_index, sign = self.leaves[node]
                return value(node), np.full(shape, 2 * key_index + (sign > 0), dtype=np.int32)
            best, arg = ev(node.children[0])
            best = np.array(best, copy=True)
            for child in node.children[1:]:
                val, idx = ev(child)
                better = val < best if node.op == 'min' else val > best
                np.copyto(best, val, where=better)
                np.copyto(arg, idx, where=better)
            return best, arg

        kids = self.root.children if _is_min(self.root) else (self.root,)
        vals, codes = zip(*(ev(k) for k in kids))
        return np.stack(vals), np.stack(codes)

    def sub_values(self, dets: ArrayLike) -> np.ndarray:
        """Values of the root's children (e.g. the AND-ed factors), ``(n_children, ...)``."""
        value = self._leaf_values(_rows(dets), {})
        kids = self.root.children if isinstance(self.root, _Node) else (self.root,)

        def ev(node):
            if not isinstance(node, _Node):
                return value(node)
            fn = np.minimum if node.op == 'min' else np.maximum
            out = fn(ev(node.children[0]), ev(node.children[1]))
            for child in node.children[2:]:
                out = fn(out, ev(child))
            return out

        return np.stack([ev(k) for k in kids])


def _is_min(node):
    return isinstance(node, _Node) and node.op == 'min'


def _rows(dets):
    """Accept an array ``(n_keys, ...)`` or a list of per-key arrays."""
    if isinstance(dets, (list, tuple)):
        return [np.asarray(d, dtype=float) for d in dets]
    return np.asarray(dets, dtype=float)


def compile_rho(tree: Predicate) -> RhoProgram:
    """Compile a predicate tree into its distance measure (section 4)."""
    return RhoProgram(tree)
