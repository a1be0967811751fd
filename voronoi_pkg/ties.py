"""The simplified Voronoi diagram, defined once for the planar and the 3-2-1 planners.

Section 5 of Vaca, Aranda & Thomas takes the diagram from Canny & Donald (1988): the
configuration space is covered by obstacles, each with its own (simplified, piecewise affine)
distance; the measure of distance to all of them is the minimum; the *simplified Voronoi
diagram* is the set of free configurations where that minimum is attained by two or more
obstacles. In the paper's construction the fused predicate is an AND of factors, so rho is the
minimum over the children of the root min node of the compiled tree (negation normal form,
nested ANDs flattened, :meth:`~voronoi_pkg.distance.RhoProgram.contact_values`). Those
children are the obstacles here; we call them *contacts*: one singularity factor
``max(D, -D)`` per pure-condition determinant, one basic contact per segment pair (planar) or
segment-face pair (3-2-1), one containment test per convex obstacle, and (3-2-1) the bounds
and leg-length margins.

Definition used by both planners::

    D = { q free : f_(1)(q) = f_(2)(q) }

where ``f_(1)`` is the smallest contact value and ``f_(2)`` the smallest value of a contact
decided by a *different* signed determinant (two contacts decided by the same determinant,
e.g. two boundary edges through one corner, are one feature: they are equal on a whole
region, not on a sheet). Changes of the deciding determinant *inside* one contact are not part
of ``D``: inside a max (OR) node they are valley creases of rho, inside a nested min they
belong to one obstacle's own distance, exactly as the edges of one convex C-obstacle do in
Canny & Donald.

In a planar orientation slice every contact is piecewise affine in (x, y), so ``D`` is an
arrangement of straight pieces (the paper's "straight skeleton" remark). No ROS imports.
"""
import numpy as np

__all__ = ['on_diagram', 'tie_gap', 'tie_tolerance', 'two_smallest']


def two_smallest(values: np.ndarray, codes: np.ndarray) -> tuple:
    """Smallest contact and the smallest one decided by another determinant.

    ``values``, ``codes``: ``(n_contacts, ...)`` from ``contact_values``. Returns
    ``(i1, f1, i2, f2)``, each shaped ``(...)``: indices and values; ``f2`` is ``inf`` where
    every contact is decided by the same determinant.
    """
    values = np.asarray(values, dtype=float)
    codes = np.asarray(codes)
    i1 = np.argmin(values, axis=0)
    f1 = np.take_along_axis(values, i1[None], axis=0)[0]
    c1 = np.take_along_axis(codes, i1[None], axis=0)[0]
    other = np.where(codes == c1[None], np.inf, values)
    i2 = np.argmin(other, axis=0)
    f2 = np.take_along_axis(other, i2[None], axis=0)[0]
    return i1, f1, i2, f2


def tie_gap(values: np.ndarray, codes: np.ndarray) -> np.ndarray:
    """``f_(2) - f_(1)`` (>= 0): zero exactly on the diagram (before the freeness test)."""
    _, f1, _, f2 = two_smallest(values, codes)
    return f2 - f1


def tie_tolerance(f1: np.ndarray, f2: np.ndarray, floor: float) -> np.ndarray:
    """Gap below which two contact values count as tied: ``floor`` (the model's rounding
    scale of a determinant) plus a relative 1e-9 of the values."""
    return floor + 1e-9 * (np.abs(f1) + np.abs(np.where(np.isfinite(f2), f2, 0.0)))


def on_diagram(values: np.ndarray, codes: np.ndarray, floor: float) -> np.ndarray:
    """Configurations on the simplified Voronoi diagram: free (``f_(1) > floor``) and the two
    smallest distinct contacts tied within :func:`tie_tolerance`."""
    _, f1, _, f2 = two_smallest(values, codes)
    return (f1 > floor) & (f2 - f1 <= tie_tolerance(f1, f2, floor))
