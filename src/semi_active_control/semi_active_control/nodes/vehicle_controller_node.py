"""
Vehicle controller node (managed): one full-car state per cycle in, one four-damper command out.

``ros2 run semi_active_control vehicle_controller_node --ros-args -p autostart:=true``

A lifecycle node over the ROS-free
:class:`semi_active_control.runtime.VehicleControllerCore`: the full-car law, each corner's
inverse model under its supervisor, deadline supervision. Each ``FullCarState`` is answered by
one ``FullCarCommand`` (four currents, the cycle answered, per corner the mode and the reason).
A state that arrives after its deadline (``deadline_s`` from its stamp, on the node's clock) is
old: it gets no law command, counts a miss (``states_skipped_late``), and gets the safe command
while the misses trip (``VehicleControllerCore.answer``), as the loop layout does; so no law
command built on old sensors follows a sensor timeout's safe one.

Lifecycle (docs/vehicle.md): **configure** builds the law and loads each corner's model
(``model_files``: an end-of-line parameter file per corner, "" for the corner's live
identifier), subscribes and publishes; a file that cannot be read or a record marked invalid
leaves its corner on the safe current (named in the status), the other corners go on.
**activate** starts commanding. **deactivate** publishes one command with every corner on
the safe current (``INACTIVE``), not the last command, and stops. **cleanup** drops the
topics; **error** (a callback that failed) publishes the safe command if it can and cleans up.

Topics (relative; remap with ``--ros-args -r``)
------------------------------------------------
- sub ``vehicle/state`` (mr_damper_interfaces/FullCarState; reliable, KEEP_LAST 2), on a lane
  of its own (an EventsExecutor thread);
- sub ``<c>/mr_damper/kwok_parameters`` (KwokParameters; latched) for each live corner;
- pub ``vehicle/command`` (mr_damper_interfaces/FullCarCommand; reliable, KEEP_LAST 2): one per
  state in time, one per ``check_period_s`` while no state came for ``sensor_timeout_s``
  (``sensor_timeout``), one at deactivation;
- sub ``full_car/road_preview`` (mr_damper_interfaces/RoadPreview; reliable, depth 10), only
  with ``controller:=preview-look-ahead``, on the state lane: the look-ahead sensor's frames
  and the speed signal for the LQ preview law (docs/preview.md), stamped on the states'
  clock; without a usable preview (no frame yet, none for ``preview_timeout_s``, stale or
  invalid frames, the map not reaching a wheel) the law runs without preview for that cycle,
  counted in the status's ``preview.*``;
- pub ``~/heartbeat`` (std_msgs/Header, the lifecycle state in ``frame_id``);
- pub ``/diagnostics`` (status ``vehicle_controller``): the core's status (per corner mode,
  reason, model source and supervisor figures; ``deadline`` with misses and their lateness).
"""
import sys
import threading

from rclpy.lifecycle import LifecycleNode

from mr_damper_common import messages
from mr_damper_common.health import OK, worst
from mr_damper_common.lifecycle_utils import (apply_scheduling, FAILURE, MANAGED_PARAMETERS,
                                              managed_services, run_managed, SafeTransitions,
                                              state_label, SUCCESS)
from mr_damper_common.node_utils import (CONTROL_QOS, declare_parameters, FastLane, LATCHED_QOS,
                                         node_time_s, VEHICLE_QOS)
from mr_damper_interfaces.msg import FullCarCommand, FullCarState, KwokParameters, RoadPreview
from semi_active_control.car.full_car import CORNERS, PASSENGER_CAR
from semi_active_control.nodes.common import (identified_set_or_error,
                                              log_model_verdicts, log_refused_parameters,
                                              make_vehicle_controller, road_preview_or_error,
                                              vehicle_controller_problems,
                                              VEHICLE_CONTROLLER_PARAMETERS)
from semi_active_control.runtime import full_car_state

#: The node's parameters.
PARAMETERS = VEHICLE_CONTROLLER_PARAMETERS + MANAGED_PARAMETERS


class VehicleControllerNode(SafeTransitions, LifecycleNode):
    """Thin lifecycle node over :class:`VehicleControllerCore` (see the module docstring)."""

    def __init__(self, **node_kwargs):
        super().__init__('vehicle_controller', **node_kwargs)
        self.p = declare_parameters(self, PARAMETERS)
        self.lock = threading.Lock()
        self.core = None
        self.lane = None
        self.state_sub = None
        self.params_subs = []
        self.cmd_pub = None
        self.timer = None
        self.cmd_msg = FullCarCommand()
        self.geometry = PASSENGER_CAR.geometry
        managed_services(self, self.p, 'vehicle_controller')

    # --- lifecycle ------------------------------------------------------------------------------
    def on_configure(self, state):
        """Build the law and load the models; subscribe and publish."""
        p = self.p
        try:
            core = make_vehicle_controller(p)
        except ValueError as exc:
            self.get_logger().error(f'configure refused: {exc}')
            return FAILURE
        log_model_verdicts(self.get_logger(), core.configure(node_time_s(self)))
        models = core.models
        with self.lock:
            self.core = core
        self.cmd_pub = self.create_publisher(FullCarCommand, 'vehicle/command', VEHICLE_QOS)
        self.lane = FastLane(self, 'states')
        self.state_sub = self.lane.node.create_subscription(FullCarState, 'vehicle/state',
                                                            self.on_state, VEHICLE_QOS)
        self.preview_sub = None
        if core.preview is not None:
            self.preview_sub = self.drops.subscribe(self.lane.node, RoadPreview,
                                                    'full_car/road_preview', self.on_preview,
                                                    CONTROL_QOS)
        self.params_subs = [
            self.create_subscription(KwokParameters, f'{c}/mr_damper/kwok_parameters',
                                     lambda m, i=i: self.on_params(i, m), LATCHED_QOS)
            for i, c in enumerate(CORNERS) if models.source(i) == 'live']
        self.timer = self.create_timer(p['check_period_s'], self.on_check)
        self.lane.start()
        apply_scheduling(self, p)
        self.get_logger().info(
            f'{core.controller.name}: vehicle/state -> vehicle/command every '
            f'{p["cycle_s"] * 1e3:g} ms; models: '
            + ', '.join(f'{c} {models.source(c)}' for c in CORNERS))
        return SUCCESS

    def on_activate(self, state):
        """Start commanding."""
        with self.lock:
            self.core.activate(node_time_s(self))
        return SUCCESS

    def on_deactivate(self, state):
        """Put every corner on the safe current (one command), then stop commanding."""
        now = node_time_s(self)
        with self.lock:         # published under the lock: no law command after this one
            self._publish(self.core.deactivate(now), now)
        return SUCCESS

    def _in_safe_reach(self, shutdown):
        if self.core is None:
            return False
        return self.core.active if shutdown else self.cmd_pub is not None

    def _teardown(self):
        if self.lane is not None:
            self.lane.close()
            self.lane = None
        for sub in self.params_subs:
            self.destroy_subscription(sub)
        self.params_subs = []
        if self.timer is not None:
            self.destroy_timer(self.timer)
            self.timer = None
        if self.cmd_pub is not None:
            self.destroy_publisher(self.cmd_pub)
            self.cmd_pub = None
        with self.lock:
            self.core = None

    # --- callbacks ------------------------------------------------------------------------------
    def on_state(self, msg):
        """Answer one state (the lane's thread)."""
        f = messages.full_car_state_fields(msg)
        state = full_car_state(self.geometry, f['t'], f['body'], f['body_rates'],
                               f['body_acc'], f['travel'], f['travel_velocity'],
                               f['tyre_deflection'], f['wheel_velocity'], f['damper_force'])
        now = node_time_s(self)
        with self.lock:
            if self.core is None:
                return
            cmd = self.core.answer(state, f['sequence'], f['valid'], f['reason'], now)
            if cmd is not None:
                self._publish(cmd, now)
                self.core.sent(node_time_s(self))             # its deadline: published

    def on_check(self):
        """Sensor timeout: the safe command while no state comes (timer)."""
        now = node_time_s(self)
        with self.lock:
            cmd = self.core.check(now) if self.core is not None else None
            if cmd is not None:
                self._publish(cmd, now)

    def on_params(self, i, msg):
        """Offer a live identifier's set to corner ``i``."""
        values = identified_set_or_error(msg)
        with self.lock:
            if self.core is None:
                return
            verdict = self.core.offer_parameters(i, values, node_time_s(self))
        log_refused_parameters(self.get_logger(), CORNERS[i], verdict)

    def on_preview(self, msg):
        """Hand a road-preview frame to the core (a message that does not decode is counted)."""
        fields = road_preview_or_error(msg, self.get_logger())
        with self.lock:
            if self.core is not None:
                self.core.offer_preview(fields)

    def _publish(self, cmd, now):
        if self.cmd_pub is None:
            return
        self.drops.publish(self.cmd_pub, messages.full_car_command_msg(cmd, now, self.cmd_msg))

    # --- status ---------------------------------------------------------------------------------
    def status(self):
        """Return the status dict (the core's, the lifecycle state and the drop counts)."""
        with self.lock:
            st = self.core.status(node_time_s(self)) if self.core is not None else {}
        st.update(lifecycle=state_label(self), dropped=self.drops.counts())
        return st

    def health(self):
        """Return the node's :class:`~mr_damper_common.health.Health` (``/diagnostics``)."""
        st = self.status()
        problems = vehicle_controller_problems(st)
        return worst(problems or [(OK, 'ok')], st)


def main(args=None):
    """Entry point of ``vehicle_controller_node``."""
    return run_managed(VehicleControllerNode, 'vehicle_controller_node', args=args)


if __name__ == '__main__':
    sys.exit(main())
