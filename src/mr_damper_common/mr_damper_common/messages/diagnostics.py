"""
Health on ``/diagnostics``: ``DiagnosticArray`` to and from :class:`~.health.Health`.

Part of :mod:`mr_damper_common.messages`.
"""
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue

from mr_damper_common.health import flatten, Health, unflatten
from mr_damper_common.messages.header import seconds_to_stamp


def diagnostic_status_msg(name, health, hardware_id=''):
    """
    Build one ``diagnostic_msgs/DiagnosticStatus`` from a :class:`~.health.Health`.

    Parameters
    ----------
    name : str
        Status name, by convention ``'<node name>: <component>'``.
    health : Health
        Level, message and values (flattened to key-values, see :mod:`.health`).
    hardware_id : str
        The device (e.g. the damper or corner).

    Returns
    -------
    diagnostic_msgs.msg.DiagnosticStatus
        The status.

    """
    return DiagnosticStatus(level=bytes([health.level]), name=name, message=health.message,
                            hardware_id=hardware_id,
                            values=[KeyValue(key=k, value=v) for k, v in flatten(health.values)])


def diagnostic_array_msg(statuses, stamp_s=None):
    """
    Wrap statuses in a ``diagnostic_msgs/DiagnosticArray`` stamped ``stamp_s`` [s].

    Parameters
    ----------
    statuses : list of DiagnosticStatus
        Statuses (:func:`diagnostic_status_msg`).
    stamp_s : float, optional
        ``header.stamp`` [s] (the publisher's clock).

    Returns
    -------
    diagnostic_msgs.msg.DiagnosticArray
        The array.

    """
    msg = DiagnosticArray(status=list(statuses))
    if stamp_s is not None:
        seconds_to_stamp(stamp_s, msg.header.stamp)
    return msg


def health_from_diagnostic(status):
    """
    Read one ``diagnostic_msgs/DiagnosticStatus`` back into a :class:`~.health.Health`.

    Parameters
    ----------
    status : diagnostic_msgs.msg.DiagnosticStatus
        A status of the suite (or any: non-JSON values stay text).

    Returns
    -------
    Health
        Level, message and nested values (:func:`~.health.unflatten`).

    """
    level = status.level[0] if isinstance(status.level, (bytes, bytearray)) else status.level
    return Health(int(level), status.message,
                  unflatten((kv.key, kv.value) for kv in status.values))
