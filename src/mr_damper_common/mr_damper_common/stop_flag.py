"""
The stop flag of the suite's processes: SIGINT and SIGTERM set it, loops poll it.

Deliberately light (only ``signal``, ``threading`` and ``importlib``): console scripts install
the handlers through :func:`early_main` *before* they import their node module. Importing rclpy,
scipy and python-control takes 1-4 s, 10-20 s on an over-subscribed machine; a SIGINT in that
window used to hit Python's default handler, whose ``KeyboardInterrupt`` was swallowed somewhere
inside an import, so the node came up and ran on as if nothing had been asked (found by sending
SIGINT 1-2 s after start under load: the process had to be killed).

A stop that does not end: once a stop signal arrived, a later SIGTERM (the launcher's next step,
10 s after its SIGINT, before its SIGKILL) first prints every thread's Python stack to stderr
(:mod:`faulthandler`, from the C signal handler: it prints also while the main thread is stuck
in a C call), so the node's log names where its shutdown stuck (a full-car identifier that
wrote its final parameters and then never exited, at load 6-10, left no trace but exit -9).
"""
import faulthandler
import importlib
import signal
import sys
import threading
import time


class StopFlag:
    """
    A stop flag that a signal handler can set at any moment: no lock anywhere.

    Not ``threading.Event``: its ``set()`` and ``clear()`` take the event's non-reentrant lock,
    and a Python signal handler runs in the main thread between two bytecodes, also while that
    thread holds the lock (inside ``clear()`` right after the handlers were installed): the
    handler's ``set()`` then waited for the lock forever and the node never exited (a SIGTERM
    to ``rig_node`` during start-up under a CPU burner; reproduced at every bytecode by
    tests/mr_damper_common/test_stop_flag.py). Assigning one attribute is atomic under the GIL.
    Nothing waits on the flag: loops poll it.
    """

    __slots__ = ('_value',)

    def __init__(self):
        self._value = False

    def is_set(self):
        """Return True once the flag is set."""
        return self._value

    def set(self):
        """Set the flag (safe in a signal handler)."""
        self._value = True

    def clear(self):
        """Reset the flag."""
        self._value = False


_STOP = StopFlag()
_INSTALLED = [False]
_STACKS_ARMED = [False]


class Interrupts:
    """
    SIGINT / SIGTERM handler of a process that supervises others (the suite's launcher).

    The first signal sets :attr:`flag` (a :class:`StopFlag`: no lock), a second one also calls
    ``on_repeat`` (e.g. kill the children: no more patience). The launcher used a
    ``threading.Event`` here, set from the handler and waited on by its main loop: a Ctrl-C that
    landed while the loop held the event's lock inside ``Event.wait`` waited for that lock
    forever, and the launcher never stopped its nodes (a CI run under load: the test's hang
    guard found the launcher blocked 300 s after its Ctrl-C, every node still running).
    :meth:`wait` sleeps instead.
    """

    def __init__(self, on_repeat=None):
        self.flag = StopFlag()
        self.signals = 0
        self._on_repeat = on_repeat

    def __call__(self, signum=None, frame=None):
        """Handle SIGINT / SIGTERM: set the flag; a repeated signal also calls ``on_repeat``."""
        self.signals += 1
        if self.flag.is_set() and self._on_repeat is not None:
            self._on_repeat()
        self.flag.set()

    def is_set(self):
        """Return True once a signal arrived."""
        return self.flag.is_set()

    def wait(self, timeout_s):
        """Sleep ``timeout_s`` [s] unless a signal arrived (a signal ends the sleep early)."""
        if not self.flag.is_set():
            time.sleep(timeout_s)
        return self.flag.is_set()


def stop_requested():
    """Return True once SIGINT or SIGTERM asked this process to stop."""
    return _STOP.is_set()


def request_stop(signum=None, frame=None):
    """Set the stop flag (the SIGINT / SIGTERM handler); the first signal arms the stack dump."""
    _STOP.set()
    if signum is not None and not _STACKS_ARMED[0]:
        _STACKS_ARMED[0] = True
        try:
            # a later SIGTERM prints every thread's stack, then runs this handler again
            faulthandler.register(signal.SIGTERM, file=sys.stderr, all_threads=True,
                                  chain=True)
        except (AttributeError, OSError, RuntimeError, ValueError):
            pass    # no usable stderr (closed, replaced by an object without a descriptor)


def install_stop_handlers():
    """
    Make SIGINT and SIGTERM set the stop flag instead of raising or killing.

    rclpy's own handlers (not installed by the suite) shut the context down at once and then
    raise ``KeyboardInterrupt`` wherever the main thread happens to be (a callback, the shutdown
    code, an executor call converting a message: ``RuntimeError: Unable to convert call
    argument``) and leave SIGTERM to its default action. With a flag the main thread leaves the
    spin loop between two ``spin_once`` calls, then the node is finished and destroyed in order,
    and the process exits 0. The first call clears the flag; later calls keep a stop that
    arrived in between (e.g. during the imports after :func:`early_main` installed the
    handlers). Returns False when not called from the main thread (signal handlers cannot be set
    there; nothing changes). The flag is cleared *before* the handlers go in: a signal that
    arrives while they are being installed is never wiped out by the clearing.
    """
    if threading.current_thread() is not threading.main_thread():
        return False
    if not _INSTALLED[0]:
        _STOP.clear()
    try:
        signal.signal(signal.SIGINT, request_stop)
        signal.signal(signal.SIGTERM, request_stop)
    except ValueError:
        return False
    _INSTALLED[0] = True
    return True


def early_main(module, func='main'):
    """
    Console-script entry: install the stop handlers, then import ``module`` and run ``func``.

    Parameters
    ----------
    module : str
        Node module (imports rclpy and the numerical stack).
    func : str
        Its entry function; called without arguments, its return value is the exit status.

    Returns
    -------
    int
        0 when the stop came before the node existed (nothing to clean up), else ``func()``.

    """
    install_stop_handlers()
    entry = getattr(importlib.import_module(module), func)
    if stop_requested():
        return 0
    return entry()
