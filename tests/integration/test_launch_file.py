"""
The ROS 2 launch file cannot run here (no ``launch`` / ``launch_ros`` on PyPI): check it.

It is executed against small stand-ins of the ``launch`` API that record what it asks for, and the
result is checked against the installed console scripts, the packages' setup.py entry points and
the suite's parameter YAMLs (node names are the YAML keys, parameters file path exists).
"""
import ast
import importlib.util
from pathlib import Path
import re
import sys
import types

import numpy as np

import pytest
import yaml

from conftest import REPO, VENV_BIN
from integration.ros_helpers import console_scripts, package_of
from mr_damper_bringup.config import IDENT, node_params, NODES, QC, resolve_config, RIG
from mr_damper_bringup.launcher import main, parse_args
from mr_damper_bringup.processes import wait_while_progressing

LAUNCH_FILE = REPO / 'src' / 'mr_damper_bringup' / 'launch' / 'suite.launch.py'
CONFIG_DIR = REPO / 'src' / 'mr_damper_bringup' / 'config'


class _Recorded:
    def __init__(self, *args, **kwargs):
        self.args = args
        self.kwargs = kwargs


class _LaunchConfiguration(_Recorded):
    pass


class _PythonExpression(_Recorded):
    def evaluate(self, values):
        text = ''
        for part in self.args[0]:
            text += values[part.args[0]] if isinstance(part, _LaunchConfiguration) else part
        return eval(text)  # noqa: S307 - the launch file's own expression, test only


@pytest.fixture
def launch_description(monkeypatch):
    """Run ``generate_launch_description`` with recording stand-ins of launch / launch_ros."""
    launch = types.ModuleType('launch')
    launch.LaunchDescription = _Recorded
    actions = types.ModuleType('launch.actions')
    actions.DeclareLaunchArgument = _Recorded
    subs = types.ModuleType('launch.substitutions')
    subs.LaunchConfiguration = _LaunchConfiguration
    subs.PythonExpression = _PythonExpression
    launch_ros = types.ModuleType('launch_ros')
    ros_actions = types.ModuleType('launch_ros.actions')
    ros_actions.Node = _Recorded
    for name, mod in (('launch', launch), ('launch.actions', actions),
                      ('launch.substitutions', subs), ('launch_ros', launch_ros),
                      ('launch_ros.actions', ros_actions)):
        monkeypatch.setitem(sys.modules, name, mod)
    spec = importlib.util.spec_from_file_location('suite_launch', LAUNCH_FILE)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module.generate_launch_description()


def _entries(action_list, kind):
    return [a for a in action_list if a.__class__ is _Recorded and kind(a)]


def test_launcher_nodes_with_installed_console_scripts(launch_description):
    items = launch_description.args[0]
    nodes = [a.kwargs for a in items if 'executable' in a.kwargs]
    # the launcher's nodes (mr_damper_bringup.config.NODES), each from the package declaring it
    assert [(n['package'], n['executable']) for n in nodes] == [
        (package_of(exe), exe) for exe in NODES.values()]
    for n in nodes:
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
def test_one_parameter_file_whose_keys_are_the_node_names(launch_description, config):
    items = launch_description.args[0]
    args = {a.args[0]: a.kwargs for a in items if 'executable' not in a.kwargs}
    assert set(args) >= {'config', 'params_file'}
    default = args['params_file']['default_value']
    path = Path(default.evaluate({'config': config}))
    assert path == CONFIG_DIR / f'suite_{config}.yaml' and path.exists()
    cfg = yaml.safe_load(path.read_text())
    nodes = [a.kwargs for a in items if 'executable' in a.kwargs]
    for n in nodes:
        # every node gets the same parameters file first (then at most literal overrides)
        first = n['parameters'][0]
        assert isinstance(first, _LaunchConfiguration) and first.args[0] == 'params_file'
        assert n['name'] in cfg and 'ros__parameters' in cfg[n['name']]
    assert set(cfg) - {'/**'} == {n['name'] for n in nodes}
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


def test_node_names_match_the_nodes_and_the_launcher(launch_description):
    """The name in the launch file is the name each node gives itself (YAML keys must match)."""
    nodes = [a.kwargs for a in launch_description.args[0] if 'executable' in a.kwargs]
    for n in nodes:
        module = _node_module(n['package'], n['executable'])
        text = (REPO / 'src' / n['package'] / (module.replace('.', '/') + '.py')).read_text()
        assert f"super().__init__('{n['name']}'" in text
    assert NODES == {n['name']: n['executable'] for n in nodes}


@pytest.mark.parametrize('config', ['sim', 'replay', 'hil'])
def test_yaml_parameters_are_declared_by_the_nodes(config):
    """Every parameter in the YAML is one the node declares (typos would be silently ignored)."""
    cfg = yaml.safe_load((CONFIG_DIR / f'suite_{config}.yaml').read_text())
    modules = {'mr_damper_rig': 'mr_damper_rig.rig_node',
               'mr_damper_identifier': 'mr_damper_model.nodes.identifier_node',
               'quarter_car_node': 'quarter_car_sim.quarter_car_node'}
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
    from quarter_car_sim.quarter_car_node import PARAMETERS
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
