"""Full-car ISO 2631-1 metrics: We weighting, axis factors, vibration total value, VDV."""
import math

import numpy as np
import pytest
from scipy import signal

from quarter_car_sim.metrics.full_car import iso2631_seat, RunningIso2631
from quarter_car_sim.metrics.full_car import AXIS_FACTORS
from semi_active_control.iso2631 import wk_sos


@pytest.mark.parametrize('f, table', [(1.0, 0.482), (4.0, 0.967), (8.0, 1.036)])
def test_vertical_sine_weighted_by_wk_table_values(f, table):
    # ISO 2631-1 Table 3 Wk factors; digital filter at 1 kHz, steady state after 4 s
    fs, amp = 1000.0, 1.0
    t = np.arange(0, 24.0, 1 / fs)
    a = amp * np.sin(2 * math.pi * f * t)
    keep = t >= 4.0
    wk = signal.sosfilt(wk_sos(fs), a)
    steady = iso2631_seat(t[keep], a[keep], 0 * t[keep], 0 * t[keep])
    assert np.sqrt(np.mean(wk[keep] ** 2)) == pytest.approx(table * amp / math.sqrt(2),
                                                            rel=0.02)
    # the metric (filter started at rest) agrees once the start transient is diluted
    assert iso2631_seat(t, a, 0 * t, 0 * t)['a_wz'] == pytest.approx(table / math.sqrt(2),
                                                                     rel=0.03)
    assert steady['a_wz'] == pytest.approx(table / math.sqrt(2), rel=0.03)


def test_vibration_total_value_combines_axes_with_the_factors():
    fs = 1000.0
    t = np.arange(0, 20.0, 1 / fs)
    rng = np.random.default_rng(4)
    az, ap, ar = (rng.normal(0, s, t.size) for s in (0.5, 0.8, 1.1))
    m = iso2631_seat(t, az, ap, ar)
    expected = math.sqrt(m['a_wz'] ** 2 + (0.40 * m['a_w_pitch']) ** 2
                         + (0.63 * m['a_w_roll']) ** 2)
    assert m['a_v'] == pytest.approx(expected, rel=1e-12)
    assert AXIS_FACTORS == {'z': 1.0, 'roll': 0.63, 'pitch': 0.40}
    assert m['vdv_required'] is False                # Gaussian: crest factor well below 9
    # a run's body accelerations by column (heave, pitch, roll, then the wheels): the same a_v
    from quarter_car_sim.metrics.full_car import body_a_v
    acc = np.column_stack([az, ap, ar, rng.normal(0, 9.0, (t.size, 4))])
    assert body_a_v(t, acc) == m['a_v']


def test_vdv_of_a_sine_and_crest_factor_of_a_shock():
    fs = 1000.0
    t = np.arange(0, 40.0, 1 / fs)
    zero = 0 * t
    m = iso2631_seat(t, np.sin(2 * math.pi * 4.0 * t), zero, zero)
    a_w = 0.967                                    # Wk at 4 Hz (Table 3)
    # VDV of a sine of amplitude A over T: A (3 T / 8)^(1/4)
    assert m['vdv_z'] == pytest.approx(a_w * (3 * 40.0 / 8) ** 0.25, rel=0.03)
    assert m['crest_z'] == pytest.approx(math.sqrt(2), rel=0.03)
    shock = zero.copy()
    shock[20000:20020] = 30.0                      # a 20 ms pothole blow in a quiet ride
    shock += 0.01 * np.sin(2 * math.pi * 4.0 * t)
    s = iso2631_seat(t, shock, zero, zero)
    assert s['crest_z'] > 9 and s['vdv_required'] is True
    assert s['vdv_total'] == pytest.approx(s['vdv_z'], rel=1e-9)


def test_running_figures_fed_in_chunks_equal_the_figures_of_the_whole_signal():
    # the filters' state carries from chunk to chunk: any split gives the one-shot figures
    fs = 1000.0
    t = np.arange(0, 6.0, 1 / fs)
    rng = np.random.default_rng(7)
    a = np.stack([rng.normal(0, s, t.size) for s in (0.5, 0.8, 1.1)], axis=1)
    a[3000, 0] += 40.0                                 # a shock: the peak is in one chunk
    whole = iso2631_seat(t, *a.T)
    running = RunningIso2631(1 / fs)
    assert math.isnan(running.as_dict()['a_v'])        # no sample yet
    for lo, hi in [(0, 1), (1, 777), (777, 777), (777, 3001), (3001, t.size)]:
        running.add(*a[lo:hi].T)
    assert running.n == t.size
    got = running.as_dict()
    assert set(got) == set(whole)
    for key, value in whole.items():
        assert got[key] == pytest.approx(value, rel=1e-10), key
    assert got['vdv_required'] is True and whole['crest_z'] > 9


def test_running_figures_refuse_a_bad_period_and_uneven_axes():
    with pytest.raises(ValueError, match='dt'):
        RunningIso2631(0.0)
    with pytest.raises(ValueError, match='same length'):
        RunningIso2631(1e-3).add(np.zeros(3), np.zeros(3), np.zeros(2))
