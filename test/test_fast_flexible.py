"""Flexible-cable error analysis (Lu et al.): the elastic catenary, and what terminal
feedback leaves of the static error a cable model's omissions cause."""
import math

import pytest

from cable_robot_pkg.fast.configuration import load_config
from cable_robot_pkg.fast.flexible_cable import axial_stiffness, elastic_catenary, errors


def test_axial_stiffness_from_diameter_and_modulus():
    assert axial_stiffness(0.006, 1e11, fill=1.0) == pytest.approx(1e11 * math.pi * 9e-6)


def test_elastic_catenary_limits():
    """A light cable is the straight elastic cable (its upper end also carries the weight);
    a heavy taut one sags like a parabola: H = w l^2 / (8 sag)."""
    span, rise, L0, EA = 20.0, 6.0, 20.5, 6e4
    chord = math.hypot(span, rise)
    T = EA * (chord - L0) / L0
    H, V = elastic_catenary(span, rise, L0, EA, 1e-3)
    assert H == pytest.approx(T * span / chord, rel=1e-3)
    assert V == pytest.approx(T * rise / chord + 1e-3 * L0, rel=1e-3)
    w, span, sag = 10.0, 30.0, 0.3
    L0 = span * (1 + 8 * sag ** 2 / (3 * span ** 2))          # parabola arc length, inextensible
    H, V = elastic_catenary(span, 0.0, L0, 1e12, w)
    assert H == pytest.approx(w * span ** 2 / (8 * sag), rel=0.02)
    assert V == pytest.approx(w * L0 / 2, rel=1e-3)


def test_terminal_feedback_removes_the_flexible_cable_error():
    """Winch lengths from rigid cables leave the trolley metres low on the field model's
    soft effective cables; sag alone leaves centimetres; the integral on the tracked pose
    removes both."""
    cfg = load_config()
    rigid = errors(cfg, model='rigid', iterations=12, ki_dt=1.0)
    assert rigid['open_loop_m'] > 1.0 and rigid['feedback_m'] < 0.02 * rigid['open_loop_m']
    exact = errors(cfg, model='elastic', iterations=2)
    assert exact['open_loop_m'] < 1e-6
    sag = errors(cfg, w=1.6, model='elastic', iterations=12, ki_dt=1.0)
    assert 0.005 < sag['open_loop_m'] < 0.2 and sag['feedback_m'] < 1e-3
