"""
The suite's topics in one table, and the one decoder of each payload kind, without ROS.

:data:`SUITE_TOPICS` is what ``mr-damper-record`` records and what the report reads back: one
row per topic, ``key -> Topic(name, type, qos)``. Changing a topic's message type (e.g. the
parameters to ``mr_damper_interfaces/msg/KwokParameters``, the JSON status topics to
``/diagnostics``) is a change of this table and of :func:`decode_parameters` /
:func:`decode_status`, nothing else: the recorder writes whatever type the row names (still
serialised, typed schema from ``mr_damper_model.io.bag_types.suite_typestore``) and the launcher's
monitor and the report decode through these two functions.

The decoders take a message object of either origin, the rclpy class (the launcher's monitor)
or the rosbags dataclass (the report reading ``suite.mcap``): both have the same field names.
They import ``mr_damper_common.messages`` (message packages, no rclpy) when first called, so
importing this module stays ROS-free.
"""
from collections import namedtuple
import importlib

#: One recorded topic: absolute name, ROS 2 type name, QoS kind
#: (``'measurement'`` reliable KEEP_ALL, ``'latched'`` transient local, ``'default'`` depth 10).
Topic = namedtuple('Topic', 'name type qos')


def message_class(type_name):
    """Return the message class of ``'pkg/msg/Name'`` (imports that message package)."""
    pkg, kind, name = type_name.split('/')
    return getattr(importlib.import_module(f'{pkg}.{kind}'), name)


STRING = 'std_msgs/msg/String'
FLOAT64 = 'std_msgs/msg/Float64'
UINT64 = 'std_msgs/msg/UInt64'
JOINT_STATE = 'sensor_msgs/msg/JointState'
DIAGNOSTICS = 'diagnostic_msgs/msg/DiagnosticArray'
KWOK = 'mr_damper_interfaces/msg/KwokParameters'
DAMPER_MODEL = 'mr_damper_interfaces/msg/DamperModel'
CAR_STATE = 'mr_damper_interfaces/msg/QuarterCarState'
DAMPER_SAMPLES = 'mr_damper_interfaces/msg/DamperSamples'
IMU = 'sensor_msgs/msg/Imu'

#: Every topic of the suite (node defaults, root namespace), by key. The :data:`STATUS_KEYS` rows
#: are the status topics (one per node), decoded with :func:`decode_status`.
SUITE_TOPICS = {
    'measurement': Topic('/mr_damper/measurement', DAMPER_SAMPLES, 'measurement'),
    'parameters': Topic('/mr_damper/kwok_parameters', KWOK, 'latched'),
    'truth': Topic('/mr_damper/true_parameters', KWOK, 'latched'),
    'truth_spencer': Topic('/mr_damper/true_spencer_parameters', DAMPER_MODEL, 'latched'),
    'current_command': Topic('/mr_damper/current_command', FLOAT64, 'default'),
    'displacement_command': Topic('/mr_damper/displacement_command', FLOAT64, 'default'),
    'samples_received': Topic('/mr_damper/samples_received', UINT64, 'default'),
    'car_joint_state': Topic('/quarter_car/state', JOINT_STATE, 'default'),
    'car_state': Topic('/quarter_car/car_state', CAR_STATE, 'default'),
    'diagnostics': Topic('/diagnostics', DIAGNOSTICS, 'default'),
}

#: The CAN bridge's topics (``mr-damper-suite --config can``; ``mr-damper-record --can``): the
#: driver's measured coil current (the car's command in that run) and the chassis sensor frames.
CAN_TOPICS = {
    'measured_current': Topic('/mr_damper/measured_current', FLOAT64, 'default'),
    'can_car_state': Topic('/can/car_state', CAR_STATE, 'default'),
    'can_body_imu': Topic('/can/body_imu', IMU, 'default'),
    'can_wheel_imu': Topic('/can/wheel_imu', IMU, 'default'),
}

#: Vehicle sensing (``mr-damper-suite --sensing vehicle``; ``mr-damper-record --sensing``): the
#: car's sensors and its true state (the car state topic then carries the estimate).
SENSING_TOPICS = {
    'body_imu': Topic('/quarter_car/body_imu', IMU, 'default'),
    'suspension_position': Topic('/quarter_car/suspension_position', JOINT_STATE, 'default'),
    'true_state': Topic('/quarter_car/true_state', CAR_STATE, 'default'),
}

#: Written once by the recorder at its start, not a DDS topic: the parameter YAML the suite's
#: nodes were started with (``std_msgs/String``), so the report needs nothing but the MCAP.
CONFIG_TOPIC = Topic('/mr_damper/suite_config', STRING, 'latched')

#: Written by the recorder, not a DDS topic: the parameters each suite node actually runs with
#: (asked from the node's parameter services, its defaults included), as a ROS 2 parameter YAML
#: ``{node: {ros__parameters: {...}}}`` (``std_msgs/String``), one message per node whenever they
#: changed. The report takes its settings from these, not from copied node defaults.
NODE_PARAMETERS_TOPIC = Topic('/mr_damper/node_parameters', STRING, 'latched')
#: Nodes whose parameters the recorder asks for (names in the root namespace).
PARAMETER_NODES = ('mr_damper_rig', 'mr_damper_identifier', 'quarter_car_node',
                   'semi_active_controller', 'can_bridge', 'can_driver_sim', 'state_estimator')

#: Keys of the table whose messages are node statuses (decoded by :func:`decode_status`).
STATUS_KEYS = ('diagnostics',)
#: Node name -> the short name the launcher and the report use for its status.
NODE_KEYS = {'mr_damper_rig': 'rig', 'mr_damper_identifier': 'identifier',
             'quarter_car_node': 'quarter_car', 'semi_active_controller': 'controller',
             'mr_damper_record': 'recorder', 'state_estimator': 'estimator'}


def topic_table(keys=None, can=False, sensing=False):
    """
    Return the rows to record, by key.

    Parameters
    ----------
    keys : iterable of str or None
        Keys of :data:`SUITE_TOPICS` or :data:`CAN_TOPICS` (None: every row of
        :data:`SUITE_TOPICS`, and of :data:`CAN_TOPICS` with ``can``).
    can : bool
        Also the CAN bridge's rows (when ``keys`` is None).
    sensing : bool
        Also the vehicle sensing rows, :data:`SENSING_TOPICS` (when ``keys`` is None).

    Returns
    -------
    dict
        ``key -> Topic``.

    Raises
    ------
    ValueError
        For a key that is not in the table (the message lists the known keys).

    """
    if keys is None:
        return {**SUITE_TOPICS, **(CAN_TOPICS if can else {}),
                **(SENSING_TOPICS if sensing else {})}
    known = {**SUITE_TOPICS, **CAN_TOPICS, **SENSING_TOPICS}
    keys = list(keys)
    unknown = [k for k in keys if k not in known]
    if unknown:
        raise ValueError(f'unknown topic keys {unknown}; known: {sorted(known)}')
    return {k: known[k] for k in keys}


def decode_status(key, msg):
    """
    Decode one status message into ``{node: status dict}`` (the only status decoder of the suite).

    Parameters
    ----------
    key : str
        Topic key of the message (one of :data:`STATUS_KEYS`).
    msg : diagnostic_msgs/DiagnosticArray (rclpy or rosbags)
        One entry per ``DiagnosticStatus``: the node from its ``name`` (the node's fully
        qualified name without the leading slash, e.g. ``'fl/mr_damper_identifier'``;
        :data:`NODE_KEYS`), nested values rebuilt from the dotted keys and parsed
        (:func:`mr_damper_common.messages.health_from_diagnostic`), ``level`` and ``message``
        added.

    Returns
    -------
    dict
        Node short name (``rig``, ``identifier``, ``quarter_car``, ``controller``,
        ``recorder``; ``'fl/identifier'`` for a node in namespace ``fl``) -> status dict.

    Raises
    ------
    ValueError
        If the payload is not a status (``mr_damper_common.messages.MessageError`` or bad JSON).

    """
    if not hasattr(msg, 'status'):
        raise ValueError(f'{key}: not a diagnostic_msgs/DiagnosticArray')
    from mr_damper_common.messages import health_from_diagnostic
    out = {}
    for st in msg.status:
        full = str(st.name).split(':')[0].strip()
        ns, _, node = full.rpartition('/')
        short = NODE_KEYS.get(node, node)
        health = health_from_diagnostic(st)
        d = dict(health.values)
        d.update(level=health.level, message=health.message)
        out[f'{ns}/{short}' if ns else short] = d
    return out


def decode_parameters(msg):
    """
    Decode one parameter message (identified or true) into a flat dict by name.

    Parameters
    ----------
    msg : mr_damper_interfaces/KwokParameters or DamperModel (rclpy or rosbags)
        Identified (or kwok-current true) parameters, or a named-parameter true model.

    Returns
    -------
    dict
        KwokParameters: coefficients by name, ``i_ref_a``, ``window_start_s``,
        ``window_end_s``, ``current_min_a``, ``current_max_a``, ``rmse_n``, ``nrmse_percent``
        as floats, ``valid`` 1.0 or 0.0 and ``reason``. DamperModel: its parameters by name.

    Raises
    ------
    ValueError
        On a message no model can use (``mr_damper_common.messages.MessageError``).

    """
    from mr_damper_common.messages import damper_model_from_msg, identified_set_from_msg
    if hasattr(msg, 'parameter_names'):
        return damper_model_from_msg(msg)['parameters']
    d = identified_set_from_msg(msg).to_flat()
    d['valid'] = 1.0 if d['valid'] else 0.0
    return d


def decode_measurement(msg):
    """
    Decode one measurement message (rclpy or rosbags): a ``DamperSamples`` batch or a JointState.

    Returns
    -------
    tuple of numpy.ndarray
        ``(t, x, v, f, i)``: stamps [s], displacement [m], velocity [m/s], force [N], current
        [A] (``mr_damper_common.messages.measurement_arrays``; one sample for a JointState).

    """
    from mr_damper_common.messages import measurement_arrays
    return measurement_arrays(msg)


#: Topics that stay absolute in a namespace (by ROS convention).
ABSOLUTE_KEYS = ('diagnostics',)


def namespaced_table(table, namespaces):
    """
    Return ``table`` for the nodes of each namespace (one car corner per namespace).

    Parameters
    ----------
    table : dict
        ``key -> Topic`` (root-namespace names, :func:`topic_table`).
    namespaces : sequence of str
        Namespaces, e.g. ``('fl', 'fr')``; empty: ``table`` unchanged.

    Returns
    -------
    dict
        ``'fl/measurement' -> Topic('/fl/mr_damper/measurement', ...)`` for every row and
        namespace, except :data:`ABSOLUTE_KEYS` (``/diagnostics``), kept once under their key.

    Raises
    ------
    ValueError
        For a namespace that is not a plain name (letters, digits, underscores).

    """
    if not namespaces:
        return dict(table)
    out = {}
    for ns in namespaces:
        if not ns or not ns.replace('_', '').isalnum() or ns[0].isdigit():
            raise ValueError(f'namespace {ns!r}: use a plain name such as fl, fr, rl, rr')
        for key, row in table.items():
            if key in ABSOLUTE_KEYS:
                out[key] = row
            else:
                out[f'{ns}/{key}'] = row._replace(name=f'/{ns}{row.name}')
    return out
