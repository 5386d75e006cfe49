"""Tests of the Spencer modified Bouc-Wen model and its exact z update."""
import math

import numpy as np
import pytest

from conftest import QUIROZ_DIR
from mr_damper_model.io.data import read_csv
from mr_damper_model.models.plant import SpencerPlant
from mr_damper_model.models.presets import spencer_thesis_like
from mr_damper_model.models.spencer import (Spencer, spencer_force, spencer_force_numpy,
                                            spring_fit, z_step_array, z_step_scalar)


@pytest.mark.parametrize('beta,gamma', [(3.63e6, 3.63e6), (5e6, 2e6), (1e6, 4e6)])
def test_z_step_exact_against_fine_euler(beta, gamma):
    A = 301.0
    for z0 in (-6e-3, -1e-3, 0.0, 2e-3, 6.4e-3):
        for dr in (-4e-5, -1e-6, 3e-6, 5e-5):
            z = z0
            nsub = 5000
            h = dr / nsub
            for _ in range(nsub):
                z += A * h - gamma * abs(h) * z * abs(z) - beta * h * z * z
            exact = z_step_scalar(z0, dr, A, beta, gamma)
            assert exact == pytest.approx(z, rel=2e-3, abs=1e-8)
            arr = z_step_array(np.array([z0]), np.array([dr]), A, beta, gamma)
            assert arr[0] == pytest.approx(exact, rel=1e-10, abs=1e-15)


def _cam(T, fs=1000.0):
    t = np.arange(int(T * fs)) / fs
    w = 2 * np.pi * 1.1
    return t, -0.03 * np.cos(w * t), 0.03 * w * np.sin(w * t)


def test_grid_converged():
    """1 kHz with 0.1 ms sub-steps matches 5 us sub-steps within 0.2 % of the peak."""
    t, x, v = _cam(0.5)
    i = np.where(t < 0.25, 0.0, 2.0)
    p = Spencer().from_dict(spencer_thesis_like())
    f = Spencer(y0_m=0.0).force(p, x, v, i, t)
    # fine reference with the streaming plant (same formulae, tested equal to the batch model)
    fine = SpencerPlant(spencer_thesis_like(), max_substep_s=5e-6, y0_m=0.0)
    f_fine = np.array([fine.step(0.0 if k == 0 else t[k] - t[k - 1], x[k], v[k], i[k])
                       for k in range(t.size)])
    assert np.max(np.abs(f - f_fine)) < 2e-3 * np.max(np.abs(f_fine))


def test_current_raises_force_and_lag():
    t, x, v = _cam(0.6)
    m = Spencer(y0_m=0.0)
    p = m.from_dict(spencer_thesis_like())
    i = np.where(t < 0.3, 0.0, 2.0)
    f_step = m.force(p, x, v, i, t)
    f0 = m.force(p, x, v, np.zeros_like(t), t)
    f2 = m.force(p, x, v, np.full_like(t, 2.0), t)
    assert np.max(np.abs(f2)) > 4 * np.max(np.abs(f0))
    # first-order coil filter eta = 190 1/s: one time constant after the step the force is
    # between the two constant-current forces
    k = np.searchsorted(t, 0.3 + 1 / 190.0)
    assert min(f0[k], f2[k]) < f_step[k] < max(f0[k], f2[k])
    np.testing.assert_allclose(f_step[t < 0.3], f0[t < 0.3])


def test_validation():
    m = Spencer()
    p = m.from_dict(dict(spencer_thesis_like(), A=-1.0))
    with pytest.raises(ValueError, match='A > 0'):
        m.force(p, [0.0, 0.0], [0.0, 0.0], [0.0, 0.0], [0.0, 0.001])
    with pytest.raises(ValueError, match='n = 2'):
        Spencer(n=3)


def _swarm(p, seed):
    m = Spencer()
    lo, hi = m.default_bounds()
    P = lo + (hi - lo) * np.random.default_rng(seed).uniform(0.0, 0.3, size=(p, lo.size))
    return np.vstack([m.from_dict(spencer_thesis_like()), P])


def test_compiled_equals_numpy_reference_random_swarm():
    t, x, v = _cam(0.12)
    i = np.where(t < 0.06, 0.3, 1.7)
    P = _swarm(12, 8)
    f = spencer_force(P, x, v, i, t, y0_m=0.0)
    ref = spencer_force_numpy(P, x, v, i, t, y0_m=0.0)
    scale = np.max(np.abs(ref), axis=1, keepdims=True)
    # scalar exact z step (the plant's) against its vectorised twin: round-off only
    assert np.max(np.abs(f - ref) / scale) < 1e-11


@pytest.mark.slow
def test_compiled_equals_numpy_reference_on_quiroz_record():
    d = read_csv(QUIROZ_DIR / 'quiroz_sine_2mm5Hz_0p5A.csv.gz').select(slice(0, 120))
    P = _swarm(6, 9)
    f = Spencer().force(P, d.x, d.v, d.i, d.t)      # 200 Hz: 50 sub-steps per sample
    ref = spencer_force_numpy(P, d.x, d.v, d.i, d.t)
    scale = np.max(np.abs(ref), axis=1, keepdims=True)
    assert np.max(np.abs(f - ref) / scale) < 1e-11


def test_compiled_batch_equals_streaming_plant_bit_for_bit():
    t, x, v = _cam(0.3)
    i = np.where(t < 0.15, 0.5, 1.8)
    plant = SpencerPlant(spencer_thesis_like(), initial_current_a=0.5, y0_m=0.0)
    f_plant = np.array([plant.step(0.0 if k == 0 else t[k] - t[k - 1], x[k], v[k], i[k])
                        for k in range(t.size)])
    m = Spencer(y0_m=0.0)
    np.testing.assert_array_equal(m.force(m.from_dict(spencer_thesis_like()), x, v, i, t),
                                  f_plant)


@pytest.mark.parametrize('beta,gamma', [(3.63e6, 3.63e6), (5e6, 2e6), (1e6, 4e6), (0.0, 2e6)])
def test_z_step_scalar_tanh_addition_equals_array_reference(beta, gamma):
    """
    The scalar step (tanh addition form) against the vectorised atanh/tanh form.

    All branches: same direction, opposite (linear, tanh, tan) with and without a zero
    crossing, near saturation and beyond the tan branch's quarter period.
    """
    A = 301.0
    zs = math.sqrt(A / (beta + gamma))
    for z0 in (-0.999 * zs, -0.5 * zs, -1e-3 * zs, 0.0, 0.3 * zs, zs):
        for dr in (-1e-2, -1e-3, -4e-5, -1e-6, -1e-9, 0.0, 1e-9, 3e-6, 5e-5, 2e-3, 1e-2):
            want = z_step_array(np.array([z0]), np.array([dr]), A, beta, gamma)[0]
            got = z_step_scalar(z0, dr, A, beta, gamma)
            assert got == pytest.approx(want, rel=1e-10, abs=1e-12 * zs)


def test_compiled_equals_numpy_reference_coarse_substeps_all_branches():
    """The sub-steps the identification uses (0.5 and 1 ms), beta == gamma and beta < gamma."""
    t, x, v = _cam(0.12)
    i = np.where(t < 0.06, 0.3, 1.7)
    P = _swarm(12, 8)
    P[3, 9:11] = [2e6, 2e6]                 # beta == gamma: the linear branch
    P[4, 9:11] = [4e6, 1e6]                 # beta < gamma: the tan branch
    for sub in (5e-4, 1e-3):
        ref = spencer_force_numpy(P, x, v, i, t, y0_m=0.0, max_substep_s=sub)
        f = spencer_force(P, x, v, i, t, y0_m=0.0, max_substep_s=sub)
        assert np.max(np.abs(f - ref) / np.max(np.abs(ref), axis=1, keepdims=True)) < 1e-11


def test_identification_model_coarser_substep_same_model():
    m = Spencer(y0_m=0.01)
    fit = m.for_identification(5e-4)
    assert fit.options == {'n': 2, 'max_substep_s': 5e-4, 'y0_m': 0.01}
    assert Spencer(max_substep_s=1e-3).for_identification(5e-4).options['max_substep_s'] == 1e-3
    t, x, v = _cam(0.1)
    i = np.full(t.size, 1.0)
    P = _swarm(3, 4)
    np.testing.assert_array_equal(fit.force(P, x, v, i, t),
                                  spencer_force(P, x, v, i, t, y0_m=0.01, max_substep_s=5e-4))


def test_spring_fit_exact_without_active_bounds():
    rng = np.random.default_rng(5)
    t, x, v = _cam(0.5)
    g = rng.normal(scale=100.0, size=(4, t.size))
    k1 = np.array([300.0, 1000.0, 0.5, 4000.0])
    x0 = np.array([0.01, -0.05, 0.1, 0.0])
    noise = rng.normal(scale=2.0, size=t.size)
    f = g[0] + k1[0] * (x - x0[0]) + noise
    theta, rss = spring_fit(g[:1], x, f, (0.0, -0.2), (5000.0, 0.2))
    # unconstrained two-column least squares in (k1, k1*x0)
    sol, *_ = np.linalg.lstsq(np.column_stack([x, -np.ones_like(x)]), f - g[0], rcond=None)
    assert theta[0, 0] == pytest.approx(sol[0], rel=1e-9)
    assert theta[0, 1] == pytest.approx(sol[1] / sol[0], rel=1e-9)
    direct = np.sum((f - g[0] - theta[0, 0] * (x - theta[0, 1])) ** 2)
    assert rss[0] == pytest.approx(direct, rel=1e-9)
    assert rss[0] <= np.sum(noise ** 2)
    # noise-free batch: the spring comes back exactly
    F = g + k1[:, None] * (x[None] - x0[:, None])
    for q in range(4):
        th, r = spring_fit(g[q:q + 1], x, F[q], (0.0, -0.2), (5000.0, 0.2))
        assert th[0, 0] == pytest.approx(k1[q], rel=1e-8)
        assert abs(th[0, 1] - x0[q]) < 1e-8
        assert r[0] < 1e-12 * np.sum(F[q] ** 2)


def test_spring_fit_bounds_respected_and_rss_consistent():
    rng = np.random.default_rng(6)
    t, x, v = _cam(0.5)
    g = rng.normal(scale=50.0, size=(3, t.size))
    f = g[0] - 200.0 * x + 30.0                     # negative stiffness: k1 at 0
    f2 = g[1] + 8000.0 * (x - 0.5)                  # k1 and x0 beyond their boxes
    f3 = g[2] + 100.0 * (x + 0.9)                   # x0 beyond its box
    for gq, fq in ((g[0], f), (g[1], f2), (g[2], f3)):
        theta, rss = spring_fit(gq[None], x, fq, (0.0, -0.2), (5000.0, 0.2))
        k1, x0 = theta[0]
        assert 0.0 <= k1 <= 5000.0 and -0.2 <= x0 <= 0.2
        assert rss[0] == pytest.approx(np.sum((fq - gq - k1 * (x - x0)) ** 2), rel=1e-9)
        # no worse than the spring left out
        assert rss[0] <= np.sum((fq - gq) ** 2) * (1 + 1e-12)


def test_jacobian_state_columns_by_differences_spring_columns_exact():
    t, x, v = _cam(0.2)
    i = np.where(t < 0.1, 0.5, 1.5)
    m = Spencer(y0_m=0.0)
    p = m.from_dict(dict(spencer_thesis_like(), x0=0.004))
    J = m.jacobian(p, x, v, i, t)
    names = m.param_names
    np.testing.assert_array_equal(J[:, names.index('k1')], x - 0.004)
    np.testing.assert_array_equal(J[:, names.index('x0')], -p[names.index('k1')])
    for j, name in enumerate(names):
        if name in ('k1', 'x0'):
            continue
        h = 1e-5 * max(abs(p[j]), 1.0)
        dp = np.zeros(p.size)
        dp[j] = h
        cd = (m.force(p + dp, x, v, i, t) - m.force(p - dp, x, v, i, t)) / (2 * h)
        scale = np.max(np.abs(cd)) + 1e-12
        assert np.max(np.abs(J[:, j] - cd)) < 1e-4 * scale, name
