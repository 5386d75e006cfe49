"""run_suite.py with the law in the controller node: the resolved configuration (no processes)."""
from integration.ros_helpers import load_run_suite


def _resolve(tmp_path, *argv):
    rs = load_run_suite()
    args = rs.parse_args(['--out', str(tmp_path), *argv])
    return rs, rs.resolve_config(args, tmp_path)


def test_built_in_controller_stays_the_default(tmp_path):
    rs, cfg = _resolve(tmp_path)
    assert rs.node_params(cfg, rs.QC)['controller'] == 'skyhook'
    assert list(rs.suite_nodes(cfg)) == list(rs.NODES) and rs.CTRL not in cfg


def test_external_controller_moves_the_law_into_the_controller_node(tmp_path):
    rs, cfg = _resolve(tmp_path, '--external-controller',
                       '--set', 'quarter_car_node.safe_current_a=0.25')
    car = rs.node_params(cfg, rs.QC)
    ctrl = rs.node_params(cfg, rs.CTRL)
    assert car['controller'] == 'external'
    # the shipped suite's law, options and fail-safe settings go with it
    assert ctrl['controller'] == 'skyhook'
    assert ctrl['controller_options'] == car['controller_options'] == '{"c_sky": 3000.0}'
    assert ctrl['safe_current_a'] == 0.25 and ctrl['param_timeout_s'] == car['param_timeout_s']
    nodes = rs.suite_nodes(cfg)
    assert list(nodes) == [rs.RIG, rs.IDENT, rs.CTRL, rs.QC]       # controller before the car
    assert nodes[rs.CTRL] == 'semi_active_controller_node'


def test_controller_external_in_the_config_starts_the_node_too(tmp_path):
    rs, cfg = _resolve(tmp_path, '--set', 'quarter_car_node.controller=external',
                       '--set', 'semi_active_controller.controller=groundhook')
    assert rs.CTRL in rs.suite_nodes(cfg)
    assert rs.node_params(cfg, rs.CTRL)['controller'] == 'groundhook'     # its own wins
    rs2, cfg2 = _resolve(tmp_path, '--set', 'quarter_car_node.controller=external')
    assert 'controller' not in rs2.node_params(cfg2, rs2.CTRL)           # node default
