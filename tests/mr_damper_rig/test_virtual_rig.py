"""Tests of the virtual rig (sensor model, DAQ, repeatability, follow mode)."""
import numpy as np
import pytest

from mr_damper_model.models.plant import make_plant
from mr_damper_model.identification.presets import thesis_kwok_current
from mr_damper_rig.excitation import CamSine, ConstantSchedule
from mr_damper_rig.virtual_rig import identify_damper, VirtualRig


def _kwok_rig(**kw):
    return VirtualRig(make_plant('kwok-current'), CamSine(), ConstantSchedule(1.0), **kw)


def test_quantisation_step():
    rig = _kwok_rig(force_noise_n=0.0, rng=0)
    assert rig.quantisation_step('f') == 4000.0 / 2 ** 16
    data = rig.run(1.0)
    for ch, arr in (('x', data.x), ('v', data.v), ('f', data.f), ('i', data.i)):
        q = rig.quantisation_step(ch)
        np.testing.assert_allclose(arr / q, np.round(arr / q), atol=1e-6)
    assert rig.quantise('f', 1e6) == pytest.approx(2000.0 - rig.quantisation_step('f'))
    assert rig.clipped_samples == 1


def test_noise_free_rig_matches_model_and_noise_level():
    model, p = thesis_kwok_current()
    rig = _kwok_rig(force_noise_n=0.0, rng=0)
    data = rig.run(2.0)
    t = data.t
    x, v = CamSine()(t)
    settled = t > 0.3
    f_true = model.force(model.from_dict(p), x, v, np.full(t.size, 1.0))
    # only quantisation error remains (half a step of each channel, propagated)
    assert np.max(np.abs(data.f - f_true)[settled]) < 0.1
    noisy = _kwok_rig(force_noise_n=5.0, rng=1).run(2.0)
    assert np.std((noisy.f - f_true)[settled]) == pytest.approx(5.0, rel=0.1)
    assert data.sample_rate_hz == pytest.approx(1000.0)


def test_seed_repeatability():
    a = _kwok_rig(rng=7).run(0.5)
    b = _kwok_rig(rng=7).run(0.5)
    c = _kwok_rig(rng=8).run(0.5)
    np.testing.assert_array_equal(a.f, b.f)
    assert not np.array_equal(a.f, c.f)


def test_follow_command_and_truth():
    rig = _kwok_rig(rng=0)
    for _ in range(50):
        rig.sample()
    rig.command_current(2.0)
    for _ in range(200):
        sample = rig.sample()
    assert sample[4] == pytest.approx(2.0, abs=1e-3)     # measured actual coil current
    truth = rig.true_parameters()
    assert truth['model'] == 'kwok-current'
    assert truth['parameters'] == thesis_kwok_current()[1]
    assert truth['model_options'] == {'i_ref_a': 2.0}


@pytest.mark.slow
def test_default_rig_is_thesis_like():
    rig = VirtualRig(rng=0)
    assert rig.true_parameters()['model'] == 'spencer'
    data = rig.run(2 / 1.1)
    assert np.max(np.abs(data.f)) == pytest.approx(150.0, rel=0.15)
    with pytest.raises(ValueError, match='force_noise_n'):
        VirtualRig(force_noise_n=-1.0)


def _node_options(**changes):
    options = {'plant': 'kwok-current', 'excitation': 'cam', 'amplitude_m': 0.03,
               'frequency_hz': 1.1, 'currents_a': [0.0, 1.0, 2.0], 'step_s': 0.5,
               'current_source': 'schedule', 'noise_n': 0.0, 'seed': 1, 'rate_hz': 1000.0,
               'truth_file': '', 'actuator': 'ideal', 'actuator_tau_s': 0.012,
               'actuator_wn_rad_s': 157.0, 'actuator_zeta': 0.7, 'actuator_delay_s': 0.0}
    options.update(changes)
    return options


def test_rig_node_options_build_a_repeating_schedule_or_a_commanded_rig():
    from mr_damper_rig.actuator import CommandedMotion
    from mr_damper_rig.virtual_rig import build_virtual_rig
    rig = build_virtual_rig(_node_options())
    # the steps 0, 1, 2 A of 0.5 s start again every 1.5 s
    for t in (0.1, 0.6, 1.1):
        assert rig.schedule(t) == rig.schedule(t + 1.5) == rig.schedule(t + 3.0)
    assert [rig.schedule(t) for t in (0.1, 0.6, 1.1)] == [0.0, 1.0, 2.0]
    commanded = build_virtual_rig(_node_options(excitation='commanded',
                                                current_source='command'))
    assert isinstance(commanded.excitation, CommandedMotion)
    assert commanded.schedule(10.0) == 0.0            # 0 A until the first current command
    with pytest.raises(ValueError, match='current_source'):
        build_virtual_rig(_node_options(current_source='both'))


@pytest.mark.slow
def test_identify_damper_recovers_kwok_truth():
    d = identify_damper(make_plant('kwok-current'), seed=1)
    assert d['model'] == 'kwok-current'
    for k in ('c1', 'alpha1', 'alpha2', 'beta0', 'delta'):
        assert d['parameters'][k] == pytest.approx(thesis_kwok_current()[1][k], rel=0.05), k
    from quarter_car_sim.simulate.quarter_car import make_inverse
    inv = make_inverse(d)
    assert inv.i_ref_a == 2.0
