"""
ROS 2 launch file of the MR damper suite, for machines with a full ROS 2 install.

    ros2 launch mr_damper_bringup suite.launch.py [config:=sim|replay|hil] [params_file:=FILE]
        [file:=REPLAY.csv|BAG_DIR]

Starts the three nodes, each with the same parameter YAML (default
``config/suite_<config>.yaml`` of this package, installed to ``share/mr_damper_bringup``):

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

HERE = os.path.dirname(os.path.abspath(__file__))
#: the package's config folder: next to launch/ in the source tree and in share/mr_damper_bringup
CONFIG_DIR = os.path.join(os.path.dirname(HERE), 'config')

#: (package, executable, node name): the console scripts of the three ament_python packages
NODES = (
    ('mr_damper_rig', 'rig_node', 'mr_damper_rig'),
    ('mr_damper_model', 'identifier_node', 'mr_damper_identifier'),
    ('quarter_car_sim', 'quarter_car_node', 'quarter_car_node'),
)


def generate_launch_description():
    """Return the launch description of the suite (three nodes, one parameter YAML)."""
    config = LaunchConfiguration('config')
    params_file = LaunchConfiguration('params_file')
    replay_file = LaunchConfiguration('file')
    default_params = PythonExpression([
        "'", os.path.join(CONFIG_DIR, 'suite_'), "' + '", config, "' + '.yaml'"])
    actions = [
        DeclareLaunchArgument('config', default_value='sim',
                              description='sim (virtual rig) or replay (CSV / bag)'),
        DeclareLaunchArgument('params_file', default_value=default_params,
                              description='the single parameter YAML of the three nodes'),
        DeclareLaunchArgument('file', default_value='',
                              description='replay input (CSV or rosbag2 folder), replay only'),
    ]
    for package, executable, name in NODES:
        parameters = [params_file]
        if package == 'mr_damper_rig':
            # replay: the file given on the command line overrides the YAML's (empty) one
            parameters.append({'file': replay_file})
        actions.append(Node(package=package, executable=executable, name=name,
                            parameters=parameters, output='screen', emulate_tty=True))
    return LaunchDescription(actions)
