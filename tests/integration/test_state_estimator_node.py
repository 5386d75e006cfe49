"""
The state estimator node feeding the semi-active controller node over ROS 2 (real processes).

This test process plays the vehicle: it publishes the body accelerometer (``sensor_msgs/Imu``)
and the suspension position (``sensor_msgs/JointState``) of a car at rest with sensor noise,
and a valid identified parameter set. Order of events and counters only; waits are hang
guards:

1. the estimator's estimate is valid, its states reach the controller, which commands with the
   model (``commands_normal`` rises);
2. the accelerometer falls silent: the estimator marks its state invalid (``dropout_body_accel``,
   counted once), the controller refuses those states (``state_rejected.non_finite`` rises)
   and commands its safe current;
3. the accelerometer is back: the estimate is valid again and normal commands resume;
4. both nodes exit 0 on SIGINT.
"""
import threading

import numpy as np
import pytest

from integration.ros_helpers import NodeProcess
from kwok_messages import thesis_parameter_values

pytestmark = [pytest.mark.integration, pytest.mark.slow]

GUARD_S = 60.0
NS = 'estimator_node_test'
EST_NAME, CTRL_NAME = f'{NS}/state_estimator', f'{NS}/semi_active_controller'
RATE_HZ = 200.0
SAFE_A = 0.5
# dropout_s: long enough that a stall of the test's own sensor timer on a loaded machine is
# rarely taken for a dropout (and when it is, the counts below allow for it)
EST = {'rate_hz': RATE_HZ, 'dropout_s': 1.0, 'accel_latency_s': 0.0, 'travel_latency_s': 0.0,
       'param_timeout_s': 3600.0, 'diagnostics_period_s': 0.05}
CTRL = {'rate_hz': RATE_HZ, 'safe_current_a': SAFE_A, 'param_timeout_s': 3600.0,
        'diagnostics_period_s': 0.05}


class _Vehicle:
    """Sensor publishers of a car at rest, on a timer of the listener node."""

    def __init__(self, lis):
        from rclpy.qos import qos_profile_sensor_data
        from sensor_msgs.msg import Imu, JointState
        from semi_active_control.estimation.sensor_specs import (accelerometer_spec, G0,
                                                                 ride_height_spec)
        self.imu_pub = lis.node.create_publisher(Imu, f'/{NS}/quarter_car/body_imu',
                                                 qos_profile_sensor_data)
        self.pos_pub = lis.node.create_publisher(JointState,
                                                 f'/{NS}/quarter_car/suspension_position',
                                                 qos_profile_sensor_data)
        band = RATE_HZ / 2.0
        self.acc_std = accelerometer_spec().noise_density * band ** 0.5
        self.pos_std = ride_height_spec().noise_density * band ** 0.5
        self.g = G0
        self.rng = np.random.default_rng(5)
        self.imu_on = threading.Event()
        self.imu_on.set()
        self.imu, self.pos = Imu(), JointState(name=['suspension'], position=[0.0])
        self.timer = lis.node.create_timer(1.0 / RATE_HZ, self.tick)

    def tick(self):
        if self.imu_on.is_set():
            self.imu.linear_acceleration.z = self.g + self.acc_std * self.rng.standard_normal()
            self.imu_pub.publish(self.imu)
        self.pos.position = [self.pos_std * self.rng.standard_normal()]
        self.pos_pub.publish(self.pos)


@pytest.fixture(scope='module')
def listener(listener):
    """Return the module's listening node (conftest.py), thesis parameters, a vehicle."""
    from mr_damper_interfaces.msg import KwokParameters
    from mr_damper_common.messages import kwok_parameters_msg
    from mr_damper_common.node_utils import LATCHED_QOS
    pub = listener.publisher(f'/{NS}/mr_damper/kwok_parameters', KwokParameters, LATCHED_QOS)
    pub.publish(kwok_parameters_msg(thesis_parameter_values()))
    listener.params_pub = pub
    listener.vehicle = _Vehicle(listener)
    return listener


def test_dropout_marks_the_state_and_the_controller_falls_back(listener):
    diag = listener.diagnostics()
    wait = listener.wait_for
    veh = listener.vehicle

    def est():
        return diag.values(EST_NAME)

    def ctrl():
        return diag.values(CTRL_NAME)

    def rejected():
        return (ctrl().get('state_rejected') or {}).get('non_finite', 0)

    with NodeProcess('state_estimator_node', params=EST, namespace=NS) as ep, \
            NodeProcess('semi_active_controller_node', params=CTRL, namespace=NS) as cp:
        procs = [ep, cp]
        # 1. valid estimates -> normal commands
        assert wait(lambda: est().get('valid') is True and ctrl().get('commands_normal', 0) > 20,
                    GUARD_S, procs=procs), ep.output() + cp.output()
        # a stall of this test process may already have counted a dropout: counts from here
        before = dict(est().get('invalid_entries') or {})
        accel_before = before.get('dropout_body_accel', 0)
        rejected_before = rejected()
        # 2. the accelerometer falls silent
        veh.imu_on.clear()
        assert wait(lambda: est().get('reason') == 'dropout_body_accel'
                    and rejected() > rejected_before + 5, GUARD_S, procs=procs), ep.output()
        assert est()['valid'] is False
        assert est()['invalid_entries'].get('dropout_body_accel', 0) >= accel_before + 1
        assert wait(lambda: ctrl().get('current_a') == SAFE_A, GUARD_S, procs=procs)
        normal_during = ctrl()['commands_normal']
        # 3. back: valid again, normal commands resume
        veh.imu_on.set()
        assert wait(lambda: est().get('valid') is True
                    and ctrl().get('commands_normal', 0) > normal_during + 20, GUARD_S,
                    procs=procs), ep.output()
        assert est()['invalid_entries'].get('dropout_body_accel', 0) >= accel_before + 1
        assert ctrl()['mode'] == 'normal'
    # 4. both exit 0 on SIGINT
    assert ep.proc.returncode == 0, ep.output()
    assert cp.proc.returncode == 0, cp.output()
