"""Tests for mr_damper_model.identification.metrics (thesis eq. 4.1-4.3)."""
import numpy as np
import pytest

from mr_damper_model.identification.metrics import fit_metrics, METRIC_KEYS


def test_perfect_fit_is_zero():
    f = np.sin(np.linspace(0, 10, 500)) * 300
    m = fit_metrics(f, f)
    assert set(m) == set(METRIC_KEYS)
    assert all(m[k] == 0.0 for k in METRIC_KEYS)


def test_known_values():
    f_exp = np.array([100.0, -200.0, 5.0, 400.0])
    f_sim = np.array([110.0, -180.0, 50.0, 400.0])
    m = fit_metrics(f_exp, f_sim)
    err = np.array([-10.0, -20.0, -45.0, 0.0])
    assert m['mean_abs_error_n'] == pytest.approx(np.mean(np.abs(err)))
    assert m['rmse_n'] == pytest.approx(np.sqrt(np.mean(err ** 2)))
    assert m['nrmse_percent'] == pytest.approx(100 * m['rmse_n'] / 600.0)
    # 5 N is below 10 % of max |F| = 40 N, so it is left out of the percentage errors
    pct = [10.0, 10.0, 0.0]
    assert m['mean_percent_error'] == pytest.approx(np.mean(pct))
    assert m['max_percent_error'] == pytest.approx(10.0)


def test_constant_offset_rmse_equals_offset():
    f = np.linspace(-500, 500, 1001)
    m = fit_metrics(f, f + 7.0)
    assert m['rmse_n'] == pytest.approx(7.0)
    assert m['mean_abs_error_n'] == pytest.approx(7.0)


@pytest.mark.parametrize('a, b, match', [
    ([], [], 'empty'), ([1.0, 2.0], [1.0], 'differ in length'), ([1.0, np.nan], [1, 2], 'NaN'),
])
def test_bad_input(a, b, match):
    with pytest.raises(ValueError, match=match):
        fit_metrics(a, b)
