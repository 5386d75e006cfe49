"""
Full-car controller node: four corner states in, four supervised coil currents out.

``ros2 run quarter_car_sim full_car_controller_node --ros-args -p controller:=modal-skyhook``

The full-car law (modal skyhook by default) without the simulated car, for a vehicle or for
``full_car_node`` run as the plant (``controller:=external``). The callbacks convert messages
and call the ROS-free
:class:`semi_active_control.runtime.full_car_controller_core.FullCarControllerCore`: when each
corner has sent its state of one stamp, the core rebuilds the body's heave, pitch and roll from the
four body points, runs the law, and turns each corner's force into a current through the inverse of
that corner's identified model under that corner's fail-safe supervisor. A corner without a valid,
fresh model gets ``safe_current_a``; the other three go on controlling. One set of four states is
answered by one command per corner, in the order ``fl, fr, rl, rr``.

Topics (relative; ``<c>`` is each of ``fl``, ``fr``, ``rl``, ``rr``, the corner namespaces of
``mr-damper-suite --config full-car``)
------------------------------------------------------------------------------------------
- sub ``<c>/quarter_car/car_state`` (mr_damper_interfaces/QuarterCarState; reliable, depth
  10): the corner's body point (displacement, velocity, acceleration), wheel, travel, its
  rate, road height and ``header.stamp`` (the four of one instant carry the same stamp);
- sub ``<c>/mr_damper/kwok_parameters`` (mr_damper_interfaces/KwokParameters; reliable,
  transient local, depth 1): that corner's identified model;
- pub ``<c>/mr_damper/current_command`` (std_msgs/Float64 [A], one per complete set; reliable,
  depth 10);
- sub ``full_car/road_preview`` (mr_damper_interfaces/RoadPreview; reliable, depth 10), only
  with ``controller:=preview-look-ahead``: the look-ahead sensor's frames and the speed signal
  for the LQ preview law (docs/preview.md); without a usable preview (no frame yet, none for
  ``preview_timeout_s``, stale or invalid frames, the map not reaching a wheel) the law runs
  without preview for that step, counted in ``preview.*``;
- pub ``/diagnostics`` (status name ``full_car_controller``): OK with four corners normal, WARN
  naming the corners in fail-safe; values: controller, sets, corners_normal,
  dropped_states.replaced / dropped_states.incomplete (states of sets that never
  completed),
  corners.<c>.* (mode, reason, failsafe_s, params_accepted, params_rejected.<reason>,
  param_age_s, states, normal_commands, current_a, ...), dropped.<reason> (messages); with
  preview: preview.law.* (steps, previewed_steps, fallback_steps, dropouts),
  preview.road_preview.* (frames taken and refused by the map), preview.input.* (messages
  received / lost by sequence number, refused.<reason>, fallback.<reason>, usable), and the
  stamps first_previewed_t, last_previewed_t, last_fallback_t.

Parameter ages and timeouts are on the node's clock (ROS time: ``/clock`` under
``use_sim_time``).
"""
import sys

from rclpy.node import Node
from std_msgs.msg import Float64

from mr_damper_interfaces.msg import KwokParameters, QuarterCarState, RoadPreview
from mr_damper_common import messages
from mr_damper_common.health import WARN, worst
from mr_damper_common.node_utils import (CONTROL_QOS, declare_parameters, DiagnosticsPublisher,
                                         DropCounter, LATCHED_QOS, node_time_s, Param, run_node,
                                         set_realtime_priority, spin_node)
from semi_active_control.car.full_car import CORNERS, PASSENGER_CAR
from semi_active_control.nodes.common import CORNER_SUPERVISOR_PARAMETERS, offer_parameters
from semi_active_control.runtime.full_car_controller_core import FullCarControllerCore
from semi_active_control.runtime.preview_controller_core import (LIVE_PREVIEW_LAWS,
                                                                 PreviewControllerCore)

#: The node's parameters (the one place they are declared; docs/nodes.md shows this table).
PARAMETERS = (
    Param('controller', 'modal-skyhook', 'Full-car law: modal-skyhook, '
          'full-car-clipped-optimal(-wk), per-corner-<law> (e.g. per-corner-skyhook), '
          'passive@<I>A or preview-look-ahead (full-car-clipped-optimal-wk with LQ preview on '
          'full_car/road_preview)'),
    Param('rate_hz', 1000.0, 'Rate of the corner states [Hz]: the sample time of a filter '
          'inside the law', 10.0, 10000.0),
) + CORNER_SUPERVISOR_PARAMETERS + (
    Param('preview_horizon_s', 0.3, 'Preview law: horizon of the feedforward on the road ahead '
          '[s]', 0.0, 2.0),
    Param('preview_timeout_s', 0.25, 'Preview law: without a frame taken for this long the law '
          'runs without preview [s, state stamps]', 0.001, 60.0),
    Param('preview_max_age_s', 0.1, 'Preview law: a frame older than this when its step comes '
          'is stale (refused) [s]', 0.001, 60.0),
    Param('diagnostics_period_s', 1.0, 'Period of the /diagnostics status [s]', 0.01, 60.0),
    Param('realtime_priority', 0, 'SCHED_FIFO priority of the node\'s threads (1..99; 0 = '
          'normal scheduling); needs CAP_SYS_NICE [-]', 0, 99),
)


class FullCarControllerNode(Node):
    """
    Thin ROS adapter over :class:`~semi_active_control.runtime.FullCarControllerCore`.

    Topics and status: see the module docstring. Keyword arguments (e.g. ``context``,
    ``parameter_overrides``) go to ``rclpy.node.Node``.
    """

    def __init__(self, **node_kwargs):
        super().__init__('full_car_controller', **node_kwargs)
        p = self.p = declare_parameters(self, PARAMETERS)
        supervision = dict(timeout_s=p['param_timeout_s'], safe_current_a=p['safe_current_a'],
                           i_min_a=p['i_min_a'], i_max_a=p['i_max_a'],
                           min_current_span_a=p['min_current_span_a'],
                           hold_on_reject=p['hold_on_reject'])
        self.preview = p['controller'].strip().lower() in LIVE_PREVIEW_LAWS
        if self.preview:
            self.core = PreviewControllerCore(
                PASSENGER_CAR, p['controller'], dt=1.0 / p['rate_hz'],
                horizon_s=p['preview_horizon_s'], preview_timeout_s=p['preview_timeout_s'],
                preview_max_age_s=p['preview_max_age_s'], **supervision)
        else:
            self.core = FullCarControllerCore(PASSENGER_CAR, p['controller'],
                                              dt=1.0 / p['rate_hz'], **supervision)
        self.drops = DropCounter(self.get_logger())
        if self.preview:
            self.drops.subscribe(self, RoadPreview, 'full_car/road_preview', self.on_preview,
                                 CONTROL_QOS)
        self.cmd = Float64()
        self.cmd_pubs = []
        for i, c in enumerate(CORNERS):
            self.cmd_pubs.append(self.create_publisher(Float64, f'{c}/mr_damper/current_command',
                                                       CONTROL_QOS))
            self.drops.subscribe(self, QuarterCarState, f'{c}/quarter_car/car_state',
                                 lambda m, i=i: self.on_state(i, m), CONTROL_QOS, 'states_lost')
            self.drops.subscribe(self, KwokParameters, f'{c}/mr_damper/kwok_parameters',
                                 lambda m, i=i: self.on_params(i, m), LATCHED_QOS)
        self.diagnostics = DiagnosticsPublisher(self, self.health,
                                                period_s=p['diagnostics_period_s'],
                                                hardware_id='full_car_controller',
                                                drops=self.drops)
        set_realtime_priority(int(p['realtime_priority']), self.get_logger())
        self.get_logger().info(
            f'{self.core.controller.name}: {", ".join(CORNERS)} states -> currents; fail-safe '
            f'{p["safe_current_a"]:g} A per corner, parameter timeout '
            f'{p["param_timeout_s"]:g} s')

    def on_state(self, i, msg):
        """Hand corner ``i``'s state to the core; publish the four currents of a complete set."""
        currents = self.core.offer_state(i, messages.corner_state_from_msg(msg),
                                         node_time_s(self))
        if currents is None:
            return
        for pub, current in zip(self.cmd_pubs, currents):
            self.cmd.data = float(current)
            self.drops.publish(pub, self.cmd)

    def on_params(self, i, msg):
        """Offer a parameter message to corner ``i``'s supervisor (at the node clock's now)."""
        offer_parameters(self.core.supervisor(i), msg, node_time_s(self), self.get_logger())

    def on_preview(self, msg):
        """Hand a road-preview frame to the core (a message that does not decode is counted)."""
        try:
            self.core.offer_preview(messages.road_preview_fields(msg))
        except messages.MessageError as exc:
            self.core.preview.refuse(exc.reason)
            self.get_logger().warning(f'road preview refused: {exc}', throttle_duration_sec=1.0)

    def status(self):
        """Return the status dict (the core's and the message drop counts)."""
        st = self.core.status(node_time_s(self))
        st['dropped_states'] = st.pop('dropped')
        st['dropped'] = self.drops.counts()
        return st

    def health(self):
        """Return the node's :class:`~mr_damper_common.health.Health` (``/diagnostics``)."""
        st = self.status()
        safe = [c for c, d in st['corners'].items() if d['mode'] != 'normal']
        problems = []
        if safe:
            problems.append((WARN, 'fail-safe at ' + ', '.join(
                f'{c} ({st["corners"][c]["reason"]})' for c in safe)))
        return worst(problems, st)


def main(args=None):
    """Entry point of ``full_car_controller_node``."""
    # ValueError: bad controller name (exit 2 with one line)
    return run_node(FullCarControllerNode, 'full_car_controller_node', (ValueError,),
                    run=lambda node: spin_node(node, events=True), args=args)


if __name__ == '__main__':
    sys.exit(main())
