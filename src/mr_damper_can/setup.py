"""Setup for the mr_damper_can ament_python package."""
import glob

from setuptools import find_packages, setup

package_name = 'mr_damper_can'
PACKAGE_DESCRIPTION = (
    'CAN bus bridge of the MR damper suite: DBC of the damper driver and chassis sensors, '
    'ROS <-> CAN bridge node and a simulated damper driver / sensor cluster ECU.'
)

setup(
    name=package_name,
    version='0.1.0',
    packages=find_packages(exclude=['test']),
    package_data={package_name: ['dbc/*.dbc']},
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + package_name]),
        ('share/' + package_name, ['package.xml']),
        ('share/' + package_name + '/dbc', glob.glob('mr_damper_can/dbc/*.dbc')),
    ],
    install_requires=['setuptools'],
    zip_safe=False,
    maintainer='MR damper suite developers',
    maintainer_email='mr-damper-suite@example.org',
    description=PACKAGE_DESCRIPTION,
    license='Apache-2.0',
    extras_require={'test': ['pytest']},
    entry_points={
        'console_scripts': [
            'can_bridge_node = mr_damper_can.entry_points:can_bridge_node',
            'can_driver_sim = mr_damper_can.entry_points:can_driver_sim',
            'vehicle_bridge_node = mr_damper_can.entry_points:vehicle_bridge_node',
            'vehicle_computer_node = mr_damper_can.entry_points:vehicle_computer_node',
        ],
    },
)
