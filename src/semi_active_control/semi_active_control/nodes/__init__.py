"""
The vehicle's nodes: thin ROS adapters over the ROS-free cores.

- ``semi_active_controller_node``: a corner's state in, a supervised coil current out
  (:class:`semi_active_control.runtime.ControllerCore`);
- ``state_estimator_node``: the corner's sensors in, its estimated state out
  (:class:`semi_active_control.estimation.StateEstimatorCore`);
- the vehicle computer's managed nodes: ``vehicle_estimator_node`` (the chassis bus's sensors
  in, the full car's estimate out, :class:`semi_active_control.estimation.VehicleEstimatorCore`),
  ``vehicle_controller_node`` (the estimate, or a simulated car's true state, in, four
  supervised currents out, :class:`semi_active_control.runtime.VehicleControllerCore`; with
  the LQ road-preview law on the road-preview topic) and ``lifecycle_manager_node``
  (the chain's order of transitions, :mod:`semi_active_control.supervision.lifecycle_chain`).

``common`` holds what these nodes and the simulator's car nodes share (parameter tables,
offering a parameter message to a supervisor); ``entry_points`` the console scripts
(``ros2 run semi_active_control <node>``). No node module imports another
(tests/test_node_imports.py).
"""
