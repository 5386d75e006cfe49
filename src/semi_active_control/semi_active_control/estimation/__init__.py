"""
State estimation on a vehicle: Kalman filters from production sensors, and the nodes' cores.

Public API::

    from semi_active_control.estimation import design_estimator, QuarterCarEstimator, Estimate
    from semi_active_control.estimation import design_full_car_estimator, FullCarEstimator
    from semi_active_control.estimation import StateEstimatorCore, PreviewInput
    from semi_active_control.estimation import VehicleEstimatorCore, EstimatorSettings
    from semi_active_control.estimation import SensorSpec, default_specs, accelerometer_spec

Modules: ``quarter_car`` (a corner's filter), ``full_car`` (the 7-DOF car's filter from three
or four body accelerometers and four position sensors), ``steady_step`` (its clean steady
cycle compiled), ``state_estimator_core`` (readings,
current and identified model in, one estimate per tick out: what ``state_estimator_node``
calls), ``vehicle_estimator`` (the vehicle computer's full-car estimator on the chassis bus's
sensors: what ``vehicle_estimator_node`` calls), ``road_preview`` (the road ahead from a
look-ahead sensor and the speed signal), ``preview_input`` (the road-preview topic to a law's
map: held speed, frames at their step, refusals, timeout), ``sensor_specs`` (the sensors'
datasheet error models the filters are designed on), ``sensor_cdr`` (the sensor messages
read from their serialised bytes).
"""
from semi_active_control.estimation.full_car import (design_full_car_estimator,  # noqa: F401
                                                     FullCarEstimator)
from semi_active_control.estimation.preview_input import PreviewInput  # noqa: F401
from semi_active_control.estimation.quarter_car import (design_estimator, Estimate,  # noqa: F401
                                                        EstimatorError, QuarterCarEstimator)
from semi_active_control.estimation.sensor_specs import (accelerometer_spec,  # noqa: F401
                                                         default_specs, ride_height_spec,
                                                         SensorSpec)
from semi_active_control.estimation.state_estimator_core import StateEstimatorCore  # noqa: F401
from semi_active_control.estimation.vehicle_estimator import (BUS_SENSORS,  # noqa: F401
                                                              EstimatorSettings,
                                                              VehicleEstimate,
                                                              VehicleEstimatorCore)
