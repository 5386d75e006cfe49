"""
The live simulated cars the car nodes call, one control step at a time (ROS-free).

Modules: ``quarter_car`` (:class:`~quarter_car_sim.runtime.quarter_car.CarRuntime`: built-in
law or external controller, lock-step, hardware in the loop, probing, sensing, trace log),
``full_car`` (:class:`~quarter_car_sim.runtime.full_car.FullCarRuntime`), ``control_thread``
(the paced control thread), ``command_input`` (an external controller's commands, checked and
timed), ``hil`` (the rig in the loop: delay compensation, remote plant), ``probing`` (current
bins for the identifier), ``car_health`` (the car node's health rules), ``look_ahead`` (the
car's simulated look-ahead sensor for the road-preview topic).
"""
