"""full-car-sim console script: runs on a short road, JSON holds every law and metric."""
import json
import subprocess

import pytest

from conftest import REPO
from quarter_car_sim.tools.full_car_sim import _laws, build_parser, main

EXE = REPO / '.venv' / 'bin' / 'full-car-sim'
METRICS = ('a_v', 'a_wz', 'a_w_pitch', 'a_w_roll', 'vdv_total', 'vdv_required', 'crest_max',
           'rms_tyre_load_ratio', 'rms_suspension_travel', 'peak_suspension_travel')


def _run(*args):
    return subprocess.run([str(EXE), *args], capture_output=True, text=True, timeout=600)


@pytest.mark.slow
def test_compare_json_has_every_law_and_metric():
    laws = 'passive@0A,passive@2A,per-corner-skyhook,modal-skyhook'
    proc = _run('--compare', '--json', '--duration', '0.5', '--laws', laws)
    assert proc.returncode == 0, proc.stderr
    out = json.loads(proc.stdout)
    assert list(out['laws']) == ['passive@0.0A', 'passive@2.0A', 'per-corner-skyhook',
                                 'modal-skyhook']
    for name, m in out['laws'].items():
        for key in METRICS:
            assert key in m, (name, key)
        assert set(m['rms_tyre_load_ratio']) == {'fl', 'fr', 'rl', 'rr'}
        assert set(m['rms_suspension_travel']) == {'fl', 'fr', 'rl', 'rr'}
        assert m['failsafe_corners'] == []
        assert m['a_v'] >= m['a_wz'] > 0
    assert out['laws']['passive@2.0A']['mean_current_a'] == {c: 2.0 for c in
                                                             ('fl', 'fr', 'rl', 'rr')}
    assert out['plants'] == {c: 'kwok-current' for c in ('fl', 'fr', 'rl', 'rr')}


def test_default_compare_set_and_table(capsys):
    names = _laws(build_parser().parse_args(['--compare']))
    assert names[:5] == ['passive@0A', 'passive@0.5A', 'passive@1A', 'passive@1.5A',
                         'passive@2A']
    assert 'modal-skyhook' in names and 'per-corner-skyhook' in names
    assert names[-8:] == ['full-car-clipped-optimal', 'full-car-clipped-optimal-wk',
                          'preview-wheelbase', 'preview-look-ahead-ideal', 'preview-look-ahead',
                          'preview-mpc-look-ahead-ideal', 'preview-mpc-look-ahead', 'bound']
    assert main(['--law', 'modal-skyhook', '--road', 'pothole', '--speed', '10',
                 '--duration', '0.3']) == 0
    out = capsys.readouterr().out
    assert 'modal-skyhook' in out and 'a_v' in out


@pytest.mark.parametrize('args, msg', [
    (('--road', 'gravel'), 'unknown road'),
    (('--law', 'sideways'), 'unknown full-car law'),
    (('--plant', 'spencer'), 'needs --damper-params'),
    (('--plant', 'kwok,kwok'), 'four'),
    (('--zeta', '1,2'), 'zeta'),
    (('--speed', '0'), 'speed'),
    (('--damper-params', '/nonexistent.json'), 'nonexistent'),
    (('--law', 'bound', '--bound-rho', '-1'), 'bound-rho'),
])
def test_bad_input_exits_2_with_one_line(args, msg, capsys):
    try:
        status = main(['--duration', '0.2', *args])
    except SystemExit as exc:          # argparse's own checks
        status = exc.code
    err = capsys.readouterr().err
    assert status == 2
    assert msg in err and len(err.strip().splitlines()) == 1


@pytest.mark.slow
def test_bound_is_listed_with_the_laws_and_beats_them(capsys):
    # the offline bound (full preview) in the same table: its replay on the plants is no worse
    # than the best live law and the softest passive setting on the same road
    laws = 'passive@0A,full-car-clipped-optimal-wk,bound'
    assert main(['--compare', '--json', '--duration', '1.5', '--laws', laws,
                 '--bound-rho', '0']) == 0
    out = json.loads(capsys.readouterr().out)['laws']
    assert list(out) == ['passive@0.0A', 'full-car-clipped-optimal-wk', 'bound']
    b = out['bound']
    for key in METRICS:
        assert key in b
    assert b['failsafe_corners'] == []
    assert b['bound']['cost'] < b['bound']['cost_start'] == pytest.approx(1.0)
    assert b['a_v'] < out['full-car-clipped-optimal-wk']['a_v'] < out['passive@0.0A']['a_v']
