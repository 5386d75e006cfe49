"""
Tests of the identification (mr_damper_model.identification.identify): recover known parameters.

Data: thesis cam excitation (1.1 Hz, 30 mm) at 1 kHz, force from the model with Gaussian noise
of 1 % of the peak force. Tolerances: a least-squares fit of n = 2000 samples with p parameters
matches the noise-free force to about sigma * sqrt(p / n) (~0.07 sigma), so the fitted force must
be within 0.25 sigma RMS of the truth; the parameters that carry the force (viscous c, hysteretic
alpha, slope beta) within 5-10 %, the ones that carry little (k x, f0) within 1 % of the peak
force, delta within 0.05.
"""
import numpy as np
import pytest

from mr_damper_model.io.data import DamperData
from mr_damper_model.identification.identify import (compare_models, current_groups,
                                                     identify, identify_per_current)
from mr_damper_model.identification.separable import _full_cost
from mr_damper_model.models import get_model
from mr_damper_model.models.presets import THESIS_TABLE_4_3, thesis_kwok_current

FREQ, AMP = 1.1, 0.03


def cam(duration=2.0, rate=1000.0, i=0.0):
    t = np.arange(int(round(duration * rate))) / rate
    w = 2 * np.pi * FREQ
    x = AMP * np.sin(w * t)
    v = AMP * w * np.cos(w * t)
    i = np.broadcast_to(np.asarray(i, dtype=float), t.shape).copy()
    return t, x, v, i


def synth(model, params, t, x, v, i, *, noise=0.01, seed=0):
    f = model.force(model.from_dict(params), x, v, i=i, t=t)
    sigma = noise * np.max(np.abs(f))
    rng = np.random.default_rng(seed)
    return DamperData(t, x, v, f + sigma * rng.standard_normal(f.size), i), f, sigma


def check_force(res, model, data, f_true, sigma):
    f_fit = model.force(res.x, data.x, data.v, i=data.i, t=data.t)
    assert np.sqrt(np.mean((f_fit - f_true) ** 2)) < 0.25 * sigma
    assert res.metrics['rmse_n'] == pytest.approx(sigma, rel=0.1)


def test_recover_kwok():
    m = get_model('kwok')
    truth = {'c': 800.0, 'k': 150.0, 'alpha': 400.0, 'beta': 25.0, 'delta': 0.4, 'f0': 6.0}
    data, f_true, sigma = synth(m, truth, *cam())
    res = identify(data, 'kwok', seed=1)
    p = res.parameters
    peak = np.max(np.abs(f_true))
    for name, rel in (('c', 0.05), ('alpha', 0.05), ('beta', 0.1)):
        assert p[name] == pytest.approx(truth[name], rel=rel)
    assert abs(p['delta'] - truth['delta']) < 0.05
    assert abs(p['k'] - truth['k']) * AMP < 0.01 * peak
    assert abs(p['f0'] - truth['f0']) < 0.01 * peak
    check_force(res, m, data, f_true, sigma)
    assert res.method == 'separable' and res.model == 'kwok' and res.seed == 1


def test_recover_kwok_current_2s_window():
    m, truth = thesis_kwok_current()
    t, x, v, _ = cam()
    i = np.repeat([0.0, 0.5, 1.0, 1.5, 2.0], t.size // 5)
    data, f_true, sigma = synth(m, truth, t, x, v, i)
    res = identify(data, 'kwok-current', seed=2)
    check_force(res, m, data, f_true, sigma)
    # the current-dependent coefficients at each level, not the collinear raw parameters
    from mr_damper_model.models.kwok_current import kwok_current_coefficients
    s = np.array([0.0, 0.25, 0.5, 0.75, 1.0])
    got = kwok_current_coefficients(res.x[None], s)
    want = kwok_current_coefficients(m.from_dict(truth)[None], s)
    for g, w_, rel in zip(got, want, (0.1, 0.05, 0.1)):     # c(i), alpha(i), beta(i)
        np.testing.assert_allclose(np.ravel(g), np.ravel(w_), rtol=rel)
    assert res.current_min_a == 0.0 and res.current_max_a == 2.0
    assert res.model_options == {'i_ref_a': 2.0}


def test_same_seed_same_answer_full_method():
    m = get_model('kwok')
    truth = {'c': 800.0, 'k': 150.0, 'alpha': 400.0, 'beta': 25.0, 'delta': 0.4, 'f0': 6.0}
    data, _, _ = synth(m, truth, *cam(duration=1.0))
    a = identify(data, 'kwok', method='full', seed=5, maxiter=40)
    b = identify(data, 'kwok', method='full', seed=5, maxiter=40)
    c = identify(data, 'kwok', method='full', seed=6, maxiter=40)
    assert np.array_equal(a.x, b.x)
    assert not np.array_equal(a.x, c.x)
    assert a.nit == 40 and not a.success and 'maxiter' in a.message


def test_recover_bingham_direct_lsq():
    m = get_model('bingham')
    truth = {'fc': 300.0, 'c0': 900.0, 'f0': -4.0}
    data, f_true, sigma = synth(m, truth, *cam())
    res = identify(data, 'bingham', seed=0)
    assert res.method == 'linear' and res.nit == 0
    for k, val in truth.items():
        assert abs(res.parameters[k] - val) < 0.02 * max(abs(val), 0.1 * np.max(np.abs(f_true)))


def test_recover_bouc_wen():
    m = get_model('bouc-wen')
    truth = {'c': 600.0, 'k': 100.0, 'alpha': 300.0, 'f0': 5.0, 'delta': 300.0, 'beta': 150.0,
             'gamma': 150.0, 'n': 1.0}
    data, f_true, sigma = synth(m, truth, *cam(duration=1.0))
    res = identify(data, 'bouc-wen', seed=3)
    # the Bouc-Wen shape parameters trade off against each other; the force must come back
    f_fit = m.force(res.x, data.x, data.v, t=data.t)
    assert np.sqrt(np.mean((f_fit - f_true) ** 2)) < 0.5 * sigma
    assert res.parameters['c'] == pytest.approx(truth['c'], rel=0.1)


def test_recover_bouc_wen_from_two_joined_records():
    """Two tests of one damper joined: one stateful fit, each test restarting from rest."""
    m = get_model('bouc-wen')
    truth = {'c': 600.0, 'k': 100.0, 'alpha': 300.0, 'f0': 5.0, 'delta': 300.0, 'beta': 150.0,
             'gamma': 150.0, 'n': 1.0}
    t, x, v, i = cam(duration=0.8)
    a, fa, sa = synth(m, truth, t, x, v, i, seed=1)
    # second test: 500 Hz, twice the frequency, half the stroke, starting at full speed
    tb = np.arange(300) / 500.0
    w = 2 * np.pi * 2 * FREQ
    xb, vb = 0.5 * AMP * np.sin(w * tb + 1.2), 0.5 * AMP * w * np.cos(w * tb + 1.2)
    b, fb, sb = synth(m, truth, tb, xb, vb, np.zeros(tb.size), seed=2)
    both = DamperData.concatenate([a, b], restamp=True)
    np.testing.assert_array_equal(both.starts, [0, a.n])
    res = identify(both, 'bouc-wen', seed=3)
    sigma = np.sqrt(np.mean(np.r_[np.full(a.n, sa), np.full(b.n, sb)] ** 2))
    for part, f_true, s in ((a, fa, sa), (b, fb, sb)):
        f_fit = m.force(res.x, part.x, part.v, t=part.t)        # each test alone
        # (fitting the joined record as one continuous test misses by about 4 sigma)
        assert np.sqrt(np.mean((f_fit - f_true) ** 2)) < 0.75 * s
    assert res.metrics['rmse_n'] == pytest.approx(sigma, rel=0.15)
    p = res.parameters
    assert p['c'] == pytest.approx(truth['c'], rel=0.1)
    # the hysteretic force amplitude alpha * z_max, z_max = (delta / (beta + gamma))**(1/n)
    zmax = (p['delta'] / (p['beta'] + p['gamma'])) ** (1 / p['n'])
    assert p['alpha'] * zmax == pytest.approx(300.0, rel=0.1)


def spencer_record(duration=2.0):
    """Thesis cam at 1 kHz, coil current in four levels, Spencer thesis-like force + 1 % noise."""
    from mr_damper_model.models.presets import spencer_thesis_like
    m = get_model('spencer')
    truth = spencer_thesis_like()
    t, x, v, _ = cam(duration=duration)
    i = np.repeat([0.0, 1.0, 2.0, 0.5], t.size // 4)
    data, f_true, sigma = synth(m, truth, t, x, v, i)
    return m, truth, data, f_true, sigma


def test_recover_spencer_default():
    """
    Default Spencer identification (swarm on the state parameters, spring by least squares).

    The Bouc-Wen part is known only up to the scale of z (alpha*s, A/s, beta*s**2, gamma*s**2
    give the same force), so the hysteretic force at saturation, alpha(i)*sqrt(A/(beta +
    gamma)), is checked instead of alpha, A, beta, gamma; k0 and k1 trade off on a 2 s record.
    """
    m, truth, data, f_true, sigma = spencer_record()
    res = identify(data, 'spencer', seed=1)
    assert res.method == 'separable'
    lo, hi = m.default_bounds()
    assert np.all(res.x >= lo) and np.all(res.x <= hi)
    check_force(res, m, data, f_true, sigma)
    p = res.parameters
    for level in (0.0, 1.0, 2.0):
        c0 = p['c0a'] + p['c0b'] * level
        assert c0 == pytest.approx(truth['c0a'] + truth['c0b'] * level, rel=0.03)

    def hysteretic(q, level):
        return (q['alpha_a'] + q['alpha_b'] * level) * np.sqrt(q['A'] / (q['beta'] + q['gamma']))
    for level in (0.0, 2.0):
        assert hysteretic(p, level) == pytest.approx(hysteretic(truth, level), rel=0.1)
    assert p['c1a'] == pytest.approx(truth['c1a'], rel=0.05)
    assert p['eta'] == pytest.approx(truth['eta'], rel=0.02)


def test_spencer_default_same_seed_same_answer():
    _, _, data, _, _ = spencer_record(duration=0.5)
    a = identify(data, 'spencer', seed=3)
    b = identify(data, 'spencer', seed=3)
    np.testing.assert_array_equal(a.x, b.x)
    assert a.nfev == b.nfev and a.nit == b.nit


@pytest.mark.slow
def test_spencer_short_record_small_budget_full_method():
    from mr_damper_model.models.presets import spencer_thesis_like
    m = get_model('spencer')
    truth = spencer_thesis_like()
    t, x, v, _ = cam(duration=0.25)
    data, f_true, sigma = synth(m, truth, t, x, v, np.full(t.size, 1.0))
    res = identify(data, 'spencer', method='full', seed=0, swarm_size=12, maxiter=12)
    assert res.method == 'full'             # the thesis method: PSO over all 13 parameters
    lo, hi = m.default_bounds()
    assert np.all(res.x >= lo) and np.all(res.x <= hi)
    # a 12-iteration swarm over 13 parameters only has to find the right force scale
    assert res.metrics['nrmse_percent'] < 15.0


@pytest.mark.parametrize('current', sorted(THESIS_TABLE_4_3))
def test_thesis_table_4_3_sets_recovered_unbounded(current):
    m = get_model('kwok')
    truth = THESIS_TABLE_4_3[current]
    data, f_true, sigma = synth(m, truth, *cam(i=current), seed=int(current * 10))
    res = identify(data, 'kwok', unbounded=True, seed=4)
    check_force(res, m, data, f_true, sigma)
    p = res.parameters
    peak = np.max(np.abs(f_true))
    # c v and alpha carry the force: within 2 % of the peak force at the peak velocity
    assert abs(p['c'] - truth['c']) * AMP * 2 * np.pi * FREQ < 0.03 * peak
    assert abs(p['alpha'] - truth['alpha']) < 0.03 * peak
    assert p['beta'] == pytest.approx(truth['beta'], rel=0.1)
    assert abs(p['delta'] - truth['delta']) < 0.05
    assert abs(p['k'] - truth['k']) * AMP < 0.02 * peak
    # the default (physical) bounds cannot reach the negative c or k of the thesis
    if truth['c'] < 0 or truth['k'] < 0:
        bounded = identify(data, 'kwok', seed=4)
        assert bounded.parameters['c'] >= 0 and bounded.parameters['k'] >= 0


def test_warm_start_dict_and_per_current_and_compare():
    m = get_model('kwok')
    truth = {'c': 800.0, 'k': 150.0, 'alpha': 400.0, 'beta': 25.0, 'delta': 0.4, 'f0': 6.0}
    t, x, v, _ = cam()
    i = np.repeat([0.0, 1.0], t.size // 2)
    data, _, sigma = synth(m, truth, t, x, v, i)
    warm = identify(data, 'kwok', seed=1, x0=truth)
    assert warm.metrics['rmse_n'] == pytest.approx(sigma, rel=0.1)
    groups = identify_per_current(data, 'kwok', seed=1)
    assert [g.current_a for g in groups] == [0.0, 1.0]
    cmp = compare_models(data, models=('bingham', 'kwok'), seed=1)
    assert list(cmp) == ['bingham', 'kwok']
    assert cmp['kwok'].metrics['rmse_n'] < cmp['bingham'].metrics['rmse_n']


def test_bad_arguments():
    t, x, v, i = cam(duration=0.2)
    data = DamperData(t, x, v, np.sin(t), i)
    with pytest.raises(ValueError, match='method'):
        identify(data, 'kwok', method='newton')
    with pytest.raises(ValueError, match='x0'):
        identify(data, 'kwok', x0=[1.0, 2.0])
    with pytest.raises(ValueError, match='unknown model'):
        identify(data, 'nope')


def test_per_current_skips_coil_transients():
    m, truth = thesis_kwok_current()
    t, x, v, _ = cam(3.0)
    i = np.where(t < 1.5, 0.5, 1.5)
    i[1500:1503] = [0.9, 1.0, 1.1]              # coil transient between the levels
    data, _, _ = synth(m, truth, t, x, v, i)
    assert [round(lv, 2) for lv, _ in current_groups(data)] == [0.5, 1.5]
    res = identify_per_current(data, 'kwok', seed=1)
    assert [round(r.current_a, 2) for r in res] == [0.5, 1.5]


@pytest.mark.parametrize('name', ['kwok', 'kwok-current', 'bingham'])
def test_full_cost_gram_form_equals_direct_rmse(name):
    mt, truth = thesis_kwok_current()
    t, x, v, _ = cam(2.0)
    data, _, _ = synth(mt, truth, t, x, v, np.linspace(0.0, 2.0, t.size))
    m = get_model(name)
    lo, hi = m.default_bounds()
    P = lo + np.random.default_rng(2).random((6, lo.size)) * (hi - lo)
    direct = np.sqrt(np.mean((m.force(P, data.x, data.v, i=data.i) - data.f) ** 2, axis=1))
    np.testing.assert_allclose(_full_cost(m, data)(P), direct, rtol=1e-9)


def test_projected_lm_matches_trf_with_an_active_bound():
    from scipy.optimize import least_squares
    from mr_damper_model.identification.separable import _projected_lm
    m, truth = thesis_kwok_current()
    t, x, v, _ = cam(2.0)
    i = np.linspace(0.0, 2.0, t.size)
    data, _, _ = synth(m, truth, t, x, v, i)
    lo, hi = m.default_bounds()
    lo, hi = lo.copy(), hi.copy()
    hi[m.param_names.index('c1')] = 500.0       # truth 850: the optimum sits on this bound
    start = np.clip(m.from_dict(truth) * 1.3, lo, hi)

    def resid(p):
        return m.force(p, data.x, data.v, i=data.i) - data.f

    def jac(p):
        return m.jacobian(p, data.x, data.v, i=data.i)
    x_lm, r_lm, _ = _projected_lm(resid, jac, start, resid(start), lo, hi)
    ref = least_squares(resid, start, jac=jac, bounds=(lo, hi), method='trf', x_scale='jac',
                        ftol=1e-12, xtol=1e-12)
    assert x_lm[m.param_names.index('c1')] == pytest.approx(500.0)
    assert r_lm @ r_lm <= (ref.fun @ ref.fun) * (1 + 1e-6)


@pytest.mark.parametrize('model_name, i', [('kwok', 0.5), ('kwok-current', None)])
def test_chunked_polish_and_solve_equal_the_whole_record(monkeypatch, model_name, i):
    """
    Memoryless models sum their normal equations chunk by chunk (bounded memory).

    The fit is the same as on the whole record up to the order of the floating-point additions:
    parameters within 1e-9 relative, RMSE within 1e-12 relative (chunks of 700 samples, not a
    divisor of the record, against one chunk).
    """
    from mr_damper_model.identification import separable as idm
    m = get_model(model_name)
    t, x, v, _ = cam(6.0)
    levels = [0.0, 0.5, 1.0, 1.5, 2.0]
    cur = np.full(t.size, i) if i is not None else np.repeat(levels, t.size // 5)
    truth = ({'c': 800.0, 'k': 150.0, 'alpha': 400.0, 'beta': 25.0, 'delta': 0.4, 'f0': 6.0}
             if model_name == 'kwok' else dict(thesis_kwok_current()[1]))
    data, _, _ = synth(m, truth, t, x, v, cur)
    whole = identify(data, model_name, seed=3)
    monkeypatch.setattr(idm, 'CHUNK_SAMPLES', 700)
    chunked = identify(data, model_name, seed=3)
    np.testing.assert_allclose(chunked.x, whole.x, rtol=1e-9, atol=1e-12)
    assert chunked.metrics['rmse_n'] == pytest.approx(whole.metrics['rmse_n'], rel=1e-12)
    assert chunked.nfev == whole.nfev
    # the Gram matrices of the final linear solve, chunk by chunk and whole
    nl = np.array([[m.from_dict(truth)[m.param_names.index(n)] for n in m.nonlinear_names]])
    G1, b1 = idm._gram_all(m, nl, data, chunk=700)
    G0, b0 = idm._gram_all(m, nl, data, chunk=10 ** 9)
    np.testing.assert_allclose(G1, G0, rtol=1e-12)
    np.testing.assert_allclose(b1, b0, rtol=1e-12)


@pytest.mark.parametrize('model_name', ['kwok-current-lag', 'kwok-current-amp'])
def test_chunked_lag_models_equal_the_whole_record(monkeypatch, model_name):
    """
    The lag models' state runs on through the chunks of a long record (bounded memory).

    Three tests at 0, 0.5 and 1 A joined (three segments: the lag and the amplitude hold
    restart at each): the chunked force equals the whole record's to rounding, the Gram
    matrices of the final linear solve agree within 1e-12, and the polish on normal equations
    summed over chunks of 1400 / 14 samples (forward differences) takes as many steps as the
    same polish on one chunk to the same sum of squares (1e-12 relative) and at least the
    truth's fit. Its parameters agree within 1e-4 relative: the joint lag / knee directions
    are nearly flat (a change of 1e-5 in kappa moves the sum of squares by less than 1e-13),
    so the order of the additions shows there.
    """
    from mr_damper_model.identification import separable as idm
    m = get_model(model_name)
    parts = []
    truth = dict(thesis_kwok_current()[1], tau0=0.004, tau1=0.006)
    if model_name == 'kwok-current-amp':
        truth['kappa'] = 20.0
    for k, level in enumerate((0.0, 0.5, 1.0)):
        t, x, v, cur = cam(1.5, i=level)
        parts.append(synth(m, truth, t, x, v, cur, seed=k)[0])
    data = DamperData.concatenate(parts, restamp=True)
    assert data.n_segments == 3
    p_true = m.from_dict(truth)
    sig = m._signals(data.x, data.v, data.i, data.t, data.starts)
    P = np.stack([p_true, p_true * 1.1])
    whole = m._eval_force(P, sig)
    chunks = list(m._eval_chunks(m._force, (P,), sig, 700))
    assert len(chunks) == 9 and [a for a, _, _ in chunks][:3] == [0, 700, 1400]
    np.testing.assert_allclose(np.concatenate([F for _, _, F in chunks], axis=1), whole,
                               rtol=0, atol=1e-12 * np.max(np.abs(whole)))
    nl = np.array([[p_true[m.param_names.index(n)] for n in m.nonlinear_names]])
    G1, b1 = idm._gram_all(m, nl, data, chunk=700)
    G0, b0 = idm._gram_all(m, nl, data, chunk=10 ** 9)      # the whole record's regressors
    np.testing.assert_allclose(G1, G0, rtol=1e-12)
    np.testing.assert_allclose(b1, b0, rtol=1e-12)
    monkeypatch.setattr(idm, 'CHUNK_SAMPLES', 1000)         # the record counts as long
    lo, hi = m.default_bounds()
    start = np.clip(p_true * 1.2, lo, hi)
    x1, n1, rss1 = idm._polish(m, data, start, lo, hi, chunk=1400)
    x0, n0, rss0 = idm._polish(m, data, start, lo, hi, chunk=10 ** 9)
    assert n1 == n0 > 3
    assert rss1 == pytest.approx(rss0, rel=1e-12)
    np.testing.assert_allclose(x1, x0, rtol=1e-4, atol=1e-12)
    r_true = m.force(p_true, data.x, data.v, i=data.i, t=data.t, starts=data.starts) - data.f
    assert rss1 <= float(r_true @ r_true) * (1 + 1e-9)
