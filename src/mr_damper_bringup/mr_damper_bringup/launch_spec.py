"""
What ``launch/suite.launch.py`` starts, as plain data (no ROS, no ``launch``): testable here.

The launch file turns :func:`node_specs` into ``launch_ros.actions.Node(**spec)`` and
:data:`LAUNCH_ARGUMENTS` into ``DeclareLaunchArgument``; the parameter file's default is the
``PythonExpression`` of :func:`default_params_parts`. The nodes are the launcher's
(:data:`mr_damper_bringup.config.NODES`), so ``ros2 launch`` and ``mr-damper-suite`` start the
same nodes with the same names and the same parameter YAML.
"""
from mr_damper_bringup.config import NODES, RIG

#: The package whose console script each node executable is (what ``ros2 run PKG EXE`` needs).
NODE_PACKAGES = {'rig_node': 'mr_damper_rig', 'identifier_node': 'mr_damper_model',
                 'quarter_car_node': 'quarter_car_sim'}
#: (name, default, description) of the launch arguments; the default of ``params_file`` is the
#: suite YAML of the chosen ``config`` (:func:`default_params_parts`).
LAUNCH_ARGUMENTS = (
    ('config', 'sim', 'sim (virtual rig), replay (CSV / bag) or hil (hardware in the loop)'),
    ('params_file', None, 'the single parameter YAML of the nodes'),
    ('file', '', 'replay input (CSV or rosbag2 folder), replay only'),
)


def default_params_parts(config_dir, config):
    """
    Return the parts of the Python expression of the default parameter file.

    ``config`` is the launch configuration of the ``config`` argument (a substitution); the
    expression evaluates to ``<config_dir>/suite_<config>.yaml``.
    """
    return ["'", f'{config_dir}/suite_', "' + '", config, "' + '.yaml'"]


def node_specs(params_file, replay_file):
    """
    Return the keyword arguments of one ``launch_ros.actions.Node`` per node, in start order.

    Every node gets ``params_file`` (a substitution or a path) first; the rig also the replay
    file given on the command line (it overrides the YAML's empty ``file``).
    """
    specs = []
    for name, executable in NODES.items():
        parameters = [params_file]
        if name == RIG:
            parameters.append({'file': replay_file})
        specs.append({'package': NODE_PACKAGES[executable], 'executable': executable,
                      'name': name, 'parameters': parameters, 'output': 'screen',
                      'emulate_tty': True})
    return specs
