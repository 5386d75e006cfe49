"""
ROS 2 message conversions of the MR damper suite (the only model module that imports msgs).

Topic payloads (see the README topic table):

- measurement: ``sensor_msgs/JointState`` per DAQ sample; ``header.stamp`` is the sample time,
  joints ``('mr_damper_piston', 'mr_damper_coil')``; piston position = displacement [m],
  velocity [m/s], effort = damper force [N]; coil effort = coil current [A], coil position and
  velocity NaN.
- parameters: ``std_msgs/Float64MultiArray`` with ``layout.dim[0].label`` the comma-separated
  element names, ``size`` = ``stride`` = their number.  Decoding is by label, never by position.
- status: ``std_msgs/String`` holding one JSON object (non-finite floats become ``null``).

This module imports message types but not rclpy, so it works in any process.
"""
import json

from sensor_msgs.msg import JointState
from std_msgs.msg import Float64MultiArray, MultiArrayDimension, String

from .columnlog import finite_or_none
from .data import COIL_JOINT, PISTON_JOINT
from .kwok_current import KwokCurrent

MEASUREMENT_JOINTS = (PISTON_JOINT, COIL_JOINT)

KWOK_CURRENT_NAMES = KwokCurrent.param_names
KWOK_PARAMETER_LABELS = KWOK_CURRENT_NAMES + (
    'i_ref_a', 'window_end_s', 'current_min_a', 'current_max_a', 'rmse_n', 'nrmse_percent',
    'valid')

_NAN = float('nan')


class MessageError(ValueError):
    """
    A message that cannot be converted.

    ``reason`` is a short machine-readable key used for the status counters
    (``'joint_names'``, ``'layout'``).

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


def measurement_to_msg(t, x, v, f, i, msg=None):
    """
    Build the JointState of one DAQ sample.

    Parameters
    ----------
    t : float
        Sample time [s] (header stamp).
    x, v, f, i : float
        Displacement [m], velocity [m/s], force [N], coil current [A].
    msg : sensor_msgs.msg.JointState, optional
        Message to fill (new one if None).

    Returns
    -------
    sensor_msgs.msg.JointState
        The measurement message.

    """
    if msg is None:
        msg = JointState()
        msg.header.frame_id = 'mr_damper'
        msg.name = list(MEASUREMENT_JOINTS)
    seconds_to_stamp(t, msg.header.stamp)
    msg.position = [float(x), _NAN]
    msg.velocity = [float(v), _NAN]
    msg.effort = [float(f), float(i)]
    return msg


def measurement_from_msg(msg):
    """
    Read one DAQ sample from a measurement JointState.

    Joint order in ``msg.name`` is free; both joints must be present with a position, velocity
    (piston) and effort (both) each.  Values are returned as they are (non-finite values are for
    the caller to count and reject).

    Parameters
    ----------
    msg : sensor_msgs.msg.JointState
        Measurement message.

    Returns
    -------
    tuple of float
        ``(t, x, v, f, i)``: stamp [s], displacement [m], velocity [m/s], force [N], current [A].

    Raises
    ------
    MessageError
        ``reason='joint_names'`` if the joints are not the two expected ones,
        ``reason='layout'`` if the arrays are too short.

    """
    names = msg.name
    if len(names) == 2 and names[0] == PISTON_JOINT and names[1] == COIL_JOINT:
        ip, ic = 0, 1
    else:
        try:
            ip, ic = names.index(PISTON_JOINT), names.index(COIL_JOINT)
        except ValueError:
            raise MessageError('joint_names', f'measurement joints {list(names)!r}, expected '
                               f'{list(MEASUREMENT_JOINTS)!r}') from None
    pos, vel, eff = msg.position, msg.velocity, msg.effort
    if len(pos) <= ip or len(vel) <= ip or len(eff) <= max(ip, ic):
        raise MessageError('layout', 'measurement arrays shorter than the joint list '
                           f'(position {len(pos)}, velocity {len(vel)}, effort {len(eff)})')
    return (stamp_to_seconds(msg.header.stamp), float(pos[ip]), float(vel[ip]),
            float(eff[ip]), float(eff[ic]))


def dict_to_array_msg(values, labels=None):
    """
    Encode named floats as a labelled ``Float64MultiArray``.

    Parameters
    ----------
    values : dict[str, float]
        Values; booleans become 1.0 / 0.0.
    labels : sequence of str, optional
        Element names in order (default: the keys of ``values``).  Missing names are NaN.

    Returns
    -------
    std_msgs.msg.Float64MultiArray
        Message with ``layout.dim[0].label = ','.join(labels)``.

    """
    labels = tuple(values) if labels is None else tuple(labels)
    for name in labels:
        if ',' in name:
            raise ValueError(f'`labels`: name {name!r} contains a comma')
    msg = Float64MultiArray()
    n = len(labels)
    msg.layout.dim = [MultiArrayDimension(label=','.join(labels), size=n, stride=n)]
    msg.data = [float(values.get(name, _NAN)) for name in labels]
    return msg


def array_msg_to_dict(msg):
    """
    Decode a labelled ``Float64MultiArray`` into a dict by label.

    Parameters
    ----------
    msg : std_msgs.msg.Float64MultiArray
        Message written by :func:`dict_to_array_msg` (or any publisher of the same layout).

    Returns
    -------
    dict[str, float]
        Element name -> value.

    Raises
    ------
    MessageError
        ``reason='layout'`` if the label is missing or its count differs from the data.

    """
    if not msg.layout.dim or not msg.layout.dim[0].label:
        raise MessageError('layout', 'Float64MultiArray without layout.dim[0].label')
    labels = msg.layout.dim[0].label.split(',')
    data = list(msg.data)
    if len(labels) != len(data):
        raise MessageError('layout', f'{len(labels)} labels for {len(data)} elements')
    return {name.strip(): float(value) for name, value in zip(labels, data)}


def kwok_parameters_msg(estimate):
    """
    Encode a kwok-current estimate for ``/mr_damper/kwok_parameters`` (or the true parameters).

    Parameters
    ----------
    estimate : dict
        Must contain the ten kwok-current parameters; optional ``i_ref_a`` (default 2.0),
        ``window_end_s``, ``current_min_a``, ``current_max_a``, ``rmse_n``, ``nrmse_percent``
        (NaN if absent) and ``valid`` (bool, default False).

    Returns
    -------
    std_msgs.msg.Float64MultiArray
        Message with the :data:`KWOK_PARAMETER_LABELS` layout.

    """
    missing = [n for n in KWOK_CURRENT_NAMES if n not in estimate]
    if missing:
        raise ValueError(f'`estimate` misses kwok-current parameters {missing}')
    values = dict(estimate)
    values.setdefault('i_ref_a', 2.0)
    values['valid'] = 1.0 if values.get('valid', False) else 0.0
    return dict_to_array_msg(values, KWOK_PARAMETER_LABELS)


def kwok_parameters_from_msg(msg):
    """
    Decode ``/mr_damper/kwok_parameters`` by label.

    Parameters
    ----------
    msg : std_msgs.msg.Float64MultiArray
        Parameters message.

    Returns
    -------
    dict
        ``'parameters'`` (dict of the ten kwok-current parameters), ``'valid'`` (bool) and the
        remaining labelled values (``i_ref_a``, ``window_end_s``, ``current_min_a``,
        ``current_max_a``, ``rmse_n``, ``nrmse_percent``) as floats.

    Raises
    ------
    MessageError
        ``reason='layout'`` on a bad layout or a missing parameter name.

    """
    d = array_msg_to_dict(msg)
    missing = [n for n in KWOK_CURRENT_NAMES if n not in d]
    if missing:
        raise MessageError('layout', f'kwok parameters message misses {missing}')
    out = {k: v for k, v in d.items() if k not in KWOK_CURRENT_NAMES}
    out['parameters'] = {n: d[n] for n in KWOK_CURRENT_NAMES}
    out['valid'] = d.get('valid', 0.0) == 1.0
    return out


def status_msg(status):
    """
    Encode a status dict as ``std_msgs/String`` with one JSON object.

    Parameters
    ----------
    status : dict
        Counters and figures (nested dicts allowed); NaN/inf become ``null``.

    Returns
    -------
    std_msgs.msg.String
        The status message.

    """
    return String(data=json.dumps(finite_or_none(status), sort_keys=True, allow_nan=False))


def status_from_msg(msg):
    """
    Decode a status ``std_msgs/String`` into a dict.

    Parameters
    ----------
    msg : std_msgs.msg.String
        Status message.

    Returns
    -------
    dict
        The JSON object.

    """
    d = json.loads(msg.data)
    if not isinstance(d, dict):
        raise MessageError('layout', 'status message is not a JSON object')
    return d
