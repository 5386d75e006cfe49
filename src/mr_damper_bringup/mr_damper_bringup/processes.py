"""
The node processes of one suite run: start, watch, stop in order, CPU and memory samples.

:class:`Suite` starts the console scripts (``ros2 run`` executables) of the venv with ONE
parameter YAML, on loopback-only discovery and a domain ID of its own, forwards the stop in the
shutdown order and tells a death from a finished node; :class:`ProcessStats` samples their CPU
and memory (psutil). Neither imports ROS.

The nodes die with the process that started them: each gets SIGTERM from the kernel when it
goes (:func:`die_with_parent`, ``PR_SET_PDEATHSIG``), and a small watcher process
(:mod:`mr_damper_bringup.reaper`) SIGKILLs what is left after a grace (a node frozen in the
middleware ignores SIGTERM). :class:`DomainLock` keeps a second suite off a ROS domain that a
suite on this machine (this network namespace) already uses.
"""
import errno
import os
from pathlib import Path
import signal
import subprocess
import sys
import tempfile
import time

from .config import (CAN_BRIDGE, CAN_DRIVER, CTRL, EST, IDENT, NODES, QC, RECORDER, RIG,
                     SuiteError)

#: Exit statuses of a clean stop: every node handles SIGINT and SIGTERM (node_utils.run_node)
#: and exits 0, so death by a signal or a traceback on the way out is an unclean shutdown.
CLEAN_EXIT = (0,)
#: prctl(2) option: the signal a process gets when the thread that created it exits
PR_SET_PDEATHSIG = 1
#: Seconds the nodes of a launcher that died get to end on SIGTERM before the reaper's SIGKILL
#: (as long as the launcher's own stop gives a node after SIGINT).
REAPER_GRACE_S = 10.0


def is_rig(name):
    """Return True if process ``name`` is a rig: :data:`RIG` or a corner's ``<corner>.RIG``."""
    return name == RIG or name.endswith('.' + RIG)


def die_with_parent(sig=signal.SIGTERM):
    """
    Return a ``preexec_fn`` that makes a child process get ``sig`` when this process dies.

    ``prctl(PR_SET_PDEATHSIG, sig)`` in the child between fork and exec (kept across exec).
    The parent may die before the call: the child then finds another parent (``getppid``) and
    kills itself at once. The kernel sends the signal when the *thread* that started the child
    ends: start nodes from a thread that lives as long as the process (the launcher's main
    thread). Returns None where prctl is not available (not Linux).

    Parameters
    ----------
    sig : int
        The signal (SIGTERM: the suite's nodes stop cleanly and exit 0 on it).

    """
    try:
        import ctypes
        prctl = ctypes.CDLL(None, use_errno=True).prctl
    except (OSError, AttributeError):
        return None
    prctl.argtypes = [ctypes.c_int, ctypes.c_ulong, ctypes.c_ulong, ctypes.c_ulong,
                      ctypes.c_ulong]
    prctl.restype = ctypes.c_int
    parent = os.getpid()

    def child():
        # between fork and exec: no locks, no imports, nothing that allocates much
        prctl(PR_SET_PDEATHSIG, int(sig), 0, 0, 0)
        if os.getppid() != parent:
            os.kill(os.getpid(), signal.SIGKILL)    # the parent is already gone
    return child


class Reaper:
    """
    The watcher that ends the nodes when their starter is gone (:mod:`mr_damper_bringup.reaper`).

    Parameters
    ----------
    log : path
        Its stderr (one line when it had to stop nodes).
    grace_s : float
        Time [s] the nodes get to end on SIGTERM before SIGKILL.
    pass_fds : tuple of int
        File descriptors it keeps open (the :class:`DomainLock`, held until it exits).

    """

    def __init__(self, log, grace_s=REAPER_GRACE_S, pass_fds=()):
        self.log = open(log, 'a')
        self.proc = subprocess.Popen(
            [sys.executable, '-m', 'mr_damper_bringup.reaper', f'{float(grace_s):g}'],
            stdin=subprocess.PIPE, stdout=self.log, stderr=self.log, start_new_session=True,
            pass_fds=tuple(pass_fds))

    def watch(self, pid):
        """Tell the reaper of one more node process (it leads its own process group)."""
        try:
            self.proc.stdin.write(f'{int(pid)}\n'.encode())
            self.proc.stdin.flush()
        except (BrokenPipeError, ValueError):
            pass            # the reaper is gone: the nodes still have their PDEATHSIG

    def close(self, timeout_s=10.0):
        """End the reaper (EOF: it signals the nodes still running, none after a clean stop)."""
        try:
            self.proc.stdin.close()
        except BrokenPipeError:
            pass
        try:
            self.proc.wait(timeout_s)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            self.proc.wait()
        self.log.close()


def network_namespace():
    """Return an id of this process's network namespace (DDS LOCALHOST discovery's reach)."""
    try:
        return ''.join(c for c in os.readlink('/proc/self/ns/net') if c.isdigit()) or 'host'
    except OSError:
        return 'host'


class DomainLock:
    """
    This machine's lock of one ROS domain ID: one suite per domain and network namespace.

    A ``flock`` on ``<tmp>/mr-damper-suite.net<NS>.domain<ID>.lock``; the kernel drops it when
    the last process holding the open file ends, whatever the way. The suite's nodes and the
    reaper inherit it, so it is held until every process of the suite has gone: a second
    launcher on the same domain is refused while any of them runs (two controllers would
    command one damper). Loopback discovery (``ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST``)
    reaches exactly the processes of this network namespace, hence the lock's scope.

    Parameters
    ----------
    domain_id : int
        ROS_DOMAIN_ID (0..232).
    folder : path, optional
        Where the lock files are (default: the temporary folder).

    Attributes
    ----------
    fd : int or None
        The open lock file (None until :meth:`acquire` succeeded).

    """

    def __init__(self, domain_id, folder=None):
        self.domain_id = int(domain_id)
        folder = Path(folder) if folder is not None else Path(tempfile.gettempdir())
        self.path = folder / (f'mr-damper-suite.net{network_namespace()}'
                              f'.domain{self.domain_id}.lock')
        self.fd = None

    def acquire(self):
        """Take the lock; return True, or False when another suite holds it."""
        import fcntl
        try:
            fd = os.open(self.path, os.O_RDWR | os.O_CREAT, 0o644)
        except PermissionError:             # another user's lock file: lock it read-only
            fd = os.open(self.path, os.O_RDONLY)
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError as exc:
            os.close(fd)
            if exc.errno in (errno.EWOULDBLOCK, errno.EAGAIN, errno.EACCES):
                return False
            raise
        try:
            os.ftruncate(fd, 0)
            os.write(fd, f'{os.getpid()}\n'.encode())
        except OSError:
            pass                            # read-only: the holder's pid is not written
        os.set_inheritable(fd, False)
        self.fd = fd
        return True

    def holder(self):
        """Return the process id written by the suite that holds the lock ('?' if unknown)."""
        try:
            return self.path.read_text().strip() or '?'
        except OSError:
            return '?'

    def release(self):
        """Close this process's copy of the lock (children started with it keep theirs)."""
        if self.fd is not None:
            os.close(self.fd)
            self.fd = None


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
    keep_fds : tuple of int, optional
        File descriptors every node and the reaper keep open (the launcher's
        :class:`DomainLock`).
    dds : dict, optional
        The DDS variables of the nodes (:func:`mr_damper_bringup.network.dds_environment`;
        default: its default, the loopback profile).

    """

    def __init__(self, params_file, out, domain_id, bin_dir=None, nodes=None, args=None,
                 keep_fds=(), dds=None):
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
        self.keep_fds = tuple(keep_fds)
        if dds is None:
            from .network import dds_environment
            dds = dds_environment()
        self.dds = dict(dds)
        self.reaper = None
        (self.out / 'logs').mkdir(parents=True, exist_ok=True)
        (self.out / 'ros_log').mkdir(parents=True, exist_ok=True)
        for name in self.nodes:       # a new run starts new logs (a restart appends)
            (self.out / 'logs' / f'{name}.log').write_text('')

    def env(self):
        """Return the environment of the children (DDS on loopback, own domain, log dir)."""
        from .network import apply
        env = apply(self.dds, dict(os.environ))
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
        if self.reaper is None:
            self.reaper = Reaper(self.out / 'logs' / 'reaper.log', pass_fds=self.keep_fds)
        # own session: a Ctrl-C on the terminal reaches the launcher only; it forwards SIGINT
        # to each child itself, in the shutdown order. SIGTERM when this process dies.
        self.procs[name] = subprocess.Popen(self.command(name), env=self.env(), stdout=log,
                                            stderr=subprocess.STDOUT, start_new_session=True,
                                            preexec_fn=die_with_parent(),
                                            pass_fds=self.keep_fds)
        self.reaper.watch(self.procs[name].pid)
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
        """
        Send ``sig`` to node ``name`` and its process group; wait for its end.

        A deliberate kill: not counted as a death (:meth:`poll`). Returns its return code.
        """
        self.stopping.add(name)
        proc = self.procs[name]
        if proc.poll() is None:
            try:
                os.killpg(proc.pid, sig)        # the node leads its own group (own session)
            except (ProcessLookupError, PermissionError):
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
        every corner's nodes and the drain comes after the last rig. The drain starts once every
        rig has exited: a rig on a loaded machine goes on publishing for seconds after its
        SIGINT, and an identifier stopped meanwhile would miss the end of the stream.

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
                    if is_rig(name) and drain_s > 0 \
                            and not any(is_rig(n) for n in group[group.index(name) + 1:]):
                        # the stream ends when its rigs have exited (a loaded rig publishes
                        # for seconds after its SIGINT: the drain must not start before)
                        for rig in group[:group.index(name) + 1]:
                            if is_rig(rig) and rig in self.procs:
                                codes[rig] = self._wait(rig, timeout_s)
                        time.sleep(drain_s)
                        if drained is not None:
                            wait_while_progressing(drained, stall_s, guard_s)
            for name in group:
                if name in self.procs and name not in codes:
                    codes[name] = self._wait(name, timeout_s)
        self.close()
        return codes

    def close(self):
        """End the reaper (after the stop: it finds nothing left to end)."""
        if self.reaper is not None:
            reaper, self.reaper = self.reaper, None
            reaper.close()

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

    #: ``{name: (time.monotonic(), CPU seconds, main thread's CPU seconds)}``: user + system
    #: CPU time of each running node's process, and of its main thread (the one whose executor
    #: publishes its status; None if it could not be read), at its latest sample (the
    #: launcher's hang watch reads it)
    cpu_seconds = None

    def __init__(self, suite, out):
        import psutil
        from mr_damper_common.recording.columnlog import ColumnWriter
        self.psutil = psutil
        self.suite = suite
        self.handles = {}
        self.stats = {}
        self.names = list(NODES) + [RECORDER, 'launcher']
        self.t0 = time.monotonic()
        self.cpu_seconds = {}
        self.log = ColumnWriter(Path(out) / 'process_samples',
                                ('t_s', 'process', 'cpu_percent', 'rss_mb'), chunk_rows=256,
                                meta={'processes': self.names})

    def sample(self):
        """Take one sample of every running node (and of this launcher)."""
        procs = {name: self.suite.procs[name].pid for name in self.suite.procs
                 if self.suite.alive(name)}
        procs['launcher'] = os.getpid()
        t = time.monotonic()
        now = t - self.t0
        self.cpu_seconds = {n: v for n, v in self.cpu_seconds.items() if n in procs}
        for name, pid in procs.items():
            try:
                h = self.handles.get(name)
                if h is None or h.pid != pid:
                    h = self.handles[name] = self.psutil.Process(pid)
                    h.cpu_percent(None)           # first call primes the counter
                    self.cpu_seconds[name] = self.cpu_times(h, t)
                    continue
                self.cpu_seconds[name] = self.cpu_times(h, t)
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

    def cpu_times(self, h, t):
        """Return ``(t, CPU seconds, main thread's CPU seconds or None)`` of process ``h``."""
        times = h.cpu_times()
        main = None
        try:
            for thread in h.threads():
                if thread.id == h.pid:
                    main = thread.user_time + thread.system_time
                    break
        except self.psutil.AccessDenied:
            pass
        return (t, times.user + times.system, main)

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
