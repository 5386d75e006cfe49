"""
The typed messages of ``mr_damper_interfaces``, as built and installed by setup_venv.sh.

Checks that the generated Python classes import from the venv, carry the fields of the ``.msg``
files, survive rclpy (CDR) serialisation, travel over a real topic between two DDS participants
(this run's private domain, loopback only: tests/conftest.py), and that a rosbags MCAP written
with the suite type store carries the typed ``ros2msg`` schema and decodes field by field.
Also checks that ``diagnostic_msgs/DiagnosticArray`` (pip wheel) publishes and arrives.
"""
import os
from pathlib import Path
import struct
import subprocess
import sys
import time

from builtin_interfaces.msg import Time
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from mr_damper_interfaces.msg import (ChassisSensors, FullCarCommand, FullCarState,
                                      KwokParameters, QuarterCarState, RoadPreview)
from mr_damper_model.io import bag_types
from mr_damper_model.models.kwok_current import KwokCurrent
import numpy as np
import pytest
import rclpy
from rclpy.executors import SingleThreadedExecutor
from rclpy.serialization import deserialize_message, serialize_message
from rosbags.highlevel import AnyReader
from rosbags.rosbag2 import StoragePlugin, Writer

from conftest import REPO
from ros_context import ros_context

SRC_MSG = REPO / 'src' / 'mr_damper_interfaces' / 'msg'
HANG_GUARD_S = 30.0

KWOK_FIELDS = ('c0', 'c1', 'k', 'alpha0', 'alpha1', 'alpha2', 'beta0', 'beta1', 'delta', 'f0',
               'i_ref_a', 'window_start', 'window_end', 'current_min_a', 'current_max_a',
               'rmse_n', 'nrmse_percent', 'valid', 'reason')
STATE_FLOATS = ('body_displacement_m', 'body_velocity_m_s', 'body_acceleration_m_s2',
                'wheel_displacement_m', 'wheel_velocity_m_s', 'wheel_acceleration_m_s2',
                'suspension_travel_m', 'suspension_velocity_m_s', 'damper_force_n',
                'tyre_load_n', 'road_height_m', 'current_command_a', 'coil_current_a')


def kwok_message():
    """Return a KwokParameters with a distinct value in every field."""
    msg = KwokParameters()
    msg.header.stamp = Time(sec=12, nanosec=345_000_000)
    msg.header.frame_id = 'mr_damper'
    for n, name in enumerate(KwokCurrent.param_names):
        setattr(msg, name, 1.5 * n - 3.25)
    msg.i_ref_a = 2.0
    msg.window_start = Time(sec=10, nanosec=1)
    msg.window_end = Time(sec=12, nanosec=999_999_999)
    msg.current_min_a, msg.current_max_a = 0.05, 1.95
    msg.rmse_n, msg.nrmse_percent = 7.9, 2.4
    msg.valid = False
    msg.reason = 'nrmse_too_high'
    return msg


def state_message():
    """Return a QuarterCarState with a distinct value in every field."""
    msg = QuarterCarState()
    msg.header.stamp = Time(sec=3, nanosec=7)
    msg.header.frame_id = 'front_left'
    msg.sequence = 2**64 - 3                    # the whole uint64 range survives the wire
    for n, name in enumerate(STATE_FLOATS):
        setattr(msg, name, -0.125 * (n + 1))
    msg.fail_safe_mode = QuarterCarState.MODE_FAIL_SAFE
    msg.fail_safe_reason = 'stale'
    return msg


def chassis_message():
    """Return a ChassisSensors with a distinct value in every field (NaN: a frame missing)."""
    msg = ChassisSensors()
    msg.header.stamp = Time(sec=4, nanosec=2_000_000)
    msg.header.frame_id = 'chassis'
    msg.sequence = 2 ** 40 + 3
    msg.cycle_period_s = 0.002
    msg.body_acceleration_m_s2 = [0.25, -0.5, 1.0, -2.0]
    msg.wheel_acceleration_m_s2 = [float('nan')] * 4
    msg.suspension_travel_m = [0.001, -0.002, 0.003, -0.004]
    msg.current_command_a = [0.5, 0.75, 1.0, 1.25]
    msg.coil_current_a = [0.49, 0.74, 0.99, 1.24]
    msg.frames_missing = ChassisSensors.MISSING_WHEEL_ACCELERATION
    return msg


def full_car_state_message():
    """Return a FullCarState with a distinct value in every field."""
    msg = FullCarState()
    msg.header.stamp = Time(sec=4, nanosec=2_000_000)
    msg.header.frame_id = 'base_link'
    msg.sequence = 17
    for n, name in enumerate(('heave_m', 'pitch_rad', 'roll_rad', 'heave_velocity_m_s',
                              'pitch_rate_rad_s', 'roll_rate_rad_s', 'heave_acceleration_m_s2',
                              'pitch_acceleration_rad_s2', 'roll_acceleration_rad_s2')):
        setattr(msg, name, 0.01 * (n + 1))
    for n, name in enumerate(('suspension_travel_m', 'suspension_velocity_m_s',
                              'tyre_deflection_m', 'wheel_velocity_m_s', 'damper_force_n')):
        setattr(msg, name, [n + 0.1 * k for k in range(4)])
    msg.valid = False
    msg.reason = 'too_few_sensors'
    msg.sensor_faults = ['dropout_accel_fr', 'stuck_travel_rl']
    msg.travel_std_m, msg.heave_velocity_std_m_s = 5e-5, 1e-3
    msg.tyre_deflection_std_m, msg.wheel_velocity_std_m_s = 2e-3, 0.03
    return msg


def full_car_command_message():
    """Return a FullCarCommand with a distinct value in every field."""
    msg = FullCarCommand()
    msg.header.stamp = Time(sec=4, nanosec=3_000_000)
    msg.header.frame_id = 'base_link'
    msg.sequence = 9
    msg.state_sequence = 17
    msg.state_stamp = Time(sec=4, nanosec=2_000_000)
    msg.current_a = [0.1, 0.5, 0.9, 0.5]
    msg.demanded_force_n = [-120.0, float('nan'), 300.0, float('nan')]
    msg.mode = [FullCarCommand.MODE_NORMAL, FullCarCommand.MODE_FAIL_SAFE,
                FullCarCommand.MODE_NORMAL, FullCarCommand.MODE_INACTIVE]
    msg.reason = ['ok', 'stale', 'ok', 'inactive']
    return msg


def road_preview_message():
    """Return a RoadPreview with a distinct value in every field (NaN: a point not measured)."""
    msg = RoadPreview()
    msg.header.stamp = Time(sec=7, nanosec=55_555_556)
    msg.header.frame_id = 'front_axle'
    msg.sequence = 2 ** 33 + 1
    msg.vehicle_speed_m_s = 20.4
    msg.distance_m = [0.5, 0.6, 0.7]
    msg.track_count = 2
    msg.height_m = [0.001, -0.002, float('nan'), 0.0, 0.003, -0.004]
    msg.valid = False
    msg.reason = 'outage'
    return msg


def assert_same(typed, msg):
    """Assert a rosbags-decoded message has the field values of an rclpy message, recursively."""
    for name in msg.get_fields_and_field_types():
        want, have = getattr(msg, name), getattr(typed, name)
        if hasattr(want, 'get_fields_and_field_types'):
            assert_same(have, want)
        else:
            assert have == want, (name, have, want)


def test_generated_classes_come_from_the_venv_install():
    import mr_damper_interfaces
    assert Path(mr_damper_interfaces.__file__).is_relative_to(sys.prefix)
    assert KwokParameters.get_fields_and_field_types()['window_end'] == 'builtin_interfaces/Time'
    assert tuple(KwokParameters.get_fields_and_field_types()) == ('header',) + KWOK_FIELDS
    assert tuple(QuarterCarState.get_fields_and_field_types()) == (
        ('header', 'sequence') + STATE_FLOATS + ('fail_safe_mode', 'fail_safe_reason'))
    assert QuarterCarState.get_fields_and_field_types()['sequence'] == 'uint64'
    assert (QuarterCarState.MODE_NORMAL, QuarterCarState.MODE_FAIL_SAFE) == (0, 1)


@pytest.mark.slow
def test_venv_python_needs_no_environment_variable():
    """A node started by hand (README) gets no LD_LIBRARY_PATH, PYTHONPATH, AMENT_PREFIX_PATH."""
    code = ('import sys; from mr_damper_interfaces.msg import QuarterCarState as Q; '
            'from rclpy.serialization import serialize_message as s, deserialize_message as d; '
            'm = Q(tyre_load_n=3531.6, fail_safe_reason="stale"); '
            'assert d(s(m), Q) == m; print(sys.prefix)')
    env = {'PATH': '/usr/bin:/bin', 'HOME': os.environ.get('HOME', '/tmp'),
           'ROS_LOG_DIR': os.environ['ROS_LOG_DIR']}
    out = subprocess.run([sys.executable, '-c', code], env=env, capture_output=True, text=True,
                         timeout=60)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == sys.prefix


def test_kwok_fields_are_the_model_parameter_names():
    assert KWOK_FIELDS[:10] == KwokCurrent.param_names


def test_installed_definitions_are_the_sources():
    """A stale venv (sources changed, not rebuilt) fails here."""
    installed = bag_types.interfaces_msg_dir()
    names = sorted(p.name for p in SRC_MSG.glob('*.msg'))
    assert names == ['ChassisSensors.msg', 'DamperModel.msg', 'DamperSamples.msg',
                     'FullCarCommand.msg', 'FullCarState.msg', 'KwokParameters.msg',
                     'QuarterCarState.msg', 'RoadPreview.msg']
    assert sorted(p.name for p in installed.glob('*.msg')) == names
    for name in names:
        assert (installed / name).read_text() == (SRC_MSG / name).read_text()


def test_ament_index_finds_the_package(monkeypatch):
    from ament_index_python.packages import get_package_share_directory
    monkeypatch.setenv('AMENT_PREFIX_PATH', sys.prefix)
    share = Path(get_package_share_directory('mr_damper_interfaces'))
    assert share == bag_types.interfaces_msg_dir().parent


@pytest.mark.parametrize('make, cls', [(kwok_message, KwokParameters),
                                       (state_message, QuarterCarState),
                                       (chassis_message, ChassisSensors),
                                       (full_car_state_message, FullCarState),
                                       (full_car_command_message, FullCarCommand),
                                       (road_preview_message, RoadPreview)])
def test_rclpy_serialization_round_trip(make, cls):
    msg = make()
    back = deserialize_message(serialize_message(msg), cls)
    assert back is not msg
    assert_values_equal(back, msg)


def assert_values_equal(have, want):
    """Assert two rclpy messages hold the same values, recursively (NaN equals NaN)."""
    for name in want.get_fields_and_field_types():
        a, b = getattr(have, name), getattr(want, name)
        if hasattr(b, 'get_fields_and_field_types'):
            assert_values_equal(a, b)
        elif isinstance(b, (str, bytes, bool, int)) or (
                isinstance(b, list) and b and isinstance(b[0], str)):
            assert a == b, name
        else:
            np.testing.assert_array_equal(a, b, err_msg=name)


def test_full_car_messages_carry_four_corners_and_the_modes():
    cmd = FullCarCommand()
    assert len(cmd.current_a) == len(cmd.mode) == len(cmd.reason) == 4
    assert (FullCarCommand.MODE_NORMAL, FullCarCommand.MODE_FAIL_SAFE,
            FullCarCommand.MODE_INACTIVE) == (0, 1, 2)
    state = FullCarState()
    assert all(len(getattr(state, f)) == 4 for f in (
        'suspension_travel_m', 'suspension_velocity_m_s', 'tyre_deflection_m',
        'wheel_velocity_m_s', 'damper_force_n'))


class Participant:
    """One node in a context of its own (a separate DDS participant) with its executor."""

    def __init__(self, name, context):
        self.context = context
        self.node = rclpy.create_node(name, context=context)
        self.executor = SingleThreadedExecutor(context=context)
        self.executor.add_node(self.node)

    def close(self):
        self.executor.shutdown()
        self.node.destroy_node()


@pytest.fixture
def two_nodes():
    with ros_context() as talking, ros_context() as listening:
        talker = Participant('iface_talker', talking)
        try:
            listener = Participant('iface_listener', listening)
            try:
                yield talker, listener
            finally:
                listener.close()
        finally:
            talker.close()


def spin_until(participants, condition, what):
    """Spin both participants until ``condition()`` (hang guard only, never a timing check)."""
    end = time.monotonic() + HANG_GUARD_S
    while not condition():
        assert time.monotonic() < end, f'hang guard: {what} did not happen'
        for p in participants:
            p.executor.spin_once(timeout_sec=0.01)


@pytest.mark.integration
@pytest.mark.parametrize('topic, make, cls', [
    ('/test_interfaces/kwok_parameters', kwok_message, KwokParameters),
    ('/test_interfaces/state', state_message, QuarterCarState),
    ('/test_interfaces/road_preview', road_preview_message, RoadPreview),
    ('/diagnostics', None, DiagnosticArray),
])
def test_publish_and_receive_between_two_nodes(two_nodes, topic, make, cls):
    talker, listener = two_nodes
    got = []
    listener.node.create_subscription(cls, topic, got.append, 10)
    pub = talker.node.create_publisher(cls, topic, 10)
    spin_until(two_nodes, lambda: pub.get_subscription_count() >= 1, 'discovery')
    if make is None:
        msg = DiagnosticArray()
        msg.header.stamp = Time(sec=5)
        msg.status = [DiagnosticStatus(level=DiagnosticStatus.WARN, name='quarter_car: supervisor',
                                       message='fail-safe: stale', hardware_id='mr_damper',
                                       values=[KeyValue(key='failsafe_s', value='1.25')])]
    else:
        msg = make()
    pub.publish(msg)
    spin_until(two_nodes, lambda: len(got) >= 1, 'delivery')
    if cls is RoadPreview:                  # a NaN height (not measured) is not == itself
        assert len(got) == 1
        assert_values_equal(got[0], msg)
    else:
        assert got == [msg]
    if cls is DiagnosticArray:
        status = got[0].status[0]
        assert (status.level, status.values[0].key) == (DiagnosticStatus.WARN, 'failsafe_s')


def read_mcap_schemas(path):
    """
    Return ``{name: (encoding, text)}`` of the Schema records of an MCAP file.

    A minimal reader of the MCAP record framing (opcode u8, length u64, then the record; schema
    = id u16, name, encoding, data as u32-prefixed strings), independent of rosbags.
    """
    data = Path(path).read_bytes()
    magic = b'\x89MCAP0\r\n'
    assert data[:8] == magic and data[-8:] == magic, 'not an MCAP file'
    pos, schemas = 8, {}
    while pos < len(data) - 8:
        opcode, length = struct.unpack_from('<BQ', data, pos)
        body = data[pos + 9:pos + 9 + length]
        pos += 9 + length
        if opcode != 0x03:
            continue
        fields, off = [], 2
        for _ in range(3):
            (n,) = struct.unpack_from('<I', body, off)
            fields.append(body[off + 4:off + 4 + n])
            off += 4 + n
        schemas[fields[0].decode()] = (fields[1].decode(), fields[2].decode())
    return schemas


def test_mcap_has_typed_schema_and_round_trips(tmp_path):
    typestore = bag_types.suite_typestore()
    bag = tmp_path / 'typed_bag'
    sent = {'/mr_damper/kwok_parameters': (KwokParameters, [kwok_message()]),
            '/quarter_car/state': (QuarterCarState, [state_message(), QuarterCarState()])}
    with Writer(bag, version=9, storage_plugin=StoragePlugin.MCAP) as writer:
        t_ns = 1_000_000_000
        for topic, (cls, msgs) in sent.items():
            typename = f'mr_damper_interfaces/msg/{cls.__name__}'
            conn = writer.add_connection(topic, typename, typestore=typestore)
            for msg in msgs:
                # bytes from rclpy (the generated C type support), framed by rosbags' schema
                writer.write(conn, t_ns, serialize_message(msg))
                t_ns += 1_000_000

    schemas = read_mcap_schemas(next(bag.glob('*.mcap')))
    for name, fields in (('KwokParameters', KWOK_FIELDS), ('QuarterCarState', STATE_FLOATS)):
        encoding, text = schemas[f'mr_damper_interfaces/msg/{name}']
        assert encoding == 'ros2msg'
        lines = text.split('=' * 80)[0].splitlines()
        for field in fields:
            assert any(line.split()[-1:] == [field] for line in lines), (name, field)
    assert 'float64 c0' in schemas['mr_damper_interfaces/msg/KwokParameters'][1]
    assert 'uint8 MODE_FAIL_SAFE=1' in schemas['mr_damper_interfaces/msg/QuarterCarState'][1]

    received = {topic: [] for topic in sent}
    with AnyReader([bag], default_typestore=bag_types.suite_typestore()) as reader:
        for conn, _, raw in reader.messages(connections=reader.connections):
            received[conn.topic].append((reader.deserialize(raw, conn.msgtype),
                                         deserialize_message(bytes(raw),
                                                             sent[conn.topic][0])))
    for topic, (cls, msgs) in sent.items():
        assert [rcl for _, rcl in received[topic]] == msgs
        for (typed, _), msg in zip(received[topic], msgs):
            assert_same(typed, msg)   # rosbags decodes every field to the value sent
    typed_kwok = received['/mr_damper/kwok_parameters'][0][0]
    assert (typed_kwok.window_end.sec, typed_kwok.window_end.nanosec) == (12, 999_999_999)
    assert typed_kwok.reason == 'nrmse_too_high'


def test_full_car_messages_in_a_typed_mcap(tmp_path):
    # the vehicle computer's three messages are recorded with their ros2msg schema and read
    # back by rosbags byte for byte (NaN fields included)
    typestore = bag_types.suite_typestore()
    bag = tmp_path / 'vehicle_bag'
    sent = {'/vehicle/chassis_sensors': (ChassisSensors, chassis_message()),
            '/vehicle/state': (FullCarState, full_car_state_message()),
            '/vehicle/command': (FullCarCommand, full_car_command_message()),
            '/full_car/road_preview': (RoadPreview, road_preview_message())}
    with Writer(bag, version=9, storage_plugin=StoragePlugin.MCAP) as writer:
        for k, (topic, (cls, msg)) in enumerate(sent.items()):
            conn = writer.add_connection(topic, f'mr_damper_interfaces/msg/{cls.__name__}',
                                         typestore=typestore)
            writer.write(conn, 1_000_000 * (k + 1), serialize_message(msg))
    schemas = read_mcap_schemas(next(bag.glob('*.mcap')))
    assert 'string[4] reason' in schemas['mr_damper_interfaces/msg/FullCarCommand'][1]
    with AnyReader([bag], default_typestore=typestore) as reader:
        for conn, _, raw in reader.messages(connections=reader.connections):
            cls, msg = sent[conn.topic]
            typed = reader.deserialize(raw, conn.msgtype)
            assert typed.sequence == msg.sequence
            assert_values_equal(deserialize_message(bytes(raw), cls), msg)
