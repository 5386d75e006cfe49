"""Tests of the Spencer modified Bouc-Wen model and its exact z update."""
import numpy as np
import pytest

from conftest import QUIROZ_DIR
from mr_damper_model.data import read_csv
from mr_damper_model.plant import SpencerPlant
from mr_damper_model.presets import spencer_thesis_like
from mr_damper_model.spencer import (Spencer, spencer_force, spencer_force_numpy, z_step_array,
                                     z_step_scalar)


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


def test_compiled_equals_numpy_reference_on_quiroz_record():
    d = read_csv(QUIROZ_DIR / 'quiroz_sine_2mm5Hz_0p5A.csv').select(slice(0, 120))
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
