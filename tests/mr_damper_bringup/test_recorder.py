"""Tests of mr_damper_bringup.recorder (one MCAP of every suite topic) and topics, without ROS."""
import tracemalloc

import numpy as np
import pytest
from rosbags.highlevel import AnyReader

from mr_damper_bringup import topics
from mr_damper_bringup.recorder import (part_path, recording_parts, remove_recording,
                                        SuiteRecorder, work_file)
from mr_damper_model.io.bag_types import suite_typestore

TS = suite_typestore()


def _stamp(t):
    sec, nsec = divmod(int(round(t * 1e9)), 1_000_000_000)
    return TS.types['std_msgs/msg/Header'](
        stamp=TS.types['builtin_interfaces/msg/Time'](sec=sec, nanosec=nsec), frame_id='x')


def _joint_state(k):
    return TS.types[topics.JOINT_STATE](
        header=_stamp(0.001 * k), name=['mr_damper_piston', 'mr_damper_coil'],
        position=np.array([0.01 * k, np.nan]), velocity=np.array([-0.2, np.nan]),
        effort=np.array([100.0 + k, 0.5]))


def _samples(k, n=20):
    """Batch ``k`` of ``n`` samples at 1 kHz, as the rig publishes them."""
    offsets = np.arange(n) * 1e-3
    return TS.types[topics.DAMPER_SAMPLES](
        header=_stamp(0.001 * n * k), sequence=k, first_index=n * k, sample_period_s=1e-3,
        t_offset_s=offsets, x_m=0.01 * np.sin(offsets + k), v_m_s=np.full(n, -0.2),
        f_n=100.0 + offsets, i_a=np.full(n, 0.5))


def _time(t):
    sec, nsec = divmod(int(round(t * 1e9)), 1_000_000_000)
    return TS.types['builtin_interfaces/msg/Time'](sec=sec, nanosec=nsec)


def _kwok(k):
    cls = TS.types[topics.KWOK]
    values = {name: float(j + k) for j, name in enumerate(cls.__dataclass_fields__)
              if name not in ('header', 'window_start', 'window_end', 'valid', 'reason')
              and name != '__msgtype__'}
    return cls(header=_stamp(0.001 * k), window_start=_time(k), window_end=_time(k + 2.0),
               valid=bool(k % 2), reason='' if k % 2 else 'nrmse_above_threshold', **values)


def _damper_model(k):
    return TS.types[topics.DAMPER_MODEL](
        header=_stamp(0.001 * k), model='spencer', parameter_names=['c0a', 'gamma'],
        parameter_values=np.array([784.0 + k, 136320.0]), option_names=[],
        option_values=np.array([], dtype=float))


def _diagnostics(k):
    kv = TS.types['diagnostic_msgs/msg/KeyValue']
    st = TS.types['diagnostic_msgs/msg/DiagnosticStatus']
    return TS.types[topics.DIAGNOSTICS](header=_stamp(0.001 * k), status=[
        st(level=k % 3, name='mr_damper_rig', message='running', hardware_id='mr_damper',
           values=[kv(key='samples_published', value=str(100 * k))])])


def _car_state(k):
    cls = TS.types[topics.CAR_STATE]
    values = {name: float(j + k) for j, name in enumerate(cls.__dataclass_fields__)
              if name not in ('header', 'sequence', 'fail_safe_mode', 'fail_safe_reason')
              and not name.isupper() and name != '__msgtype__'}
    return cls(header=_stamp(0.001 * k), sequence=k, fail_safe_mode=1, fail_safe_reason='stale',
               **values)


#: a message builder for every type of the topic table (a new type needs one here)
BUILDERS = {
    topics.JOINT_STATE: _joint_state,
    topics.DAMPER_SAMPLES: _samples,
    topics.KWOK: _kwok,
    topics.DAMPER_MODEL: _damper_model,
    topics.DIAGNOSTICS: _diagnostics,
    topics.FLOAT64: lambda k: TS.types[topics.FLOAT64](data=0.25 * k),
    topics.UINT64: lambda k: TS.types[topics.UINT64](data=1000 * k),
    topics.STRING: lambda k: TS.types[topics.STRING](data=f'{{"n": {k}}}'),
    topics.CAR_STATE: _car_state,
}


def test_every_suite_type_round_trips_through_one_mcap(tmp_path):
    assert {row.type for row in topics.SUITE_TOPICS.values()} <= set(BUILDERS)
    path = tmp_path / 'suite.mcap'
    sent = {}
    with SuiteRecorder(path, config_text='a: 1.0\n', typestore=TS, start_ns=10) as rec:
        for k in range(3):
            for key, row in topics.SUITE_TOPICS.items():
                raw = TS.serialize_cdr(BUILDERS[row.type](k), row.type)
                rec.write(key, raw, 1_000 + 10 * k)
                sent.setdefault(key, []).append(raw)
    assert rec.counts == {key: 3 for key in topics.SUITE_TOPICS}
    # one file, the working folder is gone
    assert path.is_file() and [p.name for p in tmp_path.iterdir()] == ['suite.mcap']
    got = {}
    with AnyReader([path], default_typestore=TS) as reader:
        by_topic = {row.name: key for key, row in topics.SUITE_TOPICS.items()}
        by_topic[topics.CONFIG_TOPIC.name] = 'config'
        for conn in reader.connections:
            # typed schema: the full message definition with named fields
            assert conn.msgdef.data, conn.topic
        schema = {c.topic: c.msgdef.data for c in reader.connections}
        assert 'float64 body_displacement_m' in schema['/quarter_car/car_state']
        for conn, t, raw in reader.messages():
            msg = reader.deserialize(raw, conn.msgtype)
            got.setdefault(by_topic[conn.topic], []).append(
                (t, TS.serialize_cdr(msg, conn.msgtype)))
    assert [raw for _, raw in got.pop('config')] == [
        TS.serialize_cdr(TS.types[topics.STRING](data='a: 1.0\n'), topics.STRING)]
    assert set(got) == set(sent)
    for key, msgs in got.items():
        assert [t for t, _ in msgs] == [1_000, 1_010, 1_020], key
        assert [bytes(raw) for _, raw in msgs] == sent[key], key


def test_rclpy_payloads_read_back_with_the_suite_decoders(tmp_path):
    """What the node writes (rclpy CDR) decodes with the one decoder of each kind."""
    from rclpy.serialization import serialize_message

    from mr_damper_common import messages as mm
    from mr_damper_common.contract import KWOK_CURRENT_NAMES
    from mr_damper_common.health import Health, WARN
    status = {'samples_received': 12, 'mode': 'normal', 'windows_skipped': {'gap': 2}}
    diag = mm.diagnostic_array_msg([mm.diagnostic_status_msg(
        'fl/mr_damper_identifier', Health(WARN, 'gap', status))], stamp_s=2.0)
    params = dict({n: float(k) for k, n in enumerate(KWOK_CURRENT_NAMES)}, valid=True,
                  window_end_s=3.5)
    truth = mm.damper_model_msg('spencer', {'c0a': 784.0, 'gamma': 136320.0})
    path = tmp_path / 'r.mcap'
    with SuiteRecorder(path, typestore=TS) as rec:
        batch = mm.samples_to_msg([1.5, 1.501], [0.01, 0.02], [-0.2, -0.1], [80.0, 81.0],
                                  [0.5, 0.5], sequence=3, first_index=60)
        rec.write('measurement', serialize_message(batch), 5)
        rec.write('diagnostics', serialize_message(diag), 6)
        rec.write('parameters', serialize_message(mm.kwok_parameters_msg(params)), 7)
        rec.write('truth_spencer', serialize_message(truth), 8)
    with AnyReader([path], default_typestore=TS) as reader:
        msgs = {c.topic: reader.deserialize(raw, c.msgtype)
                for c, _, raw in reader.messages()}
    assert rec.counts['measurement'] == 1 and rec.measurements() == 2   # samples, not messages
    t, x, v, f, i = topics.decode_measurement(msgs['/mr_damper/measurement'])
    np.testing.assert_allclose(t, [1.5, 1.501], rtol=0, atol=1e-9)
    assert [x.tolist(), v.tolist(), f.tolist(), i.tolist()] == [
        [0.01, 0.02], [-0.2, -0.1], [80.0, 81.0], [0.5, 0.5]]
    expected = {'fl/identifier': dict(status, level=WARN, message='gap')}
    assert topics.decode_status('diagnostics', msgs['/diagnostics']) == expected
    d = topics.decode_parameters(msgs['/mr_damper/kwok_parameters'])
    assert d['valid'] == 1.0 and all(d[n] == params[n] for n in KWOK_CURRENT_NAMES)
    assert d['window_end_s'] == 3.5
    assert topics.decode_parameters(msgs['/mr_damper/true_spencer_parameters']) == {
        'c0a': 784.0, 'gamma': 136320.0}
    # the same decoders on the rclpy messages (the launcher's monitor)
    assert topics.decode_status('diagnostics', diag) == expected
    assert topics.decode_parameters(mm.kwok_parameters_msg(params))['window_end_s'] == 3.5


def test_bad_arguments_are_refused(tmp_path):
    with pytest.raises(ValueError, match='must end in .mcap'):
        SuiteRecorder(tmp_path / 'x.bag', typestore=TS)
    (tmp_path / 'y.mcap').write_text('')
    with pytest.raises(ValueError, match='already exists'):
        SuiteRecorder(tmp_path / 'y.mcap', typestore=TS)
    bad = {'odd': topics.Topic('/odd', 'nowhere_msgs/msg/Nothing', 'default')}
    with pytest.raises(ValueError, match='not in the type store'):
        SuiteRecorder(tmp_path / 'z.mcap', bad, typestore=TS)
    with pytest.raises(ValueError, match='unknown topic keys'):
        topics.topic_table(['measurement', 'nope'])
    assert list(topics.topic_table(['measurement'])) == ['measurement']


def test_status_decoder_takes_diagnostics_by_node_and_namespace():
    """``{node: dict}`` from /diagnostics; nested values from dotted keys; namespaces kept."""
    kv = TS.types['diagnostic_msgs/msg/KeyValue']
    st = TS.types['diagnostic_msgs/msg/DiagnosticStatus']
    arr = TS.types['diagnostic_msgs/msg/DiagnosticArray'](header=_stamp(1.0), status=[
        st(level=0, name='mr_damper_identifier', message='ok', hardware_id='',
           values=[kv(key='samples_received', value='1200'), kv(key='mode', value='fit')]),
        st(level=1, name='rl/quarter_car_node', message='fail-safe', hardware_id='',
           values=[kv(key='failsafe_s', value='1.5'),
                   kv(key='ride_metrics.rms_body_accel_wk', value='0.93')])])
    assert topics.decode_status('diagnostics', arr) == {
        'identifier': {'samples_received': 1200, 'mode': 'fit', 'level': 0, 'message': 'ok'},
        'rl/quarter_car': {'failsafe_s': 1.5, 'ride_metrics': {'rms_body_accel_wk': 0.93},
                           'level': 1, 'message': 'fail-safe'}}
    assert set(topics.STATUS_KEYS) <= set(topics.SUITE_TOPICS)
    with pytest.raises(ValueError, match='DiagnosticArray'):
        topics.decode_status('diagnostics', TS.types[topics.STRING](data='[1, 2]'))


@pytest.mark.slow
def test_memory_stays_flat_while_recording(tmp_path):
    """20,000 batches of 20 samples (~20 MB of file): the writer holds one chunk, not the run."""
    raw = TS.serialize_cdr(_samples(1), topics.DAMPER_SAMPLES)
    with SuiteRecorder(tmp_path / 'long.mcap', typestore=TS) as rec:
        for k in range(1000):                   # warm up (first chunk, caches)
            rec.write('measurement', raw, k)
        tracemalloc.start()
        for k in range(1000, 21000):
            rec.write('measurement', raw, k)
        _, peak = tracemalloc.get_traced_memory()
        tracemalloc.stop()
        assert rec.measurements() == 21000 * 20
    size = (tmp_path / 'long.mcap').stat().st_size
    assert size > 20000 * len(raw)
    assert peak < 4 * 2 ** 20 < size / 2


def test_namespaced_table_prefixes_every_topic_but_diagnostics():
    table = topics.namespaced_table(topics.topic_table(['measurement', 'diagnostics']),
                                    ['fl', 'fr'])
    assert table == {
        'fl/measurement': topics.SUITE_TOPICS['measurement']._replace(
            name='/fl/mr_damper/measurement'),
        'fr/measurement': topics.SUITE_TOPICS['measurement']._replace(
            name='/fr/mr_damper/measurement'),
        'diagnostics': topics.SUITE_TOPICS['diagnostics']}
    assert topics.namespaced_table(topics.SUITE_TOPICS, []) == topics.SUITE_TOPICS
    with pytest.raises(ValueError, match='plain name'):
        topics.namespaced_table(topics.SUITE_TOPICS, ['/fl'])


def test_measurements_are_counted_in_every_namespace(tmp_path):
    table = topics.namespaced_table(topics.topic_table(['measurement', 'diagnostics']),
                                    ['fl', 'fr'])
    raw = TS.serialize_cdr(BUILDERS[table['fl/measurement'].type](0),
                           table['fl/measurement'].type)
    with SuiteRecorder(tmp_path / 'c.mcap', table, typestore=TS) as rec:
        for key in ('fl/measurement', 'fl/measurement', 'fr/measurement'):
            rec.write(key, raw, 1_000)
        assert rec.measurements() == 3 * 20          # samples: batches of 20


def test_statuses_are_counted_per_node_name(tmp_path):
    """Each status entry of /diagnostics counts under its node's name; a bad payload counts."""
    kv = TS.types['diagnostic_msgs/msg/KeyValue']
    st = TS.types['diagnostic_msgs/msg/DiagnosticStatus']

    def array(*names):
        return TS.serialize_cdr(TS.types[topics.DIAGNOSTICS](header=_stamp(1.0), status=[
            st(level=0, name=n, message='ok', hardware_id='mr_damper',
               values=[kv(key='k', value='1')]) for n in names]), topics.DIAGNOSTICS)

    table = topics.namespaced_table(topics.topic_table(['measurement', 'diagnostics']),
                                    ['fl', 'fr'])
    with SuiteRecorder(tmp_path / 's.mcap', table, typestore=TS) as rec:
        assert rec.statuses == {}
        rec.write('diagnostics', array('fl/quarter_car_node'), 1)
        rec.write('diagnostics', array('fr/mr_damper_rig', 'fl/quarter_car_node: final'), 2)
        rec.write('diagnostics', b'\x00\x01\x00\x00\xff', 3)        # not a DiagnosticArray
        rec.write('fl/measurement', TS.serialize_cdr(_samples(0), topics.DAMPER_SAMPLES), 4)
    assert rec.statuses == {'fl/quarter_car_node': 2, 'fr/mr_damper_rig': 1}
    assert rec.undecodable == {'diagnostics': 1}
    assert rec.counts['diagnostics'] == 3                 # every message written as it came


def test_measurement_batches_lost_on_the_way_are_counted_from_their_sequence(tmp_path):
    """Batches 3, 4 and 7 of one namespace never came, the other lost none: 3 counted there."""
    table = topics.namespaced_table(topics.topic_table(['measurement', 'car_state']),
                                    ['fl', 'fr'])
    with SuiteRecorder(tmp_path / 'g.mcap', table, typestore=TS) as rec:
        got = [rec.write('fl/measurement', TS.serialize_cdr(_samples(k), topics.DAMPER_SAMPLES),
                         k) for k in (0, 1, 2, 5, 6, 8)]
        got += [rec.write('fr/measurement', TS.serialize_cdr(_samples(k), topics.DAMPER_SAMPLES),
                          k) for k in range(4)]
        # a car state with a gap in its numbers is recorded as it came (not a measurement)
        got += [rec.write('fl/car_state', TS.serialize_cdr(_car_state(k), topics.CAR_STATE), k)
                for k in (0, 5)]
    assert got == [0, 0, 0, 2, 0, 1] + [0] * 6
    assert rec.lost == {'fl/measurement': 3, 'fr/measurement': 0}
    assert rec.measurements() == 10 * 20


def test_recording_parts_in_order_finished_or_left_by_a_killed_recorder(tmp_path):
    rec = tmp_path / 'suite.mcap'
    assert part_path(rec, 0) == rec and part_path(rec, 2) == tmp_path / 'suite.2.mcap'
    assert recording_parts(rec) == []
    with SuiteRecorder(part_path(rec, 1), topics.topic_table(['measurement'])) as r:
        r.write('measurement', TS.serialize_cdr(_samples(1), topics.DAMPER_SAMPLES), 1)
    killed = SuiteRecorder(rec, topics.topic_table(['measurement'])).open()   # never closed
    killed.write('measurement', TS.serialize_cdr(_samples(0), topics.DAMPER_SAMPLES), 0)
    (tmp_path / 'suite.10.mcap').write_bytes(b'')          # an empty part (a recorder that
    (tmp_path / 'suites.mcap').write_bytes(b'')            # wrote nothing), not another stem
    assert recording_parts(rec) == [(0, work_file(rec)), (1, part_path(rec, 1)),
                                    (10, tmp_path / 'suite.10.mcap')]
    with pytest.raises(ValueError, match='already exists'):      # never over an earlier part
        SuiteRecorder(part_path(rec, 1))
    remove_recording(rec)
    assert recording_parts(rec) == [] and sorted(p.name for p in tmp_path.iterdir()) == [
        'suites.mcap']


@pytest.mark.parametrize('chunk_s', [1.0, 0.25])
def test_a_killed_recorder_loses_at_most_its_last_chunk_s(tmp_path, chunk_s):
    """Chunks are closed every ``chunk_s`` of log time: a cut file holds all but the last one."""
    from mr_damper_common.recording.mcap_scan import McapScan
    raw = TS.serialize_cdr(_samples(1), topics.DAMPER_SAMPLES)
    rec = SuiteRecorder(tmp_path / 'k.mcap', topics.topic_table(['measurement']), typestore=TS,
                        chunk_s=chunk_s).open()
    n = 1000                                    # 10 s at 100 messages/s: far below 1 MiB
    for k in range(n):
        rec.write('measurement', raw, 10_000_000 * k)
    # killed here: nothing closes the file; read what is on disk
    scan = McapScan(work_file(tmp_path / 'k.mcap'))
    got = [t for _, _, t, _ in scan.messages()]
    assert scan.complete is False
    assert got == [10_000_000 * k for k in range(len(got))]      # the first ones, in order
    per_chunk = int(round(chunk_s / 0.01)) + 1                   # a chunk ends with its span
    assert n - per_chunk <= len(got) < n
    with pytest.raises(ValueError, match='chunk_s'):
        SuiteRecorder(tmp_path / 'x.mcap', chunk_s=-1.0)


def test_a_measurement_message_it_cannot_read_is_written_and_counted(tmp_path):
    """An empty batch from rclpy does not deserialise with rosbags: written, counted, no raise."""
    from rclpy.serialization import serialize_message

    from mr_damper_common import messages as mm
    from mr_damper_interfaces.msg import DamperSamples
    with SuiteRecorder(tmp_path / 'e.mcap', typestore=TS) as rec:
        rec.write('measurement', serialize_message(DamperSamples()), 5)
        batch = mm.samples_to_msg([1.5], [0.0], [0.1], [8.0], [0.5], sequence=1, first_index=0)
        rec.write('measurement', serialize_message(batch), 6)
    assert rec.counts['measurement'] == 2 and rec.measurements() == 1
    assert rec.undecodable == {'measurement': 1}
