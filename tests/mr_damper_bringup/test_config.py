"""Tests of mr_damper_bringup.config (the suite's parameter YAMLs and one run's parameters)."""
import pytest
import yaml

from mr_damper_bringup import config
from mr_damper_bringup.launcher import parse_args


@pytest.mark.parametrize('name', ['sim', 'replay', 'hil'])
def test_shipped_configs_load_with_a_section_per_node(name):
    cfg = config.load_config(name)
    raw = yaml.safe_load((config.CONFIG_DIR / f'suite_{name}.yaml').read_text())
    assert set(cfg) == set(raw) | set(config.NODES)
    assert set(raw) <= {'/**', config.CTRL, *config.NODES}
    for node in config.NODES:
        assert isinstance(cfg[node]['ros__parameters'], dict)
    # the true damper is shared by the rig and the car (honest loop); in HIL the car's damper
    # IS the rig's
    car = config.node_params(cfg, config.QC)['plant']
    assert car == ('rig' if name == 'hil' else config.node_params(cfg, config.RIG)['plant'])


def test_node_params_merge_shared_then_own():
    cfg = {'/**': {'ros__parameters': {'plant': 'spencer', 'seed': 1}},
           'quarter_car_node': {'ros__parameters': {'seed': 7}}}
    assert config.node_params(cfg, config.QC) == {'plant': 'spencer', 'seed': 7}
    assert config.node_params(cfg, config.RIG) == {'plant': 'spencer', 'seed': 1}
    config.set_param(cfg, config.RIG, 'seed', 3)
    assert config.node_params(cfg, config.RIG)['seed'] == 3


def test_bad_parameter_files_are_refused(tmp_path):
    with pytest.raises(config.SuiteError, match='cannot read parameter file'):
        config.load_config(params=tmp_path / 'missing.yaml')
    (tmp_path / 'list.yaml').write_text('- 1\n- 2\n')
    with pytest.raises(config.SuiteError, match='top level is not a mapping'):
        config.load_config(params=tmp_path / 'list.yaml')


def test_set_values_are_yaml_typed(tmp_path):
    args = parse_args(['--out', str(tmp_path), '--set', 'quarter_car_node.safe_current_a=1.0',
                       '--set', 'mr_damper_rig.seed=4',
                       '--set', 'quarter_car_node.road_repeat=true',
                       '--set', 'quarter_car_node.road=bump', '--set', '/**.truth_file='])
    cfg = config.resolve_config(args, tmp_path)
    qc = config.node_params(cfg, config.QC)
    assert qc['safe_current_a'] == 1.0 and isinstance(qc['safe_current_a'], float)
    assert config.node_params(cfg, config.RIG)['seed'] == 4
    assert qc['road_repeat'] is True and qc['road'] == 'bump' and qc['truth_file'] == ''
    with pytest.raises(config.SuiteError, match='expected NODE.PARAM=VALUE'):
        config.resolve_config(parse_args(['--out', str(tmp_path), '--set', 'noequals']),
                              tmp_path)


def test_replay_needs_existing_files(tmp_path):
    args = parse_args(['--out', str(tmp_path), '--config', 'replay',
                       '--file', str(tmp_path / 'gone.csv')])
    with pytest.raises(config.SuiteError, match='no such file'):
        config.resolve_config(args, tmp_path)


@pytest.mark.slow
def test_replay_default_input_is_the_data_shipped_in_the_repository(tmp_path):
    import numpy as np
    from mr_damper_model.io.data import read_csv
    from conftest import REPO
    assert len(config.DEFAULT_REPLAY) == 5
    for f in config.DEFAULT_REPLAY:
        assert f.is_file() and f.is_relative_to(REPO / 'data'), f
    cfg = config.resolve_config(parse_args(['--out', str(tmp_path), '--config', 'replay']),
                                tmp_path)
    rig = config.node_params(cfg, config.RIG)
    assert rig['mode'] == 'csv' and rig['file'] == str(tmp_path / 'replay_input.csv')
    joined, parts = read_csv(rig['file']), [read_csv(f) for f in config.DEFAULT_REPLAY]
    assert joined.n == sum(p.n for p in parts) and np.all(np.diff(joined.t) > 0)
    np.testing.assert_array_equal(joined.i, np.concatenate([p.i for p in parts]))
    # one compressed file is replayed as it is, as a CSV (not taken for a bag)
    one = parse_args(['--out', str(tmp_path), '--file', str(config.DEFAULT_REPLAY[2])])
    rig = config.node_params(config.resolve_config(one, tmp_path), config.RIG)
    assert rig['mode'] == 'csv' and rig['file'] == str(config.DEFAULT_REPLAY[2])


def test_corner_configs_key_nodes_by_namespace_and_separate_what_must_differ(tmp_path):
    from mr_damper_bringup.config import corner_configs, IDENT, QC, RIG, SuiteError
    cfg = {'/**': {'ros__parameters': {'plant': 'spencer'}},
           RIG: {'ros__parameters': {'seed': 3, 'mode': 'sim'}},
           IDENT: {'ros__parameters': {'window_s': 2.0}},
           QC: {'ros__parameters': {'road_seed': 7, 'safe_current_a': 0.5}}}
    out = corner_configs(cfg, ['fl', 'fr'], tmp_path)
    assert list(out) == ['fl', 'fr']
    fl, fr = out['fl'], out['fr']
    assert set(fl) == {'/**', f'/fl/{RIG}', f'/fl/{IDENT}', f'/fl/{QC}'}
    assert fl['/**'] == cfg['/**'] and fl['/**'] is not cfg['/**']
    # what differs between corners: rig seed, road seed, identifier file, car log
    assert (fl[f'/fl/{RIG}']['ros__parameters']['seed'],
            fr[f'/fr/{RIG}']['ros__parameters']['seed']) == (3, 4)
    assert (fl[f'/fl/{QC}']['ros__parameters']['road_seed'],
            fr[f'/fr/{QC}']['ros__parameters']['road_seed']) == (7, 8)
    assert fl[f'/fl/{IDENT}']['ros__parameters']['params_file'] != \
        fr[f'/fr/{IDENT}']['ros__parameters']['params_file']
    assert fr[f'/fr/{QC}']['ros__parameters']['log_file'].endswith('quarter_car_log_fr')
    # the rest is the same, and the input is untouched
    assert fl[f'/fl/{QC}']['ros__parameters']['safe_current_a'] == 0.5
    assert cfg[RIG]['ros__parameters']['seed'] == 3
    for bad in (['fl', 'fl'], ['front'], []):
        with pytest.raises(SuiteError, match='--corners'):
            corner_configs(cfg, bad, tmp_path)


def test_the_external_controller_takes_the_law_and_the_car_s_control_rate():
    cfg = {'quarter_car_node': {'ros__parameters': {
        'controller': 'clipped-optimal-wk', 'rate_hz': 500.0, 'safe_current_a': 0.4}}}
    config.use_external_controller(cfg)
    ctrl = config.node_params(cfg, config.CTRL)
    # the law's Wk filter runs at the car's control period, not the node's 1 kHz default
    assert ctrl == {'controller': 'clipped-optimal-wk', 'rate_hz': 500.0, 'safe_current_a': 0.4}
    assert config.node_params(cfg, config.QC)['controller'] == 'external'
    assert list(config.suite_nodes(cfg)) == [config.RIG, config.IDENT, config.CTRL, config.QC]
