"""Message conversions: measurement JointState, labelled Float64MultiArray, JSON status."""
import math

import numpy as np
import pytest
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64MultiArray, MultiArrayDimension, String

from mr_damper_model import messages as m


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


def test_kwok_parameters_layout_and_decoding_by_label():
    params = dict(zip(m.KWOK_CURRENT_NAMES, np.arange(1.0, 11.0)))
    msg = m.kwok_parameters_msg(dict(params, window_end_s=12.5, current_min_a=0.0,
                                     current_max_a=2.0, rmse_n=3.0, nrmse_percent=1.5,
                                     valid=True))
    dim = msg.layout.dim[0]
    assert dim.label.split(',') == list(m.KWOK_PARAMETER_LABELS)
    assert dim.size == dim.stride == len(msg.data) == 17
    back = m.kwok_parameters_from_msg(msg)
    assert back['parameters'] == params
    assert back['valid'] is True and back['i_ref_a'] == 2.0 and back['window_end_s'] == 12.5
    # a publisher with another element order decodes the same (by label)
    order = list(reversed(m.KWOK_PARAMETER_LABELS))
    d = m.array_msg_to_dict(msg)
    other = m.dict_to_array_msg(d, order)
    assert m.kwok_parameters_from_msg(other) == back


def test_kwok_parameters_invalid_flag_and_missing_names():
    params = dict(zip(m.KWOK_CURRENT_NAMES, np.ones(10)))
    assert m.kwok_parameters_from_msg(m.kwok_parameters_msg(params))['valid'] is False
    with pytest.raises(ValueError, match='beta1'):
        m.kwok_parameters_msg({k: v for k, v in params.items() if k != 'beta1'})
    short = m.dict_to_array_msg({'c0': 1.0})
    with pytest.raises(m.MessageError, match='misses'):
        m.kwok_parameters_from_msg(short)


def test_array_msg_label_count_mismatch_is_layout_error():
    msg = Float64MultiArray(data=[1.0, 2.0])
    with pytest.raises(m.MessageError):
        m.array_msg_to_dict(msg)
    msg.layout.dim = [MultiArrayDimension(label='a,b,c', size=3, stride=3)]
    with pytest.raises(m.MessageError, match='3 labels for 2'):
        m.array_msg_to_dict(msg)


def test_status_json_round_trip_with_non_finite_and_numpy():
    msg = m.status_msg({'n': np.int64(3), 'x': float('nan'), 'ok': np.bool_(True),
                        'nested': {'a': np.float64(1.5)}, 'lst': [1, float('inf')]})
    assert isinstance(msg, String)
    assert m.status_from_msg(msg) == {'n': 3, 'x': None, 'ok': True, 'nested': {'a': 1.5},
                                      'lst': [1, None]}
    with pytest.raises(m.MessageError):
        m.status_from_msg(String(data='[1, 2]'))
