"""Coil current commands: clamped to their range, non-finite ones refused, counted."""
import math

import pytest

from mr_damper_common.commands import CurrentCommandLimiter, OUTCOMES


def test_commands_in_range_pass_unchanged():
    lim = CurrentCommandLimiter(0.0, 2.0)
    for i in (0.0, 0.7, 2.0):
        assert lim.apply(i) == (i, 'accepted')
    assert lim.counts == {'accepted': 3, 'clamped_low': 0, 'clamped_high': 0,
                          'refused_non_finite': 0}


@pytest.mark.parametrize('command, expected, outcome', [
    (-5.0, 0.0, 'clamped_low'), (1e9, 2.0, 'clamped_high'), (2.0000001, 2.0, 'clamped_high'),
    (-1e-12, 0.0, 'clamped_low')])
def test_out_of_range_commands_are_clamped_and_counted(command, expected, outcome):
    lim = CurrentCommandLimiter(0.0, 2.0)
    assert lim.apply(command) == (expected, outcome)
    assert lim.counts[outcome] == 1 and sum(lim.counts.values()) == 1


@pytest.mark.parametrize('command', [math.nan, math.inf, -math.inf])
def test_non_finite_commands_are_refused_and_counted(command):
    lim = CurrentCommandLimiter(0.5, 1.5)
    assert lim.apply(command) == (None, 'refused_non_finite')
    assert lim.counts['refused_non_finite'] == 1 and lim.counts['accepted'] == 0


def test_a_mixed_stream_is_counted_by_outcome():
    lim = CurrentCommandLimiter(0.0, 2.0)
    stream = [1.0, -5.0, 1e9, math.nan, 0.5, math.inf, 3.0]
    applied = [lim.apply(c)[0] for c in stream]
    assert applied == [1.0, 0.0, 2.0, None, 0.5, None, 2.0]
    assert lim.counts == {'accepted': 2, 'clamped_low': 1, 'clamped_high': 2,
                          'refused_non_finite': 2}
    assert set(lim.counts) == set(OUTCOMES)


@pytest.mark.parametrize('lo, hi, name', [(2.0, 2.0, 'i_min_a'), (3.0, 1.0, 'i_min_a'),
                                          (math.nan, 1.0, 'i_min_a'), (0.0, math.inf, 'i_max_a')])
def test_bad_range_is_refused_naming_the_argument(lo, hi, name):
    with pytest.raises(ValueError, match=name):
        CurrentCommandLimiter(lo, hi)


def test_range_changes_while_running_and_a_bad_one_changes_nothing():
    lim = CurrentCommandLimiter(0.0, 2.0)
    lim.set_range(0.5, 1.5)
    assert lim.apply(2.0) == (1.5, 'clamped_high') and lim.apply(0.0) == (0.5, 'clamped_low')
    with pytest.raises(ValueError, match='i_min_a'):
        lim.set_range(1.5, 1.0)
    assert (lim.i_min_a, lim.i_max_a) == (0.5, 1.5)
