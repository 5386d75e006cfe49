"""Tests of mr_damper_common.recording.mcap_scan: a recording cut by its killed writer, read."""
import shutil

import numpy as np
import pytest

from mr_damper_common.recording.mcap_scan import McapScan
from mr_damper_model.io.bag_io import MEASUREMENT_TOPIC, read_bag, write_bag
from mr_damper_model.io.data import DamperData, DataError

N = 20000          # several 1 MiB chunks of the rosbags writer


def _bag(tmp_path):
    """Write N measurements into one MCAP bag; return its file and the samples."""
    t = np.arange(N) * 1e-3
    data = DamperData(t, np.sin(t), np.cos(t), 100.0 * np.sin(t), np.full(N, 0.5))
    write_bag(tmp_path / 'bag', data, storage='mcap')
    return tmp_path / 'bag' / 'bag.mcap', data


def _chunks(path):
    """Return ``[(end offset, messages)]`` of every chunk of a complete file (its index)."""
    from rosbags.rosbag2.storage_mcap import McapReader
    reader = McapReader(path)
    reader.open()
    try:
        return [(c.chunk_start_offset + c.chunk_length, sum(c.channel_count.values()))
                for c in reader.chunks]
    finally:
        reader.close()


@pytest.mark.slow
def test_a_complete_file_reads_whole(tmp_path):
    path, data = _bag(tmp_path)
    scan = McapScan(path)
    stamps = [t for _, _, t, _ in scan.messages()]
    assert scan.complete is True and scan.error is None and scan.count == N
    assert len(stamps) == N and stamps == sorted(stamps)
    assert scan.topics()[MEASUREMENT_TOPIC] == ('sensor_msgs/msg/JointState', N)
    # the front-to-back reader (used for cut files) reads a complete file the same
    stream = [(t, raw) for _, _, t, raw in scan._stream(None)]
    assert scan.complete is True and scan.count == N
    assert stream == [(t, raw) for _, _, t, raw in McapScan(path).messages()]


@pytest.mark.parametrize('where', [0.5, 0.999])
@pytest.mark.slow
def test_a_cut_file_yields_the_messages_of_its_complete_chunks(tmp_path, where):
    path, data = _bag(tmp_path)
    chunks = _chunks(path)
    assert len(chunks) >= 3
    # cut inside the last-but-one chunk: what survives is the chunks that end before the cut
    cut = int(chunks[-3][0] + where * (chunks[-2][0] - chunks[-3][0]))
    expected = sum(n for end, n in chunks if end <= cut)
    assert 0 < expected < N
    broken = tmp_path / 'cut.mcap'
    shutil.copyfile(path, broken)
    with open(broken, 'r+b') as f:
        f.truncate(cut)
    scan = McapScan(broken)
    got = list(scan.messages())
    assert scan.complete is False and scan.count == len(got) == expected
    assert 'cut.mcap' in scan.where() and 'truncated' in scan.where()
    assert scan.summary()['last_log_time_s'] == pytest.approx(data.t[expected - 1])
    # the payloads are the first messages, intact
    from rosbags.typesys import get_typestore, Stores
    ts = get_typestore(Stores.ROS2_KILTED)
    msg = scan.deserialize(got[-1][3], got[-1][1], ts)
    assert msg.effort[0] == pytest.approx(data.f[expected - 1])


@pytest.mark.slow
def test_read_bag_reads_a_cut_file_and_says_where(tmp_path):
    path, data = _bag(tmp_path)
    cut = _chunks(path)[1][0] + 100
    broken = tmp_path / 'cut.mcap'
    shutil.copyfile(path, broken)
    with open(broken, 'r+b') as f:
        f.truncate(cut)
    recovery = {}
    got = read_bag(broken, recovery=recovery)
    n = sum(k for end, k in _chunks(path) if end <= cut)
    assert got.t.size == n
    np.testing.assert_allclose(got.f, data.f[:n])
    assert recovery['complete'] is False and recovery['messages'] == n
    assert 'cut.mcap' in recovery['note'] and 'truncated' in recovery['note']
    # a file cut before its first chunk ends has nothing to give: a clear error naming it
    with open(broken, 'r+b') as f:
        f.truncate(200)
    with pytest.raises(DataError, match='cut.mcap'):
        read_bag(broken)


def test_a_missing_file_is_named():
    with pytest.raises(FileNotFoundError, match='nowhere.mcap'):
        McapScan('nowhere.mcap')
