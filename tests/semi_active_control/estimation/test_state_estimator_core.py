"""Tests of semi_active_control.estimation.state_estimator_core: readings in, estimates out."""
import math

import numpy as np
import pytest

from kwok_messages import thesis_parameters_msg


def test_core_needs_a_model_then_estimates_and_counts_faults():
    from mr_damper_common.messages import identified_set_from_msg
    from semi_active_control.supervision.failsafe import ModelSupervisor
    from semi_active_control.car.quarter_car import QuarterCarParams
    from semi_active_control.estimation.sensor_specs import default_specs, G0
    from semi_active_control.estimation.state_estimator_core import StateEstimatorCore
    core = StateEstimatorCore(QuarterCarParams(), 1e-3, default_specs(), ModelSupervisor())
    rng = np.random.default_rng(0)

    def tick(k, acc=True):
        if acc:
            core.offer_reading('body_accel', G0 + 0.05 * rng.standard_normal())
        core.offer_reading('travel', 5e-5 * rng.standard_normal())
        return core.tick(k * 1e-3)
    e = tick(0)
    assert not e.valid and e.reason == 'no_model'
    core.offer_parameters(identified_set_from_msg(thesis_parameters_msg()), 0.001)
    for k in range(1, 300):
        e = tick(k)
    assert e.valid and math.isfinite(e.v_s)
    for k in range(300, 340):
        e = tick(k, acc=False)
    assert not e.valid and e.reason == 'dropout_body_accel'
    st = core.status()
    assert st['no_model_entries'] == 1 and st['no_model_steps'] == 1
    assert st['invalid_entries'] == {'dropout_body_accel': 1}
    core.offer_reading('travel', 0.0)
    core.offer_reading('travel', 0.0)
    assert core.readings_replaced['travel'] == 1
    assert core.offer_current(math.nan) is False and core.offer_current(1.5)
    assert core.current_a == 1.5
    with pytest.raises(ValueError, match='wheel_accel'):
        core.offer_reading('wheel_accel', 1.0)


def test_core_clocked_by_readings_predicts_through_missing_periods():
    """tick_at: the readings' stamps are the filter's time; gaps predicted, counted."""
    from mr_damper_common.messages import identified_set_from_msg
    from semi_active_control.supervision.failsafe import ModelSupervisor
    from semi_active_control.car.quarter_car import QuarterCarParams
    from semi_active_control.estimation.sensor_specs import default_specs, G0
    from semi_active_control.estimation.state_estimator_core import REBASE_S, StateEstimatorCore
    core = StateEstimatorCore(QuarterCarParams(), 1e-3, default_specs(), ModelSupervisor())
    core.offer_parameters(identified_set_from_msg(thesis_parameters_msg()), 0.0)
    rng = np.random.default_rng(1)
    stamps = [k * 1e-3 for k in range(400) if k % 7 != 3]      # every 7th reading lost
    for t in stamps:
        core.offer_reading('body_accel', G0 + 0.05 * rng.standard_normal())
        core.offer_reading('travel', 5e-5 * rng.standard_normal())
        e = core.tick_at(t, 0.0)
    # one filter step per control period of the vehicle's time, whatever was lost
    assert core.estimator.steps == 400
    assert core.predict_steps == 400 - len(stamps)
    assert e.valid and e.t == pytest.approx(stamps[-1])
    # a reading not after the last tick: no step, counted; the reading waits
    core.offer_reading('travel', 0.0)
    assert core.tick_at(stamps[-1], 0.0) is None and core.stale_ticks == 1
    assert core.estimator.steps == 400
    # the vehicle's clock restarted: the time line re-bases instead of 400 s of prediction
    assert core.tick_at(stamps[-1] - 2 * REBASE_S, 0.0) is not None
    assert core.rebases == 1 and core.estimator.steps == 401


def test_core_counts_readings_lost_between_stamps():
    """Readings the vehicle sent that never arrived: the periods skipped between stamps."""
    from semi_active_control.supervision.failsafe import ModelSupervisor
    from semi_active_control.car.quarter_car import QuarterCarParams
    from semi_active_control.estimation.sensor_specs import accelerometer_spec, default_specs, G0
    from semi_active_control.estimation.state_estimator_core import REBASE_S, StateEstimatorCore
    core = StateEstimatorCore(QuarterCarParams(), 1e-3, default_specs(), ModelSupervisor())
    sent = range(1000)
    lost = {k for k in sent if k % 9 == 4} | set(range(500, 530))
    for k in sent:
        if k not in lost:
            core.offer_reading('travel', 0.0, k * 1e-3)
        if k % 2:                                   # every other accelerometer reading lost
            core.offer_reading('body_accel', G0, k * 1e-3)
    # the last reading of each stream arrived, so every lost one lies between two stamps
    assert core.readings_lost['travel'] == len(lost)
    assert core.readings_received['travel'] + core.readings_lost['travel'] == len(sent)
    assert core.readings_lost['body_accel'] == 499        # 1, 3, ..., 999: 499 gaps
    # not newer (a repeat): nothing skipped; a clock restart: no loss counted
    core.offer_reading('travel', 0.0, 0.999)
    core.offer_reading('travel', 0.0, 0.999 - 2 * REBASE_S)
    core.offer_reading('travel', 0.0, 1.0 - 2 * REBASE_S)
    assert core.readings_lost['travel'] == len(lost)
    # a sensor slower than the control rate counts in its own sample period (4 ms)
    specs = dict(default_specs(), body_accel=accelerometer_spec(rate_hz=250.0))
    slow = StateEstimatorCore(QuarterCarParams(), 1e-3, specs, ModelSupervisor())
    for k in (0, 1, 2, 4):
        slow.offer_reading('body_accel', G0, k * 4e-3)
    assert slow.readings_lost['body_accel'] == 1
    assert core.status()['readings_lost'] == dict(core.readings_lost)
