"""Tension-only elastic cables of the FAST trolley and their inverse kinematics.

The trolley of the FAST field model (Lu, Zhu, Ren, Sec. I, Fig. 2) hangs from ten cables, each
fed in/out by its own winch: drive cables 1-4 and pretension cables 7-10 run straight from a
fixed pulley to a point on the trolley; suspension cables 5-6 run from a tower pulley over a
pulley on the trolley to another tower pulley, so both spans carry one tension.

Cable model (used by the simulator to produce forces and by the controller for its feedforward):

- stretched (geometric) length ``L`` = sum of the spans' lengths from the pulley exits to the
  trolley point;
- the winch sets the unstretched length ``L0``; the spring rate is ``EA / L0``, so the elastic
  tension is ``EA (L - L0) / L0``;
- viscous damping ``c (dL/dt - dL0/dt)`` on the stretch rate;
- tension is never negative: ``T = max(0, ...)``; a cable with ``L <= L0`` is *slack* (T = 0,
  damping included, a rope cannot push).

Cable inverse kinematics (trolley pose -> winch commands): the geometric lengths at the target
pose, a tension distribution that balances the suspended weight within the tension limits
(minimum-norm deviation from a mid tension, bounded least squares when that leaves the limits),
then ``L0 = EA L / (EA + T)``.
"""
from __future__ import annotations

import os
from collections.abc import Callable, Iterable
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike
from scipy.optimize import lsq_linear

from paramotion.backend import resolve_backend


@dataclass(frozen=True)
class Cable:
    """One cable: pulley exit(s) in the world, attachment (or trolley pulley) on the trolley."""

    name: str
    kind: str                 # 'drive', 'suspension' or 'pretension'
    anchors: np.ndarray       # (k, 3) world pulley exits; k = 2 for a cable over a trolley pulley
    attach: np.ndarray        # (3,) point on the trolley, trolley frame (m)


class InfeasibleTensionError(ValueError):
    """No tension distribution within the limits balances the load at this pose."""


class CableSystem:
    """Ten (or any number of) cables acting on one rigid trolley; vectorised over cables.

    ``EA`` and ``damping`` may be scalars or per-cable arrays.
    """

    def __init__(self, cables: Iterable[Cable], EA: ArrayLike, damping: ArrayLike):
        self.cables = list(cables)
        self.names = [c.name for c in self.cables]
        self.n = len(self.cables)
        self.EA = np.broadcast_to(np.asarray(EA, float), (self.n,)).copy()
        self.damping = np.broadcast_to(np.asarray(damping, float), (self.n,)).copy()
        self.attach = np.array([c.attach for c in self.cables], float)          # (n, 3)
        k = max(len(c.anchors) for c in self.cables)
        # Pad anchors to (n, k, 3) with a mask so the geometry stays vectorised.
        self.anchors = np.zeros((self.n, k, 3))
        self.anchor_mask = np.zeros((self.n, k), bool)
        for i, c in enumerate(self.cables):
            a = np.asarray(c.anchors, float).reshape(-1, 3)
            self.anchors[i, :len(a)] = a
            self.anchor_mask[i, :len(a)] = True
        self._mask3 = self.anchor_mask[..., None]

    # ----------------------------------------------------------------- geometry
    def attach_world(self, position: ArrayLike, rotation: ArrayLike) -> np.ndarray:
        """World positions (n, 3) of the trolley attachment points."""
        return np.asarray(position) + self.attach @ np.asarray(rotation).T

    def geometry(self, position: ArrayLike,
                 rotation: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
        """Stretched lengths (n,) and force directions (n, 3) for a trolley pose.

        The direction of cable i is the sum of the unit vectors from its trolley point toward
        each of its pulley exits (two for a suspension cable over a trolley pulley), so the force
        on the trolley is ``T_i * direction_i``.
        """
        p = self.attach_world(position, rotation)                              # (n, 3)
        spans = self.anchors - p[:, None, :]                                   # (n, k, 3)
        span_len = np.linalg.norm(spans, axis=2)
        span_len = np.where(self.anchor_mask, span_len, 1.0)
        units = np.where(self.anchor_mask[..., None], spans / span_len[..., None], 0.0)
        lengths = np.where(self.anchor_mask, span_len, 0.0).sum(axis=1)
        return lengths, units.sum(axis=1)

    def lengths(self, position: ArrayLike, rotation: ArrayLike) -> np.ndarray:
        """Stretched (geometric) cable lengths (n,) at a trolley pose."""
        return self.geometry(position, rotation)[0]

    def wrench_matrix(self, position: ArrayLike, rotation: ArrayLike) -> np.ndarray:
        """Structure matrix W (6, n): the wrench on the trolley (force; torque about its
        origin, world axes) is ``W @ T`` for cable tensions T."""
        _, dirs = self.geometry(position, rotation)
        r = np.asarray(self.attach) @ np.asarray(rotation).T
        return np.vstack([dirs.T, np.cross(r, dirs).T])

    def length_rates(self, position: ArrayLike, rotation: ArrayLike,
                     linear_velocity: ArrayLike, angular_velocity: ArrayLike) -> np.ndarray:
        """dL/dt (n,) from the trolley twist: minus the projection of each point's velocity on
        the cable direction (the cable shortens when the point moves toward the pulleys)."""
        kernel = compiled_kernel('cable_length_rates')
        if kernel is not None:      # the same arithmetic compiled (cable_kernel.py)
            rates = np.empty(self.n)
            kernel(self.attach @ np.asarray(rotation).T, self.anchors, self.anchor_mask,
                   np.asarray(position, float), np.asarray(linear_velocity, float),
                   np.asarray(angular_velocity, float), rates)
            return rates
        r, dirs, _ = self._attachments(position, rotation)
        v = np.asarray(linear_velocity) + _cross(angular_velocity, r)
        return -np.einsum('ij,ij->i', v, dirs)

    def _attachments(self, position: ArrayLike, rotation: ArrayLike
                     ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Attachment offsets (n, 3, world axes), force directions (n, 3) and stretched
        lengths (n,): :meth:`geometry` with the offsets kept and the masks precomputed (the
        same arithmetic, operation for operation)."""
        r = self.attach @ np.asarray(rotation).T
        spans = self.anchors - (np.asarray(position) + r)[:, None, :]           # (n, k, 3)
        span_len = np.sqrt(np.add.reduce(spans * spans, axis=2))
        span_len = np.where(self.anchor_mask, span_len, 1.0)
        dirs = np.where(self._mask3, spans / span_len[..., None], 0.0).sum(axis=1)
        lengths = np.where(self.anchor_mask, span_len, 0.0).sum(axis=1)
        return r, dirs, lengths

    # ----------------------------------------------------------------- forces
    def tensions(self, lengths: ArrayLike, length_rates: ArrayLike, unstretched: ArrayLike,
                 unstretched_rates: ArrayLike = 0.0) -> tuple[np.ndarray, np.ndarray]:
        """Cable tensions (n,) and slack mask: elastic EA (L - L0)/L0 plus damping, clipped at 0.

        A cable whose stretched length does not exceed its unstretched length is slack and
        carries no tension (its damping does not push either).
        """
        lengths = np.asarray(lengths, float)
        unstretched = np.maximum(np.asarray(unstretched, float), 1e-6)
        strain = (lengths - unstretched) / unstretched
        taut = strain > 0.0
        t = self.EA * strain + self.damping * (np.asarray(length_rates)
                                               - np.asarray(unstretched_rates))
        t = np.where(taut, np.maximum(t, 0.0), 0.0)
        return t, ~taut

    def wrench(self, position: ArrayLike, rotation: ArrayLike, linear_velocity: ArrayLike,
               angular_velocity: ArrayLike, unstretched: ArrayLike,
               unstretched_rates: ArrayLike = 0.0
               ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Total cable force and torque (about the trolley origin, world axes) on the trolley.

        Returns ``(force (3,), torque (3,), tensions (n,), lengths (n,), slack (n,))``.
        This runs every physics step, so it is :meth:`geometry`, :meth:`length_rates` and
        :meth:`tensions` fused into one pass with the attachment offsets computed once and the
        padding masks precomputed; the arithmetic is the same operation for operation, so the
        results are bit-identical to calling those methods. With numba installed the pass is
        the compiled :func:`cable_robot_pkg.fast.cable_kernel.cable_wrench` (same arithmetic
        in the same order, bit-identical; ``PARAMOTION_BACKEND=numpy`` keeps numpy).
        """
        kernel = compiled_kernel('cable_wrench')
        if kernel is not None:
            r = self.attach @ np.asarray(rotation).T
            n = self.n
            out = (np.empty(3), np.empty(3), np.empty(n), np.empty(n), np.empty(n, bool))
            kernel(r, self.anchors, self.anchor_mask, np.asarray(position, float),
                   np.asarray(linear_velocity, float), np.asarray(angular_velocity, float),
                   np.asarray(unstretched, float),
                   np.broadcast_to(np.asarray(unstretched_rates, float), (n,)),
                   self.EA, self.damping, *out)
            return out
        return self._wrench_numpy(position, rotation, linear_velocity, angular_velocity,
                                  unstretched, unstretched_rates)

    def _wrench_numpy(self, position, rotation, linear_velocity, angular_velocity, unstretched,
                      unstretched_rates):
        """:meth:`wrench` in numpy (the fallback without numba, and its reference)."""
        r, dirs, lengths = self._attachments(position, rotation)
        v = np.asarray(linear_velocity) + _cross(angular_velocity, r)
        rates = -np.einsum('ij,ij->i', v, dirs)
        t, slack = self.tensions(lengths, rates, unstretched, unstretched_rates)
        f_i = t[:, None] * dirs
        return f_i.sum(axis=0), _cross(r, f_i).sum(axis=0), t, lengths, slack

    # ----------------------------------------------------------------- inverse kinematics
    def unstretched_for(self, lengths: ArrayLike, tensions: ArrayLike) -> np.ndarray:
        """Unstretched lengths that give ``tensions`` at stretched ``lengths``:
        L0 = EA L / (EA + T) (inverse of T = EA (L - L0) / L0)."""
        return self.EA * np.asarray(lengths) / (self.EA + np.asarray(tensions))

    def tension_distribution(self, position: ArrayLike, rotation: ArrayLike,
                             load_wrench: ArrayLike, t_min: float, t_max: float,
                             t_ref: ArrayLike | None = None) -> np.ndarray:
        """Tensions T (n,) with ``W T + load_wrench = 0`` and ``t_min <= T <= t_max``.

        Minimises ``|T - t_ref|`` (default mid-range): the closed-form minimum-norm solution when
        it is inside the limits, bounded least squares otherwise. Raises
        :class:`InfeasibleTensionError` when the load cannot be balanced within the limits.
        """
        W = self.wrench_matrix(position, rotation)
        b = -np.asarray(load_wrench, float)
        t_ref = np.full(self.n, 0.5 * (t_min + t_max)) if t_ref is None else np.asarray(t_ref)
        t = t_ref + np.linalg.pinv(W) @ (b - W @ t_ref)
        if np.all(t >= t_min - 1e-9) and np.all(t <= t_max + 1e-9) \
                and np.linalg.norm(W @ t - b) < 1e-6 * max(1.0, np.linalg.norm(b)):
            return t
        # Equality rows dominate a weak pull toward t_ref, within the box; then a minimum-norm
        # projection removes the remaining equality residual.
        pull = 1e-4
        A = np.vstack([W, pull * np.eye(self.n)])
        rhs = np.concatenate([b, pull * t_ref])
        t = bounded_least_squares(A, rhs, t_min, t_max)
        # Cables strictly inside their limits absorb the residual (those on a bound stay).
        free = (t > t_min + 1e-9) & (t < t_max - 1e-9)
        if free.any():
            t[free] += np.linalg.pinv(W[:, free]) @ (b - W @ t)
        if np.linalg.norm(W @ t - b) > 1e-6 * max(1.0, np.linalg.norm(b)):
            raise InfeasibleTensionError(
                f'no cable tensions in [{t_min:g}, {t_max:g}] N balance the load at '
                f'position {np.round(position, 3).tolist()} (residual '
                f'{np.linalg.norm(W @ t - b):.1f} N)')
        slack = 1e-6 * (t_max - t_min)
        if np.any(t < t_min - slack) or np.any(t > t_max + slack):
            residual = np.linalg.norm(W @ np.clip(t, t_min, t_max) - b)
            raise InfeasibleTensionError(
                f'no cable tensions in [{t_min:g}, {t_max:g}] N balance the load at '
                f'position {np.round(position, 3).tolist()} (residual {residual:.1f} N)')
        return np.clip(t, t_min, t_max)

    def inverse_kinematics(self, position: ArrayLike, rotation: ArrayLike,
                           load_wrench: ArrayLike, t_min: float, t_max: float
                           ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Trolley pose -> (unstretched lengths L0 (n,), stretched lengths L (n,), tensions)."""
        t = self.tension_distribution(position, rotation, load_wrench, t_min, t_max)
        lengths = self.lengths(position, rotation)
        return self.unstretched_for(lengths, t), lengths, t


#: Compiled kernel name -> (PARAMOTION_BACKEND value, kernel or None), see compiled_kernel.
_KERNELS: dict = {}


def compiled_kernel(name: str) -> Callable | None:
    """The numba kernel ``name`` of :mod:`cable_robot_pkg.fast.cable_kernel`, or None for
    numpy (resolved again when ``PARAMOTION_BACKEND`` changes)."""
    env = os.environ.get('PARAMOTION_BACKEND')
    hit = _KERNELS.get(name)
    if hit is None or hit[0] != env:
        kernel = None
        if resolve_backend() == 'numba':
            from cable_robot_pkg.fast import cable_kernel
            kernel = getattr(cable_kernel, name)
        hit = _KERNELS[name] = (env, kernel)
    return hit[1]


def bounded_least_squares(A: np.ndarray, b: np.ndarray, lower: float,
                          upper: float) -> np.ndarray:
    """``x`` minimising ``|A x - b|`` with ``lower <= x <= upper``: scipy's ``lsq_linear``
    with ``method='bvls'``. It stays scipy's: a numba port saves about 0.02 CPU s per sim s
    in the cable controller but takes 20-30 s to compile in every FAST process, each of which
    checks its config's tension plans while it starts (docs/performance.md)."""
    return lsq_linear(A, b, bounds=(lower, upper), method='bvls').x


def _cross(a, b):
    """Cross product of (..., 3) arrays without np.cross's call overhead (same arithmetic)."""
    a = np.asarray(a, float)
    b = np.asarray(b, float)
    out = np.empty(np.broadcast_shapes(a.shape, b.shape))
    a0, a1, a2 = a[..., 0], a[..., 1], a[..., 2]
    b0, b1, b2 = b[..., 0], b[..., 1], b[..., 2]
    out[..., 0] = a1 * b2 - a2 * b1
    out[..., 1] = a2 * b0 - a0 * b2
    out[..., 2] = a0 * b1 - a1 * b0
    return out


def gravity_wrench(mass: float, com_world_offset: ArrayLike,
                   gravity: float = 9.81) -> np.ndarray:
    """Weight of the suspended mass as a wrench about the trolley origin (world axes)."""
    f = np.array([0.0, 0.0, -mass * gravity])
    return np.concatenate([f, np.cross(np.asarray(com_world_offset, float), f)])
