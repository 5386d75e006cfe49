"""Tests of semi_active_control.iso2631: the ISO 2631-1 Wk and We weightings."""
import math

import numpy as np
import pytest
from scipy import signal

from semi_active_control import iso2631
from semi_active_control.iso2631 import we_sos, WE_CONSTANTS, weighting_sections, wk_state_space

# ISO 2631-1:1997 Table 3, Wk weighting factors (x 1000) at one-third-octave band centres
WK_TABLE = {0.5: 418, 1.0: 482, 2.0: 531, 4.0: 967, 5.0: 1039, 6.3: 1054, 8.0: 1036,
            10.0: 988, 12.5: 902, 16.0: 768, 20.0: 636, 31.5: 405, 50.0: 246, 80.0: 132}


def test_analog_wk_matches_standard_table():
    f = np.array(list(WK_TABLE))
    expected = np.array(list(WK_TABLE.values())) / 1000.0
    np.testing.assert_allclose(iso2631.wk_gain(f), expected, rtol=0.005)


@pytest.mark.parametrize('f, tol', [(1.0, 0.005), (5.0, 0.005), (8.0, 0.005), (16.0, 0.005),
                                    (31.5, 0.01), (80.0, 0.05)])
def test_digital_wk_at_1khz(f, tol):
    _, h = signal.sosfreqz(iso2631.wk_sos(1000.0), worN=[f], fs=1000.0)
    assert abs(h[0]) == pytest.approx(WK_TABLE[f] / 1000.0, rel=tol)


def test_wk_needs_sample_rate():
    with pytest.raises(ValueError, match='fs'):
        iso2631.wk_sos(100.0)


def _analog_gain(sections, f):
    w = 2 * math.pi * f
    g = 1.0
    for num, den in sections:
        g *= abs(np.polyval(num, 1j * w) / np.polyval(den, 1j * w))
    return g


def _we_by_hand(f):
    """|We| from the ISO 2631-1 Annex A formulae with f3 = f4 = 1 Hz, Q4 = 0.63."""
    s = 1j * f                                 # in units of the 1 Hz corner
    hp = 1 / math.sqrt(1 + (0.4 / f) ** 4)     # 2nd-order Butterworth at 0.4 Hz
    lp = 1 / math.sqrt(1 + (f / 100.0) ** 4)
    return hp * lp * abs((1 + s) / (1 + s / 0.63 + s * s))


def test_we_matches_the_iso8041_reference_value():
    # ISO 8041 reference: |We| = 0.06287 at 100 rad/s (15.915 Hz)
    assert _analog_gain(weighting_sections(WE_CONSTANTS), 100 / (2 * math.pi)) == \
        pytest.approx(0.06287, rel=1e-3)
    for f in (0.5, 1.0, 2.0, 4.0, 8.0):
        assert _analog_gain(weighting_sections(WE_CONSTANTS), f) == \
            pytest.approx(_we_by_hand(f), rel=1e-9)


def test_we_digital_filter_on_pitch_and_roll_sines():
    fs = 1000.0
    t = np.arange(0, 30.0, 1 / fs)
    for f in (1.0, 2.0, 5.0):
        x = np.sin(2 * math.pi * f * t)
        y = signal.sosfilt(we_sos(fs), x)[t >= 5.0]
        assert np.sqrt(np.mean(y ** 2)) == pytest.approx(_we_by_hand(f) / math.sqrt(2), rel=0.02)


def test_wk_state_space_is_the_metric_weighting():
    f = np.logspace(-1, 2.5, 60)
    resp = wk_state_space().frequency_response(2.0 * np.pi * f)
    np.testing.assert_allclose(np.abs(resp.complex).ravel(), iso2631.wk_gain(f), rtol=1e-9)
