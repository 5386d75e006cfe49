"""CornerModels: the shipped end-of-line files load, bad files and records are refused."""
import json
import math

import pytest

from conftest import REPO
from kwok_messages import thesis_parameter_values
from semi_active_control.supervision.corner_models import CornerModels, load_model_file

MODELS = REPO / 'src' / 'semi_active_control' / 'config' / 'models'
SHIPPED = [str(MODELS / f'{c}.json') for c in ('fl', 'fr', 'rl', 'rr')]
SUP = dict(safe_current_a=0.5, i_min_a=0.0, i_max_a=2.0, min_current_span_a=1.0)


def test_the_shipped_files_are_accepted_and_never_age():
    models = CornerModels(SHIPPED, timeout_s=1.0, **SUP)
    verdicts = models.load_files(0.0)
    assert [v.accepted for v in verdicts.values()] == [True] * 4
    assert models.update(1.0e6) == ['normal'] * 4          # a file model does not age
    m = models.force_model('rl')
    # the identified damper resists motion: compression (v < 0) pushes, rebound pulls
    assert m.force(1.0, 0.0, 0.1) > m.force(0.0, 0.0, 0.1) > 0
    assert m.force(1.0, 0.0, -0.1) < 0
    st = models.status(1.0)
    assert st['fl']['source'] == 'file' and st['fl']['params_accepted'] == 1
    assert math.isnan(st['fl']['param_age_s'])


def test_bad_files_and_invalid_records_leave_their_corner_on_the_safe_current(tmp_path):
    bad_json = tmp_path / 'bad.json'
    bad_json.write_text('{"model": "kwok-current", "param')
    failed = tmp_path / 'failed.json'
    record = json.loads((MODELS / 'fr.json').read_text())
    failed.write_text(json.dumps(dict(record, valid=False)))
    files = [str(bad_json), str(failed), str(tmp_path / 'missing.json'), SHIPPED[3]]
    models = CornerModels(files, **SUP)
    verdicts = models.load_files(0.0)
    assert [verdicts[c].reason for c in ('fl', 'fr', 'rl', 'rr')] == [
        'undecodable', 'invalid_flag', 'undecodable', 'ok']
    assert models.update(0.1) == ['failsafe', 'failsafe', 'failsafe', 'normal']
    assert set(models.load_errors) == {'fl', 'rl'} and 'bad.json' in models.load_errors['fl']
    assert models.force_model('fl') is None and models.force_model('rr') is not None
    with pytest.raises(ValueError, match='not valid JSON'):
        load_model_file(bad_json)


def test_a_live_corner_takes_the_identifier_and_goes_stale():
    models = CornerModels(['', SHIPPED[1], '', ''], timeout_s=1.0, **SUP)
    models.load_files(0.0)
    assert models.offer_live('fl', thesis_parameter_values(), 0.0).accepted
    assert models.offer_live('fr', thesis_parameter_values(), 0.0) is None   # a file corner
    assert models.update(0.5)[:2] == ['normal', 'normal']
    assert models.update(1.5)[:2] == ['failsafe', 'normal']
    assert models.supervisors[0].reason == 'stale'
    with pytest.raises(ValueError, match='one entry per corner'):
        CornerModels(['', ''])
