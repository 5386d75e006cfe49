"""Closed loop on estimated states: estimation errors, injected sensor faults -> safe current."""
import numpy as np
import pytest

from semi_active_control.laws import Passive, Skyhook
from quarter_car_sim.plant.quarter_car import LinearDamperPlant
from semi_active_control.car.quarter_car import QuarterCarParams
from quarter_car_sim.plant.road import make_road
from quarter_car_sim.simulate.sensed_loop import SAFE_CURRENT_A, simulate_sensed
from semi_active_control.estimation.sensor_specs import (accelerometer_spec, Fault, G0, ideal_spec,
                                                         ride_height_spec)

C = 1500.0


class _LinearModel:
    """A linear damper as the 'identified model' (model sign: resisting extension +)."""

    def force(self, i, x, v):
        return C * v

    def current(self, f_des, x, v):
        return 0.0, 0


def _run(specs, controller=None, duration=3.0, options=None, **kw):
    p = QuarterCarParams()
    road = make_road('iso8608-C', speed_m_s=20.0, duration_s=duration, rng=2)
    return simulate_sensed(p, road, controller or Passive(0.0), LinearDamperPlant(C),
                           _LinearModel(), specs=specs, rng=4, settle_s=0.2,
                           estimator_options={'coil_tau_s': 0.0, **(options or {})}, **kw)


def test_ideal_sensors_on_the_linear_car_give_small_errors():
    specs = {'body_accel': ideal_spec(offset=G0), 'travel': ideal_spec()}
    # exact readings repeat while the car stands before the road: no stuck test here
    r = _run(specs, options={'stuck_s': 1e9})
    m = r.metrics()
    assert r.status['failsafe_steps'] == 0 and r.status['invalid_steps'] == 0
    # travel is measured; its rate and the body acceleration follow closely; the absolute
    # velocities and the tyre deflection also depend on the unknown road velocity
    assert m['est_rel_error_travel'] < 1e-6
    assert m['est_rel_error_v_rel'] < 0.01
    assert m['est_rel_error_a_s'] < 0.02
    assert m['est_rel_error_v_u'] < 0.1 and m['est_rel_error_tyre_def'] < 0.1
    assert m['est_rel_error_v_s'] < 0.25
    assert np.all(r.est['valid'])


def test_default_sensors_errors_within_the_filter_covariance():
    r = _run({'body_accel': accelerometer_spec(), 'travel': ride_height_spec()})
    err = r.est['travel'] - r.sim.travel
    # the filter's own standard deviation bounds the error: RMS within a factor 2 of it
    std = np.sqrt(np.mean(r.est['std_travel'] ** 2))
    assert np.sqrt(np.mean(err ** 2)) < 2.0 * std
    assert r.metrics()['est_rel_error_travel'] < 0.02


@pytest.mark.slow
@pytest.mark.parametrize('sensor, kind, reason', [
    ('body_accel', 'dropout', 'dropout_body_accel'),
    ('travel', 'stuck', 'stuck_travel')])
def test_injected_fault_makes_the_estimate_invalid_and_the_law_falls_back(
        sensor, kind, reason):
    fault = Fault(kind, 1.0, 1.5)
    specs = {'body_accel': accelerometer_spec(dropout_prob=0.0),
             'travel': ride_height_spec(dropout_prob=0.0)}
    specs[sensor] = specs[sensor].replace(faults=(fault,))
    r = _run(specs)
    st = r.status
    assert st['invalid_entries'] == {reason: 1}
    bad = ~r.est['valid']
    t_bad = r.sim.t[bad]
    # invalid only inside the fault window (after the detection time), valid again after it
    assert t_bad.min() > 1.0 and t_bad.max() < 1.5 + 0.01
    assert st['failsafe_steps'] == int(bad.sum()) > 100
    assert np.all(r.sim.current_cmd[bad] == SAFE_CURRENT_A)
    assert np.all(r.sim.current_cmd[~bad] == 0.0)


def test_active_law_refused():
    from semi_active_control.laws import SkyhookIdeal
    with pytest.raises(ValueError, match='damper law'):
        _run({'travel': ride_height_spec(), 'body_accel': accelerometer_spec()},
             controller=SkyhookIdeal())
    assert Skyhook().kind == 'semi-active'
