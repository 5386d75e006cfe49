"""Tests of quarter_car_sim.metrics.quarter_car: the metric values (weightings: test_iso2631)."""
import math

import numpy as np
import pytest

from quarter_car_sim.metrics import quarter_car as rm
from mr_damper_common.contract import CornerState


def _sine_result(f_hz, amp=1.0, duration=20.0, fs=1000.0):
    t = np.arange(int(duration * fs)) / fs
    a = amp * np.sin(2 * np.pi * f_hz * t)
    z = np.zeros_like(t)
    return {'t': t, 'a_s': a, 'travel': 0.01 * np.sin(2 * np.pi * f_hz * t),
            'tyre_force': 1000.0 + 100.0 * np.sin(2 * np.pi * f_hz * t), 'damper_force': z,
            'static_tyre_load': 1000.0, 'current_cmd': np.full(t.size, 0.5),
            'saturated': t > 15.0}


def test_metric_values_on_a_sine():
    m = rm.ride_metrics(_sine_result(5.0))
    assert m['rms_body_accel'] == pytest.approx(1 / math.sqrt(2), rel=1e-3)
    # Wk at 5 Hz = 1.039 (the first seconds hold the filter transient)
    assert m['rms_body_accel_wk'] == pytest.approx(1.039 / math.sqrt(2), rel=0.01)
    assert m['rms_suspension_travel'] == pytest.approx(0.01 / math.sqrt(2), rel=1e-3)
    assert m['rms_tyre_load_ratio'] == pytest.approx(0.1 / math.sqrt(2), rel=1e-3)
    assert m['peak_tyre_load_ratio'] == pytest.approx(0.1, rel=1e-3)
    assert m['mean_current_a'] == 0.5 and m['max_current_a'] == 0.5
    assert m['saturated_fraction'] == pytest.approx(0.25, abs=1e-3)
    assert m['contact_loss_fraction'] == 0.0
    assert set(m) == set(rm.METRIC_KEYS)


def test_running_metrics_equal_batch():
    res = _sine_result(2.3, duration=5.0)
    res['a_s'] = res['a_s'] + np.random.default_rng(0).normal(0, 0.3, res['t'].size)
    batch = rm.ride_metrics(res)
    run = rm.RunningRideMetrics(1000.0, 1000.0)
    for k in range(res['t'].size):
        s = CornerState(res['t'][k], 0, 0, res['a_s'][k], 0, 0, 0, 0, res['travel'][k], 0,
                        res['tyre_force'][k], 0.0, 0.5)
        run.update(s, 0.5, bool(res['saturated'][k]))
    d = run.as_dict()
    for key in rm.METRIC_KEYS:
        assert d[key] == pytest.approx(batch[key], rel=1e-9, abs=1e-12), key


def test_running_metrics_empty_and_no_current():
    run = rm.RunningRideMetrics(1000.0, 1000.0)
    assert run.as_dict()['n_samples'] == 0
    run.update(CornerState(0, 0, 0, 1.0, 0, 0, 0, 0, 0, 0, 1000.0, 0, math.nan))
    d = run.as_dict()
    assert math.isnan(d['mean_current_a']) and math.isnan(d['saturated_fraction'])
