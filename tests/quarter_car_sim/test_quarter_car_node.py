"""In-process tests of the quarter-car node: parameters, callbacks, status, log file."""
import json
import math

import numpy as np
import pytest


@pytest.fixture
def node_factory(tmp_path):
    import rclpy
    from rclpy.context import Context
    from rclpy.parameter import Parameter
    from quarter_car_sim.quarter_car_node import QuarterCarNode
    ctx = Context()
    rclpy.init(context=ctx)
    made = []

    def make(**params):
        values = {'real_time_factor': 5.0, 'plant': 'kwok-current', 'road_duration_s': 30.0,
                  'log_file': str(tmp_path / 'log'), 'params_topic': '/h5unit/params',
                  'command_topic': '/h5unit/cmd', 'state_topic': '/h5unit/state',
                  'status_topic': '/h5unit/status', 'metrics_topic': '/h5unit/metrics'}
        values.update(params)
        node = QuarterCarNode(context=ctx, parameter_overrides=[
            Parameter(k, value=v) for k, v in values.items()])
        made.append(node)
        return node
    yield make
    for node in made:
        node.stop()
        node.destroy_node()
    rclpy.try_shutdown(context=ctx)


def _msg(**changes):
    from mr_damper_model import presets
    from mr_damper_model.messages import kwok_parameters_msg
    model, params = presets.thesis_kwok_current()
    values = dict(params, i_ref_a=2.0, window_end_s=1.0, current_min_a=0.0, current_max_a=2.0,
                  rmse_n=1.0, nrmse_percent=0.5, valid=1.0)
    values.update(changes)
    return kwok_parameters_msg(values)


def test_callbacks_drive_the_supervisor_and_status(node_factory, tmp_path):
    from mr_damper_interfaces.msg import KwokParameters
    node = node_factory(safe_current_a=0.25)
    assert node.sup.safe_current_a == 0.25 and node.sup.mode == 'failsafe'
    node.on_params(_msg())
    assert node.sup.mode == 'normal'
    node.on_params(_msg(valid=0.0))
    node.on_params(KwokParameters())              # i_ref_a 0: undecodable
    st = node.status()
    assert st['mode'] == 'failsafe' and st['reason'] == 'undecodable'
    assert st['params_accepted'] == 1
    assert st['params_rejected']['invalid_flag'] == 1 and st['params_rejected']['undecodable'] == 1
    json.dumps(st)                                   # JSON-ready (status_msg also maps NaN)
    node.on_params(_msg())
    import time
    time.sleep(0.3)                                  # ~1.5 s of simulated time at x5
    st = node.status()
    assert st['steps'] > 200 and st['t_sim'] > -0.5 + 0.2
    assert st['loop']['steps'] == st['steps'] or st['loop']['steps'] >= st['steps'] - 1
    node.stop()
    from mr_damper_model.columnlog import ColumnReader
    log = ColumnReader(tmp_path / 'log')
    z = log.read()
    assert z['t'].size >= st['steps'] and log.meta['dt'] == pytest.approx(1e-3)
    assert np.all((z['i_cmd'] >= 0.0) & (z['i_cmd'] <= 2.0))
    assert log.meta['status']['controller'] == 'skyhook'


def test_bad_parameters_raise_value_error(node_factory):
    with pytest.raises(ValueError, match='force actuator'):
        node_factory(controller='lqr-active')
    with pytest.raises(ValueError):
        node_factory(road_class='Z')


def test_state_message_layout():
    from quarter_car_sim.quarter_car_node import _fmt, STATE_JOINTS
    from quarter_car_sim.dynamics import CarState
    s = CarState(0.1, 1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0, 8.0, 9.0, 10.0, 11.0, 12.0)
    pos, vel, eff = _fmt(s)
    assert STATE_JOINTS == ('body', 'wheel', 'suspension', 'tyre')
    assert pos == [1.0, 4.0, 8.0, 7.0]               # z_s, z_u, travel, z_r
    assert vel == [2.0, 5.0, 9.0, 12.0]              # v_s, v_u, v_rel, coil current
    assert eff == [3.0, 6.0, 11.0, 10.0]             # a_s, a_u, damper force, tyre load
    assert not any(math.isnan(v) for v in pos + vel + eff)
