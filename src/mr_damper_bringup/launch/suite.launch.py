"""
ROS 2 launch file of the MR damper suite, for machines with a full ROS 2 install.

    ros2 launch mr_damper_bringup suite.launch.py [config:=sim|replay|hil] [params_file:=FILE]
        [file:=REPLAY.csv|BAG_DIR]

Starts the launcher's nodes (``mr_damper_bringup.launch_spec``, the same as ``mr-damper-suite``),
each with the same parameter YAML (default ``config/suite_<config>.yaml`` of this package,
installed to ``share/mr_damper_bringup``):

- ``ros2 run mr_damper_rig rig_node``            (node name ``mr_damper_rig``)
- ``ros2 run mr_damper_model identifier_node``   (node name ``mr_damper_identifier``)
- ``ros2 run quarter_car_sim quarter_car_node``  (node name ``quarter_car_node``)

Set ``ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST`` and a ``ROS_DOMAIN_ID`` of your own in the shell
first when several people share the network. Where ``ros2 launch`` does not exist (pip-installed
rclpy), ``mr-damper-suite`` does the same, records every topic into one MCAP file and writes the
run's summary; here, record with ``ros2 run mr_damper_bringup mr-damper-record --out run.mcap``.
"""
import os

from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument
from launch.substitutions import LaunchConfiguration, PythonExpression
from launch_ros.actions import Node

from mr_damper_bringup.launch_spec import default_params_parts, LAUNCH_ARGUMENTS, node_specs

HERE = os.path.dirname(os.path.abspath(__file__))
#: the package's config folder: next to launch/ in the source tree and in share/mr_damper_bringup
CONFIG_DIR = os.path.join(os.path.dirname(HERE), 'config')


def generate_launch_description():
    """Return the launch description of the suite (mr_damper_bringup.launch_spec as actions)."""
    defaults = {'params_file': PythonExpression(
        default_params_parts(CONFIG_DIR, LaunchConfiguration('config')))}
    actions = [DeclareLaunchArgument(name, default_value=defaults.get(name, default),
                                     description=description)
               for name, default, description in LAUNCH_ARGUMENTS]
    specs = node_specs(LaunchConfiguration('params_file'), LaunchConfiguration('file'))
    actions += [Node(**spec) for spec in specs]
    return LaunchDescription(actions)
