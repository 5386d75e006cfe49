"""
The simulated cars' nodes: ``quarter_car_node`` and ``full_car_node``.

``car_process`` runs a car node's process (its control thread's end); ``entry_points`` holds
the console scripts, among them the old names of the vehicle's nodes (moved to
``semi_active_control``, kept for one release with a warning).
"""
