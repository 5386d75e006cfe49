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


def test_tracking_error_is_zero_for_an_ideal_actuator_and_the_lag_of_a_first_order_one():
    from mr_damper_rig.actuator import CommandedMotion, ServoActuator
    from mr_damper_rig.commands import CommandFollower
    from mr_damper_rig.virtual_rig import VirtualRig
    ideal = CommandFollower(VirtualRig(excitation=CommandedMotion(
        ServoActuator('ideal', 1e-3, delay_s=0.0)), force_noise_n=0.0, daq_bits=32), _guard())
    for x in (0.01, 0.02, -0.01):
        ideal.command(x)
        ideal.sample()
    track = ideal.tracking.as_dict()
    assert track['n'] == 3 and track['peak_m'] == pytest.approx(0.0, abs=1e-9)
    assert track['non_finite'] == 0
    # first-order lag, tau = 10 ms, step of 10 mm held: the error after k samples of 1 ms is
    # 10 mm * exp(-k dt / tau) (exact zero-order-hold discretisation)
    tau, dt = 0.01, 1e-3
    lag = CommandFollower(VirtualRig(excitation=CommandedMotion(
        ServoActuator('first', dt, tau_s=tau, delay_s=0.0)), force_noise_n=0.0, daq_bits=32),
        _guard(timeout_s=1.0))
    lag.command(0.01)
    errors = [0.01 - lag.sample()[1] for _ in range(50)]
    expected = 0.01 * np.exp(-np.arange(1, 51) * dt / tau)
    np.testing.assert_allclose(errors, expected, rtol=1e-6, atol=1e-12)
    track = lag.tracking.as_dict()
    assert track['peak_m'] == pytest.approx(expected[0], rel=1e-6)
    assert track['rms_m'] == pytest.approx(np.sqrt(np.mean(expected ** 2)), rel=1e-6)
    assert track['last_m'] == pytest.approx(expected[-1], rel=1e-6)


def test_tracking_of_a_delayed_actuator_estimates_its_delay():
    from mr_damper_rig.actuator import CommandedMotion, ServoActuator
    from mr_damper_rig.commands import CommandFollower
    from mr_damper_rig.virtual_rig import VirtualRig
    dt, delay = 1e-3, 0.005
    fol = CommandFollower(VirtualRig(excitation=CommandedMotion(
        ServoActuator('ideal', dt, delay_s=delay)), force_noise_n=0.0, daq_bits=32),
        _guard(timeout_s=1.0))
    for k in range(2000):        # 2 s of a 10 mm, 1 Hz sine command
        fol.command(0.01 * np.sin(2 * np.pi * k * dt))
        fol.sample()
    track = fol.tracking.as_dict()
    # a pure delay of 5 samples: the least-squares remaining delay is that delay (first-order
    # in dt: the target's velocity is its one-sample difference)
    assert track['delay_s'] == pytest.approx(delay, rel=0.02)
    assert fol.tracking.recent_delay_s == pytest.approx(delay, rel=0.02)
    assert track['n'] == 2000 and track['non_finite'] == 0


def test_guard_settings_change_while_running_and_bad_ones_change_nothing():
    guard = _guard(stroke_m=0.05, timeout_s=0.05, return_speed_m_s=0.05)
    guard.configure(stroke_m=0.02)
    assert guard.command(0.03, 0.0) == (0.02, 'clamped_high')
    with pytest.raises(ValueError, match='timeout_s'):
        guard.configure(stroke_m=0.04, timeout_s=-1.0)
    assert (guard.stroke_m, guard.timeout_s) == (0.02, 0.05)   # nothing applied
