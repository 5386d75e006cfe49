"""Tests of semi_active_control.car.quarter_car."""
import pytest

from semi_active_control.car.quarter_car import ParamsError, QuarterCarParams


def test_defaults_and_derived():
    p = QuarterCarParams()
    assert (p.m_s, p.m_u, p.k_s, p.k_t) == (300.0, 60.0, 16000.0, 190000.0)
    assert p.static_tyre_load == pytest.approx(360 * 9.81)
    assert QuarterCarParams.from_dict(p.to_dict()) == p


@pytest.mark.parametrize('kw, match', [({'m_s': 0.0}, 'm_s'), ({'k_t': -1.0}, 'k_t'),
                                       ({'c_t': float('nan')}, 'c_t'), ({'i_max': 0.0}, 'i_max'),
                                       ({'m_u': 'heavy'}, 'm_u')])
def test_invalid(kw, match):
    with pytest.raises(ParamsError, match=match):
        QuarterCarParams(**kw)


def test_unknown_key():
    with pytest.raises(ParamsError, match='wheelbase'):
        QuarterCarParams.from_dict({'wheelbase': 2.7})
