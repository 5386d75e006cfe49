"""Message conversions: measurement JointState, typed parameters, diagnostics, JSON status."""
import array
import math

import numpy as np
import pytest
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from mr_damper_interfaces.msg import DamperModel, KwokParameters
from sensor_msgs.msg import JointState

from mr_damper_common import messages as m
from mr_damper_common.contract import KWOK_CURRENT_NAMES
from mr_damper_common.health import Health, WARN


def test_measurement_round_trip_keeps_values_and_stamp():
    msg = m.measurement_to_msg(1795315554.249414, 0.0123, -0.2, 512.5, 1.5)
    assert list(msg.name) == ['mr_damper_piston', 'mr_damper_coil']
    assert math.isnan(msg.position[1]) and math.isnan(msg.velocity[1])
    t, x, v, f, i = m.measurement_from_msg(msg)
    assert abs(t - 1795315554.249414) < 1e-6   # ns stamp resolution, float64 seconds
    assert (x, v, f, i) == (0.0123, -0.2, 512.5, 1.5)


def test_measurement_joint_order_is_free():
    msg = JointState(name=['mr_damper_coil', 'mr_damper_piston'], position=[math.nan, 0.01],
                     velocity=[math.nan, 0.1], effort=[2.0, 300.0])
    msg.header.stamp.sec = 3
    assert m.measurement_from_msg(msg) == (3.0, 0.01, 0.1, 300.0, 2.0)


@pytest.mark.parametrize('names, reason', [
    (['piston', 'coil'], 'joint_names'),
    (['mr_damper_piston'], 'joint_names'),
])
def test_measurement_wrong_names_raise_with_reason(names, reason):
    msg = JointState(name=names, position=[0.0, 0.0], velocity=[0.0, 0.0], effort=[0.0, 0.0])
    with pytest.raises(m.MessageError, match='expected') as info:
        m.measurement_from_msg(msg)
    assert info.value.reason == reason


def test_measurement_short_arrays_raise_layout():
    msg = JointState(name=list(m.MEASUREMENT_JOINTS), position=[0.0], velocity=[0.0],
                     effort=[1.0])
    with pytest.raises(m.MessageError) as info:
        m.measurement_from_msg(msg)
    assert info.value.reason == 'layout'


def test_negative_stamp_is_refused():
    with pytest.raises(ValueError, match='`t`'):
        m.measurement_to_msg(-1.0, 0, 0, 0, 0)


def test_kwok_parameters_typed_round_trip():
    params = dict(zip(KWOK_CURRENT_NAMES, np.arange(1.0, 11.0)))
    msg = m.kwok_parameters_msg(dict(params, window_start_s=10.5, window_end_s=12.5,
                                     current_min_a=0.0, current_max_a=2.0, rmse_n=3.0,
                                     nrmse_percent=1.5, valid=True), stamp_s=20.25)
    assert isinstance(msg, KwokParameters)
    assert (msg.c0, msg.f0, msg.i_ref_a) == (1.0, 10.0, 2.0)
    assert (msg.window_end.sec, msg.window_end.nanosec) == (12, 500_000_000)
    assert msg.header.frame_id == 'mr_damper' and msg.header.stamp.sec == 20
    assert msg.valid and msg.reason == ''
    back = m.identified_set_from_msg(msg)
    assert back.parameters == params
    assert back.valid is True and back.i_ref_a == 2.0
    assert (back.window_start_s, back.window_end_s, back.stamp_s) == (10.5, 12.5, 20.25)
    assert (back.current_min_a, back.current_max_a, back.rmse_n) == (0.0, 2.0, 3.0)
    flat = back.to_flat()
    assert {k: flat[k] for k in KWOK_CURRENT_NAMES} == params
    assert flat['valid'] is True and flat['current_max_a'] == 2.0
    # the typed set encodes as its flat mapping does
    assert m.kwok_parameters_msg(back, stamp_s=20.25) == msg


def test_kwok_parameters_unknown_times_invalid_flag_and_missing_names():
    params = dict(zip(KWOK_CURRENT_NAMES, np.ones(10)))
    msg = m.kwok_parameters_msg(dict(params, reason='nrmse_above_threshold'))
    back = m.identified_set_from_msg(msg)
    assert back.valid is False and back.reason == 'nrmse_above_threshold'
    assert math.isnan(back.window_start_s) and math.isnan(back.window_end_s)
    assert math.isnan(back.rmse_n)
    # not valid always carries a reason
    assert m.identified_set_from_msg(m.kwok_parameters_msg(params)).reason == 'not_valid'
    with pytest.raises(ValueError, match='beta1'):
        m.kwok_parameters_msg({k: v for k, v in params.items() if k != 'beta1'})
    with pytest.raises(ValueError, match='i_ref_a'):
        m.kwok_parameters_msg(dict(params, i_ref_a=0.0))


def test_kwok_parameters_with_zero_reference_current_is_refused_as_bad_i_ref():
    msg = KwokParameters()           # every field 0: no model can use it
    with pytest.raises(m.MessageError, match='i_ref_a') as info:
        m.identified_set_from_msg(msg)
    assert info.value.reason == 'bad_i_ref'
    msg.i_ref_a = -1.0
    with pytest.raises(m.MessageError, match='i_ref_a') as info:
        m.identified_set_from_msg(msg)
    assert info.value.reason == 'bad_i_ref'


def test_damper_model_round_trip_and_mismatch():
    params = {'c0a': 784.0, 'alpha_a': 12441.0, 'gamma': 136320.0}
    msg = m.damper_model_msg('spencer', params, {'i_ref_a': 2.0}, stamp_s=1.5)
    assert isinstance(msg, DamperModel) and msg.header.stamp.nanosec == 500_000_000
    assert m.damper_model_from_msg(msg) == {'model': 'spencer', 'parameters': params,
                                            'model_options': {'i_ref_a': 2.0}}
    msg.parameter_values = [1.0]
    with pytest.raises(m.MessageError, match='3 names for 1 values'):
        m.damper_model_from_msg(msg)


def test_diagnostic_status_round_trip_with_nesting_non_finite_and_numpy():
    values = {'samples_received': np.int64(12000), 'valid': np.bool_(True),
              'param_age_s': float('nan'), 'windows_skipped': {'gap': 2, 'no_bins': 0},
              'reason': 'stale', 'bins_a': [0.0, np.float64(2.0)], 'cap': float('inf')}
    status = m.diagnostic_status_msg('fl/mr_damper_identifier', Health(WARN, 'stale', values),
                                     hardware_id='fl')
    assert isinstance(status, DiagnosticStatus)
    assert status.level == DiagnosticStatus.WARN
    kv = {v.key: v.value for v in status.values}
    assert kv['windows_skipped.gap'] == '2' and kv['valid'] == 'true'
    assert kv['param_age_s'] == 'nan' and kv['reason'] == 'stale'
    back = m.health_from_diagnostic(status)
    assert back.level == WARN and back.message == 'stale'
    assert back.values['samples_received'] == 12000 and back.values['valid'] is True
    assert back.values['windows_skipped'] == {'gap': 2, 'no_bins': 0}
    assert math.isnan(back.values['param_age_s']) and back.values['cap'] == math.inf
    assert back.values['bins_a'] == [0.0, 2.0]
    array = m.diagnostic_array_msg([status], stamp_s=3.0)
    assert isinstance(array, DiagnosticArray) and array.header.stamp.sec == 3


def test_status_reusing_the_last_key_values_writes_what_a_new_one_writes():
    """A periodic writer's KeyValue messages are reused for the keys that come again."""
    from mr_damper_common.health import OK
    reused = {}
    first = {'a': 1, 'b': {'x': 0.5, 'y': 'text'}, 'gone': True}
    second = {'a': 2, 'b': {'x': float('nan'), 'y': 'text'}, 'new': [1, 2]}
    for values in (first, second, second):
        status = m.diagnostic_status_msg('n', Health(OK, 'ok', values), key_values=reused)
        fresh = m.diagnostic_status_msg('n', Health(OK, 'ok', values))
        assert [(v.key, v.value) for v in status.values] == \
            [(v.key, v.value) for v in fresh.values]
        assert list(reused) == [v.key for v in status.values]    # this status's keys only
    kept = reused['a']
    m.diagnostic_status_msg('n', Health(OK, 'ok', {'a': 3}), key_values=reused)
    assert reused == {'a': kept} and kept.value == '3'      # the same message, its new text


def test_samples_batch_round_trip_keeps_values_and_stamps():
    t = 1795315554.25 + np.arange(20) * 1e-3
    ends = ((0.0, 0.01), (-0.2, 0.2), (-500, 500), (0.0, 2.0))
    x, v, f, i = (np.linspace(a, b, 20) for a, b in ends)
    msg = m.samples_to_msg(t, x, v, f, i, sequence=7, first_index=140, sample_period_s=1e-3)
    assert (msg.sequence, msg.first_index, msg.sample_period_s) == (7, 140, 1e-3)
    assert msg.t_offset_s[0] == 0.0
    back = m.samples_from_msg(msg)
    np.testing.assert_allclose(back[0], t, rtol=0, atol=1e-6)   # ns stamp of the first sample
    for got, want in zip(back[1:], (x, v, f, i)):
        np.testing.assert_array_equal(got, want)
    # the message filled again in place carries only the new batch
    msg = m.samples_to_msg(t[:3], x[:3], v[:3], f[:3], i[:3], sequence=8, first_index=160,
                           msg=msg)
    assert len(msg.x_m) == 3 and msg.first_index == 160


def test_samples_batch_refuses_bad_layouts():
    with pytest.raises(ValueError, match='one length'):
        m.samples_to_msg([0.0, 1.0], [0.0], [0.0, 0.0], [0.0, 0.0], [0.0, 0.0], sequence=0,
                         first_index=0)
    with pytest.raises(ValueError, match='one length'):
        m.samples_to_msg([], [], [], [], [], sequence=0, first_index=0)
    msg = m.samples_to_msg([1.0, 2.0], [0.0, 0.0], [0.0, 0.0], [0.0, 0.0], [0.0, 0.0],
                           sequence=0, first_index=0)
    msg.f_n = array.array('d', [1.0])            # a sender with unequal arrays
    with pytest.raises(m.MessageError) as info:
        m.samples_from_msg(msg)
    assert info.value.reason == 'layout'


def test_measurement_arrays_reads_both_layouts():
    single = m.measurement_to_msg(3.5, 0.01, 0.1, 300.0, 2.0)
    t, x, v, f, i = m.measurement_arrays(single)
    assert [a.tolist() for a in (t, x, v, f, i)] == [[3.5], [0.01], [0.1], [300.0], [2.0]]
    batch = m.samples_to_msg([3.5, 3.501], [0.01, 0.02], [0.1, 0.2], [300.0, 301.0],
                             [2.0, 2.0], sequence=0, first_index=0)
    assert [len(a) for a in m.measurement_arrays(batch)] == [2] * 5


def test_corner_state_round_trip_keeps_every_field():
    from mr_damper_common.contract import CORNER_FIELDS, CornerState
    s = CornerState(2.5, 0.01, 0.3, 2.0, 0.0, 0.1, -1.0, 0.0, 0.01, 0.2, 2900.0, -50.0, 0.4)
    msg = m.corner_state_to_msg(s, 1.25, False, 'stale')
    v = m.corner_state_from_msg(msg)
    assert v.t == pytest.approx(2.5, abs=1e-9)
    for name in CORNER_FIELDS[1:]:     # the laws' fields, the tyre deflection's and the rest
        assert getattr(v, name) == getattr(s, name)
    assert msg.current_command_a == 1.25 and msg.fail_safe_reason == 'stale'
    assert msg.fail_safe_mode == msg.MODE_FAIL_SAFE
    assert (msg.tyre_load_n, msg.coil_current_a) == (s.tyre_force, s.coil_current)
    assert msg.header.frame_id == 'quarter_car'
    # a car settling before the road starts (t < 0) is stamped 0; a NaN field stays NaN
    early = m.corner_state_from_msg(m.corner_state_to_msg(CornerState(-0.2), 0.5, True, 'ok'))
    assert early.t == 0.0 and math.isnan(early.v_s) and math.isnan(early.coil_current)


def test_road_preview_round_trip_keeps_every_value_through_the_wire():
    from mr_damper_interfaces.msg import RoadPreview
    from rclpy.serialization import deserialize_message, serialize_message
    d = np.array([0.5, 0.6, 0.75, 15.0])
    h = np.array([[0.001, -0.002, math.nan, 0.004], [0.0, 1e-6, -0.03, 0.02]])
    msg = m.road_preview_msg(12.345678901, d, h, sequence=2 ** 40 + 7, speed_m_s=20.4)
    back = m.road_preview_fields(deserialize_message(serialize_message(msg), RoadPreview))
    assert back['sequence'] == 2 ** 40 + 7
    assert back['stamp'] == pytest.approx(12.345678901, abs=1e-9)
    assert back['speed_m_s'] == 20.4 and back['valid'] and back['reason'] == ''
    np.testing.assert_array_equal(back['distance_m'], d)
    np.testing.assert_array_equal(back['heights_m'], h)       # NaN: not measured, kept
    assert msg.track_count == 2 and msg.header.frame_id == 'front_axle'
    one = m.road_preview_fields(m.road_preview_msg(0.0, d, h[:1], sequence=1,
                                                   speed_m_s=math.nan, valid=False))
    assert one['heights_m'].shape == (1, 4) and math.isnan(one['speed_m_s'])
    assert not one['valid'] and one['reason'] == 'not_valid'


def test_road_preview_refuses_bad_layouts():
    with pytest.raises(ValueError, match='heights_m'):
        m.road_preview_msg(0.0, [1.0, 2.0], np.zeros((2, 3)), sequence=1, speed_m_s=1.0)
    msg = m.road_preview_msg(0.0, [1.0, 2.0], np.zeros((2, 2)), sequence=1, speed_m_s=1.0)
    msg.track_count = 3
    with pytest.raises(m.MessageError) as err:
        m.road_preview_fields(msg)
    assert err.value.reason == 'layout'
    msg.track_count = 0
    with pytest.raises(m.MessageError):
        m.road_preview_fields(msg)
