"""Command-line tools of the simulator: ``full-car-sim`` and the one-line-error argument parser."""
