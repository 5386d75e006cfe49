"""
Health on ``/diagnostics``: ``DiagnosticArray`` to and from :class:`~.health.Health`.

Part of :mod:`mr_damper_common.messages`.
"""
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue

from mr_damper_common.health import flatten, Health, unflatten
from mr_damper_common.messages.header import seconds_to_stamp


def diagnostic_status_msg(name, health, hardware_id='', key_values=None):
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
    key_values : dict, optional
        A periodic writer's ``KeyValue`` messages by key, from its last status: those of the
        keys again in this one are reused with their new value text instead of built anew
        (building hundreds of them is most of a status's cost), and the dict then holds this
        status's. The last status's messages change with it: publish a status before the next.

    Returns
    -------
    diagnostic_msgs.msg.DiagnosticStatus
        The status.

    """
    pairs = flatten(health.values)
    if key_values is None:
        values = [KeyValue(key=k, value=v) for k, v in pairs]
    else:
        last = dict(key_values)
        key_values.clear()          # this status's keys only: the dict does not grow
        values = []
        for k, v in pairs:
            kv = last.get(k)
            if kv is None:
                kv = KeyValue(key=k, value=v)
            else:
                kv.value = v
            key_values[k] = kv
            values.append(kv)
    return DiagnosticStatus(level=bytes([health.level]), name=name, message=health.message,
                            hardware_id=hardware_id, values=values)


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
