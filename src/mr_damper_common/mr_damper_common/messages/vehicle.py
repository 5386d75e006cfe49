"""
A corner's state and the vehicle computer's messages.

Chassis sensors, full car state and command, road preview.

Part of :mod:`mr_damper_common.messages`.
"""
from mr_damper_interfaces.msg import (ChassisSensors, FullCarCommand, FullCarState,
                                      QuarterCarState, RoadPreview)
import numpy as np

from mr_damper_common.contract import CornerState
from mr_damper_common.messages.header import (_doubles, _time_or_zero, MessageError,
                                              seconds_to_stamp, stamp_to_seconds)


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
    _time_or_zero(cmd.state_t, msg.state_stamp)
    msg.current_a = cmd.currents_a
    msg.demanded_force_n = cmd.demanded_n
    msg.mode = [int(m) for m in cmd.modes]
    msg.reason = [str(r) for r in cmd.reasons]
    return msg


def full_car_command_fields(msg):
    """
    Return a ``FullCarCommand``'s values: ``(sequence, state_sequence, currents, modes)``.

    ``currents`` [A] as an array of four; ``modes`` a list of four ints (``MODE_*``).
    """
    return (int(msg.sequence), int(msg.state_sequence),
            np.asarray(msg.current_a, dtype=float), [int(m) for m in msg.mode])


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
