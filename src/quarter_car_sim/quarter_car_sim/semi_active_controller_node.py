"""
Semi-active controller node: a car or vehicle state in, a supervised coil current out.

``ros2 run quarter_car_sim semi_active_controller_node --ros-args -p controller:=skyhook``

The skyhook (or any law the quarter-car node accepts) without the simulated car: each state
message is answered with one current command, computed by the ROS-free
:class:`quarter_car_sim.controller_core.ControllerCore` (law + inverse of the live identified
Kwok-current model + fail-safe supervisor: no, stale, invalid or refused model -> safe current).
The callback of the state converts the message, calls the core and publishes; nothing else runs
per state. See docs/controller-node.md for the vehicle contract.

Topics (defaults)
-----------------
- sub ``/quarter_car/car_state`` (mr_damper_interfaces/QuarterCarState; reliable, depth 10):
  the laws read ``body_velocity_m_s``, ``body_acceleration_m_s2``, ``wheel_velocity_m_s``,
  ``suspension_travel_m``, ``suspension_velocity_m_s`` and ``header.stamp``;
- sub ``/mr_damper/kwok_parameters`` (std_msgs/Float64MultiArray, decoded by label; reliable,
  transient local, depth 1);
- pub ``/mr_damper/current_command`` (std_msgs/Float64, A, one per state; reliable, depth 10);
- pub ``/semi_active_controller/status`` (std_msgs/String JSON at ``status_rate_hz``).
"""
import json
import sys
import time

from rclpy.node import Node
from rclpy.qos import QoSProfile, ReliabilityPolicy
from rcl_interfaces.msg import FloatingPointRange, ParameterDescriptor
from std_msgs.msg import Float64, Float64MultiArray, String

from mr_damper_interfaces.msg import QuarterCarState
from mr_damper_model import messages
from mr_damper_model.node_utils import (DropCounter, LATCHED_QOS, run_node,
                                        set_realtime_priority, spin_node)
from quarter_car_sim.controller_core import ControllerCore, VehicleState
from quarter_car_sim.controllers import make_controller
from quarter_car_sim.failsafe import ModelSupervisor
from quarter_car_sim.params import QuarterCarParams

#: State and command topics: reliable, depth 10 (only the newest matters; a stalled reader
#: costs the writer nothing).
CONTROL_QOS = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE)


def vehicle_state_from_msg(msg):
    """Return the :class:`VehicleState` of a ``QuarterCarState`` message (the fields used)."""
    return VehicleState(t=messages.stamp_to_seconds(msg.header.stamp),
                        v_s=msg.body_velocity_m_s, a_s=msg.body_acceleration_m_s2,
                        v_u=msg.wheel_velocity_m_s, travel=msg.suspension_travel_m,
                        v_rel=msg.suspension_velocity_m_s)


def car_state_to_msg(state, current_command_a, normal, reason, msg=None):
    """
    Fill a ``QuarterCarState`` from a simulated ``CarState`` (the quarter car's publisher).

    Parameters
    ----------
    state : quarter_car_sim.dynamics.CarState
        State (SI); ``header.stamp`` = ``max(state.t, 0)`` (simulated time).
    current_command_a : float
        Coil current command in force [A].
    normal : bool
        Mode of whoever commands the current (False: fail-safe).
    reason : str
        Fail-safe reason (``'ok'`` in normal mode).
    msg : QuarterCarState, optional
        Message to fill in place (one allocation for a 1 kHz publisher).

    Returns
    -------
    QuarterCarState

    """
    if msg is None:
        msg = QuarterCarState()
        msg.header.frame_id = 'quarter_car'
    messages.seconds_to_stamp(max(state.t, 0.0), msg.header.stamp)
    msg.body_displacement_m = state.z_s
    msg.body_velocity_m_s = state.v_s
    msg.body_acceleration_m_s2 = state.a_s
    msg.wheel_displacement_m = state.z_u
    msg.wheel_velocity_m_s = state.v_u
    msg.wheel_acceleration_m_s2 = state.a_u
    msg.suspension_travel_m = state.travel
    msg.suspension_velocity_m_s = state.v_rel
    msg.damper_force_n = state.damper_force
    msg.tyre_load_n = state.tyre_force
    msg.road_height_m = state.z_r
    msg.current_command_a = float(current_command_a)
    msg.coil_current_a = state.coil_current
    msg.fail_safe_mode = QuarterCarState.MODE_NORMAL if normal else QuarterCarState.MODE_FAIL_SAFE
    msg.fail_safe_reason = reason
    return msg


class SemiActiveControllerNode(Node):
    """
    The controller node (see the module docstring).

    Keyword arguments (e.g. ``context``, ``parameter_overrides``) go to ``rclpy.node.Node``.
    """

    def __init__(self, **node_kwargs):
        super().__init__('semi_active_controller', **node_kwargs)
        d = self._declare
        controller = d('controller', 'skyhook', 'Controller name (skyhook, skyhook-onoff, '
                       'groundhook, hybrid, add, passive@<I>A)')
        ctrl_opts = d('controller_options', '{}',
                      'JSON keyword options of the controller, e.g. {"c_sky": 3000.0}')
        safe = d('safe_current_a', 0.5, 'Coil current in fail-safe [A]', (0.0, 10.0))
        timeout = d('param_timeout_s', 1.0,
                    'Identified parameters older than this [s, wall clock] are stale',
                    (0.01, 3600.0))
        i_min = d('i_min_a', 0.0, 'Coil current minimum [A]', (0.0, 10.0))
        i_max = d('i_max_a', 2.0, 'Coil current maximum [A]', (0.0, 10.0))
        span = d('min_current_span_a', 1.0,
                 'Refuse models identified over a narrower current range [A]', (0.0, 10.0))
        hold = d('hold_on_reject', False,
                 'Keep the model in use when a later message is refused (until stale)')
        status_rate = d('status_rate_hz', 5.0, 'Status rate [Hz]', (0.1, 100.0))
        self.rt_priority = d('realtime_priority', 0,
                             'SCHED_FIFO priority of the node\'s threads (1..99; 0 = normal '
                             'scheduling); needs CAP_SYS_NICE')
        car = {k: d(k, v, doc) for k, v, doc in (
            ('m_s', 300.0, 'Sprung mass [kg] (LQR-designed laws only)'),
            ('m_u', 60.0, 'Unsprung mass [kg] (LQR-designed laws only)'),
            ('k_s', 16000.0, 'Suspension spring [N/m] (LQR-designed laws only)'),
            ('k_t', 190000.0, 'Tyre stiffness [N/m] (LQR-designed laws only)'))}
        topics = {k: d(k, v, 'Topic name') for k, v in (
            ('params_topic', '/mr_damper/kwok_parameters'),
            ('car_state_topic', '/quarter_car/car_state'),
            ('command_topic', '/mr_damper/current_command'),
            ('status_topic', '/semi_active_controller/status'))}

        sup = ModelSupervisor(timeout_s=timeout, safe_current_a=safe, i_min_a=i_min,
                              i_max_a=i_max, hold_on_reject=hold, min_current_span_a=span)
        law = make_controller(controller, params=QuarterCarParams(**car), damper_only=True,
                              **json.loads(ctrl_opts or '{}'))
        self.core = ControllerCore(law, sup)
        self.drops = DropCounter(self.get_logger())
        self.cmd = Float64()
        self.cmd_pub = self.create_publisher(Float64, topics['command_topic'], CONTROL_QOS)
        self.status_pub = self.create_publisher(String, topics['status_topic'], 10)
        self.drops.subscribe(self, QuarterCarState, topics['car_state_topic'], self.on_state,
                             CONTROL_QOS, 'states_lost')
        self.drops.subscribe(self, Float64MultiArray, topics['params_topic'], self.on_params,
                             LATCHED_QOS, 'parameters_lost')
        self.create_timer(1.0 / status_rate, self.publish_status)
        set_realtime_priority(int(self.rt_priority), self.get_logger())
        self.get_logger().info(f'{law.name} on {topics["car_state_topic"]} -> '
                               f'{topics["command_topic"]}; fail-safe {safe:g} A, parameter '
                               f'timeout {timeout:g} s')

    def _declare(self, name, default, description, fp_range=None):
        desc = ParameterDescriptor(description=description)
        if fp_range is not None and isinstance(default, float):
            desc.floating_point_range = [FloatingPointRange(
                from_value=fp_range[0], to_value=fp_range[1], step=0.0)]
        return self.declare_parameter(name, default, desc).value

    def on_state(self, msg):
        """Answer one state with one current command."""
        rejected = sum(self.core.state_rejected.values())
        self.cmd.data = self.core.command(vehicle_state_from_msg(msg), time.monotonic())
        self.drops.publish(self.cmd_pub, self.cmd)
        if sum(self.core.state_rejected.values()) > rejected:
            self.get_logger().warning(
                f'state refused ({self.core.state_rejected}): safe current commanded',
                throttle_duration_sec=1.0)

    def on_params(self, msg):
        """Offer a parameter message to the supervisor (decoded by label)."""
        now = time.monotonic()
        try:
            values = messages.array_msg_to_dict(msg)
        except ValueError as exc:
            self.core.sup.refuse('undecodable', str(exc), now)
            self.get_logger().warning(f'undecodable parameters: {exc}',
                                      throttle_duration_sec=1.0)
            return
        verdict = self.core.offer_parameters(values, now)
        if not verdict.accepted:
            self.get_logger().warning(f'parameters refused ({verdict.reason}): {verdict.detail}',
                                      throttle_duration_sec=1.0)

    def status(self):
        """Return the status dict (the core's, the parameter age and the drop counts)."""
        now = time.monotonic()
        self.core.sup.update(now)
        st = self.core.status()
        st['param_age_s'] = self.core.sup.age(now)
        st['dropped'] = self.drops.counts()
        return st

    def publish_status(self):
        """Publish the status (executor timer)."""
        self.drops.publish(self.status_pub, messages.status_msg(self.status()))


def main(args=None):
    """Entry point of ``semi_active_controller_node``."""
    # ValueError: bad controller name or options (exit 2 with one line)
    return run_node(SemiActiveControllerNode, 'semi_active_controller_node', (ValueError,),
                    run=lambda node: spin_node(node, events=True), args=args)


if __name__ == '__main__':
    sys.exit(main())
