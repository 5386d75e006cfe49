"""
Helpers for multi-process ROS 2 tests: start console-script nodes, listen to topics, wait.

Node processes inherit ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST and the private ROS_DOMAIN_ID
that tests/conftest.py sets.  Discovery usually takes < 50 ms but sometimes ~3 s, so every
wait here uses a timeout of at least 5 s.

Usage::

    with NodeProcess('rig_node', params={'mode': 'csv', 'file': path}) as rig, \
            Listener() as lis:
        status = lis.subscribe('/mr_damper/identifier_status', String)
        lis.wait_for(lambda: len(status) > 0, timeout=10)
"""
import os
from pathlib import Path
import signal
import subprocess
import tempfile
import threading
import time

from conftest import VENV_BIN

DISCOVERY_TIMEOUT_S = 8.0


def ros_param(value):
    """Format a Python value as a ``-p name:=value`` literal (types are strict in ROS)."""
    if isinstance(value, bool):
        return 'true' if value else 'false'
    if isinstance(value, float):
        return repr(value)
    if isinstance(value, (list, tuple)):
        return '[' + ','.join(ros_param(v) for v in value) + ']'
    return str(value)


class NodeProcess:
    """
    A console-script node in its own process (context manager: stopped with SIGINT on exit).

    Parameters
    ----------
    exe : str
        Console script name in the venv's bin directory (or a full path).
    params : dict, optional
        ROS parameters given as ``-p name:=value``.
    args : list of str, optional
        Extra arguments before ``--ros-args``.
    env : dict, optional
        Extra environment variables.

    """

    def __init__(self, exe, params=None, args=(), env=None):
        path = Path(exe) if os.sep in str(exe) else VENV_BIN / exe
        cmd = [str(path), *args, '--ros-args']
        for name, value in (params or {}).items():
            cmd += ['-p', f'{name}:={ros_param(value)}']
        self.cmd = cmd
        self.log = tempfile.NamedTemporaryFile(prefix=f'{path.name}_', suffix='.log',
                                               delete=False)
        full_env = dict(os.environ, PYTHONUNBUFFERED='1')
        full_env.update(env or {})
        assert full_env.get('ROS_AUTOMATIC_DISCOVERY_RANGE') == 'LOCALHOST'
        self.proc = subprocess.Popen(cmd, stdout=self.log, stderr=subprocess.STDOUT,
                                     env=full_env)

    def output(self):
        """Return what the process printed so far."""
        with open(self.log.name, errors='replace') as fh:
            return fh.read()

    def alive(self):
        """Return True while the process runs."""
        return self.proc.poll() is None

    def wait(self, timeout):
        """Wait for the process to end; return its exit status."""
        return self.proc.wait(timeout=timeout)

    def stop(self, timeout=10.0):
        """Stop with SIGINT (then SIGKILL after ``timeout``); return the exit status."""
        if self.proc.poll() is None:
            self.proc.send_signal(signal.SIGINT)
            try:
                self.proc.wait(timeout=timeout)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait(timeout=5)
        return self.proc.returncode

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.stop()
        return False


class Listener:
    """
    An rclpy node in the test process, spun in a background thread, recording messages.

    ``subscribe`` returns a list that fills with ``(receive_time, msg)`` tuples.
    """

    def __init__(self, name='test_listener'):
        import rclpy
        from rclpy.executors import SingleThreadedExecutor
        if not rclpy.ok():
            rclpy.init()
        self.node = rclpy.create_node(name)
        self._executor = SingleThreadedExecutor()
        self._executor.add_node(self.node)
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._spin, daemon=True)
        self._thread.start()

    def _spin(self):
        while not self._stop.is_set():
            self._executor.spin_once(timeout_sec=0.05)

    def subscribe(self, topic, msg_type, qos=None):
        """Subscribe and return the list receiving ``(t_receive, msg)``."""
        from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
        if qos is None:
            qos = QoSProfile(depth=100, reliability=ReliabilityPolicy.RELIABLE,
                             durability=DurabilityPolicy.TRANSIENT_LOCAL)
        received = []
        self.node.create_subscription(msg_type, topic,
                                      lambda m: received.append((time.monotonic(), m)), qos)
        return received

    def publisher(self, topic, msg_type, qos=None):
        """Create a publisher: reliable, depth 1000, unless ``qos`` is given."""
        from rclpy.qos import QoSProfile, ReliabilityPolicy
        if qos is None:
            qos = QoSProfile(depth=1000, reliability=ReliabilityPolicy.RELIABLE)
        return self.node.create_publisher(msg_type, topic, qos)

    @staticmethod
    def wait_for(predicate, timeout, poll=0.05, procs=()):
        """
        Wait until ``predicate()`` is true; return True, or False after ``timeout`` seconds.

        Stops early (False) if one of ``procs`` (NodeProcess) died.
        """
        end = time.monotonic() + timeout
        while time.monotonic() < end:
            if predicate():
                return True
            if any(not p.alive() for p in procs):
                return bool(predicate())
            time.sleep(poll)
        return bool(predicate())

    def close(self):
        """Stop spinning and destroy the node."""
        self._stop.set()
        self._thread.join(timeout=5)
        self._executor.shutdown()
        self.node.destroy_node()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()
        return False


def status_qos():
    """Return the QoS the tests subscribe to JSON status topics with (reliable, depth 100)."""
    from rclpy.qos import QoSProfile, ReliabilityPolicy
    return QoSProfile(depth=100, reliability=ReliabilityPolicy.RELIABLE)


def latest_status(received):
    """Return the newest JSON status of a :meth:`Listener.subscribe` list ({} if none)."""
    import json
    return json.loads(received[-1][1].data) if received else {}
