"""
The car the laws and estimators are designed on: nominal parameters and linear models.

Public API::

    from semi_active_control.car import QuarterCarParams, ParamsError
    from semi_active_control.car import FullCarParams, CORNERS, PASSENGER_CAR, symmetric_car
    from semi_active_control.car import linear_model, lqr_design, LqrDesign

Modules: ``quarter_car`` (a corner's parameters and sign conventions), ``full_car`` (the 7-DOF
car's parameters and corner geometry), ``quarter_car_linear`` (the linear quarter car: state
space, natural frequencies, transmissibility, the LQR design of the LQR laws).
"""
from semi_active_control.car.full_car import (CORNERS, FullCarParams,  # noqa: F401
                                              PASSENGER_CAR, symmetric_car)
from semi_active_control.car.quarter_car import ParamsError, QuarterCarParams  # noqa: F401
from semi_active_control.car.quarter_car_linear import (linear_model, lqr_design,  # noqa: F401
                                                        LqrDesign)
