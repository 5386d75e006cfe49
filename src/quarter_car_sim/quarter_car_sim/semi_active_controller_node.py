"""
Semi-active controller node: a car or vehicle state in, a supervised coil current out.

``ros2 run quarter_car_sim semi_active_controller_node --ros-args -p controller:=skyhook``

The skyhook (or any law the quarter-car node accepts) without the simulated car: each state
message is answered with one current command, computed by the ROS-free
:class:`quarter_car_sim.controller_core.ControllerCore` (law + inverse of the live identified
Kwok-current model + fail-safe supervisor: no, stale, invalid or refused model -> safe current).
The callback of the state converts the message, calls the core and publishes; nothing else runs
per state. See docs/controller-node.md for the vehicle contract.

Topics (relative: remap with ``--ros-args -r old:=new`` or run in a namespace)
-----------------------------------------------------------------------------
- sub ``quarter_car/car_state`` (mr_damper_interfaces/QuarterCarState; reliable, depth 10):
  the laws read ``body_velocity_m_s``, ``body_acceleration_m_s2``, ``wheel_velocity_m_s``,
  ``suspension_travel_m``, ``suspension_velocity_m_s`` and ``header.stamp``;
- sub ``mr_damper/kwok_parameters`` (mr_damper_interfaces/KwokParameters; reliable,
  transient local, depth 1);
- pub ``mr_damper/current_command`` (std_msgs/Float64, A, one per state; reliable, depth 10);
- pub ``/diagnostics`` (diagnostic_msgs/DiagnosticArray every ``diagnostics_period_s``, status
  name ``semi_active_controller`` or ``<ns>/semi_active_controller``): level and message from
  :class:`quarter_car_sim.health.ControllerHealth` (OK normal; WARN fail-safe and why, states
  refused, state stamps re-based, drops; ERROR states refused persistently); values: mode,
  reason (``state_<reason>`` while the last state was refused), failsafe_s,
  failsafe_entries, params_accepted, params_rejected.<reason>, param_age_s, current_a,
  commands, commands_normal, saturated_steps, state_rejected.<reason>, stamp_rebases,
  dropped.<reason>.

Stamps (:class:`mr_damper_common.stamps.StampGuard`): a state stamped more than
``max_future_s`` ahead of the node clock, or older than the newest state taken, is answered
with the safe current and counted; it never becomes the reference. ``rebase_after``
consecutive out-of-order (or future) states increasing among themselves re-base the stamps (a
vehicle clock jump: counted, warned).

Parameter age and timeout are on the node's clock (ROS time: ``/clock`` under
``use_sim_time``).
"""
import json
import sys

from rclpy.node import Node
from rclpy.qos import QoSProfile, ReliabilityPolicy
from std_msgs.msg import Float64

from mr_damper_interfaces.msg import KwokParameters, QuarterCarState
from mr_damper_common import messages
from mr_damper_common.node_utils import (declare_parameters, DiagnosticsPublisher, DropCounter,
                                         LATCHED_QOS, LogThrottle, node_time_s, Param,
                                         run_node, set_realtime_priority, spin_node)
from quarter_car_sim import controller_core
from quarter_car_sim.controller_core import ControllerCore, VehicleState
from quarter_car_sim.controllers import DAMPER_LAW_NAMES
from quarter_car_sim.failsafe import ModelSupervisor
from quarter_car_sim.health import ControllerHealth
from quarter_car_sim.params import QuarterCarParams

#: Parameters of the supervised law, shared with the quarter car's built-in controller.
SUPERVISED_LAW_PARAMETERS = (
    Param('controller_options', '{}', 'JSON keyword options (gains) of the controller, e.g. '
          '{"c_sky": 3000.0}; a change rebuilds the law (refused: the old one stays)',
          dynamic=True),
    Param('safe_current_a', 0.5, 'Coil current in fail-safe [A]', 0.0, 10.0, dynamic=True),
    Param('param_timeout_s', 1.0, 'Identified parameters older than this are stale [s, node '
          'clock]', 0.01, 3600.0, dynamic=True),
    Param('i_min_a', 0.0, 'Coil current minimum [A]', 0.0, 10.0),
    Param('i_max_a', 2.0, 'Coil current maximum [A]', 0.0, 10.0),
    Param('min_current_span_a', 1.0, 'Refuse models identified over a narrower current range '
          '[A]', 0.0, 10.0, dynamic=True),
    Param('hold_on_reject', False, 'Keep the model in use when a later message is refused '
          '(until stale)', dynamic=True),
)

#: The node's parameters (the one place they are declared; docs/nodes.md shows this table).
PARAMETERS = (
    Param('controller', 'skyhook', f'Controller name ({", ".join(DAMPER_LAW_NAMES)})'),
    Param('rate_hz', 1000.0, 'Rate of the vehicle states, one command each [Hz]: the sample '
          'time of a filter inside the law (clipped-optimal-wk)', 10.0, 10000.0),
) + SUPERVISED_LAW_PARAMETERS + (
    Param('max_future_s', controller_core.MAX_FUTURE_S, 'A state stamped further ahead of '
          'the node clock than this is refused (future_stamp) [s]', 0.001, 3600.0),
    Param('rebase_after', controller_core.REBASE_AFTER, 'Consecutive out-of-order (or future) '
          'states, increasing among themselves, that re-base the stamps: a vehicle clock '
          'jump [-]', 1, 100000),
    Param('diagnostics_period_s', 1.0, 'Period of the /diagnostics status [s]', 0.01, 60.0),
    Param('realtime_priority', 0, 'SCHED_FIFO priority of the node\'s threads (1..99; 0 = '
          'normal scheduling); needs CAP_SYS_NICE [-]', 0, 99),
    Param('m_s', 300.0, 'Sprung mass (LQR-designed laws only) [kg]', 1.0, 1e5),
    Param('m_u', 60.0, 'Unsprung mass (LQR-designed laws only) [kg]', 0.1, 1e4),
    Param('k_s', 16000.0, 'Suspension spring (LQR-designed laws only) [N/m]', 1.0, 1e8),
    Param('k_t', 190000.0, 'Tyre stiffness (LQR-designed laws only) [N/m]', 1.0, 1e9),
)

#: State and command topics: reliable, depth 10 (only the newest matters; a stalled reader
#: costs the writer nothing).
CONTROL_QOS = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE)


def vehicle_state_from_msg(msg):
    """Return the :class:`VehicleState` of a ``QuarterCarState`` message (the fields used)."""
    return VehicleState(t=messages.stamp_to_seconds(msg.header.stamp),
                        v_s=msg.body_velocity_m_s, a_s=msg.body_acceleration_m_s2,
                        v_u=msg.wheel_velocity_m_s, travel=msg.suspension_travel_m,
                        v_rel=msg.suspension_velocity_m_s, z_u=msg.wheel_displacement_m,
                        z_r=msg.road_height_m)


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


def offer_parameters(supervisor, msg, now, logger):
    """
    Offer a ``KwokParameters`` message received at ``now`` [s, node clock] to ``supervisor``.

    A message the decoder refuses is refused by the decoder's reason when the supervisor
    knows it (``'bad_i_ref'``), else as ``'undecodable'``; refusals are logged (throttled).
    The caller holds the supervisor's lock if it has one. Returns the ``Verdict``.
    """
    try:
        values = messages.kwok_parameters_flat(msg)
    except ValueError as exc:
        reason = getattr(exc, 'reason', None)
        reason = reason if reason in supervisor.rejected else 'undecodable'
        verdict = supervisor.refuse(reason, str(exc), now)
    else:
        verdict = supervisor.offer(values, now)
    if not verdict.accepted:
        logger.warning(f'parameters refused ({verdict.reason}): {verdict.detail}',
                       throttle_duration_sec=1.0)
    return verdict


class SemiActiveControllerNode(Node):
    """
    The controller node (see the module docstring).

    Keyword arguments (e.g. ``context``, ``parameter_overrides``) go to ``rclpy.node.Node``.
    """

    def __init__(self, **node_kwargs):
        super().__init__('semi_active_controller', **node_kwargs)
        p = self.p = declare_parameters(self, PARAMETERS, self._on_set)
        self.car_params = QuarterCarParams(**{k: p[k] for k in ('m_s', 'm_u', 'k_s', 'k_t')})
        sup = ModelSupervisor(timeout_s=p['param_timeout_s'], safe_current_a=p['safe_current_a'],
                              i_min_a=p['i_min_a'], i_max_a=p['i_max_a'],
                              hold_on_reject=p['hold_on_reject'],
                              min_current_span_a=p['min_current_span_a'])
        law = self._make_law(json.loads(p['controller_options'] or '{}'))
        self.core = ControllerCore(law, sup, max_future_s=p['max_future_s'],
                                   rebase_after=int(p['rebase_after']))
        self.health_rules = ControllerHealth()
        self.drops = DropCounter(self.get_logger())
        self.warn_refused = LogThrottle(1.0)
        self.cmd = Float64()
        self.cmd_pub = self.create_publisher(Float64, 'mr_damper/current_command', CONTROL_QOS)
        self.drops.subscribe(self, QuarterCarState, 'quarter_car/car_state', self.on_state,
                             CONTROL_QOS, 'states_lost')
        self.drops.subscribe(self, KwokParameters, 'mr_damper/kwok_parameters', self.on_params,
                             LATCHED_QOS)
        self.diagnostics = DiagnosticsPublisher(self, self.health,
                                                period_s=p['diagnostics_period_s'],
                                                hardware_id='semi_active_controller',
                                                drops=self.drops)
        set_realtime_priority(int(p['realtime_priority']), self.get_logger())
        self.get_logger().info(
            f'{law.name}: {self.resolve_topic_name("quarter_car/car_state")} -> '
            f'{self.resolve_topic_name("mr_damper/current_command")}; fail-safe '
            f'{p["safe_current_a"]:g} A, parameter timeout {p["param_timeout_s"]:g} s')

    def _make_law(self, options):
        return controller_core.make_node_law(self.p['controller'], self.car_params,
                                             self.p['rate_hz'], options)

    def _on_set(self, changes):
        """Apply changed dynamic parameters (validated by the cores); '' or the reason."""
        return controller_core.reconfigure(changes, self.core.sup, core=self.core,
                                           make_law=self._make_law)

    def on_state(self, msg):
        """Answer one state with one current command."""
        core = self.core
        rebases = core.stamps.rebases
        self.cmd.data = core.command(vehicle_state_from_msg(msg), node_time_s(self))
        self.drops.publish(self.cmd_pub, self.cmd)
        if core.last_refusal is not None and self.warn_refused.due():
            self.get_logger().warning(
                f'state refused ({core.last_refusal}; {core.state_rejected}): safe current '
                'commanded')
        if core.stamps.rebases > rebases:
            jump = core.stamps.last_rebase
            self.get_logger().warning(
                f'vehicle clock jumped {jump["direction"]}: state stamps re-based from '
                f'{jump["from_s"]:.6f} s to {jump["to_s"]:.6f} s ({core.stamps.rebases} in all)')

    def on_params(self, msg):
        """Offer a parameter message to the supervisor (received at the node clock's now)."""
        offer_parameters(self.core.sup, msg, node_time_s(self), self.get_logger())

    def status(self):
        """Return the status dict (the core's, the parameter age and the drop counts)."""
        now = node_time_s(self)
        self.core.sup.update(now)
        st = self.core.status()
        st['param_age_s'] = self.core.sup.age(now)
        st['param_timeout_s'] = self.core.sup.timeout_s
        st['dropped'] = self.drops.counts()
        return st

    def health(self):
        """Return the node's :class:`~mr_damper_common.health.Health` (``/diagnostics``)."""
        return self.health_rules(self.status())


def main(args=None):
    """Entry point of ``semi_active_controller_node``."""
    # ValueError: bad controller name or options (exit 2 with one line)
    return run_node(SemiActiveControllerNode, 'semi_active_controller_node', (ValueError,),
                    run=lambda node: spin_node(node, events=True), args=args)


if __name__ == '__main__':
    sys.exit(main())
