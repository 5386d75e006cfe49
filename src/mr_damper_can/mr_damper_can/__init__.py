"""CAN bus bridge of the MR damper suite (DBC, ROS-free bridge core, simulated ECU, nodes)."""
