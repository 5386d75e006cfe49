"""
Identified sets (``KwokParameters``) and named-parameter damper models (``DamperModel``).

Part of :mod:`mr_damper_common.messages`.
"""
from mr_damper_interfaces.msg import DamperModel, KwokParameters

from mr_damper_common.contract import IdentifiedSet, KWOK_CURRENT_NAMES
from mr_damper_common.messages.header import (_seconds_or_nan, _time_or_zero, MessageError,
                                              seconds_to_stamp, stamp_to_seconds)


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
