"""Tests of the mr-damper-identify command line tool."""
import json
import subprocess

import numpy as np
import pytest

from conftest import QUIROZ_DIR, VENV_BIN
from mr_damper_model.cli import run
from mr_damper_model.params_file import load_params

QFILE = QUIROZ_DIR / 'quiroz_sine_2mm5Hz_0p5A.csv'
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
    trunc.write_text(QFILE.read_text()[:500])
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


def test_per_current_groups_and_default_model(tmp_path, capsys):
    from mr_damper_model.data import DamperData, read_csv, write_csv
    a = read_csv(QUIROZ_DIR / 'quiroz_sine_2mm5Hz_0A.csv')
    b = read_csv(QUIROZ_DIR / 'quiroz_sine_2mm5Hz_1p0A.csv')
    both = DamperData.concatenate([a, b], restamp=True)
    path = tmp_path / 'two.csv'
    write_csv(path, both)
    assert run([str(path), '--json', '--per-current']) == 0
    doc = json.loads(capsys.readouterr().out)
    assert [g['current_a'] for g in doc['groups']] == [0.0, 1.0]
    assert all('parameters' in g and 'metrics' in g for g in doc['groups'])
    assert run([str(path), '--json']) == 0                   # several levels: kwok-current
    assert json.loads(capsys.readouterr().out)['model'] == 'kwok-current'


def test_table_and_plot(tmp_path, capsys):
    png = tmp_path / 'fit.png'
    assert run([str(QFILE), '--plot', str(png)]) == 0
    text = capsys.readouterr().out
    assert 'c [N s/m]' in text and 'RMSE [N]' in text
    assert png.stat().st_size > 10000
