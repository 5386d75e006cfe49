"""State estimation on a vehicle: the full car's state from the chassis sensors (no ROS)."""
from semi_active_control.estimation.vehicle_estimator import (BUS_SENSORS, EstimatorSettings,
                                                              VehicleEstimate,
                                                              VehicleEstimatorCore)

__all__ = ['BUS_SENSORS', 'EstimatorSettings', 'VehicleEstimate', 'VehicleEstimatorCore']
