"""Tests of the current-dependent Kwok model with a first-order fluid lag."""
import math

import numpy as np
import pytest

from mr_damper_model.io.data import DamperData
from mr_damper_model.identification.identify import identify
from mr_damper_model.models.inverse import KwokCurrentLagInverse
from mr_damper_model.models.kwok_current import KwokCurrent
from mr_damper_model.models.kwok_current_lag import first_order_lag, KwokCurrentLag
from mr_damper_model.models import get_model, ModelError


def _p(tau0=0.003, tau1=0.008):
    return {'c0': 800.0, 'c1': 3000.0, 'k': 1500.0, 'alpha0': 110.0, 'alpha1': 900.0,
            'alpha2': 500.0, 'beta0': 150.0, 'beta1': -0.4, 'delta': 0.15, 'f0': 5.0,
            'tau0': tau0, 'tau1': tau1}


def _record(n=1500, fs=500.0):
    """Two sine tests (1 Hz / 10 mm and 4 Hz / 3 mm) at currents stepping 0 -> 1 A."""
    t = np.arange(n) / fs
    half = n // 2
    w = np.where(np.arange(n) < half, 2 * np.pi * 1.0, 2 * np.pi * 4.0)
    amp = np.where(np.arange(n) < half, 0.010, 0.003)
    x = amp * np.sin(w * t)
    v = amp * w * np.cos(w * t)
    i = np.repeat([0.0, 0.25, 0.5, 0.75, 1.0], -(-n // 5))[:n]
    return t, x, v, i


def test_force_by_hand():
    m = KwokCurrentLag(i_ref_a=1.0)
    q = _p(tau0=0.002, tau1=0.004)
    t = np.array([0.0, 0.002, 0.004, 0.006])
    x = np.array([0.001, 0.002, -0.001, -0.002])
    v = np.array([0.01, 0.05, -0.02, 0.03])
    i = np.array([0.5, 0.5, 1.0, 0.0])
    u = [0.01]
    for k in range(1, 4):
        a = math.exp(-0.002 / (0.002 + 0.004 * i[k]))
        u.append(a * u[-1] + (1 - a) * v[k])
    expected = []
    for k in range(4):
        s = i[k]
        c = q['c0'] + q['c1'] * s
        alpha = q['alpha0'] + q['alpha1'] * s * (2 - s) + q['alpha2'] * s * s
        beta = q['beta0'] * math.exp(q['beta1'] * s)
        expected.append(c * v[k] + q['k'] * x[k]
                        + alpha * math.tanh(beta * u[k] + q['delta'] * math.copysign(1, x[k]))
                        + q['f0'])
    f = m.force(m.from_dict(q), x, v, i=i, t=t)
    np.testing.assert_allclose(f, expected, rtol=1e-12)


def test_step_response_is_exact_on_uneven_sampling():
    # 1 kHz then 200 Hz: a held unit step gives 1 - exp(-(t - t0)/tau) at every sample
    t = np.concatenate([np.arange(50) * 1e-3, 0.049 + np.arange(1, 40) * 5e-3])
    v = np.ones(t.size)
    v[0] = 0.0
    tau = np.array([0.01, 0.03])
    u = first_order_lag(v, t, tau)
    np.testing.assert_allclose(u, 1.0 - np.exp(-(t - t[0])[None] / tau[:, None]), atol=1e-12)


def test_zero_lag_is_kwok_current():
    t, x, v, i = _record()
    lag, kc = KwokCurrentLag(), KwokCurrent()
    q = _p(tau0=0.0, tau1=0.0)
    p_lag = lag.from_dict(q)
    p_kc = kc.from_dict(q)
    np.testing.assert_allclose(lag.force(p_lag, x, v, i=i, t=t), kc.force(p_kc, x, v, i=i),
                               rtol=1e-13, atol=1e-10)
    np.testing.assert_allclose(lag.jacobian(p_lag, x, v, i=i, t=t)[:, :10],
                               kc.jacobian(p_kc, x, v, i=i), rtol=1e-4, atol=1e-3)
    nl_lag = [q[n] for n in lag.nonlinear_names]
    nl_kc = [q[n] for n in kc.nonlinear_names]
    np.testing.assert_allclose(lag.regressors(nl_lag, x, v, i=i, t=t),
                               kc.regressors(nl_kc, x, v, i=i), rtol=1e-13, atol=1e-12)


def test_lag_changes_the_force():
    t, x, v, i = _record()
    m = KwokCurrentLag()
    f0 = m.force(m.from_dict(_p(tau0=0.0, tau1=0.0)), x, v, i=i, t=t)
    f1 = m.force(m.from_dict(_p()), x, v, i=i, t=t)
    assert np.max(np.abs(f1 - f0)) > 50.0


def test_regressors_and_separable_parts_match_force():
    t, x, v, i = _record()
    m = get_model('kwok-current-lag')
    lo, hi = m.default_bounds()
    rng = np.random.default_rng(2)
    P = lo + (hi - lo) * rng.uniform(0.05, 0.6, size=(3, lo.size))
    nl = P[:, [m.param_names.index(n) for n in m.nonlinear_names]]
    lin = P[:, [m.param_names.index(n) for n in m.linear_names]]
    phi = m.regressors(nl, x, v, i=i, t=t)
    np.testing.assert_allclose(np.einsum('pnk,pk->pn', phi, lin), m.force(P, x, v, i=i, t=t),
                               rtol=1e-12, atol=1e-9)
    parts = m.separable_parts(x, v, i=i, t=t)
    np.testing.assert_allclose(phi[:, :, parts.fixed_index],
                               np.broadcast_to(parts.fixed, phi[:, :, parts.fixed_index].shape),
                               atol=1e-12)
    h = m.nonlinear_factor(nl, x, v, i=i, t=t)
    np.testing.assert_allclose(phi[:, :, parts.factor_index], h[:, :, None] * parts.weights,
                               rtol=1e-12, atol=1e-12)


def test_errors():
    m = KwokCurrentLag()
    t, x, v, i = _record(20)
    with pytest.raises(ModelError, match='time'):
        m.force(m.from_dict(_p()), x, v, i=i)
    with pytest.raises(ModelError, match='tau'):
        m.force(m.from_dict(_p(tau0=-0.001)), x, v, i=i, t=t)
    with pytest.raises(ModelError, match='tau'):
        first_order_lag(v, t, [np.nan])


@pytest.mark.slow
def test_identify_recovers_known_parameters():
    t, x, v, i = _record(n=3000, fs=1000.0)
    m = KwokCurrentLag(i_ref_a=1.0)
    truth = _p()
    f = m.force(m.from_dict(truth), x, v, i=i, t=t)
    f = f + 0.005 * np.ptp(f) * np.random.default_rng(7).standard_normal(f.size)
    data = DamperData(t, x, v, f, i, source='synthetic')
    # identify's default for this stateful model is the polish (polish_by_default): the swarm
    # on every k-th sample, then all parameters on all samples
    res = identify(data, 'kwok-current-lag', seed=3, model_options={'i_ref_a': 1.0})
    explicit = identify(data, 'kwok-current-lag', seed=3, model_options={'i_ref_a': 1.0},
                        polish=True)
    np.testing.assert_array_equal(res.x, explicit.x)
    got = res.parameters
    for name, rtol in (('tau0', 0.1), ('tau1', 0.05), ('beta0', 0.05), ('delta', 0.1),
                       ('alpha0', 0.1), ('alpha1', 0.05), ('alpha2', 0.05), ('c1', 0.05)):
        assert abs(got[name] - truth[name]) <= rtol * abs(truth[name]), name
    # the fit is at the noise level: RMSE within 1 % of the truth's on the noisy force
    rmse_truth = np.sqrt(np.mean((m.force(m.from_dict(truth), x, v, i=i, t=t) - f) ** 2))
    assert res.metrics['rmse_n'] <= 1.01 * rmse_truth


def _lag_force_by_sample(q, x, v, i, dt):
    """Compute the model's force by its recursion, each sample with its own time constant."""
    out, u = [], v[0]
    for k in range(x.size):
        s = i[k]
        if k:
            a = math.exp(-dt / (q['tau0'] + q['tau1'] * s))
            u = a * u + (1 - a) * v[k]
        c = q['c0'] + q['c1'] * s
        alpha = q['alpha0'] + q['alpha1'] * s * (2 - s) + q['alpha2'] * s * s
        beta = q['beta0'] * math.exp(q['beta1'] * s)
        out.append(c * v[k] + q['k'] * x[k] + q['f0']
                   + alpha * math.tanh(beta * u + q['delta'] * np.sign(x[k])))
    return np.array(out), u


def test_inverse_round_trip_is_exact():
    # force -> current -> force: the currents the inverse returns make the demanded force
    # (the current itself is not unique where the lag makes F(i) rise and fall)
    n = 400
    t = np.arange(n) * 1e-3
    w = 2 * np.pi * 3.0
    x = 0.005 * np.sin(w * t)
    v = 0.005 * w * np.cos(w * t)
    i = 0.1 + 0.8 * np.mod(np.arange(n) * 0.37, 1.0)     # a jump at every sample
    m = KwokCurrentLag(i_ref_a=1.0)
    q = _p(tau0=0.003, tau1=0.008)
    f = m.force(m.from_dict(q), x, v, i=i, t=t)
    np.testing.assert_allclose(_lag_force_by_sample(q, x, v, i, 1e-3)[0], f, rtol=1e-12,
                               atol=1e-9)
    inv = KwokCurrentLagInverse(m.from_dict(q), i_ref_a=1.0, i_min=0.0, i_max=1.0)
    got = np.array([inv.step(f[k], x[k], v[k], 1e-3) for k in range(n)])
    np.testing.assert_array_equal(got[:, 1], 0)
    f_back, u_last = _lag_force_by_sample(q, x, v, got[:, 0], 1e-3)
    np.testing.assert_allclose(f_back, f, rtol=0, atol=1e-6 * np.max(np.abs(f)))
    assert abs(inv.u - u_last) <= 1e-12
    # where F(i) is monotone the current itself comes back
    assert np.mean(np.abs(got[:, 0] - i) <= 1e-6) >= 0.5


def test_inverse_saturates_and_rejects_bad_input():
    m = KwokCurrentLag(i_ref_a=1.0)
    p = m.from_dict(_p())
    inv = KwokCurrentLagInverse(p, i_ref_a=1.0, i_min=0.0, i_max=1.0)
    assert inv.step(1e6, 0.001, 0.05, 1e-3) == (1.0, 1)
    assert inv.step(-1e6, 0.001, 0.05, 1e-3) == (0.0, -1)
    with pytest.raises(ModelError, match='dt'):
        inv.step(0.0, 0.0, 0.0, 0.0)
    with pytest.raises(ModelError, match='tau'):
        KwokCurrentLagInverse(m.from_dict(_p(tau0=-1.0)))
