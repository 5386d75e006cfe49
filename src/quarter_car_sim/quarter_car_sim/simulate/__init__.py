"""
Offline closed loops: law -> inverse -> car, with ideal or sensed states (ROS-free).

Modules: ``live_loop`` (:class:`~quarter_car_sim.simulate.live_loop.ClosedLoop`, the car's one
closed loop, offline and live; pacing and the trace log), ``quarter_car``
(:func:`~quarter_car_sim.simulate.quarter_car.simulate`, comparisons, the identified set of a
study's damper parameters), ``sensed_loop`` (the laws on Kalman-estimated states), ``full_car``
(:func:`~quarter_car_sim.simulate.full_car.simulate_full_car`, law comparisons, sensed full car),
``vehicle_chain`` (:func:`~quarter_car_sim.simulate.vehicle_chain.simulate_vehicle_chain`, the
vehicle computer's estimator and controller on the car's bus sensors, offline).
"""
