"""The vehicle computer's nodes: estimator, controller (managed) and the lifecycle manager."""
