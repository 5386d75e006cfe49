"""Tests of the mr-damper-identify command line tool."""
import json
from pathlib import Path
import subprocess

import numpy as np
import pytest

from conftest import csv_text, QUIROZ_DIR, VENV_BIN
from mr_damper_model.tools.cli import EXIT_TRUNCATED, run
from mr_damper_model.io.params_file import load_params

QFILE = QUIROZ_DIR / 'quiroz_sine_2mm5Hz_0p5A.csv.gz'
HEADER = 't,x,v,f,i\n'


def _rows(n=200, **over):
    t = np.arange(n) * 1e-3
    cols = {'t': t, 'x': 0.01 * np.sin(2 * np.pi * 5 * t), 'v': 0.1 * np.pi * np.cos(
        2 * np.pi * 5 * t), 'f': 300 * np.sin(2 * np.pi * 5 * t + 1), 'i': np.zeros(n)}
    cols.update(over)
    return cols


def _write(path, cols, names='t,x,v,f,i'):
    arr = np.column_stack([cols[c] for c in names.split(',')])
    np.savetxt(path, arr, delimiter=',', header=names, comments='')
    return path


def _bad_files(tmp_path):
    n = 200
    t = np.arange(n) * 1e-3
    f_nan = _rows()['f'].copy()
    f_nan[7] = np.nan
    t_bad = t.copy()
    t_bad[50] = t_bad[49]
    trunc = tmp_path / 'trunc.csv'
    trunc.write_text(csv_text(QFILE)[:500])
    return {
        'missing column': _write(tmp_path / 'nof.csv', _rows(), 't,x,v,i'),
        'NaN': _write(tmp_path / 'nan.csv', _rows(f=f_nan)),
        'time': _write(tmp_path / 'time.csv', _rows(t=t_bad)),
        'few samples': _write(tmp_path / 'few.csv', _rows(n=10)),
        'motion': _write(tmp_path / 'still.csv', _rows(x=np.zeros(n), v=np.zeros(n))),
        'truncated': trunc,
        'absent': tmp_path / 'absent.csv',
    }


def test_bad_inputs_exit_2_with_one_line(tmp_path, capsys):
    for problem, path in _bad_files(tmp_path).items():
        code = run([str(path)])
        err = capsys.readouterr().err
        assert code == 2, problem
        assert len(err.strip().splitlines()) == 1, (problem, err)
        assert path.name in err and 'Traceback' not in err, (problem, err)


@pytest.mark.slow
def test_unknown_model_via_console_script(tmp_path):
    proc = subprocess.run([str(VENV_BIN / 'mr-damper-identify'), str(QFILE), '--model', 'foo'],
                          capture_output=True, text=True, timeout=60)
    assert proc.returncode == 2
    assert len(proc.stderr.strip().splitlines()) == 1
    assert QFILE.name in proc.stderr and 'foo' in proc.stderr
    assert 'Traceback' not in proc.stderr


def test_json_output_and_params_file(tmp_path, capsys):
    out = tmp_path / 'p.json'
    assert run([str(QFILE), '--json', '--seed', '3', '--out', str(out)]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert {'model', 'parameters', 'metrics', 'seconds', 'seed'} <= set(doc)
    assert doc['model'] == 'kwok' and doc['seed'] == 3
    assert set(doc['metrics']) == {'mean_abs_error_n', 'rmse_n', 'mean_percent_error',
                                   'max_percent_error', 'nrmse_percent'}
    pf = load_params(out)
    assert pf.model == 'kwok'
    assert pf.parameters == pytest.approx(doc['parameters'])


@pytest.mark.slow
def test_per_current_groups_and_default_model(tmp_path, capsys):
    from mr_damper_model.io.data import DamperData, read_csv, write_csv
    a = read_csv(QUIROZ_DIR / 'quiroz_sine_2mm5Hz_0A.csv.gz')
    b = read_csv(QUIROZ_DIR / 'quiroz_sine_2mm5Hz_1p0A.csv.gz')
    both = DamperData.concatenate([a, b], restamp=True)
    path = tmp_path / 'two.csv'
    write_csv(path, both)
    assert run([str(path), '--json', '--per-current']) == 0
    doc = json.loads(capsys.readouterr().out)
    assert [g['current_a'] for g in doc['groups']] == [0.0, 1.0]
    assert all('parameters' in g and 'metrics' in g for g in doc['groups'])
    # several levels: the best cross-validated model (docs/cross-validation.md)
    assert run([str(path), '--json']) == 0
    assert json.loads(capsys.readouterr().out)['model'] == 'kwok-current-amp'


@pytest.mark.slow
def test_table_and_plot(tmp_path, capsys):
    png = tmp_path / 'fit.png'
    assert run([str(QFILE), '--plot', str(png)]) == 0
    text = capsys.readouterr().out
    assert 'c [N s/m]' in text and 'RMSE [N]' in text
    assert png.stat().st_size > 10000


# --- many files, one model; validation; bags ------------------------------------------------

# different current, amplitude, frequency and sample rate (1 kHz, 200 Hz); sorted by name
TRIO = sorted(QUIROZ_DIR / name for name in ('quiroz_sine_2mm5Hz_0A.csv.gz',
                                             'quiroz_sine_25mm0x25Hz_0p5A.csv.gz',
                                             'quiroz_sine_5mm3Hz_1p0A.csv.gz'))


def _direct_metrics(params_path, paths):
    """Per-file and overall metrics of a saved model, computed here without the tool."""
    from mr_damper_model.io.data import read_csv
    from mr_damper_model.identification.metrics import fit_metrics
    from mr_damper_model.models import get_model
    pf = load_params(params_path)
    mdl = get_model(pf.model, **pf.model_options)
    x = np.array([pf.parameters[n] for n in mdl.param_names])
    recs = [read_csv(p) for p in paths]
    fms = [mdl.force(x, d.x, d.v, i=d.i, t=d.t) for d in recs]
    per = [fit_metrics(d.f, fm) for d, fm in zip(recs, fms)]
    return per, fit_metrics(np.concatenate([d.f for d in recs]), np.concatenate(fms))


def _assert_metrics_equal(doc_metrics, ref):
    assert set(doc_metrics) == set(ref)
    for k in ref:
        assert doc_metrics[k] == pytest.approx(ref[k], rel=1e-12, abs=1e-12), k


@pytest.fixture(scope='module')
def joint_fit(tmp_path_factory):
    """One kwok-current-amp model (the default) fitted to three files of three current levels."""
    import contextlib
    import io
    out = tmp_path_factory.mktemp('joint') / 'joint.json'
    buf = io.StringIO()
    with contextlib.redirect_stdout(buf):
        code = run([*map(str, TRIO), '--json', '--seed', '2', '--out', str(out)])
    assert code == 0
    return json.loads(buf.getvalue()), out


@pytest.mark.slow
def test_many_files_one_model_per_file_metrics_match_saved_parameters(joint_fit):
    doc, out = joint_fit
    assert doc['model'] == 'kwok-current-amp'      # three current levels: the default
    from mr_damper_model.io.data import read_csv
    assert sorted(round(read_csv(p).sample_rate_hz) for p in TRIO) == [200, 200, 1000]
    assert [f['source'] for f in doc['files']] == [str(p) for p in TRIO]
    assert [f['samples'] for f in doc['files']] == [read_csv(p).n for p in TRIO]
    per, overall = _direct_metrics(out, TRIO)
    for got, ref in zip(doc['files'], per):
        _assert_metrics_equal(got['metrics'], ref)
    # each file restarts the lag state: the joint fit's metrics are those of all files together
    _assert_metrics_equal(doc['metrics'], overall)
    pf = load_params(out)
    assert pf.parameters == doc['parameters']
    assert pf.source == ', '.join(str(p) for p in TRIO)
    assert pf.current_min_a == 0.0 and pf.current_max_a == pytest.approx(1.0, abs=0.05)


@pytest.mark.slow
def test_glob_and_directory_give_the_same_fit_as_the_list(tmp_path, capsys):
    import shutil
    folder = tmp_path / 'tests'
    folder.mkdir()
    copies = [shutil.copy(p, folder / p.name) for p in TRIO]
    (folder / 'notes.txt').write_text('not a record\n')
    (folder / 'empty_subdir').mkdir()
    docs = {}
    for how, argv in {'list': [str(c) for c in copies], 'dir': [str(folder)],
                      'glob': [str(folder / '*Hz_*A.csv.gz')],
                      'dir+repeat': [str(folder), str(copies[0])]}.items():
        assert run([*argv, '--json', '--seed', '2']) == 0, how
        docs[how] = json.loads(capsys.readouterr().out)
    for how in ('dir', 'glob', 'dir+repeat'):
        assert docs[how]['parameters'] == docs['list']['parameters'], how
        assert docs[how]['files'] == docs['list']['files'], how
        assert docs[how]['source'] == docs['list']['source'], how


@pytest.mark.slow
def test_multi_file_table_and_plot(tmp_path, capsys):
    png = tmp_path / 'joint.png'
    assert run([*map(str, TRIO[:2]), '--plot', str(png), '--seed', '2']) == 0
    text = capsys.readouterr().out
    assert text.startswith('2 files: ') and 'metrics of the joint fit per file' in text
    assert TRIO[0].name in text and TRIO[1].name in text and 'all files' in text
    assert png.stat().st_size > 10000


@pytest.mark.slow
def test_validate_json_equals_metrics_of_the_saved_model(joint_fit, tmp_path, capsys):
    _, params = joint_fit
    held_out = [QUIROZ_DIR / 'quiroz_sine_2mm5Hz_0p25A.csv.gz',
                QUIROZ_DIR / 'quiroz_sine_2mm5Hz_0p75A.csv.gz']
    png = tmp_path / 'val.png'
    assert run(['--validate', str(params), *map(str, held_out), '--json',
                '--plot', str(png)]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert set(doc) == {'model', 'params_file', 'files', 'metrics'}
    assert doc['model'] == 'kwok-current-amp' and doc['params_file'] == str(params)
    per, overall = _direct_metrics(params, held_out)
    assert [f['source'] for f in doc['files']] == [str(p) for p in held_out]
    for got, ref in zip(doc['files'], per):
        assert set(got) == {'source', 'samples', 'metrics'}
        _assert_metrics_equal(got['metrics'], ref)
    _assert_metrics_equal(doc['metrics'], overall)
    assert png.stat().st_size > 10000
    # the text form prints the same numbers
    assert run(['--validate', str(params), *map(str, held_out), '--model',
                'kwok-current-amp']) == 0
    text = capsys.readouterr().out
    assert f'{overall["rmse_n"]:.6g}' in text and held_out[1].name in text


def test_validate_stateful_model_starts_from_rest_in_each_file(tmp_path, capsys):
    from mr_damper_model.io.data import read_csv
    from mr_damper_model.identification.metrics import fit_metrics
    from mr_damper_model.models import get_model
    from mr_damper_model.io.params_file import save_params
    mdl = get_model('bouc-wen')
    lo, hi = mdl.default_bounds()
    x = (lo + hi) / 2
    params = tmp_path / 'bw.json'
    save_params(params, {'model': 'bouc-wen', 'parameters': mdl.to_dict(x)})
    assert run(['--validate', str(params), *map(str, TRIO), '--json']) == 0
    doc = json.loads(capsys.readouterr().out)
    for got, path in zip(doc['files'], TRIO):
        d = read_csv(path)                         # this file alone: the model starts at rest
        _assert_metrics_equal(got['metrics'],
                              fit_metrics(d.f, mdl.force(x, d.x, d.v, i=d.i, t=d.t)))


@pytest.mark.slow
@pytest.mark.parametrize('storage', ['sqlite3', 'mcap'])
def test_bag_input_fits_and_validates_like_the_csv(joint_fit, tmp_path, capsys, storage):
    from mr_damper_model.io.bag_io import write_bag
    from mr_damper_model.io.data import read_csv
    bag = tmp_path / 'bag'
    write_bag(bag, read_csv(QFILE), storage=storage, topic='/rig/measurement')
    single = next(p for p in bag.iterdir() if p.suffix in ('.db3', '.mcap'))
    docs = []
    for src in (QFILE, bag, single):
        assert run([str(src), '--json', '--seed', '4']) == 0
        docs.append(json.loads(capsys.readouterr().out))
    for d in docs[1:]:
        assert d['parameters'] == pytest.approx(docs[0]['parameters'], rel=1e-12)
        _assert_metrics_equal(d['metrics'], docs[0]['metrics'])
    _, params = joint_fit
    vals = []
    for src in (QFILE, bag):
        assert run(['--validate', str(params), str(src), '--json',
                    '--topic', '/rig/measurement']) == 0
        vals.append(json.loads(capsys.readouterr().out))
    _assert_metrics_equal(vals[1]['metrics'], vals[0]['metrics'])
    # a directory holding a bag and a CSV: both are read
    (tmp_path / 'mixed').mkdir()
    write_bag(tmp_path / 'mixed' / 'b_bag', read_csv(QFILE), storage=storage)
    (tmp_path / 'mixed' / 'a.csv').write_text(csv_text(QFILE))
    assert run(['--validate', str(params), str(tmp_path / 'mixed'), '--json']) == 0
    doc = json.loads(capsys.readouterr().out)
    assert [Path(f['source']).name for f in doc['files']] == ['a.csv', 'b_bag']
    _assert_metrics_equal(doc['files'][1]['metrics'], doc['files'][0]['metrics'])


def _bag_error_inputs(tmp_path):
    from mr_damper_model.io.bag_io import write_bag
    from mr_damper_model.io.data import read_csv
    from rosbags.rosbag2 import StoragePlugin, Writer
    from rosbags.typesys import get_typestore, Stores
    d = read_csv(QFILE)
    write_bag(tmp_path / 'other', d, topic='/a', storage='mcap')
    ts = get_typestore(Stores.ROS2_KILTED)
    T = ts.types
    with Writer(tmp_path / 'joints', version=9, storage_plugin=StoragePlugin.SQLITE3) as w:
        c = w.add_connection('/mr_damper/measurement', 'sensor_msgs/msg/JointState',
                             typestore=ts)
        for k in range(60):
            msg = T['sensor_msgs/msg/JointState'](
                header=T['std_msgs/msg/Header'](
                    stamp=T['builtin_interfaces/msg/Time'](sec=k, nanosec=0), frame_id=''),
                name=['wheel', 'coil'], position=np.zeros(2), velocity=np.zeros(2),
                effort=np.zeros(2))
            w.write(c, k + 1, ts.serialize_cdr(msg, 'sensor_msgs/msg/JointState'))
    cut = tmp_path / 'cut.mcap'
    write_bag(tmp_path / 'full', d, storage='mcap')
    raw = next((tmp_path / 'full').glob('*.mcap')).read_bytes()
    cut.write_bytes(raw[:len(raw) // 2])
    return {
        'no topic /mr_damper/measurement': [str(tmp_path / 'other'), '--topic',
                                            '/mr_damper/measurement'],
        "joints ['wheel', 'coil']": [str(tmp_path / 'joints')],
        'cannot read bag': [str(cut)],
    }


def test_error_paths_exit_2_with_one_line(joint_fit, tmp_path, capsys):
    _, params = joint_fit
    notjson = tmp_path / 'notjson.json'
    notjson.write_text('{"model": ')
    strange = tmp_path / 'strange.json'
    strange.write_text('{"model": "magic", "parameters": {}}')
    nof = _write(tmp_path / 'nof.csv', _rows(), 't,x,v,i')
    (tmp_path / 'empty').mkdir()
    cases = {
        'cannot read parameter file': ['--validate', str(tmp_path / 'none.json'), str(QFILE)],
        'not valid JSON': ['--validate', str(notjson), str(QFILE)],
        'unknown model "magic"': ['--validate', str(strange), str(QFILE)],
        'model is "kwok-current-amp", expected "bingham"': ['--validate', str(params),
                                                            str(QFILE), '--model', 'bingham'],
        'missing column(s) f': ['--validate', str(params), str(nof)],
        'no file matches this pattern': ['--validate', str(params),
                                         str(tmp_path / 'nothing*.csv')],
        'directory holds no .csv': [str(tmp_path / 'empty')],
        '--out cannot be used with it': ['--validate', str(params), str(QFILE), '--out',
                                         str(tmp_path / 'x.json')],
        'the following arguments are required': ['--validate', str(params)],
    }
    for msg, argv in {**cases, **_bag_error_inputs(tmp_path)}.items():
        for extra in ([], ['--validate', str(params)]) if '--validate' not in argv else ([],):
            code = run([*extra, *argv])
            err = capsys.readouterr().err
            assert code == 2, (msg, extra, err)
            assert len(err.strip().splitlines()) == 1, (msg, err)
            assert msg in err and 'Traceback' not in err, (msg, err)
    assert not (tmp_path / 'x.json').exists()


@pytest.mark.slow
def test_a_closed_output_pipe_ends_quietly():
    """``mr-damper-identify ... | head -1``: no internal-error line when the reader is gone."""
    import os
    r, w = os.pipe()
    os.close(r)                                    # the reader is gone before anything is written
    try:
        # without PYTHONUNBUFFERED (a user's shell): stdout to a pipe is block-buffered and
        # written only at the flush
        env = {k: v for k, v in os.environ.items() if k != 'PYTHONUNBUFFERED'}
        proc = subprocess.run([str(VENV_BIN / 'mr-damper-identify'), str(QFILE)], stdout=w,
                              stderr=subprocess.PIPE, text=True, timeout=120, env=env)
    finally:
        os.close(w)
    assert proc.returncode == 141 and proc.stderr == ''


def test_every_registered_model_can_be_chosen():
    from mr_damper_model.tools.cli import MODEL_CHOICES, MULTI_CURRENT_MODEL
    from mr_damper_model.models import MODEL_NAMES
    assert sorted(MODEL_CHOICES) == sorted(MODEL_NAMES)
    assert MULTI_CURRENT_MODEL in MODEL_CHOICES


@pytest.mark.slow
def test_a_recording_cut_by_a_killed_recorder_is_fitted_with_a_warning(tmp_path, capsys):
    """mr-damper-identify reads a footer-less MCAP up to its last chunk and says where it ends."""
    from mr_damper_model.io.bag_io import write_bag
    from mr_damper_model.io.data import DamperData, read_csv
    d = read_csv(QFILE)
    reps = 30                                   # several 1 MiB chunks of measurements
    n = d.t.size
    t = np.concatenate([d.t + k * (d.t[-1] + d.t[1] - d.t[0]) for k in range(reps)])
    data = DamperData(t, *(np.tile(getattr(d, c), reps) for c in 'xvfi'))
    write_bag(tmp_path / 'bag', data, storage='mcap')
    raw = (tmp_path / 'bag' / 'bag.mcap').read_bytes()
    cut = tmp_path / 'cut.mcap'
    cut.write_bytes(raw[:len(raw) // 2])
    assert run([str(cut), '--json']) == EXIT_TRUNCATED == 3
    out = capsys.readouterr()
    doc = json.loads(out.out)
    got = doc['samples'] if 'samples' in doc else doc['files'][0]['samples']
    assert n <= got < reps * n
    assert f'warning: {cut}: truncated' in out.err and f'{got} messages read' in out.err
    assert f'{got} samples used (exit code 3)' in out.err
    (entry,) = doc['truncated_inputs']
    assert entry['file'] == str(cut) and entry['samples'] == entry['messages'] == got
    assert entry['last_log_time_s'] > entry['first_log_time_s']
    # the saved set validates on the cut file too: the same exit code; on the whole file 0
    params = tmp_path / 'p.json'
    assert run([str(cut), '--out', str(params)]) == 3
    capsys.readouterr()
    assert run(['--validate', str(params), str(cut), '--json']) == 3
    assert json.loads(capsys.readouterr().out)['truncated_inputs'][0]['samples'] == got
    assert run(['--validate', str(params), str(tmp_path / 'bag'), '--json']) == 0
    assert 'truncated_inputs' not in json.loads(capsys.readouterr().out)
