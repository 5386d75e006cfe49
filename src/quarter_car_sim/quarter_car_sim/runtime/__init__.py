"""The simulated cars at run time (ROS-free): what the car nodes call."""
