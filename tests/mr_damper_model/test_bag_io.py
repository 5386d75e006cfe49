"""Measurement bags without ROS: reading (sqlite3, MCAP, single files), writing, errors."""
import numpy as np
import pytest

from conftest import QUIROZ_DIR
from mr_damper_model.io import bag_io
from mr_damper_common.contract import COIL_JOINT, PISTON_JOINT
from mr_damper_model.io.data import DamperData, DataError, read_csv

QFILE = QUIROZ_DIR / 'quiroz_sine_2mm5Hz_0p5A.csv.gz'
PLUGINS = {'sqlite3': 'SQLITE3', 'mcap': 'MCAP'}


def rosbags_write(path, data, *, storage, topic=bag_io.MEASUREMENT_TOPIC, joints=None,
                  extra_topics=()):
    """Write ``data`` as JointState CDR messages with plain rosbags (the reference writer)."""
    from rosbags.rosbag2 import StoragePlugin, Writer
    from rosbags.typesys import get_typestore, Stores
    ts = get_typestore(Stores.ROS2_KILTED)
    T = ts.types
    joints = joints or [PISTON_JOINT, COIL_JOINT]
    with Writer(path, version=9, storage_plugin=getattr(StoragePlugin, PLUGINS[storage])) as w:
        conns = [w.add_connection(tp, bag_io.JOINTSTATE_TYPE, typestore=ts)
                 for tp in (topic, *extra_topics)]
        for t, x, v, f, i in zip(data.t, data.x, data.v, data.f, data.i):
            ns = int(round(t * 1e9))
            msg = T[bag_io.JOINTSTATE_TYPE](
                header=T['std_msgs/msg/Header'](stamp=T['builtin_interfaces/msg/Time'](
                    sec=ns // 10 ** 9, nanosec=ns % 10 ** 9), frame_id='rig'),
                name=list(joints), position=np.array([x, np.nan]),
                velocity=np.array([v, np.nan]), effort=np.array([f, i]))
            raw = ts.serialize_cdr(msg, bag_io.JOINTSTATE_TYPE)
            for c in conns:
                w.write(c, ns, raw)
    return path


def assert_same_samples(back, ref):
    for c in 'xvfi':
        np.testing.assert_array_equal(getattr(back, c), getattr(ref, c))
    np.testing.assert_allclose(back.t, ref.t, rtol=0, atol=1e-9)    # integer ns stamps


@pytest.mark.parametrize('storage', ['sqlite3', 'mcap'])
def test_bag_of_a_csv_reads_back_equal_to_the_csv(tmp_path, storage):
    csv = read_csv(QFILE)
    bag = rosbags_write(tmp_path / 'bag', csv, storage=storage)
    back = bag_io.read_bag(bag)
    assert back.source == str(bag)
    assert_same_samples(back, csv)
    # the storage file alone (no metadata.yaml) reads the same
    single = next(p for p in bag.iterdir() if p.suffix in bag_io.BAG_SUFFIXES)
    assert bag_io.is_bag(single) and bag_io.is_bag(bag) and not bag_io.is_bag(QFILE)
    assert_same_samples(bag_io.read_bag(single), csv)
    assert bag_io.bag_topics(bag) == {bag_io.MEASUREMENT_TOPIC: (bag_io.JOINTSTATE_TYPE, csv.n)}


@pytest.mark.parametrize('storage', ['sqlite3', 'mcap'])
def test_write_bag_round_trip(tmp_path, storage):
    d = read_csv(QFILE).select(slice(0, 300))
    bag_io.write_bag(tmp_path / 'w', d, storage=storage)
    assert_same_samples(bag_io.read_bag(tmp_path / 'w'), d)
    with pytest.raises(ValueError, match='already exists'):
        bag_io.write_bag(tmp_path / 'w', d)
    with pytest.raises(ValueError, match='`storage`'):
        bag_io.write_bag(tmp_path / 'x', d, storage='wav')


@pytest.mark.parametrize('storage', ['sqlite3', 'mcap'])
def test_batched_bags_as_the_rig_publishes_read_back_the_same_samples(tmp_path, storage):
    d = read_csv(QFILE).select(slice(0, 1013))
    assert d.n % 20                                   # a partial last batch
    bag_io.write_bag(tmp_path / 'b', d, storage=storage, samples_per_message=20)
    topics = bag_io.bag_topics(tmp_path / 'b')
    assert topics == {bag_io.MEASUREMENT_TOPIC: (bag_io.SAMPLES_TYPE, -(-d.n // 20))}
    back = bag_io.read_bag(tmp_path / 'b')
    assert back.n == d.n
    np.testing.assert_allclose(back.t, d.t, rtol=0, atol=2e-9)   # ns stamp + offset
    for c in 'xvfi':
        np.testing.assert_array_equal(getattr(back, c), getattr(d, c))


@pytest.mark.slow
def test_topic_choice(tmp_path):
    d = read_csv(QFILE).select(slice(0, 100))
    one = rosbags_write(tmp_path / 'one', d, storage='mcap', topic='/daq/joints')
    assert_same_samples(bag_io.read_bag(one), d)              # the only JointState topic
    assert_same_samples(bag_io.read_bag(one, '/daq/joints'), d)
    with pytest.raises(DataError, match=r'one: no topic /nope in the bag \(topics: /daq/joints\)'):
        bag_io.read_bag(one, '/nope')
    two = rosbags_write(tmp_path / 'two', d, storage='sqlite3', topic='/a', extra_topics=['/b'])
    with pytest.raises(DataError, match='two: no topic /mr_damper/measurement and several '
                       'measurement topics .*/a, /b.*--topic'):
        bag_io.read_bag(two)
    assert_same_samples(bag_io.read_bag(two, '/b'), d)
    # the rig's topic wins over other JointState topics
    both = rosbags_write(tmp_path / 'both', d, storage='mcap', extra_topics=['/other'])
    assert bag_io.read_bag(both).n == d.n


def test_wrong_joint_names_and_type(tmp_path):
    d = read_csv(QFILE).select(slice(0, 20))
    bad = rosbags_write(tmp_path / 'names', d, storage='mcap', joints=['a', 'b'])
    with pytest.raises(DataError, match=r"names: message 0 has joints \['a', 'b'\], expected"):
        bag_io.read_bag(bad)
    from rosbags.rosbag2 import StoragePlugin, Writer
    from rosbags.typesys import get_typestore, Stores
    ts = get_typestore(Stores.ROS2_KILTED)
    with Writer(tmp_path / 'f64', version=9, storage_plugin=StoragePlugin.SQLITE3) as w:
        c = w.add_connection(bag_io.MEASUREMENT_TOPIC, 'std_msgs/msg/Float64', typestore=ts)
        w.write(c, 1, ts.serialize_cdr(ts.types['std_msgs/msg/Float64'](data=1.0),
                                       'std_msgs/msg/Float64'))
    with pytest.raises(DataError, match='f64: topic .* has type std_msgs/msg/Float64'):
        bag_io.read_bag(tmp_path / 'f64')
    with Writer(tmp_path / 'empty', version=9, storage_plugin=StoragePlugin.MCAP):
        pass
    with pytest.raises(DataError, match=r'empty: no topic /mr_damper/measurement and no '
                       r'DamperSamples or JointState topic in the bag \(topics: none\)'):
        bag_io.read_bag(tmp_path / 'empty')


@pytest.mark.parametrize('storage', ['sqlite3', 'mcap'])
def test_truncated_or_corrupt_storage_is_one_error(tmp_path, storage):
    d = read_csv(QFILE)
    bag = rosbags_write(tmp_path / 'bag', d, storage=storage)
    single = next(p for p in bag.iterdir() if p.suffix in bag_io.BAG_SUFFIXES)
    raw = single.read_bytes()
    cut = tmp_path / f'cut{single.suffix}'
    cut.write_bytes(raw[:len(raw) // 2])
    with pytest.raises(DataError, match=f'cut{single.suffix}: cannot (read|open) bag'):
        bag_io.read_bag(cut)
    junk = tmp_path / f'junk{single.suffix}'
    junk.write_bytes(b'\x00not a bag\x00' * 100)
    with pytest.raises(DataError, match=f'junk{single.suffix}: cannot (read|open) bag'):
        bag_io.read_bag(junk)
    with pytest.raises(DataError, match=f'junk{single.suffix}: cannot open bag'):
        bag_io.bag_topics(junk)


def test_not_a_bag(tmp_path):
    with pytest.raises(DataError, match='nowhere: bag not found'):
        bag_io.read_bag(tmp_path / 'nowhere')
    (tmp_path / 'dir').mkdir()
    with pytest.raises(DataError, match='dir: not a rosbag2 directory'):
        bag_io.read_bag(tmp_path / 'dir')
    with pytest.raises(DataError, match='not a rosbag2 directory or a .db3/.mcap file'):
        bag_io.read_bag(QFILE)
    assert not bag_io.is_bag(tmp_path / 'dir')


def test_values_are_returned_as_recorded(tmp_path):
    """Checks (time order, NaN) are the caller's: the reader keeps every sample."""
    d = read_csv(QFILE).select(slice(0, 50))
    f = d.f.copy()
    f[7] = np.nan
    bag = rosbags_write(tmp_path / 'nan', DamperData(d.t, d.x, d.v, f, d.i), storage='mcap')
    back = bag_io.read_bag(bag)
    assert back.n == 50 and np.isnan(back.f[7]) and np.isnan(back.f).sum() == 1
