"""
The simulated cars: dynamics, roads, damper plants in the loop, vehicle sensors (ROS-free).

Public API::

    from quarter_car_sim.plant import QuarterCar, LinearDamperPlant, FullCar
    from quarter_car_sim.plant import make_road, RoadProfile, make_two_track_road, TwoTrackRoad
    from quarter_car_sim.plant import VehicleSensors, FullCarSensors, SensorSampler

Modules: ``quarter_car`` and ``full_car`` (the exactly discretised cars with tyre lift-off;
their damper plants are :mod:`mr_damper_model.models.plant`'s), ``road`` (ISO 8608 and event
roads, CSV profiles), ``two_track_road`` (the full car's two tracks), ``sensors`` (sensors
sampled with the error models of :mod:`semi_active_control.estimation.sensor_specs`).
"""
from quarter_car_sim.plant.full_car import FullCar, mechanical_energy  # noqa: F401
from quarter_car_sim.plant.quarter_car import LinearDamperPlant, QuarterCar  # noqa: F401
from quarter_car_sim.plant.road import make_road, RoadError, RoadProfile  # noqa: F401
from quarter_car_sim.plant.sensors import (bus_sensor_cluster, FullCarSensors,  # noqa: F401
                                           SensorSampler, VehicleSensors)
from quarter_car_sim.plant.two_track_road import (make_two_track_road,  # noqa: F401
                                                  TwoTrackRoad)
