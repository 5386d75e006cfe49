"""Tests of the thesis parameter sets and the thesis-like true dampers."""
import numpy as np
import pytest

from mr_damper_model.kwok import Kwok
from mr_damper_model.kwok_current import KwokCurrent
from mr_damper_model.plant import make_plant
from mr_damper_model.presets import (spencer_thesis_like, THESIS_TABLE_4_3,
                                     thesis_kwok_current)

FS = 1000.0
W = 2 * np.pi * 1.1


def _cam(periods=2.0):
    t = np.arange(int(periods / 1.1 * FS)) / FS
    return t, -0.03 * np.cos(W * t), 0.03 * W * np.sin(W * t)


def test_table_verbatim_spot_values():
    assert sorted(THESIS_TABLE_4_3) == [0.0, 0.5, 1.0, 1.5, 2.0]
    assert THESIS_TABLE_4_3[0.0]['c'] == -19.03
    assert THESIS_TABLE_4_3[1.5]['k'] == 1453.66
    assert THESIS_TABLE_4_3[2.0]['alpha'] == 658.72
    assert THESIS_TABLE_4_3[0.5]['f0'] == 36.71
    assert THESIS_TABLE_4_3[1.0]['beta'] == 5.83
    assert THESIS_TABLE_4_3[2.0]['delta'] == 0.53
    # the thesis damper force levels: Table 4.3 at the cam's peak velocity
    for current, level in ((0.0, 150.0), (2.0, 850.0)):
        t, x, v = _cam()
        f = Kwok().force(Kwok().from_dict(THESIS_TABLE_4_3[current]), x, v)
        assert np.ptp(f) / 2 == pytest.approx(level, rel=0.15)


@pytest.mark.parametrize('current,level', [(0.0, 150.0), (2.0, 850.0)])
def test_kwok_current_truth_levels(current, level):
    model, p = thesis_kwok_current()
    assert isinstance(model, KwokCurrent) and model.options['i_ref_a'] == 2.0
    t, x, v = _cam()
    f = model.force(model.from_dict(p), x, v, np.full_like(t, current))
    assert f.max() == pytest.approx(level, rel=0.15)
    assert -f.min() == pytest.approx(level, rel=0.15)


def test_kwok_current_truth_shape():
    model, p = thesis_kwok_current()
    lo, hi = model.default_bounds()
    vec = model.from_dict(p)
    assert np.all(vec >= lo) and np.all(vec <= hi)
    assert p['beta1'] != 0 and p['c1'] > 0 and p['alpha1'] + p['alpha2'] > 0
    # hysteresis: at zero velocity the force has the sign of x (delta > 0), like Fig 4.5
    f = model.force(vec, [0.03, -0.03], [0.0, 0.0], [1.0, 1.0])
    assert f[0] > 0 > f[1]


@pytest.mark.parametrize('current,level', [(0.0, 150.0), (2.0, 850.0)])
def test_spencer_thesis_like_levels(current, level):
    plant = make_plant('spencer', y0_m=0.0, initial_current_a=current)
    t, x, v = _cam(2.0)
    f = np.array([plant.step(0.0 if k == 0 else 1 / FS, x[k], v[k], current)
                  for k in range(t.size)])
    last = t >= 1 / 1.1
    assert f[last].max() == pytest.approx(level, rel=0.15)
    assert -f[last].min() == pytest.approx(level, rel=0.15)
    assert set(spencer_thesis_like()) >= {'alpha_a', 'alpha_b', 'eta'}
