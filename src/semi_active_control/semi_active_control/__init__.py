"""
semi_active_control: the vehicle side of the suite, what runs on a car.

Control laws, supervision (fail-safe, model acceptance, deadlines), state estimation, the
ROS-free cores the vehicle nodes call, and those nodes. It imports ``mr_damper_common`` and the
damper models it evaluates (``mr_damper_model.models``), never the simulator
(``quarter_car_sim``) nor the fitting stack (identification, live identifier, file I/O).
"""
