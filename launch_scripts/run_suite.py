#!/usr/bin/env python3
"""
Run the whole MR damper suite here, where ``ros2 launch`` does not exist.

Starts the console scripts ``rig_node``, ``identifier_node`` and ``quarter_car_node`` of the venv
with ONE parameter YAML (``--ros-args --params-file FILE``), on loopback-only discovery
(``ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST``) and a domain ID of its own, records the topics the
summary needs in its own process, forwards Ctrl-C (SIGINT) to the children, shuts everything down
in order (rig first, so the identifier drains the stream) and exits non-zero if a node died.
At the end it writes ``summary.json`` and plots into ``--out``
(see ``quarter_car_sim.suite_report``).

Usage (venv python)::

    .venv/bin/python launch_scripts/run_suite.py [--duration 30] [--out suite_out]
        [--config sim|replay|hil] [--file PATH ...] [--real-time | --faster | --rate-factor F]
        [--domain-id N] [--set NODE.PARAM=VALUE ...] [--no-plots] [--quiet]
        [--external-controller]

``--external-controller`` (or ``quarter_car_node.controller: external`` in the YAML / --set)
also starts ``semi_active_controller_node`` (YAML key ``semi_active_controller``): the car is
then the plant only and its law runs in the controller node (docs/controller-node.md).

Exit status: 0 clean run, 1 a node died or failed to shut down, 2 bad command line / config.
"""
import argparse
import json
import math
import os
from pathlib import Path
import random
import signal
import subprocess
import sys
import threading
import time

import yaml

HERE = Path(__file__).resolve().parent
REPO = HERE.parent
CONFIG_DIR = HERE / 'config'
#: node name (the YAML key) -> console script (the ``ros2 run`` executable), in start order
NODES = {'mr_damper_rig': 'rig_node', 'mr_damper_identifier': 'identifier_node',
         'quarter_car_node': 'quarter_car_node'}
RIG, IDENT, QC = NODES
#: the stand-alone controller node (started with ``--external-controller``)
CTRL = 'semi_active_controller'
CONTROLLER_NODE = {CTRL: 'semi_active_controller_node'}
#: car parameters the controller node takes over when the law moves out of the car
CONTROLLER_PARAMS = ('controller', 'controller_options', 'safe_current_a', 'param_timeout_s',
                     'min_current_span_a', 'hold_on_reject', 'i_min_a', 'i_max_a',
                     'params_topic', 'command_topic', 'car_state_topic')
QUIROZ_DIR = REPO.parent / 'shared' / 'data' / 'quiroz_mr_damper'
DEFAULT_REPLAY = tuple(QUIROZ_DIR / f'quiroz_sine_10mm1Hz_{c}A_preproc.csv'
                       for c in ('0', '0p25', '0p5', '0p75', '1p0'))
#: Exit statuses of a clean stop: every node handles SIGINT and SIGTERM (node_utils.run_node)
#: and exits 0, so death by a signal or a traceback on the way out is an unclean shutdown.
CLEAN_EXIT = (0,)


class SuiteError(Exception):
    """A bad command line or configuration (exit status 2)."""


# ---------------------------------------------------------------------------------- config
def _parse_value(text):
    """Parse a --set value with YAML rules (1.0 float, 1 int, true bool, else string)."""
    value = yaml.safe_load(text)
    return text if value is None else value


def load_config(config='sim', params=None):
    """
    Load the suite parameter YAML.

    Parameters
    ----------
    config : {'sim', 'replay', 'hil'}
        Which shipped configuration (``launch_scripts/config/suite_<config>.yaml``).
    params : path, optional
        A parameter YAML of your own instead (same layout).

    Returns
    -------
    dict
        ``{node_name_or_/**: {'ros__parameters': {...}}}``.

    """
    path = Path(params) if params else CONFIG_DIR / f'suite_{config}.yaml'
    try:
        cfg = yaml.safe_load(path.read_text())
    except (OSError, yaml.YAMLError) as exc:
        raise SuiteError(f'cannot read parameter file {path}: {exc}') from None
    if not isinstance(cfg, dict):
        raise SuiteError(f'{path}: not a ROS 2 parameter file (top level is not a mapping)')
    for node in NODES:
        cfg.setdefault(node, {}).setdefault('ros__parameters', {})
    return cfg


def node_params(cfg, node):
    """Return the merged parameters a node sees (``/**`` section, then its own)."""
    merged = dict(cfg.get('/**', {}).get('ros__parameters', {}))
    merged.update(cfg.get(node, {}).get('ros__parameters', {}))
    return merged


def set_param(cfg, node, name, value):
    """Set ``node``'s parameter ``name`` (a node name or ``/**``) in the config dict."""
    cfg.setdefault(node, {}).setdefault('ros__parameters', {})[name] = value


def concatenate_csv(files, out_path):
    """Concatenate DAQ CSV files (header t,x,v,f,i) into one with continuous time."""
    from mr_damper_model.data import DamperData, read_csv, write_csv
    data = DamperData.concatenate([read_csv(f) for f in files], restamp=True)
    write_csv(out_path, data)
    return out_path


def resolve_config(args, out):
    """Build the single parameter dict of this run from the command line; write nothing."""
    cfg = load_config(args.config, args.params)
    qc = QC
    if args.rate_factor is not None:
        set_param(cfg, RIG, 'rate_factor', float(args.rate_factor))
        set_param(cfg, qc, 'real_time_factor', float(args.rate_factor))
    set_param(cfg, qc, 'log_file', str(out / 'quarter_car_log'))
    # the identifier saves its last good parameters here (and restarts from them); a new run
    # starts without them so that the time to the first valid model is measured honestly
    ident_file = out / 'identifier_params.json'
    if ident_file.exists():
        ident_file.unlink()
    set_param(cfg, IDENT, 'params_file', str(ident_file))
    # a run that outlasts the car's road drives it again (ISO 8608 roads repeat seamlessly):
    # memory stays one road length however long the run (held flat otherwise)
    factor = node_params(cfg, qc).get('real_time_factor', 1.0) or 20.0
    need = float(args.duration) * float(factor) + 10.0 if args.duration else math.inf
    if node_params(cfg, qc).get('road_duration_s', 300.0) < need:
        set_param(cfg, qc, 'road_repeat', True)
    if args.config == 'replay' or args.file:
        files = [Path(f) for f in (args.file or DEFAULT_REPLAY)]
        for f in files:
            if not f.exists():
                raise SuiteError(f'--file {f}: no such file or directory')
        if len(files) > 1:
            for f in files:
                if f.suffix.lower() != '.csv':
                    raise SuiteError(f'--file {f}: several files can only be CSV files')
            path = concatenate_csv(files, out / 'replay_input.csv')
            mode = 'csv'
        else:
            path = files[0]
            mode = 'csv' if path.suffix.lower() == '.csv' else 'bag'
        set_param(cfg, RIG, 'mode', mode)
        set_param(cfg, RIG, 'file', str(path.resolve()))
    for item in args.set or ():
        try:
            key, text = item.split('=', 1)
            node, name = key.rsplit('.', 1)
        except ValueError:
            raise SuiteError(f'--set {item!r}: expected NODE.PARAM=VALUE') from None
        set_param(cfg, node, name, _parse_value(text))
    if getattr(args, 'external_controller', False) or external_controller(cfg):
        use_external_controller(cfg)
    return cfg


def external_controller(cfg):
    """Return True when the car's law runs in the controller node (``controller: external``)."""
    return str(node_params(cfg, QC).get('controller', '')).strip().lower() == 'external'


def use_external_controller(cfg):
    """Move the car's law into the controller node's section; the car becomes the plant."""
    car = node_params(cfg, QC)
    own = cfg.setdefault(CTRL, {}).setdefault('ros__parameters', {})
    for name in CONTROLLER_PARAMS:
        if name in car and not (name == 'controller' and external_controller(cfg)):
            own.setdefault(name, car[name])
    set_param(cfg, QC, 'controller', 'external')


def suite_nodes(cfg):
    """Return the nodes to start, in order (the controller before the car when external)."""
    if not external_controller(cfg):
        return dict(NODES)
    return {RIG: NODES[RIG], IDENT: NODES[IDENT], **CONTROLLER_NODE, QC: NODES[QC]}


# ---------------------------------------------------------------------------------- processes
class Suite:
    """
    The three node processes of one suite run.

    Parameters
    ----------
    params_file : path
        The single parameter YAML given to every node.
    out : path
        Output folder: ``logs/NODE.log`` (stdout+stderr) and ``ros_log/``.
    domain_id : int
        ROS_DOMAIN_ID of this run (0..232).
    bin_dir : path, optional
        Folder with the console scripts (default: next to this interpreter, i.e. the venv).
    nodes : dict, optional
        Node name -> console script, in start order (default :data:`NODES`; see
        :func:`suite_nodes`).

    """

    def __init__(self, params_file, out, domain_id, bin_dir=None, nodes=None):
        self.params_file = Path(params_file)
        self.out = Path(out)
        self.domain_id = int(domain_id)
        self.bin_dir = Path(bin_dir) if bin_dir else Path(sys.executable).parent
        self.nodes = dict(NODES if nodes is None else nodes)
        self.procs = {}
        self.logs = {}
        self.starts = {}
        self.deaths = {}          # name -> return code of a death we did not ask for
        self.stopping = set()
        self.finished = set()
        (self.out / 'logs').mkdir(parents=True, exist_ok=True)
        (self.out / 'ros_log').mkdir(parents=True, exist_ok=True)
        for name in self.nodes:       # a new run starts new logs (a restart appends)
            (self.out / 'logs' / f'{name}.log').write_text('')

    def env(self):
        """Return the environment of the children (LOCALHOST discovery, own domain, log dir)."""
        env = dict(os.environ)
        env['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
        env['ROS_DOMAIN_ID'] = str(self.domain_id)
        env['ROS_LOG_DIR'] = str(self.out / 'ros_log')
        env['PYTHONUNBUFFERED'] = '1'
        env.pop('ROS_LOCALHOST_ONLY', None)
        return env

    def command(self, name):
        """Return the command line of node ``name``."""
        exe = self.bin_dir / self.nodes[name]
        return [str(exe), '--ros-args', '--params-file', str(self.params_file)]

    def start(self, name):
        """Start (or restart) node ``name``; its output goes to ``logs/NAME.log``."""
        if name in self.procs and self.procs[name].poll() is None:
            raise RuntimeError(f'{name} is already running')
        exe = self.bin_dir / self.nodes[name]
        if not exe.exists():
            raise SuiteError(f'console script {exe} not found: run launch_scripts/setup_venv.sh')
        log = open(self.out / 'logs' / f'{name}.log', 'a')
        log.write(f'--- start {time.strftime("%H:%M:%S")}: {" ".join(self.command(name))}\n')
        log.flush()
        # own session: a Ctrl-C on the terminal reaches the launcher only; it forwards SIGINT
        # to each child itself, in the shutdown order
        self.procs[name] = subprocess.Popen(self.command(name), env=self.env(), stdout=log,
                                            stderr=subprocess.STDOUT, start_new_session=True)
        self.logs[name] = log
        self.starts[name] = time.monotonic()
        self.stopping.discard(name)
        self.deaths.pop(name, None)
        return self.procs[name]

    def start_all(self):
        """Start every node, in order."""
        for name in self.nodes:
            self.start(name)

    def pid(self, name):
        """Return the process id of node ``name``."""
        return self.procs[name].pid

    def alive(self, name):
        """Return True while node ``name`` runs."""
        return name in self.procs and self.procs[name].poll() is None

    def kill(self, name, sig=signal.SIGKILL, wait_s=10.0):
        """Send ``sig`` to node ``name`` (a deliberate kill: not counted as a death)."""
        self.stopping.add(name)
        proc = self.procs[name]
        if proc.poll() is None:
            proc.send_signal(sig)
            try:
                proc.wait(wait_s)
            except subprocess.TimeoutExpired:
                proc.kill()
                proc.wait(5.0)
        return proc.returncode

    def poll(self):
        """
        Record and return nodes that died without being asked to: {name: return code}.

        A node that ends by itself with status 0 (the rig at the end of a replay file) has
        finished, not died; it is listed in :attr:`finished`.
        """
        for name, proc in self.procs.items():
            rc = proc.poll()
            if rc is None or name in self.stopping or name in self.deaths:
                continue
            if rc == 0:
                self.finished.add(name)
                self.stopping.add(name)
            else:
                self.deaths[name] = rc
        return dict(self.deaths)

    def stop(self, order=(QC, CTRL, RIG, IDENT), drain_s=1.0, timeout_s=10.0, drained=None,
             stall_s=3.0, guard_s=60.0):
        """
        Stop every node with SIGINT (then SIGTERM, SIGKILL if it hangs).

        Order: the quarter car first (so the end of the stream does not read as stale parameters
        and a fail-safe), then the rig; the identifier gets ``drain_s`` to take the rest of the
        stream before it is stopped, or, with ``drained`` (a callable returning ``(done,
        progress)``), until ``done`` - as long as ``progress`` (the identifier's sample count)
        keeps moving: a slow identifier on a loaded machine still gets every sample, a stuck one
        holds the stop for ``stall_s`` at most (and everything for ``guard_s``).

        Returns
        -------
        dict
            name -> return code; codes outside ``CLEAN_EXIT`` mean an unclean shutdown.

        """
        self.poll()
        codes = {}
        for k, name in enumerate(order):
            if name not in self.procs:
                continue
            self.stopping.add(name)
            proc = self.procs[name]
            if proc.poll() is None:
                proc.send_signal(signal.SIGINT)
                if name == RIG and drain_s > 0:
                    time.sleep(drain_s)
                    if drained is not None:
                        wait_while_progressing(drained, stall_s, guard_s)
        for name in order:
            if name not in self.procs:
                continue
            proc = self.procs[name]
            for sig, wait in ((None, timeout_s), (signal.SIGTERM, 3.0), (signal.SIGKILL, 3.0)):
                if sig is not None and proc.poll() is None:
                    proc.send_signal(sig)
                try:
                    proc.wait(wait)
                    break
                except subprocess.TimeoutExpired:
                    continue
            codes[name] = proc.returncode if proc.returncode is not None else -signal.SIGKILL
            self.logs[name].close()
        return codes

    def log_tail(self, name, n=15):
        """Return the last ``n`` lines of a node's log."""
        try:
            lines = (self.out / 'logs' / f'{name}.log').read_text(errors='replace').splitlines()
        except OSError:
            return ''
        return '\n'.join(lines[-n:])


# ---------------------------------------------------------------------------------- recording
class Recording:
    """
    What the launcher's recorder node collects, streamed to ``out`` as it comes (flat memory).

    - every measurement -> column log ``out/measurement`` (t, x, v, f, i, recv_epoch_s;
      ``mr_damper_model.columnlog``), written in chunks;
    - every parameter message -> ``out/parameters.jsonl`` (``[wall_s, dict]`` per line);
    - in memory only bounded state: counters, the latest status of each node, the truths, the
      latest ride metrics and parameter message.
    """

    MEAS_COLUMNS = ('t', 'x', 'v', 'f', 'i', 'recv_epoch_s')

    def __init__(self, out):
        from mr_damper_model.columnlog import ColumnWriter, JsonLines
        self.lock = threading.Lock()
        self.t0 = time.monotonic()
        self.meas = ColumnWriter(Path(out) / 'measurement', self.MEAS_COLUMNS, chunk_rows=4096)
        self.params = JsonLines(Path(out) / 'parameters.jsonl')
        self.n_valid = 0
        self.last_params = None
        self.meas_gaps = 0        # samples missing between consecutive stamps
        self.meas_out_of_order = 0
        self.truth = None
        self.truth_spencer = None
        self.status = {}          # topic key -> latest dict
        self.status_count = {}    # topic key -> messages
        self.metrics = None
        self.dt_meas = None

    def wall(self):
        """Return seconds since the recording started."""
        return time.monotonic() - self.t0

    def add_params(self, d):
        """Stream one decoded parameter message (with its receipt time)."""
        with self.lock:
            self.params.append([self.wall(), d])
            self.last_params = d
            self.n_valid += d.get('valid') == 1.0

    def close(self):
        """Write what is buffered and close the files."""
        with self.lock:
            self.meas.close()
            self.params.close()

    def to_dict(self):
        """Return a JSON-ready dict (streams excluded) for ``recording.json``."""
        with self.lock:
            return {'truth': self.truth, 'truth_spencer': self.truth_spencer,
                    'status': self.status, 'status_messages': self.status_count,
                    'ride_metrics': self.metrics,
                    'parameter_messages': self.params.count,
                    'measurement_gaps': self.meas_gaps,
                    'measurement_out_of_order': self.meas_out_of_order,
                    'measurements_received': len(self.meas)}


def start_recorder(rec, topics):
    """
    Create the recorder node in this process and spin it in a thread.

    Returns
    -------
    callable
        Stops the recorder (destroys the node, shuts rclpy down, joins the thread).

    """
    import rclpy
    from rclpy.executors import ExternalShutdownException
    from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
    from sensor_msgs.msg import JointState
    from mr_damper_interfaces.msg import DamperModel, KwokParameters
    from std_msgs.msg import String

    from mr_damper_model import messages as mm

    ctx = rclpy.context.Context()
    rclpy.init(context=ctx, signal_handler_options=rclpy.signals.SignalHandlerOptions.NO)
    node = rclpy.create_node('suite_recorder', context=ctx)
    # deeper than the nodes' 1000: this process also runs the launcher and may lag in bursts
    reliable = QoSProfile(depth=10000, reliability=ReliabilityPolicy.RELIABLE)
    latched = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE,
                         durability=DurabilityPolicy.TRANSIENT_LOCAL)
    status_qos = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE)
    last = {'t': None}

    def on_meas(msg):
        try:
            sample = mm.measurement_from_msg(msg)
        except ValueError:
            return
        with rec.lock:
            t = sample[0]
            if last['t'] is not None:
                step = t - last['t']
                if step <= 0:
                    rec.meas_out_of_order += 1
                    return
                if rec.dt_meas is None or len(rec.meas) < 20:
                    rec.dt_meas = step if rec.dt_meas is None else min(rec.dt_meas, step)
                elif step > 1.5 * rec.dt_meas:
                    rec.meas_gaps += int(round(step / rec.dt_meas)) - 1
            last['t'] = t
            if not rec.meas.closed:
                rec.meas.append(sample + (time.time(),))

    def on_params(msg):
        try:
            d = mm.kwok_parameters_flat(msg)
        except ValueError:
            return
        d['recv_epoch_s'] = time.time()
        rec.add_params(d)

    def on_truth(msg):
        try:
            rec.truth = mm.kwok_parameters_flat(msg)
        except ValueError:
            pass

    def on_truth_spencer(msg):
        try:
            rec.truth_spencer = mm.damper_model_from_msg(msg)['parameters']
        except ValueError:
            pass

    def on_status(key):
        def cb(msg):
            try:
                d = json.loads(msg.data)
            except ValueError:
                return
            with rec.lock:
                rec.status[key] = d
                rec.status_count[key] = rec.status_count.get(key, 0) + 1
        return cb

    def on_metrics(msg):
        try:
            rec.metrics = json.loads(msg.data)
        except ValueError:
            pass

    subs = [
        node.create_subscription(JointState, topics['measurement'], on_meas, reliable),
        node.create_subscription(KwokParameters, topics['parameters'], on_params, latched),
        node.create_subscription(KwokParameters, topics['truth'], on_truth, latched),
        node.create_subscription(DamperModel, topics['truth_spencer'], on_truth_spencer,
                                 latched),
        node.create_subscription(String, topics['ride_metrics'], on_metrics, status_qos),
    ]
    for key in ('rig', 'identifier', 'quarter_car'):
        subs.append(node.create_subscription(String, topics[f'{key}_status'], on_status(key),
                                             status_qos))
    try:
        from rclpy.experimental import EventsExecutor
        executor = EventsExecutor(context=ctx)
    except (ImportError, TypeError):
        executor = rclpy.executors.SingleThreadedExecutor(context=ctx)
    executor.add_node(node)

    running = threading.Event()
    running.set()

    def spin():
        # spin_once in a loop: EventsExecutor.shutdown() from another thread hangs while it
        # spins (rclpy 9.1), so the thread stops itself between two spin_once calls
        try:
            while running.is_set():
                executor.spin_once(timeout_sec=0.1)
        except (ExternalShutdownException, KeyboardInterrupt):
            pass
        except Exception as exc:  # noqa: B902 - report and stop recording, never kill the run
            print(f'run_suite: recorder stopped: {exc}', file=sys.stderr)

    thread = threading.Thread(target=spin, name='suite_recorder', daemon=True)
    thread.start()

    def stop():
        running.clear()
        thread.join(5.0)
        executor.remove_node(node)
        node.destroy_node()
        rclpy.try_shutdown(context=ctx)

    return stop


def identifier_drained(rec):
    """
    Return ``(done, progress)``: does the identifier's status count every sample seen so far.

    ``progress`` is the identifier's ``samples_received`` (None before its first status).
    """
    with rec.lock:
        ident = rec.status.get('identifier') or {}
        seen = len(rec.meas) + rec.meas_gaps
    got = ident.get('samples_received')
    ok = isinstance(got, (int, float))
    return ok and got >= seen, got if ok else None


def wait_while_progressing(check, stall_s, guard_s, poll_s=0.1):
    """
    Wait until ``check()[0]``, while ``check()[1]`` keeps changing; return ``check()[0]``.

    Gives up when the progress value has not changed for ``stall_s`` or after ``guard_s`` in
    all (wall seconds: hang guards, not a time budget).
    """
    start = last_move = time.monotonic()
    done, last = check()
    while not done:
        now = time.monotonic()
        if now - last_move > stall_s or now - start > guard_s:
            return False
        time.sleep(poll_s)
        done, value = check()
        if value != last:
            last, last_move = value, time.monotonic()
    return True


def save_recording(rec, out):
    """Close the streamed files and write ``recording.json`` into ``out``; return its path."""
    from mr_damper_model.columnlog import finite_or_none
    rec.close()
    rpath = Path(out) / 'recording.json'
    rpath.write_text(json.dumps(finite_or_none(rec.to_dict())))
    return rpath


class ProcessStats:
    """
    CPU and memory of the node processes (psutil), sampled about once a second.

    Every sample is streamed to the column log ``out/process_samples`` (``t_s`` since the
    start, ``process`` index into the header's ``processes``, ``cpu_percent``, ``rss_mb``): the
    soak benchmark fits its memory slopes from it. In memory: running sums, peaks and a CPU
    histogram (0.5 % bins) per process, so the summary is bounded for runs of any length.
    """

    CPU_BIN = 0.5       # [%]

    def __init__(self, suite, out):
        import psutil
        from mr_damper_model.columnlog import ColumnWriter
        self.psutil = psutil
        self.suite = suite
        self.handles = {}
        self.stats = {}
        self.names = list(NODES) + ['launcher_recorder']
        self.t0 = time.monotonic()
        self.log = ColumnWriter(Path(out) / 'process_samples',
                                ('t_s', 'process', 'cpu_percent', 'rss_mb'), chunk_rows=256,
                                meta={'processes': self.names})

    def sample(self):
        """Take one sample of every running node (and of this launcher)."""
        procs = {name: self.suite.procs[name].pid for name in self.suite.procs
                 if self.suite.alive(name)}
        procs['launcher_recorder'] = os.getpid()
        now = time.monotonic() - self.t0
        for name, pid in procs.items():
            try:
                h = self.handles.get(name)
                if h is None or h.pid != pid:
                    h = self.handles[name] = self.psutil.Process(pid)
                    h.cpu_percent(None)           # first call primes the counter
                    continue
                cpu = h.cpu_percent(None)
                rss = h.memory_info().rss / 2 ** 20
            except self.psutil.Error:
                continue
            if name not in self.names:
                self.names.append(name)
            self.log.append((now, self.names.index(name), cpu, rss))
            st = self.stats.setdefault(name, {'n': 0, 'cpu_sum': 0.0, 'rss_peak': 0.0,
                                              'hist': {}})
            st['n'] += 1
            st['cpu_sum'] += cpu
            st['rss_peak'] = max(st['rss_peak'], rss)
            b = int(cpu // self.CPU_BIN)
            st['hist'][b] = st['hist'].get(b, 0) + 1

    def close(self):
        """Close the sample log."""
        self.log.close(processes=self.names)

    def summary(self):
        """Return {name: {cpu_mean_percent, cpu_p95_percent, rss_peak_mb, samples}}."""
        out = {}
        for name, st in self.stats.items():
            seen, p95 = 0, 0.0
            for b in sorted(st['hist']):
                seen += st['hist'][b]
                if seen >= 0.95 * st['n']:
                    p95 = (b + 1) * self.CPU_BIN      # upper edge of the bin
                    break
            out[name] = {'cpu_mean_percent': st['cpu_sum'] / st['n'], 'cpu_p95_percent': p95,
                         'rss_peak_mb': st['rss_peak'], 'samples': st['n']}
        nodes = [v['cpu_mean_percent'] for k, v in out.items() if k in self.suite.nodes]
        out['nodes_total_cpu_cores'] = sum(nodes) / 100.0
        return out


# ---------------------------------------------------------------------------------- main
def progress_line(rec, elapsed):
    """Return one progress line from the latest statuses."""
    with rec.lock:
        n_meas = len(rec.meas)
        params = rec.last_params
        n_params = rec.params.count
        n_valid = rec.n_valid
        qc = rec.status.get('quarter_car', {})
        metrics = rec.metrics or {}
    ident = f'identifier {n_params} updates ({n_valid} valid)'
    if params is not None:
        ident += f', nrmse {params.get("nrmse_percent", float("nan")):.1f} %'
    car = 'quarter car: no status yet'
    if qc:
        car = (f'quarter car {qc.get("mode", "?")}'
               f'{" (" + str(qc.get("reason")) + ")" if qc.get("mode") == "failsafe" else ""}'
               f', t_sim {qc.get("t_sim", float("nan")):.1f} s'
               f', fail-safe {qc.get("failsafe_s", float("nan")):.1f} s'
               f', i {qc.get("current_a", float("nan")):.2f} A')
        wk = metrics.get('rms_body_accel_wk')
        if wk is not None:
            car += f', Wk {wk:.3f} m/s^2'
    return f'[{elapsed:6.1f} s] rig {n_meas} samples | {ident} | {car}'


def hil_report_config(cfg):
    """Config for the report of a HIL run: the passive reference drives the rig's damper."""
    import copy
    report = copy.deepcopy(cfg)
    set_param(report, QC, 'plant', node_params(cfg, RIG).get('plant', 'spencer'))
    set_param(report, QC, 'truth_file', node_params(cfg, RIG).get('truth_file', ''))
    return report


def add_hil_summary(summary, rec, cfg, out):
    """Add tracking error and identification quality vs the cam rig (``--config hil``)."""
    from mr_damper_model.columnlog import finite_or_none
    from mr_damper_rig.car_in_the_loop import format_hil_summary, hil_summary
    with rec.lock:
        status = dict(rec.status)
    rig = node_params(cfg, RIG)
    summary['hil'] = hil_summary(status.get('quarter_car'), status.get('rig'),
                                 (summary.get('identification') or {}).get('parameters'),
                                 plant=rig.get('plant', 'spencer'),
                                 truth_file=rig.get('truth_file', ''))
    (out / 'summary.json').write_text(json.dumps(finite_or_none(summary), indent=2,
                                                 allow_nan=False))
    print(format_hil_summary(summary['hil']), flush=True)


def parse_args(argv):
    """Parse the launcher's command line."""
    p = argparse.ArgumentParser(
        prog='run_suite.py', description=__doc__.split('\n\n')[0].strip(),
        formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument('--duration', type=float, default=30.0,
                   help='run time [s, wall clock] (default 30; 0 = until Ctrl-C)')
    p.add_argument('--out', default=str(REPO / 'runs' / 'suite'),
                   help='output folder (default runs/suite in the repository)')
    p.add_argument('--config', choices=('sim', 'replay', 'hil'), default='sim',
                   help='sim: virtual rig; replay: a CSV or bag replayed into the identifier; '
                        'hil: the rig follows the car (hardware in the loop, docs/hil.md)')
    p.add_argument('--file', action='append',
                   help='replay input: a CSV (t,x,v,f,i) or rosbag2 folder; repeat for several '
                        'CSVs, concatenated (default: the Quiroz 10 mm 1 Hz set, 0..1 A)')
    p.add_argument('--params',
                   help='your own parameter YAML instead of config/suite_<config>.yaml')
    speed = p.add_mutually_exclusive_group()
    speed.add_argument('--real-time', dest='rate_factor', action='store_const', const=1.0,
                       help='rig and quarter car in real time (default of the YAML)')
    speed.add_argument('--faster', dest='rate_factor', action='store_const', const=2.0,
                       help='rig and quarter car at twice real time')
    speed.add_argument('--rate-factor', dest='rate_factor', type=float,
                       help='rig replay and quarter-car speed relative to real time')
    p.add_argument('--domain-id', type=int,
                   help='ROS_DOMAIN_ID of this run (default: random in 20..220)')
    p.add_argument('--set', action='append', metavar='NODE.PARAM=VALUE',
                   help='override one parameter (NODE is mr_damper_rig, mr_damper_identifier, '
                        'quarter_car_node or /**), YAML-typed: 1.0 is a float, 1 an int')
    p.add_argument('--bin-dir', help='folder of the node console scripts (default: the venv)')
    p.add_argument('--progress-s', type=float, default=5.0, help='progress line period [s]')
    p.add_argument('--external-controller', action='store_true',
                   help='run the car\'s law in semi_active_controller_node (the car is the '
                        'plant only, controller:=external)')
    p.add_argument('--no-plots', action='store_true', help='summary.json only')
    p.add_argument('--quiet', action='store_true', help='no progress lines')
    args = p.parse_args(argv)
    if args.duration < 0:
        p.error('--duration must be >= 0')
    if args.domain_id is not None and not 0 <= args.domain_id <= 232:
        p.error('--domain-id must be in 0..232')
    if args.rate_factor is not None and not args.rate_factor > 0:
        p.error('--rate-factor must be > 0')
    return args


def topics_of(cfg):
    """Return the topic names the recorder listens to (defaults of the nodes)."""
    qc = node_params(cfg, QC)
    return {
        'measurement': '/mr_damper/measurement',
        'parameters': qc.get('params_topic', '/mr_damper/kwok_parameters'),
        'truth': '/mr_damper/true_parameters',
        'truth_spencer': '/mr_damper/true_spencer_parameters',
        'rig_status': '/mr_damper/rig_status',
        'identifier_status': '/mr_damper/identifier_status',
        'quarter_car_status': qc.get('status_topic', '/quarter_car/status'),
        'ride_metrics': qc.get('metrics_topic', '/quarter_car/ride_metrics'),
    }


def main(argv=None):
    """Run the suite; return the exit status."""
    args = parse_args(argv)
    out = Path(args.out).resolve()
    out.mkdir(parents=True, exist_ok=True)
    try:
        cfg = resolve_config(args, out)
    except SuiteError as exc:
        print(f'run_suite: {exc}', file=sys.stderr)
        return 2
    except ValueError as exc:         # DataError of a bad replay CSV
        print(f'run_suite: {exc}', file=sys.stderr)
        return 2
    params_file = out / 'suite_params.yaml'
    params_file.write_text(yaml.safe_dump(cfg, sort_keys=False))
    domain_id = args.domain_id if args.domain_id is not None else random.randint(20, 220)
    # the recorder node of this process must use the same discovery settings as the children
    os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
    os.environ['ROS_DOMAIN_ID'] = str(domain_id)
    os.environ.setdefault('ROS_LOG_DIR', str(out / 'ros_log'))
    suite = Suite(params_file, out, domain_id, args.bin_dir, suite_nodes(cfg))
    print(f'run_suite: config {args.config}, domain {domain_id}, '
          f'duration {args.duration:g} s, output {out}', flush=True)

    interrupted = threading.Event()

    def on_sigint(signum, frame):
        if interrupted.is_set():       # second Ctrl-C: no more patience
            for name in suite.nodes:
                if suite.alive(name):
                    suite.procs[name].kill()
        interrupted.set()

    old_int = signal.signal(signal.SIGINT, on_sigint)
    old_term = signal.signal(signal.SIGTERM, on_sigint)
    rec = Recording(out)
    stop_recorder = start_recorder(rec, topics_of(cfg))
    status = 0
    codes = {}
    try:
        try:
            suite.start_all()
        except SuiteError as exc:
            print(f'run_suite: {exc}', file=sys.stderr)
            return 2
        t_start = time.monotonic()
        next_progress = args.progress_s
        stats = ProcessStats(suite, out)
        next_stats = 0.0
        while not interrupted.is_set():
            elapsed = time.monotonic() - t_start
            if args.duration and elapsed >= args.duration:
                break
            dead = suite.poll()
            if dead:
                for name, rc in dead.items():
                    print(f'run_suite: {name} died (exit {rc}); last lines of its log:\n'
                          f'{suite.log_tail(name)}', file=sys.stderr)
                status = 1
                break
            if elapsed >= next_stats:
                stats.sample()
                next_stats += 1.0
            if not args.quiet and elapsed >= next_progress:
                print(progress_line(rec, elapsed), flush=True)
                next_progress += args.progress_s
            interrupted.wait(0.1)
        if interrupted.is_set():
            print('run_suite: interrupted, stopping the nodes', flush=True)
        elapsed = time.monotonic() - t_start
    finally:
        codes = suite.stop(drained=lambda: identifier_drained(rec))
        time.sleep(0.2)
        stop_recorder()
        signal.signal(signal.SIGINT, old_int)
        signal.signal(signal.SIGTERM, old_term)
    unclean = {n: rc for n, rc in codes.items() if rc not in CLEAN_EXIT}
    if unclean:
        for name, rc in unclean.items():
            print(f'run_suite: {name} exited with {rc}; last lines of its log:\n'
                  f'{suite.log_tail(name)}', file=sys.stderr)
        status = 1
    save_recording(rec, out)
    try:
        stats.close()
        (out / 'process_stats.json').write_text(json.dumps(stats.summary(), indent=2))
    except NameError:                   # the nodes never started
        pass
    try:
        from quarter_car_sim import suite_report
        hil = node_params(cfg, QC).get('plant') == 'rig'
        summary = suite_report.make_report(out, duration_s=elapsed,
                                           config=hil_report_config(cfg) if hil else cfg,
                                           plots=not args.no_plots)
        print(suite_report.format_summary(summary), flush=True)
        if hil:
            add_hil_summary(summary, rec, cfg, out)
    except Exception as exc:  # noqa: B902 - the run itself succeeded; say why there is no summary
        print(f'run_suite: no summary: {type(exc).__name__}: {exc}', file=sys.stderr)
        status = status or 1
    print(f'run_suite: outputs in {out} (summary.json, plots *.png, logs/)', flush=True)
    return status


if __name__ == '__main__':
    sys.exit(main())
