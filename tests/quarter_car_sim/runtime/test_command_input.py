"""Tests of quarter_car_sim.runtime.command_input: the car side of an external controller."""
import math

import pytest

from quarter_car_sim.runtime.command_input import COMMAND_OUTCOMES, CommandInput

SAFE = 0.5


# ---------------------------------------------------------------------------- CommandInput
def test_command_timeout_falls_back_to_the_safe_current():
    cmd = CommandInput(timeout_s=0.05, safe_current_a=SAFE)
    assert cmd.current(0.0) == SAFE and cmd.timed_out and cmd.timeouts == 0   # none yet
    cmd.offer(1.5, 0.01)
    assert cmd.current(0.02) == 1.5 and cmd.current(0.06) == 1.5 and not cmd.timed_out
    assert cmd.current(0.0601) == SAFE and cmd.timeouts == 1
    assert cmd.current(0.2) == SAFE and cmd.timeouts == 1           # one entry, not per step
    cmd.offer(0.2, 0.3)
    assert cmd.current(0.3) == 0.2 and not cmd.timed_out
    assert cmd.current(0.5) == SAFE and cmd.timeouts == 2
    # time on the safe current: 0..0.02 (none yet) and 0.0601..0.3 (0.3 -> 0.5 was fresh)
    assert cmd.timeout_s_total == pytest.approx(0.02 + (0.3 - 0.0601), abs=1e-9)
    st = cmd.status()
    assert st['command_timeouts'] == 2 and st['commands_received'] == 2


def test_bad_commands_are_clamped_or_refused_and_counted():
    cmd = CommandInput(timeout_s=1.0, safe_current_a=SAFE, i_min_a=0.0, i_max_a=2.0)
    applied = []
    for k, value in enumerate((-5.0, 1e9, math.nan, math.inf, 1.2, 'x')):
        cmd.offer(value, 0.1 * k)
        applied.append(cmd.current(0.1 * k))
    # a refused command leaves the previous one in force (it still ages)
    assert applied == [0.0, 2.0, 2.0, 2.0, 1.2, 1.2]
    assert cmd.status()['commands'] == {'accepted': 1, 'clamped_low': 1, 'clamped_high': 1,
                                        'refused_non_finite': 3}
    assert tuple(cmd.status()['commands']) == COMMAND_OUTCOMES
    assert cmd.received_at == pytest.approx(0.4)


@pytest.mark.parametrize('kwargs, match', [
    ({'timeout_s': 0.0}, 'timeout_s'), ({'timeout_s': math.nan}, 'timeout_s'),
    ({'safe_current_a': 3.0}, 'safe_current_a'), ({'i_min_a': 2.0, 'i_max_a': 1.0}, 'i_min_a'),
])
def test_command_input_rejects_bad_settings(kwargs, match):
    args = dict(timeout_s=0.05, safe_current_a=SAFE, i_min_a=0.0, i_max_a=2.0)
    args.update(kwargs)
    with pytest.raises(ValueError, match=match):
        CommandInput(**args)
