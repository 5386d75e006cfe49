"""Tests of the kwok-current-lag model with a velocity-amplitude-dependent knee."""
import math

import numpy as np
import pytest

from mr_damper_model.io.data import DamperData
from mr_damper_model.identification.identify import identify
from mr_damper_model.models.kwok_current_amp import KwokCurrentAmp, velocity_amplitude
from mr_damper_model.models.kwok_current_lag import KwokCurrentLag
from mr_damper_model.models import get_model, ModelError


def _p(kappa=40.0, tau0=0.003, tau1=0.008):
    return {'c0': 800.0, 'c1': 3000.0, 'k': 1500.0, 'alpha0': 110.0, 'alpha1': 900.0,
            'alpha2': 500.0, 'beta0': 150.0, 'beta1': -0.4, 'delta': 0.15, 'f0': 5.0,
            'tau0': tau0, 'tau1': tau1, 'kappa': kappa}


def _sine(freq_hz, amp_m, current_a, fs=1000.0, cycles=3, t0=0.0):
    """One sine test at one current: a DamperData with a zero force column."""
    n = int(round(cycles * fs / freq_hz))
    t = t0 + np.arange(n) / fs
    w = 2 * np.pi * freq_hz
    x = amp_m * np.sin(w * (t - t0))
    v = amp_m * w * np.cos(w * (t - t0))
    return DamperData(t, x, v, np.zeros(n), np.full(n, current_a), source='synthetic')


def _record():
    """Sine tests of peak velocities 0.019 to 0.094 m/s at currents 0 to 1 A, joined."""
    parts = [_sine(f, a, i) for f, a, i in ((0.5, 0.006, 0.0), (3.0, 0.005, 0.25),
                                            (1.0, 0.010, 0.5), (5.0, 0.002, 0.75),
                                            (1.5, 0.008, 1.0), (0.3, 0.010, 0.5))]
    return DamperData.concatenate(parts, restamp=True)


def _force_by_sample(q, x, v, i, t, tau_a):
    """Compute the force by its definition, sample by sample (reference implementation)."""
    out, u = [], v[0]
    for n in range(x.size):
        s = i[n]
        if n:
            a = math.exp(-(t[n] - t[n - 1]) / (q['tau0'] + q['tau1'] * s))
            u = a * u + (1 - a) * v[n]
        amp = max(abs(v[m]) * math.exp(-(t[n] - t[m]) / tau_a) for m in range(n + 1))
        c = q['c0'] + q['c1'] * s
        alpha = q['alpha0'] + q['alpha1'] * s * (2 - s) + q['alpha2'] * s * s
        beta = q['beta0'] * math.exp(q['beta1'] * s) / (1.0 + q['kappa'] * amp)
        out.append(c * v[n] + q['k'] * x[n] + q['f0']
                   + alpha * math.tanh(beta * u + q['delta'] * np.sign(x[n])))
    return np.array(out)


def test_force_equals_definition_sample_by_sample():
    n = 300
    t = np.concatenate([np.arange(150) * 1e-3, 0.149 + np.arange(1, 151) * 3e-3])  # 1 kHz, 333 Hz
    x = 0.004 * np.sin(2 * np.pi * 2.0 * t)
    v = 0.05 * np.cos(2 * np.pi * 2.0 * t) * (1.0 + 0.5 * np.sin(2 * np.pi * 0.3 * t))
    i = np.repeat([0.0, 0.4, 1.0], n // 3)
    m = KwokCurrentAmp(i_ref_a=1.0, tau_a=0.4)
    q = _p(kappa=60.0, tau0=0.002, tau1=0.004)
    f = m.force(m.from_dict(q), x, v, i=i, t=t)
    np.testing.assert_allclose(f, _force_by_sample(q, x, v, i, t, 0.4), rtol=1e-11,
                               atol=1e-9)


def test_velocity_amplitude_of_a_sine_and_its_decay():
    t = np.arange(3000) * 1e-3
    v = 0.05 * np.sin(2 * np.pi * 2.0 * t)
    # a hold much longer than the period keeps the amplitude after the first peak (0.125 s)
    amp = velocity_amplitude(v, t, 1e12)
    np.testing.assert_allclose(amp[125:], 0.05, rtol=1e-6)
    np.testing.assert_allclose(amp[:126], np.maximum.accumulate(np.abs(v[:126])), rtol=1e-12,
                               atol=1e-15)
    # one pulse, then silence on uneven sampling: exactly exp(-(t - t_pulse)/tau_a)
    t = np.concatenate([np.arange(10) * 1e-3, 9e-3 + np.arange(1, 30) * 7e-3])
    v = np.zeros(t.size)
    v[3] = -2.0
    amp = velocity_amplitude(v, t, 0.05)
    np.testing.assert_allclose(amp[3:], 2.0 * np.exp(-(t[3:] - t[3]) / 0.05), rtol=1e-12)
    assert np.all(amp[:3] < 1e-250)


def test_zero_kappa_is_kwok_current_lag():
    rec = _record()
    amp, lag = KwokCurrentAmp(), KwokCurrentLag()
    q = _p(kappa=0.0)
    p_amp, p_lag = amp.from_dict(q), lag.from_dict(q)
    args = (rec.x, rec.v)
    kw = dict(i=rec.i, t=rec.t, starts=rec.starts)
    np.testing.assert_array_equal(amp.force(p_amp, *args, **kw), lag.force(p_lag, *args, **kw))
    nl_amp = [q[n] for n in amp.nonlinear_names]
    nl_lag = [q[n] for n in lag.nonlinear_names]
    np.testing.assert_array_equal(amp.regressors(nl_amp, *args, **kw),
                                  lag.regressors(nl_lag, *args, **kw))
    assert amp.nonlinear_names == lag.nonlinear_names + ('kappa',)
    assert amp.linear_names == lag.linear_names


def test_kappa_divides_beta_by_one_plus_kappa_times_amplitude():
    # a sine of 0.094 m/s starts at its peak velocity: with a hold far longer than the test,
    # V = 0.094 m/s throughout, and kappa = 40 s/m is beta0 divided by 1 + 40*0.094
    rec = _sine(3.0, 0.005, 0.5)
    vmax = 0.005 * 2 * np.pi * 3.0
    m = KwokCurrentAmp(tau_a=1e12)
    q1 = _p(kappa=40.0)
    q0 = dict(q1, kappa=0.0, beta0=q1['beta0'] / (1.0 + 40.0 * vmax))
    kw = dict(i=rec.i, t=rec.t)
    np.testing.assert_allclose(m.force(m.from_dict(q1), rec.x, rec.v, **kw),
                               m.force(m.from_dict(q0), rec.x, rec.v, **kw), rtol=1e-12,
                               atol=1e-9)
    f_sharp = m.force(m.from_dict(dict(q1, kappa=0.0)), rec.x, rec.v, **kw)
    assert np.max(np.abs(f_sharp - m.force(m.from_dict(q1), rec.x, rec.v, **kw))) > 50.0


def test_regressors_and_separable_parts_match_force():
    rec = _record()
    m = get_model('kwok-current-amp', tau_a=2.0)
    lo, hi = m.default_bounds()
    rng = np.random.default_rng(2)
    P = lo + (hi - lo) * rng.uniform(0.05, 0.6, size=(3, lo.size))
    nl = P[:, [m.param_names.index(n) for n in m.nonlinear_names]]
    lin = P[:, [m.param_names.index(n) for n in m.linear_names]]
    kw = dict(i=rec.i, t=rec.t, starts=rec.starts)
    phi = m.regressors(nl, rec.x, rec.v, **kw)
    np.testing.assert_allclose(np.einsum('pnk,pk->pn', phi, lin),
                               m.force(P, rec.x, rec.v, **kw), rtol=1e-12, atol=1e-9)
    parts = m.separable_parts(rec.x, rec.v, **kw)
    h = m.nonlinear_factor(nl, rec.x, rec.v, **kw)
    np.testing.assert_allclose(phi[:, :, parts.factor_index], h[:, :, None] * parts.weights,
                               rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(phi[:, :, parts.fixed_index],
                               np.broadcast_to(parts.fixed, phi[:, :, parts.fixed_index].shape),
                               atol=1e-12)


def test_segments_restart_the_amplitude_and_the_lag():
    big, small = _sine(1.0, 0.010, 0.5), _sine(1.0, 0.002, 0.5)
    joined = DamperData.concatenate([big, small], restamp=True)
    m = KwokCurrentAmp(tau_a=5.0)
    p = m.from_dict(_p())
    f = m.force(p, joined.x, joined.v, i=joined.i, t=joined.t, starts=joined.starts)
    alone = np.concatenate([m.force(p, d.x, d.v, i=d.i, t=d.t) for d in (big, small)])
    np.testing.assert_allclose(f, alone, rtol=1e-12, atol=1e-9)
    # without the start the big test's amplitude is held into the small one: a softer knee
    cont = m.force(p, joined.x, joined.v, i=joined.i, t=joined.t)
    assert np.max(np.abs(cont[big.n:] - alone[big.n:])) > 20.0


def test_options_and_errors():
    m = KwokCurrentAmp(i_ref_a=1.0, tau_a=3.0)
    assert m.options == {'i_ref_a': 1.0, 'tau_a': 3.0}
    assert get_model('kwok-current-amp').options == {'i_ref_a': 2.0, 'tau_a': 5.0}
    for bad in (0.0, -1.0, float('nan')):
        with pytest.raises(ModelError, match='tau_a'):
            KwokCurrentAmp(tau_a=bad)
    rec = _sine(1.0, 0.01, 0.5, cycles=1)
    with pytest.raises(ModelError, match='time'):
        m.force(m.from_dict(_p()), rec.x, rec.v, i=rec.i)
    with pytest.raises(ModelError, match='kappa'):
        m.force(m.from_dict(_p(kappa=-1.0)), rec.x, rec.v, i=rec.i, t=rec.t)
    with pytest.raises(ModelError, match='tau_a'):
        velocity_amplitude(rec.v, rec.t, 0.0)


@pytest.mark.slow
def test_identify_recovers_known_parameters():
    rec = _record()
    m = KwokCurrentAmp(i_ref_a=1.0, tau_a=5.0)
    truth = _p()
    f = m.force(m.from_dict(truth), rec.x, rec.v, i=rec.i, t=rec.t, starts=rec.starts)
    f = f + 0.005 * np.ptp(f) * np.random.default_rng(7).standard_normal(f.size)
    data = DamperData(rec.t, rec.x, rec.v, f, rec.i, source='synthetic', starts=rec.starts)
    res = identify(data, 'kwok-current-amp', seed=3, model_options={'i_ref_a': 1.0})
    got = res.parameters
    for name, rtol in (('kappa', 0.1), ('beta0', 0.1), ('tau1', 0.1), ('delta', 0.1),
                       ('alpha1', 0.05), ('alpha2', 0.05), ('c1', 0.05)):
        assert abs(got[name] - truth[name]) <= rtol * abs(truth[name]), name
    rmse_truth = np.sqrt(np.mean((m.force(m.from_dict(truth), rec.x, rec.v, i=rec.i, t=rec.t,
                                          starts=rec.starts) - f) ** 2))
    assert res.metrics['rmse_n'] <= 1.01 * rmse_truth
