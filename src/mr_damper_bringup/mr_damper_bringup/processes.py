"""
The node processes of one suite run: start, watch, stop in order, CPU and memory samples.

:class:`Suite` starts the console scripts (``ros2 run`` executables) of the venv with ONE
parameter YAML, on loopback-only discovery and a domain ID of its own, forwards the stop in the
shutdown order and tells a death from a finished node; :class:`ProcessStats` samples their CPU
and memory (psutil). Neither imports ROS.
"""
import os
from pathlib import Path
import signal
import subprocess
import sys
import time

from .config import (CAN_BRIDGE, CAN_DRIVER, CTRL, EST, IDENT, NODES, QC, RECORDER, RIG,
                     SuiteError)

#: Exit statuses of a clean stop: every node handles SIGINT and SIGTERM (node_utils.run_node)
#: and exits 0, so death by a signal or a traceback on the way out is an unclean shutdown.
CLEAN_EXIT = (0,)


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
        :func:`~mr_damper_bringup.config.suite_nodes`).
    args : dict, optional
        Node name -> its command-line arguments, instead of ``--ros-args --params-file
        PARAMS_FILE`` (the recorder).

    """

    def __init__(self, params_file, out, domain_id, bin_dir=None, nodes=None, args=None):
        self.params_file = Path(params_file)
        self.out = Path(out)
        self.domain_id = int(domain_id)
        self.bin_dir = Path(bin_dir) if bin_dir else Path(sys.executable).parent
        self.nodes = dict(NODES if nodes is None else nodes)
        self.args = dict(args or {})
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
        if name in self.args:
            return [str(exe)] + [str(a) for a in self.args[name]]
        return [str(exe), '--ros-args', '--params-file', str(self.params_file)]

    def start(self, name):
        """Start (or restart) node ``name``; its output goes to ``logs/NAME.log``."""
        if name in self.procs and self.procs[name].poll() is None:
            raise RuntimeError(f'{name} is already running')
        exe = self.bin_dir / self.nodes[name]
        if not exe.exists():
            raise SuiteError(f'console script {exe} not found: run launch_scripts/setup_venv.sh')
        if name in self.logs:
            self.logs[name].close()         # the log of the previous (dead) process
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
        self.write_pids()
        return self.procs[name]

    def write_pids(self):
        """Write ``out/pids.json``, ``{node: process id}`` of the latest start of each node."""
        import json
        path = self.out / 'pids.json'
        tmp = path.with_name(path.name + '.tmp')
        tmp.write_text(json.dumps({name: proc.pid for name, proc in self.procs.items()}))
        os.replace(tmp, path)

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

    def stop(self, order=(QC, CTRL, EST, RIG, IDENT, CAN_BRIDGE), last=(RECORDER,), drain_s=1.0,
             timeout_s=10.0, drained=None, stall_s=3.0, guard_s=60.0, then=(CAN_DRIVER,)):
        """
        Stop every node with SIGINT (then SIGTERM, SIGKILL if it hangs).

        Order: the quarter car first (so the end of the stream does not read as stale parameters
        and a fail-safe), then the rig; the identifier gets ``drain_s`` to take the rest of the
        stream before it is stopped, or, with ``drained`` (a callable returning ``(done,
        progress)``), until ``done`` - as long as ``progress`` (the identifier's sample count)
        keeps moving: a slow identifier on a loaded machine still gets every sample, a stuck one
        holds the stop for ``stall_s`` at most (and everything for ``guard_s``). The nodes in
        ``last`` (the recorder) are stopped only once all the others have exited, so they take
        every final message; the nodes in ``then`` (the simulated CAN driver of a CAN run) are
        stopped after ``order`` and before ``last``, so the driver hears every frame the bridge
        sent and reports it before the recorder stops (the reverse of the start order). With
        car corners (node names ``<corner>.<node>``), ``order`` lists
        every corner's nodes and the drain comes after the last rig.

        Returns
        -------
        dict
            name -> return code; codes outside ``CLEAN_EXIT`` mean an unclean shutdown.

        """
        self.poll()
        codes = {}
        for group in (order, then, last):
            for name in group:
                if name not in self.procs:
                    continue
                self.stopping.add(name)
                proc = self.procs[name]
                if proc.poll() is None:
                    proc.send_signal(signal.SIGINT)
                    if (name == RIG or name.endswith('.' + RIG)) and drain_s > 0 \
                            and not any(n == RIG or n.endswith('.' + RIG)
                                        for n in group[group.index(name) + 1:]):
                        time.sleep(drain_s)
                        if drained is not None:
                            wait_while_progressing(drained, stall_s, guard_s)
            for name in group:
                if name in self.procs:
                    codes[name] = self._wait(name, timeout_s)
        return codes

    def _wait(self, name, timeout_s):
        """Wait for node ``name`` to exit (SIGTERM, SIGKILL if it hangs); return its code."""
        proc = self.procs[name]
        for sig, wait in ((None, timeout_s), (signal.SIGTERM, 3.0), (signal.SIGKILL, 3.0)):
            if sig is not None and proc.poll() is None:
                proc.send_signal(sig)
            try:
                proc.wait(wait)
                break
            except subprocess.TimeoutExpired:
                continue
        self.logs[name].close()
        return proc.returncode if proc.returncode is not None else -signal.SIGKILL

    def log_tail(self, name, n=15):
        """Return the last ``n`` lines of a node's log."""
        try:
            lines = (self.out / 'logs' / f'{name}.log').read_text(errors='replace').splitlines()
        except OSError:
            return ''
        return '\n'.join(lines[-n:])


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
        from mr_damper_model.io.columnlog import ColumnWriter
        self.psutil = psutil
        self.suite = suite
        self.handles = {}
        self.stats = {}
        self.names = list(NODES) + [RECORDER, 'launcher']
        self.t0 = time.monotonic()
        self.log = ColumnWriter(Path(out) / 'process_samples',
                                ('t_s', 'process', 'cpu_percent', 'rss_mb'), chunk_rows=256,
                                meta={'processes': self.names})

    def sample(self):
        """Take one sample of every running node (and of this launcher)."""
        procs = {name: self.suite.procs[name].pid for name in self.suite.procs
                 if self.suite.alive(name)}
        procs['launcher'] = os.getpid()
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
        # the suite's nodes; the recorder (a monitor, not part of the loop) is listed apart
        nodes = [v['cpu_mean_percent'] for k, v in out.items()
                 if k in self.suite.nodes and k != RECORDER]
        out['nodes_total_cpu_cores'] = sum(nodes) / 100.0
        return out
