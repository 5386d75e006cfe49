"""
ISO-weighted full-car clipped-optimal LQR: unit-gain limit, stability, the law's filters.

The run on the car (dissipative demands) is in test_full_car_lqr.py.
"""
from types import SimpleNamespace

import numpy as np
import pytest
from scipy import signal

from semi_active_control.car.full_car import PASSENGER_CAR
from semi_active_control.laws.full_car_lqr import full_car_lqr_design, relative_model
from semi_active_control.laws.full_car_lqr_wk import (full_car_lqr_wk_design,
                                                      FullCarClippedOptimalWk, weighting_filter)
from semi_active_control.iso2631 import we_sos
from semi_active_control.iso2631 import wk_sos


def test_unit_gain_filters_give_the_unweighted_design():
    # a static unit "filter" makes the weighted acceleration the plain one: the weights add up
    w = dict(q_travel=10.0, q_tyre=2e3, r_force=1e-6)
    d = full_car_lqr_wk_design(PASSENGER_CAR, weighting='none', q_wk=0.7, q_heave=0.3,
                               q_we_pitch=0.1, q_pitch=0.06, q_we_roll=0.4, q_roll=0.0, **w)
    ref = full_car_lqr_design(PASSENGER_CAR, q_heave=1.0, q_pitch=0.16, q_roll=0.4, **w)
    assert d.gain.shape == ref.gain.shape == (4, 15)
    np.testing.assert_allclose(d.gain, ref.gain, rtol=1e-6, atol=1e-6 * np.abs(ref.gain).max())
    for part in (np.real, np.imag):
        np.testing.assert_allclose(np.sort(part(d.poles)), np.sort(part(ref.poles)), rtol=1e-6,
                                   atol=1e-9)


def test_iso_design_is_stable_and_ignores_the_road_warp():
    d = full_car_lqr_wk_design(PASSENGER_CAR)
    assert d.gain.shape == (4, 15 + 20) and d.poles.size == 14 + 20
    assert np.all(d.poles.real < 0)
    _, _, _, _, n = relative_model(PASSENGER_CAR)
    warp = np.concatenate([n, n, np.zeros(7), np.zeros(20)])
    np.testing.assert_allclose(d.gain @ warp, 0.0, atol=1e-9 * np.abs(d.gain).max())
    with pytest.raises(ValueError, match='unknown LQR weight'):
        full_car_lqr_wk_design(PASSENGER_CAR, q_yaw=1.0)
    with pytest.raises(ValueError, match='weighting'):
        full_car_lqr_wk_design(PASSENGER_CAR, weighting='wk')


def test_filters_in_the_law_are_the_metric_weightings_and_feed_back_the_analog_state():
    dt, seat = 1e-3, (0.4, -0.3)
    law = FullCarClippedOptimalWk(full_car_lqr_wk_design(PASSENGER_CAR, seat=seat), dt=dt)
    rng = np.random.default_rng(4)
    nt = 3000
    t = np.arange(nt) * dt
    acc = rng.normal(size=(nt, 3)) * [1.0, 0.5, 0.8]
    seat_z = acc[:, 0] - seat[0] * acc[:, 1] + seat[1] * acc[:, 2]
    out = np.empty((nt, 3))
    for k in range(nt):
        st = SimpleNamespace(t=t[k], acc=np.concatenate([acc[k], np.zeros(4)]))
        law.step_filters(st)
        law.step_filters(st)                          # same time: not stepped again
        out[k] = law.weighted
    fs = 1.0 / dt
    ref = np.column_stack([signal.sosfilt(wk_sos(fs), seat_z),
                           signal.sosfilt(we_sos(fs), acc[:, 1]),
                           signal.sosfilt(we_sos(fs), acc[:, 2])])
    np.testing.assert_allclose(out, ref, rtol=1e-7, atol=1e-9 * np.abs(ref).max())
    assert law.rejected_samples == 0
    # a non-finite sample is counted and held: the filters stay finite
    law.step_filters(SimpleNamespace(t=t[-1] + dt, acc=np.full(7, np.nan)))
    law.step_filters(SimpleNamespace(t=t[-1] + 2 * dt, acc=np.zeros(7)))
    assert law.rejected_samples == 1 and np.all(np.isfinite(law.weighted))
    # on a smooth input the fed-back state is the analog filter's (trapezoid vs exact, dt^2)
    law.reset()
    a = np.column_stack([np.sin(2 * np.pi * 1.5 * t), 0.5 * np.sin(2 * np.pi * 0.9 * t),
                         np.cos(2 * np.pi * 2.2 * t) - 1.0])
    aw, bw, _, _ = weighting_filter('iso')
    sys = signal.StateSpace(aw, bw, np.eye(aw.shape[0]), np.zeros((aw.shape[0], 3)))
    a_seat = a.copy()                                 # the filters see the seat vertical
    a_seat[:, 0] += -seat[0] * a[:, 1] + seat[1] * a[:, 2]
    _, _, x = signal.lsim(sys, a_seat, t)
    fw = np.array([law.step_filters(SimpleNamespace(t=t[k], acc=np.r_[a[k], np.zeros(4)]))
                   for k in range(nt)])
    ref_fw = x @ law.design.gain[:, 15:].T
    np.testing.assert_allclose(fw, ref_fw, atol=1e-3 * np.abs(ref_fw).max())
