"""Tests of the mr-damper-rig-test command line tool."""
import json
import subprocess

import numpy as np
import pytest

from conftest import VENV_BIN
from mr_damper_model.io.data import read_csv
from mr_damper_rig.rig_test_cli import main


def test_writes_thesis_like_csv(tmp_path):
    out = tmp_path / 'rig.csv'
    truth = tmp_path / 'truth.json'
    assert main(['--out', str(out), '--duration', '3', '--currents', '0,2', '--hold', '1.5',
                 '--seed', '1', '--truth-out', str(truth)]) == 0
    data = read_csv(out)
    assert data.n == 3000
    assert open(out).readline().strip() == 't,x,v,f,i'
    levels = [c for c, _ in data.split_by_current(tol_a=0.05)]
    assert any(abs(c) < 0.05 for c in levels) and any(abs(c - 2.0) < 0.05 for c in levels)
    assert abs(np.max(np.abs(data.x)) - 0.03) < 1e-4
    t = json.loads(truth.read_text())
    assert t['model'] == 'spencer' and 'alpha_b' in t['parameters']


def test_seed_repeatable(tmp_path):
    a, b = tmp_path / 'a.csv', tmp_path / 'b.csv'
    for f in (a, b):
        assert main(['--out', str(f), '--duration', '0.5', '--plant', 'kwok-current',
                     '--excitation', 'random', '--seed', '4']) == 0
    assert a.read_text() == b.read_text()


@pytest.mark.slow
def test_bad_arguments_exit_2(tmp_path):
    exe = str(VENV_BIN / 'mr-damper-rig-test')
    for args in (['--out', str(tmp_path / 'x.csv'), '--currents', '0,abc'],
                 ['--out', str(tmp_path / 'x.csv'), '--duration', '-1'],
                 ['--out', str(tmp_path / 'x.csv'), '--plant', 'magic'],
                 ['--out', str(tmp_path / 'nodir' / 'x.csv'), '--duration', '0.1']):
        r = subprocess.run([exe] + args, capture_output=True, text=True, timeout=60)
        assert r.returncode == 2, args
        assert len(r.stderr.strip().splitlines()) == 1 and 'Traceback' not in r.stderr
