"""
Real-time scheduling of a thread someone else creates, without ROS.

A library that makes its own reader thread (python-can's ``Notifier``) gives no handle to set
that thread's policy before it runs. :func:`fifo_on_first_call` wraps the callback the thread
calls, so the thread puts itself under SCHED_FIFO on its first call (``os.sched_setscheduler``
on the calling thread), before it runs the callback. The nodes' own threads get their policy
from ``mr_damper_common.node_utils.set_realtime_priority`` (every thread of the process) and
``quarter_car_sim``'s control thread from its constructor.

:func:`freeze_heap` keeps a real-time process's start-up heap out of the cyclic garbage
collector's passes (the managed nodes and the car nodes call it before they spin).
"""
import os


class FifoOnFirstCall:
    """
    ``fn`` wrapped: its first caller's thread goes under SCHED_FIFO ``priority`` first.

    Parameters
    ----------
    fn : callable
        The callback (its arguments are passed through; its return value too).
    priority : int
        SCHED_FIFO priority, 1..99.
    on_error : callable, optional
        ``on_error(message)`` when the policy is refused (no CAP_SYS_NICE): the thread then
        runs ``fn`` at its own scheduling, as before.

    Attributes
    ----------
    error : str or None
        Why the policy was refused (None: applied, or no call yet); a status shows it.

    Raises
    ------
    ValueError
        If ``priority`` is not in 1..99.

    """

    def __init__(self, fn, priority, on_error=None):
        if not 1 <= int(priority) <= 99:
            raise ValueError(f'`priority` must be in 1..99, got {priority}')
        self.fn = fn
        self.on_error = on_error
        self.error = None
        self._param = os.sched_param(int(priority))
        self._pending = True

    def __call__(self, *args, **kwargs):
        """Set the policy on the first call, then call ``fn``."""
        if self._pending:
            self._pending = False
            try:
                os.sched_setscheduler(0, os.SCHED_FIFO, self._param)
            except OSError as exc:
                self.error = str(exc)
                if self.on_error is not None:
                    self.on_error(self.error)
        return self.fn(*args, **kwargs)


def fifo_on_first_call(fn, priority, on_error=None):
    """Return :class:`FifoOnFirstCall` of ``fn`` (see there)."""
    return FifoOnFirstCall(fn, priority, on_error)


def freeze_heap():
    """
    Collect once, then leave every object there is out of the garbage collector's later passes.

    A node's heap after its start (rclpy, numpy, scipy, python-control, cantools' database,
    the filter's design: about a hundred thousand objects) never becomes garbage; without this
    every full collection walks all of it (tens of milliseconds on this project's 2-vCPU VM),
    and the thread that triggers one holds the GIL meanwhile (py-spy on
    ``vehicle_computer_node``: most of its executor thread's samples were in
    ``gc_collect_main``, and the bus reader waited). :func:`gc.freeze` is CPython's tool for
    this; objects made later are collected as before.
    """
    import gc
    gc.collect()
    gc.freeze()
