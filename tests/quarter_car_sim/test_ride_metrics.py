"""Tests of quarter_car_sim.ride_metrics: ISO 2631-1 Wk weighting and the metric values."""
import math

import numpy as np
import pytest
from scipy import signal

from quarter_car_sim import ride_metrics as rm
from quarter_car_sim.dynamics import CarState

# ISO 2631-1:1997 Table 3, Wk weighting factors (x 1000) at one-third-octave band centres
WK_TABLE = {0.5: 418, 1.0: 482, 2.0: 531, 4.0: 967, 5.0: 1039, 6.3: 1054, 8.0: 1036,
            10.0: 988, 12.5: 902, 16.0: 768, 20.0: 636, 31.5: 405, 50.0: 246, 80.0: 132}


def test_analog_wk_matches_standard_table():
    f = np.array(list(WK_TABLE))
    expected = np.array(list(WK_TABLE.values())) / 1000.0
    np.testing.assert_allclose(rm.wk_gain(f), expected, rtol=0.005)


@pytest.mark.parametrize('f, tol', [(1.0, 0.005), (5.0, 0.005), (8.0, 0.005), (16.0, 0.005),
                                    (31.5, 0.01), (80.0, 0.05)])
def test_digital_wk_at_1khz(f, tol):
    _, h = signal.sosfreqz(rm.wk_sos(1000.0), worN=[f], fs=1000.0)
    assert abs(h[0]) == pytest.approx(WK_TABLE[f] / 1000.0, rel=tol)


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
        s = CarState(res['t'][k], 0, 0, res['a_s'][k], 0, 0, 0, 0, res['travel'][k], 0,
                     res['tyre_force'][k], 0.0, 0.5)
        run.update(s, 0.5, bool(res['saturated'][k]))
    d = run.as_dict()
    for key in rm.METRIC_KEYS:
        assert d[key] == pytest.approx(batch[key], rel=1e-9, abs=1e-12), key


def test_running_metrics_empty_and_no_current():
    run = rm.RunningRideMetrics(1000.0, 1000.0)
    assert run.as_dict()['n_samples'] == 0
    run.update(CarState(0, 0, 0, 1.0, 0, 0, 0, 0, 0, 0, 1000.0, 0, math.nan))
    d = run.as_dict()
    assert math.isnan(d['mean_current_a']) and math.isnan(d['saturated_fraction'])


def test_wk_needs_sample_rate():
    with pytest.raises(ValueError, match='fs'):
        rm.wk_sos(100.0)
