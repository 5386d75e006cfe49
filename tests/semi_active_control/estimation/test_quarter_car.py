"""Kalman filter of a corner: convergence, the DARE solution, observability, fault detection."""
import math

import numpy as np
import pytest

from quarter_car_sim.plant.quarter_car import LinearDamperPlant, QuarterCar
from semi_active_control.estimation.quarter_car import (design_estimator, EstimatorError,
                                                        QuarterCarEstimator,
                                                        road_velocity_intensity)
from semi_active_control.car.quarter_car import QuarterCarParams
from quarter_car_sim.plant.road import step as step_road
from semi_active_control.estimation.sensor_specs import accelerometer_spec, G0, ride_height_spec

C_LIN = 1500.0
DT = 1e-3


def _lin_force(i, x, v):
    return -C_LIN * v


def _specs(latency_s=0.0, wheel=False):
    out = {'body_accel': accelerometer_spec(latency_s=latency_s),
           'travel': ride_height_spec(latency_s=latency_s)}
    if wheel:
        out['wheel_accel'] = accelerometer_spec(latency_s=latency_s)
    return out


def _run_free(est, n, latency_steps=0, **init):
    """Free vibration of the linear car on a flat road, exact readings; return errors."""
    p = est.d.params
    car = QuarterCar(p, LinearDamperPlant(C_LIN), step_road(0.0, duration_s=10.0))
    s = car.set_state(damper_force=0.0, **init)
    hist = []
    errs = []
    for _ in range(n):
        hist.append({'body_accel': s.a_s + G0, 'wheel_accel': s.a_u + G0,
                     'travel': s.travel})
        rd = hist[-1 - latency_steps] if len(hist) > latency_steps else {}
        e = est.step(s.t, rd, 0.0)
        errs.append([e.travel - s.travel, e.v_s - s.v_s, e.tyre_def - (s.z_u - s.z_r),
                     e.v_u - s.v_u, e.a_s - s.a_s])
        s = car.step(DT, 0.0)
    return np.array(errs), e


@pytest.mark.parametrize('latency', [0, 2])
@pytest.mark.slow
def test_estimate_converges_to_the_truth_on_the_linear_car(latency):
    p = QuarterCarParams()
    est = QuarterCarEstimator(design_estimator(p, DT, _specs(latency * DT)), _lin_force,
                              stuck_s=1e9)      # the car comes to rest: readings repeat
    errs, e = _run_free(est, 20000, latency, z_s=0.03, v_s=0.2, z_u=0.005, v_u=-0.3)
    first = np.abs(errs[:5]).max(axis=0)
    last = np.abs(errs[-200:]).max(axis=0)
    # initial errors: 25 mm travel, 0.2 / 0.3 m/s velocities, 5 mm tyre deflection
    assert first[0] > 0.01 and first[3] > 0.1
    # the slowest filter mode (body velocity against accelerometer bias) has a time constant
    # of about 2.5 s: after 20 s the errors are below 1 % of the initial ones
    assert last[0] < 1e-5 and last[2] < 1e-5
    assert last[1] < 2e-3 and last[3] < 3e-3 and last[4] < 1e-2
    assert e.valid and e.reason == ''


@pytest.mark.slow
def test_covariance_converges_to_the_dare_solution():
    p = QuarterCarParams()
    d = design_estimator(p, DT, _specs(1e-3))
    # the DARE itself: P = A P A' - A P H' S^-1 H P A' + Q
    S = d.H @ d.P @ d.H.T + d.R
    rhs = d.Ad @ d.P @ d.Ad.T - d.Ad @ d.P @ d.H.T @ np.linalg.solve(S, d.H @ d.P @ d.Ad.T) \
        + d.Qd
    assert np.allclose(rhs, d.P, rtol=1e-8, atol=1e-12 * np.abs(d.P).max())
    assert np.allclose(d.L, d.Ad @ d.M, rtol=1e-6, atol=1e-9 * np.abs(d.L).max())
    # the runtime filter from a very different covariance ends on the DARE's posterior
    est = QuarterCarEstimator(d, _lin_force, stuck_s=1e9)
    est.P = d.P * 3.0 + np.diag(np.diag(d.P))
    for k in range(15000):
        est.step(k * DT, {'body_accel': G0, 'travel': 0.0}, 0.0)
    scale = np.sqrt(np.outer(np.diag(d.P_post), np.diag(d.P_post)))
    assert np.max(np.abs(est.P - d.P_post) / scale) < 1e-4


@pytest.mark.slow
@pytest.mark.parametrize('tol, most_steps', [(1e-6, None), (1e-3, 100)])
def test_steady_gain_resumes_after_a_lost_reading_per_steady_tol(tol, most_steps):
    """One lost reading leaves the steady gain; ``steady_tol`` says how soon it comes back."""
    d = design_estimator(QuarterCarParams(), DT, _specs(1e-3))
    est = QuarterCarEstimator(d, _lin_force, stuck_s=1e9, steady_tol=tol)
    rng = np.random.default_rng(3)
    k = 0

    def step(readings=True):
        nonlocal k
        k += 1
        return est.step(k * DT, {'body_accel': G0 + 0.05 * rng.standard_normal(),
                                 'travel': 5e-5 * rng.standard_normal()} if readings else {},
                        0.0)
    while not est.steady:
        step()
    step(readings=False)
    assert not est.steady
    back = 0
    while not est.steady and back < 20000:
        step()
        back += 1
    if most_steps is None:
        assert back > 1000              # the strict default: thousands of periods
    else:
        assert back <= most_steps
    assert est.steady and np.array_equal(est.P, d.P_post)


def test_road_intensity_matches_the_iso_class_velocity_psd():
    # one-sided velocity PSD (2 pi)^2 Gd(n0) n0^2 V for class C at 20 m/s, halved
    assert road_velocity_intensity('C', 20.0) == pytest.approx(
        0.5 * (2 * math.pi) ** 2 * 256e-6 * 0.01 * 20.0)
    with pytest.raises(EstimatorError, match='road_class'):
        road_velocity_intensity('Z')


def test_unobservable_sensor_set_raises_naming_the_state():
    p = QuarterCarParams()
    # a lasting force error (random walk) is balanced by the spring: the body accelerometer
    # alone never sees it
    with pytest.raises(EstimatorError, match='force_error'):
        design_estimator(p, DT, {'body_accel': accelerometer_spec()}, force_tau_s=math.inf)
    # without that state the body accelerometer observes the car (and its bias)
    d = design_estimator(p, DT, {'body_accel': accelerometer_spec()}, estimate_force=False)
    assert d.states[:4] == ('travel', 'v_s', 'tyre_def', 'v_u')
    with pytest.raises(EstimatorError, match='no sensors'):
        design_estimator(p, DT, {})
    with pytest.raises(EstimatorError, match='unknown sensor'):
        design_estimator(p, DT, {'gyro': accelerometer_spec()})


def test_wheel_accelerometer_adds_its_bias_state_and_lowers_the_covariance():
    p = QuarterCarParams()
    d2 = design_estimator(p, DT, _specs())
    d3 = design_estimator(p, DT, _specs(wheel=True))
    assert 'bias_wheel_accel' in d3.states
    i = d2.states.index('tyre_def')
    assert d3.P_post[i, i] < d2.P_post[i, i]


def _feed(est, n, t0, make):
    for k in range(n):
        t = t0 + k * DT
        e = est.step(t, make(k), 0.0)
    return e


def _at_rest(seed):
    """Return ``good(k)``: noisy readings of the default sensors on a car at rest."""
    rng = np.random.default_rng(seed)
    acc, pos = accelerometer_spec(), ride_height_spec()

    def good(k):
        return {'body_accel': G0 + acc.noise_std * rng.standard_normal(),
                'travel': pos.noise_std * rng.standard_normal()}
    return good


@pytest.mark.slow
def test_stuck_dropout_and_innovation_faults_are_named_and_counted():
    p = QuarterCarParams()
    est = QuarterCarEstimator(design_estimator(p, DT, _specs()), _lin_force, dropout_s=0.02)
    good = _at_rest(1)
    e = _feed(est, 500, 0.0, good)
    assert e.valid
    # dropout of the accelerometer: NaN readings bridged for 20 ms, then invalid
    e = _feed(est, 15, 0.5, lambda k: {**good(k), 'body_accel': math.nan})
    assert e.valid
    e = _feed(est, 20, 0.515, lambda k: {**good(k), 'body_accel': math.nan})
    assert not e.valid and e.reason == 'dropout_body_accel'
    e = _feed(est, 300, 0.535, good)
    assert e.valid
    # stuck position sensor (same reading 0.25 s)
    e = _feed(est, 300, 0.835, lambda k: {**good(k), 'travel': 1.234e-3})
    assert not e.valid and e.reason == 'stuck_travel'
    e = _feed(est, 500, 1.135, good)
    assert e.valid
    # accelerometer bias step of 2 m/s^2: first taken for a force error, then the travel
    # sensor disagrees and its innovation test trips (about 1.6 s here)
    e = _feed(est, 3000, 1.635, lambda k: {**good(k),
                                           'body_accel': good(k)['body_accel'] + 2.0})
    assert est.invalid_entries['innovation_travel'] >= 1
    assert est.invalid_entries['dropout_body_accel'] == 1
    assert est.invalid_entries['stuck_travel'] == 1
    assert est.samples_missing['body_accel'] == 35
    assert est.invalid_steps > 0


def test_bad_settings():
    p = QuarterCarParams()
    with pytest.raises(EstimatorError, match='dt'):
        design_estimator(p, 0.0, _specs())
    with pytest.raises(EstimatorError, match='q_force'):
        design_estimator(p, DT, _specs(), q_force=-1.0)
    d = design_estimator(p, DT, _specs())
    with pytest.raises(EstimatorError, match='coil_tau_s'):
        QuarterCarEstimator(d, _lin_force, coil_tau_s=-1.0)
    with pytest.raises(EstimatorError, match='steady_tol'):
        QuarterCarEstimator(d, _lin_force, steady_tol=0.0)


def test_single_spike_is_capped_and_travel_near_zero_gets_the_models_mean_sign():
    p = QuarterCarParams()
    seen = []

    def force(i, x, v):
        seen.append(x)
        return -C_LIN * v
    est = QuarterCarEstimator(design_estimator(p, DT, _specs()), force)
    assert est.travel_deadband_m == pytest.approx(3.0 * est._std_post[0])
    good = _at_rest(2)
    acc = accelerometer_spec()
    e = _feed(est, 600, 0.0, good)
    # a car at rest: the travel estimate is noise around 0, inside the band: the model sees 0
    assert e.valid and set(seen[-100:]) == {0.0}
    # one reading 1000 standard deviations off: capped, the 0.5 s mean stays below 3
    e = est.step(0.6, {**good(0), 'body_accel': G0 + 1000 * acc.noise_std}, 0.0)
    e = _feed(est, 50, 0.601, good)
    assert e.valid and est.invalid_entries['innovation_body_accel'] == 0
    with pytest.raises(EstimatorError, match='travel_deadband_m'):
        QuarterCarEstimator(est.d, force, travel_deadband_m=-1.0)
