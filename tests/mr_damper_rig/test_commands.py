"""Rig displacement commands: clamped to the stroke, non-finite refused, stale timed out."""
import math

import numpy as np
import pytest


# ------------------------------------------------------------ displacement commands (HIL)
def _guard(**kw):
    from mr_damper_rig.commands import DisplacementCommandGuard
    return DisplacementCommandGuard(**kw)


@pytest.mark.parametrize('command, expected, outcome', [
    (0.5, 0.08, 'clamped_high'), (-1.0, -0.08, 'clamped_low'), (0.03, 0.03, 'accepted')])
def test_displacement_commands_are_clamped_to_the_stroke_and_counted(
        command, expected, outcome):
    g = _guard(stroke_m=0.08)
    assert g.command(command, 0.0) == (expected, outcome)
    assert g.target(0.001) == expected
    assert g.counts[outcome] == 1 and sum(g.counts.values()) == 1


@pytest.mark.parametrize('command', [math.nan, math.inf, -math.inf])
def test_non_finite_displacement_commands_are_refused_and_the_last_one_kept(command):
    g = _guard()
    g.command(0.01, 0.0)
    assert g.command(command, 0.001) == (None, 'refused_non_finite')
    assert g.target(0.002) == 0.01
    assert g.counts['refused_non_finite'] == 1 and g.counts['accepted'] == 1


def test_a_silent_commander_is_held_then_returned_to_neutral_and_counted():
    g = _guard(timeout_s=0.05, return_speed_m_s=0.1, center_m=0.0)
    assert g.target(0.0) == 0.0                      # before any command: neutral
    g.command(0.02, 0.0)
    dt = 0.001
    held = [g.target(k * dt) for k in range(1, 51)]  # within the timeout: held
    assert held == [0.02] * 50 and g.counts['stale_timeouts'] == 0
    ramp = [g.target(k * dt) for k in range(51, 400)]
    # back to neutral at 0.1 m/s: 0.02 m in 0.2 s, monotonic, never beyond neutral
    assert np.all(np.diff(ramp) <= 0) and min(ramp) == 0.0
    assert ramp[0] == pytest.approx(0.02 - 0.1 * dt)
    assert ramp.index(0.0) == pytest.approx(200, abs=1)
    assert g.counts['stale_timeouts'] == 1 and g.counts['stale_samples'] == len(ramp)
    g.command(-0.01, 0.4)                            # a new command takes over at once
    assert g.target(0.401) == -0.01
    g.target(0.5)                                    # a second silence counts again
    assert g.counts['stale_timeouts'] == 2


def test_guard_refuses_bad_settings():
    for kw, name in (({'stroke_m': 0.0}, 'stroke_m'), ({'timeout_s': -1.0}, 'timeout_s'),
                     ({'return_speed_m_s': math.nan}, 'return_speed_m_s'),
                     ({'center_m': math.inf}, 'center_m')):
        with pytest.raises(ValueError, match=name):
            _guard(**kw)


def test_command_follower_drives_the_actuator_with_the_guarded_target():
    from mr_damper_rig.actuator import CommandedMotion, ServoActuator
    from mr_damper_rig.commands import CommandFollower
    from mr_damper_rig.excitation import CamSine
    from mr_damper_rig.virtual_rig import VirtualRig
    act = ServoActuator('ideal', 1e-3, delay_s=0.0)
    rig = VirtualRig(excitation=CommandedMotion(act), force_noise_n=0.0, daq_bits=32)
    fol = CommandFollower(rig, _guard(stroke_m=0.05))
    fol.command(0.2)                                 # clamped to the stroke
    t, x, *_ = fol.sample()
    assert t == 0.0 and x == pytest.approx(0.05)
    fol.command(0.01)
    assert fol.sample()[1] == pytest.approx(0.01) and fol.samples == 2
    assert fol.guard.counts['clamped_high'] == 1 and fol.guard.counts['accepted'] == 1
    with pytest.raises(ValueError, match='CommandedMotion'):
        CommandFollower(VirtualRig(excitation=CamSine()), _guard())
