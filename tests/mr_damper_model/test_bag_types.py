"""Tests of mr_damper_model.io.bag_types (suite messages in a rosbags type store, no ROS)."""
from pathlib import Path
import struct
import sys

from mr_damper_model.io import bag_types
import pytest
from rosbags.typesys import get_typestore, Stores

from conftest import REPO

SRC_MSG = REPO / 'src' / 'mr_damper_interfaces' / 'msg'
KWOK = 'mr_damper_interfaces/msg/KwokParameters'
STATE = 'mr_damper_interfaces/msg/QuarterCarState'
MODEL = 'mr_damper_interfaces/msg/DamperModel'
SAMPLES = 'mr_damper_interfaces/msg/DamperSamples'


def fake_prefix(root, definitions):
    """Make an install prefix holding ``mr_damper_interfaces`` with the given .msg texts."""
    (root / 'share' / 'ament_index' / 'resource_index' / 'packages').mkdir(parents=True)
    (root / 'share' / 'ament_index' / 'resource_index' / 'packages'
     / 'mr_damper_interfaces').write_text('')
    msg_dir = root / 'share' / 'mr_damper_interfaces' / 'msg'
    msg_dir.mkdir(parents=True)
    for name, text in definitions.items():
        (msg_dir / f'{name}.msg').write_text(text)
    return msg_dir


def test_finds_the_venv_install_without_environment(monkeypatch):
    monkeypatch.delenv('AMENT_PREFIX_PATH', raising=False)
    msg_dir = bag_types.interfaces_msg_dir()
    assert msg_dir == Path(sys.prefix) / 'share' / 'mr_damper_interfaces' / 'msg'


def test_ament_prefix_path_comes_first(monkeypatch, tmp_path):
    msg_dir = fake_prefix(tmp_path / 'overlay', {'Only': 'float64 x_m\n'})
    monkeypatch.setenv('AMENT_PREFIX_PATH', str(tmp_path / 'overlay'))
    assert bag_types.interfaces_msg_dir() == msg_dir
    assert tuple(bag_types.interface_types()) == ('mr_damper_interfaces/msg/Only',)


def test_prefix_without_the_marker_is_skipped(tmp_path):
    msg_dir = fake_prefix(tmp_path / 'a', {'Only': 'float64 x_m\n'})
    (tmp_path / 'a' / 'share' / 'ament_index' / 'resource_index' / 'packages'
     / 'mr_damper_interfaces').unlink()
    with pytest.raises(bag_types.BagTypesError, match='not installed') as err:
        bag_types.interfaces_msg_dir([tmp_path / 'a'])
    assert str(tmp_path / 'a') in str(err.value)
    assert msg_dir.is_dir()


def test_missing_package_names_every_prefix(tmp_path):
    prefixes = [tmp_path / 'x', tmp_path / 'y']
    with pytest.raises(bag_types.BagTypesError, match='setup_venv.sh') as err:
        bag_types.interfaces_msg_dir(prefixes)
    assert all(str(p) in str(err.value) for p in prefixes)


def test_empty_and_broken_definitions_are_errors(tmp_path):
    empty = fake_prefix(tmp_path / 'e', {})
    with pytest.raises(bag_types.BagTypesError, match='no .msg file'):
        bag_types.interface_types(empty)
    broken = fake_prefix(tmp_path / 'b', {'Bad': 'float64\n'})
    with pytest.raises(bag_types.BagTypesError, match='Bad.msg: not a valid message'):
        bag_types.interface_types(broken)


def test_source_definitions_parse_with_every_field_and_constant():
    types = bag_types.interface_types(SRC_MSG)
    vehicle = [f'mr_damper_interfaces/msg/{n}'
               for n in ('ChassisSensors', 'FullCarCommand', 'FullCarState', 'RoadPreview')]
    assert sorted(types) == sorted([MODEL, SAMPLES, KWOK, STATE] + vehicle)
    consts, _ = types[vehicle[1]]
    assert ('MODE_INACTIVE', 'uint8', 2) in consts
    assert [name for name, _ in types[MODEL][1]] == [
        'header', 'model', 'parameter_names', 'parameter_values', 'option_names', 'option_values']
    consts, fields = types[STATE]
    assert ('MODE_FAIL_SAFE', 'uint8', 1) in consts
    assert [name for name, _ in types[KWOK][1]][:11] == [
        'header', 'c0', 'c1', 'k', 'alpha0', 'alpha1', 'alpha2', 'beta0', 'beta1', 'delta', 'f0']
    assert dict(fields)['header'][1] == 'std_msgs/msg/Header'


def test_suite_typestore_serialises_known_values():
    store = bag_types.suite_typestore(SRC_MSG)
    assert KWOK in store.types and 'sensor_msgs/msg/JointState' in store.types
    Kwok = store.types[KWOK]
    Time = store.types['builtin_interfaces/msg/Time']
    Header = store.types['std_msgs/msg/Header']
    values = dict(c0=1.0, c1=2.0, k=3.0, alpha0=4.0, alpha1=5.0, alpha2=6.0, beta0=7.0,
                  beta1=8.0, delta=9.0, f0=10.0, i_ref_a=2.0, window_start=Time(1, 2),
                  window_end=Time(3, 4), current_min_a=0.0, current_max_a=2.0, rmse_n=0.5,
                  nrmse_percent=1.5, valid=True, reason='')
    msg = Kwok(header=Header(stamp=Time(5, 6), frame_id='d'), **values)
    raw = store.serialize_cdr(msg, KWOK)
    back = store.deserialize_cdr(raw, KWOK)
    assert back == msg
    # little-endian CDR: 4-byte encapsulation header; payload: sec, nanosec (4 + 4 bytes),
    # frame_id (u32 length 2, 'd', NUL) ends at 14, so c0 is aligned to payload offset 16
    assert raw[:4] == b'\x00\x01\x00\x00'
    assert struct.unpack_from('<iII', raw, 4) == (5, 6, 2)
    assert raw[16:18] == b'd\x00'
    assert struct.unpack_from('<2d', raw, 4 + 16) == (1.0, 2.0)


def test_register_adds_to_an_existing_store():
    store = get_typestore(Stores.ROS2_KILTED)
    assert KWOK not in store.types
    vehicle = tuple(f'mr_damper_interfaces/msg/{n}'
                    for n in ('ChassisSensors', 'FullCarCommand', 'FullCarState', 'RoadPreview'))
    assert bag_types.register_interface_types(store, SRC_MSG) == tuple(sorted(
        (MODEL, SAMPLES, KWOK, STATE) + vehicle))
    assert STATE in store.types
