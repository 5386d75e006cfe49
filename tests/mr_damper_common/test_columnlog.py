"""Tests of mr_damper_common.recording.columnlog: logs streamed to disk, read in bounded chunks."""
import json
import tracemalloc

import numpy as np
import pytest

from mr_damper_common.recording.columnlog import (ArrayLog, ColumnReader, ColumnWriter,
                                                  exists, finite_or_none, JsonLines, log_paths,
                                                  open_log, read_json_lines)


def _rows(n, width=3):
    return np.arange(n * width, dtype=float).reshape(n, width)


def test_round_trip_and_names(tmp_path):
    rows = _rows(1000)
    with ColumnWriter(tmp_path / 'log', ('a', 'b', 'c'), chunk_rows=64, meta={'dt': 1e-3}) as w:
        for r in rows[:500]:
            w.append(r)
        w.append_block(rows[500:])
    assert log_paths(tmp_path / 'log.f64') == log_paths(tmp_path / 'log.json')
    assert exists(tmp_path / 'log') and not exists(tmp_path / 'other')
    r = ColumnReader(tmp_path / 'log')
    assert r.rows == 1000 and r.columns == ('a', 'b', 'c') and r.meta == {'dt': 1e-3}
    np.testing.assert_array_equal(r.read()['b'], rows[:, 1])
    assert json.loads((tmp_path / 'log.json').read_text())['rows'] == 1000


def test_rows_reach_the_file_chunk_by_chunk(tmp_path):
    w = ColumnWriter(tmp_path / 'log', ('a', 'b', 'c'), chunk_rows=100)
    for k, r in enumerate(_rows(250)):
        w.append(r)
        if k == 199:
            assert ColumnReader(tmp_path / 'log').rows == 200     # two chunks written
    assert ColumnReader(tmp_path / 'log').rows == 200             # 50 still buffered
    w.close(status='done')
    r = ColumnReader(tmp_path / 'log')
    assert r.rows == 250 and r.meta == {'status': 'done'}


def test_log_cut_short_by_a_crash_is_read_up_to_its_last_whole_row(tmp_path):
    with ColumnWriter(tmp_path / 'log', ('a', 'b', 'c'), chunk_rows=10) as w:
        w.append_block(_rows(30))
    data = (tmp_path / 'log.f64').read_bytes()
    (tmp_path / 'log.f64').write_bytes(data[:-13])     # half a row lost
    r = ColumnReader(tmp_path / 'log')
    assert r.rows == 29
    np.testing.assert_array_equal(r.read()['a'], _rows(29)[:, 0])


def test_chunks_overlap_and_strided(tmp_path):
    rows = _rows(1001)
    with ColumnWriter(tmp_path / 'log', ('a', 'b', 'c')) as w:
        w.append_block(rows)
    for src in (ColumnReader(tmp_path / 'log'), ArrayLog({k: rows[:, j] for j, k in
                                                         enumerate('abc')})):
        chunks = list(src.chunks(100, ('a',), overlap=1))
        assert len(chunks) == 11 and chunks[0]['a'].size == 100 and chunks[1]['a'].size == 101
        # differences across boundaries are all there, each once
        d = np.concatenate([np.diff(c['a']) for c in chunks])
        np.testing.assert_array_equal(d, np.diff(rows[:, 0]))
        s = src.strided(100, ('a', 'c'))
        assert s['stride'] == 11 and s['a'][0] == rows[0, 0] and s['a'][-1] == rows[-1, 0]
        assert s['a'].size <= 101 + 1
        assert src.strided(5000)['a'].size == 1001


def test_bad_input_is_a_clear_error(tmp_path):
    with pytest.raises(ValueError, match='unique'):
        ColumnWriter(tmp_path / 'log', ('a', 'a'))
    with pytest.raises(FileNotFoundError, match='no column log'):
        ColumnReader(tmp_path / 'missing')
    with ColumnWriter(tmp_path / 'log', ('a', 'b')) as w:
        with pytest.raises(ValueError, match='shape'):
            w.append_block(np.zeros((3, 3)))
    with pytest.raises(KeyError, match='no column'):
        list(ColumnReader(tmp_path / 'log').chunks(10, ('z',)))
    with pytest.raises(ValueError, match='closed'):
        w.append((1.0, 2.0))
    (tmp_path / 'bad.json').write_text('{"rows": 3}')
    (tmp_path / 'bad.f64').write_bytes(b'')
    with pytest.raises(ValueError, match='not a column log'):
        ColumnReader(tmp_path / 'bad')
    with pytest.raises(MemoryError, match='chunks'):
        ColumnReader(tmp_path / 'log').read(max_rows=-1)


def test_reading_a_large_log_in_chunks_keeps_memory_bounded(tmp_path):
    n = 1_000_000                      # 24 MB of data
    with ColumnWriter(tmp_path / 'log', ('a', 'b', 'c'), chunk_rows=50000) as w:
        for k in range(0, n, 50000):
            w.append_block(_rows(50000) + k)
    r = ColumnReader(tmp_path / 'log')
    tracemalloc.start()
    total = 0.0
    for c in r.chunks(65536, ('b',)):
        total += float(c['b'].sum())
    s = r.strided(10000)
    _, peak = tracemalloc.get_traced_memory()
    tracemalloc.stop()
    expected = sum(float((_rows(50000) + k)[:, 1].sum()) for k in range(0, n, 50000))
    assert total == pytest.approx(expected, rel=1e-12)
    assert s['a'].size <= 10001
    assert peak < 4 * 2 ** 20         # a few chunks, never the 24 MB file


def test_json_lines_stream_and_survive_a_cut_line(tmp_path):
    jl = JsonLines(tmp_path / 'p.jsonl')
    jl.append([1.0, {'a': float('nan'), 'b': np.float64(2.0), 'ok': np.bool_(True)}])
    jl.append([2.0, {'a': 1}])
    jl.close()
    with open(tmp_path / 'p.jsonl', 'a') as fh:
        fh.write('[3.0, {"a":')                    # a crash in the middle of a line
    bad = []
    recs = list(read_json_lines(tmp_path / 'p.jsonl', bad))
    assert recs == [[1.0, {'a': None, 'b': 2.0, 'ok': True}], [2.0, {'a': 1}]]
    assert bad == [3] and jl.count == 2
    with pytest.raises(ValueError, match=':3'):
        list(read_json_lines(tmp_path / 'p.jsonl'))


def test_finite_or_none_is_plain_json():
    v = finite_or_none({1: [np.float32(1.5), float('inf'), (np.int64(3), None, 'x')],
                        'o': object})
    assert v == {'1': [1.5, None, [3, None, 'x']], 'o': str(object)}
    json.dumps(v, allow_nan=False)


def test_open_log_accepts_paths_readers_and_dicts(tmp_path):
    with ColumnWriter(tmp_path / 'log', ('a',)) as w:
        w.append((1.0,))
    assert open_log(tmp_path / 'log').rows == 1
    a = ArrayLog({'t': [0.0, 1.0], 'dt': 0.5})
    assert open_log(a) is a and a.meta == {'dt': 0.5} and open_log({'t': [1.0]}).rows == 1
    with pytest.raises(ValueError, match='lengths'):
        ArrayLog({'a': [1.0], 'b': [1.0, 2.0]})
