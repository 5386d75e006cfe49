"""
The stop flag of the suite's processes: SIGINT and SIGTERM set it, loops poll it.

Deliberately light (only ``signal``, ``threading`` and ``importlib``): console scripts install
the handlers through :func:`early_main` *before* they import their node module. Importing rclpy,
scipy and python-control takes 1-4 s, 10-20 s on an over-subscribed machine; a SIGINT in that
window used to hit Python's default handler, whose ``KeyboardInterrupt`` was swallowed somewhere
inside an import, so the node came up and ran on as if nothing had been asked (found by sending
SIGINT 1-2 s after start under load: the process had to be killed).
"""
import importlib
import signal
import threading

_STOP = threading.Event()
_INSTALLED = [False]


def stop_requested():
    """Return True once SIGINT or SIGTERM asked this process to stop."""
    return _STOP.is_set()


def request_stop(signum=None, frame=None):
    """Set the stop flag (the SIGINT / SIGTERM handler)."""
    _STOP.set()


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
    there; nothing changes).
    """
    try:
        signal.signal(signal.SIGINT, request_stop)
        signal.signal(signal.SIGTERM, request_stop)
    except ValueError:
        return False
    if not _INSTALLED[0]:
        _STOP.clear()
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
