"""Tests of semi_active_control.car.quarter_car_linear: natural frequencies, responses, LQR."""
import math

import numpy as np
import pytest

from semi_active_control.car import quarter_car_linear as la
from semi_active_control.car.quarter_car import QuarterCarParams

P = QuarterCarParams()


def test_natural_frequencies_match_analytic_two_dof():
    body, wheel = la.natural_frequencies(P)
    b_an, w_an = la.analytic_frequencies(P)
    assert body == pytest.approx(b_an, rel=1e-9)
    assert wheel == pytest.approx(w_an, rel=1e-9)
    # and the textbook uncoupled approximations (body on series springs, wheel between both)
    k_eq = P.k_s * P.k_t / (P.k_s + P.k_t)
    assert body == pytest.approx(math.sqrt(k_eq / P.m_s) / (2 * math.pi), rel=0.01)
    assert wheel == pytest.approx(math.sqrt((P.k_s + P.k_t) / P.m_u) / (2 * math.pi), rel=0.01)
    assert 1.0 < body < 1.3 and 9.0 < wheel < 9.6


def test_transmissibility_limits():
    f = np.array([0.01, 1000.0])
    t = la.transmissibility(P, [1000.0], f)[1000.0]
    w = 2 * np.pi * f
    # very low frequency: the car follows the road (a_s = w^2 z_r, no travel, no deflection)
    assert t['a_s'][0] == pytest.approx(w[0] ** 2, rel=1e-3)
    assert t['travel'][0] < 1e-3 and t['tyre_deflection'][0] < 1e-4
    # very high frequency: body and wheel stand still, the tyre takes the road
    assert t['tyre_deflection'][1] == pytest.approx(1.0, rel=0.01)
    assert t['travel'][1] < 0.01


def test_transmissibility_peak_falls_with_damping():
    f = np.linspace(0.5, 2.0, 200)
    tr = la.transmissibility(P, [300.0, 3000.0], f)
    assert tr[300.0]['a_s'].max() > 2 * tr[3000.0]['a_s'].max()


def test_linear_model_static_gain_of_force():
    # a static force F on the body: travel F / k_s, tyre deflection 0
    sys = la.linear_model(P, 1000.0)
    g = sys.dcgain()
    assert g[1, 1] == pytest.approx(1.0 / P.k_s, rel=1e-9)
    assert abs(g[2, 1]) < 1e-12


def test_lqr_closed_loop_is_stable():
    d = la.lqr_design(P)
    assert np.all(np.real(d.poles) < 0)
    assert d.gain.shape == (4,) and np.all(np.isfinite(d.gain))
