"""
The suite's topics in one table, and the one decoder of each payload kind, without ROS.

:data:`SUITE_TOPICS` is what ``mr-damper-record`` records and what the report reads back: one
row per topic, ``key -> Topic(name, type, qos)``. Changing a topic's message type (e.g. the
parameters to ``mr_damper_interfaces/msg/KwokParameters``, the JSON status topics to
``/diagnostics``) is a change of this table and of :func:`decode_parameters` /
:func:`decode_status`, nothing else: the recorder writes whatever type the row names (still
serialised, typed schema from ``mr_damper_model.bag_types.suite_typestore``) and the launcher's
monitor and the report decode through these two functions.

The decoders take a message object of either origin, the rclpy class (the launcher's monitor)
or the rosbags dataclass (the report reading ``suite.mcap``): both have the same field names.
They import ``mr_damper_model.messages`` (message packages, no rclpy) when first called, so
importing this module stays ROS-free.
"""
from collections import namedtuple
import json

#: One recorded topic: absolute name, ROS 2 type name, QoS kind
#: (``'measurement'`` reliable KEEP_ALL, ``'latched'`` transient local, ``'default'`` depth 10).
Topic = namedtuple('Topic', 'name type qos')

STRING = 'std_msgs/msg/String'
FLOAT64 = 'std_msgs/msg/Float64'
ARRAY = 'std_msgs/msg/Float64MultiArray'
JOINT_STATE = 'sensor_msgs/msg/JointState'
CAR_STATE = 'mr_damper_interfaces/msg/QuarterCarState'

#: Every topic of the suite (node defaults, root namespace), by key. The :data:`STATUS_KEYS` rows
#: are the status topics (one per node), decoded with :func:`decode_status`.
SUITE_TOPICS = {
    'measurement': Topic('/mr_damper/measurement', JOINT_STATE, 'measurement'),
    'parameters': Topic('/mr_damper/kwok_parameters', ARRAY, 'latched'),
    'truth': Topic('/mr_damper/true_parameters', ARRAY, 'latched'),
    'truth_spencer': Topic('/mr_damper/true_spencer_parameters', ARRAY, 'latched'),
    'current_command': Topic('/mr_damper/current_command', FLOAT64, 'default'),
    'displacement_command': Topic('/mr_damper/displacement_command', FLOAT64, 'default'),
    'car_joint_state': Topic('/quarter_car/state', JOINT_STATE, 'default'),
    'car_state': Topic('/quarter_car/car_state', CAR_STATE, 'default'),
    'ride_metrics': Topic('/quarter_car/ride_metrics', STRING, 'default'),
    'rig_status': Topic('/mr_damper/rig_status', STRING, 'default'),
    'identifier_status': Topic('/mr_damper/identifier_status', STRING, 'default'),
    'quarter_car_status': Topic('/quarter_car/status', STRING, 'default'),
    'controller_status': Topic('/semi_active_controller/status', STRING, 'default'),
    'recorder_status': Topic('/mr_damper/recorder_status', STRING, 'default'),
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
                   'semi_active_controller')

#: Keys of the table whose messages are node statuses (decoded by :func:`decode_status`). With
#: ``/diagnostics`` this becomes the one key of that topic.
STATUS_KEYS = ('rig_status', 'identifier_status', 'quarter_car_status', 'controller_status',
               'recorder_status')
#: Node name -> the short name the launcher and the report use for its status.
NODE_KEYS = {'mr_damper_rig': 'rig', 'mr_damper_identifier': 'identifier',
             'quarter_car_node': 'quarter_car', 'semi_active_controller': 'controller',
             'mr_damper_record': 'recorder'}


def topic_table(keys=None):
    """
    Return the rows to record, by key.

    Parameters
    ----------
    keys : iterable of str or None
        Keys of :data:`SUITE_TOPICS` (None: all of them).

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
        return dict(SUITE_TOPICS)
    keys = list(keys)
    unknown = [k for k in keys if k not in SUITE_TOPICS]
    if unknown:
        raise ValueError(f'unknown topic keys {unknown}; known: {sorted(SUITE_TOPICS)}')
    return {k: SUITE_TOPICS[k] for k in keys}


def decode_status(key, msg):
    """
    Decode one status message into ``{node: status dict}`` (the only status decoder of the suite).

    Parameters
    ----------
    key : str
        Topic key of the message (one of :data:`STATUS_KEYS`).
    msg : std_msgs/String or diagnostic_msgs/DiagnosticArray (rclpy or rosbags)
        A node's JSON status (``*_status`` topics: the node is the key without ``_status``), or
        a diagnostics array: one entry per ``DiagnosticStatus``, the node from its ``name``
        (``'NODE: task'``, :data:`NODE_KEYS`), values parsed as JSON where they are (numbers,
        booleans, objects), ``level`` and ``message`` added.

    Returns
    -------
    dict
        Node short name (``rig``, ``identifier``, ``quarter_car``, ``controller``,
        ``recorder``) -> status dict.

    Raises
    ------
    ValueError
        If the payload is not a status (``mr_damper_model.messages.MessageError`` or bad JSON).

    """
    if hasattr(msg, 'status'):                  # diagnostic_msgs/DiagnosticArray
        out = {}
        for st in msg.status:
            node = str(st.name).split(':')[0].strip()
            d = {kv.key: _parse_value(kv.value) for kv in st.values}
            level = st.level
            d.update(level=int.from_bytes(level, 'little') if isinstance(level, bytes)
                     else int(level), message=str(st.message))
            out[NODE_KEYS.get(node, node)] = d
        return out
    from mr_damper_model.messages import status_from_msg
    return {key[:-len('_status')] if key.endswith('_status') else key: status_from_msg(msg)}


def _parse_value(text):
    try:
        return json.loads(text)
    except ValueError:
        return text


def decode_parameters(msg):
    """
    Decode one parameter message (identified or true) into a flat dict by name.

    Parameters
    ----------
    msg : std_msgs/Float64MultiArray (rclpy or rosbags)
        Labelled array (``mr_damper_model.messages`` layout).

    Returns
    -------
    dict
        Coefficients by name, ``i_ref_a``, ``window_end_s``, ``rmse_n``, ``nrmse_percent``,
        ``valid`` (1.0 or 0.0), ... as floats.

    Raises
    ------
    ValueError
        On a bad layout.

    """
    from mr_damper_model.messages import array_msg_to_dict
    return array_msg_to_dict(msg)


def decode_measurement(msg):
    """
    Decode one measurement ``sensor_msgs/JointState`` (rclpy or rosbags).

    Returns
    -------
    tuple of float
        ``(t, x, v, f, i)``: stamp [s], displacement [m], velocity [m/s], force [N], current
        [A] (``mr_damper_model.messages.measurement_from_msg``).

    """
    from mr_damper_model.messages import measurement_from_msg
    return measurement_from_msg(msg)


def decode_json(msg):
    """
    Decode a JSON object in a ``std_msgs/String`` (the ride metrics) into a dict.

    Raises
    ------
    ValueError
        If the payload is not a JSON object.

    """
    value = json.loads(msg.data)
    if not isinstance(value, dict):
        raise ValueError('not a JSON object')
    return value
