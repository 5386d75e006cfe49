"""Tests of mr_damper_rig.actuator: servo actuator step responses and commanded rig motion."""
import math

import numpy as np
import pytest

from mr_damper_rig.actuator import CommandedMotion, ServoActuator
from mr_damper_rig.excitation import ExcitationError
from mr_damper_rig.virtual_rig import VirtualRig

DT = 1e-3


def test_first_order_step_matches_analytic_with_transport_delay():
    act = ServoActuator('first', DT, tau_s=0.012, delay_s=0.003)
    assert act.delay_samples == 3
    x = act.response(np.full(100, 0.01))
    t = DT * np.arange(1, 101)                       # position after each sample
    t_eff = np.clip(t - 0.003, 0.0, None)
    np.testing.assert_allclose(x, 0.01 * (1 - np.exp(-t_eff / 0.012)), rtol=0, atol=1e-12)
    assert act.equivalent_delay_s == pytest.approx(0.015)


def test_second_order_step_matches_analytic():
    wn, zeta = 2 * math.pi * 25.0, 0.3
    act = ServoActuator('second', DT, wn_rad_s=wn, zeta=zeta, delay_s=0.0)
    x = act.response(np.full(200, 1.0))
    t = DT * np.arange(1, 201)
    wd = wn * math.sqrt(1 - zeta ** 2)
    truth = 1 - np.exp(-zeta * wn * t) * (np.cos(wd * t)
                                          + zeta / math.sqrt(1 - zeta ** 2) * np.sin(wd * t))
    np.testing.assert_allclose(x, truth, rtol=0, atol=1e-10)
    # overshoot of a zeta = 0.3 system: exp(-pi zeta / sqrt(1 - zeta^2)) = 37.2 %
    assert x.max() == pytest.approx(1 + math.exp(-math.pi * zeta / math.sqrt(1 - zeta ** 2)),
                                    abs=2e-3)
    assert act.equivalent_delay_s == pytest.approx(2 * zeta / wn)


def test_ideal_actuator_is_the_delayed_command():
    act = ServoActuator('ideal', DT, delay_s=0.002)
    u = np.sin(np.arange(50) * 0.1)
    x = act.response(u)
    np.testing.assert_array_equal(x[2:], u[:-2])
    np.testing.assert_array_equal(x[:2], [0.0, 0.0])


@pytest.mark.parametrize('kwargs, match', [
    ({'kind': 'third'}, 'kind'), ({'tau_s': 0.0}, 'tau_s'), ({'delay_s': -1.0}, 'delay_s'),
    ({'dt': math.nan}, 'dt')])
def test_bad_settings_are_named(kwargs, match):
    with pytest.raises(ExcitationError, match=match):
        ServoActuator(**kwargs)


def test_non_finite_command_is_refused():
    with pytest.raises(ExcitationError, match='finite'):
        ServoActuator().step(math.inf)
    with pytest.raises(ExcitationError, match='finite'):
        CommandedMotion(ServoActuator()).command(math.nan)


def test_virtual_rig_follows_commanded_motion():
    act = ServoActuator('first', DT, tau_s=0.01, delay_s=0.0)
    rig = VirtualRig(excitation=CommandedMotion(act), force_noise_n=0.0, rng=0)
    xs = []
    for _ in range(100):
        rig.excitation.command(0.01)
        xs.append(rig.sample()[1])
    truth = 0.01 * (1 - np.exp(-DT * np.arange(1, 101) / 0.01))
    np.testing.assert_allclose(xs, truth, atol=rig.quantisation_step('x'))
    # the same sample time again does not step the actuator
    x1 = rig.excitation(0.099)
    assert rig.excitation(0.099) == x1
    with pytest.raises(ExcitationError, match='back'):
        rig.excitation(0.05)
