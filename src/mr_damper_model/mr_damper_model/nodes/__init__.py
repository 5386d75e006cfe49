"""
The identifier's ROS 2 node (``ros2 run mr_damper_model identifier_node``).

Modules: ``identifier_node`` (messages in and out around
:class:`mr_damper_model.live.worker.IdentifierRuntime`), ``entry_points`` (the console script,
with the stop handlers installed before rclpy loads).
"""
