"""
Running a node: its clock, the executor, the spin loop, a fast lane for a hot input, ``main``.

:func:`run_node` is every node's ``main`` (SIGINT / SIGTERM only set the stop flag of
:mod:`mr_damper_common.stop_flag`, then the node finishes and exits 0); :func:`spin_node` and
:func:`spin` the loop it runs; :class:`FastLane` a second minimal node in its own thread.
Imports rclpy.
"""
import faulthandler
import os
import sys
import threading

import rclpy
from rclpy.exceptions import InvalidHandle, ParameterException
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.signals import SignalHandlerOptions

from mr_damper_common.stop_flag import _STOP, install_stop_handlers

#: Seconds the middleware gets to tear a finished node down (``destroy_node``, then
#: ``rclpy.try_shutdown``) before the process exits without it: by then the node's outputs are
#: written (``finish`` ran). A full-car identifier under load once stayed for good in
#: ``destroy_node`` -> ``Publisher.destroy`` (Fast DDS deleting its writer) after it had
#: written its final parameters, until the launcher's SIGKILL (exit -9, a failed run).
TEARDOWN_GUARD_S = 5.0
#: Seconds after which faulthandler's watchdog ends a teardown stuck while holding the GIL.
TEARDOWN_WATCHDOG_S = 10.0


def node_time_s(node):
    """Return the node clock's now [s]: ROS time (``/clock`` under ``use_sim_time``)."""
    return node.get_clock().now().nanoseconds * 1e-9


def spin(executor, done=lambda: False, timeout_sec=0.1):
    """
    Spin ``executor`` until shutdown, a stop request (SIGINT / SIGTERM) or ``done()``.

    A ``spin_once`` loop: the kilted EventsExecutor's ``spin()`` stalls timers (checked here:
    one tick of a 5 ms timer per second), its ``spin_once`` runs them on time. An error from
    ``spin_once`` once shutdown has begun (e.g. ``RuntimeError: Unable to convert call
    argument`` of a message taken while the context went down) ends the loop quietly; before
    that it is raised.
    """
    while rclpy.ok() and not _STOP.is_set() and not done():
        try:
            executor.spin_once(timeout_sec=timeout_sec)
        except ExternalShutdownException:
            return
        except RuntimeError:
            if _STOP.is_set() or not rclpy.ok():
                return
            raise


#: Nice value of the libraries' threads under ``set_realtime_priority(..., native_threads=False)``
#: (the highest priority of normal scheduling).
NATIVE_NICE = -20


def _each_thread(fn):
    """Call ``fn(tid)`` for the id of every thread of this process now; an error propagates."""
    for tid in os.listdir('/proc/self/task'):
        fn(int(tid))


def set_realtime_priority(priority, logger, native_threads=True):
    """
    Put the threads of this process that exist now under SCHED_FIFO ``priority`` (0: no-op).

    Called after the node is created, so the executor (main) thread and the middleware's
    receive threads (created with the node) get it; threads started later (the fitting worker)
    reset themselves to SCHED_OTHER (see ``IdentifierNode._work``).

    ``native_threads=False`` puts only the interpreter's threads (``threading.enumerate()``:
    the executor's, a lane's, a bus reader's) under the priority; the libraries' own threads
    (the middleware's ``dds.*``, numba's and BLAS's workers) stay at normal scheduling with
    the highest nice value (:data:`NATIVE_NICE`); and ``SCHED_RESET_ON_FORK`` keeps threads
    made later from inheriting either unasked (a reader that wants the priority sets it
    itself: ``scheduling.fifo_on_first_call``). The libraries' threads are not written for
    SCHED_FIFO at one priority on one core: in a vehicle computer pinned to one core with
    every thread at SCHED_FIFO 20, Fast DDS's asynchronous writer thread (``dds.asyn``) once
    spun at the real-time limit (95 % of the core) while the threads it waited for, runnable
    at the same priority, never ran again (SCHED_FIFO has no time slices within a priority):
    the node froze in its configure (docs/faults.md). At normal scheduling they share the
    core by time slices; the nice value lets them run before the machine's other normal work
    when a real-time thread waits on one of them (a lock of the middleware's that a publish
    takes): at nice 0 that wait cost the vehicle computer 0.4-1 % of its cycles in the
    intervals without hypervisor steal (docs/vehicle.md).

    Needs CAP_SYS_NICE (root); otherwise a warning and nothing changes.
    """
    if priority <= 0:
        return False
    try:
        param = os.sched_param(int(priority))
        policy = os.SCHED_FIFO | (0 if native_threads else os.SCHED_RESET_ON_FORK)
        python = {t.native_id for t in threading.enumerate()}

        def put(tid):
            try:
                if native_threads or tid in python:
                    os.sched_setscheduler(tid, policy, param)
                else:
                    os.setpriority(os.PRIO_PROCESS, tid, NATIVE_NICE)
            except ProcessLookupError:
                pass                          # the thread ended meanwhile
        _each_thread(put)
        return True
    except (OSError, AttributeError) as exc:
        logger.warning(f'realtime_priority {priority} not applied: {exc}')
        return False


def parse_cpu_list(spec):
    """
    Return the CPU numbers of a Linux CPU list (``taskset -c`` syntax: ``'1'``, ``'0,2-3'``).

    ``''`` gives an empty set. Raises ValueError for anything else (a word, a reversed range,
    a negative number).
    """
    cpus = set()
    for part in filter(None, (x.strip() for x in str(spec).split(','))):
        lo, sep, hi = part.partition('-')
        if not lo.isdigit() or (sep and not hi.isdigit()):
            raise ValueError(f'not a CPU list: {spec!r}')
        first, last = int(lo), int(hi) if sep else int(lo)
        if last < first:
            raise ValueError(f'not a CPU list (reversed range {part!r}): {spec!r}')
        cpus.update(range(first, last + 1))
    return cpus


def set_cpu_affinity(spec, logger):
    """
    Pin every thread of this process that exists now to the CPUs of ``spec`` (``''``: no-op).

    ``spec`` is a CPU list (:func:`parse_cpu_list`); threads started later inherit the mask of
    the thread that starts them. As a real-time deployment keeps its control process on a
    core of its own (the suite's vehicle configuration: the simulated car on one core, the
    vehicle computer on the other). CPUs this process may not use are left out with a
    warning; with none left, nothing changes. Returns the set applied (empty: none).
    """
    try:
        wanted = parse_cpu_list(spec)
    except ValueError as exc:
        logger.warning(f'cpu_affinity not applied: {exc}')
        return set()
    if not wanted:
        return set()
    allowed = os.sched_getaffinity(0)
    cpus = wanted & allowed
    if cpus != wanted:
        logger.warning(f'cpu_affinity {spec!r}: CPUs {sorted(wanted - allowed)} not available '
                       f'(this process may use {sorted(allowed)})'
                       + ('' if cpus else '; nothing pinned'))
    if not cpus:
        return set()
    try:
        _each_thread(lambda tid: os.sched_setaffinity(tid, cpus))
    except OSError as exc:
        logger.warning(f'cpu_affinity {spec!r} not applied: {exc}')
        return set()
    return cpus


def make_executor(events=True, context=None):
    """Return the executor of the suite's nodes: EventsExecutor when available and ``events``."""
    if events:
        try:
            from rclpy.experimental import EventsExecutor
            return EventsExecutor(context=context)
        except ImportError:  # pragma: no cover - older rclpy
            pass
    return SingleThreadedExecutor(context=context)


class FastLane:
    """
    A minimal node of its own, spun in its own thread, for one hot input of a node.

    rclpy's SingleThreadedExecutor rebuilds its wait set from every entity of its nodes on each
    wake-up (subscriptions, timers, the six parameter services, QoS event handlers) in Python:
    for a node taking a 1 kHz stream that is most of its CPU (the HIL car: 80 % of its samples
    in ``wait_for_ready_callbacks``). A lane has only what is subscribed on it (no parameter
    services, no rosout), in the parent's namespace and context; the process's remappings
    apply to it as to the parent. Its callbacks run in the lane's thread (the parent's code
    must be thread-safe for them, as for any second thread).

    Parameters
    ----------
    parent : rclpy.node.Node
        The node the lane serves (its name, namespace and context).
    suffix : str
        The lane node is ``<parent name>_<suffix>``. Its thread exists once :meth:`start`
        returned, so :func:`set_realtime_priority` called after that covers it.

    Attributes
    ----------
    node : rclpy.node.Node
        Create the lane's subscriptions on it (e.g. ``DropCounter.subscribe(lane.node, ...)``).

    """

    def __init__(self, parent, suffix):
        self.node = rclpy.create_node(
            f'{parent.get_name()}_{suffix}', namespace=parent.get_namespace(),
            context=parent.context, start_parameter_services=False, enable_rosout=False)
        self._executor = make_executor(events=True, context=parent.context)
        self._executor.add_node(self.node)
        self._thread = None

    def start(self):
        """Start spinning the lane (daemon thread, :func:`spin` loop); return self."""
        self._thread = threading.Thread(target=self._run, name=self.node.get_name(),
                                        daemon=True)
        self._thread.start()
        return self

    def _run(self):
        # not the stop flag: the lane serves the parent until it is closed (the control
        # thread's last step after SIGINT still gets its answer)
        context = self.node.context
        while self._thread is not None and context.ok():
            try:
                self._executor.spin_once(timeout_sec=0.05)
            except (ExternalShutdownException, InvalidHandle, RuntimeError):
                return      # the context went down under a take

    def close(self, timeout_s=1.0):
        """
        Stop the lane's thread (waits up to ``timeout_s`` [s]) and destroy its node.

        The node's destruction gets :data:`TEARDOWN_GUARD_S`; if the middleware blocks it, one
        line on stderr and the caller goes on (to write its outputs; the process's own
        :func:`tear_down` comes after).
        """
        thread, self._thread = self._thread, None
        if thread is not None:
            thread.join(timeout_s)

        def destroy():
            self._executor.remove_node(self.node)
            self.node.destroy_node()

        run_guarded(destroy, name='fast_lane_teardown',
                    what=f'{self.node.get_name()}: the middleware\'s destruction of the fast '
                    'lane\'s node')


def spin_node(node, done=lambda: False, *, events=True):
    """Spin ``node`` on :func:`make_executor` with the :func:`spin` loop."""
    executor = make_executor(events)
    executor.add_node(node)
    spin(executor, done)


def run_node(make_node, name, errors=(ValueError,), *, run=spin_node, finish=None, args=None):
    """
    Run a node until SIGINT, SIGTERM or shutdown and return the process exit status.

    SIGINT and SIGTERM only set a flag (:func:`install_stop_handlers`): ``run`` returns, then
    ``finish`` and ``destroy_node`` run undisturbed, and the status is 0 however busy the node
    was. rclpy's own signal handlers are not installed.

    Parameters
    ----------
    make_node : callable
        Builds the node (after ``rclpy.init``).
    name : str
        Node name for the error line on stderr.
    errors : tuple of type
        Exceptions that mean bad parameters or input files: one error line, exit status 2
        (rclpy's ``ParameterException``, e.g. a value outside its declared range or of the
        wrong type, always counts as one).
    run : callable
        ``run(node)`` spins the node until :func:`stop_requested`; default :func:`spin_node`.
    finish : callable or None
        ``finish(node)`` before ``destroy_node``; a non-None return value replaces the status.
    args : list of str or None
        Passed to ``rclpy.init``.

    Returns
    -------
    int
        0, 2 on one of ``errors``, or what ``finish`` returned.

    """
    install_stop_handlers()
    faulthandler.enable()   # a crash in the middleware: every thread's Python stack to the log
    rclpy.init(args=args, signal_handler_options=SignalHandlerOptions.NO)
    node = None
    code = 0
    try:
        node = make_node()
        if not _STOP.is_set():
            run(node)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    except tuple(errors) + (ParameterException,) as exc:
        print(f'{name}: error: {exc}', file=sys.stderr)
        code = 2
    finally:
        if node is not None and finish is not None:
            status = finish(node)
            code = code if status is None else status
        tear_down(node, name, code)
    return code


def run_guarded(work, guard_s=None, name='teardown', what=None):
    """
    Run ``work()`` in a daemon thread and wait up to ``guard_s`` [s] for it to end.

    For calls into the middleware that have been seen to block for good (``destroy_node``,
    ``rclpy.try_shutdown``): the caller goes on either way. Returns True when ``work`` ended
    (raised or not: the exception is the thread's, printed by :mod:`threading`), False when it
    is still running (a daemon thread: it does not keep the process alive).

    ``guard_s`` defaults to :data:`TEARDOWN_GUARD_S`. With ``what`` (e.g. ``"x: the
    middleware's teardown of y"``), a work still running is also said in one line on stderr:
    ``<what> did not end within <guard> s; going on without it``.
    """
    guard_s = TEARDOWN_GUARD_S if guard_s is None else guard_s
    ended = threading.Event()   # set by the worker thread; no signal handler touches it

    def run():
        try:
            work()
        finally:
            ended.set()

    threading.Thread(target=run, name=name, daemon=True).start()
    if ended.wait(guard_s):
        return True
    if what is not None:
        print(f'{what} did not end within {guard_s:g} s; going on without it',
              file=sys.stderr, flush=True)
    return False


def tear_down(node, name, code, guard_s=None):
    """
    Destroy ``node`` (if any) and shut rclpy down, or exit with ``code`` if that gets stuck.

    The teardown runs in a daemon thread (:func:`run_guarded`); if it has not ended after
    ``guard_s`` [s] (default :data:`TEARDOWN_GUARD_S`), one line and every thread's stack go to
    stderr (the node's log) and the process exits at once with ``code``: its outputs are
    written, only the middleware's goodbye is skipped (readers see the writer go at its lease's
    end, as after a kill). If the stuck call holds the GIL, so that this thread cannot wake,
    faulthandler's own watchdog thread prints the stacks and exits (status 1) after
    :data:`TEARDOWN_WATCHDOG_S`.
    """
    guard_s = TEARDOWN_GUARD_S if guard_s is None else guard_s

    def work():
        try:
            if node is not None:
                node.destroy_node()
        finally:
            rclpy.try_shutdown()

    faulthandler.dump_traceback_later(max(TEARDOWN_WATCHDOG_S, guard_s), exit=True)
    if not run_guarded(work, guard_s):
        print(f'{name}: the middleware did not tear the node down within {guard_s:g} s after '
              'it finished (its outputs are written); exiting without it. Every thread:',
              file=sys.stderr, flush=True)
        faulthandler.dump_traceback(all_threads=True)
        sys.stdout.flush()
        os._exit(code)
    faulthandler.cancel_dump_traceback_later()
