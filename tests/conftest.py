"""
Test-wide set-up: keep ROS 2 discovery on loopback and on a domain of this run's own.

This runs before any test module imports rclpy, so every node a test creates (in this process or
in a subprocess that inherits the environment) uses LOCALHOST discovery and a private domain.
"""
import os
import random
import sys
import tempfile
from pathlib import Path

os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
os.environ.setdefault('ROS_DOMAIN_ID', str(random.Random(os.getpid()).randint(20, 220)))
os.environ.setdefault('ROS_LOG_DIR', tempfile.mkdtemp(prefix='ros_log_'))

REPO = Path(__file__).resolve().parents[1]
SHARED = REPO.parent / 'shared'
QUIROZ_DIR = SHARED / 'data' / 'quiroz_mr_damper'
# console scripts of the editable installs live next to the interpreter running the tests
VENV_BIN = Path(sys.executable).parent
