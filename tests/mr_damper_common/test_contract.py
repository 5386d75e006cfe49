"""The wire contracts' types: CornerState and IdentifiedSet, and their conversions."""
import dataclasses
import math
from types import SimpleNamespace

import pytest

from mr_damper_common.contract import (CORNER_FIELDS, CornerState, IdentifiedSet,
                                       IdentifiedSetError, KWOK_CURRENT_NAMES, SET_FIELDS)

PARAMS = {n: float(k + 1) for k, n in enumerate(KWOK_CURRENT_NAMES)}


def test_corner_state_fields_not_given_are_nan_and_it_is_frozen():
    s = CornerState(1.5, v_s=0.2, travel=0.01)
    assert CORNER_FIELDS[0] == 't' and len(CORNER_FIELDS) == 13
    assert (s.t, s.v_s, s.travel) == (1.5, 0.2, 0.01)
    assert all(math.isnan(getattr(s, n)) for n in CORNER_FIELDS if n not in ('t', 'v_s', 'travel'))
    with pytest.raises(dataclasses.FrozenInstanceError):
        s.v_s = 1.0
    # the positional order is the simulator's (t, body, wheel, road, travel, forces, current)
    full = CornerState(*range(13))
    assert [getattr(full, n) for n in CORNER_FIELDS] == list(range(13))


def test_identified_set_from_flat_round_trip_and_defaults():
    s = IdentifiedSet.from_flat(dict(PARAMS, current_min_a=0.0, current_max_a=2.0, valid=1.0,
                                     rmse_n=3))
    assert s.parameters == PARAMS and s.valid is True and s.i_ref_a == 2.0
    assert s.rmse_n == 3.0 and isinstance(s.rmse_n, float)
    assert math.isnan(s.window_start_s) and math.isnan(s.stamp_s) and s.reason == ''
    flat = s.to_flat()
    assert set(flat) == set(KWOK_CURRENT_NAMES) | set(SET_FIELDS)
    assert IdentifiedSet.from_flat(flat) == s
    nested = s.to_dict()
    assert nested['parameters'] == PARAMS and nested['current_max_a'] == 2.0
    assert s.replace(valid=False).valid is False and s.valid is True


@pytest.mark.parametrize('flag, valid', [(1, True), (1.0, True), (True, True), (0.0, False),
                                         (0.5, False), (math.nan, False), ('yes', False),
                                         (None, False)])
def test_only_a_flag_equal_to_one_is_valid(flag, valid):
    assert IdentifiedSet.from_flat(dict(PARAMS, valid=flag)).valid is valid


def test_a_missing_or_non_numeric_element_is_refused_with_the_supervisors_reason():
    with pytest.raises(IdentifiedSetError, match='delta') as info:
        IdentifiedSet.from_flat({k: v for k, v in PARAMS.items() if k != 'delta'})
    assert info.value.reason == 'missing'
    with pytest.raises(IdentifiedSetError, match='f0') as info:
        IdentifiedSet.from_flat(dict(PARAMS, f0='heavy'))
    assert info.value.reason == 'non_finite'
    with pytest.raises(IdentifiedSetError, match='i_ref_a') as info:
        IdentifiedSet(PARAMS, i_ref_a=[2.0])
    assert info.value.reason == 'non_finite'
    with pytest.raises(IdentifiedSetError) as info:
        IdentifiedSet.from_flat([1.0, 2.0])
    assert info.value.reason == 'missing'
    # NaN is a number: the set holds it, the supervisor refuses it
    assert math.isnan(IdentifiedSet(dict(PARAMS, c0=math.nan)).parameters['c0'])


def test_from_params_file_takes_a_file_dict_or_an_object_with_its_fields():
    content = {'model': 'kwok-current', 'parameters': PARAMS, 'model_options': {'i_ref_a': 1.5},
               'current_min_a': 0.25, 'current_max_a': 1.75, 'valid': True}
    s = IdentifiedSet.from_params_file(content)
    assert (s.i_ref_a, s.current_min_a, s.current_max_a, s.valid) == (1.5, 0.25, 1.75, True)
    assert s.parameters == PARAMS
    assert IdentifiedSet.from_params_file(SimpleNamespace(**content)) == s
    # a file without a current range: identified over the suite's 0-2 A; without valid: valid
    bare = IdentifiedSet.from_params_file({'parameters': PARAMS,
                                           'current_min_a': math.nan})
    assert (bare.current_min_a, bare.current_max_a, bare.valid, bare.i_ref_a) == \
        (0.0, 2.0, True, 2.0)
    assert not IdentifiedSet.from_params_file(dict(content, valid=False)).valid
