"""Tests of the excitations (analytic derivative) and current schedules."""
import numpy as np
import pytest

from mr_damper_rig.excitation import (BandLimitedRandom, CamSine, Chirp, CommandedSchedule,
                                      ConstantSchedule, make_excitation, Multisine,
                                      StepSchedule)


@pytest.mark.parametrize('exc', [CamSine(), Multisine(), Chirp(duration_s=2.0),
                                 BandLimitedRandom(rng=3)])
def test_velocity_is_derivative(exc):
    t = np.linspace(0.0, 3.0, 3001)
    h = 1e-6
    x, v = exc(t)
    dxdt = (exc(t + h)[0] - exc(t - h)[0]) / (2 * h)
    np.testing.assert_allclose(v, dxdt, atol=1e-6 * max(1.0, np.max(np.abs(v))))
    xs, vs = exc(1.234)
    assert isinstance(xs, float) and xs == pytest.approx(exc(np.array([1.234]))[0][0])


def test_cam_thesis_values():
    cam = CamSine()
    x, v = cam(np.linspace(0, 1 / 1.1, 10001))
    assert x[0] == pytest.approx(-0.03) and v[0] == 0.0
    assert np.max(v) == pytest.approx(2 * np.pi * 1.1 * 0.03, rel=1e-6)   # 0.207 m/s
    assert np.max(v) == pytest.approx(0.207, abs=0.001)


@pytest.mark.slow
def test_random_seeded_and_rms():
    a = BandLimitedRandom(rms_m=0.01, rng=5)
    b = BandLimitedRandom(rms_m=0.01, rng=5)
    t = np.arange(0, 100.0, 0.01)
    np.testing.assert_array_equal(a(t)[0], b(t)[0])
    assert np.std(a(t)[0]) == pytest.approx(0.01, rel=0.1)
    assert not np.array_equal(a(t)[0], BandLimitedRandom(rms_m=0.01, rng=6)(t)[0])


def test_chirp_frequency_continuous():
    c = Chirp(f0_hz=1.0, f1_hz=3.0, duration_s=2.0)
    x, _ = c(np.array([1.999999, 2.0, 2.000001]))
    assert abs(x[2] - x[0]) < 1e-3


def test_schedules():
    s = StepSchedule()
    assert s.duration_s == pytest.approx(5 * 4 / 1.1)
    t = np.array([0.0, 3.6, 3.7, 10.0, 17.9, 100.0])
    np.testing.assert_array_equal(s(t), [0.0, 0.0, 0.5, 1.0, 2.0, 2.0])
    assert s(4.0) == 0.5
    assert ConstantSchedule(1.2)(5.0) == 1.2
    c = CommandedSchedule()
    c.set(0.7)
    assert c(1.0) == 0.7
    with pytest.raises(ValueError, match='unknown excitation'):
        make_excitation('square')
    with pytest.raises(ValueError, match='amplitude_m'):
        CamSine(amplitude_m=-1)


def test_make_excitation_common_options():
    cam = make_excitation('cam', amplitude_m=0.02, frequency_hz=2.0)
    assert cam.amplitude_m == 0.02 and cam.freq_hz == 2.0
    a = make_excitation('random', amplitude_m=0.005, seed=3)
    b = make_excitation('random', amplitude_m=0.005, rng=3)
    np.testing.assert_array_equal(a(np.arange(10.0))[0], b(np.arange(10.0))[0])
    assert make_excitation('chirp', frequency_hz=4.0).f1_hz == 4.0
