"""
ROS 2 helpers shared by the suite's nodes: QoS, parameters, diagnostics, spin loop, ``main``.

Public API (what the nodes import)::

    from mr_damper_common.node_utils import MEASUREMENT_QOS, LATCHED_QOS, PARAMETERS_QOS
    from mr_damper_common.node_utils import STATUS_QOS, SENSOR_QOS, VEHICLE_QOS, DIAGNOSTICS_QOS
    from mr_damper_common.node_utils import PUBLISH_ERRORS, ResettablePublisher
    from mr_damper_common.node_utils import Param, declare_parameters, merge_parameters
    from mr_damper_common.node_utils import DropCounter, LogThrottle, DiagnosticsPublisher
    from mr_damper_common.node_utils import node_time_s, spin, spin_node, run_node
    from mr_damper_common.node_utils import run_guarded, tear_down
    from mr_damper_common.node_utils import make_executor, FastLane, set_realtime_priority
    from mr_damper_common.node_utils import set_cpu_affinity, parse_cpu_list
    from mr_damper_common.node_utils import install_stop_handlers, request_stop, stop_requested

Modules: ``qos`` (the QoS profiles and the publishers that go with them), ``parameters``
(declared parameters), ``diagnostics`` (drop counts, log throttle, ``/diagnostics``),
``spinning`` (clock, executor, spin loop, fast lane, ``run_node``; not named ``spin``, which is
the function). Imports rclpy (listed in ``ROS_MODULES`` of ``tests/test_core_is_ros_free.py``);
the numerical core never imports this package.
"""
from mr_damper_common.node_utils.diagnostics import (DiagnosticsPublisher,  # noqa: F401
                                                     DropCounter, LogThrottle)
from mr_damper_common.node_utils.parameters import (declare_parameters,  # noqa: F401
                                                    merge_parameters, Param)
from mr_damper_common.node_utils.qos import (CONTROL_QOS, DIAGNOSTICS_QOS,  # noqa: F401
                                             LATCHED_QOS, MEASUREMENT_QOS, PARAMETERS_QOS,
                                             PUBLISH_ERRORS,
                                             ResettablePublisher, SENSOR_QOS, STATUS_QOS,
                                             VEHICLE_QOS)
from mr_damper_common.node_utils.spinning import (FastLane, make_executor,  # noqa: F401
                                                  node_time_s, parse_cpu_list, run_guarded,
                                                  run_node, set_cpu_affinity,
                                                  set_realtime_priority, spin, spin_node,
                                                  tear_down)
from mr_damper_common.stop_flag import (_STOP, install_stop_handlers,  # noqa: F401
                                        request_stop, stop_requested)
