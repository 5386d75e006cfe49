"""
ROS 2 message conversions of the MR damper suite (the only model module that imports msgs).

Topic payloads (see the README topic table):

- measurement: ``mr_damper_interfaces/DamperSamples``, a batch of consecutive DAQ samples
  (arrays ``t_offset_s, x_m, v_m_s, f_n, i_a`` from ``header.stamp``, with a message
  ``sequence`` and the stream index ``first_index`` of its first sample, so a reader counts lost
  samples exactly): :func:`samples_to_msg`, :func:`samples_from_msg`.
- single-sample measurement (the layout of earlier recordings and of DAQ drivers that publish
  one message per sample): ``sensor_msgs/JointState``; ``header.stamp`` is the sample time,
  joints ``('mr_damper_piston', 'mr_damper_coil')``; piston position = displacement [m],
  velocity [m/s], effort = damper force [N]; coil effort = coil current [A], coil position and
  velocity NaN. :func:`measurement_arrays` reads either kind into arrays.
- parameters: ``mr_damper_interfaces/KwokParameters`` (one field per coefficient, window times,
  current range, fit quality, ``valid`` and ``reason``), typed as
  :class:`mr_damper_common.contract.IdentifiedSet`: :func:`kwok_parameters_msg`,
  :func:`identified_set_from_msg`.
- true damper of a simulation: ``mr_damper_interfaces/DamperModel`` (named parameters) or
  ``KwokParameters`` for a kwok-current truth.
- a corner's state: ``mr_damper_interfaces/QuarterCarState`` (the fields of
  :class:`mr_damper_common.contract.CornerState`, the current command and the commander's mode):
  :func:`corner_state_to_msg`, :func:`corner_state_from_msg`.
- road preview: ``mr_damper_interfaces/RoadPreview`` (a look-ahead sensor's frame: heights per
  track at distances ahead of the front axle, stamp, speed signal, validity):
  :func:`road_preview_msg`, :func:`road_preview_fields`.
- health: ``diagnostic_msgs/DiagnosticArray`` on ``/diagnostics`` (levels and flat key-values,
  see :mod:`mr_damper_common.health`).

This module imports message types but not rclpy, so it works in any process.
"""
import array
import math

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from mr_damper_interfaces.msg import (ChassisSensors, DamperModel, DamperSamples,
                                      FullCarCommand, FullCarState, KwokParameters,
                                      QuarterCarState, RoadPreview)
import numpy as np
from sensor_msgs.msg import JointState

from mr_damper_common.contract import (COIL_JOINT, CornerState, IdentifiedSet,
                                       KWOK_CURRENT_NAMES, PISTON_JOINT)
from mr_damper_common.health import flatten, Health, unflatten

MEASUREMENT_JOINTS = (PISTON_JOINT, COIL_JOINT)


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


def _doubles(values):
    """Return ``values`` as an ``array.array('d')`` (the generated setter takes it as is)."""
    return array.array('d', np.ascontiguousarray(values, dtype=float).tobytes())


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


def _time_or_zero(t, stamp):
    """Write ``t`` [s] into ``stamp``; a NaN or negative time (unknown) becomes 0."""
    if t is None or not math.isfinite(t) or t < 0:
        stamp.sec, stamp.nanosec = 0, 0
        return stamp
    return seconds_to_stamp(t, stamp)


def _seconds_or_nan(stamp):
    """Read a stamp [s]; the zero stamp (unknown) becomes NaN."""
    return math.nan if stamp.sec == 0 and stamp.nanosec == 0 else stamp_to_seconds(stamp)


def kwok_parameters_msg(identified, msg=None, *, stamp_s=None, frame_id='mr_damper'):
    """
    Encode an identified set as ``mr_damper_interfaces/KwokParameters``.

    Parameters
    ----------
    identified : mr_damper_common.contract.IdentifiedSet or mapping
        The set; a flat mapping (the ten kwok-current parameters, optional ``i_ref_a`` (default
        2.0), ``window_start_s``, ``window_end_s``, ``current_min_a``, ``current_max_a``,
        ``rmse_n``, ``nrmse_percent``, ``valid`` (default False) and ``reason``) is converted by
        :meth:`~mr_damper_common.contract.IdentifiedSet.from_flat`. Unknown (NaN) window times
        are sent as the zero time.
    msg : KwokParameters, optional
        Message to fill (new one if None).
    stamp_s : float, optional
        ``header.stamp`` [s] (the publisher's clock); None leaves it unchanged.
    frame_id : str
        ``header.frame_id``: the damper.

    Returns
    -------
    mr_damper_interfaces.msg.KwokParameters
        The message.

    Raises
    ------
    ValueError
        If a parameter is missing or not a number, or ``i_ref_a`` is not > 0.

    """
    s = (identified if isinstance(identified, IdentifiedSet)
         else IdentifiedSet.from_flat(identified))
    if not s.i_ref_a > 0:
        raise ValueError(f'identified set: i_ref_a must be > 0 A, got {s.i_ref_a!r}')
    if msg is None:
        msg = KwokParameters()
    msg.header.frame_id = frame_id
    if stamp_s is not None:
        seconds_to_stamp(stamp_s, msg.header.stamp)
    for name in KWOK_CURRENT_NAMES:
        setattr(msg, name, s.parameters[name])
    msg.i_ref_a = s.i_ref_a
    _time_or_zero(s.window_start_s, msg.window_start)
    _time_or_zero(s.window_end_s, msg.window_end)
    msg.current_min_a, msg.current_max_a = s.current_min_a, s.current_max_a
    msg.rmse_n, msg.nrmse_percent = s.rmse_n, s.nrmse_percent
    msg.valid = s.valid
    msg.reason = '' if s.valid else (s.reason or 'not_valid')
    return msg


def identified_set_from_msg(msg):
    """
    Decode ``mr_damper_interfaces/KwokParameters`` into an identified set.

    Parameters
    ----------
    msg : mr_damper_interfaces.msg.KwokParameters
        Parameters message (rclpy class or rosbags dataclass).

    Returns
    -------
    mr_damper_common.contract.IdentifiedSet
        Every element of the message; ``stamp_s`` is the header stamp [s], unknown window
        times (the zero time) are NaN.

    Raises
    ------
    MessageError
        ``reason='bad_i_ref'`` if ``i_ref_a`` is not > 0 (a set no model can use).

    """
    if not msg.i_ref_a > 0:
        raise MessageError('bad_i_ref',
                           f'kwok parameters with i_ref_a {msg.i_ref_a!r} (must be > 0)')
    return IdentifiedSet({n: getattr(msg, n) for n in KWOK_CURRENT_NAMES}, i_ref_a=msg.i_ref_a,
                         current_min_a=msg.current_min_a, current_max_a=msg.current_max_a,
                         valid=msg.valid, reason=msg.reason,
                         window_start_s=_seconds_or_nan(msg.window_start),
                         window_end_s=_seconds_or_nan(msg.window_end), rmse_n=msg.rmse_n,
                         nrmse_percent=msg.nrmse_percent,
                         stamp_s=stamp_to_seconds(msg.header.stamp))


def corner_state_to_msg(state, current_command_a, normal, reason, msg=None, *,
                        frame_id='quarter_car'):
    """
    Fill a ``QuarterCarState`` from a :class:`~mr_damper_common.contract.CornerState`.

    Parameters
    ----------
    state : CornerState
        The corner (SI); ``header.stamp`` = ``max(state.t, 0)`` (a car settling before the
        road starts has negative times).
    current_command_a : float
        Coil current command in force [A].
    normal : bool
        Mode of whoever commands the current (False: fail-safe).
    reason : str
        Fail-safe reason (``'ok'`` in normal mode).
    msg : QuarterCarState, optional
        Message to fill in place (one allocation for a 1 kHz publisher).
    frame_id : str
        ``header.frame_id`` of a new message.

    Returns
    -------
    mr_damper_interfaces.msg.QuarterCarState

    """
    if msg is None:
        msg = QuarterCarState()
        msg.header.frame_id = frame_id
    seconds_to_stamp(max(state.t, 0.0), msg.header.stamp)
    msg.body_displacement_m = state.z_s
    msg.body_velocity_m_s = state.v_s
    msg.body_acceleration_m_s2 = state.a_s
    msg.wheel_displacement_m = state.z_u
    msg.wheel_velocity_m_s = state.v_u
    msg.wheel_acceleration_m_s2 = state.a_u
    msg.suspension_travel_m = state.travel
    msg.suspension_velocity_m_s = state.v_rel
    msg.damper_force_n = state.damper_force
    msg.tyre_load_n = state.tyre_force
    msg.road_height_m = state.z_r
    msg.current_command_a = float(current_command_a)
    msg.coil_current_a = state.coil_current
    msg.fail_safe_mode = QuarterCarState.MODE_NORMAL if normal else QuarterCarState.MODE_FAIL_SAFE
    msg.fail_safe_reason = reason
    return msg


def corner_state_from_msg(msg):
    """
    Read a ``QuarterCarState`` into a :class:`~mr_damper_common.contract.CornerState`.

    Parameters
    ----------
    msg : mr_damper_interfaces.msg.QuarterCarState
        State message (rclpy class or rosbags dataclass).

    Returns
    -------
    CornerState
        Every field as sent (``t`` the header stamp [s]; a NaN field stays NaN: not measured).

    """
    return CornerState(stamp_to_seconds(msg.header.stamp), msg.body_displacement_m,
                       msg.body_velocity_m_s, msg.body_acceleration_m_s2,
                       msg.wheel_displacement_m, msg.wheel_velocity_m_s,
                       msg.wheel_acceleration_m_s2, msg.road_height_m, msg.suspension_travel_m,
                       msg.suspension_velocity_m_s, msg.tyre_load_n, msg.damper_force_n,
                       msg.coil_current_a)


def damper_model_msg(model, parameters, options=None, *, stamp_s=None, frame_id='mr_damper'):
    """
    Encode a named-parameter damper model as ``mr_damper_interfaces/DamperModel``.

    Parameters
    ----------
    model : str
        Model name (``'spencer'``, ``'kwok-current'``, ...).
    parameters : dict[str, float]
        Parameter name -> value (SI), in the model's order.
    options : dict[str, float], optional
        Model options (e.g. ``{'i_ref_a': 2.0}``).
    stamp_s : float, optional
        ``header.stamp`` [s].
    frame_id : str
        ``header.frame_id``: the damper.

    Returns
    -------
    mr_damper_interfaces.msg.DamperModel
        The message.

    """
    msg = DamperModel()
    msg.header.frame_id = frame_id
    if stamp_s is not None:
        seconds_to_stamp(stamp_s, msg.header.stamp)
    msg.model = str(model)
    msg.parameter_names = [str(k) for k in parameters]
    msg.parameter_values = [float(v) for v in parameters.values()]
    options = dict(options or {})
    msg.option_names = [str(k) for k in options]
    msg.option_values = [float(v) for v in options.values()]
    return msg


def damper_model_from_msg(msg):
    """
    Decode ``mr_damper_interfaces/DamperModel``.

    Returns
    -------
    dict
        ``{'model': str, 'parameters': {name: value}, 'model_options': {name: value}}`` (the
        layout of a parameter file, :mod:`mr_damper_model.io.params_file`).

    Raises
    ------
    MessageError
        ``reason='layout'`` if names and values differ in number.

    """
    names, values = list(msg.parameter_names), list(msg.parameter_values)
    onames, ovalues = list(msg.option_names), list(msg.option_values)
    if len(names) != len(values) or len(onames) != len(ovalues):
        raise MessageError('layout', f'damper model with {len(names)} names for {len(values)} '
                           f'values, {len(onames)} option names for {len(ovalues)} values')
    return {'model': msg.model,
            'parameters': {n: float(v) for n, v in zip(names, values)},
            'model_options': {n: float(v) for n, v in zip(onames, ovalues)}}


# --- the vehicle computer's three messages (ChassisSensors, FullCarState, FullCarCommand) ---

def _stamp_or_zero(t, stamp):
    """Write ``t`` [s] into ``stamp``, or 0 s for a NaN (no time)."""
    return seconds_to_stamp(t if t == t and t >= 0 else 0.0, stamp)


def chassis_sensors_msg(cycle, cycle_period_s, msg=None, frame_id='chassis'):
    """
    Fill a ``ChassisSensors`` from one sensor cycle of the bus.

    Parameters
    ----------
    cycle : object
        With ``sequence``, ``t_bus`` [s], ``body_accel``, ``wheel_accel`` [m/s^2],
        ``susp_pos`` [m], ``current_sent_a``, ``current_measured_a`` [A] (four each) and
        ``missing`` (the ``MISSING_*`` bits), e.g. ``mr_damper_can.vehicle_bridge.
        ChassisCycle``.
    cycle_period_s : float
        Nominal cycle [s].
    msg : ChassisSensors, optional
        Filled in place (a publisher's reused message).
    frame_id : str
        The header's frame.

    """
    msg = ChassisSensors() if msg is None else msg
    seconds_to_stamp(cycle.t_bus, msg.header.stamp)
    msg.header.frame_id = frame_id
    msg.sequence = int(cycle.sequence)
    msg.cycle_period_s = float(cycle_period_s)
    msg.body_acceleration_m_s2 = cycle.body_accel
    msg.wheel_acceleration_m_s2 = cycle.wheel_accel
    msg.suspension_travel_m = cycle.susp_pos
    msg.current_command_a = cycle.current_sent_a
    msg.coil_current_a = cycle.current_measured_a
    msg.frames_missing = int(cycle.missing)
    return msg


def full_car_state_msg(est, msg=None, frame_id='base_link'):
    """
    Fill a ``FullCarState`` from an estimate.

    ``est`` has ``sequence``, ``t`` [s], ``body`` (heave, pitch, roll), ``body_rates``,
    ``body_acc``, ``travel``, ``travel_velocity``, ``tyre_deflection``, ``wheel_velocity``,
    ``damper_force``, ``valid``, ``reason``, ``faults`` and the four standard deviations, e.g.
    ``semi_active_control.estimation.VehicleEstimate``.
    """
    msg = FullCarState() if msg is None else msg
    seconds_to_stamp(est.t, msg.header.stamp)
    msg.header.frame_id = frame_id
    msg.sequence = int(est.sequence)
    msg.heave_m, msg.pitch_rad, msg.roll_rad = (float(v) for v in est.body)
    (msg.heave_velocity_m_s, msg.pitch_rate_rad_s,
     msg.roll_rate_rad_s) = (float(v) for v in est.body_rates)
    (msg.heave_acceleration_m_s2, msg.pitch_acceleration_rad_s2,
     msg.roll_acceleration_rad_s2) = (float(v) for v in est.body_acc)
    msg.suspension_travel_m = est.travel
    msg.suspension_velocity_m_s = est.travel_velocity
    msg.tyre_deflection_m = est.tyre_deflection
    msg.wheel_velocity_m_s = est.wheel_velocity
    msg.damper_force_n = est.damper_force
    msg.valid = bool(est.valid)
    msg.reason = str(est.reason)
    msg.sensor_faults = list(est.faults)
    msg.travel_std_m = float(est.travel_std_m)
    msg.heave_velocity_std_m_s = float(est.heave_velocity_std_m_s)
    msg.tyre_deflection_std_m = float(est.tyre_deflection_std_m)
    msg.wheel_velocity_std_m_s = float(est.wheel_velocity_std_m_s)
    return msg


def full_car_state_fields(msg):
    """
    Return a ``FullCarState``'s values as a dict (SI; arrays of four per corner).

    Keys ``sequence``, ``t`` [s], ``body``, ``body_rates``, ``body_acc`` (arrays of three),
    ``travel``, ``travel_velocity``, ``tyre_deflection``, ``wheel_velocity``,
    ``damper_force``, ``valid``, ``reason``.
    """
    return {'sequence': int(msg.sequence), 't': stamp_to_seconds(msg.header.stamp),
            'body': np.array([msg.heave_m, msg.pitch_rad, msg.roll_rad]),
            'body_rates': np.array([msg.heave_velocity_m_s, msg.pitch_rate_rad_s,
                                    msg.roll_rate_rad_s]),
            'body_acc': np.array([msg.heave_acceleration_m_s2, msg.pitch_acceleration_rad_s2,
                                  msg.roll_acceleration_rad_s2]),
            'travel': np.asarray(msg.suspension_travel_m, dtype=float),
            'travel_velocity': np.asarray(msg.suspension_velocity_m_s, dtype=float),
            'tyre_deflection': np.asarray(msg.tyre_deflection_m, dtype=float),
            'wheel_velocity': np.asarray(msg.wheel_velocity_m_s, dtype=float),
            'damper_force': np.asarray(msg.damper_force_n, dtype=float),
            'valid': bool(msg.valid), 'reason': str(msg.reason)}


def full_car_command_msg(cmd, stamp_s, msg=None, frame_id='base_link'):
    """
    Fill a ``FullCarCommand`` from a command.

    ``cmd`` has ``sequence``, ``state_sequence``, ``state_t`` [s] (NaN: none),
    ``currents_a``, ``demanded_n``, ``modes`` and ``reasons`` (four each), e.g.
    ``semi_active_control.runtime.VehicleCommand``; ``stamp_s`` is when it was computed.
    """
    msg = FullCarCommand() if msg is None else msg
    seconds_to_stamp(stamp_s, msg.header.stamp)
    msg.header.frame_id = frame_id
    msg.sequence = int(cmd.sequence)
    msg.state_sequence = int(cmd.state_sequence)
    _stamp_or_zero(cmd.state_t, msg.state_stamp)
    msg.current_a = cmd.currents_a
    msg.demanded_force_n = cmd.demanded_n
    msg.mode = [int(m) for m in cmd.modes]
    msg.reason = [str(r) for r in cmd.reasons]
    return msg


def full_car_command_fields(msg):
    """
    Return a ``FullCarCommand``'s values: ``(sequence, state_sequence, currents, failsafe)``.

    ``currents`` [A] as an array of four; ``failsafe`` a list of four bools (any mode but
    NORMAL).
    """
    return (int(msg.sequence), int(msg.state_sequence),
            np.asarray(msg.current_a, dtype=float),
            [int(m) != FullCarCommand.MODE_NORMAL for m in msg.mode])


def road_preview_msg(stamp_s, distance_m, heights_m, *, sequence, speed_m_s, valid=True,
                     reason='', msg=None, frame_id='front_axle'):
    """
    Fill a ``RoadPreview`` from one look-ahead frame.

    Parameters
    ----------
    stamp_s : float
        Measurement time of the frame [s], >= 0.
    distance_m : array_like with shape (m,)
        Distances ahead of the front axle [m], increasing.
    heights_m : array_like with shape (tracks, m)
        Road height of each track [m] (NaN: not measured).
    sequence : int
        Frame number of the sensor (+1 per frame).
    speed_m_s : float
        The car's speed signal when the frame was sent [m/s] (NaN: unknown).
    valid : bool
        The sensor's validity flag.
    reason : str
        Why it is not valid (ignored when valid).
    msg : RoadPreview, optional
        Filled in place (a publisher's reused message).
    frame_id : str
        The header's frame.

    Returns
    -------
    mr_damper_interfaces.msg.RoadPreview

    Raises
    ------
    ValueError
        ``heights_m`` not of shape (tracks, m) with 1..255 tracks.

    """
    d = np.asarray(distance_m, dtype=float).ravel()
    h = np.asarray(heights_m, dtype=float)
    if h.ndim != 2 or h.shape[1] != d.size or not 1 <= h.shape[0] <= 255:
        raise ValueError(f'`heights_m` must have shape (tracks, {d.size}) with 1..255 tracks, '
                         f'got {h.shape}')
    msg = RoadPreview() if msg is None else msg
    seconds_to_stamp(stamp_s, msg.header.stamp)
    msg.header.frame_id = frame_id
    msg.sequence = int(sequence)
    msg.vehicle_speed_m_s = float(speed_m_s)
    msg.distance_m = _doubles(d)
    msg.track_count = int(h.shape[0])
    msg.height_m = _doubles(h.ravel())
    msg.valid = bool(valid)
    msg.reason = '' if msg.valid else (str(reason) or 'not_valid')
    return msg


def road_preview_fields(msg):
    """
    Read a ``RoadPreview`` (rclpy class or rosbags dataclass).

    Returns
    -------
    dict
        ``sequence`` (int), ``stamp`` [s], ``speed_m_s`` [m/s], ``distance_m`` (m,),
        ``heights_m`` (tracks, m) [m], ``valid`` (bool), ``reason`` (str).

    Raises
    ------
    MessageError
        ``reason='layout'`` when the heights do not fill ``track_count`` rows of the
        distances (or there are no tracks).

    """
    d = np.asarray(msg.distance_m, dtype=float)
    h = np.asarray(msg.height_m, dtype=float)
    k = int(msg.track_count)
    if k < 1 or h.size != k * d.size:
        raise MessageError('layout', f'road preview with {h.size} heights for {k} tracks of '
                           f'{d.size} distances')
    return {'sequence': int(msg.sequence), 'stamp': stamp_to_seconds(msg.header.stamp),
            'speed_m_s': float(msg.vehicle_speed_m_s), 'distance_m': d,
            'heights_m': h.reshape(k, d.size), 'valid': bool(msg.valid),
            'reason': str(msg.reason)}


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
