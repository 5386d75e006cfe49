"""
The ROS 2 launch file cannot run here (no ``launch`` / ``launch_ros`` on PyPI): check it.

What it starts is plain data in ``mr_damper_bringup.launch_spec``, called here directly and checked
against the installed console scripts, the packages' setup.py entry points and the suite's
parameter YAMLs (node names are the YAML keys, the parameters file exists); the launch file's own
code only turns that data into launch actions, which is checked by reading it (no stand-ins of
the launch API).
"""
import ast
import importlib.util
from pathlib import Path
import re

import numpy as np

import pytest
import yaml

from conftest import REPO, VENV_BIN
from integration.ros_helpers import console_scripts, package_of
from mr_damper_bringup.config import IDENT, node_params, NODES, QC, resolve_config, RIG
from mr_damper_bringup.launch_spec import default_params_parts, LAUNCH_ARGUMENTS, node_specs
from mr_damper_bringup.launcher import main, parse_args
from mr_damper_bringup.processes import wait_while_progressing

LAUNCH_FILE = REPO / 'src' / 'mr_damper_bringup' / 'launch' / 'suite.launch.py'
CONFIG_DIR = REPO / 'src' / 'mr_damper_bringup' / 'config'


PARAMS, REPLAY = 'PARAMS_FILE', 'REPLAY_FILE'


def test_the_launch_file_starts_what_launch_spec_says():
    """The launch file's only logic is launch_spec turned into launch actions (read, not run)."""
    tree = ast.parse(LAUNCH_FILE.read_text())
    imported = {a.name for n in ast.walk(tree) if isinstance(n, ast.ImportFrom)
                and n.module == 'mr_damper_bringup.launch_spec' for a in n.names}
    assert imported == {'default_params_parts', 'LAUNCH_ARGUMENTS', 'node_specs'}
    calls = [n for n in ast.walk(tree) if isinstance(n, ast.Call)
             and getattr(n.func, 'id', '') == 'Node']
    assert len(calls) == 1 and [k.arg for k in calls[0].keywords] == [None]   # Node(**spec)
    compile(tree, str(LAUNCH_FILE), 'exec')


def test_launcher_nodes_with_installed_console_scripts():
    specs = node_specs(PARAMS, REPLAY)
    # the launcher's nodes (mr_damper_bringup.config.NODES), each from the package declaring it
    assert [(n['package'], n['executable']) for n in specs] == [
        (package_of(exe), exe) for exe in NODES.values()]
    for n in specs:
        # what `ros2 run PKG EXE` starts: a console script of that package, installed here
        scripts = console_scripts(n['package'])
        assert n['executable'] in scripts
        module, func = scripts[n['executable']].split(':')
        assert module.startswith(n['package'] + '.')
        assert (VENV_BIN / n['executable']).exists()
        # the entry point exists in the package (module file + main function)
        path = REPO / 'src' / n['package'] / (module.replace('.', '/') + '.py')
        tree = ast.parse(path.read_text())
        assert func in {f.name for f in tree.body if isinstance(f, ast.FunctionDef)}


@pytest.mark.parametrize('config', ['sim', 'replay', 'hil'])
def test_one_parameter_file_whose_keys_are_the_node_names(config):
    assert [a[0] for a in LAUNCH_ARGUMENTS] == ['config', 'params_file', 'file']
    # the default parameter file: the launch file's PythonExpression of these parts
    parts = default_params_parts(str(CONFIG_DIR), config)
    path = Path(eval(''.join(parts)))  # noqa: S307 - the launch file's own expression
    assert path == CONFIG_DIR / f'suite_{config}.yaml' and path.exists()
    cfg = yaml.safe_load(path.read_text())
    specs = node_specs(PARAMS, REPLAY)
    for n in specs:
        # every node gets the same parameters file first (then at most literal overrides)
        assert n['parameters'][0] == PARAMS
        assert n['name'] in cfg and 'ros__parameters' in cfg[n['name']]
    assert [n['parameters'][1:] for n in specs if n['name'] == RIG] == [[{'file': REPLAY}]]
    assert set(cfg) - {'/**'} == {n['name'] for n in specs}
    # the true damper is shared by the rig and the car (honest loop)
    assert 'plant' in cfg['/**']['ros__parameters']


def _node_module(package, executable):
    """Return the node module a console script runs (through ``entry_points.early_main``)."""
    module, func = console_scripts(package)[executable].split(':')
    if module.endswith('.entry_points'):
        src = (REPO / 'src' / package / (module.replace('.', '/') + '.py')).read_text()
        found = re.search(rf"def {func}\(\):.*?early_main\('([\w.]+)'\)", src, re.S)
        assert found, f'{executable}: no early_main in {module}.{func}'
        module = found.group(1)
    return module


def test_node_names_match_the_nodes_and_the_launcher():
    """The name in the launch file is the name each node gives itself (YAML keys must match)."""
    specs = node_specs(PARAMS, REPLAY)
    for n in specs:
        module = _node_module(n['package'], n['executable'])
        text = (REPO / 'src' / n['package'] / (module.replace('.', '/') + '.py')).read_text()
        assert f"super().__init__('{n['name']}'" in text
    assert NODES == {n['name']: n['executable'] for n in specs}


@pytest.mark.parametrize('config', ['sim', 'replay', 'hil'])
def test_yaml_parameters_are_declared_by_the_nodes(config):
    """Every parameter in the YAML is one the node declares (typos would be silently ignored)."""
    cfg = yaml.safe_load((CONFIG_DIR / f'suite_{config}.yaml').read_text())
    modules = {'mr_damper_rig': 'mr_damper_rig.rig_node',
               'mr_damper_identifier': 'mr_damper_model.nodes.identifier_node',
               'quarter_car_node': 'quarter_car_sim.nodes.quarter_car_node'}
    shared = cfg.get('/**', {}).get('ros__parameters', {})
    for node, module in modules.items():
        declared = {p.name for p in importlib.import_module(module).PARAMETERS}
        names = set(cfg[node]['ros__parameters'])
        if node != 'mr_damper_identifier':      # the true damper: the rig's and the car's
            names |= set(shared)
        assert names <= declared, f'{node}: not declared: {sorted(names - declared)}'


def test_launcher_config_resolution(tmp_path):
    args = parse_args(['--out', str(tmp_path), '--rate-factor', '3', '--duration', '40',
                       '--set', 'quarter_car_node.safe_current_a=1.0',
                       '--set', '/**.plant=kwok-current'])
    cfg = resolve_config(args, tmp_path)
    qc = node_params(cfg, QC)
    assert qc['safe_current_a'] == 1.0 and isinstance(qc['safe_current_a'], float)
    assert qc['real_time_factor'] == 3.0 and node_params(cfg, RIG)['rate_factor'] == 3.0
    assert qc['plant'] == 'kwok-current' == node_params(cfg, RIG)['plant']
    # the road (default 300 s) outlasts the run (40 s at 3x): held, not repeated
    assert qc.get('road_duration_s', 300.0) >= 40 * 3.0 and not qc.get('road_repeat', False)
    assert qc['log_file'] == str(tmp_path / 'quarter_car_log')
    assert node_params(cfg, IDENT)['params_file'] == str(tmp_path / 'identifier_params.json')
    # a run longer than the road drives it again instead of a road as long as the run
    long = resolve_config(parse_args(['--out', str(tmp_path), '--duration', '3600']),
                          tmp_path)
    assert node_params(long, QC)['road_repeat'] is True
    assert node_params(long, QC).get('road_duration_s', 300.0) == 300.0


def test_launcher_replay_concatenates_csv_files(tmp_path):
    from conftest import QUIROZ_DIR
    from mr_damper_model.io.data import read_csv
    files = sorted(QUIROZ_DIR.glob('quiroz_sine_10mm1Hz_*A_preproc.csv.gz'))[:2]
    args = parse_args(['--out', str(tmp_path), '--config', 'replay']
                      + [a for f in files for a in ('--file', str(f))])
    cfg = resolve_config(args, tmp_path)
    rig = node_params(cfg, RIG)
    assert rig['mode'] == 'csv' and rig['file'] == str(tmp_path / 'replay_input.csv')
    joined = read_csv(rig['file'])
    parts = [read_csv(f) for f in files]
    assert joined.n == sum(p.n for p in parts)
    assert np.all(np.diff(joined.t) > 0)
    np.testing.assert_array_equal(joined.f, np.concatenate([p.f for p in parts]))


@pytest.mark.parametrize('argv, message', [
    (['--config', 'replay', '--file', '/nonexistent.csv'], 'no such file'),
    (['--set', 'no_equals_sign'], 'NODE.PARAM=VALUE'),
])
def test_launcher_bad_input_exits_2(tmp_path, capsys, argv, message):
    assert main(['--out', str(tmp_path), *argv]) == 2
    assert message in capsys.readouterr().err


def test_node_default_yaml_lists_every_declared_parameter():
    from quarter_car_sim.nodes.quarter_car_node import PARAMETERS
    declared = {spec.name for spec in PARAMETERS}
    cfg = yaml.safe_load((REPO / 'src/quarter_car_sim/config/quarter_car.yaml').read_text())
    assert set(cfg['quarter_car_node']['ros__parameters']) == declared


def test_drain_waits_while_the_identifier_progresses_and_not_for_a_stuck_one():
    """The stop drains a slow identifier to the last sample; a stuck one cannot hold it."""
    calls = []

    def slow():               # 1 sample more per look: done after 50 looks, however slow
        calls.append(1)
        return len(calls) >= 50, len(calls)
    assert wait_while_progressing(slow, stall_s=30.0, guard_s=300.0, poll_s=0.0)
    assert len(calls) == 50
    assert not wait_while_progressing(lambda: (False, 7), stall_s=0.05, guard_s=300.0,
                                      poll_s=0.01)
    assert wait_while_progressing(lambda: (True, None), stall_s=0.0, guard_s=0.0)
