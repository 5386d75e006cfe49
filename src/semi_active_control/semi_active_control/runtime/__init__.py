"""
The ROS-free cores the vehicle's controller nodes call: one control step, supervised.

Public API::

    from semi_active_control.runtime import ControllerCore, LAW_FIELDS, STATE_REJECTIONS
    from semi_active_control.runtime import make_node_law, reconfigure, SUPERVISOR_PARAMETERS
    from semi_active_control.runtime import FullCarController, LivePreview, LIVE_PREVIEW_LAWS
    from semi_active_control.runtime import VehicleControllerCore, VehicleCommand, VehicleLoop

Modules: ``controller_core`` (a corner: law + the inverse of the identified model + the
fail-safe supervisor, the state checks; the node's law and parameter changes),
``full_car_controller_core`` (the whole car's step: the law, then each corner's inverse under
its own supervisor), ``live_preview`` (the LQ road-preview law fed from the road-preview
topic), ``vehicle_controller`` (the vehicle computer's full-car controller on one state per
cycle, with deadlines and an inactive state), ``vehicle_loop`` (the vehicle computer in one
control loop: estimator, controller and the bus's write on each sensor cycle).
"""
from semi_active_control.runtime.controller_core import (ControllerCore,  # noqa: F401
                                                         LAW_FIELDS, make_node_law,
                                                         MAX_FUTURE_S, REBASE_AFTER,
                                                         reconfigure, STATE_REJECTIONS,
                                                         SUPERVISOR_PARAMETERS)
from semi_active_control.runtime.full_car_controller_core import (  # noqa: F401
    corner_supervisors, FullCarController)
from semi_active_control.runtime.live_preview import LIVE_PREVIEW_LAWS, LivePreview  # noqa: F401
from semi_active_control.runtime.vehicle_controller import (  # noqa: F401
    failsafe_flags, full_car_state, MODE_FAIL_SAFE, MODE_INACTIVE, MODE_NORMAL, VehicleCommand,
    VehicleControllerCore)
from semi_active_control.runtime.vehicle_loop import VehicleLoop  # noqa: F401
