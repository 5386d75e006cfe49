"""Replay readers (CSV, rosbag2 sqlite3 / MCAP), bag writer, and replay pacing sources."""
import math

import numpy as np
import pytest

from conftest import csv_text, QUIROZ_DIR
from mr_damper_model.io.data import DamperData, DataError
from mr_damper_rig import replay

QUIROZ = QUIROZ_DIR / 'quiroz_sine_5mm3Hz_0p5A.csv.gz'


def small(n=200, t0=5.0):
    t = t0 + np.arange(n) * 1e-3
    return DamperData(t, 0.01 * np.sin(t), 0.01 * np.cos(t), 100 * np.sin(3 * t),
                      np.full(n, 0.5))


def test_csv_stream_reads_the_shipped_quiroz_file():
    d = replay.read_csv_stream(QUIROZ)
    assert d.n > 1000 and d.sample_rate_hz == pytest.approx(1000.0, rel=1e-6)
    assert np.all(d.i == 0.5) and np.all(np.diff(d.t) > 0)


def test_csv_stream_of_a_gzip_file_equals_the_plain_one_and_a_cut_one_fails(tmp_path):
    plain = tmp_path / 'q.csv'
    plain.write_text(csv_text(QUIROZ))
    a, b = replay.read_stream('csv', plain), replay.read_stream('csv', QUIROZ)
    for c in 'txvfi':
        np.testing.assert_array_equal(getattr(b, c), getattr(a, c))
    cut = tmp_path / 'cut.csv.gz'
    cut.write_bytes(QUIROZ.read_bytes()[:-100])
    with pytest.raises(DataError, match=f'{cut}: truncated or corrupt gzip file'):
        replay.read_csv_stream(cut)


@pytest.mark.parametrize('storage', ['sqlite3', 'mcap'])
def test_bag_round_trip_is_exact(tmp_path, storage):
    d = small()
    replay.write_bag(tmp_path / 'bag', d, storage=storage)
    assert replay.bag_topics(tmp_path / 'bag') == {
        replay.MEASUREMENT_TOPIC: (replay.JOINTSTATE_TYPE, d.n)}
    back = replay.read_bag(tmp_path / 'bag')
    for c in 'xvfi':
        np.testing.assert_array_equal(getattr(back, c), getattr(d, c))
    np.testing.assert_allclose(back.t, d.t, rtol=0, atol=1e-9)   # ns stamps
    back2 = replay.read_stream('bag', tmp_path / 'bag')
    np.testing.assert_array_equal(back2.f, d.f)


def test_replay_reads_bags_with_the_model_package_reader(tmp_path):
    """One home for measurement bags: replay = mr_damper_model.io.bag_io + the stream checks."""
    from mr_damper_model.io import bag_io
    assert replay.BagWriter is bag_io.BagWriter and replay.write_bag is bag_io.write_bag
    assert replay.MEASUREMENT_TOPIC == bag_io.MEASUREMENT_TOPIC
    d = small()
    bag_io.write_bag(tmp_path / 'bag', d, topic='/only', storage='mcap')
    back = replay.read_bag(tmp_path / 'bag', None)       # the bag's only JointState topic
    np.testing.assert_array_equal(back.f, bag_io.read_bag(tmp_path / 'bag').f)
    np.testing.assert_array_equal(back.f, d.f)


def test_bag_on_other_topic_and_missing_topic(tmp_path):
    replay.write_bag(tmp_path / 'bag', small(), topic='/rig/daq', storage='mcap')
    assert replay.read_bag(tmp_path / 'bag', '/rig/daq').n == 200
    with pytest.raises(DataError, match=r'bag: no topic /mr_damper/measurement .*/rig/daq'):
        replay.read_bag(tmp_path / 'bag')


@pytest.mark.slow
def test_bag_with_wrong_type_names_or_values(tmp_path):
    from rosbags.rosbag2 import StoragePlugin, Writer
    from rosbags.typesys import Stores, get_typestore
    ts = get_typestore(Stores.ROS2_KILTED)
    Float64 = ts.types['std_msgs/msg/Float64']
    with Writer(tmp_path / 'wrongtype', version=9, storage_plugin=StoragePlugin.SQLITE3) as w:
        c = w.add_connection(replay.MEASUREMENT_TOPIC, 'std_msgs/msg/Float64', typestore=ts)
        w.write(c, 1, ts.serialize_cdr(Float64(data=1.0), 'std_msgs/msg/Float64'))
    with pytest.raises(DataError, match='wrongtype: topic .* has type std_msgs/msg/Float64'):
        replay.read_bag(tmp_path / 'wrongtype')
    # out-of-order stamps and NaN: the whole bag is refused, naming the sample
    d = small()
    t = d.t.copy()
    t[50] = t[49]
    replay.write_bag(tmp_path / 'dup', DamperData(t, d.x, d.v, d.f, d.i))
    with pytest.raises(DataError, match='dup: time is not strictly increasing at sample 50'):
        replay.read_bag(tmp_path / 'dup')
    f = d.f.copy()
    f[7] = math.nan
    replay.write_bag(tmp_path / 'nan', DamperData(d.t, d.x, d.v, f, d.i))
    with pytest.raises(DataError, match='nan: column f has 1 NaN/inf value.*sample 7'):
        replay.read_bag(tmp_path / 'nan')


def test_bag_wrong_joint_names(tmp_path):
    from rosbags.rosbag2 import StoragePlugin, Writer
    from rosbags.typesys import Stores, get_typestore
    ts = get_typestore(Stores.ROS2_KILTED)
    T = ts.types
    msg = T['sensor_msgs/msg/JointState'](
        header=T['std_msgs/msg/Header'](
            stamp=T['builtin_interfaces/msg/Time'](sec=1, nanosec=0), frame_id=''),
        name=['a', 'b'], position=np.zeros(2), velocity=np.zeros(2), effort=np.zeros(2))
    with Writer(tmp_path / 'names', version=9, storage_plugin=StoragePlugin.MCAP) as w:
        c = w.add_connection(replay.MEASUREMENT_TOPIC, replay.JOINTSTATE_TYPE, typestore=ts)
        w.write(c, 1, ts.serialize_cdr(msg, replay.JOINTSTATE_TYPE))
    with pytest.raises(DataError, match=r"names: message 0 has joints \['a', 'b'\]"):
        replay.read_bag(tmp_path / 'names')


def test_not_a_bag_and_bad_csv(tmp_path):
    with pytest.raises(DataError, match='nowhere: bag not found'):
        replay.read_bag(tmp_path / 'nowhere')
    (tmp_path / 'dir').mkdir()
    with pytest.raises(DataError, match='not a rosbag2 directory'):
        replay.read_bag(tmp_path / 'dir')
    bad = tmp_path / 'bad.csv'
    bad.write_text('t,x,v,f,i\n0,0,0,0,0\n0.001,0,0,x,0\n')
    with pytest.raises(DataError, match="bad.csv: line 3 column f: 'x' is not a number"):
        replay.read_stream('csv', bad)
    back = tmp_path / 'back.csv'
    back.write_text('t,x,v,f,i\n0,0,0,0,0\n0.002,0,0,1,0\n0.001,0,0,2,0\n')
    with pytest.raises(DataError, match='back.csv: time is not strictly increasing'):
        replay.read_csv_stream(back)
    neg = tmp_path / 'neg.csv'
    neg.write_text('t,x,v,f,i\n-1,0,0,0,0\n0,0,0,1,0\n')
    with pytest.raises(DataError, match='neg.csv: negative time stamp'):
        replay.read_csv_stream(neg)
    with pytest.raises(ValueError, match='`mode`'):
        replay.read_stream('wav', bad)


def test_array_source_keeps_original_timing_and_loops_with_increasing_stamps():
    d = small(n=100, t0=2.0)            # 2.000 .. 2.099 s
    src = replay.ArraySource(d)
    assert src.count_due(0.0) == 1 and src.count_due(0.0495) == 50
    assert src.count_due(10.0) == 100 == src.total()
    looped = replay.ArraySource(d, loop=True)
    assert looped.total() is None
    assert looped.period == pytest.approx(0.1)
    assert looped.count_due(0.1 + 0.0495) == 150
    stamps = np.array([looped.sample(k)[0] for k in range(300)])
    assert np.all(np.diff(stamps) > 0)
    np.testing.assert_allclose(np.diff(stamps), 1e-3, atol=1e-9)
    assert looped.sample(157)[1:] == src.sample(57)[1:]
    offset = replay.ArraySource(d, offset_s=100.0)
    assert offset.sample(0)[0] == pytest.approx(102.0)


def test_sim_source_counts_exact_rate():
    src = replay.SimSource(rig=None, rate_hz=1000.0, t0_s=0.0, duration_s=2.5)
    assert src.count_due(0.0) == 1 and src.count_due(1.0) == 1001
    assert src.total() == 2500
    assert replay.SimSource(None, 1000.0, 0.0, 0.0).total() is None
