"""
State estimator node: vehicle sensors in, the car state for the controller node out.

``ros2 run quarter_car_sim state_estimator_node``

A Kalman filter of one corner
(:class:`semi_active_control.estimation.state_estimator_core.StateEstimatorCore`, no ROS) on the
body accelerometer, the suspension position sensor (and optionally a wheel accelerometer), with the
damper force of the live identified model as a known input. At the control rate it publishes the
typed car state the semi-active controller node reads, so the controller is unchanged
(docs/sensing.md, docs/controller-node.md "Vehicle contract"). Callbacks only convert messages and
call the core; the control-rate timer calls ``tick``.

Topics (relative: remap with ``--ros-args -r old:=new`` or run in a namespace)
-----------------------------------------------------------------------------
- sub ``quarter_car/body_imu`` (sensor_msgs/Imu, best effort, KEEP_LAST 100):
  ``linear_acceleration.z``,
  specific force [m/s^2] as REP 145 has it (+9.81 at rest); NaN marks a lost sample. The
  sensor readers take the serialised messages and read the stamp and the one value from the
  CDR (:mod:`semi_active_control.estimation.sensor_cdr`; other encodings through rclpy's
  deserialisation, an undecodable message counted as ``dropped.undecodable_reading``); readings
  missing between consecutive stamps are counted (``readings_lost``);
- sub ``quarter_car/wheel_imu`` (sensor_msgs/Imu) with ``wheel_accel:=true``;
- sub ``quarter_car/suspension_position`` (sensor_msgs/JointState, best effort, KEEP_LAST 100):
  the first ``position`` [m] (the suspension as a prismatic joint: travel ``z_s - z_u``, extension
  positive, zero at static equilibrium). JointState because a suspension *is* a prismatic joint:
  it is what ros2_control's joint_state_broadcaster and a URDF of the car publish, it carries a
  stamp and the joint name of the corner, and no custom type is needed on the vehicle side;
- sub ``mr_damper/current_command`` (std_msgs/Float64, reliable depth 10): the coil current in
  force (the controller's command);
- sub ``mr_damper/kwok_parameters`` (mr_damper_interfaces/KwokParameters, latched);
- pub ``quarter_car/car_state`` (mr_damper_interfaces/QuarterCarState, reliable depth 10, at
  ``rate_hz``): ``body_velocity_m_s``, ``body_acceleration_m_s2``, ``wheel_velocity_m_s``,
  ``suspension_travel_m``, ``suspension_velocity_m_s``, the tyre deflection in
  ``wheel_displacement_m`` with ``road_height_m`` 0, the model's ``damper_force_n`` and
  ``current_command_a``. An invalid estimate has NaN in those fields, ``fail_safe_mode``
  FAIL_SAFE and the reason in ``fail_safe_reason``: the controller refuses it and commands its
  safe current (counted there in ``state_rejected.non_finite``, here in ``invalid_entries``);
- pub ``/diagnostics``: status ``state_estimator``: OK valid; WARN invalid and why.
"""
import sys

from rclpy.node import Node
from rclpy.serialization import deserialize_message
from sensor_msgs.msg import Imu, JointState
from std_msgs.msg import Float64

from mr_damper_interfaces.msg import KwokParameters, QuarterCarState
from mr_damper_common import messages
from mr_damper_common.health import OK, WARN, worst
from mr_damper_common.node_utils import (CONTROL_QOS, declare_parameters, DiagnosticsPublisher,
                                         DropCounter, LATCHED_QOS, LogThrottle, node_time_s,
                                         Param, run_node, SENSOR_QOS, set_realtime_priority,
                                         spin_node)
from semi_active_control.supervision.failsafe import ModelSupervisor
from semi_active_control.car.quarter_car import QuarterCarParams
from semi_active_control.estimation import sensor_cdr
from semi_active_control.estimation.sensor_specs import accelerometer_spec, ride_height_spec
from semi_active_control.estimation.state_estimator_core import StateEstimatorCore
from semi_active_control.nodes.common import offer_parameters

#: The node's parameters (the one place they are declared; docs/nodes.md shows this table).
PARAMETERS = (
    Param('rate_hz', 1000.0, 'Control rate: one estimate published per period [Hz]', 10.0,
          10000.0),
    Param('wheel_accel', False, 'Also use a wheel (hub) accelerometer on quarter_car/wheel_imu'),
    Param('accel_noise_density', 0.00245, 'Accelerometer noise density '
          '[m/s^2/sqrt(Hz)] (ADXL313 z axis: 250 ug/sqrt(Hz))', 1e-7, 1.0),
    Param('accel_latency_s', 1e-3, 'Accelerometer latency [s] (whole periods)', 0.0, 0.1),
    Param('travel_noise_density', 2.2e-6, 'Position sensor noise density '
          '[m/sqrt(Hz)] (0.05 mm over the 500 Hz band)', 1e-9, 1e-2),
    Param('travel_latency_s', 1e-3, 'Position sensor latency [s] (whole periods)', 0.0, 0.1),
    Param('road_class', 'C', 'ISO 8608 class of the design road (process noise)'),
    Param('speed_m_s', 20.0, 'Design speed [m/s] (process noise)', 0.1, 100.0),
    Param('coil_tau_s', 0.00526, 'Coil time constant between command and force [s]', 0.0,
          1.0),
    Param('dropout_s', 0.02, 'No reading of a sensor for this long: estimate invalid [s]',
          1e-3, 10.0),
    Param('nis_threshold', 3.0, 'Limit on the mean normalised innovation squared [-]', 0.1,
          1e6),
    Param('safe_current_a', 0.5, 'Coil current assumed before the first command [A]', 0.0,
          10.0),
    Param('param_timeout_s', 1.0, 'Identified parameters older than this are stale, aged from '
          'their stamp (from receipt when it is on another clock) [s, node clock]', 0.01,
          3600.0),
    Param('i_min_a', 0.0, 'Coil current minimum [A]', 0.0, 10.0),
    Param('i_max_a', 2.0, 'Coil current maximum [A]', 0.0, 10.0),
    Param('m_s', 300.0, 'Sprung mass the filter assumes [kg]', 1.0, 1e5),
    Param('m_u', 60.0, 'Unsprung mass the filter assumes [kg]', 0.1, 1e4),
    Param('k_s', 16000.0, 'Suspension spring the filter assumes [N/m]', 1.0, 1e8),
    Param('k_t', 190000.0, 'Tyre stiffness the filter assumes [N/m]', 1.0, 1e9),
    Param('diagnostics_period_s', 1.0, 'Period of the /diagnostics status [s]', 0.01, 60.0),
    Param('realtime_priority', 0, 'SCHED_FIFO priority of the node\'s threads (1..99; 0 = '
          'normal scheduling; needs CAP_SYS_NICE, else a warning)', 0, 99),
    Param('clock', 'timer', 'What steps the filter: timer (a rate_hz timer on the node clock) '
          'or readings (each suspension position reading, at its stamp; periods without one '
          'are predicted through: the vehicle\'s time however late the executor)'),
)

_NAN = float('nan')


def estimate_to_msg(est, current_a, msg):
    """Fill a ``QuarterCarState`` from an Estimate (NaN law fields when it is invalid)."""
    return messages.corner_state_to_msg(est.corner_state(), current_a, est.valid,
                                        'ok' if est.valid else est.reason, msg)


def _imu_reading(msg):
    """Return (stamp [s], ``linear_acceleration.z``) of an Imu message."""
    return messages.stamp_to_seconds(msg.header.stamp), msg.linear_acceleration.z


def _joint_reading(msg):
    """Return (stamp [s], first position or NaN) of a JointState message."""
    return (messages.stamp_to_seconds(msg.header.stamp),
            msg.position[0] if len(msg.position) else _NAN)


def estimator_health(status):
    """Return the node's Health: OK with a valid estimate, WARN with the reason otherwise."""
    if status.get('valid'):
        return worst([(OK, 'ok')], status)
    return worst([(WARN, f'estimate invalid: {status.get("reason") or "no_data_yet"}')], status)


class StateEstimatorNode(Node):
    """
    The estimator node (see the module docstring).

    Keyword arguments (e.g. ``context``, ``parameter_overrides``) go to ``rclpy.node.Node``.
    """

    def __init__(self, **node_kwargs):
        super().__init__('state_estimator', **node_kwargs)
        p = self.p = declare_parameters(self, PARAMETERS)
        car = QuarterCarParams(**{k: p[k] for k in ('m_s', 'm_u', 'k_s', 'k_t')})
        specs = {'body_accel': accelerometer_spec(noise_density=p['accel_noise_density'],
                                                  latency_s=p['accel_latency_s']),
                 'travel': ride_height_spec(noise_density=p['travel_noise_density'],
                                            latency_s=p['travel_latency_s'])}
        if p['wheel_accel']:
            specs['wheel_accel'] = accelerometer_spec(noise_density=p['accel_noise_density'],
                                                      latency_s=p['accel_latency_s'])
        sup = ModelSupervisor(timeout_s=p['param_timeout_s'], safe_current_a=p['safe_current_a'],
                              i_min_a=p['i_min_a'], i_max_a=p['i_max_a'])
        self.core = StateEstimatorCore(
            car, 1.0 / p['rate_hz'], specs, sup,
            design_options={'road_class': p['road_class'], 'speed_m_s': p['speed_m_s']},
            run_options={'coil_tau_s': p['coil_tau_s'], 'dropout_s': p['dropout_s'],
                         'nis_threshold': p['nis_threshold']})
        self.drops = DropCounter(self.get_logger())
        self.warn_invalid = LogThrottle(1.0)
        self.msg = QuarterCarState()
        self.msg.header.frame_id = 'quarter_car'
        self.pub = self.create_publisher(QuarterCarState, 'quarter_car/car_state', CONTROL_QOS)
        # the sensor readers take the serialised messages (raw) and read their stamp and value
        # in place: building the message objects cost more than the filter (sensor_cdr)
        self.drops.subscribe(self, Imu, 'quarter_car/body_imu',
                             lambda data: self.on_accel('body_accel', data), SENSOR_QOS,
                             raw=True)
        if p['wheel_accel']:
            self.drops.subscribe(self, Imu, 'quarter_car/wheel_imu',
                                 lambda data: self.on_accel('wheel_accel', data), SENSOR_QOS,
                                 raw=True)
        self.drops.subscribe(self, JointState, 'quarter_car/suspension_position',
                             self.on_position, SENSOR_QOS, raw=True)
        self.drops.subscribe(self, Float64, 'mr_damper/current_command',
                             lambda m: self.core.offer_current(m.data), CONTROL_QOS)
        self.drops.subscribe(self, KwokParameters, 'mr_damper/kwok_parameters', self.on_params,
                             LATCHED_QOS)
        self.diagnostics = DiagnosticsPublisher(self, self.health,
                                                period_s=p['diagnostics_period_s'],
                                                hardware_id='state_estimator', drops=self.drops)
        clock = p['clock'].strip().lower()
        if clock not in ('timer', 'readings'):
            raise ValueError(f"clock must be 'timer' or 'readings', got {p['clock']!r}")
        self.on_readings = clock == 'readings'
        self.timer = (None if self.on_readings
                      else self.create_timer(1.0 / p['rate_hz'], self.on_tick))
        set_realtime_priority(int(p['realtime_priority']), self.get_logger())
        self.get_logger().info(
            f'Kalman filter of {", ".join(self.core.sensors)} at {p["rate_hz"]:g} Hz -> '
            f'{self.resolve_topic_name("quarter_car/car_state")}')

    def _read(self, data, read_raw, msg_type, read_msg):
        """Return (stamp [s], value) of a serialised reading (None: undecodable, counted)."""
        try:
            reading = read_raw(data)
            if reading is None:         # not plain CDR: rclpy decodes it
                reading = read_msg(deserialize_message(data, msg_type))
        except (ValueError, RuntimeError) as exc:
            self.drops.count('undecodable_reading', detail=str(exc))
            return None
        return reading

    def on_accel(self, sensor, data):
        """Take the z specific force of a serialised Imu (``linear_acceleration.z``)."""
        reading = self._read(data, sensor_cdr.imu_reading, Imu, _imu_reading)
        if reading is not None:
            self.core.offer_reading(sensor, reading[1], reading[0])

    def on_position(self, data):
        """Take the suspension travel of a serialised JointState (first position; NaN if none)."""
        reading = self._read(data, sensor_cdr.joint_reading, JointState, _joint_reading)
        if reading is None:
            return
        self.core.offer_reading('travel', reading[1], reading[0])
        if self.on_readings:
            self._publish(self.core.tick_at(reading[0], node_time_s(self)))

    def on_params(self, msg):
        """Offer an identified parameter set to the core's supervisor."""
        offer_parameters(self.core.sup, msg, node_time_s(self), self.get_logger())

    def on_tick(self):
        """One control period: step the filter, publish the state."""
        self._publish(self.core.tick(node_time_s(self)))

    def _publish(self, est):
        if est is None:
            return
        self.drops.publish_next(self.pub, estimate_to_msg(est, self.core.current_a, self.msg))
        if not est.valid and self.warn_invalid.due():
            self.get_logger().warning(f'estimate invalid: {est.reason}')

    def status(self):
        """Return the core's status and the drop counts."""
        st = self.core.status()
        st['dropped'] = self.drops.counts()
        return st

    def health(self):
        """Return the node's :class:`~mr_damper_common.health.Health` (``/diagnostics``)."""
        return estimator_health(self.status())


def main(args=None):
    """Entry point of ``state_estimator_node``."""
    return run_node(StateEstimatorNode, 'state_estimator_node', (ValueError,),
                    run=lambda node: spin_node(node, events=True), args=args)


if __name__ == '__main__':
    sys.exit(main())
