"""Tests for mr_damper_model.io.data: CSV reading, validation, current splitting."""
from pathlib import Path

import numpy as np
import pytest

from mr_damper_model.io.data import DamperData, DataError, derive_velocity, is_csv, read_csv, \
    validate, write_csv


def _record(n=2000, fs=1000.0, freq=1.1, amp=0.03, currents=(0.0,)):
    t = np.arange(n) / fs
    x = amp * np.sin(2 * np.pi * freq * t)
    v = amp * 2 * np.pi * freq * np.cos(2 * np.pi * freq * t)
    i = np.repeat(np.asarray(currents, float), int(np.ceil(n / len(currents))))[:n]
    f = 500.0 * v + 100.0 * np.tanh(20 * v)
    return DamperData(t, x, v, f, i, source='synthetic')


def test_csv_round_trip(tmp_path):
    d = _record()
    path = tmp_path / 'rec.csv'
    write_csv(path, d)
    back = read_csv(path)
    for c in 'txvfi':
        np.testing.assert_allclose(getattr(back, c), getattr(d, c), rtol=1e-9, atol=1e-12)
    assert back.source == str(path)


def test_column_order_and_extra_columns(tmp_path):
    path = tmp_path / 'shuffled.csv'
    path.write_text('f,i,extra,t,x,v\n1,0,9,0,0.001,0.1\n2,0,9,0.001,0.002,0.1\n')
    d = read_csv(path)
    np.testing.assert_allclose(d.f, [1, 2])
    np.testing.assert_allclose(d.x, [0.001, 0.002])


def test_empty_velocity_is_derived_from_displacement(tmp_path):
    d = _record()
    path = tmp_path / 'nov.csv'
    lines = ['t,x,v,f,i'] + [f'{t:.12g},{x:.12g},,{f:.12g},{i:.12g}' for t, x, f, i in
                             zip(d.t, d.x, d.f, d.i)]
    path.write_text('\n'.join(lines) + '\n')
    back = read_csv(path)
    # away from the ends the Savitzky-Golay derivative of a clean sine is nearly exact
    np.testing.assert_allclose(back.v[50:-50], d.v[50:-50], atol=1e-4 * np.abs(d.v).max())


def test_derive_velocity_nonuniform_uses_gradient():
    t = np.cumsum(np.r_[0.0, np.linspace(1e-3, 3e-3, 199)])
    x = 0.5 * t ** 2
    np.testing.assert_allclose(derive_velocity(t, x)[1:-1], t[1:-1], rtol=1e-2)


@pytest.mark.parametrize('text, match', [
    ('', 'file is empty'),
    ('t,x,f,i\n0,0,0,0\n', 'missing column'),
    ('t,x,v,f,i\n', 'no data rows'),
    ('t,x,v,f,i\n0,0,0,0,0\n0.001,0.1,0\n', 'truncated'),
    ('t,x,v,f,i\n0,0,0,abc,0\n', "'abc' is not a number"),
    ('t,x,v,f,i\n0,0,0,nan,0\n', 'NaN'),
    ('t,x,v,f,i\n0,0,,1,0\n0.001,0,0.1,1,0\n', 'empty on some rows'),
])
def test_bad_files_raise_one_line_error_naming_the_file(tmp_path, text, match):
    path = tmp_path / 'bad.csv'
    path.write_text(text)
    with pytest.raises(DataError, match=match) as info:
        read_csv(path)
    msg = str(info.value)
    assert str(path) in msg and '\n' not in msg


def test_missing_file():
    with pytest.raises(DataError, match='cannot read file'):
        read_csv('/nonexistent/file.csv')


def test_validate_accepts_good_and_rejects_bad():
    d = _record()
    assert validate(d) is d
    with pytest.raises(DataError, match='too few samples'):
        validate(d.select(slice(0, 10)))
    t = d.t.copy()
    t[100] = t[99]
    with pytest.raises(DataError, match='not strictly increasing at sample 100'):
        validate(DamperData(t, d.x, d.v, d.f, d.i))
    with pytest.raises(DataError, match='no motion'):
        validate(DamperData(d.t, np.zeros(d.n), np.zeros(d.n), d.f, d.i))
    with pytest.raises(DataError, match='force is constant'):
        validate(DamperData(d.t, d.x, d.v, np.full(d.n, 3.0), d.i))
    f = d.f.copy()
    f[5] = np.inf
    with pytest.raises(DataError, match='NaN/inf'):
        validate(DamperData(d.t, d.x, d.v, f, d.i))


def test_mismatched_lengths_rejected():
    with pytest.raises(DataError, match='different lengths'):
        DamperData([0, 1], [0, 1], [0, 1], [0, 1], [0])


def test_split_by_current_groups_levels_with_tolerance():
    d = _record(n=5000, currents=(0.0, 0.5, 1.0, 1.5, 2.0))
    noisy = DamperData(d.t, d.x, d.v, d.f, d.i + 0.01 * np.sin(np.arange(d.n)))
    groups = noisy.split_by_current(tol_a=0.05)
    assert [round(level, 2) for level, _ in groups] == [0.0, 0.5, 1.0, 1.5, 2.0]
    assert sum(g.n for _, g in groups) == d.n
    for level, g in groups:
        assert np.all(np.abs(g.i - level) < 0.05)
        assert np.all(np.diff(g.t) > 0)


def test_concatenate_restamps_continuously():
    d = _record(n=100)
    joined = DamperData.concatenate([d, d], restamp=True)
    assert joined.n == 200
    assert np.all(np.diff(joined.t) > 0)
    np.testing.assert_allclose(np.diff(joined.t), 1e-3)
    assert DamperData.concatenate([d, d]).t[100] == 0.0


def test_byte_order_mark_of_a_spreadsheet_csv_is_accepted(tmp_path):
    path = tmp_path / 'excel.csv'
    path.write_bytes('\ufefft,x,v,f,i\n0,0.001,0.01,5,0.5\n0.001,0.002,0.01,6,0.5\n'
                     .encode('utf-8'))
    d = read_csv(path)
    np.testing.assert_array_equal(d.f, [5.0, 6.0])
    np.testing.assert_array_equal(d.t, [0.0, 0.001])


def _gzip_copy(src, dst):
    import gzip
    dst.write_bytes(gzip.compress(src.read_bytes(), mtime=0))
    return dst


def test_gzip_csv_reads_the_same_arrays_as_the_plain_file(tmp_path):
    from conftest import csv_text, QUIROZ_DIR
    shipped = QUIROZ_DIR / 'quiroz_sine_2mm5Hz_0p5A.csv.gz'
    plain = tmp_path / 'q.csv'
    plain.write_text(csv_text(shipped))
    a, b = read_csv(plain), read_csv(shipped)
    assert a.n > 500 and b.source == str(shipped)
    for c in 'txvfi':
        np.testing.assert_array_equal(getattr(b, c), getattr(a, c))
    # a byte-order mark, a derived velocity and a missing .gz ending work the same compressed
    bom = tmp_path / 'bom.csv'
    bom.write_bytes('\ufefft,x,v,f,i\n0,0.001,,5,0.5\n0.001,0.002,,6,0.5\n0.002,0.003,,7,0.5\n'
                    .encode('utf-8'))
    for packed in (_gzip_copy(bom, tmp_path / 'bom.csv.gz'), _gzip_copy(bom, tmp_path / 'x.dat')):
        got, want = read_csv(packed), read_csv(bom)
        for c in 'txvfi':
            np.testing.assert_array_equal(getattr(got, c), getattr(want, c))
    # write_csv compresses for a .gz name (numpy.savetxt), and the reader takes it back
    d = _record()
    write_csv(tmp_path / 'rec.csv.gz', d)
    np.testing.assert_allclose(read_csv(tmp_path / 'rec.csv.gz').f, d.f, rtol=1e-9)


@pytest.mark.parametrize('cut', ['middle', 'header'])
def test_truncated_or_corrupt_gzip_is_a_data_error_naming_the_file(tmp_path, cut):
    from conftest import QUIROZ_DIR
    raw = (QUIROZ_DIR / 'quiroz_sine_2mm5Hz_0p5A.csv.gz').read_bytes()
    bad = tmp_path / 'cut.csv.gz'
    bad.write_bytes(raw[:len(raw) // 2] if cut == 'middle' else raw[:5])
    with pytest.raises(DataError, match='truncated or corrupt gzip file') as info:
        read_csv(bad)
    assert str(bad) in str(info.value) and '\n' not in str(info.value)
    junk = tmp_path / 'junk.csv.gz'
    junk.write_bytes(raw[:20] + bytes(200))     # a gzip header followed by garbage
    with pytest.raises(DataError, match=f'{junk}: truncated or corrupt gzip file'):
        read_csv(junk)


def test_is_csv_knows_plain_and_compressed_names():
    assert is_csv('a.csv') and is_csv('dir/A.CSV.GZ') and is_csv(Path('x.csv.gz'))
    assert not is_csv('a.mcap') and not is_csv('a.gz') and not is_csv('bag_dir')


def test_blank_line_inside_the_data_is_an_error_trailing_ones_are_not(tmp_path):
    path = tmp_path / 'blank.csv'
    path.write_text('t,x,v,f,i\n0,0,0,1,0\n\n0.001,0,0,1,0\n')
    with pytest.raises(DataError, match='line 3 has 0 fields'):
        read_csv(path)
    path.write_text('t,x,v,f,i\n0,0,0,1,0\n0.001,0,0,1,0\n\n\n')
    assert read_csv(path).n == 2


@pytest.mark.slow
def test_large_csv_is_read_in_bounded_memory(tmp_path, monkeypatch):
    """Peak memory of read_csv stays within 3x the arrays it returns (several blocks)."""
    import tracemalloc
    from mr_damper_model.io import data as data_mod
    monkeypatch.setattr(data_mod, '_CSV_BLOCK_ROWS', 4096)   # many blocks, small file
    n = 60000
    t = np.arange(n) * 1e-3
    arr = np.column_stack([t, 0.01 * np.sin(t), 0.01 * np.cos(t), 100 * np.sin(t), 0 * t + 0.5])
    path = tmp_path / 'large.csv'
    np.savetxt(path, arr, delimiter=',', header='t,x,v,f,i', comments='', fmt='%.10g')
    tracemalloc.start()
    try:
        d = read_csv(path)
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    final = 5 * 8 * n
    assert d.n == n and d.f[-1] == pytest.approx(arr[-1, 3], rel=1e-9)
    assert peak <= 3 * final, f'peak {peak / 1e6:.1f} MB for {final / 1e6:.1f} MB of arrays'


def test_default_single_segment_and_bad_starts():
    d = _record(n=50)
    np.testing.assert_array_equal(d.starts, [0])
    assert d.n_segments == 1
    np.testing.assert_array_equal(DamperData(d.t, d.x, d.v, d.f, d.i, starts=[20]).starts,
                                  [0, 20])
    with pytest.raises(DataError, match=r'synthetic: `starts` must be strictly increasing'):
        DamperData(d.t, d.x, d.v, d.f, d.i, source='synthetic', starts=[0, 30, 10])
    with pytest.raises(DataError, match=r'\[0, 50\)'):
        DamperData(d.t, d.x, d.v, d.f, d.i, starts=[0, 50])


def test_concatenate_marks_each_part_and_keeps_inner_starts():
    a, b = _record(n=100), _record(n=60)
    ab = DamperData.concatenate([a, b])
    np.testing.assert_array_equal(ab.starts, [0, 100])
    abab = DamperData.concatenate([ab, b.select(slice(0, 0)), ab], restamp=True)
    np.testing.assert_array_equal(abab.starts, [0, 100, 160, 260])     # empty part adds none
    assert np.all(np.diff(abab.t) > 0)
    for seg, part in zip(abab.segments(), (a, b, a, b)):
        np.testing.assert_array_equal(seg.f, part.f)
        np.testing.assert_array_equal(seg.starts, [0])


def test_concatenate_release_frees_each_part_and_joins_the_same():
    """
    ``release=True`` empties the list as it copies (a long record's parts are freed one by one).

    The joined record is the same, bit for bit, as without release (restamped, inner starts);
    the parts' arrays die with the list's references (nothing else held).
    """
    import gc
    import weakref
    ab = DamperData.concatenate([_record(n=100), _record(n=60)])
    ref = DamperData.concatenate([ab, _record(n=80)], restamp=True)
    parts = [DamperData.concatenate([_record(n=100), _record(n=60)]), _record(n=80)]
    alive = [weakref.ref(p.f) for p in parts]
    joined = DamperData.concatenate(parts, restamp=True, release=True)
    gc.collect()
    assert parts == [None, None]
    assert [w() for w in alive] == [None, None]
    for c in ('t', 'x', 'v', 'f', 'i', 'starts'):
        np.testing.assert_array_equal(getattr(joined, c), getattr(ref, c))
    with pytest.raises(TypeError, match='list'):
        DamperData.concatenate((ab, ab), release=True)


def test_select_follows_segments():
    ab = DamperData.concatenate([_record(n=100), _record(n=60)])
    np.testing.assert_array_equal(ab.select(slice(50, 130)).starts, [0, 50])
    np.testing.assert_array_equal(ab.select(slice(None, None, 7)).starts, [0, 15])  # 105 first
    np.testing.assert_array_equal(ab.select(slice(0, 100)).starts, [0])
    mask = np.zeros(ab.n, dtype=bool)
    mask[10:20] = mask[40:50] = mask[120:130] = True
    np.testing.assert_array_equal(ab.select(mask).starts, [0, 20])          # gap: same test
    np.testing.assert_array_equal(ab.select(mask, split_gaps=True).starts, [0, 10, 20])
    np.testing.assert_array_equal(ab.select([5, 6, 2, 3]).starts, [0, 2])   # reordered


def test_split_by_current_starts_each_run_of_a_level():
    d = _record(n=400, currents=(0.0, 1.0, 0.0, 1.0))       # 0 A, 1 A, 0 A, 1 A runs of 100
    joined = DamperData.concatenate([d, d])
    groups = dict(joined.split_by_current())
    for level in (0.0, 1.0):
        g = groups[level]
        assert g.n == 400
        np.testing.assert_array_equal(g.starts, [0, 100, 200, 300])
