"""Tests of the streaming plants against the batch models."""
import numpy as np
import pytest

from mr_damper_model.models.plant import KwokCurrentPlant, make_plant, SpencerPlant
from mr_damper_model.models.presets import spencer_thesis_like, thesis_kwok_current
from mr_damper_model.models.spencer import Spencer

FS = 1000.0


def _cam(T):
    t = np.arange(int(T * FS)) / FS
    w = 2 * np.pi * 1.1
    return t, -0.03 * np.cos(w * t), 0.03 * w * np.sin(w * t)


def _run(plant, t, x, v, i):
    return np.array([plant.step(0.0 if k == 0 else t[k] - t[k - 1], x[k], v[k], i[k])
                     for k in range(t.size)])


def test_kwok_current_plant_equals_batch_after_coil_settles():
    model, p = thesis_kwok_current()
    t, x, v = _cam(1.0)
    i = np.full_like(t, 1.3)
    plant = make_plant('kwok-current')
    f = _run(plant, t, x, v, i)
    batch = model.force(model.from_dict(p), x, v, i)
    settled = t > 40 / 190.0          # 40 coil time constants
    np.testing.assert_allclose(f[settled], batch[settled], rtol=1e-12, atol=1e-9)
    assert plant.current == pytest.approx(1.3, abs=1e-9)


def test_coil_lag_and_slew():
    _, p = thesis_kwok_current()
    plant = KwokCurrentPlant(p, coil_tau_s=0.01)
    plant.step(0.0, 0.0, 0.0, 0.0)
    plant.step(0.01, 0.0, 0.0, 1.0)
    assert plant.current == pytest.approx(1.0 - np.exp(-1.0), rel=1e-12)
    slewed = KwokCurrentPlant(p, coil_tau_s=0.0, slew_a_per_s=50.0)
    for _ in range(10):
        slewed.step(0.001, 0.0, 0.0, 2.0)
    assert slewed.current == pytest.approx(0.5, rel=1e-12)
    slewed.reset()
    assert slewed.current == 0.0


def test_spencer_plant_equals_batch():
    t, x, v = _cam(0.6)
    i = np.where(t < 0.3, 0.5, 1.8)
    plant = SpencerPlant(spencer_thesis_like(), initial_current_a=0.5, y0_m=0.0)
    f = _run(plant, t, x, v, i)
    m = Spencer(y0_m=0.0)
    batch = m.force(m.from_dict(spencer_thesis_like()), x, v, i, t)
    np.testing.assert_allclose(f, batch, rtol=1e-9, atol=1e-7)


def test_compiled_spencer_step_equals_the_interpreted_reference_bit_for_bit():
    # the thesis cam with current steps across the coil range (the coil lag and the
    # hysteresis both move), a slew limit and an uneven last interval: the compiled step
    # (numba) is the interpreted one's arithmetic, so the forces, coil currents and internal
    # states are the same floats
    t, x, v = _cam(0.8)
    t = t.copy()
    t[-1] += 3.7e-4
    i = np.where(t < 0.2, 0.0, np.where(t < 0.5, 2.0, 0.7))
    runs = []
    for compiled in (True, False):
        plant = SpencerPlant(spencer_thesis_like(), initial_current_a=0.5, y0_m=0.0,
                             slew_a_per_s=400.0, compiled=compiled)
        f = _run(plant, t, x, v, i)
        runs.append((f, plant.current, list(plant._state)))
    (f_c, cur_c, st_c), (f_p, cur_p, st_p) = runs
    assert np.all(np.isfinite(f_c)) and np.ptp(f_c) > 100.0     # a real hysteresis loop
    np.testing.assert_array_equal(f_c, f_p)
    assert cur_c == cur_p and st_c == st_p
    assert make_plant('spencer')._advance is not None           # the default is compiled


def test_make_plant_errors():
    with pytest.raises(ValueError, match='unknown plant'):
        make_plant('nope')
    plant = make_plant('kwok-current')
    with pytest.raises(ValueError, match='dt'):
        plant.step(-1.0, 0.0, 0.0, 0.0)
    with pytest.raises(ValueError, match='finite'):
        plant.step(0.001, float('nan'), 0.0, 0.0)
    with pytest.raises(ValueError, match='beta0'):
        KwokCurrentPlant({'c0': 1.0})


def test_load_plant_reads_a_parameter_file(tmp_path):
    # a truth file (params_file format) gives the same plant as its parameters; '' the preset
    from mr_damper_model.io.params_file import load_plant, save_params
    model, truth = thesis_kwok_current()
    changed = dict(truth, c0=2.0 * truth['c0'])
    path = tmp_path / 'truth.json'
    save_params(path, {'model': 'kwok-current', 'parameters': changed})
    a, b = load_plant('kwok-current', str(path)), make_plant('kwok-current', changed)
    assert a.params == b.params == {k: float(v) for k, v in changed.items()}
    assert load_plant('kwok-current', path).params == a.params
    assert load_plant('kwok-current', '').params == make_plant('kwok-current').params
    with pytest.raises(ValueError, match='model'):
        load_plant('spencer', str(path))            # the file holds another model
    with pytest.raises(ValueError, match='load_plant'):
        make_plant('kwok-current', path)            # models read no files: it says who does
