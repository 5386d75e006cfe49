"""Tests of the quarter-car-sim command line."""
import json
import subprocess

import pytest

from conftest import VENV_BIN
from mr_damper_model.identification import presets
from mr_damper_model.io.params_file import save_params
from mr_damper_bringup import ride_study_cli as cli


@pytest.fixture
def params_file(tmp_path):
    _, truth = presets.thesis_kwok_current()
    p = tmp_path / 'fit.json'
    save_params(p, {'model': 'kwok-current', 'parameters': truth,
                    'model_options': {'i_ref_a': 2.0}})
    return p


@pytest.mark.slow
def test_compare_json(params_file, capsys):
    rc = cli.main(['--compare', '--json', '--duration', '3', '--plant', 'kwok',
                   '--damper-params', str(params_file)])
    assert rc == 0
    out = json.loads(capsys.readouterr().out)
    names = set(out['controllers'])
    assert {'passive@0.0A', 'passive@2.0A', 'skyhook', 'skyhook-onoff', 'groundhook', 'hybrid',
            'sh-add', 'clipped-optimal', 'clipped-optimal-wk', 'skyhook-ideal', 'lqr-active',
            'bound'} <= names
    assert names == set(f'passive@{i:.1f}A' for i in cli.COMPARE_CURRENTS_A) | set(
        cli.COMPARE_NAMES) | set(cli.PREVIEW_ROWS) | {'bound'}
    assert out['controllers']['preview-look-ahead']['preview']['sensor']['latency_s'] == 0.02
    assert 0.0 <= out['controllers']['bound']['mean_current_a'] <= 2.0
    for m in out['controllers'].values():
        for key in ('rms_body_accel_wk', 'rms_body_accel', 'rms_suspension_travel',
                    'rms_tyre_load_ratio'):
            assert m[key] > 0
    assert out['controllers']['lqr-active']['mean_current_a'] is None


@pytest.mark.slow
def test_compare_table_names_the_new_laws_and_the_bound(params_file, capsys):
    rc = cli.main(['--compare', '--duration', '2', '--plant', 'kwok',
                   '--damper-params', str(params_file)])
    assert rc == 0
    rows = [line.split()[0] for line in capsys.readouterr().out.splitlines()[2:-1]]
    assert rows[-5:] == ['skyhook-ideal', 'lqr-active', 'preview-look-ahead-ideal',
                         'preview-look-ahead', 'bound']
    assert 'sh-add' in rows and 'clipped-optimal' in rows


def test_a_preview_row_reports_its_settings_and_counters(params_file, capsys):
    rc = cli.main(['--controller', 'preview-look-ahead', '--duration', '0.5', '--plant', 'kwok',
                   '--damper-params', str(params_file), '--json', '--preview-noise', '0.002',
                   '--preview-horizon', '0.2', '--speed-error', '-0.01'])
    assert rc == 0
    out = json.loads(capsys.readouterr().out)
    (name, m), = out['controllers'].items()
    pv = m['preview']
    assert name == 'preview-look-ahead' and pv['source'] == 'look-ahead'
    assert pv['horizon_s'] == 0.2 and pv['speed_scale_error'] == -0.01
    assert pv['sensor']['height_noise_m'] == 0.002 and pv['sensor']['range_m'] == [0.5, 15.0]
    assert pv['law']['steps'] == 1001                           # 0.5 s settling + 0.5 s
    assert pv['road_preview']['frames_taken'] == pv['sensor_frames']['delivered'] > 0
    # a road in time only has no distances to preview
    assert cli.main(['--controller', 'preview-look-ahead', '--road', 'sine', '--plant', 'kwok',
                     '--damper-params', str(params_file)]) == 2


def test_single_controller_table(params_file, capsys):
    rc = cli.main(['--controller', 'skyhook', '--road', 'bump', '--speed', '10',
                   '--duration', '2', '--plant', 'kwok', '--damper-params', str(params_file)])
    assert rc == 0
    out = capsys.readouterr().out
    assert 'skyhook' in out and 'Wk' in out


@pytest.mark.parametrize('args, match', [
    (['--road', 'iso8608-Z'], 'road class'),
    (['--road', 'missing.csv'], 'not found'),
    (['--controller', 'magic'], 'unknown controller'),
])
def test_bad_input_exit_2_one_line(args, match, capsys):
    assert cli.main(args + ['--duration', '1']) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and match in err[0] and 'Traceback' not in err[0]


def test_bad_params_file_nan(tmp_path, capsys):
    p = tmp_path / 'nan.json'
    _, truth = presets.thesis_kwok_current()
    text = json.dumps({'model': 'kwok-current', 'parameters': dict(truth, c0='NaN')})
    p.write_text(text.replace('"NaN"', 'NaN'))
    assert cli.main(['--damper-params', str(p), '--duration', '1']) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and 'c0' in err[0]


@pytest.mark.slow
def test_console_script_negative_speed_and_missing_params(tmp_path):
    exe = str(VENV_BIN / 'quarter-car-sim')
    for args, match in ((['--speed', '-5'], 'speed'),
                        (['--damper-params', str(tmp_path / 'none.json')], 'none.json')):
        r = subprocess.run([exe] + args, capture_output=True, text=True, timeout=60)
        assert r.returncode == 2
        lines = r.stderr.strip().splitlines()
        assert len(lines) == 1 and match in lines[0], r.stderr


@pytest.mark.slow
def test_sensing_vehicle_json_reports_estimation_errors(params_file, capsys):
    args = ['--controller', 'clipped-optimal-wk', '--json', '--duration', '3', '--plant',
            'kwok', '--damper-params', str(params_file)]
    assert cli.main(args + ['--sensing', 'ideal']) == 0
    ideal = json.loads(capsys.readouterr().out)
    assert cli.main(args + ['--sensing', 'vehicle']) == 0
    out = json.loads(capsys.readouterr().out)
    assert ideal['sensing'] == 'ideal' and out['sensing'] == 'vehicle'
    m, m0 = out['controllers']['clipped-optimal-wk'], ideal['controllers']['clipped-optimal-wk']
    for state in ('travel', 'v_s', 'tyre_def', 'v_u', 'v_rel', 'a_s'):
        assert m[f'est_rms_error_{state}'] > 0
    assert m['est_rel_error_travel'] < 0.02
    assert m['estimator']['steps'] > 3000 and m['estimator']['failsafe_steps'] == 0
    assert 'est_rms_error_travel' not in m0
    # the same road and law on estimated states: Wk within 5 % of the ideal-state run
    assert abs(m['rms_body_accel_wk'] / m0['rms_body_accel_wk'] - 1.0) < 0.05
