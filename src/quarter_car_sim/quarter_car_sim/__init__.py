"""
quarter_car_sim: the simulator of the suite, by role, for the quarter car and the full car.

- ``plant``: the cars (quarter car, 7-DOF full car) on their roads with their "true" damper
  plants, and the vehicle sensors sampled with their error models;
- ``metrics``: ride metrics (Wk body acceleration, travel, tyre load) and the full car's
  ISO 2631-1 seat metrics;
- ``bound``: the offline optimal semi-active bounds (full road preview);
- ``simulate``: the offline closed loops (law, inverse, car), with ideal or sensed states;
- ``runtime``: the live cars the car nodes call (pacing, external controller, hardware in the
  loop, probing, health);
- ``analysis``: plots of the linear car and of ride studies;
- ``nodes``: ``quarter_car_node`` and ``full_car_node`` (and the old names of the vehicle's
  nodes, which moved to ``semi_active_control``);
- ``tools``: ``full-car-sim`` and the command-line helpers (``quarter-car-sim`` is
  mr_damper_bringup's: it needs the rig too).

What runs on a vehicle (the laws, their supervision, the estimators, the controller cores and
nodes) is ``semi_active_control``'s; the simulator imports it, never the other way round.
"""
