"""
Damper measurements on the wire: ``DamperSamples`` batches and single-sample ``JointState``.

Part of :mod:`mr_damper_common.messages`.
"""
from mr_damper_interfaces.msg import DamperSamples
import numpy as np
from sensor_msgs.msg import JointState

from mr_damper_common.contract import COIL_JOINT, PISTON_JOINT
from mr_damper_common.messages.header import (_doubles, _NAN, MessageError, seconds_to_stamp,
                                              stamp_to_seconds)


MEASUREMENT_JOINTS = (PISTON_JOINT, COIL_JOINT)


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


def samples_to_msg(t, x, v, f, i, *, sequence, first_index, sample_period_s=0.0, msg=None,
                   frame_id='mr_damper'):
    """
    Build one ``DamperSamples`` message from a batch of consecutive DAQ samples.

    Parameters
    ----------
    t, x, v, f, i : array_like with shape (n,)
        Sample times [s] (increasing, ``t[0]`` >= 0), displacement [m], velocity [m/s],
        force [N], coil current [A]; n >= 1.
    sequence : int
        Message number of this publisher's stream (+1 per message).
    first_index : int
        Stream index of the first sample (+n per message).
    sample_period_s : float
        Nominal DAQ period [s] (0: irregular).
    msg : DamperSamples, optional
        Message to fill (new one if None).
    frame_id : str
        ``header.frame_id``: the damper.

    Returns
    -------
    mr_damper_interfaces.msg.DamperSamples
        The message; ``header.stamp`` is ``t[0]``, ``t_offset_s`` is ``t - t[0]``.

    Raises
    ------
    ValueError
        Arrays of different lengths or empty, a negative first stamp.

    """
    t = np.asarray(t, dtype=float)
    n = t.shape[0] if t.ndim == 1 else 0
    if n == 0 or any(np.shape(a) != (n,) for a in (x, v, f, i)):
        raise ValueError('`t`, `x`, `v`, `f`, `i` must be 1-D arrays of one length >= 1, got '
                         f'shapes {[np.shape(a) for a in (t, x, v, f, i)]}')
    if msg is None:
        msg = DamperSamples()
        msg.header.frame_id = frame_id
    seconds_to_stamp(float(t[0]), msg.header.stamp)
    msg.sequence = int(sequence)
    msg.first_index = int(first_index)
    msg.sample_period_s = float(sample_period_s)
    msg.t_offset_s = _doubles(t - t[0])
    msg.x_m = _doubles(x)
    msg.v_m_s = _doubles(v)
    msg.f_n = _doubles(f)
    msg.i_a = _doubles(i)
    return msg


def samples_from_msg(msg):
    """
    Read the samples of one ``DamperSamples`` message (rclpy class or rosbags dataclass).

    Values are returned as they are (non-finite values are for the caller to count and reject).

    Parameters
    ----------
    msg : DamperSamples
        Measurement batch.

    Returns
    -------
    tuple of numpy.ndarray
        ``(t, x, v, f, i)``, each of shape (n,): stamps [s] (``header.stamp`` +
        ``t_offset_s``), displacement [m], velocity [m/s], force [N], current [A].

    Raises
    ------
    MessageError
        ``reason='layout'`` if the arrays are empty or of different lengths.

    """
    cols = [np.asarray(a, dtype=float) for a in (msg.t_offset_s, msg.x_m, msg.v_m_s, msg.f_n,
                                                 msg.i_a)]
    n = cols[0].shape[0]
    if n == 0 or any(c.shape[0] != n for c in cols):
        raise MessageError('layout', 'measurement batch arrays empty or of different lengths '
                           f'({[c.shape[0] for c in cols]})')
    cols[0] = stamp_to_seconds(msg.header.stamp) + cols[0]
    return tuple(cols)


def measurement_arrays(msg):
    """
    Read a measurement message of either layout into arrays.

    Parameters
    ----------
    msg : DamperSamples or sensor_msgs/JointState
        A batch (:func:`samples_from_msg`) or one single-sample JointState
        (:func:`measurement_from_msg`), rclpy class or rosbags dataclass.

    Returns
    -------
    tuple of numpy.ndarray
        ``(t, x, v, f, i)``, each of shape (n,) (n = 1 for a JointState).

    Raises
    ------
    MessageError
        As :func:`samples_from_msg` / :func:`measurement_from_msg`.

    """
    if hasattr(msg, 't_offset_s'):
        return samples_from_msg(msg)
    return tuple(np.array([value]) for value in measurement_from_msg(msg))
