"""Tests for mr_damper_model.io.params_file: JSON parameter files."""
import json
import math

import pytest

from mr_damper_model.io.data import DataError
from mr_damper_model.io.params_file import load_params, ParamsFile, save_params

KWOK = {'c': 800.0, 'k': 150.0, 'alpha': 300.0, 'beta': 40.0, 'delta': 0.5, 'f0': 5.0}


def test_round_trip(tmp_path):
    path = tmp_path / 'sub' / 'p.json'
    pf = ParamsFile(model='kwok', parameters=KWOK, current_min_a=0.0, current_max_a=0.0,
                    metrics={'rmse_n': 3.0}, seed=4, source='x.csv')
    save_params(path, pf)
    back = load_params(path, model='kwok')
    assert back.parameters == KWOK
    assert back.metrics == {'rmse_n': 3.0}
    assert back.seed == 4 and back.current_max_a == 0.0
    assert not list(path.parent.glob('*.tmp'))


def test_accepts_plain_dict_and_object_with_to_json_dict(tmp_path):
    class Result:
        def to_json_dict(self):
            return {'model': 'kwok', 'parameters': KWOK, 'extra_key': 1}

    save_params(tmp_path / 'a.json', Result())
    save_params(tmp_path / 'b.json', {'model': 'kwok', 'parameters': KWOK})
    assert load_params(tmp_path / 'a.json').parameters == KWOK
    assert math.isnan(load_params(tmp_path / 'b.json').current_min_a)


@pytest.mark.parametrize('content, match', [
    ('{not json', 'not valid JSON'),
    ('[1, 2]', 'expected a JSON object'),
    ('{"parameters": {}}', 'missing "model"'),
    ('{"model": "kwok"}', 'missing "parameters"'),
    ('{"model": "nonsense", "parameters": {}}', 'unknown model'),
    (json.dumps({'model': 'kwok', 'parameters': {k: v for k, v in KWOK.items() if k != 'beta'}}),
     'missing parameter.*beta'),
    (json.dumps({'model': 'kwok', 'parameters': dict(KWOK, alpha='x')}), 'alpha is not a number'),
    ('{"model": "kwok", "parameters": {"c": 1, "k": 1, "alpha": 1, "beta": NaN, "delta": 0,'
     ' "f0": 0}}', 'beta is nan'),
])
def test_bad_files(tmp_path, content, match):
    path = tmp_path / 'bad.json'
    path.write_text(content)
    with pytest.raises(DataError, match=match) as info:
        load_params(path)
    assert str(path) in str(info.value)


def test_wrong_model_and_missing_file(tmp_path):
    path = tmp_path / 'p.json'
    save_params(path, {'model': 'kwok', 'parameters': KWOK})
    with pytest.raises(DataError, match='expected "kwok-current"'):
        load_params(path, model='kwok-current')
    with pytest.raises(DataError, match='cannot read'):
        load_params(tmp_path / 'none.json')
