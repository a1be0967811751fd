"""Flexible-cable error analysis (Lu, Zhu, Ren: "a simple error analysis on control with
flexible cable"): how far the trolley, hence the feed, ends up from its target when the winch
lengths come from a cable model that ignores elasticity or sag, and what terminal feedback
leaves of that error.

- Axial stiffness from the rope: ``EA = E * fill * pi d^2 / 4`` (:func:`axial_stiffness`).
- Sag: Irvine's elastic catenary for a cable of unstretched length ``L0``, weight ``w`` per unit
  unstretched length, between a lower and an upper end (:func:`elastic_catenary`).
- Static equilibrium of the trolley position (level trolley, moments not balanced) under the
  cable forces and the suspended weight (:func:`equilibrium`).
- Open loop the winches set ``L0`` from a model (rigid: ``L0 = L``; elastic straight:
  ``L0 = EA L / (EA + T)``, the controller's cable IK); terminal feedback iterates the
  per-winch integral on ``L(target) - L(tracked pose)`` to its fixed point (:func:`errors`).

A suspension cable over the trolley pulley is analysed as its two spans, each with its share
of the unstretched length (the pulley's equalisation of the two tensions is not modelled).
"""
from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike

from cable_robot_pkg.fast.configuration import FastConfig, load_config


def axial_stiffness(diameter: float, modulus: float, fill: float = 0.58) -> float:
    """``E A`` (N) of a wire rope of nominal ``diameter`` (m): metallic area ``fill`` of the
    circle (0.58 for a six-strand rope)."""
    return modulus * fill * math.pi * diameter ** 2 / 4.0


def elastic_catenary(span: float, rise: float, L0: float, EA: float, w: float,
                     guess: tuple[float, float] | None = None) -> tuple[float, float]:
    """Horizontal tension ``H`` and vertical force ``V`` at the *upper* end of an elastic
    catenary (Irvine) whose upper end is ``span`` (horizontal) and ``rise`` (vertical, > 0)
    from its lower end. The lower end feels ``H`` toward the upper end horizontally and
    ``V - w L0`` upward. Newton on the two compatibility equations; ``w = 0`` is the straight
    elastic cable (tension-only: no force when slack)."""
    chord = math.hypot(span, rise)
    if w <= 0.0:
        T = max(EA * (chord - L0) / L0, 0.0)
        return T * span / chord, T * rise / chord
    W = w * L0

    def residual(x):
        H, V = math.exp(x[0]), x[1]
        a, b = V / H, (V - W) / H
        f1 = H * L0 / EA + H / w * (math.asinh(a) - math.asinh(b)) - span
        f2 = W * L0 / EA * (V / W - 0.5) + H / w * (math.hypot(1, a) - math.hypot(1, b)) - rise
        return np.array([f1, f2])

    if guess is None:
        T0 = max(EA * (chord - L0) / L0, 1e-3 * EA)
        guess = (T0 * max(span, 1e-6) / chord, T0 * rise / chord + 0.5 * W)
    x = np.array([math.log(guess[0]), guess[1]])
    for _ in range(60):
        f = residual(x)
        if np.abs(f).max() < 1e-10:
            break
        J = np.empty((2, 2))
        for j, step in enumerate((1e-7, 1e-7 * max(1.0, abs(x[1])))):
            dx = np.zeros(2)
            dx[j] = step
            J[:, j] = (residual(x + dx) - f) / step
        step = np.linalg.solve(J, f)
        step[0] = max(-1.0, min(1.0, step[0]))        # at most a factor e in H per step
        x = x - step
    return math.exp(x[0]), float(x[1])


def _segments(cfg):
    """(cable index, anchor) of every span; share of a suspension cable's length per span."""
    out = []
    for i, c in enumerate(cfg.cable_specs):
        for a in np.asarray(c.anchors, float).reshape(-1, 3):
            out.append((i, a, np.asarray(c.attach, float), len(c.anchors)))
    return out


def cable_forces(cfg: FastConfig, position: ArrayLike, L0: ArrayLike, EA: float,
                 w: float) -> np.ndarray:
    """Total cable force (3,) on a level trolley at ``position`` for unstretched lengths
    ``L0`` (n,); each span an elastic catenary (``w`` = 0: straight)."""
    total = np.zeros(3)
    position = np.asarray(position, float)
    for i, anchor, attach, spans in _segments(cfg):
        p = position + attach
        d = anchor - p
        chords = [np.linalg.norm(np.asarray(a) - p) for a in
                  np.asarray(cfg.cable_specs[i].anchors, float).reshape(-1, 3)]
        share = L0[i] * np.linalg.norm(d) / sum(chords) if spans > 1 else L0[i]
        horiz = math.hypot(d[0], d[1])
        u = d[:2] / horiz if horiz > 1e-9 else np.zeros(2)
        if d[2] >= 0:                   # anchor above: the trolley is the lower end
            H, V = elastic_catenary(horiz, d[2], share, EA, w)
            fz = V - w * share
        else:                           # anchor below (pretension): trolley is the upper end
            H, V = elastic_catenary(horiz, -d[2], share, EA, w)
            fz = -V
        total += np.array([H * u[0], H * u[1], fz])
    return total


def equilibrium(cfg: FastConfig, L0: ArrayLike, EA: float, w: float,
                start: ArrayLike) -> np.ndarray:
    """Trolley position where the cable forces carry the suspended weight (Newton)."""
    weight = np.array([0.0, 0.0, -9.81 * cfg.suspended_mass])
    x = np.asarray(start, float).copy()
    for _ in range(40):
        f = cable_forces(cfg, x, L0, EA, w) + weight
        if np.abs(f).max() < 1e-6:
            break
        J = np.empty((3, 3))
        for j in range(3):
            dx = np.zeros(3)
            dx[j] = 1e-6
            J[:, j] = (cable_forces(cfg, x + dx, L0, EA, w) + weight - f) / 1e-6
        step = np.linalg.solve(J, f)
        x = x - step * min(1.0, 0.2 / max(np.linalg.norm(step), 1e-12))
    return x


def errors(cfg: FastConfig | None = None, EA: float | None = None, w: float = 0.0,
           model: str = 'elastic', ki_dt: float = 1.0, iterations: int = 60,
           tol: float = 1e-6) -> dict[str, float | list[float]]:
    """Trolley position error (m) at the track's first target, open loop and under terminal
    feedback, for a plant with stiffness ``EA`` and cable weight ``w`` (N/m) and winch lengths
    from ``model`` (``'rigid'``: L0 = L, ``'elastic'``: the controller's cable IK). Terminal
    feedback runs ``iterations`` integral steps at most, stopping once the error is below
    ``tol`` (m)."""
    cfg = cfg or load_config()
    EA = float(cfg.raw['cables']['EA']) if EA is None else float(EA)
    feed_p, feed_R = cfg.track.pose(0.0)
    target, _, _, _ = cfg.chain.coarse_targets(feed_p, feed_R)
    lengths = cfg.cables.lengths(target, np.eye(3))
    tensions = cfg.tension_targets(target, np.eye(3))
    L0 = lengths.copy() if model == 'rigid' else EA * lengths / (EA + tensions)
    open_loop = equilibrium(cfg, L0, EA, w, target)
    x = open_loop
    for _ in range(iterations):           # terminal feedback: integral on the length error
        if np.linalg.norm(x - target) < tol:
            break
        L0 = L0 + ki_dt * (lengths - cfg.cables.lengths(x, np.eye(3)))
        x = equilibrium(cfg, L0, EA, w, x)
    return {'open_loop_m': float(np.linalg.norm(open_loop - target)),
            'feedback_m': float(np.linalg.norm(x - target)),
            'open_loop_vector_m': (open_loop - target).tolist()}


def error_table(quick: bool = False) -> list[str]:
    """Markdown rows: static trolley (= feed, the legs hold their nominal pose) error from
    ignoring elasticity or sag, open loop and with terminal feedback (``quick``: the two
    steel-rope rows only)."""
    cfg = load_config()
    EA_model = float(cfg.raw['cables']['EA'])
    rope_EA = axial_stiffness(0.006, 1.0e11)
    rope_w = 7850.0 * 9.81 * 0.58 * math.pi * 0.006 ** 2 / 4.0
    rows = ['| cable (plant) | winch lengths from | open loop mm | terminal feedback mm |',
            '|---|---|---|---|']
    for label, EA, w, model in (
            (f'effective EA {EA_model:.3g} N, no weight', EA_model, 0.0, 'rigid'),
            (f'effective EA {EA_model:.3g} N, no weight', EA_model, 0.0, 'elastic'),
            (f'effective EA {EA_model:.3g} N, rope weight {rope_w:.2f} N/m', EA_model, rope_w,
             'elastic'),
            (f'6 mm steel rope, EA {rope_EA:.3g} N, no weight', rope_EA, 0.0, 'rigid'),
            (f'6 mm steel rope, EA {rope_EA:.3g} N, {rope_w:.2f} N/m', rope_EA, rope_w,
             'elastic'))[3 if quick else 0:]:
        e = errors(cfg, EA, w, model)
        what = 'rigid cables (L0 = L)' if model == 'rigid' else 'elastic straight cable IK'
        rows.append(f"| {label} | {what} | {1000 * e['open_loop_m']:.1f} | "
                    f"{1000 * e['feedback_m']:.3f} |")
    return rows
