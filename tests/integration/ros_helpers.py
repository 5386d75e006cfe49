"""
Helpers for multi-process ROS 2 tests: start console-script nodes, listen to topics, wait.

Node processes inherit the loopback DDS settings and the private ROS_DOMAIN_ID that
tests/conftest.py sets.  Discovery usually takes < 50 ms but sometimes ~3 s, so every
wait here uses a timeout of at least 5 s. Every process started here runs in a process group
of its own that gets SIGTERM if the test process dies, and is stopped as a group
(``process_helpers``).

Usage::

    with NodeProcess('rig_node', params={'mode': 'csv', 'file': path}) as rig, \
            Listener() as lis:
        status = lis.subscribe('/mr_damper/identifier_status', String)
        lis.wait_for(lambda: len(status) > 0, timeout=10)
"""
import ast
import contextlib
import json
import os
import re
from pathlib import Path
import signal
import subprocess
import tempfile
import threading
import time

from conftest import REPO, VENV_BIN
from process_helpers import end_suite, popen, run, stop_group
from ros_context import ros_context


def console_scripts(package):
    """
    Return the console scripts ``{name: 'module:function'}`` of ``src/<package>/setup.py``.

    Parsed, not executed: the one list of what ``ros2 run PACKAGE NAME`` can start, which the
    launch-file and colcon tests check against (a new node cannot be missed).
    """
    tree = ast.parse((REPO / 'src' / package / 'setup.py').read_text())
    scripts = {}
    for node in ast.walk(tree):
        if isinstance(node, ast.Constant) and isinstance(node.value, str) and ' = ' in node.value:
            name, target = (s.strip() for s in node.value.split('=', 1))
            scripts[name] = target
    return scripts


def python_packages():
    """Return the names of the Python packages under ``src/`` (those with a setup.py), sorted."""
    return sorted(p.parent.name for p in (REPO / 'src').glob('*/setup.py'))


def package_of(executable):
    """Return the package whose setup.py declares the console script ``executable``."""
    owners = [p for p in python_packages() if executable in console_scripts(p)]
    assert len(owners) == 1, f'{executable}: declared by {owners or "no package"}'
    return owners[0]


#: Folder of the node processes' output files (tests/integration/conftest.py sets it to one in
#: pytest's base temporary folder, which pytest prunes to its last few runs; None: the system's)
LOG_DIR = None


def fault_test_suite(out):
    """
    Return the suite of a fault test (:class:`mr_damper_bringup.processes.Suite`, not started).

    The main job's parameters at real time, with a 1 s parameter timeout, car diagnostics every
    0.1 s, a rig that waits for one reader and an identifier that saves its parameters every
    0.5 s (a restarted identifier starts from them); no end of its own (the test stops it; the
    road repeats); written to ``out/suite_params.yaml``.
    """
    import yaml
    from mr_damper_bringup.config import IDENT, QC, resolve_config, RIG, set_param
    from mr_damper_bringup.launcher import parse_args
    from mr_damper_bringup.processes import Suite
    args = parse_args(['--out', str(out), '--rate-factor', '1.0', '--duration', '0'])
    cfg = resolve_config(args, out)
    set_param(cfg, QC, 'param_timeout_s', 1.0)
    set_param(cfg, QC, 'diagnostics_period_s', 0.1)
    set_param(cfg, RIG, 'wait_for_subscribers', 1)
    set_param(cfg, IDENT, 'save_period_s', 0.5)
    params_file = Path(out) / 'suite_params.yaml'
    params_file.write_text(yaml.safe_dump(cfg))
    return Suite(params_file, out, int(os.environ['ROS_DOMAIN_ID']))


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
    remap : dict, optional
        Remappings ``-r from:=to`` (topic names, ``__ns``, ``__node``).
    namespace : str, optional
        Node namespace (``-r __ns:=/namespace``).

    """

    def __init__(self, exe, params=None, args=(), env=None, remap=None, namespace=None):
        path = Path(exe) if os.sep in str(exe) else VENV_BIN / exe
        cmd = [str(path), *args, '--ros-args']
        if namespace:
            cmd += ['-r', f'__ns:=/{namespace.strip("/")}']
        for old, new in (remap or {}).items():
            cmd += ['-r', f'{old}:={new}']
        for name, value in (params or {}).items():
            cmd += ['-p', f'{name}:={ros_param(value)}']
        self.cmd = cmd
        self.log = tempfile.NamedTemporaryFile(prefix=f'{path.name}_', suffix='.log',
                                               dir=LOG_DIR, delete=False)
        full_env = dict(os.environ, PYTHONUNBUFFERED='1')
        full_env.update(env or {})
        from mr_damper_bringup.network import on_loopback
        assert on_loopback(full_env), 'DDS must stay on loopback (tests/conftest.py)'
        self.proc = popen(cmd, stdout=self.log, stderr=subprocess.STDOUT, env=full_env)

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
        """
        Stop with SIGINT (then SIGKILL after ``timeout``), its group too; return the status.

        One SIGINT, to the group (the node is its leader): a second one sent right after the
        first could reach a node already finishing, during the interpreter's finalization,
        when Python has put back the default handler (exit -2 instead of 0, seen under load).
        """
        return stop_group(self.proc, signal.SIGINT, timeout)

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.stop()
        return False


class Listener:
    """
    An rclpy node in the test process, spun in a background thread, recording messages.

    ``subscribe`` returns a list that fills with ``(receive_time, msg)`` tuples. The node lives
    in an rclpy context of its own (``context``; :func:`ros_context.ros_context`), shut down by
    :meth:`close`, also when the construction fails half-way.
    """

    def __init__(self, name='test_listener'):
        import rclpy
        from rclpy.executors import SingleThreadedExecutor
        self._stop = threading.Event()
        self._thread = None
        with contextlib.ExitStack() as stack:
            self.context = stack.enter_context(ros_context())
            self.node = rclpy.create_node(name, context=self.context)
            stack.callback(self.node.destroy_node)
            self._executor = SingleThreadedExecutor(context=self.context)
            stack.callback(self._executor.shutdown)
            self._executor.add_node(self.node)
            self._thread = threading.Thread(target=self._spin, daemon=True)
            self._thread.start()
            self._closing = stack.pop_all()

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

    def diagnostics(self):
        """Subscribe to ``/diagnostics`` and return the :class:`Diagnostics` collecting it."""
        from diagnostic_msgs.msg import DiagnosticArray
        diag = Diagnostics()
        self.node.create_subscription(DiagnosticArray, '/diagnostics', diag.add,
                                      status_qos())
        return diag

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
        """Stop spinning, destroy the node and shut its context down."""
        self._stop.set()
        self._thread.join(timeout=5)
        self._closing.close()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()
        return False


def status_qos():
    """Return the QoS the tests subscribe to ``/diagnostics`` with (reliable, depth 100)."""
    from rclpy.qos import QoSProfile, ReliabilityPolicy
    return QoSProfile(depth=100, reliability=ReliabilityPolicy.RELIABLE)


class Diagnostics:
    """
    The ``/diagnostics`` statuses received, by status name.

    The name is the node's fully qualified name without the leading slash, e.g.
    ``'mr_damper_identifier'`` or ``'fl/mr_damper_identifier'``. Keeps the newest
    :class:`~mr_damper_common.health.Health` and a count per name, and the sequence of levels
    (bounded), so tests assert order and counts of events.

    """

    def __init__(self, max_levels=10_000):
        self._lock = threading.Lock()
        self._latest = {}
        self._counts = {}
        self._levels = {}
        self._max = int(max_levels)

    def add(self, msg):
        """Subscription callback: record each status of a ``DiagnosticArray``."""
        from mr_damper_common.messages import health_from_diagnostic
        with self._lock:
            for status in msg.status:
                health = health_from_diagnostic(status)
                self._latest[status.name] = health
                self._counts[status.name] = self._counts.get(status.name, 0) + 1
                levels = self._levels.setdefault(status.name, [])
                if len(levels) < self._max:
                    levels.append(health.level)

    def latest(self, name):
        """Return the newest Health of ``name`` (None before the first)."""
        with self._lock:
            return self._latest.get(name)

    def values(self, name):
        """Return the newest status values of ``name`` ({} before the first)."""
        health = self.latest(name)
        return dict(health.values) if health is not None else {}

    def count(self, name):
        """Return how many statuses of ``name`` arrived."""
        with self._lock:
            return self._counts.get(name, 0)

    def levels(self, name):
        """Return the levels of ``name`` in the order they arrived."""
        with self._lock:
            return list(self._levels.get(name, []))

    def names(self):
        """Return the status names seen so far."""
        with self._lock:
            return sorted(self._latest)


def pump_lines(stream, lines):
    """Put every line of ``stream`` on the queue ``lines``, then None at its end (a thread)."""
    for line in iter(stream.readline, ''):
        lines.put(line)
    lines.put(None)


def run_until_ready(cmd, env, is_ready, guard_s=300.0, out=None):
    """
    Start ``cmd``, read its output until ``is_ready(line)``, then stop it with SIGINT (Ctrl-C).

    ``guard_s`` is a hang guard only (also without output). Returns ``(ready, returncode,
    seen, rest)``: whether a line made it ready (else the process group is killed), the exit
    status, the lines read before and the text after the SIGINT. With ``out`` (the folder of a
    ``mr-damper-suite`` run) it also makes sure every node of the run has gone.
    """
    import queue
    proc = popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, env=env)
    seen, ready, rest = [], False, ''
    lines = queue.Queue()
    reader = threading.Thread(target=pump_lines, args=(proc.stdout, lines), daemon=True)
    reader.start()
    deadline = time.monotonic() + guard_s
    try:
        while not ready:
            try:
                line = lines.get(timeout=max(deadline - time.monotonic(), 0.0))
            except queue.Empty:
                break
            if line is None:                            # the process ended
                break
            seen.append(line)
            ready = bool(is_ready(line))
        if ready:
            proc.send_signal(signal.SIGINT)
            # the stop and the report may take long on a loaded machine: the process first
            # (the reader thread keeps taking its output), then what it wrote
            proc.wait(timeout=guard_s)
            reader.join(timeout=guard_s)
            parts = []
            while not lines.empty():
                parts.append(lines.get() or '')
            rest = ''.join(parts)
    finally:
        if proc.poll() is None or out is not None:
            end_suite(proc, out)
    return ready, proc.returncode, seen, rest


class SuiteRun:
    """
    ``mr-damper-suite`` running until stopped, its output read line by line (context manager).

    Started in a process group of its own (:func:`process_helpers.popen`); on exit the launcher
    is stopped and every node it started has to be gone (``left`` lists any that outlived it).

    Parameters
    ----------
    out : path
        Its ``--out`` folder.
    options : str
        More command-line options (``--duration 0`` and the test's domain are given).
    guard_s : float
        Hang guard of every wait [s] (also without output).

    """

    def __init__(self, out, *options, guard_s=400.0):
        import queue
        self.out = Path(out)
        cmd = [str(VENV_BIN / 'mr-damper-suite'), '--duration', '0', '--out', str(out),
               '--progress-s', '1', '--no-plots', '--domain-id', os.environ['ROS_DOMAIN_ID'],
               *options]
        self.proc = popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                          env=dict(os.environ))
        self.lines = queue.Queue()
        self.seen = []
        self.left = None
        self.deadline = time.monotonic() + guard_s
        threading.Thread(target=pump_lines, args=(self.proc.stdout, self.lines),
                         daemon=True).start()

    def wait_for(self, pattern, n=1):
        """Read the output until the regular expression ``pattern`` matched ``n`` more lines."""
        import queue
        import re
        found = 0
        while found < n:
            try:
                line = self.lines.get(timeout=max(self.deadline - time.monotonic(), 0.0))
            except queue.Empty:
                line = None
            assert line is not None, f'no {pattern!r}:\n' + ''.join(self.seen[-40:])
            self.seen.append(line)
            found += bool(re.search(pattern, line))
        return self.seen[-1]

    def pids(self):
        """Return ``{node: pid}`` of the latest start of each node (``pids.json``)."""
        import json
        return json.loads((self.out / 'pids.json').read_text())

    def stop(self):
        """Stop the run with SIGINT (Ctrl-C) and wait for its end; return the exit status."""
        self.proc.send_signal(signal.SIGINT)
        self.wait_for('outputs in')
        return self.proc.wait(timeout=max(self.deadline - time.monotonic(), 1.0))

    def text(self):
        """Return every line read so far."""
        return ''.join(self.seen)

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.left = end_suite(self.proc, self.out)
        return False


def end_suite_nodes(out, guard_s=60.0):
    """Wait until the nodes of the suite run in ``out`` are gone; return those that were not."""
    from process_helpers import suite_pids, wait_gone
    left = wait_gone(suite_pids(out), guard_s)
    for pid in left:
        try:
            os.killpg(pid, signal.SIGKILL)
        except (ProcessLookupError, PermissionError):
            pass
    return left


def run_suite(out, *options, timeout_s=240):
    """
    Run ``mr-damper-suite`` to its end (``--no-plots``, the test's domain) and check it was clean.

    Asserts exit status 0 and no node died or exited uncleanly (the launcher says so); the
    timeout is a hang guard. Returns the completed process (``stdout``, ``stderr``).
    """
    env = dict(os.environ)
    cmd = [str(VENV_BIN / 'mr-damper-suite'), *options, '--out', str(out), '--progress-s', '5',
           '--no-plots', '--domain-id', env['ROS_DOMAIN_ID']]
    try:
        proc = run(cmd, timeout_s, env=env)
    finally:
        left = end_suite_nodes(out)
    assert not left, f'nodes outlived the launcher: {left}'
    text = proc.stdout[-3000:] + proc.stderr[-3000:]
    # exit 0: every node ran to the end and exited 0 (CLEAN_EXIT), else the launcher says 1
    assert proc.returncode == 0, text
    assert 'exited with' not in proc.stderr and 'died (exit' not in proc.stderr, text
    return proc


#: car time in a progress line of ``mr-damper-suite``: ``t_sim 12.3 s`` (a quarter car) or
#: ``car t 12.34 s`` (the full car)
CAR_TIME = re.compile(r'(?:t_sim|car t) (-?[\d.]+) s')
COMMANDING = re.compile(r'\| controller normal, (\d+) commands on a model')


def controller_commanding(line):
    """
    Whether a progress line says the external controller commands on a model.

    Its mode ``normal`` (a model accepted) and a positive count of commands on a model: a
    controller starved of car states (seen with two CI runs and a CPU burner on two cores) had
    accepted a model and commanded nothing, and its last status went on saying normal.
    """
    m = COMMANDING.search(line)
    return m is not None and int(m.group(1)) > 0


def run_suite_until_controlled(out, *options, controlled, car_s=2.0, guard_s=300.0,
                               plots=False):
    """
    Run ``mr-damper-suite`` until its car drove ``car_s`` of car time on models, then Ctrl-C.

    No wall-clock duration (``--duration 0``): the suite runs until a progress line (one a
    second) says ``controlled(line)`` (the car, or every corner, commands on a model) and the car
    time of a later line is ``car_s`` past the first such line's, so a slow machine runs to the
    same events. ``guard_s`` is a hang guard only; ``plots``: the report's plots too. Asserts
    exit status 0 and no node died;
    returns ``(summary, output)``: the run's ``summary.json`` and the launcher's output.
    """
    env = dict(os.environ)
    cmd = [str(VENV_BIN / 'mr-damper-suite'), *options, '--duration', '0', '--out', str(out),
           '--progress-s', '1', '--domain-id', env['ROS_DOMAIN_ID'],
           *([] if plots else ['--no-plots'])]
    t_first = []

    def ready(line):
        t_car = CAR_TIME.search(line)
        if t_car is None:
            return False
        if not t_first and controlled(line):
            t_first.append(float(t_car.group(1)))
        return bool(t_first) and float(t_car.group(1)) >= t_first[0] + car_s

    ok, returncode, seen, rest = run_until_ready(cmd, env, ready, guard_s=guard_s, out=out)
    text = ''.join(seen[-20:]) + rest[-3000:]
    assert ok, text
    assert returncode == 0, text
    assert 'exited with' not in rest and 'died (exit' not in rest, text
    return json.loads((Path(out) / 'summary.json').read_text()), ''.join(seen) + rest


def assert_reached_control(summary, units=('car',)):
    """
    Assert the summary's ``control`` section: the car reached control.

    Every identifier published a valid set, every law unit (``'car'``, or the corners)
    commanded on a model, and the car was not in fail-safe throughout after that.
    """
    c = summary['control']
    assert set(c['units']) == set(units), c['units']
    for unit in units:
        u = c['units'][unit]
        assert u.get('first_valid_set_s') is not None, (unit, c)
        assert u.get('first_normal_s') is not None, (unit, c)
    assert c['failsafe_fraction'] is None or c['failsafe_fraction'] < 1.0, c
    assert c['real_time_factor'] is not None and c['real_time_factor'] > 0, c
