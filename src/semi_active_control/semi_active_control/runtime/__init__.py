"""The vehicle's ROS-free cores: the full-car controller on one state per cycle."""
from semi_active_control.runtime.vehicle_controller import (full_car_state, MODE_FAIL_SAFE,
                                                            MODE_INACTIVE, MODE_NORMAL,
                                                            VehicleCommand,
                                                            VehicleControllerCore)

__all__ = ['full_car_state', 'MODE_FAIL_SAFE', 'MODE_INACTIVE', 'MODE_NORMAL',
           'VehicleCommand', 'VehicleControllerCore']
