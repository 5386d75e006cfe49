"""
Tests of multi-record data (segments): a joined record is the sum of its parts for every model.

Truth: each part evaluated alone. A stateful model restarts from rest at every segment start,
so on the joined record it must give, sample for sample, exactly the force of each part alone;
memoryless models must ignore the starts.
"""
import numpy as np
import pytest

from mr_damper_model.io.data import DamperData
from mr_damper_model.models import get_model, MODEL_NAMES, ModelError
from mr_damper_model.models.presets import spencer_thesis_like


def _part(n, fs, freq, amp, phase, current, t0=0.0):
    t = t0 + np.arange(n) / fs
    w = 2 * np.pi * freq
    x = amp * np.sin(w * t + phase)
    v = amp * w * np.cos(w * t + phase)
    return DamperData(t, x, v, np.zeros(n), np.full(n, current))


PARTS = [_part(300, 1000.0, 1.7, 0.02, 0.3, 0.5),
         _part(120, 200.0, 0.9, 0.03, 2.0, 1.5, t0=5.0),     # other rate, mid-stroke start
         _part(1, 1000.0, 1.0, 0.01, 1.0, 1.0)]              # a one-sample record


def _params(name):
    model = get_model(name)
    if name == 'spencer':
        p = model.from_dict(spencer_thesis_like())
        return model, np.vstack([p, p * np.r_[np.ones(12), 1.3]])
    lo, hi = model.default_bounds()
    rng = np.random.default_rng(7)
    return model, lo + (hi - lo) * rng.uniform(0.05, 0.5, size=(3, lo.size))


@pytest.mark.parametrize('restamp', [False, True])
@pytest.mark.parametrize('name', MODEL_NAMES)
def test_joined_force_equals_each_part_alone(name, restamp):
    model, P = _params(name)
    joined = DamperData.concatenate(PARTS, restamp=restamp)
    np.testing.assert_array_equal(joined.starts, [0, 300, 420])
    f = model.force(P, joined.x, joined.v, i=joined.i, t=joined.t, starts=joined.starts)
    alone = np.hstack([model.force(P, d.x, d.v, i=d.i, t=d.t) for d in PARTS])
    if model.stateful and not restamp:
        np.testing.assert_array_equal(f, alone)
    elif model.stateful:
        # restamped times give sample intervals equal to the parts' within round-off only
        np.testing.assert_allclose(f, alone, rtol=1e-12, atol=1e-9)
        # one continuous record is another thing: the state carries over the join
        cont = model.force(P, joined.x, joined.v, i=joined.i, t=joined.t)
        assert np.max(np.abs(cont[:, 300:320] - alone[:, 300:320])) > 1.0
    else:       # memoryless: starts change nothing
        np.testing.assert_allclose(f, alone, rtol=1e-13, atol=1e-9)


def test_bouc_wen_regressors_factor_and_jacobian_per_segment():
    model = get_model('bouc-wen')
    joined = DamperData.concatenate(PARTS)
    nl = np.array([[300.0, 150.0, 150.0, 1.0], [900.0, 50.0, 400.0, 2.2]])
    args = (joined.x, joined.v)
    kw = dict(t=joined.t, starts=joined.starts)
    h = model.nonlinear_factor(nl, *args, **kw)
    phi = model.regressors(nl, *args, **kw)
    np.testing.assert_array_equal(phi[:, :, 2], h)
    for (a, b), d in zip([(0, 300), (300, 420), (420, 421)], PARTS):
        np.testing.assert_array_equal(h[:, a:b], model.nonlinear_factor(nl, d.x, d.v, t=d.t))
    p = np.array([600.0, 100.0, 300.0, 5.0, 300.0, 150.0, 150.0, 1.5])
    J = model.jacobian(p, *args, **kw)
    J_alone = np.vstack([model.jacobian(p, d.x, d.v, t=d.t) for d in PARTS])
    np.testing.assert_array_equal(J, J_alone)


def test_time_may_jump_back_only_at_a_start():
    model = get_model('bouc-wen')
    p = np.array([600.0, 100.0, 300.0, 5.0, 300.0, 150.0, 150.0, 1.5])
    back = DamperData.concatenate([PARTS[1], PARTS[0]])     # t: 5.595 s -> 0 s at sample 120
    assert back.t[120] < back.t[119]
    model.force(p, back.x, back.v, t=back.t, starts=back.starts)
    with pytest.raises(ModelError, match='strictly increasing'):
        model.force(p, back.x, back.v, t=back.t)
    with pytest.raises(ModelError, match='strictly increasing'):
        model.force(p, back.x, back.v, t=back.t, starts=[0, 100])


@pytest.mark.parametrize('starts,match', [([0, 5, 5], 'strictly increasing'),
                                          ([0, 421], r'\[0, 421\)'),
                                          ([[0, 1]], '1-D'),
                                          ([0.5], '1-D')])
def test_bad_starts_rejected(starts, match):
    model = get_model('kwok')
    joined = DamperData.concatenate(PARTS)
    with pytest.raises(ModelError, match=match):
        model.force(np.ones(model.n_params), joined.x, joined.v, starts=starts)


def test_zero_is_implied():
    model = get_model('bouc-wen')
    joined = DamperData.concatenate(PARTS)
    p = np.array([600.0, 100.0, 300.0, 5.0, 300.0, 150.0, 150.0, 1.5])
    a = model.force(p, joined.x, joined.v, t=joined.t, starts=[300, 420])
    b = model.force(p, joined.x, joined.v, t=joined.t, starts=joined.starts)
    np.testing.assert_array_equal(a, b)
