"""
Stamps, arrays and the conversion error shared by the message conversions.

Part of :mod:`mr_damper_common.messages`.
"""
import array
import math

import numpy as np


_NAN = float('nan')


class MessageError(ValueError):
    """
    A message that cannot be converted.

    ``reason`` is a short machine-readable key used for the status counters
    (``'joint_names'``, ``'layout'``, ``'bad_i_ref'``).

    """

    def __init__(self, reason, message):
        super().__init__(message)
        self.reason = reason


def stamp_to_seconds(stamp):
    """
    Convert a ``builtin_interfaces/Time`` to seconds.

    Parameters
    ----------
    stamp : builtin_interfaces.msg.Time
        Stamp.

    Returns
    -------
    float
        Time [s].

    """
    return stamp.sec + stamp.nanosec * 1e-9


def seconds_to_stamp(t, stamp):
    """
    Write time ``t`` [s] into ``stamp`` (a ``builtin_interfaces/Time``) and return it.

    Parameters
    ----------
    t : float
        Time [s], >= 0.
    stamp : builtin_interfaces.msg.Time
        Stamp to fill in place.

    Returns
    -------
    builtin_interfaces.msg.Time
        ``stamp``.

    """
    ns = int(round(t * 1e9))
    if ns < 0:
        raise ValueError(f'`t` must be >= 0 s for a ROS stamp, got {t!r}')
    stamp.sec, stamp.nanosec = divmod(ns, 1_000_000_000)
    return stamp


def _doubles(values):
    """Return ``values`` as an ``array.array('d')`` (the generated setter takes it as is)."""
    return array.array('d', np.ascontiguousarray(values, dtype=float).tobytes())


def _time_or_zero(t, stamp):
    """Write ``t`` [s] into ``stamp``; a NaN or negative time (unknown) becomes 0."""
    if t is None or not math.isfinite(t) or t < 0:
        stamp.sec, stamp.nanosec = 0, 0
        return stamp
    return seconds_to_stamp(t, stamp)


def _seconds_or_nan(stamp):
    """Read a stamp [s]; the zero stamp (unknown) becomes NaN."""
    return math.nan if stamp.sec == 0 and stamp.nanosec == 0 else stamp_to_seconds(stamp)
