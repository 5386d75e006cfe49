"""Tests of the classic Bouc-Wen model (thesis eq. 2.30-2.31)."""
import numpy as np
import pytest
from scipy.integrate import solve_ivp

from conftest import QUIROZ_DIR
from mr_damper_model.models.bouc_wen import bouc_wen_z, bouc_wen_z_numpy, BoucWen
from mr_damper_model.io.data import read_csv


def _motion(fs=1000.0, T=1.8):
    t = np.arange(int(T * fs)) / fs
    w = 2 * np.pi * 1.1
    return t, -0.03 * np.cos(w * t), 0.03 * w * np.sin(w * t), w


@pytest.mark.slow
def test_matches_fine_reference_integration():
    m = BoucWen()
    t, x, v, w = _motion()
    p = {'c': 200.0, 'k': 50.0, 'alpha': 300.0, 'f0': 2.0, 'delta': 800.0, 'beta': 300.0,
         'gamma': 500.0, 'n': 1.5}

    def rhs(tt, z):
        vv = 0.03 * w * np.sin(w * tt)
        az = abs(z[0])
        return [p['delta'] * vv - p['beta'] * vv * az ** p['n']
                - p['gamma'] * z[0] * abs(vv) * az ** (p['n'] - 1)]

    ref = solve_ivp(rhs, (t[0], t[-1]), [0.0], t_eval=t, rtol=1e-10, atol=1e-12,
                    method='LSODA')
    f_ref = p['c'] * v + p['k'] * x + p['alpha'] * ref.y[0] + p['f0']
    f = m.force(m.from_dict(p), x, v, t=t)
    # first-order scheme on the 1 kHz grid: within 1 % of the force range
    assert np.max(np.abs(f - f_ref)) < 0.01 * np.ptp(f_ref)


def test_saturation_value_and_no_overflow():
    m = BoucWen()
    t, x, v, _ = _motion()
    lo, hi = m.default_bounds(unbounded=True)
    rng = np.random.default_rng(2)
    P = lo + (hi - lo) * rng.uniform(size=(30, lo.size))
    f = m.force(P, x, v, t=t)          # RuntimeWarnings are errors in this suite
    assert np.all(np.isfinite(f))
    # z saturates at (delta/(beta+gamma))**(1/n): alpha = 1, other linear terms 0
    p = np.array([0, 0, 1.0, 0, 1000.0, 200.0, 300.0, 2.0])
    z = m.force(p, x, v, t=t)
    np.testing.assert_allclose(np.max(np.abs(z)), np.sqrt(1000.0 / 500.0), rtol=1e-3)


def _swarm(p, unbounded, seed):
    lo, hi = BoucWen().default_bounds(unbounded=unbounded)
    nl = slice(4, 8)
    return lo[nl] + (hi[nl] - lo[nl]) * np.random.default_rng(seed).uniform(size=(p, 4))


@pytest.mark.parametrize('unbounded', [False, True])
@pytest.mark.slow
def test_compiled_equals_numpy_reference_random_swarm(unbounded):
    t, x, v, _ = _motion(T=0.7)
    N = _swarm(40, unbounded, 5)
    z = bouc_wen_z(*N.T, v, t)
    ref = bouc_wen_z_numpy(*N.T, v, t)
    scale = np.max(np.abs(ref), axis=1, keepdims=True) + 1e-300
    # |z|**n formed as |z|**(n-1) * |z|: agreement to round-off, not bit for bit
    assert np.max(np.abs(z - ref) / scale) < 1e-12
    # n = 1 takes no power at all: bit for bit
    N[:, 3] = 1.0
    np.testing.assert_array_equal(bouc_wen_z(*N.T, v, t), bouc_wen_z_numpy(*N.T, v, t))


def test_compiled_equals_numpy_reference_on_quiroz_record():
    d = read_csv(QUIROZ_DIR / 'quiroz_sine_2mm5Hz_0p5A.csv.gz')
    N = _swarm(25, False, 6)
    z = bouc_wen_z(*N.T, d.v, d.t)
    ref = bouc_wen_z_numpy(*N.T, d.v, d.t)
    scale = np.max(np.abs(ref), axis=1, keepdims=True) + 1e-300
    assert np.max(np.abs(z - ref) / scale) < 1e-12
    assert np.all(np.max(np.abs(ref), axis=1) > 0)      # the record moves z for every particle
