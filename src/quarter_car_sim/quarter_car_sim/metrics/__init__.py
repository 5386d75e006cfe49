"""
Ride metrics of both cars (ROS-free).

Public API::

    from quarter_car_sim.metrics import ride_metrics, RunningRideMetrics, METRIC_KEYS
    from quarter_car_sim.metrics import full_car_metrics, iso2631_seat, RunningIso2631

Modules: ``quarter_car`` (Wk-weighted body acceleration, travel, tyre load, batch and
running), ``full_car`` (ISO 2631-1 at the seat: a_v, VDV, crest factors; per-wheel tyre load
and per-corner travel; :class:`RunningIso2631` for a run fed in chunks). The weightings are
:mod:`semi_active_control.iso2631`'s.
"""
from quarter_car_sim.metrics.full_car import (body_a_v, full_car_metrics,  # noqa: F401
                                              iso2631_seat, RunningIso2631)
from quarter_car_sim.metrics.quarter_car import (METRIC_KEYS, ride_metrics,  # noqa: F401
                                                 RunningRideMetrics)
