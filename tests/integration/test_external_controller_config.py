"""mr-damper-suite with the law in the controller node: the resolved configuration, no process."""
from mr_damper_bringup.config import (CTRL, IDENT, node_params, NODES, QC, resolve_config, RIG,
                                      suite_nodes)
from mr_damper_bringup.launcher import parse_args


def _resolve(tmp_path, *argv):
    args = parse_args(['--out', str(tmp_path), *argv])
    return resolve_config(args, tmp_path)


def test_built_in_controller_stays_the_default(tmp_path):
    cfg = _resolve(tmp_path)
    assert node_params(cfg, QC)['controller'] == 'skyhook'
    assert list(suite_nodes(cfg)) == list(NODES) and CTRL not in cfg


def test_external_controller_moves_the_law_into_the_controller_node(tmp_path):
    cfg = _resolve(tmp_path, '--external-controller',
                   '--set', 'quarter_car_node.safe_current_a=0.25')
    car = node_params(cfg, QC)
    ctrl = node_params(cfg, CTRL)
    assert car['controller'] == 'external'
    # the shipped suite's law, options and fail-safe settings go with it
    assert ctrl['controller'] == 'skyhook'
    assert ctrl['controller_options'] == car['controller_options'] == '{"c_sky": 3000.0}'
    assert ctrl['safe_current_a'] == 0.25 and ctrl['param_timeout_s'] == car['param_timeout_s']
    nodes = suite_nodes(cfg)
    assert list(nodes) == [RIG, IDENT, CTRL, QC]       # controller before the car
    assert nodes[CTRL] == 'semi_active_controller_node'


def test_controller_external_in_the_config_starts_the_node_too(tmp_path):
    cfg = _resolve(tmp_path, '--set', 'quarter_car_node.controller=external',
                   '--set', 'semi_active_controller.controller=groundhook')
    assert CTRL in suite_nodes(cfg)
    assert node_params(cfg, CTRL)['controller'] == 'groundhook'     # its own wins
    cfg2 = _resolve(tmp_path, '--set', 'quarter_car_node.controller=external')
    assert 'controller' not in node_params(cfg2, CTRL)           # node default
